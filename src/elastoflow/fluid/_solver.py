from __future__ import annotations

import inspect
import math
import time as _time
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from elastoflow.fluid import _flux_kernels as flux_kernels
from elastoflow.fluid import _kernels as kernels
from elastoflow.fluid._boundaries import (
    DomainBoundaries,
    Inflow,
    Jet,
    Outflow,
    WallMoving,
    WallNoSlip,
)
from elastoflow.fluid._interior import InteriorBoundary
from elastoflow.fluid._state import FluidState
from elastoflow.grid import Grid2D
from elastoflow.linalg import (
    LowRankTerm,
    Operator5Point,
    PoissonSolverMGPCG,
    SolveReport,
    apply_operator,
)

_ADVECTION_SCHEMES = ("semi_lagrangian", "maccormack", "upwind3")
_ADVECTING_VELOCITIES = ("current", "extrapolated")
_VISCOSITY_SCHEMES = ("backward_euler", "crank_nicolson", "bdf2")
# Cells into the bodies that the incremental form's pressure is extended to after each step.
_PRESSURE_EXTENSION_LAYERS = 2
_PRESSURE_GUESSES = ("previous", "extrapolated")


class CoupledBodies(Protocol):
    """Bodies whose inertia the pressure solve sees (the strongly coupled projection).

    The body side of the projection's flux balance, ``(1 - A) u_s`` on every face a body
    covers, is a linear function of the bodies' velocities; the pressure pushes back on the
    bodies through the transpose of that function. The fluid only needs three things:
    """

    def add_to_rhs(self, rhs: np.ndarray, scale: float, active: np.ndarray) -> None:
        """``rhs -= scale * (net body outflow of each active cell)`` for the predicted body
        velocities (the ``(1 - A) u_s`` terms of ``pressure_rhs``)."""
        ...

    def coupling_term(self, active: np.ndarray) -> LowRankTerm:
        """The bodies' term of the pressure operator (symmetric, positive semi-definite)."""
        ...

    def respond(self, pressure: np.ndarray, active: np.ndarray, *closed: np.ndarray) -> None:
        """Apply ``pressure``'s force to the bodies; write the new body velocity into the
        arrays of u / v (/ w in 3D) faces that the fluid treats as closed."""
        ...


@dataclass(frozen=True)
class FluidStepReport:
    """What one fluid step did.

    Attributes:
        pressure_iterations: Iterations of the pressure solve.
        pressure_residual: Final relative residual of the pressure solve.
        pressure_converged: Whether the pressure solve reached its tolerance.
        viscosity_iterations: Iterations of the two viscosity solves together (0 if inviscid).
        seconds_by_phase: Wall time [s] of "advection", "viscosity", "forces", "pressure".
    """

    pressure_iterations: int
    pressure_residual: float
    pressure_converged: bool
    viscosity_iterations: int
    seconds_by_phase: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class FluidPrediction:
    """What `FluidSolver.predict` did.

    Attributes:
        projection_dt: The time step [s] the projection must take: the step's dt, or
            ``2 dt / 3`` on a BDF2 step.
        viscosity_iterations: Iterations of the two viscosity solves together.
        seconds_by_phase: Wall time [s] of "advection", "viscosity", "forces".
    """

    projection_dt: float
    viscosity_iterations: int
    seconds_by_phase: dict[str, float] = field(default_factory=dict)


def _check_positive(name: str, value: Any) -> float:
    if not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0.0:
        raise ValueError(f"FluidSolver {name} = {value!r}: must be a finite number > 0")
    return float(value)


def _takes_out(solver: Any) -> bool:
    try:
        return "out" in inspect.signature(solver.solve).parameters
    except (TypeError, ValueError):
        return False


def _writable_into(array: np.ndarray) -> bool:
    return array.dtype == np.float64 and array.flags.c_contiguous and array.flags.writeable


class FluidSolver:
    """Incompressible Navier–Stokes on the MAC grid by stable fluids (METHOD.md §3, §6).

    One step is: advect (semi-Lagrangian, midpoint back-trace, bilinear sampling), diffuse
    (implicit, one 5-point solve per velocity component), apply forces (gravity, dye buoyancy,
    jets, side values), project (pressure Poisson equation with open-fraction face weights).

    Guarantees: after `project`, the open-fraction-weighted divergence
    ``div(A u + (1 - A) u_s)`` of every cell is zero up to the pressure solver's tolerance
    (relative to the divergence before the projection), for every connected fluid region that
    has an outflow side or whose boundary fluxes balance; velocity points inside bodies hold the
    body velocity.

    Args:
        grid: The MAC grid.
        density: Fluid density rho [kg/m^3], > 0.
        viscosity: Kinematic viscosity nu [m^2/s], >= 0 (0 skips the viscosity solves).
        boundaries: The condition on each side of the domain.
        jets: Regions with prescribed velocity and dye, applied every step.
        gravity: Gravitational acceleration (gx, gy) [m/s^2].
        buoyancy: Upward acceleration per unit dye [m/s^2] (None or 0: passive dye).
        pressure_solver: Solver of the pressure Poisson equation.
        viscosity_solver: Solver of the implicit viscosity equations.
        advection: "semi_lagrangian" (first-order in time per step, diffusive),
            "maccormack" (semi-Lagrangian forward and backward with Selle et al.'s clamped
            correction, second order in smooth regions) or "upwind3" (flux form: the
            velocity's momentum fluxes by third-order upwind-biased interpolation, carried
            by the frozen advecting velocity, three-stage SSP Runge-Kutta in time, sub-steps
            above an advective CFL sum of 1.2; `_flux_kernels`). With "upwind3" the dye is
            still carried by the plain semi-Lagrangian step.
        incremental_pressure: False (the paper's scheme): the projection solves for the whole
            pressure. True: `diffuse` already subtracts the previous pressure gradient and the
            projection solves for the increment (pressure-correction form), which removes the
            O(dt) error of the plain splitting at viscous walls in steady flow. It also makes the
            pre-projection velocity already feel most of the pressure, so the paper's
            momentum-exchange force (evaluated before the projection) becomes small. With
            the strongly coupled projection the bodies' prediction must hold the previous
            pressure's force (`elastoflow.simulation.MonolithicCoupling` does): the coupled
            solve is for the increment and answers the bodies with its force.
        maccormack_limiter: True (default): MacCormack's corrected value is clamped to the
            range of the four samples around its departure point (no new extrema). False
            leaves it unclamped: for studies of what the limiter costs in accuracy (on DFG
            2D-2 nothing measurable, docs/method_notes.md item 10); the unlimited scheme can
            oscillate at steep fronts.
        advecting_velocity: The velocity the back-trace follows. "current" (the paper's):
            u^n, which makes the departure point's error O(dt^2) per step, first order in
            time. "extrapolated": u^{n+1/2} ~ u^n + dt_n / (2 dt_{n-1}) (u^n - u^{n-1})
            (the two-time-level extrapolation of semi-Lagrangian weather codes, Staniforth &
            Cote 1991), second order; the field transported is still u^n. The state keeps
            the start-of-step velocity for this (`FluidState.previous_velocity_x`); the first
            step, and a restart from a checkpoint without it, trace with u^n.
        viscosity_scheme: "backward_euler" (the paper's): ``(I - nu dt L) u = u*``, first
            order. "crank_nicolson": ``(I - nu dt L / 2) u = (I + nu dt L / 2) u*`` with the
            same cut-distance and wall stencils in both halves, second order.
            "bdf2": the whole step by BDF2 along trajectories (Xiu & Karniadakis 2001), in
            `step` only: ``u = (4 u^n(x_d) - u^{n-1}(x_dd)) / 3``, then viscosity, forces and
            projection over ``2 dt / 3``, so that the pressure and viscous forces are
            second order along the trajectory too (Crank-Nicolson at the arrival point
            leaves the pressure's backward Euler). ``x_dd`` is traced over 2 dt with u^n
            (the midpoint of that trajectory). The first step, a restart without the previous
            velocity and a step whose dt differs from the last fall back to backward Euler.
            In `step` and in `predict` (which the coupling schemes call, then project over
            its ``projection_dt``); the separate phases `advect`, `diffuse` and `project`
            stay first order.
        pressure_guess: Where the pressure solve starts. "previous" (the paper's): the last
            pressure. "extrapolated": ``p + dt / dt_p (p - p_previous)``, linear in time from
            the last two (the state keeps the one before, `FluidState.previous_pressure`);
            the answer is the same to the solver's tolerance, reached in fewer iterations
            where the pressure changes smoothly (Turek-Hron FSI3 at 20 cells per diameter:
            initial residual 3.7e-3 -> 4.7e-4 of the right-hand side, 9 -> 4 iterations).
            The first projection, a restart without it and the incremental form start from
            the last pressure.
    """

    def __init__(
        self,
        grid: Grid2D,
        *,
        density: float,
        viscosity: float,
        boundaries: DomainBoundaries,
        jets: tuple[Jet, ...] | list[Jet] = (),
        gravity: tuple[float, float] = (0.0, 0.0),
        buoyancy: float | None = None,
        pressure_solver: Any = None,
        viscosity_solver: Any = None,
        advection: str = "semi_lagrangian",
        incremental_pressure: bool = False,
        maccormack_limiter: bool = True,
        advecting_velocity: str = "current",
        viscosity_scheme: str = "backward_euler",
        pressure_guess: str = "previous",
    ) -> None:
        if not isinstance(grid, Grid2D):
            raise ValueError(f"FluidSolver grid = {grid!r}: must be an elastoflow.grid.Grid2D")
        self.grid = grid
        self.density = _check_positive("density", density)
        if not isinstance(viscosity, (int, float)) or not math.isfinite(viscosity) or viscosity < 0:
            raise ValueError(f"FluidSolver viscosity = {viscosity!r}: must be a finite number >= 0")
        self.viscosity = float(viscosity)
        if not isinstance(boundaries, DomainBoundaries):
            raise ValueError(
                f"FluidSolver boundaries = {boundaries!r}: must be a DomainBoundaries"
            )
        self.boundaries = boundaries
        jets = tuple(jets)
        for jet in jets:
            if not isinstance(jet, Jet):
                raise ValueError(f"FluidSolver jets entry {jet!r}: must be a Jet")
        self.jets = jets
        try:
            gx, gy = (float(c) for c in gravity)
        except (TypeError, ValueError):
            raise ValueError(
                f"FluidSolver gravity = {gravity!r}: must be two finite numbers (gx, gy)"
            ) from None
        if not (math.isfinite(gx) and math.isfinite(gy)):
            raise ValueError(f"FluidSolver gravity = {gravity!r}: must be two finite numbers")
        self.gravity = (gx, gy)
        if buoyancy is not None and (
            not isinstance(buoyancy, (int, float)) or not math.isfinite(buoyancy)
        ):
            raise ValueError(f"FluidSolver buoyancy = {buoyancy!r}: must be None or a finite number")
        self.buoyancy = 0.0 if buoyancy is None else float(buoyancy)
        if pressure_solver is None:
            pressure_solver = PoissonSolverMGPCG(rtol=1e-6)
        if viscosity_solver is None:
            viscosity_solver = PoissonSolverMGPCG(rtol=1e-6)
        for name, solver in (("pressure_solver", pressure_solver),
                             ("viscosity_solver", viscosity_solver)):
            if not callable(getattr(solver, "solve", None)):
                raise ValueError(
                    f"FluidSolver {name} = {solver!r}: must have a solve(operator, rhs, x0) method"
                )
        self.pressure_solver = pressure_solver
        self.viscosity_solver = viscosity_solver
        # Solvers that can write the solution into a given array spare a copy and a fresh
        # allocation (page faults on large grids) per solve.
        self._pressure_out = _takes_out(pressure_solver)
        self._viscosity_out = _takes_out(viscosity_solver)
        if advection not in _ADVECTION_SCHEMES:
            raise ValueError(
                f"FluidSolver advection = {advection!r}: must be one of {_ADVECTION_SCHEMES}"
            )
        self.advection = advection
        if not isinstance(maccormack_limiter, bool):
            raise ValueError(
                f"FluidSolver maccormack_limiter = {maccormack_limiter!r}: must be True or False"
            )
        self.maccormack_limiter = maccormack_limiter
        if not isinstance(incremental_pressure, bool):
            raise ValueError(
                f"FluidSolver incremental_pressure = {incremental_pressure!r}: must be True or False"
            )
        self.incremental_pressure = incremental_pressure
        if advecting_velocity not in _ADVECTING_VELOCITIES:
            raise ValueError(
                f"FluidSolver advecting_velocity = {advecting_velocity!r}: must be one of "
                f"{_ADVECTING_VELOCITIES}"
            )
        self.advecting_velocity = advecting_velocity
        if viscosity_scheme not in _VISCOSITY_SCHEMES:
            raise ValueError(
                f"FluidSolver viscosity_scheme = {viscosity_scheme!r}: must be one of "
                f"{_VISCOSITY_SCHEMES}"
            )
        self.viscosity_scheme = viscosity_scheme
        if pressure_guess not in _PRESSURE_GUESSES:
            raise ValueError(
                f"FluidSolver pressure_guess = {pressure_guess!r}: must be one of "
                f"{_PRESSURE_GUESSES}"
            )
        self.pressure_guess = pressure_guess
        self._setup_sides()
        self._setup_jets()
        self._allocate()

    # -- set-up ------------------------------------------------------------------------------

    def _setup_sides(self) -> None:
        grid = self.grid
        sides = self.boundaries.sides()
        tangential_modes = np.zeros(4, dtype=np.int64)
        tangential_values = np.zeros(4)
        dye_modes = np.zeros(4, dtype=np.int64)
        dye_values = np.zeros(4)
        outflow = np.zeros(4, dtype=np.bool_)
        for index, side in enumerate(sides):
            if isinstance(side, (WallNoSlip, Inflow)):
                tangential_modes[index] = 1
            elif isinstance(side, WallMoving):
                tangential_modes[index] = 1
                tangential_values[index] = side.velocity
            if isinstance(side, Inflow):
                dye_modes[index] = 2
                dye_values[index] = side.dye
            outflow[index] = isinstance(side, Outflow)
        # u samples need ghosts only beyond bottom and top, v only beyond left and right.
        self._modes_u = np.array([0, 0, tangential_modes[2], tangential_modes[3]], dtype=np.int64)
        self._values_u = np.array([0.0, 0.0, tangential_values[2], tangential_values[3]])
        self._modes_v = np.array([tangential_modes[0], tangential_modes[1], 0, 0], dtype=np.int64)
        self._values_v = np.array([tangential_values[0], tangential_values[1], 0.0, 0.0])
        self._modes_dye = dye_modes
        self._values_dye = dye_values
        self._outflow = outflow
        self._tangential_u = (self._modes_u[2:].copy(), self._values_u[2:].copy())
        self._tangential_v = (self._modes_v[:2].copy(), self._values_v[:2].copy())
        # Full-speed normal velocity into the domain on each inflow side, signed along the axis.
        self._inflow_profiles: list[tuple[int, Inflow, np.ndarray]] = []
        for index, side in enumerate(sides):
            if isinstance(side, Inflow):
                if index < 2:
                    s = (np.arange(grid.ny) + 0.5) * grid.h
                    profile = side.profile_values(s, grid.ly)
                else:
                    s = (np.arange(grid.nx) + 0.5) * grid.h
                    profile = side.profile_values(s, grid.lx)
                sign = 1.0 if index in (0, 2) else -1.0
                self._inflow_profiles.append((index, side, sign * profile))

    def _setup_jets(self) -> None:
        grid = self.grid
        h, ox, oy = grid.h, grid.origin[0], grid.origin[1]
        self._jet_slices = []
        for jet in self.jets:
            x0, y0, x1, y1 = (float(c) for c in jet.region)

            def index_range(low: float, high: float, offset: float, count: int) -> slice:
                start = max(math.ceil(low / h - offset - 1e-12), 0)
                stop = min(math.floor(high / h - offset + 1e-12) + 1, count)
                return slice(start, max(start, stop))

            u_slice = (index_range(x0 - ox, x1 - ox, 0.0, grid.nx + 1),
                       index_range(y0 - oy, y1 - oy, 0.5, grid.ny))
            v_slice = (index_range(x0 - ox, x1 - ox, 0.5, grid.nx),
                       index_range(y0 - oy, y1 - oy, 0.0, grid.ny + 1))
            cell_slice = (index_range(x0 - ox, x1 - ox, 0.5, grid.nx),
                          index_range(y0 - oy, y1 - oy, 0.5, grid.ny))
            self._jet_slices.append((jet, u_slice, v_slice, cell_slice))

    def _allocate(self) -> None:
        grid = self.grid
        fx, fy, c = grid.shape_faces_x, grid.shape_faces_y, grid.shape_cells
        self._buffer_u = np.zeros(fx)
        self._buffer_v = np.zeros(fy)
        self._buffer_dye = np.zeros(c)
        # MacCormack's clamp ranges (low, high per field), kept by its first pass; its second
        # pass writes the result over the lows. Semi-Lagrangian advection needs neither.
        if self.advection == "maccormack":
            self._ranges = tuple(np.zeros(shape) for shape in (fx, fx, fy, fy, c, c))
        else:
            self._ranges = (np.zeros((1, 1)),) * 6
        # The flux form's two intermediate Runge-Kutta stages per component.
        if self.advection == "upwind3":
            self._flux_buffers = tuple((np.zeros(shape), np.zeros(shape)) for shape in (fx, fy))
        # The extrapolated advecting velocity, and A u* of the explicit Crank-Nicolson half.
        if self.advecting_velocity == "extrapolated":
            self._advecting = (np.zeros(fx), np.zeros(fy))
        if self.viscosity_scheme == "bdf2":
            self._two_steps_back = (np.zeros(fx), np.zeros(fy))
        if self.viscosity_scheme == "crank_nicolson":
            self._explicit_half = (np.zeros(fx), np.zeros(fy))
        self._rhs_pressure = np.zeros(c)
        self._solid_u = np.zeros(fx)
        self._solid_v = np.zeros(fy)
        # Stand-ins for the interior arrays when there are no bodies (never read then).
        self._no_solid = np.zeros((1, 1), dtype=np.bool_)
        self._no_theta = np.full((4, 1, 1), np.inf)
        self._no_values = np.zeros((1, 1))
        self._no_cut = np.zeros((4, 1, 1))
        # Stencil blocks that may meet a body (`kernels.near_regions`): all when bodies may be
        # anywhere, else marked from ``InteriorBoundary.regions``.
        self._near = np.empty((grid.nx + 2, grid.ny + 2), dtype=np.bool_)
        self._near_everywhere = np.ones((grid.nx + 2, grid.ny + 2), dtype=np.bool_)
        self._pressure_buffers: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        # Assembled on first use: with bodies the operator is assembled every step instead.
        self._pressure_operator_open: Operator5Point | None = None
        self._viscosity_operators: dict[tuple[int, float], Operator5Point] = {}
        self._viscosity_scratch = []
        for shape in (fx, fy):
            m, n = shape
            self._viscosity_scratch.append(
                (np.zeros(shape), np.zeros((m - 1, n)), np.zeros((m, n - 1)), np.zeros(shape))
            )

    def _assemble_pressure_operator(
        self, open_x: np.ndarray, open_y: np.ndarray, reuse: bool = False
    ) -> Operator5Point:
        """The pressure operator for these open fractions; ``reuse`` assembles it into the
        solver's own buffers (for `project`, whose solver recognises a changed operator by
        comparing values, not arrays), sparing three grid-sized allocations per step."""
        nx, ny = self.grid.shape_cells
        if reuse:
            if self._pressure_buffers is None:
                self._pressure_buffers = (np.empty((nx, ny)), np.empty((nx - 1, ny)),
                                          np.empty((nx, ny - 1)))
            diagonal, weights_x, weights_y = self._pressure_buffers
        else:
            diagonal = np.empty((nx, ny))
            weights_x = np.empty((nx - 1, ny))
            weights_y = np.empty((nx, ny - 1))
        kernels.build_pressure_operator(
            open_x, open_y, self._outflow, diagonal, weights_x, weights_y
        )
        return Operator5Point(diagonal, weights_x, weights_y)

    def pressure_operator(self, interior: InteriorBoundary | None = None) -> Operator5Point:
        """The operator ``A p = -h^2 div(A grad p)`` of the pressure equation (for tests)."""
        if interior is None:
            return self._open_pressure_operator()
        return self._assemble_pressure_operator(interior.open_fraction_x, interior.open_fraction_y)

    def _open_pressure_operator(self) -> Operator5Point:
        if self._pressure_operator_open is None:
            grid = self.grid
            self._pressure_operator_open = self._assemble_pressure_operator(
                np.ones(grid.shape_faces_x), np.ones(grid.shape_faces_y))
        return self._pressure_operator_open

    # -- phases ------------------------------------------------------------------------------

    def _interior_arrays(self, interior: InteriorBoundary | None, axis: int) -> tuple:
        if interior is None:
            return (False, self._no_solid, self._no_theta, self._no_cut, self._no_values)
        if axis == 0:
            return (True, interior.solid_faces_x, interior.cut_theta_x, interior.cut_velocity_x,
                    interior.velocity_faces_x)
        return (True, interior.solid_faces_y, interior.cut_theta_y, interior.cut_velocity_y,
                interior.velocity_faces_y)

    def _near_regions(self, interior: InteriorBoundary | None) -> np.ndarray:
        if interior is None or interior.regions is None:
            return self._near_everywhere
        kernels.near_regions(np.ascontiguousarray(interior.regions), self._near)
        return self._near

    def _check_step_input(
        self, state: FluidState, dt: float, interior: InteriorBoundary | None
    ) -> None:
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"time step dt = {dt!r}: must be a finite number > 0")
        if not isinstance(state, FluidState):
            raise ValueError(f"state = {state!r}: must be a FluidState")
        state.check(self.grid)
        if interior is not None:
            interior.check(self.grid)

    def _advect_once(
        self, state: FluidState, sources: tuple[np.ndarray, np.ndarray, np.ndarray],
        outs: tuple[np.ndarray, np.ndarray, np.ndarray], dt: float,
        interior: InteriorBoundary | None, velocity: tuple[np.ndarray, np.ndarray],
        pass_kind: int = kernels.PASS_TRACE, forwards: tuple[np.ndarray, ...] | None = None,
        dye: bool = True, only_dye: bool = False,
    ) -> None:
        h = self.grid.h
        has, solid_x, theta_x, cut_x, body_x = self._interior_arrays(interior, 0)
        _, solid_y, theta_y, cut_y, body_y = self._interior_arrays(interior, 1)
        forwards = forwards if forwards is not None else sources
        bodies = (solid_x, theta_x, cut_x, solid_y, theta_y, cut_y,
                  self._near_regions(interior))
        ghosts = (self._modes_u, self._values_u, self._modes_v, self._values_v)
        ranges = self._ranges
        solid_cells = interior.solid_cells if interior is not None else self._no_solid
        owns = ((solid_x, body_x, self._modes_u, self._values_u),
                (solid_y, body_y, self._modes_v, self._values_v),
                (solid_cells, self._no_values, self._modes_dye, self._values_dye))
        fields = (kernels.FIELD_X, kernels.FIELD_Y, kernels.FIELD_CELLS)
        for index in range(2 if only_dye else 0, 3 if dye else 2):
            kernels.advect(velocity, sources[index], outs[index], fields[index], dt, h, ghosts,
                           has, bodies, owns[index], pass_kind,
                           (forwards[index], ranges[2 * index], ranges[2 * index + 1]))

    def advect(
        self, state: FluidState, dt: float, interior: InteriorBoundary | None = None
    ) -> None:
        """Transport velocity and dye by the current velocity over ``dt`` [s], in place.

        Midpoint back-trace, bilinear sampling with side ghosts; with bodies, corners across a
        body boundary are replaced by cut-distance ghosts (METHOD.md §6), velocity points
        inside bodies take the body velocity and dye does not enter bodies. With
        ``advection="maccormack"`` the semi-Lagrangian result is corrected by the error of a
        backward step and clamped to the local range at the departure point (Selle et al.
        2008). With ``advection="upwind3"`` the velocity is transported in flux form instead
        (`FluidSolver`'s ``advection``).
        """
        self._check_step_input(state, dt, interior)
        fields = (state.velocity_x, state.velocity_y, state.dye)
        velocity = self._advecting_velocity(state, dt)
        dye = self._carries_dye(state)
        result = self._transport(state, fields, velocity, dt, interior, dye=dye)
        for source, target in zip(result if dye else result[:2], fields):
            kernels.copy_into(source, target)

    def _carries_dye(self, state: FluidState) -> bool:
        """Whether advection can change the dye: not when there is none and no inflow brings
        any (then it stays exactly 0; a third of MacCormack's advection saved in scenes
        without dye, such as the benchmarks')."""
        return bool(np.any(self._values_dye) or kernels.any_nonzero(state.dye))

    def _transport(
        self, state: FluidState, fields: tuple[np.ndarray, np.ndarray, np.ndarray],
        velocity: tuple[np.ndarray, np.ndarray], dt: float, interior: InteriorBoundary | None,
        dye: bool = True,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``fields`` carried by ``velocity`` over ``dt``, into the solver's buffers (the
        third, the dye, only with ``dye``)."""
        forward = (self._buffer_u, self._buffer_v, self._buffer_dye)
        if self.advection == "upwind3":
            self._transport_flux(fields, velocity, dt, interior)
            if dye:
                self._advect_once(state, fields, forward, dt, interior, velocity, only_dye=True)
            return forward
        if self.advection == "maccormack":
            # Two passes, one back-trace each: forward with the clamp's ranges, then backward
            # and corrected (`PASS_TRACE_RANGE`, `PASS_CORRECT`), written over the lows.
            limited = self.maccormack_limiter
            self._advect_once(state, fields, forward, dt, interior, velocity,
                              kernels.PASS_TRACE_RANGE if limited else kernels.PASS_TRACE,
                              dye=dye)
            ranges = self._ranges
            result = (ranges[0], ranges[2], ranges[4])
            self._advect_once(
                state, fields, result, -dt, interior, velocity,
                kernels.PASS_CORRECT if limited else kernels.PASS_CORRECT_UNCLAMPED,
                forwards=forward, dye=dye)
        else:
            self._advect_once(state, fields, forward, dt, interior, velocity, dye=dye)
            result = forward
        return result

    def _transport_flux(
        self, fields: tuple[np.ndarray, np.ndarray, np.ndarray],
        velocity: tuple[np.ndarray, np.ndarray], dt: float, interior: InteriorBoundary | None,
    ) -> None:
        """The velocity components of ``fields`` carried by the frozen ``velocity`` over
        ``dt`` in flux form (three-stage SSP Runge-Kutta, in equal sub-steps of an advective
        CFL number of at most `flux_kernels.CFL_LIMIT`), into ``_buffer_u`` / ``_buffer_v``."""
        h = self.grid.h
        ghosts = (self._modes_u, self._values_u, self._modes_v, self._values_v)
        speed = (flux_kernels.largest_magnitude(velocity[0])
                 + flux_kernels.largest_magnitude(velocity[1]))
        substeps = max(1, math.ceil(abs(dt) * speed / (h * flux_kernels.CFL_LIMIT)))
        sub_dt = dt / substeps
        outs = (self._buffer_u, self._buffer_v)
        near = self._near_regions(interior)
        for axis in range(2):
            has, solid, theta, cut, body_velocity = self._interior_arrays(interior, axis)
            first, second = self._flux_buffers[axis]
            body = (solid, theta, cut, body_velocity, near)
            start, out = fields[axis], outs[axis]
            for _ in range(substeps):
                # Shu & Osher's stages: u1 = u + dt L(u), u2 = 3/4 u + 1/4 (u1 + dt L(u1)),
                # u_next = 1/3 u + 2/3 (u2 + dt L(u2)); the advecting velocity stays fixed.
                for stage, weight, target in ((start, 0.0, first), (first, 0.75, second),
                                              (second, 1.0 / 3.0, out)):
                    flux_kernels.runge_kutta_stage(velocity, stage, start, target, axis,
                                                   sub_dt, weight, h, ghosts, has, body)
                start = out

    def _advecting_velocity(
        self, state: FluidState, dt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """The velocity of the back-trace; with "extrapolated" also keeps u^n in the state.

        The extrapolation runs over every face: faces inside bodies hold the body velocity
        at both levels (extrapolated body motion), and the kernels do not read them anyway
        (samples across a body boundary use the cut velocities). Side faces extrapolate the
        inflow ramp to mid-step, as they should.
        """
        current = (state.velocity_x, state.velocity_y)
        if self.advecting_velocity == "current" and self.viscosity_scheme != "bdf2":
            return current
        previous_x, previous_y = state.previous_velocity_x, state.previous_velocity_y
        previous_dt = state.previous_dt
        state.previous_dt = float(dt)
        if previous_x is None or previous_y is None or previous_dt is None:
            state.previous_velocity_x = state.velocity_x.copy()
            state.previous_velocity_y = state.velocity_y.copy()
            return current
        if self.advecting_velocity == "current":
            kernels.copy_into(current[0], previous_x)
            kernels.copy_into(current[1], previous_y)
            return current
        ratio = 0.5 * dt / previous_dt
        kernels.extrapolate_and_keep(current[0], previous_x, ratio, self._advecting[0])
        kernels.extrapolate_and_keep(current[1], previous_y, ratio, self._advecting[1])
        return self._advecting

    def _bdf2_history(
        self, state: FluidState, dt: float, interior: InteriorBoundary | None
    ) -> bool:
        """u^{n-1} carried over 2 dt by u^n into ``_two_steps_back``; False (nothing done)
        when BDF2 does not apply to this step."""
        previous_x, previous_y = state.previous_velocity_x, state.previous_velocity_y
        if (self.viscosity_scheme != "bdf2" or previous_x is None or previous_y is None
                or state.previous_dt != dt):
            return False
        # BDF2 concerns the velocity: the dye keeps its one transport over dt.
        result = self._transport(state, (previous_x, previous_y, state.dye),
                                 (state.velocity_x, state.velocity_y), 2.0 * dt, interior,
                                 dye=False)
        kernels.copy_into(result[0], self._two_steps_back[0])
        kernels.copy_into(result[1], self._two_steps_back[1])
        return True

    def _viscosity_operator(
        self, f: np.ndarray, axis: int, dt: float, interior: InteriorBoundary | None
    ) -> tuple[Operator5Point, np.ndarray]:
        c = self.viscosity * dt / self.grid.h**2
        diagonal, weights_x, weights_y, rhs = self._viscosity_scratch[axis]
        has, solid, theta, cut, _ = self._interior_arrays(interior, axis)
        if axis == 0:
            fixed_low, fixed_high = not self._outflow[0], not self._outflow[1]
            modes, values = self._tangential_u
        else:
            fixed_low, fixed_high = not self._outflow[2], not self._outflow[3]
            modes, values = self._tangential_v
        # Without bodies the operator depends on dt only: keep it between steps.
        cached = self._viscosity_operators.get((axis, dt)) if interior is None else None
        kernels.build_viscosity_system(
            f, c, axis, (fixed_low, fixed_high, modes, values), has,
            (solid, theta, cut, self._near_regions(interior)), cached is None,
            (diagonal, weights_x, weights_y), rhs,
        )
        if interior is None:
            if cached is None:
                if len(self._viscosity_operators) > 8:
                    self._viscosity_operators.clear()
                cached = Operator5Point(diagonal.copy(), weights_x.copy(), weights_y.copy())
                self._viscosity_operators[(axis, dt)] = cached
            return cached, rhs
        return Operator5Point(diagonal, weights_x, weights_y), rhs

    def diffuse(
        self, state: FluidState, dt: float, interior: InteriorBoundary | None = None
    ) -> int:
        """Implicit viscosity ``(I - nu dt lap) u = u*`` for both components, in place.

        Walls and inflow sides hold their normal velocity; tangential wall conditions enter
        through ghosts; a body boundary between two velocity points turns
        ``(phi_N - phi_P)/h^2`` into ``(phi_b - phi_P)/(theta h^2)`` (METHOD.md §6).
        With ``viscosity_scheme="crank_nicolson"``: ``(I - nu dt lap / 2) u =
        (I + nu dt lap / 2) u*``, the explicit half from the same stencils: if ``A u = r``
        is the system assembled for dt / 2 (``r`` = u* plus the boundary terms), the
        right-hand side is ``2 r - A u*``.

        With ``incremental_pressure`` the previous pressure gradient is subtracted first.

        Returns:
            Iterations of the two solves together.
        """
        self._check_step_input(state, dt, interior)
        if self.incremental_pressure:
            self._subtract_gradient(state, state.pressure, dt, interior)
        if self.viscosity == 0.0:
            return 0
        iterations = 0
        crank_nicolson = self.viscosity_scheme == "crank_nicolson"
        for axis, f in ((0, state.velocity_x), (1, state.velocity_y)):
            if crank_nicolson:
                operator, rhs = self._viscosity_operator(f, axis, 0.5 * dt, interior)
                explicit = self._explicit_half[axis]
                apply_operator(operator, f, out=explicit)
                np.multiply(rhs, 2.0, out=rhs)
                np.subtract(rhs, explicit, out=rhs)
            else:
                operator, rhs = self._viscosity_operator(f, axis, dt, interior)
            if self._viscosity_out and _writable_into(f):
                _, report = self.viscosity_solver.solve(operator, rhs, x0=f, out=f)
            else:
                solution, report = self.viscosity_solver.solve(operator, rhs, x0=f)
                kernels.copy_into(solution, f)
            iterations += int(report.iterations)
        return iterations

    def apply_forces(self, state: FluidState, dt: float, time: float) -> None:
        """Gravity, dye buoyancy, jets and side values at ``time + dt`` [s], in place.

        Wall sides get zero normal velocity, inflow sides their (ramped) profile, outflow
        sides the normal velocity of the adjacent interior face (zero normal gradient).
        """
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"time step dt = {dt!r}: must be a finite number > 0")
        self._apply_forces(state, dt, time + dt)

    def _apply_forces(self, state: FluidState, dt: float, side_time: float,
                      body_forces: bool = True) -> None:
        u, v = state.velocity_x, state.velocity_y
        if body_forces:
            self._add_body_forces(state, dt)
        for jet, u_slice, v_slice, cell_slice in self._jet_slices:
            u[u_slice] = jet.velocity[0]
            v[v_slice] = jet.velocity[1]
            state.dye[cell_slice] = jet.dye
        self.apply_side_values(state, side_time)

    def _add_body_forces(self, state: FluidState, dt: float) -> None:
        """Gravity and dye buoyancy over ``dt``, in place."""
        gx, gy = self.gravity
        if gx != 0.0 or gy != 0.0 or self.buoyancy != 0.0:
            kernels.add_body_forces(state.velocity_x, state.velocity_y, state.dye, dt, gx, gy,
                                    self.buoyancy)

    def apply_side_values(self, state: FluidState, time: float) -> None:
        """Set the normal velocity on the four sides of the domain at ``time`` [s]."""
        u, v = state.velocity_x, state.velocity_y
        targets = (u[0, :], u[-1, :], v[:, 0], v[:, -1])
        inside = (u[1, :], u[-2, :], v[:, 1], v[:, -2])
        for index in range(4):
            if self._outflow[index]:
                targets[index][:] = inside[index]
            else:
                targets[index][:] = 0.0
        for index, side, profile in self._inflow_profiles:
            np.multiply(profile, side.ramp(time), out=targets[index])

    def _start_pressure(self, state: FluidState, dt: float) -> None:
        """Keep the pressure as the one before and move ``state.pressure`` to the solve's
        starting guess (with ``pressure_guess="extrapolated"``)."""
        if self.pressure_guess != "extrapolated":
            return
        previous, previous_dt = state.previous_pressure, state.previous_pressure_dt
        if previous is None or previous.shape != state.pressure.shape:
            state.previous_pressure = state.pressure.copy()
        else:
            # Swap the roles of the two arrays: no allocation per step.
            kernels.extrapolate_into(state.pressure, previous,
                                     dt / previous_dt if previous_dt else 0.0)
        state.previous_pressure_dt = float(dt)

    def project(
        self, state: FluidState, dt: float, interior: InteriorBoundary | None = None,
        bodies: CoupledBodies | None = None,
    ) -> SolveReport:
        """Make the velocity divergence-free: ``lap p = (rho/dt) div w``, ``u = w - dt/rho grad p``.

        With bodies the faces are weighted by their open fraction A (Batty et al. 2007):
        ``div(A grad p) = (rho/dt) div(A w + (1 - A) u_s)``; faces with A = 0 take the body
        velocity. The previous pressure is the initial guess; the new one is stored in
        ``state.pressure`` [Pa].

        With ``bodies`` the projection is strongly coupled: the bodies' velocities are unknowns
        of the same solve (their inertia enters the operator, `CoupledBodies`), the pressure's
        force is applied to them, and closed faces take their new velocity.
        """
        self._check_step_input(state, dt, interior)
        if bodies is not None:
            return self._project_coupled(state, dt, interior, bodies)
        h = self.grid.h
        u, v = state.velocity_x, state.velocity_y
        if interior is None:
            has = False
            open_x = open_y = self._no_values
            solid_u, solid_v = self._no_values, self._no_values
            operator = self._open_pressure_operator()
        else:
            has = True
            open_x, open_y = interior.open_fraction_x, interior.open_fraction_y
            solid_u, solid_v = self._solid_face_velocities(interior)
            operator = self._assemble_pressure_operator(open_x, open_y, reuse=True)
        kernels.pressure_rhs(
            u, v, self.density * h / dt, has, open_x, open_y, solid_u, solid_v,
            self._rhs_pressure,
        )
        if self.incremental_pressure:
            increment, report = self.pressure_solver.solve(operator, self._rhs_pressure)
            self._subtract_gradient(state, increment, dt, interior, solid_known=True)
            state.pressure += increment
            if interior is not None:
                self._extend_pressure(state, operator)
            return report
        self._start_pressure(state, dt)
        if self._pressure_out and _writable_into(state.pressure):
            _, report = self.pressure_solver.solve(
                operator, self._rhs_pressure, x0=state.pressure, out=state.pressure
            )
        else:
            pressure, report = self.pressure_solver.solve(
                operator, self._rhs_pressure, x0=state.pressure
            )
            kernels.copy_into(pressure, state.pressure)
        self._subtract_gradient(state, state.pressure, dt, interior, solid_known=True)
        return report

    def _project_coupled(
        self, state: FluidState, dt: float, interior: InteriorBoundary | None,
        bodies: CoupledBodies,
    ) -> SolveReport:
        if interior is None:
            raise ValueError("a strongly coupled projection needs the bodies' InteriorBoundary")
        solve_coupled = getattr(self.pressure_solver, "solve_coupled", None)
        if solve_coupled is None:
            raise ValueError(
                f"pressure_solver = {self.pressure_solver!r}: the strongly coupled projection "
                "needs a solver with solve_coupled (PoissonSolverMGPCG)"
            )
        h = self.grid.h
        u, v = state.velocity_x, state.velocity_y
        open_x, open_y = interior.open_fraction_x, interior.open_fraction_y
        operator = self._assemble_pressure_operator(open_x, open_y, reuse=True)
        active = operator.diagonal > 0.0
        active[:-1, :] |= operator.weights_x > 0.0
        active[1:, :] |= operator.weights_x > 0.0
        active[:, :-1] |= operator.weights_y > 0.0
        active[:, 1:] |= operator.weights_y > 0.0
        self._solid_u[...] = 0.0
        self._solid_v[...] = 0.0
        scale = self.density * h / dt
        kernels.pressure_rhs(u, v, scale, True, open_x, open_y, self._solid_u, self._solid_v,
                             self._rhs_pressure)
        bodies.add_to_rhs(self._rhs_pressure, scale, active)
        term = bodies.coupling_term(active)
        if self.incremental_pressure:
            # The bodies' prediction holds the last pressure's force (the caller's part, as
            # `diffuse` subtracted its gradient from the fluid's): the solve is for the
            # increment, from 0.
            increment, report = solve_coupled(operator, term, self._rhs_pressure)
            bodies.respond(increment, active, self._solid_u, self._solid_v)
            kernels.subtract_pressure_gradient(
                u, v, increment, dt / (self.density * h), self._outflow, True, open_x,
                open_y, self._solid_u, self._solid_v,
            )
            state.pressure += increment
            self._extend_pressure(state, operator)
            return report
        self._start_pressure(state, dt)
        if self._pressure_out and _writable_into(state.pressure):
            _, report = solve_coupled(operator, term, self._rhs_pressure, x0=state.pressure,
                                      out=state.pressure)
        else:
            pressure, report = solve_coupled(operator, term, self._rhs_pressure,
                                             x0=state.pressure)
            kernels.copy_into(pressure, state.pressure)
        bodies.respond(state.pressure, active, self._solid_u, self._solid_v)
        kernels.subtract_pressure_gradient(
            u, v, state.pressure, dt / (self.density * h), self._outflow, True, open_x, open_y,
            self._solid_u, self._solid_v,
        )
        return report

    def _extend_pressure(self, state: FluidState, operator: Operator5Point) -> None:
        """The incremental form reads the last pressure where the next step's equation has
        it: in a cell a moving body clears, a value left from long ago (or 0) gave the next
        viscosity step and the bodies' held force a jump of the whole pressure across the
        cell's faces. Extend the pressure two cells into the bodies (a body moves less than
        a cell per step at the CFL numbers the scenes use)."""
        kernels.extend_into_inactive(state.pressure, operator.diagonal, operator.weights_x,
                                     operator.weights_y, _PRESSURE_EXTENSION_LAYERS)

    def _solid_face_velocities(
        self, interior: InteriorBoundary
    ) -> tuple[np.ndarray, np.ndarray]:
        """Body velocity u_s on faces that are not fully open (buffers, overwritten)."""
        near = self._near_regions(interior)
        kernels.face_solid_velocity(
            interior.solid_faces_x, interior.velocity_faces_x, interior.open_fraction_x,
            interior.cut_theta_x, interior.cut_velocity_x, 2, near, self._solid_u,
        )
        kernels.face_solid_velocity(
            interior.solid_faces_y, interior.velocity_faces_y, interior.open_fraction_y,
            interior.cut_theta_y, interior.cut_velocity_y, 0, near, self._solid_v,
        )
        return self._solid_u, self._solid_v

    def _subtract_gradient(
        self, state: FluidState, pressure: np.ndarray, dt: float,
        interior: InteriorBoundary | None, solid_known: bool = False,
    ) -> None:
        """``u -= dt/rho grad p``; ``solid_known``: the body face velocities are in the buffers."""
        if interior is None:
            has, open_x, open_y = False, self._no_values, self._no_values
            solid_u, solid_v = self._no_values, self._no_values
        else:
            has, open_x, open_y = True, interior.open_fraction_x, interior.open_fraction_y
            if solid_known:
                solid_u, solid_v = self._solid_u, self._solid_v
            else:
                solid_u, solid_v = self._solid_face_velocities(interior)
        kernels.subtract_pressure_gradient(
            state.velocity_x, state.velocity_y, pressure, dt / (self.density * self.grid.h),
            self._outflow, has, open_x, open_y, solid_u, solid_v,
        )

    def predict(
        self, state: FluidState, dt: float, time: float = 0.0,
        interior: InteriorBoundary | None = None,
    ) -> FluidPrediction:
        """Advect, diffuse and apply forces: every phase of a step of ``dt`` [s] from
        ``time`` before the projection, which must then take ``projection_dt`` (the coupling
        schemes call this, then their own projection).

        On a BDF2 step (``viscosity_scheme="bdf2"`` with the last velocity kept and an
        unchanged dt) the advected velocity becomes ``(4 u^n(x_d) - u^{n-1}(x_dd)) / 3`` and
        the viscosity, the forces and the projection act over ``2 dt / 3``: the pressure is
        still p^{n+1}, the force per unit volume ``rho du / (2 dt / 3)``.
        """
        clock = _time.perf_counter
        t0 = clock()
        bdf2 = self._bdf2_history(state, dt, interior)
        self.advect(state, dt, interior)
        # BDF2: (3 u^{n+1} - 4 u^n_d + u^{n-1}_dd) / (2 dt) = f^{n+1}, i.e. the backward
        # Euler phases over 2 dt / 3 from (4 u^n_d - u^{n-1}_dd) / 3.
        effective = dt
        if bdf2:
            effective = 2.0 * dt / 3.0
            for field, back in zip((state.velocity_x, state.velocity_y), self._two_steps_back):
                np.multiply(field, 4.0 / 3.0, out=field)
                back *= 1.0 / 3.0
                np.subtract(field, back, out=field)
        t1 = clock()
        # The incremental form's viscosity step sees the last pressure gradient: it must see
        # the body forces with it, or at a viscous wall the two no longer cancel where they
        # balance (water at rest would start to flow along the walls). Without a pressure yet
        # the step is the plain one, whose viscosity must not see them alone.
        body_forces_first = self.incremental_pressure and kernels.any_nonzero(state.pressure)
        if body_forces_first:
            self._add_body_forces(state, effective)
        viscosity_iterations = self.diffuse(state, effective, interior)
        t2 = clock()
        if effective == dt and not body_forces_first:
            self.apply_forces(state, dt, time)
        else:
            self._apply_forces(state, effective, time + dt, body_forces=not body_forces_first)
        t3 = clock()
        return FluidPrediction(
            projection_dt=effective, viscosity_iterations=viscosity_iterations,
            seconds_by_phase={"advection": t1 - t0, "viscosity": t2 - t1, "forces": t3 - t2},
        )

    def step(
        self, state: FluidState, dt: float, time: float = 0.0,
        interior: InteriorBoundary | None = None,
    ) -> FluidStepReport:
        """Advect, diffuse, apply forces and project: one fluid step of ``dt`` [s] from ``time``."""
        prediction = self.predict(state, dt, time, interior)
        t0 = _time.perf_counter()
        report = self.project(state, prediction.projection_dt, interior)
        seconds = dict(prediction.seconds_by_phase)
        seconds["pressure"] = _time.perf_counter() - t0
        return FluidStepReport(
            pressure_iterations=int(report.iterations),
            pressure_residual=float(report.residual),
            pressure_converged=bool(report.converged),
            viscosity_iterations=prediction.viscosity_iterations,
            seconds_by_phase=seconds,
        )

    def divergence(
        self, state: FluidState, interior: InteriorBoundary | None = None
    ) -> np.ndarray:
        """Cell divergence [1/s] ``div(A u + (1 - A) u_s)`` of the state, shape (nx, ny)."""
        h = self.grid.h
        out = np.empty(self.grid.shape_cells)
        if interior is None:
            kernels.divergence(state.velocity_x, state.velocity_y, h, False,
                               self._no_values, self._no_values, out)
            return out
        self._solid_face_velocities(interior)
        kernels.pressure_rhs(
            state.velocity_x, state.velocity_y, -1.0 / h, True, interior.open_fraction_x,
            interior.open_fraction_y, self._solid_u, self._solid_v, out,
        )
        return out
