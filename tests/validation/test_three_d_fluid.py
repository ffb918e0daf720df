"""3D fluid against analytic flows at two resolutions (docs/validation/three_d.md runs the
same cases at three): the Taylor-Green mode's decay in the Stokes limit and the square duct's
series solution, each with an observed order."""

from __future__ import annotations

import numpy as np

from elastoflow.validation._boundary_study import observed_order
from elastoflow.validation._three_d import (
    duct_flow_rate,
    duct_series,
    run_duct,
    run_taylor_green_3d,
)


def test_duct_series_matches_its_flow_rate_and_walls() -> None:
    # Midpoint rule over 400^2 cells against the closed-form flow rate (White eq. 3-49).
    centres = (np.arange(400) + 0.5) / 400
    y, z = np.meshgrid(centres, centres, indexing="ij")
    assert abs(duct_series(y, z, 1.0, 1.0, 1.0).mean() / duct_flow_rate(1.0, 1.0, 1.0) - 1) < 1e-5
    assert abs(float(duct_series(np.array(0.0), np.array(0.3), 1.0, 1.0, 1.0))) < 1e-12
    # The centre velocity of a square duct: 0.07367 G H^2 / mu.
    assert abs(float(duct_series(np.array(0.5), np.array(0.5), 1.0, 1.0, 1.0)) - 0.073671) < 1e-6


def test_square_duct_converges_at_second_order() -> None:
    runs = [run_duct(n) for n in (8, 16)]
    order = observed_order([r.h for r in runs], [r.error for r in runs])
    # Measured: 2.34e-2 and 6.26e-3 of u_max, order 1.90; flow rate +5.9 % and +1.5 %.
    assert runs[-1].error < 0.01
    assert order > 1.8
    assert abs(runs[-1].flow_rate_error) < 0.02


def test_taylor_green_mode_decays_at_the_stokes_rate_with_second_order_error() -> None:
    runs = [run_taylor_green_3d(n) for n in (8, 16)]
    order = observed_order([r.h for r in runs], [r.error for r in runs])
    # Measured: 5.6e-3 and 1.4e-3 of the amplitude at t = 1 (dt ~ h^2), order 1.99.
    assert runs[-1].error < 2e-3
    assert order > 1.8
    assert abs(runs[-1].amplitude_ratio - 1.0) < 2e-3
