"""The coupled simulation: model (grid, fluid solver, bodies, obstacles), state (fluid fields,
body states, time), the coupling schemes that step one state into the next, and the checks
each new state must pass."""

from elastoflow.simulation._checks import CflLimit, FiniteFields, StepCheck, cfl_number
from elastoflow.simulation._free_surface import FreeSurfaceScheme
from elastoflow.simulation._report import SimulationBlowUp, StepReport
from elastoflow.simulation._schemes import (
    COUPLING_SCHEMES,
    FORCE_MODELS,
    CouplingScheme,
    ExplicitCoupling,
    MonolithicCoupling,
)
from elastoflow.simulation._simulation import Simulation
from elastoflow.simulation._state import CoupledModel, CoupledState, StepBoundary

__all__ = [
    "COUPLING_SCHEMES",
    "FORCE_MODELS",
    "CflLimit",
    "CoupledModel",
    "CoupledState",
    "CouplingScheme",
    "ExplicitCoupling",
    "FiniteFields",
    "FreeSurfaceScheme",
    "MonolithicCoupling",
    "Simulation",
    "SimulationBlowUp",
    "StepBoundary",
    "StepCheck",
    "StepReport",
    "cfl_number",
]
