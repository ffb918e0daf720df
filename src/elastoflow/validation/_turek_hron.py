"""The Turek & Hron (2006) FSI benchmark: CFD1-3, CSM1-3, FSI1-3 in their exact geometry.

Channel [0, 2.5] x [0, 0.41] m; rigid cylinder of radius 0.05 m about (0.2, 0.2), a static
obstacle in the boundary map; an elastic flag [0.2490, 0.6] x [0.19, 0.21] m clamped where it
meets the cylinder; parabolic inflow of mean speed U with the benchmark's start-up ramp
``(1 - cos(pi t / 2)) / 2`` over the first 2 s; no slip on the walls; outflow on the right.
St. Venant-Kirchhoff solid in plane strain. The quantities: the displacement of point A (the
flag's trailing-edge midpoint, (0.6, 0.2) at rest) and the force (drag, lift) of the fluid on
cylinder and flag together, by the traction integral. Periodic cases report ``mean ± amplitude
[frequency]`` over the last full period, steady ones the final value. The CFD cases, whose
cylinder and flag stand still, also read that force by the momentum balance over a box of
whole cells `BALANCE_REACH` beyond them ("drag_cv", "lift_cv"; `elastoflow.fluid.
MomentumBalance`), which no cut cell enters: on CFD1 its error is a third to a half of the
traction's at N = 10-40 (docs/validation/turek-hron.md).

Resolution ``N`` means about ``N`` cells per cylinder diameter: the channel's height 0.41 m is
cut into ``k`` cells, the smallest ``k >= 4.1 N`` that is not a multiple of 41 (h = 0.41 / k),
and the channel is extended to whole cells at the outflow (at most h longer than 2.5 m).
Every h that divides both 0.41 m and 2.5 m puts the flag's faces (y = 0.19 and 0.21 m) exactly
on grid lines, where the faces along them flip between fluid and solid with every round-off
of motion and drive a step-to-step oscillation of the flag (docs/method_notes.md); with
``k`` not a multiple of 41 they lie 0.46 of a cell from the nearest line. The flag gets
``max(2, round(N / 5))`` crossed element layers through its thickness (elements about as
large as the cells).
"""

from __future__ import annotations

import math
import time as _time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal

import numpy as np

from elastoflow.analysis import PeriodicStatistics, periodic_statistics

if TYPE_CHECKING:
    from elastoflow.fluid import MomentumBalance
    from elastoflow.simulation import CoupledModel, Simulation
    from elastoflow.solid import ElasticBody, MaterialStVK

CHANNEL = (2.5, 0.41)
CENTER = (0.2, 0.2)
RADIUS = 0.05
DIAMETER = 2.0 * RADIUS
FLAG_Y = (0.19, 0.21)
FLAG_RIGHT = 0.6
# The flag's left end lies on the cylinder: x = 0.2 + sqrt(0.05^2 - 0.01^2).
FLAG_LEFT = CENTER[0] + math.sqrt(RADIUS**2 - (FLAG_Y[1] - CENTER[1]) ** 2)
POINT_A = (0.6, 0.2)
RAMP_TIME = 2.0
# The CFD cases' control volume reaches this far beyond the cylinder and the flag [m] (one
# diameter): boxes reaching 0.05 / 0.10 / 0.13 m beyond the cylinder gave CFD1's drag within
# 0.8 % and its lift within 0.2 % of each other at N = 10-40.
BALANCE_REACH = 0.1

# Published values (Turek & Hron 2006, as quoted in ../shared/reference/turek_hron.json).
REFERENCE: dict[str, dict[str, float]] = {
    "CFD1": {"drag": 14.29, "lift": 1.119},
    "CSM1": {"ux_A": -7.187e-3, "uy_A": -66.1e-3},
}
# Quantities read by the momentum balance, and the traction quantity each stands for.
BALANCE_OF = {"drag_cv": "drag", "lift_cv": "lift"}

Kind = Literal["CFD", "CSM", "FSI"]


@dataclass(frozen=True)
class Case:
    """Parameters of one benchmark case (SI units; Turek & Hron 2006, Tables 1-3).

    Attributes:
        name: "CFD1" ... "FSI3".
        kind: "CFD" (rigid flag), "CSM" (flag alone under gravity) or "FSI".
        periodic: Whether the answer is an oscillation (mean, amplitude, frequency) rather than
            a steady state.
        mean_speed: Mean inflow speed U [m/s]; the peak of the parabola is 1.5 U.
        duration: Default simulated time [s]: long enough to settle or to reach the fully
            developed oscillation.
        solid_density: rho_s [kg/m^3].
        shear_modulus: mu_s [Pa].
        gravity: Gravity on the flag [m/s^2], downwards (CSM cases only).
    """

    name: str
    kind: Kind
    periodic: bool
    mean_speed: float
    duration: float
    solid_density: float = 1000.0
    shear_modulus: float = 0.5e6
    gravity: float = 0.0
    fluid_density: float = 1000.0
    viscosity: float = 1e-3
    poisson_ratio: float = 0.4
    benchmark: str = "Turek-Hron"
    columns: tuple[str, ...] | None = None
    window: float = 0.5
    """Periodic cases: the fraction of the record, from its end, searched for periods."""

    @property
    def young_modulus(self) -> float:
        return 2.0 * self.shear_modulus * (1.0 + self.poisson_ratio)

    @property
    def quantities(self) -> tuple[str, ...]:
        """Names of the benchmark's quantities for this kind of case."""
        if self.columns is not None:
            return self.columns
        return {"CFD": ("drag", "lift", "drag_cv", "lift_cv"), "CSM": ("ux_A", "uy_A"),
                "FSI": ("ux_A", "uy_A", "drag", "lift")}[self.kind]


CASES: dict[str, Case] = {
    case.name: case
    for case in (
        Case("CFD1", "CFD", False, 0.2, 12.0),
        Case("CFD2", "CFD", False, 1.0, 10.0),
        Case("CFD3", "CFD", True, 2.0, 20.0),
        Case("CSM1", "CSM", False, 0.0, 0.0, gravity=2.0),
        Case("CSM2", "CSM", False, 0.0, 0.0, shear_modulus=2.0e6, gravity=2.0),
        Case("CSM3", "CSM", True, 0.0, 10.0, gravity=2.0),
        Case("FSI1", "FSI", False, 0.2, 15.0),
        Case("FSI2", "FSI", True, 1.0, 15.0, solid_density=10000.0),
        Case("FSI3", "FSI", True, 2.0, 10.0, shear_modulus=2.0e6),
    )
}

# Units the benchmark prints each quantity in: displacements in 1e-3 m, forces in N/m.
UNITS: dict[str, tuple[float, str]] = {
    "ux_A": (1e3, "1e-3 m"), "uy_A": (1e3, "1e-3 m"), "drag": (1.0, "N/m"), "lift": (1.0, "N/m"),
    "drag_cv": (1.0, "N/m"), "lift_cv": (1.0, "N/m"), "ux_tip": (1.0, "m"), "uy_tip": (1.0, "m"),
}


def check_resolution(resolution: int) -> None:
    """Refuse a resolution outside 5..200 cells per cylinder diameter."""
    if not (isinstance(resolution, int) and 5 <= resolution <= 200):
        raise ValueError(
            f"resolution = {resolution!r}: must be a whole number of cells per cylinder "
            "diameter in 5..200"
        )


def cells_across(resolution: int) -> int:
    """Cells across the channel's height: the smallest ``k >= 4.1 N`` not a multiple of 41
    (a multiple would put the flag's faces on grid lines)."""
    k = math.ceil(4.1 * resolution - 1e-9)
    return k + 1 if k % 41 == 0 else k


def get_case(name: str) -> Case:
    """The case called ``name`` (case-insensitive), or ValueError naming the choices."""
    case = CASES.get(name.upper())
    if case is None:
        raise ValueError(f"case = {name!r}: must be one of {', '.join(CASES)}")
    return case


def flag_mesh(layers: int) -> tuple[np.ndarray, np.ndarray]:
    """The flag as a crossed structured mesh with ``layers`` square cells through its
    thickness: points (n, 2) and triangles (m, 3).

    The left column of nodes is moved onto the cylinder's circle and the shift fades linearly
    to zero at the free end, so the elements stay nearly square and the clamped edge is the
    arc itself.
    """
    from elastoflow.solid import mesh_rectangle

    thickness = FLAG_Y[1] - FLAG_Y[0]
    length = FLAG_RIGHT - FLAG_LEFT
    cells_x = round(length / (thickness / layers))
    mesh = mesh_rectangle(length, thickness, counts=(cells_x, layers),
                          origin=(FLAG_LEFT, FLAG_Y[0]), pattern="crossed")
    points = mesh.points.copy()
    arc = CENTER[0] + np.sqrt(RADIUS**2 - (points[:, 1] - CENTER[1]) ** 2)
    points[:, 0] += (arc - FLAG_LEFT) * (FLAG_RIGHT - points[:, 0]) / length
    return points, np.asarray(mesh.triangles)


def _circle_segments(h: float) -> int:
    """Polygon vertices for the cylinder: edges no longer than h / 2 (at least 64)."""
    return max(64, math.ceil(2.0 * math.pi * RADIUS / (0.5 * h)))


def cantilever_shape(x: np.ndarray) -> np.ndarray:
    """The flag's deflection per unit tip deflection under a tip load (Euler-Bernoulli),
    ``a^2 (3 L - a) / (2 L^3)`` with ``a`` the distance from the root: 0 and flat at the
    root, 1 at the trailing edge."""
    length = FLAG_RIGHT - FLAG_LEFT
    a = np.clip(np.asarray(x, dtype=np.float64) - FLAG_LEFT, 0.0, length)
    return np.asarray(a**2 * (3.0 * length - a) / (2.0 * length**3))


def rigid_flag_polygon(segments: int, tip_deflection: float = 0.0,
                       spacing: float = 0.0025) -> np.ndarray:
    """Cylinder and flag as one counter-clockwise polygon (the CFD cases' rigid body): the
    circle from the flag's top corner round to its bottom corner, then the flag's outline.

    ``tip_deflection`` [m] bends the flag rigidly into `cantilever_shape` (each point moved
    vertically, the trailing edge by the whole amount; a shear, so the area is kept), its long
    sides cut into pieces of about ``spacing``: the geometry of a deflected FSI1 flag held
    still, to measure how the fluid's force answers the flag's deflection."""
    top = math.atan2(FLAG_Y[1] - CENTER[1], FLAG_LEFT - CENTER[0])
    angles = np.linspace(top, 2.0 * math.pi - top, max(segments, 8))
    arc = np.stack([CENTER[0] + RADIUS * np.cos(angles), CENTER[1] + RADIUS * np.sin(angles)],
                   axis=1)
    arc[0] = (FLAG_LEFT, FLAG_Y[1])
    arc[-1] = (FLAG_LEFT, FLAG_Y[0])
    if tip_deflection == 0.0:
        outline = np.array([[FLAG_RIGHT, FLAG_Y[0]], [FLAG_RIGHT, FLAG_Y[1]]])
        return np.concatenate([arc, outline])
    if not math.isfinite(tip_deflection) or abs(tip_deflection) > 0.5 * (FLAG_Y[1] - FLAG_Y[0]):
        raise ValueError(f"tip_deflection = {tip_deflection!r}: must be a finite length of at "
                         f"most half the flag's thickness, {0.5 * (FLAG_Y[1] - FLAG_Y[0])} m")
    if not (spacing > 0.0 and math.isfinite(spacing)):
        raise ValueError(f"spacing = {spacing!r}: must be a finite positive length [m]")
    pieces = max(1, math.ceil((FLAG_RIGHT - FLAG_LEFT) / spacing))
    x = np.linspace(FLAG_LEFT, FLAG_RIGHT, pieces + 1)[1:]
    lift = tip_deflection * cantilever_shape(x)
    bottom = np.column_stack([x, FLAG_Y[0] + lift])
    top_side = np.column_stack([x[::-1], FLAG_Y[1] + lift[::-1]])
    return np.concatenate([arc, bottom, top_side])


@dataclass
class Setup:
    """What a case is run with: resolution, time step, scheme, boundary treatment, and whether
    the fluid solves for the pressure increment (`FluidSolver`'s ``incremental_pressure``)."""

    case: Case
    resolution: int
    h: float
    dt: float
    duration: float
    scheme: str
    layers: int
    boundary: str = "cut_cell"
    incremental_pressure: bool = False

    @property
    def steps(self) -> int:
        return max(1, round(self.duration / self.dt))


def default_setup(case: Case, resolution: int, *, duration: float | None = None,
                  dt: float | None = None, scheme: str = "monolithic",
                  boundary: str = "cut_cell", incremental_pressure: bool = False,
                  cells: int | None = None) -> Setup:
    """Resolution N -> h = 0.41 / `cells_across` (N), about N/5 flag layers; dt from a CFL
    number of 0.5 on the inflow peak (fluid cases), 0.005 s (CSM3, the benchmark's own
    step). ``incremental_pressure`` is refused for the CSM cases, which have no fluid.
    ``cells``: the cells across the channel's height instead of `cells_across` (N), to place
    the flag elsewhere in the grid at about the same h; a multiple of 41 (the flag's faces on
    grid lines) is refused."""
    check_resolution(resolution)
    if cells is None:
        cells = cells_across(resolution)
    elif not (isinstance(cells, int) and cells >= 8 and cells % 41 != 0):
        raise ValueError(f"cells = {cells!r}: must be a whole number of cells across the "
                         "channel's height, at least 8 and not a multiple of 41 (which puts "
                         "the flag's faces on grid lines)")
    h = CHANNEL[1] / cells
    if duration is None:
        duration = case.duration
    if not (duration >= 0.0 and math.isfinite(duration)):
        raise ValueError(f"duration = {duration!r}: must be a finite number >= 0 [s]")
    if dt is None:
        dt = 0.5 * h / (1.5 * case.mean_speed) if case.mean_speed > 0.0 else 0.005
    if not (dt > 0.0 and math.isfinite(dt)):
        raise ValueError(f"dt = {dt!r}: must be a finite positive time step [s]")
    if scheme not in ("monolithic", "explicit"):
        raise ValueError(f"scheme = {scheme!r}: must be 'monolithic' or 'explicit'")
    check_boundary(boundary)
    if incremental_pressure and case.kind == "CSM":
        raise ValueError(f"incremental_pressure = True: {case.name} has no fluid (CSM cases "
                         "are the flag alone)")
    return Setup(case, resolution, h, float(dt), float(duration), scheme,
                 max(2, round(resolution / 5)), boundary, bool(incremental_pressure))


def check_boundary(boundary: str) -> None:
    """Refuse a boundary treatment name that `elastoflow.coupling` does not know."""
    from elastoflow.coupling import BOUNDARY_TREATMENTS

    if boundary not in BOUNDARY_TREATMENTS:
        raise ValueError(f"boundary = {boundary!r}: must be one of "
                         f"{', '.join(BOUNDARY_TREATMENTS)}")


@dataclass
class Result:
    """A run of one case: its time series and the benchmark's quantities.

    Attributes:
        setup: What it was run with.
        time: Sample times [s], shape (k,).
        series: Quantity name -> samples, shape (k,) each (SI units).
        quantities: Quantity name -> final value (steady cases) or `PeriodicStatistics`.
        errors: Quantity name -> relative error against the published value, where there is
            one (CFD1, CSM1).
        seconds: Wall time of the run [s].
        cells: Fluid grid (nx, ny), or None for the CSM cases.
        elements: Triangles of the flag (0 for the rigid flag of the CFD cases).
        steps: Steps taken (fluid steps, or solid output intervals for CSM).
        drift: Quantity name -> change over the last 10 % of the run (steady cases: how far
            from settled the final value is).
        failure: None, or why the quantities could not be computed (e.g. not periodic yet).
    """

    setup: Setup
    time: np.ndarray
    series: dict[str, np.ndarray]
    quantities: dict[str, float | PeriodicStatistics]
    errors: dict[str, float]
    seconds: float
    cells: tuple[int, int] | None
    elements: int
    steps: int
    drift: dict[str, float] = field(default_factory=dict)
    failure: str | None = None


Progress = Callable[[int, int], None]


def run_case(name: str, resolution: int = 20, *, duration: float | None = None,
             dt: float | None = None, scheme: str = "monolithic",
             progress: Progress | None = None, boundary: str = "cut_cell",
             incremental_pressure: bool = False) -> Result:
    """Run one Turek-Hron case and evaluate its quantities.

    Args:
        name: "CFD1" ... "FSI3".
        resolution: About this many cells per cylinder diameter (see `cells_across`).
        duration: Simulated time [s] (default: the case's).
        dt: Fluid time step [s] (default: CFL 0.5 on the inflow peak).
        scheme: Coupling scheme of the FSI cases ("monolithic" or "explicit").
        progress: Called with (steps done, steps in all) as the run goes.
        boundary: How the fluid sees the bodies (`elastoflow.coupling.BOUNDARY_TREATMENTS`).
        incremental_pressure: The fluid solves for the pressure increment (CFD and FSI cases).
    """
    setup = default_setup(get_case(name), resolution, duration=duration, dt=dt, scheme=scheme,
                          boundary=boundary, incremental_pressure=incremental_pressure)
    return run_setup(setup, progress)


def run_setup(setup: Setup, progress: Progress | None = None) -> Result:
    """Run one case as ``setup`` says (`default_setup`, possibly changed) and evaluate its
    quantities."""
    case = setup.case
    began = _time.perf_counter()
    if case.kind == "CSM":
        time, series, elements, steps = _run_solid(setup, progress)
        cells = None
    else:
        time, series, elements, steps, cells = _run_fluid(setup, progress)
    seconds = _time.perf_counter() - began
    return evaluate(setup, time, series, seconds, cells, elements, steps)


def evaluate(setup: Setup, time: np.ndarray, series: dict[str, np.ndarray], seconds: float,
              cells: tuple[int, int] | None, elements: int, steps: int) -> Result:
    case = setup.case
    quantities: dict[str, float | PeriodicStatistics] = {}
    drift: dict[str, float] = {}
    failure = None
    for key in case.quantities:
        if key not in series:
            continue  # a record from before the quantity was measured
        values = series[key]
        if case.periodic:
            try:
                # Periods are sought after the start-up, at the end of the record.
                quantities[key] = periodic_statistics(time, values, window=case.window)
            except ValueError as error:
                failure = f"{key}: {error}"
        else:
            quantities[key] = float(values[-1])
            if len(time) > 1:
                tail = time >= time[-1] - 0.1 * (time[-1] - time[0])
                drift[key] = float(values[-1] - values[np.flatnonzero(tail)[0]])
    errors = {}
    published_values = REFERENCE.get(case.name, {})
    for key, value in quantities.items():
        published = published_values.get(BALANCE_OF.get(key, key))
        if published is not None and isinstance(value, float):
            errors[key] = value / published - 1.0
    return Result(setup, time, series, quantities, errors, seconds, cells, elements, steps,
                  drift, failure)


def _material(case: Case) -> MaterialStVK:
    from elastoflow.solid import MaterialStVK

    return MaterialStVK(density=case.solid_density, young_modulus=case.young_modulus,
                        poisson_ratio=case.poisson_ratio)


def _flag_body(case: Case, layers: int) -> tuple[ElasticBody, int]:
    """The flag, clamped along its arc on the cylinder, and the node at point A."""
    from elastoflow.solid import ElasticBody, TriangleMesh

    points, triangles = flag_mesh(layers)
    mesh = TriangleMesh(points, triangles)
    on_cylinder = np.linalg.norm(points - np.asarray(CENTER), axis=1) <= RADIUS * (1 + 1e-9)
    body = ElasticBody(mesh, _material(case), fixed_nodes=np.flatnonzero(on_cylinder),
                       gravity=(0.0, -case.gravity))
    node_a = int(np.argmin(np.linalg.norm(points - np.asarray(POINT_A), axis=1)))
    return body, node_a


def _run_solid(setup: Setup, progress: Progress | None
               ) -> tuple[np.ndarray, dict[str, np.ndarray], int, int]:
    """CSM: the flag alone under gravity. Steady cases by Newton's method on the static
    equilibrium (one sample, the answer); CSM3 swings undamped from rest, sampled every
    ``dt``."""
    from elastoflow.solid import ExplicitFem, static_equilibrium

    case = setup.case
    body, node_a = _flag_body(case, setup.layers)
    rest = body.mesh.points[node_a].copy()
    if not case.periodic:
        state = body.state()
        iterations = static_equilibrium(body, state)
        d = state.positions[node_a] - rest
        if progress is not None:
            progress(1, 1)
        series = {"ux_A": np.array([float(d[0])]), "uy_A": np.array([float(d[1])])}
        return np.array([0.0]), series, body.mesh.triangle_count, iterations
    times, ux, uy = [0.0], [0.0], [0.0]
    steps = setup.steps
    state = body.state()
    fem = ExplicitFem("auto")
    for k in range(steps):
        fem.advance(body, state, state, setup.dt)
        d = state.positions[node_a] - rest
        times.append((k + 1) * setup.dt)
        ux.append(float(d[0]))
        uy.append(float(d[1]))
        if progress is not None:
            progress(k + 1, steps)
    series = {"ux_A": np.array(ux), "uy_A": np.array(uy)}
    return np.array(times), series, body.mesh.triangle_count, steps


def case_simulation(setup: Setup, *, tip_deflection: float = 0.0
                    ) -> tuple[Simulation, int | None]:
    """The `Simulation` of a CFD or FSI case, and the flag's point-A node (None for CFD).
    ``tip_deflection`` [m]: a CFD case's rigid flag bent by that much (`rigid_flag_polygon`);
    refused for the FSI cases, whose flag bends by itself."""
    from elastoflow import coupling, fluid, linalg
    from elastoflow.grid import Grid2D
    from elastoflow.simulation import MonolithicCoupling, Simulation

    case = setup.case
    grid = Grid2D(nx=math.ceil(CHANNEL[0] / setup.h - 1e-9), ny=round(CHANNEL[1] / setup.h),
                  h=setup.h)
    boundaries = fluid.DomainBoundaries(
        left=fluid.Inflow(speed=1.5 * case.mean_speed, profile="parabolic", ramp_time=RAMP_TIME),
        right=fluid.Outflow(), bottom=fluid.WallNoSlip(), top=fluid.WallNoSlip(),
    )
    solver = fluid.FluidSolver(
        grid, density=case.fluid_density, viscosity=case.viscosity, boundaries=boundaries,
        pressure_solver=linalg.PoissonSolverMGPCG(), advection="maccormack",
        pressure_guess="extrapolated", incremental_pressure=setup.incremental_pressure,
    )
    segments = _circle_segments(setup.h)
    bodies = []
    node_a = None
    if tip_deflection != 0.0 and case.kind != "CFD":
        raise ValueError(f"tip_deflection = {tip_deflection!r}: only a CFD case's rigid flag "
                         f"is bent ({case.name} is {case.kind})")
    if case.kind == "CFD":
        obstacles = [coupling.Obstacle(rigid_flag_polygon(segments, tip_deflection))]
    else:
        obstacles = [coupling.obstacle_circle(CENTER, RADIUS, segments=segments)]
        body, node_a = _flag_body(case, setup.layers)
        bodies.append(body)
    scheme = MonolithicCoupling() if setup.scheme == "monolithic" else "explicit"
    simulation = Simulation(grid, solver, bodies=bodies, obstacles=obstacles, dt=setup.dt,
                            coupling=scheme, boundary=setup.boundary)
    return simulation, node_a


def _run_fluid(setup: Setup, progress: Progress | None
               ) -> tuple[np.ndarray, dict[str, np.ndarray], int, int, tuple[int, int]]:
    simulation, node_a = case_simulation(setup)
    steps = setup.steps
    times = np.zeros(steps + 1)
    columns = {key: np.zeros(steps + 1) for key in ("ux_A", "uy_A", "drag", "lift")}
    rest = None
    if node_a is not None:
        rest = simulation.bodies[0].mesh.points[node_a].copy()
    balance = control_volume(simulation) if setup.case.kind == "CFD" else None
    if balance is not None:
        columns.update(drag_cv=np.zeros(steps + 1), lift_cv=np.zeros(steps + 1))
    for k in range(1, steps + 1):
        simulation.step()
        times[k] = simulation.time
        total = sum(force.sum(axis=0) for force in simulation.traction_forces())
        columns["drag"][k], columns["lift"][k] = float(total[0]), float(total[1])
        if balance is not None:
            fluid_state = simulation.state.fluid
            columns["drag_cv"][k], columns["lift_cv"][k] = balance.force(
                fluid_state.velocity_x, fluid_state.velocity_y, fluid_state.pressure,
                simulation.dt)
        if rest is not None:
            d = simulation.state.bodies[0].positions[node_a] - rest
            columns["ux_A"][k], columns["uy_A"][k] = float(d[0]), float(d[1])
        if progress is not None:
            progress(k, steps)
    elements = sum(body.mesh.triangle_count for body in model_2d(simulation).bodies)
    keys = setup.case.quantities
    # Forces at t = 0 are undefined (no map yet): the series start at the first step.
    series = {key: columns[key][1:] for key in keys}
    grid = simulation.grid
    return times[1:], series, elements, steps, (grid.nx, grid.ny)


def control_volume(simulation: Simulation) -> MomentumBalance:
    """The momentum balance over the box of whole cells reaching `BALANCE_REACH` beyond a
    CFD case's cylinder and flag, started from the simulation's current momentum."""
    from elastoflow.fluid import BoxCells, MomentumBalance

    model = model_2d(simulation)
    grid, solver = model.grid, model.fluid
    box = BoxCells.around(
        grid, (CENTER[0] - RADIUS - BALANCE_REACH, CENTER[1] - RADIUS - BALANCE_REACH),
        (FLAG_RIGHT + BALANCE_REACH, CENTER[1] + RADIUS + BALANCE_REACH))
    balance = MomentumBalance(grid, box, solver.density, solver.viscosity,
                              bdf2=solver.viscosity_scheme == "bdf2")
    state = simulation.state.fluid
    balance.start([balance.momentum(state.velocity_x, state.velocity_y)])
    return balance


def model_2d(simulation: Simulation) -> CoupledModel:
    """The model of a 2D simulation (the benchmarks here are 2D)."""
    from elastoflow.simulation import CoupledModel

    model = simulation.model
    if not isinstance(model, CoupledModel):
        raise TypeError("the Turek-Hron benchmark runs in 2D")
    return model
