from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from elastoflow.coupling import _kernels
from elastoflow.grid import Grid2D

if TYPE_CHECKING:
    from elastoflow.coupling._thin import ThinCuts


@dataclass(frozen=True, eq=False)
class BoundaryMap:
    """Crossings of body boundaries with the half-grid lines (METHOD.md §5).

    Two maps in CSR form. The **x-map** holds, for every half-grid row ``J = 0..2ny`` (the line
    ``y = origin_y + J h/2``), every crossing of a boundary edge with that row, sorted by x. The
    **y-map** holds the same for every half-grid column ``I = 0..2nx`` (``x = origin_x + I h/2``),
    sorted by y. Crossings are kept wherever they lie along the line, also outside the domain,
    so that a body crossing the domain edge still fills correctly.

    Index spaces: ``P`` boundary points, ``E`` boundary edges, ``Cx`` x-map entries, ``Cy``
    y-map entries. Entries of row ``J`` are ``x_offsets[J]:x_offsets[J+1]`` of every ``x_*``
    entry array; entries of column ``I`` are ``y_offsets[I]:y_offsets[I+1]`` of every ``y_*``
    entry array. Within a line, entries are sorted by coordinate, ties with the leaving
    crossing first.

    Attributes:
        grid: The grid whose half grid the lines belong to.
        points: Boundary point positions [m], shape (P, 2).
        velocities: Boundary point velocities [m/s], shape (P, 2).
        edges: Boundary edges (a, b) into ``points``, body on the left of a->b, int64,
            shape (E, 2).
        edge_body: Body index of each edge, int64, shape (E,).
        x_offsets: Row offsets into the x-map entries, int64, shape (2ny+2,).
        x_coordinate: x [m] of each crossing, shape (Cx,).
        x_edge: Edge index (into ``edges``) of each crossing, int64, shape (Cx,).
        x_parameter: Parameter t in [0, 1] of the crossing on its edge (0 at a, 1 at b),
            shape (Cx,).
        x_velocity: Solid velocity (1-t) v_a + t v_b [m/s] at each crossing, shape (Cx, 2).
        x_sign: +1 where walking the row towards +x enters a body at the crossing, -1 where it
            leaves one (from the edge orientation), int8, shape (Cx,).
        y_offsets: Column offsets into the y-map entries, int64, shape (2nx+2,).
        y_coordinate: y [m] of each crossing, shape (Cy,).
        y_edge: Edge index of each crossing, int64, shape (Cy,).
        y_parameter: Parameter t on the edge, shape (Cy,).
        y_velocity: Solid velocity at each crossing [m/s], shape (Cy, 2).
        y_sign: +1 where walking the column towards +y enters a body, -1 where it leaves,
            int8, shape (Cy,).
    """

    grid: Grid2D
    points: np.ndarray
    velocities: np.ndarray
    edges: np.ndarray
    edge_body: np.ndarray
    x_offsets: np.ndarray
    x_coordinate: np.ndarray
    x_edge: np.ndarray
    x_parameter: np.ndarray
    x_velocity: np.ndarray
    x_sign: np.ndarray
    y_offsets: np.ndarray
    y_coordinate: np.ndarray
    y_edge: np.ndarray
    y_parameter: np.ndarray
    y_velocity: np.ndarray
    y_sign: np.ndarray

    @cached_property
    def thin_cuts(self) -> ThinCuts:
        """The connections that bodies thinner than a cell cut (`elastoflow.coupling.thin_cuts`
        on this map's grid), found once: the classification and the coupled step's flux both
        need them."""
        from elastoflow.coupling._thin import thin_cuts

        return thin_cuts(self.grid, self)

    @property
    def crossing_count(self) -> int:
        """Total number of entries in both maps."""
        return int(self.x_coordinate.shape[0] + self.y_coordinate.shape[0])

    @property
    def point_count(self) -> int:
        """Number of boundary points P."""
        return int(self.points.shape[0])

    def row(self, index: int) -> slice:
        """Slice of the x-map entry arrays that belong to half-grid row ``J = index``."""
        return slice(int(self.x_offsets[index]), int(self.x_offsets[index + 1]))

    def column(self, index: int) -> slice:
        """Slice of the y-map entry arrays that belong to half-grid column ``I = index``."""
        return slice(int(self.y_offsets[index]), int(self.y_offsets[index + 1]))


def _as_points(name: str, value: np.ndarray) -> np.ndarray:
    array = np.ascontiguousarray(value, dtype=np.float64)
    if array.ndim != 2 or array.shape[1] != 2:
        raise ValueError(f"{name} shape {array.shape}: must be (P, 2)")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name}: contains non-finite values; all must be finite")
    return array


def build_boundary_map(
    grid: Grid2D,
    points: np.ndarray,
    velocities: np.ndarray,
    edges: np.ndarray,
    edge_body: np.ndarray | None = None,
) -> BoundaryMap:
    """Build the x- and y-maps from boundary edges (METHOD.md §5.2).

    Loops over edges, never over grid points: the cost is proportional to the number of
    crossings (perimeter / h). An edge crosses line ``L`` when ``lo <= L < hi`` in half-cell
    units (half-open, so a vertex exactly on a line is counted once by the two edges meeting
    there); edges parallel to the lines are skipped.

    Args:
        grid: The MAC grid.
        points: Boundary point positions [m], shape (P, 2).
        velocities: Boundary point velocities [m/s], shape (P, 2).
        edges: Edges (a, b) into ``points``, body on the left of a->b, shape (E, 2).
        edge_body: Body index of each edge, shape (E,); all 0 when omitted.

    Returns:
        The boundary map.
    """
    points = _as_points("points", points)
    velocities = _as_points("velocities", velocities)
    if velocities.shape != points.shape:
        raise ValueError(
            f"velocities shape {velocities.shape}: must match points shape {points.shape}"
        )
    edges = np.ascontiguousarray(edges, dtype=np.int64).reshape(-1, 2)
    if edges.size and (edges.min() < 0 or edges.max() >= points.shape[0]):
        raise ValueError(
            f"edges index range [{edges.min()}, {edges.max()}]: must lie in [0, {points.shape[0]})"
        )
    if edge_body is None:
        edge_body = np.zeros(edges.shape[0], dtype=np.int64)
    else:
        edge_body = np.ascontiguousarray(edge_body, dtype=np.int64)
        if edge_body.shape != (edges.shape[0],):
            raise ValueError(
                f"edge_body shape {edge_body.shape}: must be ({edges.shape[0]},), one per edge"
            )
    half_h = 0.5 * grid.h
    x = np.ascontiguousarray(points[:, 0])
    y = np.ascontiguousarray(points[:, 1])
    x_map = _kernels.build_axis_map(
        x, y, velocities, edges, grid.origin[1], half_h, 2 * grid.ny + 1,
        True,
    )
    y_map = _kernels.build_axis_map(
        y, x, velocities, edges, grid.origin[0], half_h, 2 * grid.nx + 1,
        False,
    )
    return BoundaryMap(grid, points, velocities, edges, edge_body, *x_map, *y_map)
