"""The dual-cell boundary treatment: face weights continuous in the bodies' positions.

The cut-cell treatment weights a face by the fluid share of its *segment*; a body edge lying
along a face line (the perpendicular flap's tip, a flag's long sides at its turns) switches
that share between 1 and the uncovered part from one step to the next, and the coupled
pressure answers with a jump of the force (docs/method_notes.md item 9). Here a face is
weighted by the fluid share of its *dual cell*, the h x h square centred on the face, as in
Batty, Bertails & Bridson's variational projection (2007): an edge parallel to the face then
changes the weight linearly over one cell of travel.

Three consistent parts, all from the same exact clipped areas (`segment_moments`):

* the open fractions ``A_f = 1 - (covered area) / h^2`` of the fluid's `InteriorBoundary`;
* ``W``'s rows (the body flux through a face): ``(covered area of body b) / h^2`` times body
  b's velocity at the centroid of its covered part (barycentric inside an elastic body, so
  the row is exact for affine motion, the nearest boundary point for an obstacle);
* the thin-body cuts of the cut-cell treatment (a body thinner than a cell separating two
  cells), which no area share closes: kept as they are.

Solid flags and cut distances (advection, viscosity) are the cut-cell treatment's. Faces on
the domain's edge keep the segment share (their dual cells reach out of the domain, and the
walls, not the weights, close them).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from numba import njit

from elastoflow.coupling._area import segment_moments
from elastoflow.coupling._classify import interior_boundary_from_map
from elastoflow.coupling._interface import (
    InterfaceFlux,
    SparseRows,
    _active_cells,
    _csr_by_rows,
    _next_to_active,
    _sample_weights,
    _with_cells,
    _with_thin_cuts,
)
from elastoflow.coupling._map import BoundaryMap
from elastoflow.fluid import OPEN_MIN, InteriorBoundary
from elastoflow.grid import Grid2D

U_FACES = 0
V_FACES = 1


@dataclass(frozen=True)
class DualCover:
    """What each body covers of the faces' dual cells: one entry per (face, body) pair with
    a covered area, body by body, each body's u faces then its v faces.

    Attributes:
        axis: `U_FACES` or `V_FACES`, int8, shape (N,).
        i, j: The face's index in its family, int64, shape (N,).
        body: The covering body (``BoundaryMap.edge_body``'s index), int64, shape (N,).
        share: Covered area over h^2, in (0, 1], shape (N,).
        centroid: Centroid [m] of the covered part, shape (N, 2).
        windows: The index boxes ``(i_begin, i_end, j_begin, j_end)`` (half-open, in the index
            space of `InteriorBoundary.regions`) that hold every face of every body's
            entries, int64, shape (K, 4).
    """

    axis: np.ndarray
    i: np.ndarray
    j: np.ndarray
    body: np.ndarray
    share: np.ndarray
    centroid: np.ndarray
    windows: np.ndarray


@njit(cache=True)
def _window(low, high, corner, h, count):
    """The squares ``[corner + k h, corner + (k+1) h)`` that ``[low, high]`` meets, clipped
    to ``0 <= k < count``; half-open."""
    first = max(int(np.floor((low - corner) / h)), 0)
    last = min(int(np.floor((high - corner) / h)), count - 1)
    return first, last + 1


@njit(cache=True)
def _cover_entries(segments, bounds, origin_x, origin_y, h, nx, ny, fill, axis, i, j, body,
                   share, centroid, windows):
    """Count (``fill`` False) or write the cover's entries and windows; returns (entries,
    windows). ``segments`` (E, 4) grouped by body, body b's rows ``bounds[b]:bounds[b+1]``."""
    count = 0
    window_count = 0
    floor = 1e-12 * h * h  # round-off of the running sums beside an edge
    for b in range(bounds.shape[0] - 1):
        lo, hi = bounds[b], bounds[b + 1]
        if hi <= lo:
            continue
        mine = segments[lo:hi]
        x_low = min(mine[:, 0].min(), mine[:, 2].min())
        x_high = max(mine[:, 0].max(), mine[:, 2].max())
        y_low = min(mine[:, 1].min(), mine[:, 3].min())
        y_high = max(mine[:, 1].max(), mine[:, 3].max())
        for family in range(2):
            corner_x = origin_x - 0.5 * h if family == U_FACES else origin_x
            corner_y = origin_y if family == U_FACES else origin_y - 0.5 * h
            count_x = nx + 1 if family == U_FACES else nx
            count_y = ny if family == U_FACES else ny + 1
            i0, i1 = _window(x_low, x_high, corner_x, h, count_x)
            j0, j1 = _window(y_low, y_high, corner_y, h, count_y)
            if i1 <= i0 or j1 <= j0:
                continue
            if fill:
                windows[window_count, 0] = i0
                windows[window_count, 1] = i1
                windows[window_count, 2] = j0
                windows[window_count, 3] = j1
            window_count += 1
            moments = np.zeros((i1 - i0, j1 - j0, 3))
            segment_moments(mine, corner_x + i0 * h, corner_y + j0 * h, h, i1 - i0, j1 - j0,
                            moments)
            for a in range(i1 - i0):
                for c in range(j1 - j0):
                    covered = moments[a, c, 0]
                    if covered <= floor:
                        continue
                    if fill:
                        axis[count] = family
                        i[count] = i0 + a
                        j[count] = j0 + c
                        body[count] = b
                        share[count] = min(covered / (h * h), 1.0)
                        centroid[count, 0] = corner_x + (i0 + a + 0.5) * h + moments[a, c, 1] / covered
                        centroid[count, 1] = corner_y + (j0 + c + 0.5) * h + moments[a, c, 2] / covered
                    count += 1
    return count, window_count


def dual_cover(grid: Grid2D, bmap: BoundaryMap) -> DualCover:
    """The `DualCover` of the map's closed outlines (each body on the left of its edges).

    Cost: per body, the squares of its bounding box (plus one on each side), for both face
    families; the clipping itself follows the outline's length (`segment_moments`).
    """
    if bmap.grid is not grid and bmap.grid != grid:
        raise ValueError(f"boundary map grid {bmap.grid!r}: must be the grid {grid!r}")
    h = grid.h
    ox, oy = grid.origin
    edges, edge_body = bmap.edges, bmap.edge_body
    order = np.argsort(edge_body, kind="stable")
    segments = np.ascontiguousarray(np.concatenate(
        [bmap.points[edges[order, 0]], bmap.points[edges[order, 1]]], axis=1))
    bounds = np.searchsorted(edge_body[order],
                             np.arange(int(edge_body.max(initial=-1)) + 2)).astype(np.int64)
    none_i, none_f = np.zeros(0, np.int64), np.zeros(0)
    count, window_count = _cover_entries(
        segments, bounds, ox, oy, h, grid.nx, grid.ny, False, np.zeros(0, np.int8), none_i,
        none_i, none_i, none_f, np.zeros((0, 2)), np.zeros((0, 4), np.int64))
    cover = DualCover(np.zeros(count, np.int8), np.zeros(count, np.int64),
                      np.zeros(count, np.int64), np.zeros(count, np.int64), np.zeros(count),
                      np.zeros((count, 2)), np.zeros((window_count, 4), np.int64))
    _cover_entries(segments, bounds, ox, oy, h, grid.nx, grid.ny, True, cover.axis, cover.i,
                   cover.j, cover.body, cover.share, cover.centroid, cover.windows)
    return cover


@njit(cache=True)
def _open_dual(windows, axis, i, j, share, open_x, open_y):
    """Open fractions from the cover inside ``windows``: 1 less the covered shares, at
    least 0; faces on the domain's edge are left as they are."""
    nx, ny = open_y.shape[0], open_x.shape[1]
    for w in range(windows.shape[0]):
        for a in range(windows[w, 0], windows[w, 1]):
            for b in range(windows[w, 2], windows[w, 3]):
                if 0 < a < nx and b < ny:
                    open_x[a, b] = 1.0
                if a < nx and 0 < b < ny:
                    open_y[a, b] = 1.0
    for k in range(axis.shape[0]):
        a, b = i[k], j[k]
        if axis[k] == 0:
            if 0 < a < nx:
                open_x[a, b] = max(open_x[a, b] - share[k], 0.0)
        elif 0 < b < ny:
            open_y[a, b] = max(open_y[a, b] - share[k], 0.0)


def _fill_covered_velocity(grid: Grid2D, bmap: BoundaryMap, cover: DualCover,
                           interior: InteriorBoundary) -> None:
    """``velocity_faces`` on the partly open faces whose point is fluid: the share-weighted
    mean, over the bodies covering the face's dual cell, of each one's boundary velocity
    nearest to its part's centroid (the interior has no triangles; the strongly coupled
    scheme's ``W`` samples them). The projection reads it where no crossing lies along the
    face (`elastoflow.fluid` ``face_solid_velocity``)."""
    if not cover.axis.shape[0] or not np.any(bmap.velocities):
        return
    is_u = cover.axis == U_FACES
    nx, ny = grid.nx, grid.ny
    i, j = cover.i, cover.j
    open_here = np.where(is_u, interior.open_fraction_x[np.minimum(i, nx), np.minimum(j, ny - 1)],
                         interior.open_fraction_y[np.minimum(i, nx - 1), np.minimum(j, ny)])
    solid_here = np.where(is_u, interior.solid_faces_x[np.minimum(i, nx), np.minimum(j, ny - 1)],
                          interior.solid_faces_y[np.minimum(i, nx - 1), np.minimum(j, ny)])
    wanted = np.flatnonzero((open_here > 0.0) & (open_here < 1.0) & ~solid_here)
    if not wanted.shape[0]:
        return
    # Grouped by face (the cover lists each body's faces in turn).
    wanted = wanted[np.lexsort((j[wanted], i[wanted], cover.axis[wanted]))]
    nodes = np.zeros((wanted.shape[0], 3), dtype=np.int64)
    weights = np.zeros((wanted.shape[0], 3))
    _sample_weights(np.ascontiguousarray(cover.centroid[wanted]), cover.body[wanted],
                    bmap.points, bmap.edges, bmap.edge_body, np.zeros((0, 3), dtype=np.int64),
                    np.zeros(1, dtype=np.int64), nodes, weights)
    component = cover.axis[wanted].astype(np.int64)
    share = cover.share[wanted]
    velocity = np.einsum("kc,kc->k", weights, bmap.velocities[nodes, component[:, None]])
    face = (cover.axis[wanted].astype(np.int64) * (nx + 1) + i[wanted]) * (ny + 1) + j[wanted]
    starts = np.flatnonzero(np.r_[True, face[1:] != face[:-1]])
    mean = np.add.reduceat(share * velocity, starts) / np.add.reduceat(share, starts)
    first = wanted[starts]
    u_face = cover.axis[first] == U_FACES
    interior.velocity_faces_x[i[first][u_face], j[first][u_face]] = mean[u_face]
    interior.velocity_faces_y[i[first][~u_face], j[first][~u_face]] = mean[~u_face]


@dataclass(frozen=True)
class DualCellInteriorBoundary(InteriorBoundary):
    """An `InteriorBoundary` built by `interior_boundary_dual_cell`; ``cover`` is the step's
    `DualCover`, which `interface_flux` reads for ``W``'s rows."""

    cover: DualCover | None = None


def interior_boundary_dual_cell(grid: Grid2D, bmap: BoundaryMap, *,
                                out: InteriorBoundary | None = None
                                ) -> DualCellInteriorBoundary:
    """The fluid's `InteriorBoundary` with dual-cell open fractions (module docstring).

    As `interior_boundary_from_map` (whose flags, cut distances and thin cuts it keeps, and
    whose ``out`` reuse it follows), with the open fractions of the faces whose dual cells a
    body covers replaced by their fluid share; ``regions`` also holds the cover's windows.
    """
    base = interior_boundary_from_map(grid, bmap, out=out)
    cover = dual_cover(grid, bmap)
    _open_dual(cover.windows, cover.axis, cover.i, cover.j, cover.share,
               base.open_fraction_x, base.open_fraction_y)
    cuts = bmap.thin_cuts
    if cuts.count:
        is_u = cuts.axis == 0
        base.open_fraction_x[cuts.i[is_u], cuts.j[is_u]] = 0.0
        base.open_fraction_y[cuts.i[~is_u], cuts.j[~is_u]] = 0.0
    _fill_covered_velocity(grid, bmap, cover, base)
    regions = base.regions
    if regions is not None:
        regions = np.concatenate([regions[np.any(regions != 0, axis=1)], cover.windows])
    fields = {f.name: getattr(base, f.name) for f in dataclasses.fields(InteriorBoundary)}
    fields["regions"] = regions
    return DualCellInteriorBoundary(**fields, cover=cover)


def interface_flux_dual(grid: Grid2D, bmap: BoundaryMap, interior: InteriorBoundary,
                        cover: DualCover, triangles: np.ndarray,
                        triangle_offsets: np.ndarray) -> InterfaceFlux:
    """``W`` of the dual-cell treatment (module docstring): each body's covered
    share of a face's dual cell times its velocity at the centroid of that part; rows scaled
    to the face's solid share ``1 - A`` (all of it on faces the fluid closes), which only
    changes rows where outlines overlap (a flag clamped inside a cylinder counts the overlap
    twice); the thin cuts' rows as in the cut-cell treatment."""
    nx, ny = grid.nx, grid.ny
    u_faces = (nx + 1) * ny
    flat = np.where(cover.axis == 0, cover.i * ny + cover.j,
                    u_faces + cover.i * (ny + 1) + cover.j)
    near = _next_to_active(flat, interior.open_fraction_x, interior.open_fraction_y)
    flat, share, component = flat[near], cover.share[near], cover.axis[near].astype(np.int64)
    samples = np.ascontiguousarray(cover.centroid[near])
    # A face the fluid closes carries the body's whole flux at the face itself: sampled at its
    # centre, so that a uniform pressure on the closed faces around the cells the pressure
    # equation drops gives no torque (their centroids sit off centre by the sliver of fluid).
    i, j = cover.i[near], cover.j[near]
    is_u = component == 0
    open_here = np.where(is_u, interior.open_fraction_x[np.minimum(i, nx), np.minimum(j, ny - 1)],
                         interior.open_fraction_y[np.minimum(i, nx - 1), np.minimum(j, ny)])
    closed = open_here < OPEN_MIN
    h = grid.h
    ox, oy = grid.origin
    samples[closed, 0] = ox + (i[closed] + np.where(is_u[closed], 0.0, 0.5)) * h
    samples[closed, 1] = oy + (j[closed] + np.where(is_u[closed], 0.5, 0.0)) * h
    nodes = np.zeros((flat.shape[0], 3), dtype=np.int64)
    weights = np.zeros((flat.shape[0], 3))
    _sample_weights(samples, cover.body[near], bmap.points, bmap.edges, bmap.edge_body,
                    np.ascontiguousarray(triangles, dtype=np.int64),
                    np.ascontiguousarray(triangle_offsets, dtype=np.int64), nodes, weights)
    rows = np.repeat(flat, 3)
    cols = (2 * nodes + component[:, None]).ravel()
    values = (weights * share[:, None]).ravel()
    cuts = bmap.thin_cuts
    thin = np.zeros(0, dtype=np.int64)
    if cuts.count:
        active = np.zeros((nx + 2, ny + 2), dtype=np.bool_)
        _active_cells(interior.open_fraction_x, interior.open_fraction_y, active[1:-1, 1:-1])
        rows, cols, values = _with_thin_cuts(grid, bmap, cuts, active, rows, cols, values)
        is_u = cuts.axis == 0
        thin = np.where(is_u, cuts.i * ny + cuts.j, u_faces + cuts.i * (ny + 1) + cuts.j)
    faces, indptr, indices, data = _csr_by_rows(rows, cols, values)
    if faces.shape[0]:
        is_u = faces < u_faces
        open_fraction = np.where(
            is_u,
            interior.open_fraction_x.reshape(-1)[np.minimum(faces, u_faces - 1)],
            interior.open_fraction_y.reshape(-1)[np.maximum(faces - u_faces, 0)],
        )
        target = np.where(open_fraction < OPEN_MIN, 1.0, 1.0 - open_fraction)
        # Barycentric and edge weights sum to 1: a row's sum is its covered share.
        carried = np.add.reduceat(data, indptr[:-1])
        scale = np.where((carried > 0.0) & ~np.isin(faces, thin), target / carried, 1.0)
        data *= np.repeat(scale, np.diff(indptr))
    return _with_cells(grid, faces, SparseRows(indptr, indices, data, 2 * bmap.point_count))
