"""Incompressible fluid on the MAC grid: state, domain boundaries, jets, solver phases.

``FluidSolver`` advances a ``FluidState`` by stable fluids (METHOD.md §3): semi-Lagrangian or
MacCormack advection, implicit viscosity, forces, and a projection whose faces are weighted by
their open fraction so that bodies described by an ``InteriorBoundary`` (METHOD.md §6) enter
with cut-distance boundary conditions. ``divergence_faces_to_cells`` and
``gradient_cells_to_faces`` are the discrete operators the projection is built from.
Validation: docs/validation_fluid.md.
"""

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
from elastoflow.fluid._kernels import OPEN_MIN
from elastoflow.fluid._operators import divergence_faces_to_cells, gradient_cells_to_faces
from elastoflow.fluid._solver import CoupledBodies, FluidSolver, FluidStepReport
from elastoflow.fluid._state import FluidState

__all__ = [
    "OPEN_MIN",
    "CoupledBodies",
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
