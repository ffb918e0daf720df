"""Circular Couette flow between two cut-cell cylinders: an exact solution with curved walls
and inertia.

Fluid between a cylinder of radius ``r1`` turning at ``U / r1`` and a fixed one of radius
``r2`` about the same centre, both cut into the grid through the boundary map (the inner one
a rotating obstacle, the outer one the hole of a solid frame). The steady flow is exact at
any Reynolds number: ``u_theta = a r + b / r`` with ``a = -omega r1^2 / (r2^2 - r1^2)``,
``b = omega r1^2 r2^2 / (r2^2 - r1^2)``, and the pressure balances the centripetal
acceleration, ``p(r) = rho (a^2 r^2 / 2 + 2 a b ln r - b^2 / (2 r^2)) + const``.

The run starts from the exact velocity and steps for ``duration``: what it measures is how
far the scheme's own steady state lies from the exact one (the fluid phases' consistency at
curved walls), not a spin-up. The centre sits off the grid's nodes by a fixed fraction of a
cell, so that no circle passes through grid nodes.
"""

from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from elastoflow.fluid import FluidSolver, InteriorBoundary
    from elastoflow.grid import Grid2D

CENTER_OFFSET = (0.31, 0.17)  # cells, from the domain's centre
INNER_RADIUS = 0.15
OUTER_RADIUS = 0.40
FRAME = 0.03  # the solid frame's distance from the domain's sides [m]
# Distances from the inner wall [cells] over which the pressure error is averaged.
PRESSURE_BANDS = ((0.5, 1.0), (1.0, 1.5), (1.5, 2.0), (2.0, 3.0), (3.0, 5.0))
CORE = 3.0  # cells from either wall: the core where errors are measured away from the walls


@dataclass(frozen=True)
class CouetteSetup:
    """What a Couette run uses.

    Attributes:
        cells: Cells along each side of the unit square.
        speed: The inner wall's speed U [m/s].
        viscosity: Kinematic viscosity [m^2/s].
        duration: Simulated time [s].
        cfl: Time step as a fraction of h / U.
        advection: The fluid's advection scheme.
        viscosity_scheme: "backward_euler" or "bdf2" (`FluidSolver`).
        advecting_velocity: "current" or "extrapolated" (`FluidSolver`).
        incremental_pressure: The fluid's pressure-correction form.
    """

    cells: int
    speed: float = 1.0
    viscosity: float = 0.01
    duration: float = 3.0
    cfl: float = 0.5
    advection: str = "maccormack"
    viscosity_scheme: str = "backward_euler"
    advecting_velocity: str = "current"
    incremental_pressure: bool = False

    @property
    def h(self) -> float:
        return 1.0 / self.cells

    @property
    def dt(self) -> float:
        return self.cfl * self.h / self.speed

    @property
    def steps(self) -> int:
        return max(1, round(self.duration / self.dt))

    @property
    def center(self) -> tuple[float, float]:
        return (0.5 + CENTER_OFFSET[0] * self.h, 0.5 + CENTER_OFFSET[1] * self.h)

    @property
    def angular_velocity(self) -> float:
        return self.speed / INNER_RADIUS


def exact_coefficients(omega: float) -> tuple[float, float]:
    """``(a, b)`` of ``u_theta = a r + b / r``."""
    span = OUTER_RADIUS**2 - INNER_RADIUS**2
    return -omega * INNER_RADIUS**2 / span, omega * INNER_RADIUS**2 * OUTER_RADIUS**2 / span


def exact_speed(r: np.ndarray, omega: float) -> np.ndarray:
    a, b = exact_coefficients(omega)
    return a * r + b / r


def exact_pressure(r: np.ndarray, omega: float, density: float = 1.0) -> np.ndarray:
    """Up to a constant."""
    a, b = exact_coefficients(omega)
    return density * (0.5 * a * a * r * r + 2.0 * a * b * np.log(r) - 0.5 * b * b / (r * r))


@dataclass
class CouetteResult:
    """Errors of the state after ``setup.duration``, relative to U (velocity) and
    rho U^2 (pressure, its constant fitted over the core).

    Attributes:
        setup: What it was run with.
        speed_error_core: RMS error of u_theta at cell centres in the core.
        speed_error_max: Largest error of u_theta over the fluid cells (centres at least
            half a cell from both walls).
        pressure_error_core: RMS pressure error in the core.
        pressure_error_bands: Mean pressure error over the cells at each of
            `PRESSURE_BANDS` from the inner wall.
        seconds: Wall time of the stepping.
    """

    setup: CouetteSetup
    speed_error_core: float
    speed_error_max: float
    pressure_error_core: float
    pressure_error_bands: list[float] = field(default_factory=list)
    seconds: float = 0.0


def couette_solver(setup: CouetteSetup) -> tuple[Grid2D, FluidSolver, InteriorBoundary]:
    """Grid, fluid solver and interior boundary of the two cylinders."""
    from elastoflow import coupling, fluid, linalg
    from elastoflow.grid import Grid2D

    h = setup.h
    grid = Grid2D(nx=setup.cells, ny=setup.cells, h=h)
    center = np.asarray(setup.center)

    def circle(radius: float, clockwise: bool) -> np.ndarray:
        count = max(64, math.ceil(4.0 * 2.0 * math.pi * radius / h))  # edges <= h / 4
        angle = 2.0 * math.pi * np.arange(count) / count
        if clockwise:
            angle = -angle
        return center + radius * np.stack([np.cos(angle), np.sin(angle)], axis=1)

    inner = circle(INNER_RADIUS, clockwise=False)
    frame = np.array([[FRAME, FRAME], [1.0 - FRAME, FRAME], [1.0 - FRAME, 1.0 - FRAME],
                      [FRAME, 1.0 - FRAME]])
    # The outer cylinder: a hole (clockwise) in a solid frame (counter-clockwise).
    loops = (inner, frame, circle(OUTER_RADIUS, clockwise=True))
    points = np.concatenate(loops)
    edges = []
    start = 0
    for loop in loops:
        count = len(loop)
        edges.append(start + np.stack([np.arange(count), (np.arange(count) + 1) % count], 1))
        start += count
    velocities = np.zeros_like(points)
    omega = setup.angular_velocity
    arm = inner - center
    velocities[:len(inner), 0] = -omega * arm[:, 1]
    velocities[:len(inner), 1] = omega * arm[:, 0]
    bmap = coupling.build_boundary_map(grid, points, velocities,
                                       np.concatenate(edges).astype(np.int64))
    interior = coupling.interior_boundary_from_map(grid, bmap)
    walls = fluid.WallNoSlip()
    solver = fluid.FluidSolver(
        grid, density=1.0, viscosity=setup.viscosity,
        boundaries=fluid.DomainBoundaries(left=walls, right=walls, bottom=walls, top=walls),
        pressure_solver=linalg.PoissonSolverMGPCG(rtol=1e-8), advection=setup.advection,
        viscosity_scheme=setup.viscosity_scheme, advecting_velocity=setup.advecting_velocity,
        incremental_pressure=setup.incremental_pressure,
    )
    return grid, solver, interior


def run_couette(setup: CouetteSetup) -> CouetteResult:
    """Step from the exact flow for ``setup.duration`` and measure the errors."""
    from elastoflow.fluid import FluidState

    grid, solver, interior = couette_solver(setup)
    cx, cy = setup.center
    omega = setup.angular_velocity
    state = FluidState.zeros(grid)
    for axis, (x, y) in enumerate((grid.faces_x(), grid.faces_y())):
        r = np.hypot(x - cx, y - cy)
        inside = (r > INNER_RADIUS) & (r < OUTER_RADIUS)
        # u_theta (-sin, cos): the x component on u points, the y component on v points.
        tangent = -(y - cy) if axis == 0 else (x - cx)
        r = np.where(inside, r, 1.0)
        value = np.where(inside, exact_speed(r, omega) * tangent / r, 0.0)
        (state.velocity_x if axis == 0 else state.velocity_y)[...] = value
    began = _time.perf_counter()
    for k in range(setup.steps):
        solver.step(state, setup.dt, k * setup.dt, interior)
    seconds = _time.perf_counter() - began

    h = setup.h
    x, y = grid.cell_centers()
    r = np.hypot(x - cx, y - cy)
    fluid_cells = ((r > INNER_RADIUS + 0.5 * h) & (r < OUTER_RADIUS - 0.5 * h)
                   & ~interior.solid_cells)
    core = (r > INNER_RADIUS + CORE * h) & (r < OUTER_RADIUS - CORE * h)
    u = 0.5 * (state.velocity_x[1:, :] + state.velocity_x[:-1, :])
    v = 0.5 * (state.velocity_y[:, 1:] + state.velocity_y[:, :-1])
    rs = np.where(r > 0.0, r, 1.0)
    speed_error = ((-u * (y - cy) + v * (x - cx)) / rs - exact_speed(rs, omega)) / setup.speed
    pressure = state.pressure - exact_pressure(rs, omega)
    pressure = (pressure - pressure[core].mean()) / setup.speed**2
    distance = (r - INNER_RADIUS) / h
    bands = []
    for low, high in PRESSURE_BANDS:
        chosen = fluid_cells & (distance >= low) & (distance < high)
        bands.append(float(pressure[chosen].mean()) if chosen.any() else math.nan)
    return CouetteResult(
        setup,
        speed_error_core=float(np.sqrt(np.mean(speed_error[core] ** 2))),
        speed_error_max=float(np.abs(speed_error[fluid_cells]).max()),
        pressure_error_core=float(np.sqrt(np.mean(pressure[core] ** 2))),
        pressure_error_bands=bands,
        seconds=seconds,
    )
