"""Incompressible fluid on the MAC grid: state, domain boundaries, jets, solver phases.

``FluidSolver`` advances a ``FluidState`` by stable fluids (METHOD.md §3): semi-Lagrangian or
MacCormack advection, implicit viscosity, forces, and a projection whose faces are weighted by
their open fraction so that bodies described by an ``InteriorBoundary`` (METHOD.md §6) enter
with cut-distance boundary conditions. ``divergence_faces_to_cells`` and
``gradient_cells_to_faces`` are the discrete operators the projection is built from;
``MomentumBalance`` the force on what a box of cells holds, from the momentum balance.
``FreeSurfaceSolver`` adds a free surface (a level set in ``FreeSurfaceState``, a ghost-fluid
projection, ``LevelSetTransport``). In 3D: ``FluidSolver3D`` on a ``FluidState3D`` with
``DomainBoundaries3D``, bodies through ``InteriorBoundary3D``. Validation: docs/validation_fluid.md, and for the free
surface docs/validation/free_surface.md, for 3D docs/validation/three_d.md.
"""

from elastoflow.fluid._balance import BoxCells, MomentumBalance
from elastoflow.fluid._boundaries import (
    DomainBoundaries,
    Inflow,
    Jet,
    Outflow,
    WallFreeSlip,
    WallMoving,
    WallNoSlip,
)
from elastoflow.fluid._free_surface import (
    FreeSurfaceSolver,
    FreeSurfaceState,
    FreeSurfaceStepReport,
    GhostFluidProjection,
    ViscosityStressFree,
    ViscosityWholeGrid,
)
from elastoflow.fluid._boundaries3d import (
    DomainBoundaries3D,
    Jet3D,
    Side3D,
    WallMoving3D,
    inflow_profile_3d,
)
from elastoflow.fluid._interior import InteriorBoundary
from elastoflow.fluid._interior3d import InteriorBoundary3D
from elastoflow.fluid._kernels import OPEN_MIN
from elastoflow.fluid._level_set import (
    LevelSetTransport,
    RedistanceFastSweeping,
    correct_volume,
    level_set_below,
    level_set_box,
    level_set_from_function,
    liquid_area,
)
from elastoflow.fluid._operators import divergence_faces_to_cells, gradient_cells_to_faces
from elastoflow.fluid._solver import (
    CoupledBodies,
    FluidPrediction,
    FluidSolver,
    FluidStepReport,
)
from elastoflow.fluid._solver3d import FluidSolver3D
from elastoflow.fluid._state import FluidState
from elastoflow.fluid._state3d import FluidState3D

__all__ = [
    "OPEN_MIN",
    "BoxCells",
    "CoupledBodies",
    "DomainBoundaries",
    "DomainBoundaries3D",
    "FluidPrediction",
    "FluidSolver",
    "FluidSolver3D",
    "FluidState",
    "FluidState3D",
    "FluidStepReport",
    "FreeSurfaceSolver",
    "FreeSurfaceState",
    "FreeSurfaceStepReport",
    "GhostFluidProjection",
    "Inflow",
    "InteriorBoundary",
    "InteriorBoundary3D",
    "Side3D",
    "Jet",
    "Jet3D",
    "LevelSetTransport",
    "MomentumBalance",
    "Outflow",
    "RedistanceFastSweeping",
    "ViscosityStressFree",
    "ViscosityWholeGrid",
    "WallFreeSlip",
    "WallMoving",
    "WallMoving3D",
    "WallNoSlip",
    "correct_volume",
    "divergence_faces_to_cells",
    "gradient_cells_to_faces",
    "inflow_profile_3d",
    "level_set_below",
    "level_set_box",
    "level_set_from_function",
    "liquid_area",
]
