from __future__ import annotations

import numpy as np
import pytest

from elastoflow.coupling import (
    Obstacle,
    RigidMotion,
    build_boundary_map,
    classify_points,
    concatenate_boundaries,
    obstacle_circle,
    obstacle_pipe,
    obstacle_rectangle,
    polygon_signed_area,
)
from elastoflow.grid import Grid2D


def test_clockwise_polygon_is_reoriented():
    clockwise = np.array([[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]])
    obstacle = Obstacle(clockwise)
    assert polygon_signed_area(obstacle.polygon) == pytest.approx(1.0)
    np.testing.assert_array_equal(obstacle.edges, [[0, 1], [1, 2], [2, 3], [3, 0]])
    # Body on the left of every edge: the left normal of each edge points to the centroid.
    a = obstacle.polygon[obstacle.edges[:, 0]]
    b = obstacle.polygon[obstacle.edges[:, 1]]
    left = np.stack([-(b - a)[:, 1], (b - a)[:, 0]], axis=1)
    assert np.all(np.sum(left * (obstacle.pivot - 0.5 * (a + b)), axis=1) > 0)


def test_fixed_obstacle_has_zero_velocity():
    obstacle = obstacle_rectangle((0.1, 0.2), (0.3, 0.5))
    np.testing.assert_array_equal(obstacle.points_at(3.0), obstacle.polygon)
    np.testing.assert_array_equal(obstacle.velocities_at(3.0), 0.0)


@pytest.mark.parametrize("center", [None, (0.2, -0.1)])
def test_rigid_motion_velocities_are_time_derivatives_of_points(center):
    motion = RigidMotion(velocity=(0.3, -0.5), angular_velocity=1.7, center=center)
    obstacle = obstacle_circle((0.5, 0.4), 0.2, 16, motion=motion)
    time, step = 0.8, 1e-6
    difference = (obstacle.points_at(time + step) - obstacle.points_at(time - step)) / (2 * step)
    np.testing.assert_allclose(obstacle.velocities_at(time), difference, atol=1e-8)
    # Rigid: distances between vertices are kept.
    before = np.linalg.norm(obstacle.polygon - obstacle.polygon[0], axis=1)
    after = np.linalg.norm(obstacle.points_at(time) - obstacle.points_at(time)[0], axis=1)
    np.testing.assert_allclose(after, before, atol=1e-12)


def test_callable_motion():
    def swing(time):
        return (np.array([0.0, 0.1 * np.sin(time)]), 0.2 * time,
                np.array([0.0, 0.1 * np.cos(time)]), 0.2)

    obstacle = Obstacle(np.array([[0.0, 0.0], [1.0, 0.0], [0.5, 1.0]]), motion=swing,
                        pivot=np.array([0.5, 0.0]))
    time, step = 1.3, 1e-6
    difference = (obstacle.points_at(time + step) - obstacle.points_at(time - step)) / (2 * step)
    np.testing.assert_allclose(obstacle.velocities_at(time), difference, atol=1e-8)


def test_pipe_walls_leave_the_channel_open():
    grid = Grid2D(32, 16, 1.0 / 16.0)
    walls = obstacle_pipe((0.2, 0.5), (1.6, 0.5), inner_width=0.25, wall_thickness=0.125)
    points, velocities, edges, edge_body, offsets = concatenate_boundaries(
        [(wall.points_at(0.0), wall.velocities_at(0.0), wall.edges) for wall in walls])
    np.testing.assert_array_equal(offsets, [0, 4, 8])
    np.testing.assert_array_equal(edge_body, [0, 0, 0, 0, 1, 1, 1, 1])
    assert edges.max() == 7
    result = classify_points(grid, build_boundary_map(grid, points, velocities, edges, edge_body))
    x, y = grid.cell_centers()
    along = (x > 0.2) & (x < 1.6)
    upper = along & (y > 0.625) & (y < 0.75)
    lower = along & (y > 0.25) & (y < 0.375)
    np.testing.assert_array_equal(result.solid_cells, upper | lower)
    assert set(np.unique(result.body_cells[upper])) | set(np.unique(result.body_cells[lower])) \
        == {0, 1}
    assert len(set(np.unique(result.body_cells[upper]))) == 1


def test_concatenate_boundaries_of_nothing():
    points, _, edges, edge_body, offsets = concatenate_boundaries([])
    assert points.shape == (0, 2) and edges.shape == (0, 2) and edge_body.shape == (0,)
    np.testing.assert_array_equal(offsets, [0])


def test_bad_obstacles_raise():
    with pytest.raises(ValueError, match="polygon"):
        Obstacle(np.zeros((2, 2)))
    with pytest.raises(ValueError, match="area"):
        Obstacle(np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]))
    with pytest.raises(ValueError, match="radius"):
        obstacle_circle((0.0, 0.0), -1.0)
    with pytest.raises(ValueError, match="rectangle"):
        obstacle_rectangle((1.0, 0.0), (0.0, 1.0))
    with pytest.raises(ValueError, match="inner_width"):
        obstacle_pipe((0.0, 0.0), (1.0, 0.0), 0.0, 0.1)
    with pytest.raises(ValueError, match="velocities"):
        concatenate_boundaries([(np.zeros((3, 2)), np.zeros((2, 2)), np.zeros((0, 2)))])
