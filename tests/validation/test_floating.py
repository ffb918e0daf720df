"""Short, coarse versions of the floating-body validation (docs/validation/free_surface.md,
"Bodies in the water"; `elastoflow.validation._floating`): a box of half the water's density
in a tank, 5 cells over its height."""

from __future__ import annotations

import pytest

from elastoflow.validation._floating import (
    BODY_HEIGHT,
    GRAVITY,
    WATER_DEPTH,
    build_floating,
    run_floating,
    sinking_acceleration,
)


def test_box_placed_at_archimedes_draft_stays_there() -> None:
    """Released at rest with its bottom 0.5 H under the surface: after 0.25 s the draft is
    within 1 % of H of Archimedes' and the box hardly moves (measured at H/h = 10: bottom
    0.15005 m after 1 s)."""
    run = run_floating(5, 0.5, duration=0.25, release_draft=0.5 * BODY_HEIGHT)
    assert run.failure is None
    assert abs(run.drafts[-1] - 0.5 * BODY_HEIGHT) < 0.01 * BODY_HEIGHT, run.drafts[-1]
    assert abs(run.bottoms - run.bottoms[0]).max() < 0.02 * BODY_HEIGHT


@pytest.mark.slow
def test_box_released_off_its_draft_settles_at_archimedes_draft() -> None:
    """Released with 3/4 of its draft under water it heaves and settles: the mean draft over
    the last 2 s of 4 s within 2 % of H of 0.5 H (measured +0.6 % at H/h = 5; the page's
    table for H/h = 10 and 20)."""
    run = run_floating(5, 0.5, duration=4.0)
    assert run.failure is None
    assert abs(run.settled_draft() - 0.5 * BODY_HEIGHT) < 0.02 * BODY_HEIGHT, (
        run.settled_draft())
    assert run.water_areas[-1] == pytest.approx(run.water_areas[1], rel=1e-12)


def test_box_denser_than_water_sinks() -> None:
    """Density 2, released under the surface: it accelerates downwards, slower than without
    added mass (g / 2), faster than a fifth of that (measured 2.77 m/s^2 at H/h = 5)."""
    run = run_floating(5, 2.0, duration=0.1, release_draft=BODY_HEIGHT)
    assert run.failure is None
    acceleration = -sinking_acceleration(run)
    assert 0.1 * GRAVITY < acceleration < 0.5 * GRAVITY, acceleration
    assert (run.bottoms[1:] < run.bottoms[:-1]).all()


def test_dropped_box_is_wetted_only_below_the_surface() -> None:
    """A box released above the water feels no pressure until it touches the water, then
    only from below: the fluid force is zero in the air and upwards once wetted."""
    simulation, _ = build_floating(5, 0.5, release_draft=-0.05)
    for _ in range(5):
        simulation.step()
    assert abs(simulation.state.body_forces[0]).max() == 0.0
    while simulation.state.bodies[0].positions[:, 1].min() > WATER_DEPTH - 0.02:
        simulation.step()
    assert simulation.state.body_forces[0][:, 1].sum() > 0.0
