"""Coupling of bodies and fluid through the boundary map (METHOD.md §5–7).

The boundary map (``BoundaryMap``, built by ``build_boundary_map``) holds every crossing of the
bodies' boundary edges with the half-grid lines. From it come the classification of grid points
(``classify_points``), the fluid's ``InteriorBoundary`` (``interior_boundary_from_map``) and the
fluid-to-solid force (``force_momentum_exchange``, the paper's eq. 8; ``force_traction``, the
stress integral). Static or rigidly moving obstacles (``Obstacle``) go through the same map.

How the fluid sees the bodies is a swappable part (``BoundaryTreatment``): ``BoundaryCutCell``
(open fractions and cut distances, the default), ``BoundaryDualCell`` (the same with each
face weighted by the fluid share of its dual cell, ``interior_boundary_dual_cell``: weights
continuous in the bodies' positions) or ``BoundaryStaircase`` (cells by their
centres, faces open or closed: ``interior_boundary_staircase``). ``classify_points_brute_force``
tests every grid point against every element, the cost the map avoids. Bodies thinner than a
cell, down to an open polyline of zero thickness (``obstacle_polyline``), cut the pressure
connections their mid-line crosses (``elastoflow.coupling._thin``), so no fluid passes them.

In 3D (``BoundaryMap3D``, ``build_boundary_map_3d``): the crossings of closed surface
triangles with the grid lines along x, y and z (``LineCrossings``), and the cells inside
(``solid_cells_3d``), the cut distances of the velocity points (``cut_distances_3d``), and the fluid share of every face from the bodies' exact cross-sections
(``face_open_fractions_3d``); from them the 3D fluid's ``InteriorBoundary3D``
(``interior_boundary_3d``) and the traction on the surface triangles (``force_traction_3d``).
The bodies' flux through the faces as a linear map of their nodal velocities, whose
transpose is the pressure's nodal force (``interface_flux_3d``), is the 3D twin of
``interface_flux``.
Obstacles in 3D are closed surfaces (``Obstacle3D``: ``obstacle_sphere``, ``obstacle_box``,
``obstacle_cylinder``) with an optional ``RigidMotion3D``.
"""

from elastoflow.coupling._brute_force import classify_points_brute_force
from elastoflow.coupling._classify import (
    PointClassification,
    classify_points,
    interior_boundary_from_map,
)
from elastoflow.coupling._dual import (
    U_FACES,
    V_FACES,
    DualCellInteriorBoundary,
    DualCover,
    dual_cover,
    interface_flux_dual,
    interior_boundary_dual_cell,
)
from elastoflow.coupling._forces import force_momentum_exchange, force_traction
from elastoflow.coupling._interface import (
    InterfaceFlux,
    PressureCoupledBodies,
    SparseRows,
    interface_flux,
)
from elastoflow.coupling._interface3d import InterfaceFlux3D, interface_flux_3d
from elastoflow.coupling._interior3d import force_traction_3d, interior_boundary_3d
from elastoflow.coupling._map import BoundaryMap, build_boundary_map
from elastoflow.coupling._map3d import (
    BoundaryMap3D,
    CutDistances3D,
    LineCrossings,
    build_boundary_map_3d,
    cut_distances_3d,
    face_open_fractions_3d,
    solid_cells_3d,
)
from elastoflow.coupling._obstacle import (
    Obstacle,
    RigidMotion,
    concatenate_boundaries,
    obstacle_circle,
    obstacle_pipe,
    obstacle_polyline,
    obstacle_rectangle,
    polygon_signed_area,
)
from elastoflow.coupling._obstacle3d import (
    Obstacle3D,
    RigidMotion3D,
    obstacle_box,
    obstacle_cylinder,
    obstacle_sphere,
)
from elastoflow.coupling._staircase import (
    StaircaseInteriorBoundary,
    interface_flux_staircase,
    interior_boundary_staircase,
)
from elastoflow.coupling._treatment import (
    BOUNDARY_TREATMENTS,
    BoundaryCutCell,
    BoundaryDualCell,
    BoundaryStaircase,
    BoundaryTreatment,
    boundary_treatment,
)

__all__ = [
    "BOUNDARY_TREATMENTS",
    "BoundaryCutCell",
    "BoundaryDualCell",
    "BoundaryMap",
    "BoundaryMap3D",
    "BoundaryStaircase",
    "BoundaryTreatment",
    "CutDistances3D",
    "DualCellInteriorBoundary",
    "DualCover",
    "InterfaceFlux",
    "InterfaceFlux3D",
    "LineCrossings",
    "Obstacle",
    "Obstacle3D",
    "PointClassification",
    "PressureCoupledBodies",
    "RigidMotion",
    "RigidMotion3D",
    "SparseRows",
    "StaircaseInteriorBoundary",
    "U_FACES",
    "V_FACES",
    "boundary_treatment",
    "build_boundary_map",
    "build_boundary_map_3d",
    "classify_points",
    "classify_points_brute_force",
    "concatenate_boundaries",
    "cut_distances_3d",
    "dual_cover",
    "face_open_fractions_3d",
    "force_momentum_exchange",
    "force_traction",
    "force_traction_3d",
    "interface_flux",
    "interface_flux_3d",
    "interface_flux_dual",
    "interface_flux_staircase",
    "interior_boundary_dual_cell",
    "interior_boundary_3d",
    "interior_boundary_from_map",
    "interior_boundary_staircase",
    "obstacle_box",
    "obstacle_circle",
    "obstacle_cylinder",
    "obstacle_pipe",
    "obstacle_polyline",
    "obstacle_rectangle",
    "obstacle_sphere",
    "polygon_signed_area",
    "solid_cells_3d",
]
