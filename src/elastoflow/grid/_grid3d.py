"""The 3D MAC grid: geometry only (sizes, spacing, where each kind of point sits).

Picture of one cell ``(i, j, k)`` of side ``h`` (x to the right, y up, z towards the viewer)::

              +-------------+            p[i, j, k] at ((i+1/2) h, (j+1/2) h, (k+1/2) h)
             /|   v-face   /|                       shape (nx, ny, nz)
            / |  (i,j+1,k)/ |            u[i, j, k] at (i h, (j+1/2) h, (k+1/2) h)
           +-------------+  |                       shape (nx+1, ny, nz)
   u-face  |  |    p     |  |  u-face    v[i, j, k] at ((i+1/2) h, j h, (k+1/2) h)
   (i,j,k) >  +----------|--+ (i+1,j,k)             shape (nx, ny+1, nz)
           | / w-face    | /             w[i, j, k] at ((i+1/2) h, (j+1/2) h, k h)
           |/  (i,j,k)   |/                         shape (nx, ny, nz+1)
           +-------------+

Arrays are indexed ``[i, j, k]`` with ``i`` along x, ``j`` along y, ``k`` along z (C order, so
``k`` is the fastest index). Positions are relative to ``origin``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

_AXES = ("x", "y", "z")


@dataclass(frozen=True)
class Grid3D:
    """A uniform 3D MAC grid of ``nx × ny × nz`` cubic cells of side ``h`` [m].

    Attributes:
        nx: Number of cells along x.
        ny: Number of cells along y.
        nz: Number of cells along z.
        h: Cell side [m].
        origin: Position of the domain corner with the smallest coordinates [m].
    """

    nx: int
    ny: int
    nz: int
    h: float
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        for axis, count in zip(_AXES, (self.nx, self.ny, self.nz), strict=True):
            if isinstance(count, bool) or int(count) != count or count < 2:
                raise ValueError(f"grid n{axis} = {count!r}: must be an integer >= 2")
        if not (self.h > 0.0 and np.isfinite(self.h)):
            raise ValueError(f"grid h = {self.h!r}: must be a finite positive length")
        if len(self.origin) != 3 or not all(np.isfinite(float(c)) for c in self.origin):
            raise ValueError(f"grid origin = {self.origin!r}: must be three finite numbers")

    @classmethod
    def from_extent(
        cls, lx: float, ly: float, lz: float, nx: int,
        origin: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> Grid3D:
        """Grid of ``nx`` cells across ``lx`` [m]; ``ly / h`` and ``lz / h`` must be whole
        numbers of cells."""
        h = lx / nx
        counts = []
        for name, length in (("ly", ly), ("lz", lz)):
            count = int(round(length / h))
            if abs(count * h - length) > 1e-9 * max(length, 1.0):
                raise ValueError(
                    f"domain {name} = {length!r}: must be a whole number of cells of side {h!r}"
                )
            counts.append(count)
        return cls(nx=nx, ny=counts[0], nz=counts[1], h=h, origin=origin)

    @property
    def lx(self) -> float:
        """Domain length along x [m]."""
        return self.nx * self.h

    @property
    def ly(self) -> float:
        """Domain length along y [m]."""
        return self.ny * self.h

    @property
    def lz(self) -> float:
        """Domain length along z [m]."""
        return self.nz * self.h

    @property
    def shape_cells(self) -> tuple[int, int, int]:
        """Shape of cell-centred arrays (pressure, dye): ``(nx, ny, nz)``."""
        return (self.nx, self.ny, self.nz)

    @property
    def shape_faces_x(self) -> tuple[int, int, int]:
        """Shape of x-face arrays (u): ``(nx+1, ny, nz)``."""
        return (self.nx + 1, self.ny, self.nz)

    @property
    def shape_faces_y(self) -> tuple[int, int, int]:
        """Shape of y-face arrays (v): ``(nx, ny+1, nz)``."""
        return (self.nx, self.ny + 1, self.nz)

    @property
    def shape_faces_z(self) -> tuple[int, int, int]:
        """Shape of z-face arrays (w): ``(nx, ny, nz+1)``."""
        return (self.nx, self.ny, self.nz + 1)

    def shape_faces(self, axis: int) -> tuple[int, int, int]:
        """Shape of the arrays on the faces normal to ``axis`` (0: x, 1: y, 2: z)."""
        if axis not in (0, 1, 2):
            raise ValueError(f"axis = {axis!r}: must be 0, 1 or 2")
        shape = list(self.shape_cells)
        shape[axis] += 1
        return (shape[0], shape[1], shape[2])

    @property
    def cell_count(self) -> int:
        return self.nx * self.ny * self.nz

    def _coordinates(
        self, offsets: tuple[float, float, float], shape: tuple[int, int, int]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        lines = [self.origin[a] + (np.arange(shape[a]) + offsets[a]) * self.h for a in range(3)]
        x, y, z = np.meshgrid(lines[0], lines[1], lines[2], indexing="ij")
        return x, y, z

    def cell_centers(
        self,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Coordinates ``(x, y, z)`` of cell centres [m], each of shape ``(nx, ny, nz)``."""
        return self._coordinates((0.5, 0.5, 0.5), self.shape_cells)

    def faces_x(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Coordinates ``(x, y, z)`` of x-faces (u points) [m], each of shape ``(nx+1, ny, nz)``."""
        return self._coordinates((0.0, 0.5, 0.5), self.shape_faces_x)

    def faces_y(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Coordinates ``(x, y, z)`` of y-faces (v points) [m], each of shape ``(nx, ny+1, nz)``."""
        return self._coordinates((0.5, 0.0, 0.5), self.shape_faces_y)

    def faces_z(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Coordinates ``(x, y, z)`` of z-faces (w points) [m], each of shape ``(nx, ny, nz+1)``."""
        return self._coordinates((0.5, 0.5, 0.0), self.shape_faces_z)
