"""A video rendered again from saved ``.npz`` snapshots (``elastoflow render``)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np

from elastoflow.io._checkpoint import damage
from elastoflow.render._frame import default_value_range, render_frame, view_values
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
    for path in paths:
        data = _read_snapshot(path)
        nx, ny = data["pressure"].shape
        try:
            grid = Grid2D(nx=nx, ny=ny, h=float(data["h"]), origin=tuple(data["origin"]))
        except (ValueError, TypeError) as error:
            raise ValueError(f"field snapshot {path} is damaged: {error}") from None
        state = SimpleNamespace(velocity_x=data["velocity_x"], velocity_y=data["velocity_y"],
                                pressure=data["pressure"], dye=data["dye"])
        a, b = default_value_range(view_values(grid, state, view), view)
        low, high = min(low, a), max(high, b)
        snapshots.append((grid, state, data))
    with VideoWriter(output, fps=fps) as video:
        for grid, state, data in snapshots:
            bodies = [(data[f"body{k}_points"], data[f"body{k}_triangles"])
                      for k in range(sum(1 for key in data if key.endswith("_triangles")))]
            obstacles = [data[f"obstacle{k}_points"]
                         for k in range(sum(1 for key in data if key.startswith("obstacle")))]
            video.append(render_frame(grid, state, bodies, obstacles, view, float(data["time"]),
                                      value_range=(low, high)))
    return video.path, len(snapshots)


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
        raise ValueError(f"field snapshot {path} is damaged ({damage(error)}); delete it and "
                         "render again") from None
    missing = [key for key in _SNAPSHOT_KEYS if key not in data]
    if missing or data["pressure"].ndim != 2:
        raise ValueError(f"field snapshot {path} is not a complete elastoflow snapshot (missing "
                         f"{', '.join(missing) or 'a 2D pressure'})")
    return data
