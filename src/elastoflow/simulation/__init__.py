"""The coupled simulation: owns the fluid state, bodies, obstacles, boundary maps and time."""

from elastoflow.simulation._report import SimulationBlowUp, StepReport
from elastoflow.simulation._schemes import (
    COUPLING_SCHEMES,
    CouplingScheme,
    ExplicitCoupling,
    MonolithicCoupling,
)
from elastoflow.simulation._simulation import FORCE_MODELS, Simulation

__all__ = [
    "COUPLING_SCHEMES",
    "FORCE_MODELS",
    "CouplingScheme",
    "ExplicitCoupling",
    "MonolithicCoupling",
    "Simulation",
    "SimulationBlowUp",
    "StepReport",
]
