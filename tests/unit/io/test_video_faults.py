"""A video whose encoder fails while finishing it (a full or read-only disk): an error that
says so, never a success with the frames lost (``render`` said "wrote v.gif (3 frames)" and
wrote nothing; a run lost the segment's frames without a word)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from elastoflow.render import SegmentedVideo, VideoWriter

_FAILING_FFMPEG = """#!/bin/sh
cat > /dev/null
echo "[out#0/mp4] Error opening output files: No space left on device" >&2
exit 1
"""


@pytest.fixture()
def failing_ffmpeg(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """ffmpeg that takes every frame, then fails to write its file."""
    import imageio_ffmpeg

    script = tmp_path / "bin" / "ffmpeg"
    script.parent.mkdir()
    script.write_text(_FAILING_FFMPEG)
    os.chmod(script, 0o755)
    monkeypatch.setattr(imageio_ffmpeg, "get_ffmpeg_exe", lambda: str(script))
    return script


def test_an_encoder_failing_at_the_end_is_an_error_and_leaves_nothing(
        tmp_path: Path, failing_ffmpeg: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    video = VideoWriter(out / "v.mp4", fps=10)
    for k in range(3):
        video.append(np.full((16, 16, 3), 40 * k, dtype=np.uint8))
    with pytest.raises(OSError, match="No space left on device"):
        video.close()
    assert list(out.iterdir()) == []


def test_a_segment_that_cannot_be_finished_stops_the_run(tmp_path: Path,
                                                         failing_ffmpeg: Path) -> None:
    video = SegmentedVideo(tmp_path / "video.mp4", fps=10)
    video.append(np.zeros((16, 16, 3), dtype=np.uint8))
    with pytest.raises(OSError, match="No space left on device"):
        video.cut(5)
    assert video.segments() == []
    assert [p.name for p in video.parts.iterdir()] == []


def test_render_says_it_could_not_write(tmp_path: Path, failing_ffmpeg: Path) -> None:
    from typer.testing import CliRunner

    from elastoflow.cli import app
    from elastoflow.grid import Grid2D
    from elastoflow.io import FieldWriter, snapshot_arrays
    from elastoflow.fluid import FluidState

    grid = Grid2D(8, 8, 1 / 8)
    writer = FieldWriter(tmp_path / "run" / "fields", grid, ["npz"])
    for step in (0, 1):
        writer.write(snapshot_arrays(grid, FluidState.zeros(grid), time=0.1 * step, step=step))
    writer.close()
    result = CliRunner().invoke(app, ["render", str(tmp_path / "run")])
    assert result.exit_code == 2, result.output
    assert "No space left on device" in result.output and "wrote" not in result.output
    assert not list((tmp_path / "run").glob("render_*"))


def test_ffmpeg_exiting_with_an_errno_names_it(tmp_path: Path,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    """ffmpeg exits with AVERROR(ENOSPC) & 0xff = 228 when the disk fills, and may say only
    "Nothing was written into output file": the error names the errno."""
    import errno

    import imageio_ffmpeg

    script = tmp_path / "bin" / "ffmpeg"
    script.parent.mkdir()
    script.write_text("#!/bin/sh\ncat > /dev/null\n"
                      "echo 'Nothing was written into output file' >&2\nexit 228\n")
    os.chmod(script, 0o755)
    monkeypatch.setattr(imageio_ffmpeg, "get_ffmpeg_exe", lambda: str(script))
    out = tmp_path / "out"
    out.mkdir()
    video = VideoWriter(out / "v.mp4", fps=10)
    video.append(np.zeros((16, 16, 3), dtype=np.uint8))
    with pytest.raises(OSError, match=r"status 228 \(No space left on device\)") as raised:
        video.close()
    assert raised.value.errno == errno.ENOSPC
    assert list(out.iterdir()) == []
