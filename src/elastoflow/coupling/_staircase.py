"""The staircase boundary: the baseline the boundary map is compared with (METHOD.md §6).

A staircase code sees a body only through its cells: a cell whose centre lies inside a body is
solid, a face is closed when a solid cell touches it and fully open otherwise, and no cut
distance exists (the wall sits on the solid sample point next to a fluid one). Here the solid
flags still come from the boundary map's scanline fill (the cheap way to find cell centres
inside a body); only what the fluid is told differs from `interior_boundary_from_map`:

====================  =================================  ==================================
                      cut cell (the map)                 staircase
====================  =================================  ==================================
solid flags           cell centres, u and v points       cell centres; a face is solid when
                      each from its own position         a solid cell touches it
open fraction         the fluid length of the face / h   0 (closed) or 1
cut distances         from the map's crossings           none (``inf``)
body velocity         at the point (span interpolation)  the mean of the solid cells'
                                                         centre velocities next to the face
====================  =================================  ==================================

The strongly coupled projection needs the body's flux through every closed face as a linear
map of the nodal velocities; `interface_flux_staircase` gives it (each closed face next to a
fluid cell carries its whole length at the velocity of the body at the solid cell's centre).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from elastoflow.coupling import _kernels
from elastoflow.coupling._classify import _check_grid, _check_reused, _reset, _touched_boxes
from elastoflow.coupling._map import BoundaryMap
from elastoflow.fluid import OPEN_MIN, InteriorBoundary
from elastoflow.grid import Grid2D

if TYPE_CHECKING:
    from elastoflow.coupling._interface import InterfaceFlux


@dataclass(frozen=True)
class StaircaseInteriorBoundary(InteriorBoundary):
    """An `InteriorBoundary` built by `interior_boundary_staircase`: faces are fully open or
    closed by the cell flags, no cut distances. Its type tells `interface_flux` that closed
    faces carry their whole length of body flux (a cut-cell face carries only its solid
    part)."""


@njit(cache=True)
def _staircase_faces(
    solid_cells: np.ndarray, velocity_cells_x: np.ndarray, velocity_cells_y: np.ndarray,
    boxes: np.ndarray, solid_faces_x: np.ndarray, velocity_faces_x: np.ndarray,
    open_fraction_x: np.ndarray, solid_faces_y: np.ndarray, velocity_faces_y: np.ndarray,
    open_fraction_y: np.ndarray,
) -> None:
    """Close every face a solid cell touches, inside the index boxes (K, 4).

    The face's body velocity is the mean of its solid cells' centre velocities (the cell
    velocity arrays are read at solid cells only). Faces that no solid cell touches are left
    as they are (the empty state: open, fluid).
    """
    nx, ny = solid_cells.shape
    for box in range(boxes.shape[0]):
        i_begin, i_end = max(boxes[box, 0], 0), min(boxes[box, 1], nx + 1)
        j_begin, j_end = max(boxes[box, 2], 0), min(boxes[box, 3], ny + 1)
        for i in range(i_begin, i_end):
            for j in range(j_begin, min(j_end, ny)):
                # u face (i, j) between cells (i-1, j) and (i, j).
                count = 0
                total = 0.0
                if i >= 1 and solid_cells[i - 1, j]:
                    count += 1
                    total += velocity_cells_x[i - 1, j]
                if i < nx and solid_cells[i, j]:
                    count += 1
                    total += velocity_cells_x[i, j]
                if count > 0:
                    solid_faces_x[i, j] = True
                    open_fraction_x[i, j] = 0.0
                    velocity_faces_x[i, j] = total / count
        for i in range(i_begin, min(i_end, nx)):
            for j in range(j_begin, j_end):
                # v face (i, j) between cells (i, j-1) and (i, j).
                count = 0
                total = 0.0
                if j >= 1 and solid_cells[i, j - 1]:
                    count += 1
                    total += velocity_cells_y[i, j - 1]
                if j < ny and solid_cells[i, j]:
                    count += 1
                    total += velocity_cells_y[i, j]
                if count > 0:
                    solid_faces_y[i, j] = True
                    open_fraction_y[i, j] = 0.0
                    velocity_faces_y[i, j] = total / count


def _classify_cells(grid: Grid2D, bmap: BoundaryMap, solid_cells: np.ndarray,
                    body_cells: np.ndarray, velocity_x: np.ndarray,
                    velocity_y: np.ndarray | None) -> None:
    """Scanline fill of the cell centres (rows ``J = 2j+1``): flags, body ids (unless empty)
    and the body's velocity components at solid centres (``velocity_y`` None: x only)."""
    common = (bmap.x_offsets, bmap.x_coordinate, bmap.x_sign, bmap.x_edge, bmap.x_velocity,
              bmap.edge_body, 1, grid.ny, 1, grid.nx, grid.origin[0], 0.5 * grid.h)
    _kernels.classify_lines(*common, 0, solid_cells, body_cells, velocity_x)
    if velocity_y is not None:
        _kernels.classify_lines(*common, 1, solid_cells, body_cells, velocity_y)


_NO_BODY = np.empty((0, 0), dtype=np.int32)


def interior_boundary_staircase(
    grid: Grid2D, bmap: BoundaryMap, *, out: InteriorBoundary | None = None
) -> StaircaseInteriorBoundary:
    """The fluid's `InteriorBoundary` of a staircase boundary (module docstring).

    * solid cells: cell centres inside a body (the map's scanline fill, as `classify_points`);
    * faces: closed (open fraction 0, solid, the body velocity of the mean of the solid cells
      next to it) when a solid cell touches them, fully open and fluid otherwise;
    * no cut distances: ``cut_theta`` is ``inf`` everywhere, so the fluid's advection and
      viscosity read the solid neighbour's body velocity as the wall value one spacing away.

    ``regions`` holds one index box per body, as `interior_boundary_from_map` (the faces a
    solid cell closes lie one index from it, inside the boxes' 2 h margin). The work is that
    of the map's classification plus the boxes' area; with ``out`` a result of an earlier
    call, only its regions are reset.

    Args:
        grid: The MAC grid.
        bmap: The boundary map of that grid.
        out: An interior boundary of this grid to overwrite in place (its arrays hold the
            empty state outside its ``regions``).

    Returns:
        A `StaircaseInteriorBoundary`: ``out`` itself when it is one with a writable
        ``regions`` of at least as many rows as this map has boxes, else a new object
        (sharing the arrays of ``out`` when given).
    """
    _check_grid(grid, bmap)
    nx, ny = grid.nx, grid.ny
    boxes = _touched_boxes(grid, bmap)
    if out is None:
        out = StaircaseInteriorBoundary.empty(grid)
    else:
        _check_reused(out, grid)
        _reset(out, np.array([[0, nx + 1, 0, ny + 1]], dtype=np.int64)
               if out.regions is None else out.regions)
    # Read at solid cells only, where the fill has written them.
    velocity_x = np.empty((nx, ny))
    velocity_y = np.empty((nx, ny))
    _classify_cells(grid, bmap, out.solid_cells, _NO_BODY, velocity_x, velocity_y)
    _staircase_faces(out.solid_cells, velocity_x, velocity_y, boxes, out.solid_faces_x,
                     out.velocity_faces_x, out.open_fraction_x, out.solid_faces_y,
                     out.velocity_faces_y, out.open_fraction_y)
    regions = out.regions
    if (isinstance(out, StaircaseInteriorBoundary) and regions is not None
            and regions.flags.writeable and regions.shape[0] >= boxes.shape[0]):
        regions[:boxes.shape[0]] = boxes
        regions[boxes.shape[0]:] = 0
        return out
    fields = {item.name: getattr(out, item.name) for item in dataclasses.fields(out)}
    fields["regions"] = boxes
    return StaircaseInteriorBoundary(**fields)


def interface_flux_staircase(grid: Grid2D, bmap: BoundaryMap, interior: InteriorBoundary,
                             triangles: np.ndarray, triangle_offsets: np.ndarray
                             ) -> InterfaceFlux:
    """``W`` of `interface_flux` for a staircase boundary.

    Every closed face (open fraction below ``OPEN_MIN``) between a cell the pressure equation
    has and a solid cell carries its whole length of body flux, at the body's velocity at the
    solid cell's centre (barycentric in the elastic body's triangle that holds it; the
    nearest boundary point for obstacles), the velocity the staircase interior gives that
    face. Open faces carry none, whatever the outline does inside them. A uniform pressure
    still exerts no net force and no torque: the closed faces form closed staircase loops,
    and moving each face's point of application along its own normal changes no torque.
    """
    from elastoflow.coupling._interface import (
        InterfaceFlux,
        SparseRows,
        _csr_by_rows,
        _sample_weights,
    )

    _check_grid(grid, bmap)
    nx, ny, h = grid.nx, grid.ny, grid.h
    ox, oy = grid.origin
    solid = np.zeros((nx, ny), dtype=np.bool_)
    body = np.full((nx, ny), -1, dtype=np.int32)
    _classify_cells(grid, bmap, solid, body, np.empty((nx, ny)), None)
    open_x = interior.open_fraction_x >= OPEN_MIN
    open_y = interior.open_fraction_y >= OPEN_MIN
    active = np.zeros((nx, ny), dtype=bool)
    active[1:, :] |= open_x[1:-1, :]
    active[:-1, :] |= open_x[1:-1, :]
    active[:, 1:] |= open_y[:, 1:-1]
    active[:, :-1] |= open_y[:, 1:-1]
    # Closed interior faces with an active cell on one side and a solid one on the other;
    # the solid cell's index gives the sample.
    rows: list[np.ndarray] = []
    cells: list[tuple[np.ndarray, np.ndarray]] = []
    u_faces = (nx + 1) * ny
    closed_x = ~open_x[1:-1, :]
    for low_active in (True, False):
        fluid_side = active[:-1, :] if low_active else active[1:, :]
        solid_side = solid[1:, :] if low_active else solid[:-1, :]
        i, j = np.nonzero(closed_x & fluid_side & solid_side)
        rows.append((i + 1) * ny + j)
        cells.append((i + 1, j) if low_active else (i, j))
    closed_y = ~open_y[:, 1:-1]
    for low_active in (True, False):
        fluid_side = active[:, :-1] if low_active else active[:, 1:]
        solid_side = solid[:, 1:] if low_active else solid[:, :-1]
        i, j = np.nonzero(closed_y & fluid_side & solid_side)
        rows.append(u_faces + i * (ny + 1) + j + 1)
        cells.append((i, j + 1) if low_active else (i, j))
    sample_faces = np.concatenate(rows).astype(np.int64)
    ci = np.concatenate([c[0] for c in cells]).astype(np.int64)
    cj = np.concatenate([c[1] for c in cells]).astype(np.int64)
    samples = np.ascontiguousarray(np.column_stack((ox + (ci + 0.5) * h, oy + (cj + 0.5) * h)))
    bodies = body[ci, cj].astype(np.int64)
    total = int(sample_faces.shape[0])
    nodes = np.zeros((total, 3), dtype=np.int64)
    weights = np.zeros((total, 3))
    _sample_weights(samples, bodies, bmap.points, bmap.edges, bmap.edge_body,
                    np.ascontiguousarray(triangles, dtype=np.int64),
                    np.ascontiguousarray(triangle_offsets, dtype=np.int64), nodes, weights)
    component = (sample_faces >= u_faces).astype(np.int64)
    faces, indptr, indices, data = _csr_by_rows(
        np.repeat(sample_faces, 3), (2 * nodes + component[:, None]).ravel(), weights.ravel())
    flux_rows = SparseRows(indptr, indices, data, 2 * bmap.point_count)
    is_u = faces < u_faces
    v_index = faces - u_faces
    i = np.where(is_u, faces // ny, v_index // (ny + 1))
    j = np.where(is_u, faces % ny, v_index % (ny + 1))
    low = np.where(is_u, (i - 1) * ny + j, i * ny + (j - 1))
    high = i * ny + j
    low = np.where(np.where(is_u, i >= 1, j >= 1), low, -1).astype(np.int64)
    high = np.where(np.where(is_u, i <= nx - 1, j <= ny - 1), high, -1).astype(np.int64)
    return InterfaceFlux(grid, flux_rows, faces.astype(np.int64), low, high,
                         np.where(is_u, 0, 1).astype(np.int8))
