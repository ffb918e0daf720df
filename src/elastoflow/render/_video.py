"""Video files from RGB frames: MP4 (h264, yuv420p) through imageio-ffmpeg, GIF as fallback."""

from __future__ import annotations

import contextlib
import os
from pathlib import Path
from types import TracebackType
from typing import Any, Self

import numpy as np

from elastoflow.render._kernels import rgb_to_yuv420

_X264_PRESETS = ("ultrafast", "superfast", "veryfast", "faster", "fast", "medium", "slow",
                 "slower", "veryslow")


def _even(frame: np.ndarray) -> np.ndarray:
    """Pad to even height and width by repeating the last row/column (h264 needs even sizes)."""
    height, width = frame.shape[:2]
    if height % 2 == 0 and width % 2 == 0:
        return frame
    return np.pad(frame, ((0, height % 2), (0, width % 2), (0, 0)), mode="edge")


class VideoWriter:
    """Context manager that writes frames to a video, atomically.

    Frames go to a temporary file beside ``path``; `close` (or leaving the ``with`` block, also
    on an exception or Ctrl-C) finishes it and renames it to ``path``, so the file at ``path``
    is always a complete video. If ffmpeg cannot be started or fails, the frames go to a GIF
    (``path`` with suffix ``.gif``) instead; `path` then names the file actually written.

    Args:
        path: Output file (``.mp4``; ``.gif`` writes a GIF directly).
        fps: Frames per second.
        quality: imageio-ffmpeg quality, 0-10.
        preset: x264 speed preset. The encoder shares the CPU with the simulation, so its CPU
            is what a video costs a run: per 614x512 frame at quality 7 (crf 15), one encoder
            thread, ``"ultrafast"`` takes ~2.1 ms, ``"superfast"`` ~3.5 ms and x264's default
            ``"medium"`` ~8 ms, all at PSNR ~41 dB; ``"ultrafast"`` files are about three
            times larger than ``"medium"`` ones (~7 kB per frame).

    Example:
        >>> with VideoWriter("out/run.mp4", fps=30) as video:  # doctest: +SKIP
        ...     video.append(frame)
    """

    def __init__(self, path: str | Path, fps: int = 30, quality: float = 7.0,
                 preset: str = "ultrafast") -> None:
        if preset not in _X264_PRESETS:
            raise ValueError(f"preset = {preset!r}: must be one of {_X264_PRESETS}")
        self.path = Path(path)
        self.fps = int(fps)
        self.quality = quality
        self.preset = preset
        self.frame_count = 0
        self.fallback_reason: str | None = None
        self._writer: Any = None
        self._temporary: Path | None = None
        self._frames_for_gif: list[np.ndarray] = []
        self._format = "gif" if self.path.suffix.lower() == ".gif" else "mp4"
        self._size: tuple[int, int] | None = None
        self._yuv = np.empty(0, dtype=np.uint8)

    def __enter__(self) -> Self:
        return self

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self.close()

    def _open_ffmpeg(self) -> None:
        import imageio_ffmpeg

        assert self._size is not None
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._temporary = self.path.with_name(f".{self.path.stem}.{os.getpid()}.tmp.mp4")
        height, width = self._size
        self._writer = imageio_ffmpeg.write_frames(
            str(self._temporary), (width, height), pix_fmt_in="yuv420p", pix_fmt_out="yuv420p",
            fps=self.fps, codec="libx264", quality=self.quality, macro_block_size=1,
            # One encoder thread: with ultrafast it keeps far ahead of a simulation, and
            # threads only add synchronisation CPU taken from the run.
            output_params=["-preset", self.preset, "-threads", "1"],
            ffmpeg_log_level="error",
        )
        self._writer.send(None)
        self._yuv = np.empty(height * width * 3 // 2, dtype=np.uint8)

    def _fall_back(self, error: Exception) -> None:
        self.fallback_reason = f"ffmpeg failed ({error}); writing a GIF instead"
        if self._writer is not None:
            # The writer is broken already; closing it is only a courtesy.
            with contextlib.suppress(Exception):
                self._writer.close()
        self._writer = None
        self._discard_temporary()
        self._format = "gif"
        self.path = self.path.with_suffix(".gif")

    def append(self, frame: np.ndarray) -> None:
        """Add one RGB frame (H, W, 3) uint8; every frame must have the first one's size."""
        frame = _even(np.ascontiguousarray(frame, dtype=np.uint8))
        size = (frame.shape[0], frame.shape[1])
        if self._size is None:
            self._size = size
        elif size != self._size:
            raise ValueError(f"frame size {size}: must match the first frame's {self._size}")
        if self._format == "mp4":
            try:
                if self._writer is None:
                    self._open_ffmpeg()
                rgb_to_yuv420(frame, self._yuv)
                self._writer.send(self._yuv)
            except Exception as error:  # noqa: BLE001 - any ffmpeg failure means: use GIF
                self._fall_back(error)
        if self._format == "gif":
            self._frames_for_gif.append(frame)
        self.frame_count += 1

    def close(self) -> Path | None:
        """Finish the file and move it into place; returns its path (None if no frames)."""
        if self._format == "mp4" and self._writer is not None:
            try:
                self._writer.close()
            except Exception as error:  # noqa: BLE001
                self._fall_back(error)
            else:
                self._writer = None
                os.replace(self._temporary, self.path)  # type: ignore[arg-type]
                self._temporary = None
                return self.path
        if self._format == "gif" and self._frames_for_gif:
            self._write_gif()
            self._frames_for_gif = []
            return self.path
        return self.path if self.path.exists() else None

    def _write_gif(self) -> None:
        from PIL import Image

        self.path.parent.mkdir(parents=True, exist_ok=True)
        temporary = self.path.with_name(f".{self.path.stem}.{os.getpid()}.tmp.gif")
        images = [Image.fromarray(f) for f in self._frames_for_gif]
        try:
            images[0].save(temporary, save_all=True, append_images=images[1:],
                           duration=max(1, round(1000 / self.fps)), loop=0)
            os.replace(temporary, self.path)
        finally:
            if temporary.exists():
                temporary.unlink()

    def _discard_temporary(self) -> None:
        if self._temporary is not None and self._temporary.exists():
            self._temporary.unlink()
        self._temporary = None
