"""``elastoflow run`` on a tiny 3D scene writes the perspective picture as its video (the
default ``style = "3d"``) or the flat slice (``style = "slice"``), each frame as the renderer
draws the run's state, and a resumed run continues the same video."""

from __future__ import annotations

from pathlib import Path

import imageio.v2 as imageio
import numpy as np
from typer.testing import CliRunner

import elastoflow

from elastoflow.cli import app
from elastoflow.render._scene3d import BACKGROUND_COLOR, SCENE_SIZE

TINY = Path(__file__).with_name("tiny3d.toml")
runner = CliRunner()


def _scene(tmp_path: Path, video: str) -> Path:
    """tiny3d (12x8x8 cells, a sphere obstacle, a box body) with ``video`` as its only
    output, 2 steps."""
    text = TINY.read_text()
    head, outputs = text.split("[outputs]")
    head = head.replace("steps = 6", "steps = 2")
    scene = tmp_path / "tiny.toml"
    scene.write_text(f"{head}[outputs]\nvideo = {video}\n")
    return scene


def _frames(path: Path) -> list[np.ndarray]:
    reader = imageio.get_reader(path)
    frames = [np.asarray(frame) for frame in reader]
    reader.close()
    return frames


def test_a_3d_run_video_shows_the_scene_in_perspective_and_resumes(tmp_path: Path) -> None:
    scene = _scene(tmp_path, '{ view = "speed", fps = 10 }')
    out = tmp_path / "out"
    result = runner.invoke(app, ["run", str(scene), "--out", str(out), "--quiet",
                                 "--checkpoint-every", "1"])
    assert result.exit_code == 0, result.output
    frames = _frames(out / "video.mp4")
    assert len(frames) == 3  # the initial state and one per step
    height, width = frames[0].shape[:2]
    assert height == SCENE_SIZE[1] and width > SCENE_SIZE[0]
    # The dark background around the box (lossy h264: within a few levels).
    corner = frames[-1][SCENE_SIZE[1] - 40, 8].astype(int)
    assert np.abs(corner - BACKGROUND_COLOR).max() < 12
    assert "style = \"3d\"" in (out / "scene.toml").read_text()
    # The first frame is the picture the Python API draws of the same initial state.
    picture = elastoflow.frame(elastoflow.load(scene), "speed", style="3d")
    assert frames[0].shape == picture.shape
    assert np.abs(frames[0].astype(int) - picture).mean() < 3.0

    result = runner.invoke(app, ["run", str(scene), "--out", str(out), "--quiet", "--resume",
                                 "--steps", "3"])
    assert result.exit_code == 0, result.output
    assert len(_frames(out / "video.mp4")) == 4


def test_style_slice_keeps_the_flat_slice(tmp_path: Path) -> None:
    scene = _scene(tmp_path, '{ view = "speed", fps = 10, style = "slice" }')
    out = tmp_path / "out"
    result = runner.invoke(app, ["run", str(scene), "--out", str(out), "--quiet",
                                 "--checkpoint-every", "0"])
    assert result.exit_code == 0, result.output
    frame = _frames(out / "video.mp4")[0]
    # A z-slice of 12 x 8 cells, 43 pixels each, as render_slice_3d draws it.
    assert frame.shape[0] == 8 * 43
    assert "style = \"slice\"" in (out / "scene.toml").read_text()


def test_the_camera_can_be_turned_in_the_scene_file(tmp_path: Path) -> None:
    scene = _scene(tmp_path, '{ view = "vorticity", fps = 10, azimuth = -40.0, '
                             'elevation = -15.0 }')
    out = tmp_path / "out"
    result = runner.invoke(app, ["run", str(scene), "--out", str(out), "--quiet", "--steps",
                                 "1", "--checkpoint-every", "0"])
    assert result.exit_code == 0, result.output
    frame = _frames(out / "video.mp4")[0]
    simulation = elastoflow.load(scene)
    turned = elastoflow.frame(simulation, "vorticity", style="3d", azimuth=-40.0,
                              elevation=-15.0)
    default = elastoflow.frame(simulation, "vorticity", style="3d")
    assert np.abs(frame.astype(int) - turned).mean() < 3.0
    assert np.abs(frame.astype(int) - default).mean() > 10.0
