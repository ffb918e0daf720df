"""The 3D viewer headless (SDL dummy driver): every key, the push within the plane, what the
picture shows, and the background stepping."""

# ruff: noqa: E402 - the SDL drivers are set, and pygame skipped if missing, before the imports

from __future__ import annotations

import os
import time

import numpy as np
import pytest

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
pygame = pytest.importorskip("pygame")
pytest.importorskip("elastoflow.simulation")

from elastoflow.render import BODY_FILL_COLOR, OBSTACLE_FILL_COLOR
from elastoflow.render._slice3d import SILHOUETTE_COLOR
from elastoflow.scenes import parse_scene
from elastoflow.viewer import HELP_3D, Viewer3D, run_viewer

SCALE = 8
_SCENE = {
    "name": "viewer_test_3d",
    "domain": {"lx": 1.0, "ly": 0.5, "lz": 0.5, "nx": 16},
    "fluid": {"density": 1000.0, "viscosity": 1e-3},
    "boundaries": {"left": {"type": "inflow", "speed": 0.05}, "right": "outflow"},
    "obstacles": [{"shape": "sphere", "center": (0.25, 0.25, 0.25), "radius": 0.12}],
    "bodies": [{
        "shape": {"type": "box", "box": (0.55, 0.1, 0.18, 0.7, 0.4, 0.32),
                  "divisions": (1, 3, 1)},
        "material": {"density": 2000.0, "young_modulus": 1e4, "poisson_ratio": 0.3},
        "fixed": {"box": (0.54, 0.39, 0.18, 0.71, 0.41, 0.32)},
    }],
    "time": {"dt": 0.02, "steps": 10},
}


@pytest.fixture(scope="module")
def scene():
    return parse_scene(_SCENE)


@pytest.fixture(scope="module")
def viewer(scene, tmp_path_factory) -> Viewer3D:
    pygame.init()
    yield Viewer3D(scene, scale=SCALE, screenshot_dir=tmp_path_factory.mktemp("shots"))
    pygame.quit()


def _key(key: int) -> pygame.event.Event:
    return pygame.event.Event(pygame.KEYDOWN, key=key)


def _reset(viewer: Viewer3D) -> None:
    """A new run, stepping, each axis's plane through the middle layer, across z."""
    viewer.handle_event(_key(pygame.K_r))
    viewer.paused = False
    for axis in "xyz":
        viewer.set_axis(axis)
        viewer.move_slice(viewer.layer_count // 2 - viewer.layer)


def test_keys_pause_step_cycle_view_reset_screenshot_and_quit(viewer: Viewer3D) -> None:
    _reset(viewer)
    viewer.update()
    assert viewer.simulation.step_index == 1 and viewer.simulation.dimension == 3
    viewer.handle_event(_key(pygame.K_SPACE))
    assert viewer.paused
    viewer.update()
    assert viewer.simulation.step_index == 1
    viewer.handle_event(_key(pygame.K_s))
    viewer.update()
    viewer.update()
    assert viewer.simulation.step_index == 2
    seen = {viewer.view}
    for _ in range(3):
        viewer.handle_event(_key(pygame.K_v))
        seen.add(viewer.view)
    assert seen == {"speed", "vorticity", "dye", "pressure"}
    viewer.handle_event(_key(pygame.K_h))
    assert viewer.show_help
    viewer.draw()
    viewer.handle_event(_key(pygame.K_h))
    assert not viewer.show_help
    viewer.handle_event(_key(pygame.K_r))
    assert viewer.simulation.step_index == 0
    viewer.handle_event(_key(pygame.K_p))
    assert viewer.last_screenshot is not None and viewer.last_screenshot.exists()
    viewer.handle_event(_key(pygame.K_q))
    assert not viewer.running
    viewer.running = True


def test_keys_and_wheel_turn_and_move_the_slice(viewer: Viewer3D) -> None:
    _reset(viewer)
    assert (viewer.axis, viewer.layer, viewer.layer_count) == ("z", 4, 8)
    viewer.handle_event(_key(pygame.K_UP))
    assert viewer.layer == 5
    assert viewer.slice_position == pytest.approx(5.5 * viewer.simulation.grid.h)
    viewer.handle_event(_key(pygame.K_DOWN))
    viewer.handle_event(_key(pygame.K_DOWN))
    assert viewer.layer == 3
    viewer.handle_event(_key(pygame.K_PAGEDOWN))
    assert viewer.layer == 2
    for _ in range(10):
        viewer.handle_event(_key(pygame.K_PAGEDOWN))
    assert viewer.layer == 0
    viewer.handle_event(pygame.event.Event(pygame.MOUSEWHEEL, x=0, y=3))
    assert viewer.layer == 3
    viewer.handle_event(_key(pygame.K_x))
    assert (viewer.axis, viewer.layer, viewer.layer_count) == ("x", 8, 16)
    viewer.handle_event(_key(pygame.K_PAGEUP))
    assert viewer.layer == 10
    for _ in range(20):
        viewer.handle_event(_key(pygame.K_UP))
    assert viewer.layer == 15
    viewer.handle_event(_key(pygame.K_y))
    assert (viewer.axis, viewer.layer) == ("y", 4)
    viewer.handle_event(_key(pygame.K_z))
    assert (viewer.axis, viewer.layer) == ("z", 3)  # each axis keeps its own layer
    with pytest.raises(ValueError, match="axis"):
        viewer.set_axis("w")


def test_pixels_map_to_the_plane_of_each_axis(viewer: Viewer3D) -> None:
    _reset(viewer)
    h = viewer.simulation.grid.h
    np.testing.assert_allclose(viewer.to_world((8.0, 64.0 - 16.0)), [h, 2 * h, 4.5 * h])
    viewer.set_axis("x")
    np.testing.assert_allclose(viewer.to_world((8.0, 64.0 - 16.0)), [8.5 * h, h, 2 * h])
    viewer.set_axis("y")
    np.testing.assert_allclose(viewer.to_world((8.0, 64.0 - 16.0)), [h, 4.5 * h, 2 * h])
    assert viewer.on_plane((127, 63)) and not viewer.on_plane((128, 10))


def test_left_drag_pushes_the_fluid_within_the_plane(viewer: Viewer3D) -> None:
    _reset(viewer)
    fluid = viewer.simulation.state.fluid
    for array in (fluid.velocity_x, fluid.velocity_y, fluid.velocity_z, fluid.dye):
        array[...] = 0.0
    start, end = (20, 40), (28, 40)  # pixels: a drag to the right near (0.2, 0.19) m
    viewer.handle_event(pygame.event.Event(pygame.MOUSEBUTTONDOWN, button=1, pos=start))
    viewer.handle_event(pygame.event.Event(pygame.MOUSEMOTION, pos=end, rel=(8, 0),
                                           buttons=(1, 0, 0)))
    viewer.handle_event(pygame.event.Event(pygame.MOUSEBUTTONUP, button=1, pos=end))
    assert fluid.velocity_x.max() > 0.0 and fluid.velocity_x.min() >= 0.0
    assert np.abs(fluid.velocity_y).max() == 0.0 and np.abs(fluid.velocity_z).max() == 0.0
    h = viewer.simulation.grid.h
    near = viewer.to_world(end)
    i, j, k = round(near[0] / h), int(near[1] / h), int(near[2] / h)
    assert k == viewer.layer
    assert fluid.velocity_x[i, j, k] == fluid.velocity_x.max()
    assert fluid.dye[int(near[0] / h), j, k] == pytest.approx(fluid.dye.max())
    # Within a few cells only.
    assert fluid.velocity_x[:, :, 0].max() < fluid.velocity_x[:, :, k].max()
    assert fluid.velocity_x[-1].max() == 0.0
    # A drag across the colour bar or the overview pushes nothing; a right click says why.
    before = fluid.velocity_x.copy()
    outside = (300, 40)
    viewer.handle_event(pygame.event.Event(pygame.MOUSEBUTTONDOWN, button=1, pos=outside))
    viewer.handle_event(pygame.event.Event(pygame.MOUSEMOTION, pos=(310, 40), rel=(10, 0),
                                           buttons=(1, 0, 0)))
    viewer.handle_event(pygame.event.Event(pygame.MOUSEBUTTONUP, button=1, pos=(310, 40)))
    np.testing.assert_array_equal(fluid.velocity_x, before)
    viewer.handle_event(pygame.event.Event(pygame.MOUSEBUTTONDOWN, button=3, pos=start))
    assert "2D only" in viewer.message
    assert any("not available in 3D" in line for line in HELP_3D)


def _pixel(pixels: np.ndarray, viewer: Viewer3D, point: tuple[float, float]) -> tuple:
    """The colour at in-plane point [m] (x, y on a z-slice); pixels (W, H, 3)."""
    h = viewer.simulation.grid.h
    return tuple(pixels[int(point[0] / h * SCALE), int(viewer.plane_height - point[1] / h * SCALE)])


def test_draw_shows_the_sections_the_outlines_and_the_overview(viewer: Viewer3D) -> None:
    _reset(viewer)
    surface = viewer.draw()
    image = viewer.frame()
    assert surface.get_size() == (image.shape[1], image.shape[0])
    assert image.shape[1] >= 16 * SCALE + viewer.overview.size
    pixels = pygame.surfarray.array3d(surface)  # (W, H, 3)
    assert _pixel(pixels, viewer, (0.25, 0.25)) == tuple(OBSTACLE_FILL_COLOR)
    assert _pixel(pixels, viewer, (0.62, 0.25)) == tuple(BODY_FILL_COLOR)
    assert "z = 0.2812 m (layer 5/8)" in viewer.status()
    # A plane past the body and the sphere: no section, their outlines seen along z.
    viewer.move_slice(3)
    field = viewer.frame()[:viewer.plane_height, :viewer.plane_width]
    assert not np.all(field == BODY_FILL_COLOR, axis=-1).any()
    magenta = np.all(field == SILHOUETTE_COLOR, axis=-1)
    rows, cols = np.nonzero(magenta)
    assert rows.size > 0
    h = viewer.simulation.grid.h
    assert cols.min() / SCALE * h == pytest.approx(0.25 - 0.12, abs=h)
    assert (cols.max() + 1) / SCALE * h == pytest.approx(0.70, abs=h)
    # The overview panel holds the shaded surfaces.
    panel = viewer.frame()[:viewer.overview.size, -viewer.overview.size:]
    assert len(np.unique(panel.reshape(-1, 3), axis=0)) > 10


def test_the_picture_key_changes_with_what_is_shown(viewer: Viewer3D) -> None:
    _reset(viewer)
    first = viewer.picture_key()
    assert viewer.picture_key() == first
    viewer.move_slice(1)
    assert viewer.picture_key() != first
    second = viewer.picture_key()
    viewer.update()
    assert viewer.picture_key() != second


def test_background_stepping_steps_and_applies_queued_pushes(viewer: Viewer3D) -> None:
    _reset(viewer)
    viewer.draw()
    if not viewer.start_stepping():
        pytest.skip("Numba's threading layer is not thread-safe here: steps stay in update")
    try:
        assert viewer.stepping_in_background
        viewer.update()  # the thread steps: update leaves it alone
        deadline = time.monotonic() + 60.0
        while viewer.simulation.step_index < 2 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert viewer.simulation.step_index >= 2
        viewer.handle_event(_key(pygame.K_SPACE))
        edits = viewer.edits
        viewer.handle_event(pygame.event.Event(pygame.MOUSEBUTTONDOWN, button=1, pos=(20, 40)))
        viewer.handle_event(pygame.event.Event(pygame.MOUSEMOTION, pos=(28, 40), rel=(8, 0),
                                               buttons=(1, 0, 0)))
        deadline = time.monotonic() + 60.0
        while viewer.edits == edits and time.monotonic() < deadline:
            time.sleep(0.01)
        assert viewer.edits == edits + 1
    finally:
        viewer.stop_stepping()
    assert not viewer.stepping_in_background


def test_the_overview_lays_the_slice_on_its_plane_behind_what_is_in_front() -> None:
    from elastoflow.grid import Grid3D
    from elastoflow.solid import mesh_box
    from elastoflow.viewer._overview import Overview

    overview = Overview(Grid3D(8, 8, 8, 0.1), 200)
    image = np.empty((200, 200, 3), dtype=np.uint8)
    red = np.zeros((32, 32, 3), dtype=np.uint8)
    red[..., 0] = 255
    overview.draw(image, 2, 0.4, picture=red)
    pixels, _ = overview.to_pixels(np.array([[0.4, 0.4, 0.4]]))
    col, row = pixels[0]
    assert image[int(row), int(col), 0] > 200 and image[int(row), int(col), 1] < 10
    # A box from the plane towards the eye hides the plane's centre.
    box = mesh_box((0.3, 0.3, 0.4), counts=(1, 1, 1), origin=(0.3, 0.3, 0.4))
    overview.draw(image, 2, 0.4, bodies=[(box.points, box.boundary_triangles)], picture=red)
    assert image[int(row), int(col), 1] > 50


def test_left_drag_on_the_overview_turns_it_and_pushes_nothing(viewer: Viewer3D) -> None:
    _reset(viewer)
    viewer.draw()
    fluid = viewer.simulation.state.fluid
    before = fluid.velocity_x.copy()
    azimuth, elevation = viewer.overview.azimuth, viewer.overview.elevation
    key = viewer.picture_key()
    left = viewer.frame().shape[1] - viewer.overview.size
    start, end = (left + 100, 100), (left + 120, 90)
    viewer.handle_event(pygame.event.Event(pygame.MOUSEBUTTONDOWN, button=1, pos=start))
    viewer.handle_event(pygame.event.Event(pygame.MOUSEMOTION, pos=end, rel=(20, -10),
                                           buttons=(1, 0, 0)))
    viewer.handle_event(pygame.event.Event(pygame.MOUSEBUTTONUP, button=1, pos=end))
    assert viewer.overview.azimuth == pytest.approx(azimuth - 10.0)
    assert viewer.overview.elevation == pytest.approx(elevation - 5.0)
    assert viewer.picture_key() != key
    np.testing.assert_array_equal(fluid.velocity_x, before)
    viewer.overview.orient(0.0, 120.0)
    assert viewer.overview.elevation == 85.0
    viewer.draw()
    viewer.overview.orient(azimuth, elevation)


def test_the_scene_video_chooses_the_first_plane_and_view() -> None:
    data = {**_SCENE, "bodies": [], "obstacles": [],
            "outputs": {"video": {"view": "dye", "axis": "x", "at": 0.3}}}
    viewer = Viewer3D(parse_scene(data), scale=SCALE)
    assert (viewer.view, viewer.axis, viewer.layer) == ("dye", "x", 4)  # 0.3 m in layer 4
    assert viewer.scale == SCALE and viewer.frame().shape[0] == viewer.overview.size


def test_run_viewer_opens_a_3d_window_and_stops_its_thread(scene) -> None:
    # Last: run_viewer ends with pygame.quit(), which the fixture's viewer's font needs.
    viewer = run_viewer(scene, scale=4, max_frames=3)
    assert isinstance(viewer, Viewer3D)
    assert not viewer.stepping_in_background
