"""Video files from RGB frames: MP4 (h264, yuv420p) through imageio-ffmpeg, GIF as fallback."""

from __future__ import annotations

import contextlib
import errno
import os
import queue
import subprocess
import tempfile
import threading
from fractions import Fraction
from pathlib import Path
from types import TracebackType
from typing import Self

import numpy as np

from elastoflow.render._kernels import rgb_to_yuv420

_X264_PRESETS = ("ultrafast", "superfast", "veryfast", "faster", "fast", "medium", "slow",
                 "slower", "veryslow")
# Converted frames waiting for (or being written to) ffmpeg: enough to ride out the moments
# when the encoder, which shares the CPU with the simulation, falls behind by a frame or two.
_QUEUED_FRAMES = 3
# A pipe that holds whole frames (~0.5 MB at 614x512), so a write rarely waits for ffmpeg to
# read; Linux's default of 64 kB makes every frame a dozen round trips between the processes.
_PIPE_BYTES = 1 << 20


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

    `append` converts a frame to YUV at once and hands it to a background thread that pipes
    it to ffmpeg, in order, so the run does not wait for the encoder; at most a few frames
    are in flight, and `close` writes them all before finishing the file. A failure of
    ffmpeg shows at the next `append` or at `close`; the frames in flight then are lost.

    Args:
        path: Output file (``.mp4``; ``.gif`` writes a GIF directly).
        fps: Frames per second.
        quality: imageio-ffmpeg quality, 1-10 (x264 crf ``int((1 - quality / 10) * 51)``).
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
        if not 1.0 <= quality <= 10.0:
            raise ValueError(f"quality = {quality!r}: must be between 1 and 10")
        self.path = Path(path)
        self.fps = int(fps)
        self.quality = quality
        self.preset = preset
        self.frame_count = 0
        self.fallback_reason: str | None = None
        self._encoder: _Encoder | None = None
        self._temporary: Path | None = None
        self._frames_for_gif: list[np.ndarray] = []
        self._format = "gif" if self.path.suffix.lower() == ".gif" else "mp4"
        self._size: tuple[int, int] | None = None

    def __enter__(self) -> Self:
        return self

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self.close()

    def _open_ffmpeg(self) -> None:
        assert self._size is not None
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._temporary = self.path.with_name(f".{self.path.stem}.{os.getpid()}.tmp.mp4")
        height, width = self._size
        self._encoder = _Encoder(self._temporary, width, height, self.fps, self.quality,
                                 self.preset)

    def _fall_back(self, error: Exception) -> None:
        self.fallback_reason = f"ffmpeg failed ({error}); writing a GIF instead"
        if self._encoder is not None:
            # The encoder is broken already; stopping it is only a courtesy.
            self._encoder.abort()
        self._encoder = None
        self._discard_temporary()
        self._format = "gif"
        self.path = self.path.with_suffix(".gif")

    def append(self, frame: np.ndarray) -> None:
        """Add one RGB frame (H, W, 3) uint8; every frame must have the first one's size.

        The frame is converted at once, so the caller may reuse its array afterwards; the
        encoder receives it in the background, in order.
        """
        frame = _even(np.ascontiguousarray(frame, dtype=np.uint8))
        size = (frame.shape[0], frame.shape[1])
        if self._size is None:
            self._size = size
        elif size != self._size:
            raise ValueError(f"frame size {size}: must match the first frame's {self._size}")
        if self._format == "mp4":
            try:
                if self._encoder is None:
                    self._open_ffmpeg()
                assert self._encoder is not None
                self._encoder.send(frame)
            except Exception as error:  # noqa: BLE001 - any ffmpeg failure means: use GIF
                self._fall_back(error)
        if self._format == "gif":
            # Copied: callers may draw the next frame into the same array.
            self._frames_for_gif.append(frame.copy())
        self.frame_count += 1

    def close(self) -> Path | None:
        """Finish the file and move it into place; returns its path (None if no frames).

        Raises:
            OSError: ffmpeg failed while finishing the file (a read-only or full disk): the
                frames it held are lost, no file is left (never a GIF without them).
        """
        if self._format == "mp4" and self._encoder is not None:
            encoder, self._encoder = self._encoder, None
            try:
                encoder.close()
            except Exception as error:
                self._discard_temporary()
                # Keep the errno (a full disk stays ENOSPC for the caller), not its "[Errno N]".
                if isinstance(error, OSError) and error.errno is not None:
                    raise OSError(error.errno, f"video not written: {error.strerror}") from None
                raise OSError(f"video not written: {error}") from None
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

    def abort(self) -> None:
        """Stop without writing the file (after an error while producing the frames): no
        temporary is left, nothing is written at `path`."""
        if self._encoder is not None:
            self._encoder.abort()
            self._encoder = None
        self._discard_temporary()
        self._frames_for_gif = []

    def _discard_temporary(self) -> None:
        if self._temporary is not None and self._temporary.exists():
            self._temporary.unlink()
        self._temporary = None


class _Encoder:
    """An ffmpeg process encoding planar YUV 4:2:0 frames to an h264 mp4, fed from a thread.

    `send` converts a frame into a free buffer and queues it; a writer thread pipes queued
    buffers to ffmpeg in order (the write releases the GIL, so the simulation goes on) and
    hands them back. With all buffers in flight `send` waits, so memory stays bounded. A
    failed write is raised by the next `send` or by `close`.

    The command line is the one ``imageio_ffmpeg.write_frames`` builds for these settings,
    so the file is the same as before the encoder ran in the background.
    """

    def __init__(self, path: Path, width: int, height: int, fps: int, quality: float,
                 preset: str) -> None:
        import imageio_ffmpeg

        crf = int((1.0 - quality / 10.0) * 51)
        command = [
            imageio_ffmpeg.get_ffmpeg_exe(), "-y", "-f", "rawvideo", "-vcodec", "rawvideo",
            "-s", f"{width}x{height}", "-pix_fmt", "yuv420p",
            "-r", str(Fraction(fps).limit_denominator()), "-i", "-", "-an",
            "-vcodec", "libx264", "-pix_fmt", "yuv420p", "-crf", str(crf), "-v", "error",
            # One encoder thread: with ultrafast it keeps far ahead of a simulation, and
            # threads only add synchronisation CPU taken from the run.
            "-preset", preset, "-threads", "1", str(path),
        ]
        # Own process group: Ctrl-C stops the run, not the encoder, so `close` still
        # finishes the file.
        group = ({"process_group": 0} if os.name == "posix"
                 else {"creationflags": getattr(subprocess, "CREATE_NEW_PROCESS_GROUP", 0)})
        # ffmpeg's own messages go to a file, read back into the error when it fails (not
        # onto the user's terminal, and no pipe that could fill up).
        self._log = tempfile.TemporaryFile()  # noqa: SIM115 - closed in close/abort
        self._process = subprocess.Popen(command, stdin=subprocess.PIPE,
                                         stdout=subprocess.DEVNULL, stderr=self._log, **group)
        assert self._process.stdin is not None
        self._stdin = self._process.stdin
        with contextlib.suppress(AttributeError, OSError):
            import fcntl

            fcntl.fcntl(self._stdin.fileno(), fcntl.F_SETPIPE_SZ, _PIPE_BYTES)
        frame_bytes = height * width * 3 // 2
        self._free: queue.SimpleQueue[np.ndarray] = queue.SimpleQueue()
        for _ in range(_QUEUED_FRAMES):
            self._free.put(np.empty(frame_bytes, dtype=np.uint8))
        self._queued: queue.SimpleQueue[np.ndarray | None] = queue.SimpleQueue()
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._write_queued, name="elastoflow-video",
                                        daemon=True)
        self._thread.start()

    def _write_queued(self) -> None:
        descriptor = self._stdin.fileno()
        try:
            while (buffer := self._queued.get()) is not None:
                remaining = memoryview(buffer.data)
                while remaining:
                    remaining = remaining[os.write(descriptor, remaining):]
                self._free.put(buffer)
        except BaseException as error:  # noqa: BLE001 - handed to the caller's thread
            self._error = error

    def _said(self) -> str:
        """ffmpeg's last message, if any."""
        try:
            self._log.seek(0)
            lines = self._log.read().decode("utf-8", "replace").strip().splitlines()
        except (OSError, ValueError):
            return ""
        return f": {lines[-1].strip()}" if lines else ""

    def _raise_if_failed(self) -> None:
        if self._error is not None:
            with contextlib.suppress(subprocess.TimeoutExpired):
                self._process.wait(timeout=1.0)
            raise OSError(f"writing a frame to ffmpeg failed: {self._error}"
                          f"{self._said()}") from self._error

    def send(self, frame: np.ndarray) -> None:
        """Queue one RGB frame (H, W, 3) uint8, H and W even, of the size given at start."""
        while True:
            self._raise_if_failed()
            try:
                buffer = self._free.get(timeout=0.05)
                break
            except queue.Empty:
                continue
        rgb_to_yuv420(frame, buffer)
        self._queued.put(buffer)

    def close(self) -> None:
        """Write what is queued, end the stream and wait for ffmpeg to finish the file."""
        try:
            self._queued.put(None)
            self._thread.join()
            self._raise_if_failed()
            self._stdin.close()
            status = self._process.wait()
        except BaseException:
            self.abort()
            raise
        said = self._said()
        self._log.close()
        if status != 0:
            code = _ffmpeg_errno(status)
            if code is not None:
                raise OSError(code, f"ffmpeg exited with status {status} "
                                    f"({os.strerror(code)}){said}")
            raise OSError(f"ffmpeg exited with status {status}{said}")

    def abort(self) -> None:
        """Stop ffmpeg and the writer thread without finishing the file."""
        with contextlib.suppress(OSError):
            self._process.kill()
        self._queued.put(None)
        self._thread.join(timeout=5.0)
        with contextlib.suppress(OSError, ValueError):
            self._stdin.close()
        with contextlib.suppress(subprocess.TimeoutExpired):
            self._process.wait(timeout=5.0)
        self._log.close()


_PART = "upto_"


class SegmentedVideo:
    """A video that survives a killed run: written as segments, each a complete file, and
    joined into one file at the end.

    Frames go to a `VideoWriter` on ``{stem}_parts/``; `cut` (called at every checkpoint)
    finishes the segment and names it after the last step it holds,
    ``{stem}_parts/upto_{step:08d}.mp4``, so after a kill the folder holds complete segments up
    to the last checkpoint (the frames after it are in a temporary file, which a resume
    removes, and drawn again by the resumed run). `close` cuts the last segment and joins them
    all into ``path`` with ffmpeg's concat demuxer (stream copy, no re-encoding). The segments
    are kept, so that a later resume from any kept checkpoint continues the same video.

    Args:
        path: The joined video (``.mp4``).
        fps: Frames per second.
        resume_step: Keep the segments up to this step and delete later ones (a resumed run);
            None deletes every segment (a new run).
    """

    def __init__(self, path: str | Path, fps: int = 30, *, resume_step: int | None = None
                 ) -> None:
        self.path = Path(path)
        self.fps = int(fps)
        self.parts = self.path.with_name(f"{self.path.stem}_parts")
        self.parts.mkdir(parents=True, exist_ok=True)
        for part in self.parts.iterdir():
            step = _part_step(part)
            if part.is_file() and (step is None or resume_step is None or step > resume_step):
                part.unlink()
        self.fallback_reason: str | None = None
        self._writer: VideoWriter | None = None

    def append(self, frame: np.ndarray) -> None:
        """Add one RGB frame (H, W, 3) uint8 to the current segment."""
        if self._writer is None:
            self._writer = VideoWriter(self.parts / "current.mp4", fps=self.fps)
        self._writer.append(frame)

    def cut(self, step: int) -> Path | None:
        """Finish the current segment as the one up to ``step``; returns it (None if no frames
        since the last cut)."""
        writer, self._writer = self._writer, None
        if writer is None:
            return None
        written = writer.close()
        self.fallback_reason = writer.fallback_reason or self.fallback_reason
        if written is None:
            return None
        part = self.parts / f"{_PART}{step:08d}{written.suffix}"
        os.replace(written, part)
        return part

    def segments(self) -> list[Path]:
        """The finished segments, in step order."""
        found = [(step, p) for p in self.parts.iterdir() if (step := _part_step(p)) is not None]
        return [p for _, p in sorted(found)]

    def close(self, step: int) -> Path | None:
        """Cut the last segment at ``step`` and join every segment into `path`; returns the
        file written (None without frames; the folder of segments when they cannot be joined,
        which `fallback_reason` then explains)."""
        self.cut(step)
        segments = self.segments()
        if not segments:
            return None
        if any(p.suffix != ".mp4" for p in segments):
            self.fallback_reason = (f"some segments are GIFs (ffmpeg failed); the video is left "
                                    f"as segments in {self.parts}")
            return self.parts
        join_videos(segments, self.path)
        return self.path


def _part_step(path: Path) -> int | None:
    name = path.name
    if not name.startswith(_PART) or path.suffix not in (".mp4", ".gif"):
        return None
    digits = name[len(_PART):-len(path.suffix)]
    return int(digits) if digits.isdigit() else None


def join_videos(segments: list[Path], path: str | Path) -> Path:
    """Join mp4 files of one encoding into ``path`` (atomically) without re-encoding."""
    import shutil
    import tempfile

    import imageio_ffmpeg

    path = Path(path)
    temporary = path.with_name(f".{path.stem}.{os.getpid()}.tmp{path.suffix}")
    try:
        if len(segments) == 1:
            shutil.copyfile(segments[0], temporary)
        else:
            with tempfile.NamedTemporaryFile("w", suffix=".txt", delete=False) as listing:
                for segment in segments:
                    escaped = str(Path(segment).resolve()).replace("'", "'\\''")
                    listing.write(f"file '{escaped}'\n")
            try:
                result = subprocess.run(
                    [imageio_ffmpeg.get_ffmpeg_exe(), "-y", "-v", "error", "-f", "concat",
                     "-safe", "0", "-i", listing.name, "-c", "copy", "-f", "mp4", str(temporary)],
                    stdin=subprocess.DEVNULL, capture_output=True, text=True, check=False)
            finally:
                os.unlink(listing.name)
            if result.returncode != 0:
                raise OSError(f"joining the video segments failed: {result.stderr.strip()}")
        os.replace(temporary, path)
    finally:
        if temporary.exists():
            temporary.unlink()
    return path


# The file-system errors that ffmpeg reports by exiting with AVERROR(errno) & 0xff, i.e.
# 256 - errno (a full disk: 228): named in the error, as a writer of our own would.
_FILE_SYSTEM_ERRNOS = frozenset(
    code for code in (getattr(errno, name, None) for name in
                      ("ENOSPC", "EDQUOT", "EROFS", "EIO", "EACCES", "EFBIG"))
    if code is not None
)


def _ffmpeg_errno(status: int) -> int | None:
    """The errno behind ffmpeg's exit status, for the file-system errors it exits with."""
    code = 256 - status
    return code if 0 < status < 256 and code in _FILE_SYSTEM_ERRNOS else None
