"""The coupled simulation: model (grid, fluid solver, bodies, obstacles), state (fluid fields,
body states, time), the coupling schemes that step one state into the next, and the checks
each new state must pass. In 3D: `CoupledModel3D`, `StepBoundary3D`, `ExplicitCoupling3D` and `MonolithicCoupling3D`,
behind the same `Simulation`."""

from elastoflow.simulation._checks import CflLimit, FiniteFields, StepCheck, cfl_number
from elastoflow.simulation._free_surface import FreeSurfaceScheme
from elastoflow.simulation._free_surface_bodies import FreeSurfaceMonolithicCoupling
from elastoflow.simulation._report import SimulationBlowUp, StepReport
from elastoflow.simulation._schemes import (
    COUPLING_SCHEMES,
    FORCE_MODELS,
    CouplingScheme,
    ExplicitCoupling,
    MonolithicCoupling,
)
from elastoflow.simulation._schemes3d import ExplicitCoupling3D, MonolithicCoupling3D
from elastoflow.simulation._simulation import Simulation
from elastoflow.simulation._state import (
    CoupledModel,
    CoupledModel3D,
    CoupledState,
    StepBoundary,
    StepBoundary3D,
)

__all__ = [
    "COUPLING_SCHEMES",
    "FORCE_MODELS",
    "CflLimit",
    "CoupledModel",
    "CoupledModel3D",
    "CoupledState",
    "CouplingScheme",
    "ExplicitCoupling",
    "ExplicitCoupling3D",
    "FiniteFields",
    "FreeSurfaceMonolithicCoupling",
    "FreeSurfaceScheme",
    "MonolithicCoupling",
    "MonolithicCoupling3D",
    "Simulation",
    "SimulationBlowUp",
    "StepBoundary",
    "StepBoundary3D",
    "StepCheck",
    "StepReport",
    "cfl_number",
]
