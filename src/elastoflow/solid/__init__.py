"""Elastic bodies: triangle meshes, St. Venant-Kirchhoff material with Voigt damping, explicit FEM.

Linear triangles in 2D (METHOD §4), linear tetrahedra in 3D (:class:`TetrahedralMesh`,
:class:`ElasticBody3D`). Model, state and what advances it are separate: a
:class:`TriangleMesh` is the rest shape, an :class:`ElasticBody` the static model (mesh,
material, constraints, masses), a :class:`BodyState` the changing positions and velocities,
and an integrator (:class:`ExplicitFem`, :class:`EnergyMomentumFem`, :class:`MidpointFem`,
:class:`NewmarkFem`, :func:`static_equilibrium`: each one for 2D and 3D bodies, the body
bringing its forces and step matrix) steps one state into another::

    mesh = mesh_rectangle(0.02, 0.2, counts=(4, 24), origin=(0.5, 0.3))
    body = ElasticBody(mesh, MaterialStVK(1000.0, 1e6, 0.3, damping_mu=10.0),
                       fixed_nodes=nodes_in_box(mesh, (0.5, 0.5, 0.52, 0.5)),
                       gravity=(0.0, -9.81))
    state = body.state()
    report = ExplicitFem("auto").advance(body, state, state, 0.013, fluid_force)

    beam = mesh_box((0.2, 0.02, 0.02), counts=(20, 2, 2))
    body3d = ElasticBody3D(beam, MaterialStVK(1000.0, 1e6, 0.3),
                           fixed_nodes=nodes_in_box_3d(beam, (0, 0, 0, 0, 0.02, 0.02)),
                           gravity=(0.0, -9.81, 0.0))
    state3d = body3d.state()
    rule = EnergyMomentumFem(damping=0.1)
    rule.advance(body3d, state3d, state3d, 1e-3, np.zeros((beam.point_count, 3)),
                 rule.response(body3d, state3d, 1e-3))
"""


from elastoflow.solid._body3d import ElasticBody3D
from elastoflow.solid._contact import (
    HeldResponse,
    WallBox,
    WallContact,
    WallHold,
    hold_response,
    project_onto_box,
    wall_hold,
)
from elastoflow.solid._body import (
    DEFAULT_SAFETY,
    ElasticBody,
    SolidInversionError,
    SolidStepReport,
    stable_substep,
)
from elastoflow.solid._integrators import (
    ExplicitFem,
    EnergyMomentumFem,
    MidpointFem,
    NewmarkFem,
    static_equilibrium,
)
from elastoflow.solid._implicit3d import StepResponse3D
from elastoflow.solid._material import MaterialStVK
from elastoflow.solid._mesh import (
    TriangleMesh,
    mesh_from_polygon,
    mesh_rectangle,
    mesh_windmill,
    nearest_node,
    nodes_in_box,
    read_mesh,
)
from elastoflow.solid._response import StepResponse
from elastoflow.solid._rod import BodyModel, MaterialRod, PolylineMesh, RodBody
from elastoflow.solid._state import BodyState
from elastoflow.solid._tet_mesh import (
    TetrahedralMesh,
    mesh_box,
    mesh_cylinder,
    mesh_sphere,
    nodes_in_box_3d,
    read_tetrahedral_mesh,
    tetrahedralize_surface,
)

__all__ = [
    "DEFAULT_SAFETY",
    "BodyModel",
    "BodyState",
    "ElasticBody",
    "ElasticBody3D",
    "ExplicitFem",
    "HeldResponse",
    "MaterialRod",
    "MaterialStVK",
    "EnergyMomentumFem",
    "MidpointFem",
    "NewmarkFem",
    "PolylineMesh",
    "RodBody",
    "SolidInversionError",
    "SolidStepReport",
    "StepResponse",
    "StepResponse3D",
    "TetrahedralMesh",
    "TriangleMesh",
    "WallBox",
    "WallContact",
    "WallHold",
    "hold_response",
    "mesh_box",
    "mesh_cylinder",
    "mesh_from_polygon",
    "mesh_rectangle",
    "mesh_sphere",
    "mesh_windmill",
    "nearest_node",
    "nodes_in_box",
    "nodes_in_box_3d",
    "project_onto_box",
    "read_mesh",
    "read_tetrahedral_mesh",
    "stable_substep",
    "static_equilibrium",
    "tetrahedralize_surface",
    "wall_hold",
]
