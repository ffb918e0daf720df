"""The bodies' side of the 3D pressure equation as a linear map of their nodal velocities.

The 3D twin of `interface_flux`. The projection keeps ``div(A u + (1 - A) u_s)`` at zero
(`FluidSolver3D.project`), ``(1 - A)`` the part of a face's square that a body covers. For a
strongly coupled step that part must be linear in the bodies' nodal velocities ``V`` (degree
of freedom ``3 node + component``), and its transpose must give the pressure's nodal force:

    (1 - A_f) u_s,f = (W V)_f = (1 / h^2) int_{Q_f} v_n dA

with ``Q_f`` the covered part of face f's square (the bodies' cross-section in the face's
plane) and ``v_n`` the normal (the face axis) component of the body's own velocity field
there: **the exact mean normal velocity over the covered part**. The field is the bodies'
finite-element one, linear in each tetrahedron. A plane cuts a tetrahedron in a triangle or a
quadrilateral on which the field is linear; clipped to the face square, each piece adds the
integrals of its corners' barycentric functions (area times their value at the piece's
centroid). A body without tetrahedra (an obstacle, or a body handed over by its surface only)
is filled by signed cones from one of its own surface vertices to each surface triangle: for
a closed surface their signed sections add up to its cross-section at every point, and the
field, linear in each cone, is the affine one wherever the motion is affine.

What this makes exact (tests/unit/coupling/test_interface3d.py):

* the covered area: the pieces tile ``Q_f``, so a unit translation gives ``1 - A_f`` to
  round-off (the same cross-sections and the same "a vertex on a plane counts as above it"
  as `face_open_fractions_3d`);
* the flux of any affine motion (rigid translation and rotation, uniform strain): the
  covered part's area times the velocity at its centroid. By the divergence theorem on
  (cell n body), a cell's net body outflow ``(D W V)_c`` is then minus the flux of the body
  surface inside it plus ``div v`` times the body's volume there: 0 in every cell a rigid
  body fills, and ``sum_c (D W V)_c = 0`` over the cells the pressure equation has;
* the force as the transpose: ``f = h^2 W^T D^T p`` (``D``: a face's row counts + in its
  low cell, - in its high one, over the cells the pressure equation has), so that power
  ``f . V = h^2 p . D W V`` is the pressure's work on the flux. A uniform pressure gives
  no net force and no torque, and hydrostatic pressure Archimedes' force exactly on a box
  lying on the grid (within 0.33 % on a sphere 8 cells across, 0.05 % at 32: each cell's
  centre pressure acts on the body surface inside it).

Faces the fluid treats as closed (open fraction below ``OPEN_MIN``) carry their whole flux,
as in 2D: each piece's functions are read at its centroid shifted by the face centre minus
the covered part's centroid, and the row is divided by ``1 - A``: an affine motion's exact
flux through the whole face (the velocity at its centre), so that a cell the pressure
equation drops, closed all round, keeps a rigid motion's zero net flux.

Not yet: bodies that overlap (a flag clamped in an obstacle) add both their covered parts,
as the open fractions count the overlap twice; no thin-body cuts (none exist in 3D).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from elastoflow.coupling import _kernels3d
from elastoflow.coupling._interface import SparseRows, _cell_rows, _merge_segments
from elastoflow.coupling._map3d import BoundaryMap3D
from elastoflow.fluid import OPEN_MIN
from elastoflow.fluid._interior3d import InteriorBoundary3D
from elastoflow.grid import Grid3D

# Rows of W: x faces, then y faces, then z faces, each in C order of its (x, y, z) shape.
_AXES = (0, 1, 2)
# Entries a piece of a tetrahedron adds to its face's row: one per corner.
_CORNERS = 4


@dataclass(frozen=True, eq=False)
class InterfaceFlux3D:
    """``W`` restricted to the faces it touches, with each face's two cells.

    Attributes:
        grid: The grid.
        rows: ``W`` (`SparseRows`), shape (F, 3P): row r is face ``faces[r]``'s body flux
            over the face's area [m/s] from the nodal velocity components (column ``3 point
            + component``, points those of the boundary map).
        faces: Flat face index of each row: x faces ``(i ny + j) nz + k``, then y faces from
            ``(nx+1) ny nz`` as ``(i (ny+1) + j) nz + k``, then z faces from ``(nx+1) ny nz +
            nx (ny+1) nz`` as ``(i ny + j) (nz+1) + k``, int64, shape (F,).
        low_cell: Flat index ``(i ny + j) nz + k`` of the cell on the face's low side, or -1
            outside the domain, int64, shape (F,).
        high_cell: The same on the high side.
        axis: Normal of each row's face (0 x, 1 y, 2 z), int8, shape (F,).
        active: Cells the pressure equation has (an interior face open by ``OPEN_MIN``), bool,
            shape (nx, ny, nz).
    """

    grid: Grid3D
    rows: SparseRows
    faces: np.ndarray
    low_cell: np.ndarray
    high_cell: np.ndarray
    axis: np.ndarray
    active: np.ndarray

    def cell_rows(self) -> tuple[np.ndarray, SparseRows]:
        """``D W`` on the `active` cells next to ``W``'s faces, the coupling block of the
        pressure equation: ``(cells, rows)``, ``cells`` their flat indices ascending (int64)
        and row k cell ``cells[k]``'s net body outflow over a face area per unit nodal
        velocity (``(D W)^T`` applied to a pressure and times h^2 is `pressure_forces`)."""
        rows = self.rows
        cells, indptr, indices, data = _cell_rows(
            rows.indptr, rows.indices, rows.data, self.low_cell, self.high_cell,
            np.ascontiguousarray(self.active).reshape(-1))
        return cells, SparseRows(indptr, indices, data, rows.columns)

    def face_flux(self, velocities: np.ndarray) -> np.ndarray:
        """``W V``: body flux over each row's face area [m/s] for nodal ``velocities``
        (P, 3), shape (F,)."""
        return self.rows.times(velocities)

    def cell_flux(self, velocities: np.ndarray, cells: np.ndarray | None = None) -> np.ndarray:
        """``D W V``: each cell's net body outflow over a face area [m/s] (times h^2: the
        volume flux [m^3/s]), shape (nx, ny, nz); only ``cells`` (bool, default `active`)
        are filled, the others are 0."""
        cells = self.active if cells is None else cells
        flux = self.face_flux(velocities)
        out = np.zeros(self.grid.shape_cells).reshape(-1)
        keep = cells.reshape(-1)
        for side, sign in ((self.low_cell, 1.0), (self.high_cell, -1.0)):
            inside = side >= 0
            chosen = inside.copy()
            chosen[inside] = keep[side[inside]]
            np.add.at(out, side[chosen], sign * flux[chosen])
        return out.reshape(self.grid.shape_cells)

    def pressure_forces(self, pressure: np.ndarray, cells: np.ndarray | None = None
                        ) -> np.ndarray:
        """``h^2 W^T D^T p``: the force [N] of the cell ``pressure`` [Pa] (nx, ny, nz) on the
        nodes, shape (P, 3), over ``cells`` (bool, default `active`; the others' pressure
        counts as 0). The adjoint of `cell_flux`: ``sum f . V = h^2 sum p D W V``."""
        cells = self.active if cells is None else cells
        flat = np.where(cells, pressure, 0.0).reshape(-1)
        difference = np.zeros(self.faces.shape[0])
        for side, sign in ((self.low_cell, 1.0), (self.high_cell, -1.0)):
            inside = side >= 0
            difference[inside] += sign * flat[side[inside]]
        forces = self.grid.h**2 * self.rows.transpose_times(difference)
        return forces.reshape(-1, 3)


def _check_tetrahedra(bmap: BoundaryMap3D, tetrahedra: np.ndarray | None,
                      tetrahedron_offsets: np.ndarray | None
                      ) -> tuple[np.ndarray, np.ndarray]:
    point_count = bmap.points.shape[0]
    if tetrahedra is None and tetrahedron_offsets is None:
        return np.zeros((0, _CORNERS), dtype=np.int64), np.zeros(1, dtype=np.int64)
    if tetrahedra is None or tetrahedron_offsets is None:
        raise ValueError("tetrahedra and tetrahedron_offsets: give both or neither")
    tetrahedra = np.ascontiguousarray(tetrahedra)
    offsets = np.ascontiguousarray(tetrahedron_offsets)
    if tetrahedra.ndim != 2 or tetrahedra.shape[1] != _CORNERS or not np.issubdtype(
            tetrahedra.dtype, np.integer):
        raise ValueError(f"tetrahedra: shape {tetrahedra.shape} of {tetrahedra.dtype} is not "
                         "allowed; expected integers (T, 4)")
    if tetrahedra.size and (tetrahedra.min() < 0 or tetrahedra.max() >= point_count):
        raise ValueError(f"tetrahedra: indices must lie in [0, {point_count}); got "
                         f"[{tetrahedra.min()}, {tetrahedra.max()}]")
    if (offsets.ndim != 1 or offsets.shape[0] < 1 or not np.issubdtype(offsets.dtype,
                                                                      np.integer)
            or offsets[0] != 0 or offsets[-1] != tetrahedra.shape[0]
            or np.any(np.diff(offsets) < 0)):
        raise ValueError(f"tetrahedron_offsets = {offsets!r}: must rise from 0 to "
                         f"{tetrahedra.shape[0]} (body b's tetrahedra offsets[b]:offsets[b+1])")
    return tetrahedra.astype(np.int64), offsets.astype(np.int64)


def _cones(bmap: BoundaryMap3D, bodies: np.ndarray) -> np.ndarray:
    """Signed cones (apex, a, b, c) from each listed body's first surface vertex to each of
    its surface triangles, (T', 4)."""
    parts = []
    for body in bodies:
        triangles = bmap.triangles[bmap.triangle_body == body]
        if triangles.shape[0]:
            apex = np.full((triangles.shape[0], 1), triangles[0, 0], dtype=np.int64)
            parts.append(np.hstack((apex, triangles)))
    if not parts:
        return np.zeros((0, _CORNERS), dtype=np.int64)
    return np.ascontiguousarray(np.concatenate(parts))


def interface_flux_3d(grid: Grid3D, bmap: BoundaryMap3D, interior: InteriorBoundary3D,
                      tetrahedra: np.ndarray | None = None,
                      tetrahedron_offsets: np.ndarray | None = None) -> InterfaceFlux3D:
    """Build the 3D ``W`` (module docstring) for the faces next to a cell the pressure
    equation has.

    Args:
        grid: The grid.
        bmap: This step's boundary map; its points are the columns' nodes (bodies' nodes
            first, interior ones included, then obstacles' surface points).
        interior: The fluid's view of it (open fractions, `interior_boundary_3d`).
        tetrahedra: The elastic bodies' tetrahedra, indices into ``bmap.points``, (T, 4).
            Bodies without any (all, when None) are filled by signed cones of their
            surface triangles (exact for affine motion).
        tetrahedron_offsets: Body b's tetrahedra are ``tetrahedra[offsets[b]:offsets[b+1]]``,
            body indices those of ``bmap.triangle_body``, (B + 1,).

    Raises:
        ValueError: On a different grid, a mismatched interior or bad tetrahedra (one line).
    """
    if not isinstance(bmap, BoundaryMap3D):
        raise ValueError(f"bmap = {type(bmap).__name__}: must be a BoundaryMap3D")
    if bmap.grid != grid:
        raise ValueError(f"boundary map grid {bmap.grid!r}: must be the grid {grid!r}")
    if not isinstance(interior, InteriorBoundary3D):
        raise ValueError(f"interior = {type(interior).__name__}: must be an "
                         "InteriorBoundary3D")
    interior.check(grid)
    tetrahedra, offsets = _check_tetrahedra(bmap, tetrahedra, tetrahedron_offsets)
    elastic = np.diff(offsets) > 0
    surface_bodies = np.unique(bmap.triangle_body)
    has_tetrahedra = np.array([body < elastic.shape[0] and bool(elastic[body])
                               for body in surface_bodies], dtype=np.bool_)
    coned = surface_bodies[~has_tetrahedra]
    pieces = np.concatenate((tetrahedra, _cones(bmap, coned)))
    points = bmap.points
    counts = np.array([grid.nx, grid.ny, grid.nz], dtype=np.int64)
    origin = np.array([float(c) for c in grid.origin])
    face_counts = [int(np.prod(counts + np.eye(3, dtype=np.int64)[axis])) for axis in _AXES]
    face_offsets = np.concatenate(([0], np.cumsum(face_counts)))
    active = np.zeros(grid.shape_cells, dtype=np.bool_)
    _kernels3d.pressure_cells_3d(interior.open_fraction_x, interior.open_fraction_y,
                                 interior.open_fraction_z, OPEN_MIN, active)
    wanted = _faces_next_to(active)
    bound = sum(_kernels3d.tetrahedron_section_bound(points, pieces, axis, origin, grid.h,
                                                     counts, wanted, int(face_offsets[axis]))
                for axis in _AXES)
    rows = np.empty(bound, dtype=np.int64)
    columns = np.empty(bound, dtype=np.int64)
    values = np.empty((bound, _kernels3d.SECTION_COLUMNS))
    entry = 0
    for axis in _AXES:
        entry = _kernels3d.tetrahedron_sections(points, pieces, axis, origin, grid.h, counts,
                                                int(face_offsets[axis]), wanted, rows,
                                                columns, values, entry)
    rows, columns, values = rows[:entry], columns[:entry], values[:entry]
    weights = _closed_faces_whole(grid, interior, rows, values, face_offsets)
    faces, indptr, indices, data = _kernels3d.group_by_row(rows, columns, weights,
                                                           int(face_offsets[-1]))
    indptr, indices, data = _merge_segments(indptr, indices, data)
    axis_of, _ = _face_index(grid, faces, face_offsets)
    low, high = _cells_of(grid, faces, face_offsets)
    matrix = SparseRows(indptr, indices, data, 3 * points.shape[0])
    return InterfaceFlux3D(grid, matrix, faces, low, high, axis_of.astype(np.int8), active)


def _faces_next_to(cells: np.ndarray) -> np.ndarray:
    """Per flat face index (x, y, z faces), whether a cell on either side is in ``cells``."""
    parts = []
    for axis in _AXES:
        shape = list(cells.shape)
        shape[axis] += 1
        near = np.zeros(shape, dtype=np.bool_)
        low = [slice(None)] * 3
        high = [slice(None)] * 3
        low[axis] = slice(1, None)
        high[axis] = slice(None, -1)
        near[tuple(low)] |= cells
        near[tuple(high)] |= cells
        parts.append(near.reshape(-1))
    return np.concatenate(parts)


def _closed_faces_whole(grid: Grid3D, interior: InteriorBoundary3D, rows: np.ndarray,
                        values: np.ndarray, face_offsets: np.ndarray) -> np.ndarray:
    """The entries' weights, those of the faces the fluid closes (open fraction in (0,
    ``OPEN_MIN``)) turned from the covered part's flux to the whole face's: every piece's
    functions read at its centroid shifted by ``d`` = face centre - covered centroid, over
    ``1 - A``, so that an affine motion gives its exact flux through the whole face (a cell
    closed all round keeps a rigid body's zero net flux, the uniform pressure's zero torque)."""
    weights = values[:, _kernels3d.SECTION_WEIGHT].copy()
    open_fraction = np.empty(rows.shape[0])
    for axis in _AXES:
        mine = (rows >= face_offsets[axis]) & (rows < face_offsets[axis + 1])
        open_fraction[mine] = interior.open_fraction(axis).reshape(-1)[
            rows[mine] - face_offsets[axis]]
    closed = (open_fraction < OPEN_MIN) & (open_fraction > 0.0)
    if not closed.any():
        return weights
    faces, slot = np.unique(rows[closed], return_inverse=True)
    chosen = values[closed]
    area = np.bincount(slot, chosen[:, _kernels3d.SECTION_AREA])
    centroid_u = np.bincount(slot, chosen[:, _kernels3d.SECTION_MOMENT_U]) / area
    centroid_v = np.bincount(slot, chosen[:, _kernels3d.SECTION_MOMENT_V]) / area
    normal, index = _face_index(grid, faces, face_offsets)
    origin = np.asarray(grid.origin, dtype=np.float64)
    along = np.arange(faces.shape[0])
    u, v = (normal + 1) % 3, (normal + 2) % 3
    centre_u = origin[u] + (index[u, along] + 0.5) * grid.h
    centre_v = origin[v] + (index[v, along] + 0.5) * grid.h
    shift_u = (centre_u - centroid_u)[slot]
    shift_v = (centre_v - centroid_v)[slot]
    whole = (chosen[:, _kernels3d.SECTION_WEIGHT]
             + chosen[:, _kernels3d.SECTION_SLOPE_U] * shift_u
             + chosen[:, _kernels3d.SECTION_SLOPE_V] * shift_v)
    weights[closed] = whole / (1.0 - open_fraction[closed])
    return weights


def _face_index(grid: Grid3D, faces: np.ndarray, face_offsets: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """Axis (F,) and (x, y, z) index (3, F) of flat face indices."""
    axis = np.searchsorted(face_offsets, faces, side="right") - 1
    local = faces - face_offsets[axis]
    shape_y = grid.ny + (axis == 1)
    shape_z = grid.nz + (axis == 2)
    k = local % shape_z
    j = (local // shape_z) % shape_y
    i = local // (shape_z * shape_y)
    return axis, np.stack((i, j, k))


def _cells_of(grid: Grid3D, faces: np.ndarray, face_offsets: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """Low and high cell (flat, -1 outside the domain) of flat face indices."""
    nx, ny, nz = grid.nx, grid.ny, grid.nz
    axis, index = _face_index(grid, faces, face_offsets)
    along = np.arange(faces.shape[0])
    normal = index[axis, along]
    size = np.array([nx, ny, nz])[axis]
    low_index = index.copy()
    low_index[axis, along] -= 1
    low = np.where(normal >= 1, (low_index[0] * ny + low_index[1]) * nz + low_index[2], -1)
    high = np.where(normal <= size - 1, (index[0] * ny + index[1]) * nz + index[2], -1)
    return low.astype(np.int64), high.astype(np.int64)
