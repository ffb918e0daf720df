"""The real-time window for a 3D scene: a slice through the fluid, stepped in the background.

What the window shows, for a plane across ``axis`` through cell layer ``layer``::

    +------------------------------+---+-------------------+
    | the view on the cell layer   | c |  overview: the    |   slice: bodies' sections
    |   (speed, vorticity along    | o |  domain's box,    |   filled (light), obstacles'
    |    the normal, dye, pressure)| l |  the plane, the   |   (grey), both outlined;
    |                              | o |  bodies' and      |   magenta: each surface's
    |                              | u |  obstacles'       |   outline seen along the
    | status line                  | r |  surfaces shaded  |   normal (off the plane)
    +------------------------------+---+-------------------+

The picture's horizontal axis is the first of the two other axes (y for an x-slice, x
otherwise), its vertical axis the second, as `elastoflow.render.render_slice_3d` draws it.
"""

from __future__ import annotations

import math
import os
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from elastoflow.render import AXES
from elastoflow.viewer._overview import Overview
from elastoflow.viewer._viewer import PUSH_RADIUS_CELLS, Viewer

HELP_3D: tuple[str, ...] = (
    "left-drag: push the fluid within the slice plane (and add dye)",
    "left-drag on the 3D view (right): turn it",
    "mouse wheel or Up / Down: move the slice one cell along its axis",
    "Page Up / Page Down: move the slice an eighth of the domain",
    "x, y, z: slice across that axis",
    "v: cycle the view (speed, vorticity along the slice's normal, dye, pressure)",
    "space: pause, s: one step, r: reset, p: screenshot (PNG), q or Esc: quit",
    "magenta: the surfaces' outline seen along the slice's normal",
    "right: the box (x red, y green, z blue), the slice on its plane, the surfaces",
    "grabbing a body node (right-drag in 2D) is not available in 3D",
    "h: hide this help",
)
"""The help overlay's lines (key ``h``)."""

_PAGE_FRACTION = 8
_OVERVIEW_MIN_PIXELS = 256
TURN_DEGREES_PER_PIXEL = 0.5
"""How far a drag on the overview turns it."""
_WORKER_IDLE_S = 0.01


def default_scale_3d(grid: Any) -> int:
    """Pixels per cell for every slice of ``grid``: about 512 pixels along the domain's
    longest side, at least 128 along its shortest (the window keeps its size when the slice
    turns to another axis, unless the plane's sides differ)."""
    counts = grid.shape_cells
    return max(1, round(512 / max(counts)), math.ceil(128 / min(counts)))


def _thread_safe_numba() -> bool:
    """Whether Numba's parallel kernels may run from two threads at once (the rendering in
    the window's thread while the step runs in the worker): its ``tbb`` and ``omp`` layers may,
    ``workqueue`` aborts the process."""
    import numba

    try:
        return str(numba.threading_layer()) in ("tbb", "omp")
    except ValueError:  # no parallel kernel has run yet: the layer is not chosen
        return False


class Viewer3D(Viewer):
    """The interactive view of a 3D scene through a plane, testable without a window.

    The plane is normal to `axis` ("x", "y" or "z") and shows the cell layer `layer`: the
    field of `view`, the bodies' and obstacles' sections and their outlines seen along the
    normal (`elastoflow.render.render_slice_3d`); on its right the `Overview`, the domain
    in 3D with the slice's picture on its plane and the surfaces shaded (the module's
    picture shows the layout).

    Mouse: left-drag pushes the fluid within the plane (the drag's velocity blended into the
    faces within a few cells of the cursor, the layers next to the plane included, with
    dye); left-drag on the overview turns it; the wheel moves the plane. Grabbing a body
    node (right-drag in 2D) is not available in 3D. Keys: x, y, z slice across that axis;
    Up / Down one layer, Page Up / Page Down an eighth of the domain; h help; space pause,
    s single step, r reset, v cycle view, p screenshot (PNG), q or Esc quit.

    `update` steps in the calling thread; `start_stepping` steps in a background thread
    instead (what `run_viewer` does), so that the window stays responsive when a step takes
    longer than a frame; pushes are then queued and applied between steps.

    Args:
        scene: The `elastoflow.scenes.Scene3D`.
        scale: Pixels per cell (default `default_scale_3d`).
        screenshot_dir: Folder for ``p`` screenshots.
    """

    def __init__(self, scene: Any, *, scale: int | None = None,
                 screenshot_dir: str | Path = ".") -> None:
        os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
        import pygame

        self._pygame = pygame
        self.scene = scene
        self.simulation = self._build()
        grid = self.simulation.grid
        self.scale = default_scale_3d(grid) if scale is None else int(scale)
        video = scene.outputs.video
        self.view = video.view if video is not None else "speed"
        self.axis: str = video.axis if video is not None else "z"
        self._layers = {name: grid.shape_cells[k] // 2 for name, k in AXES.items()}
        if video is not None and video.at is not None:
            k = AXES[self.axis]
            self._layers[self.axis] = int(np.clip((video.at - grid.origin[k]) // grid.h, 0,
                                                  grid.shape_cells[k] - 1))
        self.paused = False
        self.running = True
        self.single_step = False
        self.show_help = False
        self.steps_per_second = 0.0
        self.message = ""
        self.screenshot_dir = Path(screenshot_dir)
        self.last_screenshot: Path | None = None
        self.edits = 0
        """Pushes applied so far: the picture changes with them while paused."""
        self._push_from: np.ndarray | None = None
        self._turn_from: tuple[int, int] | None = None
        self._overview_left: int | None = None
        self._grab: tuple[int, int] | None = None
        self._grab_target: np.ndarray | None = None
        self._frame: np.ndarray | None = None
        self._slice: np.ndarray | None = None
        self._panel: np.ndarray | None = None
        self._font: Any = None
        self._surface: Any = None
        side = max(_OVERVIEW_MIN_PIXELS, max(grid.ny, grid.nz) * self.scale)
        self.overview = Overview(grid, side + side % 2)
        self._pushes: list[tuple[np.ndarray, np.ndarray]] = []
        self._pushes_lock = threading.Lock()
        self._worker: threading.Thread | None = None
        self._stop = threading.Event()

    # -- the plane -----------------------------------------------------------------------

    @property
    def layer(self) -> int:
        """The cell layer the plane shows, 0 .. n - 1 along `axis`."""
        return self._layers[self.axis]

    @property
    def layer_count(self) -> int:
        """Cell layers along `axis`."""
        return int(self.simulation.grid.shape_cells[AXES[self.axis]])

    @property
    def slice_position(self) -> float:
        """The plane's coordinate along `axis` [m]: the centre of its cell layer."""
        grid = self.simulation.grid
        k = AXES[self.axis]
        return float(grid.origin[k] + (self.layer + 0.5) * grid.h)

    def move_slice(self, layers: int) -> None:
        """Move the plane by ``layers`` cells along its axis (kept inside the domain)."""
        self._layers[self.axis] = int(np.clip(self.layer + layers, 0, self.layer_count - 1))

    def set_axis(self, axis: str) -> None:
        """Turn the plane across ``axis`` ("x", "y" or "z"), at the layer it last had there."""
        if axis not in AXES:
            raise ValueError(f"axis = {axis!r}: must be one of x, y, z")
        self.axis = axis

    @property
    def plane_height(self) -> int:
        """Height of the field's picture [pixels] (the plane's second axis)."""
        grid = self.simulation.grid
        others = [k for k in range(3) if k != AXES[self.axis]]
        return int(grid.shape_cells[others[1]] * self.scale)

    @property
    def plane_width(self) -> int:
        """Width of the field's picture [pixels] (the plane's first axis)."""
        grid = self.simulation.grid
        others = [k for k in range(3) if k != AXES[self.axis]]
        return int(grid.shape_cells[others[0]] * self.scale)

    def on_overview(self, pixel: tuple[float, float]) -> bool:
        """Whether a window pixel lies on the overview (known once a frame is drawn)."""
        left = self._overview_left
        return (left is not None and left <= pixel[0] < left + self.overview.size
                and 0 <= pixel[1] < self.overview.size)

    def on_plane(self, pixel: tuple[float, float]) -> bool:
        """Whether a window pixel lies on the field's picture (not the colour bar or the
        overview)."""
        return 0 <= pixel[0] < self.plane_width and 0 <= pixel[1] < self.plane_height

    def to_world(self, pixel: tuple[float, float]) -> np.ndarray:
        """Window pixel (x right, y down) to the point of the plane there [m], shape (3,)."""
        grid = self.simulation.grid
        k = AXES[self.axis]
        across, up = [a for a in range(3) if a != k]
        h = grid.h / self.scale
        point = np.empty(3)
        point[k] = self.slice_position
        point[across] = grid.origin[across] + pixel[0] * h
        point[up] = grid.origin[up] + (self.plane_height - pixel[1]) * h
        return point

    # -- input ---------------------------------------------------------------------------

    def handle_event(self, event: Any) -> None:
        """React to one pygame event (keys, mouse, wheel, window close)."""
        pg = self._pygame
        if event.type == pg.QUIT:
            self.running = False
        elif event.type == pg.KEYDOWN:
            self._key(event.key)
        elif event.type == pg.MOUSEBUTTONDOWN:
            if event.button == 1 and self.on_plane(event.pos):
                self._push_from = self.to_world(event.pos)
            elif event.button == 1 and self.on_overview(event.pos):
                self._turn_from = tuple(event.pos)
            elif event.button == 3:
                self.message = "grabbing a body node is 2D only (h: help)"
        elif event.type == pg.MOUSEBUTTONUP:
            if event.button == 1:
                self._push_from = None
                self._turn_from = None
        elif event.type == pg.MOUSEMOTION:
            if self._turn_from is not None:
                dx = event.pos[0] - self._turn_from[0]
                dy = event.pos[1] - self._turn_from[1]
                self.overview.orient(
                    self.overview.azimuth - TURN_DEGREES_PER_PIXEL * dx,
                    self.overview.elevation + TURN_DEGREES_PER_PIXEL * dy)
                self._turn_from = tuple(event.pos)
            if self._push_from is not None and self.on_plane(event.pos):
                position = self.to_world(event.pos)
                self._queue_push(self._push_from, position)
                self._push_from = position
        elif event.type == pg.MOUSEWHEEL:
            self.move_slice(int(event.y))

    def _key(self, key: int) -> None:
        pg = self._pygame
        axes = {pg.K_x: "x", pg.K_y: "y", pg.K_z: "z"}
        page = max(1, self.layer_count // _PAGE_FRACTION)
        moves = {pg.K_UP: 1, pg.K_DOWN: -1, pg.K_PAGEUP: page, pg.K_PAGEDOWN: -page}
        if key in axes:
            self.set_axis(axes[key])
            self._push_from = None
        elif key in moves:
            self.move_slice(moves[key])
            self._push_from = None
        elif key == pg.K_h:
            self.show_help = not self.show_help
        else:
            super()._key(key)

    def _queue_push(self, start: np.ndarray, end: np.ndarray) -> None:
        """Push now, or between steps when the background thread steps."""
        if self._worker is None:
            self.push_fluid(start, end)
            return
        with self._pushes_lock:
            self._pushes.append((start, end))

    def _apply_pushes(self) -> None:
        with self._pushes_lock:
            pushes, self._pushes = self._pushes, []
        for start, end in pushes:
            self.push_fluid(start, end)

    def push_fluid(self, start: np.ndarray, end: np.ndarray) -> None:
        """Blend the drag velocity (start → end over one step, its component along the plane's
        normal dropped) into the faces near ``end`` [m], and dye into its cells.

        The weight is a Gaussian of the distance with a radius of `PUSH_RADIUS_CELLS` cells,
        cut below 0.05, so only a box around ``end`` is touched; the speed is capped at two
        cells per step so a fast flick cannot blow up the run.
        """
        sim = self.simulation
        grid, dt = sim.grid, sim.dt
        end = np.asarray(end, dtype=np.float64)
        velocity = (end - np.asarray(start, dtype=np.float64)) / dt
        velocity[AXES[self.axis]] = 0.0
        cap = 2.0 * grid.h / dt
        speed = float(np.linalg.norm(velocity))
        if speed > cap:
            velocity *= cap / speed
        radius = PUSH_RADIUS_CELLS * grid.h
        state = sim.state.fluid
        arrays = (state.velocity_x, state.velocity_y, state.velocity_z)
        for component, array in enumerate(arrays):
            box, weight = self._push_weight(array.shape, component, end, radius)
            if weight is not None:
                array[box] += weight * (velocity[component] - array[box])
        box, weight = self._push_weight(state.dye.shape, -1, end, radius)
        if weight is not None:
            np.maximum(state.dye[box], weight, out=state.dye[box])
        self.edits += 1

    def _push_weight(self, shape: tuple[int, ...], component: int, centre: np.ndarray,
                     radius: float) -> tuple[tuple[slice, ...], np.ndarray | None]:
        """The box of points of ``shape`` (faces normal to ``component``, cells for -1)
        within reach of ``centre`` and their Gaussian weights (None when the box is empty)."""
        grid = self.simulation.grid
        reach = 1.75 * radius  # exp(-1.75^2) < 0.05: nothing beyond is pushed
        box: list[slice] = []
        lines: list[np.ndarray] = []
        for a in range(3):
            offset = 0.0 if a == component else 0.5
            low = math.floor((centre[a] - reach - grid.origin[a]) / grid.h - offset)
            high = math.ceil((centre[a] + reach - grid.origin[a]) / grid.h - offset) + 1
            low, high = max(low, 0), min(high, shape[a])
            if high <= low:
                return tuple(box), None
            box.append(slice(low, high))
            lines.append(grid.origin[a] + (np.arange(low, high) + offset) * grid.h - centre[a])
        distance2 = (lines[0][:, None, None] ** 2 + lines[1][None, :, None] ** 2
                     + lines[2][None, None, :] ** 2)
        weight = np.exp(-distance2 / radius**2)
        weight[weight < 0.05] = 0.0
        return tuple(box), weight

    # -- stepping ------------------------------------------------------------------------

    @property
    def stepping_in_background(self) -> bool:
        """Whether the background thread steps the simulation."""
        return self._worker is not None and self._worker.is_alive()

    def start_stepping(self) -> bool:
        """Step in a background thread from now on; pushes are queued for it.

        Refused (False, stepping stays with `update`) when Numba's threading layer cannot run
        kernels from two threads at once (see `_thread_safe_numba`); call after a first
        `draw` so that the layer is chosen.
        """
        if self._worker is not None:
            return True
        if not _thread_safe_numba():
            return False
        self._stop.clear()
        self._worker = threading.Thread(target=self._step_loop, name="elastoflow-stepper",
                                        daemon=True)
        self._worker.start()
        return True

    def stop_stepping(self, timeout: float = 30.0) -> None:
        """Stop the background thread (after the step it is in) and apply queued pushes."""
        worker, self._worker = self._worker, None
        if worker is not None:
            self._stop.set()
            worker.join(timeout)
        self._apply_pushes()

    def _step_loop(self) -> None:
        while not self._stop.is_set():
            try:
                self._apply_pushes()
            except Exception as error:  # noqa: BLE001 - shown in the window
                self.message = f"push failed: {error}"
            if self.paused and not self.single_step:
                self._stop.wait(_WORKER_IDLE_S)
                continue
            Viewer.update(self)

    def update(self) -> None:
        """One step unless paused (``s`` asks for exactly one while paused); nothing while
        the background thread steps."""
        if self.stepping_in_background:
            return
        self._apply_pushes()
        super().update()

    # -- drawing -------------------------------------------------------------------------

    def picture_key(self) -> tuple[object, ...]:
        """What the picture depends on: a new one is drawn only when this changes."""
        sim = self.simulation
        return (id(sim), sim.step_index, self.edits, self.view, self.axis, self.layer,
                self.show_help, self.paused, self.message, self.last_screenshot,
                self.overview.azimuth, self.overview.elevation)

    def frame(self) -> np.ndarray:
        """The current picture as an RGB array (H, W, 3) uint8: the slice with its colour
        bar, and the overview on its right."""
        from elastoflow.render import layer_values, render_slice_3d

        sim = self.simulation
        state = sim.state
        now = sim.time
        bodies = [(body_state.positions, body.mesh.tetrahedra)
                  for body, body_state in zip(sim.bodies, state.bodies)]
        surfaces = sim.body_geometry()
        obstacles = [(obstacle.points_at(now), obstacle.triangles) for obstacle in sim.obstacles]
        picture = render_slice_3d(sim.grid, state.fluid, axis=self.axis,
                                  position=self.slice_position, view=self.view, bodies=bodies,
                                  time=now, scale=self.scale, out=self._slice,
                                  obstacles=obstacles, surfaces=surfaces,
                                  values=layer_values(sim.grid, state.fluid, AXES[self.axis],
                                                      self.layer, self.view))
        self._slice = picture
        side = self.overview.size
        shape = (max(picture.shape[0], side), picture.shape[1] + side, 3)
        image = self._frame
        if image is None or image.shape != shape:
            image = np.empty(shape, dtype=np.uint8)
        image[:picture.shape[0], :picture.shape[1]] = picture
        image[picture.shape[0]:, :picture.shape[1]] = 255
        if self._panel is None:
            self._panel = np.empty((side, side, 3), dtype=np.uint8)
        self.overview.draw(self._panel, AXES[self.axis], self.slice_position, surfaces,
                           obstacles, picture[:self.plane_height, :self.plane_width])
        image[:side, picture.shape[1]:] = self._panel
        self._overview_left = picture.shape[1]
        image[side:, picture.shape[1]:] = 255
        self._frame = image
        return image

    def status(self) -> str:
        state = "paused" if self.paused else f"{self.steps_per_second:.1f} steps/s"
        text = (f"{self.view} | {self.axis} = {self.slice_position:.4g} m "
                f"(layer {self.layer + 1}/{self.layer_count}) | step "
                f"{self.simulation.step_index} | {state} | h: help")
        return f"{text} | {self.message}" if self.message else text

    def draw(self) -> Any:
        """The frame as a pygame Surface, status line at the bottom and, with ``h``, the
        help over the picture (the Surface is reused as in 2D)."""
        surface = super().draw()
        if self.show_help:
            lines = [self._font.render(line, True, (255, 255, 255), (0, 0, 0))
                     for line in HELP_3D]
            y = 4
            for text in lines:
                surface.blit(text, (4, y))
                y += text.get_height() + 2
        return surface


def run_viewer_3d(viewer: Viewer3D, *, max_fps: int = 60, max_frames: int | None = None,
                  caption: str = "elastoflow", max_redraws_per_second: float = 30.0
                  ) -> Viewer3D:
    """The window's loop for a 3D scene (pygame initialised by the caller): the simulation
    steps in the background; the window reads events ``max_fps`` times a second and draws a
    new picture only when it changed, at most ``max_redraws_per_second`` times a second (a
    picture costs ~10 ms at 64^3 that the step, on two cores, would otherwise lose), and
    resizes when the plane's sides change."""
    pygame = viewer._pygame
    surface = viewer.draw()
    drawn = viewer.picture_key()
    screen = pygame.display.set_mode(surface.get_size())
    pygame.display.set_caption(caption)
    screen.blit(surface, (0, 0))
    pygame.display.flip()
    viewer.start_stepping()
    clock = pygame.time.Clock()
    frames = 0
    interval = 1.0 / max_redraws_per_second
    last = time.perf_counter()
    try:
        while viewer.running and (max_frames is None or frames < max_frames):
            frames += 1
            for event in pygame.event.get():
                viewer.handle_event(event)
            viewer.update()
            key = viewer.picture_key()
            if key != drawn and time.perf_counter() - last >= interval:
                drawn = key
                last = time.perf_counter()
                surface = viewer.draw()
                if surface.get_size() != screen.get_size():
                    screen = pygame.display.set_mode(surface.get_size())
                screen.blit(surface, (0, 0))
                pygame.display.flip()
            clock.tick(max_fps)
    finally:
        viewer.stop_stepping()
    return viewer
