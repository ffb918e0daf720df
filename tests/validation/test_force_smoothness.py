"""Issue 12's force smoothness: a heavy disc coasting across the grid under the monolithic
scheme, its outline crossing faces every few steps. The dual-cell face weights
(`coupling.boundary = "dual_cell"`, docs/method_notes.md item 9) change continuously as it
moves, the cut cells' segment fractions do not: the drag's step-to-step noise must be smaller
with the dual cells, and no jump larger than a few per cent of the drag with either."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from elastoflow.cli import app
from elastoflow.validation._force_smoothness import run_force_smoothness


@pytest.mark.slow
def test_dual_cell_weights_take_the_noise_out_of_a_moving_bodys_drag(tmp_path) -> None:
    """Measured (2026-12-02): drag -9.87 / -9.84 N/m (cut / dual cells); largest
    step-to-step change 3.9 % / 2.1 % of it; noise (the drag less its 15-step cubic
    Savitzky-Golay fit) 0.096 / 0.055 N/m rms."""
    study = run_force_smoothness(["disc"])
    cut, dual = study.run("disc", "cut_cell"), study.run("disc", "dual_cell")
    for run, bound in ((cut, 0.05), (dual, 0.03)):
        assert 9.0 < abs(run.mean) < 10.5, (run.boundary, run.mean)
        assert run.largest_jump <= bound * abs(run.mean), (run.boundary, run.largest_jump)
    assert dual.noise <= 0.75 * cut.noise, (dual.noise, cut.noise)
    # The same physics: the two drags agree within 1 %.
    assert dual.mean == pytest.approx(cut.mean, rel=0.01)


def test_cli_names_the_cases() -> None:
    result = CliRunner().invoke(app, ["validate", "force-smoothness", "cylinder"])
    assert result.exit_code == 2 and "disc, flap10, flap20, fsi2" in result.output
    assert "Traceback" not in result.output
