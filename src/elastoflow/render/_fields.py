"""Derived fields for display and output, from the MAC arrays (pure NumPy, no physics)."""

from __future__ import annotations

from typing import Any

import numpy as np

from elastoflow.render._kernels import speed_from_faces


def velocity_at_cells(state: Any) -> np.ndarray:
    """Velocity averaged from the faces to the cell centres [m/s], shape (nx, ny, 2)."""
    u = state.velocity_x
    v = state.velocity_y
    return np.stack((0.5 * (u[:-1, :] + u[1:, :]), 0.5 * (v[:, :-1] + v[:, 1:])), axis=-1)


def speed_at_cells(state: Any) -> np.ndarray:
    """Velocity magnitude at cell centres [m/s], shape (nx, ny)."""
    u = np.asarray(state.velocity_x, dtype=np.float64)
    v = np.asarray(state.velocity_y, dtype=np.float64)
    # One pass without temporaries: a frame is drawn after every step when writing video.
    speed = np.empty((v.shape[0], u.shape[1]))
    speed_from_faces(u, v, speed)
    return speed


def vorticity_at_cells(state: Any, h: float) -> np.ndarray:
    """Vorticity dv/dx - du/dy [1/s] at cell centres, shape (nx, ny).

    Taken at the cell corners from the face values (the natural MAC stencil), then averaged to
    the centres; the domain's edge corners use one-sided values.
    """
    u = state.velocity_x
    v = state.velocity_y
    nx, ny = v.shape[0], u.shape[1]
    corner = np.zeros((nx + 1, ny + 1))
    corner[1:-1, :] += (v[1:, :] - v[:-1, :]) / h
    corner[:, 1:-1] -= (u[:, 1:] - u[:, :-1]) / h
    return 0.25 * (corner[:-1, :-1] + corner[1:, :-1] + corner[:-1, 1:] + corner[1:, 1:])
