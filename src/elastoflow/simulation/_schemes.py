"""Coupling schemes: what advances a `Simulation`'s fluid and bodies by one step.

A scheme owns the order of the fluid phases, the fluid-to-body force and the body advance.
`ExplicitCoupling` is the paper's partitioned scheme (METHOD.md §8); `MonolithicCoupling` solves
the pressure and the bodies' answer to it in one symmetric positive definite system
(docs/method_notes.md, "Strong coupling").
"""

from __future__ import annotations

import time as _time
from typing import TYPE_CHECKING, Protocol

import numpy as np

from elastoflow.simulation._report import SimulationBlowUp, StepReport

if TYPE_CHECKING:
    from elastoflow.coupling import BoundaryMap
    from elastoflow.fluid import InteriorBoundary
    from elastoflow.linalg import SolveReport
    from elastoflow.simulation._simulation import Simulation


class CouplingScheme(Protocol):
    """Advances a simulation by one fluid step; raises `SimulationBlowUp` on divergence."""

    name: str

    def step(self, sim: Simulation) -> StepReport:
        ...


class ExplicitCoupling:
    """The paper's explicit (partitioned) step, METHOD.md §8.

    Map and classification from the bodies' current state; advect, diffuse and force the
    fluid; take the momentum-exchange force from that intermediate velocity or, after the
    projection, the traction force; advance each body by its substeps under that force, held
    constant (optionally under-relaxed, with an optional added-mass estimate). Unstable when
    the fluid a body displaces outweighs it (added-mass effect): see `Simulation`.
    """

    name = "explicit"

    def step(self, sim: Simulation) -> StepReport:
        from elastoflow.coupling import (
            build_boundary_map,
            force_momentum_exchange,
            force_traction,
            interior_boundary_from_map,
        )

        seconds: dict[str, float] = {}
        clock = _time.perf_counter
        dt, fluid, state = sim.dt, sim.fluid_solver, sim.state
        next_step = sim.step_index + 1

        interior = None
        bmap = None
        if sim.has_boundaries:
            t0 = clock()
            points, velocities, edges, edge_body, offsets = sim._boundary_arrays()
            bmap = build_boundary_map(sim.grid, points, velocities, edges, edge_body)
            # Reusing the dense arrays keeps the per-step cost at the map's own work.
            interior = interior_boundary_from_map(sim.grid, bmap, out=sim.interior)
            seconds["map"] = clock() - t0

        _intermediate_velocity(sim, interior, next_step, seconds)

        nodal_force = np.zeros((0, 2))
        if sim.bodies and sim.force_model == "momentum_exchange":
            assert bmap is not None
            t0 = clock()
            nodal_force = force_momentum_exchange(
                sim.grid, bmap, state.velocity_x, state.velocity_y,
                fluid.density, dt, sim.alpha,
            )
            seconds["coupling_force"] = clock() - t0

        t0 = clock()
        try:
            solve = fluid.project(state, dt, interior)
        except ValueError:
            # A non-finite velocity stops the linear solvers first: report it as a blow-up
            # naming the step (re-raised unchanged when the fields are finite).
            sim._check_fluid(next_step)
            raise
        seconds["pressure"] = clock() - t0

        if sim.bodies and sim.force_model == "traction":
            assert bmap is not None
            t0 = clock()
            nodal_force = force_traction(
                sim.grid, bmap, state.velocity_x, state.velocity_y,
                state.pressure, fluid.density, fluid.viscosity, interior,
                gravity=fluid.gravity,
            )
            seconds["coupling_force"] = clock() - t0

        cfl = sim._check_fluid(next_step)

        substeps_taken: list[int] = []
        if sim.bodies:
            t0 = clock()
            for index, body in enumerate(sim.bodies):
                force = nodal_force[offsets[index]:offsets[index + 1]]
                if sim.force_relaxation < 1.0 and sim.step_index > 0:
                    previous = sim.body_forces[index]
                    force = previous + sim.force_relaxation * (force - previous)
                sim.body_forces[index] = force.copy()
                extra = None
                if sim.added_mass_coefficient > 0.0:
                    extra = sim.added_mass[index]
                    acceleration = (body.velocities - sim._previous_velocities[index]) / dt
                    force = force + extra[:, None] * acceleration
                sim._previous_velocities[index] = body.velocities.copy()
                try:
                    report = body.advance(
                        dt, sim.substeps, force, step=next_step, added_mass=extra
                    )
                except Exception as error:  # re-raised with where it happened
                    raise SimulationBlowUp(
                        f"step {next_step}, t = {sim.time + dt:.6g} s, body {index}: {error}"
                    ) from error
                substeps_taken.append(int(report.substeps))
            seconds["solid"] = clock() - t0

        sim.time += dt
        return _finish(sim, next_step, interior, bmap, solve, substeps_taken, cfl, seconds)


class MonolithicCoupling:
    """Strong coupling: the pressure solve sees the bodies' inertia (docs/method_notes.md).

    One step:

    1. map, classification and cut data from the bodies' current state (as the explicit
       scheme);
    2. the explicit part of the fluid's force, its viscous traction, from the current fields;
    3. the fluid's advection, viscosity and forces give the intermediate velocity ``w``;
    4. predictor: each body takes its explicit substeps under its elastic forces, gravity and
       that viscous traction, without the pressure: ``X*``, ``V*``;
    5. one pressure solve for fluid and bodies together: the flux balance of every cell counts
       the bodies' velocity ``V* + dv(p)``, where ``dv = dt A^-1 f_p`` is the body's linearised
       backward-Euler answer (`elastoflow.solid.ElasticBody.step_response`) to the pressure's
       nodal force ``f_p = h W^T D^T p`` (`elastoflow.coupling.interface_flux`). The system
       ``(L + rho h^2 DW A^-1 (DW)^T) p = rhs`` is symmetric positive definite (Robinson-Mosher,
       Schroeder & Fedkiw 2011), solved by CG with the fluid's multigrid as preconditioner;
    6. the bodies take ``dv``: ``V = V* + dv``, ``X = X* + (n+1)/(2n) dt dv`` (what ``n``
       substeps under the constant force ``f_p`` would add to the positions of a rigid body),
       and faces inside bodies their new velocity.

    No force relaxation and no added-mass estimate: the fluid that a body pushes answers in the
    same solve, so the added-mass instability of the explicit scheme does not arise for any
    density ratio.

    Args:
        gamma: Newmark's gamma (beta = gamma / 2, the family whose answer to a held force is
            ``dt/2 A^-1 f``). 0.5 conserves the energy of every mode, also the highest, which
            then ring undamped: a thin flag's thickness modes swung at 0.2 m/s with forces
            jumping by +-5 N/m from step to step. 0.55 (default) damps modes with
            ``omega dt >~ 1`` (radius 0.98 at 1, 0.91 at 10) and resolved ones little (about
            ``1 - 0.025 (omega dt)^2`` per step); 0.6 damps twice as hard.
    """

    name = "monolithic"

    def __init__(self, gamma: float = 0.55) -> None:
        if not 0.5 <= gamma <= 1.0:
            raise ValueError(f"gamma = {gamma!r}: must lie in [0.5, 1]")
        self.gamma = float(gamma)
        self._explicit = ExplicitCoupling()

    def step(self, sim: Simulation) -> StepReport:
        from elastoflow.coupling import (
            PressureCoupledBodies,
            build_boundary_map,
            force_traction,
            interface_flux,
            interior_boundary_from_map,
        )

        if not sim.bodies:
            # Nothing to couple: obstacles have prescribed velocities.
            return self._explicit.step(sim)
        seconds: dict[str, float] = {}
        clock = _time.perf_counter
        dt, fluid, state, grid = sim.dt, sim.fluid_solver, sim.state, sim.grid
        next_step = sim.step_index + 1
        where = f"step {next_step}, t = {sim.time + dt:.6g} s"

        t0 = clock()
        points, velocities, edges, edge_body, offsets = sim._boundary_arrays()
        bmap = build_boundary_map(grid, points, velocities, edges, edge_body)
        interior = interior_boundary_from_map(grid, bmap, out=sim.interior)
        seconds["map"] = clock() - t0

        t0 = clock()
        viscous = np.zeros_like(points)
        if fluid.viscosity > 0.0:
            viscous = force_traction(
                grid, bmap, state.velocity_x, state.velocity_y, np.zeros(grid.shape_cells),
                fluid.density, fluid.viscosity, interior,
            )
        seconds["coupling_force"] = clock() - t0

        _intermediate_velocity(sim, interior, next_step, seconds)

        t0 = clock()
        before = [(body.positions.copy(), body.velocities.copy()) for body in sim.bodies]
        # Newmark's matrix M + dt/2 D + dt^2/4 K: the predictor's Newton matrix and the body's
        # answer to the pressure in the coupled solve (the same rule, which keeps it stable).
        responses = [body.newmark_response(dt, self.gamma) for body in sim.bodies]
        substeps_taken: list[int] = []
        for index, body in enumerate(sim.bodies):
            try:
                body.advance_newmark(
                    dt, viscous[offsets[index]:offsets[index + 1]], responses[index],
                    step=next_step, gamma=self.gamma,
                )
            except Exception as error:  # re-raised with where it happened
                _restore(sim, before)
                raise SimulationBlowUp(f"{where}, body {index}: {error}") from error
            substeps_taken.append(1)
        # The flux balance counts what the bodies sweep over the step, their mean velocity
        # (X* - X^n) / dt; the answer to the pressure is Newmark's: mean velocity
        # dt/2 A^-1 f, end velocity twice that.
        predicted = np.array(velocities)
        for index, body in enumerate(sim.bodies):
            lo, hi = offsets[index], offsets[index + 1]
            predicted[lo:hi] = (body.positions - before[index][0]) / dt
        for index, obstacle in enumerate(sim.obstacles, start=len(sim.bodies)):
            predicted[offsets[index]:offsets[index + 1]] = obstacle.velocities_at(sim.time + dt)
        seconds["solid"] = clock() - t0

        t0 = clock()
        triangles = np.concatenate([body.mesh.triangles + offsets[index]
                                    for index, body in enumerate(sim.bodies)])
        triangle_offsets = np.cumsum([0] + [body.mesh.triangle_count for body in sim.bodies])
        coupled = PressureCoupledBodies(
            interface_flux(grid, bmap, interior, triangles, triangle_offsets), predicted,
            responses,
            offsets[:len(sim.bodies) + 1], fluid.density, dt, bmap=bmap,
            gravity=fluid.gravity,
        )
        try:
            solve = fluid.project(state, dt, interior, bodies=coupled)
        except ValueError:
            _restore(sim, before)
            sim._check_fluid(next_step)
            raise
        seconds["pressure"] = clock() - t0

        t0 = clock()
        for index, body in enumerate(sim.bodies):
            lo, hi = offsets[index], offsets[index + 1]
            change = coupled.velocities[lo:hi] - predicted[lo:hi]
            body.positions += dt * change
            body.velocities += 2.0 * change
            sim.body_forces[index] = viscous[lo:hi] + coupled.pressure_forces[lo:hi]
            determinants = body.deformation_determinants()
            if not (np.isfinite(body.positions).all() and determinants.min() > 0.0):
                element = int(np.argmin(np.nan_to_num(determinants, nan=-np.inf)))
                _restore(sim, before)
                raise SimulationBlowUp(
                    f"{where}, body {index}: the pressure's answer inverted element {element} "
                    f"(det F = {determinants[element]:.3g}); use a smaller dt"
                )
        seconds["solid"] += clock() - t0

        cfl = sim._check_fluid(next_step)
        sim.time += dt
        return _finish(sim, next_step, interior, bmap, solve, substeps_taken, cfl, seconds)


def _finish(sim: Simulation, step: int, interior: InteriorBoundary | None,
            bmap: BoundaryMap | None, solve: SolveReport, substeps: list[int], cfl: float,
            seconds: dict[str, float]) -> StepReport:
    """Commit the step index and this step's boundary data; the report of the step (the
    caller has advanced ``sim.time``)."""
    sim.step_index = step
    sim.interior = interior
    sim.boundary_map = bmap
    return StepReport(
        step=step,
        time=sim.time,
        pressure_iterations=int(solve.iterations),
        pressure_residual=float(solve.residual),
        substeps=substeps,
        cfl=cfl,
        crossing_count=0 if bmap is None else int(bmap.crossing_count),
        seconds_by_phase=seconds,
    )


def _intermediate_velocity(sim: Simulation, interior: InteriorBoundary | None, step: int,
                           seconds: dict[str, float]) -> None:
    """The fluid phases before the projection: advect, diffuse, apply forces (timed)."""
    clock = _time.perf_counter
    fluid, state, dt = sim.fluid_solver, sim.state, sim.dt
    t0 = clock()
    fluid.advect(state, dt, interior)
    seconds["advection"] = clock() - t0
    t0 = clock()
    try:
        fluid.diffuse(state, dt, interior)
    except ValueError:
        # A non-finite velocity stops the solver first: report the blow-up with its step.
        sim._check_fluid(step)
        raise
    seconds["viscosity"] = clock() - t0
    t0 = clock()
    fluid.apply_forces(state, dt, sim.time)
    seconds["forces"] = clock() - t0


def _restore(sim: Simulation, states: list[tuple[np.ndarray, np.ndarray]]) -> None:
    """Put the bodies back to the state they had at the start of the step."""
    for body, (positions, velocities) in zip(sim.bodies, states):
        body.positions[...] = positions
        body.velocities[...] = velocities


COUPLING_SCHEMES: dict[str, type[ExplicitCoupling | MonolithicCoupling]] = {
    "explicit": ExplicitCoupling,
    "monolithic": MonolithicCoupling,
}
