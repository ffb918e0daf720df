"""Helpers shared by the simulation tests."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from elastoflow.simulation import Simulation


def _step_above_floor(simulation: Simulation, steps: int) -> list[float]:
    """Step ``simulation``; no node of its first body ever below the floor (y = 0, 2D or
    3D). Returns the body's largest node speed after each step."""
    speeds = []
    for _ in range(steps):
        simulation.step()
        state = simulation.state.bodies[0]
        assert state.positions[:, 1].min() >= 0.0
        speeds.append(float(np.abs(state.velocities).max()))
    return speeds


@pytest.fixture
def step_above_floor() -> Callable[[Simulation, int], list[float]]:
    """`_step_above_floor`: the wall-contact tests' stepping loop."""
    return _step_above_floor
