"""3D scenes: a [domain] with lz makes a Scene3D, built into a 3D Simulation."""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
import pytest

from elastoflow.scenes import (
    Scene3D,
    SceneError,
    build_simulation,
    get_scene,
    list_scenes,
    parse_scene,
    scene_to_toml,
    step_count,
)
from elastoflow.simulation import CoupledModel3D

SCENE: dict[str, Any] = {
    "domain": {"lx": 1.5, "ly": 1.0, "lz": 1.0, "nx": 12},
    "fluid": {"viscosity": 0.01, "initial_velocity": [1.0, 0.0, 0.0]},
    "boundaries": {"left": {"type": "inflow", "speed": 1.0}, "right": "outflow",
                   "bottom": "free_slip", "top": "free_slip", "back": "free_slip",
                   "front": "free_slip"},
    "obstacles": [{"shape": "sphere", "center": [0.5, 0.5, 0.5], "radius": 0.2}],
    "bodies": [{"shape": {"type": "box", "box": [0.9, 0.3, 0.3, 1.2, 0.6, 0.6]},
                "material": {"density": 3000.0, "young_modulus": 1e5, "poisson_ratio": 0.3},
                "fixed": {"box": [0.9, 0.3, 0.3, 0.95, 0.6, 0.6]}}],
    "time": {"cfl": 1.0, "steps": 3},
}


def changed(path: str, value: Any) -> dict[str, Any]:
    data = copy.deepcopy(SCENE)
    *keys, last = path.split(".")
    target: Any = data
    for key in keys:
        target = target[int(key)] if isinstance(target, list) else target[key]
    if value is None:
        del target[last]
    else:
        target[last] = value
    return data


def test_a_domain_with_lz_is_a_3d_scene_that_builds_and_runs() -> None:
    scene = parse_scene(SCENE)
    assert isinstance(scene, Scene3D)
    assert scene.domain.cells == (12, 8, 8)
    assert step_count(scene) == 3
    simulation = build_simulation(scene)
    assert isinstance(simulation.model, CoupledModel3D)
    simulation.run(step_count(scene))
    body = simulation.state.bodies[0]
    assert np.isfinite(body.positions).all()
    # The fixed face stays put; the rest is pushed downstream.
    fixed = simulation.model.bodies[0].fixed_nodes
    assert fixed.size > 0
    np.testing.assert_array_equal(body.positions[fixed],
                                  simulation.model.bodies[0].mesh.points[fixed])


def test_a_3d_scene_round_trips_through_toml() -> None:
    import tomllib

    scene = parse_scene(SCENE)
    again = parse_scene(tomllib.loads(scene_to_toml(scene)))
    assert again == scene


@pytest.mark.parametrize(("path", "value", "expected"), [
    ("domain.nz", 8, "domain.nz: unknown key (allowed keys: lx, ly, lz, nx, h, origin)"),
    ("obstacles.0.center", [0.5, 0.5], "obstacles.0.center = [0.5, 0.5]: too few items"),
    ("coupling", {"scheme": "partitioned"}, "coupling.scheme = 'partitioned': must be "
     "'explicit' or 'monolithic'"),
    ("coupling", {"scheme": "monolithic", "force_relaxation": 0.5}, "coupling = { scheme = "
     "'monolithic', force_relaxation = 0.5 }: force_relaxation stabilises the explicit "
     "scheme only"),
    ("boundaries.right", "no_slip", "boundaries.left: fluid flows in but no side lets it out"),
    ("obstacles.0.radius", 0.6, "obstacles.0 (sphere, bounds [-0.1, -0.1, -0.1, 1.1, 1.1, "
     "1.1]): must lie inside the domain [0, 0, 0, 1.5, 1, 1]"),
    ("bodies.0.shape.box", [0.9, 0.3, 0.3, 0.8, 0.6, 0.6], "bodies.0.shape.box"),
    ("domain.lz", 1.05, "domain.nx = 12 gives cells of side 0.125: lz must be a whole number"),
    ("boundaries.back", {"type": "moving", "velocity": [0.0, 0.0, 1.0]},
     "boundaries.back.velocity = [0, 0, 1]: a moving wall slides along itself"),
])
def test_bad_3d_scenes_get_one_line_each(path: str, value: Any, expected: str) -> None:
    with pytest.raises(SceneError) as error:
        parse_scene(changed(path, value))
    assert len(error.value.problems) == 1
    assert expected in error.value.problems[0]


def test_a_fixed_box_that_holds_no_node_is_refused() -> None:
    scene = parse_scene(changed("bodies.0.fixed.box", [0.0, 0.0, 0.0, 0.1, 0.1, 0.1]))
    with pytest.raises(SceneError, match="bodies.0.fixed.box .* holds no node"):
        build_simulation(scene)


def test_a_moving_obstacle_that_leaves_the_domain_is_refused() -> None:
    data = changed("obstacles.0.motion", {"velocity": [0.0, 0.0, 10.0]})
    with pytest.raises(SceneError, match="obstacles.0.motion: the obstacle leaves the domain"):
        build_simulation(parse_scene(data))


@pytest.mark.parametrize("name", ["sphere_drag", "bar_in_jet_3d"])
def test_the_library_3d_scenes_build(name: str) -> None:
    assert name in list_scenes()
    scene = get_scene(name)
    assert isinstance(scene, Scene3D)
    simulation = build_simulation(scene)
    assert isinstance(simulation.model, CoupledModel3D)


@pytest.mark.parametrize("name", ["elastic_block_3d", "sphere_settling"])
def test_the_library_scenes_of_bodies_as_dense_as_the_fluid_are_monolithic(name: str) -> None:
    """Both run with the monolithic coupling (a block as dense as the water; a sphere in
    viscous oil) and take steps from their names."""
    from elastoflow.simulation import MonolithicCoupling3D

    simulation = build_simulation(get_scene(name))
    assert isinstance(simulation.scheme, MonolithicCoupling3D)
    simulation.run(2)
    report = simulation.last_report
    assert report is not None and report.pressure_residual <= 1e-6
