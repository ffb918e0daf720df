"""Coupling schemes: what advances a coupled state by one step.

A scheme steps ``state_in`` into ``state_out`` for a `CoupledModel` (Newton's
``Solver.step(state_in, state_out, ...)``): it owns the order of the fluid phases, the
fluid-to-body force and the body advance, and leaves ``state_in`` untouched, so a step that
fails leaves the last good state. `ExplicitCoupling` is the paper's partitioned scheme
(METHOD.md §8); `MonolithicCoupling` solves the pressure and the bodies' answer to it in one
symmetric positive definite system (docs/method_notes.md, "Strong coupling").
"""

from __future__ import annotations

import time as _time
from typing import TYPE_CHECKING, Any, Literal, Protocol

import numpy as np

from elastoflow.simulation._checks import check_fluid_finite, cfl_number
from elastoflow.simulation._report import SimulationBlowUp, StepReport
from elastoflow.simulation._state import (
    BoundaryT,
    CoupledModel,
    CoupledModel3D,
    CoupledState,
    StepBoundary,
)
from elastoflow.solid import (
    BodyModel,
    ElasticBody,
    ElasticBody3D,
    EnergyMomentumFem,
    ExplicitFem,
    MidpointFem,
    NewmarkFem,
    RodBody,
    WallHold,
    hold_response,
    project_onto_box,
    wall_hold,
)

if TYPE_CHECKING:
    from collections.abc import Sequence

    from elastoflow.coupling import BoundaryMap, PressureCoupledBodies
    from elastoflow.fluid import InteriorBoundary
    from elastoflow.linalg import SolveReport

ForceModel = Literal["traction", "momentum_exchange"]
FORCE_MODELS: tuple[str, ...] = ("traction", "momentum_exchange")
# The monolithic scheme's default numerical damping of the bodies' unresolved modes, in units
# of dt (`elastoflow.solid.EnergyMomentumFem`).
DEFAULT_NUMERICAL_DAMPING = 0.1


class CouplingScheme(Protocol):
    """Steps a coupled state by ``dt``; raises `SimulationBlowUp` on divergence."""

    name: str

    def step(self, model: CoupledModel, state_in: CoupledState, state_out: CoupledState,
             dt: float) -> StepReport:
        """Write the state after ``dt`` [s] into ``state_out``; ``state_in`` is not changed
        (``state_out`` holds no data the step needs)."""
        ...


class ExplicitCoupling:
    """The paper's explicit (partitioned) step, METHOD.md §8.

    Map and classification from the bodies' current state; advect, diffuse and force the
    fluid; take the momentum-exchange force from that intermediate velocity or, after the
    projection, the traction force; advance each body by its substeps under that force, held
    constant (optionally under-relaxed, with an optional added-mass estimate).

    Unstable when the fluid a body displaces outweighs it (added-mass effect): the fluid's
    pressure answers the body's last acceleration with ``-m_a a^(n-1)``, which diverges when
    the added mass ``m_a`` exceeds the body's mass. Such runs stop with `SimulationBlowUp`.

    Args:
        substeps: FEM substeps per fluid step, or "auto" for the stability bound.
        force_model: Which fluid-to-solid force drives the bodies: "traction" (pressure and
            viscous stress integrated along the edges) or "momentum_exchange" (paper eq. 8).
        alpha: Volume fraction of the momentum-exchange model, in (0, 1].
        force_relaxation: Under-relaxation ``omega`` in (0, 1] of the force handed to the
            bodies: ``F_applied^n = F_applied^(n-1) + omega (F^n - F_applied^(n-1))`` (1: none).
            Damps the added-mass feedback (stable for roughly ``omega (1 + m_a / m_s) < 2``)
            at the price of a lag of about ``dt / omega`` in the force; steady forces are
            unchanged.
        added_mass: Coefficient ``c`` of the added-mass stabilisation (0: off). Each boundary
            node gets the extra inertia ``c rho_f l_i R`` (``l_i`` its share of the boundary
            length, ``R`` half the body's largest rest extent), and the force
            ``m_i (v^n - v^(n-1)) / dt`` that cancels it at constant acceleration: the body
            sees ``a^n = (F + (m~ - m_a) a^(n-1)) / (m_s + m~)``, stable whenever
            ``m~ > (m_a - m_s) / 2``.
    """

    name = "explicit"

    def __init__(self, substeps: int | Literal["auto"] = "auto",
                 force_model: ForceModel = "traction", alpha: float = 0.5,
                 force_relaxation: float = 1.0, added_mass: float = 0.0) -> None:
        if substeps != "auto" and not (
            isinstance(substeps, (int, float)) and np.isfinite(substeps)
            and int(substeps) == substeps and substeps >= 1
        ):
            raise ValueError(f"substeps = {substeps!r}: must be a positive integer or 'auto'")
        if force_model not in FORCE_MODELS:
            raise ValueError(f"force_model = {force_model!r}: must be one of {FORCE_MODELS}")
        if not 0.0 < alpha <= 1.0:
            raise ValueError(f"alpha = {alpha!r}: must lie in (0, 1]")
        if not 0.0 < force_relaxation <= 1.0:
            raise ValueError(
                f"force_relaxation = {force_relaxation!r}: must lie in (0, 1] (1: no relaxation)"
            )
        if not (0.0 <= added_mass < np.inf):
            raise ValueError(f"added_mass = {added_mass!r}: must be a finite number >= 0")
        self.fem = ExplicitFem(substeps if substeps == "auto" else int(substeps))
        self.force_model = force_model
        self.alpha = float(alpha)
        self.force_relaxation = float(force_relaxation)
        self.added_mass_coefficient = float(added_mass)
        self._added_mass: dict[int, np.ndarray] = {}

    def added_mass(self, body: BodyModel, fluid_density: float) -> np.ndarray:
        """The nodal added-mass estimate of ``body`` [kg/m], shape (n,) (cached)."""
        key = id(body)
        if key not in self._added_mass:
            self._added_mass[key] = _added_mass_estimate(
                body, fluid_density, self.added_mass_coefficient
            )
        return self._added_mass[key]

    def step(self, model: CoupledModel, state_in: CoupledState, state_out: CoupledState,
             dt: float) -> StepReport:
        from elastoflow.coupling import (
            build_boundary_map,
            force_momentum_exchange,
            force_traction,
        )

        seconds: dict[str, float] = {}
        clock = _time.perf_counter
        fluid = model.fluid
        next_step = state_in.step_index + 1
        state_out.assign(state_in)
        out = state_out.fluid

        boundary = None
        offsets = model.object_offsets()
        if model.has_boundaries:
            t0 = clock()
            points, velocities, edges, edge_body = model.boundary_points(state_in)
            bmap = build_boundary_map(model.grid, points, velocities, edges, edge_body)
            boundary = _step_boundary(model, bmap, state_out)
            seconds["map"] = clock() - t0
        interior = None if boundary is None else boundary.interior

        projection_dt = _intermediate_velocity(model, state_out, interior, dt, next_step,
                                               seconds)

        nodal_force = np.zeros((0, 2))
        if model.bodies and self.force_model == "momentum_exchange":
            assert boundary is not None
            t0 = clock()
            nodal_force = force_momentum_exchange(
                model.grid, boundary.boundary_map, out.velocity_x, out.velocity_y,
                fluid.density, projection_dt, self.alpha, interior,
            )
            seconds["coupling_force"] = clock() - t0

        t0 = clock()
        try:
            solve = fluid.project(out, projection_dt, interior)
        except ValueError:
            # A non-finite velocity stops the linear solvers first: report it as a blow-up
            # naming the step (re-raised unchanged when the fields are finite).
            check_fluid_finite(out, next_step, state_in.time + dt)
            raise
        seconds["pressure"] = clock() - t0

        if model.bodies and self.force_model == "traction":
            assert boundary is not None
            t0 = clock()
            nodal_force = force_traction(
                model.grid, boundary.boundary_map, out.velocity_x, out.velocity_y,
                out.pressure, fluid.density, fluid.viscosity, interior, gravity=fluid.gravity,
            )
            seconds["coupling_force"] = clock() - t0

        # The bodies must not take a force from a diverged fluid: name the fluid field.
        check_fluid_finite(out, next_step, state_in.time + dt)

        substeps_taken: list[int] = []
        if model.bodies:
            t0 = clock()
            walls = None if model.contact is None else model.wall_box()
            friction = 0.0 if model.contact is None else model.contact.friction
            for index, body in enumerate(model.bodies):
                body_in, body_out = state_in.bodies[index], state_out.bodies[index]
                force = nodal_force[offsets[index]:offsets[index + 1]]
                if self.force_relaxation < 1.0 and state_in.step_index > 0:
                    previous = state_in.body_forces[index]
                    force = previous + self.force_relaxation * (force - previous)
                state_out.body_forces[index][...] = force
                extra = None
                if self.added_mass_coefficient > 0.0:
                    extra = self.added_mass(body, fluid.density)
                    acceleration = (body_in.velocities
                                    - state_in.previous_velocities[index]) / dt
                    force = force + extra[:, None] * acceleration
                state_out.previous_velocities[index][...] = body_in.velocities
                if not isinstance(body, ElasticBody):
                    # Rods have no explicit substeps: their bending modes would need
                    # substeps of O(h^2) (the monolithic scheme's implicit step has none).
                    raise TypeError(f"body {index} is a {type(body).__name__}: the explicit "
                                    "scheme advances triangle bodies only; use "
                                    "coupling='monolithic'")
                try:
                    report = self.fem.advance(body, body_in, body_out, dt, force,
                                              step=next_step, added_mass=extra, walls=walls,
                                              friction=friction)
                except Exception as error:  # re-raised with where it happened
                    raise SimulationBlowUp(
                        f"step {next_step}, t = {state_in.time + dt:.6g} s, body {index}: "
                        f"{error}"
                    ) from error
                substeps_taken.append(int(report.substeps))
            seconds["solid"] = clock() - t0

        return finish_step(model, state_in, state_out, dt, boundary, solve, substeps_taken, seconds)


class MonolithicCoupling:
    """Strong coupling: the pressure solve sees the bodies' inertia (docs/method_notes.md).

    One step:

    1. map, classification and cut data from the bodies' current state (as the explicit
       scheme);
    2. the explicit part of the fluid's force, its viscous traction, from the current fields;
    3. the fluid's advection, viscosity and forces give the intermediate velocity ``w``;
    4. predictor: each body takes its implicit step (by default
       `elastoflow.solid.EnergyMomentumFem`) under its elastic forces, gravity and that viscous
       traction, without the pressure: ``X*``, ``V*``;
    5. one pressure solve for fluid and bodies together: the flux balance of every cell counts
       the bodies' mean velocity ``(X* - X^n) / dt + dv(p)``, where ``dv = dt/2 A^-1 f_p`` is
       the implicit step's answer (its ``response``) to the pressure's nodal force
       ``f_p = h W^T D^T p`` (`elastoflow.coupling.interface_flux`). The system
       ``(L + rho h^2 DW A^-1 (DW)^T) p = rhs`` is symmetric positive definite (Robinson-Mosher,
       Schroeder & Fedkiw 2011), solved by CG with the fluid's multigrid as preconditioner;
    6. the bodies take ``dv``: ``X = X* + dt dv``, ``V = V* + 2 dv``, and faces inside bodies
       their new velocity.

    No force relaxation and no added-mass estimate: the fluid that a body pushes answers in the
    same solve, so the added-mass instability of the explicit scheme does not arise for any
    density ratio.

    Args:
        gamma: Use Newmark's rule with this gamma (beta = gamma / 2, the family whose answer
            to a held force is ``dt/2 A^-1 f``) instead of the default integrator. Newmark's
            rule keeps a body's angular momentum only to O(dt^2) of its internal forces: discs
            spinning in water spin up under it (docs/method_notes.md item 8).
        integrator: The bodies' implicit step. Default: `elastoflow.solid.EnergyMomentumFem`
            with numerical damping ``DEFAULT_NUMERICAL_DAMPING`` (0.1 dt): it keeps every
            body's momentum and angular momentum and changes the energy only by the damping,
            which is objective (rigid motion feels none). On a linear mode it damps as
            Newmark's gamma = 0.6 does: spectral radius per step 0.9956 at ``omega dt =
            0.3`` (damping ratio ``0.05 omega dt``), 0.96 at 1, 0.82 at 10, 0.996 at 100.
            `elastoflow.solid.MidpointFem` keeps the momenta but not the energy in large
            rotations.
    """

    name = "monolithic"

    def __init__(self, gamma: float | None = None,
                 integrator: MidpointFem | NewmarkFem | None = None) -> None:
        self.fem: MidpointFem | NewmarkFem = implicit_integrator(gamma, integrator)
        self.gamma = self.fem.gamma
        self._explicit = ExplicitCoupling()

    def step(self, model: CoupledModel, state_in: CoupledState, state_out: CoupledState,
             dt: float) -> StepReport:
        from elastoflow.coupling import (
            PressureCoupledBodies,
            build_boundary_map,
            force_traction,
            interface_flux,
        )

        if not model.bodies:
            # Nothing to couple: obstacles have prescribed velocities.
            return self._explicit.step(model, state_in, state_out, dt)
        seconds: dict[str, float] = {}
        clock = _time.perf_counter
        fluid, grid = model.fluid, model.grid
        next_step = state_in.step_index + 1
        where = f"step {next_step}, t = {state_in.time + dt:.6g} s"
        state_out.assign(state_in)
        out = state_out.fluid

        t0 = clock()
        offsets = model.object_offsets()
        points, velocities, edges, edge_body = model.boundary_points(state_in)
        bmap = build_boundary_map(grid, points, velocities, edges, edge_body)
        boundary = _step_boundary(model, bmap, state_out)
        interior = boundary.interior
        seconds["map"] = clock() - t0

        t0 = clock()
        triangles = np.concatenate([body.mesh.triangles + offsets[index]
                                    for index, body in enumerate(model.bodies)])
        triangle_offsets = np.cumsum([0] + [body.mesh.triangle_count for body in model.bodies])
        flux = interface_flux(grid, bmap, interior, triangles, triangle_offsets)
        # The fluid's force held over the step: its viscous traction from the current
        # fields and, with ``incremental_pressure``, the last pressure's force through W (as
        # the fluid's viscosity step subtracts the last pressure's gradient; the coupled
        # solve then answers with the increment).
        held = np.zeros_like(points)
        if fluid.viscosity > 0.0:
            held = force_traction(
                grid, bmap, out.velocity_x, out.velocity_y, np.zeros(grid.shape_cells),
                fluid.density, fluid.viscosity, interior,
            )
        if fluid.incremental_pressure:
            held = held + flux.pressure_forces(out.pressure, interior.open_fraction_x,
                                               interior.open_fraction_y)
        seconds["coupling_force"] = clock() - t0

        projection_dt = _intermediate_velocity(model, state_out, interior, dt, next_step,
                                               seconds)

        t0 = clock()
        # Newmark's matrix M + gamma dt D + beta dt^2 K: the predictor's Newton matrix and the
        # body's answer to the pressure in the coupled solve (the same rule keeps it stable),
        # held on the components resting on a wall.
        holds = wall_holds(model, state_in, dt)
        responses, substeps_taken = implicit_predictor(self.fem, model, state_in, state_out,
                                                       dt, held, offsets, holds,
                                                       next_step, where, damped=True)
        # The flux balance counts what the bodies sweep over the step, their mean velocity
        # (X* - X^n) / dt; the answer to the pressure is Newmark's: mean velocity
        # dt/2 A^-1 f, end velocity twice that.
        predicted = np.array(velocities)
        for index in range(len(model.bodies)):
            lo, hi = offsets[index], offsets[index + 1]
            predicted[lo:hi] = (state_out.bodies[index].positions
                                - state_in.bodies[index].positions) / dt
        for index, obstacle in enumerate(model.obstacles, start=len(model.bodies)):
            predicted[offsets[index]:offsets[index + 1]] = obstacle.velocities_at(
                state_in.time + dt)
        seconds["solid"] = clock() - t0

        t0 = clock()
        coupled = PressureCoupledBodies(
            flux, predicted, responses, offsets[:len(model.bodies) + 1].tolist(),
            fluid.density, projection_dt, bmap=bmap, gravity=fluid.gravity,
        )
        try:
            solve = fluid.project(out, projection_dt, interior, bodies=coupled)
        except ValueError:
            check_fluid_finite(out, next_step, state_in.time + dt)
            raise
        seconds["pressure"] = clock() - t0

        t0 = clock()
        take_pressure_answer(model.bodies, state_out, offsets, predicted, coupled, held, dt,
                             where)
        project_onto_walls(model, state_out, holds)
        seconds["solid"] += clock() - t0

        check_fluid_finite(out, next_step, state_in.time + dt)
        return finish_step(model, state_in, state_out, dt, boundary, solve, substeps_taken, seconds)


def implicit_integrator(gamma: float | None, integrator: MidpointFem | NewmarkFem | None
                        ) -> MidpointFem | NewmarkFem:
    """The monolithic schemes' body integrator: ``integrator``, Newmark's rule with ``gamma``,
    or by default `EnergyMomentumFem` with ``DEFAULT_NUMERICAL_DAMPING``."""
    if gamma is not None and integrator is not None:
        raise ValueError("give gamma (Newmark's rule) or an integrator, not both")
    if integrator is not None:
        return integrator
    return EnergyMomentumFem(DEFAULT_NUMERICAL_DAMPING) if gamma is None else NewmarkFem(gamma)


def wall_holds(model: CoupledModel | CoupledModel3D, state_in: CoupledState, dt: float
               ) -> list[WallHold | None]:
    """Per body, the node components resting on a wall and pressing on it at the step's start
    (`elastoflow.solid.wall_hold`), or None (no contact, or no node on a wall). The press is
    judged by the node's internal force, gravity and the fluid's force of the last step."""
    holds: list[WallHold | None] = [None] * len(model.bodies)
    if model.contact is None:
        return holds
    box = model.wall_box()
    for index, body in enumerate(model.bodies):
        body_in = state_in.bodies[index]
        if not box.near(body_in.positions):
            continue
        forces = (body.forces_at(body_in.positions, body_in.velocities)
                  + body.mass[:, None] * body.gravity + state_in.body_forces[index])
        hold = wall_hold(box, body_in.positions, body_in.velocities, forces, body.mass,
                         body.fixed_mask, dt)
        holds[index] = hold if hold.count else None
    return holds


# The wall velocity's weight in the 2D traction's one-sided normal derivative, in 1 / h:
# the quadratic through the wall value and the samples at d1 = 1.5 h and d2 = 2.5 h
# (`coupling.force_traction`) has slope weight (d1 + d2) / (d1 d2) on the wall value.
_WALL_WEIGHT = (1.5 + 2.5) / (1.5 * 2.5)


def _viscous_damping(body: ElasticBody | RodBody, positions: np.ndarray, dynamic_viscosity: float,
                    h: float) -> np.ndarray:
    """What the implicit rules take of the viscous traction's dependence on a 2D body's own
    velocity, as nodal blocks (n, 2, 2) ``C``: the body takes ``-C (v - v0)`` implicitly
    beside the traction held at ``v0`` (docs/method_notes.md item 8). Per boundary edge
    (length ``L``, unit tangent ``t``, normal ``n``) and each of its two nodes (a rod's
    outline is its line and back, so both its sides count):

    * ``mu w / h (L / 2) t t^T`` (``w`` = `_WALL_WEIGHT`): the wall value's weight in the
      one-sided normal derivative (its normal part is replaced by continuity in
      `force_traction`). Held explicitly this is a nodal damping ``c dt / m`` of about ``4 mu
      dt / (rho_s h^2)`` on a boundary node, above 2 (unstable) on the Turek-Hron flag's
      corner at 40 cells per diameter (FSI1 inverted an element at t = 13 s).
    * ``mu / 2 (t t^T + 2 n n^T)``: a bound on the wall's own tangential derivative, which
      enters the traction as ``mu [(dv.n) t - 2 (dv.t) n]`` per edge (``dv = v_b - v_a``, half
      to each node). That term couples a node to its neighbours, so it stays explicit; held
      alone over the step it pumped node-scale vibrations of a disc settling at nu = 0.035
      m^2/s. The blocks are its Gershgorin bound on a straight wall (row sums of its
      coefficients: ``mu`` along t, ``2 mu`` along n), so the explicit coupling is damped by
      an implicit term at least as large; ``-S (v - v0)`` vanishes as the motion settles
      (an O(dt) lag of transients, ``dt sum S`` against the body's mass)."""
    edges = body.mesh.boundary_edges
    a, b = edges[:, 0], edges[:, 1]
    tangent = positions[b] - positions[a]
    length = np.linalg.norm(tangent, axis=1)
    unit = tangent / np.maximum(length, np.finfo(float).tiny)[:, None]
    normal = np.column_stack([unit[:, 1], -unit[:, 0]])
    along = unit[:, :, None] * unit[:, None, :]
    across = normal[:, :, None] * normal[:, None, :]
    blocks = (_WALL_WEIGHT / h * 0.5 * length + 0.5)[:, None, None] * along + across
    damping = np.zeros((positions.shape[0], 2, 2))
    np.add.at(damping, a, blocks)
    np.add.at(damping, b, blocks)
    return np.asarray(dynamic_viscosity * damping)


def implicit_predictor(fem: MidpointFem | NewmarkFem, model: CoupledModel,
                       state_in: CoupledState, state_out: CoupledState, dt: float,
                       held_forces: np.ndarray, offsets: np.ndarray,
                       holds: Sequence[WallHold | None], step: int, where: str,
                       damped: bool = False) -> tuple[list, list[int]]:
    """Each body's response (held on its wall contacts) and implicit step without the
    pressure under ``held_forces`` (P, 2) into ``state_out``; returns the responses and the
    substep counts (1 each). ``damped``: the held forces hold the viscous traction on the
    whole outline, and elastic bodies take its dependence on their own velocity implicitly
    (`_viscous_damping`)."""
    fluid = model.fluid
    dampings = [_viscous_damping(body, body_state.positions,
                                fluid.density * fluid.viscosity, model.grid.h)
                if damped and fluid.viscosity > 0.0 and isinstance(body, ElasticBody | RodBody)
                else None
                for body, body_state in zip(model.bodies, state_in.bodies, strict=True)]
    responses = []
    for body, body_state, hold, damping in zip(model.bodies, state_in.bodies, holds,
                                               dampings, strict=True):
        response = fem.response(body, body_state, dt, damping)
        responses.append(response if hold is None else hold_response(response, hold.held))
    for index, body in enumerate(model.bodies):
        hold = holds[index]
        try:
            fem.advance(
                body, state_in.bodies[index], state_out.bodies[index], dt,
                held_forces[offsets[index]:offsets[index + 1]], responses[index],
                step=step, nodal_damping=dampings[index],
                hold=None if hold is None else hold.held,
            )
        except Exception as error:  # re-raised with where it happened
            raise SimulationBlowUp(f"{where}, body {index}: {error}") from error
    return responses, [1] * len(model.bodies)


def project_onto_walls(model: CoupledModel | CoupledModel3D, state_out: CoupledState,
                       holds: Sequence[WallHold | None]) -> None:
    """Put the bodies' nodes that ended the step beyond a wall back onto it (inelastic, with
    the model's Coulomb friction, also on the held components). Friction changes the
    velocity only: moving the end position with it (dt/2 per unit velocity, as the implicit
    rules would) raised a resting box's energy by up to 1e-6 of it in some steps, from
    the elastic energy of the shifted nodes; the velocity alone only removes energy."""
    if model.contact is None:
        return
    box = model.wall_box()
    for index, body in enumerate(model.bodies):
        body_out = state_out.bodies[index]
        hold = holds[index]
        if hold is None and not box.near(body_out.positions):
            continue
        project_onto_box(box, body_out.positions, body_out.velocities, body.fixed_mask,
                         model.contact.friction, 0.0,
                         None if hold is None else hold.impulse)


def take_pressure_answer(bodies: Sequence[BodyModel | ElasticBody3D], state_out: CoupledState,
                         offsets: np.ndarray, predicted: np.ndarray,
                         coupled: PressureCoupledBodies, held: np.ndarray, dt: float,
                         where: str) -> None:
    """Each body of a monolithic step takes the coupled solve's answer (2D and 3D): the mean
    velocity change ``dv`` over the step moves it by ``dt dv`` and its end velocity by
    ``2 dv`` (the implicit rules' answer to a held force); its recorded force is the held
    part ``held`` plus the pressure's. Raises `SimulationBlowUp` naming the body and the
    element the answer inverted."""
    for index, body in enumerate(bodies):
        lo, hi = offsets[index], offsets[index + 1]
        body_out = state_out.bodies[index]
        change = coupled.velocities[lo:hi] - predicted[lo:hi]
        body_out.positions += dt * change
        body_out.velocities += 2.0 * change
        state_out.body_forces[index][...] = held[lo:hi] + coupled.pressure_forces[lo:hi]
        determinants = body.deformation_determinants(body_out)
        if not (np.isfinite(body_out.positions).all() and determinants.min() > 0.0):
            element = int(np.argmin(np.nan_to_num(determinants, nan=-np.inf)))
            raise SimulationBlowUp(
                f"{where}, body {index}: the pressure's answer inverted element {element} "
                f"(det F = {determinants[element]:.3g}); use a smaller dt"
            )


def _step_boundary(model: CoupledModel, bmap: BoundaryMap,
                   state_out: CoupledState) -> StepBoundary:
    """The step's boundary data, built by the model's boundary treatment (cut cell or
    staircase), reusing the dense arrays of the classification ``state_out`` held two steps
    ago (keeps the per-step cost at the map's own work)."""
    reuse = None if state_out.boundary is None else state_out.boundary.interior
    interior = model.boundary.interior(model.grid, bmap, out=reuse)
    return StepBoundary(bmap, interior)


def finish_step(model: CoupledModel | CoupledModel3D, state_in: CoupledState[Any, BoundaryT],
            state_out: CoupledState[Any, BoundaryT], dt: float, boundary: BoundaryT | None,
            solve: SolveReport, substeps: list[int], seconds: dict[str, float]) -> StepReport:
    """Commit time, step index and this step's boundary data to ``state_out``; the report
    (2D and 3D schemes alike)."""
    state_out.step_index = state_in.step_index + 1
    state_out.time = state_in.time + dt
    state_out.boundary = boundary
    return StepReport(
        step=state_out.step_index,
        time=state_out.time,
        pressure_iterations=int(solve.iterations),
        pressure_residual=float(solve.residual),
        substeps=substeps,
        cfl=cfl_number(model.grid, state_out.fluid, dt),
        crossing_count=0 if boundary is None else int(boundary.boundary_map.crossing_count),
        seconds_by_phase=seconds,
    )


def _intermediate_velocity(model: CoupledModel, state: CoupledState,
                           interior: InteriorBoundary | None, dt: float, step: int,
                           seconds: dict[str, float]) -> float:
    """The fluid phases before the projection (`FluidSolver.predict`, timed); returns the
    time step the projection takes (2 dt / 3 on a BDF2 step)."""
    try:
        prediction = model.fluid.predict(state.fluid, dt, state.time, interior)
    except ValueError:
        # A non-finite velocity stops the solver first: report the blow-up with its step.
        check_fluid_finite(state.fluid, step, state.time + dt)
        raise
    seconds.update(prediction.seconds_by_phase)
    return prediction.projection_dt


def _added_mass_estimate(body: BodyModel, fluid_density: float,
                         coefficient: float) -> np.ndarray:
    """Nodal added-mass estimate ``c rho_f l_i R`` [kg/m], shape (n,); 0 off the boundary.

    ``l_i`` is half the rest length of the boundary edges at node i, ``R`` half the largest
    side of the body's rest bounding box. For a plate of length b moving broadside this totals
    ``c rho_f b^2`` against the potential-flow value ``pi rho_f b^2 / 4``; for a disc of radius
    R it totals ``2 pi c rho_f R^2`` against ``pi rho_f R^2``: an overestimate for c = 1,
    which only slows transients, never destabilises.
    """
    mesh = body.mesh
    extra = np.zeros(len(mesh.points))
    if coefficient == 0.0:
        return extra
    edges = mesh.boundary_edges
    lengths = np.linalg.norm(mesh.points[edges[:, 1]] - mesh.points[edges[:, 0]], axis=1)
    np.add.at(extra, edges[:, 0], 0.5 * lengths)
    np.add.at(extra, edges[:, 1], 0.5 * lengths)
    extent = mesh.points.max(axis=0) - mesh.points.min(axis=0)
    return coefficient * fluid_density * extra * 0.5 * float(extent.max())


COUPLING_SCHEMES: dict[str, type[ExplicitCoupling | MonolithicCoupling]] = {
    "explicit": ExplicitCoupling,
    "monolithic": MonolithicCoupling,
}

