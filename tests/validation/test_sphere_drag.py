"""Drag on a fixed sphere at Re 100 on a coarse grid (docs/validation/three_d.md runs the
case at D/h = 8, 12 and 16 in a larger box against the published 1.08-1.10)."""

from __future__ import annotations

from elastoflow.validation._three_d import SPHERE_DRAG_RE100, run_sphere_drag


def test_sphere_drag_at_re_100_on_a_coarse_grid() -> None:
    """D/h = 6 in a 6 x 4 x 4 D box to t = 6 D/U (36 steps, ~10 s once compiled).

    The bound is 20 % of the published values, what a run this coarse can promise: at 6
    cells per diameter the boundary layer (~D / sqrt(Re) = 0.1 D) is 0.6 of a cell, which
    makes the viscous part low (measured: it grows from 0.46 at D/h = 8 to 0.52 at 12 in the
    6 D box); the 4 D wide box raises the drag (1.17 at D/h = 8 here against 1.08 in the
    6 D box); and the run still drifts by ~0.7 % per D/U at its end. Measured: 1.083.
    """
    run = run_sphere_drag(6, upstream=2.0, downstream=4.0, half_width=2.0, end_time=6.0)
    published = sum(SPHERE_DRAG_RE100.values()) / len(SPHERE_DRAG_RE100)
    assert abs(run.drag_final / published - 1.0) < 0.2
    # Both parts push downstream; the steady axisymmetric flow gives no lateral force.
    pressure = float(run.pressure_drag[-1])
    assert 0.3 < pressure < run.drag[-1] - 0.2
    assert run.lift < 1e-3 * run.drag_final
    assert abs(run.drift) < 0.02
