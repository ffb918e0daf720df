"""The body side of the pressure equation as a linear operator of the boundary velocities.

The projection keeps ``div(A u + (1 - A) u_s)`` at zero, where ``(1 - A) u_s`` is the part of
a face's flux that the body carries. For the strongly coupled step that part must be a linear
function of the bodies' nodal velocities, and its transpose must give the force that the cell
pressures exert on the nodes, so that the coupled system stays symmetric. Along the line
through a face (the vertical line through a u point, the horizontal one through a v point) the
boundary map's crossings split the face into fluid and solid intervals; each solid interval
carries its length times the body velocity at its midpoint:

    (1 - A_f) u_s,f = sum_k  W[f, k] V_k          (V: nodal velocity components)

The velocity at the midpoint is the body's own: barycentric in the triangle of the elastic body
that contains it, or, for obstacles (no triangles) and round-off at the outline, that of the
nearest point of the nearest boundary edge. Both are exact for affine motion, so ``W`` gives the
exact swept flux of any rigid motion (the midpoint rule is exact for a linear field), and a
uniform pressure exerts no net force and no torque. A face's velocity is taken where the face
is, not interpolated along the line between the span's far crossings: a thin flag lying along
a row of faces would otherwise hand the pressure on its sides to its two ends.

A face whose pressure connection a body thinner than a cell cuts (`elastoflow.coupling._thin`)
has open fraction 0 although its segment may lie in fluid: its row is the whole face's flux at
the body velocity of the cut (the mean of two or four crossings), the velocity the explicit
projection gives it too.

The force of the cell pressures on the nodes is ``h W^T (p_low - p_high)`` per unit depth: the
exact discrete counterpart (virtual work) of the flux, so that ``div`` and the force are
adjoint.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np
from numba import njit
from scipy import sparse

from elastoflow.coupling._map import BoundaryMap
from elastoflow.coupling._map3d import BoundaryMap3D
from elastoflow.coupling._thin import ThinCuts
from elastoflow.fluid import OPEN_MIN, InteriorBoundary
from elastoflow.grid import Grid2D, Grid3D
from elastoflow.linalg import BandedInverse, LowRankTerm

if TYPE_CHECKING:
    from elastoflow.coupling._interface3d import InterfaceFlux3D


@njit(cache=True)
def _solid_intervals(crossings: tuple, edge_body: np.ndarray, family: tuple, h: float,
                     elastic_count: int, fill: bool, out: tuple, start: int) -> int:
    """Every solid interval of every face along one family of lines: its face, its length
    over h, its midpoint (x, y) and the body that covers it, into ``out`` from slot
    ``start``. Where outlines overlap (a flag clamped inside a cylinder) an elastic body
    (index below ``elastic_count``) wins over an obstacle. With ``fill`` False only counts;
    returns the next free slot.

    Args:
        crossings: ``(offsets, coordinate, sign, edge_index)`` of the map's lines along the
            family's direction.
        edge_body: The body of each edge.
        family: ``(line_count, point_count, origin_along, origin_across, point_first,
            stride, face_offset)``: lines ``l < line_count`` at ``origin_across + l h``
            (every other line of the map), faces ``k < point_count`` along each; face
            ``face_offset + k stride + l`` (``point_first``) or ``face_offset + l stride +
            k``.
        out: ``(faces, fractions, samples, bodies)``, not written without ``fill``.
    """
    offsets, coordinate, sign, edge_index = crossings
    (line_count_out, point_count, origin_along, origin_across, point_first, stride,
     face_offset) = family
    faces, fractions, samples, bodies = out
    extent = point_count * h
    slot = start
    body_total = 0
    for e in range(edge_body.shape[0]):
        body_total = max(body_total, edge_body[e] + 1)
    windings = np.zeros(max(body_total, 1), np.int64)
    for l in range(line_count_out):
        line = 2 * l
        begin = offsets[line]
        end = offsets[line + 1]
        across = origin_across + l * h
        # Every body's winding starts at zero on every line: the loop below stops before a
        # line's last crossing, so a body crossed on an earlier line is left at +-1 there and,
        # kept, would claim the solid intervals of another body on a later line (a pipe wall's
        # pressure pushed on a windmill's node).
        windings[:] = 0
        winding = 0
        for c in range(begin, end - 1):
            winding += sign[c]
            windings[edge_body[edge_index[c]]] += sign[c]
            if winding == 0:
                continue
            cover = -1
            for candidate in range(body_total):
                if windings[candidate] != 0 and (
                        cover < 0 or candidate < elastic_count <= cover):
                    cover = candidate
            a = max(coordinate[c] - origin_along, 0.0)
            b = min(coordinate[c + 1] - origin_along, extent)
            if b <= a:
                continue
            k0 = min(int(a / h), point_count - 1)
            k1 = min(int(b / h), point_count - 1)
            for k in range(k0, k1 + 1):
                lo = max(a, k * h)
                hi = min(b, (k + 1) * h)
                if hi <= lo:
                    continue
                if fill:
                    if point_first:
                        faces[slot] = face_offset + k * stride + l
                        samples[slot, 0] = origin_along + 0.5 * (lo + hi)
                        samples[slot, 1] = across
                    else:
                        faces[slot] = face_offset + l * stride + k
                        samples[slot, 0] = across
                        samples[slot, 1] = origin_along + 0.5 * (lo + hi)
                    fractions[slot] = (hi - lo) / h
                    bodies[slot] = cover if cover >= 0 else edge_body[edge_index[c]]
                slot += 1
    return slot


@njit(cache=True)
def _barycentric(px: float, py: float, ax: float, ay: float, bx: float, by: float, cx: float,
                 cy: float) -> tuple[float, float, float]:
    det = (by - cy) * (ax - cx) + (cx - bx) * (ay - cy)
    if det == 0.0:
        return -1.0, -1.0, -1.0
    wa = ((by - cy) * (px - cx) + (cx - bx) * (py - cy)) / det
    wb = ((cy - ay) * (px - cx) + (ax - cx) * (py - cy)) / det
    return wa, wb, 1.0 - wa - wb


@njit(cache=True)
def _sample_weights(
    samples: np.ndarray, bodies: np.ndarray, points: np.ndarray, edges: np.ndarray,
    edge_body: np.ndarray, triangles: np.ndarray, triangle_offsets: np.ndarray,
    nodes: np.ndarray, weights: np.ndarray,
) -> None:
    """The body velocity at each sample as weights of at most three points.

    Inside an elastic body (``bodies[s] < triangle_offsets.shape[0] - 1``): the barycentric
    weights of the triangle containing the sample (exact for affine motion: rigid motion,
    uniform strain). Otherwise, or when no triangle contains it (round-off at the outline; an
    obstacle, which has no triangles): the nearest point of the body's nearest boundary edge.
    """
    body_count = triangle_offsets.shape[0] - 1
    last = -1
    for s in range(samples.shape[0]):
        px, py = samples[s, 0], samples[s, 1]
        body = bodies[s]
        found = False
        if body < body_count:
            # Samples come line by line: the triangle of the previous one is the likeliest.
            if triangle_offsets[body] <= last < triangle_offsets[body + 1]:
                i0, i1, i2 = triangles[last, 0], triangles[last, 1], triangles[last, 2]
                wa, wb, wc = _barycentric(px, py, points[i0, 0], points[i0, 1],
                                          points[i1, 0], points[i1, 1], points[i2, 0],
                                          points[i2, 1])
                if min(wa, min(wb, wc)) >= 0.0:
                    nodes[s, 0], nodes[s, 1], nodes[s, 2] = i0, i1, i2
                    weights[s, 0], weights[s, 1], weights[s, 2] = wa, wb, wc
                    continue
            best = -np.inf
            for triangle in range(triangle_offsets[body], triangle_offsets[body + 1]):
                i0, i1, i2 = (triangles[triangle, 0], triangles[triangle, 1],
                              triangles[triangle, 2])
                wa, wb, wc = _barycentric(px, py, points[i0, 0], points[i0, 1],
                                          points[i1, 0], points[i1, 1], points[i2, 0],
                                          points[i2, 1])
                worst = min(wa, min(wb, wc))
                if worst > best:
                    best = worst
                    nodes[s, 0], nodes[s, 1], nodes[s, 2] = i0, i1, i2
                    weights[s, 0], weights[s, 1], weights[s, 2] = wa, wb, wc
                if worst >= 0.0:
                    last = triangle
                    break
            found = best >= -1e-9
        if found:
            continue
        nearest = np.inf
        for e in range(edges.shape[0]):
            if edge_body[e] != body:
                continue
            a, b = edges[e, 0], edges[e, 1]
            dx = points[b, 0] - points[a, 0]
            dy = points[b, 1] - points[a, 1]
            length = dx * dx + dy * dy
            t = 0.0
            if length > 0.0:
                t = ((px - points[a, 0]) * dx + (py - points[a, 1]) * dy) / length
                t = min(max(t, 0.0), 1.0)
            qx = points[a, 0] + t * dx - px
            qy = points[a, 1] + t * dy - py
            distance = qx * qx + qy * qy
            if distance < nearest:
                nearest = distance
                nodes[s, 0], nodes[s, 1], nodes[s, 2] = a, b, b
                weights[s, 0], weights[s, 1], weights[s, 2] = 1.0 - t, t, 0.0


@njit(cache=True)
def _is_active(open_x: np.ndarray, open_y: np.ndarray, i: int, j: int) -> bool:
    """Whether cell (i, j) has an interior face open by ``OPEN_MIN`` (the pressure equation
    has it); False outside the grid."""
    nx, ny = open_y.shape[0], open_x.shape[1]
    if i < 0 or i >= nx or j < 0 or j >= ny:
        return False
    return ((i >= 1 and open_x[i, j] >= OPEN_MIN)
            or (i <= nx - 2 and open_x[i + 1, j] >= OPEN_MIN)
            or (j >= 1 and open_y[i, j] >= OPEN_MIN)
            or (j <= ny - 2 and open_y[i, j + 1] >= OPEN_MIN))


@njit(cache=True)
def _active_cells(open_x: np.ndarray, open_y: np.ndarray, out: np.ndarray) -> None:
    for i in range(out.shape[0]):
        for j in range(out.shape[1]):
            out[i, j] = _is_active(open_x, open_y, i, j)


@njit(cache=True)
def _next_to_active(faces: np.ndarray, open_x: np.ndarray, open_y: np.ndarray) -> np.ndarray:
    """For each flat face index (u faces, then v faces), whether a cell on either side is
    active (`_is_active`)."""
    nx, ny = open_y.shape[0], open_x.shape[1]
    u_faces = (nx + 1) * ny
    near = np.empty(faces.shape[0], np.bool_)
    for k in range(faces.shape[0]):
        face = faces[k]
        if face < u_faces:
            # u face (i, j) joins cells (i - 1, j) and (i, j).
            i, j = face // ny, face % ny
            near[k] = _is_active(open_x, open_y, i - 1, j) or _is_active(open_x, open_y, i, j)
        else:
            # v face (i, j) joins cells (i, j - 1) and (i, j).
            i, j = (face - u_faces) // (ny + 1), (face - u_faces) % (ny + 1)
            near[k] = _is_active(open_x, open_y, i, j - 1) or _is_active(open_x, open_y, i, j)
    return near


@njit(cache=True)
def _merge_segments(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each row's entries sorted by column, equal columns summed (in their given order, so the
    sums do not depend on anything but the input): CSR ``(indptr, indices, data)``."""
    rows = indptr.shape[0] - 1
    out_ptr = np.zeros(rows + 1, np.int64)
    out_indices = np.empty(indices.shape[0], np.int64)
    out_data = np.empty(indices.shape[0])
    kept = 0
    for r in range(rows):
        begin = kept
        for e in range(indptr[r], indptr[r + 1]):
            column = indices[e]
            value = data[e]
            # Rows are short (a few nodes per face or cell): insertion keeps them sorted.
            k = kept
            while k > begin and out_indices[k - 1] > column:
                k -= 1
            if k > begin and out_indices[k - 1] == column:
                out_data[k - 1] += value
                continue
            for m in range(kept, k, -1):
                out_indices[m] = out_indices[m - 1]
                out_data[m] = out_data[m - 1]
            out_indices[k] = column
            out_data[k] = value
            kept += 1
        out_ptr[r + 1] = kept
    return out_ptr, out_indices[:kept].copy(), out_data[:kept].copy()


@njit(cache=True)
def _csr_by_rows(rows: np.ndarray, cols: np.ndarray, values: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Triplets to CSR over the rows that occur: ``(rows ascending, indptr, indices,
    data)``, duplicates summed."""
    order = np.argsort(rows, kind="mergesort")
    count = 0
    for k in range(order.shape[0]):
        if k == 0 or rows[order[k]] != rows[order[k - 1]]:
            count += 1
    unique = np.empty(count, np.int64)
    indptr = np.zeros(count + 1, np.int64)
    indices = np.empty(order.shape[0], np.int64)
    data = np.empty(order.shape[0])
    r = -1
    for k in range(order.shape[0]):
        e = order[k]
        if k == 0 or rows[e] != rows[order[k - 1]]:
            r += 1
            unique[r] = rows[e]
        indptr[r + 1] = k + 1
        indices[k] = cols[e]
        data[k] = values[e]
    indptr, indices, data = _merge_segments(indptr, indices, data)
    return unique, indptr, indices, data


@njit(cache=True)
def _cell_rows(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, low: np.ndarray,
               high: np.ndarray, active: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``D W`` on the active cells next to ``W``'s faces (a face's row counts + in its low
    cell and - in its high one): ``(cells ascending, indptr, indices, data)``."""
    size = active.shape[0]
    slot = np.full(size, -1, np.int64)
    faces = low.shape[0]
    listed = np.empty(2 * faces, np.int64)
    count = 0
    for r in range(faces):
        for side in range(2):
            cell = low[r] if side == 0 else high[r]
            if cell >= 0 and active[cell] and slot[cell] < 0:
                slot[cell] = 0
                listed[count] = cell
                count += 1
    cells = np.sort(listed[:count])
    length = np.zeros(count + 1, np.int64)
    for k in range(count):
        slot[cells[k]] = k
    for r in range(faces):
        for side in range(2):
            cell = low[r] if side == 0 else high[r]
            if cell >= 0 and active[cell]:
                length[slot[cell] + 1] += indptr[r + 1] - indptr[r]
    for k in range(count):
        length[k + 1] += length[k]
    fill = length[:-1].copy()
    gathered = np.empty(length[count], np.int64)
    values = np.empty(length[count])
    for r in range(faces):
        for side in range(2):
            cell = low[r] if side == 0 else high[r]
            if cell < 0 or not active[cell]:
                continue
            sign = 1.0 if side == 0 else -1.0
            k = slot[cell]
            for e in range(indptr[r], indptr[r + 1]):
                gathered[fill[k]] = indices[e]
                values[fill[k]] = sign * data[e]
                fill[k] += 1
    out_ptr, out_indices, out_data = _merge_segments(length, gathered, values)
    return cells, out_ptr, out_indices, out_data


@njit(cache=True)
def _columns_below(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray,
                   row_ids: np.ndarray, limit: int
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The transpose of a CSR matrix restricted to its nonzero columns below ``limit``:
    ``(columns ascending, offsets, row ids, values)``, each column's entries by row."""
    count = np.zeros(limit + 1, np.int64)
    for e in range(indptr[-1]):
        if indices[e] < limit:
            count[indices[e] + 1] += 1
    touched = 0
    for c in range(limit):
        if count[c + 1] > 0:
            touched += 1
    columns = np.empty(touched, np.int64)
    offsets = np.zeros(touched + 1, np.int64)
    where = np.full(limit, -1, np.int64)
    t = 0
    for c in range(limit):
        if count[c + 1] > 0:
            columns[t] = c
            where[c] = t
            offsets[t + 1] = offsets[t] + count[c + 1]
            t += 1
    fill = offsets[:-1].copy()
    points = np.empty(offsets[touched], np.int64)
    weights = np.empty(offsets[touched])
    for r in range(indptr.shape[0] - 1):
        for e in range(indptr[r], indptr[r + 1]):
            c = indices[e]
            if c < limit:
                k = where[c]
                points[fill[k]] = row_ids[r]
                weights[fill[k]] = data[e]
                fill[k] += 1
    return columns, offsets, points, weights


@njit(cache=True)
def _rows_times(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, vector: np.ndarray,
                out: np.ndarray) -> None:
    for r in range(indptr.shape[0] - 1):
        total = 0.0
        for e in range(indptr[r], indptr[r + 1]):
            total += data[e] * vector[indices[e]]
        out[r] = total


@njit(cache=True)
def _rows_transpose_times(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray,
                          vector: np.ndarray, out: np.ndarray) -> None:
    out[:] = 0.0
    for r in range(indptr.shape[0] - 1):
        for e in range(indptr[r], indptr[r + 1]):
            out[indices[e]] += data[e] * vector[r]


@dataclass(frozen=True)
class SparseRows:
    """A small CSR matrix applied by compiled loops: SciPy's constructors and products cost
    0.2-0.7 ms each on matrices of a few hundred rows, as much as the arithmetic of the
    whole coupled set-up.

    Attributes:
        indptr: Row offsets, int64, (rows + 1,).
        indices: Column of each entry, int64, ascending within a row.
        data: Value of each entry, float64.
        columns: Number of columns.
    """

    indptr: np.ndarray
    indices: np.ndarray
    data: np.ndarray
    columns: int

    @property
    def rows(self) -> int:
        return int(self.indptr.shape[0] - 1)

    def to_scipy(self) -> sparse.csr_matrix:
        return sparse.csr_matrix((self.data, self.indices, self.indptr),
                                 shape=(self.rows, self.columns))

    def times(self, vector: np.ndarray) -> np.ndarray:
        """``M v`` for ``v`` of ``columns`` values (any shape, flat order)."""
        out = np.empty(self.rows)
        _rows_times(self.indptr, self.indices, self.data,
                    np.ascontiguousarray(vector, dtype=np.float64).reshape(-1), out)
        return out

    def transpose_times(self, vector: np.ndarray) -> np.ndarray:
        """``M^T v`` for ``v`` of ``rows`` values."""
        out = np.empty(self.columns)
        _rows_transpose_times(self.indptr, self.indices, self.data,
                              np.ascontiguousarray(vector, dtype=np.float64).reshape(-1), out)
        return out


@dataclass(frozen=True)
class InterfaceFlux:
    """``W`` restricted to the faces it touches, with each face's two cells.

    Attributes:
        grid: The grid.
        rows: ``W``, shape (F, 2P): row r is face ``faces[r]``'s body flux per unit face
            length [m/s] from the nodal velocity components (``2 point + component``); faces
            that the fluid treats as closed (open fraction below ``OPEN_MIN``) carry their
            whole flux, so their row sums the body velocity. ``matrix`` gives it as SciPy
            CSR.
        faces: Flat face index of each row: u faces ``i * ny + j``, then v faces
            ``(nx + 1) ny + i * (ny + 1) + j``, int64, shape (F,).
        low_cell: Flat index ``i * ny + j`` of the cell on the face's low side (west or
            south), or -1 outside the domain, int64, shape (F,).
        high_cell: The same on the high side (east or north).
        axis: 0 for u faces, 1 for v faces, int8, shape (F,).
    """

    grid: Grid2D
    rows: SparseRows
    faces: np.ndarray
    low_cell: np.ndarray
    high_cell: np.ndarray
    axis: np.ndarray

    @property
    def matrix(self) -> sparse.csr_matrix:
        """``W`` as SciPy CSR, shape (F, 2P)."""
        return self.rows.to_scipy()

    def face_flux(self, velocities: np.ndarray) -> np.ndarray:
        """Body flux per unit length of each row's face [m/s] for nodal ``velocities`` (P, 2)."""
        return self.rows.times(velocities)

    def pressure_forces(self, pressure: np.ndarray, open_x: np.ndarray,
                        open_y: np.ndarray) -> np.ndarray:
        """``h W^T D^T p``: the force [N/m] of the cell ``pressure`` [Pa] (nx, ny) on the
        nodes, shape (P, 2), over the cells the pressure equation of these open fractions
        has (an interior face open by ``OPEN_MIN``; the others' pressure counts as 0): what
        `PressureCoupledBodies.respond` applies for a solved pressure."""
        active = np.zeros(self.grid.shape_cells, dtype=np.bool_)
        _active_cells(open_x, open_y, active)
        cells, indptr, indices, data = _cell_rows(
            self.rows.indptr, self.rows.indices, self.rows.data, self.low_cell,
            self.high_cell, active.reshape(-1))
        rows = SparseRows(indptr, indices, data, self.rows.columns)
        flat = np.ascontiguousarray(pressure).reshape(-1)
        return (self.grid.h * rows.transpose_times(flat[cells])).reshape(-1, 2)


def interface_flux(grid: Grid2D, bmap: BoundaryMap, interior: InteriorBoundary,
                   triangles: np.ndarray | None = None,
                   triangle_offsets: np.ndarray | None = None) -> InterfaceFlux:
    """Build ``W`` from the boundary map (module docstring) for the faces of ``interior``.

    Args:
        grid: The grid.
        bmap: This step's boundary map.
        interior: The fluid's view of it (open fractions); a staircase one
            (`StaircaseInteriorBoundary`) is handed to `interface_flux_staircase`.
        triangles: The elastic bodies' triangles, indices into ``bmap.points``, shape (T, 3);
            none: every covered face takes the velocity of the nearest boundary edge.
        triangle_offsets: Body b's triangles are ``triangles[offsets[b]:offsets[b+1]]``; body
            indices are those of ``bmap.edge_body`` (bodies first, then obstacles).
    """
    if bmap.grid is not grid and bmap.grid != grid:
        raise ValueError(f"boundary map grid {bmap.grid!r}: must be the grid {grid!r}")
    if triangles is None or triangle_offsets is None:
        triangles = np.zeros((0, 3), dtype=np.int64)
        triangle_offsets = np.zeros(1, dtype=np.int64)
    from elastoflow.coupling._dual import DualCellInteriorBoundary, interface_flux_dual
    from elastoflow.coupling._staircase import (
        StaircaseInteriorBoundary,
        interface_flux_staircase,
    )

    if isinstance(interior, StaircaseInteriorBoundary):
        # Its closed faces carry their whole length of flux, its open ones none.
        return interface_flux_staircase(grid, bmap, interior, triangles, triangle_offsets)
    if isinstance(interior, DualCellInteriorBoundary) and interior.cover is not None:
        return interface_flux_dual(grid, bmap, interior, interior.cover, triangles,
                                   triangle_offsets)
    nx, ny, h = grid.nx, grid.ny, grid.h
    ox, oy = grid.origin
    u_faces = (nx + 1) * ny
    elastic_count = int(triangle_offsets.shape[0] - 1)
    families = (
        # u faces: columns I = 2i of the y-map (x = ox + i h), segments along y.
        ((bmap.y_offsets, bmap.y_coordinate, bmap.y_sign, bmap.y_edge),
         (nx + 1, ny, oy, ox, False, ny, 0)),
        # v faces: rows J = 2j of the x-map (y = oy + j h), segments along x.
        ((bmap.x_offsets, bmap.x_coordinate, bmap.x_sign, bmap.x_edge),
         (ny + 1, nx, ox, oy, True, ny + 1, u_faces)),
    )
    empty_i = np.zeros(0, dtype=np.int64)
    nothing = (empty_i, np.zeros(0), np.zeros((0, 2)), empty_i)
    total = sum(_solid_intervals(crossings, bmap.edge_body, family, h, elastic_count, False,
                                 nothing, 0) for crossings, family in families)
    sample_faces = np.empty(total, dtype=np.int64)
    fractions = np.empty(total)
    samples = np.empty((total, 2))
    bodies = np.empty(total, dtype=np.int64)
    slot = 0
    for crossings, family in families:
        slot = _solid_intervals(crossings, bmap.edge_body, family, h, elastic_count, True,
                                (sample_faces, fractions, samples, bodies), slot)
    # Only faces next to a cell the pressure equation has (one with an interior face open by
    # OPEN_MIN) enter it; the faces deep inside bodies are dropped before the point location.
    near = _next_to_active(sample_faces, interior.open_fraction_x, interior.open_fraction_y)
    sample_faces, fractions, samples, bodies = (sample_faces[near], fractions[near],
                                                np.ascontiguousarray(samples[near]), bodies[near])
    total = int(sample_faces.shape[0])
    nodes = np.zeros((total, 3), dtype=np.int64)
    weights = np.zeros((total, 3))
    _sample_weights(samples, bodies, bmap.points, bmap.edges, bmap.edge_body,
                    np.ascontiguousarray(triangles, dtype=np.int64),
                    np.ascontiguousarray(triangle_offsets, dtype=np.int64), nodes, weights)
    component = (sample_faces >= u_faces).astype(np.int64)
    rows = np.repeat(sample_faces, 3)
    cols = (2 * nodes + component[:, None]).ravel()
    values = (weights * fractions[:, None]).ravel()
    cuts = bmap.thin_cuts
    if cuts.count:
        active = np.zeros((nx + 2, ny + 2), dtype=np.bool_)
        _active_cells(interior.open_fraction_x, interior.open_fraction_y, active[1:-1, 1:-1])
        rows, cols, values = _with_thin_cuts(grid, bmap, cuts, active, rows, cols, values)
    faces, indptr, indices, data = _csr_by_rows(rows, cols, values)
    is_u = faces < u_faces
    open_fraction = np.where(
        is_u,
        interior.open_fraction_x.reshape(-1)[np.minimum(faces, u_faces - 1)],
        interior.open_fraction_y.reshape(-1)[np.maximum(faces - u_faces, 0)],
    )
    # A face the fluid closes carries the body's whole flux: rescale its row from the solid
    # part (1 - A) to all of it.
    closed = (open_fraction < OPEN_MIN) & (open_fraction > 0.0)
    if closed.any():
        scale = np.ones(faces.shape[0])
        scale[closed] = 1.0 / (1.0 - open_fraction[closed])
        data *= np.repeat(scale, np.diff(indptr))
    return _with_cells(grid, faces, SparseRows(indptr, indices, data, 2 * bmap.point_count))


def _with_cells(grid: Grid2D, faces: np.ndarray, matrix: SparseRows) -> InterfaceFlux:
    """``W`` with the cells on either side of each of its faces."""
    nx, ny = grid.nx, grid.ny
    u_faces = (nx + 1) * ny
    is_u = faces < u_faces
    u_index = faces
    v_index = faces - u_faces
    i = np.where(is_u, u_index // ny, v_index // (ny + 1))
    j = np.where(is_u, u_index % ny, v_index % (ny + 1))
    low = np.where(is_u, (i - 1) * ny + j, i * ny + (j - 1))
    high = np.where(is_u, i * ny + j, i * ny + j)
    low_valid = np.where(is_u, i >= 1, j >= 1)
    high_valid = np.where(is_u, i <= nx - 1, j <= ny - 1)
    low = np.where(low_valid, low, -1).astype(np.int64)
    high = np.where(high_valid, high, -1).astype(np.int64)
    return InterfaceFlux(grid, matrix, faces.astype(np.int64), low, high,
                         np.where(is_u, 0, 1).astype(np.int8))


def _with_thin_cuts(grid: Grid2D, bmap: BoundaryMap, cuts: ThinCuts, active: np.ndarray,
                    rows: np.ndarray, cols: np.ndarray,
                    values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Replace the rows of the faces a thin body cuts by the whole face's flux at the body
    velocity the projection gives them (`ThinCuts.velocities`: the crossings' velocities,
    each split between its edge's two nodes by the edge parameter)."""
    nx, ny = grid.nx, grid.ny
    u_faces = (nx + 1) * ny
    is_u = cuts.axis == 0
    flat = np.where(is_u, cuts.i * ny + cuts.j, u_faces + cuts.i * (ny + 1) + cuts.j)
    kept = ~np.isin(rows, flat)
    rows, cols, values = rows[kept], cols[kept], values[kept]
    # ``active`` is padded by one cell: u face (i, j) joins cells (i-1, j) and (i, j).
    near = np.where(is_u, active[cuts.i, cuts.j + 1] | active[cuts.i + 1, cuts.j + 1],
                    active[cuts.i + 1, cuts.j] | active[cuts.i + 1, cuts.j + 1])
    extra_rows, extra_cols, extra_values = [rows], [cols], [values]
    for source, edge_of, parameter_of in ((0, bmap.x_edge, bmap.x_parameter),
                                          (1, bmap.y_edge, bmap.y_parameter)):
        for k in range(4):
            chosen = np.flatnonzero(near & (cuts.source == source) & (cuts.entries[:, k] >= 0))
            if not chosen.size:
                continue
            entry = cuts.entries[chosen, k]
            edge = bmap.edges[edge_of[entry]]
            t = parameter_of[entry]
            weight = cuts.weights[chosen, k]
            component = cuts.axis[chosen].astype(np.int64)
            extra_rows += [flat[chosen], flat[chosen]]
            extra_cols += [2 * edge[:, 0] + component, 2 * edge[:, 1] + component]
            extra_values += [weight * (1.0 - t), weight * t]
    return (np.concatenate(extra_rows), np.concatenate(extra_cols),
            np.concatenate(extra_values))


@dataclass(frozen=True)
class _CellRows:
    """A matrix over few cells: row k belongs to the flat cell index ``ids[k]``."""

    ids: np.ndarray
    matrix: SparseRows

    def transpose_times(self, field: np.ndarray) -> np.ndarray:
        """``M^T`` applied to a cell field (any shape, flat cell order)."""
        return self.matrix.transpose_times(field.reshape(-1)[self.ids])


class BodyResponse(Protocol):
    """A body's (mean) velocity change answering nodal forces held over the step (linear)."""

    def velocity_change(self, forces: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        ...

    def compliance(self, dofs: np.ndarray) -> np.ndarray:
        ...

    def compliance_factor(self, dofs: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """The compliance as a banded factor (`elastoflow.solid.StepResponse`), or None to
        have `compliance` form it."""
        ...


class PressureCoupledBodies:
    """The bodies' side of the strongly coupled projection (`elastoflow.fluid.CoupledBodies`),
    in 2D and 3D alike.

    Args:
        flux: ``W`` of this step's boundary map (`interface_flux`, or `interface_flux_3d` on
            a 3D grid: the dimension follows its grid).
        predicted: Velocities [m/s] of all boundary points, shape (P, d): what the bodies
            sweep over the step without the pressure, and the obstacles' prescribed velocity.
        responses: Per body, its answer to a force held over the step (the velocity that
            enters ``predicted``), e.g. `elastoflow.solid.StepResponse`.
        offsets: Point offsets of the bodies in the boundary arrays (``offsets[b]:offsets[b+1]``
            are body b's nodes); points past the last body are obstacles (no response).
        density: Fluid density [kg/m^3].
        dt: Fluid step [s].
        bmap: The boundary map (points and edges, or triangles in 3D), needed with
            ``gravity``.
        gravity: The fluid's gravity [m/s^2] (d components). The hydrostatic part
            ``rho g.(x - x_b)`` of the pressure (``x_b`` each body's centroid) is not left to
            ``W``, which applies each cut cell's centre pressure to the whole covered part of
            its faces and so misses the buoyancy of a straight edge lying inside a row of
            cells by up to half a cell of height (in 3D: 0.33 % of a sphere's buoyancy at 8
            cells across); its exact integral over the body's surface (edges, triangles)
            replaces it (a known force, applied in the prediction: the coupled system is
            unchanged).

    After `respond`, ``velocities`` holds the boundary points' new velocities and
    ``pressure_forces`` the nodal forces [N/m in 2D, N in 3D] of the pressure on them.
    """

    def __init__(self, flux: InterfaceFlux | InterfaceFlux3D, predicted: np.ndarray,
                 responses: Sequence[BodyResponse], offsets: Sequence[int], density: float,
                 dt: float, bmap: BoundaryMap | BoundaryMap3D | None = None,
                 gravity: tuple[float, ...] = (0.0, 0.0)) -> None:
        self.dimension = 3 if isinstance(flux.grid, Grid3D) else 2
        if any(g != 0.0 for g in gravity) and bmap is None:
            raise ValueError("PressureCoupledBodies: gravity needs the boundary map")
        if len(gravity) != self.dimension:
            raise ValueError(f"PressureCoupledBodies: gravity = {gravity!r} must have "
                             f"{self.dimension} components")
        self.bmap = bmap
        self.gravity = tuple(float(g) for g in gravity)
        self.flux = flux
        self.predicted = np.ascontiguousarray(predicted, dtype=np.float64)
        self.responses = responses
        self.offsets = offsets
        self.density = float(density)
        self.dt = float(dt)
        # The force of a cell pressure on the covered part of a face: per unit depth in 2D.
        self.face_area = flux.grid.h ** (self.dimension - 1)
        self.velocities = self.predicted.copy()
        self.pressure_forces = np.zeros_like(self.predicted)
        self._correction = np.zeros_like(self.predicted)
        self._cell_rows: _CellRows | None = None

    def _cells(self, active: np.ndarray) -> _CellRows:
        """``D W`` on the active cells next to ``W``'s faces: each row a cell's net body
        outflow per unit nodal velocity."""
        if self._cell_rows is not None:
            return self._cell_rows
        flux = self.flux
        rows = flux.rows
        cells, indptr, indices, data = _cell_rows(
            rows.indptr, rows.indices, rows.data, flux.low_cell, flux.high_cell,
            np.ascontiguousarray(active).reshape(-1))
        self._cell_rows = _CellRows(cells, SparseRows(indptr, indices, data, rows.columns))
        return self._cell_rows

    def velocity_change(self, forces: np.ndarray) -> np.ndarray:
        change = np.zeros_like(forces)
        for index, response in enumerate(self.responses):
            lo, hi = self.offsets[index], self.offsets[index + 1]
            response.velocity_change(forces[lo:hi], out=change[lo:hi])
        return change

    def _hydrostatic_correction(self, active: np.ndarray) -> np.ndarray:
        """Exact minus ``W``'s nodal force of the hydrostatic pressure, per body (P, d)."""
        correction = np.zeros_like(self.predicted)
        if self.bmap is None or not any(self.gravity) or len(self.offsets) < 2:
            return correction
        grid = self.flux.grid
        centres = grid.cell_centers()
        points = self.bmap.points
        surface = (self.bmap.triangles if isinstance(self.bmap, BoundaryMap3D)
                   else self.bmap.edges)
        cells = self._cells(active)
        gravity = np.array(self.gravity)
        for index in range(len(self.offsets) - 1):
            lo, hi = self.offsets[index], self.offsets[index + 1]
            mine = surface[(surface[:, 0] >= lo) & (surface[:, 0] < hi)]
            if not mine.shape[0]:
                continue
            reference = points[lo:hi].mean(axis=0)
            # p = rho g.(x - x_b): rho g.x rises against gravity, i.e. with depth.
            field = self.density * sum(g * (x - r) for g, x, r
                                       in zip(self.gravity, centres, reference, strict=True))
            corner_pressure = np.column_stack([
                self.density * ((points[mine[:, corner]] - reference) @ gravity)
                for corner in range(mine.shape[1])])
            nodal = _linear_pressure_forces(points, mine, corner_pressure, lo, hi)
            discrete = self.face_area * cells.transpose_times(field).reshape(
                -1, self.dimension)
            correction[lo:hi] = nodal - discrete[lo:hi]
        return correction

    def add_to_rhs(self, rhs: np.ndarray, scale: float, active: np.ndarray) -> None:
        cells = self._cells(active)
        self._correction = self._hydrostatic_correction(active)
        if np.any(self._correction):
            self.predicted = self.predicted + self.velocity_change(self._correction)
        flat = rhs.reshape(-1)
        flat[cells.ids] -= scale * cells.matrix.times(self.predicted)

    def coupling_term(self, active: np.ndarray) -> LowRankTerm:
        """``rho h^d / dt (DW) Phi (DW)^T`` with ``Phi`` the bodies' compliance on the
        degrees of freedom that ``W`` touches (block diagonal over bodies): a dense block for
        the bodies whose response is a dense inverse, and the banded factors of the others
        (never formed: applied by sweeps inside the solve)."""
        cells = self._cells(active)
        d = self.dimension
        # B^T restricted to the bodies' touched degrees of freedom (obstacles' columns, past
        # the last body's points, have no response).
        touched, offsets, points, weights = _columns_below(
            cells.matrix.indptr, cells.matrix.indices, cells.matrix.data, cells.ids,
            d * self.offsets[-1])
        dense_slots = np.full(touched.shape[0], -1, np.int64)
        band_slots = np.full(touched.shape[0], -1, np.int64)
        dense_parts: list[tuple[np.ndarray, np.ndarray]] = []
        factors: list[tuple[np.ndarray, np.ndarray]] = []
        dense_size = band_size = 0
        for index, response in enumerate(self.responses):
            lo, hi = d * self.offsets[index], d * self.offsets[index + 1]
            mine = np.flatnonzero((touched >= lo) & (touched < hi))
            if not mine.size:
                continue
            factor = response.compliance_factor(touched[mine] - lo)
            if factor is None:
                dense_slots[mine] = dense_size + np.arange(mine.size)
                dense_parts.append((mine, response.compliance(touched[mine] - lo)))
                dense_size += mine.size
            else:
                columns, rows, positions = factor
                held = positions < 0
                band_slots[mine] = np.where(held, -1, positions + band_size)
                factors.append((columns, rows))
                band_size += columns.shape[0]
        matrix = np.zeros((dense_size, dense_size))
        start = 0
        for _, block in dense_parts:
            size = block.shape[0]
            matrix[start:start + size, start:start + size] = block
            start += size
        return LowRankTerm(
            offsets=offsets, points=points, weights=weights, matrix=matrix,
            scale=self.density * self.flux.grid.h ** d / self.dt, dense_slots=dense_slots,
            banded=_stacked_factors(factors, band_slots) if factors else None,
        )

    def respond(self, pressure: np.ndarray, active: np.ndarray, *closed: np.ndarray) -> None:
        """Apply ``pressure``'s force to the bodies; write the new body velocity into the
        ``closed`` arrays, one per face axis (u, v[, w]), on ``W``'s faces."""
        if len(closed) != self.dimension:
            raise ValueError(f"respond: {len(closed)} face arrays given; expected "
                             f"{self.dimension}")
        cells = self._cells(active)
        forces = self.face_area * cells.transpose_times(pressure)
        dynamic = forces.reshape(-1, self.dimension)
        self.velocities = self.predicted + self.velocity_change(dynamic)
        self.pressure_forces = dynamic + self._correction
        face_flux = self.flux.face_flux(self.velocities)
        faces, axis = self.flux.faces, self.flux.axis
        start = 0
        for index, target in enumerate(closed):
            mine = axis == index
            target.reshape(-1)[faces[mine] - start] = face_flux[mine]
            start += target.size


def _linear_pressure_forces(points: np.ndarray, surface: np.ndarray, corner_pressure: np.ndarray,
                            lo: int, hi: int) -> np.ndarray:
    """Nodal forces ``-int p n dA`` of a pressure linear over each edge (2D, per unit depth)
    or triangle (3D) of ``surface`` (outward; corners ``corner_pressure``), on the points
    ``lo:hi``: the integral of each corner's hat function times ``p``."""
    nodal = np.zeros_like(points[lo:hi])
    if surface.shape[1] == 2:
        a, b = surface[:, 0], surface[:, 1]
        pa, pb = corner_pressure[:, 0], corner_pressure[:, 1]
        edge = points[b] - points[a]
        # n ds = (dy, -dx) (out of the body, on the right of a->b); a linear p along the edge
        # gives node a (p_a / 3 + p_b / 6) and node b the mirror.
        normal = np.column_stack((edge[:, 1], -edge[:, 0]))
        np.add.at(nodal, a - lo, -normal * (pa / 3.0 + pb / 6.0)[:, None])
        np.add.at(nodal, b - lo, -normal * (pa / 6.0 + pb / 3.0)[:, None])
        return nodal
    corners = points[surface]
    # n dA = (b - a) x (c - a) / 2, outward; int phi_i p = area (2 p_i + p_j + p_k) / 12.
    area_normal = 0.5 * np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    total = corner_pressure.sum(axis=1)
    for corner in range(3):
        share = (total + corner_pressure[:, corner]) / 12.0
        np.add.at(nodal, surface[:, corner] - lo, -area_normal * share[:, None])
    return nodal


def _stacked_factors(factors: list[tuple[np.ndarray, np.ndarray]],
                     slots: np.ndarray) -> BandedInverse:
    """One block-diagonal banded factor from the bodies' own, each widened to the largest
    half-band with zeros (the blocks stay uncoupled: no entry links two bodies)."""
    band = max(columns.shape[1] for columns, _ in factors) - 1
    size = sum(columns.shape[0] for columns, _ in factors)
    stacked_columns = np.zeros((size, band + 1))
    stacked_rows = np.zeros((size, band + 1))
    start = 0
    for columns, rows in factors:
        n, width = columns.shape
        # columns[i, t] = U[i - b + t, i]: the body's own band sits at the right end.
        stacked_columns[start:start + n, band + 1 - width:] = columns
        stacked_rows[start:start + n, :width] = rows
        start += n
    return BandedInverse(stacked_columns, stacked_rows, slots)
