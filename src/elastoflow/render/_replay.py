"""A video rendered again from saved ``.npz`` snapshots (``elastoflow render``)."""

from __future__ import annotations

import glob
import re
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

from elastoflow.io._checkpoint import damage
from elastoflow.render._frame import (
    default_value_range,
    liquid_values,
    render_frame,
    view_values,
)
from elastoflow.render._video import VideoWriter


def render_saved_frames(folder: str | Path, output: str | Path, *, view: str = "speed",
                        fps: int = 30) -> tuple[Path, int]:
    """Render every ``step_*.npz`` in ``folder`` into a video; one colour range for all frames.

    Returns:
        The video written (GIF if ffmpeg failed) and the number of frames.
    """
    from elastoflow.grid import Grid2D

    paths = sorted(Path(folder).glob("step_*.npz"))
    low, high = np.inf, -np.inf
    snapshots = []
    first: tuple[Any, ...] | None = None
    for path in paths:
        data = _read_snapshot(path)
        nx, ny = data["pressure"].shape
        try:
            grid = Grid2D(nx=nx, ny=ny, h=float(data["h"]), origin=tuple(data["origin"]))
        except (ValueError, TypeError) as error:
            raise ValueError(f"field snapshot {path} is damaged: {error}") from None
        shape = (nx, ny, float(data["h"]), tuple(float(v) for v in data["origin"]))
        if first is None:
            first = (path, *shape)
        elif shape != first[1:]:
            raise ValueError(f"field snapshot {path} is of another grid ({nx}x{ny} cells of "
                             f"{shape[2]:.6g} m) than {first[0].name} ({first[1]}x{first[2]} "
                             f"of {first[3]:.6g} m): the folder holds snapshots of two runs; "
                             "render one run's")
        state = SimpleNamespace(velocity_x=data["velocity_x"], velocity_y=data["velocity_y"],
                                pressure=data["pressure"], dye=data["dye"])
        values = view_values(grid, state, view)
        if "level_set" in data:
            values = liquid_values(values, data["level_set"])
        a, b = default_value_range(values, view)
        low, high = min(low, a), max(high, b)
        snapshots.append((grid, state, data))
    # Every snapshot is read and checked before the video starts; a failure while writing it
    # (ffmpeg, Ctrl-C) leaves no partial file.
    _remove_stale_temporaries(Path(output))
    video = VideoWriter(output, fps=fps)
    try:
        for grid, state, data in snapshots:
            bodies = [(data[f"body{k}_points"], data[f"body{k}_triangles"])
                      for k in range(_count(data, _BODY))]
            obstacles = [data[f"obstacle{k}_points"] for k in range(_count(data, _OBSTACLE))]
            video.append(render_frame(grid, state, bodies, obstacles, view, float(data["time"]),
                                      value_range=(low, high),
                                      level_set=data.get("level_set")))
    except BaseException:
        video.abort()
        raise
    return video.close() or video.path, len(snapshots)


def _remove_stale_temporaries(output: Path) -> None:
    """Delete ``.{stem}.{pid}.tmp.*`` beside ``output`` left by a render that was killed (its
    process is gone); those of a render still running are kept."""
    import os

    prefix = f".{output.stem}."
    for stale in output.parent.glob(f"{glob.escape(prefix)}*.tmp.*"):
        pid = stale.name[len(prefix):].split(".")[0]
        if not pid.isdigit() or int(pid) == os.getpid():
            continue
        try:
            os.kill(int(pid), 0)
        except ProcessLookupError:
            stale.unlink(missing_ok=True)
        except OSError:
            pass  # alive, another user's


_BODY = re.compile(r"^body(\d+)_(points|triangles)$")
_OBSTACLE = re.compile(r"^obstacle(\d+)_points$")


def _count(data: dict[str, np.ndarray], pattern: re.Pattern[str]) -> int:
    """How many bodies (or obstacles) a snapshot holds: 1 + the highest index named."""
    indices = [int(m.group(1)) for key in data if (m := pattern.match(key))]
    return max(indices) + 1 if indices else 0


_SNAPSHOT_KEYS = ("velocity_x", "velocity_y", "pressure", "dye", "h", "origin", "time")


def _read_snapshot(path: Path) -> dict[str, np.ndarray]:
    """Every array of one saved ``step_*.npz``, read in full.

    Raises:
        ValueError: The file is empty, truncated, corrupt or not a field snapshot (the message
            names it).
    """
    try:
        with np.load(path, allow_pickle=False) as archive:
            data = {key: np.array(archive[key]) for key in archive.files}
    except Exception as error:  # noqa: BLE001 - numpy/zipfile fail with many exception types
        raise ValueError(f"field snapshot {path} is damaged ({damage(error, path)}); delete it and "
                         "render again") from None
    missing = [key for key in _SNAPSHOT_KEYS if key not in data]
    if missing or data["pressure"].ndim != 2:
        raise ValueError(f"field snapshot {path} is not a complete elastoflow snapshot (missing "
                         f"{', '.join(missing) or 'a 2D pressure'})")
    problem = _check_snapshot(data)
    if problem:
        raise ValueError(f"field snapshot {path} is damaged ({problem}); delete it and render "
                         "again")
    return data


def _check_snapshot(data: dict[str, np.ndarray]) -> str:
    """What makes a snapshot's arrays unusable for a frame (shapes, types, indices, non-finite
    geometry), or an empty string: the drawing kernels do not check bounds."""
    nx, ny = data["pressure"].shape
    if nx < 1 or ny < 1:
        return f"pressure has shape {(nx, ny)}"
    expected = {"velocity_x": (nx + 1, ny), "velocity_y": (nx, ny + 1), "pressure": (nx, ny),
                "dye": (nx, ny), "origin": (2,), "h": (), "time": ()}
    for key, shape in expected.items():
        value = data[key]
        if value.shape != shape or value.dtype.kind not in "fiu":
            return f"{key} is {value.dtype} of shape {value.shape}, not numbers of shape {shape}"
    for key in ("h", "origin", "time"):
        if not np.all(np.isfinite(data[key])):
            return f"{key} is not finite"
    for k in range(_count(data, _BODY)):
        points, triangles = data.get(f"body{k}_points"), data.get(f"body{k}_triangles")
        if points is None or triangles is None:
            return f"body {k} lacks its {'points' if points is None else 'triangles'}"
        if points.ndim != 2 or points.shape[1] != 2 or points.dtype.kind not in "fiu":
            return f"body{k}_points has shape {points.shape}, not (n, 2) numbers"
        if not np.all(np.isfinite(points)):
            return f"body{k}_points holds non-finite values"
        if triangles.ndim != 2 or triangles.shape[1] != 3 or triangles.dtype.kind not in "iu":
            return f"body{k}_triangles has shape {triangles.shape}, not (m, 3) integers"
        if triangles.size and (triangles.min() < 0 or triangles.max() >= len(points)):
            return (f"body{k}_triangles index nodes {triangles.min()}..{triangles.max()} of "
                    f"{len(points)}")
    for k in range(_count(data, _OBSTACLE)):
        outline = data.get(f"obstacle{k}_points")
        if (outline is None or outline.ndim != 2 or outline.shape[1] != 2
                or outline.dtype.kind not in "fiu" or not np.all(np.isfinite(outline))):
            return f"obstacle{k}_points is not an outline of finite (x, y) points"
    return ""
