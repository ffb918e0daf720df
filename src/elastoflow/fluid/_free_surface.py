"""Liquid with a free surface: a level set in the state, a ghost-fluid projection, a solver.

Model, state and scheme, as for the rest of the fluid:

* `FreeSurfaceState`: the fluid's state (`FluidState`) and the level set beside it, with the
  liquid area the volume correction keeps; checkpointed by `to_arrays` / `load_arrays`.
* `GhostFluidProjection`: the pressure projection with ``p = 0`` on the surface, placed at its
  sub-cell position (Gibou et al. 2002, Enright et al. 2003); air is a void.
* `LevelSetTransport` (elastoflow.fluid._level_set): how the level set moves.
* `FreeSurfaceSolver`: one step from the `FluidSolver`'s own phases (advection, viscosity,
  forces: gravity on the faces) and the two parts above, which it is given.

::

    air  (phi >= 0): inactive in the pressure solve, velocity extrapolated from the liquid
    -----------------  surface phi = 0, p = 0 at theta h from the liquid cell centre
    liquid (phi < 0): 5-point Poisson equation, weight 1 between liquid cells, 1/theta on the
                      diagonal towards an air neighbour; walls: no flux
"""

from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np
from numpy.typing import NDArray

from elastoflow.fluid import _kernels as fluid_kernels
from elastoflow.fluid import _level_set_kernels as kernels
from elastoflow.fluid._boundaries import WallFreeSlip, WallMoving, WallNoSlip
from elastoflow.fluid._level_set import (
    LevelSetTransport,
    LevelSetWorkspace,
    liquid_area,
    transport_level_set,
)
from elastoflow.fluid._solver import FluidSolver
from elastoflow.fluid._solver import _takes_out as takes_out
from elastoflow.fluid._solver import _writable_into as writable_into
from elastoflow.fluid._state import FluidState
from elastoflow.grid import Grid2D
from elastoflow.linalg import Operator5Point, SolveReport

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int32]


@dataclass
class FreeSurfaceState:
    """The changing part of a liquid with a free surface.

    Attributes:
        fluid: Velocity, pressure (0 in the air) and dye; the velocity is extrapolated into the
            air after each step, so that advection sees a smooth field.
        level_set: Level set phi [m] at the cell centres, shape (nx, ny): liquid where
            ``phi < 0``; a signed distance after redistancing.
        liquid_area: The liquid area [m^2] (volume per metre of depth) that the volume
            correction keeps: the initial one.
        step_index: Steps taken (redistancing runs every `LevelSetTransport.redistance_interval`).
    """

    fluid: FluidState
    level_set: FloatArray
    liquid_area: float
    step_index: int = 0

    @classmethod
    def create(cls, grid: Grid2D, level_set: FloatArray,
               fluid: FluidState | None = None) -> FreeSurfaceState:
        """Liquid at rest (or ``fluid``) in the region where ``level_set`` [m] is negative."""
        phi = np.ascontiguousarray(level_set, dtype=np.float64).copy()
        if phi.shape != grid.shape_cells:
            raise ValueError(
                f"level_set shape {phi.shape}: must be {grid.shape_cells} (the cells)"
            )
        if not np.all(np.isfinite(phi)):
            raise ValueError("level_set: values must be finite")
        if not np.any(phi < 0.0):
            raise ValueError("level_set: no liquid (no cell with phi < 0)")
        state = FluidState.zeros(grid) if fluid is None else fluid
        return cls(fluid=state, level_set=phi, liquid_area=liquid_area(phi, grid.h))

    def copy(self) -> FreeSurfaceState:
        """An independent copy."""
        return FreeSurfaceState(self.fluid.copy(), self.level_set.copy(), self.liquid_area,
                                self.step_index)

    def assign(self, other: FreeSurfaceState) -> None:
        """Copy ``other``'s values into this state's arrays."""
        self.fluid.assign(other.fluid)
        self.level_set[...] = other.level_set
        self.liquid_area = other.liquid_area
        self.step_index = other.step_index

    def to_arrays(self) -> dict[str, np.ndarray]:
        """Every value as a named array (``fluid.velocity_x``, ..., ``level_set``), for a
        checkpoint; the optional fluid fields only when present."""
        arrays: dict[str, np.ndarray] = {}
        for item in fields(self.fluid):
            value = getattr(self.fluid, item.name)
            if value is not None:
                arrays[f"fluid.{item.name}"] = np.asarray(value).copy()
        arrays["level_set"] = self.level_set.copy()
        arrays["liquid_area"] = np.asarray(self.liquid_area)
        arrays["step_index"] = np.asarray(self.step_index)
        return arrays

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> FreeSurfaceState:
        """The state that `to_arrays` wrote (bit-exact)."""
        values: dict[str, np.ndarray | float | None] = {}
        for item in fields(FluidState):
            key = f"fluid.{item.name}"
            if key not in arrays:
                values[item.name] = None
                continue
            value = np.asarray(arrays[key])
            values[item.name] = float(value) if value.ndim == 0 else value.copy()
        fluid = FluidState(**values)  # type: ignore[arg-type]
        return cls(fluid, np.asarray(arrays["level_set"], dtype=np.float64).copy(),
                   float(arrays["liquid_area"]), int(arrays["step_index"]))


@dataclass(frozen=True)
class GhostFluidProjection:
    """Pressure projection of a liquid with a free surface (ghost fluid method).

    Solves ``A p = -(rho h / dt) h div w`` on the liquid cells with `A` from
    `build_free_surface_operator` (1/theta diagonal terms for p = 0 at the surface's sub-cell
    position), then subtracts the gradient on every face with liquid on a side, with the
    same ghost values. Faces between two air cells are not solved.

    Guarantees: after `project`, the divergence of every liquid cell is zero to the pressure
    solver's tolerance; the operator is symmetric positive definite on each liquid region that
    touches air (semi-definite on one enclosed by walls, which the solvers handle).

    The pressure is solved on the liquid's bounding box only (``liquid_box``): the air cells
    are inactive and the box holds every active cell, so the operator there is the whole
    grid's one; the box's sides are rounded up to a quarter of the grid's (at least
    `LIQUID_BOX_QUANTUM` cells), so that a run meets a handful of shapes, for each of which
    the pressure solver keeps its storage. The multigrid hierarchy of the box differs from the
    whole grid's, so the iterates differ: the same solution to the solver's tolerance, at
    the box's cost (the dam break at 256x128 spends most of its run in half the grid or less).

    Attributes:
        theta_min: Floor of the surface's fraction of the spacing (see
            `elastoflow.fluid._level_set_kernels.THETA_MIN_DEFAULT` for the choice).
        liquid_box: Solve on the liquid's bounding box (default) rather than the whole grid.
    """

    theta_min: float = kernels.THETA_MIN_DEFAULT
    liquid_box: bool = True

    def __post_init__(self) -> None:
        if not (isinstance(self.theta_min, (int, float)) and 0.0 < self.theta_min <= 1.0):
            raise ValueError(
                f"GhostFluidProjection.theta_min = {self.theta_min!r}: must be in (0, 1]"
            )

    def operator(self, level_set: FloatArray, out: tuple[FloatArray, FloatArray, FloatArray]
                 ) -> Operator5Point:
        """The pressure operator for ``level_set``, assembled into ``out`` (diagonal (nx, ny),
        weights_x (nx-1, ny), weights_y (nx, ny-1))."""
        diagonal, weights_x, weights_y = out
        bad = kernels.build_free_surface_operator(level_set, float(self.theta_min), diagonal,
                                                  weights_x, weights_y)
        if bad:
            raise ValueError(f"diagonal: values must be finite and >= 0; got {bad} non-finite "
                             "(the level set holds NaN or inf)")
        # Values finite and >= 0 by construction: no checking pass over them.
        return Operator5Point.assembled(diagonal, weights_x, weights_y)

    def project(self, solver: FluidSolver, state: FluidState, level_set: FloatArray, dt: float,
                workspace: FreeSurfaceWorkspace) -> SolveReport:
        """Make the liquid's velocity divergence-free; pressure [Pa] into ``state.pressure``
        (0 in the air); marks the solved faces in ``workspace.valid_u`` / ``valid_v``. The
        surface holds the pressure ``workspace.surface`` [Pa] of each liquid cell next to
        air (zeros: p = 0; a viscous surface's normal stress, `ViscosityStressFree`)."""
        grid = solver.grid
        h = grid.h
        operator = self.operator(level_set, workspace.operator_arrays)
        rhs = workspace.rhs
        fluid_kernels.pressure_rhs(
            state.velocity_x, state.velocity_y, solver.density * h / dt, False,
            workspace.no_values, workspace.no_values, workspace.no_values, workspace.no_values,
            rhs,
        )
        kernels.add_surface_pressure(level_set, workspace.surface, float(self.theta_min), rhs)
        pressure = state.pressure
        box = self._box(level_set) if self.liquid_box else None
        if box is not None:
            report = _solve_in_box(solver.pressure_solver, operator, rhs, pressure, box,
                                   workspace)
        elif _takes_out(solver.pressure_solver) and writable_into(pressure):
            _, report = solver.pressure_solver.solve(operator, rhs, x0=pressure, out=pressure)
        else:
            solution, report = solver.pressure_solver.solve(operator, rhs, x0=pressure)
            fluid_kernels.copy_into(solution, pressure)
        kernels.subtract_free_surface_gradient(
            state.velocity_x, state.velocity_y, pressure, level_set, workspace.surface,
            dt / (solver.density * h), float(self.theta_min), workspace.valid_u,
            workspace.valid_v,
        )
        return report

    @staticmethod
    def _box(level_set: FloatArray) -> tuple[int, int, int, int] | None:
        """The box ``(i0, i1, j0, j1)`` the pressure is solved on (None: the whole grid)."""
        nx, ny = level_set.shape
        i0, i1, j0, j1 = kernels.liquid_bounds(level_set)
        if i1 == 0:
            return None
        i0, i1 = _rounded_range(int(i0), int(i1), nx)
        j0, j1 = _rounded_range(int(j0), int(j1), ny)
        if i1 - i0 == nx and j1 - j0 == ny:
            return None
        return i0, i1, j0, j1


LIQUID_BOX_QUANTUM = 16
"""Smallest step [cells] in which `GhostFluidProjection`'s box grows."""


def _rounded_range(low: int, high: int, size: int) -> tuple[int, int]:
    """``[low, high)`` widened to a multiple of ``max(LIQUID_BOX_QUANTUM, size / 4)`` cells
    (at most ``size``), kept inside ``[0, size)``; the start even, so that the box's
    multigrid levels pair the same cells as the whole grid's where they can."""
    quantum = max(LIQUID_BOX_QUANTUM, -(-size // 4))
    low -= low % 2
    width = min(size, -(-(high - low) // quantum) * quantum)
    start = min(low, size - width)
    return start, start + width


_TAKES_OUT: dict[type, bool] = {}


def _takes_out(pressure_solver: object) -> bool:
    """Whether the solver's ``solve`` takes ``out`` (`FluidSolver`'s test, once per type:
    inspecting the signature every step cost 0.1-0.2 ms)."""
    kind = type(pressure_solver)
    known = _TAKES_OUT.get(kind)
    if known is None:
        known = _TAKES_OUT[kind] = takes_out(pressure_solver)
    return known


def _solve_in_box(pressure_solver: Any, operator: Operator5Point, rhs: FloatArray,
                  pressure: FloatArray, box: tuple[int, int, int, int],
                  workspace: FreeSurfaceWorkspace) -> SolveReport:
    """Solve ``operator p = rhs`` on the cells of ``box`` (every active cell lies in it),
    warm-started from ``pressure``, and write the solution into ``pressure``, 0 outside."""
    i0, i1, j0, j1 = box
    diagonal, weights_x, weights_y, box_rhs, box_pressure = workspace.box_arrays(i1 - i0,
                                                                                 j1 - j0)
    diagonal[...] = operator.diagonal[i0:i1, j0:j1]
    weights_x[...] = operator.weights_x[i0:i1 - 1, j0:j1]
    weights_y[...] = operator.weights_y[i0:i1, j0:j1 - 1]
    box_rhs[...] = rhs[i0:i1, j0:j1]
    box_pressure[...] = pressure[i0:i1, j0:j1]
    # Copied from the whole grid's operator (finite and >= 0 by construction).
    box_operator = Operator5Point.assembled(diagonal, weights_x, weights_y)
    if _takes_out(pressure_solver):
        _, report = pressure_solver.solve(box_operator, box_rhs, x0=box_pressure,
                                          out=box_pressure)
        solution = box_pressure
    else:
        solution, report = pressure_solver.solve(box_operator, box_rhs, x0=box_pressure)
    pressure[...] = 0.0
    pressure[i0:i1, j0:j1] = solution
    return report


@dataclass(frozen=True)
class ViscosityWholeGrid:
    """The fluid's own implicit viscosity (`FluidSolver.diffuse`) over the whole grid, the
    air holding the extrapolated velocity: at the surface this acts as a zero normal
    gradient of each velocity component, not as a stress-free surface (a potential-flow
    wave loses about half the energy it should; docs/validation/free_surface.md)."""

    def diffuse(self, solver: FluidSolver, state: FluidState, level_set: FloatArray,
                dt: float, workspace: FreeSurfaceWorkspace) -> int:
        """Diffuse ``state``'s velocity over ``dt`` [s]; returns the solver's iterations."""
        return solver.diffuse(state, dt)

    def surface_pressure(self, solver: FluidSolver, state: FluidState, level_set: FloatArray,
                         out: FloatArray) -> None:
        """The pressure the surface holds [Pa] into ``out`` (nx, ny): 0 everywhere."""
        out[...] = 0.0


VISCOSITY_FORMS = ("stress", "laplacian")
"""Choices of `ViscosityStressFree`'s ``form``."""


@dataclass(frozen=True)
class ViscosityStressFree:
    """Implicit viscosity (backward Euler) on the liquid only, with a stress-free surface.

    ``form="stress"`` (default): the divergence of the full viscous stress
    ``mu (grad u + grad u^T)``, variational (Batty & Bridson 2008): the new velocity minimises
    the kinetic energy of the change plus ``dt`` times the dissipation ``2 mu e:e``, with the
    strain's samples (``e_xx``, ``e_yy`` at the cells, ``e_xy`` at the corners) and the faces'
    masses weighted by their liquid fractions ``clamp(1/2 - phi / h, 0, 1)``; the surface's
    condition is the natural one, zero viscous traction; u and v are solved together
    (`solve_stress_viscosity`). Walls as in the fluid (no-slip reflected, free slip no
    shear, moving walls their velocity).

    ``form="laplacian"``: each component's Laplacian on the liquid's faces, the air faces
    next to the liquid entering as fixed ghost values that make the surface's shear stress
    zero (Harlow & Welch 1965; `stress_free_ghosts`). Near a free surface this dissipates
    ``mu |grad u|^2`` instead of ``2 mu e:e`` (they differ by a surface integral that vanishes
    at flat walls, not at a free surface): a potential-flow wave, for which the two are ``1 : 2``,
    is damped at about half the rate (docs/validation/free_surface.md).

    Attributes:
        form: "stress" or "laplacian" (above).
        normal_stress: Also put the surface's normal viscous stress into the projection:
            the surface pressure becomes ``2 mu du_n/dn`` of the step's starting velocity
            (`surface_normal_stress`) instead of 0. Off by default. With ``form="stress"``
            it counts the normal stress twice (the variational step already dissipates it):
            the viscous standing wave is damped 34 / 37 % above Lamb's mode at 32 / 64 cells
            per wavelength. With ``form="laplacian"`` it brought the damping from 0.74 / 0.77
            to 1.29 / 1.32 1/s (Lamb: 1.23), but at 128 cells the run diverged within a
            period, also with nu dt / h^2 lowered from 0.53 to 0.1: the explicit surface
            pressure feeds back through the surface faces (1/theta).
    """

    normal_stress: bool = False
    form: str = "stress"

    def __post_init__(self) -> None:
        if self.form not in VISCOSITY_FORMS:
            raise ValueError(
                f"ViscosityStressFree.form = {self.form!r}: must be one of {VISCOSITY_FORMS}")

    def surface_pressure(self, solver: FluidSolver, state: FluidState, level_set: FloatArray,
                         out: FloatArray) -> None:
        """The pressure the surface holds [Pa] into ``out`` (nx, ny), from ``state``'s
        velocity: ``2 mu du_n/dn`` at the liquid cells next to air, 0 elsewhere."""
        if not self.normal_stress or solver.viscosity == 0.0:
            out[...] = 0.0
            return
        kernels.surface_normal_stress(state.velocity_x, state.velocity_y, level_set,
                                      solver.grid.h, solver.density * solver.viscosity, out)

    def diffuse(self, solver: FluidSolver, state: FluidState, level_set: FloatArray,
                dt: float, workspace: FreeSurfaceWorkspace) -> int:
        """Diffuse the liquid's velocity over ``dt`` [s]; air faces keep their values.
        Returns the iterations of the two solves."""
        if solver.viscosity == 0.0:
            return 0
        grid = solver.grid
        c = solver.viscosity * dt / grid.h ** 2
        u, v = state.velocity_x, state.velocity_y
        left, right, bottom, top = solver.boundaries.sides()
        if self.form == "stress":
            w_cell, w_node, mass_u, mass_v, scratch = workspace.stress_arrays(grid)
            kernels.stress_viscosity_weights(
                level_set, grid.h, _wall_factor(left) / 2, _wall_factor(right) / 2,
                _wall_factor(bottom) / 2, _wall_factor(top) / 2, STRESS_MASS_FLOOR,
                w_cell, w_node, mass_u, mass_v)
            walls = np.array([_wall_velocity(side) for side in (left, right, bottom, top)])
            return int(kernels.solve_stress_viscosity(
                u, v, w_cell, w_node, mass_u, mass_v, c, walls, STRESS_RTOL,
                STRESS_MAX_ITERATIONS, scratch))
        kernels.mark_liquid_faces(level_set, workspace.valid_u, workspace.valid_v)
        ghost_u, ghost_v = workspace.ghosts
        kernels.stress_free_ghosts(u, v, workspace.valid_u, workspace.valid_v, ghost_u, ghost_v)
        iterations = 0
        for field_values, valid, ghost, axis, low, high, arrays in (
                (u, workspace.valid_u, ghost_u, 0, bottom, top, workspace.viscosity_u),
                (v, workspace.valid_v, ghost_v, 1, left, right, workspace.viscosity_v)):
            diagonal, weights_x, weights_y, rhs = arrays
            kernels.build_liquid_viscosity(
                field_values, valid, ghost, c, axis, _wall_factor(low), _wall_factor(high),
                _wall_velocity(low), _wall_velocity(high), diagonal, weights_x, weights_y, rhs)
            operator = Operator5Point(diagonal, weights_x, weights_y)
            solution, report = solver.viscosity_solver.solve(operator, rhs, x0=field_values)
            np.copyto(field_values, solution, where=diagonal > 0.0)
            iterations += int(report.iterations)
        return iterations


# The variational viscosity's solve: the floor of a face's mass where a strain sample with
# liquid reads a face with (almost) none, so that the system stays definite (such a face
# follows the strain, as a stress-free ghost would); CG tolerance and iteration cap.
STRESS_MASS_FLOOR = 1e-3
STRESS_RTOL = 1e-8
STRESS_MAX_ITERATIONS = 2000


def _wall_factor(side: object) -> float:
    """2 for a wall that holds the tangential velocity (the ghost reflects), 0 for free slip."""
    return 0.0 if isinstance(side, WallFreeSlip) else 2.0


def _wall_velocity(side: object) -> float:
    return float(side.velocity) if isinstance(side, WallMoving) else 0.0


class FreeSurfaceWorkspace:
    """Scratch arrays of a `FreeSurfaceSolver` on one grid (allocated once)."""

    def __init__(self, grid: Grid2D) -> None:
        nx, ny = grid.shape_cells
        self.operator_arrays = (np.zeros((nx, ny)), np.zeros((nx - 1, ny)),
                                np.zeros((nx, ny - 1)))
        self.rhs = np.zeros((nx, ny))
        self.no_values = np.zeros((1, 1))
        self.valid_u = np.zeros(grid.shape_faces_x, dtype=np.int32)
        self.valid_v = np.zeros(grid.shape_faces_y, dtype=np.int32)
        faces = max((nx + 1) * ny, nx * (ny + 1))
        # The breadth-first fronts of u's and v's extrapolation (`extrapolate_faces_pair`).
        self.frontier = np.zeros((4, faces, 2), dtype=np.int64)
        self.level_set = LevelSetWorkspace(grid)
        self.ghosts = (np.zeros(grid.shape_faces_x), np.zeros(grid.shape_faces_y))
        self.surface = np.zeros((nx, ny))
        self.viscosity_u, self.viscosity_v = (
            (np.zeros((m, n)), np.zeros((m - 1, n)), np.zeros((m, n - 1)), np.zeros((m, n)))
            for m, n in (grid.shape_faces_x, grid.shape_faces_y))
        # MacCormack's passes (`FreeSurfaceSolver.advect`), allocated on first use: the
        # forward results of u and v and the clamp's ranges (the lows take the results), and
        # the dye's semi-Lagrangian result.
        self.maccormack: tuple[FloatArray, ...] | None = None
        self.stress: tuple[FloatArray, FloatArray, FloatArray, FloatArray,
                           tuple[FloatArray, ...]] | None = None
        self.dye: FloatArray | None = None
        self.liquid_faces = (np.zeros(grid.shape_faces_x, dtype=np.int32),
                             np.zeros(grid.shape_faces_y, dtype=np.int32))
        # Per row of u and of v, the hull of the columns with a value other than 0 (low u,
        # high u, low v, high v; `nonzero_spans`).
        self.nonzero_spans = (np.zeros(nx + 1, dtype=np.int64), np.zeros(nx + 1, dtype=np.int64),
                              np.zeros(nx, dtype=np.int64), np.zeros(nx, dtype=np.int64))
        # The pressure solve's arrays on the liquid's box, per box shape (a few in a run).
        self.boxes: dict[tuple[int, int], tuple[FloatArray, ...]] = {}

    def box_arrays(self, m: int, n: int) -> tuple[FloatArray, ...]:
        """Diagonal (m, n), weights_x (m-1, n), weights_y (m, n-1), rhs and pressure (m, n)
        for a box of m x n cells (allocated once per shape)."""
        arrays = self.boxes.get((m, n))
        if arrays is None:
            arrays = (np.zeros((m, n)), np.zeros((m - 1, n)), np.zeros((m, n - 1)),
                      np.zeros((m, n)), np.zeros((m, n)))
            self.boxes[(m, n)] = arrays
        return arrays

    def stress_arrays(self, grid: Grid2D) -> tuple[FloatArray, FloatArray, FloatArray,
                                                    FloatArray, tuple[FloatArray, ...]]:
        """The variational viscosity's arrays (allocated once): cell and corner weights,
        face masses, and twelve scratch arrays (six per component) for its CG."""
        if self.stress is None:
            nx, ny = grid.shape_cells
            fx, fy = grid.shape_faces_x, grid.shape_faces_y
            self.stress = (np.zeros((nx, ny)), np.zeros((nx + 1, ny + 1)), np.zeros(fx),
                           np.zeros(fy), tuple(np.zeros(shape) for shape in (fx, fy) * 6))
        return self.stress

    def maccormack_arrays(self, grid: Grid2D) -> tuple[FloatArray, ...]:
        """MacCormack's forward u and v, and the clamp's ranges (low u, high u, low v, high v)
        (allocated once)."""
        if self.maccormack is None:
            fx, fy = grid.shape_faces_x, grid.shape_faces_y
            self.maccormack = tuple(np.zeros(shape) for shape in (fx, fy, fx, fx, fy, fy))
        return self.maccormack


@dataclass(frozen=True)
class FreeSurfaceStepReport:
    """What one free-surface step did.

    Attributes:
        pressure_iterations: Iterations of the pressure solve.
        pressure_residual: Its final relative residual.
        pressure_converged: Whether it reached its tolerance.
        viscosity_iterations: Iterations of the viscosity solves (0 if inviscid).
        liquid_cells: Cells with ``phi < 0`` after the step.
        seconds_by_phase: Wall time [s] of "level_set", "advection", "viscosity", "forces",
            "pressure", "extrapolation".
    """

    pressure_iterations: int
    pressure_residual: float
    pressure_converged: bool
    viscosity_iterations: int
    liquid_cells: int
    seconds_by_phase: dict[str, float] = field(default_factory=dict)


_WALLS = (WallNoSlip, WallFreeSlip, WallMoving)
MACCORMACK_FALLBACKS = ("walls_and_air", "walls", "none")
"""Choices of `FreeSurfaceSolver`'s ``maccormack_fallback``."""


class FreeSurfaceSolver:
    """A liquid with a free surface on the MAC grid: level set plus ghost-fluid projection.

    One step of ``dt`` (Enright et al. 2002's order, as in Bridson's book): the level set is
    carried by the velocity of the last step (`LevelSetTransport`: advection, redistancing,
    volume correction); then the fluid's own phases advect and diffuse the velocity over the
    whole grid (air included, where it holds the extrapolated field) and add gravity on the
    faces; `GhostFluidProjection` makes the liquid divergence-free with p = 0 on the new
    surface; the velocity is extrapolated from the liquid's faces into the air
    (``extrapolation_layers`` layers, the rest of the air set to 0).

    Guarantees: after `step`, every liquid cell's divergence is zero to the pressure solver's
    tolerance; with ``volume_correction`` the liquid area (`liquid_area`) equals the initial
    one to round-off.

    Args:
        fluid: The fluid solver whose density, viscosity, gravity, advection and viscosity
            schemes and pressure solver are used. Prefer ``advection="semi_lagrangian"``
            for splashing flows: with MacCormack the dam break's energy grew by 59 % by
            T = 7 (docs/validation/free_surface.md); small waves keep their amplitude with
            either. Its four sides must be walls (the air is a
            void; open sides are not supported yet) and it must not use the incremental
            pressure or BDF2 (they assume one pressure over the whole grid).
        projection: The free-surface pressure projection.
        transport: How the level set moves.
        viscosity: How viscosity acts: `ViscosityStressFree` (default; the full stress
            tensor on the liquid, zero viscous traction at the surface) or
            `ViscosityWholeGrid` (the fluid's own `diffuse` over the whole grid, air
            included).
        extrapolation_layers: Layers of faces the velocity is extended into the air; must
            exceed the CFL number of the step, since back-traces sample that far.
        maccormack_fallback: With the fluid's ``advection="maccormack"``, where the
            velocity's correction is dropped for the semi-Lagrangian value
            (`elastoflow.fluid._level_set_kernels.advect_faces_forward_range`):
            "walls_and_air" (default), at the faces whose samples read a domain side's
            ghost and at the faces in the air or whose forward sample reads an air face;
            "walls", at the first only; "none", nowhere: the fluid's own MacCormack step
            (`FluidSolver.advect`), which gains energy (kept for comparison;
            docs/validation/free_surface.md).
    """

    def __init__(
        self,
        fluid: FluidSolver,
        *,
        projection: GhostFluidProjection | None = None,
        transport: LevelSetTransport | None = None,
        viscosity: ViscosityWholeGrid | ViscosityStressFree | None = None,
        extrapolation_layers: int = 5,
        maccormack_fallback: str = "walls_and_air",
    ) -> None:
        if not isinstance(fluid, FluidSolver):
            raise ValueError(f"FreeSurfaceSolver fluid = {fluid!r}: must be a FluidSolver")
        for name, side in zip(("left", "right", "bottom", "top"), fluid.boundaries.sides()):
            if not isinstance(side, _WALLS):
                raise ValueError(
                    f"FreeSurfaceSolver: the fluid's {name} side is {side!r}; a free-surface "
                    "liquid needs walls on all four sides (open sides are not supported yet)"
                )
        if fluid.advection == "upwind3":
            raise ValueError(
                "FreeSurfaceSolver: the fluid's advection 'upwind3' is not available with a "
                "free surface (no air-side treatment); use 'semi_lagrangian' or 'maccormack'")
        if fluid.incremental_pressure or fluid.viscosity_scheme == "bdf2":
            raise ValueError(
                "FreeSurfaceSolver: the fluid's incremental_pressure and viscosity_scheme "
                "'bdf2' are not available with a free surface"
            )
        if fluid.jets:
            raise ValueError("FreeSurfaceSolver: jets are not supported with a free surface yet")
        if not isinstance(extrapolation_layers, int) or extrapolation_layers < 1:
            raise ValueError(
                f"FreeSurfaceSolver extrapolation_layers = {extrapolation_layers!r}: "
                "must be an int >= 1"
            )
        if maccormack_fallback not in MACCORMACK_FALLBACKS:
            raise ValueError(
                f"FreeSurfaceSolver maccormack_fallback = {maccormack_fallback!r}: must be one "
                f"of {MACCORMACK_FALLBACKS}"
            )
        self.maccormack_fallback = maccormack_fallback
        self.fluid = fluid
        self.grid = fluid.grid
        self.projection = projection if projection is not None else GhostFluidProjection()
        self.transport = transport if transport is not None else LevelSetTransport()
        self.viscosity = viscosity if viscosity is not None else ViscosityStressFree()
        self.extrapolation_layers = extrapolation_layers
        self.workspace = FreeSurfaceWorkspace(self.grid)

    def state(self, level_set: FloatArray) -> FreeSurfaceState:
        """Liquid at rest where ``level_set`` [m] < 0, with its velocity extrapolated (zero)
        and the hydrostatic pressure not yet computed (the first step's projection finds it)."""
        return FreeSurfaceState.create(self.grid, level_set)

    def pressure_operator(self, level_set: FloatArray) -> Operator5Point:
        """The ghost-fluid operator for ``level_set`` (fresh arrays; for tests)."""
        nx, ny = self.grid.shape_cells
        return self.projection.operator(
            level_set, (np.zeros((nx, ny)), np.zeros((nx - 1, ny)), np.zeros((nx, ny - 1))))

    def extrapolate_velocity(self, state: FreeSurfaceState, solved: bool = False) -> None:
        """Extend the velocity from the faces with liquid on a side into the air, in place.

        ``solved``: the workspace's marks are those of this state's last projection (else
        they are recomputed from the level set)."""
        workspace = self.workspace
        if not solved:
            kernels.mark_liquid_faces(state.level_set, workspace.valid_u, workspace.valid_v)
        layers = self.extrapolation_layers
        kernels.extrapolate_faces_pair(state.fluid.velocity_x, workspace.valid_u,
                                       state.fluid.velocity_y, workspace.valid_v, layers,
                                       workspace.frontier)

    def advect(self, state: FreeSurfaceState, dt: float, marked: bool = False) -> None:
        """Carry the velocity (and dye) by the velocity over ``dt`` [s], in place.

        With the fluid's semi-Lagrangian advection, or ``maccormack_fallback="none"``, this
        is `FluidSolver.advect`. Otherwise MacCormack with Selle's clamp, whose correction
        is dropped (the semi-Lagrangian value kept) where ``maccormack_fallback`` says
        (`advect_faces_forward_range`); air faces are those with no liquid on a side in
        ``state.level_set``, or with ``marked`` those `step` marked in
        ``workspace.liquid_faces`` before it moved the level set; the dye, if any, is
        carried semi-Lagrangian.
        """
        fluid = self.fluid
        if fluid.advection != "maccormack" or self.maccormack_fallback == "none":
            fluid.advect(state.fluid, dt)
            return
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"time step dt = {dt!r}: must be a finite number > 0")
        h = self.grid.h
        u, v = state.fluid.velocity_x, state.fluid.velocity_y
        forward_u, forward_v, low_u, high_u, low_v, high_v = self.workspace.maccormack_arrays(
            self.grid)
        ghosts = (fluid._modes_u, fluid._values_u, fluid._modes_v, fluid._values_v)
        air = self.maccormack_fallback == "walls_and_air"
        liquid_u, liquid_v = self.workspace.liquid_faces
        if air and not marked:
            kernels.mark_liquid_faces(state.level_set, liquid_u, liquid_v)
        # Two passes, one back-trace each (none backward where the correction is dropped,
        # none at all in still air); the results over the lows, copied once both components
        # are done: u and v are the advecting velocity of both.
        spans = self.workspace.nonzero_spans
        kernels.nonzero_spans(u, spans[0], spans[1])
        kernels.nonzero_spans(v, spans[2], spans[3])
        kernels.advect_faces_forward_range((u, v), 0, dt, h, ghosts, liquid_u, air,
                                           (forward_u, low_u, high_u), spans)
        kernels.advect_faces_forward_range((u, v), 1, dt, h, ghosts, liquid_v, air,
                                           (forward_v, low_v, high_v), spans)
        kernels.maccormack_faces_backward_correct((u, v), 0, dt, h, ghosts,
                                                  (forward_u, low_u, high_u), low_u)
        kernels.maccormack_faces_backward_correct((u, v), 1, dt, h, ghosts,
                                                  (forward_v, low_v, high_v), low_v)
        if fluid._carries_dye(state.fluid):
            if self.workspace.dye is None:
                self.workspace.dye = np.zeros(self.grid.shape_cells)
            # The fluid's advection kernel without bodies (the free surface has none yet).
            none = (fluid._no_solid, fluid._no_theta, fluid._no_cut)
            dye = state.fluid.dye
            fluid_kernels.advect(
                (u, v), dye, self.workspace.dye, fluid_kernels.FIELD_CELLS, dt, h, ghosts,
                False, (*none, *none, fluid._near_everywhere),
                (fluid._no_solid, fluid._no_values, fluid._modes_dye, fluid._values_dye),
                fluid_kernels.PASS_TRACE, (dye, fluid._no_values, fluid._no_values))
            fluid_kernels.copy_into(self.workspace.dye, dye)
        fluid_kernels.copy_into(low_u, u)
        fluid_kernels.copy_into(low_v, v)

    def stable_dt(self, state: FreeSurfaceState, cfl: float, dt_max: float) -> float:
        """``min(dt_max, cfl h / max|u|)`` [s] over the faces, and at most the time in which
        gravity alone would reach that speed from rest (``sqrt(cfl h / |g|)``)."""
        speed = max(float(np.max(np.abs(state.fluid.velocity_x))),
                    float(np.max(np.abs(state.fluid.velocity_y))))
        h = self.grid.h
        dt = float(dt_max)
        if speed > 0.0:
            dt = min(dt, cfl * h / speed)
        g = math.hypot(*self.fluid.gravity)
        if g > 0.0:
            dt = min(dt, math.sqrt(cfl * h / g))
        return dt

    def step(self, state: FreeSurfaceState, dt: float, time: float = 0.0) -> FreeSurfaceStepReport:
        """One step of ``dt`` [s] from ``time`` [s], in place."""
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"time step dt = {dt!r}: must be a finite number > 0")
        fluid, grid, workspace = self.fluid, self.grid, self.workspace
        clock = _time.perf_counter
        t0 = clock()
        # The liquid's faces before the level set moves: where the velocity is carried, not
        # extrapolated (the MacCormack fallback, `advect`).
        marked = self.fluid.advection == "maccormack" and self.maccormack_fallback == "walls_and_air"
        if marked:
            kernels.mark_liquid_faces(state.level_set, *workspace.liquid_faces)
        transport_level_set(
            self.transport, grid, state.level_set, state.fluid.velocity_x,
            state.fluid.velocity_y, dt, state.step_index, state.liquid_area,
            workspace.level_set,
        )
        # The viscous surface's normal stress from the velocity the level set moved with.
        self.viscosity.surface_pressure(fluid, state.fluid, state.level_set, workspace.surface)
        t1 = clock()
        self.advect(state, dt, marked=marked)
        t2 = clock()
        viscosity_iterations = self.viscosity.diffuse(fluid, state.fluid, state.level_set, dt,
                                                      workspace)
        t3 = clock()
        fluid.apply_forces(state.fluid, dt, time)
        t4 = clock()
        report = self.projection.project(fluid, state.fluid, state.level_set, dt, workspace)
        t5 = clock()
        self.extrapolate_velocity(state, solved=True)
        t6 = clock()
        state.step_index += 1
        return FreeSurfaceStepReport(
            pressure_iterations=int(report.iterations),
            pressure_residual=float(report.residual),
            pressure_converged=bool(report.converged),
            viscosity_iterations=int(viscosity_iterations),
            liquid_cells=int(np.count_nonzero(state.level_set < 0.0)),
            seconds_by_phase={"level_set": t1 - t0, "advection": t2 - t1,
                              "viscosity": t3 - t2, "forces": t4 - t3, "pressure": t5 - t4,
                              "extrapolation": t6 - t5},
        )

    def divergence(self, state: FreeSurfaceState) -> FloatArray:
        """Cell divergence [1/s] of the velocity, 0 in the air cells, shape (nx, ny)."""
        out = np.empty(self.grid.shape_cells)
        fluid_kernels.divergence(state.fluid.velocity_x, state.fluid.velocity_y, self.grid.h,
                                 False, self.workspace.no_values, self.workspace.no_values, out)
        out[state.level_set >= 0.0] = 0.0
        return out
