"""Scenes as typed data: pydantic models, TOML files, the built-in library, and the builder
that turns a scene into a ready `Simulation`.

A scene file is TOML with one table per model (``[domain]``, ``[fluid]``, ``[boundaries]``,
``[[jets]]``, ``[[obstacles]]``, ``[[bodies]]``, ``[time]``, ``[coupling]``, ``[outputs]``).
``elastoflow dump NAME`` writes any built-in scene as a starting file.
"""

from elastoflow.scenes._build import (
    SceneWarning,
    build_fluid_solver,
    build_grid,
    build_simulation,
    characteristic_speed,
    initial_velocity,
    obstacle_polygon,
    resolve_scene,
    step_count,
    time_step,
)
from elastoflow.scenes._checks import available_memory, memory_estimate
from elastoflow.scenes._errors import SceneError
from elastoflow.scenes._library import get_scene, list_scenes
from elastoflow.scenes._schema import (
    BodySpec,
    BoundariesSpec,
    CheckpointSpec,
    CouplingSpec,
    DomainSpec,
    FieldsSpec,
    FixedSpec,
    FluidSpec,
    InitialVelocitySpec,
    JetSpec,
    MaterialSpec,
    MeshesSpec,
    OutputsSpec,
    ProbeSpec,
    RigidMotionSpec,
    RodBodySpec,
    RodMaterialSpec,
    RodShapeSpec,
    Scene,
    TimeSpec,
    VideoSpec,
)
from elastoflow.scenes._toml import load_scene, parse_scene, scene_to_toml

__all__ = [
    "BodySpec",
    "BoundariesSpec",
    "CheckpointSpec",
    "CouplingSpec",
    "DomainSpec",
    "FieldsSpec",
    "FixedSpec",
    "FluidSpec",
    "InitialVelocitySpec",
    "JetSpec",
    "MaterialSpec",
    "MeshesSpec",
    "OutputsSpec",
    "ProbeSpec",
    "RigidMotionSpec",
    "RodBodySpec",
    "RodMaterialSpec",
    "RodShapeSpec",
    "Scene",
    "SceneError",
    "SceneWarning",
    "TimeSpec",
    "VideoSpec",
    "available_memory",
    "build_fluid_solver",
    "build_grid",
    "build_simulation",
    "characteristic_speed",
    "get_scene",
    "initial_velocity",
    "list_scenes",
    "load_scene",
    "memory_estimate",
    "obstacle_polygon",
    "parse_scene",
    "resolve_scene",
    "scene_to_toml",
    "step_count",
    "time_step",
]
