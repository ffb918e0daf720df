"""The coupled simulation: owns the fluid state, bodies, obstacles, boundary maps and time."""

from elastoflow.simulation._simulation import (
    FORCE_MODELS,
    Simulation,
    SimulationBlowUp,
    StepReport,
)

__all__ = ["FORCE_MODELS", "Simulation", "SimulationBlowUp", "StepReport"]
