from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from elastoflow.grid import Grid2D


@dataclass(frozen=True)
class InteriorBoundary:
    """Where bodies sit inside the fluid domain, as the fluid solver needs it.

    Built by ``elastoflow.coupling`` from the boundary map each step (or by hand in tests).
    Directions ``d`` of the cut arrays: 0: -x, 1: +x, 2: -y, 3: +y.

    Attributes:
        solid_cells: Cell centre inside a body, bool, shape (nx, ny).
        solid_faces_x: u point inside a body, bool, shape (nx+1, ny).
        solid_faces_y: v point inside a body, bool, shape (nx, ny+1).
        velocity_faces_x: Body x-velocity [m/s] at u points inside bodies and on faces with
            open fraction exactly 0, 0 elsewhere, shape (nx+1, ny); the dual-cell treatment
            also gives it on partly open faces with their point in fluid (the mean body
            velocity over the covered part of the face's dual cell), which the projection
            reads where no crossing lies along the face.
        velocity_faces_y: Body y-velocity [m/s] at v points inside bodies and on faces with
            open fraction exactly 0, 0 elsewhere, shape (nx, ny+1).
        open_fraction_x: Fraction in [0, 1] of the x-face (the segment of length h through the
            u point, along y) that lies in fluid, shape (nx+1, ny); 0 also where a body
            thinner than a cell separates the face's two cells without covering the segment
            (the pressure connection is cut; the face carries ``velocity_faces_x``).
        open_fraction_y: Same for y-faces (segment along x through the v point),
            shape (nx, ny+1).
        cut_theta_x: For a u point, fraction of the spacing h towards its neighbour in
            direction d at which the first body boundary is crossed, in (0, 1]; ``inf`` when no
            boundary lies within one spacing. Shape (4, nx+1, ny).
        cut_theta_y: Same for v points, shape (4, nx, ny+1).
        cut_velocity_x: Body x-velocity [m/s] at the crossing of ``cut_theta_x``,
            shape (4, nx+1, ny).
        cut_velocity_y: Body y-velocity [m/s] at the crossing of ``cut_theta_y``,
            shape (4, nx, ny+1).
        regions: Where bodies may be: index boxes ``(i_begin, i_end, j_begin, j_end)``,
            half-open, int64, shape (K, 4), in the index space that cells, u points and
            v points share (a box holds cell ``(i, j)``, u point ``(i, j)`` and v point
            ``(i, j)`` alike); boxes may reach beyond the arrays, and an empty box holds
            nothing. Guarantee: at every index ``(i, j)`` outside all boxes every array holds
            the empty state (not solid, body velocity 0, open fraction 1, ``cut_theta`` inf
            and ``cut_velocity`` 0 in all four directions), so the fluid treats those points
            as plain fluid without reading the arrays. ``None`` (the default, what hand-built
            objects get) means bodies may be anywhere. Whoever writes into the arrays outside
            the boxes, or swaps an array with ``dataclasses.replace``, must keep the guarantee
            or set ``regions=None``.
    """

    solid_cells: np.ndarray
    solid_faces_x: np.ndarray
    solid_faces_y: np.ndarray
    velocity_faces_x: np.ndarray
    velocity_faces_y: np.ndarray
    open_fraction_x: np.ndarray
    open_fraction_y: np.ndarray
    cut_theta_x: np.ndarray
    cut_theta_y: np.ndarray
    cut_velocity_x: np.ndarray
    cut_velocity_y: np.ndarray
    regions: np.ndarray | None = None

    @classmethod
    def empty(cls, grid: Grid2D) -> InteriorBoundary:
        """No bodies: every point fluid, every face fully open, nothing cut.

        ``regions`` is None: the result is meant to be filled in place (as
        ``elastoflow.coupling`` does), so it makes no promise about where bodies will be.
        """
        fx, fy = grid.shape_faces_x, grid.shape_faces_y
        return cls(
            solid_cells=np.zeros(grid.shape_cells, dtype=np.bool_),
            solid_faces_x=np.zeros(fx, dtype=np.bool_),
            solid_faces_y=np.zeros(fy, dtype=np.bool_),
            velocity_faces_x=np.zeros(fx),
            velocity_faces_y=np.zeros(fy),
            open_fraction_x=np.ones(fx),
            open_fraction_y=np.ones(fy),
            cut_theta_x=np.full((4, *fx), np.inf),
            cut_theta_y=np.full((4, *fy), np.inf),
            cut_velocity_x=np.zeros((4, *fx)),
            cut_velocity_y=np.zeros((4, *fy)),
        )

    def check(self, grid: Grid2D) -> None:
        """Raise ValueError if an array's shape, or ``regions``' shape or dtype, is wrong."""
        fx, fy, c = grid.shape_faces_x, grid.shape_faces_y, grid.shape_cells
        expected = {
            "solid_cells": c,
            "solid_faces_x": fx,
            "solid_faces_y": fy,
            "velocity_faces_x": fx,
            "velocity_faces_y": fy,
            "open_fraction_x": fx,
            "open_fraction_y": fy,
            "cut_theta_x": (4, *fx),
            "cut_theta_y": (4, *fy),
            "cut_velocity_x": (4, *fx),
            "cut_velocity_y": (4, *fy),
        }
        for name, shape in expected.items():
            value = getattr(self, name)
            if value.shape != shape:
                raise ValueError(
                    f"InteriorBoundary.{name} shape {value.shape}: must be {shape} for this grid"
                )
        if self.regions is not None:
            regions = self.regions
            if not (isinstance(regions, np.ndarray) and regions.dtype == np.int64
                    and regions.ndim == 2 and regions.shape[1] == 4):
                description = (f"shape {regions.shape}, dtype {regions.dtype}"
                               if isinstance(regions, np.ndarray) else repr(regions))
                raise ValueError(
                    f"InteriorBoundary.regions {description}: must be None or an int64 array "
                    f"of shape (K, 4)"
                )
