"""Issue 13, speed and stability parts of the boundary study at a tiny size: they run and
write their blocks, and the brute-force classification (every grid point against every
triangle) agrees with the boundary map's point for point. Timings are measurements
(docs/validation/boundary_study.md), never asserted. About 15 s."""

from __future__ import annotations

import math
from pathlib import Path

from elastoflow.validation import (
    run_speed_study,
    run_stability_study,
    write_speed_report,
    write_stability_report,
)
from elastoflow.validation._boundary_speed import (
    STABILITY_MIN_STEPS,
    bar_run,
    disc_mesh,
    speed_case,
)


def test_brute_force_agrees_with_the_map() -> None:
    for edges, cells in ((32, 40), (96, 24)):
        case = speed_case(disc_mesh(edges), cells, repeats=1)
        assert case.disagreements == 0
        assert case.crossings > 0 and math.isfinite(case.brute_force_seconds)


def test_speed_part_runs_and_writes_its_table(tmp_path: Path) -> None:
    study = run_speed_study(edges=(16, 32), cells=(16, 32), scenes=("bar_in_jet",),
                            repeats=1, step_count=2, step_cells=48, map_edges=(64,),
                            map_cells=(64, 1024))
    assert len(study.cases) == 4 and len(study.steps) == 2 and len(study.maps) == 2
    assert study.maps[1].crossings > study.maps[0].crossings
    assert all(c.disagreements == 0 for c in study.cases)
    assert all(s.disagreements == 0 for s in study.steps)
    write_speed_report(study, tmp_path)
    page = (tmp_path / "boundary_study.md").read_text()
    assert "<!-- speed:begin -->" in page and "| 32 |" in page
    assert (tmp_path / "boundary_study" / "speed.csv").read_text().count("\n") == 1 + 4 + 2 + 2
    assert (tmp_path / "boundary_study" / "speed.png").stat().st_size > 0


def test_stability_part_runs_and_writes_its_table(tmp_path: Path) -> None:
    run = bar_run("staircase", cells=48, duration=0.05)
    assert run.stable and run.steps == STABILITY_MIN_STEPS and run.displacement < 0.05
    study = run_stability_study(("cut_cell",), (("monolithic", "traction"),), bisections=0,
                                cells=48, duration=0.03)
    assert len(study.limits) == 2
    write_stability_report(study, tmp_path)
    page = (tmp_path / "boundary_study.md").read_text()
    assert "<!-- stability:begin -->" in page and "| cut cell" in page
