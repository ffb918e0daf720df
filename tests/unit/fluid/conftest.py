from __future__ import annotations

import numpy as np
import pytest

from elastoflow.fluid import InteriorBoundary
from elastoflow.grid import Grid2D


def block_interior(grid: Grid2D, x0: float, y0: float, x1: float, y1: float,
                   velocity: tuple[float, float] = (0.0, 0.0)) -> InteriorBoundary:
    """InteriorBoundary of a rectangle [x0, x1] x [y0, y1] [m] moving rigidly with ``velocity``.

    Points on the rectangle's boundary count as inside; cut fractions and open fractions are
    exact for the rectangle.
    """
    h = grid.h

    def inside(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)

    def cuts(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        # First crossing of the rectangle's boundary within one spacing, from points outside.
        theta = np.full((4, *x.shape), np.inf)
        outside = ~inside(x, y)
        in_rows = (y >= y0) & (y <= y1)
        in_columns = (x >= x0) & (x <= x1)
        candidates = (
            (in_rows & (x > x1) & (x - h <= x1), (x - x1) / h),   # -x
            (in_rows & (x < x0) & (x + h >= x0), (x0 - x) / h),   # +x
            (in_columns & (y > y1) & (y - h <= y1), (y - y1) / h),  # -y
            (in_columns & (y < y0) & (y + h >= y0), (y0 - y) / h),  # +y
        )
        for d, (hit, t) in enumerate(candidates):
            hit = hit & outside
            theta[d][hit] = t[hit]
        return theta

    def open_fraction(x: np.ndarray, y: np.ndarray, along_y: bool) -> np.ndarray:
        if along_y:
            on_line = (x >= x0) & (x <= x1)
            low, high, a, b = y - h / 2, y + h / 2, y0, y1
        else:
            on_line = (y >= y0) & (y <= y1)
            low, high, a, b = x - h / 2, x + h / 2, x0, x1
        overlap = np.clip(np.minimum(high, b) - np.maximum(low, a), 0.0, None) / h
        return np.where(on_line, np.clip(1.0 - overlap, 0.0, 1.0), 1.0)

    xc, yc = grid.cell_centers()
    xu, yu = grid.faces_x()
    xv, yv = grid.faces_y()
    solid_u, solid_v = inside(xu, yu), inside(xv, yv)
    theta_x, theta_y = cuts(xu, yu), cuts(xv, yv)
    return InteriorBoundary(
        solid_cells=inside(xc, yc),
        solid_faces_x=solid_u,
        solid_faces_y=solid_v,
        velocity_faces_x=np.where(solid_u, velocity[0], 0.0),
        velocity_faces_y=np.where(solid_v, velocity[1], 0.0),
        open_fraction_x=open_fraction(xu, yu, True),
        open_fraction_y=open_fraction(xv, yv, False),
        cut_theta_x=theta_x,
        cut_theta_y=theta_y,
        cut_velocity_x=np.where(np.isfinite(theta_x), velocity[0], 0.0),
        cut_velocity_y=np.where(np.isfinite(theta_y), velocity[1], 0.0),
    )


@pytest.fixture
def make_block():
    """The `block_interior` builder."""
    return block_interior


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)
