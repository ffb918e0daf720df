"""Elastic bodies: triangle meshes, St. Venant-Kirchhoff material with Voigt damping, explicit FEM.

Linear triangles in 2D (METHOD §4). A :class:`TriangleMesh` is the rest shape; an
:class:`ElasticBody` holds the world state and advances it with symplectic Euler substeps::

    mesh = mesh_rectangle(0.02, 0.2, counts=(4, 24), origin=(0.5, 0.3))
    body = ElasticBody(mesh, MaterialStVK(1000.0, 1e6, 0.3, damping_mu=10.0),
                       fixed_nodes=nodes_in_box(mesh, (0.5, 0.5, 0.52, 0.5)),
                       gravity=(0.0, -9.81))
    report = body.advance(dt=0.013, n_sub="auto", external_forces=fluid_force)
"""


from elastoflow.solid._body import (
    DEFAULT_SAFETY,
    ElasticBody,
    SolidInversionError,
    SolidStepReport,
    stable_substep,
)
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

__all__ = [
    "DEFAULT_SAFETY",
    "ElasticBody",
    "MaterialStVK",
    "SolidInversionError",
    "SolidStepReport",
    "TriangleMesh",
    "mesh_from_polygon",
    "mesh_rectangle",
    "mesh_windmill",
    "nearest_node",
    "nodes_in_box",
    "read_mesh",
    "stable_substep",
]
