"""Checks run after every coupled step (Oceananigans' callbacks): each raises
`SimulationBlowUp`, naming the step and what diverged, and the `Simulation` then keeps the
state from before the step."""

from __future__ import annotations

from typing import Protocol

import numpy as np

from elastoflow.fluid import FluidState, FluidState3D
from elastoflow.grid import Grid2D, Grid3D
from elastoflow.simulation._report import SimulationBlowUp, StepReport
from elastoflow.simulation._state import CoupledModel, CoupledModel3D, CoupledState

AnyFluidState = FluidState | FluidState3D


class StepCheck(Protocol):
    """Called with the state a step produced; raises `SimulationBlowUp` to reject it."""

    def __call__(self, model: CoupledModel | CoupledModel3D, state: CoupledState, dt: float,
                 report: StepReport) -> None:
        ...


def _velocity_names(fluid: AnyFluidState) -> tuple[str, ...]:
    if isinstance(fluid, FluidState3D):
        return ("velocity_x", "velocity_y", "velocity_z")
    return ("velocity_x", "velocity_y")


def max_speed(fluid: AnyFluidState) -> float:
    """The largest face-velocity component [m/s] (2D or 3D); NaN when one is NaN."""
    largest = 0.0
    for name in _velocity_names(fluid):
        values = getattr(fluid, name)
        if values.size:
            # Two reductions without a temporary (np.abs(values).max() makes one: 2.5x the
            # time at 64^3); np.maximum keeps a NaN.
            largest = float(np.maximum(largest, np.maximum(values.max(), -values.min())))
    return largest


def cfl_number(grid: Grid2D | Grid3D, fluid: AnyFluidState, dt: float) -> float:
    """``max |u| dt / h`` over the face velocities."""
    return max_speed(fluid) * dt / grid.h


def check_fluid_finite(fluid: AnyFluidState, step: int, time: float) -> None:
    """Raise `SimulationBlowUp` naming the first non-finite fluid value."""
    for name in (*_velocity_names(fluid), "pressure"):
        values = getattr(fluid, name)
        if not np.isfinite(values).all():
            bad = np.argwhere(~np.isfinite(values))[0]
            raise SimulationBlowUp(
                f"step {step}, t = {time:.6g} s: fluid {name} is not finite "
                f"at index {tuple(int(i) for i in bad)}"
            )


class FiniteFields:
    """Every fluid field and every body's positions and velocities are finite."""

    def __call__(self, model: CoupledModel | CoupledModel3D, state: CoupledState, dt: float,
                 report: StepReport) -> None:
        check_fluid_finite(state.fluid, report.step, report.time)
        for index, body in enumerate(state.bodies):
            for name in ("positions", "velocities"):
                values = getattr(body, name)
                if not np.isfinite(values).all():
                    node = int(np.argwhere(~np.isfinite(values))[0][0])
                    raise SimulationBlowUp(
                        f"step {report.step}, t = {report.time:.6g} s, body {index}: {name} "
                        f"not finite at node {node}"
                    )


class CflLimit:
    """The CFL number ``max |u| dt / h`` stays below ``limit``.

    Semi-Lagrangian advection is stable beyond 1, but a jump this large means the run has
    diverged.
    """

    def __init__(self, limit: float = 20.0) -> None:
        if not limit > 0.0:
            raise ValueError(f"cfl_limit = {limit!r}: must be > 0")
        self.limit = float(limit)

    def __call__(self, model: CoupledModel | CoupledModel3D, state: CoupledState, dt: float,
                 report: StepReport) -> None:
        if report.cfl > self.limit:
            speed = max_speed(state.fluid)
            raise SimulationBlowUp(
                f"step {report.step}, t = {report.time:.6g} s: CFL number {report.cfl:.3g} "
                f"(max speed {speed:.3g} m/s) exceeds the limit {self.limit:g}; the coupling "
                "has diverged (a body much lighter than the fluid, or dt too large)"
            )
