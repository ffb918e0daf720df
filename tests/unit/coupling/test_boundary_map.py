from __future__ import annotations

import numpy as np
import pytest
from coupling_polygons import ORIGINS, H, polygon_edges, segments_intersect, star_polygon
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from elastoflow.coupling import (
    RigidMotion,
    build_boundary_map,
    obstacle_circle,
    obstacle_rectangle,
)
from elastoflow.grid import Grid2D


def _brute_force_lines(points, velocities, edges, origin_across, half_h, line_count, along,
                       across, entering_when_decreasing):
    """Per line: sorted (coordinate, edge, t, vx, vy, sign) tuples from every edge directly."""
    scaled = (points[:, across] - origin_across) / half_h
    lines = []
    for line in range(line_count):
        found = []
        for e, (a, b) in enumerate(edges):
            sa, sb = scaled[a], scaled[b]
            if sa == sb or not (min(sa, sb) <= line < max(sa, sb)):
                continue
            t = (line - sa) / (sb - sa)
            velocity = (1 - t) * velocities[a] + t * velocities[b]
            entering = (sb < sa) == entering_when_decreasing
            found.append((points[a, along] + t * (points[b, along] - points[a, along]), e, t,
                          velocity[0], velocity[1], 1 if entering else -1))
        lines.append(sorted(found, key=lambda entry: (entry[0], entry[5])))
    return lines


def _assert_map_matches(bmap, grid, points, velocities, edges):
    half_h = 0.5 * grid.h
    for prefix, along, across, count, entering_when_decreasing in (
        ("x", 0, 1, 2 * grid.ny + 1, True),
        ("y", 1, 0, 2 * grid.nx + 1, False),
    ):
        expected = _brute_force_lines(points, velocities, edges, grid.origin[across], half_h,
                                      count, along, across, entering_when_decreasing)
        offsets = getattr(bmap, f"{prefix}_offsets")
        assert offsets.shape == (count + 1,)
        for line, entries in enumerate(expected):
            part = slice(offsets[line], offsets[line + 1])
            assert offsets[line + 1] - offsets[line] == len(entries)
            if not entries:
                continue
            reference = np.array(entries)
            np.testing.assert_allclose(getattr(bmap, f"{prefix}_coordinate")[part],
                                       reference[:, 0], rtol=0, atol=1e-12)
            np.testing.assert_allclose(getattr(bmap, f"{prefix}_velocity")[part],
                                       reference[:, 3:5], rtol=0, atol=1e-12)
            np.testing.assert_array_equal(getattr(bmap, f"{prefix}_sign")[part], reference[:, 5])
            # Where coordinates tie the order of equal entries is free: compare edge sets.
            edge_ids = getattr(bmap, f"{prefix}_edge")[part]
            assert sorted(edge_ids) == sorted(reference[:, 1].astype(int))
            t = getattr(bmap, f"{prefix}_parameter")[part]
            assert np.all((t >= 0.0) & (t <= 1.0))
            # The stored t reproduces the stored coordinate on the stored edge.
            a, b = edges[edge_ids, 0], edges[edge_ids, 1]
            np.testing.assert_allclose(
                points[a, along] + t * (points[b, along] - points[a, along]),
                getattr(bmap, f"{prefix}_coordinate")[part], rtol=0, atol=1e-12)


def test_axis_aligned_square_gives_known_crossings():
    grid = Grid2D(16, 16, 1.0 / 16.0)
    square = obstacle_rectangle((0.25, 0.25), (0.5, 0.75), motion=RigidMotion((0.3, -0.2)))
    bmap = build_boundary_map(grid, square.points_at(0.0), square.velocities_at(0.0),
                              square.edges)
    rows = np.diff(bmap.x_offsets)
    # Rows y = J/32 in [0.25, 0.75): J = 8..23; the top side y = 0.75 is counted by no row.
    np.testing.assert_array_equal(np.nonzero(rows)[0], np.arange(8, 24))
    assert np.all(rows[8:24] == 2)
    columns = np.diff(bmap.y_offsets)
    np.testing.assert_array_equal(np.nonzero(columns)[0], np.arange(8, 16))
    for J in range(8, 24):
        np.testing.assert_array_equal(bmap.x_coordinate[bmap.row(J)], [0.25, 0.5])
        np.testing.assert_array_equal(bmap.x_sign[bmap.row(J)], [1, -1])
        np.testing.assert_allclose(bmap.x_velocity[bmap.row(J)], [[0.3, -0.2]] * 2)
    for I in range(8, 16):
        np.testing.assert_array_equal(bmap.y_coordinate[bmap.column(I)], [0.25, 0.75])
        np.testing.assert_array_equal(bmap.y_sign[bmap.column(I)], [1, -1])
    assert bmap.crossing_count == 16 * 2 + 8 * 2


def test_circle_crossings_lie_between_inscribed_and_circumscribed_circles():
    grid = Grid2D(64, 64, 1.0 / 64.0)
    center, radius, segments = (0.47, 0.52), 0.31, 256
    circle = obstacle_circle(center, radius, segments)
    bmap = build_boundary_map(grid, circle.points_at(0.0), circle.velocities_at(0.0),
                              circle.edges)
    inner = radius * np.cos(np.pi / segments)
    for J in range(2 * grid.ny + 1):
        y = grid.half_grid_line_y(J)
        x = bmap.x_coordinate[bmap.row(J)]
        r = np.hypot(x - center[0], y - center[1])
        assert np.all((r >= inner - 1e-12) & (r <= radius + 1e-12))
        if abs(y - center[1]) < inner:
            assert x.size == 2
            analytic = np.sqrt(radius**2 - (y - center[1]) ** 2)
            np.testing.assert_allclose(x, center[0] + np.array([-analytic, analytic]),
                                       atol=radius * (1 - np.cos(np.pi / segments))
                                       / np.sqrt(1 - ((y - center[1]) / inner) ** 2) + 1e-12)
            np.testing.assert_array_equal(bmap.x_sign[bmap.row(J)], [1, -1])
        elif abs(y - center[1]) > radius:
            assert x.size == 0


def test_vertices_on_lines_count_once_and_parallel_edges_are_skipped():
    grid = Grid2D(8, 8, 0.125)
    # A diamond with every vertex on a half-grid line.
    polygon = np.array([[0.5, 0.25], [0.75, 0.5], [0.5, 0.75], [0.25, 0.5]])
    bmap = build_boundary_map(grid, polygon, np.zeros_like(polygon), polygon_edges(4))
    counts = np.diff(bmap.x_offsets)
    # Bottom vertex (row 4, a local minimum) starts two edges: both count, zero-width span.
    assert counts[4] == 2
    np.testing.assert_array_equal(bmap.x_coordinate[bmap.row(4)], [0.5, 0.5])
    # Side vertices on row 8 are counted once each; the top vertex (row 12, maximum) never.
    assert counts[8] == 2 and counts[12] == 0
    assert np.all(counts[5:12] == 2)

    flat = np.array([[0.25, 0.25], [0.75, 0.25], [0.75, 0.5], [0.25, 0.5]])
    bmap = build_boundary_map(grid, flat, np.zeros_like(flat), polygon_edges(4))
    # The horizontal edges lie on rows 4 and 8 and give no x-map entries: rows 4..7 see the
    # two vertical sides only, row 8 (the top side) nothing.
    counts = np.diff(bmap.x_offsets)
    assert np.sum(counts) == 8 and np.all(counts[4:8] == 2)


@settings(max_examples=60, deadline=None)
@given(data=st.data(), origin=st.sampled_from(ORIGINS), bodies=st.integers(1, 2))
def test_map_matches_brute_force_for_random_polygons(data, origin, bodies):
    grid = Grid2D(32, 32, H, origin)
    ox, oy = origin
    polygons = []
    for b in range(bodies):
        lo, hi = (0.1, 0.4) if b == 0 else (0.6, 0.9)
        polygon = data.draw(star_polygon((ox + lo, ox + hi), (oy - 0.1, oy + 1.1), 0.02,
                                         0.1 if bodies == 2 else 0.6, origin))
        assume(not segments_intersect(polygon))
        polygons.append(polygon)
    points = np.concatenate(polygons)
    edges = np.concatenate([polygon_edges(len(p), sum(len(q) for q in polygons[:k]))
                            for k, p in enumerate(polygons)])
    rng = np.random.default_rng(len(points))
    velocities = rng.normal(size=points.shape)
    bmap = build_boundary_map(grid, points, velocities, edges)
    _assert_map_matches(bmap, grid, points, velocities, edges)


def test_crossing_count_grows_with_perimeter_not_grid():
    circle = obstacle_circle((0.5, 0.5), 0.3, 512)
    counts = []
    for n in (64, 128, 256):
        grid = Grid2D(n, n, 1.0 / n)
        counts.append(build_boundary_map(grid, circle.points_at(0.0), circle.velocities_at(0.0),
                                         circle.edges).crossing_count)
    ratios = np.array(counts[1:]) / np.array(counts[:-1])
    assert np.all((ratios > 1.9) & (ratios < 2.1)), (counts, ratios)


def test_bad_input_raises():
    grid = Grid2D(4, 4, 0.25)
    points = np.zeros((3, 2))
    with pytest.raises(ValueError, match="velocities"):
        build_boundary_map(grid, points, np.zeros((2, 2)), polygon_edges(3))
    with pytest.raises(ValueError, match="edges"):
        build_boundary_map(grid, points, points, np.array([[0, 3]]))
    with pytest.raises(ValueError, match="points"):
        build_boundary_map(grid, np.zeros((3, 3)), np.zeros((3, 3)), polygon_edges(3))
    with pytest.raises(ValueError, match="edge_body"):
        build_boundary_map(grid, points, points, polygon_edges(3), edge_body=np.zeros(2))


def test_empty_boundary_gives_empty_map():
    grid = Grid2D(4, 4, 0.25)
    bmap = build_boundary_map(grid, np.zeros((0, 2)), np.zeros((0, 2)),
                              np.zeros((0, 2), dtype=np.int64))
    assert bmap.crossing_count == 0
    assert bmap.x_offsets.shape == (10,) and bmap.y_offsets.shape == (10,)
