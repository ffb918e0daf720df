"""The 3D fluid's view of the bodies (`InteriorBoundary3D`) from the 3D boundary map, and
the fluid's traction force on the surface triangles."""

from __future__ import annotations

import numpy as np

from elastoflow.coupling import _kernels3d
from elastoflow.coupling._map3d import (
    BoundaryMap3D,
    CutDistances3D,
    cut_distances_3d,
    face_open_fractions_3d,
    solid_cells_3d,
)
from elastoflow.fluid._interior3d import InteriorBoundary3D
from elastoflow.grid import Grid3D

# Where the traction samples the fluid along the normal, in cells: the velocity (with the
# cut-distance ghosts) and the pressure (over fluid cells).
_SAMPLE_DISTANCES = (1.0, 2.0)
_PRESSURE_DISTANCES = (1.5, 2.5)


def _points_inside(bmap: BoundaryMap3D, component: int,
                   out: InteriorBoundary3D | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Solid flags and body velocity component of the u (0), v (1) or w (2) points, from the
    lines along the component's own axis; into ``out``'s arrays (reset inside its box, all
    when it has none) when given."""
    grid = bmap.grid
    counts = (grid.nx, grid.ny, grid.nz)
    shape = tuple(counts[a] + (1 if a == component else 0) for a in range(3))
    u, v = (component + 1) % 3, (component + 2) % 3
    crossings = bmap.lines[component]
    if out is None:
        solid = np.zeros(shape, dtype=np.bool_)
        velocity = np.zeros(shape)
    else:
        solid, velocity = out.solid_faces(component), out.velocity_faces(component)
        if out.box is None:
            solid[...] = False
            velocity[...] = 0.0
        else:
            # Outside its box nothing was inside a body: False and 0 already.
            box = np.asarray(out.box, dtype=np.int64)
            _kernels3d.fill_box(solid, box, False)
            _kernels3d.fill_box(velocity, box, 0.0)
    _kernels3d.inside_along_lines(
        crossings.arrays(), (bmap.triangles, bmap.velocities), component,
        (component, crossings.lines_v, 1, 1, shape[u], shape[v]),
        (float(grid.origin[component]), 0.0, grid.h, shape[component]), (solid, velocity))
    return solid, velocity


def interior_boundary_3d(bmap: BoundaryMap3D, out: InteriorBoundary3D | None = None
                         ) -> InteriorBoundary3D:
    """`InteriorBoundary3D` of the map's bodies: cells and velocity points inside them (ray
    parity along x for cells, along each component's own axis for its points), the body
    velocity at the points inside (linear between the crossings that bound them, METHOD.md
    §5.4), the faces' exact open fractions and the cut distances of every velocity point.

    ``out``: an earlier interior of the same grid that is no longer read; its solid-flag
    (cells and faces), body-velocity, open-fraction and cut-distance arrays are refilled
    instead of allocated, only inside its ``box`` when it has one.
    The result's ``box`` is the map's `bodies_box_3d`."""
    solid_faces = []
    velocity_faces = []
    for component in range(3):
        solid, velocity = _points_inside(bmap, component, out)
        solid_faces.append(solid)
        velocity_faces.append(velocity)
    open_x, open_y, open_z = face_open_fractions_3d(
        bmap, out=None if out is None else (out.open_fraction_x, out.open_fraction_y,
                                            out.open_fraction_z),
        out_box=None if out is None else out.box)
    reuse = None if out is None else CutDistances3D(
        (out.cut_theta_x, out.cut_theta_y, out.cut_theta_z),
        (out.cut_velocity_x, out.cut_velocity_y, out.cut_velocity_z), out.box)
    cuts = cut_distances_3d(bmap, out=reuse)
    return InteriorBoundary3D(
        solid_cells=solid_cells_3d(bmap, out=None if out is None else out.solid_cells,
                                   out_box=None if out is None else out.box),
        solid_faces_x=solid_faces[0], solid_faces_y=solid_faces[1],
        solid_faces_z=solid_faces[2],
        velocity_faces_x=velocity_faces[0], velocity_faces_y=velocity_faces[1],
        velocity_faces_z=velocity_faces[2],
        open_fraction_x=open_x, open_fraction_y=open_y, open_fraction_z=open_z,
        cut_theta_x=cuts.theta[0], cut_theta_y=cuts.theta[1], cut_theta_z=cuts.theta[2],
        cut_velocity_x=cuts.velocity[0], cut_velocity_y=cuts.velocity[1],
        cut_velocity_z=cuts.velocity[2], box=cuts.box,
    )


def _field(name: str, value: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    array = np.ascontiguousarray(value, dtype=np.float64)
    if array.shape != shape:
        raise ValueError(f"{name}: shape {array.shape} is not allowed; expected {shape}")
    return array


def force_traction_3d(
    grid: Grid3D,
    bmap: BoundaryMap3D,
    velocity_x: np.ndarray,
    velocity_y: np.ndarray,
    velocity_z: np.ndarray,
    pressure: np.ndarray,
    density: float,
    viscosity: float,
    interior: InteriorBoundary3D | None = None,
    gravity: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> np.ndarray:
    """Fluid force on the surface's vertices by the traction integral (METHOD.md §7, the 3D
    twin of `force_traction`).

    Integrates ``(-p I + mu (grad u + grad u^T)) n`` over every triangle of the map, ``n``
    the outward unit normal, ``mu = density * viscosity``. A triangle is cut into ``s^2``
    similar pieces with ``s`` its longest edge over h (rounded up), one sample at each
    piece's centroid ``x_w``; a piece's force is split between the triangle's vertices by
    the barycentric weights of ``x_w``. At ``x_w``:

    * pressure: ``p - rho g.x`` sampled at ``x_w + 1.5 h n`` and ``x_w + 2.5 h n``
      trilinearly over fluid cells only (solid and out-of-domain cells dropped, weights
      renormalised), taken to the wall by the quadratic through both with zero normal
      derivative there; where one sample has no fluid cell the other is carried at constant
      value;
    * viscous stress: ``grad u = L + g_n n^T`` with ``L`` the wall velocity's surface
      gradient (linear over the triangle) and ``g_n`` the one-sided second-order normal
      derivative through the wall velocity and u, v, w sampled at h and 2 h along n
      (corners inside bodies replaced by the advection's cut-distance ghosts);
      with ``g_n.n`` replaced by ``-tr L`` (continuity), ``(grad u + grad u^T) n = g_t +
      L^T n - 2 tr(L) n``, ``g_t`` the tangential part of ``g_n``.

    Args:
        grid: The 3D MAC grid.
        bmap: The 3D boundary map; its points, velocities and triangles give the surface.
        velocity_x, velocity_y, velocity_z: Face velocities [m/s], (nx+1, ny, nz),
            (nx, ny+1, nz), (nx, ny, nz+1), usually after the projection.
        pressure: Cell pressure [Pa], (nx, ny, nz).
        density: Fluid density rho [kg/m^3].
        viscosity: Kinematic viscosity nu [m^2/s] (>= 0).
        interior: Solid flags of cells and velocity points (samples skip them); all fluid
            when None.
        gravity: The fluid's gravitational acceleration [m/s^2] (hydrostatic carry).

    Returns:
        Forces [N] on the map's points, shape (P, 3); their sum is the force on the bodies.
    """
    if bmap.grid != grid:
        raise ValueError(f"boundary map grid {bmap.grid!r}: must be the grid {grid!r}")
    velocity_x = _field("velocity_x", velocity_x, grid.shape_faces_x)
    velocity_y = _field("velocity_y", velocity_y, grid.shape_faces_y)
    velocity_z = _field("velocity_z", velocity_z, grid.shape_faces_z)
    pressure = _field("pressure", pressure, grid.shape_cells)
    if not (density > 0.0 and np.isfinite(density)):
        raise ValueError(f"density = {density!r}: must be a finite number > 0")
    if not (viscosity >= 0.0 and np.isfinite(viscosity)):
        raise ValueError(f"viscosity = {viscosity!r}: must be a finite number >= 0")
    if interior is None:
        interior = InteriorBoundary3D.empty(grid)
    else:
        interior.check(grid)
    force = np.zeros((bmap.points.shape[0], 3))
    origin = [float(c) for c in grid.origin]
    distances = [distance * grid.h for distance in _SAMPLE_DISTANCES]
    pressure_distances = [distance * grid.h for distance in _PRESSURE_DISTANCES]
    settings = (*origin, grid.h, float(density), float(density * viscosity),
                *(float(g) for g in gravity), *distances, *pressure_distances)
    _kernels3d.traction_triangles(
        (bmap.points, bmap.velocities, bmap.triangles),
        (velocity_x, velocity_y, velocity_z, pressure),
        ((interior.solid_faces_x, interior.solid_faces_y, interior.solid_faces_z),
         (interior.cut_theta_x, interior.cut_theta_y, interior.cut_theta_z),
         (interior.cut_velocity_x, interior.cut_velocity_y, interior.cut_velocity_z),
         interior.solid_cells),
        settings, force)
    return force
