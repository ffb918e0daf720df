from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

MotionState = tuple[np.ndarray, float, np.ndarray, float]
"""(offset (2,) [m], angle [rad], velocity (2,) [m/s], angular velocity [rad/s]) at time t."""


@dataclass(frozen=True)
class RigidMotion:
    """Constant rigid motion: translation at ``velocity`` and rotation at ``angular_velocity``
    about ``center`` (the centre moves with the translation).

    Attributes:
        velocity: Translation velocity (vx, vy) [m/s].
        angular_velocity: Counter-clockwise rotation rate [rad/s].
        center: Rotation centre at t = 0 [m]; the obstacle's polygon centroid when None.
    """

    velocity: tuple[float, float] = (0.0, 0.0)
    angular_velocity: float = 0.0
    center: tuple[float, float] | None = None

    def __call__(self, time: float) -> MotionState:
        velocity = np.asarray(self.velocity, dtype=np.float64)
        return velocity * time, self.angular_velocity * time, velocity, self.angular_velocity


def polygon_signed_area(polygon: np.ndarray) -> float:
    """Signed area [m^2] of a closed polygon (k, 2): positive when counter-clockwise."""
    x, y = polygon[:, 0], polygon[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _polygon_centroid(polygon: np.ndarray) -> np.ndarray:
    x, y = polygon[:, 0], polygon[:, 1]
    cross = x * np.roll(y, -1) - np.roll(x, -1) * y
    area = 0.5 * np.sum(cross)
    cx = np.sum((x + np.roll(x, -1)) * cross) / (6.0 * area)
    cy = np.sum((y + np.roll(y, -1)) * cross) / (6.0 * area)
    return np.array([cx, cy])


@dataclass(frozen=True, eq=False)
class Obstacle:
    """A closed polygon, or an open polyline of zero thickness (a plate, a membrane), with zero
    or prescribed rigid velocity, in the same boundary map as the elastic bodies (METHOD.md
    §5.3).

    The rest polygon is reoriented to counter-clockwise (body on the left of each edge) when
    given clockwise. An open polyline (``closed=False``) enters the map as the loop that runs
    along it and back (each segment once in each direction): it encloses no area, so no grid
    point is inside it and no face segment is covered, and only its crossings with the lines
    through cell centres and between velocity points show it, which is what the thin-body cuts
    (`elastoflow.coupling._thin`) and the cut distances read. With a motion, the points at time
    t are ``pivot + offset + R(angle) (x0 - pivot)`` and their velocities
    ``velocity + angular_velocity * perp(x - pivot - offset)``.

    Attributes:
        polygon: Rest vertices [m], shape (k, 2): a closed polygon, k >= 3, stored
            counter-clockwise; or, with ``closed=False``, the polyline's points in order,
            k >= 2, no two consecutive ones equal.
        motion: None (fixed), a ``RigidMotion``, or any callable ``motion(t) -> (offset (2,),
            angle, velocity (2,), angular_velocity)``.
        pivot: Rotation centre of the rest polygon [m], shape (2,) after construction; when
            None, the motion's ``center`` if it has one, else the polygon centroid (the mean
            of the points for a polyline).
        closed: True for a polygon, False for an open polyline.
    """

    polygon: np.ndarray
    motion: Callable[[float], MotionState] | None = None
    pivot: np.ndarray | tuple[float, float] | None = None
    closed: bool = True

    def __post_init__(self) -> None:
        polygon = np.array(self.polygon, dtype=np.float64)
        least = 3 if self.closed else 2
        if polygon.ndim != 2 or polygon.shape[1] != 2 or polygon.shape[0] < least:
            raise ValueError(
                f"obstacle polygon shape {polygon.shape}: must be (k, 2), k >= {least}")
        if not np.all(np.isfinite(polygon)):
            raise ValueError("obstacle polygon: contains non-finite values; all must be finite")
        if self.closed:
            area = polygon_signed_area(polygon)
            if area == 0.0:
                raise ValueError("obstacle polygon area 0: must enclose a positive area")
            if area < 0.0:
                polygon = polygon[::-1].copy()
        else:
            repeated = np.flatnonzero(np.all(polygon[1:] == polygon[:-1], axis=1))
            if repeated.size:
                raise ValueError(
                    f"obstacle polyline points {int(repeated[0])} and {int(repeated[0]) + 1}: "
                    "equal; consecutive points must differ")
        polygon.setflags(write=False)
        object.__setattr__(self, "polygon", polygon)
        pivot = self.pivot
        center = getattr(self.motion, "center", None)
        if pivot is None:
            if center is not None:
                pivot = center
            else:
                pivot = _polygon_centroid(polygon) if self.closed else polygon.mean(axis=0)
        object.__setattr__(self, "pivot", np.array(pivot, dtype=np.float64).reshape(2))

    @property
    def point_count(self) -> int:
        """Number of boundary points k."""
        return int(self.polygon.shape[0])

    @property
    def edges(self) -> np.ndarray:
        """Closed loop of edges (i, i+1 mod k), body on the left, int64, shape (k, 2); for a
        polyline its k - 1 segments forwards, then the same backwards, shape (2k - 2, 2)."""
        k = self.point_count
        if not self.closed:
            first = np.arange(k - 1, dtype=np.int64)
            forward = np.stack([first, first + 1], axis=1)
            return np.concatenate([forward, forward[::-1, ::-1]])
        first = np.arange(k, dtype=np.int64)
        return np.stack([first, (first + 1) % k], axis=1)

    def _state(self, time: float) -> MotionState:
        if self.motion is None:
            return np.zeros(2), 0.0, np.zeros(2), 0.0
        offset, angle, velocity, angular_velocity = self.motion(time)
        return (np.asarray(offset, dtype=np.float64), float(angle),
                np.asarray(velocity, dtype=np.float64), float(angular_velocity))

    def points_at(self, time: float) -> np.ndarray:
        """Vertex positions [m] at time ``time`` [s], shape (k, 2)."""
        offset, angle, _, _ = self._state(time)
        c, s = np.cos(angle), np.sin(angle)
        pivot = np.asarray(self.pivot)
        relative = self.polygon - pivot
        rotated = np.stack([c * relative[:, 0] - s * relative[:, 1],
                            s * relative[:, 0] + c * relative[:, 1]], axis=1)
        return pivot + offset + rotated

    def velocities_at(self, time: float) -> np.ndarray:
        """Vertex velocities [m/s] at time ``time`` [s], shape (k, 2)."""
        offset, _, velocity, angular_velocity = self._state(time)
        relative = self.points_at(time) - np.asarray(self.pivot) - offset
        return velocity + angular_velocity * np.stack([-relative[:, 1], relative[:, 0]], axis=1)


def obstacle_circle(
    center: tuple[float, float],
    radius: float,
    segments: int = 64,
    motion: Callable[[float], MotionState] | None = None,
) -> Obstacle:
    """Regular polygon of ``segments`` vertices on a circle of ``radius`` [m]."""
    if not radius > 0.0:
        raise ValueError(f"obstacle circle radius {radius!r}: must be > 0")
    if segments < 3:
        raise ValueError(f"obstacle circle segments {segments!r}: must be >= 3")
    angle = 2.0 * np.pi * np.arange(segments) / segments
    polygon = np.stack([center[0] + radius * np.cos(angle),
                        center[1] + radius * np.sin(angle)], axis=1)
    return Obstacle(polygon, motion=motion, pivot=np.asarray(center, dtype=np.float64))


def obstacle_rectangle(
    lower: tuple[float, float],
    upper: tuple[float, float],
    motion: Callable[[float], MotionState] | None = None,
) -> Obstacle:
    """Axis-aligned rectangle with corners ``lower`` (x0, y0) and ``upper`` (x1, y1) [m]."""
    (x0, y0), (x1, y1) = lower, upper
    if not (x1 > x0 and y1 > y0):
        raise ValueError(f"obstacle rectangle {lower!r}-{upper!r}: upper must exceed lower")
    polygon = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=np.float64)
    return Obstacle(polygon, motion=motion)


def obstacle_polyline(
    points: np.ndarray | Sequence[tuple[float, float]],
    motion: Callable[[float], MotionState] | None = None,
) -> Obstacle:
    """An open polyline of zero thickness through ``points`` [m], shape (k, 2), k >= 2: a
    plate or a membrane that blocks the flow through it (`Obstacle` with ``closed=False``)."""
    return Obstacle(np.asarray(points, dtype=np.float64), motion=motion, closed=False)


def obstacle_pipe(
    start: tuple[float, float],
    end: tuple[float, float],
    inner_width: float,
    wall_thickness: float,
) -> tuple[Obstacle, Obstacle]:
    """The two walls of a straight pipe from ``start`` to ``end`` (centre line) [m], as two
    rectangles of ``wall_thickness`` on either side of a channel of ``inner_width``."""
    if not inner_width > 0.0:
        raise ValueError(f"pipe inner_width {inner_width!r}: must be > 0")
    if not wall_thickness > 0.0:
        raise ValueError(f"pipe wall_thickness {wall_thickness!r}: must be > 0")
    a = np.asarray(start, dtype=np.float64)
    b = np.asarray(end, dtype=np.float64)
    length = float(np.hypot(*(b - a)))
    if length == 0.0:
        raise ValueError("pipe start == end: the pipe must have a positive length")
    direction = (b - a) / length
    normal = np.array([-direction[1], direction[0]])
    walls = []
    for side in (1.0, -1.0):
        inner = side * 0.5 * inner_width * normal
        outer = side * (0.5 * inner_width + wall_thickness) * normal
        polygon = np.array([a + inner, b + inner, b + outer, a + outer])
        walls.append(Obstacle(polygon))
    return walls[0], walls[1]


def concatenate_boundaries(
    boundaries: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]],
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Stack several bodies' boundaries into one point and edge set for the boundary map.

    Args:
        boundaries: One (points (P_b, 2), velocities (P_b, 2), edges (E_b, 2)) per body or
            obstacle, edges indexing that body's own points.

    Returns:
        points (P, 2), velocities (P, 2), edges (E, 2) into the stacked points, edge_body (E,)
        (index of the body in ``boundaries``), point offsets (B+1,): body b owns points
        ``offsets[b]:offsets[b+1]``.
    """
    offsets = np.zeros(len(boundaries) + 1, dtype=np.int64)
    points_list, velocities_list, edges_list, body_list = [], [], [], []
    for b, (points, velocities, edges) in enumerate(boundaries):
        points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        velocities = np.asarray(velocities, dtype=np.float64).reshape(-1, 2)
        edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
        if velocities.shape != points.shape:
            raise ValueError(
                f"boundary {b} velocities shape {velocities.shape}: must match points "
                f"shape {points.shape}"
            )
        if edges.size and (edges.min() < 0 or edges.max() >= points.shape[0]):
            raise ValueError(
                f"boundary {b} edges index range [{edges.min()}, {edges.max()}]: must lie in "
                f"[0, {points.shape[0]})"
            )
        points_list.append(points)
        velocities_list.append(velocities)
        edges_list.append(edges + offsets[b])
        body_list.append(np.full(edges.shape[0], b, dtype=np.int64))
        offsets[b + 1] = offsets[b] + points.shape[0]
    if not boundaries:
        empty = np.zeros((0, 2))
        return empty, empty.copy(), np.zeros((0, 2), np.int64), np.zeros(0, np.int64), offsets
    return (np.concatenate(points_list), np.concatenate(velocities_list),
            np.concatenate(edges_list), np.concatenate(body_list), offsets)
