"""Circular Couette flow between two cut-cell cylinders (exact at any Reynolds number): the
first-order step's steady error is its time step's, BDF2 with the extrapolated trace takes
it out and converges in space, and the incremental pressure form removes the plain form's
pressure layer at the wall. The study: ``python -m benchmarks unsteady --parts=couette``
(docs/validation/unsteady.md)."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow.validation import CouetteSetup, run_couette
from elastoflow.validation._couette import (
    INNER_RADIUS,
    OUTER_RADIUS,
    exact_pressure,
    exact_speed,
)

BDF2 = {"viscosity_scheme": "bdf2", "advecting_velocity": "extrapolated"}


def test_exact_solution_holds_the_walls_and_balances_the_centripetal_acceleration() -> None:
    omega = 5.0
    assert exact_speed(np.array(INNER_RADIUS), omega) == pytest.approx(omega * INNER_RADIUS)
    assert exact_speed(np.array(OUTER_RADIUS), omega) == pytest.approx(0.0, abs=1e-12)
    r = np.linspace(INNER_RADIUS, OUTER_RADIUS, 201)
    step = 1e-6
    slope = (exact_pressure(r + step, omega) - exact_pressure(r - step, omega)) / (2 * step)
    centripetal = exact_speed(r, omega) ** 2 / r
    np.testing.assert_allclose(slope, centripetal, rtol=1e-6, atol=1e-6 * centripetal.max())


def test_first_order_steady_error_halves_with_the_time_step() -> None:
    """64², 3 s from the exact flow. Measured: u_theta core error 4.95e-3, 2.62e-3 of U at
    CFL 0.5 and 0.25."""
    coarse = run_couette(CouetteSetup(64, cfl=0.5))
    fine = run_couette(CouetteSetup(64, cfl=0.25))
    assert 1.6 < coarse.speed_error_core / fine.speed_error_core < 2.4
    assert coarse.speed_error_core < 0.01


def test_bdf2_reaches_the_spatial_error_and_converges_at_second_order_in_the_core() -> None:
    """Measured: core error 2.22e-3 (32²) and 4.43e-4 (64²), order 2.3; at 64² a tenth of
    the first-order step's, and no smaller at CFL 0.25."""
    coarse = run_couette(CouetteSetup(32, **BDF2))
    fine = run_couette(CouetteSetup(64, **BDF2))
    order = np.log2(coarse.speed_error_core / fine.speed_error_core)
    assert order > 1.8, order
    first_order = run_couette(CouetteSetup(64))
    assert fine.speed_error_core < 0.2 * first_order.speed_error_core
    smaller_step = run_couette(CouetteSetup(64, cfl=0.25, **BDF2))
    assert smaller_step.speed_error_core > 0.8 * fine.speed_error_core


def test_incremental_pressure_shrinks_the_pressure_layer_at_the_wall() -> None:
    """The plain splitting leaves a pressure error of about 0.012 rho U^2 half to one cell
    from the wall at 32² and 64² alike; the incremental form 0.009 and 0.004."""
    plain = run_couette(CouetteSetup(64))
    incremental = run_couette(CouetteSetup(64, incremental_pressure=True))
    assert plain.pressure_error_bands[0] > 0.008
    assert incremental.pressure_error_bands[0] < 0.5 * plain.pressure_error_bands[0]
