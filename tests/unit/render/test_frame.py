"""render_frame: field colours from the LUT, bodies and obstacles where their geometry is,
colour bar present; VideoWriter output readable, atomic, GIF fallback."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from elastoflow.grid import Grid2D
from elastoflow.render import (
    BODY_FILL_COLOR,
    OBSTACLE_FILL_COLOR,
    VideoWriter,
    colormap_lut,
    render_frame,
    speed_at_cells,
    vorticity_at_cells,
)


def _state(grid: Grid2D, ux: float = 0.0) -> SimpleNamespace:
    return SimpleNamespace(
        velocity_x=np.full(grid.shape_faces_x, ux), velocity_y=np.zeros(grid.shape_faces_y),
        pressure=np.zeros(grid.shape_cells), dye=np.zeros(grid.shape_cells),
    )


def _pixel(grid: Grid2D, scale: int, x: float, y: float) -> tuple[int, int]:
    """(row, col) of the pixel containing world point (x, y)."""
    return int(grid.ny * scale - y / grid.h * scale), int(x / grid.h * scale)


def test_lut_shape_and_ends() -> None:
    lut = colormap_lut("jet")
    assert lut.shape == (256, 3) and lut.dtype == np.uint8
    assert tuple(lut[0]) == (0, 0, 128) and tuple(lut[-1]) == (128, 0, 0)


def test_field_colour_comes_from_lut() -> None:
    grid = Grid2D(8, 4, 0.25)
    state = _state(grid)
    # Speed rising along x: cell column i has speed i.
    state.velocity_x[:] = np.arange(grid.nx + 1)[:, None] - 0.5
    state.velocity_x[0] = 0.0
    speed = speed_at_cells(state)
    image = render_frame(grid, state, view="speed", scale=10, value_range=(0.0, 8.0))
    row, col = _pixel(grid, 10, 0.25 * 3.5, 0.5)
    expected = colormap_lut("jet")[int(speed[3, 2] * 255 / 8)]
    assert tuple(image[row, col]) == tuple(expected)


def test_body_and_obstacle_drawn_where_their_geometry_is() -> None:
    grid = Grid2D(32, 32, 1.0 / 32)
    scale = 8
    points = np.array([[0.5, 0.3], [0.9, 0.3], [0.9, 0.7]])
    triangles = np.array([[0, 1, 2]])
    angles = np.linspace(0.0, 2 * np.pi, 48, endpoint=False)
    circle = np.column_stack((0.2 + 0.1 * np.cos(angles), 0.6 + 0.1 * np.sin(angles)))
    image = render_frame(grid, _state(grid, 1.0), [(points, triangles)], [circle], "speed",
                         time=0.5, scale=scale)
    centroid = points.mean(axis=0)
    assert tuple(image[_pixel(grid, scale, *centroid)]) == tuple(BODY_FILL_COLOR)
    assert tuple(image[_pixel(grid, scale, 0.2, 0.6)]) == tuple(OBSTACLE_FILL_COLOR)
    # Outside both: the field colour (uniform speed 1 -> top of the colour map).
    assert tuple(image[_pixel(grid, scale, 0.3, 0.2)]) == tuple(colormap_lut("jet")[255])
    # Mirror position of the triangle's centroid lies outside it.
    assert tuple(image[_pixel(grid, scale, centroid[0], 1.0 - centroid[1])]) != tuple(
        BODY_FILL_COLOR)


def test_colour_bar_panel_holds_the_colour_map() -> None:
    grid = Grid2D(16, 16, 1.0 / 16)
    image = render_frame(grid, _state(grid), view="vorticity", scale=16)
    field_width = 16 * 16
    assert image.shape[1] > field_width and image.shape[0] % 2 == 0 and image.shape[1] % 2 == 0
    panel = image[:, field_width:].reshape(-1, 3)
    lut = colormap_lut("diverging")
    for entry in (lut[0], lut[128], lut[255]):
        assert np.any(np.all(panel == entry, axis=1))
    without = render_frame(grid, _state(grid), view="vorticity", scale=16, colorbar=False)
    assert without.shape[1] == field_width


def test_vorticity_of_solid_rotation_is_twice_the_rate() -> None:
    grid = Grid2D(8, 8, 0.125)
    omega = 1.5
    _, yu = grid.faces_x()
    xv, _ = grid.faces_y()
    state = SimpleNamespace(velocity_x=-omega * (yu - 0.5), velocity_y=omega * (xv - 0.5))
    vorticity = vorticity_at_cells(state, grid.h)
    np.testing.assert_allclose(vorticity[1:-1, 1:-1], 2 * omega, rtol=1e-12)


def test_unknown_view_names_allowed_views() -> None:
    grid = Grid2D(4, 4, 0.25)
    with pytest.raises(ValueError, match="view = 'temperature'"):
        render_frame(grid, _state(grid), view="temperature")


def test_video_writer_mp4_reads_back_and_leaves_no_temporary(tmp_path) -> None:
    import imageio.v2 as imageio

    frames = [np.full((31, 45, 3), 20 * k, dtype=np.uint8) for k in range(5)]
    with VideoWriter(tmp_path / "v.mp4", fps=10) as video:
        for frame in frames:
            video.append(frame)
    assert video.fallback_reason is None
    assert sorted(p.name for p in tmp_path.iterdir()) == ["v.mp4"]
    reader = imageio.get_reader(tmp_path / "v.mp4")
    read = [f for f in reader]
    reader.close()
    assert len(read) == 5 and read[0].shape == (32, 46, 3)


def test_video_writer_falls_back_to_gif(tmp_path, monkeypatch) -> None:
    def broken(self: VideoWriter) -> None:
        raise RuntimeError("no ffmpeg here")

    monkeypatch.setattr(VideoWriter, "_open_ffmpeg", broken)
    with VideoWriter(tmp_path / "v.mp4", fps=10) as video:
        for k in range(3):
            video.append(np.full((8, 8, 3), 50 * k, dtype=np.uint8))
    assert video.path == tmp_path / "v.gif" and "no ffmpeg" in (video.fallback_reason or "")
    from PIL import Image

    with Image.open(tmp_path / "v.gif") as gif:
        assert gif.n_frames == 3
    assert sorted(p.name for p in tmp_path.iterdir()) == ["v.gif"]


def test_video_writer_rejects_changing_size(tmp_path) -> None:
    with VideoWriter(tmp_path / "v.gif") as video:
        video.append(np.zeros((8, 8, 3), np.uint8))
        with pytest.raises(ValueError, match="frame size"):
            video.append(np.zeros((10, 8, 3), np.uint8))


def test_cached_colour_bar_labels_follow_the_value_range() -> None:
    grid = Grid2D(32, 32, 1.0 / 32)
    state = _state(grid, 0.5)
    field_width = 32 * 16
    first = render_frame(grid, state, view="speed", scale=16, value_range=(0.0, 1.0))
    again = render_frame(grid, state, view="speed", scale=16, value_range=(0.0, 1.0))
    other = render_frame(grid, state, view="speed", scale=16, value_range=(0.0, 7.0))
    back = render_frame(grid, state, view="speed", scale=16, value_range=(0.0, 1.0))
    np.testing.assert_array_equal(first, again)
    np.testing.assert_array_equal(first, back)
    # Same field colour scale aside, only the labels differ: the panel changes, the ramp not.
    assert np.any(first[:, field_width:] != other[:, field_width:])
    ramp_column = field_width + 32 // 2 + 2 + 4
    np.testing.assert_array_equal(first[:, ramp_column], other[:, ramp_column])
    # Labels are drawn on the panel: dark pixels right of the ramp, different per range.
    labels_first = first[:, ramp_column + 16:].min(axis=-1) < 128
    labels_other = other[:, ramp_column + 16:].min(axis=-1) < 128
    assert labels_first.any() and labels_other.any()
    assert np.any(labels_first != labels_other)


def test_video_writer_rejects_unknown_preset(tmp_path) -> None:
    with pytest.raises(ValueError, match="preset = 'quick'"):
        VideoWriter(tmp_path / "v.mp4", preset="quick")


def test_rgb_to_yuv420_gives_bt601_limited_range_values() -> None:
    from elastoflow.render._kernels import rgb_to_yuv420

    # Left half white, right half pure red; bottom rows black: 4 x 4 pixels.
    image = np.zeros((4, 4, 3), dtype=np.uint8)
    image[:2, :2] = 255
    image[:2, 2:] = (255, 0, 0)
    out = np.empty(4 * 4 * 3 // 2, dtype=np.uint8)
    rgb_to_yuv420(image, out)
    y, u, v = out[:16].reshape(4, 4), out[16:20].reshape(2, 2), out[20:].reshape(2, 2)
    # Published BT.601 studio-swing values: white (235, 128, 128), red (81, 90, 240),
    # black (16, 128, 128).
    assert y[0, 0] == 235 and y[0, 3] == 81 and y[3, 0] == 16
    assert (u[0, 0], v[0, 0]) == (128, 128) and (u[0, 1], v[0, 1]) == (90, 240)
    assert (u[1, 0], v[1, 0]) == (128, 128)


def test_video_writer_background_frames_arrive_complete_and_in_order(tmp_path) -> None:
    import imageio.v2 as imageio

    levels = [16 + 18 * k for k in range(12)]
    # One array redrawn for every frame, as OutputSession does: append must have taken
    # each frame before the next one overwrites it.
    frame = np.empty((48, 64, 3), dtype=np.uint8)
    with VideoWriter(tmp_path / "v.mp4", fps=10) as video:
        for level in levels:
            frame[...] = level
            frame[:, :8] = 255 - level
            video.append(frame)
    assert video.fallback_reason is None and video.frame_count == len(levels)
    reader = imageio.get_reader(tmp_path / "v.mp4")
    read = [f for f in reader]
    reader.close()
    assert len(read) == len(levels)
    means = np.array([f[:, 16:].mean() for f in read])
    np.testing.assert_allclose(means, levels, atol=3.0)
    assert np.all(np.diff(means) > 10.0)


def test_video_writer_falls_back_to_gif_when_ffmpeg_dies_mid_run(tmp_path) -> None:
    with VideoWriter(tmp_path / "v.mp4", fps=10) as video:
        for k in range(3):
            video.append(np.full((16, 16, 3), 40 * k, dtype=np.uint8))
        assert video._encoder is not None
        video._encoder._process.kill()
        video._encoder._process.wait()
        # More frames than the queue holds: one of these appends must see the failure.
        for k in range(6):
            video.append(np.full((16, 16, 3), 20 * k, dtype=np.uint8))
        assert "ffmpeg failed" in (video.fallback_reason or "")
    assert video.path == tmp_path / "v.gif"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["v.gif"]
    from PIL import Image

    with Image.open(tmp_path / "v.gif") as gif:
        assert 1 <= gif.n_frames <= 6


def test_video_writer_rejects_quality_out_of_range(tmp_path) -> None:
    with pytest.raises(ValueError, match="quality = 0"):
        VideoWriter(tmp_path / "v.mp4", quality=0)


def test_default_value_range_skips_non_finite_values() -> None:
    from elastoflow.render import default_value_range

    values = np.array([[np.nan, -3.0, 2.0], [np.inf, 0.5, -np.inf]])
    assert default_value_range(values, "pressure") == (-3.0, 2.0)
    assert default_value_range(values, "vorticity") == (-3.0, 3.0)
    assert default_value_range(values, "speed") == (0.0, 2.0)
    assert default_value_range(np.full((2, 2), np.nan), "speed") == (0.0, 1.0)
    assert default_value_range(np.full((2, 2), 4.0), "pressure") == (3.0, 5.0)


def test_render_frame_into_a_reused_array_equals_a_fresh_frame() -> None:
    grid = Grid2D(16, 12, 1.0 / 16)
    points = np.array([[0.2, 0.2], [0.6, 0.25], [0.4, 0.6]])
    body = (points, np.array([[0, 1, 2]]))
    first = render_frame(grid, _state(grid, 0.3), [body], view="speed", time=0.1)
    state = _state(grid, 1.0)
    state.velocity_x[5:9] = 2.0
    fresh = render_frame(grid, state, [body], view="speed", time=0.2)
    reused = render_frame(grid, state, [body], view="speed", time=0.2, out=first)
    assert reused is first
    np.testing.assert_array_equal(reused, fresh)
    # A wrong-shaped array is not drawn into.
    other = np.zeros((4, 4, 3), dtype=np.uint8)
    np.testing.assert_array_equal(render_frame(grid, state, [body], view="speed", time=0.2,
                                               out=other), fresh)
    assert not other.any()


def test_rod_is_drawn_as_a_polyline_a_few_pixels_wide() -> None:
    grid = Grid2D(16, 16, 1.0 / 16)
    scale = 4
    line = np.array([[0.5, 0.1], [0.5, 0.5], [0.7, 0.8]])
    image = render_frame(grid, _state(grid), [(line, np.zeros((0, 3), np.int64))],
                         scale=scale, colorbar=False)
    row, col = _pixel(grid, scale, 0.5, 0.3)
    # Body-coloured core with a dark rim across the line; the field beside it untouched.
    across = image[row, col - 4:col + 5]
    core = np.all(across == BODY_FILL_COLOR, axis=1)
    assert 2 <= core.sum() <= 4
    assert not np.any(np.all(image[row, col - 8:col - 5] == BODY_FILL_COLOR, axis=1))
    row, col = _pixel(grid, scale, 0.6, 0.65)
    assert np.any(np.all(image[row - 2:row + 3, col - 2:col + 3] == BODY_FILL_COLOR, axis=2))
