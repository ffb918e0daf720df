"""The viewer headless (SDL dummy driver): events change its state; frames are drawn."""

from __future__ import annotations

import os

import numpy as np
import pytest

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
pygame = pytest.importorskip("pygame")
pytest.importorskip("elastoflow.simulation")

from elastoflow.scenes import parse_scene
from elastoflow.viewer import Viewer

_SCENE = {
    "name": "viewer_test",
    "domain": {"lx": 1.0, "ly": 1.0, "nx": 16},
    "fluid": {"density": 1000.0, "viscosity": 1e-3},
    "bodies": [{
        "shape": {"type": "rectangle", "box": [0.4, 0.4, 0.6, 0.8], "divisions": [2, 4]},
        "material": {"density": 1000.0, "young_modulus": 1e4, "poisson_ratio": 0.3},
        "fixed": {"box": [0.39, 0.79, 0.61, 0.81]},
    }],
    "time": {"dt": 0.02, "steps": 10},
    "coupling": {"scheme": "explicit", "force_model": "momentum_exchange"},
}


@pytest.fixture(scope="module")
def viewer(tmp_path_factory) -> Viewer:
    pygame.init()
    yield Viewer(parse_scene(_SCENE), scale=8, screenshot_dir=tmp_path_factory.mktemp("shots"))
    pygame.quit()


def _key(key: int) -> pygame.event.Event:
    return pygame.event.Event(pygame.KEYDOWN, key=key)


def test_keys_pause_step_cycle_view_and_quit(viewer: Viewer) -> None:
    viewer.update()
    assert viewer.simulation.step_index == 1
    viewer.handle_event(_key(pygame.K_SPACE))
    assert viewer.paused
    viewer.update()
    assert viewer.simulation.step_index == 1
    viewer.handle_event(_key(pygame.K_s))
    viewer.update()
    viewer.update()
    assert viewer.simulation.step_index == 2
    first = viewer.view
    viewer.handle_event(_key(pygame.K_v))
    assert viewer.view != first
    viewer.handle_event(_key(pygame.K_r))
    assert viewer.simulation.step_index == 0
    viewer.handle_event(_key(pygame.K_p))
    assert viewer.last_screenshot is not None and viewer.last_screenshot.exists()
    viewer.handle_event(_key(pygame.K_q))
    assert not viewer.running


def test_left_drag_pushes_the_fluid_along_the_drag(viewer: Viewer) -> None:
    viewer.handle_event(_key(pygame.K_r))
    viewer.simulation.state.fluid.velocity_x[...] = 0.0
    viewer.simulation.state.fluid.velocity_y[...] = 0.0
    start, end = (20, 40), (28, 40)  # pixels: a drag to the right near (0.2, 0.69) m
    viewer.handle_event(pygame.event.Event(pygame.MOUSEBUTTONDOWN, button=1, pos=start))
    viewer.handle_event(pygame.event.Event(pygame.MOUSEMOTION, pos=end, rel=(8, 0), buttons=(1, 0, 0)))
    viewer.handle_event(pygame.event.Event(pygame.MOUSEBUTTONUP, button=1, pos=end))
    state = viewer.simulation.state.fluid
    assert state.velocity_x.max() > 0.0 and state.velocity_x.min() >= 0.0
    assert np.abs(state.velocity_y).max() == 0.0
    near = viewer.to_world(end)
    i, j = round(near[0] / viewer.simulation.grid.h), int(near[1] / viewer.simulation.grid.h)
    assert state.velocity_x[i, j] == state.velocity_x.max()


def test_right_drag_moves_the_nearest_body_node(viewer: Viewer) -> None:
    viewer.handle_event(_key(pygame.K_r))
    viewer.paused = False
    body = viewer.simulation.bodies[0]
    corner = (0.4 / viewer.simulation.grid.h * 8, (1.0 - 0.4) / viewer.simulation.grid.h * 8)
    viewer.handle_event(pygame.event.Event(pygame.MOUSEBUTTONDOWN, button=3, pos=corner))
    target = (corner[0] - 6, corner[1])
    viewer.handle_event(pygame.event.Event(pygame.MOUSEMOTION, pos=target, rel=(-6, 0),
                                           buttons=(0, 0, 1)))
    viewer.update()
    node = int(np.argmin(np.linalg.norm(body.mesh.points - [0.4, 0.4], axis=1)))
    np.testing.assert_allclose(viewer.simulation.state.bodies[0].positions[node],
                               viewer.to_world(target))
    viewer.handle_event(pygame.event.Event(pygame.MOUSEBUTTONUP, button=3, pos=target))
    assert viewer._grab is None


def test_draw_returns_the_frame_with_the_body(viewer: Viewer) -> None:
    from elastoflow.render import BODY_FILL_COLOR

    viewer.handle_event(_key(pygame.K_r))
    surface = viewer.draw()
    assert surface.get_width() >= 16 * 8 and surface.get_height() >= 16 * 8
    pixels = pygame.surfarray.array3d(surface)  # (W, H, 3)
    body = viewer.simulation.bodies[0]
    positions = viewer.simulation.state.bodies[0].positions
    centroid = positions[body.mesh.triangles[3]].mean(axis=0)
    x = centroid[0] / viewer.simulation.grid.h * 8
    y = (1.0 - centroid[1]) / viewer.simulation.grid.h * 8
    assert tuple(pixels[int(x), int(y)]) == tuple(BODY_FILL_COLOR)
    assert "step 0" in viewer.status()


def test_draw_reuses_its_surface_and_shows_the_new_frame(viewer: Viewer) -> None:
    viewer.handle_event(_key(pygame.K_r))
    viewer.view = "speed"
    first = pygame.surfarray.array3d(viewer.draw())
    viewer.simulation.state.fluid.velocity_x[...] = np.linspace(0.0, 1.0, viewer.simulation.grid.ny)
    surface = viewer.draw()
    assert viewer.draw() is surface
    second = pygame.surfarray.array3d(surface)
    assert np.any(first != second)
    expected = viewer.frame()
    rows = expected.shape[0] - 30  # above the status line
    np.testing.assert_array_equal(second.swapaxes(0, 1)[:rows], expected[:rows])


def test_run_viewer_opens_a_window_and_steps() -> None:
    from elastoflow.viewer import run_viewer

    viewer = run_viewer(parse_scene(_SCENE), scale=4, max_frames=3)
    assert viewer.simulation.step_index == 3

