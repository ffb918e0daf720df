from __future__ import annotations

import math

import numpy as np

from elastoflow.coupling import _kernels
from elastoflow.coupling._map import BoundaryMap
from elastoflow.fluid import InteriorBoundary
from elastoflow.grid import Grid2D

# Distances (in cells) along the outward normal at which the traction estimate samples the
# fluid; the next one is tried when every stencil point of a sample is solid.
_SAMPLE_DISTANCES = (1.5, 2.5, 3.5)


def _check_field(name: str, value: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    array = np.ascontiguousarray(value, dtype=np.float64)
    if array.shape != shape:
        raise ValueError(f"{name} shape {array.shape}: must be {shape} for this grid")
    return array


def _check_positive(name: str, value: float) -> None:
    if not (value > 0.0 and np.isfinite(value)):
        raise ValueError(f"{name} = {value!r}: must be a finite positive number")


def force_momentum_exchange(
    grid: Grid2D,
    bmap: BoundaryMap,
    velocity_x: np.ndarray,
    velocity_y: np.ndarray,
    density: float,
    dt: float,
    alpha: float = 0.5,
    interior: InteriorBoundary | None = None,
) -> np.ndarray:
    """Fluid force on the boundary points by the paper's momentum exchange, eq. (8).

    ``f = sum_s alpha rho h^2 (u_P - u_s) / dt`` per unit depth, over the map entries ``s``:
    entries of the x-map rows through u points (``J = 2j+1``) give f_x with ``u_P`` the u point
    of that row next to the crossing on its fluid side; entries of the y-map columns through
    v points (``I = 2i+1``) give f_y with the v point of that column. The fluid side follows
    from the edge orientation (the entry's sign). A crossing with another crossing between it
    and that point (a sliver thinner than h) contributes nothing. Each entry's force is split
    between its edge's two nodes by the edge parameter t.

    Evaluate it on the intermediate (pre-projection) velocity (METHOD.md §7); it does not see
    hydrostatic or far-field pressure.

    Args:
        grid: The MAC grid.
        bmap: Boundary map of the current boundary.
        velocity_x: Face x-velocities [m/s], shape (nx+1, ny).
        velocity_y: Face y-velocities [m/s], shape (nx, ny+1).
        density: Fluid density rho [kg/m^3].
        dt: Fluid time step [s].
        alpha: Volume fraction of the body in the cell next to the boundary (paper: 0.5).
        interior: The step's `InteriorBoundary`: ``u_P`` is then the first velocity point on
            the fluid side that it does not mark solid. Needed with a staircase boundary,
            whose closed faces carry the body's velocity (``u_P - u_s`` would be about 0
            there); with cut cells the point next to the crossing is never solid, and None
            gives the same force.

    Returns:
        Nodal forces [N per metre of depth] on the map's boundary points, shape (P, 2).
    """
    if bmap.grid != grid:
        raise ValueError(f"boundary map grid {bmap.grid!r}: must be the grid {grid!r}")
    velocity_x = _check_field("velocity_x", velocity_x, grid.shape_faces_x)
    velocity_y = _check_field("velocity_y", velocity_y, grid.shape_faces_y)
    _check_positive("density", density)
    _check_positive("dt", dt)
    if not 0.0 <= alpha <= 1.0:
        raise ValueError(f"alpha = {alpha!r}: must lie in [0, 1]")
    h = grid.h
    coefficient = alpha * density * h * h / dt
    force = np.zeros((bmap.point_count, 2))
    nothing = np.zeros((0, 0), dtype=np.bool_)
    solid_x = nothing if interior is None else np.ascontiguousarray(interior.solid_faces_x)
    solid_y = nothing if interior is None else np.ascontiguousarray(interior.solid_faces_y)
    _kernels.momentum_exchange_lines(
        (bmap.x_offsets, bmap.x_coordinate, bmap.x_sign, bmap.x_edge, bmap.x_parameter,
         bmap.x_velocity), bmap.edges, (0, 1, grid.ny, grid.nx + 1, grid.origin[0], h, True),
        velocity_x, solid_x, coefficient, force,
    )
    _kernels.momentum_exchange_lines(
        (bmap.y_offsets, bmap.y_coordinate, bmap.y_sign, bmap.y_edge, bmap.y_parameter,
         bmap.y_velocity), bmap.edges, (1, 1, grid.nx, grid.ny + 1, grid.origin[1], h, False),
        velocity_y, solid_y, coefficient, force,
    )
    return force


def force_traction(
    grid: Grid2D,
    bmap: BoundaryMap,
    velocity_x: np.ndarray,
    velocity_y: np.ndarray,
    pressure: np.ndarray,
    density: float,
    viscosity: float,
    interior: InteriorBoundary | None = None,
    gravity: tuple[float, float] = (0.0, 0.0),
    sample_distances: tuple[float, ...] = _SAMPLE_DISTANCES,
) -> np.ndarray:
    """Fluid force on the boundary points by the traction integral (METHOD.md §7).

    Integrates ``(-p I + mu (grad u + grad u^T)) n`` along every boundary edge of the map,
    ``n`` the unit normal out of the body (on the right of a->b), ``mu = density * viscosity``.
    Each edge is cut into pieces no longer than h, one midpoint each; a piece's force is split
    between the edge's nodes by t. At each midpoint ``x_w``:

    * pressure: sampled at ``x_w + 1.5 h n`` by bilinear interpolation over fluid cells only
      (solid and out-of-domain cells dropped, weights renormalised), then carried to the wall
      at constant ``p - rho g.x``: exact for a hydrostatic field, and otherwise a zeroth-order
      extrapolation along the normal (the normal pressure gradient vanishes at a no-slip wall
      up to viscous terms);
    * viscous stress: the velocity gradient at the wall is written ``grad u = g_t t^T +
      g_n n^T`` (t the unit tangent a->b). With no slip, ``g_t`` is the wall's own derivative
      along the edge, ``(v_b - v_a) / length``; ``g_n`` is the one-sided second-order
      difference through the wall velocity and u, v sampled like the pressure (over fluid
      faces) at 1.5 h and 2.5 h along n (first order from the 1.5 h sample alone when the
      other one has no fluid). The traction is ``mu [(g_n.t + g_t.n) t + 2 (g_n.n) n]`` with
      ``g_n.n`` replaced by ``-g_t.t`` (continuity). Exact for a linear profile; for the
      rotating cylinder of circular Couette flow the torque error is 2.7 %, 0.9 %, 0.3 % at
      R/h = 6.4, 12.8, 25.6.

    When every stencil point of a sample is solid the sample moves out to 2.5 h, then 3.5 h;
    failing that, that part of the traction is left out for the piece.

    Args:
        grid: The MAC grid.
        bmap: Boundary map; its points, velocities and edges give the boundary.
        velocity_x: Face x-velocities [m/s], shape (nx+1, ny), usually after the projection.
        velocity_y: Face y-velocities [m/s], shape (nx, ny+1).
        pressure: Cell pressure [Pa], shape (nx, ny), including the fluid's hydrostatic part.
        density: Fluid density rho [kg/m^3].
        viscosity: Kinematic viscosity nu [m^2/s] (>= 0).
        interior: Solid flags of cells and faces (samples skip solid points); all fluid when
            None.
        gravity: The fluid's gravitational acceleration (gx, gy) [m/s^2], for the hydrostatic
            carry to the wall.
        sample_distances: Where along the normal the samples are taken, in cells, the next
            tried when every stencil point of one is solid (a study of the carry's error:
            the lift of DFG 2D-2 depends on it, docs/validation/unsteady.md).

    Returns:
        Nodal forces [N per metre of depth] on the map's boundary points, shape (P, 2).
    """
    if bmap.grid != grid:
        raise ValueError(f"boundary map grid {bmap.grid!r}: must be the grid {grid!r}")
    velocity_x = _check_field("velocity_x", velocity_x, grid.shape_faces_x)
    velocity_y = _check_field("velocity_y", velocity_y, grid.shape_faces_y)
    pressure = _check_field("pressure", pressure, grid.shape_cells)
    _check_positive("density", density)
    if not (viscosity >= 0.0 and np.isfinite(viscosity)):
        raise ValueError(f"viscosity = {viscosity!r}: must be a finite number >= 0")
    if not sample_distances or not all(math.isfinite(d) and d > 0.0 for d in sample_distances):
        raise ValueError(f"sample_distances = {sample_distances!r}: must be one or more "
                         "finite distances > 0 [cells]")
    if interior is None:
        interior = InteriorBoundary.empty(grid)
    else:
        interior.check(grid)
    force = np.zeros((bmap.point_count, 2))
    _kernels.traction_edges(
        (bmap.points, bmap.velocities, bmap.edges), (velocity_x, velocity_y, pressure),
        (np.ascontiguousarray(interior.solid_faces_x),
         np.ascontiguousarray(interior.solid_faces_y),
         np.ascontiguousarray(interior.solid_cells)),
        (float(grid.origin[0]), float(grid.origin[1]), float(grid.h)),
        (float(density), float(density * viscosity), float(gravity[0]), float(gravity[1])),
        np.asarray(sample_distances, dtype=np.float64) * grid.h, force,
    )
    return force
