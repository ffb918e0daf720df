"""DFG 2D-1 (Schäfer & Turek 1996, steady at Re = 20) through the unsteady step: the drag
against the fine reference, and what the time scheme does to a steady state (the paper's
step has a steady state that moves with dt by about as much at each halving; BDF2's
converges in dt at about second order). The study at five resolutions is docs/validation/unsteady.md, "DFG 2D-1
through the unsteady step", made by ``python -m benchmarks unsteady --parts=steady``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from elastoflow.cli import app
from elastoflow.validation import dfg_setup, run_dfg_steady
from elastoflow.validation._dfg import STEADY_PEAK_SPEED
from elastoflow.validation._dfg_steady import STEADY_REFERENCE, format_steady

BDF2 = {"viscosity_scheme": "bdf2", "advecting_velocity": "extrapolated"}


def test_setup_of_2d1_is_the_2d2_channel_at_a_fifth_of_the_speed() -> None:
    steady = dfg_setup(10, peak_speed=STEADY_PEAK_SPEED, kick=0.0)
    shedding = dfg_setup(10)
    assert steady.name == "DFG 2D-1" and shedding.name == "DFG 2D-2"
    assert steady.mean_speed == pytest.approx(0.2) and shedding.mean_speed == 1.0
    assert steady.h == shedding.h and steady.cells == shedding.cells
    assert steady.dt == pytest.approx(5.0 * shedding.dt)
    assert dfg_setup(10, peak_speed=0.6).name.startswith("DFG geometry at Re = 40")


@pytest.mark.parametrize("peak", [0.0, -1.0, float("nan"), True])
def test_bad_peak_speed_is_refused_in_one_line(peak: object) -> None:
    with pytest.raises(ValueError, match=r"^peak_speed = .*: must be a finite number > 0"):
        dfg_setup(10, peak_speed=peak)  # type: ignore[arg-type]


def test_too_short_a_run_is_refused() -> None:
    with pytest.raises(ValueError, match=r"^duration = 0.5: must be a number >= 1"):
        run_dfg_steady(10, duration=0.5)


@pytest.mark.slow
def test_steady_state_of_each_time_scheme_against_dt_and_reference() -> None:
    """N = 10, 5 s, CFL 0.5, 0.25, 0.125. Measured: the control-volume c_D 5.806 / 5.767 /
    5.735 with the first-order step (changes 0.038, 0.032: its steady state still moves
    with dt), 5.743 / 5.706 / 5.698 with BDF2 (0.037, 0.008: about second order in dt);
    the traction c_D 5.385 / 5.309 / 5.263 and 5.302 / 5.248 / 5.229; reference 5.5795.
    About 40 s on one core."""
    cv: dict[str, list[float]] = {"first": [], "bdf2": []}
    for scheme, options in (("first", {}), ("bdf2", BDF2)):
        for cfl in (0.5, 0.25, 0.125):
            result = run_dfg_steady(10, cfl=cfl, **options)
            assert result.failure is None, result.failure
            q = result.quantities
            # Steady: the drag moves by less than 0.02 % over the last 0.5 s.
            assert q["drift"] < 1e-3 * q["drag"]
            # Validation at 10 cells per diameter: the flow's momentum balance within 4.5 %
            # of the reference, the traction integral within 7 % (it converges from below
            # at first order; the study's table).
            assert abs(result.error("drag_cv")) < 0.045
            assert abs(result.error("drag")) < 0.07
            assert abs(result.error("delta_p")) < 0.06
            cv[scheme].append(q["drag_cv"])
    first, bdf2 = np.diff(cv["first"]), np.diff(cv["bdf2"])
    # The first-order step's steady state moves by about as much at each halving of dt...
    assert abs(first[1]) > 0.5 * abs(first[0]) > 0.01
    # ...BDF2's by at least three times less at the second halving than at the first, and
    # at CFL 0.25 it lies nearer its limit (Richardson, second order) than the first-order
    # step does at CFL 0.125 (measured 0.011 against 0.040).
    assert abs(bdf2[1]) < abs(bdf2[0]) / 3.0
    limit = cv["bdf2"][-1] + bdf2[1] / 3.0
    assert abs(cv["bdf2"][1] - limit) < 0.5 * abs(cv["first"][-1] - limit)


def test_cli_prints_the_quantities_and_writes_the_report(tmp_path: Path) -> None:
    outcome = CliRunner().invoke(app, ["validate", "dfg-2d-1", "--resolution", "6",
                                       "--duration", "1", "--out", str(tmp_path), "--json"])
    assert outcome.exit_code == 0, outcome.output
    assert "DFG 2D-1, resolution 6" in outcome.output
    assert "c_D (control volume)" in outcome.output and "reference 5.5795" in outcome.output
    assert "c_L (control volume)" in outcome.output
    data = json.loads((tmp_path / "dfg2d1_maccormack_n6.json").read_text())
    assert data["benchmark"] == "DFG 2D-1"
    assert data["reference"]["drag"] == STEADY_REFERENCE["drag"]
    assert set(data["quantities"]) >= {"drag", "drag_cv", "lift", "lift_cv", "delta_p",
                                       "drift"}
    assert (tmp_path / "dfg2d1_maccormack_n6.png").stat().st_size > 0
    header = (tmp_path / "dfg2d1_maccormack_n6.csv").read_text().splitlines()[0]
    assert header.startswith("time [s],drag,lift")


@pytest.mark.parametrize("arguments, message", [
    (["X"], "'X': DFG 2D-1 has one case"),
    (["--duration", "0.5"], "--duration = 0.5: must be >= 1 s"),
    (["--resolution", "2"], "resolution = 2: must be a whole number"),
    (["--viscosity-scheme", "rk4"], "viscosity_scheme = 'rk4': must be one of"),
])
def test_cli_refuses_bad_input_in_one_line(arguments: list[str], message: str) -> None:
    outcome = CliRunner().invoke(app, ["validate", "dfg-2d-1", *arguments])
    assert outcome.exit_code == 2
    assert message in outcome.output
    assert "Traceback" not in outcome.output


def test_format_names_each_quantity() -> None:
    result = run_dfg_steady(6, duration=1.0)
    lines = format_steady(result)
    assert [line.split()[0] for line in lines] == ["c_D", "c_D", "c_D", "c_L", "c_L", "Δp",
                                                  "drift"]
