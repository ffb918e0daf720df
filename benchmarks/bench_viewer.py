"""Frames per second of the interactive viewer at 256², headless (SDL dummy video driver).

The ``Viewer`` of ``bar_in_jet`` (256², one step per frame, as ``run_viewer`` does) is driven
for ``--frames`` frames after warm-up; each frame is ``update()`` (one coupled step) and
``draw()`` (render_frame + pygame Surface + status line); blitting to a real window and
``flip`` are not included (no display here). Reported: frames/s, ms per frame split into
update and draw. Target: 60 frames/s.

Usage: ``python -m benchmarks viewer [--frames N] [--size N] [--quick]``.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import markdown_table, versus_target, write_results

TARGET_FPS = 60.0


def measure(frames: int, warmup: int, size: int) -> dict[str, Any]:
    """Drive the viewer of ``bar_in_jet`` at ``size``² for ``frames`` frames."""
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    import pygame

    from benchmarks.bench_scenes import scene
    from elastoflow.viewer import Viewer

    pygame.init()
    try:
        viewer = Viewer(scene("bar_in_jet", None if size == 256 else size))
        for _ in range(warmup):
            viewer.update()
            surface = viewer.draw()
        clock = time.perf_counter
        updating = drawing = 0.0
        for _ in range(frames):
            t0 = clock()
            viewer.update()
            t1 = clock()
            surface = viewer.draw()
            drawing += clock() - t1
            updating += t1 - t0
    finally:
        pygame.quit()
    total = updating + drawing
    row = {
        "case": "bar_in_jet",
        "size": f"{viewer.simulation.grid.nx}x{viewer.simulation.grid.ny}",
        "window_pixels": f"{surface.get_width()}x{surface.get_height()}",
        "frames": frames,
        "fps": frames / total,
        "ms_per_frame": 1e3 * total / frames,
        "ms_update": 1e3 * updating / frames,
        "ms_draw": 1e3 * drawing / frames,
        "fps_draw_only": frames / drawing,
        "target_fps": TARGET_FPS,
    }
    row["vs_target"] = versus_target(row["fps"], TARGET_FPS, at_most=False)
    return row


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    """Run the benchmark, print a Markdown table, write ``results/viewer.json``."""
    args = list(sys.argv[1:] if argv is None else argv)
    frames = 30 if "--quick" in args else 100
    if "--frames" in args:
        frames = int(args[args.index("--frames") + 1])
    size = int(args[args.index("--size") + 1]) if "--size" in args else 256
    rows = [measure(frames, 3 if "--quick" in args else 10, size)]
    print(markdown_table(rows, ["case", "size", "window_pixels", "fps", "ms_per_frame",
                                "ms_update", "ms_draw", "fps_draw_only", "target_fps",
                                "vs_target"]))
    path = write_results("viewer", rows)
    print(f"\nwrote {path}")
    return rows


if __name__ == "__main__":
    main()
