"""What the 3D viewer adds to a slice: a closed surface's section (closed loops, filled by the
even-odd rule), its outline seen along the normal, and the layer's values computed on the
layer alone (the same numbers as `slice_values`)."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow.fluid import FluidState3D
from elastoflow.grid import Grid3D
from elastoflow.render import OBSTACLE_FILL_COLOR
from elastoflow.render._slice3d import (
    SILHOUETTE_COLOR,
    VIEWS_3D,
    fill_segments,
    layer_values,
    render_slice_3d,
    slice_values,
    surface_section,
    surface_silhouette,
)
from elastoflow.solid import mesh_box, mesh_sphere


def _loops_close(starts: np.ndarray, ends: np.ndarray) -> bool:
    """Every segment end is some segment's start (to the bit): closed loops."""
    begin = {tuple(p) for p in starts.tolist()}
    return all(tuple(p) in begin for p in ends.tolist()) and len(begin) == len(starts)


def test_the_section_of_a_closed_surface_is_closed_loops_of_its_outline() -> None:
    box = mesh_box((0.3, 0.2, 0.1), counts=(3, 2, 2), origin=(0.1, 0.1, 0.1))
    starts, ends = surface_section(box.points, box.boundary_triangles, 2, 0.137)
    assert _loops_close(starts, ends)
    perimeter = np.linalg.norm(ends - starts, axis=1).sum()
    assert perimeter == pytest.approx(2 * (0.3 + 0.2), rel=1e-12)
    # Counter-clockwise: the shoelace sum is the section's area.
    area = 0.5 * (starts[:, 0] * ends[:, 1] - ends[:, 0] * starts[:, 1]).sum()
    assert area == pytest.approx(0.3 * 0.2, rel=1e-12)
    for axis, position, expected in ((0, 0.25, 0.2 * 0.1), (1, 0.15, 0.3 * 0.1)):
        starts, ends = surface_section(box.points, box.boundary_triangles, axis, position)
        area = 0.5 * (starts[:, 0] * ends[:, 1] - ends[:, 0] * starts[:, 1]).sum()
        assert area == pytest.approx(expected, rel=1e-12)
    sphere = mesh_sphere(0.2, element_size=0.05)
    starts, ends = surface_section(sphere.points, sphere.boundary_triangles, 0, 0.05)
    assert _loops_close(starts, ends)
    radius = np.linalg.norm(starts, axis=1)
    assert radius.max() <= np.sqrt(0.2**2 - 0.05**2) + 1e-12 and radius.min() > 0.17
    starts, ends = surface_section(box.points, box.boundary_triangles, 2, 0.5)
    assert starts.shape == ends.shape == (0, 2)


def test_fill_segments_fills_the_inside_of_the_loops() -> None:
    image = np.zeros((40, 40, 3), dtype=np.uint8)
    square = np.array([[5.0, 5.0], [25.0, 5.0], [25.0, 25.0], [5.0, 25.0]])
    hole = np.array([[10.0, 10.0], [10.0, 20.0], [20.0, 20.0], [20.0, 10.0]])
    starts = np.concatenate((square, hole))
    ends = np.concatenate((np.roll(square, -1, axis=0), np.roll(hole, -1, axis=0)))
    order = np.random.default_rng(0).permutation(len(starts))  # any order
    fill_segments(image, starts[order], ends[order], OBSTACLE_FILL_COLOR)
    painted = np.all(image == OBSTACLE_FILL_COLOR, axis=-1)
    assert painted.sum() == 20 * 20 - 10 * 10
    assert painted[7, 7] and not painted[15, 15] and not painted[30, 30]


def test_the_silhouette_is_the_outline_seen_along_the_axis() -> None:
    box = mesh_box((0.3, 0.2, 0.1), counts=(3, 2, 2), origin=(0.1, 0.1, 0.1))
    starts, ends = surface_silhouette(box.points, box.boundary_triangles, 2)
    assert np.linalg.norm(ends - starts, axis=1).sum() == pytest.approx(1.0, rel=1e-12)
    sphere = mesh_sphere(0.2, element_size=0.05)
    for axis in range(3):
        starts, ends = surface_silhouette(sphere.points, sphere.boundary_triangles, axis)
        radius = np.linalg.norm(np.concatenate((starts, ends)), axis=1)
        assert radius.max() <= 0.2 + 1e-12 and radius.min() > 0.17
        assert np.linalg.norm(ends - starts, axis=1).sum() == pytest.approx(
            2 * np.pi * 0.2, rel=0.1)


def _random_state(grid: Grid3D) -> FluidState3D:
    rng = np.random.default_rng(1)
    state = FluidState3D.zeros(grid)
    for array in (state.velocity_x, state.velocity_y, state.velocity_z, state.pressure,
                  state.dye):
        array[...] = rng.standard_normal(array.shape)
    return state


def test_layer_values_are_slice_values_to_the_bit() -> None:
    grid = Grid3D(6, 5, 4, 0.1)
    state = _random_state(grid)
    for view in VIEWS_3D:
        for axis in range(3):
            for index in range(grid.shape_cells[axis]):
                np.testing.assert_array_equal(
                    layer_values(grid, state, axis, index, view),
                    slice_values(grid, state, axis, index, view))
    with pytest.raises(ValueError, match="slice index"):
        layer_values(grid, state, 0, 6, "speed")


def test_render_slice_3d_draws_the_obstacles_and_the_surfaces_outlines() -> None:
    grid = Grid3D(8, 8, 8, 0.1, origin=(-0.4, -0.4, -0.4))
    state = FluidState3D.zeros(grid)
    sphere = mesh_sphere(0.2, element_size=0.05)
    plain = render_slice_3d(grid, state, axis="z", scale=4, colorbar=False)
    with_none = render_slice_3d(grid, state, axis="z", scale=4, colorbar=False, obstacles=(),
                                surfaces=(), values=slice_values(grid, state, 2, 4, "speed"))
    np.testing.assert_array_equal(plain, with_none)
    image = render_slice_3d(grid, state, axis="z", position=0.05, scale=4, colorbar=False,
                            obstacles=[(sphere.points, sphere.boundary_triangles)])
    assert tuple(image[16, 16]) == tuple(OBSTACLE_FILL_COLOR)
    # Off the plane, a body's surface shows as its outline alone.
    body = (sphere.points + [0.0, 0.0, 0.3], sphere.boundary_triangles)
    image = render_slice_3d(grid, state, axis="z", position=-0.2, scale=4, colorbar=False,
                            surfaces=[body])
    outline = np.all(image == SILHOUETTE_COLOR, axis=-1)
    rows, cols = np.nonzero(outline)
    assert 0.3 * 40 < cols.max() - cols.min() + 1 <= 0.4 * 40 + 1
