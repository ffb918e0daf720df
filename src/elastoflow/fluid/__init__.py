"""Incompressible fluid on the MAC grid: state, domain boundaries, jets, solver phases."""

from elastoflow.fluid._boundaries import (
    DomainBoundaries,
    Inflow,
    Jet,
    Outflow,
    WallFreeSlip,
    WallMoving,
    WallNoSlip,
)
from elastoflow.fluid._interior import InteriorBoundary
from elastoflow.fluid._operators import divergence_faces_to_cells, gradient_cells_to_faces
from elastoflow.fluid._solver import FluidSolver, FluidStepReport
from elastoflow.fluid._state import FluidState

__all__ = [
    "DomainBoundaries",
    "FluidSolver",
    "FluidState",
    "FluidStepReport",
    "Inflow",
    "InteriorBoundary",
    "Jet",
    "Outflow",
    "WallFreeSlip",
    "WallMoving",
    "WallNoSlip",
    "divergence_faces_to_cells",
    "gradient_cells_to_faces",
]
