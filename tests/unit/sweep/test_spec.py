"""Sweep files: designs (grid, points, samples), key paths, one line per bad point, results."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from elastoflow.sweep import (
    SweepError,
    load_sweep,
    parse_sweep,
    plan_sweep,
    scalar_results,
    set_key_path,
    summary_frame,
)

SCENE = """
name = "tiny"
[domain]
lx = 1.0
ly = 1.0
nx = 8
[fluid]
viscosity = 0.01
[boundaries]
top = { type = "moving", velocity = 1.0 }
[time]
dt = 0.01
steps = 20
substeps = 1
[outputs]
probes = [{ kind = "kinetic_energy" }]
"""


@pytest.fixture()
def scene_file(tmp_path: Path) -> Path:
    path = tmp_path / "tiny.toml"
    path.write_text(SCENE)
    return path


def _sweep(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "sweep.toml"
    path.write_text('scene = "tiny.toml"\n' + text)
    return path


def test_grid_is_every_combination_in_order(tmp_path: Path, scene_file: Path) -> None:
    spec = load_sweep(_sweep(tmp_path, '[grid]\n"fluid.viscosity" = [0.01, 0.02]\n'
                                       '"boundaries.top.velocity" = [1.0, 2.0, 3.0]\n'))
    points = spec.parameter_points()
    assert len(points) == 6
    assert points[0] == {"fluid.viscosity": 0.01, "boundaries.top.velocity": 1.0}
    assert points[-1] == {"fluid.viscosity": 0.02, "boundaries.top.velocity": 3.0}
    plan = plan_sweep(spec)
    assert [p.scene.fluid.viscosity for p in plan.points] == [0.01] * 3 + [0.02] * 3
    assert plan.points[4].scene.boundaries.top.velocity == 2.0
    assert plan.points[0].folder_name == "point_00000"
    # Checkpoints are always on (a killed point resumes), the video off by default.
    assert plan.points[0].scene.outputs.checkpoint.every == 2
    assert plan.points[0].scene.outputs.video is None


def test_latin_hypercube_has_one_sample_per_slice_and_is_reproducible() -> None:
    data = {"scene": "cavity", "sample": {"count": 10, "seed": 3, "ranges": {
        "fluid.viscosity": {"low": 1e-3, "high": 1e-1, "scale": "log"},
        "boundaries.top.velocity": [0.5, 1.5]}}}
    points = parse_sweep(data).parameter_points()
    again = parse_sweep(data).parameter_points()
    assert points == again and len(points) == 10
    speed = np.array([p["boundaries.top.velocity"] for p in points])
    assert sorted(np.floor((speed - 0.5) * 10).astype(int)) == list(range(10))
    logs = np.log10([p["fluid.viscosity"] for p in points])
    assert sorted(np.floor((logs + 3) / 2 * 10).astype(int)) == list(range(10))
    other = parse_sweep({**data, "sample": {**data["sample"], "seed": 4}}).parameter_points()
    assert other != points
    rounded = parse_sweep({"scene": "cavity", "sample": {"method": "random", "count": 5, "ranges": {
        "domain.nx": {"low": 8, "high": 16, "integer": True}}}}).parameter_points()
    assert all(isinstance(p["domain.nx"], int) and 8 <= p["domain.nx"] <= 16 for p in rounded)


def test_every_bad_point_gets_one_line(tmp_path: Path, scene_file: Path) -> None:
    path = _sweep(tmp_path, """
[[points]]
"fluid.viscosity" = 0.02
[[points]]
"fluid.viscosity" = -1.0
[[points]]
"fluid.viscosty" = 1.0
[[points]]
"bodies.0.material.density" = 1.0
[[points]]
"domain.nx" = "8"
[[points]]
"time.dt" = 0.02
"obstacles.x" = 1
""")
    with pytest.raises(SweepError) as caught:
        plan_sweep(load_sweep(path))
    lines = str(caught.value).splitlines()
    assert len(lines) == 5, lines
    assert all(line.startswith(f"{path}: point ") for line in lines)
    assert "point 1 (fluid.viscosity = -1.0): fluid.viscosity = -1.0: must be greater" in lines[0]
    assert "fluid.viscosty: unknown key" in lines[1]
    assert "bodies is an empty array" in lines[2]
    assert "domain.nx" in lines[3] and "integer" in lines[3]
    assert "point 5" in lines[4] and "obstacles is an empty array" in lines[4]


def test_bad_sweep_files_say_where(tmp_path: Path, scene_file: Path) -> None:
    with pytest.raises(SweepError, match="exactly one of"):
        load_sweep(_sweep(tmp_path, '[grid]\n"fluid.viscosity" = [1.0]\n[[points]]\n'
                                    '"fluid.viscosity" = 1.0\n'))
    with pytest.raises(SweepError, match="sample.ranges.a: high = 1.0 must exceed low = 2.0"):
        parse_sweep({"scene": "cavity", "sample": {"count": 2, "ranges": {"a": [2.0, 1.0]}}})
    with pytest.raises(SweepError, match="not valid TOML"):
        load_sweep(_sweep(tmp_path, "[grid\n"))
    with pytest.raises(SweepError, match="scene = 'nowhere.toml'"):
        plan_sweep(parse_sweep({"scene": "nowhere.toml", "points": [{}]}, base_dir=tmp_path))
    with pytest.raises(SweepError, match=r"set\.domain\.nz\.q: domain has no 'nz'"):
        plan_sweep(parse_sweep({"scene": "cavity", "set": {"domain.nz.q": 1}, "points": [{}]}))
    with pytest.raises(SweepError, match="snapshots: every point must have the same grid"):
        plan_sweep(parse_sweep({"scene": "tiny.toml", "grid": {"domain.nx": [8, 16]},
                                "snapshots": {"times": [0.1]}}, base_dir=tmp_path))
    # Same cells, other origin: the store's x and y would be those of point 0 for both.
    with pytest.raises(SweepError, match=r"8x8 cells of 0\.125 m from \(0, 0\) \(point 0\), "
                                         r"8x8 cells of 0\.125 m from \(1, 0\) \(point 1\)"):
        plan_sweep(parse_sweep({"scene": "tiny.toml", "grid": {"domain.origin": [[0.0, 0.0],
                                                                                  [1.0, 0.0]]},
                                "snapshots": {"times": [0.1]}}, base_dir=tmp_path),
                   build=False)


def test_set_key_path_walks_tables_and_arrays_and_drops_the_alternative() -> None:
    data = {"time": {"dt": 0.1, "steps": 3}, "bodies": [{"material": {"density": 1.0}}]}
    set_key_path(data, "bodies.0.material.density", 2.0)
    set_key_path(data, "time.cfl", 0.5)
    set_key_path(data, "time.duration", 2.0)
    assert data == {"time": {"cfl": 0.5, "duration": 2.0},
                    "bodies": [{"material": {"density": 2.0}}]}
    with pytest.raises(KeyError, match="must be an index 0..0"):
        set_key_path(data, "bodies.1.material", {})
    with pytest.raises(KeyError, match="is a value"):
        set_key_path(data, "time.cfl.x", 1)


def test_scalar_results_final_and_periodic_statistics() -> None:
    time = np.arange(0.0, 10.0, 0.01)
    rows = np.column_stack((np.arange(len(time)), time, 2.0 + 0.5 * np.sin(2 * np.pi * 1.5 * time),
                            time**2)).tolist()
    results = scalar_results(["step", "time [s]", "force_y [N/m]", "ramp"], rows, after=2.0)
    assert results["force_y_frequency [Hz]"] == pytest.approx(1.5, rel=1e-3)
    assert results["force_y_mean [N/m]"] == pytest.approx(2.0, abs=1e-3)
    assert results["force_y_amplitude [N/m]"] == pytest.approx(0.5, rel=1e-3)
    assert results["force_y_final [N/m]"] == pytest.approx(rows[-1][2])
    assert results["ramp_final"] == pytest.approx(rows[-1][3])
    assert math.isnan(results["ramp_frequency [Hz]"]) and math.isnan(results["ramp_mean"])


def test_summary_frame_has_typed_columns() -> None:
    rows = [{"point": 0, "parameters": {"a": 1.0, "b": [1, 2]}, "status": "done", "message": "",
             "wall_time [s]": 1.0, "steps": 10, "time [s]": 0.1, "attempts": 1,
             "resumed_from_step": 0, "worker": "w", "folder": "point_00000",
             "results": {"x_final": 2.0}},
            {"point": 1, "parameters": {"a": 2.0, "b": [3, 4]}, "status": "pending"}]
    frame = summary_frame(rows, ["a", "b"])
    assert list(frame.columns[:4]) == ["point", "a", "b", "status"]
    assert frame["b"].tolist() == ["[1, 2]", "[3, 4]"]
    assert frame["x_final"].dtype == np.float64 and math.isnan(frame["x_final"][1])
    assert frame["status"].tolist() == ["done", "pending"]


def test_a_scene_that_is_neither_built_in_nor_a_file_says_both(tmp_path: Path) -> None:
    spec = parse_sweep({"scene": "cavty", "grid": {"fluid.viscosity": [0.01]}},
                       base_dir=tmp_path, source="s.toml")
    with pytest.raises(SweepError) as caught:
        plan_sweep(spec)
    from elastoflow.scenes import list_scenes

    assert caught.value.problems == [
        f"scene = 'cavty': neither a built-in scene ({', '.join(list_scenes())}) nor a file "
        f"({tmp_path / 'cavty'} does not exist)"]


def test_a_sweep_file_not_in_utf8_is_one_line(tmp_path: Path) -> None:
    path = tmp_path / "s.toml"
    path.write_bytes(b'name = "caf\xe9"\n')
    with pytest.raises(SweepError) as caught:
        load_sweep(path)
    assert caught.value.problems == [
        "not a text file in UTF-8 (byte 0xe9 at offset 11); a sweep file is UTF-8 TOML"]
