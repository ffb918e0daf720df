"""A 3D state in perspective: a fixed picture size, the camera's projection, the body's shaded
surface where it projects, the slice's colours where the plane is seen, the same picture every
time, and one-line errors."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow.fluid import FluidState3D
from elastoflow.grid import Grid3D
from elastoflow.render import colormap_lut, render_scene_3d, scene_camera, scene_orientation
from elastoflow.render._scene3d import (
    BACKGROUND_COLOR,
    BODY_SURFACE_COLOR,
    OBSTACLE_SURFACE_COLOR,
    SCENE_SIZE,
    shade_triangles,
)
from elastoflow.solid import mesh_box

GRID = Grid3D(12, 8, 8, 0.125)
"""1.5 x 1 x 1 m."""
SIZE = (160, 120)


def _shear_state() -> FluidState3D:
    """u = x / 1.5 m/s along x: the speed grows from left to right, 0 to 1."""
    state = FluidState3D.zeros(GRID)
    state.velocity_x[...] = (np.arange(GRID.nx + 1) * GRID.h / 1.5)[:, None, None]
    return state


def _cube(low: tuple[float, float, float], side: float) -> tuple[np.ndarray, np.ndarray]:
    mesh = mesh_box((side, side, side), counts=(2, 2, 2), origin=low)
    return mesh.points, mesh.boundary_triangles


def _pixel(camera, point) -> tuple[int, int]:
    pixels, inverse = camera.project(np.array([point], dtype=np.float64))
    assert inverse[0] > 0.0
    return int(pixels[0, 1]), int(pixels[0, 0])


def test_the_picture_has_one_size_whatever_the_grid() -> None:
    image = render_scene_3d(GRID, _shear_state(), time=0.25)
    assert image.dtype == np.uint8 and image.shape[:2] == (SCENE_SIZE[1], image.shape[1])
    assert image.shape[1] > SCENE_SIZE[0] and image.shape[1] % 2 == 0
    other = Grid3D(6, 20, 4, 0.05)
    assert render_scene_3d(other, FluidState3D.zeros(other), axis="y").shape == image.shape
    odd = render_scene_3d(GRID, _shear_state(), size=(161, 121), colorbar=False)
    assert odd.shape == (122, 162, 3)


def test_the_camera_sees_the_whole_box_in_front_of_it() -> None:
    for axis in "xyz":
        camera = scene_camera(GRID, axis, SIZE)
        low = np.zeros(3)
        high = np.array([1.5, 1.0, 1.0])
        corners = np.array([[(low, high)[i][0], (low, high)[j][1], (low, high)[k][2]]
                            for i in (0, 1) for j in (0, 1) for k in (0, 1)])
        pixels, inverse = camera.project(corners)
        assert (inverse > 0.0).all()
        assert (pixels >= 0.0).all() and (pixels[:, 0] <= SIZE[0]).all()
        assert (pixels[:, 1] <= SIZE[1]).all()
        # The box's picture fills the frame along one side (margins of 4 %).
        span = pixels.max(axis=0) - pixels.min(axis=0)
        assert max(span[0] / SIZE[0], span[1] / SIZE[1]) == pytest.approx(0.92)
        # In front of the slice: the eye lies on the plane's + side, y up in the picture.
        assert camera.eye["xyz".index(axis)] > high["xyz".index(axis)]
        top, bottom = camera.project(np.array([[0.75, 1.0, 0.5], [0.75, 0.0, 0.5]]))[0]
        assert top[1] < bottom[1]


def test_the_slice_shows_the_flow_through_the_colour_map() -> None:
    state = _shear_state()
    image = render_scene_3d(GRID, state, axis="z", position=0.5, size=SIZE, colorbar=False,
                            value_range=(0.0, 1.0))
    camera = scene_camera(GRID, "z", SIZE)
    lut = colormap_lut("jet")
    for x in (0.06, 0.8, 1.44):
        color = image[_pixel(camera, (x, 0.5, 0.5))]
        # The cell's speed (u at its centre, x / 1.5) through the map, exactly.
        cell = int(x / GRID.h)
        speed = (cell + 0.5) * GRID.h / 1.5
        np.testing.assert_array_equal(color, lut[int(speed * 255.0)])
    # Off the plane (above the box) the background.
    np.testing.assert_array_equal(image[1, SIZE[0] // 2], BACKGROUND_COLOR)
    still = render_scene_3d(GRID, FluidState3D.zeros(GRID), axis="z", position=0.5, size=SIZE,
                            colorbar=False, value_range=(0.0, 1.0))
    np.testing.assert_array_equal(still[_pixel(camera, (0.75, 0.5, 0.5))], lut[0])


def test_the_body_is_drawn_shaded_where_it_projects_in_front_of_the_slice() -> None:
    state = _shear_state()
    cube = _cube((0.6, 0.4, 0.6), 0.2)
    camera = scene_camera(GRID, "z", SIZE)
    plain = render_scene_3d(GRID, state, size=SIZE, colorbar=False, value_range=(0.0, 1.0))
    image = render_scene_3d(GRID, state, size=SIZE, colorbar=False, value_range=(0.0, 1.0),
                            surfaces=[cube])
    colors = {tuple(c) for c in shade_triangles(camera, *cube, BODY_SURFACE_COLOR)}
    # The cube's front face's centre and a point of its top seen from above the plane.
    for point in ((0.7, 0.5, 0.8), (0.7, 0.6, 0.7)):
        pixel = _pixel(camera, point)
        assert tuple(image[pixel]) in colors
        assert tuple(plain[pixel]) not in colors
    changed = np.any(image != plain, axis=-1)
    pixels, _ = camera.project(cube[0])
    rows, cols = np.nonzero(changed)
    # Only pixels within the cube's projection change.
    assert rows.min() >= pixels[:, 1].min() - 1 and rows.max() <= pixels[:, 1].max() + 1
    assert cols.min() >= pixels[:, 0].min() - 1 and cols.max() <= pixels[:, 0].max() + 1
    # A cube behind the plane is hidden by it (the camera held in front); an obstacle takes the obstacle's colours.
    hidden = render_scene_3d(GRID, state, size=SIZE, colorbar=False, value_range=(0.0, 1.0),
                             surfaces=[_cube((0.6, 0.4, 0.1), 0.2)], azimuth=30.0,
                             elevation=20.0)
    np.testing.assert_array_equal(hidden[_pixel(camera, (0.7, 0.5, 0.5))],
                                  plain[_pixel(camera, (0.7, 0.5, 0.5))])
    obstacle = render_scene_3d(GRID, state, size=SIZE, colorbar=False,
                               value_range=(0.0, 1.0), obstacles=[cube])
    grey = {tuple(c) for c in shade_triangles(camera, *cube, OBSTACLE_SURFACE_COLOR)}
    assert tuple(obstacle[_pixel(camera, (0.7, 0.5, 0.8))]) in grey


def test_bodies_behind_the_slice_are_seen_from_the_other_side() -> None:
    state = _shear_state()
    behind = _cube((0.6, 0.4, 0.1), 0.2)
    assert scene_orientation("z", 0.5, [behind]) == (150.0, 20.0)
    assert scene_orientation("z", 0.5, [_cube((0.6, 0.4, 0.6), 0.2)]) == (30.0, 20.0)
    # A body the slice cuts shows from the default side, however little more lies behind.
    assert scene_orientation("z", 0.5, [_cube((0.6, 0.4, 0.39), 0.2)]) == (30.0, 20.0)
    assert scene_orientation("y", 0.9, [behind]) == (30.0, -50.0)
    assert scene_orientation("x", 1.4, [behind]) == (-65.0, 20.0)
    image = render_scene_3d(GRID, state, size=SIZE, colorbar=False, value_range=(0.0, 1.0),
                            surfaces=[behind])
    camera = scene_camera(GRID, "z", SIZE, azimuth=150.0, elevation=20.0)
    assert camera.eye[2] < 0.0
    colors = {tuple(c) for c in shade_triangles(camera, *behind, BODY_SURFACE_COLOR)}
    # The cube's face towards -z, now in front of the slice.
    assert tuple(image[_pixel(camera, (0.7, 0.5, 0.1))]) in colors


def test_the_same_input_gives_the_same_picture_also_drawn_into_an_old_one() -> None:
    state = _shear_state()
    cube = _cube((0.6, 0.4, 0.6), 0.2)
    kwargs = dict(axis="x", position=0.8, view="vorticity", surfaces=[cube], time=1.5)
    first = render_scene_3d(GRID, state, **kwargs)
    again = render_scene_3d(GRID, state, **kwargs)
    np.testing.assert_array_equal(first, again)
    old = render_scene_3d(GRID, FluidState3D.zeros(GRID), axis="y")
    reused = render_scene_3d(GRID, state, out=old, **kwargs)
    assert reused is old
    np.testing.assert_array_equal(reused, first)


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"axis": "w"}, "axis = 'w': must be one of x, y, z"),
    ({"position": 2.0}, "position = 2.0: the plane must cut the domain"),
    ({"size": (8, 8)}, "size = (8, 8): must be at least 16 x 16 pixels"),
])
def test_bad_arguments_are_refused_in_one_line(kwargs: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        render_scene_3d(GRID, FluidState3D.zeros(GRID), **kwargs)
