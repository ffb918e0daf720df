"""A 3D state through a plane: the cell layer's values, the curl's normal component, the bodies'
exact cross-sections, and one-line errors."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow.fluid import FluidState3D
from elastoflow.grid import Grid3D
from elastoflow.render import BODY_FILL_COLOR
from elastoflow.render._slice3d import render_slice_3d, slice_values, tetrahedra_section
from elastoflow.solid import mesh_box, mesh_sphere

GRID = Grid3D(8, 6, 5, 0.1)


def _rotating_state(omega: float = 2.0) -> FluidState3D:
    """Solid-body rotation about z through (0.4, 0.3), pressure = x + 10 y + 100 z."""
    state = FluidState3D.zeros(GRID)
    h = GRID.h
    state.velocity_x[...] = -omega * ((np.arange(GRID.ny) + 0.5) * h - 0.3)[None, :, None]
    state.velocity_y[...] = omega * ((np.arange(GRID.nx) + 0.5) * h - 0.4)[:, None, None]
    x, y, z = np.meshgrid(*((np.arange(n) + 0.5) * h for n in GRID.shape_cells), indexing="ij")
    state.pressure[...] = x + 10.0 * y + 100.0 * z
    return state


def test_slices_take_the_cell_layer_in_the_other_axes_order() -> None:
    state = _rotating_state()
    z_slice = slice_values(GRID, state, 2, 3, "pressure")
    x_slice = slice_values(GRID, state, 0, 1, "pressure")
    assert z_slice.shape == (8, 6) and x_slice.shape == (6, 5)
    np.testing.assert_allclose(z_slice, state.pressure[:, :, 3])
    np.testing.assert_allclose(x_slice, state.pressure[1])
    # The rotation's vorticity is 2 omega along z, none across it.
    np.testing.assert_allclose(slice_values(GRID, state, 2, 0, "vorticity"), 4.0, atol=1e-12)
    np.testing.assert_allclose(slice_values(GRID, state, 0, 4, "vorticity"), 0.0, atol=1e-12)
    speed = slice_values(GRID, state, 2, 2, "speed")
    assert speed.min() >= 0.0 and speed.max() > 0.5


def _area(points: np.ndarray, triangles: np.ndarray) -> float:
    a, b, c = (points[triangles[:, k]] for k in range(3))
    return float(np.abs(0.5 * ((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])).sum())


def test_the_section_of_a_box_and_of_a_sphere_has_their_area() -> None:
    box = mesh_box((0.3, 0.2, 0.1), counts=(3, 2, 2), origin=(0.1, 0.1, 0.1))
    for axis, position, area in ((2, 0.137, 0.3 * 0.2), (0, 0.25, 0.2 * 0.1)):
        points, triangles = tetrahedra_section(box.points, box.tetrahedra, axis, position)
        assert _area(points, triangles) == pytest.approx(area, rel=1e-12)
    points, triangles = tetrahedra_section(box.points, box.tetrahedra, 2, 0.5)
    assert points.shape == (0, 2) and triangles.shape == (0, 3)
    sphere = mesh_sphere(0.2, element_size=0.05)
    points, triangles = tetrahedra_section(sphere.points, sphere.tetrahedra, 1, 0.05)
    area = _area(points, triangles)
    # The faceted sphere's section is a polygon inside the circle of radius sqrt(0.2^2 - 0.05^2).
    circle = np.pi * (0.2**2 - 0.05**2)
    assert 0.9 * circle < area <= circle


def test_frame_shows_the_field_and_fills_the_section() -> None:
    state = _rotating_state()
    box = mesh_box((0.2, 0.2, 0.2), counts=(2, 2, 2), origin=(0.3, 0.2, 0.15))
    image = render_slice_3d(GRID, state, axis="z", view="speed", time=0.5, scale=10,
                            bodies=[(box.points, box.tetrahedra)])
    assert image.dtype == np.uint8 and image.shape[0] == 60 and image.shape[1] > 80
    # Pixel of the box's middle (x = 0.4 m, y = 0.3 m): the body colour.
    row, column = 60 - int(0.3 / 0.1 * 10), int(0.4 / 0.1 * 10)
    np.testing.assert_array_equal(image[row, column], BODY_FILL_COLOR)
    plain = render_slice_3d(GRID, state, axis="x", position=0.05, view="pressure", scale=10,
                            colorbar=False)
    assert plain.shape[:2] == (50, 60)


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"axis": "w"}, "axis = 'w'"),
    ({"view": "temperature"}, "view = 'temperature'"),
    ({"axis": "y", "position": 2.0}, "position = 2.0"),
])
def test_bad_arguments_are_refused_in_one_line(kwargs, message) -> None:
    with pytest.raises(ValueError, match=message.replace("(", r"\(")):
        render_slice_3d(GRID, FluidState3D.zeros(GRID), **kwargs)
