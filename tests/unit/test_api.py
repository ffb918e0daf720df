"""The notebook API of the README: load a scene, step, read fields and bodies, render."""

from __future__ import annotations

import numpy as np
import pytest

import elastoflow
from elastoflow.scenes import SceneError, get_scene, scene_to_toml


def _tiny_bar_scene_toml() -> str:
    scene = get_scene("bar_in_jet")
    data = scene.model_dump(mode="json")
    data["domain"]["nx"] = 32
    text = scene_to_toml(type(scene).model_validate(data))
    return text


def test_load_by_file_steps_and_renders(tmp_path):
    path = tmp_path / "bar.toml"
    path.write_text(_tiny_bar_scene_toml())
    sim = elastoflow.load(path)
    before = sim.state.bodies[0].positions.copy()
    for _ in range(3):
        sim.step()
    assert sim.step_index == 3
    assert sim.state.fluid.velocity_x.shape == (33, 32)
    assert np.isfinite(sim.state.fluid.pressure).all()
    assert sim.state.bodies[0].positions.shape == before.shape
    frame = elastoflow.frame(sim, view="speed")
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3


def test_load_by_name_and_unknown_name():
    sim = elastoflow.load("cavity")
    assert sim.grid.nx == 64 and not sim.bodies
    with pytest.raises(SceneError, match="no_such_scene"):
        elastoflow.load("no_such_scene")
