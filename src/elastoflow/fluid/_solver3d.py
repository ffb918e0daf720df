"""Incompressible Navier-Stokes on the 3D MAC grid: the phases of one step, acting on a
`FluidState3D`."""

from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from elastoflow.fluid import _kernels as fluid_kernels
from elastoflow.fluid import _kernels3d as kernels
from elastoflow.fluid._boundaries import Inflow, Outflow, WallNoSlip
from elastoflow.fluid._boundaries3d import (
    DomainBoundaries3D,
    Jet3D,
    WallMoving3D,
    inflow_profile_3d,
)
from elastoflow.fluid._interior3d import InteriorBoundary3D
from elastoflow.fluid._solver import CoupledBodies, FluidStepReport
from elastoflow.fluid._state3d import FluidState3D
from elastoflow.grid import Grid3D
from elastoflow.linalg import Operator7Point, PoissonSolverMGPCG3D, SolveReport

Array = NDArray[np.float64]
_ADVECTION_SCHEMES = ("semi_lagrangian", "maccormack")
# Where the point [i, j, k] of each field sits, in cells: u, v, w, then cell fields.
_OFFSETS = ((0.0, 0.5, 0.5), (0.5, 0.0, 0.5), (0.5, 0.5, 0.0), (0.5, 0.5, 0.5))


@dataclass(frozen=True)
class _InflowSide:
    """An inflow side's normal velocity at full ramp, signed along its axis, on its face
    plane (shape of the component's array without its own axis)."""

    side: int
    inflow: Inflow
    velocity: Array


Box = tuple[slice, slice, slice]


def _index_box(grid: Grid3D, region: tuple[float, ...], offsets: tuple[float, float, float],
               shape: tuple[int, int, int]) -> Box:
    """Index ranges of the points ``(i + ox, j + oy, k + oz) h`` inside ``region``
    (``(x0, y0, z0, x1, y1, z1)`` [m], boundary included) of an array of ``shape``."""
    ranges = []
    for axis in range(3):
        low = (region[axis] - grid.origin[axis]) / grid.h - offsets[axis]
        high = (region[axis + 3] - grid.origin[axis]) / grid.h - offsets[axis]
        start = max(math.ceil(low - 1e-12), 0)
        stop = min(math.floor(high + 1e-12) + 1, shape[axis])
        ranges.append(slice(start, max(start, stop)))
    return (ranges[0], ranges[1], ranges[2])


def _bodies_region(last: tuple[int, ...], box: tuple[int, ...]) -> NDArray[np.int64]:
    """The index box (``(i0, j0, k0, i1, j1, k1)``, ends exclusive) covering two
    `InteriorBoundary3D` boxes (empty ones left out) widened by one point: a point's
    viscosity row reads its neighbours' solid flags and cut distances."""
    boxes = [b for b in (last, box) if all(b[a + 3] > b[a] for a in range(3))]
    if not boxes:
        return np.zeros(6, dtype=np.int64)
    start = [min(b[a] for b in boxes) - 1 for a in range(3)]
    stop = [max(b[a + 3] for b in boxes) + 1 for a in range(3)]
    return np.array([*start, *stop], dtype=np.int64)


def _check_finite_positive(name: str, value: float) -> float:
    if not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0.0:
        raise ValueError(f"FluidSolver3D {name} = {value!r}: must be a finite number > 0")
    return float(value)


def _check_dt(dt: float) -> None:
    if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0.0):
        raise ValueError(f"time step dt = {dt!r}: must be a finite number > 0")


def _side_plane(array: Array, side: int, inside: bool = False) -> Array:
    """The plane of ``array`` on ``side`` (a view), or the one just inside it."""
    axis, high = divmod(side, 2)
    index = (-2 if inside else -1) if high else (1 if inside else 0)
    return array[(slice(None),) * axis + (index,)]


class FluidSolver3D:
    """Incompressible Navier-Stokes on the 3D MAC grid by stable fluids (METHOD.md §3).

    The model (grid, density, viscosity, sides, gravity) and the numerical choices live
    here; the fields live in a `FluidState3D` that the phases update in place. One step is:
    advect (semi-Lagrangian, midpoint back-trace, trilinear sampling with side ghosts;
    or MacCormack), apply forces (gravity, side values), diffuse (implicit, one 7-point
    solve per velocity component), project (7-point pressure Poisson equation).

    Bodies enter every phase through an `InteriorBoundary3D` (``interior=``; None: no
    bodies), as in 2D (METHOD.md §5-6): open face fractions weight the pressure equation,
    points inside bodies hold the body velocity, cut distances give the no-slip ghosts of
    the viscosity and the advection.

    Guarantees: after `project`, the divergence ``h * div u`` of every cell is zero up to the
    pressure solver's tolerance relative to its value before (for a closed box, when the
    side fluxes balance); wall and inflow sides keep their normal velocity.

    Args:
        grid: The MAC grid.
        density: Fluid density rho [kg/m^3], > 0.
        viscosity: Kinematic viscosity nu [m^2/s], >= 0 (0 skips the viscosity solves).
        boundaries: The condition on each of the six sides.
        gravity: Gravitational acceleration (gx, gy, gz) [m/s^2].
        jets: Boxes with prescribed velocity and dye, applied every step.
        buoyancy: Upward (+y) acceleration per unit dye [m/s^2] (None or 0: passive dye).
        pressure_solver: Solver of the pressure equation (`PoissonSolverMGPCG3D(rtol=1e-6)`
            by default); any object with ``solve(operator, rhs, x0=None, out=None)``.
        viscosity_solver: Solver of the viscosity systems (same default).
        advection: "semi_lagrangian" (first order in time per step, diffusive) or
            "maccormack" (forward and backward semi-Lagrangian steps with Selle et al.'s
            clamped correction, second order in smooth regions).
        incremental_pressure: True (the default in 3D): `diffuse` first subtracts the last
            pressure gradient and `project` solves for the increment (pressure-correction
            form). With the forces applied before the viscosity, this keeps both a fluid at
            rest under gravity exactly at rest (the last pressure already balances the force,
            so the viscosity sees no velocity at the walls) and a steady force-driven flow
            exactly on the discrete steady state (the square duct). False: the paper's
            projection of the whole pressure, as the 2D solver's default; then a fluid at
            rest under gravity next to no-slip walls gets currents of order nu dt g / h.
    """

    # The fields `advect` writes every value of (from a ``source`` state, none read).
    ADVECTED_FIELDS = ("velocity_x", "velocity_y", "velocity_z", "dye")

    def __init__(
        self,
        grid: Grid3D,
        *,
        density: float,
        viscosity: float,
        boundaries: DomainBoundaries3D,
        gravity: tuple[float, float, float] = (0.0, 0.0, 0.0),
        jets: tuple[Jet3D, ...] | list[Jet3D] = (),
        buoyancy: float | None = None,
        pressure_solver: PoissonSolverMGPCG3D | None = None,
        viscosity_solver: PoissonSolverMGPCG3D | None = None,
        advection: str = "semi_lagrangian",
        incremental_pressure: bool = True,
    ) -> None:
        if not isinstance(grid, Grid3D):
            raise ValueError(f"FluidSolver3D grid = {grid!r}: must be an elastoflow.grid.Grid3D")
        self.grid = grid
        self.density = _check_finite_positive("density", density)
        if not isinstance(viscosity, (int, float)) or not math.isfinite(viscosity) or viscosity < 0:
            raise ValueError(
                f"FluidSolver3D viscosity = {viscosity!r}: must be a finite number >= 0")
        self.viscosity = float(viscosity)
        if not isinstance(boundaries, DomainBoundaries3D):
            raise ValueError(
                f"FluidSolver3D boundaries = {boundaries!r}: must be a DomainBoundaries3D")
        self.boundaries = boundaries
        try:
            gx, gy, gz = (float(c) for c in gravity)
        except (TypeError, ValueError):
            raise ValueError(
                f"FluidSolver3D gravity = {gravity!r}: must be three finite numbers") from None
        if not all(math.isfinite(c) for c in (gx, gy, gz)):
            raise ValueError(f"FluidSolver3D gravity = {gravity!r}: must be three finite numbers")
        self.gravity = (gx, gy, gz)
        jets = tuple(jets)
        for jet in jets:
            if not isinstance(jet, Jet3D):
                raise ValueError(f"FluidSolver3D jets entry {jet!r}: must be a Jet3D")
        self.jets = jets
        if buoyancy is not None and (
                not isinstance(buoyancy, (int, float)) or not math.isfinite(buoyancy)):
            raise ValueError(
                f"FluidSolver3D buoyancy = {buoyancy!r}: must be None or a finite number")
        self.buoyancy = 0.0 if buoyancy is None else float(buoyancy)
        if advection not in _ADVECTION_SCHEMES:
            raise ValueError(
                f"FluidSolver3D advection = {advection!r}: must be one of {_ADVECTION_SCHEMES}")
        self.advection = advection
        if not isinstance(incremental_pressure, bool):
            raise ValueError(f"FluidSolver3D incremental_pressure = {incremental_pressure!r}: "
                             "must be True or False")
        self.incremental_pressure = incremental_pressure
        self.pressure_solver = pressure_solver or PoissonSolverMGPCG3D(rtol=1e-6)
        self.viscosity_solver = viscosity_solver or PoissonSolverMGPCG3D(rtol=1e-6)
        for name, solver in (("pressure_solver", self.pressure_solver),
                             ("viscosity_solver", self.viscosity_solver)):
            if not callable(getattr(solver, "solve", None)):
                raise ValueError(f"FluidSolver3D {name} = {solver!r}: must have a solve method")
        self._setup_sides()
        shapes = (grid.shape_faces_x, grid.shape_faces_y, grid.shape_faces_z, grid.shape_cells)
        # Per jet, the index box of u, v, w and the cells inside its region.
        self._jet_boxes = [tuple(_index_box(grid, jet.region, offsets, shape)
                                 for offsets, shape in zip(_OFFSETS, shapes, strict=True))
                           for jet in jets]
        self._allocate()

    # -- set-up ------------------------------------------------------------------------------

    def _setup_sides(self) -> None:
        grid = self.grid
        sides = self.boundaries.sides()
        self._outflow = np.array([isinstance(s, Outflow) for s in sides], dtype=np.bool_)
        # Tangential velocity beyond a side: held at the wall's velocity by a wall (0 unless
        # it moves) or an inflow (its velocity is normal), copied from inside (zero gradient)
        # by free slip and outflow.
        tangential = np.array(
            [kernels.GHOST_DIRICHLET if isinstance(s, (WallNoSlip, WallMoving3D, Inflow))
             else kernels.GHOST_COPY for s in sides], dtype=np.int64)
        self._tangential_modes = tangential
        # Each velocity component samples with the tangential ghosts on the four sides along
        # the other axes; along its own axis its samples stay within the stored faces.
        self._velocity_modes = np.tile(tangential, (3, 1))
        for axis in range(3):
            self._velocity_modes[axis, 2 * axis:2 * axis + 2] = kernels.GHOST_COPY
        # (3, 6): component, side; a moving wall's component along the side.
        self._velocity_values = np.zeros((3, 6))
        for index, side in enumerate(sides):
            if isinstance(side, WallMoving3D):
                for axis in range(3):
                    if axis != index // 2:
                        self._velocity_values[axis, index] = float(side.velocity[axis])
        # (1, 6): the kernels read one row of a ghost table.
        self._dye_modes = np.array(
            [[kernels.GHOST_VALUE if isinstance(s, Inflow) else kernels.GHOST_COPY
              for s in sides]], dtype=np.int64)
        self._dye_values = np.array([[s.dye if isinstance(s, Inflow) else 0.0 for s in sides]])
        self._inflows: list[_InflowSide] = []
        lengths = (grid.lx, grid.ly, grid.lz)
        counts = grid.shape_cells
        for index, side in enumerate(sides):
            if not isinstance(side, Inflow):
                continue
            axis, high = divmod(index, 2)
            first, second = (a for a in range(3) if a != axis)
            s = (np.arange(counts[first]) + 0.5) * grid.h / lengths[first]
            t = (np.arange(counts[second]) + 0.5) * grid.h / lengths[second]
            profile = inflow_profile_3d(side, s[:, None], t[None, :])
            self._inflows.append(_InflowSide(index, side, (-1.0 if high else 1.0) * profile))

    def _allocate(self) -> None:
        grid = self.grid
        shapes = (grid.shape_faces_x, grid.shape_faces_y, grid.shape_faces_z, grid.shape_cells)
        # The fields at the start of the phase: advection reads them while writing the state.
        self._sources = tuple(np.zeros(shape) for shape in shapes)
        if self.advection == "maccormack":
            self._forward = tuple(np.zeros(shape) for shape in shapes)
            self._backward = tuple(np.zeros(shape) for shape in shapes)
        self._rhs_pressure = np.zeros(grid.shape_cells)
        self._pressure_increment = np.zeros(grid.shape_cells)
        self._pressure_operator: Operator7Point | None = None
        self._viscosity_operators: dict[tuple[int, float], Operator7Point] = {}
        self._viscosity_rhs = tuple(np.zeros(shape) for shape in shapes[:3])
        # Per component, the last viscosity operator with bodies: (c, its arrays, the
        # interior's box), rewritten around the bodies only while c stays.
        self._viscosity_bodies: list[tuple[float, tuple[Array, Array, Array, Array],
                                           tuple[int, ...] | None] | None] = [None] * 3
        # With bodies: the face velocities u_s, and the last weighted pressure operator with
        # the open fractions it was built from (kept while they do not change).
        self._solid_velocity: tuple[Array, Array, Array] = (
            np.zeros(shapes[0]), np.zeros(shapes[1]), np.zeros(shapes[2]))
        self._bodies_operator: Operator7Point | None = None
        self._bodies_fractions: tuple[Array, ...] = ()
        # Stand-ins for the body arrays when there are no bodies (never read then).
        no_solid = np.zeros((1, 1, 1), dtype=np.bool_)
        no_theta = np.full((6, 1, 1, 1), np.inf)
        no_cut = np.zeros((6, 1, 1, 1))
        no_values = np.zeros((1, 1, 1))
        self._no_body = (no_solid, no_theta, no_cut)
        self._no_own = (no_solid, no_theta, no_cut, no_values)
        self._no_bodies = ((no_solid,) * 3, (no_theta,) * 3, (no_cut,) * 3,
                           kernels.NO_BODIES_BOXES)
        self._no_faces = (no_values,) * 3
        self._no_operator = (no_values,) * 4

    def rest_state(self) -> FluidState3D:
        """Fluid at rest with the pressure [Pa] that balances gravity (hydrostatic in a
        closed box), no dye: the state to start from when gravity is on.

        Started from zero pressure instead, the first step's viscosity meets the whole
        ``dt g`` at the no-slip walls before the pressure balances it, which leaves currents
        of order ``nu dt g / h`` (3e-4 m/s for water in a 10 cm box at dt = 10 ms,
        tests/unit/fluid/test_fluid3d.py) that only viscosity then removes.
        """
        state = FluidState3D.zeros(self.grid)
        if any(g != 0.0 for g in self.gravity):
            # The pressure of one projection of the velocity g * (1 s) is the balancing one.
            incremental, self.incremental_pressure = self.incremental_pressure, False
            try:
                self.apply_forces(state, 1.0, -1.0)
                self.project(state, 1.0)
            finally:
                self.incremental_pressure = incremental
            for field in state.velocity():
                field[...] = 0.0
        return state

    # -- operators ---------------------------------------------------------------------------

    def pressure_operator(self, interior: InteriorBoundary3D | None = None) -> Operator7Point:
        """The operator ``A p = -h^2 div(A grad p)`` of the pressure equation: unit weights
        without bodies (assembled once), the faces' open fractions with them (kept while the
        fractions do not change, so that the solver keeps its multigrid levels)."""
        if interior is not None:
            return self._pressure_operator_bodies(interior)
        if self._pressure_operator is None:
            grid = self.grid
            self._pressure_operator = self._assemble_pressure_operator(
                (np.ones(grid.shape_faces_x), np.ones(grid.shape_faces_y),
                 np.ones(grid.shape_faces_z)))
        return self._pressure_operator

    def _assemble_pressure_operator(self, fractions: tuple[Array, Array, Array]
                                    ) -> Operator7Point:
        nx, ny, nz = self.grid.shape_cells
        operator = (np.empty((nx, ny, nz)), np.empty((nx - 1, ny, nz)),
                    np.empty((nx, ny - 1, nz)), np.empty((nx, ny, nz - 1)))
        kernels.build_pressure_operator_3d(fractions, self._outflow, operator)
        return Operator7Point.assembled(*operator)

    def _pressure_operator_bodies(self, interior: InteriorBoundary3D) -> Operator7Point:
        fractions = (interior.open_fraction_x, interior.open_fraction_y,
                     interior.open_fraction_z)
        if self._bodies_operator is None:
            self._bodies_fractions = tuple(fraction.copy() for fraction in fractions)
        else:
            # Every array is brought up to date, whether or not an earlier one differed.
            changed = [kernels.update_into_3d(new, old)
                       for new, old in zip(fractions, self._bodies_fractions, strict=True)]
            if not any(changed):
                return self._bodies_operator
        self._bodies_operator = self._assemble_pressure_operator(fractions)
        return self._bodies_operator

    def _solid_face_velocities(self, interior: InteriorBoundary3D) -> tuple[Array, Array, Array]:
        """Body velocity u_s on the faces that are not fully open (buffers, overwritten)."""
        for axis, out in enumerate(self._solid_velocity):
            kernels.face_solid_velocity_3d(
                interior.solid_faces(axis), interior.velocity_faces(axis),
                interior.open_fraction(axis), interior.cut_theta(axis),
                interior.cut_velocity(axis), axis, out)
        u, v, w = self._solid_velocity
        return u, v, w

    def _subtract_gradient(self, state: FluidState3D, pressure: Array, dt: float,
                           interior: InteriorBoundary3D | None) -> None:
        """``u -= dt / rho grad p``; with bodies closed faces take u_s (in the buffers)."""
        scale = dt / (self.density * self.grid.h)
        has_interior, fractions, solid_velocity = self._face_arrays(interior)
        kernels.subtract_pressure_gradient_3d(state.velocity(), pressure, scale, self._outflow,
                                              has_interior, fractions, solid_velocity)

    def _face_arrays(self, interior: InteriorBoundary3D | None
                     ) -> tuple[bool, tuple[Array, Array, Array], tuple[Array, Array, Array]]:
        """``(has_interior, open fractions, u_s)`` for the pressure kernels (stand-ins without
        bodies; u_s: the buffers `_solid_face_velocities` fills)."""
        if interior is None:
            return False, self._no_faces, self._no_faces
        return (True, (interior.open_fraction_x, interior.open_fraction_y,
                       interior.open_fraction_z), self._solid_velocity)

    def _fixed_ends(self, axis: int) -> tuple[bool, bool]:
        """Whether the boundary faces of component ``axis`` are held (not outflow)."""
        return (not bool(self._outflow[2 * axis]), not bool(self._outflow[2 * axis + 1]))

    def viscosity_system(self, field: Array, axis: int, dt: float,
                         interior: InteriorBoundary3D | None = None
                         ) -> tuple[Operator7Point, Array]:
        """``(I - nu dt lap)`` for component ``axis`` (0 u, 1 v, 2 w) and its right-hand
        side for the values ``field``; without bodies the operator depends on dt only and is
        kept. With bodies, points inside them are held and the cut distances give the
        no-slip ghosts (METHOD.md §6); the operator's arrays are then those of the last call
        with bodies, rewritten only around the bodies (``interior.box``, this call's and the
        last one's) when ``c`` is the same: the last operator returned changes with them."""
        c = self.viscosity * dt / self.grid.h**2
        fixed_low, fixed_high = self._fixed_ends(axis)
        sides = (fixed_low, fixed_high, self._tangential_modes, self._velocity_values[axis])
        rhs = self._viscosity_rhs[axis]
        region = kernels.WHOLE_REGION
        m, n, l = field.shape
        if interior is None:
            has_interior, body = False, self._no_body
            operator = self._viscosity_operators.get((axis, dt))
            if operator is not None:
                kernels.build_viscosity_system_3d(field, c, axis, sides, False, body, False,
                                                  self._no_operator, rhs, region)
                return operator, rhs
            arrays = (np.empty((m, n, l)), np.empty((m - 1, n, l)), np.empty((m, n - 1, l)),
                      np.empty((m, n, l - 1)))
        else:
            has_interior = True
            body = (interior.solid_faces(axis), interior.cut_theta(axis),
                    interior.cut_velocity(axis))
            kept = self._viscosity_bodies[axis]
            if (kept is not None and kept[0] == c and kept[2] is not None
                    and interior.box is not None):
                arrays = kept[1]
                region = _bodies_region(kept[2], interior.box)
            else:
                arrays = (np.empty((m, n, l)), np.empty((m - 1, n, l)),
                          np.empty((m, n - 1, l)), np.empty((m, n, l - 1)))
            self._viscosity_bodies[axis] = (c, arrays, interior.box)
        kernels.build_viscosity_system_3d(field, c, axis, sides, has_interior, body, True,
                                          arrays, rhs, region)
        operator = Operator7Point.assembled(*arrays)
        if interior is not None:
            return operator, rhs
        # One dt at a time in practice; a changing dt must not grow the cache without end.
        if len(self._viscosity_operators) >= 6:
            self._viscosity_operators.clear()
        self._viscosity_operators[(axis, dt)] = operator
        return operator, rhs

    # -- phases ------------------------------------------------------------------------------

    def _check(self, state: FluidState3D, dt: float,
               interior: InteriorBoundary3D | None = None) -> None:
        _check_dt(dt)
        if not isinstance(state, FluidState3D):
            raise ValueError(f"state = {state!r}: must be a FluidState3D")
        state.check(self.grid)
        if interior is not None:
            if not isinstance(interior, InteriorBoundary3D):
                raise ValueError(f"interior = {interior!r}: must be an InteriorBoundary3D")
            interior.check(self.grid)

    def advect(self, state: FluidState3D, dt: float,
               interior: InteriorBoundary3D | None = None,
               source: FluidState3D | None = None) -> None:
        """Transport velocity and dye by the current velocity over ``dt`` [s], in place, or
        from ``source`` into ``state``.

        With bodies (``interior``): velocity points inside them take the body velocity, dye
        there 0; samples whose corners lie inside a body use cut-distance ghosts (velocity)
        or the fluid corners only (dye), in the trace as in the transported field.

        Args:
            source: The state whose velocity and dye are transported (read only); every
                value of ``state``'s velocity and dye is then written, none read. None:
                ``state`` itself (copied to buffers first).
        """
        self._check(state, dt, interior)
        if source is None or source is state:
            source = None
        elif not isinstance(source, FluidState3D):
            raise ValueError(f"source = {source!r}: must be a FluidState3D")
        else:
            source.check(self.grid)
        before_dye = state.dye if source is None else source.dye
        # Dye that is 0 everywhere, with no inflow bringing any, stays 0: a quarter of the
        # advection saved in scenes and benchmarks without dye (as `FluidSolver` does).
        dye = bool(np.any(self._dye_values) or fluid_kernels.any_nonzero(before_dye))
        fields = (*state.velocity(), state.dye) if dye else state.velocity()
        if source is None:
            for field, buffer in zip(fields, self._sources, strict=False):
                kernels.copy_into_3d(field, buffer)
            sources = self._sources
        else:
            sources = (*source.velocity(), source.dye)
            if not dye:
                kernels.copy_into_3d(source.dye, state.dye)
        velocity = sources[:3]
        h = self.grid.h
        if interior is None:
            bodies = self._no_bodies
        else:
            # Where the solid points are: samples whose cell misses the box read no solid
            # flag. Only the interior's own box can hold one (0.2 -> ~0.01 ms an array at
            # 64^3 with the bar).
            boxes = np.empty((4, 6), dtype=np.int64)
            region = (kernels.WHOLE_REGION if interior.box is None
                      else np.array(interior.box, dtype=np.int64))
            for index, solid in enumerate((interior.solid_faces_x, interior.solid_faces_y,
                                           interior.solid_faces_z, interior.solid_cells)):
                kernels.solid_box(solid, boxes[index], region)
            bodies = ((interior.solid_faces_x, interior.solid_faces_y, interior.solid_faces_z),
                      (interior.cut_theta_x, interior.cut_theta_y, interior.cut_theta_z),
                      (interior.cut_velocity_x, interior.cut_velocity_y,
                       interior.cut_velocity_z), boxes)
        for index, (field, before) in enumerate(zip(fields, sources[:len(fields)],
                                                    strict=True)):
            is_dye = index == kernels.FIELD_CELLS
            if is_dye:
                modes, values = self._dye_modes, self._dye_values
            else:
                modes = self._velocity_modes[index:index + 1]
                values = self._velocity_values[index:index + 1]
            if interior is None:
                own = self._no_own
            elif is_dye:
                # Dye reads no cut distances: the velocity's stand in.
                own = (interior.solid_cells, interior.cut_theta_x, interior.cut_velocity_x,
                       field)
            else:
                own = (interior.solid_faces(index), interior.cut_theta(index),
                       interior.cut_velocity(index), interior.velocity_faces(index))
            ghosts = (self._velocity_modes, self._velocity_values, modes, values)
            common = (index, dt, h, ghosts, interior is not None, bodies, own)
            if self.advection == "semi_lagrangian":
                kernels.advect_3d(velocity, before, field, (before, before), *common,
                                  kernels.PASS_TRACE)
                continue
            forward, backward = self._forward[index], self._backward[index]
            kernels.advect_3d(velocity, before, forward, (before, before), *common,
                              kernels.PASS_TRACE)
            backwards = (index, -dt, *common[2:])
            kernels.advect_3d(velocity, forward, backward, (before, before), *backwards,
                              kernels.PASS_TRACE)
            kernels.advect_3d(velocity, before, field, (forward, backward), *common,
                              kernels.PASS_CORRECT)

    def diffuse(self, state: FluidState3D, dt: float,
                interior: InteriorBoundary3D | None = None) -> int:
        """Implicit viscosity ``(I - nu dt lap) u = u*`` for the three components, in place.

        Wall and inflow sides hold their normal velocity; tangential conditions enter through
        ghosts (no slip: the mirror, zero at the wall; free slip and outflow: zero gradient).
        With bodies, points inside them are held at the body velocity and the cut distances
        give the no-slip ghosts at the body's surface. With ``incremental_pressure`` the last
        pressure gradient is subtracted first.

        Returns:
            Iterations of the three solves together.
        """
        self._check(state, dt, interior)
        if interior is not None:
            for axis, field in enumerate(state.velocity()):
                solid = interior.solid_faces(axis)
                np.copyto(field, interior.velocity_faces(axis), where=solid)
                # The forces came first (3D order): points inside bodies take this step's
                # gravity too, as the 2D order (viscosity, then forces) gives them. Otherwise
                # the fluid part of a face whose point lies in a body misses g dt: the
                # projection then bends the hydrostatic pressure at the surface (a stiff
                # neutrally buoyant cube sank at 3.5 mm/s after one step) and the viscosity
                # sees a jump of g dt at the wall.
                if self.gravity[axis] != 0.0:
                    np.add(field, self.gravity[axis] * dt, out=field, where=solid)
            self._solid_face_velocities(interior)
        if self.incremental_pressure:
            self._subtract_gradient(state, state.pressure, dt, interior)
        if self.viscosity == 0.0:
            return 0
        iterations = 0
        for axis, field in enumerate(state.velocity()):
            operator, rhs = self.viscosity_system(field, axis, dt, interior)
            _, report = self.viscosity_solver.solve(operator, rhs, x0=field, out=field)
            iterations += int(report.iterations)
        return iterations

    def apply_forces(self, state: FluidState3D, dt: float, time: float) -> None:
        """Gravity and dye buoyancy over ``dt`` [s], jets, and the side values at
        ``time + dt`` [s], in place."""
        _check_dt(dt)
        for field, g in zip(state.velocity(), self.gravity, strict=True):
            if g != 0.0:
                kernels.add_constant_3d(field, g * dt)
        if self.buoyancy != 0.0:
            kernels.add_buoyancy_3d(state.velocity_y, state.dye, self.buoyancy * dt)
        fields = (*state.velocity(), state.dye)
        for jet, boxes in zip(self.jets, self._jet_boxes, strict=True):
            values = (*jet.velocity, jet.dye)
            for field, box, value in zip(fields, boxes, values, strict=True):
                field[box] = value
        self.apply_side_values(state, time + dt)

    def apply_side_values(self, state: FluidState3D, time: float) -> None:
        """Set the normal velocity on the six sides at ``time`` [s]: 0 on walls, the ramped
        profile on inflow sides, the adjacent interior face's value on outflow sides (zero
        normal gradient)."""
        velocity = state.velocity()
        for side in range(6):
            field = velocity[side // 2]
            target = _side_plane(field, side)
            if self._outflow[side]:
                target[...] = _side_plane(field, side, inside=True)
            else:
                target[...] = 0.0
        for inflow in self._inflows:
            target = _side_plane(velocity[inflow.side // 2], inflow.side)
            np.multiply(inflow.velocity, inflow.inflow.ramp(time), out=target)

    def project(self, state: FluidState3D, dt: float,
                interior: InteriorBoundary3D | None = None,
                bodies: CoupledBodies | None = None) -> SolveReport:
        """Make the velocity divergence-free: ``lap q = (rho / dt) div u*``,
        ``u = u* - (dt / rho) grad q``. ``q`` is the pressure [Pa], kept in
        ``state.pressure`` (the previous one is the initial guess), or with
        ``incremental_pressure`` its increment, added to ``state.pressure``.

        With bodies the faces are weighted by their open fraction A (Batty et al. 2007):
        ``div(A grad q) = (rho / dt) div(A u* + (1 - A) u_s)``; faces open by less than 1 %
        count as closed and take the body velocity u_s. Guarantee: ``div(A u + (1 - A)
        u_s)`` (`divergence` with ``interior``) vanishes to the solver's tolerance.

        With ``bodies`` the projection is strongly coupled, as `FluidSolver.project`'s: the
        bodies' velocities are unknowns of the same solve (their inertia enters the operator,
        `CoupledBodies`), the pressure's force moves them, and the faces they cover take
        their new velocity. With ``incremental_pressure`` the bodies answer the increment:
        their prediction must hold the last pressure's force."""
        self._check(state, dt, interior)
        if bodies is not None:
            return self._project_coupled(state, dt, interior, bodies)
        if interior is not None:
            self._solid_face_velocities(interior)
        kernels.pressure_rhs_3d(state.velocity(), self.density * self.grid.h / dt,
                                *self._face_arrays(interior), self._rhs_pressure)
        operator = self.pressure_operator(interior)
        if self.incremental_pressure:
            increment = self._pressure_increment
            _, report = self.pressure_solver.solve(operator, self._rhs_pressure, out=increment)
            self._subtract_gradient(state, increment, dt, interior)
            state.pressure += increment
            return report
        _, report = self.pressure_solver.solve(operator, self._rhs_pressure,
                                               x0=state.pressure, out=state.pressure)
        self._subtract_gradient(state, state.pressure, dt, interior)
        return report

    def _project_coupled(self, state: FluidState3D, dt: float,
                         interior: InteriorBoundary3D | None,
                         bodies: CoupledBodies) -> SolveReport:
        if interior is None:
            raise ValueError("a strongly coupled projection needs the bodies' "
                             "InteriorBoundary3D")
        solve_coupled = getattr(self.pressure_solver, "solve_coupled", None)
        if solve_coupled is None:
            raise ValueError(
                f"pressure_solver = {self.pressure_solver!r}: the strongly coupled projection "
                "needs a solver with solve_coupled (PoissonSolverMGPCG3D)")
        operator = self.pressure_operator(interior)
        # The cells the pressure equation has: a diagonal term or an open face.
        active = operator.diagonal > 0.0
        for axis, weights in enumerate((operator.weights_x, operator.weights_y,
                                        operator.weights_z)):
            connected = weights > 0.0
            low = [slice(None)] * 3
            high = [slice(None)] * 3
            low[axis], high[axis] = slice(None, -1), slice(1, None)
            active[tuple(low)] |= connected
            active[tuple(high)] |= connected
        # The bodies' part of the flux balance is theirs: u_s = 0 in the fluid's own terms.
        for solid in self._solid_velocity:
            solid[...] = 0.0
        has_interior, fractions, solid_velocity = self._face_arrays(interior)
        scale = self.density * self.grid.h / dt
        kernels.pressure_rhs_3d(state.velocity(), scale, has_interior, fractions,
                                solid_velocity, self._rhs_pressure)
        bodies.add_to_rhs(self._rhs_pressure, scale, active)
        term = bodies.coupling_term(active)
        # With incremental_pressure the bodies' prediction holds the last pressure's force
        # (the caller's part, as `diffuse` subtracted its gradient from the fluid's): the
        # solve is for the increment, from 0.
        if self.incremental_pressure:
            target = self._pressure_increment
            _, report = solve_coupled(operator, term, self._rhs_pressure, out=target)
        else:
            target = state.pressure
            _, report = solve_coupled(operator, term, self._rhs_pressure, x0=state.pressure,
                                      out=target)
        bodies.respond(target, active, *self._solid_velocity)
        kernels.subtract_pressure_gradient_3d(state.velocity(), target,
                                              dt / (self.density * self.grid.h),
                                              self._outflow, has_interior, fractions,
                                              solid_velocity)
        if self.incremental_pressure:
            state.pressure += target
        return report

    def step(self, state: FluidState3D, dt: float, time: float = 0.0,
             interior: InteriorBoundary3D | None = None) -> FluidStepReport:
        """Advect, apply forces, diffuse and project: one step of ``dt`` [s] from ``time``,
        with the bodies of ``interior`` (None: none).

        Forces come before the implicit viscosity (the 2D solver applies them after it): a
        body force is then balanced by the viscous term of the same solve, so a steady
        force-driven flow is the discrete steady state itself, not offset by ``dt g`` (the
        square duct, docs/validation/three_d.md); and the viscosity sees this step's side
        values on the faces it holds."""
        clock = _time.perf_counter
        t0 = clock()
        self.advect(state, dt, interior)
        t1 = clock()
        self.apply_forces(state, dt, time)
        t2 = clock()
        viscosity_iterations = self.diffuse(state, dt, interior)
        t3 = clock()
        report = self.project(state, dt, interior)
        t4 = clock()
        return FluidStepReport(
            pressure_iterations=int(report.iterations),
            pressure_residual=float(report.residual),
            pressure_converged=bool(report.converged),
            viscosity_iterations=viscosity_iterations,
            seconds_by_phase={"advection": t1 - t0, "forces": t2 - t1,
                              "viscosity": t3 - t2, "pressure": t4 - t3},
        )

    def divergence(self, state: FluidState3D,
                   interior: InteriorBoundary3D | None = None) -> Array:
        """Cell divergence [1/s] of the state's velocity, shape (nx, ny, nz); with bodies
        ``div(A u + (1 - A) u_s)``, the flux through each face's fluid part plus the body's
        through the rest: what `project` makes vanish."""
        state.check(self.grid)
        out = np.empty(self.grid.shape_cells)
        if interior is not None:
            interior.check(self.grid)
            self._solid_face_velocities(interior)
        # The pressure equation's right-hand side with scale -1 / h is the divergence.
        kernels.pressure_rhs_3d(state.velocity(), -1.0 / self.grid.h,
                                *self._face_arrays(interior), out)
        return out
