from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Grid2D:
    """A uniform 2D MAC grid of ``nx × ny`` square cells of side ``h`` [m].

    Attributes:
        nx: Number of cells along x.
        ny: Number of cells along y.
        h: Cell side [m].
        origin: Position of the lower-left domain corner [m].
    """

    nx: int
    ny: int
    h: float
    origin: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        if int(self.nx) != self.nx or self.nx < 2:
            raise ValueError(f"grid nx = {self.nx!r}: must be an integer >= 2")
        if int(self.ny) != self.ny or self.ny < 2:
            raise ValueError(f"grid ny = {self.ny!r}: must be an integer >= 2")
        if not (self.h > 0.0 and np.isfinite(self.h)):
            raise ValueError(f"grid h = {self.h!r}: must be a finite positive length")

    @classmethod
    def from_extent(
        cls, lx: float, ly: float, nx: int, origin: tuple[float, float] = (0.0, 0.0)
    ) -> Grid2D:
        """Grid of ``nx`` cells across ``lx`` [m]; ``ly / h`` must be a whole number of cells."""
        h = lx / nx
        ny = int(round(ly / h))
        if abs(ny * h - ly) > 1e-9 * max(ly, 1.0):
            raise ValueError(
                f"domain height ly = {ly!r}: must be a whole number of cells of side {h!r}"
            )
        return cls(nx=nx, ny=ny, h=h, origin=origin)

    @property
    def lx(self) -> float:
        """Domain width [m]."""
        return self.nx * self.h

    @property
    def ly(self) -> float:
        """Domain height [m]."""
        return self.ny * self.h

    @property
    def shape_cells(self) -> tuple[int, int]:
        """Shape of cell-centred arrays (pressure, dye): ``(nx, ny)``."""
        return (self.nx, self.ny)

    @property
    def shape_faces_x(self) -> tuple[int, int]:
        """Shape of x-face arrays (u): ``(nx+1, ny)``."""
        return (self.nx + 1, self.ny)

    @property
    def shape_faces_y(self) -> tuple[int, int]:
        """Shape of y-face arrays (v): ``(nx, ny+1)``."""
        return (self.nx, self.ny + 1)

    @property
    def shape_half(self) -> tuple[int, int]:
        """Shape of the half grid ``(2nx+1, 2ny+1)``."""
        return (2 * self.nx + 1, 2 * self.ny + 1)

    @property
    def cell_count(self) -> int:
        return self.nx * self.ny

    def cell_centers(self) -> tuple[np.ndarray, np.ndarray]:
        """Coordinates ``(x, y)`` of cell centres [m], each of shape ``(nx, ny)``."""
        x = self.origin[0] + (np.arange(self.nx) + 0.5) * self.h
        y = self.origin[1] + (np.arange(self.ny) + 0.5) * self.h
        return np.meshgrid(x, y, indexing="ij")

    def faces_x(self) -> tuple[np.ndarray, np.ndarray]:
        """Coordinates ``(x, y)`` of x-faces (u points) [m], each of shape ``(nx+1, ny)``."""
        x = self.origin[0] + np.arange(self.nx + 1) * self.h
        y = self.origin[1] + (np.arange(self.ny) + 0.5) * self.h
        return np.meshgrid(x, y, indexing="ij")

    def faces_y(self) -> tuple[np.ndarray, np.ndarray]:
        """Coordinates ``(x, y)`` of y-faces (v points) [m], each of shape ``(nx, ny+1)``."""
        x = self.origin[0] + (np.arange(self.nx) + 0.5) * self.h
        y = self.origin[1] + np.arange(self.ny + 1) * self.h
        return np.meshgrid(x, y, indexing="ij")

    def half_grid_line_x(self, index: int) -> float:
        """x coordinate [m] of the half-grid column ``I = index``."""
        return self.origin[0] + 0.5 * index * self.h

    def half_grid_line_y(self, index: int) -> float:
        """y coordinate [m] of the half-grid row ``J = index``."""
        return self.origin[1] + 0.5 * index * self.h
