"""``elastoflow render`` of damaged field snapshots: exit 2, one line naming the file and what
is wrong, no video and no temporary left. The drawing kernels do not check bounds, so a
snapshot whose arrays do not fit each other rendered garbage (or hung) without a word."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from elastoflow.cli import app

N = 8


def _snapshot(step: int, n: int = N) -> dict[str, np.ndarray]:
    h = 1.0 / n
    return {
        "velocity_x": np.full((n + 1, n), 0.1 * step), "velocity_y": np.zeros((n, n + 1)),
        "pressure": np.zeros((n, n)), "dye": np.zeros((n, n)), "h": np.array(h),
        "origin": np.zeros(2), "time": np.array(0.1 * step), "step": np.array(step),
        "body0_points": np.array([[0.4, 0.4], [0.6, 0.4], [0.6, 0.6], [0.4, 0.6]]),
        "body0_triangles": np.array([[0, 1, 2], [0, 2, 3]]),
        "obstacle0_points": np.array([[0.1, 0.1], [0.2, 0.1], [0.15, 0.2]]),
    }


def _run_folder(tmp_path: Path, damage: Callable[[dict[str, np.ndarray]], None] | None = None,
                last: dict[str, np.ndarray] | None = None) -> Path:
    fields = tmp_path / "run" / "fields"
    fields.mkdir(parents=True)
    for step in (0, 1, 2):
        data = _snapshot(step)
        if step == 2:
            if last is not None:
                data = last
            if damage is not None:
                damage(data)
        np.savez(fields / f"step_{step:06d}.npz", **data)
    return tmp_path / "run"


DAMAGES: dict[str, tuple[Callable[[dict[str, np.ndarray]], None], str]] = {
    "velocity shape": (lambda d: d.update(velocity_x=np.zeros((3, 3))), "velocity_x"),
    "triangle index": (lambda d: d.update(body0_triangles=d["body0_triangles"] + 1000),
                       "body0_triangles index nodes"),
    "negative index": (lambda d: d.update(body0_triangles=d["body0_triangles"] - 1000),
                       "body0_triangles index nodes"),
    "nan body": (lambda d: d.update(body0_points=np.full((4, 2), np.nan)), "non-finite"),
    "origin": (lambda d: d.update(origin=np.zeros(1)), "origin"),
    "text time": (lambda d: d.update(time=np.array("abc")), "time"),
    "flat points": (lambda d: d.update(body0_points=np.zeros(5)), "body0_points"),
    "float triangles": (lambda d: d.update(body0_triangles=np.zeros((2, 3))), "integers"),
    "no triangles": (lambda d: d.pop("body0_triangles"), "body 0 lacks its triangles"),
    "obstacle": (lambda d: d.update(obstacle0_points=np.array([np.inf, 0.0])), "obstacle0"),
}


@pytest.mark.parametrize("case", list(DAMAGES))
def test_a_damaged_snapshot_is_one_line_and_no_video(case: str, tmp_path: Path) -> None:
    damage, says = DAMAGES[case]
    run = _run_folder(tmp_path, damage)
    result = CliRunner().invoke(app, ["render", str(run)])
    assert result.exit_code == 2, result.output
    assert isinstance(result.exception, SystemExit), result.output
    errors = [line for line in result.output.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "step_000002.npz" in errors[0] and says in errors[0], errors
    assert sorted(p.name for p in run.iterdir()) == ["fields"]


def test_snapshots_of_two_grids_are_refused_before_any_video(tmp_path: Path) -> None:
    run = _run_folder(tmp_path, last=_snapshot(2, n=2 * N))
    result = CliRunner().invoke(app, ["render", str(run)])
    assert result.exit_code == 2, result.output
    assert "step_000002.npz is of another grid (16x16" in result.output
    assert sorted(p.name for p in run.iterdir()) == ["fields"]


def test_a_body_far_outside_the_picture_is_drawn_at_once(tmp_path: Path) -> None:
    # Segments 1e12 pixels long were drawn sample by sample: render did not end.
    run = _run_folder(tmp_path, lambda d: d.update(body0_points=d["body0_points"] * 1e12))
    result = CliRunner().invoke(app, ["render", str(run)])
    assert result.exit_code == 0, result.output
    assert "wrote" in result.output and "(3 frames)" in result.output


def test_a_long_segment_is_clipped_to_the_image() -> None:
    from elastoflow.render._kernels import draw_segments

    image = np.zeros((10, 20, 3), dtype=np.uint8)
    color = np.array([255, 0, 0], dtype=np.uint8)
    draw_segments(image, np.array([[-1e12, 5.5]]), np.array([[1e12, 5.5]]), color)
    assert (image[5, :, 0] == 255).all() and image[[4, 6], :, 0].max() == 0
    vertical = np.zeros((10, 20, 3), dtype=np.uint8)
    draw_segments(vertical, np.array([[3.5, 1e15]]), np.array([[3.5, -1e15]]), color)
    assert (vertical[:, 3, 0] == 255).all() and vertical[:, [2, 4], 0].max() == 0
    # A segment wholly outside draws nothing; one inside is as before.
    outside = np.zeros((10, 20, 3), dtype=np.uint8)
    draw_segments(outside, np.array([[-50.0, -50.0]]), np.array([[-1e9, 3.0]]), color)
    assert outside.max() == 0
    inside = np.zeros((10, 20, 3), dtype=np.uint8)
    draw_segments(inside, np.array([[2.5, 2.5]]), np.array([[7.5, 2.5]]), color)
    assert inside[2, 2:8, 0].tolist() == [255] * 6 and inside[:, :2].max() == 0


def test_the_temporary_of_a_killed_render_is_removed(tmp_path: Path) -> None:
    import subprocess
    import sys

    run = _run_folder(tmp_path)
    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    dead = int(gone.stdout)  # a process that has ended: its temporary is stale
    stale = run / f".render_speed.{dead}.tmp.mp4"
    stale.write_bytes(b"half a video")
    alive = run / f".render_speed.{os.getppid()}.tmp.mp4"  # a process still running
    alive.write_bytes(b"being written")
    result = CliRunner().invoke(app, ["render", str(run)])
    assert result.exit_code == 0, result.output
    assert not stale.exists() and alive.exists()
    assert (run / "render_speed.mp4").exists()
