"""Where bodies sit inside the 3D fluid: the 3D twin of `InteriorBoundary`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from elastoflow.grid import Grid3D

_AXES = ("x", "y", "z")


@dataclass(frozen=True)
class InteriorBoundary3D:
    """Where bodies sit inside the 3D fluid domain, as `FluidSolver3D` needs it.

    Built by ``elastoflow.coupling.interior_boundary_3d`` from the 3D boundary map (or by
    hand in tests). Fields are named per axis as in the 2D `InteriorBoundary`; ``_x``, ``_y``,
    ``_z`` belong to the u (nx+1, ny, nz), v (nx, ny+1, nz) and w (nx, ny, nz+1) points.
    Directions ``d`` of the cut arrays: 0 -x, 1 +x, 2 -y, 3 +y, 4 -z, 5 +z.

    Attributes:
        solid_cells: Cell centre inside a body, bool, shape (nx, ny, nz).
        solid_faces_x, solid_faces_y, solid_faces_z: Velocity point inside a body, bool.
        velocity_faces_x, velocity_faces_y, velocity_faces_z: The body's velocity component
            [m/s] (x at u points, ...) at the points inside bodies, 0 elsewhere.
        open_fraction_x, open_fraction_y, open_fraction_z: Fraction in [0, 1] of the face
            (the h x h square through the point, normal to its axis) that lies in fluid.
        cut_theta_x, cut_theta_y, cut_theta_z: For a velocity point, fraction of h towards
            its neighbour in direction d at which the first body boundary is crossed, in
            (0, 1]; ``inf`` when none lies within one spacing. Shape (6, *point shape).
        cut_velocity_x, cut_velocity_y, cut_velocity_z: The body's velocity component at
            that crossing [m/s], same shapes.
        box: Index box ``(i0, j0, k0, i1, j1, k1)`` (ends exclusive) outside which every
            point of every array above is fluid and uncut (solid flags False, velocities 0,
            cut distances ``inf``) and its face open (fraction 1, to the rounding of the
            section areas: 2e-16 seen), so that work done per step near the bodies can
            skip the rest; None: not known (the whole grid).

    Bodies are thicker than a cell: there is no 3D counterpart yet of the 2D thin-body cuts
    (a face closed by a body's mid-surface without covering its point).
    """

    solid_cells: np.ndarray
    solid_faces_x: np.ndarray
    solid_faces_y: np.ndarray
    solid_faces_z: np.ndarray
    velocity_faces_x: np.ndarray
    velocity_faces_y: np.ndarray
    velocity_faces_z: np.ndarray
    open_fraction_x: np.ndarray
    open_fraction_y: np.ndarray
    open_fraction_z: np.ndarray
    cut_theta_x: np.ndarray
    cut_theta_y: np.ndarray
    cut_theta_z: np.ndarray
    cut_velocity_x: np.ndarray
    cut_velocity_y: np.ndarray
    cut_velocity_z: np.ndarray
    box: tuple[int, int, int, int, int, int] | None = None

    @classmethod
    def empty(cls, grid: Grid3D) -> InteriorBoundary3D:
        """No bodies: every point fluid, every face fully open, nothing cut."""
        shapes = (grid.shape_faces_x, grid.shape_faces_y, grid.shape_faces_z)
        fields: dict[str, np.ndarray] = {"solid_cells": np.zeros(grid.shape_cells, np.bool_)}
        for name, shape in zip(_AXES, shapes, strict=True):
            fields[f"solid_faces_{name}"] = np.zeros(shape, dtype=np.bool_)
            fields[f"velocity_faces_{name}"] = np.zeros(shape)
            fields[f"open_fraction_{name}"] = np.ones(shape)
            fields[f"cut_theta_{name}"] = np.full((6, *shape), np.inf)
            fields[f"cut_velocity_{name}"] = np.zeros((6, *shape))
        return cls(**fields, box=(0, 0, 0, 0, 0, 0))

    def solid_faces(self, axis: int) -> np.ndarray:
        return (self.solid_faces_x, self.solid_faces_y, self.solid_faces_z)[axis]

    def velocity_faces(self, axis: int) -> np.ndarray:
        return (self.velocity_faces_x, self.velocity_faces_y, self.velocity_faces_z)[axis]

    def open_fraction(self, axis: int) -> np.ndarray:
        return (self.open_fraction_x, self.open_fraction_y, self.open_fraction_z)[axis]

    def cut_theta(self, axis: int) -> np.ndarray:
        return (self.cut_theta_x, self.cut_theta_y, self.cut_theta_z)[axis]

    def cut_velocity(self, axis: int) -> np.ndarray:
        return (self.cut_velocity_x, self.cut_velocity_y, self.cut_velocity_z)[axis]

    def check(self, grid: Grid3D) -> None:
        """Raise ValueError if an array's shape or dtype is wrong for ``grid``."""
        expected: dict[str, tuple[tuple[int, ...], type]] = {
            "solid_cells": (grid.shape_cells, np.bool_)}
        shapes: tuple[tuple[int, ...], ...] = (grid.shape_faces_x, grid.shape_faces_y,
                                               grid.shape_faces_z)
        for name, shape in zip(_AXES, shapes, strict=True):
            expected[f"solid_faces_{name}"] = (shape, np.bool_)
            expected[f"velocity_faces_{name}"] = (shape, np.float64)
            expected[f"open_fraction_{name}"] = (shape, np.float64)
            expected[f"cut_theta_{name}"] = ((6, *shape), np.float64)
            expected[f"cut_velocity_{name}"] = ((6, *shape), np.float64)
        for name, (shape, dtype) in expected.items():
            value = getattr(self, name)
            if not isinstance(value, np.ndarray) or value.shape != shape or value.dtype != dtype:
                got = (f"shape {value.shape}, dtype {value.dtype}"
                       if isinstance(value, np.ndarray) else repr(value))
                raise ValueError(f"InteriorBoundary3D.{name} {got}: must be "
                                 f"{np.dtype(dtype).name} of shape {shape} for this grid")
