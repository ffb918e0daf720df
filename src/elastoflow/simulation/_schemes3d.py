"""The coupling schemes of 3D runs: the paper's explicit step and the monolithic one.

`ExplicitCoupling3D` is `ExplicitCoupling` with tetrahedral bodies and closed-surface
obstacles: the 3D boundary map (`elastoflow.coupling.build_boundary_map_3d`) and
classification (`interior_boundary_3d`) from the bodies' current state, the 3D fluid's phases
in the order of `FluidSolver3D.step`, the traction on the surface triangles
(`force_traction_3d`) and `ExplicitFem` substeps of each body under that force.

`MonolithicCoupling3D` is `MonolithicCoupling` on the same parts: the pressure solve sees the
bodies' inertia through the 3D interface flux (`interface_flux_3d`), so that bodies lighter
than the fluid they displace are stable.
"""

from __future__ import annotations

import time as _time
from typing import TYPE_CHECKING, Literal

import numpy as np

from elastoflow.fluid import FluidState3D
from elastoflow.linalg import SolveReport
from elastoflow.simulation._checks import cfl_number, check_fluid_finite
from elastoflow.simulation._report import SimulationBlowUp, StepReport
from elastoflow.simulation._state import CoupledModel3D, CoupledState, StepBoundary3D
from elastoflow.simulation._schemes import implicit_integrator, take_pressure_answer
from elastoflow.solid import ElasticBody3D, ExplicitFem, MidpointFem, NewmarkFem

if TYPE_CHECKING:
    from elastoflow.fluid import InteriorBoundary3D

State3D = CoupledState[FluidState3D, StepBoundary3D]


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
        from elastoflow.coupling import (
            build_boundary_map_3d,
            force_traction_3d,
            interior_boundary_3d,
        )

        seconds: dict[str, float] = {}
        clock = _time.perf_counter
        fluid = model.fluid
        next_step = state_in.step_index + 1
        now = state_in.time + dt
        state_out.assign(state_in)
        out = state_out.fluid

        boundary = None
        interior: InteriorBoundary3D | None = None
        if model.has_boundaries:
            t0 = clock()
            points, velocities, triangles, owner = model.boundary_points(state_in)
            bmap = build_boundary_map_3d(model.grid, points, velocities, triangles, owner)
            # The spare state's boundary is two steps old and read by nobody: reuse its
            # arrays (the current state's, which outputs and forces read, stays intact).
            reuse = None if state_out.boundary is None else state_out.boundary.interior
            interior = interior_boundary_3d(bmap, out=reuse)
            boundary = StepBoundary3D(bmap, interior)
            seconds["map"] = clock() - t0

        try:
            t0 = clock()
            fluid.advect(out, dt, interior)
            t1 = clock()
            fluid.apply_forces(out, dt, state_in.time)
            t2 = clock()
            fluid.diffuse(out, dt, interior)
            t3 = clock()
            solve = fluid.project(out, dt, interior)
            t4 = clock()
        except ValueError:
            # A non-finite velocity stops the linear solvers first: report it as a blow-up
            # naming the step (re-raised unchanged when the fields are finite).
            check_fluid_finite(out, next_step, now)
            raise
        seconds.update({"advection": t1 - t0, "forces": t2 - t1, "viscosity": t3 - t2,
                        "pressure": t4 - t3})
        # The bodies must not take a force from a diverged fluid: name the fluid field.
        check_fluid_finite(out, next_step, now)

        substeps_taken: list[int] = []
        if model.bodies:
            assert boundary is not None
            t0 = clock()
            nodal_force = force_traction_3d(
                model.grid, boundary.boundary_map, out.velocity_x, out.velocity_y,
                out.velocity_z, out.pressure, fluid.density, fluid.viscosity, interior,
                gravity=fluid.gravity,
            )
            seconds["coupling_force"] = clock() - t0
            t0 = clock()
            offsets = model.object_offsets()
            for index, body in enumerate(model.bodies):
                body_in, body_out = state_in.bodies[index], state_out.bodies[index]
                force = nodal_force[offsets[index]:offsets[index + 1]]
                if self.force_relaxation < 1.0 and state_in.step_index > 0:
                    previous = state_in.body_forces[index]
                    force = previous + self.force_relaxation * (force - previous)
                state_out.body_forces[index][...] = force
                state_out.previous_velocities[index][...] = body_in.velocities
                try:
                    report = self.fem.advance(body, body_in, body_out, dt, force,
                                              step=next_step)
                except Exception as error:  # re-raised with where it happened
                    raise SimulationBlowUp(
                        f"step {next_step}, t = {now:.6g} s, body {index}: {error}"
                    ) from error
                substeps_taken.append(int(report.substeps))
            seconds["solid"] = clock() - t0

        return _finish(model, state_in, state_out, dt, boundary, solve, substeps_taken,
                       seconds)


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
        from elastoflow.coupling import (
            PressureCoupledBodies,
            build_boundary_map_3d,
            force_traction_3d,
            interface_flux_3d,
            interior_boundary_3d,
        )

        if not model.bodies:
            # Nothing to couple: obstacles have prescribed velocities.
            return self._explicit.step(model, state_in, state_out, dt)
        seconds: dict[str, float] = {}
        clock = _time.perf_counter
        fluid, grid = model.fluid, model.grid
        next_step = state_in.step_index + 1
        now = state_in.time + dt
        where = f"step {next_step}, t = {now:.6g} s"
        state_out.assign(state_in)
        out = state_out.fluid

        t0 = clock()
        offsets = model.object_offsets()
        body_count = len(model.bodies)
        points, velocities, triangles, owner = model.boundary_points(state_in)
        bmap = build_boundary_map_3d(grid, points, velocities, triangles, owner)
        reuse = None if state_out.boundary is None else state_out.boundary.interior
        interior = interior_boundary_3d(bmap, out=reuse)
        boundary = StepBoundary3D(bmap, interior)
        tetrahedra = np.concatenate([body.mesh.tetrahedra + offsets[index]
                                     for index, body in enumerate(model.bodies)])
        tetrahedron_offsets = np.cumsum([0] + [body.mesh.tetrahedra.shape[0]
                                               for body in model.bodies])
        flux = interface_flux_3d(grid, bmap, interior, tetrahedra, tetrahedron_offsets)
        seconds["map"] = clock() - t0

        t0 = clock()
        held = np.zeros_like(points)
        if fluid.viscosity > 0.0:
            held += force_traction_3d(grid, bmap, out.velocity_x, out.velocity_y,
                                      out.velocity_z, np.zeros(grid.shape_cells),
                                      fluid.density, fluid.viscosity, interior)
        if fluid.incremental_pressure:
            held += flux.pressure_forces(out.pressure)
        seconds["coupling_force"] = clock() - t0

        try:
            t0 = clock()
            fluid.advect(out, dt, interior)
            t1 = clock()
            fluid.apply_forces(out, dt, state_in.time)
            t2 = clock()
            fluid.diffuse(out, dt, interior)
            t3 = clock()
        except ValueError:
            check_fluid_finite(out, next_step, now)
            raise
        seconds.update({"advection": t1 - t0, "forces": t2 - t1, "viscosity": t3 - t2})

        t0 = clock()
        dampings = [_viscous_damping(body, body_state.positions,
                                     fluid.density * fluid.viscosity, grid.h)
                    if fluid.viscosity > 0.0 else None
                    for body, body_state in zip(model.bodies, state_in.bodies, strict=True)]
        responses = [self.fem.response(body, body_state, dt, damping)
                     for body, body_state, damping
                     in zip(model.bodies, state_in.bodies, dampings, strict=True)]
        for index, body in enumerate(model.bodies):
            try:
                self.fem.advance(body, state_in.bodies[index], state_out.bodies[index], dt,
                                 held[offsets[index]:offsets[index + 1]], responses[index],
                                 step=next_step, nodal_damping=dampings[index])
            except Exception as error:  # re-raised with where it happened
                raise SimulationBlowUp(f"{where}, body {index}: {error}") from error
        # The flux balance counts what the bodies sweep over the step, their mean velocity.
        predicted = np.array(velocities)
        for index in range(body_count):
            lo, hi = offsets[index], offsets[index + 1]
            predicted[lo:hi] = (state_out.bodies[index].positions
                                - state_in.bodies[index].positions) / dt
        for index, obstacle in enumerate(model.obstacles, start=body_count):
            predicted[offsets[index]:offsets[index + 1]] = obstacle.velocities_at(now)
        seconds["solid"] = clock() - t0

        t0 = clock()
        coupled = PressureCoupledBodies(flux, predicted, responses,
                                        offsets[:body_count + 1].tolist(), fluid.density, dt,
                                        bmap=bmap, gravity=fluid.gravity)
        try:
            solve = fluid.project(out, dt, interior, bodies=coupled)
        except ValueError:
            check_fluid_finite(out, next_step, now)
            raise
        seconds["pressure"] = clock() - t0

        t0 = clock()
        take_pressure_answer(model.bodies, state_out, offsets, predicted, coupled, held, dt,
                             where)
        seconds["solid"] += clock() - t0

        check_fluid_finite(out, next_step, now)
        return _finish(model, state_in, state_out, dt, boundary, solve,
                       [1] * body_count, seconds)


# The wall velocity's weight in the traction's one-sided normal derivative, in 1 / h:
# ``(-3 u_wall + 4 u(h) - u(2 h)) / (2 h)`` (`force_traction_3d`'s samples at 1 h and 2 h).
_WALL_WEIGHT = 1.5


def _viscous_damping(body: ElasticBody3D, positions: np.ndarray, dynamic_viscosity: float,
                     h: float) -> np.ndarray:
    """The viscous traction's dependence on the body's own velocity, as nodal blocks (n, 3,
    3): ``mu 1.5 / h`` times each surface node's share of the area (a third of each of its
    triangles') times the tangential projector ``I - n n^T`` (the normal part of the
    traction's wall gradient is replaced by continuity in `force_traction_3d`). The traction
    itself is held over the step (explicit); its change with the body's velocity over the
    step, ``-C (v - v0)``, is taken implicitly by the body's rule. Explicit, it is a nodal
    damping ``c dt / m ~ 9 mu dt / (rho_s h^2)`` on a surface node that made bodies in
    viscous oil vibrate and diverge (docs/method_notes.md item 14)."""
    triangles = body.boundary_triangles
    corners = positions[triangles]
    area_normal = 0.5 * np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    area = np.linalg.norm(area_normal, axis=1)
    normal = area_normal / np.maximum(area, np.finfo(float).tiny)[:, None]
    blocks = (area / 3.0)[:, None, None] * (np.eye(3) - normal[:, :, None] * normal[:, None, :])
    damping = np.zeros((positions.shape[0], 3, 3))
    for corner in range(3):
        np.add.at(damping, triangles[:, corner], blocks)
    return np.asarray(dynamic_viscosity * _WALL_WEIGHT / h * damping)


Scheme3D = ExplicitCoupling3D | MonolithicCoupling3D
"""The coupling schemes a 3D `Simulation` takes."""


def _finish(model: CoupledModel3D, state_in: State3D, state_out: State3D, dt: float,
            boundary: StepBoundary3D | None, solve: SolveReport, substeps: list[int],
            seconds: dict[str, float]) -> StepReport:
    """Commit time, step index and this step's boundary data to ``state_out``; the report."""
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
