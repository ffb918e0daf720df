from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np

from elastoflow.coupling import BoundaryMap, BoundaryTreatment, Obstacle, boundary_treatment
from elastoflow.fluid import FluidSolver, FluidState, InteriorBoundary
from elastoflow.grid import Grid2D
from elastoflow.simulation._checks import CflLimit, FiniteFields, StepCheck, cfl_number
from elastoflow.simulation._free_surface import FreeSurfaceScheme
from elastoflow.simulation._report import SimulationBlowUp, StepReport
from elastoflow.simulation._schemes import (
    COUPLING_SCHEMES,
    CouplingScheme,
    ExplicitCoupling,
    ForceModel,
)
from elastoflow.simulation._state import CoupledModel, CoupledState
from elastoflow.solid import BodyModel


class Simulation:
    """Fluid, elastic bodies and static obstacles, coupled through the boundary map.

    A `CoupledModel` (what does not change), a `CoupledState` (what does), a coupling scheme
    (what steps one state into the next) and the checks each new state must pass. `step`
    lets the scheme write the next state into a second buffer, runs the checks on it and only
    then copies it into `state`: a step that fails (`SimulationBlowUp`, naming the step and
    what diverged) leaves `state` at the last good step. `state` and its arrays are the same
    objects for the whole run.

    Args:
        grid: The MAC grid.
        fluid_solver: A `elastoflow.fluid.FluidSolver` on ``grid``.
        state: Initial fluid state (zeros if None).
        bodies: Elastic bodies' models (`elastoflow.solid.ElasticBody`, or a rod,
            `elastoflow.solid.RodBody`, under the monolithic scheme); each starts from its
            ``state()``.
        obstacles: Static or prescribed-motion obstacles (`elastoflow.coupling.Obstacle`).
        dt: Fluid time step [s].
        substeps: Explicit scheme: FEM substeps per fluid step, or "auto" for the stability
            bound (the monolithic scheme takes one implicit step).
        force_model: Explicit scheme: "traction" or "momentum_exchange" (paper eq. 8).
        alpha: Explicit scheme: volume fraction of the momentum-exchange model.
        cfl_limit: Stop when max |u| dt / h exceeds this (`CflLimit`).
        force_relaxation: Explicit scheme: under-relaxation of the force (1: none).
        added_mass: Explicit scheme: coefficient of the added-mass estimate (0: off).
        coupling: "explicit" (the paper's partitioned step, `ExplicitCoupling`, built from the
            keys above) or "monolithic" (`MonolithicCoupling`: the pressure solve sees the
            bodies' inertia, stable for any density ratio without relaxation), or a scheme
            object.
        checks: What each new state must pass; default `FiniteFields` and `CflLimit`.
        boundary: How the fluid sees bodies and obstacles: "cut_cell" (default: open
            fractions and cut distances from the boundary map), "staircase" (cells by their
            centres, faces open or closed), or a `elastoflow.coupling.BoundaryTreatment`.
        level_set: With ``coupling`` a `FreeSurfaceScheme`: the initial level set [m]
            (nx, ny), liquid where negative (required then, refused otherwise).
    """

    def __init__(
        self,
        grid: Grid2D,
        fluid_solver: FluidSolver,
        *,
        state: FluidState | None = None,
        bodies: Sequence[BodyModel] = (),
        obstacles: Sequence[Obstacle] = (),
        dt: float,
        substeps: int | Literal["auto"] = "auto",
        force_model: ForceModel = "traction",
        alpha: float = 0.5,
        cfl_limit: float = 20.0,
        force_relaxation: float = 1.0,
        added_mass: float = 0.0,
        coupling: str | CouplingScheme = "explicit",
        checks: Sequence[StepCheck] | None = None,
        boundary: str | BoundaryTreatment = "cut_cell",
        level_set: np.ndarray | None = None,
    ) -> None:
        if not (dt > 0.0 and np.isfinite(dt)):
            raise ValueError(f"dt = {dt!r}: must be a finite positive time step [s]")
        explicit = ExplicitCoupling(substeps, force_model, alpha, force_relaxation, added_mass)
        if isinstance(coupling, str):
            if coupling not in COUPLING_SCHEMES:
                raise ValueError(
                    f"coupling = {coupling!r}: must be one of {tuple(COUPLING_SCHEMES)}"
                )
            scheme: CouplingScheme = explicit if coupling == "explicit" else (
                COUPLING_SCHEMES[coupling]())
        else:
            scheme = coupling
        if scheme.name == "monolithic" and (force_relaxation != 1.0 or added_mass != 0.0):
            raise ValueError(
                "force_relaxation and added_mass belong to the explicit coupling; the monolithic "
                "coupling needs neither (leave them at 1 and 0)"
            )
        treatment = boundary_treatment(boundary) if isinstance(boundary, str) else boundary
        self.model = CoupledModel(grid, fluid_solver, tuple(bodies), tuple(obstacles),
                                  treatment)
        self.scheme = scheme
        self.dt = float(dt)
        self.checks: list[StepCheck] = (
            [FiniteFields(), CflLimit(cfl_limit)] if checks is None else list(checks)
        )
        self.state: CoupledState = self.model.state(state)
        if isinstance(scheme, FreeSurfaceScheme):
            scheme.check_model(self.model)
            if level_set is None:
                raise ValueError("a free-surface simulation needs level_set (the initial "
                                 "liquid, where it is negative)")
            scheme.prepare(self.state, level_set)
        elif level_set is not None:
            raise ValueError("level_set needs coupling = FreeSurfaceScheme(...)")
        self._next: CoupledState | None = None
        self.last_report: StepReport | None = None

    # -- the model's parts, by their usual names ---------------------------------------------

    @property
    def grid(self) -> Grid2D:
        return self.model.grid

    @property
    def fluid_solver(self) -> FluidSolver:
        return self.model.fluid

    @property
    def bodies(self) -> tuple[BodyModel, ...]:
        return self.model.bodies

    @property
    def obstacles(self) -> tuple[Obstacle, ...]:
        return self.model.obstacles

    @property
    def has_boundaries(self) -> bool:
        return self.model.has_boundaries

    @property
    def force_model(self) -> str:
        """The force that drives the bodies: the explicit scheme's model, else "traction"."""
        return str(getattr(self.scheme, "force_model", "traction"))

    # -- the current state, by its usual names -------------------------------------------------

    @property
    def time(self) -> float:
        """Simulated time [s] of the current state."""
        return self.state.time

    @property
    def step_index(self) -> int:
        """Steps taken to reach the current state."""
        return self.state.step_index

    @property
    def level_set(self) -> np.ndarray | None:
        """The liquid's level set [m] (nx, ny), negative in the liquid; None without a free
        surface."""
        return self.state.level_set

    @property
    def body_forces(self) -> list[np.ndarray]:
        """The fluid force each body received in the last step [N/m], shape (n, 2)."""
        return self.state.body_forces

    @property
    def boundary_map(self) -> BoundaryMap | None:
        """The boundary map of the last step (None before the first)."""
        return None if self.state.boundary is None else self.state.boundary.boundary_map

    @property
    def interior(self) -> InteriorBoundary | None:
        """The grid's classification of the last step (None before the first)."""
        return None if self.state.boundary is None else self.state.boundary.interior

    def body_geometry(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Each body's current node positions and its triangles, what drawing and mesh export
        need."""
        return [(state.positions, body.mesh.triangles)
                for body, state in zip(self.bodies, self.state.bodies)]

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

        offsets = self.model.object_offsets()
        boundary = self.state.boundary
        if boundary is None:
            nodal = np.zeros((int(offsets[-1]), 2))
        else:
            fluid, state = self.fluid_solver, self.state.fluid
            nodal = force_traction(
                self.grid, boundary.boundary_map, state.velocity_x, state.velocity_y,
                state.pressure, fluid.density, fluid.viscosity, boundary.interior,
                gravity=fluid.gravity,
            )
        return [nodal[offsets[k]:offsets[k + 1]] for k in range(len(offsets) - 1)]

    # -- the coupled step ------------------------------------------------------------------

    def step(self) -> StepReport:
        """Advance fluid and bodies by one fluid time step ``dt`` with the coupling scheme.

        Raises:
            SimulationBlowUp: The step or a check failed; `state` is still the one before.
        """
        if self._next is None:
            self._next = self.state.copy()
        previous = self.state.boundary
        try:
            report = self.scheme.step(self.model, self.state, self._next, self.dt)
        except SimulationBlowUp as error:
            self._blame_the_fluid(error)
            raise
        for check in self.checks:
            check(self.model, self._next, self.dt, report)
        # Copied rather than swapped: `state` and its arrays stay the same objects for the
        # whole run (a user's reference to them stays valid), for a copy of 0.1 ms on
        # bar_in_jet (0.1-0.3 % of its step). The last step's boundary arrays go to the spare
        # state for reuse.
        self.state.assign(self._next)
        self.state.boundary, self._next.boundary = self._next.boundary, previous
        self.last_report = report
        return report

    def _blame_the_fluid(self, error: SimulationBlowUp) -> None:
        """A body that failed in a diverged flow (forces from a runaway velocity) is a
        symptom: raise what the checks find wrong with the fluid the step had reached, if
        anything, as the cause."""
        assert self._next is not None
        step = self.state.step_index + 1
        partial = StepReport(step=step, time=self.state.time + self.dt, pressure_iterations=0,
                             pressure_residual=float("nan"),
                             cfl=cfl_number(self.grid, self._next.fluid, self.dt))
        for check in self.checks:
            try:
                check(self.model, self._next, self.dt, partial)
            except SimulationBlowUp as cause:
                if "body" not in str(cause).split(":")[0]:
                    raise cause from error

    def run(self, steps: int, callbacks: Sequence[object] = ()) -> list[StepReport]:
        """Take ``steps`` steps, calling each ``callback(simulation, report)`` after each."""
        reports = []
        for _ in range(int(steps)):
            report = self.step()
            for callback in callbacks:
                callback(self, report)  # type: ignore[operator]
            reports.append(report)
        return reports

    # -- checkpoints -----------------------------------------------------------------------

    def checkpoint(self) -> dict[str, np.ndarray]:
        """The state's saved fields as arrays keyed by their path (bit-exact resume)."""
        return self.state.to_arrays()

    def restore(self, data: dict[str, np.ndarray]) -> None:
        """Put the simulation back into the state saved by `checkpoint`.

        Raises:
            ValueError: ``data`` belongs to another scene (other bodies or grid).
        """
        self.state.load_arrays(data)
