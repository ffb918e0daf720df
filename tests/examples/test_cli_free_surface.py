"""The free-surface scenes (``[liquid]``) from the command line: dam_break and sloshing run a
few steps with video, fields and checkpoints; a resume is bit for bit; bad input is one line."""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np
import pytest
from typer.testing import CliRunner

from elastoflow.cli import app

runner = CliRunner()


def _invoke(*args: object):
    result = runner.invoke(app, [str(a) for a in args])
    return result, result.output


def test_dam_break_runs_with_video_fields_and_checkpoints(tmp_path) -> None:
    out = tmp_path / "dam"
    result, text = _invoke("run", "dam_break", "--steps", "4", "--out", out, "--fields",
                           "npz,vtk,xdmf", "--every", "2", "--checkpoint-every", "2",
                           "--meshes")
    assert result.exit_code == 0, text
    assert "4/4" in text  # the progress bar reached the end
    assert (out / "video.mp4").stat().st_size > 0
    with np.load(out / "fields" / "step_000004.npz") as frame:
        phi = frame["level_set"]
        assert phi.shape == (256, 128)
        liquid = phi < 0.0
        # The column a / 32 cells wide and twice as tall: 32 x 64 cells of water.
        assert 0.9 * 32 * 64 < np.count_nonzero(liquid) < 1.1 * 32 * 64
        assert np.all(frame["pressure"][~liquid] == 0.0)
        # The surface as polylines: the column's outline inside the cell centres' box.
        points, offsets = frame["surface_points"], frame["surface_offsets"]
        assert len(offsets) >= 2 and offsets[-1] == len(points) > 10
        assert points[:, 1].max() == pytest.approx(2 * 0.05715, abs=0.01)
    mesh = meshio.read(out / "fields" / "fluid_000004.vtu")
    np.testing.assert_array_equal(mesh.cell_data["level_set"][0], phi.ravel())
    assert "level_set" in (out / "fields" / "fluid.xdmf").read_text()
    # The surface for Blender, beside the (absent) bodies' meshes.
    surface = meshio.read(out / "meshes" / "surface_000004.obj")
    assert len(surface.points) > 20
    with np.load(out / "checkpoints" / "checkpoint_00000004.npz") as checkpoint:
        np.testing.assert_array_equal(checkpoint["level_set"], phi)
        assert float(checkpoint["liquid_area"]) > 0.0


def test_sloshing_resume_is_bit_for_bit(tmp_path) -> None:
    straight, split = tmp_path / "straight", tmp_path / "split"
    args = ("--no-video", "--no-probes", "--quiet", "--fields", "none")
    result, text = _invoke("run", "sloshing", "--out", straight, "--steps", "6", *args)
    assert result.exit_code == 0, text
    assert _invoke("run", "sloshing", "--out", split, "--steps", "3", *args)[0].exit_code == 0
    result, text = _invoke("run", "sloshing", "--out", split, "--steps", "6", "--resume", *args)
    assert result.exit_code == 0 and "resuming from" in text, text
    with np.load(straight / "checkpoints" / "checkpoint_00000006.npz") as a, \
            np.load(split / "checkpoints" / "checkpoint_00000006.npz") as b:
        assert set(a.files) == set(b.files)
        assert "level_set" in a.files
        for key in a.files:
            np.testing.assert_array_equal(a[key], b[key], err_msg=key)


_LIQUID = """
[domain]
lx = 1.0
ly = 0.5
nx = 16
[fluid]
gravity = [0.0, -9.81]
[liquid]
boxes = [[0.0, 0.0, 0.25, 0.25]]
[time]
dt = 0.01
steps = 2
"""


def _validate(tmp_path: Path, text: str) -> tuple[int, list[str]]:
    path = tmp_path / "scene.toml"
    path.write_text(text)
    result, output = _invoke("validate", path)
    return result.exit_code, output.strip().splitlines()


def test_liquid_scene_errors_are_one_line_each(tmp_path) -> None:
    code, lines = _validate(tmp_path, _LIQUID)
    assert code == 0, lines
    floating = _LIQUID + """
[[bodies]]
shape = { type = "rectangle", box = [0.5, 0.1, 0.6, 0.2], divisions = [2, 2] }
material = { density = 500.0, young_modulus = 1e5, poisson_ratio = 0.3 }
"""
    code, lines = _validate(tmp_path, floating)
    assert code == 0, lines
    code, lines = _validate(tmp_path, floating + '[coupling]\nscheme = "explicit"\n')
    assert code == 2 and len(lines) == 1, lines
    assert 'scene.toml: coupling.scheme = "explicit": bodies and obstacles in a liquid' in lines[0]
    code, lines = _validate(tmp_path, floating.replace("density = 500.0", "density = -5.0"))
    assert code == 2 and len(lines) == 1, lines
    assert "bodies.0.material.density" in lines[0]
    code, lines = _validate(tmp_path, _LIQUID.replace("[[0.0, 0.0, 0.25, 0.25]]",
                                                      "[[0.0, 0.0, 1.5, 0.25]]"))
    assert code == 2 and len(lines) == 1, lines
    assert "scene.toml: liquid.boxes.0 = [0, 0, 1.5, 0.25]: must lie inside the domain" in lines[0]
    code, lines = _validate(tmp_path, _LIQUID.replace("[time]", '[boundaries]\ntop = "outflow"\n'
                                                      "[time]"))
    assert code == 2 and len(lines) == 1, lines
    assert "boundaries.top = outflow: a scene with [liquid] needs walls" in lines[0]
    code, lines = _validate(tmp_path, _LIQUID.replace("boxes = [[0.0, 0.0, 0.25, 0.25]]",
                                                      'viscosity = "air"'))
    assert code == 2 and len(lines) == 1, lines
    assert "liquid.viscosity = 'air': must be 'stress_free' or 'whole_grid'" in lines[0]
    code, lines = _validate(tmp_path, _LIQUID.replace("boxes = [[0.0, 0.0, 0.25, 0.25]]",
                                                      'viscosity = "whole_grid"'))
    assert code == 2 and len(lines) == 1, lines
    assert "liquid = " in lines[0] and "give boxes" in lines[0]


def test_floating_runs_from_its_name_with_video_probes_and_a_bit_exact_resume(tmp_path) -> None:
    """The library scene `floating` (three elastic bodies dropped into water): a few steps
    with video and probes, bodies falling in the air (no fluid force yet); a resume repeats
    the same probes."""
    from elastoflow.io import read_probes

    out = tmp_path / "floating"
    result, text = _invoke("run", "floating", "--steps", "4", "--out", out, "--every", "2",
                           "--checkpoint-every", "2")
    assert result.exit_code == 0, text
    assert (out / "video.mp4").stat().st_size > 0
    columns, rows = read_probes(out / "probes.csv")
    assert len(rows) == 4 and any("body1" in c for c in columns), columns
    force_y = [row[i] for row in rows for i, c in enumerate(columns)
               if c.startswith("body1_force_y")]
    assert force_y and all(f == 0.0 for f in force_y)  # still in the air
    again = tmp_path / "again"
    assert _invoke("run", "floating", "--steps", "2", "--out", again, "--checkpoint-every",
                   "2", "--no-video", "--quiet")[0].exit_code == 0
    result, text = _invoke("run", "floating", "--steps", "4", "--out", again, "--resume",
                           "--no-video", "--quiet")
    assert result.exit_code == 0, text
    assert read_probes(again / "probes.csv")[1] == rows


@pytest.mark.parametrize("name", ["elastic_gate", "dam_break_obstacle"])
def test_free_surface_fsi_scenes_run_from_their_names(name: str, tmp_path) -> None:
    """The library scenes `elastic_gate` and `dam_break_obstacle` (a clamped elastic body in
    a dam break): a few steps with video and probes; the clamped body is pushed downstream
    by the water from the first step (the gate), or not yet touched (the obstacle)."""
    from elastoflow.io import read_probes

    out = tmp_path / name
    result, text = _invoke("run", name, "--steps", "3", "--out", out, "--every", "1")
    assert result.exit_code == 0, text
    assert (out / "video.mp4").stat().st_size > 0
    columns, rows = read_probes(out / "probes.csv")
    assert len(rows) == 3
    moved = [row[i] for row in rows for i, c in enumerate(columns)
             if c.startswith("body0_") and c.endswith("displacement_x [m]")]
    assert len(moved) == 3 and all(np.isfinite(moved))
    if name == "elastic_gate":
        assert moved[-1] > 0.0
    else:
        assert max(abs(m) for m in moved) < 1e-6
