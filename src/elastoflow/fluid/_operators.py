from __future__ import annotations

import numpy as np

from elastoflow.fluid import _kernels as kernels


def divergence_faces_to_cells(
    velocity_x: np.ndarray,
    velocity_y: np.ndarray,
    h: float,
    open_fraction_x: np.ndarray | None = None,
    open_fraction_y: np.ndarray | None = None,
) -> np.ndarray:
    """Cell divergence ``div(A u)`` [1/s] of face velocities, with face weights A (default 1).

    Args:
        velocity_x: u [m/s], shape (nx+1, ny).
        velocity_y: v [m/s], shape (nx, ny+1).
        h: Cell side [m].
        open_fraction_x: Weights A of the x-faces, shape (nx+1, ny), or None for 1.
        open_fraction_y: Weights A of the y-faces, shape (nx, ny+1), or None for 1.

    Returns:
        Divergence per cell, shape (nx, ny).
    """
    u = np.ascontiguousarray(velocity_x, dtype=np.float64)
    v = np.ascontiguousarray(velocity_y, dtype=np.float64)
    nx, ny = v.shape[0], u.shape[1]
    if u.shape != (nx + 1, ny) or v.shape != (nx, ny + 1):
        raise ValueError(
            f"velocity shapes {u.shape}, {v.shape}: must be (nx+1, ny) and (nx, ny+1)"
        )
    weighted = open_fraction_x is not None or open_fraction_y is not None
    ax = np.ones(u.shape) if open_fraction_x is None else np.ascontiguousarray(open_fraction_x,
                                                                                dtype=np.float64)
    ay = np.ones(v.shape) if open_fraction_y is None else np.ascontiguousarray(open_fraction_y,
                                                                                dtype=np.float64)
    out = np.empty((nx, ny))
    kernels.divergence(u, v, float(h), weighted, ax, ay, out)
    return out


def gradient_cells_to_faces(pressure: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Face gradient of a cell field; the faces on the domain sides get 0.

    Args:
        pressure: Cell values, shape (nx, ny).
        h: Cell side [m].

    Returns:
        ``(gx, gy)``: x-face gradient, shape (nx+1, ny), and y-face gradient, shape (nx, ny+1).
        With zero side faces, ``divergence_faces_to_cells`` is minus the transpose of this map.
    """
    p = np.asarray(pressure, dtype=np.float64)
    nx, ny = p.shape
    gx = np.zeros((nx + 1, ny))
    gy = np.zeros((nx, ny + 1))
    gx[1:-1] = (p[1:] - p[:-1]) / h
    gy[:, 1:-1] = (p[:, 1:] - p[:, :-1]) / h
    return gx, gy
