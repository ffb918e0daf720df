"""Elastic bodies and obstacles in a liquid with a free surface, strongly coupled.

`FreeSurfaceMonolithicCoupling` is `MonolithicCoupling`'s step on a liquid with a level set:
the pressure operator has both the bodies' open fractions and the surface's ghost-fluid terms
(`elastoflow.fluid._free_surface_bodies.GhostFluidCoupledProjection`); air cells hold p = 0
and are no unknowns, so the pressure pushes on a body only where liquid touches it. Floating
bodies are lighter than the water they displace: the explicit scheme's added-mass
instability rules it out, so only the strong coupling is offered.
"""

from __future__ import annotations

import math
import time as _time
from collections.abc import Sequence

import numpy as np

from elastoflow.coupling import BoundaryMap, PressureCoupledBodies
from elastoflow.fluid import FreeSurfaceSolver
from elastoflow.fluid._free_surface_bodies import (
    FreeSurfaceBodiesWorkspace,
    GhostFluidCoupledProjection,
    extrapolate_velocity_from_valid,
    transport_level_set_with_bodies,
    water_area,
)
from elastoflow.grid import Grid2D
from elastoflow.simulation._checks import check_fluid_finite
from elastoflow.simulation._free_surface import FreeSurfaceScheme
from elastoflow.simulation._report import StepReport
from elastoflow.simulation._schemes import (
    MonolithicCoupling,
    finish_step,
    _intermediate_velocity,
    _step_boundary,
    implicit_predictor,
    project_onto_walls,
    take_pressure_answer,
    wall_holds,
)
from elastoflow.simulation._state import CoupledModel, CoupledState
from elastoflow.solid import MidpointFem, NewmarkFem


def level_set_at(grid: Grid2D, level_set: np.ndarray, points: np.ndarray) -> np.ndarray:
    """The cell-centred ``level_set`` [m] (nx, ny) interpolated bilinearly at ``points`` [m]
    (P, 2); between the outer cell centres and the domain's sides, extrapolated linearly
    from the last two centres (a body lying on the floor is half a cell deeper than the
    lowest centres: held at their value, its buoyancy came out 10 % short); points
    outside the domain take its sides' values."""
    nx, ny = level_set.shape
    x = np.clip((points[:, 0] - grid.origin[0]) / grid.h - 0.5, -0.5, nx - 0.5)
    y = np.clip((points[:, 1] - grid.origin[1]) / grid.h - 0.5, -0.5, ny - 0.5)
    i = np.clip(np.floor(x).astype(np.int64), 0, nx - 2)
    j = np.clip(np.floor(y).astype(np.int64), 0, ny - 2)
    fx, fy = x - i, y - j
    return ((1 - fx) * (1 - fy) * level_set[i, j] + fx * (1 - fy) * level_set[i + 1, j]
            + (1 - fx) * fy * level_set[i, j + 1] + fx * fy * level_set[i + 1, j + 1])


def _clipped_shares(depth_a: np.ndarray, depth_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``int_0^1 max(0, d(t)) (1 - t) dt`` and ``int_0^1 max(0, d(t)) t dt`` for the linear
    ``d(t) = depth_a + (depth_b - depth_a) t`` (per edge): exact, two Gauss points on the part
    where d > 0 (the integrand is a quadratic there)."""
    a, b = depth_a, depth_b
    with np.errstate(divide="ignore", invalid="ignore"):
        crossing = np.where(a != b, a / (a - b), 0.0)
    start = np.where(a > 0.0, 0.0, np.clip(crossing, 0.0, 1.0))
    end = np.where(b > 0.0, 1.0, np.clip(crossing, 0.0, 1.0))
    end = np.where((a <= 0.0) & (b <= 0.0), start, end)
    half = 0.5 * (end - start)
    middle = 0.5 * (end + start)
    share_a = np.zeros_like(a)
    share_b = np.zeros_like(a)
    for node in (-1.0 / np.sqrt(3.0), 1.0 / np.sqrt(3.0)):
        t = middle + half * node
        d = np.maximum(a + (b - a) * t, 0.0)
        share_a += half * d * (1.0 - t)
        share_b += half * d * t
    return share_a, share_b


class FreeSurfaceCoupledBodies(PressureCoupledBodies):
    """`PressureCoupledBodies` in a liquid with a free surface.

    The hydrostatic part of the pressure, whose force ``W`` misses by up to half a cell of
    height on a straight edge inside a row of cells, is here ``rho |g| max(0, -phi)`` (depth
    below the surface from the signed distance ``phi``, carried across the bodies): its exact
    integral along the edges, where the edge lies in liquid, replaces ``W``'s force of the
    same field on the liquid cells. Air pushes on nothing.

    Args:
        level_set: The step's level set [m] (nx, ny).
        Others: as `PressureCoupledBodies`.
    """

    def __init__(self, flux, predicted: np.ndarray, responses: Sequence, offsets: Sequence[int],
                 density: float, dt: float, *, bmap, gravity: tuple[float, float],
                 level_set: np.ndarray) -> None:
        super().__init__(flux, predicted, responses, offsets, density, dt, bmap=bmap,
                         gravity=gravity)
        self.level_set = level_set

    def _hydrostatic_correction(self, active: np.ndarray) -> np.ndarray:
        """Exact minus ``W``'s nodal force of the hydrostatic pressure, per body (P, 2)."""
        correction = np.zeros_like(self.predicted)
        g = math.hypot(*self.gravity)
        bmap = self.bmap
        if bmap is None or g == 0.0 or len(self.offsets) < 2:
            return correction
        grid = self.flux.grid
        assert isinstance(grid, Grid2D) and isinstance(bmap, BoundaryMap)
        field = self.density * g * np.maximum(-self.level_set, 0.0)
        cells = self._cells(active)
        discrete = grid.h * cells.transpose_times(field).reshape(-1, 2)
        points, edges = bmap.points, bmap.edges
        depth = -level_set_at(grid, self.level_set, points)
        for index in range(len(self.offsets) - 1):
            lo, hi = self.offsets[index], self.offsets[index + 1]
            mine = edges[(edges[:, 0] >= lo) & (edges[:, 0] < hi)]
            if not mine.shape[0]:
                continue
            share_a, share_b = _clipped_shares(depth[mine[:, 0]], depth[mine[:, 1]])
            edge = points[mine[:, 1]] - points[mine[:, 0]]
            # -p n ds with n ds = (dy, -dx), out of the body (on the right of a->b).
            normal = np.column_stack((edge[:, 1], -edge[:, 0])) * (self.density * g)
            nodal = np.zeros((hi - lo, 2))
            np.add.at(nodal, mine[:, 0] - lo, -normal * share_a[:, None])
            np.add.at(nodal, mine[:, 1] - lo, -normal * share_b[:, None])
            correction[lo:hi] = nodal - discrete[lo:hi]
        return correction


class FreeSurfaceMonolithicCoupling(FreeSurfaceScheme):
    """Elastic bodies and obstacles in a liquid with a free surface, strongly coupled.

    One step (`MonolithicCoupling`'s, on the liquid):

    1. map, classification and cut data from the bodies' current state;
    2. the level set moves with the last step's velocity (`LevelSetTransport` of the
       solver), is carried across the bodies (linear extrapolation from outside into the
       cells whose centre lies in a body, so that a floating body's surface is straight
       through it and a body leaving the water is not filled), redistanced, and its water
       outside the bodies kept (the volume correction's target is taken on the first step);
    3. the viscous traction from the current fields, on the nodes in the liquid only;
    4. the fluid's own advection, viscosity and gravity with the bodies' cut data
       (`FluidSolver.predict`; the viscosity is the whole grid's, as `ViscosityWholeGrid`:
       the solver's stress-free viscosity does not know bodies);
    5. each body's implicit predictor; one coupled solve with the bodies' open fractions
       and the surface's ghost-fluid terms (`GhostFluidCoupledProjection`); the bodies take
       the pressure's answer, with the hydrostatic part integrated exactly below the surface
       (`FreeSurfaceCoupledBodies`);
    6. the velocity is extrapolated from the liquid and the bodies' closed faces into the air.

    Contact with the floor and walls is the model's (`CoupledModel.contact`): components of
    nodes resting on a wall are held inside the implicit step and its answer to the pressure,
    nodes that end a step beyond a wall are put back onto it (`elastoflow.solid._contact`).

    Args:
        solver: The free-surface solver (its transport, ``theta_min`` and extrapolation layers
            are used); its ``fluid`` must be the simulation's fluid solver, preferably with
            ``advection="semi_lagrangian"``.
        gamma, integrator: The bodies' implicit step, as `MonolithicCoupling`.
    """

    name = "free_surface_monolithic"

    def __init__(self, solver: FreeSurfaceSolver, *, gamma: float | None = None,
                 integrator: MidpointFem | NewmarkFem | None = None) -> None:
        super().__init__(solver)
        self.monolithic = MonolithicCoupling(gamma=gamma, integrator=integrator)
        self.fem = self.monolithic.fem
        self.projection = GhostFluidCoupledProjection(solver.projection.theta_min)
        self.workspace = FreeSurfaceBodiesWorkspace(solver.grid)

    def check_model(self, model: CoupledModel) -> None:
        """Raise ValueError for a model this scheme cannot step (another fluid solver)."""
        if model.fluid is not self.solver.fluid:
            raise ValueError("FreeSurfaceMonolithicCoupling: the solver's fluid must be the "
                             "simulation's fluid solver")

    def step(self, model: CoupledModel, state_in: CoupledState, state_out: CoupledState,
             dt: float) -> StepReport:
        """One coupled step of ``dt`` [s] from ``state_in`` into ``state_out``."""
        if not model.has_boundaries:
            return super().step(model, state_in, state_out, dt)
        if state_in.level_set is None or state_in.liquid_area is None:
            raise ValueError("FreeSurfaceMonolithicCoupling: the state has no level set "
                             "(call prepare)")
        from elastoflow.coupling import build_boundary_map, force_traction, interface_flux

        seconds: dict[str, float] = {}
        clock = _time.perf_counter
        fluid, grid, workspace = model.fluid, model.grid, self.workspace
        next_step = state_in.step_index + 1
        where = f"step {next_step}, t = {state_in.time + dt:.6g} s"
        state_out.assign(state_in)
        out = state_out.fluid
        level_set = state_out.level_set
        assert level_set is not None

        t0 = clock()
        offsets = model.object_offsets()
        points, velocities, edges, edge_body = model.boundary_points(state_in)
        bmap = build_boundary_map(grid, points, velocities, edges, edge_body)
        boundary = _step_boundary(model, bmap, state_out)
        interior = boundary.interior
        seconds["map"] = clock() - t0

        t0 = clock()
        target = float(state_in.liquid_area)
        if state_in.step_index == 0:
            # The water the run keeps: outside the bodies where they start.
            target = water_area(level_set, interior, grid.h, workspace)
        transport_level_set_with_bodies(
            self.solver.transport, grid, level_set, out.velocity_x, out.velocity_y, dt,
            state_in.step_index, target, interior, workspace)
        state_out.liquid_area = target
        seconds["level_set"] = clock() - t0

        body_count = len(model.bodies)
        t0 = clock()
        viscous = np.zeros_like(points)
        if fluid.viscosity > 0.0 and body_count:
            viscous = force_traction(
                grid, bmap, out.velocity_x, out.velocity_y, np.zeros(grid.shape_cells),
                fluid.density, fluid.viscosity, interior,
            )
            viscous[level_set_at(grid, level_set, points) >= 0.0] = 0.0
        seconds["coupling_force"] = clock() - t0

        projection_dt = _intermediate_velocity(model, state_out, interior, dt, next_step,
                                               seconds)

        t0 = clock()
        holds = wall_holds(model, state_in, dt)
        responses, substeps_taken = implicit_predictor(self.fem, model, state_in, state_out,
                                                       dt, viscous, offsets, holds,
                                                       next_step, where)
        predicted = np.array(velocities)
        for index in range(body_count):
            lo, hi = offsets[index], offsets[index + 1]
            predicted[lo:hi] = (state_out.bodies[index].positions
                                - state_in.bodies[index].positions) / dt
        for index, obstacle in enumerate(model.obstacles, start=body_count):
            predicted[offsets[index]:offsets[index + 1]] = obstacle.velocities_at(
                state_in.time + dt)
        seconds["solid"] = clock() - t0

        t0 = clock()
        triangles = (np.concatenate([body.mesh.triangles + offsets[index]
                                     for index, body in enumerate(model.bodies)])
                     if body_count else np.zeros((0, 3), dtype=np.int64))
        triangle_offsets = np.cumsum([0] + [body.mesh.triangle_count for body in model.bodies])
        coupled = FreeSurfaceCoupledBodies(
            interface_flux(grid, bmap, interior, triangles, triangle_offsets), predicted,
            responses, offsets[:body_count + 1].tolist(), fluid.density, projection_dt,
            bmap=bmap, gravity=fluid.gravity, level_set=level_set,
        )
        try:
            solve = self.projection.project(fluid, out, level_set, projection_dt, interior,
                                            coupled, workspace)
        except ValueError:
            check_fluid_finite(out, next_step, state_in.time + dt)
            raise
        seconds["pressure"] = clock() - t0

        t0 = clock()
        take_pressure_answer(model.bodies, state_out, offsets, predicted, coupled, viscous, dt,
                             where)
        project_onto_walls(model, state_out, holds)
        seconds["solid"] += clock() - t0

        t0 = clock()
        extrapolate_velocity_from_valid(out, self.solver.extrapolation_layers, workspace)
        seconds["extrapolation"] = clock() - t0
        check_fluid_finite(out, next_step, state_in.time + dt)
        return finish_step(model, state_in, state_out, dt, boundary, solve, substeps_taken, seconds)
