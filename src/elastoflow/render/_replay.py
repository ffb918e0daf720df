"""A video rendered again from saved ``.npz`` snapshots (``elastoflow render``)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np

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
        with np.load(path) as archive:
            data = {key: archive[key] for key in archive.files}
        nx, ny = data["pressure"].shape
        grid = Grid2D(nx=nx, ny=ny, h=float(data["h"]), origin=tuple(data["origin"]))
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
