"""Sweep throughput on Dask: 1 and 2 local workers, and the engine's cost per point against the
same points run one after another in a plain loop.

    python -m benchmarks sweep [--points N] [--steps N] [--size N] [--tiny N] [--quick]

Two cases, each run in a plain loop in this process (one Numba thread), then by the engine on
a local cluster of 1 and of 2 workers:

* ``throughput``: ``--points`` lid-driven cavities (``--size``² cells, ``--steps`` steps, lid
  speeds spread over [0.5, 1.5] m/s) with the sweep's normal per-point outputs (probes CSV and
  plot, checkpoints, ``result.json``);
* ``overhead``: ``--tiny`` cavities of 16² cells and 10 steps without the plot, so that the
  time is the engine's own: (engine seconds x workers - loop seconds) / points.

Times are the best of ``--repeat`` rounds, each running the loop, 1 worker and 2 workers once
in turn (the machine may be shared: load that comes and goes falls on all three). No process compiles: the kernels come from Numba's disk cache, loaded once per process before
the clock starts (a warm-up run in the loop's process and on every worker). Cluster start-up
is timed apart.
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

from benchmarks._common import markdown_table, write_results


def _spec(size: int, steps: int, points: int, plot: bool = True) -> Any:
    from elastoflow.sweep import parse_sweep

    speeds = [0.5 + k / max(points - 1, 1) for k in range(points)]
    return parse_sweep({"name": "bench", "scene": "cavity",
                        "set": {"domain.nx": size, "time.steps": steps},
                        "grid": {"boundaries.top.velocity": speeds},
                        "run": {"checkpoint_every": max(1, steps // 4), "probe_plot": plot}})


def _warm_up() -> None:
    """Load the kernels of the cavity's step into this process (from Numba's disk cache)."""
    from elastoflow.scenes import build_simulation, get_scene

    scene = get_scene("cavity")
    scene = scene.model_copy(update={"domain": scene.domain.model_copy(update={"nx": 16})})
    simulation = build_simulation(scene, steps=2)
    simulation.step()
    simulation.step()


def _loop_once(plan: Any, out: Path) -> float:
    from elastoflow.sweep import run_point
    from elastoflow.sweep._engine import _task

    began = time.perf_counter()
    for point in plan.points:
        run_point(_task(plan, point, out))
    return time.perf_counter() - began


def _engine_once(plan: Any, out: Path, client: Any) -> float:
    from elastoflow.sweep import run_sweep

    began = time.perf_counter()
    outcome = run_sweep(plan, out, client)
    seconds = time.perf_counter() - began
    assert outcome.progress.done == len(plan.points), outcome.failed_points
    return seconds


def _case(name: str, plan: Any, root: Path, repeat: int) -> list[dict[str, Any]]:
    """The loop, 1 worker and 2 workers, interleaved: round r runs each of the three once, so
    that load from other jobs that comes and goes falls on all three alike (blocks of one
    engine after the other measured the other jobs' schedule as much as the engine)."""
    import contextlib

    import numba

    from elastoflow.sweep import open_client

    n = len(plan.points)
    engines = ("loop", 1, 2)
    times: dict[Any, list[float]] = {engine: [] for engine in engines}
    started: dict[Any, float] = {"loop": 0.0}
    _warm_up()
    with contextlib.ExitStack() as stack:
        clients = {}
        for workers in (1, 2):
            began = time.perf_counter()
            client = stack.enter_context(open_client(workers=workers, dashboard=False))
            client.wait_for_workers(workers)
            client.run(_warm_up)
            started[workers] = time.perf_counter() - began
            clients[workers] = client
        threads = numba.get_num_threads()
        numba.set_num_threads(1)  # as on each worker
        try:
            for attempt in range(repeat):
                for engine in engines:
                    out = root / f"{name}_{engine}" / str(attempt)
                    times[engine].append(_loop_once(plan, out) if engine == "loop" else
                                         _engine_once(plan, out, clients[engine]))
        finally:
            numba.set_num_threads(threads)
    loop = min(times["loop"])
    rows = [{"case": name, "engine": "loop, 1 process", "workers": 1, "points": n,
             "seconds": loop, "s_per_point": loop / n, "start_s": 0.0,
             "speedup_vs_1_worker": None, "overhead_per_point_ms": 0.0,
             "all_seconds": times["loop"]}]
    one = min(times[1])
    for workers in (1, 2):
        seconds = min(times[workers])
        rows.append({
            "case": name, "engine": f"dask, {workers} worker{'s' if workers > 1 else ''}",
            "workers": workers, "points": n, "seconds": seconds, "s_per_point": seconds / n,
            "start_s": started[workers], "speedup_vs_1_worker": one / seconds,
            "overhead_per_point_ms": 1000 * (seconds * workers - loop) / n,
            "all_seconds": times[workers],
        })
    return rows


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    from elastoflow.sweep import plan_sweep

    parser = argparse.ArgumentParser(prog="python -m benchmarks sweep")
    parser.add_argument("--points", type=int, default=12)
    parser.add_argument("--steps", type=int, default=600)
    parser.add_argument("--size", type=int, default=48)
    parser.add_argument("--tiny", type=int, default=40)
    parser.add_argument("--repeat", type=int, default=3, help="best of this many runs each "
                        "(interleaved rounds)")
    parser.add_argument("--quick", action="store_true", help="2 points of 20 steps at 16^2")
    args = parser.parse_args(argv or [])
    if args.quick:
        args.points, args.steps, args.size, args.tiny, args.repeat = 2, 20, 16, 2, 1
    root = Path(tempfile.mkdtemp(prefix="bench_sweep_"))
    load = os.getloadavg()[0]
    try:
        rows = _case("throughput", plan_sweep(_spec(args.size, args.steps, args.points)), root,
                     args.repeat)
        for row in rows:
            row.update(size=args.size, steps=args.steps)
        tiny = _case("overhead", plan_sweep(_spec(16, 10, args.tiny, plot=False)), root,
                     args.repeat)
        for row in tiny:
            row.update(size=16, steps=10)
        rows += tiny
    finally:
        shutil.rmtree(root, ignore_errors=True)
    after = os.getloadavg()[0]
    for row in rows:
        row["load_before"] = load  # other work on the machine skews the speed-up
        row["load_after"] = after
    print(f"load average before: {load:.2f}, after: {after:.2f}; best of "
          f"{args.repeat} interleaved rounds; throughput: {args.points} cavities, {args.size}^2 cells, {args.steps} steps each; "
          f"overhead: {args.tiny} cavities, 16^2 cells, 10 steps each\n")
    print(markdown_table(rows, ["case", "engine", "points", "seconds", "s_per_point", "start_s",
                                "speedup_vs_1_worker", "overhead_per_point_ms"]))
    for row in rows:
        print(f"{row['case']}, {row['engine']}: every round "
              + ", ".join(f"{s:.2f}" for s in row["all_seconds"]) + " s")
    print("\noverhead_per_point_ms: (engine seconds x workers - loop seconds) / points: the "
          "engine's cost per point in worker time")
    write_results("sweep", rows)
    return rows
