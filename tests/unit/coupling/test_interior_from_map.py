from __future__ import annotations

import numpy as np
from coupling_polygons import H, polygon_edges, segments_intersect, star_polygon
from hypothesis import assume, given, note, settings
from hypothesis import strategies as st

from elastoflow.coupling import (
    Obstacle,
    RigidMotion,
    build_boundary_map,
    classify_points,
    interior_boundary_from_map,
    obstacle_circle,
    obstacle_rectangle,
)
from elastoflow.fluid import InteriorBoundary
from elastoflow.grid import Grid2D

DIRECTIONS = np.array([[-1.0, 0.0], [1.0, 0.0], [0.0, -1.0], [0.0, 1.0]])


def _interior(grid, obstacle, time=0.0):
    bmap = build_boundary_map(grid, obstacle.points_at(time), obstacle.velocities_at(time),
                              obstacle.edges)
    interior = interior_boundary_from_map(grid, bmap)
    interior.check(grid)
    return interior


def _clip_length(start, end, polygon):
    """Length of the segment start->end inside a convex counter-clockwise polygon."""
    d = end - start
    s_lo, s_hi = 0.0, 1.0
    for a, b in zip(polygon, np.roll(polygon, -1, axis=0), strict=True):
        outward = np.array([b[1] - a[1], a[0] - b[0]])
        numerator = outward @ (start - a)
        denominator = outward @ d
        if denominator == 0.0:
            if numerator > 0.0:
                return 0.0
            continue
        s = -numerator / denominator
        if denominator > 0.0:
            s_hi = min(s_hi, s)
        else:
            s_lo = max(s_lo, s)
    return max(s_hi - s_lo, 0.0) * float(np.hypot(*d))


def _ray_hits(origin, direction, polygon, velocities, h):
    """All (s, velocity) where origin + s h direction meets a polygon edge, s in [0, 1]."""
    a, b = polygon, np.roll(polygon, -1, axis=0)
    velocity_a, velocity_b = velocities, np.roll(velocities, -1, axis=0)
    ray = direction * h
    edge = b - a
    # Solve origin + s ray = a + t edge by Cramer's rule, for every edge at once.
    determinant = ray[0] * (-edge[:, 1]) - ray[1] * (-edge[:, 0])
    rhs = a - origin
    valid = np.abs(determinant) > 1e-15
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (rhs[:, 0] * (-edge[:, 1]) - rhs[:, 1] * (-edge[:, 0])) / determinant
        t = (ray[0] * rhs[:, 1] - ray[1] * rhs[:, 0]) / determinant
    hit = valid & (s >= 0) & (s <= 1) & (t >= 0) & (t <= 1)
    return [(s[k], (1 - t[k]) * velocity_a[k] + t[k] * velocity_b[k]) for k in np.nonzero(hit)[0]]


@settings(max_examples=30, deadline=None)
@given(data=st.data(), velocity=st.tuples(st.floats(-2, 2), st.floats(-2, 2)),
       angular_velocity=st.floats(-5, 5), time=st.floats(0.0, 0.05))
def test_velocity_inside_rigid_body_is_exact(data, velocity, angular_velocity, time):
    grid = Grid2D(32, 32, H)
    polygon = data.draw(star_polygon((0.3, 0.7), (0.3, 0.7), 0.05, 0.3, grid.origin, snap=False))
    assume(not segments_intersect(polygon))
    motion = RigidMotion(velocity, angular_velocity, center=(0.5, 0.45))
    body = Obstacle(polygon, motion=motion)
    interior = _interior(grid, body, time)
    center = np.array([0.5, 0.45]) + np.array(velocity) * time
    for locate, solid, values, open_fraction, component in (
        (grid.faces_x, interior.solid_faces_x, interior.velocity_faces_x,
         interior.open_fraction_x, 0),
        (grid.faces_y, interior.solid_faces_y, interior.velocity_faces_y,
         interior.open_fraction_y, 1),
    ):
        x, y = locate()
        rigid = (velocity[0] - angular_velocity * (y - center[1]) if component == 0
                 else velocity[1] + angular_velocity * (x - center[0]))
        # A face that a spike thinner than a cell cuts takes the velocity at the spike's
        # mid-line, not at its own point (tests/unit/coupling/test_thin.py).
        thin = open_fraction == 0.0
        np.testing.assert_allclose(values[solid & ~thin], rigid[solid & ~thin], rtol=0,
                                   atol=1e-11)
        assert np.all(values[~solid & ~thin] == 0.0)


def test_open_fractions_of_aligned_rectangle_are_analytic():
    grid = Grid2D(16, 16, 1.0 / 16.0)
    x0, y0, x1, y1 = 0.23, 0.31, 0.61, 0.77
    interior = _interior(grid, obstacle_rectangle((x0, y0), (x1, y1)))
    h = grid.h
    x, y = grid.faces_x()
    overlap = np.clip(np.minimum(y + 0.5 * h, y1) - np.maximum(y - 0.5 * h, y0), 0.0, h)
    expected = 1.0 - np.where((x >= x0) & (x <= x1), overlap / h, 0.0)
    np.testing.assert_allclose(interior.open_fraction_x, expected, rtol=0, atol=1e-12)
    x, y = grid.faces_y()
    overlap = np.clip(np.minimum(x + 0.5 * h, x1) - np.maximum(x - 0.5 * h, x0), 0.0, h)
    expected = 1.0 - np.where((y >= y0) & (y <= y1), overlap / h, 0.0)
    np.testing.assert_allclose(interior.open_fraction_y, expected, rtol=0, atol=1e-12)
    assert np.any((interior.open_fraction_x > 0) & (interior.open_fraction_x < 1))


def test_open_fractions_of_rotated_square_match_clipping():
    grid = Grid2D(16, 16, 1.0 / 16.0)
    angle = 0.37
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * 0.22
    rotation = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    square = corners @ rotation.T + np.array([0.52, 0.47])
    interior = _interior(grid, Obstacle(square))
    h = grid.h
    x, y = grid.faces_x()
    expected = np.array([1.0 - _clip_length(np.array([px, py - h / 2]),
                                            np.array([px, py + h / 2]), square) / h
                         for px, py in zip(x.ravel(), y.ravel(), strict=True)])
    np.testing.assert_allclose(interior.open_fraction_x.ravel(), expected, atol=1e-12)
    x, y = grid.faces_y()
    expected = np.array([1.0 - _clip_length(np.array([px - h / 2, py]),
                                            np.array([px + h / 2, py]), square) / h
                         for px, py in zip(x.ravel(), y.ravel(), strict=True)])
    np.testing.assert_allclose(interior.open_fraction_y.ravel(), expected, atol=1e-12)
    # The open area of the faces adds up to the domain minus the square, row by row.
    solid_length = np.sum(1.0 - interior.open_fraction_y) * h * h
    np.testing.assert_allclose(solid_length, 0.44**2, rtol=0.05)


def test_cut_thetas_of_circle_match_ray_casting_and_analytic_distances():
    grid = Grid2D(24, 24, 1.0 / 24.0)
    center, radius, segments = np.array([0.51, 0.47]), 0.27, 96
    circle = obstacle_circle(tuple(center), radius, segments,
                             motion=RigidMotion((0.4, -0.3), angular_velocity=1.5))
    polygon, velocities = circle.points_at(0.0), circle.velocities_at(0.0)
    interior = _interior(grid, circle)
    h = grid.h
    sag = radius * (1 - np.cos(np.pi / segments))
    compared_with_circle = 0
    for locate, theta, cut_velocity, component in (
        (grid.faces_x, interior.cut_theta_x, interior.cut_velocity_x, 0),
        (grid.faces_y, interior.cut_theta_y, interior.cut_velocity_y, 1),
    ):
        x, y = locate()
        for i, j in np.ndindex(x.shape):
            point = np.array([x[i, j], y[i, j]])
            for d, direction in enumerate(DIRECTIONS):
                hits = _ray_hits(point, direction, polygon, velocities, h)
                # Towards minus the window is [0, 1), towards plus (0, 1].
                plus = d % 2 == 1
                hits = [hit for hit in hits if (0.0 < hit[0] <= 1.0 if plus else hit[0] < 1.0)]
                if not hits:
                    assert theta[d, i, j] == np.inf
                    assert cut_velocity[d, i, j] == 0.0
                    continue
                s, velocity = min(hits, key=lambda hit: hit[0])
                np.testing.assert_allclose(theta[d, i, j], s, atol=1e-12)
                np.testing.assert_allclose(cut_velocity[d, i, j], velocity[component], atol=1e-12)
                # Against the true circle where the ray is not grazing it.
                relative = point - center
                b = relative @ direction
                disc = b * b - (relative @ relative - radius**2)
                if disc <= 0.0:
                    continue
                roots = np.array([-b - np.sqrt(disc), -b + np.sqrt(disc)]) / h
                roots = roots[roots > 0]
                if roots.size == 0:
                    continue
                hit_point = point + roots[0] * h * direction
                cosine = abs((hit_point - center) @ direction) / radius
                if cosine > 0.3:
                    assert abs(theta[d, i, j] - roots[0]) <= sag / (cosine * h) + 1e-9
                    compared_with_circle += 1
    assert compared_with_circle > 100


def test_empty_map_gives_empty_interior():
    grid = Grid2D(8, 6, 0.1)
    bmap = build_boundary_map(grid, np.zeros((0, 2)), np.zeros((0, 2)),
                              np.zeros((0, 2), dtype=np.int64))
    interior = interior_boundary_from_map(grid, bmap)
    empty = InteriorBoundary.empty(grid)
    for name in ("solid_cells", "solid_faces_x", "open_fraction_y", "cut_theta_x",
                 "cut_velocity_y"):
        np.testing.assert_array_equal(getattr(interior, name), getattr(empty, name))


def test_body_on_a_face_point_sees_the_floored_fraction():
    grid = Grid2D(8, 8, 0.125)
    # The right side x = 0.5 passes through the u points of column i = 4.
    square = np.array([[0.3, 0.3], [0.5, 0.3], [0.5, 0.7], [0.3, 0.7]])
    bmap = build_boundary_map(grid, square, np.zeros_like(square), polygon_edges(4))
    interior = interior_boundary_from_map(grid, bmap)
    # A point on a leaving crossing is fluid; its cut towards the body is floored above 0.
    assert not interior.solid_faces_x[4, 3]
    assert 0.0 < interior.cut_theta_x[0, 4, 3] <= 1e-6
    assert interior.cut_theta_x[1, 3, 3] == 1.0


def test_out_is_reset_and_refilled_like_a_fresh_result():
    grid = Grid2D(16, 16, 1.0 / 16.0)
    first = obstacle_circle((0.3, 0.4), 0.2, 24, motion=RigidMotion((1.0, 0.5), 2.0))
    second = obstacle_rectangle((0.55, 0.2), (0.8, 0.6), motion=RigidMotion((-0.3, 0.1)))
    out = _interior(grid, first)
    classification = classify_points(grid, build_boundary_map(
        grid, first.points_at(0.0), first.velocities_at(0.0), first.edges))
    bmap = build_boundary_map(grid, second.points_at(0.0), second.velocities_at(0.0),
                              second.edges)
    fresh = interior_boundary_from_map(grid, bmap)
    reused = interior_boundary_from_map(grid, bmap, out=out)
    assert reused is out
    fresh_classification = classify_points(grid, bmap)
    classify_points(grid, bmap, out=classification)
    for name in ("solid_cells", "solid_faces_x", "body_faces_y", "velocity_faces_x"):
        np.testing.assert_array_equal(getattr(classification, name),
                                      getattr(fresh_classification, name))
    for name in ("solid_cells", "solid_faces_x", "solid_faces_y", "velocity_faces_x",
                 "velocity_faces_y", "open_fraction_x", "open_fraction_y", "cut_theta_x",
                 "cut_theta_y", "cut_velocity_x", "cut_velocity_y"):
        np.testing.assert_array_equal(getattr(reused, name), getattr(fresh, name))
    with_classification = interior_boundary_from_map(grid, bmap, fresh_classification)
    np.testing.assert_array_equal(with_classification.velocity_faces_y, fresh.velocity_faces_y)


@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_fluid_point_next_to_a_solid_one_always_sees_a_cut(data):
    # Vertices snapped onto half-grid lines put grid points exactly on edges: the x-map
    # (classification) and the y-map (cuts along y) must still agree.
    grid = Grid2D(32, 32, H)
    polygon = data.draw(star_polygon((0.2, 0.8), (0.2, 0.8), 0.05, 0.4, grid.origin))
    assume(not segments_intersect(polygon))
    note(repr(polygon.tolist()))
    interior = _interior(grid, Obstacle(polygon))
    for solid, theta in ((interior.solid_faces_x, interior.cut_theta_x),
                         (interior.solid_faces_y, interior.cut_theta_y)):
        neighbours = (
            (0, solid[:-1, :], solid[1:, :]),  # towards -x: the point is [1:], neighbour [:-1]
            (1, solid[1:, :], solid[:-1, :]),
            (2, solid[:, :-1], solid[:, 1:]),
            (3, solid[:, 1:], solid[:, :-1]),
        )
        for d, neighbour, point in neighbours:
            cut = theta[d][1:, :] if d == 0 else theta[d][:-1, :] if d == 1 else \
                theta[d][:, 1:] if d == 2 else theta[d][:, :-1]
            changes = neighbour != point
            assert np.all(np.isfinite(cut[changes]))
            assert np.all((cut[changes] > 0.0) & (cut[changes] <= 1.0))
