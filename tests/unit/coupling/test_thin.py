"""Bodies thinner than a cell cut the pressure connections their mid-line crosses
(`elastoflow.coupling._thin`); bodies two cells thick and more, and the caps of round ones, cut
nothing."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from elastoflow.coupling import (
    Obstacle,
    build_boundary_map,
    interface_flux,
    interior_boundary_from_map,
    obstacle_circle,
    obstacle_polyline,
    obstacle_rectangle,
)
from elastoflow.coupling._thin import thin_cuts
from elastoflow.fluid import OPEN_MIN
from elastoflow.grid import Grid2D

GRID = Grid2D(24, 20, 1.0 / 24.0)
H = GRID.h
OFFSETS = [0.1, 0.3, 0.5, 0.7, 0.9]


def _plate(x_mid: float, thickness_cells: float, angle: float = 0.0,
           y: tuple[float, float] = (0.2, 0.6)) -> Obstacle:
    """A plate (or, at thickness 0, a polyline) from y0 to y1 whose mid-line passes through
    (x_mid, (y0 + y1) / 2) at ``angle`` degrees from the vertical."""
    slope = np.tan(np.radians(angle))
    y0, y1 = y
    bottom = (x_mid - 0.5 * slope * (y1 - y0), y0)
    top = (x_mid + 0.5 * slope * (y1 - y0), y1)
    if thickness_cells == 0.0:
        return obstacle_polyline([bottom, top])
    half = 0.5 * thickness_cells * H / np.cos(np.radians(angle))
    return Obstacle(np.array([(bottom[0] - half, y0), (bottom[0] + half, y0),
                              (top[0] + half, y1), (top[0] - half, y1)]))


def _map(obstacle: Obstacle, velocity: tuple[float, float] = (0.0, 0.0)):
    points = obstacle.points_at(0.0)
    velocities = np.tile(np.asarray(velocity, dtype=np.float64), (points.shape[0], 1))
    return build_boundary_map(GRID, points, velocities, obstacle.edges), velocities


def _components(interior) -> np.ndarray:
    """Connected components of the cells through faces open by at least OPEN_MIN."""
    nx, ny = GRID.nx, GRID.ny
    index = np.arange(nx * ny).reshape(nx, ny)
    open_x = interior.open_fraction_x[1:-1, :] >= OPEN_MIN
    open_y = interior.open_fraction_y[:, 1:-1] >= OPEN_MIN
    rows = np.concatenate([index[:-1, :][open_x], index[:, :-1][open_y]])
    cols = np.concatenate([index[1:, :][open_x], index[:, 1:][open_y]])
    graph = coo_matrix((np.ones(rows.shape[0]), (rows, cols)), shape=(nx * ny, nx * ny))
    return connected_components(graph, directed=False)[1].reshape(nx, ny)


@pytest.mark.parametrize("thickness", [0.25, 0.0])
@pytest.mark.parametrize("offset", OFFSETS)
def test_a_vertical_plate_closes_the_face_line_nearest_its_mid_line(thickness: float,
                                                                    offset: float) -> None:
    x_mid = 10 * H + offset * H
    bmap, _ = _map(_plate(x_mid, thickness, y=(0.2, 0.6)))
    cuts = thin_cuts(GRID, bmap)
    assert np.all(cuts.axis == 0)
    face = 10 if offset <= 0.5 else 11
    assert np.all(cuts.i == face)
    xc, yc = GRID.cell_centers()
    rows = np.flatnonzero((yc[0] > 0.2) & (yc[0] <= 0.6))
    assert np.array_equal(np.sort(cuts.j), rows)
    interior = interior_boundary_from_map(GRID, bmap)
    assert np.all(interior.open_fraction_x[face, rows] == 0.0)


@pytest.mark.parametrize("thickness", [0.0, 0.25, 0.6, 1.3])
@pytest.mark.parametrize("angle", [0.0, 20.0, 35.0])
@pytest.mark.parametrize("offset", OFFSETS)
def test_no_cell_path_crosses_a_thin_plate(thickness: float, angle: float,
                                           offset: float) -> None:
    """A plate from wall to wall leaves the cells on its two sides in different components of
    the pressure graph (at any tilt and offset, down to zero thickness)."""
    x_mid = 12 * H + offset * H
    plate = _plate(x_mid, thickness, angle, y=(-0.1, 0.95))
    interior = interior_boundary_from_map(GRID, _map(plate)[0])
    components = _components(interior)
    assert components[0, :].min() == components[0, :].max()
    assert components[-1, :].min() == components[-1, :].max()
    assert components[0, 0] != components[-1, 0]


@pytest.mark.parametrize("radius_cells", [2.2, 3.7, 6.3, 11.9])
@pytest.mark.parametrize("shift", [0.0, 0.13, 0.41, 0.77])
def test_round_and_thick_bodies_cut_nothing(radius_cells: float, shift: float) -> None:
    """Caps (a centre line grazing the top of a disc) are not thin bodies: the open fractions
    already see them."""
    center = (0.5 + shift * H, 0.4 + 0.61 * shift * H)
    bmap, _ = _map(obstacle_circle(center, radius_cells * H, segments=97))
    assert thin_cuts(GRID, bmap).count == 0
    bmap, _ = _map(obstacle_rectangle((0.3 + shift * H, 0.3), (0.3 + (2.0 + shift) * H, 0.7)))
    assert thin_cuts(GRID, bmap).count == 0


@pytest.mark.parametrize("thickness", [0.0, 0.25])
@pytest.mark.parametrize("angle", [0.0, 30.0])
def test_cut_faces_carry_the_body_velocity_in_the_projection_and_in_w(thickness: float,
                                                                       angle: float) -> None:
    """The projection's velocity on a cut face (``velocity_faces``) and ``W``'s row for it
    give the same flux: the whole face at the body velocity, exact for rigid motion."""
    velocity = (0.37, -1.21)
    bmap, velocities = _map(_plate(10.3 * H, thickness, angle), velocity)
    interior = interior_boundary_from_map(GRID, bmap)
    cuts = thin_cuts(GRID, bmap)
    assert cuts.count > 0
    is_u = cuts.axis == 0
    expected = np.where(is_u, velocity[0], velocity[1])
    assert np.allclose(cuts.velocities(bmap), expected, rtol=0, atol=1e-14)
    assert np.allclose(interior.velocity_faces_x[cuts.i[is_u], cuts.j[is_u]], velocity[0])
    assert np.allclose(interior.velocity_faces_y[cuts.i[~is_u], cuts.j[~is_u]], velocity[1])
    flux = interface_flux(GRID, bmap, interior)
    u_faces = (GRID.nx + 1) * GRID.ny
    flat = np.where(is_u, cuts.i * GRID.ny + cuts.j, u_faces + cuts.i * (GRID.ny + 1) + cuts.j)
    rows = np.searchsorted(flux.faces, flat)
    assert np.array_equal(flux.faces[rows], flat)
    assert np.allclose(flux.face_flux(velocities)[rows], expected, rtol=0, atol=1e-14)


def test_polyline_obstacle() -> None:
    line = obstacle_polyline([(0.1, 0.2), (0.4, 0.25), (0.5, 0.7)])
    assert line.edges.tolist() == [[0, 1], [1, 2], [2, 1], [1, 0]]
    assert np.allclose(line.pivot, line.polygon.mean(axis=0))
    interior = interior_boundary_from_map(GRID, _map(line)[0])
    assert not interior.solid_cells.any() and not interior.solid_faces_x.any()
    with pytest.raises(ValueError, match="k >= 2"):
        obstacle_polyline([(0.1, 0.2)])
    with pytest.raises(ValueError, match="consecutive points must differ"):
        obstacle_polyline([(0.1, 0.2), (0.1, 0.2), (0.3, 0.3)])
