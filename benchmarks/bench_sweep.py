"""Sweep throughput on Dask: 1 and 2 local workers, and the engine's cost per point against the
same points run one after another in a plain loop.

    python -m benchmarks sweep [--points N] [--steps N] [--size N] [--tiny N] [--quick]

Two cases, each run in a plain loop in this process (one Numba thread), in two plain loops
side by side in two processes (every other point each: the most two workers can give on this
machine, with no engine at all), then by the engine on a local cluster of 1 and of 2 workers:

* ``throughput``: ``--points`` lid-driven cavities (``--size``² cells, ``--steps`` steps, lid
  speeds spread over [0.5, 1.5] m/s) with the sweep's normal per-point outputs (probes CSV and
  plot, checkpoints, ``result.json``);
* ``overhead``: ``--tiny`` cavities of 16² cells and 10 steps without the plot, so that the
  time is the engine's own: (engine seconds x workers - loop seconds) / points.

Times are the best of ``--repeat`` rounds, each running the four once in turn (the machine may
be shared: load that comes and goes falls on all alike). No process compiles or imports on
the clock: each loads the kernels from Numba's disk cache and the output modules by running a
tiny point first. Cluster start-up is timed apart. For the best round the CPU time of this
process (client, scheduler and nannies of the local cluster: ``driver_cpu_pct`` of a core)
and of the loop or worker processes per point are kept: with two workers on two cores the
first is taken from the workers.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import resource
import shutil
import tempfile
import time
from collections.abc import Iterator
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
    """Load into this process what a point uses: the kernels of the cavity's step (from
    Numba's disk cache), the output modules and matplotlib (the probe plot), by running a tiny
    point with the plot in a scratch folder."""
    from elastoflow.sweep import plan_sweep, run_point
    from elastoflow.sweep._engine import _task

    plan = plan_sweep(_spec(16, 4, 1))
    with tempfile.TemporaryDirectory(prefix="bench_sweep_warm_") as folder:
        row = run_point(_task(plan, plan.points[0], Path(folder)))
    assert row["status"] == "done", row


def _cpu_seconds() -> float:
    """CPU time of this process, all its threads."""
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def _pid_after(seconds: float) -> int:
    time.sleep(seconds)
    return os.getpid()


def _run_tasks(tasks: list[Any]) -> float:
    from elastoflow.sweep import run_point

    began = _cpu_seconds()
    for task in tasks:
        row = run_point(task)
        assert row["status"] == "done", row
    return _cpu_seconds() - began


def _loop_once(plan: Any, out: Path) -> tuple[float, float]:
    from elastoflow.sweep._engine import _task

    began, cpu = time.perf_counter(), _cpu_seconds()
    _run_tasks([_task(plan, point, out) for point in plan.points])
    return time.perf_counter() - began, _cpu_seconds() - cpu


def _loops_once(plan: Any, out: Path, pool: Any) -> tuple[float, float]:
    """Two plain loops in two processes side by side, each over every other point: the most
    two workers could give on this machine (no engine at all)."""
    from elastoflow.sweep._engine import _task

    tasks = [_task(plan, point, out) for point in plan.points]
    began = time.perf_counter()
    cpu = pool.map(_run_tasks, [tasks[0::2], tasks[1::2]], chunksize=1)
    return time.perf_counter() - began, sum(cpu)


def _engine_once(plan: Any, out: Path, client: Any) -> tuple[float, float, float]:
    """Wall seconds, CPU seconds of this process (client, scheduler and nannies of the local
    cluster) and of the workers."""
    from elastoflow.sweep import run_sweep

    workers_before = client.run(_cpu_seconds)
    began, cpu = time.perf_counter(), _cpu_seconds()
    outcome = run_sweep(plan, out, client)
    seconds, driver = time.perf_counter() - began, _cpu_seconds() - cpu
    workers_after = client.run(_cpu_seconds)
    assert outcome.progress.done == len(plan.points), outcome.failed_points
    workers = sum(workers_after[w] - workers_before.get(w, 0.0) for w in workers_after)
    return seconds, driver, workers


@contextlib.contextmanager
def _two_processes() -> Iterator[Any]:
    """Two warmed-up processes, one Numba thread each, as the workers have."""
    import multiprocessing

    previous = os.environ.get("NUMBA_NUM_THREADS")
    os.environ["NUMBA_NUM_THREADS"] = "1"
    try:
        pool = multiprocessing.get_context("spawn").Pool(2, initializer=_warm_up)
    finally:
        if previous is None:
            del os.environ["NUMBA_NUM_THREADS"]
        else:
            os.environ["NUMBA_NUM_THREADS"] = previous
    try:
        # Both processes through their warm-up before any clock starts.
        while len(set(pool.map(_pid_after, [0.2, 0.2], chunksize=1))) < 2:
            pass
        yield pool
    finally:
        pool.terminate()
        pool.join()


def _case(name: str, plan: Any, root: Path, repeat: int) -> list[dict[str, Any]]:
    """The loop, two loops side by side, 1 worker and 2 workers, interleaved: round r runs
    each once, so that load from other jobs that comes and goes falls on all alike (blocks of
    one engine after the other measured the other jobs' schedule as much as the engine)."""
    import numba

    from elastoflow.sweep import open_client

    n = len(plan.points)
    engines = ("loop", "loops", 1, 2)
    times: dict[Any, list[float]] = {engine: [] for engine in engines}
    driver: dict[Any, list[float]] = {engine: [] for engine in engines}
    worker_cpu: dict[Any, list[float]] = {engine: [] for engine in engines}
    started: dict[Any, float] = {"loop": 0.0, "loops": 0.0}
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
        pool = stack.enter_context(_two_processes())
        threads = numba.get_num_threads()
        numba.set_num_threads(1)  # as on each worker
        try:
            for attempt in range(repeat):
                for engine in engines:
                    out = root / f"{name}_{engine}" / str(attempt)
                    if engine == "loop":
                        seconds, cpu = _loop_once(plan, out)
                        used = (0.0, cpu)
                    elif engine == "loops":
                        seconds, cpu = _loops_once(plan, out, pool)
                        used = (0.0, cpu)
                    else:
                        seconds, *pair = _engine_once(plan, out, clients[engine])
                        used = (pair[0], pair[1])
                    times[engine].append(seconds)
                    driver[engine].append(used[0])
                    worker_cpu[engine].append(used[1])
        finally:
            numba.set_num_threads(threads)
    loop = min(times["loop"])
    one = min(times[1])
    labels = {"loop": "loop, 1 process", "loops": "loop, 2 processes", 1: "dask, 1 worker",
              2: "dask, 2 workers"}
    rows = []
    for engine in engines:
        best = times[engine].index(min(times[engine]))
        seconds = times[engine][best]
        workers = 2 if engine in ("loops", 2) else 1
        rows.append({
            "case": name, "engine": labels[engine], "workers": workers, "points": n,
            "seconds": seconds, "s_per_point": seconds / n, "start_s": started[engine],
            "speedup_vs_1_worker": one / seconds if engine in (1, 2) else None,
            "speedup_vs_loop": loop / seconds,
            "overhead_per_point_ms": 1000 * (seconds * workers - loop) / n,
            # Where the time went in the best round: CPU of the command's process (client,
            # scheduler, nannies) as a share of one core, and of the workers per point.
            "driver_cpu_pct": 100 * driver[engine][best] / seconds,
            "worker_cpu_s_per_point": worker_cpu[engine][best] / n,
            "all_seconds": times[engine],
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
                                "speedup_vs_1_worker", "speedup_vs_loop",
                                "overhead_per_point_ms", "driver_cpu_pct",
                                "worker_cpu_s_per_point"]))
    for row in rows:
        print(f"{row['case']}, {row['engine']}: every round "
              + ", ".join(f"{s:.2f}" for s in row["all_seconds"]) + " s")
    print("\noverhead_per_point_ms: (engine seconds x workers - loop seconds) / points: the "
          "engine's cost per point in worker time; 'loop, 2 processes': two plain loops side "
          "by side, the most two workers can give here; driver_cpu_pct: CPU of this process "
          "(client, scheduler, nannies) in % of a core; worker_cpu_s_per_point: CPU of the "
          "loop or worker processes per point")
    write_results("sweep", rows)
    return rows
