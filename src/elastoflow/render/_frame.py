"""One frame of the simulation as an RGB image, in the look of the paper's Fig. 6."""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import cache, lru_cache
from typing import Any

import numpy as np

from elastoflow.render._colormap import COLORMAP_BY_VIEW, colormap_lut
from elastoflow.render._fields import speed_at_cells, vorticity_at_cells
from elastoflow.render._kernels import (
    color_field,
    draw_liquid,
    draw_segments,
    draw_triangle_edges,
    fill_polygon,
    fill_triangles,
    finite_range,
)

VIEWS: tuple[str, ...] = ("speed", "vorticity", "pressure", "dye")
BODY_FILL_COLOR = np.array([235, 235, 235], dtype=np.uint8)
BODY_EDGE_COLOR = np.array([40, 40, 40], dtype=np.uint8)
OBSTACLE_FILL_COLOR = np.array([128, 128, 128], dtype=np.uint8)
OBSTACLE_EDGE_COLOR = np.array([20, 20, 20], dtype=np.uint8)
PANEL_COLOR = (255, 255, 255)
AIR_COLOR = np.array([255, 255, 255], dtype=np.uint8)
SURFACE_COLOR = np.array([20, 50, 120], dtype=np.uint8)
SURFACE_LINE_PIXELS = 2.0
"""Width of the free surface's line [pixels]."""
_LABELS = {"speed": "speed [m/s]", "vorticity": "vorticity [1/s]", "pressure": "pressure [Pa]",
           "dye": "dye"}


def view_values(grid: Any, state: Any, view: str) -> np.ndarray:
    """The cell-centred scalar field that ``view`` shows, shape (nx, ny)."""
    if view == "speed":
        return speed_at_cells(state)
    if view == "vorticity":
        return vorticity_at_cells(state, grid.h)
    if view == "pressure":
        return np.asarray(state.pressure)
    if view == "dye":
        return np.asarray(state.dye)
    raise ValueError(f"view = {view!r}: must be one of {VIEWS}")


def liquid_values(values: np.ndarray, level_set: np.ndarray) -> np.ndarray:
    """``values`` (nx, ny) with the air cells (level set >= 0) NaN: what a colour range of
    the liquid alone is taken from (`default_value_range` skips NaN)."""
    return np.where(np.asarray(level_set) < 0.0, values, np.nan)


def default_value_range(values: np.ndarray, view: str) -> tuple[float, float]:
    """Colour range of a view: from 0 for speed and dye, symmetric about 0 for vorticity."""
    count, low, high, largest = finite_range(np.asarray(values, dtype=np.float64))
    if count == 0:
        return (0.0, 1.0)
    if view == "speed":
        return (0.0, max(high, 1e-12))
    if view == "dye":
        return (0.0, max(high, 1.0))
    if view == "vorticity":
        bound = max(largest, 1e-12)
        return (-bound, bound)
    return (low, high) if high > low else (low - 1.0, low + 1.0)


def default_scale(grid: Any) -> int:
    """Pixels per cell: about 512 pixels along the longer side, at least 128 along the other."""
    return max(1, round(512 / max(grid.nx, grid.ny)), math.ceil(128 / min(grid.nx, grid.ny)))


def _body_geometry(body: Any) -> tuple[np.ndarray, np.ndarray]:
    if isinstance(body, tuple):
        points, triangles = body
    else:
        points, triangles = body.positions, body.mesh.triangles
    return np.asarray(points, dtype=np.float64), np.asarray(triangles, dtype=np.int64)


ROD_CORE_RADIUS = 1
"""Half-width [pixels] of a rod's body-coloured core; its dark rim adds one pixel each side,
so a rod is 5 pixels wide at any scale: a line of zero thickness must still show in a video."""


def _draw_polyline(image: np.ndarray, pixels: np.ndarray, radius: int,
                   color: np.ndarray) -> None:
    """The polyline through ``pixels`` (n, 2), ``2 radius + 1`` pixels wide: the one-pixel
    segments drawn again at every offset within ``radius`` (a disc of offsets, so turns and
    ends come out round)."""
    starts, ends = pixels[:-1], pixels[1:]
    for dx in range(-radius, radius + 1):
        for dy in range(-radius, radius + 1):
            if dx * dx + dy * dy <= radius * radius + radius:
                offset = np.array([dx, dy], dtype=np.float64)
                draw_segments(image, starts + offset, ends + offset, color)


def _draw_rod(image: np.ndarray, pixels: np.ndarray) -> None:
    """A body without triangles (a rod, `elastoflow.solid.RodBody`) as its polyline in the
    body colour with a dark rim, as triangle bodies are filled and outlined."""
    if pixels.shape[0] < 2:
        return
    _draw_polyline(image, pixels, ROD_CORE_RADIUS + 1, BODY_EDGE_COLOR)
    _draw_polyline(image, pixels, ROD_CORE_RADIUS, BODY_FILL_COLOR)


def _obstacle_outline(obstacle: Any, time: float) -> np.ndarray:
    if hasattr(obstacle, "points_at"):
        return np.asarray(obstacle.points_at(time), dtype=np.float64)
    return np.asarray(obstacle, dtype=np.float64)


def triangle_edges(triangles: np.ndarray) -> np.ndarray:
    """Each edge of a triangle mesh once, shape (k, 2) int."""
    edges = np.concatenate((triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]))
    return np.unique(np.sort(edges, axis=1), axis=0)


def render_frame(
    grid: Any,
    state: Any,
    bodies: Sequence[Any] = (),
    obstacles: Sequence[Any] = (),
    view: str = "speed",
    time: float | None = None,
    *,
    value_range: tuple[float, float] | None = None,
    scale: int | None = None,
    colorbar: bool = True,
    values: np.ndarray | None = None,
    out: np.ndarray | None = None,
    level_set: np.ndarray | None = None,
) -> np.ndarray:
    """Draw the fluid field with bodies and obstacles on top.

    The field is coloured cell by cell through a lookup table; body triangles are filled and
    their edges drawn; bodies without triangles (rods) are drawn as their polyline, 5 pixels
    wide; obstacles are filled; the elapsed time is written in the top-left corner
    and a colour bar with its range sits on the right.

    Args:
        grid: The `Grid2D`.
        state: Fluid state (``velocity_x``, ``velocity_y``, ``pressure``, ``dye``).
        bodies: Elastic bodies (``positions`` and ``mesh.triangles``) or ``(points (n, 2),
            triangles (m, 3))`` pairs [m]; a rod has no triangles (m = 0) and its points are
            its polyline in order.
        obstacles: Obstacles (with ``points_at(time)``) or outlines (k, 2) [m].
        view: ``"speed"``, ``"vorticity"``, ``"pressure"`` or ``"dye"``.
        time: Elapsed time [s] to print; nothing printed when None.
        value_range: Colour range (low, high); default from this frame's values.
        scale: Pixels per cell (default `default_scale`).
        colorbar: Add the colour bar panel.
        values: The field ``view_values(grid, state, view)`` (nx, ny), if the caller has it
            already; computed when None.
        out: Image to draw into and return, (H, W, 3) uint8 C-contiguous of the result's
            shape, e.g. the previous frame's, so that a frame per step allocates nothing; a new
            array when None (or when the shape differs).
        level_set: A free surface's level set (nx, ny) [m], liquid where negative: the
            liquid keeps the field's colours, the air is blank (white) and the surface is a
            dark line ``SURFACE_LINE_PIXELS`` wide; the default colour range is then the
            liquid cells' (`liquid_values`).

    Returns:
        RGB image, shape (H, W, 3) uint8, H and W even (video encoders need that).
    """
    if values is None:
        values = view_values(grid, state, view)
    if value_range is None:
        shown = values if level_set is None else liquid_values(values, level_set)
        value_range = default_value_range(shown, view)
    low, high = value_range
    low, high = float(low), float(high)
    scale = default_scale(grid) if scale is None else int(scale)
    colormap = COLORMAP_BY_VIEW[view]

    height, width = grid.ny * scale, grid.nx * scale
    panel_width = _panel_width(height) if colorbar else 0
    out_height = height + (height % 2)
    out_width = width + panel_width
    out_width += out_width % 2
    shape = (out_height, out_width, 3)
    if (out is not None and out.shape == shape and out.dtype == np.uint8
            and out.flags.c_contiguous and out.flags.writeable):
        image = out
    else:
        image = np.empty(shape, dtype=np.uint8)
    field = image[:height, :width]
    # The whole (contiguous) image: the kernel fills only its top-left, and indexes a
    # C-contiguous array ~1.5x faster than the strided field view.
    color_field(image, np.asarray(values, dtype=np.float64), low, high, colormap_lut(colormap),
                scale)
    if level_set is not None:
        draw_liquid(image, np.ascontiguousarray(level_set, dtype=np.float64), scale,
                    0.5 * SURFACE_LINE_PIXELS * grid.h / scale, AIR_COLOR, SURFACE_COLOR)
    if out_height > height:
        image[height:] = PANEL_COLOR

    origin = np.asarray(getattr(grid, "origin", (0.0, 0.0)), dtype=np.float64)
    pixels_per_metre = scale / grid.h

    def to_pixels(points: np.ndarray) -> np.ndarray:
        pixels = np.empty_like(points)
        pixels[:, 0] = (points[:, 0] - origin[0]) * pixels_per_metre
        pixels[:, 1] = height - (points[:, 1] - origin[1]) * pixels_per_metre
        return pixels

    now = 0.0 if time is None else float(time)
    for obstacle in obstacles:
        outline = to_pixels(_obstacle_outline(obstacle, now))
        fill_polygon(field, outline, OBSTACLE_FILL_COLOR)
        draw_segments(field, outline, np.roll(outline, -1, axis=0), OBSTACLE_EDGE_COLOR)
    for body in bodies:
        points, triangles = _body_geometry(body)
        pixels = to_pixels(points)
        if triangles.shape[0] == 0:
            _draw_rod(field, pixels)
            continue
        fill_triangles(field, pixels, triangles, BODY_FILL_COLOR)
        draw_triangle_edges(field, pixels, triangles, BODY_EDGE_COLOR)

    if colorbar:
        image[:, width:] = _static_panel(out_height, out_width - width, height, colormap,
                                         _LABELS[view])
        _draw_colorbar_values(image, width, height, low, high)
    elif out_width > width:
        image[:, width:] = PANEL_COLOR
    if time is not None:
        _draw_time(image, now, height)
    return image


def _panel_width(height: int) -> int:
    return max(64, min(110, height // 5))


@cache
def _font(size: int) -> Any:
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1 has only the fixed bitmap font.
        return ImageFont.load_default()


def _text_size(height: int) -> int:
    return max(9, min(16, height // 28))


def _colorbar_layout(x_start: int, height: int) -> tuple[int, int, int, int]:
    """(top, bottom, left, bar_width) of the colour bar in image pixels."""
    margin = max(6, height // 20)
    bar_width = max(8, height // 32)
    top, bottom = margin + 2 * _text_size(height), height - margin
    left = x_start + margin // 2 + 2
    if bottom - top < 8:
        top, bottom = 2, height - 2
    return top, bottom, left, bar_width


@lru_cache(maxsize=16)
def _static_panel(out_height: int, panel_width: int, height: int, colormap: str,
                  label: str) -> np.ndarray:
    """The colour bar panel without its value labels: ramp, frame and the view's name.

    Shape (out_height, panel_width, 3) uint8, read-only; drawn once per size, map and label
    because it does not change from frame to frame.
    """
    from PIL import Image, ImageDraw

    panel = np.empty((out_height, panel_width, 3), dtype=np.uint8)
    panel[...] = PANEL_COLOR
    top, bottom, left, bar_width = _colorbar_layout(0, height)
    # Highest value at the top.
    ramp = colormap_lut(colormap)[np.linspace(255, 0, bottom - top).astype(np.intp)]
    panel[top:bottom, left:left + bar_width] = ramp[:, None, :]
    panel[top:bottom, left - 1] = 0
    panel[top:bottom, left + bar_width] = 0
    panel[top - 1, left - 1:left + bar_width + 1] = 0
    panel[bottom, left - 1:left + bar_width + 1] = 0
    picture = Image.fromarray(panel)
    ImageDraw.Draw(picture).text((3, 2), label, fill=(0, 0, 0), font=_font(_text_size(height)))
    panel = np.asarray(picture).copy()
    panel.flags.writeable = False
    return panel


@lru_cache(maxsize=1024)
def _text_patch(text: str, size: int) -> tuple[int, int, np.ndarray]:
    """Black ``text`` on white as drawn at the origin: (dx, dy, patch (h, w, 3) uint8), the
    patch's top-left corner at (dx, dy) from the text's anchor."""
    from PIL import Image, ImageDraw

    font = _font(size)
    x0, y0, x1, y1 = (int(v) for v in font.getbbox(text))
    picture = Image.new("RGB", (max(1, x1 - x0), max(1, y1 - y0)), PANEL_COLOR)
    ImageDraw.Draw(picture).text((-x0, -y0), text, fill=(0, 0, 0), font=font)
    patch = np.asarray(picture).copy()
    patch.flags.writeable = False
    return x0, y0, patch


def _draw_colorbar_values(image: np.ndarray, x_start: int, height: int, low: float,
                          high: float) -> None:
    """Write the colour bar's top, middle and bottom values beside it.

    The cached glyph patches are black on white and the panel behind them is white, so the
    darker of the two is the text exactly as Pillow draws it there.
    """
    top, bottom, left, bar_width = _colorbar_layout(x_start, height)
    size = _text_size(height)
    for value, row in ((high, top), (0.5 * (low + high), (top + bottom) // 2), (low, bottom)):
        dx, dy, patch = _text_patch(f"{value:.3g}", size)
        x, y = left + bar_width + 3 + dx, row - size // 2 + dy
        _paste_darker(image, patch, x, y)


def _paste_darker(image: np.ndarray, patch: np.ndarray, x: int, y: int) -> None:
    rows = slice(max(y, 0), min(y + patch.shape[0], image.shape[0]))
    cols = slice(max(x, 0), min(x + patch.shape[1], image.shape[1]))
    if rows.start >= rows.stop or cols.start >= cols.stop:
        return
    part = patch[rows.start - y:rows.stop - y, cols.start - x:cols.stop - x]
    np.minimum(image[rows, cols], part, out=image[rows, cols])


def _time_box(time: float, height: int) -> tuple[str, int, tuple[float, float, float, float]]:
    size = _text_size(height) + 2
    text = f"t = {time:.2f} s"
    return text, size, (2, 2, 4 + size * len(text) * 0.6, 4 + size * 1.2)


@lru_cache(maxsize=16)
def _time_box_mask(rows: int, cols: int, box: tuple[float, float, float, float]) -> np.ndarray:
    """The pixels the time label's black box covers, as Pillow fills it: (rows, cols, 1)
    bool, read-only."""
    from PIL import Image, ImageDraw

    covered = Image.new("L", (cols, rows), 0)
    ImageDraw.Draw(covered).rectangle(box, fill=255)
    inside = (np.asarray(covered) > 0)[:, :, None]
    inside.flags.writeable = False
    return inside


@lru_cache(maxsize=1024)
def _time_patch(text: str, size: int, box: tuple[float, float, float, float]
                ) -> tuple[np.ndarray, np.ndarray] | None:
    """The time label as Pillow draws it at the top-left corner: (covered (h, w, 1) bool,
    pixels (h, w, 3) uint8), or None when the text overhangs its black box (then the field
    shows through the glyphs' edges and the label is drawn in place).

    The label changes every frame or two, so this runs about once per frame: only the text
    is drawn here, the box's pixels come from a cache of their own.
    """
    from PIL import Image, ImageDraw

    font = _font(size)
    x0, y0, x1, y1 = font.getbbox(text)
    rows, cols = math.ceil(box[3]) + 2, math.ceil(box[2]) + 2
    inside = _time_box_mask(rows, cols, box)
    text_rows, text_cols = slice(3 + y0, 3 + y1), slice(4 + x0, 4 + x1)
    if 3 + y0 < 0 or 4 + x0 < 0 or 3 + y1 > rows or 4 + x1 > cols or not np.all(
            inside[text_rows, text_cols]):
        return None
    picture = Image.new("RGB", (cols, rows), (0, 0, 0))
    ImageDraw.Draw(picture).text((4, 3), text, fill=(255, 255, 255), font=font)
    return inside, np.asarray(picture)


def _draw_time(image: np.ndarray, time: float, height: int) -> None:
    text, size, box = _time_box(time, height)
    cached = _time_patch(text, size, box)
    if cached is not None:
        inside, pixels = cached
        rows, cols = min(inside.shape[0], image.shape[0]), min(inside.shape[1], image.shape[1])
        np.copyto(image[:rows, :cols], pixels[:rows, :cols], where=inside[:rows, :cols])
        return
    from PIL import Image, ImageDraw

    picture = Image.fromarray(image)
    draw = ImageDraw.Draw(picture)
    draw.rectangle(box, fill=(0, 0, 0))
    draw.text((4, 3), text, fill=(255, 255, 255), font=_font(size))
    image[...] = np.asarray(picture)
