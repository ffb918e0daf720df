"""The free-surface scheme: a liquid with a level set, stepped as a `CouplingScheme`.

Bodies in the water are not in yet (issue 15, item 2: the coupling is being reworked), so the
scheme steps the fluid alone: `elastoflow.fluid.FreeSurfaceSolver` on the `CoupledState`'s
fluid fields and its ``level_set`` / ``liquid_area``, which checkpoints save like every other
field.
"""

from __future__ import annotations

import numpy as np

from elastoflow.fluid import FreeSurfaceSolver, FreeSurfaceState, liquid_area
from elastoflow.simulation._checks import cfl_number
from elastoflow.simulation._report import StepReport
from elastoflow.simulation._state import CoupledModel, CoupledState


class FreeSurfaceScheme:
    """Steps a liquid with a free surface (`elastoflow.fluid.FreeSurfaceSolver`).

    The state's ``level_set`` (liquid where negative) and ``liquid_area`` must be set
    (`prepare`); the model must have no bodies or obstacles.

    Args:
        solver: The free-surface solver; its ``fluid`` must be the model's fluid solver.
    """

    name = "free_surface"

    def __init__(self, solver: FreeSurfaceSolver) -> None:
        if not isinstance(solver, FreeSurfaceSolver):
            raise ValueError(f"FreeSurfaceScheme solver = {solver!r}: must be a FreeSurfaceSolver")
        self.solver = solver

    def check_model(self, model: CoupledModel) -> None:
        """Raise ValueError for a model this scheme cannot step."""
        if model.has_boundaries:
            raise ValueError(
                f"a free surface with bodies or obstacles ({len(model.bodies)} bodies, "
                f"{len(model.obstacles)} obstacles) is not supported yet; run the liquid alone"
            )
        if model.fluid is not self.solver.fluid:
            raise ValueError("FreeSurfaceScheme: the solver's fluid must be the simulation's "
                             "fluid solver")

    def prepare(self, state: CoupledState, level_set: np.ndarray) -> None:
        """Give ``state`` the liquid where ``level_set`` [m] (nx, ny) is negative, and the area
        the volume correction keeps."""
        surface = FreeSurfaceState.create(self.solver.grid, level_set, state.fluid)
        state.level_set = surface.level_set
        state.liquid_area = float(liquid_area(surface.level_set, self.solver.grid.h))

    def step(self, model: CoupledModel, state_in: CoupledState, state_out: CoupledState,
             dt: float) -> StepReport:
        """One free-surface step of ``dt`` [s] from ``state_in`` into ``state_out``."""
        if state_in.level_set is None or state_in.liquid_area is None:
            raise ValueError("FreeSurfaceScheme: the state has no level set (call prepare)")
        state_out.assign(state_in)
        assert state_out.level_set is not None
        surface = FreeSurfaceState(state_out.fluid, state_out.level_set,
                                   float(state_in.liquid_area), state_in.step_index)
        report = self.solver.step(surface, dt, state_in.time)
        state_out.time = state_in.time + dt
        state_out.step_index = state_in.step_index + 1
        return StepReport(
            step=state_out.step_index, time=state_out.time,
            pressure_iterations=report.pressure_iterations,
            pressure_residual=report.pressure_residual,
            cfl=cfl_number(model.grid, state_out.fluid, dt),
            seconds_by_phase=dict(report.seconds_by_phase),
        )
