from __future__ import annotations

import numpy as np
from coupling_polygons import (
    ORIGINS,
    H,
    distance_to_polygon,
    inside_even_odd,
    polygon_edges,
    segments_intersect,
    star_polygon,
)
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from elastoflow.coupling import build_boundary_map, classify_points, concatenate_boundaries
from elastoflow.grid import Grid2D


def _check_against_brute_force(grid, polygons, reverse=False):
    boundaries = []
    for polygon in polygons:
        loop = polygon[::-1] if reverse else polygon
        boundaries.append((loop, np.zeros_like(loop), polygon_edges(len(loop))))
    points, velocities, edges, edge_body, _ = concatenate_boundaries(boundaries)
    bmap = build_boundary_map(grid, points, velocities, edges, edge_body)
    result = classify_points(grid, bmap)
    checked = 0
    for locate, solid, body in (
        (grid.cell_centers, result.solid_cells, result.body_cells),
        (grid.faces_x, result.solid_faces_x, result.body_faces_x),
        (grid.faces_y, result.solid_faces_y, result.body_faces_y),
    ):
        x, y = locate()
        query = np.stack([x.ravel(), y.ravel()], axis=1)
        expected_body = np.full(query.shape[0], -1)
        away = np.ones(query.shape[0], dtype=bool)
        for b, polygon in enumerate(polygons):
            expected_body[inside_even_odd(query, polygon)] = b
            # On the boundary itself inside/outside is a convention: leave those points out.
            away &= distance_to_polygon(query, polygon) > 1e-9
        np.testing.assert_array_equal(solid.ravel()[away], expected_body[away] >= 0)
        np.testing.assert_array_equal(body.ravel()[away], expected_body[away])
        checked += int(np.sum(away))
    return checked


@settings(max_examples=60, deadline=None)
@given(data=st.data(), origin=st.sampled_from(ORIGINS), reverse=st.booleans())
def test_one_body_matches_point_in_polygon(data, origin, reverse):
    grid = Grid2D(32, 32, H, origin)
    ox, oy = origin
    # Centres may sit outside the domain so that bodies cross its edges.
    polygon = data.draw(star_polygon((ox - 0.1, ox + 1.1), (oy - 0.1, oy + 1.1), 0.01, 0.6,
                                     origin))
    assume(not segments_intersect(polygon))
    assert _check_against_brute_force(grid, [polygon], reverse) > 0


@settings(max_examples=40, deadline=None)
@given(data=st.data(), origin=st.sampled_from(ORIGINS))
def test_several_bodies_match_point_in_polygon(data, origin):
    grid = Grid2D(32, 32, H, origin)
    ox, oy = origin
    polygons = []
    for lo, hi in ((0.1, 0.25), (0.45, 0.55), (0.75, 0.9)):
        polygon = data.draw(star_polygon((ox + lo, ox + hi), (oy - 0.1, oy + 1.1), 0.005, 0.09,
                                         origin))
        assume(not segments_intersect(polygon))
        polygons.append(polygon)
    _check_against_brute_force(grid, polygons)


@settings(max_examples=30, deadline=None)
@given(angle=st.floats(0.0, np.pi), width=st.floats(1e-4, 0.5),
       center=st.tuples(st.floats(0.2, 0.8), st.floats(0.2, 0.8)))
def test_thin_slivers_match_point_in_polygon(angle, width, center):
    grid = Grid2D(32, 32, H)
    direction = np.array([np.cos(angle), np.sin(angle)])
    normal = np.array([-direction[1], direction[0]])
    half_length, half_width = 0.3, 0.5 * width * H
    c = np.asarray(center)
    sliver = np.array([c - half_length * direction - half_width * normal,
                       c + half_length * direction - half_width * normal,
                       c + half_length * direction + half_width * normal,
                       c - half_length * direction + half_width * normal])
    _check_against_brute_force(grid, [sliver])


def test_touching_squares_fill_both():
    grid = Grid2D(16, 16, 1.0 / 16.0)
    left = np.array([[0.2, 0.2], [0.5, 0.2], [0.5, 0.8], [0.2, 0.8]])
    right = np.array([[0.5, 0.2], [0.8, 0.2], [0.8, 0.8], [0.5, 0.8]])
    points, velocities, edges, edge_body, _ = concatenate_boundaries(
        [(left, np.zeros((4, 2)), polygon_edges(4)), (right, np.zeros((4, 2)), polygon_edges(4))])
    result = classify_points(grid, build_boundary_map(grid, points, velocities, edges, edge_body))
    x, y = grid.cell_centers()
    inside = (x > 0.2) & (x < 0.8) & (y > 0.2) & (y < 0.8)
    np.testing.assert_array_equal(result.solid_cells, inside)
    np.testing.assert_array_equal(result.body_cells[inside], np.where(x[inside] < 0.5, 0, 1))


def test_body_with_a_hole_leaves_the_hole_fluid():
    grid = Grid2D(32, 32, H)
    outer = np.array([[0.2, 0.15], [0.85, 0.2], [0.8, 0.9], [0.15, 0.8]])
    # The hole's loop runs clockwise so that the body stays on the left of its edges.
    hole = np.array([[0.4, 0.35], [0.45, 0.6], [0.62, 0.63], [0.6, 0.4]])
    points, velocities, edges, edge_body, _ = concatenate_boundaries(
        [(outer, np.zeros((4, 2)), polygon_edges(4)), (hole, np.zeros((4, 2)), polygon_edges(4))])
    edge_body[:] = 0
    result = classify_points(grid, build_boundary_map(grid, points, velocities, edges, edge_body))
    x, y = grid.cell_centers()
    query = np.stack([x.ravel(), y.ravel()], axis=1)
    expected = inside_even_odd(query, outer) & ~inside_even_odd(query, hole)
    np.testing.assert_array_equal(result.solid_cells.ravel(), expected)
    assert np.all(result.body_cells.ravel()[expected] == 0)
    assert np.any(inside_even_odd(query, hole))
