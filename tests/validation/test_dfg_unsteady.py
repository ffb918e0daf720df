"""DFG 2D-2 (Schäfer & Turek 1996, Re = 100): the shedding starts on a coarse grid with the
default advection and its Strouhal number is within 10 % of the published one; the
evaluation of the benchmark's quantities on signals of known shape; the CLI command.

The full study (three resolutions, each advection scheme) is docs/validation/unsteady.md,
made by ``python -m benchmarks unsteady``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from elastoflow.cli import app
from elastoflow.validation import dfg_setup, run_dfg
from elastoflow.validation._dfg import (
    BOUNDS,
    DfgResult,
    DIAMETER,
    MEAN_SPEED,
    describe,
    evaluate,
    quantities_json,
)

PUBLISHED_STROUHAL = 0.5 * sum(BOUNDS["strouhal"])


def _coarse_run_sheds(advection: str) -> DfgResult:
    """12 cells per diameter for 6 s: the lift oscillates about zero with an amplitude of
    the published order (1), St within 10 % of the bounds' midpoint."""
    result = run_dfg(12, duration=6.0, advection=advection)
    assert result.failure is None, result.failure
    lift = result.statistics["lift"]
    assert lift.amplitude > 0.5, f"lift amplitude {lift.amplitude:.3f}: no shedding"
    assert abs(lift.mean) < 0.1 * lift.amplitude
    strouhal = result.quantities["strouhal"]
    assert abs(strouhal / PUBLISHED_STROUHAL - 1.0) < 0.10, f"St = {strouhal:.4f}"
    return result


@pytest.mark.slow
def test_coarse_run_sheds_with_strouhal_within_10_percent() -> None:
    """12 cells per diameter, 6 s (2195 steps), MacCormack (the scene default). Measured:
    St = 0.2789 (-7.0 % from the bounds' midpoint 0.300), lift amplitude 0.908, mean c_D
    3.487; 30 s and 138 s on one core in two runs at load averages of 5 and 6."""
    result = _coarse_run_sheds("maccormack")
    # The drag is periodic at twice the shedding frequency, about a mean near 3.2.
    drag = result.statistics["drag"]
    assert drag.frequency == pytest.approx(2.0 * result.statistics["lift"].frequency, rel=0.05)
    assert 3.0 < drag.mean < 4.0


@pytest.mark.slow
def test_flux_form_sheds_at_a_coarse_grid_with_less_drag_than_maccormack() -> None:
    """The same set-up with ``advection="upwind3"`` (flux form). Measured: St = 0.2824
    (-5.9 %), lift amplitude 0.926, mean c_D 3.358 (MacCormack's 3.487 above: the flux form
    is nearer the published drag at every resolution, docs/validation/unsteady.md); 26 s on
    two shared cores."""
    assert 3.0 < _coarse_run_sheds("upwind3").statistics["drag"].mean < 3.45


def test_evaluation_of_known_signals() -> None:
    """St from the lift's period, maxima over the last period, Δp half a period after the
    last lift maximum."""
    setup = dfg_setup(10, duration=4.0)
    time = np.arange(1, 40001) * 1e-4
    frequency = 3.1
    phase = 2.0 * np.pi * frequency * time
    series = {
        "lift": 0.9 * np.sin(phase),
        "drag": 3.3 + 0.02 * np.sin(2.0 * phase),
        "drag_cv": 3.3 + 0.03 * np.sin(2.0 * phase),
        "lift_cv": 1.05 * np.sin(phase),
        "delta_p": 2.4 + 0.05 * np.cos(phase),
    }
    result = evaluate(setup, time, series, seconds=1.0)
    assert result.failure is None
    assert result.quantities["strouhal"] == pytest.approx(DIAMETER * frequency / MEAN_SPEED,
                                                          rel=1e-3)
    assert result.quantities["lift_max"] == pytest.approx(0.9, rel=1e-4)
    assert result.quantities["drag_max"] == pytest.approx(3.32, rel=1e-5)
    # Lift maximum at phase pi/2; half a period later cos(3 pi / 2) = 0.
    assert result.quantities["delta_p"] == pytest.approx(2.4, abs=2e-3)
    assert result.within_bounds("delta_p") is False
    assert result.balance["lift_max"] == pytest.approx(1.05, rel=1e-4)
    assert result.balance["drag_max"] == pytest.approx(3.33, rel=1e-5)
    assert result.within_bounds("lift_max", balance=True) is False
    assert quantities_json(result)["balance"]["lift_max"]["inside"] is False


def test_evaluation_of_a_steady_record_fails_with_a_reason() -> None:
    setup = dfg_setup(10, duration=1.0)
    time = np.linspace(0.01, 1.0, 100)
    steady = {key: np.full(100, 3.0) for key in ("lift", "drag", "drag_cv", "lift_cv",
                                                  "delta_p")}
    result = evaluate(setup, time, steady, seconds=0.0)
    assert result.failure is not None and "not periodic" in result.failure
    assert result.quantities == {}


def test_momentum_balance_takes_the_steps_time_derivative() -> None:
    """A uniform stream in the box whose speed grows like t^2: no net flux through the box,
    so the force is minus the box's momentum rate. BDF2's three-level difference is exact
    for t^2; the two-level one is dt behind; the first force is NaN and the second two-level
    (the first step of a BDF2 run is backward Euler)."""
    from elastoflow.grid import Grid2D
    from elastoflow.validation._dfg import DENSITY, ControlVolumeDrag

    grid = Grid2D(40, 20, 0.02)
    dt = 0.01
    forces = {}
    for bdf2 in (False, True):
        balance = ControlVolumeDrag(grid, (0.4, 0.2), half=1.0, bdf2=bdf2)
        box = balance.box
        mass = DENSITY * (box.i1 - box.i0) * (box.j1 - box.j0) * grid.h**2
        series = []
        for n in range(4):
            speed = (n * dt) ** 2
            series.append(balance.force(np.full(grid.shape_faces_x, speed),
                                        np.zeros(grid.shape_faces_y),
                                        np.zeros(grid.shape_cells), dt)[0])
        forces[bdf2] = np.array(series) / mass
    t = dt * np.arange(4)
    assert np.isnan(forces[False][0]) and np.isnan(forces[True][0])
    np.testing.assert_allclose(forces[False][1:], -(2.0 * t[1:] - dt), rtol=1e-9)
    np.testing.assert_allclose(forces[True][1], -(2.0 * t[1] - dt), rtol=1e-9)
    np.testing.assert_allclose(forces[True][2:], -2.0 * t[2:], rtol=1e-9)


def test_with_the_steps_derivative_the_balance_does_not_depend_on_the_box() -> None:
    """The balance over two boxes (1 and 1.9 diameters from the centre) on a BDF2 run: the
    boxes' lifts differ by what the flux evaluation on their sides misses, four times less
    than with the two-level difference, whose error grows with the momentum the box holds.
    Measured (N = 10, 1 s, flux form, incremental pressure): 1.9e-4 against 7.5e-4 N/m with
    lifts up to 0.011 N/m; at N = 20 in the shedding, c_L max 1.0326 / 1.0319 against
    1.0316 / 1.0733 (docs/validation/unsteady.md)."""
    from elastoflow.validation._dfg import ControlVolumeDrag, dfg_solver, initial_state

    setup = dfg_setup(10, duration=1.0, advection="upwind3", incremental_pressure=True,
                      viscosity_scheme="bdf2", advecting_velocity="extrapolated")
    grid, solver, _, interior = dfg_solver(setup)
    state = initial_state(grid, interior, setup.kick, setup.center, setup.peak_speed)
    boxes = {(half, bdf2): ControlVolumeDrag(grid, setup.center, half=half, bdf2=bdf2)
             for half in (1.0, 1.9) for bdf2 in (False, True)}
    lifts: dict[tuple[float, bool], list[float]] = {key: [] for key in boxes}
    for step in range(setup.steps + 1):
        if step:
            solver.step(state, setup.dt, (step - 1) * setup.dt, interior)
        for key, balance in boxes.items():
            lifts[key].append(balance.force(state.velocity_x, state.velocity_y,
                                            state.pressure, setup.dt)[1])
    late = slice(setup.steps // 3, None)
    gap = {bdf2: np.abs(np.subtract(lifts[(1.0, bdf2)], lifts[(1.9, bdf2)])[late]).max()
           for bdf2 in (False, True)}
    assert gap[True] < 0.5 * gap[False], gap


def test_cli_short_run_writes_report_and_says_not_periodic(tmp_path: Path) -> None:
    result = CliRunner().invoke(app, ["validate", "dfg-2d-2", "--resolution", "4",
                                      "--duration", "0.05", "--advection", "semi_lagrangian",
                                      "--out", str(tmp_path), "--json"])
    assert result.exit_code == 1, result.output
    assert "not periodic yet" in result.output
    assert "semi_lagrangian advection" in result.output
    stem = tmp_path / "dfg2d2_semi_lagrangian_n4"
    data = json.loads(stem.with_suffix(".json").read_text())
    assert data["benchmark"] == "DFG 2D-2" and data["cells"] == list(dfg_setup(4).cells)
    rows = stem.with_suffix(".csv").read_text().splitlines()
    assert rows[0].startswith("time [s],drag,lift") and len(rows) == 1 + data["steps"]
    assert stem.with_suffix(".png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (["--resolution", "2"], "in 4..160"),
        (["--resolution", "500"], "in 4..160"),
        (["--advection", "weno"], "advection = 'weno'"),
        (["--dt", "-1"], "dt = -1.0"),
        (["--duration", "0"], "duration = 0.0"),
        (["FSI1"], "one case"),
    ],
)
def test_cli_bad_input_is_one_line_and_exit_2(arguments: list[str], message: str) -> None:
    result = CliRunner().invoke(app, ["validate", "dfg-2d-2", *arguments])
    assert result.exit_code == 2, result.output
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and message in lines[0], result.output
    assert "Traceback" not in result.output


def test_offset_moves_the_cylinder_and_the_pressure_points_by_a_fraction_of_a_cell() -> None:
    """``offset`` shifts the obstacle downstream: the cells inside it are those whose centres
    lie inside the moved circle (checked away from its outline, where the polygon's sag and
    round-off cannot decide), and Δp's points move with it."""
    from elastoflow.validation._dfg import BACK, CENTER, FRONT, RADIUS, dfg_solver

    for offset in (0.0, 0.5, 0.75, 1.5):
        setup = dfg_setup(10, duration=0.1, offset=offset)
        h = setup.h
        assert setup.center == (CENTER[0] + offset * h, CENTER[1])
        front, back = setup.front_and_back
        assert front == (FRONT[0] + offset * h, FRONT[1])
        assert back == (BACK[0] + offset * h, BACK[1])
        grid, _, _, interior = dfg_solver(setup)
        x, y = grid.cell_centers()
        distance = np.hypot(x - setup.center[0], y - setup.center[1]) - RADIUS
        clear = np.abs(distance) > 0.01 * h
        np.testing.assert_array_equal(interior.solid_cells[clear], distance[clear] < 0.0)
        assert interior.solid_cells.sum() > 50


def test_offset_zero_is_the_benchmark_placement_and_other_offsets_run() -> None:
    reference = run_dfg(4, duration=0.05)
    same = run_dfg(4, duration=0.05, offset=0.0)
    for key, values in reference.series.items():
        np.testing.assert_array_equal(values, same.series[key])
    moved = run_dfg(4, duration=0.05, offset=0.5)
    assert all(np.isfinite(values[1:]).all() for values in moved.series.values())
    assert not np.array_equal(moved.series["drag"], reference.series["drag"])
    assert "cylinder 0.5 cell downstream" in describe(moved)
    assert "downstream" not in describe(reference)
    assert quantities_json(moved)["offset"] == 0.5


@pytest.mark.parametrize("offset", [-0.1, 20.0, 25, True, float("nan"), "1"])
def test_offset_outside_the_channel_is_refused(offset: float) -> None:
    with pytest.raises(ValueError, match=r"offset = .*must be a number of cells in \[0, 20\)"):
        dfg_setup(10, offset=offset)


def test_across_sets_the_grid_about_the_same_geometry() -> None:
    """``across`` cells across the height: h = 0.41 / across, the cylinder where the
    benchmark puts it (its centre no longer on a grid node), the default grid's run
    unchanged bitwise when ``across`` names it."""
    from elastoflow.validation._dfg import CENTER, cells_across

    setup = dfg_setup(10, duration=0.1, across=43)
    assert setup.h == pytest.approx(0.41 / 43, rel=1e-15)
    assert setup.cells == (math.ceil(2.2 / setup.h - 1e-9), 43)
    assert setup.center == CENTER
    assert setup.dt == pytest.approx(setup.h / 3.0, rel=1e-12)
    assert "across" in repr(setup)
    reference = run_dfg(4, duration=0.05)
    same = run_dfg(4, duration=0.05, across=cells_across(4))
    for key, values in reference.series.items():
        np.testing.assert_array_equal(values, same.series[key])
    other = run_dfg(4, duration=0.05, across=cells_across(4) + 1)
    assert other.setup.cells[1] == cells_across(4) + 1
    assert all(np.isfinite(values[1:]).all() for values in other.series.values())
    assert quantities_json(other)["cells"][1] == cells_across(4) + 1


@pytest.mark.parametrize("across", [11, 657, 20.5, True, "40"])
def test_across_outside_its_range_is_refused(across: object) -> None:
    with pytest.raises(ValueError, match=r"across = .*must be a whole number of cells across"):
        dfg_setup(10, across=across)  # type: ignore[arg-type]
