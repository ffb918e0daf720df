"""A 3D state as a user sees it without ParaView: the bodies' and obstacles' surfaces shaded
in perspective, the domain's box and a field's slice, with colour bar and time stamp.

::

       +----------------------+---+     box edges grey, the three through the domain's
      /|       ______        /| c |     origin corner x red, y green, z blue; the slice
     +----------------------+ | o |     plane x[axis] = at coloured cell by cell (the
     | |      ( body )      | | l |     video's view, the colour bar's map), opaque; the
     | |  slice  ~~~~~      | | o |     surfaces in front of it shaded by a light over the
     | +------------------- | + u |     viewer's shoulder, one colour per triangle; what lies
     |/                     |/  r |     behind the plane is hidden (a depth buffer of 1/z);
     +----------------------+     |     the time top left, the slice's place and the axes'
   slice z = 0.5 m   axes x y z         colours bottom left

The camera looks at the domain from in front of the slice (from +z for a z-slice, +x for an
x-slice, above for a y-slice; y up; from the other side when the bodies all lie behind
the slice), turned ``azimuth`` and raised ``elevation``, and is zoomed so that the whole box
fills the picture: whatever lies in the domain is in view.

Why a rasteriser of our own (Numba kernels, `elastoflow.render._kernels3d`) and not
VTK/PyVista or matplotlib: VTK's pip wheel renders only through a system libEGL or libGL
(its libvtkglad opens libEGL.so.1 / libGL.so.1 at run time and bundles neither; VTK's
OSMesa build is on its own wheel index, not PyPI), which a bare CI machine with only pip
packages lacks; mplot3d is headless everywhere but took 0.6-1.1 s a frame with a body of
4800 triangles and sorts whole polygons by depth (a body cut by the slice comes out wrong).
This takes milliseconds, is exact per pixel, and gives the same picture to the bit on every
machine.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from types import SimpleNamespace
from typing import Any

import numpy as np

from elastoflow.render._colormap import COLORMAP_BY_VIEW, colormap_lut
from elastoflow.render._frame import (
    _LABELS,
    _draw_colorbar_values,
    _draw_time,
    _panel_width,
    _static_panel,
    _text_patch,
    _text_size,
    default_value_range,
)
from elastoflow.render._kernels3d import (
    draw_plane_cells,
    draw_segments_perspective,
    fill_triangles_perspective,
    lit_triangle_colors,
    plane_cells,
    project_points,
)
from elastoflow.render._slice3d import AXES, layer_values

SCENE_SIZE = (640, 480)
"""The 3D picture's default width and height [pixels], the colour bar's panel not included."""
BACKGROUND_COLOR = np.array([34, 38, 46], dtype=np.uint8)
BOX_COLOR = np.array([150, 154, 165], dtype=np.uint8)
AXIS_COLORS = np.array([[235, 70, 70], [70, 205, 90], [90, 140, 255]], dtype=np.uint8)
PLANE_EDGE_COLOR = np.array([250, 250, 250], dtype=np.uint8)
BODY_SURFACE_COLOR = np.array([240, 228, 205], dtype=np.float64)
"""The bodies' colour lit head-on; a face turned from the light is darker, down to
`AMBIENT` of it."""
OBSTACLE_SURFACE_COLOR = np.array([160, 160, 165], dtype=np.float64)
AMBIENT = 0.3
"""Share of a surface's colour that a face turned away from the light keeps."""
DEFAULT_ORIENTATION = {"x": (65.0, 20.0), "y": (30.0, 50.0), "z": (30.0, 20.0)}
"""(azimuth from +z towards +x, elevation) [degrees] of the eye for each slice axis: in front
of the plane, turned and raised enough to show the bodies' depth."""
FIELD_OF_VIEW = 30.0
"""The lens's angle across the box's larger projected side [degrees]: mild perspective."""
PANEL_EXTRA = 32
"""Pixels the colour bar's panel has beyond the 2D frame's (`render_frame`)."""
_MARGIN = 0.04
"""Share of the picture left free on each side of the box."""


def _unit(vector: np.ndarray) -> np.ndarray:
    return vector / np.linalg.norm(vector)


@dataclass(frozen=True)
class Camera3D:
    """A perspective camera: where it is, where it looks, and its lens in pixels.

    Attributes:
        eye: The eye's position [m], shape (3,).
        forward, right, up: Unit vectors [-], shape (3,): the viewing direction, the
            picture's x axis, its upward direction (rows run down, against it).
        focal: Focal length [pixels].
        centre: The pixel (column, row) the viewing direction passes through.
        size: The picture's (width, height) [pixels].
    """

    eye: np.ndarray
    forward: np.ndarray
    right: np.ndarray
    up: np.ndarray
    focal: float
    centre: tuple[float, float]
    size: tuple[int, int]

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Points [m] (n, 3) to pixels (n, 2) (x right, y down) and their inverse distance
        1/z [1/m] along ``forward`` (n,), non-positive at or behind the eye."""
        points = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        pixels = np.empty((points.shape[0], 2))
        inverse = np.empty(points.shape[0])
        project_points(points, self.eye, self.forward, self.right, self.up, self.focal,
                       self.centre[0], self.centre[1], pixels, inverse)
        return pixels, inverse


def _box(grid: Any) -> tuple[np.ndarray, np.ndarray]:
    low = np.asarray(grid.origin, dtype=np.float64)
    return low, low + np.asarray(grid.shape_cells, dtype=np.float64) * grid.h


def _corners(low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """The box's 8 corners, corner ``4 i + 2 j + k`` at (x_i, y_j, z_k), 0 low and 1 high."""
    return np.array([[(low, high)[i][0], (low, high)[j][1], (low, high)[k][2]]
                     for i in (0, 1) for j in (0, 1) for k in (0, 1)])


def scene_camera(grid: Any, axis: str = "z", size: tuple[int, int] = SCENE_SIZE, *,
                 azimuth: float | None = None, elevation: float | None = None) -> Camera3D:
    """The camera `render_scene_3d` uses: in front of a slice across ``axis``, the domain's
    box filling the ``size`` (width, height) picture.

    ``azimuth`` turns the eye about y from +z towards +x and ``elevation`` raises it above
    the x-z plane [degrees] (as the viewer's overview); defaults `DEFAULT_ORIENTATION`, in
    front of the slice.
    """
    if axis not in AXES:
        raise ValueError(f"axis = {axis!r}: must be one of x, y, z")
    default_azimuth, default_elevation = DEFAULT_ORIENTATION[axis]
    a = math.radians(default_azimuth if azimuth is None else float(azimuth))
    e = math.radians(float(np.clip(default_elevation if elevation is None else elevation,
                                   -85.0, 85.0)))
    direction = np.array([math.sin(a), 0.0, math.cos(a)])
    to_eye = _unit(np.array([direction[0] * math.cos(e), math.sin(e),
                             direction[2] * math.cos(e)]))
    width, height = int(size[0]), int(size[1])
    low, high = _box(grid)
    centre = 0.5 * (low + high)
    forward = -to_eye
    right = _unit(np.cross(forward, [0.0, 1.0, 0.0]))
    up = np.cross(right, forward)
    radius = 0.5 * float(np.linalg.norm(high - low))
    eye = centre + to_eye * radius / math.sin(0.5 * math.radians(FIELD_OF_VIEW))
    # Look at the box's centre, then zoom and shift the lens so its picture fills the frame.
    unit = Camera3D(eye, forward, right, up, 1.0, (0.0, 0.0), (width, height))
    flat, _ = unit.project(_corners(low, high))
    span = flat.max(axis=0) - flat.min(axis=0)
    focal = (1.0 - 2.0 * _MARGIN) * min(width / span[0], height / span[1])
    middle = 0.5 * (flat.max(axis=0) + flat.min(axis=0))
    return Camera3D(eye, forward, right, up, float(focal),
                    (0.5 * width - focal * middle[0], 0.5 * height - focal * middle[1]),
                    (width, height))


def scene_orientation(axis: str, position: float,
                      surfaces: Sequence[tuple[np.ndarray, np.ndarray]] = ()
                      ) -> tuple[float, float]:
    """The camera's (azimuth, elevation) [degrees] for a slice across ``axis`` at
    ``position`` [m]: `DEFAULT_ORIENTATION`, or its mirror image through the plane when all
    the ``surfaces``' points ``(points (n, 3), triangles)`` lie behind it (below
    ``position`` along ``axis``): the opaque slice must not hide every body, and a body the
    slice cuts shows its front half from either side. A run keeps the first frame's answer
    (`elastoflow.io.OutputSession`), so the view does not flip when a body crosses the
    plane."""
    if axis not in AXES:
        raise ValueError(f"axis = {axis!r}: must be one of x, y, z")
    azimuth, elevation = DEFAULT_ORIENTATION[axis]
    k = AXES[axis]
    along = [np.asarray(points, dtype=np.float64).reshape(-1, 3)[:, k]
             for points, triangles in surfaces if len(triangles)]
    if along and float(np.concatenate(along).max()) < position:
        if axis == "y":
            elevation = -elevation
        elif axis == "z":
            azimuth = 180.0 - azimuth
        else:
            azimuth = -azimuth
    return azimuth, elevation


def shade_triangles(camera: Camera3D, points: np.ndarray, triangles: np.ndarray,
                    color: np.ndarray) -> np.ndarray:
    """Each triangle's colour (T, 3) uint8: ``color`` (3,) times the light on it, from
    `AMBIENT` (edge-on or turned away) to 1 (facing a light above the viewer's right
    shoulder); both sides lit alike, so an open or inward surface shows too."""
    light = _unit(-camera.forward + 0.6 * camera.up + 0.3 * camera.right)
    colors = np.empty((triangles.shape[0], 3), dtype=np.uint8)
    lit_triangle_colors(np.asarray(points, dtype=np.float64),
                        np.asarray(triangles, dtype=np.int64), light,
                        np.asarray(color, dtype=np.float64), AMBIENT, colors)
    return colors


@dataclass(frozen=True)
class _Layout:
    """What stays the same from frame to frame of one run's video: the camera, the cell each
    pixel sees on the slice (flat index, -1 for none, (H, W)) and the slice's 1/z there,
    and the box's, axes' and slice rim's lines (starts, ends, their 1/z, colour)."""

    camera: Camera3D
    plane_cells: np.ndarray
    plane_depth: np.ndarray
    lines: tuple[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray], ...]


@lru_cache(maxsize=8)
def _layout(box: tuple[tuple[int, ...], float, tuple[float, ...]], axis: str, position: float,
            width: int, height: int, azimuth: float | None,
            elevation: float | None) -> _Layout:
    """The `_Layout` of a grid (its ``(shape_cells, h, origin)``), slice and camera."""
    shape_cells, h, origin = box
    grid = SimpleNamespace(shape_cells=shape_cells, h=h, origin=origin)
    camera = scene_camera(grid, axis, (width, height), azimuth=azimuth, elevation=elevation)
    k = AXES[axis]
    others = [a for a in range(3) if a != k]
    low_box, high_box = _box(grid)
    cells = np.empty((height, width), dtype=np.int64)
    plane_depth = np.empty((height, width))
    plane_cells(camera.eye, camera.forward, camera.right, camera.up,
                np.array([camera.focal, *camera.centre]), k, position,
                np.array([low_box[others[0]], low_box[others[1]]]), h,
                np.array([shape_cells[others[0]], shape_cells[others[1]]], dtype=np.int64),
                cells, plane_depth)
    corners, corner_depth = camera.project(_corners(low_box, high_box))
    edges = np.array([(c, c | bit) for bit in (4, 2, 1) for c in range(8) if not c & bit])
    lines = [(corners[edges[:, 0]], corners[edges[:, 1]], corner_depth[edges[:, 0]],
              corner_depth[edges[:, 1]], BOX_COLOR)]
    for a, bit in enumerate((4, 2, 1)):
        lines.append((corners[:1], corners[bit:bit + 1], corner_depth[:1],
                      corner_depth[bit:bit + 1], AXIS_COLORS[a]))
    rim = np.array([low_box, low_box, high_box, high_box])
    rim[1, others[1]], rim[3, others[1]] = high_box[others[1]], low_box[others[1]]
    rim[:, k] = position
    rim_pixels, rim_depth = camera.project(rim)
    lines.append((rim_pixels, np.roll(rim_pixels, -1, axis=0), rim_depth,
                  np.roll(rim_depth, -1), PLANE_EDGE_COLOR))
    for array in (cells, plane_depth):
        array.flags.writeable = False
    return _Layout(camera, cells, plane_depth, tuple(lines))


@lru_cache(maxsize=64)
def _light_text(text: str, size: int, tint: tuple[int, int, int] | None = None
                ) -> tuple[int, int, np.ndarray]:
    """``text`` white (or ``tint``) on black (a `_text_patch` inverted), to lay on the dark
    background."""
    dx, dy, patch = _text_patch(text, size)
    light = 255 - patch
    if tint is not None:
        light = (light.astype(np.uint16) * np.array(tint, dtype=np.uint16) // 255).astype(
            np.uint8)
    light.flags.writeable = False
    return dx, dy, light


def _paste_lighter(image: np.ndarray, patch: np.ndarray, x: int, y: int) -> None:
    rows = slice(max(y, 0), min(y + patch.shape[0], image.shape[0]))
    cols = slice(max(x, 0), min(x + patch.shape[1], image.shape[1]))
    if rows.start >= rows.stop or cols.start >= cols.stop:
        return
    part = patch[rows.start - y:rows.stop - y, cols.start - x:cols.stop - x]
    np.maximum(image[rows, cols], part, out=image[rows, cols])


def render_scene_3d(
    grid: Any,
    state: Any,
    *,
    axis: str = "z",
    position: float | None = None,
    view: str = "speed",
    surfaces: Sequence[tuple[np.ndarray, np.ndarray]] = (),
    obstacles: Sequence[tuple[np.ndarray, np.ndarray]] = (),
    time: float | None = None,
    value_range: tuple[float, float] | None = None,
    colorbar: bool = True,
    size: tuple[int, int] = SCENE_SIZE,
    azimuth: float | None = None,
    elevation: float | None = None,
    values: np.ndarray | None = None,
    out: np.ndarray | None = None,
) -> np.ndarray:
    """Draw a 3D state in perspective: the domain's box, the slice ``axis = position`` [m]
    (default the domain's middle) coloured by ``view``, the bodies' and obstacles' surfaces
    shaded, a colour bar with the slice's range and the time.

    Args:
        grid: The `Grid3D`.
        state: A `FluidState3D` (``velocity_x/_y/_z``, ``pressure``, ``dye``).
        axis: "x", "y" or "z": the slice's normal.
        position: Where the slice cuts that axis [m].
        view: "speed", "vorticity" (its component along ``axis``), "pressure" or "dye".
        surfaces: The bodies' surfaces ``(positions (n, 3), triangles (T, 3))`` [m] (what
            `Simulation.body_geometry` gives).
        obstacles: Obstacles' surfaces ``(points (k, 3), triangles (T, 3))`` [m] (an
            `Obstacle3D`'s ``points_at(t)`` and ``triangles``).
        time: Elapsed time [s] to print; nothing printed when None.
        value_range: The colour range (low, high); default from this slice's values.
        colorbar: Add the colour bar panel on the right.
        size: The 3D picture's (width, height) [pixels], without the panel.
        azimuth, elevation: The camera's turn and height [degrees] (`scene_camera`);
            default `scene_orientation`'s: in front of the slice on the bodies' side.
        values: The slice's cell values (`layer_values` of the layer the plane cuts), if the
            caller has them.
        out: Image to draw into and return when its shape is the result's (see
            `render_frame`).

    Returns:
        RGB image (H, W, 3) uint8 of a size fixed by ``size`` and ``colorbar`` alone, H and
        W even (video encoders need that).
    """
    if axis not in AXES:
        raise ValueError(f"axis = {axis!r}: must be one of x, y, z")
    k = AXES[axis]
    low_box, high_box = _box(grid)
    if position is None:
        position = 0.5 * (low_box[k] + high_box[k])
    position = float(position)
    if not low_box[k] <= position <= high_box[k]:
        raise ValueError(f"position = {position!r}: the plane must cut the domain "
                         f"[{low_box[k]}, {high_box[k]}] m along {axis}")
    index = min(int((position - low_box[k]) / grid.h), grid.shape_cells[k] - 1)
    if values is None:
        values = layer_values(grid, state, k, index, view)
    if value_range is None:
        value_range = default_value_range(values, view)
    low, high = float(value_range[0]), float(value_range[1])
    colormap = COLORMAP_BY_VIEW[view]

    width, height = int(size[0]) + int(size[0]) % 2, int(size[1]) + int(size[1]) % 2
    if width < 16 or height < 16:
        raise ValueError(f"size = {size!r}: must be at least 16 x 16 pixels")
    # Wider than the 2D frame's panel: "vorticity [1/s]" fits at every height.
    panel_width = _panel_width(height) + PANEL_EXTRA if colorbar else 0
    shape = (height, width + panel_width + panel_width % 2, 3)
    if (out is not None and out.shape == shape and out.dtype == np.uint8
            and out.flags.c_contiguous and out.flags.writeable):
        image = out
    else:
        image = np.empty(shape, dtype=np.uint8)
    if azimuth is None or elevation is None:
        chosen = scene_orientation(axis, position, (*surfaces, *obstacles))
        azimuth = chosen[0] if azimuth is None else azimuth
        elevation = chosen[1] if elevation is None else elevation
    layout = _layout((tuple(int(n) for n in grid.shape_cells), float(grid.h),
                      tuple(float(o) for o in grid.origin)), axis, position, width, height,
                     float(azimuth), float(elevation))
    camera = layout.camera
    scene = image[:, :width]
    depth = np.empty((height, width))
    # The slice and the background first; the surfaces in front of the slice over it.
    draw_plane_cells(scene, depth, layout.plane_cells, layout.plane_depth,
                     np.ascontiguousarray(values, dtype=np.float64).ravel(), low, high,
                     colormap_lut(colormap), BACKGROUND_COLOR)
    for group, color in ((surfaces, BODY_SURFACE_COLOR), (obstacles, OBSTACLE_SURFACE_COLOR)):
        for points, triangles in group:
            points = np.asarray(points, dtype=np.float64)
            triangles = np.asarray(triangles, dtype=np.int64)
            if not triangles.shape[0]:
                continue
            pixels, inverse = camera.project(points)
            fill_triangles_perspective(scene, depth, pixels, inverse, triangles,
                                       shade_triangles(camera, points, triangles, color))

    for starts, ends, inverse_starts, inverse_ends, color in layout.lines:
        draw_segments_perspective(scene, depth, starts, ends, inverse_starts, inverse_ends,
                                  color)

    # Bottom left: where the slice is, then the axes' names in the colours of their edges.
    text_size = _text_size(height)
    x = 4
    for text, tint in ((f"slice {axis} = {position:.3g} m   axes", None),
                       ("x", AXIS_COLORS[0]), ("y", AXIS_COLORS[1]), ("z", AXIS_COLORS[2])):
        dx, dy, patch = _light_text(text, text_size, None if tint is None else tuple(tint))
        _paste_lighter(scene, patch, x + dx, height - 4 - text_size + dy)
        x += dx + patch.shape[1] + text_size // 3
    if colorbar:
        image[:, width:] = _static_panel(height, shape[1] - width, height, colormap,
                                         _LABELS[view])
        _draw_colorbar_values(image, width, height, low, high)
    if time is not None:
        _draw_time(image, float(time), height)
    return image
