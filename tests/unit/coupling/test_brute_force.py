"""The brute-force classification (every grid point against every element) agrees with the
boundary map's scanline fill: flags, body ids and, for rigid motion, velocities."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow.coupling import (
    build_boundary_map,
    classify_points,
    classify_points_brute_force,
    concatenate_boundaries,
    obstacle_circle,
    obstacle_rectangle,
)
from elastoflow.grid import Grid2D
from elastoflow.solid import mesh_from_polygon

GRID = Grid2D(40, 36, 1.0 / 40.0, origin=(-0.013, 0.007))


def _rigid(points, centre, velocity, omega):
    arm = points - centre
    return velocity + omega * np.column_stack((-arm[:, 1], arm[:, 0]))


def _compare(brute, mapped, velocity_tolerance=1e-12):
    for name in ("solid_cells", "solid_faces_x", "solid_faces_y", "body_cells",
                 "body_faces_x", "body_faces_y"):
        np.testing.assert_array_equal(getattr(brute, name), getattr(mapped, name),
                                      err_msg=name)
    for name in ("velocity_faces_x", "velocity_faces_y"):
        np.testing.assert_allclose(getattr(brute, name), getattr(mapped, name),
                                   atol=velocity_tolerance, err_msg=name)


def test_obstacles_by_their_edges() -> None:
    """Outlines only: the winding number along the row, as the map counts it (exactly)."""
    circle = obstacle_circle((0.31, 0.42), 0.137, segments=53)
    box = obstacle_rectangle((0.52, 0.16), (0.86, 0.71))
    shapes = [(o.points_at(0.0), np.zeros((o.point_count, 2)), o.edges) for o in (circle, box)]
    points, _, edges, edge_body, _ = concatenate_boundaries(shapes)
    velocities = _rigid(points, np.array([0.5, 0.5]), np.array([0.2, -0.4]), 1.7)
    bmap = build_boundary_map(GRID, points, velocities, edges, edge_body)
    mapped = classify_points(GRID, bmap)
    brute = classify_points_brute_force(GRID, points, velocities, edges, edge_body)
    assert mapped.solid_cells.sum() > 100 and set(np.unique(mapped.body_cells)) == {-1, 0, 1}
    _compare(brute, mapped)


@pytest.mark.parametrize("omega", [0.0, -3.1])
def test_elastic_bodies_by_their_triangles(omega: float) -> None:
    """Two meshed bodies and an obstacle: the bodies point by triangle, the obstacle by its
    edges; velocities barycentric against the map's span interpolation, both exact for a
    rigid motion."""
    angles = np.linspace(0.0, 2.0 * np.pi, 37, endpoint=False)
    disc = mesh_from_polygon(np.column_stack((0.27 + 0.16 * np.cos(angles),
                                              0.55 + 0.16 * np.sin(angles))), element_size=0.04)
    bar = mesh_from_polygon(np.array([[0.55, 0.1], [0.93, 0.13], [0.91, 0.31], [0.57, 0.27]]),
                            element_size=0.04)
    wall = obstacle_rectangle((0.5, 0.52), (0.95, 0.83))
    bodies = [disc, bar]
    points = np.concatenate([disc.points, bar.points, wall.points_at(0.0)])
    offsets = np.cumsum([0, disc.points.shape[0], bar.points.shape[0]])
    edges = np.concatenate([disc.boundary_edges, bar.boundary_edges + offsets[1],
                            wall.edges + offsets[2]])
    edge_body = np.concatenate([np.full(len(b.boundary_edges), k) for k, b in enumerate(bodies)]
                               + [np.full(len(wall.edges), 2)])
    triangles = np.concatenate([disc.triangles, bar.triangles + offsets[1]])
    triangle_body = np.concatenate([np.full(b.triangle_count, k) for k, b in enumerate(bodies)])
    velocities = _rigid(points, np.array([0.6, 0.4]), np.array([-0.7, 0.25]), omega)
    bmap = build_boundary_map(GRID, points, velocities, edges, edge_body)
    mapped = classify_points(GRID, bmap)
    brute = classify_points_brute_force(GRID, points, velocities, edges, edge_body,
                                        triangles=triangles, triangle_body=triangle_body)
    assert set(np.unique(mapped.body_faces_x)) == {-1, 0, 1, 2}
    _compare(brute, mapped)
