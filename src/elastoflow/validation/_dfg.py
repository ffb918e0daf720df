"""DFG 2D-2 (Schäfer & Turek 1996): periodic vortex shedding behind a cylinder at Re = 100.

Channel [0, 2.2] x [0, 0.41] m, rigid cylinder of radius 0.05 m about (0.2, 0.2) (a static
obstacle in the boundary map, cut-distance boundary conditions), parabolic inflow of peak
1.5 m/s (mean U = 1 m/s), no slip on the walls, outflow on the right; rho = 1 kg/m^3,
nu = 1e-3 m^2/s (../shared/reference/dfg_cylinder.json). The quantities, as the benchmark
defines them over a period of the fully developed shedding: the Strouhal number
``St = D f / U`` (f from the lift), the maxima of ``c_D = 2 F_D / (rho U^2 D)`` and ``c_L``
(forces by the traction integral), and the pressure difference
``Δp = p(0.15, 0.2) - p(0.25, 0.2)`` at ``t0 + 1 / (2 f)``, t0 the time of the last lift
maximum (the definition the reference file marks as not verified from a stored source).

Resolution ``N`` means N cells per cylinder diameter: ``h = 0.41 / ceil(4.1 N)`` (exactly
D / N when 4.1 N is whole), the channel extended to whole cells at the outflow. The run is
driven through the fluid solver's own phases (no bodies), so the fields are this module's
own: the pressure at the two points is extrapolated to the cylinder's surface from the fluid
side, and the drag is also measured by a control-volume momentum balance on a box around the
cylinder (independent of the traction evaluation at cut cells; docs/method_notes.md).

The flow starts as the inflow's Poiseuille profile everywhere plus a small transverse
kick behind the cylinder (``kick``), which only shortens the wait for the shedding: the
limit cycle does not depend on it.
"""

from __future__ import annotations

import math
import time as _time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from elastoflow.analysis import PeriodicStatistics, periodic_statistics
from elastoflow.fluid import BoxCells, MomentumBalance

if TYPE_CHECKING:
    from elastoflow.fluid import FluidSolver, FluidState, InteriorBoundary
    from elastoflow.grid import Grid2D

CHANNEL = (2.2, 0.41)
CENTER = (0.2, 0.2)
RADIUS = 0.05
DIAMETER = 2.0 * RADIUS
PEAK_SPEED = 1.5
MEAN_SPEED = 2.0 * PEAK_SPEED / 3.0
# DFG 2D-1's inflow peak (Re = 20, steady; `elastoflow.validation._dfg_steady`).
STEADY_PEAK_SPEED = 0.3
DENSITY = 1.0
VISCOSITY = 1e-3
FRONT = (0.15, 0.2)
BACK = (0.25, 0.2)

# Published bounds of DFG 2D-2 (Schäfer & Turek 1996, Table 4; the reference file withholds
# the 2D-2 results, so these are quoted from the paper): the range the participating codes'
# best results were required to fall in.
BOUNDS: dict[str, tuple[float, float]] = {
    "strouhal": (0.2950, 0.3050),
    "drag_max": (3.2200, 3.2400),
    "lift_max": (0.9900, 1.0100),
    "delta_p": (2.4600, 2.5000),
}
LABELS = {"strouhal": "St", "drag_max": "c_D max", "lift_max": "c_L max", "delta_p": "Δp [Pa]"}
ADVECTION_SCHEMES = ("maccormack", "semi_lagrangian", "upwind3")
# The farthest the cylinder may be moved downstream [cells] (`DfgSetup.offset`).
MAX_OFFSET = 20.0
ADVECTING_VELOCITIES = ("current", "extrapolated")
VISCOSITY_SCHEMES = ("backward_euler", "crank_nicolson", "bdf2")

Progress = Callable[[int, int], None]


def check_resolution(resolution: Any) -> None:
    """Refuse a resolution outside 4..160 cells per cylinder diameter."""
    if isinstance(resolution, bool) or not (isinstance(resolution, int)
                                            and 4 <= resolution <= 160):
        raise ValueError(
            f"resolution = {resolution!r}: must be a whole number of cells per cylinder "
            "diameter in 4..160"
        )


def cells_across(resolution: int) -> int:
    """Cells across the channel's height 0.41 m: ``ceil(4.1 N)``."""
    return math.ceil(4.1 * resolution - 1e-9)


@dataclass(frozen=True)
class DfgSetup:
    """What a DFG 2D-2 run uses.

    Attributes:
        resolution: Cells per cylinder diameter N.
        h: Cell side [m].
        dt: Time step [s].
        duration: Simulated time [s].
        advection: The fluid's advection scheme.
        incremental_pressure: The fluid's pressure-correction form (`FluidSolver`).
        kick: Peak transverse velocity [m/s] of the start-up perturbation.
        limiter: MacCormack's clamp (`FluidSolver` maccormack_limiter).
        advecting_velocity: The back-trace's velocity (`FluidSolver`): "current" or
            "extrapolated" (to mid-step, second order in time).
        viscosity_scheme: "backward_euler" or "crank_nicolson" (`FluidSolver`).
        offset: The cylinder moved downstream by this many cells (0 <= offset < 20).
            This changes the problem as well as the grid's placement: the cylinder's
            distance from the inflow decides much of the lift (c_L max falls by 0.62-0.66 %
            per millimetre the cylinder moves downstream, at every resolution;
            docs/validation/unsteady.md). ``across`` places the grid differently about the
            same geometry.
        across: Cells across the channel's height 0.41 m (default ``ceil(4.1 N)``): another
            h about the same geometry, so another placement of the grid about the
            cylinder (at the default the centre lies on a grid node and the circle passes
            through nodes).
        peak_speed: The inflow's peak velocity [m/s]: 1.5 for 2D-2 (Re = 100), 0.3 for the
            steady 2D-1 (Re = 20, `run_dfg_steady`).
    """

    resolution: int
    h: float
    dt: float
    duration: float
    advection: str
    incremental_pressure: bool = False
    kick: float = 0.3
    limiter: bool = True
    advecting_velocity: str = "current"
    viscosity_scheme: str = "backward_euler"
    offset: float = 0.0
    peak_speed: float = PEAK_SPEED
    across: int | None = None

    @property
    def mean_speed(self) -> float:
        """The inflow's mean velocity U [m/s], two thirds of its peak."""
        return 2.0 * self.peak_speed / 3.0

    @property
    def name(self) -> str:
        """"DFG 2D-2", "DFG 2D-1", or the geometry's name with the Reynolds number."""
        if self.peak_speed == PEAK_SPEED:
            return "DFG 2D-2"
        if self.peak_speed == STEADY_PEAK_SPEED:
            return "DFG 2D-1"
        return f"DFG geometry at Re = {self.mean_speed * DIAMETER / VISCOSITY:.4g}"

    @property
    def center(self) -> tuple[float, float]:
        """The cylinder's centre [m]: the benchmark's, moved by ``offset`` cells along x."""
        return (CENTER[0] + self.offset * self.h, CENTER[1])

    @property
    def front_and_back(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """The points of Δp: the cylinder's upstream and downstream ends [m]."""
        shift = self.offset * self.h
        return (FRONT[0] + shift, FRONT[1]), (BACK[0] + shift, BACK[1])

    @property
    def steps(self) -> int:
        return max(1, round(self.duration / self.dt))

    @property
    def cells(self) -> tuple[int, int]:
        across = cells_across(self.resolution) if self.across is None else self.across
        return (math.ceil(CHANNEL[0] / self.h - 1e-9), across)


def dfg_setup(resolution: int = 20, *, duration: float | None = None, dt: float | None = None,
              advection: str = "maccormack", cfl: float = 0.5,
              incremental_pressure: bool = False, kick: float = 0.3,
              limiter: bool = True, advecting_velocity: str = "current",
              viscosity_scheme: str = "backward_euler", offset: float = 0.0,
              peak_speed: float = PEAK_SPEED, across: int | None = None) -> DfgSetup:
    """Resolution N -> h = 0.41 / ceil(4.1 N) (or 0.41 / ``across``); dt from ``cfl`` on
    the inflow peak (0.5: dt = h / 3 s/m at 2D-2's peak); 10 s of simulated time by default;
    the cylinder ``offset`` cells downstream of its benchmark position (see `DfgSetup`).

    Raises:
        ValueError: one line naming the bad argument.
    """
    check_resolution(resolution)
    if advection not in ADVECTION_SCHEMES:
        raise ValueError(f"advection = {advection!r}: must be one of "
                         f"{', '.join(ADVECTION_SCHEMES)}")
    if across is not None and (isinstance(across, bool) or not isinstance(across, int)
                               or not 12 <= across <= 656):
        raise ValueError(f"across = {across!r}: must be a whole number of cells across the "
                         "channel's 0.41 m in 12..656")
    h = CHANNEL[1] / (cells_across(resolution) if across is None else across)
    if duration is None:
        duration = 10.0
    if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > 0.0):
        raise ValueError(f"duration = {duration!r}: must be a finite number > 0 [s]")
    if advecting_velocity not in ADVECTING_VELOCITIES:
        raise ValueError(f"advecting_velocity = {advecting_velocity!r}: must be one of "
                         f"{', '.join(ADVECTING_VELOCITIES)}")
    if viscosity_scheme not in VISCOSITY_SCHEMES:
        raise ValueError(f"viscosity_scheme = {viscosity_scheme!r}: must be one of "
                         f"{', '.join(VISCOSITY_SCHEMES)}")
    if not (isinstance(cfl, (int, float)) and math.isfinite(cfl) and cfl > 0.0):
        raise ValueError(f"cfl = {cfl!r}: must be a finite number > 0")
    if isinstance(offset, bool) or not (isinstance(offset, (int, float))
                                        and 0.0 <= offset < MAX_OFFSET):
        raise ValueError(f"offset = {offset!r}: must be a number of cells in [0, {MAX_OFFSET:g})")
    if isinstance(peak_speed, bool) or not (isinstance(peak_speed, (int, float))
                                            and math.isfinite(peak_speed) and peak_speed > 0.0):
        raise ValueError(f"peak_speed = {peak_speed!r}: must be a finite number > 0 [m/s]")
    if dt is None:
        dt = cfl * h / peak_speed
    if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0.0):
        raise ValueError(f"dt = {dt!r}: must be a finite positive time step [s]")
    return DfgSetup(resolution, h, float(dt), float(duration), advection,
                    incremental_pressure, float(kick), limiter, advecting_velocity,
                    viscosity_scheme, float(offset), float(peak_speed), across)


@dataclass
class DfgResult:
    """A DFG 2D-2 run: time series and the benchmark's quantities.

    Attributes:
        setup: What it was run with.
        time: Sample times [s], shape (k,), one per step.
        series: "drag", "lift" (coefficients by the traction integral), "drag_pressure"
            (the pressure part of c_D in the traction integral), "drag_pressure_constant"
            and "drag_pressure_linear" (the same from normal samples at 1.5 h and 2.5 h,
            carried at constant value or extrapolated linearly, `SurfacePressureDrag`),
            "drag_cv" and "lift_cv" (by the control-volume balance), "delta_p" [Pa];
            shape (k,) each.
        quantities: "strouhal", "drag_max", "lift_max", "delta_p" (missing when the run is
            not periodic yet, see ``failure``), the forces by the traction integral (what
            a scene's force probe reads).
        balance: "drag_max", "lift_max" from the control-volume momentum balance, the
            scheme's own force (`ControlVolumeDrag`; the traction integral reads the lift
            low by a first-order error, docs/validation/unsteady.md).
        statistics: Periodic statistics of drag, lift, drag_cv, lift_cv over the last
            period.
        seconds: Wall time of the stepping [s].
        failure: None, or why the quantities could not be computed.
    """

    setup: DfgSetup
    time: np.ndarray
    series: dict[str, np.ndarray]
    quantities: dict[str, float] = field(default_factory=dict)
    balance: dict[str, float] = field(default_factory=dict)
    statistics: dict[str, PeriodicStatistics] = field(default_factory=dict)
    seconds: float = 0.0
    failure: str | None = None

    def within_bounds(self, key: str, *, balance: bool = False) -> bool:
        low, high = BOUNDS[key]
        value = (self.balance if balance else self.quantities).get(key)
        return value is not None and low <= value <= high


def dfg_solver(setup: DfgSetup) -> tuple[Grid2D, FluidSolver, Any, InteriorBoundary]:
    """Grid, fluid solver, boundary map and interior boundary of the channel and cylinder."""
    from elastoflow import coupling, fluid, linalg
    from elastoflow.grid import Grid2D

    nx, ny = setup.cells
    grid = Grid2D(nx=nx, ny=ny, h=setup.h)
    boundaries = fluid.DomainBoundaries(
        left=fluid.Inflow(speed=setup.peak_speed, profile="parabolic"), right=fluid.Outflow(),
        bottom=fluid.WallNoSlip(), top=fluid.WallNoSlip(),
    )
    solver = fluid.FluidSolver(
        grid, density=DENSITY, viscosity=VISCOSITY, boundaries=boundaries,
        pressure_solver=linalg.PoissonSolverMGPCG(rtol=1e-6), advection=setup.advection,
        incremental_pressure=setup.incremental_pressure, maccormack_limiter=setup.limiter,
        advecting_velocity=setup.advecting_velocity, viscosity_scheme=setup.viscosity_scheme,
    )
    # Edges no longer than h / 4 (the 2D-1 study's choice), at least 64.
    segments = max(64, math.ceil(4.0 * 2.0 * math.pi * RADIUS / setup.h))
    cylinder = coupling.obstacle_circle(setup.center, RADIUS, segments=segments)
    bmap = coupling.build_boundary_map(grid, cylinder.points_at(0.0),
                                       cylinder.velocities_at(0.0), cylinder.edges)
    interior = coupling.interior_boundary_from_map(grid, bmap)
    return grid, solver, bmap, interior


def initial_state(grid: Grid2D, interior: InteriorBoundary, kick: float,
                  center: tuple[float, float] = CENTER,
                  peak_speed: float = PEAK_SPEED) -> FluidState:
    """Poiseuille profile of peak ``peak_speed`` everywhere, zero inside the cylinder, plus a
    transverse Gaussian kick of peak ``kick`` [m/s] one diameter behind the cylinder centred
    at ``center``."""
    from elastoflow.fluid import FluidState

    state = FluidState.zeros(grid)
    _, y = grid.faces_x()
    height = CHANNEL[1]
    state.velocity_x[...] = 4.0 * peak_speed * y * (height - y) / height**2
    state.velocity_x[interior.solid_faces_x] = 0.0
    x, y = grid.faces_y()
    r2 = (x - center[0] - DIAMETER) ** 2 + (y - center[1]) ** 2
    state.velocity_y[...] = kick * np.exp(-r2 / RADIUS**2)
    state.velocity_y[interior.solid_faces_y] = 0.0
    return state


def surface_pressure(grid: Grid2D, pressure: np.ndarray, solid: np.ndarray,
                     point: tuple[float, float], center: tuple[float, float] = CENTER) -> float:
    """Pressure [Pa] at a point on the surface of the cylinder about ``center``, on its
    horizontal axis, extrapolated linearly along x from the two nearest fluid cells outside
    it (interpolated linearly in y between the two cell rows around the point)."""
    h = grid.h
    row = point[1] / h - 0.5
    j0 = int(math.floor(row))
    weight = row - j0
    column = point[0] / h - 0.5
    side = 1 if point[0] > center[0] else -1
    i = int(math.floor(column)) if side < 0 else int(math.ceil(column))
    while solid[i, j0] or solid[i, j0 + 1]:
        i += side
    p1 = (1.0 - weight) * pressure[i, j0] + weight * pressure[i, j0 + 1]
    p2 = (1.0 - weight) * pressure[i + side, j0] + weight * pressure[i + side, j0 + 1]
    return float(p1 - (p2 - p1) * abs(column - i))


class ControlVolumeDrag(MomentumBalance):
    """Force on the cylinder from the momentum balance over a box of whole cells around it
    (`elastoflow.fluid.MomentumBalance`): the box reaches ``half`` diameters from the
    cylinder's centre on each side (clipped to the channel), and ``bdf2`` takes the time
    derivative a BDF2 step takes."""

    def __init__(self, grid: Grid2D, center: tuple[float, float] = CENTER, *,
                 half: float = 1.5, bdf2: bool = False) -> None:
        reach = half * DIAMETER
        box = BoxCells.around(grid, (center[0] - reach, center[1] - reach),
                              (center[0] + reach, center[1] + reach))
        super().__init__(grid, box, DENSITY, VISCOSITY, bdf2=bdf2)


class SurfacePressureDrag:
    """The pressure part of the drag, ``-oint p n_x dS``, from pressures sampled along the
    normal at 1.5 h and 2.5 h from the cylinder's surface (bilinear over cell centres, all
    of them fluid at these distances), carried to the surface at constant value (as the
    traction integral does) or extrapolated linearly: how much the carry matters."""

    def __init__(self, grid: Grid2D, count: int = 720,
                 center: tuple[float, float] = CENTER) -> None:
        angle = 2.0 * math.pi * (np.arange(count) + 0.5) / count
        self.normal = np.stack([np.cos(angle), np.sin(angle)], axis=1)
        self.length = 2.0 * math.pi * RADIUS / count
        h = grid.h
        self.samples = []
        for distance in (1.5 * h, 2.5 * h):
            points = np.asarray(center) + (RADIUS + distance) * self.normal
            fx, fy = points[:, 0] / h - 0.5, points[:, 1] / h - 0.5
            i, j = np.floor(fx).astype(np.int64), np.floor(fy).astype(np.int64)
            self.samples.append((i, j, fx - i, fy - j))

    def _pressure(self, p: np.ndarray, k: int) -> np.ndarray:
        i, j, a, b = self.samples[k]
        return ((1 - a) * (1 - b) * p[i, j] + a * (1 - b) * p[i + 1, j]
                + (1 - a) * b * p[i, j + 1] + a * b * p[i + 1, j + 1])

    def drag(self, p: np.ndarray) -> tuple[float, float]:
        """(carried at constant value, extrapolated linearly) [N/m]."""
        near, far = self._pressure(p, 0), self._pressure(p, 1)
        linear = near + 1.5 * (near - far)
        weight = -self.normal[:, 0] * self.length
        return float(np.sum(near * weight)), float(np.sum(linear * weight))


def run_dfg(resolution: int = 20, *, duration: float | None = None, dt: float | None = None,
            advection: str = "maccormack", cfl: float = 0.5,
            incremental_pressure: bool = False, kick: float = 0.3, limiter: bool = True,
            advecting_velocity: str = "current", viscosity_scheme: str = "backward_euler",
            offset: float = 0.0, across: int | None = None,
            progress: Progress | None = None) -> DfgResult:
    """Run DFG 2D-2 and evaluate its quantities over the last period.

    Args:
        resolution: Cells per cylinder diameter (4..160).
        duration: Simulated time [s] (default 10).
        dt: Time step [s] (default: ``cfl`` on the inflow peak).
        advection: "maccormack" or "semi_lagrangian".
        cfl: Time step as a fraction of h / 1.5 m/s, when ``dt`` is not given.
        incremental_pressure: The fluid's pressure-correction form.
        kick: Peak transverse velocity [m/s] of the start-up perturbation (0: none).
        limiter: MacCormack's clamp (False only for studies).
        advecting_velocity: "current" or "extrapolated" (`FluidSolver`).
        viscosity_scheme: "backward_euler" or "crank_nicolson" (`FluidSolver`).
        offset: The cylinder moved downstream by this many cells (`DfgSetup`).
        across: Cells across the channel's height (`DfgSetup`).
        progress: Called with (steps done, steps in all) as the run goes.
    """
    setup = dfg_setup(resolution, duration=duration, dt=dt, advection=advection, cfl=cfl,
                      incremental_pressure=incremental_pressure, kick=kick, limiter=limiter,
                      advecting_velocity=advecting_velocity, viscosity_scheme=viscosity_scheme,
                      offset=offset, across=across)
    times, columns, seconds = step_series(setup, progress)
    if not all(np.isfinite(values[1:]).all() for values in columns.values()):
        result = DfgResult(setup, times, columns, seconds=seconds)
        result.failure = "non-finite forces: the run blew up"
        return result
    return evaluate(setup, times, columns, seconds)


SERIES_NAMES = ("drag", "lift", "drag_pressure", "drag_pressure_constant",
                "drag_pressure_linear", "drag_cv", "lift_cv", "delta_p")


def step_series(setup: DfgSetup, progress: Progress | None = None
                ) -> tuple[np.ndarray, dict[str, np.ndarray], float]:
    """Step the channel flow of ``setup`` from its initial state and record, after every
    step, the series `DfgResult` describes (coefficients on the setup's own mean speed).

    Returns:
        Sample times [s], the series by name, and the stepping's wall time [s].
    """
    from elastoflow.coupling import force_traction

    grid, solver, bmap, interior = dfg_solver(setup)
    state = initial_state(grid, interior, setup.kick, setup.center, setup.peak_speed)
    balance = ControlVolumeDrag(grid, setup.center, bdf2=setup.viscosity_scheme == "bdf2")
    surface = SurfacePressureDrag(grid, center=setup.center)
    front, back = setup.front_and_back
    steps = setup.steps
    columns = {name: np.zeros(steps) for name in SERIES_NAMES}
    times = np.zeros(steps)
    scale = 2.0 / (DENSITY * setup.mean_speed**2 * DIAMETER)
    balance.force(state.velocity_x, state.velocity_y, state.pressure, setup.dt)
    began = _time.perf_counter()
    now = 0.0
    for k in range(steps):
        solver.step(state, setup.dt, now, interior)
        now = (k + 1) * setup.dt
        times[k] = now
        u, v, p = state.velocity_x, state.velocity_y, state.pressure
        total = force_traction(grid, bmap, u, v, p, DENSITY, VISCOSITY, interior).sum(axis=0)
        pressure_part = force_traction(grid, bmap, u, v, p, DENSITY, 0.0, interior).sum(axis=0)
        control = balance.force(u, v, p, setup.dt)
        constant, linear = surface.drag(p)
        columns["drag_pressure_constant"][k] = scale * constant
        columns["drag_pressure_linear"][k] = scale * linear
        columns["drag"][k] = scale * total[0]
        columns["lift"][k] = scale * total[1]
        columns["drag_pressure"][k] = scale * pressure_part[0]
        columns["drag_cv"][k] = scale * control[0]
        columns["lift_cv"][k] = scale * control[1]
        columns["delta_p"][k] = (
            surface_pressure(grid, p, interior.solid_cells, front, setup.center)
            - surface_pressure(grid, p, interior.solid_cells, back, setup.center))
        if progress is not None:
            progress(k + 1, steps)
    return times, columns, _time.perf_counter() - began


def evaluate(setup: DfgSetup, time: np.ndarray, series: dict[str, np.ndarray],
             seconds: float) -> DfgResult:
    """The benchmark's quantities from the time series: periods from the lift over the last
    half of the record; maxima over the last full period; Δp half a period after the last
    lift maximum that leaves room for it."""
    result = DfgResult(setup, time, series, seconds=seconds)
    try:
        for key in ("lift", "drag", "drag_cv", "lift_cv"):
            result.statistics[key] = _statistics(time, series[key])
        result.quantities.update(dfg_quantities(time, series["drag"], series["lift"],
                                                series["delta_p"], setup.mean_speed))
        result.balance.update({"drag_max": result.statistics["drag_cv"].maximum,
                               "lift_max": result.statistics["lift_cv"].maximum})
    except ValueError as error:
        result.failure = f"not periodic yet: {error}"
    return result


def _statistics(time: np.ndarray, values: np.ndarray) -> PeriodicStatistics:
    finite = np.isfinite(values)
    return periodic_statistics(time[finite], values[finite], window=0.5)


def dfg_quantities(time: np.ndarray, drag: np.ndarray, lift: np.ndarray,
                   delta_p: np.ndarray, mean_speed: float = MEAN_SPEED) -> dict[str, float]:
    """DFG 2D-2's quantities from time series, as the benchmark defines them: St = D f / U
    with f from the lift over the last half of the record; c_D max and c_L max over the last
    full period; Δp half a period after the last lift maximum that leaves room for it.

    Args:
        time: Sample times [s], increasing, shape (k,).
        drag, lift: The coefficients ``2 F / (rho U^2 D)``, shape (k,).
        delta_p: ``p(front) - p(back)`` [Pa], shape (k,).
        mean_speed: U [m/s] (the inflow's mean; 1 m/s for 2D-2).

    Returns:
        "strouhal", "drag_max", "lift_max", "delta_p".

    Raises:
        ValueError: the lift or the drag is not periodic yet over the last half.
    """
    time = np.asarray(time, dtype=np.float64)
    lift = np.asarray(lift, dtype=np.float64)
    lift_statistics = _statistics(time, lift)
    frequency = lift_statistics.frequency
    quantities = {"strouhal": DIAMETER * frequency / mean_speed,
                  "drag_max": _statistics(time, np.asarray(drag, dtype=np.float64)).maximum,
                  "lift_max": lift_statistics.maximum}
    # The last lift maximum with half a period after it inside the record: the maximum over
    # the full period that ends half a period before the record does.
    end = time[-1] - 0.5 / frequency
    candidates = np.flatnonzero((time >= end - 1.0 / frequency) & (time <= end))
    t0 = float(time[candidates[np.argmax(lift[candidates])]])
    quantities["delta_p"] = float(np.interp(t0 + 0.5 / frequency, time,
                                            np.asarray(delta_p, dtype=np.float64)))
    return quantities


def describe(result: DfgResult) -> str:
    """One line: benchmark, resolution, grid, advection, steps and wall time."""
    s = result.setup
    nx, ny = s.cells
    end = float(result.time[-1]) if len(result.time) else 0.0
    form = ", incremental pressure" if s.incremental_pressure else ""
    form += "" if s.limiter or s.advection != "maccormack" else ", unlimited"
    form += ", extrapolated trace" if s.advecting_velocity == "extrapolated" else ""
    form += ", Crank-Nicolson viscosity" if s.viscosity_scheme == "crank_nicolson" else ""
    form += f", cylinder {s.offset:g} cell downstream" if s.offset else ""
    return (f"DFG 2D-2, resolution {s.resolution}: {nx}x{ny} cells (h = {s.h:.5g} m), "
            f"{s.advection} advection{form}, dt = {s.dt:.4g} s, t = 0-{end:.4g} s "
            f"({s.steps} steps), {result.seconds:.1f} s wall")


def format_quantities(result: DfgResult) -> list[str]:
    """Each quantity beside the published bounds, one per line."""
    def line(label: str, value: float, low: float, high: float) -> str:
        if low <= value <= high:
            verdict = "inside"
        else:
            edge = low if value < low else high
            verdict = f"outside, {100.0 * (value / edge - 1.0):+.2f} % from the bound"
        return f"{label:<10} {value:.4f}   bounds {low:.4f}-{high:.4f}   {verdict}"

    lines = [line(LABELS[key], result.quantities[key], *bounds)
             for key, bounds in BOUNDS.items() if key in result.quantities]
    if result.balance:
        lines.append("by the momentum balance on a box around the cylinder (the scheme's own "
                     "force):")
        lines += [line(LABELS[key], result.balance[key], *BOUNDS[key])
                  for key in ("drag_max", "lift_max") if key in result.balance]
    if "drag" in result.statistics and "drag_cv" in result.statistics:
        lines.append(f"{'c_D mean':<10} {result.statistics['drag'].mean:.4f}   (control volume: "
                     f"{result.statistics['drag_cv'].mean:.4f})")
    if result.failure is not None:
        lines.append(f"not evaluated: {result.failure}")
    return lines


def setup_record(setup: DfgSetup) -> dict[str, Any]:
    """What a run was set up with, as JSON-ready data (the head of every DFG report)."""
    return {
        "benchmark": setup.name,
        "resolution": setup.resolution,
        "h": setup.h,
        "dt": setup.dt,
        "cells": list(setup.cells),
        "advection": setup.advection,
        "incremental_pressure": setup.incremental_pressure,
        "maccormack_limiter": setup.limiter,
        "advecting_velocity": setup.advecting_velocity,
        "viscosity_scheme": setup.viscosity_scheme,
        "offset": setup.offset,
    }


def quantities_json(result: DfgResult) -> dict[str, Any]:
    """The run and its quantities as JSON-ready data."""
    return {
        **setup_record(result.setup),
        "duration": float(result.time[-1]) if len(result.time) else 0.0,
        "steps": result.setup.steps,
        "wall_seconds": result.seconds,
        "quantities": {key: {"value": value, "bounds": list(BOUNDS[key]),
                             "inside": result.within_bounds(key)}
                       for key, value in result.quantities.items()},
        "balance": {key: {"value": value, "bounds": list(BOUNDS[key]),
                          "inside": result.within_bounds(key, balance=True)}
                    for key, value in result.balance.items()},
        "statistics": {key: value.as_dict() for key, value in result.statistics.items()},
        "failure": result.failure,
    }


def report_stem(advection: str, resolution: int, advecting_velocity: str = "current",
                viscosity_scheme: str = "backward_euler") -> str:
    """``dfg2d2_<advection>[_extrapolated][_crank_nicolson]_n<N>``: the first-order time
    step keeps the name it always had."""
    time_scheme = ("_extrapolated" if advecting_velocity == "extrapolated" else "") + (
        "_crank_nicolson" if viscosity_scheme == "crank_nicolson" else "")
    return f"dfg2d2_{advection}{time_scheme}_n{resolution}"


def write_dfg_report(result: DfgResult, folder: str | Path, *, json_file: bool = True
                     ) -> list[Path]:
    """Write ``dfg2d2_<advection>_n<N>.csv`` (time series), ``.png`` (plots) and, with
    ``json_file``, ``.json`` into ``folder``; each file appears whole or not at all."""
    from elastoflow.validation._report import write_series_report

    s = result.setup
    stem = report_stem(s.advection, s.resolution, s.advecting_velocity, s.viscosity_scheme)
    return write_series_report(folder, stem, result.time, result.series, list(result.series),
                               lambda path: _plot(result, path),
                               quantities_json(result) if json_file else None)


def _plot(result: DfgResult, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from elastoflow.io import atomic_path

    figure, axes = plt.subplots(1, 3, figsize=(13, 3.4))
    panels = (("drag", "c_D", "drag_max"), ("lift", "c_L", "lift_max"),
              ("delta_p", "Δp [Pa]", "delta_p"))
    for axis, (key, label, bound) in zip(axes, panels):
        axis.plot(result.time, result.series[key], lw=0.8)
        low, high = BOUNDS[bound]
        axis.axhspan(low, high, color="tab:green", alpha=0.25, label="published bounds")
        # The start-up transient (the first steps' impulsive pressure) is left off the scale.
        values = result.series[key][len(result.time) // 10:]
        values = values[np.isfinite(values)]
        if len(values):
            span = max(float(np.ptp(values)), 0.05)
            axis.set_ylim(min(values.min(), low) - 0.3 * span,
                          max(values.max(), high) + 0.3 * span)
        stats = result.statistics.get("lift")
        if stats is not None:
            axis.axvspan(stats.start, stats.end, color="0.9", zorder=0, label="last period")
        axis.set_xlabel("t [s]")
        axis.set_ylabel(label)
        axis.grid(alpha=0.3)
        axis.legend(loc="lower left", fontsize=7)
    figure.suptitle(describe(result), fontsize=8)
    figure.tight_layout()
    with atomic_path(path) as temporary:
        figure.savefig(temporary, dpi=100, format="png")
    plt.close(figure)
