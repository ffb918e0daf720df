"""The preCICE perpendicular flap: an elastic flap clamped to the floor of a channel in a
uniform cross-flow (solid 3000 times denser than the fluid).

Channel [-3, 3] x [0, 4] m; flap [-0.05, 0.05] x [0, 1] m clamped along y = 0; uniform inflow
10 m/s from the left, the fluid started impulsively (the whole field at 10 m/s at t = 0, as the
tutorial's OpenFOAM case); no slip on floor and ceiling; outflow on the right. Fluid
rho = 1, nu = 1 (Re 10 on the flap's length); solid rho = 3000, E = 4 MPa, nu = 0.3 (the
tutorial's solvers are linear elastic; this is St. Venant-Kirchhoff, which agrees at small
strains). The quantity: the displacement of the flap's tip (0, 1) over 5 s.

Resolution ``N`` means about ``N`` cells per metre: ``k`` cells across the 4 m height, the
smallest even ``k >= 4 N`` whose grid keeps the flap's sides (x = -0.05, 0.05) at least a fifth
of a cell off the grid lines (see Turek-Hron's `cells_across` for why).
"""

from __future__ import annotations

import math
import time as _time

from typing import TYPE_CHECKING

import numpy as np

from elastoflow.validation._turek_hron import (
    Case,
    Progress,
    Result,
    Setup,
    check_boundary,
    evaluate,
    model_2d,
)

if TYPE_CHECKING:
    from elastoflow.simulation import Simulation

DOMAIN = ((-3.0, 3.0), (0.0, 4.0))
FLAP = ((-0.05, 0.05), (0.0, 1.0))
TIP = (0.0, 1.0)
SPEED = 10.0

FLAP_CASE = Case("FLAP", "FSI", True, SPEED, 5.0, solid_density=3000.0,
                 shear_modulus=4.0e6 / (2.0 * 1.3), fluid_density=1.0, viscosity=1.0,
                 poisson_ratio=0.3, benchmark="Perpendicular flap", columns=("ux_tip", "uy_tip"),
                 window=0.75)


def cells_high(resolution: int) -> int:
    """Cells across the 4 m height for about ``resolution`` cells per metre."""
    if not (isinstance(resolution, int) and 5 <= resolution <= 200):
        raise ValueError(f"resolution = {resolution!r}: must be a whole number of cells per "
                         "metre in 5..200")
    k = 2 * math.ceil(2.0 * resolution - 1e-9)
    while True:
        h = 4.0 / k
        offsets = [((x - DOMAIN[0][0]) / h) % 1.0 for x in FLAP[0]]
        if all(0.2 < offset < 0.8 for offset in offsets):
            return k
        k += 2


def flap_setup(resolution: int, *, duration: float | None = None, dt: float | None = None,
               scheme: str = "monolithic", boundary: str = "cut_cell",
               incremental_pressure: bool = False) -> Setup:
    """h = 4 / `cells_high`, flap elements about as large as the cells (at least 2 across),
    dt from a CFL number of 0.5 on the inflow speed."""
    h = 4.0 / cells_high(resolution)
    duration = FLAP_CASE.duration if duration is None else duration
    if not (duration >= 0.0 and math.isfinite(duration)):
        raise ValueError(f"duration = {duration!r}: must be a finite number >= 0 [s]")
    dt = 0.5 * h / SPEED if dt is None else dt
    if not (dt > 0.0 and math.isfinite(dt)):
        raise ValueError(f"dt = {dt!r}: must be a finite positive time step [s]")
    if scheme not in ("monolithic", "explicit"):
        raise ValueError(f"scheme = {scheme!r}: must be 'monolithic' or 'explicit'")
    check_boundary(boundary)
    layers = max(2, round(0.1 / h))
    return Setup(FLAP_CASE, resolution, h, float(dt), float(duration), scheme, layers, boundary,
                 bool(incremental_pressure))


def flap_simulation(setup: Setup) -> tuple[Simulation, int, np.ndarray]:
    """The `Simulation` of the flap (fluid at the inflow speed everywhere: the impulsive
    start), the tip's node and its rest position."""
    from elastoflow import fluid, linalg
    from elastoflow.grid import Grid2D
    from elastoflow.simulation import MonolithicCoupling, Simulation
    from elastoflow.solid import ElasticBody, MaterialStVK, mesh_rectangle

    h = setup.h
    grid = Grid2D(nx=round(6.0 / h), ny=round(4.0 / h), h=h, origin=(DOMAIN[0][0], 0.0))
    boundaries = fluid.DomainBoundaries(
        left=fluid.Inflow(speed=SPEED), right=fluid.Outflow(), bottom=fluid.WallNoSlip(),
        top=fluid.WallNoSlip())
    solver = fluid.FluidSolver(
        grid, density=FLAP_CASE.fluid_density, viscosity=FLAP_CASE.viscosity,
        boundaries=boundaries, pressure_solver=linalg.PoissonSolverMGPCG(),
        advection="maccormack", pressure_guess="extrapolated",
        incremental_pressure=setup.incremental_pressure)
    layers = setup.layers
    mesh = mesh_rectangle(0.1, 1.0, counts=(layers, 10 * layers), origin=(FLAP[0][0], 0.0),
                          pattern="crossed")
    material = MaterialStVK(density=FLAP_CASE.solid_density,
                            young_modulus=FLAP_CASE.young_modulus,
                            poisson_ratio=FLAP_CASE.poisson_ratio)
    body = ElasticBody(mesh, material, fixed_nodes=np.flatnonzero(mesh.points[:, 1] <= 1e-12))
    tip = int(np.argmin(np.linalg.norm(mesh.points - np.asarray(TIP), axis=1)))
    coupling = MonolithicCoupling() if setup.scheme == "monolithic" else "explicit"
    simulation = Simulation(grid, solver, bodies=[body], dt=setup.dt, coupling=coupling,
                            boundary=setup.boundary)
    simulation.state.fluid.velocity_x[...] = SPEED
    return simulation, tip, mesh.points[tip].copy()


def run_flap(resolution: int = 20, *, duration: float | None = None, dt: float | None = None,
             scheme: str = "monolithic", progress: Progress | None = None,
             boundary: str = "cut_cell", incremental_pressure: bool = False) -> Result:
    """Run the perpendicular flap and evaluate the tip's oscillation."""
    setup = flap_setup(resolution, duration=duration, dt=dt, scheme=scheme, boundary=boundary,
                       incremental_pressure=incremental_pressure)
    simulation, tip, rest = flap_simulation(setup)
    grid = simulation.grid
    mesh_triangles = model_2d(simulation).bodies[0].mesh.triangle_count
    began = _time.perf_counter()
    steps = setup.steps
    times = np.zeros(steps + 1)
    ux = np.zeros(steps + 1)
    uy = np.zeros(steps + 1)
    for k in range(1, steps + 1):
        simulation.step()
        times[k] = simulation.time
        d = simulation.state.bodies[0].positions[tip] - rest
        ux[k], uy[k] = float(d[0]), float(d[1])
        if progress is not None:
            progress(k, steps)
    seconds = _time.perf_counter() - began
    return evaluate(setup, times, {"ux_tip": ux, "uy_tip": uy}, seconds, (grid.nx, grid.ny),
                    mesh_triangles, steps)
