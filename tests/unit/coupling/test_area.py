"""Exact polygon areas per grid square (`elastoflow.coupling._area`) against clipping each
square separately, and their continuity."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from elastoflow.coupling._area import polygon_areas, segment_moments


def clipped_area(polygon: np.ndarray, x0: float, x1: float, y0: float, y1: float) -> float:
    """Area of a counter-clockwise polygon inside a rectangle by Sutherland-Hodgman."""
    return float(clipped_moments(polygon, x0, x1, y0, y1)[0])


def clipped_moments(polygon: np.ndarray, x0: float, x1: float, y0: float,
                    y1: float) -> np.ndarray:
    """(area, int (x - xc) dA, int (y - yc) dA) of the polygon inside the rectangle, (xc, yc)
    its centre, by Sutherland-Hodgman and the shoelace formulas."""
    vertices = [tuple(p) for p in polygon]
    for axis, level, keep in ((0, x0, 1.0), (0, x1, -1.0), (1, y0, 1.0), (1, y1, -1.0)):
        clipped = []
        for k in range(len(vertices)):
            p, q = vertices[k - 1], vertices[k]
            p_in = (p[axis] - level) * keep >= 0.0
            q_in = (q[axis] - level) * keep >= 0.0
            if p_in != q_in:
                t = (level - p[axis]) / (q[axis] - p[axis])
                clipped.append((p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])))
            if q_in:
                clipped.append(q)
        vertices = clipped
        if not vertices:
            return np.zeros(3)
    x = np.array([v[0] for v in vertices]) - 0.5 * (x0 + x1)
    y = np.array([v[1] for v in vertices]) - 0.5 * (y0 + y1)
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    return np.array([0.5 * cross.sum(), (cross * (x + xn)).sum() / 6.0,
                     (cross * (y + yn)).sum() / 6.0])


def _star(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    count = int(rng.integers(3, 14))
    angles = np.sort(rng.uniform(0.0, 2.0 * np.pi, count))
    radii = rng.uniform(0.15, 0.5, count)
    centre = rng.uniform(0.1, 0.9, 2)
    return np.column_stack([centre[0] + radii * np.cos(angles),
                            centre[1] + radii * np.sin(angles)])


def _areas(polygon: np.ndarray, h: float, n: int, origin: tuple[float, float]) -> np.ndarray:
    count = polygon.shape[0]
    edges = np.column_stack([np.arange(count), (np.arange(count) + 1) % count])
    out = np.zeros((n, n))
    polygon_areas(polygon, edges, origin[0], origin[1], h, n, n, out)
    return out


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_areas_match_clipping_every_square(seed: int) -> None:
    """Random star-shaped polygons, partly outside the grid: every square's area to
    round-off."""
    polygon = _star(seed)
    h, n, origin = 0.1, 10, (0.03, -0.02)
    areas = _areas(polygon, h, n, origin)
    expected = np.array([[clipped_area(polygon, origin[0] + i * h, origin[0] + (i + 1) * h,
                                       origin[1] + j * h, origin[1] + (j + 1) * h)
                          for j in range(n)] for i in range(n)])
    assert np.allclose(areas, expected, rtol=0.0, atol=1e-15)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_first_moments_match_clipping_every_square(seed: int) -> None:
    """Area and first moments about each square's centre (its covered part's centroid)."""
    polygon = _star(seed)
    segments = np.column_stack([polygon, np.roll(polygon, -1, axis=0)])
    h, n, origin = 0.1, 10, (0.03, -0.02)
    out = np.zeros((n, n, 3))
    segment_moments(segments, origin[0], origin[1], h, n, n, out)
    expected = np.array([[clipped_moments(polygon, origin[0] + i * h, origin[0] + (i + 1) * h,
                                          origin[1] + j * h, origin[1] + (j + 1) * h)
                          for j in range(n)] for i in range(n)])
    assert np.allclose(out, expected, rtol=0.0, atol=1e-15)


def test_an_edge_sliding_along_a_grid_line_changes_the_areas_linearly() -> None:
    """The case the segment fractions get wrong (docs/method_notes.md item 9): a rectangle's
    top edge moving up across the line y = 0.5 changes the squares' areas in proportion."""
    h, n = 0.125, 8
    previous = None
    for top in (0.5 - 1e-9, 0.5, 0.5 + 1e-9):
        rectangle = np.array([[0.3, 0.2], [0.7, 0.2], [0.7, top], [0.3, top]])
        areas = _areas(rectangle, h, n, (0.0, 0.0))
        if previous is not None:
            assert np.abs(areas - previous).max() <= 1.01e-9 * h + 1e-15
        previous = areas
    assert np.isclose(previous.sum(), 0.4 * (0.5 + 1e-9 - 0.2))


def test_a_hole_is_taken_out() -> None:
    outer = np.array([[0.1, 0.1], [0.9, 0.1], [0.9, 0.9], [0.1, 0.9]])
    hole = np.array([[0.3, 0.3], [0.3, 0.6], [0.6, 0.6], [0.6, 0.3]])  # clockwise
    points = np.vstack([outer, hole])
    edges = np.array([[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 7], [7, 4]])
    out = np.zeros((4, 4))
    polygon_areas(points, edges, 0.0, 0.0, 0.25, 4, 4, out)
    assert np.isclose(out.sum(), 0.64 - 0.09)
    assert np.isclose(out[1, 1], 0.25**2 - 0.2**2)  # square [0.25, 0.5]^2 minus the hole's part


def _rectangle_map(top: float):
    from elastoflow.coupling import build_boundary_map
    from elastoflow.grid import Grid2D

    grid = Grid2D(nx=16, ny=16, h=1.0 / 16)
    points = np.array([[0.3, 0.2], [0.7, 0.2], [0.7, top], [0.3, top]])
    edges = np.array([[0, 1], [1, 2], [2, 3], [3, 0]])
    bmap = build_boundary_map(grid, points, np.zeros_like(points), edges,
                              np.zeros(4, dtype=np.int64))
    return grid, bmap


def test_dual_cell_weights_change_continuously_where_segment_fractions_jump() -> None:
    """A body's top edge crossing the v-face line y = 0.5 (item 9's flip): the faces'
    segment fractions jump by the covered share of the face, the dual-cell weights move by
    the edge's travel over h; the centroid of the covered part lies inside the body."""
    from elastoflow.coupling import (
        V_FACES,
        dual_cover,
        interior_boundary_dual_cell,
        interior_boundary_from_map,
    )

    delta = 1e-7
    below, above = (_rectangle_map(0.5 + s * delta) for s in (-1.0, 1.0))
    segment_jump = np.abs(interior_boundary_from_map(*above).open_fraction_y
                          - interior_boundary_from_map(*below).open_fraction_y).max()
    dual_below, dual_above = (interior_boundary_dual_cell(*below),
                              interior_boundary_dual_cell(*above))
    dual_change = np.abs(dual_above.open_fraction_y - dual_below.open_fraction_y).max()
    assert segment_jump > 0.5
    assert dual_change <= 2.0 * delta * 16 * 1.01
    grid = below[0]
    cover = dual_cover(*above)
    centroids = cover.centroid
    assert np.all((centroids[:, 0] >= 0.3 - 1e-12) & (centroids[:, 0] <= 0.7 + 1e-12))
    assert np.all((centroids[:, 1] >= 0.2 - 1e-12) & (centroids[:, 1] <= 0.5 + delta))
    # The body's area is the dual cells' covered areas summed (each family tiles the plane
    # around the body), and the open fractions are what the cover leaves.
    area = 0.4 * (0.3 + delta)
    for family, open_fraction in ((V_FACES, dual_above.open_fraction_y),
                                  (1 - V_FACES, dual_above.open_fraction_x)):
        mine = cover.axis == family
        assert np.isclose(cover.share[mine].sum() * grid.h**2, area, rtol=1e-12)
        assert np.isclose(((1.0 - open_fraction) * grid.h**2).sum(), area, rtol=1e-12)
