"""Reusing ``out`` resets and rescans only the region written last time: every array must
still equal, bit for bit, a fresh result built without ``out``."""

from __future__ import annotations

import numpy as np
import pytest
from coupling_polygons import polygon_edges

from elastoflow.coupling import build_boundary_map, interior_boundary_from_map
from elastoflow.fluid import InteriorBoundary
from elastoflow.grid import Grid2D

FIELDS = ("solid_cells", "solid_faces_x", "solid_faces_y", "velocity_faces_x",
          "velocity_faces_y", "open_fraction_x", "open_fraction_y", "cut_theta_x",
          "cut_theta_y", "cut_velocity_x", "cut_velocity_y")


def _body(center, time, radius, spin, wobble, count=23):
    """A wobbling ellipse, translated and rotated: points and velocities (finite difference)."""

    def points_at(t):
        angles = np.linspace(0.0, 2.0 * np.pi, count, endpoint=False)
        r = radius * (1.0 + wobble * np.sin(3.0 * angles + 5.0 * t))
        local = np.column_stack([1.3 * r * np.cos(angles), 0.8 * r * np.sin(angles)])
        c, s = np.cos(spin * t), np.sin(spin * t)
        rotated = local @ np.array([[c, s], [-s, c]])
        return rotated + np.asarray(center(t))

    step = 1e-4
    return points_at(time), (points_at(time + step) - points_at(time - step)) / (2.0 * step)


def _map(grid, bodies):
    points, velocities, edges, edge_body = [], [], [], []
    start = 0
    for index, (p, v) in enumerate(bodies):
        points.append(p)
        velocities.append(v)
        edges.append(polygon_edges(len(p), start))
        edge_body.append(np.full(len(p), index))
        start += len(p)
    if not points:
        empty = np.zeros((0, 2))
        return build_boundary_map(grid, empty, empty, np.zeros((0, 2), dtype=np.int64))
    return build_boundary_map(grid, np.concatenate(points), np.concatenate(velocities),
                              np.concatenate(edges), np.concatenate(edge_body))


def _assert_same(reused, fresh, step):
    for name in FIELDS:
        same = np.array_equal(getattr(reused, name), getattr(fresh, name))
        assert same, f"{name} differs from a fresh result at step {step}"


def _run(grid, bodies_at, steps, out=None):
    for step in range(steps):
        bmap = _map(grid, bodies_at(0.05 * step))
        fresh = interior_boundary_from_map(grid, bmap)
        reused = interior_boundary_from_map(grid, bmap, out=out)
        assert out is None or reused is out
        _assert_same(reused, fresh, step)
        out = reused
    return out


def test_moving_rotating_deforming_body_matches_a_fresh_result_every_step():
    grid = Grid2D(48, 40, 1.0 / 48.0)

    def bodies_at(t):
        return [_body(lambda s: (0.25 + 0.9 * s, 0.35 + 0.3 * s), t, 0.09, 4.0, 0.15)]

    _run(grid, bodies_at, 12)


def test_two_bodies_one_leaving_a_region_the_other_never_touched():
    grid = Grid2D(48, 48, 1.0 / 48.0)

    def bodies_at(t):
        # The first sweeps from the lower left to the upper right; the second stays put; both
        # vanish in the last steps (an empty map must clear everything).
        if t > 0.5:
            return []
        return [
            _body(lambda s: (0.2 + 1.2 * s, 0.2 + 1.0 * s), t, 0.08, -3.0, 0.2),
            _body(lambda s: (0.75, 0.25), t, 0.07, 1.0, 0.1),
        ]

    _run(grid, bodies_at, 14)


def test_body_crossing_the_domain_edge_matches_a_fresh_result():
    grid = Grid2D(40, 32, 1.0 / 40.0, origin=(0.1, -0.05))

    def bodies_at(t):
        # Leaves through the left edge and comes back through the bottom one.
        return [_body(lambda s: (0.2 - 0.9 * s, 0.3 - 1.2 * s * s), t, 0.12, 2.0, 0.1),
                _body(lambda s: (1.05, 0.4 + 0.5 * s), t, 0.1, 0.5, 0.05)]

    _run(grid, bodies_at, 12)


def test_out_not_made_by_this_function_is_reset_everywhere():
    grid = Grid2D(24, 24, 1.0 / 24.0)
    out = InteriorBoundary.empty(grid)
    rng = np.random.default_rng(3)
    for name in FIELDS:
        array = getattr(out, name)
        array[...] = rng.random(array.shape) < 0.5 if array.dtype == bool \
            else rng.random(array.shape)
    bodies = [_body(lambda s: (0.5, 0.5), 0.0, 0.1, 0.0, 0.0)]
    bmap = _map(grid, bodies)
    _assert_same(interior_boundary_from_map(grid, bmap, out=out),
                 interior_boundary_from_map(grid, bmap), 0)


@pytest.mark.parametrize("reverse", [False, True])
def test_open_chain_filling_to_the_line_end_is_cleared_next_step(reverse):
    # An open polyline leaves a non-zero winding at the end of its rows: the fill runs to the
    # domain edge, far outside the chain's bounding box.
    grid = Grid2D(32, 32, 1.0 / 32.0)
    points = np.array([[0.3, 0.2], [0.35, 0.5], [0.3, 0.7]])
    if reverse:
        points = points[::-1].copy()
    velocities = np.ones_like(points)
    chain = build_boundary_map(grid, points, velocities, np.array([[0, 1], [1, 2]]))
    fresh = interior_boundary_from_map(grid, chain)
    assert fresh.solid_faces_x[-1].any()
    out = interior_boundary_from_map(grid, chain)
    bodies = [_body(lambda s: (0.7, 0.3), 0.0, 0.1, 0.0, 0.1)]
    bmap = _map(grid, bodies)
    _assert_same(interior_boundary_from_map(grid, bmap, out=out),
                 interior_boundary_from_map(grid, bmap), 0)


@pytest.mark.parametrize("chain_body", [0, 1, 1000])
def test_open_chain_span_over_another_body_is_charged_and_cleared(chain_body):
    # Every row of the chain meets the closed body of another id further on: the rows fill
    # from the chain to the body and on to the domain edge, and the span between them must
    # count as written (a body id of 1000, beyond the number of edges, takes the one-box path).
    grid = Grid2D(32, 32, 1.0 / 32.0)
    chain = np.array([[0.2, 0.47], [0.22, 0.5], [0.2, 0.53]])
    closed, closed_velocities = _body(lambda s: (0.6, 0.5), 0.0, 0.08, 0.0, 0.1)
    points = np.concatenate([chain, closed])
    velocities = np.concatenate([np.full_like(chain, 0.5), closed_velocities])
    edges = np.concatenate([np.array([[0, 1], [1, 2]]), polygon_edges(len(closed), 3)])
    edge_body = np.concatenate([[chain_body, chain_body], np.full(len(closed), 2)])
    mixed = build_boundary_map(grid, points, velocities, edges, edge_body)
    out = interior_boundary_from_map(grid, mixed)
    assert out.solid_cells[10:16, 16].all()
    for step, bodies in enumerate(([_body(lambda s: (0.6, 0.5), 0.0, 0.08, 0.0, 0.1)],
                                   [_body(lambda s: (0.3, 0.3), 0.0, 0.05, 0.0, 0.0)], [])):
        bmap = _map(grid, bodies)
        _assert_same(interior_boundary_from_map(grid, bmap, out=out),
                     interior_boundary_from_map(grid, bmap), step)
