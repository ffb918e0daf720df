"""The changing part of the 3D fluid."""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import NDArray

from elastoflow.grid import Grid3D


@dataclass
class FluidState3D:
    """Velocity on the faces, pressure and dye in the cells of a `Grid3D`.

    The solver updates these arrays in place, so references to them stay valid across steps.

    Attributes:
        velocity_x: Face x-velocities u [m/s] at ``(i h, (j+1/2) h, (k+1/2) h)``,
            shape (nx+1, ny, nz).
        velocity_y: Face y-velocities v [m/s] at ``((i+1/2) h, j h, (k+1/2) h)``,
            shape (nx, ny+1, nz).
        velocity_z: Face z-velocities w [m/s] at ``((i+1/2) h, (j+1/2) h, k h)``,
            shape (nx, ny, nz+1).
        pressure: Cell-centred pressure [Pa] of the last projection, shape (nx, ny, nz).
        dye: Cell-centred passive scalar (dimensionless concentration), shape (nx, ny, nz).
    """

    velocity_x: NDArray[np.float64]
    velocity_y: NDArray[np.float64]
    velocity_z: NDArray[np.float64]
    pressure: NDArray[np.float64]
    dye: NDArray[np.float64]

    @classmethod
    def zeros(cls, grid: Grid3D) -> FluidState3D:
        """Fluid at rest, zero pressure and no dye on ``grid``."""
        return cls(
            velocity_x=np.zeros(grid.shape_faces_x),
            velocity_y=np.zeros(grid.shape_faces_y),
            velocity_z=np.zeros(grid.shape_faces_z),
            pressure=np.zeros(grid.shape_cells),
            dye=np.zeros(grid.shape_cells),
        )

    def velocity(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """``(u, v, w)``, the three face-velocity arrays."""
        return (self.velocity_x, self.velocity_y, self.velocity_z)

    def copy(self) -> FluidState3D:
        """An independent copy."""
        return FluidState3D(**{item.name: getattr(self, item.name).copy()
                               for item in fields(self)})

    def assign(self, other: FluidState3D, names: Collection[str] | None = None) -> None:
        """Copy ``other``'s values into this state's arrays (same shapes): all, or the
        fields ``names``."""
        for item in fields(self):
            if names is None or item.name in names:
                getattr(self, item.name)[...] = getattr(other, item.name)

    def check(self, grid: Grid3D) -> None:
        """Raise ValueError if an array is not a C-contiguous float64 array of the shape
        ``grid`` gives it."""
        expected = {
            "velocity_x": grid.shape_faces_x,
            "velocity_y": grid.shape_faces_y,
            "velocity_z": grid.shape_faces_z,
            "pressure": grid.shape_cells,
            "dye": grid.shape_cells,
        }
        for name, shape in expected.items():
            value = getattr(self, name)
            if not isinstance(value, np.ndarray) or value.shape != shape:
                got = getattr(value, "shape", type(value).__name__)
                raise ValueError(f"FluidState3D.{name} shape {got}: must be {shape} for this grid")
            if value.dtype != np.float64 or not value.flags.c_contiguous:
                raise ValueError(
                    f"FluidState3D.{name} dtype {value.dtype}: must be C-contiguous float64")
