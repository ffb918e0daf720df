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
    the end (the wake's history force decays slowly, as t^-1/2). Measured: 0.0315-0.0374 m/s
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
