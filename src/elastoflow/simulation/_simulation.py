from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np

from elastoflow.coupling import (
    BoundaryMap,
    BoundaryMap3D,
    BoundaryTreatment,
    Obstacle,
    Obstacle3D,
    boundary_treatment,
)
from elastoflow.fluid import (
    FluidSolver,
    FluidSolver3D,
    FluidState,
    FluidState3D,
    InteriorBoundary,
    InteriorBoundary3D,
)
from elastoflow.grid import Grid2D, Grid3D
from elastoflow.simulation._checks import CflLimit, FiniteFields, StepCheck, cfl_number
from elastoflow.simulation._free_surface import FreeSurfaceScheme
from elastoflow.simulation._report import SimulationBlowUp, StepReport
from elastoflow.simulation._schemes import (
    COUPLING_SCHEMES,
    CouplingScheme,
    ExplicitCoupling,
    ForceModel,
    MonolithicCoupling,
)
from elastoflow.simulation._schemes3d import ExplicitCoupling3D, MonolithicCoupling3D, Scheme3D
from elastoflow.simulation._state import CoupledModel, CoupledModel3D, CoupledState
from elastoflow.solid import BodyModel, ElasticBody3D, WallContact


class Simulation:
    """Fluid, elastic bodies and static obstacles, coupled through the boundary map.

    A `CoupledModel` (what does not change), a `CoupledState` (what does), a coupling scheme
    (what steps one state into the next) and the checks each new state must pass. `step`
    lets the scheme write the next state into a second buffer, runs the checks on it and only
    then copies it into `state`: a step that fails (`SimulationBlowUp`, naming the step and
    what diverged) leaves `state` at the last good step. `state` and its arrays are the same
    objects for the whole run.

    The dimension follows the grid: a `elastoflow.grid.Grid3D` with a
    `elastoflow.fluid.FluidSolver3D` makes a 3D run (a `CoupledModel3D`, tetrahedral
    `elastoflow.solid.ElasticBody3D` bodies, `elastoflow.coupling.Obstacle3D` obstacles and
    the `ExplicitCoupling3D` or `MonolithicCoupling3D` scheme); the 2D-only options (the
    momentum-exchange force, added mass, boundary treatments other than the cut cell, a free
    surface) are refused there.

    Args:
        grid: The MAC grid (`Grid2D` or `Grid3D`).
        fluid_solver: A `elastoflow.fluid.FluidSolver` on ``grid`` (3D: `FluidSolver3D`).
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
            object. On a 3D grid: `ExplicitCoupling3D` / `MonolithicCoupling3D` (a 2D
            `MonolithicCoupling` object gives its integrator to the latter).
        checks: What each new state must pass; default `FiniteFields` and `CflLimit`.
        boundary: How the fluid sees bodies and obstacles: "cut_cell" (default: open
            fractions and cut distances from the boundary map), "staircase" (cells by their
            centres, faces open or closed), or a `elastoflow.coupling.BoundaryTreatment`.
        level_set: With ``coupling`` a `FreeSurfaceScheme`: the initial level set [m]
            (nx, ny), liquid where negative (required then, refused otherwise).
        contact: The bodies' contact with the domain's wall sides
            (`elastoflow.solid.WallContact`, default: on, friction 0.3), or None for none
            (2D and 3D).
    """

    def __init__(
        self,
        grid: Grid2D | Grid3D,
        fluid_solver: FluidSolver | FluidSolver3D,
        *,
        state: FluidState | FluidState3D | None = None,
        bodies: Sequence[BodyModel | ElasticBody3D] = (),
        obstacles: Sequence[Obstacle | Obstacle3D] = (),
        dt: float,
        substeps: int | Literal["auto"] = "auto",
        force_model: ForceModel = "traction",
        alpha: float = 0.5,
        cfl_limit: float = 20.0,
        force_relaxation: float = 1.0,
        added_mass: float = 0.0,
        coupling: str | CouplingScheme | Scheme3D = "explicit",
        checks: Sequence[StepCheck] | None = None,
        boundary: str | BoundaryTreatment = "cut_cell",
        level_set: np.ndarray | None = None,
        contact: WallContact | None = WallContact(),
    ) -> None:
        if not (dt > 0.0 and np.isfinite(dt)):
            raise ValueError(f"dt = {dt!r}: must be a finite positive time step [s]")
        self.dt = float(dt)
        self.checks: list[StepCheck] = (
            [FiniteFields(), CflLimit(cfl_limit)] if checks is None else list(checks)
        )
        self._next: CoupledState | None = None
        self.last_report: StepReport | None = None
        self.model: CoupledModel | CoupledModel3D
        self.scheme: CouplingScheme | Scheme3D
        if isinstance(grid, Grid3D):
            self._set_up_3d(grid, fluid_solver, state, bodies, obstacles, substeps,
                            force_model, force_relaxation, added_mass, coupling, boundary,
                            level_set, contact)
            return
        if not isinstance(fluid_solver, FluidSolver):
            raise ValueError(f"fluid_solver = {type(fluid_solver).__name__}: a 2D grid needs "
                             "an elastoflow.fluid.FluidSolver")
        if isinstance(coupling, ExplicitCoupling3D | MonolithicCoupling3D):
            raise ValueError(f"coupling = {type(coupling).__name__}: a 2D grid needs a 2D "
                             "scheme")
        if not all(isinstance(obstacle, Obstacle) for obstacle in obstacles):
            raise ValueError("obstacles: a 2D run takes elastoflow.coupling.Obstacle")
        if any(isinstance(body, ElasticBody3D) for body in bodies):
            raise ValueError("bodies: a 2D run takes 2D bodies, not ElasticBody3D")
        if state is not None and not isinstance(state, FluidState):
            raise ValueError("state: a 2D run takes an elastoflow.fluid.FluidState")
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
        model = CoupledModel(grid, fluid_solver,
                             tuple(body for body in bodies if not isinstance(body, ElasticBody3D)),
                             tuple(o for o in obstacles if isinstance(o, Obstacle)), treatment,
                             contact)
        self.model = model
        self.scheme = scheme
        self.state: CoupledState = model.state(state)
        if isinstance(scheme, FreeSurfaceScheme):
            scheme.check_model(model)
            if level_set is None:
                raise ValueError("a free-surface simulation needs level_set (the initial "
                                 "liquid, where it is negative)")
            scheme.prepare(self.state, level_set)
        elif level_set is not None:
            raise ValueError("level_set needs coupling = FreeSurfaceScheme(...)")

    def _set_up_3d(self, grid: Grid3D, fluid_solver: FluidSolver | FluidSolver3D,
                   state: FluidState | FluidState3D | None,
                   bodies: Sequence[BodyModel | ElasticBody3D],
                   obstacles: Sequence[Obstacle | Obstacle3D],
                   substeps: int | Literal["auto"], force_model: str, force_relaxation: float,
                   added_mass: float, coupling: object, boundary: object,
                   level_set: np.ndarray | None, contact: WallContact | None) -> None:
        """The 3D model and scheme; what 3D does not have yet is refused in one line."""
        if not isinstance(fluid_solver, FluidSolver3D):
            raise ValueError(f"fluid_solver = {type(fluid_solver).__name__}: a 3D grid needs "
                             "an elastoflow.fluid.FluidSolver3D")
        if state is not None and not isinstance(state, FluidState3D):
            raise ValueError("state: a 3D run takes an elastoflow.fluid.FluidState3D")
        for index, body in enumerate(bodies):
            if not isinstance(body, ElasticBody3D):
                raise ValueError(f"bodies[{index}] = {type(body).__name__}: a 3D run takes "
                                 "elastoflow.solid.ElasticBody3D")
        for index, obstacle in enumerate(obstacles):
            if not isinstance(obstacle, Obstacle3D):
                raise ValueError(f"obstacles[{index}] = {type(obstacle).__name__}: a 3D run "
                                 "takes elastoflow.coupling.Obstacle3D")
        refused = {
            "force_model": (force_model, "traction"),
            "added_mass": (added_mass, 0.0),
            "boundary": (boundary, "cut_cell"),
        }
        for name, (value, allowed) in refused.items():
            same = (isinstance(value, str) and value == allowed if isinstance(allowed, str)
                    else isinstance(value, int | float) and value == allowed)
            if not same:
                raise ValueError(f"{name} = {value!r}: a 3D run has only {allowed!r} so far")
        if level_set is not None:
            raise ValueError("level_set: a 3D run has no free surface so far")
        scheme: Scheme3D
        if isinstance(coupling, ExplicitCoupling3D | MonolithicCoupling3D):
            scheme = coupling
        elif isinstance(coupling, MonolithicCoupling):
            scheme = MonolithicCoupling3D(integrator=coupling.fem)
        elif isinstance(coupling, str) and coupling == "explicit":
            scheme = ExplicitCoupling3D(substeps, force_relaxation)
        elif isinstance(coupling, str) and coupling == "monolithic":
            scheme = MonolithicCoupling3D()
        else:
            raise ValueError(f"coupling = {coupling!r}: a 3D run takes 'explicit', "
                             "'monolithic', an ExplicitCoupling3D or a MonolithicCoupling3D")
        if scheme.name == "monolithic" and force_relaxation != 1.0:
            raise ValueError(f"force_relaxation = {force_relaxation!r}: the monolithic "
                             "scheme needs none (it must be 1)")
        model = CoupledModel3D(grid, fluid_solver,
                               tuple(b for b in bodies if isinstance(b, ElasticBody3D)),
                               tuple(o for o in obstacles if isinstance(o, Obstacle3D)),
                               contact)
        self.model = model
        self.scheme = scheme
        self.state = model.state(state)

    @property
    def dimension(self) -> int:
        """2 or 3."""
        return 3 if isinstance(self.model, CoupledModel3D) else 2

    # -- the model's parts, by their usual names ---------------------------------------------

    @property
    def grid(self) -> Grid2D | Grid3D:
        return self.model.grid

    @property
    def fluid_solver(self) -> FluidSolver | FluidSolver3D:
        return self.model.fluid

    @property
    def bodies(self) -> tuple[BodyModel | ElasticBody3D, ...]:
        return self.model.bodies

    @property
    def obstacles(self) -> tuple[Obstacle | Obstacle3D, ...]:
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
    def boundary_map(self) -> BoundaryMap | BoundaryMap3D | None:
        """The boundary map of the last step (None before the first)."""
        return None if self.state.boundary is None else self.state.boundary.boundary_map

    @property
    def interior(self) -> InteriorBoundary | InteriorBoundary3D | None:
        """The grid's classification of the last step (None before the first)."""
        return None if self.state.boundary is None else self.state.boundary.interior

    def body_geometry(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Each body's current node positions and its triangles, what drawing and mesh export
        need: in 2D the mesh's triangles, in 3D its outward surface triangles."""
        return [(state.positions, body.boundary_triangles if isinstance(body, ElasticBody3D)
                 else body.mesh.triangles)
                for body, state in zip(self.bodies, self.state.bodies)]

    def traction_forces(self) -> list[np.ndarray]:
        """The fluid's traction on each body and obstacle, from the current fields.

        Pressure and viscous stress integrated along the boundary of the last step's map
        (`elastoflow.coupling.force_traction`), whatever force the coupling scheme itself
        used: one definition of "the force on an object" for every scheme, obstacles included.

        Returns:
            Nodal forces [N per metre of depth], one array per object, bodies first (shape
            (n_nodes, 2), zero on interior nodes) then obstacles (shape (vertices, 2)); all
            zero before the first step. In 3D forces [N], shape (n, 3), on the surface
            triangles (`elastoflow.coupling.force_traction_3d`).
        """
        from elastoflow.coupling import force_traction, force_traction_3d

        offsets = self.model.object_offsets()
        boundary = self.state.boundary
        fluid, state = self.fluid_solver, self.state.fluid
        if boundary is None:
            nodal = np.zeros((int(offsets[-1]), self.dimension))
        elif isinstance(self.model, CoupledModel3D):
            nodal = force_traction_3d(
                self.model.grid, boundary.boundary_map, state.velocity_x, state.velocity_y,
                state.velocity_z, state.pressure, fluid.density, fluid.viscosity,
                boundary.interior, gravity=self.model.fluid.gravity,
            )
        else:
            assert isinstance(self.model, CoupledModel)
            nodal = force_traction(
                self.model.grid, boundary.boundary_map, state.velocity_x, state.velocity_y,
                state.pressure, fluid.density, fluid.viscosity, boundary.interior,
                gravity=self.model.fluid.gravity,
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
            if isinstance(self.scheme, ExplicitCoupling3D | MonolithicCoupling3D):
                assert isinstance(self.model, CoupledModel3D)
                report = self.scheme.step(self.model, self.state, self._next, self.dt)
            else:
                assert isinstance(self.model, CoupledModel)
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
