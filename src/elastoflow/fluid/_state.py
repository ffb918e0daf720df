from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from elastoflow.grid import Grid2D


@dataclass
class FluidState:
    """The changing part of the fluid: velocity on the faces, pressure and dye in the cells.

    The solver updates these arrays in place, so references to them stay valid across steps.

    Attributes:
        velocity_x: Face x-velocities u [m/s] at ``(i h, (j+1/2) h)``, shape (nx+1, ny).
        velocity_y: Face y-velocities v [m/s] at ``((i+1/2) h, j h)``, shape (nx, ny+1).
        pressure: Cell-centred pressure [Pa] of the last projection, shape (nx, ny).
        dye: Cell-centred passive scalar (dimensionless concentration), shape (nx, ny).
    """

    velocity_x: np.ndarray
    velocity_y: np.ndarray
    pressure: np.ndarray
    dye: np.ndarray

    @classmethod
    def zeros(cls, grid: Grid2D) -> FluidState:
        """Fluid at rest, zero pressure and no dye on ``grid``."""
        return cls(
            velocity_x=np.zeros(grid.shape_faces_x),
            velocity_y=np.zeros(grid.shape_faces_y),
            pressure=np.zeros(grid.shape_cells),
            dye=np.zeros(grid.shape_cells),
        )

    def check(self, grid: Grid2D) -> None:
        """Raise ValueError if an array's shape does not match ``grid`` or is not float64."""
        expected = {
            "velocity_x": grid.shape_faces_x,
            "velocity_y": grid.shape_faces_y,
            "pressure": grid.shape_cells,
            "dye": grid.shape_cells,
        }
        for name, shape in expected.items():
            value = getattr(self, name)
            if not isinstance(value, np.ndarray) or value.shape != shape:
                got = getattr(value, "shape", type(value).__name__)
                raise ValueError(f"FluidState.{name} shape {got}: must be {shape} for this grid")
            if value.dtype != np.float64:
                raise ValueError(f"FluidState.{name} dtype {value.dtype}: must be float64")
