"""Static and prescribed-motion obstacles in 3D: closed triangulated surfaces.

The 3D twin of `Obstacle`: a closed, outward-oriented surface that enters the 3D boundary map
(`build_boundary_map_3d`) beside the elastic bodies' surfaces, with a rigid motion of constant
translation and rotation rates (or none).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from elastoflow.solid import TetrahedralMesh, mesh_box, mesh_cylinder, mesh_sphere


@dataclass(frozen=True)
class RigidMotion3D:
    """Constant rigid motion in 3D: translation at ``velocity`` and rotation at
    ``angular_velocity`` (a vector: axis times rate, right-handed) about the pivot, which
    moves with the translation.

    Attributes:
        velocity: Translation velocity (vx, vy, vz) [m/s].
        angular_velocity: Rotation vector (wx, wy, wz) [rad/s].
    """

    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    angular_velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        for name in ("velocity", "angular_velocity"):
            value = np.asarray(getattr(self, name), dtype=np.float64)
            if value.shape != (3,) or not np.isfinite(value).all():
                raise ValueError(f"{name} = {getattr(self, name)!r}: must be three finite "
                                 "numbers")


def _rotation(vector: np.ndarray) -> np.ndarray:
    """The rotation matrix of the rotation vector ``vector`` (Rodrigues' formula)."""
    angle = float(np.linalg.norm(vector))
    if angle == 0.0:
        return np.eye(3)
    kx, ky, kz = vector / angle
    cross = np.array([[0.0, -kz, ky], [kz, 0.0, -kx], [-ky, kx, 0.0]])
    return np.eye(3) + np.sin(angle) * cross + (1.0 - np.cos(angle)) * (cross @ cross)


@dataclass(frozen=True, eq=False)
class Obstacle3D:
    """A closed, outward-oriented triangulated surface with zero or prescribed rigid
    velocity, in the same 3D boundary map as the elastic bodies.

    With a motion, the vertices at time t are ``pivot + v t + R(w t) (x0 - pivot)`` and
    their velocities ``v + w x (x - pivot - v t)``.

    Attributes:
        points: Rest vertices [m], shape (k, 3), read-only after construction.
        triangles: Vertex indices, int64, shape (T, 3), outward orientation (``(b - a) x
            (c - a)`` points out of the solid).
        motion: None (fixed) or a `RigidMotion3D`.
        pivot: Rotation centre at t = 0 [m], shape (3,); the mean of the vertices when None.
        solid: The tetrahedral mesh the surface bounds, when it came from one (drawing
            sections of it, `solid_at`); None for a bare surface.
    """

    points: np.ndarray
    triangles: np.ndarray
    motion: RigidMotion3D | None = None
    pivot: np.ndarray | tuple[float, float, float] | None = None
    solid: TetrahedralMesh | None = None

    def __post_init__(self) -> None:
        points = np.array(self.points, dtype=np.float64)
        triangles = np.array(self.triangles, dtype=np.int64)
        if points.ndim != 2 or points.shape[1] != 3 or points.shape[0] < 4:
            raise ValueError(f"obstacle points shape {points.shape}: must be (k, 3), k >= 4")
        if not np.isfinite(points).all():
            raise ValueError("obstacle points: contain non-finite values; all must be finite")
        if triangles.ndim != 2 or triangles.shape[1] != 3 or triangles.shape[0] < 4:
            raise ValueError(
                f"obstacle triangles shape {triangles.shape}: must be (T, 3), T >= 4")
        if triangles.min() < 0 or triangles.max() >= points.shape[0]:
            raise ValueError(f"obstacle triangles: indices must lie in [0, {points.shape[0]})")
        # A closed surface has every edge twice, once in each direction.
        directed = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]],
                                   triangles[:, [2, 0]]])
        forward = {tuple(edge) for edge in directed.tolist()}
        if len(forward) != len(directed) or any((b, a) not in forward for a, b in forward):
            raise ValueError("obstacle triangles: not a closed, consistently oriented surface "
                             "(every edge must appear once in each direction)")
        corners = points[triangles]
        volume = float(np.einsum("ti,ti->t", corners[:, 0],
                                 np.cross(corners[:, 1], corners[:, 2])).sum()) / 6.0
        if volume == 0.0:
            raise ValueError("obstacle surface encloses no volume")
        if volume < 0.0:
            triangles = triangles[:, ::-1].copy()
        points.setflags(write=False)
        triangles.setflags(write=False)
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "triangles", triangles)
        pivot = points.mean(axis=0) if self.pivot is None else self.pivot
        pivot_array = np.array(pivot, dtype=np.float64).reshape(3)
        object.__setattr__(self, "pivot", pivot_array)

    @classmethod
    def from_mesh(cls, mesh: TetrahedralMesh, motion: RigidMotion3D | None = None
                  ) -> Obstacle3D:
        """The boundary surface of a tetrahedral mesh (unused interior nodes dropped)."""
        used, triangles = np.unique(mesh.boundary_triangles, return_inverse=True)
        return cls(mesh.points[used], triangles.reshape(-1, 3), motion=motion,
                   pivot=mesh.points[used].mean(axis=0), solid=mesh)

    @property
    def point_count(self) -> int:
        """Number of surface vertices k."""
        return int(self.points.shape[0])

    @property
    def volume(self) -> float:
        """Enclosed volume [m^3]."""
        corners = self.points[self.triangles]
        return float(np.einsum("ti,ti->t", corners[:, 0],
                               np.cross(corners[:, 1], corners[:, 2])).sum()) / 6.0

    def _moved(self, points: np.ndarray, time: float) -> np.ndarray:
        if self.motion is None:
            return np.array(points)
        pivot = np.asarray(self.pivot)
        rotation = _rotation(np.asarray(self.motion.angular_velocity) * time)
        return pivot + np.asarray(self.motion.velocity) * time + (points - pivot) @ rotation.T

    def points_at(self, time: float) -> np.ndarray:
        """Vertex positions [m] at ``time`` [s], shape (k, 3)."""
        return self._moved(self.points, time)

    def solid_at(self, time: float) -> tuple[np.ndarray, np.ndarray] | None:
        """The solid's nodes [m] at ``time`` and its tetrahedra, or None without a solid."""
        if self.solid is None:
            return None
        return self._moved(self.solid.points, time), self.solid.tetrahedra

    def velocities_at(self, time: float) -> np.ndarray:
        """Vertex velocities [m/s] at ``time`` [s], shape (k, 3)."""
        if self.motion is None:
            return np.zeros_like(self.points)
        velocity = np.asarray(self.motion.velocity, dtype=np.float64)
        relative = self.points_at(time) - np.asarray(self.pivot) - velocity * time
        return velocity + np.cross(np.asarray(self.motion.angular_velocity), relative)


def obstacle_sphere(center: tuple[float, float, float], radius: float, element_size: float,
                    motion: RigidMotion3D | None = None) -> Obstacle3D:
    """A sphere of ``radius`` [m] whose surface triangles have sides of about
    ``element_size`` [m] (the boundary of `mesh_sphere`)."""
    return Obstacle3D.from_mesh(mesh_sphere(radius, element_size, center=center), motion)


def obstacle_box(lower: tuple[float, float, float], upper: tuple[float, float, float],
                 element_size: float, motion: RigidMotion3D | None = None) -> Obstacle3D:
    """An axis-aligned box from ``lower`` to ``upper`` [m], triangles of about
    ``element_size``."""
    x0, y0, z0 = (float(c) for c in lower)
    x1, y1, z1 = (float(c) for c in upper)
    if min(x1 - x0, y1 - y0, z1 - z0) <= 0.0:
        raise ValueError(f"obstacle box {lower!r}-{upper!r}: upper must exceed lower")
    mesh = mesh_box((x1 - x0, y1 - y0, z1 - z0), element_size, origin=(x0, y0, z0))
    return Obstacle3D.from_mesh(mesh, motion)


def obstacle_cylinder(center: tuple[float, float, float], radius: float, length: float,
                      element_size: float, axis: int = 2,
                      motion: RigidMotion3D | None = None) -> Obstacle3D:
    """A solid cylinder of ``radius`` and ``length`` [m] along ``axis`` (0, 1 or 2) centred
    at ``center``, triangles of about ``element_size`` (the boundary of `mesh_cylinder`)."""
    if axis not in (0, 1, 2):
        raise ValueError(f"obstacle cylinder axis = {axis!r}: must be 0, 1 or 2")
    mesh = mesh_cylinder(radius, length, element_size)
    # A cyclic permutation of the coordinates turns the z axis into ``axis`` and keeps the
    # orientation of the triangles.
    order = {2: (0, 1, 2), 0: (2, 0, 1), 1: (1, 2, 0)}[axis]
    solid = TetrahedralMesh(mesh.points[:, order] + np.asarray(center, dtype=np.float64),
                            mesh.tetrahedra)
    return Obstacle3D.from_mesh(solid, motion)
