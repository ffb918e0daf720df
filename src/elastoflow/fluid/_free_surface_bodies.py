"""A free surface with bodies in the liquid: the strongly coupled ghost-fluid projection and the
level set carried across the bodies.

::

    air  (phi >= 0): p = 0, no unknown; velocity extrapolated from the liquid and the bodies
    ---------------  surface phi = 0, p = 0 at theta h from a liquid cell centre
    liquid (phi < 0): weight A (open fraction) between liquid cells, A / theta on the
                      diagonal towards an air cell, nothing through closed faces
    body: its nodes are unknowns of the same solve (`CoupledBodies`); only the liquid cells
          next to it push on it (air cells hold p = 0)

The level set inside a body is not the liquid's: after each advection the cells whose centre
lies inside a body take the values just outside their nearest face, extended inwards layer
by layer (`carry_level_set_across_bodies`), so that a cell the body uncovers, or a back-trace
that ends inside it, finds what lies on that side: a body lifted out of the water leaves no
liquid behind inside it, one pushed under is wetted from below, and a gate with water on one
side and air on the other leaves no film on its dry face. The volume correction keeps the water outside the bodies
(`water_area`): the area of ``phi < 0`` weighted by each cell's fluid fraction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from elastoflow.fluid import _free_surface_bodies_kernels as kernels
from elastoflow.fluid import _kernels as fluid_kernels
from elastoflow.fluid import _level_set_kernels as level_set_kernels
from elastoflow.fluid._interior import InteriorBoundary
from elastoflow.fluid._level_set import LevelSetTransport, LevelSetWorkspace, still_air_spans
from elastoflow.fluid._solver import CoupledBodies, FluidSolver
from elastoflow.fluid._solver import _takes_out as takes_out
from elastoflow.fluid._solver import _writable_into as writable_into
from elastoflow.fluid._state import FluidState
from elastoflow.grid import Grid2D
from elastoflow.linalg import Operator5Point, SolveReport

FloatArray = NDArray[np.float64]


class FreeSurfaceBodiesWorkspace:
    """Scratch arrays of the free surface with bodies on one grid (allocated once)."""

    def __init__(self, grid: Grid2D) -> None:
        nx, ny = grid.shape_cells
        self.operator_arrays = (np.zeros((nx, ny)), np.zeros((nx - 1, ny)),
                                np.zeros((nx, ny - 1)))
        self.rhs = np.zeros((nx, ny))
        self.closed_u = np.zeros(grid.shape_faces_x)
        self.closed_v = np.zeros(grid.shape_faces_y)
        self.valid_u = np.zeros(grid.shape_faces_x, dtype=np.int32)
        self.valid_v = np.zeros(grid.shape_faces_y, dtype=np.int32)
        faces = max((nx + 1) * ny, nx * (ny + 1))
        # The breadth-first fronts of u's and v's extrapolation (`extrapolate_faces_pair`).
        self.frontier = np.zeros((4, faces, 2), dtype=np.int64)
        self.level_set = LevelSetWorkspace(grid)
        self.known = np.zeros((nx, ny), dtype=np.int8)
        self.fresh = np.zeros((nx, ny), dtype=np.int8)
        self.fractions = np.zeros((nx, ny))


@dataclass(frozen=True)
class GhostFluidCoupledProjection:
    """The strongly coupled projection of a liquid with a free surface around bodies.

    Solves ``(A + C) p = rhs`` (`PoissonSolverMGPCG.solve_coupled`) with ``A`` from
    `build_cut_free_surface_operator` (open fractions and the surface's 1/theta terms), ``C``
    the bodies' inertia on the liquid cells next to them (`CoupledBodies.coupling_term`), and
    the right-hand side ``-(rho h / dt) h div(A w)`` minus the bodies' predicted outflow;
    the bodies take the pressure's force, closed faces their new velocity, the open faces
    with liquid on a side the pressure gradient (ghost value 0 in the air).

    Guarantees: after `project` every liquid cell's flux balance ``div(A u + (1 - A) u_s)`` is
    zero to the solver's tolerance; the operator is symmetric positive semi-definite, definite
    on every liquid region touching air.

    Attributes:
        theta_min: Floor of the surface's fraction of the spacing (as `GhostFluidProjection`).
    """

    theta_min: float = level_set_kernels.THETA_MIN_DEFAULT

    def __post_init__(self) -> None:
        if not (isinstance(self.theta_min, (int, float)) and 0.0 < self.theta_min <= 1.0):
            raise ValueError(
                f"GhostFluidCoupledProjection.theta_min = {self.theta_min!r}: must be in (0, 1]")

    def operator(self, level_set: FloatArray, interior: InteriorBoundary,
                 out: tuple[FloatArray, FloatArray, FloatArray]) -> Operator5Point:
        """The operator for ``level_set`` and the bodies' open fractions, into ``out``."""
        diagonal, weights_x, weights_y = out
        kernels.build_cut_free_surface_operator(
            level_set, interior.open_fraction_x, interior.open_fraction_y,
            float(self.theta_min), diagonal, weights_x, weights_y)
        return Operator5Point(diagonal, weights_x, weights_y)

    def project(self, solver: FluidSolver, state: FluidState, level_set: FloatArray,
                dt: float, interior: InteriorBoundary, bodies: CoupledBodies,
                workspace: FreeSurfaceBodiesWorkspace) -> SolveReport:
        """Project ``state``'s velocity with the bodies as unknowns; the pressure [Pa] into
        ``state.pressure`` (0 in the air); marks the faces that hold values in
        ``workspace.valid_u`` / ``valid_v`` (the rest is for the extrapolation)."""
        solve_coupled = getattr(solver.pressure_solver, "solve_coupled", None)
        if solve_coupled is None:
            raise ValueError(
                f"pressure_solver = {solver.pressure_solver!r}: bodies in a free-surface liquid "
                "need a solver with solve_coupled (PoissonSolverMGPCG)")
        h = solver.grid.h
        operator = self.operator(level_set, interior, workspace.operator_arrays)
        active = operator.diagonal > 0.0
        active[:-1, :] |= operator.weights_x > 0.0
        active[1:, :] |= operator.weights_x > 0.0
        active[:, :-1] |= operator.weights_y > 0.0
        active[:, 1:] |= operator.weights_y > 0.0
        workspace.closed_u[...] = 0.0
        workspace.closed_v[...] = 0.0
        scale = solver.density * h / dt
        fluid_kernels.pressure_rhs(
            state.velocity_x, state.velocity_y, scale, True, interior.open_fraction_x,
            interior.open_fraction_y, workspace.closed_u, workspace.closed_v, workspace.rhs)
        bodies.add_to_rhs(workspace.rhs, scale, active)
        term = bodies.coupling_term(active)
        pressure = state.pressure
        pressure[~active] = 0.0
        if takes_out(solver.pressure_solver) and writable_into(pressure):
            _, report = solve_coupled(operator, term, workspace.rhs, x0=pressure, out=pressure)
        else:
            solution, report = solve_coupled(operator, term, workspace.rhs, x0=pressure)
            fluid_kernels.copy_into(solution, pressure)
        bodies.respond(pressure, active, workspace.closed_u, workspace.closed_v)
        kernels.subtract_cut_free_surface_gradient(
            state.velocity_x, state.velocity_y, pressure, level_set, interior.open_fraction_x,
            interior.open_fraction_y, workspace.closed_u, workspace.closed_v,
            dt / (solver.density * h), float(self.theta_min), workspace.valid_u,
            workspace.valid_v)
        return report


def extrapolate_velocity_from_valid(state: FluidState, layers: int,
                                    workspace: FreeSurfaceBodiesWorkspace) -> None:
    """Extend the velocity from the faces `GhostFluidCoupledProjection.project` marked into
    the rest (``layers`` layers, the rest of the air set to 0), in place."""
    level_set_kernels.extrapolate_faces_pair(state.velocity_x, workspace.valid_u,
                                             state.velocity_y, workspace.valid_v, layers,
                                             workspace.frontier)


def carry_level_set_across_bodies(level_set: FloatArray, interior: InteriorBoundary, h: float,
                                  workspace: FreeSurfaceBodiesWorkspace) -> int:
    """Replace the level set [m] in the cells whose centre lies in a body by its extension
    from the cells around, in place, layer by layer inwards, each cell the mean of its
    known neighbours (`extend_level_set`). Returns the cells no outside cell reached.

    Why from the nearest face: a cell the body uncovers as it moves takes this value, and a
    back-trace that ends inside the body reads it, so it must be what lies just outside the
    face the cell is nearest to. A harmonic extension (the earlier choice) blends the two
    sides of a thin body: a gate holding water on one side and air on the other held values
    near zero at its dry face, and as it swung back each cell it uncovered there turned to
    water, a film along the dry face. A linear extrapolation, tried before that, put
    wrong-signed values inside a heaving box where directions disagree; the constant one
    has no values its neighbours do not have."""
    solid = interior.solid_cells
    if not solid.any():
        return 0
    return int(kernels.extend_level_set(level_set, solid, workspace.known, workspace.fresh))


def water_area(level_set: FloatArray, interior: InteriorBoundary | None, h: float,
               workspace: FreeSurfaceBodiesWorkspace) -> float:
    """The water area [m^2] outside the bodies: `liquid_area`'s cell fractions weighted by
    each cell's fluid fraction (the mean of its faces' open fractions)."""
    if interior is None:
        area, _ = level_set_kernels.liquid_area(level_set, float(h))
        return float(area)
    kernels.fluid_fractions(interior.open_fraction_x, interior.open_fraction_y,
                            workspace.fractions)
    area, _ = kernels.weighted_liquid_area(level_set, workspace.fractions, float(h))
    return float(area)


def correct_water_volume(level_set: FloatArray, interior: InteriorBoundary, h: float,
                         target: float, workspace: FreeSurfaceBodiesWorkspace,
                         iterations: int = 8) -> float:
    """Shift ``level_set`` in place by a constant so that its `water_area` is ``target``
    [m^2] (Newton steps, as `correct_volume`); returns the shift [m]."""
    kernels.fluid_fractions(interior.open_fraction_x, interior.open_fraction_y,
                            workspace.fractions)
    total = 0.0
    for _ in range(iterations):
        area, ramp = kernels.weighted_liquid_area(level_set, workspace.fractions, float(h))
        excess = float(area) - target
        if ramp <= 0.0 or abs(excess) <= 1e-14 * max(target, h * h):
            break
        shift = excess / (h * ramp)
        level_set += shift
        total += shift
    return total


def transport_level_set_with_bodies(
    transport: LevelSetTransport, grid: Grid2D, level_set: FloatArray, velocity_x: FloatArray,
    velocity_y: FloatArray, dt: float, step_index: int, target_area: float | None,
    interior: InteriorBoundary, workspace: FreeSurfaceBodiesWorkspace,
) -> None:
    """Advance ``level_set`` [m] in place over ``dt`` [s]: advect it by the face velocity
    (the bodies' own inside them), carry it across the bodies
    (`carry_level_set_across_bodies`), redistance, and keep the water outside the bodies at
    ``target_area`` [m^2] (`correct_water_volume`) when the transport corrects the volume."""
    lw = workspace.level_set
    step = dt / grid.h
    if transport.advection == "maccormack":
        # Two passes, each tracing back once (the clamp's range is found in the first), as
        # `LevelSetTransport`'s own.
        spans = still_air_spans(velocity_x, velocity_y, lw)
        level_set_kernels.advect_cells_forward_range(level_set, velocity_x, velocity_y, step,
                                                     lw.forward, lw.low, lw.high, *spans)
        level_set_kernels.maccormack_backward_correct(level_set, lw.forward, lw.low, lw.high,
                                                      velocity_x, velocity_y, step, lw.backward,
                                                      *spans)
        result = lw.backward
    else:
        level_set_kernels.advect_cells_semi_lagrangian(level_set, velocity_x, velocity_y, step,
                                                       lw.forward)
        result = lw.forward
    carry_level_set_across_bodies(result, interior, grid.h, workspace)
    redistancing = transport.redistancing
    if redistancing is not None and step_index % transport.redistance_interval == 0:
        other = lw.forward if result is lw.backward else lw.backward
        redistancing.redistance(result, grid.h, other, lw.fixed)
        result = other
    level_set[...] = result
    if transport.volume_correction and target_area is not None:
        correct_water_volume(level_set, interior, grid.h, target_area, workspace)
