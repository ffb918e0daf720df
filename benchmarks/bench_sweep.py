"""Sweep throughput on Dask: 1 and 2 local workers, and the engine's cost per point against the
same points run one after another in a plain loop.

    python -m benchmarks sweep [--points N] [--steps N] [--size N] [--quick]

The points are lid-driven cavities (``--size``² cells, ``--steps`` steps, lid speeds spread
over [0.5, 1.5] m/s) with the sweep's normal per-point outputs (probes CSV and plot,
checkpoints, ``result.json``). Every process compiles nothing: the kernels come from Numba's
disk cache, loaded once per process before the clock starts (a warm-up point in the loop, a
two-step run on every worker). Cluster start-up is timed apart.
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

from benchmarks._common import markdown_table, write_results


def _spec(size: int, steps: int, points: int) -> Any:
    from elastoflow.sweep import parse_sweep

    speeds = [0.5 + k / max(points - 1, 1) for k in range(points)]
    return parse_sweep({"name": "bench", "scene": "cavity",
                        "set": {"domain.nx": size, "time.steps": steps},
                        "grid": {"boundaries.top.velocity": speeds},
                        "run": {"checkpoint_every": max(1, steps // 4)}})


def _warm_up() -> None:
    """Load the kernels of the cavity's step into this process (from Numba's disk cache)."""
    from elastoflow.scenes import build_simulation, get_scene

    scene = get_scene("cavity")
    scene = scene.model_copy(update={"domain": scene.domain.model_copy(update={"nx": 16})})
    simulation = build_simulation(scene, steps=2)
    simulation.step()
    simulation.step()


def _loop(plan: Any, out: Path) -> float:
    from elastoflow.sweep import run_point
    from elastoflow.sweep._engine import _task

    _warm_up()
    began = time.perf_counter()
    for point in plan.points:
        run_point(_task(plan, point, out))
    return time.perf_counter() - began


def _engine(plan: Any, out: Path, workers: int) -> tuple[float, float]:
    from elastoflow.sweep import open_client, run_sweep

    began = time.perf_counter()
    with open_client(workers=workers, dashboard=False) as client:
        client.wait_for_workers(workers)
        client.run(_warm_up)
        started = time.perf_counter() - began
        began = time.perf_counter()
        outcome = run_sweep(plan, out, client)
        seconds = time.perf_counter() - began
    assert outcome.progress.done == len(plan.points), outcome.failed_points
    return started, seconds


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    import numba

    from elastoflow.sweep import plan_sweep

    parser = argparse.ArgumentParser(prog="python -m benchmarks sweep")
    parser.add_argument("--points", type=int, default=8)
    parser.add_argument("--steps", type=int, default=600)
    parser.add_argument("--size", type=int, default=48)
    parser.add_argument("--quick", action="store_true", help="2 points of 20 steps at 16^2")
    args = parser.parse_args(argv or [])
    if args.quick:
        args.points, args.steps, args.size = 2, 20, 16
    plan = plan_sweep(_spec(args.size, args.steps, args.points))
    n = len(plan.points)
    root = Path(tempfile.mkdtemp(prefix="bench_sweep_"))
    rows: list[dict[str, Any]] = []
    try:
        # The loop runs with one Numba thread, as each worker does.
        threads = numba.get_num_threads()
        numba.set_num_threads(1)
        try:
            loop = _loop(plan, root / "loop")
        finally:
            numba.set_num_threads(threads)
        rows.append({"case": "loop, 1 process", "workers": 1, "points": n, "seconds": loop,
                     "s_per_point": loop / n, "start_s": 0.0, "speedup_vs_1_worker": None,
                     "overhead_per_point_ms": 0.0})
        one = None
        for workers in (1, 2):
            started, seconds = _engine(plan, root / f"dask{workers}", workers)
            one = seconds if workers == 1 else one
            rows.append({
                "case": f"dask, {workers} worker{'s' if workers > 1 else ''}",
                "workers": workers, "points": n, "seconds": seconds, "s_per_point": seconds / n,
                "start_s": started,
                "speedup_vs_1_worker": (one / seconds) if one else None,
                "overhead_per_point_ms": 1000 * (seconds * workers - loop) / n,
            })
    finally:
        shutil.rmtree(root, ignore_errors=True)
    for row in rows:
        row.update(size=args.size, steps=args.steps)
    print(f"{n} cavity points, {args.size}^2 cells, {args.steps} steps each\n")
    print(markdown_table(rows, ["case", "points", "seconds", "s_per_point", "start_s",
                                "speedup_vs_1_worker", "overhead_per_point_ms"]))
    print("\noverhead_per_point_ms: (engine seconds x workers - loop seconds) / points: the "
          "engine's cost per point in worker time")
    write_results("sweep", rows)
    return rows
