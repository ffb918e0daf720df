"""What writing a video frame every step adds to a run: ``bar_in_jet`` at 256².

The same scene is stepped ``--steps`` times (after warm-up) twice in one process: without
output, and with a frame drawn by ``render_frame`` (speed view, the colour range of the
current field, drawn into the previous frame's array) and appended to a ``VideoWriter`` (mp4 through imageio-ffmpeg, GIF if that is
missing) after every step, as the CLI's ``OutputSession`` does. Reported: ms per step each way,
ms per frame split into drawing and encoding, and the added share. Target: < 25 %.

"Encoding" is the ``append`` call: the YUV conversion and queueing the frame; ffmpeg encodes
in its own process, fed by a background thread, so its CPU (~1.3 ms per frame, on the same
cores) shows only in the step time with video.

Usage: ``python -m benchmarks output [--steps N] [--size N] [--quick]``.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import markdown_table, versus_target, write_results

TARGET_ADDED_SHARE = 0.25


def measure(steps: int, warmup: int, size: int) -> dict[str, Any]:
    """Time ``steps`` steps of ``bar_in_jet`` at ``size``² without and with a frame each step."""
    from benchmarks.bench_scenes import scene
    from elastoflow.render import VideoWriter, default_value_range, render_frame, view_values
    from elastoflow.scenes import build_simulation

    simulation = build_simulation(scene("bar_in_jet", None if size == 256 else size))
    for _ in range(warmup):
        simulation.step()
    clock = time.perf_counter
    began = clock()
    for _ in range(steps):
        simulation.step()
    plain = clock() - began
    drawing = encoding = 0.0
    with tempfile.TemporaryDirectory() as folder:
        with VideoWriter(Path(folder) / "video.mp4", fps=30) as video:
            # First frame outside the clock: starts the ffmpeg process.
            frame = render_frame(simulation.grid, simulation.state.fluid,
                                 simulation.body_geometry(), simulation.obstacles, "speed",
                                 simulation.time)
            video.append(frame)
            began = clock()
            for _ in range(steps):
                simulation.step()
                t0 = clock()
                view = "speed"
                values = view_values(simulation.grid, simulation.state.fluid, view)
                value_range = default_value_range(values, view)
                frame = render_frame(simulation.grid, simulation.state.fluid,
                                     simulation.body_geometry(), simulation.obstacles, view,
                                     simulation.time,
                                     value_range=value_range, values=values, out=frame)
                t1 = clock()
                video.append(frame)
                drawing += t1 - t0
                encoding += clock() - t1
            with_video = clock() - began
        written = video.path.suffix
    row = {
        "case": "bar_in_jet",
        "size": f"{simulation.grid.nx}x{simulation.grid.ny}",
        "frame_pixels": f"{frame.shape[1]}x{frame.shape[0]}",
        "video": written,
        "steps": steps,
        "ms_per_step_plain": 1e3 * plain / steps,
        "ms_per_step_with_video": 1e3 * with_video / steps,
        "ms_per_frame_drawing": 1e3 * drawing / steps,
        "ms_per_frame_encoding": 1e3 * encoding / steps,
    }
    row["added_share"] = with_video / plain - 1.0
    row["target_added_share"] = TARGET_ADDED_SHARE
    row["vs_target"] = versus_target(row["added_share"], TARGET_ADDED_SHARE, at_most=True)
    return row


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    """Run the benchmark, print a Markdown table, write ``results/output.json``."""
    args = list(sys.argv[1:] if argv is None else argv)
    steps = 30 if "--quick" in args else 100
    if "--steps" in args:
        steps = int(args[args.index("--steps") + 1])
    size = int(args[args.index("--size") + 1]) if "--size" in args else 256
    rows = [measure(steps, 3 if "--quick" in args else 10, size)]
    print(markdown_table(rows, [
        "case", "size", "frame_pixels", "video", "ms_per_step_plain", "ms_per_step_with_video",
        "ms_per_frame_drawing", "ms_per_frame_encoding", "added_share", "target_added_share",
        "vs_target"]))
    path = write_results("output", rows)
    print(f"\nwrote {path}")
    return rows


if __name__ == "__main__":
    main()
