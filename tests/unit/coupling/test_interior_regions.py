"""``InteriorBoundary.regions`` from the coupling: outside its boxes every array holds the
empty state, the boxes stay tight around the bodies, and reusing ``out`` keeps them right."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from coupling_polygons import H, polygon_edges, segments_intersect, star_polygon
from hypothesis import assume, given, note, settings
from hypothesis import strategies as st

from elastoflow.coupling import build_boundary_map, classify_points, interior_boundary_from_map
from elastoflow.fluid import InteriorBoundary
from elastoflow.grid import Grid2D

EMPTY_STATE = (("solid_cells", False), ("solid_faces_x", False), ("solid_faces_y", False),
               ("velocity_faces_x", 0.0), ("velocity_faces_y", 0.0), ("open_fraction_x", 1.0),
               ("open_fraction_y", 1.0), ("cut_theta_x", np.inf), ("cut_theta_y", np.inf),
               ("cut_velocity_x", 0.0), ("cut_velocity_y", 0.0))


def _outside(regions: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Indices (i, j) of an array of ``shape`` in no box, bool."""
    i = np.arange(shape[0])[:, None]
    j = np.arange(shape[1])[None, :]
    inside = np.zeros(shape, dtype=bool)
    for i_begin, i_end, j_begin, j_end in regions:
        inside |= (i >= i_begin) & (i < i_end) & (j >= j_begin) & (j < j_end)
    return ~inside


def assert_empty_outside_regions(interior: InteriorBoundary) -> None:
    """Every array holds the empty state at every index outside ``interior.regions``."""
    regions = interior.regions
    assert regions is not None and regions.dtype == np.int64 and regions.shape[1] == 4
    for name, value in EMPTY_STATE:
        array = getattr(interior, name)
        outside = _outside(regions, array.shape[-2:])
        values = array[..., outside]
        assert np.all(values == value), f"{name} not empty outside the regions"


def _map(grid: Grid2D, polygons: list[np.ndarray], velocity=(0.3, -0.2)):
    if not polygons:
        empty = np.zeros((0, 2))
        return build_boundary_map(grid, empty, empty, np.zeros((0, 2), dtype=np.int64))
    points = np.concatenate(polygons)
    starts = np.cumsum([0] + [len(p) for p in polygons])
    edges = np.concatenate([polygon_edges(len(p), s) for p, s in zip(polygons, starts)])
    edge_body = np.concatenate([np.full(len(p), k) for k, p in enumerate(polygons)])
    velocities = np.broadcast_to(np.asarray(velocity), points.shape).copy()
    return build_boundary_map(grid, points, velocities, edges, edge_body)


def _ellipse(center, radius, count=19, turn=0.0):
    angles = np.linspace(0.0, 2.0 * np.pi, count, endpoint=False) + turn
    return np.column_stack([center[0] + 1.4 * radius * np.cos(angles),
                            center[1] + 0.7 * radius * np.sin(angles)])


@settings(max_examples=25, deadline=None)
@given(data=st.data(), count=st.integers(1, 3))
def test_arrays_are_empty_outside_tight_regions(data, count):
    # Centres up to beyond the domain: bodies crossing an edge get boxes clipped to the grid.
    grid = Grid2D(32, 32, H)
    polygons = []
    for k in range(count):
        low, high = (0.05, 0.95) if k == 0 else (-0.1, 1.1)
        polygon = data.draw(star_polygon((low, high), (low, high), 0.03, 0.15, grid.origin))
        assume(not segments_intersect(polygon))
        polygons.append(polygon)
    note(repr([p.tolist() for p in polygons]))
    interior = interior_boundary_from_map(grid, _map(grid, polygons))
    assert_empty_outside_regions(interior)
    # Tight: the boxes lie within the bodies' bounding box plus a few spacings (overlapping
    # bodies may charge a span between them to either one).
    corners = np.concatenate(polygons)
    low = np.floor(corners.min(axis=0) / H) - 4
    high = np.ceil(corners.max(axis=0) / H) + 5
    for i_begin, i_end, j_begin, j_end in interior.regions:
        assert i_begin >= low[0] and i_end <= high[0] and j_begin >= low[1] and j_end <= high[1]


def test_reused_out_keeps_its_identity_and_the_guarantee_while_bodies_move():
    grid = Grid2D(40, 36, 1.0 / 40.0)
    out = None
    for step in range(10):
        t = 0.1 * step
        polygons = [_ellipse((0.2 + 0.6 * t, 0.5), 0.1, turn=2.0 * t)]
        if step < 6:
            # Leaves through the bottom edge, then is gone: fewer boxes than rows.
            polygons.append(_ellipse((0.7, 0.15 - 0.12 * step), 0.08))
        bmap = _map(grid, polygons)
        reused = interior_boundary_from_map(grid, bmap, out=out)
        if out is not None:
            assert reused is out
        assert_empty_outside_regions(reused)
        fresh = interior_boundary_from_map(grid, bmap)
        for name, _ in EMPTY_STATE:
            assert np.array_equal(getattr(reused, name), getattr(fresh, name)), (name, step)
        out = reused
    assert np.all(out.regions[1] == 0)


def test_more_bodies_than_rows_give_a_new_object_sharing_the_arrays():
    grid = Grid2D(32, 32, H)
    out = interior_boundary_from_map(grid, _map(grid, [_ellipse((0.3, 0.3), 0.08)]))
    old_regions = out.regions.copy()
    two = _map(grid, [_ellipse((0.7, 0.7), 0.08), _ellipse((0.3, 0.7), 0.08)])
    result = interior_boundary_from_map(grid, two, out=out)
    assert result is not out
    assert result.solid_cells is out.solid_cells and result.cut_theta_y is out.cut_theta_y
    assert result.regions.shape == (2, 4)
    assert np.array_equal(out.regions, old_regions)
    assert_empty_outside_regions(result)


def test_hand_filled_out_without_regions_is_reset_everywhere():
    grid = Grid2D(24, 20, 1.0 / 24.0)
    out = InteriorBoundary.empty(grid)
    assert out.regions is None
    out.solid_cells[0, 0] = True
    out.cut_theta_x[2, -1, -1] = 0.5
    out.open_fraction_y[-1, 0] = 0.0
    result = interior_boundary_from_map(grid, _map(grid, [_ellipse((0.5, 0.5), 0.1)]), out=out)
    assert_empty_outside_regions(result)
    assert not result.solid_cells[0, 0] and result.open_fraction_y[-1, 0] == 1.0


def test_given_classification_counts_as_the_whole_grid():
    grid = Grid2D(20, 16, 0.05)
    bmap = _map(grid, [_ellipse((0.5, 0.4), 0.1)])
    interior = interior_boundary_from_map(grid, bmap, classify_points(grid, bmap))
    assert interior.regions.tolist() == [[0, grid.nx + 1, 0, grid.ny + 1]]


def test_empty_map_has_no_region():
    grid = Grid2D(12, 10, 0.1)
    interior = interior_boundary_from_map(grid, _map(grid, []))
    assert interior.regions.shape == (0, 4)
    assert_empty_outside_regions(interior)


@pytest.mark.parametrize("regions", [np.zeros((2, 3), dtype=np.int64),
                                     np.zeros((2, 4), dtype=np.int32), [[0, 1, 0, 1]]])
def test_check_rejects_malformed_regions(regions):
    grid = Grid2D(8, 6, 0.1)
    interior = dataclasses.replace(InteriorBoundary.empty(grid), regions=regions)
    with pytest.raises(ValueError, match="InteriorBoundary.regions"):
        interior.check(grid)
