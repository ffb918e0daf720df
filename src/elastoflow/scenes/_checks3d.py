"""Checks of a 3D scene's data (before anything is built), one line per problem naming the
key path as written, the value and what is allowed."""

from __future__ import annotations

import math
from collections.abc import Sequence

from elastoflow.scenes._schema import InflowSpec, OutflowSpec
from elastoflow.scenes._schema3d import (
    AXES,
    BoxObstacleSpec,
    BoxShape3DSpec,
    CylinderObstacleSpec,
    CylinderShape3DSpec,
    MovingWall3DSpec,
    Scene3D,
    SphereObstacleSpec,
    SphereShape3DSpec,
)

SIDES_3D = ("left", "right", "bottom", "top", "back", "front")

Box3 = tuple[float, float, float, float, float, float]


def _fmt(values: Sequence[float]) -> str:
    return "[" + ", ".join(f"{v:g}" for v in values) + "]"


def _inside(inner: Box3, outer: Box3) -> bool:
    return all(inner[k] >= outer[k] - 1e-12 for k in range(3)) and all(
        inner[k] <= outer[k] + 1e-12 for k in range(3, 6))


def _round_bounds(center: Sequence[float], half: Sequence[float]) -> Box3:
    return (center[0] - half[0], center[1] - half[1], center[2] - half[2],
            center[0] + half[0], center[1] + half[1], center[2] + half[2])


def _axis_bounds(center: Sequence[float], radius: float, length: float, axis: str) -> Box3:
    half = [radius, radius, radius]
    half[AXES.index(axis)] = 0.5 * length
    return _round_bounds(center, half)


def shape_bounds(shape: object) -> Box3 | None:
    """The rest bounding box of a body shape or obstacle (None for a mesh file)."""
    if isinstance(shape, BoxShape3DSpec | BoxObstacleSpec):
        return tuple(shape.box)  # type: ignore[return-value]
    if isinstance(shape, SphereShape3DSpec | SphereObstacleSpec):
        return _round_bounds(shape.center, (shape.radius,) * 3)
    if isinstance(shape, CylinderShape3DSpec | CylinderObstacleSpec):
        return _axis_bounds(shape.center, shape.radius, shape.length, shape.axis)
    return None


def check_scene_3d(scene: Scene3D) -> list[str]:
    """Everything wrong with the scene's data that the schema alone cannot see."""
    problems: list[str] = []
    domain = scene.domain.bounds
    where = f"the domain {_fmt(domain)}"
    for index, jet in enumerate(scene.jets):
        if not _inside(jet.region, domain):
            problems.append(f"jets.{index}.region = {_fmt(jet.region)}: must lie inside {where}")
    for index, obstacle in enumerate(scene.obstacles):
        bounds = shape_bounds(obstacle)
        if bounds is not None and obstacle.motion is None and not _inside(bounds, domain):
            problems.append(f"obstacles.{index} ({obstacle.shape}, bounds {_fmt(bounds)}): "
                            f"must lie inside {where}")
    for index, body in enumerate(scene.bodies):
        bounds = shape_bounds(body.shape)
        if bounds is not None and not _inside(bounds, domain):
            problems.append(f"bodies.{index}.shape ({body.shape.type}, bounds {_fmt(bounds)}): "
                            f"must lie inside {where}")
    for index, probe in enumerate(scene.outputs.probes):
        points = [probe.point] if probe.point is not None else list(probe.points or [])
        for point in points:
            if not _inside((*point, *point), domain):
                problems.append(f"outputs.probes.{index}: point {_fmt(point)} must lie inside "
                                f"{where}")
        if probe.body is not None and probe.body >= len(scene.bodies):
            problems.append(f"outputs.probes.{index}.body = {probe.body}: the scene has "
                            f"{len(scene.bodies)} bodies")
        for number in probe.bodies:
            if number >= len(scene.bodies):
                problems.append(f"outputs.probes.{index}.bodies: {number} is not a body index "
                                f"(the scene has {len(scene.bodies)})")
        for number in probe.obstacles:
            if number >= len(scene.obstacles):
                problems.append(f"outputs.probes.{index}.obstacles: {number} is not an "
                                f"obstacle index (the scene has {len(scene.obstacles)})")
    video = scene.outputs.video
    if video is not None and video.at is not None:
        axis = AXES.index(video.axis)
        if not domain[axis] <= video.at <= domain[axis + 3]:
            problems.append(f"outputs.video.at = {video.at:g}: must lie in "
                            f"[{domain[axis]:g}, {domain[axis + 3]:g}] along {video.axis}")
    sides = [getattr(scene.boundaries, name) for name in SIDES_3D]
    for position, (name, side) in enumerate(zip(SIDES_3D, sides, strict=True)):
        if isinstance(side, MovingWall3DSpec) and side.velocity[position // 2] != 0.0:
            problems.append(f"boundaries.{name}.velocity = {_fmt(side.velocity)}: a moving wall "
                            f"slides along itself, its {AXES[position // 2]} component must "
                            "be 0")
    inflows = [n for n, s in zip(SIDES_3D, sides, strict=True) if isinstance(s, InflowSpec)]
    outflows = [n for n, s in zip(SIDES_3D, sides, strict=True) if isinstance(s, OutflowSpec)]
    if (inflows or scene.jets) and not outflows:
        source = f"boundaries.{inflows[0]}" if inflows else "jets"
        problems.append(f"{source}: fluid flows in but no side lets it out (an incompressible "
                        "fluid in a closed box cannot take it); make a side \"outflow\"")
    if scene.time.cfl is not None and characteristic_speed_3d(scene) <= 0.0:
        problems.append(f"time.cfl = {scene.time.cfl}: needs a characteristic speed (inflow, "
                        "moving wall, jet, moving obstacle or initial velocity); this scene "
                        "has none, give time.dt instead")
    return problems


def characteristic_speed_3d(scene: Scene3D) -> float:
    """Largest speed the 3D scene imposes [m/s]: inflows, moving walls, jets, obstacle
    motion, the initial velocity."""
    speeds = [0.0, math.hypot(*scene.fluid.initial_velocity)]
    for name in SIDES_3D:
        side = getattr(scene.boundaries, name)
        if isinstance(side, InflowSpec):
            speeds.append(abs(side.speed))
        elif isinstance(side, MovingWall3DSpec):
            speeds.append(math.hypot(*side.velocity))
    speeds.extend(math.hypot(*jet.velocity) for jet in scene.jets)
    for obstacle in scene.obstacles:
        if obstacle.motion is not None:
            speeds.append(math.hypot(*obstacle.motion.velocity))
    return max(speeds)
