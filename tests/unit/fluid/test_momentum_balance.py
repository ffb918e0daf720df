"""`MomentumBalance`: the force on what a box of cells holds, exact discrete identities."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow.fluid import BoxCells, MomentumBalance
from elastoflow.grid import Grid2D


def test_still_water_pushes_an_obstacle_up_by_the_weight_of_the_water_it_displaces() -> None:
    """Hydrostatic pressure, no flow, gravity -9.81: the balance is the buoyancy of the faces
    the obstacle covers (the fluid's weight is counted on the other faces), and nothing
    sideways."""
    grid = Grid2D(30, 20, 0.05)
    gravity = -9.81
    density = 1000.0
    x, y = grid.cell_centers()
    pressure = density * -gravity * (1.0 - y)
    xv = (np.arange(grid.nx)[:, None] + 0.5) * grid.h
    yv = np.arange(grid.ny + 1)[None, :] * grid.h
    xu = np.arange(grid.nx + 1)[:, None] * grid.h
    yu = (np.arange(grid.ny)[None, :] + 0.5) * grid.h

    def inside(px: np.ndarray, py: np.ndarray) -> np.ndarray:
        return (px - 0.75) ** 2 + (py - 0.5) ** 2 < 0.2**2

    solid = (inside(xu, yu), inside(xv, yv))
    box = BoxCells.around(grid, (0.3, 0.1), (1.2, 0.9))
    balance = MomentumBalance(grid, box, density, 1e-3, gravity=(0.0, gravity))
    still = (np.zeros(grid.shape_faces_x), np.zeros(grid.shape_faces_y))
    assert np.isnan(balance.force(*still, pressure, 0.01, solid)[0])
    force = balance.force(*still, pressure, 0.01, solid)
    displaced = density * -gravity * grid.h**2 * float(solid[1].sum())
    assert force[1] == pytest.approx(displaced, rel=1e-12)
    assert force[0] == pytest.approx(0.0, abs=1e-9 * displaced)


def test_a_box_must_hold_a_cell_and_keep_off_the_edges() -> None:
    grid = Grid2D(10, 10, 0.1)
    with pytest.raises(ValueError, match="keep one cell from the edges"):
        MomentumBalance(grid, BoxCells(0, 5, 1, 5), 1.0, 1e-3)
    with pytest.raises(ValueError, match="must hold a cell"):
        MomentumBalance(grid, BoxCells(3, 3, 1, 5), 1.0, 1e-3)
    assert BoxCells.around(grid, (-1.0, 0.21), (0.46, 5.0)) == BoxCells(1, 5, 2, 9)
