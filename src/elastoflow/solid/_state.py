"""The changing part of an elastic body: node positions and velocities."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(eq=False)
class BodyState:
    """World node positions [m] and velocities [m/s] of one body, float64, shape (n, 2)
    (3D bodies: (n, 3)).

    Integrators read one state and write another (the same one for an in-place step); the
    arrays are updated in place, so references to them stay valid across steps.
    """

    positions: np.ndarray
    velocities: np.ndarray

    def copy(self) -> BodyState:
        """An independent copy."""
        return BodyState(self.positions.copy(), self.velocities.copy())

    def assign(self, other: BodyState) -> None:
        """Copy ``other``'s values into this state's arrays."""
        self.positions[...] = other.positions
        self.velocities[...] = other.velocities
