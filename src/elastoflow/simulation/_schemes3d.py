"""The coupling schemes of 3D runs: the paper's explicit step and the monolithic one.

`ExplicitCoupling3D` is `ExplicitCoupling` with tetrahedral bodies and closed-surface
obstacles: the 3D boundary map (`elastoflow.coupling.build_boundary_map_3d`) and
classification (`interior_boundary_3d`) from the bodies' current state, the 3D fluid's phases
in the order of `FluidSolver3D.step`, the traction on the surface triangles
(`force_traction_3d`) and `ExplicitFem` substeps of each body under that force.

Both take the model's wall contact (`CoupledModel3D.contact`) as the 2D schemes do: the
explicit substeps put nodes beyond a wall back onto it; the monolithic step holds the node
components resting on a wall inside the bodies' implicit step (so the coupled pressure solve
sees a body that cannot move into the wall) and projects after it.

`MonolithicCoupling3D` is `MonolithicCoupling` on the same parts: the pressure solve sees the
bodies' inertia through the 3D interface flux (`interface_flux_3d`), so that bodies lighter
than the fluid they displace are stable.
"""

from __future__ import annotations

import time as _time
from dataclasses import fields as dataclass_fields
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import TYPE_CHECKING, Literal

import numpy as np

from elastoflow.fluid import FluidSolver3D, FluidState3D
from elastoflow.linalg import SolveReport
from elastoflow.simulation._checks import check_fluid_finite
from elastoflow.simulation._report import SimulationBlowUp, StepReport
from elastoflow.simulation._state import CoupledModel3D, CoupledState, StepBoundary3D
from elastoflow.simulation._schemes import (
    finish_step,
    implicit_integrator,
    project_onto_walls,
    take_pressure_answer,
    wall_holds,
)
from elastoflow.solid import (
    ElasticBody3D,
    ExplicitFem,
    MidpointFem,
    NewmarkFem,
    WallHold,
    hold_response,
)

if TYPE_CHECKING:
    from elastoflow.coupling import InterfaceFlux3D
    from elastoflow.fluid import CoupledBodies, InteriorBoundary3D
    from elastoflow.solid import HeldResponse, StepResponse

State3D = CoupledState[FluidState3D, StepBoundary3D]


class _Step3D:
    """The bookkeeping of one 3D step that both schemes share.

    Opening it copies ``state_in`` into ``state_out``, except the fluid fields that
    `fluid_phases`' advection writes from ``state_in`` (`FluidSolver3D.ADVECTED_FIELDS`);
    the phases then change ``state_out``'s fluid (`out`) in place (a scheme must run
    `fluid_phases` before it reads `out`'s velocity or dye). Each phase it runs is timed
    into `seconds` (a phase that runs in parts
    adds them up), and an error in it names the step. `finish` commits time, step index and
    the step's boundary to ``state_out`` and gives the report.

    Attributes:
        seconds: Wall-clock seconds by phase name, the report's ``seconds_by_phase``.
        out: ``state_out``'s fluid state, the one the phases change.
        offsets: `CoupledModel3D.object_offsets`: each body's and obstacle's first surface
            point, then their count.
        next_step: The index ``state_out`` takes.
        now: The time [s] ``state_out`` takes.
        where: ``"step N, t = T s"``, for error messages.
    """

    def __init__(self, model: CoupledModel3D, state_in: State3D, state_out: State3D,
                 dt: float) -> None:
        self.model = model
        self.state_in = state_in
        self.state_out = state_out
        self.dt = dt
        self.seconds: dict[str, float] = {}
        self.next_step = state_in.step_index + 1
        self.now = state_in.time + dt
        self.where = f"step {self.next_step}, t = {self.now:.6g} s"
        # `fluid_phases` transports velocity and dye from ``state_in`` into ``state_out``,
        # writing every value: copied here, they would be a wasted pass over four grids.
        state_out.assign(state_in, fluid=False)
        state_out.fluid.assign(state_in.fluid, [
            item.name for item in dataclass_fields(FluidState3D)
            if item.name not in FluidSolver3D.ADVECTED_FIELDS])
        self.out = state_out.fluid
        self.offsets = model.object_offsets()

    @contextmanager
    def timed(self, phase: str) -> Iterator[None]:
        """Add the wall-clock time of the ``with`` block to ``seconds[phase]``."""
        start = _time.perf_counter()
        yield
        self.seconds[phase] = self.seconds.get(phase, 0.0) + _time.perf_counter() - start

    @contextmanager
    def _fluid_checked(self) -> Iterator[None]:
        try:
            yield
        except ValueError:
            # A non-finite velocity stops the linear solvers first: report it as a blow-up
            # naming the step (re-raised unchanged when the fields are finite).
            self.check_fluid()
            raise

    @contextmanager
    def body_checked(self, index: int) -> Iterator[None]:
        """Re-raise any error of the ``with`` block as `SimulationBlowUp` naming the step and
        body ``index``."""
        try:
            yield
        except Exception as error:  # re-raised with where it happened
            raise SimulationBlowUp(f"{self.where}, body {index}: {error}") from error

    def map_boundary(self) -> StepBoundary3D:
        """The boundary map and classification of the bodies' and obstacles' surfaces at
        ``state_in`` (phase "map")."""
        from elastoflow.coupling import build_boundary_map_3d, interior_boundary_3d

        with self.timed("map"):
            points, velocities, triangles, owner = self.model.boundary_points(self.state_in)
            bmap = build_boundary_map_3d(self.model.grid, points, velocities, triangles, owner)
            # The spare state's boundary is two steps old and read by nobody: reuse its
            # arrays (the current state's, which outputs and forces read, stays intact).
            boundary = self.state_out.boundary
            interior = interior_boundary_3d(bmap, out=None if boundary is None
                                            else boundary.interior)
        return StepBoundary3D(bmap, interior)

    def fluid_phases(self, interior: InteriorBoundary3D | None) -> None:
        """Advect, apply the forces and diffuse `out`: `FluidSolver3D.step`'s order up to the
        projection (phases "advection", "forces", "viscosity")."""
        fluid, dt = self.model.fluid, self.dt
        with self._fluid_checked():
            with self.timed("advection"):
                fluid.advect(self.out, dt, interior, source=self.state_in.fluid)
            with self.timed("forces"):
                fluid.apply_forces(self.out, dt, self.state_in.time)
            with self.timed("viscosity"):
                fluid.diffuse(self.out, dt, interior)

    def project(self, interior: InteriorBoundary3D | None,
                bodies: CoupledBodies | None = None) -> SolveReport:
        """Project `out` (with the coupled ``bodies`` in the solve; phase "pressure")."""
        with self._fluid_checked(), self.timed("pressure"):
            return self.model.fluid.project(self.out, self.dt, interior, bodies=bodies)

    def check_fluid(self) -> None:
        """Raise `SimulationBlowUp` naming the field where `out` is not finite."""
        check_fluid_finite(self.out, self.next_step, self.now)

    def finish(self, boundary: StepBoundary3D | None, solve: SolveReport,
               substeps: list[int]) -> StepReport:
        """Commit time, step index and this step's boundary to ``state_out``; the report."""
        return finish_step(self.model, self.state_in, self.state_out, self.dt, boundary, solve,
                       substeps, self.seconds)


class ExplicitCoupling3D:
    """The paper's explicit (partitioned) step in 3D (METHOD.md §8).

    Map and classification from the bodies' current surfaces; advect, apply the forces,
    diffuse and project the fluid (`FluidSolver3D.step`'s order, so a run without bodies is
    bit for bit the fluid solver's); the traction force on every surface triangle; each body's
    `ExplicitFem` substeps under that force, held constant (optionally under-relaxed).

    Unstable, as in 2D, when the fluid a body displaces outweighs it (added mass); such runs
    stop with `SimulationBlowUp`: `MonolithicCoupling3D` is stable there.

    Args:
        substeps: FEM substeps per fluid step, or "auto" for the stability bound.
        force_relaxation: Under-relaxation ``omega`` in (0, 1] of the force handed to the
            bodies (1: none), as `ExplicitCoupling`'s.
    """

    name = "explicit"

    def __init__(self, substeps: int | Literal["auto"] = "auto",
                 force_relaxation: float = 1.0) -> None:
        if substeps != "auto" and not (
            isinstance(substeps, (int, float)) and np.isfinite(substeps)
            and int(substeps) == substeps and substeps >= 1
        ):
            raise ValueError(f"substeps = {substeps!r}: must be a positive integer or 'auto'")
        if not 0.0 < force_relaxation <= 1.0:
            raise ValueError(
                f"force_relaxation = {force_relaxation!r}: must lie in (0, 1] (1: no relaxation)"
            )
        self.fem = ExplicitFem(substeps if substeps == "auto" else int(substeps))
        self.force_relaxation = float(force_relaxation)
        self.force_model = "traction"

    def step(self, model: CoupledModel3D, state_in: State3D, state_out: State3D,
             dt: float) -> StepReport:
        """Write the state after ``dt`` [s] into ``state_out``; ``state_in`` is unchanged."""
        run = _Step3D(model, state_in, state_out, dt)
        boundary = run.map_boundary() if model.has_boundaries else None
        interior = None if boundary is None else boundary.interior
        run.fluid_phases(interior)
        solve = run.project(interior)
        # The bodies must not take a force from a diverged fluid: name the fluid field.
        run.check_fluid()
        substeps: list[int] = []
        if model.bodies:
            assert boundary is not None
            substeps = self._advance_bodies(run, boundary)
        return run.finish(boundary, solve, substeps)

    def _advance_bodies(self, run: _Step3D, boundary: StepBoundary3D) -> list[int]:
        """The traction on the surface triangles (phase "coupling_force") and each body's
        substeps under it (phase "solid"); the substeps each body took."""
        from elastoflow.coupling import force_traction_3d

        model, state_in, state_out, out = run.model, run.state_in, run.state_out, run.out
        fluid = model.fluid
        with run.timed("coupling_force"):
            nodal_force = force_traction_3d(
                model.grid, boundary.boundary_map, out.velocity_x, out.velocity_y,
                out.velocity_z, out.pressure, fluid.density, fluid.viscosity,
                boundary.interior, gravity=fluid.gravity,
            )
        substeps: list[int] = []
        with run.timed("solid"):
            offsets = run.offsets
            walls = None if model.contact is None else model.wall_box()
            friction = 0.0 if model.contact is None else model.contact.friction
            for index, body in enumerate(model.bodies):
                body_in, body_out = state_in.bodies[index], state_out.bodies[index]
                force = nodal_force[offsets[index]:offsets[index + 1]]
                if self.force_relaxation < 1.0 and state_in.step_index > 0:
                    previous = state_in.body_forces[index]
                    force = previous + self.force_relaxation * (force - previous)
                state_out.body_forces[index][...] = force
                state_out.previous_velocities[index][...] = body_in.velocities
                with run.body_checked(index):
                    report = self.fem.advance(body, body_in, body_out, run.dt, force,
                                              step=run.next_step, walls=walls,
                                              friction=friction)
                substeps.append(int(report.substeps))
        return substeps


class MonolithicCoupling3D:
    """Strong coupling in 3D: `MonolithicCoupling`'s step (its docstring and
    docs/method_notes.md) on tetrahedral bodies.

    One step: the 3D map and classification from the bodies' current state and the interface
    flux ``W`` (`interface_flux_3d`, exact for affine motion of each tetrahedron); the
    viscous traction on the surface triangles from the current fields; the fluid's
    advection, forces and viscosity; each body's implicit step under its elastic forces,
    gravity and that traction (with the fluid's ``incremental_pressure``, the default in 3D,
    also the last pressure's force through ``W``, as the fluid's viscosity step subtracts
    the last pressure's gradient); then one pressure solve for fluid and bodies
    (``(A + rho h^3 / dt DW Phi (DW)^T) p = rhs``, `PoissonSolverMGPCG3D.solve_coupled`)
    whose answer moves both.

    Args:
        gamma: Use Newmark's rule with this gamma instead of the default integrator (as
            `MonolithicCoupling`).
        integrator: The bodies' implicit step; default `elastoflow.solid.EnergyMomentumFem`
            with numerical damping ``DEFAULT_NUMERICAL_DAMPING``.
    """

    name = "monolithic"

    def __init__(self, gamma: float | None = None,
                 integrator: MidpointFem | NewmarkFem | None = None) -> None:
        self.fem: MidpointFem | NewmarkFem = implicit_integrator(gamma, integrator)
        self.gamma = self.fem.gamma
        self._explicit = ExplicitCoupling3D()

    def step(self, model: CoupledModel3D, state_in: State3D, state_out: State3D,
             dt: float) -> StepReport:
        """Write the state after ``dt`` [s] into ``state_out``; ``state_in`` is unchanged."""
        from elastoflow.coupling import PressureCoupledBodies

        if not model.bodies:
            # Nothing to couple: obstacles have prescribed velocities.
            return self._explicit.step(model, state_in, state_out, dt)
        run = _Step3D(model, state_in, state_out, dt)
        boundary = run.map_boundary()
        with run.timed("map"):
            flux = _interface_flux(model, boundary, run.offsets)
        with run.timed("coupling_force"):
            held = _held_force(model, boundary, flux, state_in.fluid)
        run.fluid_phases(boundary.interior)
        with run.timed("solid"):
            holds = wall_holds(model, state_in, dt)
            responses, predicted = self._predict(run, boundary, held, holds)
        with run.timed("pressure"):
            coupled = PressureCoupledBodies(
                flux, predicted, responses, run.offsets[:len(model.bodies) + 1].tolist(),
                model.fluid.density, dt, bmap=boundary.boundary_map,
                gravity=model.fluid.gravity)
        solve = run.project(boundary.interior, coupled)
        with run.timed("solid"):
            take_pressure_answer(model.bodies, state_out, run.offsets, predicted, coupled, held,
                                 dt, run.where)
            project_onto_walls(model, state_out, holds)
        run.check_fluid()
        return run.finish(boundary, solve, [1] * len(model.bodies))

    def _predict(self, run: _Step3D, boundary: StepBoundary3D, held: np.ndarray,
                 holds: Sequence[WallHold | None]
                 ) -> tuple[list[StepResponse | HeldResponse], np.ndarray]:
        """Each body's implicit step under ``held`` without the pressure (into
        ``state_out``), its components in ``holds`` kept on their walls; its response to a
        nodal force (held there too), and every surface point's velocity over the step for
        the flux balance (the bodies' mean velocity, the obstacles' prescribed one)."""
        model, state_in, state_out, dt = run.model, run.state_in, run.state_out, run.dt
        fluid, grid, offsets = model.fluid, model.grid, run.offsets
        dampings = [_viscous_damping(body, body_state.positions,
                                     fluid.density * fluid.viscosity, grid.h)
                    if fluid.viscosity > 0.0 else None
                    for body, body_state in zip(model.bodies, state_in.bodies, strict=True)]
        responses = [hold_response(self.fem.response(body, body_state, dt, damping),
                                   None if hold is None else hold.held)
                     for body, body_state, damping, hold
                     in zip(model.bodies, state_in.bodies, dampings, holds, strict=True)]
        for index, body in enumerate(model.bodies):
            hold = holds[index]
            with run.body_checked(index):
                self.fem.advance(body, state_in.bodies[index], state_out.bodies[index], dt,
                                 held[offsets[index]:offsets[index + 1]], responses[index],
                                 step=run.next_step, nodal_damping=dampings[index],
                                 hold=None if hold is None else hold.held)
        predicted = np.array(boundary.boundary_map.velocities)
        for index in range(len(model.bodies)):
            lo, hi = offsets[index], offsets[index + 1]
            predicted[lo:hi] = (state_out.bodies[index].positions
                                - state_in.bodies[index].positions) / dt
        for index, obstacle in enumerate(model.obstacles, start=len(model.bodies)):
            predicted[offsets[index]:offsets[index + 1]] = obstacle.velocities_at(run.now)
        return responses, predicted


def _interface_flux(model: CoupledModel3D, boundary: StepBoundary3D, offsets: np.ndarray
                    ) -> InterfaceFlux3D:
    """The bodies' interface flux ``W`` on this step's boundary (`interface_flux_3d`)."""
    from elastoflow.coupling import interface_flux_3d

    tetrahedra = np.concatenate([body.mesh.tetrahedra + offsets[index]
                                 for index, body in enumerate(model.bodies)])
    tetrahedron_offsets = np.cumsum([0] + [body.mesh.tetrahedra.shape[0]
                                           for body in model.bodies])
    return interface_flux_3d(model.grid, boundary.boundary_map, boundary.interior,
                             tetrahedra, tetrahedron_offsets)


def _held_force(model: CoupledModel3D, boundary: StepBoundary3D, flux: InterfaceFlux3D,
                fluid_state: FluidState3D) -> np.ndarray:
    """The fluid's force held over the step [N], (P, 3) on every surface point: the viscous
    traction from the current fields and, with ``incremental_pressure``, the last pressure's
    force through ``W``."""
    from elastoflow.coupling import force_traction_3d

    fluid, grid, bmap = model.fluid, model.grid, boundary.boundary_map
    held = np.zeros_like(bmap.points)
    if fluid.viscosity > 0.0:
        held += force_traction_3d(grid, bmap, fluid_state.velocity_x, fluid_state.velocity_y,
                                  fluid_state.velocity_z, np.zeros(grid.shape_cells),
                                  fluid.density, fluid.viscosity, boundary.interior)
    if fluid.incremental_pressure:
        held += flux.pressure_forces(fluid_state.pressure)
    return held


# The wall velocity's weight in the traction's one-sided normal derivative, in 1 / h:
# ``(-3 u_wall + 4 u(h) - u(2 h)) / (2 h)`` (`force_traction_3d`'s samples at 1 h and 2 h).
_WALL_WEIGHT = 1.5


def _viscous_damping(body: ElasticBody3D, positions: np.ndarray, dynamic_viscosity: float,
                     h: float) -> np.ndarray:
    """What the implicit rules take of the viscous traction's dependence on a 3D body's own
    velocity, as nodal blocks (n, 3, 3) ``C``: the body takes ``-C (v - v0)`` implicitly
    beside the traction held at ``v0`` (docs/method_notes.md item 14). Per surface triangle
    (area ``A``, unit normal ``n``) and each of its corners:

    * ``mu 1.5 / h (A / 3) (I - n n^T)``: the wall value's weight in the one-sided normal
      derivative (its normal part is replaced by continuity in `force_traction_3d`). Held
      explicitly, this is a nodal damping ``c dt / m ~ 9 mu dt / (rho_s h^2)`` on a surface
      node that made bodies in viscous oil vibrate and diverge.
    * ``mu (l_1 + l_2) / 6 (I + n n^T)`` (``l_1``, ``l_2`` the corner's two edges): a bound on
      the wall's own surface gradient ``L``, which enters the traction as ``mu (L^T n - 2
      tr(L) n)``, couples each node to its neighbours and so stays explicit; held alone it
      pumped node-scale vibrations of a sphere at sixteen times ten Cate's viscosity, and
      with the bound taken off the translation the sphere's translation swung apart at 64
      times (a term not traced, which the full bound damps). The blocks are
      its Gershgorin bound (row sums of its coefficients, ``|grad phi_k| A / 3 = l_k / 6``
      per neighbour), so the explicit coupling is damped by an implicit term at least as
      large; ``-C (v - v0)`` vanishes as the motion settles (an O(dt) lag of transients,
      ``dt sum C`` against the body's mass: ten Cate's sphere starts 6 % slower at t = 0.2
      s, 1.3 % at 0.6 s, at 4.5 cells per diameter)."""
    triangles = body.boundary_triangles
    corners = positions[triangles]
    area_normal = 0.5 * np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    area = np.linalg.norm(area_normal, axis=1)
    normal = area_normal / np.maximum(area, np.finfo(float).tiny)[:, None]
    across = normal[:, :, None] * normal[:, None, :]
    wall = (_WALL_WEIGHT / h * area / 3.0)[:, None, None] * (np.eye(3) - across)
    # Edge k joins corners k and k + 1: corner k meets edges k and k - 1.
    edge = np.linalg.norm(np.roll(corners, -1, axis=1) - corners, axis=2)
    damping = np.zeros((positions.shape[0], 3, 3))
    for corner in range(3):
        reach = (edge[:, corner] + edge[:, corner - 1]) / 6.0
        np.add.at(damping, triangles[:, corner],
                  wall + reach[:, None, None] * (np.eye(3) + across))
    return np.asarray(dynamic_viscosity * damping)


Scheme3D = ExplicitCoupling3D | MonolithicCoupling3D
"""The coupling schemes a 3D `Simulation` takes."""
