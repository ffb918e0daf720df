from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from elastoflow.coupling import _kernels
from elastoflow.coupling._map import BoundaryMap
from elastoflow.fluid import InteriorBoundary
from elastoflow.grid import Grid2D


@dataclass(frozen=True, eq=False)
class PointClassification:
    """Which grid points lie inside which body (METHOD.md §5.3–5.4).

    Attributes:
        solid_cells: Cell centre inside a body, bool, shape (nx, ny).
        solid_faces_x: u point inside a body, bool, shape (nx+1, ny).
        solid_faces_y: v point inside a body, bool, shape (nx, ny+1).
        body_cells: Body index (``edge_body`` of the map) of each solid cell centre, -1 in
            fluid, int32, shape (nx, ny).
        body_faces_x: Body index at u points, -1 in fluid, int32, shape (nx+1, ny).
        body_faces_y: Body index at v points, -1 in fluid, int32, shape (nx, ny+1).
        velocity_faces_x: Body x-velocity [m/s] at solid u points, 0 in fluid, shape (nx+1, ny).
        velocity_faces_y: Body y-velocity [m/s] at solid v points, 0 in fluid, shape (nx, ny+1).
    """

    solid_cells: np.ndarray
    solid_faces_x: np.ndarray
    solid_faces_y: np.ndarray
    body_cells: np.ndarray
    body_faces_x: np.ndarray
    body_faces_y: np.ndarray
    velocity_faces_x: np.ndarray
    velocity_faces_y: np.ndarray


def _check_grid(grid: Grid2D, bmap: BoundaryMap) -> None:
    if bmap.grid != grid:
        raise ValueError(f"boundary map grid {bmap.grid!r}: must be the grid {grid!r}")


def _check_out(name: str, value: np.ndarray, shape: tuple[int, ...], dtype: type) -> None:
    if value.shape != shape or value.dtype != dtype or not value.flags.c_contiguous:
        raise ValueError(
            f"out.{name} shape {value.shape}, dtype {value.dtype}: must be a C-contiguous "
            f"{np.dtype(dtype)} array of shape {shape}"
        )


def _fill_classification(
    grid: Grid2D,
    bmap: BoundaryMap,
    cells: np.ndarray,
    faces_x: np.ndarray,
    faces_y: np.ndarray,
    body_cells: np.ndarray,
    body_x: np.ndarray,
    body_y: np.ndarray,
    velocity_x: np.ndarray,
    velocity_y: np.ndarray,
) -> None:
    """Reset and fill the classification arrays in place; empty body arrays are skipped."""
    for array, value in ((cells, False), (faces_x, False), (faces_y, False), (body_cells, -1),
                         (body_x, -1), (body_y, -1), (velocity_x, 0.0), (velocity_y, 0.0)):
        array.fill(value)
    nx, ny = grid.nx, grid.ny
    half_h = 0.5 * grid.h
    ox = grid.origin[0]
    common = (bmap.x_offsets, bmap.x_coordinate, bmap.x_sign, bmap.x_edge, bmap.x_velocity,
              bmap.edge_body)
    _kernels.classify_lines(*common, 1, ny, 1, nx, ox, half_h, -1, cells, body_cells,
                            velocity_x)
    _kernels.classify_lines(*common, 1, ny, 0, nx + 1, ox, half_h, 0, faces_x, body_x,
                            velocity_x)
    _kernels.classify_lines(*common, 0, ny + 1, 1, nx, ox, half_h, 1, faces_y, body_y,
                            velocity_y)


def classify_points(
    grid: Grid2D, bmap: BoundaryMap, *, out: PointClassification | None = None
) -> PointClassification:
    """Solid flags, body ids and body velocities by scanline fill of the x-map rows.

    Cell centres and u points lie on odd rows ``J = 2j+1``, v points on even rows ``J = 2j``.
    A point at x is solid when the crossings of its row at coordinates <= x have a non-zero
    winding number (the parity rule for simple loops; a point exactly on an entering crossing
    counts as solid, on a leaving one as fluid). Crossings outside the domain count too, so
    bodies may cross its edges. Inside a body the velocity is interpolated linearly between
    the two crossings that bound the span, which is exact for rigid motion. Several
    non-overlapping bodies are filled at once. Cost: crossings plus solid points.

    Args:
        grid: The MAC grid.
        bmap: The boundary map of that grid.
        out: A classification of this grid to overwrite (saves allocating every step).

    Returns:
        The classification (``out`` when given).
    """
    _check_grid(grid, bmap)
    nx, ny = grid.nx, grid.ny
    if out is None:
        out = PointClassification(
            np.zeros((nx, ny), dtype=np.bool_), np.zeros((nx + 1, ny), dtype=np.bool_),
            np.zeros((nx, ny + 1), dtype=np.bool_), np.empty((nx, ny), dtype=np.int32),
            np.empty((nx + 1, ny), dtype=np.int32), np.empty((nx, ny + 1), dtype=np.int32),
            np.zeros((nx + 1, ny)), np.zeros((nx, ny + 1)),
        )
    else:
        for name, shape, dtype in (
            ("solid_cells", (nx, ny), np.bool_), ("solid_faces_x", (nx + 1, ny), np.bool_),
            ("solid_faces_y", (nx, ny + 1), np.bool_), ("body_cells", (nx, ny), np.int32),
            ("body_faces_x", (nx + 1, ny), np.int32), ("body_faces_y", (nx, ny + 1), np.int32),
            ("velocity_faces_x", (nx + 1, ny), np.float64),
            ("velocity_faces_y", (nx, ny + 1), np.float64),
        ):
            _check_out(name, getattr(out, name), shape, dtype)
    _fill_classification(grid, bmap, out.solid_cells, out.solid_faces_x, out.solid_faces_y,
                         out.body_cells, out.body_faces_x, out.body_faces_y,
                         out.velocity_faces_x, out.velocity_faces_y)
    return out


_NO_BODY = np.empty((0, 0), dtype=np.int32)

def _touched_boxes(grid: Grid2D, bmap: BoundaryMap) -> np.ndarray:
    """One index box per body that this map's kernels may write, shape (K, 4)."""
    edge_body = bmap.edge_body
    edge_count = edge_body.shape[0]
    group_count = int(edge_body.max()) + 1 if edge_count else 0
    if edge_count and (int(edge_body.min()) < 0 or group_count > edge_count):
        # Body ids outside [0, E): one box for all rather than a table indexed by id.
        edge_body = np.zeros(edge_count, dtype=np.int64)
        group_count = 1
    return _kernels.touched_boxes(
        bmap.x_offsets, bmap.x_coordinate, bmap.x_sign, bmap.x_edge, bmap.y_offsets,
        bmap.y_coordinate, bmap.y_sign, bmap.y_edge, edge_body, group_count, grid.origin[0],
        grid.origin[1], grid.h, grid.nx, grid.ny)


def _check_reused(out: InteriorBoundary, grid: Grid2D) -> None:
    """Refuse an ``out`` to reuse whose arrays do not fit ``grid`` (shapes, dtypes)."""
    out.check(grid)
    for name in ("solid_cells", "solid_faces_x", "solid_faces_y"):
        _check_out(name, getattr(out, name), getattr(out, name).shape, np.bool_)
    for name in ("velocity_faces_x", "velocity_faces_y", "open_fraction_x", "open_fraction_y",
                 "cut_theta_x", "cut_theta_y", "cut_velocity_x", "cut_velocity_y"):
        _check_out(name, getattr(out, name), getattr(out, name).shape, np.float64)


def _reset(out: InteriorBoundary, boxes: np.ndarray) -> None:
    """Put the empty state (fluid, open, no cut) back into the index boxes of every array."""
    if boxes.shape[0] == 0:
        return
    _kernels.reset_boxes(boxes, out.solid_cells, out.solid_faces_x, out.solid_faces_y,
                         out.velocity_faces_x, out.velocity_faces_y, out.open_fraction_x,
                         out.open_fraction_y, out.cut_theta_x, out.cut_theta_y,
                         out.cut_velocity_x, out.cut_velocity_y)


def interior_boundary_from_map(
    grid: Grid2D,
    bmap: BoundaryMap,
    classification: PointClassification | None = None,
    *,
    out: InteriorBoundary | None = None,
) -> InteriorBoundary:
    """The fluid's ``InteriorBoundary`` from the boundary map (METHOD.md §5–6).

    * solid flags and body velocities: as ``classify_points``;
    * open fractions: the solid length of the segment of length h through each face,
      across the flow direction (u faces: the y-map column ``I = 2i``; v faces: the x-map row
      ``J = 2j``); then 0 on the faces whose pressure connection a body thinner than a cell
      cuts (`elastoflow.coupling._thin`), which also get that body's velocity normal to them
      in ``velocity_faces_x`` / ``_y`` (whether or not their point is solid);
    * cut fractions and velocities in the four directions: u point ``(i h, (j+1/2) h)`` reads
      ±x from the x-map row ``J = 2j+1`` and ±y from the y-map column ``I = 2i``; v point
      ``((i+1/2) h, j h)`` reads ±x from the row ``J = 2j`` and ±y from the column
      ``I = 2i+1``. The windows are half-open like the classification: towards minus the
      nearest crossing at or behind the point counts if it lies in (x - h, x], towards plus
      the nearest one ahead if it lies in (x, x + h]. A point lying exactly on the boundary
      gets a fraction floored at ``1e-6`` instead of 0. Cut data are filled for every point,
      solid ones included. Guarantee: a point whose neighbour in direction d differs in solid
      flag has a finite cut in d (where rounding makes the x-map flags and the y-map cuts
      disagree for an edge nearly parallel to a column, the cut is set at the neighbour,
      theta = 1).

    ``regions`` of the result holds one index box per body (and obstacle) of this map, around
    everything the map's kernels wrote (see ``InteriorBoundary``): outside them every array
    holds the empty state, which lets the fluid take its plain paths there. With a given
    ``classification`` it is the whole grid (the caller's flags may be set anywhere).

    The work is proportional to the number of crossings, the number of half-grid lines and
    the area of each body's bounding box (plus 2 h): with ``out`` a result of an earlier
    call, only its ``regions`` are reset and only this map's boxes are scanned for the
    guarantee above. Allocating without ``out``, an ``out`` whose ``regions`` is None and a
    given ``classification`` cost the whole grid.

    Args:
        grid: The MAC grid.
        bmap: The boundary map of that grid.
        classification: The result of ``classify_points`` when the caller already has it.
        out: An interior boundary of this grid to overwrite in place (saves allocating the
            dense arrays every step). Outside its ``regions`` (unless None) its arrays must
            hold the empty state, as ``InteriorBoundary`` guarantees: only those boxes are
            reset.

    Returns:
        The interior boundary: ``out`` itself when given with a writable ``regions`` array of
        at least as many rows as this map has boxes (the rows are overwritten, spare ones
        with the empty box 0, 0, 0, 0); otherwise a new object, sharing the arrays of ``out``
        when given (the old object's ``regions`` then no longer describe them: use only the
        result).
    """
    _check_grid(grid, bmap)
    nx, ny, h = grid.nx, grid.ny, grid.h
    ox, oy = grid.origin
    boxes = _touched_boxes(grid, bmap)
    if out is None:
        out = InteriorBoundary.empty(grid)
    else:
        _check_reused(out, grid)
        if out.regions is None:
            _reset(out, np.array([[0, nx + 1, 0, ny + 1]], dtype=np.int64))
        else:
            _reset(out, out.regions)

    if classification is None:
        _kernels.classify_lines(bmap.x_offsets, bmap.x_coordinate, bmap.x_sign, bmap.x_edge,
                                bmap.x_velocity, bmap.edge_body, 1, ny, 1, nx, ox, 0.5 * h, -1,
                                out.solid_cells, _NO_BODY, out.velocity_faces_x)
        _kernels.classify_lines(bmap.x_offsets, bmap.x_coordinate, bmap.x_sign, bmap.x_edge,
                                bmap.x_velocity, bmap.edge_body, 1, ny, 0, nx + 1, ox, 0.5 * h,
                                0, out.solid_faces_x, _NO_BODY, out.velocity_faces_x)
        _kernels.classify_lines(bmap.x_offsets, bmap.x_coordinate, bmap.x_sign, bmap.x_edge,
                                bmap.x_velocity, bmap.edge_body, 0, ny + 1, 1, nx, ox, 0.5 * h,
                                1, out.solid_faces_y, _NO_BODY, out.velocity_faces_y)
    else:
        # The caller's flags may be set anywhere: the whole grid counts as written.
        boxes = np.array([[0, nx + 1, 0, ny + 1]], dtype=np.int64)
        out.solid_cells[...] = classification.solid_cells
        out.solid_faces_x[...] = classification.solid_faces_x
        out.solid_faces_y[...] = classification.solid_faces_y
        out.velocity_faces_x[...] = classification.velocity_faces_x
        out.velocity_faces_y[...] = classification.velocity_faces_y

    _kernels.open_fraction_lines(bmap.y_offsets, bmap.y_coordinate, bmap.y_sign, 0, nx + 1, ny,
                                 oy, h, False, out.open_fraction_x)
    _kernels.open_fraction_lines(bmap.x_offsets, bmap.x_coordinate, bmap.x_sign, 0, ny + 1, nx,
                                 ox, h, True, out.open_fraction_y)

    theta_x, theta_y = out.cut_theta_x, out.cut_theta_y
    cut_velocity_x, cut_velocity_y = out.cut_velocity_x, out.cut_velocity_y
    x_map = (bmap.x_offsets, bmap.x_coordinate, bmap.x_velocity)
    y_map = (bmap.y_offsets, bmap.y_coordinate, bmap.y_velocity)
    # u points: ±x on rows J = 2j+1 (points I = 2i), ±y on columns I = 2i (points J = 2j+1).
    _kernels.cut_lines(*x_map, 0, 1, ny, 0, nx + 1, ox, h, True,
                       theta_x[0], theta_x[1], cut_velocity_x[0], cut_velocity_x[1])
    _kernels.cut_lines(*y_map, 0, 0, nx + 1, 1, ny, oy, h, False,
                       theta_x[2], theta_x[3], cut_velocity_x[2], cut_velocity_x[3])
    # v points: ±x on rows J = 2j (points I = 2i+1), ±y on columns I = 2i+1 (points J = 2j).
    _kernels.cut_lines(*x_map, 1, 0, ny + 1, 1, nx, ox, h, True,
                       theta_y[0], theta_y[1], cut_velocity_y[0], cut_velocity_y[1])
    _kernels.cut_lines(*y_map, 1, 1, nx, 0, ny + 1, oy, h, False,
                       theta_y[2], theta_y[3], cut_velocity_y[2], cut_velocity_y[3])
    _kernels.reconcile_cuts_y(out.solid_faces_x, out.velocity_faces_x, theta_x, cut_velocity_x,
                              boxes)
    _kernels.reconcile_cuts_y(out.solid_faces_y, out.velocity_faces_y, theta_y, cut_velocity_y,
                              boxes)
    cuts = bmap.thin_cuts
    if cuts.count:
        # After the reconciliation, which reads the classification's face velocities.
        velocity = cuts.velocities(bmap)
        is_u = cuts.axis == 0
        out.open_fraction_x[cuts.i[is_u], cuts.j[is_u]] = 0.0
        out.velocity_faces_x[cuts.i[is_u], cuts.j[is_u]] = velocity[is_u]
        out.open_fraction_y[cuts.i[~is_u], cuts.j[~is_u]] = 0.0
        out.velocity_faces_y[cuts.i[~is_u], cuts.j[~is_u]] = velocity[~is_u]
    regions = out.regions
    if regions is not None and regions.flags.writeable and regions.shape[0] >= boxes.shape[0]:
        # Keep ``out`` itself (its old regions would be stale): spare rows get empty boxes.
        regions[:boxes.shape[0]] = boxes
        regions[boxes.shape[0]:] = 0
        return out
    return dataclasses.replace(out, regions=boxes)
