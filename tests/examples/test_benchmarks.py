"""The benchmark modules run end to end in their smallest mode (no timing assertions).

Each writes its JSON into a temporary folder here, never over ``benchmarks/results``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("elastoflow.simulation")
_ROOT = Path(__file__).resolve().parents[2]
if (_ROOT / "benchmarks").is_dir() and str(_ROOT) not in sys.path:
    sys.path.insert(0, str(_ROOT))
benchmarks_common = pytest.importorskip("benchmarks._common")


@pytest.fixture()
def results(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setattr(benchmarks_common, "RESULTS_DIR", tmp_path)
    return tmp_path


def _written(folder: Path, name: str) -> list[dict]:
    payload = json.loads((folder / f"{name}.json").read_text())
    assert payload["machine"]["cores"] >= 1 and payload["commit"]
    return payload["results"]


def test_versus_target_says_met_or_by_how_much() -> None:
    versus = benchmarks_common.versus_target
    assert versus(10.0, 20.0, at_most=True) == "met"
    assert versus(30.0, 20.0, at_most=True) == "x1.50 over"
    assert versus(50.0, 100.0, at_most=False) == "x2.00 under"
    assert versus(100.0, 60.0, at_most=False) == "met"


def test_scenes_runs_each_case_in_its_own_process(results: Path) -> None:
    from benchmarks import bench_scenes

    rows = bench_scenes.main(["--cases", "bar_in_jet,large_512", "--steps", "2", "--warmup",
                              "1", "--size", "32"])
    assert [row["case"] for row in rows] == ["bar_in_jet", "large_512"]
    written = _written(results, "scenes")
    assert written[-1]["case"].startswith("baseline")
    for row in rows:
        assert row["peak_memory_mb"] > written[-1]["peak_memory_mb"] > 0.0
        assert row["boundary_map_ms"] > 0.0 and row["classification_ms"] > 0.0
        assert row["share_vs_5pct"] == "met" or row["share_vs_5pct"].endswith("over")
    assert rows[1]["bodies"] == 5 and rows[1]["obstacles"] == 1


def test_output_viewer_and_startup_run(results: Path) -> None:
    from benchmarks import bench_output, bench_startup, bench_viewer

    output = bench_output.main(["--steps", "2", "--size", "32"])[0]
    assert output["ms_per_step_with_video"] > 0.0 and output["ms_per_frame_drawing"] > 0.0
    viewer = bench_viewer.main(["--frames", "2", "--size", "32"])[0]
    assert viewer["fps"] > 0.0 and viewer["ms_update"] > 0.0
    startup = bench_startup.main(["--quick"])[0]
    assert 0.0 < startup["seconds_imports"] < startup["seconds_to_first_step"]
    for name in ("output", "viewer", "startup"):
        assert _written(results, name)


def test_coupling_benchmark_runs(results: Path) -> None:
    from benchmarks import bench_coupling

    rows = bench_coupling.main(["--quick", "--steps", "2", "--size", "32"])
    assert [row["case"] for row in rows] == ["bar_in_jet explicit", "bar_in_jet monolithic",
                                             "windmill explicit", "windmill monolithic"]
    assert all(row["ms_per_step"] > 0.0 and row["pressure_iterations"] > 0 for row in rows)
    assert rows[1]["ratio_to_explicit"] > 0.0 and rows[3]["ratio_to_explicit"] > 0.0
    assert _written(results, "coupling")


def test_runner_passes_option_values_to_the_benchmark(monkeypatch) -> None:
    """``python -m benchmarks coupling --steps 3``: 3 is the value of --steps, not a
    benchmark's name (it used to be refused as an unknown benchmark)."""
    import benchmarks.__main__ as runner
    from benchmarks import bench_coupling

    seen: list[list[str]] = []
    monkeypatch.setattr(bench_coupling, "main", lambda options: seen.append(options) or [])
    assert runner.main(["coupling", "--steps", "3", "--size", "32"]) == 0
    assert seen == [["--steps", "3", "--size", "32"]]
    assert runner.main(["coupling", "3"]) == 2


def test_runner_help_describes_and_runs_nothing(monkeypatch, capsys) -> None:
    """``python -m benchmarks unsteady --help`` prints the benchmark's description; it used
    to run every part of the benchmark (and rewrite its files in docs/)."""
    import benchmarks.__main__ as runner
    from benchmarks import bench_unsteady

    seen: list[list[str]] = []
    monkeypatch.setattr(bench_unsteady, "main", lambda options: seen.append(options) or [])
    assert runner.main(["unsteady", "--help"]) == 0
    assert seen == []
    assert "--parts=" in capsys.readouterr().out


def test_three_d_scenes_benchmark_runs(results: Path) -> None:
    from benchmarks import bench_three_d_scenes

    rows = bench_three_d_scenes.main(["--quick", "--cases", "bar_in_jet_3d,sphere_drag",
                                      "--size", "16"])
    assert [row["case"] for row in rows] == ["bar_in_jet_3d", "sphere_drag"]
    assert all(row["ms_per_step"] > 0.0 and row["pressure_iterations"] > 0 for row in rows)
    assert rows[0]["tetrahedra"] > 0 and rows[1]["obstacles"] == 1
    assert _written(results, "three_d_scenes")


def test_turek_hron_deflection_study_runs(results: Path) -> None:
    from benchmarks import bench_turek_hron

    rows = bench_turek_hron.main(["--deflection", "--resolutions=5", "--tips=0,1",
                                  "--duration=0.2"])
    assert [row["tip deflection [mm]"] for row in rows] == [0.0, 1.0]
    assert all(row["drag [N/m]"] > 0.0 for row in rows)
    assert "dlift/dtip since the row before [N/m per mm]" in rows[1]
    assert _written(results, "turek_hron_deflection")


def test_turek_hron_placement_study_runs(results: Path) -> None:
    from benchmarks import bench_turek_hron

    rows = bench_turek_hron.main(["--placement", "--resolutions=5", "--cells-5=20,22",
                                  "--duration=0.1", "--layers=2"])
    grids = [row for row in rows if "cells across" in row]
    assert [row["cells across"] for row in grids] == [20, 22]
    assert all(row["layers"] == 2 and 0.0 <= row["flag top in its cell"] < 1.0 for row in grids)
    summary = [row for row in rows if row.get("quantity") == "uy_A"]
    assert len(summary) == 1 and summary[0]["grids"] == 2
    assert summary[0]["min"] <= summary[0]["mean"] <= summary[0]["max"]
    assert _written(results, "turek_hron_placement")


@pytest.mark.parametrize(("argv", "message"), [
    (["--resolutions", "20"], "argument '--resolutions'"),
    (["--resolution=20"], "argument '--resolution=20'"),
    (["--parts=dfg,speeds"], "'speeds' is not one of"),
    (["--advection=upwind5"], "'upwind5' is not one of"),
])
def test_unsteady_refuses_what_it_does_not_know(argv: list[str], message: str,
                                                capsys) -> None:
    """A malformed or unknown argument used to be ignored, and the defaults (every part)
    ran instead; now it is refused in one line (exit status 2) before anything runs."""
    from benchmarks import bench_unsteady

    with pytest.raises(SystemExit) as refused:
        bench_unsteady.main(argv)
    assert refused.value.code == 2
    error = capsys.readouterr().err
    assert message in error and error.count("\n") == 1


def test_unsteady_balance_part_reads_each_force(capsys) -> None:
    """``--parts=balance`` on a short coarse run: a row per reading (each box with each
    derivative, the traction at each sample distance), all finite, and the table printed."""
    from benchmarks import bench_unsteady

    rows = bench_unsteady.balance_part([8], 0.3)
    readings = {row["reading"]: row for row in rows}
    assert len(readings) == 2 * len(bench_unsteady.BALANCE_BOXES) + len(
        bench_unsteady.BALANCE_SAMPLES)
    assert all(np.isfinite([row["c_D max"], row["c_L max"], row["c_L min"]]).all()
               for row in rows)
    assert "traction, first sample at 1.5 h" in readings
    assert "reading" in capsys.readouterr().out


def test_unsteady_placement_part_moves_the_grid_and_the_cylinder(capsys, tmp_path,
                                                                 monkeypatch) -> None:
    """``--parts=placement`` on a tiny short run: the benchmark's geometry on the grids
    around the resolution's own, then the cylinder moved by whole cells on its grid; the
    table printed, and the plot drawn from such rows."""
    from benchmarks import bench_unsteady
    from elastoflow.validation._dfg import cells_across

    rows = bench_unsteady.placement_part([4], 0.05, quick=True)
    grids = [row for row in rows if row["kind"] == "grid" and isinstance(row["across"], int)]
    assert [row["across"] for row in grids] == [
        cells_across(4) + d for d in bench_unsteady.PLACEMENT_GRIDS]
    assert all(row["offset [cells]"] == 0.0 for row in grids)
    shifted = [row for row in rows if row["kind"] == "shift"]
    assert [row["offset [cells]"] for row in shifted] == [float(s) for s in bench_unsteady.SHIFTS]
    assert all(row["across"] == cells_across(4) for row in shifted)
    assert {row["across"] for row in rows if not isinstance(row["across"], int)} == {
        "mean", "spread"}
    assert "centre [cells]" in capsys.readouterr().out

    # The plot, from rows as a finished run has them.
    for row in grids + shifted:
        row["c_L max (balance)"] = 1.0 - 0.01 * row["offset [cells]"] + 0.001 * row["d"]
        row["c_D max (balance)"] = 3.2 - 0.02 * row["offset [cells]"]
    monkeypatch.setattr(bench_unsteady, "DOCS", tmp_path)
    bench_unsteady.plot_placement(rows)
    assert (tmp_path / "dfg2d2_placement.png").stat().st_size > 0
