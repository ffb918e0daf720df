"""From a `Scene` (typed data) to the physics objects and a ready `Simulation`."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from elastoflow.scenes._errors import SceneError
from elastoflow.scenes._schema import (
    BodySpec,
    CircleObstacleSpec,
    InflowSpec,
    MeshFileShapeSpec,
    MovingWallSpec,
    PolygonObstacleSpec,
    PolygonShapeSpec,
    RectangleObstacleSpec,
    RectangleShapeSpec,
    Scene,
    WindmillShapeSpec,
)

if TYPE_CHECKING:
    from elastoflow.grid import Grid2D
    from elastoflow.simulation import Simulation


def characteristic_speed(scene: Scene) -> float:
    """Largest speed the scene imposes [m/s]: inflows, moving walls, jets, obstacle motion."""
    speeds = [0.0]
    for side in (scene.boundaries.left, scene.boundaries.right, scene.boundaries.bottom,
                 scene.boundaries.top):
        if isinstance(side, InflowSpec):
            speeds.append(abs(side.speed))
        elif isinstance(side, MovingWallSpec):
            speeds.append(abs(side.velocity))
    speeds.extend(math.hypot(*jet.velocity) for jet in scene.jets)
    for obstacle in scene.obstacles:
        if obstacle.motion is not None:
            speeds.append(math.hypot(*obstacle.motion.velocity))
    return max(speeds)


def time_step(scene: Scene) -> float:
    """The fluid step [s]: ``time.dt``, or ``cfl * h / characteristic_speed``."""
    if scene.time.dt is not None:
        return scene.time.dt
    speed = characteristic_speed(scene)
    if speed <= 0.0:
        raise SceneError([(
            f"time.cfl = {scene.time.cfl}: needs a characteristic speed (inflow, moving wall or "
            "jet); this scene has none, give time.dt instead"
        )])
    return float(scene.time.cfl) * scene.domain.cell_size / speed  # type: ignore[arg-type]


def step_count(scene: Scene) -> int:
    """Number of fluid steps of the whole run: ``time.steps`` or ``ceil(duration / dt)``."""
    if scene.time.steps is not None:
        return scene.time.steps
    return max(1, math.ceil(float(scene.time.duration) / time_step(scene) - 1e-9))  # type: ignore[arg-type]


def build_grid(scene: Scene) -> Grid2D:
    from elastoflow.grid import Grid2D

    nx, ny = scene.domain.cells
    return Grid2D(nx=nx, ny=ny, h=scene.domain.cell_size)


def _side(spec: Any) -> Any:
    from elastoflow import fluid

    factories = {
        "no_slip": lambda s: fluid.WallNoSlip(),
        "free_slip": lambda s: fluid.WallFreeSlip(),
        "moving": lambda s: fluid.WallMoving(velocity=s.velocity),
        "inflow": lambda s: fluid.Inflow(speed=s.speed, profile=s.profile, ramp_time=s.ramp_time),
        "outflow": lambda s: fluid.Outflow(),
    }
    return factories[spec.type](spec)


def build_fluid_solver(scene: Scene, grid: Grid2D) -> Any:
    """The `FluidSolver` of the scene's fluid, domain sides and jets."""
    from elastoflow import fluid, linalg

    solvers = {"mgpcg": linalg.PoissonSolverMGPCG, "jacobi": linalg.PoissonSolverJacobi}
    b = scene.boundaries
    boundaries = fluid.DomainBoundaries(
        left=_side(b.left), right=_side(b.right), bottom=_side(b.bottom), top=_side(b.top)
    )
    jets = tuple(fluid.Jet(region=j.region, velocity=j.velocity, dye=j.dye) for j in scene.jets)
    return fluid.FluidSolver(
        grid,
        density=scene.fluid.density,
        viscosity=scene.fluid.viscosity,
        boundaries=boundaries,
        jets=jets,
        gravity=scene.fluid.gravity,
        pressure_solver=solvers[scene.fluid.pressure_solver](rtol=scene.fluid.pressure_rtol),
    )


def _circle_polygon(center: tuple[float, float], radius: float, segments: int) -> np.ndarray:
    angles = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    return np.column_stack(
        (center[0] + radius * np.cos(angles), center[1] + radius * np.sin(angles))
    )


def obstacle_polygon(spec: Any) -> np.ndarray:
    """The obstacle's outline at rest, counter-clockwise, shape (k, 2) [m]."""
    if isinstance(spec, CircleObstacleSpec):
        return _circle_polygon(spec.center, spec.radius, spec.segments)
    if isinstance(spec, RectangleObstacleSpec):
        x0, y0, x1, y1 = spec.box
        return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=np.float64)
    if isinstance(spec, PolygonObstacleSpec):
        polygon = np.asarray(spec.points, dtype=np.float64)
        x, y = polygon[:, 0], polygon[:, 1]
        if np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y) < 0.0:
            polygon = polygon[::-1].copy()
        return polygon
    raise TypeError(f"unknown obstacle spec {type(spec).__name__}")


def build_obstacles(scene: Scene) -> list[Any]:
    from elastoflow import coupling

    obstacles = []
    for spec in scene.obstacles:
        motion = None
        if spec.motion is not None:
            motion = coupling.RigidMotion(
                velocity=spec.motion.velocity,
                angular_velocity=spec.motion.angular_velocity,
                center=spec.motion.center,
            )
        obstacles.append(coupling.Obstacle(obstacle_polygon(spec), motion=motion))
    return obstacles


def build_mesh(body: BodySpec, base_dir: str | None = None) -> Any:
    """The body's rest mesh (`elastoflow.solid.TriangleMesh`)."""
    from elastoflow import solid

    shape = body.shape
    if isinstance(shape, RectangleShapeSpec):
        x0, y0, x1, y1 = shape.box
        return solid.mesh_rectangle(x1 - x0, y1 - y0, counts=shape.divisions, origin=(x0, y0))
    if isinstance(shape, WindmillShapeSpec):
        return solid.mesh_windmill(
            shape.hub_radius, shape.blades, shape.radius - shape.hub_radius, shape.blade_width,
            center=shape.center, element_size=shape.element_size, angle=shape.angle,
        )
    if isinstance(shape, PolygonShapeSpec):
        return solid.mesh_from_polygon(np.asarray(shape.points, float), element_size=shape.element_size)
    if isinstance(shape, MeshFileShapeSpec):
        path = Path(shape.path)
        if not path.is_absolute() and base_dir is not None:
            path = Path(base_dir) / path
        if not path.exists():
            raise SceneError([f"shape.path = {shape.path!r}: mesh file not found ({path})"])
        mesh = solid.read_mesh(path)
        points = mesh.points * shape.scale + np.asarray(shape.offset, float)
        return solid.TriangleMesh(points, mesh.triangles)
    raise TypeError(f"unknown body shape {type(shape).__name__}")


def build_bodies(scene: Scene) -> list[Any]:
    from elastoflow import solid

    bodies = []
    for index, spec in enumerate(scene.bodies):
        try:
            mesh = build_mesh(spec, scene.base_dir)
        except SceneError as error:
            raise SceneError([f"bodies.{index}.{p}" for p in error.problems]) from None
        except ValueError as error:
            raise SceneError([f"bodies.{index}.shape: cannot mesh: {error}"]) from None
        m = spec.material
        material = solid.MaterialStVK(
            density=m.density, young_modulus=m.young_modulus, poisson_ratio=m.poisson_ratio,
            damping_lambda=m.damping_lambda, damping_mu=m.damping_mu, plane=m.plane,
        )
        fixed: np.ndarray = np.zeros(0, dtype=np.int64)
        if spec.fixed is not None:
            parts = [np.asarray(spec.fixed.nodes, dtype=np.int64)]
            if spec.fixed.box is not None:
                in_box = solid.nodes_in_box(mesh, spec.fixed.box)
                if in_box.size == 0:
                    raise SceneError([(f"bodies.{index}.fixed.box = {list(spec.fixed.box)}: "
                                       "contains no node of the body's mesh")])
                parts.append(in_box)
            fixed = np.unique(np.concatenate(parts))
            if fixed.size and fixed.max() >= mesh.points.shape[0]:
                raise SceneError([(f"bodies.{index}.fixed.nodes = {spec.fixed.nodes}: the mesh "
                                   f"has nodes 0..{mesh.points.shape[0] - 1}")])
        pivot = None if spec.pivot is None else solid.nearest_node(mesh, spec.pivot)
        bodies.append(solid.ElasticBody(
            mesh, material, fixed_nodes=fixed, pivot_node=pivot, gravity=scene.fluid.gravity,
        ))
    return bodies


def build_simulation(scene: Scene) -> Simulation:
    """The ready-to-step `Simulation` of ``scene`` (fluid at rest, bodies at their rest shape).

    Raises:
        SceneError: Something only visible when building (a mesh file that is missing, a
            fixed box that holds no node, a cfl without a characteristic speed).
    """
    from elastoflow.simulation import Simulation

    grid = build_grid(scene)
    return Simulation(
        grid,
        build_fluid_solver(scene, grid),
        bodies=build_bodies(scene),
        obstacles=build_obstacles(scene),
        dt=time_step(scene),
        substeps=scene.time.substeps,
        force_model=scene.coupling.force_model,
        alpha=scene.coupling.alpha,
        force_relaxation=scene.coupling.force_relaxation,
        added_mass=scene.coupling.added_mass,
    )


def resolve_scene(name_or_path: str) -> Scene:
    """A built-in scene by name, or a scene file by path (anything ending in .toml or that
    exists on disk)."""
    from elastoflow.scenes._library import get_scene
    from elastoflow.scenes._toml import load_scene

    path = Path(name_or_path)
    if name_or_path.endswith(".toml") or path.exists():
        return load_scene(path)
    return get_scene(name_or_path)
