from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Literal

import numpy as np

from elastoflow.grid import Grid2D
from elastoflow.simulation._report import SimulationBlowUp, StepReport
from elastoflow.simulation._schemes import (
    COUPLING_SCHEMES,
    CouplingScheme,
)

ForceModel = Literal["traction", "momentum_exchange"]
FORCE_MODELS: tuple[str, ...] = ("traction", "momentum_exchange")


class Simulation:
    """Fluid, elastic bodies and static obstacles, coupled through the boundary map.

    One `step` (METHOD.md §8): build the x- and y-maps from every boundary edge, classify the
    grid and set velocities inside bodies; advect, diffuse and force the fluid; take the
    momentum-exchange force from that intermediate velocity; project with cut-face fractions;
    take the traction force from the projected fields; advance each body by its substeps under
    the chosen force, held constant across them.

    The coupling is explicit (partitioned): a body much lighter than the fluid it displaces
    makes it unstable (added-mass effect). Such runs stop with `SimulationBlowUp` naming the
    step and what diverged instead of writing garbage.

    Args:
        grid: The MAC grid.
        fluid_solver: An `elastoflow.fluid.FluidSolver` on ``grid``.
        state: Initial fluid state (zeros if None).
        bodies: Elastic bodies (`elastoflow.solid.ElasticBody`).
        obstacles: Static or prescribed-motion obstacles (`elastoflow.coupling.Obstacle`).
        dt: Fluid time step [s].
        substeps: FEM substeps per fluid step, or "auto" for the stability bound.
        force_model: Which fluid→solid force drives the bodies: "traction" (pressure and
            viscous stress integrated along the edges) or "momentum_exchange" (paper eq. 8).
        alpha: Volume fraction α of the momentum-exchange model.
        cfl_limit: Stop when max |u| dt / h exceeds this (semi-Lagrangian advection is stable
            beyond 1, but a jump this large means the run has diverged).
        force_relaxation: Under-relaxation ``omega`` in (0, 1] of the force handed to the
            bodies: ``F_applied^n = F_applied^(n-1) + omega (F^n - F_applied^(n-1))``. 1 (the
            default) applies each step's force as computed. Explicit coupling feeds the
            pressure's answer to the body's last acceleration back as ``-m_a a^(n-1)``, which
            diverges when the added mass ``m_a`` exceeds the body's mass (slender or light
            bodies); relaxation damps that feedback (stable for roughly
            ``omega (1 + m_a / m_s) < 2``) at the price of a lag of about ``dt / omega`` in
            the force, and leaves steady forces unchanged.
        added_mass: Coefficient ``c`` of the added-mass stabilisation for bodies lighter than
            the fluid they displace (0, the default, is plain explicit coupling). Each
            boundary node gets the extra inertia ``c rho_f l_i R`` (``l_i`` its share of the
            boundary length, ``R`` half the body's largest rest extent: about the added mass of
            the body moving broadside), and the force ``m_i (v^n - v^(n-1)) / dt`` that cancels
            it at constant acceleration. The fluid's pressure answers the body's last
            acceleration with ``-m_a a^(n-1)``; the body then sees
            ``a^n = (F + (m~ - m_a) a^(n-1)) / (m_s + m~)``, stable whenever
            ``m~ > (m_a - m_s) / 2`` and equal to the physical ``F / (m_s + m_a)`` once the
            acceleration settles. 0 gives plain explicit coupling.
        coupling: The coupling scheme: "explicit" (the paper's partitioned step,
            `ExplicitCoupling`) or "monolithic" (the pressure solve sees the bodies' inertia,
            `MonolithicCoupling`; stable for any density ratio without relaxation), or a
            scheme object.
    """

    def __init__(
        self,
        grid: Grid2D,
        fluid_solver: Any,
        *,
        state: Any = None,
        bodies: Sequence[Any] = (),
        obstacles: Sequence[Any] = (),
        dt: float,
        substeps: int | Literal["auto"] = "auto",
        force_model: ForceModel = "traction",
        alpha: float = 0.5,
        cfl_limit: float = 20.0,
        force_relaxation: float = 1.0,
        added_mass: float = 0.0,
        coupling: str | CouplingScheme = "explicit",
    ) -> None:
        from elastoflow.fluid import FluidState

        if not (dt > 0.0 and np.isfinite(dt)):
            raise ValueError(f"dt = {dt!r}: must be a finite positive time step [s]")
        if force_model not in FORCE_MODELS:
            raise ValueError(f"force_model = {force_model!r}: must be one of {FORCE_MODELS}")
        if substeps != "auto" and not (
            isinstance(substeps, (int, float)) and np.isfinite(substeps)
            and int(substeps) == substeps and substeps >= 1
        ):
            raise ValueError(f"substeps = {substeps!r}: must be a positive integer or 'auto'")
        if not 0.0 < alpha <= 1.0:
            raise ValueError(f"alpha = {alpha!r}: must lie in (0, 1]")
        if not 0.0 < force_relaxation <= 1.0:
            raise ValueError(
                f"force_relaxation = {force_relaxation!r}: must lie in (0, 1] (1: no relaxation)"
            )
        if not (0.0 <= added_mass < np.inf):
            raise ValueError(f"added_mass = {added_mass!r}: must be a finite number >= 0")
        if isinstance(coupling, str):
            if coupling not in COUPLING_SCHEMES:
                raise ValueError(
                    f"coupling = {coupling!r}: must be one of {tuple(COUPLING_SCHEMES)}"
                )
            scheme: CouplingScheme = COUPLING_SCHEMES[coupling]()
        else:
            scheme = coupling
        if scheme.name == "monolithic" and (force_relaxation != 1.0 or added_mass != 0.0):
            raise ValueError(
                "force_relaxation and added_mass belong to the explicit coupling; the monolithic "
                "coupling needs neither (leave them at 1 and 0)"
            )
        self.scheme = scheme
        self.grid = grid
        self.fluid_solver = fluid_solver
        self.state = state if state is not None else FluidState.zeros(grid)
        self.bodies = list(bodies)
        self.obstacles = list(obstacles)
        self.dt = float(dt)
        self.substeps = substeps
        self.force_model = force_model
        self.alpha = float(alpha)
        self.cfl_limit = float(cfl_limit)
        self.time = 0.0
        self.step_index = 0
        self.interior: Any = None
        self.boundary_map: Any = None
        self.body_forces: list[np.ndarray] = [np.zeros_like(b.positions) for b in self.bodies]
        self.last_report: StepReport | None = None
        self.force_relaxation = float(force_relaxation)
        self.added_mass_coefficient = float(added_mass)
        self.added_mass = [
            _added_mass_estimate(body, fluid_solver.density, self.added_mass_coefficient)
            for body in self.bodies
        ]
        # Body velocities at the start of the previous step, for the added-mass correction.
        self._previous_velocities = [b.velocities.copy() for b in self.bodies]

    # -- boundary geometry -------------------------------------------------------------

    def _boundary_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, list[int]]:
        """All boundary points, their velocities, edges, edge body ids, and point offsets.

        Bodies contribute all their nodes (interior nodes are simply not on any edge), so a
        nodal force array over these points slices straight into per-body forces.
        """
        points, velocities, edges, edge_body, offsets = [], [], [], [], [0]
        for index, body in enumerate(self.bodies):
            points.append(body.positions)
            velocities.append(body.velocities)
            edges.append(body.mesh.boundary_edges + offsets[-1])
            edge_body.append(np.full(len(body.mesh.boundary_edges), index, dtype=np.int64))
            offsets.append(offsets[-1] + len(body.positions))
        for index, obstacle in enumerate(self.obstacles, start=len(self.bodies)):
            p = obstacle.points_at(self.time)
            points.append(p)
            velocities.append(obstacle.velocities_at(self.time))
            edges.append(obstacle.edges + offsets[-1])
            edge_body.append(np.full(len(obstacle.edges), index, dtype=np.int64))
            offsets.append(offsets[-1] + len(p))
        return (
            np.ascontiguousarray(np.concatenate(points), dtype=np.float64),
            np.ascontiguousarray(np.concatenate(velocities), dtype=np.float64),
            np.ascontiguousarray(np.concatenate(edges), dtype=np.int64),
            np.concatenate(edge_body),
            offsets,
        )

    @property
    def has_boundaries(self) -> bool:
        return bool(self.bodies or self.obstacles)

    def traction_forces(self) -> list[np.ndarray]:
        """The fluid's traction on each body and obstacle, from the current fields.

        Pressure and viscous stress integrated along the boundary of the last step's map
        (`elastoflow.coupling.force_traction`), whatever force the coupling scheme itself
        used: one definition of "the force on an object" for every scheme, obstacles included.

        Returns:
            Nodal forces [N per metre of depth], one array per object, bodies first (shape
            (n_nodes, 2), zero on interior nodes) then obstacles (shape (vertices, 2)); all
            zero before the first step.
        """
        from elastoflow.coupling import force_traction

        counts = [len(body.positions) for body in self.bodies]
        counts += [obstacle.point_count for obstacle in self.obstacles]
        offsets = np.cumsum([0, *counts])
        if self.boundary_map is None:
            nodal = np.zeros((int(offsets[-1]), 2))
        else:
            fluid, state = self.fluid_solver, self.state
            nodal = force_traction(
                self.grid, self.boundary_map, state.velocity_x, state.velocity_y,
                state.pressure, fluid.density, fluid.viscosity, self.interior,
                gravity=fluid.gravity,
            )
        return [nodal[offsets[k]:offsets[k + 1]] for k in range(len(counts))]

    # -- the coupled step ----------------------------------------------------------------

    def step(self) -> StepReport:
        """Advance fluid and bodies by one fluid time step ``dt`` with the coupling scheme."""
        report = self.scheme.step(self)
        self.last_report = report
        return report

    def _check_fluid(self, step: int) -> float:
        """Raise `SimulationBlowUp` on non-finite fields or runaway CFL; return the CFL number."""
        state = self.state
        for name in ("velocity_x", "velocity_y", "pressure"):
            values = getattr(state, name)
            if not np.isfinite(values).all():
                bad = np.argwhere(~np.isfinite(values))[0]
                raise SimulationBlowUp(
                    f"step {step}, t = {self.time + self.dt:.6g} s: fluid {name} is not finite "
                    f"at index {tuple(int(i) for i in bad)}"
                )
        speed = max(float(np.abs(state.velocity_x).max()), float(np.abs(state.velocity_y).max()))
        cfl = speed * self.dt / self.grid.h
        if cfl > self.cfl_limit:
            raise SimulationBlowUp(
                f"step {step}, t = {self.time + self.dt:.6g} s: CFL number {cfl:.3g} "
                f"(max speed {speed:.3g} m/s) exceeds the limit {self.cfl_limit:g}; the coupling "
                "has diverged (a body much lighter than the fluid, or dt too large)"
            )
        return cfl

    def run(self, steps: int, callbacks: Sequence[Any] = ()) -> list[StepReport]:
        """Take ``steps`` steps, calling each ``callback(simulation, report)`` after each."""
        reports = []
        for _ in range(int(steps)):
            report = self.step()
            for callback in callbacks:
                callback(self, report)
            reports.append(report)
        return reports

    # -- checkpoints -----------------------------------------------------------------------

    def checkpoint(self) -> dict[str, np.ndarray]:
        """Everything the next step depends on, as arrays (bit-exact resume)."""
        data: dict[str, np.ndarray] = {
            "time": np.array(self.time),
            "step_index": np.array(self.step_index),
            "fluid_velocity_x": self.state.velocity_x.copy(),
            "fluid_velocity_y": self.state.velocity_y.copy(),
            "fluid_pressure": self.state.pressure.copy(),
            "fluid_dye": self.state.dye.copy(),
        }
        for index, body in enumerate(self.bodies):
            data[f"body{index}_positions"] = body.positions.copy()
            data[f"body{index}_velocities"] = body.velocities.copy()
            data[f"body{index}_previous_velocities"] = self._previous_velocities[index].copy()
            data[f"body{index}_forces"] = self.body_forces[index].copy()
        return data

    def restore(self, data: dict[str, np.ndarray]) -> None:
        """Put the simulation back into the state saved by `checkpoint`."""
        body_keys = {k for k in data if k.startswith("body")}
        names = ("positions", "velocities", "previous_velocities", "forces")
        expected = {f"body{i}_{n}" for i in range(len(self.bodies)) for n in names}
        if body_keys != expected:
            raise ValueError(
                f"checkpoint bodies {sorted(body_keys)}: must match this scene's "
                f"{len(self.bodies)} bodies"
            )
        self.time = float(data["time"])
        self.step_index = int(data["step_index"])
        for name in ("velocity_x", "velocity_y", "pressure", "dye"):
            target = getattr(self.state, name)
            source = np.asarray(data[f"fluid_{name}"])
            if source.shape != target.shape:
                raise ValueError(
                    f"checkpoint fluid_{name} shape {source.shape}: must be {target.shape}"
                )
            target[...] = source
        for index, body in enumerate(self.bodies):
            body.positions[...] = data[f"body{index}_positions"]
            body.velocities[...] = data[f"body{index}_velocities"]
            self._previous_velocities[index][...] = data[f"body{index}_previous_velocities"]
            self.body_forces[index] = np.array(data[f"body{index}_forces"], dtype=np.float64)


def _added_mass_estimate(body: Any, fluid_density: float, coefficient: float) -> np.ndarray:
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
