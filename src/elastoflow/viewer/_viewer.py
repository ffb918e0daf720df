"""Real-time window: the simulation stepping live, pushed and grabbed with the mouse."""

from __future__ import annotations

import os
import time as _time
from pathlib import Path
from typing import Any

import numpy as np

VIEW_CYCLE: tuple[str, ...] = ("speed", "vorticity", "dye", "pressure")
PUSH_RADIUS_CELLS = 3.0
GRAB_RADIUS_CELLS = 4.0


class Viewer:
    """The interactive view of one scene, testable without a window.

    `handle_event` takes pygame events, `update` advances the simulation (unless paused) and
    `draw` returns the frame as a pygame Surface. Mouse: left-drag pushes the fluid (velocity
    along the drag is blended into the faces near the cursor, with dye); right-drag grabs the
    nearest body node and moves it with the cursor. Keys: space pause, s single step, r reset,
    v cycle view, p screenshot (PNG), q or Esc quit.

    Args:
        scene: The `elastoflow.scenes.Scene`.
        scale: Pixels per cell (default as for videos).
        screenshot_dir: Folder for ``p`` screenshots.
    """

    def __init__(self, scene: Any, *, scale: int | None = None,
                 screenshot_dir: str | Path = ".") -> None:
        os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
        import pygame

        from elastoflow.render._frame import default_scale

        self._pygame = pygame
        self.scene = scene
        self.simulation = self._build()
        grid = self.simulation.grid
        self.scale = default_scale(grid) if scale is None else int(scale)
        video = scene.outputs.video
        self.view = video.view if video is not None else "speed"
        self.paused = False
        self.running = True
        self.single_step = False
        self.steps_per_second = 0.0
        self.message = ""
        self.screenshot_dir = Path(screenshot_dir)
        self.last_screenshot: Path | None = None
        self.field_height = grid.ny * self.scale
        self._faces_x = grid.faces_x()
        self._faces_y = grid.faces_y()
        self._cells = grid.cell_centers()
        self._push_from: np.ndarray | None = None
        self._grab: tuple[int, int] | None = None
        self._grab_target: np.ndarray | None = None
        self._frame: np.ndarray | None = None
        self._font: Any = None
        self._surface: Any = None

    def _build(self) -> Any:
        from elastoflow.scenes import build_simulation

        return build_simulation(self.scene)

    # -- coordinates ---------------------------------------------------------------------

    def to_world(self, pixel: tuple[float, float]) -> np.ndarray:
        """Window pixel (x right, y down) to domain position [m]."""
        grid = self.simulation.grid
        h = grid.h / self.scale
        return np.array([grid.origin[0] + pixel[0] * h,
                         grid.origin[1] + (self.field_height - pixel[1]) * h])

    # -- input ---------------------------------------------------------------------------

    def handle_event(self, event: Any) -> None:
        """React to one pygame event (keys, mouse, window close)."""
        pg = self._pygame
        if event.type == pg.QUIT:
            self.running = False
        elif event.type == pg.KEYDOWN:
            self._key(event.key)
        elif event.type == pg.MOUSEBUTTONDOWN:
            position = self.to_world(event.pos)
            if event.button == 1:
                self._push_from = position
            elif event.button == 3:
                self._grab = self._nearest_node(position)
                self._grab_target = position if self._grab is not None else None
        elif event.type == pg.MOUSEBUTTONUP:
            if event.button == 1:
                self._push_from = None
            elif event.button == 3:
                self._grab = None
                self._grab_target = None
        elif event.type == pg.MOUSEMOTION:
            position = self.to_world(event.pos)
            if self._push_from is not None:
                self.push_fluid(self._push_from, position)
                self._push_from = position
            if self._grab is not None:
                self._grab_target = position

    def _key(self, key: int) -> None:
        pg = self._pygame
        if key in (pg.K_q, pg.K_ESCAPE):
            self.running = False
        elif key == pg.K_SPACE:
            self.paused = not self.paused
        elif key == pg.K_s:
            self.paused = True
            self.single_step = True
        elif key == pg.K_r:
            self.simulation = self._build()
            self.message = "reset"
            self._grab = None
        elif key == pg.K_v:
            self.view = VIEW_CYCLE[(VIEW_CYCLE.index(self.view) + 1) % len(VIEW_CYCLE)]
        elif key == pg.K_p:
            self.screenshot()

    def push_fluid(self, start: np.ndarray, end: np.ndarray) -> None:
        """Blend the drag velocity (start → end over one step) into the faces near ``end``.

        The speed is capped at two cells per step so a fast flick cannot blow up the run.
        """
        sim = self.simulation
        grid, dt = sim.grid, sim.dt
        velocity = (np.asarray(end) - np.asarray(start)) / dt
        cap = 2.0 * grid.h / dt
        speed = float(np.hypot(*velocity))
        if speed > cap:
            velocity *= cap / speed
        radius = PUSH_RADIUS_CELLS * grid.h
        state = sim.state.fluid
        for component, (x, y), array in ((0, self._faces_x, state.velocity_x),
                                         (1, self._faces_y, state.velocity_y)):
            weight = np.exp(-((x - end[0]) ** 2 + (y - end[1]) ** 2) / radius**2)
            weight[weight < 0.05] = 0.0
            array += weight * (velocity[component] - array)
        x, y = self._cells
        dye_weight = np.exp(-((x - end[0]) ** 2 + (y - end[1]) ** 2) / radius**2)
        np.maximum(state.dye, dye_weight, out=state.dye)

    def _nearest_node(self, position: np.ndarray) -> tuple[int, int] | None:
        best: tuple[float, int, int] | None = None
        for index, body in enumerate(self.simulation.state.bodies):
            distance = np.linalg.norm(body.positions - position, axis=1)
            node = int(np.argmin(distance))
            if best is None or distance[node] < best[0]:
                best = (float(distance[node]), index, node)
        if best is None or best[0] > GRAB_RADIUS_CELLS * self.simulation.grid.h:
            return None
        return best[1], best[2]

    def _apply_grab(self) -> None:
        if self._grab is None or self._grab_target is None:
            return
        index, node = self._grab
        body = self.simulation.state.bodies[index]
        body.velocities[node] = (self._grab_target - body.positions[node]) / self.simulation.dt
        body.positions[node] = self._grab_target

    # -- stepping and drawing ------------------------------------------------------------

    def update(self) -> None:
        """One step unless paused (``s`` asks for exactly one while paused)."""
        if self.paused and not self.single_step:
            return
        self.single_step = False
        self._apply_grab()
        began = _time.perf_counter()
        try:
            self.simulation.step()
        except Exception as error:  # noqa: BLE001 - shown in the window; r resets
            self.message = f"stopped: {error} (press r to reset)"
            self.paused = True
            return
        self._apply_grab()
        rate = 1.0 / max(_time.perf_counter() - began, 1e-9)
        self.steps_per_second = rate if self.steps_per_second == 0.0 else (
            0.9 * self.steps_per_second + 0.1 * rate)

    def frame(self) -> np.ndarray:
        """The current picture as an RGB array (H, W, 3) uint8, with the status line."""
        from elastoflow.render import render_frame

        sim = self.simulation
        image = render_frame(sim.grid, sim.state.fluid, sim.body_geometry(), sim.obstacles,
                             self.view,
                             sim.time, scale=self.scale,
                             level_set=getattr(sim, "level_set", None))
        self._frame = image
        return image

    def status(self) -> str:
        state = "paused" if self.paused else f"{self.steps_per_second:.1f} steps/s"
        text = f"{self.view} | step {self.simulation.step_index} | {state}"
        return f"{text} | {self.message}" if self.message else text

    def draw(self) -> Any:
        """The frame as a pygame Surface, status line at the bottom.

        The same Surface is returned (and overwritten) by every call while the frame size stays
        the same; copy it to keep a frame.
        """
        pg = self._pygame
        image = np.ascontiguousarray(self.frame())
        size = (image.shape[1], image.shape[0])
        # Wrapping the RGB rows without a copy and one SDL blit into a kept Surface costs
        # ~0.15 ms; building a new Surface from a transposed copy cost ~2 ms per frame.
        if self._surface is None or self._surface.get_size() != size:
            self._surface = pg.Surface(size)
        surface = self._surface
        surface.blit(pg.image.frombuffer(image, size, "RGB"), (0, 0))
        if self._font is None:
            pg.font.init()
            self._font = pg.font.Font(None, 20)
        text = self._font.render(self.status(), True, (255, 255, 255), (0, 0, 0))
        surface.blit(text, (4, surface.get_height() - text.get_height() - 4))
        return surface

    def screenshot(self) -> Path:
        """Save the current frame as PNG in ``screenshot_dir``."""
        from PIL import Image

        from elastoflow.io import atomic_path

        image = self.frame()
        path = self.screenshot_dir / f"elastoflow_{self.simulation.step_index:06d}.png"
        with atomic_path(path) as temporary:
            Image.fromarray(image).save(temporary, format="PNG")
        self.last_screenshot = path
        self.message = f"saved {path}"
        return path


def run_viewer(scene: Any, *, scale: int | None = None, max_fps: int = 60,
               max_frames: int | None = None) -> Viewer:
    """Open the window and run until closed (q, Esc or the window's close button), or for
    ``max_frames`` frames; returns the viewer.

    A 3D scene (``scene.dimension == 3``) opens a `elastoflow.viewer.Viewer3D`: a slice
    through the fluid, the simulation stepping in a background thread."""
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    import pygame

    pygame.init()
    try:
        if getattr(scene, "dimension", 2) == 3:
            from elastoflow.viewer._viewer3d import Viewer3D, run_viewer_3d

            return run_viewer_3d(Viewer3D(scene, scale=scale), max_fps=max_fps,
                                 max_frames=max_frames, caption=f"elastoflow: {scene.name}")
        viewer = Viewer(scene, scale=scale)
        surface = viewer.draw()
        screen = pygame.display.set_mode(surface.get_size())
        pygame.display.set_caption(f"elastoflow: {scene.name}")
        clock = pygame.time.Clock()
        frames = 0
        while viewer.running and (max_frames is None or frames < max_frames):
            frames += 1
            for event in pygame.event.get():
                viewer.handle_event(event)
            viewer.update()
            screen.blit(viewer.draw(), (0, 0))
            pygame.display.flip()
            clock.tick(max_fps)
    finally:
        pygame.quit()
    return viewer
