"""A sphere settling in a box of oil (ten Cate et al. 2002, E1) on a coarse grid: the
library scene through `elastoflow.validation._settling` (docs/validation/three_d.md runs it
at 6 and 8 cells per diameter)."""

from __future__ import annotations

import numpy as np

from elastoflow.validation._settling import U_MAX_MEASURED, run_settling


def test_the_sphere_settles_at_the_published_speed_within_the_coarse_grid_error() -> None:
    """4.5 cells per diameter to t = 0.3 s (30 steps), with the scene's monolithic coupling.

    At this resolution the viscous traction (two thirds of the drag at Re 1.5) is
    under-resolved, so the sphere falls faster than measured in the end (docs/validation/
    three_d.md). The bound is what a run this coarse can promise: the right direction and a
    speed within a factor of two of ten Cate's, rising smoothly. The speed still creeps up at
    the end (the wake's history force decays slowly, as t^-1/2). Measured: 0.0286-0.0357 m/s
    over the last half.
    """
    run = run_settling(4.5, duration=0.3)
    assert run.failure is None
    late = run.speeds[run.times > 0.15]
    assert 0.5 * U_MAX_MEASURED < late.mean() < 2.0 * U_MAX_MEASURED
    # No swings: no step loses more than a tenth of the speed.
    assert (np.diff(late) > -0.1 * late[1:]).all()
    # The sphere moved down by about its speed times the time.
    assert 0.0 < run.gaps[0] - run.gaps[-1] < 2.0 * U_MAX_MEASURED * 0.3


def test_a_sphere_in_an_oil_64_times_as_viscous_settles() -> None:
    """ten Cate's sphere in an oil 64 times as viscous (24 Pa s), 4.5 cells per diameter, 60
    steps. The viscous traction's surface-gradient terms, held over the step, made its nodes
    vibrate and diverge from 16 times the viscosity before they were bounded implicitly
    (docs/method_notes.md item 14). It now settles near Stokes' scaling of its speed at four
    times the viscosity (11.3 mm/s there, so about 0.7 mm/s here). What is left swings from
    step to step and decays (its source not traced). Measured: speeds 0.743 and 0.826 mm/s
    at the last two steps, their difference falling from 0.095 to 0.083 mm/s over the last
    0.3 s."""
    run = run_settling(4.5, duration=0.6, viscosity_factor=64.0)
    assert run.failure is None
    late = run.speeds[run.times > 0.3]
    assert np.all(late > 0.0)
    assert 0.5e-3 < late.mean() < 1.0e-3
    swing = np.abs(np.diff(late))
    assert swing.max() < 0.2 * late.mean()
    assert swing[-10:].mean() < swing[:10].mean()
