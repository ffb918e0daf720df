"""Coupling of bodies and fluid through the boundary map (METHOD.md §5–7).

The boundary map (``BoundaryMap``, built by ``build_boundary_map``) holds every crossing of the
bodies' boundary edges with the half-grid lines. From it come the classification of grid points
(``classify_points``), the fluid's ``InteriorBoundary`` (``interior_boundary_from_map``) and the
fluid-to-solid force (``force_momentum_exchange``, the paper's eq. 8; ``force_traction``, the
stress integral). Static or rigidly moving obstacles (``Obstacle``) go through the same map.
"""

from elastoflow.coupling._classify import (
    PointClassification,
    classify_points,
    interior_boundary_from_map,
)
from elastoflow.coupling._forces import force_momentum_exchange, force_traction
from elastoflow.coupling._interface import (
    InterfaceFlux,
    PressureCoupledBodies,
    interface_flux,
)
from elastoflow.coupling._map import BoundaryMap, build_boundary_map
from elastoflow.coupling._obstacle import (
    Obstacle,
    RigidMotion,
    concatenate_boundaries,
    obstacle_circle,
    obstacle_pipe,
    obstacle_rectangle,
    polygon_signed_area,
)

__all__ = [
    "BoundaryMap",
    "InterfaceFlux",
    "Obstacle",
    "PointClassification",
    "PressureCoupledBodies",
    "RigidMotion",
    "build_boundary_map",
    "classify_points",
    "concatenate_boundaries",
    "force_momentum_exchange",
    "force_traction",
    "interface_flux",
    "interior_boundary_from_map",
    "obstacle_circle",
    "obstacle_pipe",
    "obstacle_rectangle",
    "polygon_signed_area",
]
