from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from elastoflow.grid import Grid2D

OPTIONAL = {"checkpoint": "optional"}
"""Field metadata of state a checkpoint saves only when it is there (None: absent)."""


@dataclass
class FluidState:
    """The changing part of the fluid: velocity on the faces, pressure and dye in the cells.

    The solver updates these arrays in place, so references to them stay valid across steps.

    Attributes:
        velocity_x: Face x-velocities u [m/s] at ``(i h, (j+1/2) h)``, shape (nx+1, ny).
        velocity_y: Face y-velocities v [m/s] at ``((i+1/2) h, j h)``, shape (nx, ny+1).
        pressure: Cell-centred pressure [Pa] of the last projection, shape (nx, ny).
        dye: Cell-centred passive scalar (dimensionless concentration), shape (nx, ny).
        previous_velocity_x: u at the start of the last step, kept only by a solver with
            ``advecting_velocity="extrapolated"`` (None otherwise, and before its first step).
        previous_velocity_y: v at the start of the last step, likewise.
        previous_dt: The last step's dt [s] (None with the two fields above).
        previous_pressure: The pressure before the last projection, kept by a solver with
            ``pressure_guess="extrapolated"`` (None otherwise, and before its second
            projection) to start the next solve from ``p + dt / dt_p (p - p_previous)``.
        previous_pressure_dt: The step between ``previous_pressure`` and ``pressure`` [s].
    """

    velocity_x: np.ndarray
    velocity_y: np.ndarray
    pressure: np.ndarray
    dye: np.ndarray
    previous_velocity_x: np.ndarray | None = field(default=None, metadata=OPTIONAL)
    previous_velocity_y: np.ndarray | None = field(default=None, metadata=OPTIONAL)
    previous_dt: float | None = field(default=None, metadata=OPTIONAL)
    previous_pressure: np.ndarray | None = field(default=None, metadata=OPTIONAL)
    previous_pressure_dt: float | None = field(default=None, metadata=OPTIONAL)

    @classmethod
    def zeros(cls, grid: Grid2D) -> FluidState:
        """Fluid at rest, zero pressure and no dye on ``grid``."""
        return cls(
            velocity_x=np.zeros(grid.shape_faces_x),
            velocity_y=np.zeros(grid.shape_faces_y),
            pressure=np.zeros(grid.shape_cells),
            dye=np.zeros(grid.shape_cells),
        )

    def copy(self) -> FluidState:
        """An independent copy, optional fields included."""
        values: dict[str, Any] = {}
        for item in fields(self):
            value = getattr(self, item.name)
            values[item.name] = value.copy() if isinstance(value, np.ndarray) else value
        return FluidState(**values)

    def assign(self, other: FluidState) -> None:
        """Copy ``other``'s values into this state's arrays (optional ones are set, copied
        or dropped to match ``other``)."""
        for item in fields(self):
            source = getattr(other, item.name)
            target = getattr(self, item.name)
            if isinstance(source, np.ndarray):
                if isinstance(target, np.ndarray) and target.shape == source.shape:
                    target[...] = source
                else:
                    setattr(self, item.name, source.copy())
            else:
                setattr(self, item.name, source)

    def check(self, grid: Grid2D) -> None:
        """Raise ValueError if an array's shape does not match ``grid`` or is not float64."""
        expected = {
            "velocity_x": grid.shape_faces_x,
            "velocity_y": grid.shape_faces_y,
            "pressure": grid.shape_cells,
            "dye": grid.shape_cells,
            "previous_velocity_x": grid.shape_faces_x,
            "previous_velocity_y": grid.shape_faces_y,
            "previous_pressure": grid.shape_cells,
        }
        for name, shape in expected.items():
            value = getattr(self, name)
            if value is None and name.startswith("previous_"):
                continue
            if not isinstance(value, np.ndarray) or value.shape != shape:
                got = getattr(value, "shape", type(value).__name__)
                raise ValueError(f"FluidState.{name} shape {got}: must be {shape} for this grid")
            if value.dtype != np.float64:
                raise ValueError(f"FluidState.{name} dtype {value.dtype}: must be float64")
