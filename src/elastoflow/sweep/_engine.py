"""Running a checked sweep on Dask (distributed): the folder, the tasks, progress, the summary.

The engine is Dask's; elastoflow only says what a point is (`run_point`) and keeps the sweep's
folder::

    OUT/sweep.toml                       the sweep file as run
    OUT/summary.parquet                  one row per point (pandas.read_parquet)
    OUT/fields.zarr                      with [snapshots]: xarray.open_zarr
    OUT/points/point_00000/              the normal run outputs of point 0
        parameters.json                  its parameters (a rerun checks they still match)
        result.json                      written last: the point is finished
        running.json                     while it runs: pid, host, worker, attempt

A point with a ``result.json`` is never run again (``retry_failed`` runs failed ones again), so
running the same sweep twice does the work once. A point whose worker dies is given by the
scheduler to another worker (up to Dask's ``distributed.scheduler.allowed-failures`` times)
and resumes from its newest checkpoint.
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import os
import time as _time
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from elastoflow.sweep._plan import SweepPlan, SweepPoint
from elastoflow.sweep._results import read_result, write_summary
from elastoflow.sweep._spec import SweepError
from elastoflow.sweep._worker import RUNNING_FILE, PointTask, run_point, stop_points

SUMMARY_FILE = "summary.parquet"
ZARR_FILE = "fields.zarr"
_SUMMARY_INTERVAL = 5.0
"""Least seconds between two rewrites of the summary while the sweep runs."""


_POLL = 0.05
"""Seconds between two looks at the finished tasks (a Ctrl-C is seen within this)."""

_STOP_WAIT = 60.0
"""Most seconds a stopped sweep waits for its running points to save their state (each stops
at its next step); those still running then are left to the cluster (a local one is closed,
killing them: they resume from their last regular checkpoint)."""


class _StopRequest:
    """Ctrl-C (SIGINT) while the sweep runs: the first sets ``requested`` (the loop stops,
    cancels what has not finished and writes the summary); a second raises KeyboardInterrupt
    at once. Outside the main thread (no signal handlers there) it does nothing."""

    def __init__(self) -> None:
        self.requested = False
        self._previous: Any = None
        self._installed = False

    def __enter__(self) -> _StopRequest:
        import signal
        import threading

        if threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGINT, self._handle)
            self._installed = True
        return self

    def __exit__(self, *exc: object) -> None:
        import signal

        if self._installed:
            signal.signal(signal.SIGINT, self._previous)

    def _handle(self, signum: int, frame: Any) -> None:
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True


@dataclass
class SweepProgress:
    """The sweep as a whole, for the progress line."""

    total: int
    skipped: int = 0
    """Done in an earlier run of the sweep (its failed points count as failed)."""
    done: int = 0
    failed: int = 0
    lost: int = 0
    running: int = 0
    queued: int = 0
    elapsed: float = 0.0
    eta: float | None = None
    stopping: bool = False
    """Stopped (Ctrl-C): the running points are saving their state."""

    def line(self) -> str:
        """``12/40 done, 1 failed, 2 running, 25 queued, 0:01:10 elapsed, ETA 0:03:20``
        (``stopping: 12/40 done, ...`` while the running points of a stopped sweep save their
        state)."""
        finished = self.skipped + self.done
        parts = [f"{'stopping: ' if self.stopping else ''}{finished}/{self.total} done"]
        if self.skipped:
            parts[0] += f" ({self.skipped} before)"
        parts += [f"{self.failed} failed"] + ([f"{self.lost} lost"] if self.lost else [])
        parts += [f"{self.running} running", f"{self.queued} queued",
                  f"{_clock(self.elapsed)} elapsed",
                  f"ETA {_clock(self.eta) if self.eta is not None else '?'}"]
        return ", ".join(parts)


def _clock(seconds: float) -> str:
    seconds = max(0, int(round(seconds)))
    return f"{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}"


@dataclass
class SweepOutcome:
    """What a run of `run_sweep` did.

    Attributes:
        rows: Every point's summary row, by index (pending ones included).
        progress: The final counts.
        summary: The Parquet file.
        zarr: The Zarr store, or None without ``[snapshots]``.
        stopped: Interrupted (Ctrl-C) before every point finished.
    """

    rows: dict[int, dict[str, Any]]
    progress: SweepProgress
    summary: Path
    zarr: Path | None = None
    stopped: bool = False
    failed_points: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    """Problems that did not stop the sweep (unreadable snapshot files)."""


def local_worker_count() -> int:
    """Cores this process may use (one worker per core)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


_LOCAL_CLUSTER_CONFIG = {
    # The workers' statistical profiler samples the running thread's stack every 10 ms under
    # the GIL; a point's steps are long single calls that gain nothing from it.
    "distributed.worker.profile.enabled": False,
    # Every server (scheduler, each nanny and worker) measures its event loop's latency every
    # 20 ms, samples CPU, memory and network for the dashboard every 0.5 s, and the nannies
    # and workers check memory use every 0.1 s: on an idle 2-worker cluster that took 6-9 %
    # of a core in the command's process and 2.6-3.6 % in each worker (1.6-2 % and 0.6-0.7 %
    # with these), CPU the points lack when the workers fill the cores. An unresponsive loop
    # is still reported, the dashboard's system plots update every 2 s, and a worker over its
    # memory limit is paused or restarted within 0.5 s instead of 0.1 s (a point's memory
    # grows once, when it is built).
    "distributed.admin.tick.interval": "500ms",
    "distributed.admin.system-monitor.interval": "2s",
    "distributed.worker.memory.monitor-interval": "500ms",
}
"""Dask settings of the local cluster (its processes inherit them)."""


@contextlib.contextmanager
def open_client(scheduler: str | None = None, *, workers: int | None = None,
                dashboard: bool = True) -> Iterator[Any]:
    """A Dask client: of the scheduler at ``scheduler`` (an address or a scheduler file), or
    of a new local cluster of ``workers`` processes (default one per core), one thread and
    one Numba thread each, closed on exit."""
    from distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            if scheduler.endswith(".json") or Path(scheduler).is_file():
                if not Path(scheduler).is_file():
                    raise OSError(f"no scheduler file {scheduler}")
                try:
                    address = json.loads(Path(scheduler).read_text(encoding="utf-8"))["address"]
                except (UnicodeDecodeError, ValueError, KeyError, TypeError):
                    address = None
                if not isinstance(address, str):
                    raise OSError(f"{scheduler} is not a Dask scheduler file (JSON with the "
                                  "scheduler's \"address\")")
                client = Client(scheduler_file=scheduler, timeout="20s")
            else:
                client = Client(scheduler, timeout="20s")
        except (ValueError, KeyError) as error:
            # Not an address ("missing port number"), or a file that is not a scheduler's.
            raise OSError(f"not a scheduler address (tcp://host:8786) or scheduler file: "
                          f"{error}") from None
        try:
            yield client
        finally:
            client.close()
        return
    import dask

    count = workers or local_worker_count()
    # Numba's pool reads NUMBA_NUM_THREADS when the worker first imports numba; one thread
    # per worker process keeps the workers off each other's cores.
    env = {"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    cluster = None
    try:
        with dask.config.set(_LOCAL_CLUSTER_CONFIG), _sigint_blocked():
            # Without the dashboard the scheduler's HTTP server (health, metrics) still runs:
            # on any free port then, leaving 8787 to others. Only critical logs of the
            # cluster's processes reach the terminal: the sweep reports each point's failure
            # itself (a lost worker or connection included), and Dask's error logs carry
            # tracebacks. One came after a Ctrl-C: a worker busy in a step when the cluster
            # closed woke to a heartbeat to the scheduler that was gone, and printed one
            # (CI, tests/examples/test_sweep.py).
            cluster = LocalCluster(n_workers=count, threads_per_worker=1, processes=True,
                                   dashboard_address=":8787" if dashboard else ":0",
                                   scheduler_kwargs={"dashboard": dashboard}, env=env,
                                   silence_logs=logging.CRITICAL)
        client = Client(cluster)
        try:
            yield client
        finally:
            client.close()
    finally:
        if cluster is not None:
            cluster.close()


@contextlib.contextmanager
def _sigint_blocked() -> Iterator[None]:
    """SIGINT blocked in this thread and in every thread and process started from it meanwhile.

    The worker processes of a local cluster share the terminal's process group: a Ctrl-C
    would reach each of them, and a worker's own KeyboardInterrupt stops it with a traceback,
    its point cut off in the middle of a step. Dask offers no way to start them in a session
    of their own, but a blocked signal stays blocked across fork and exec: the cluster's event
    loop thread, started in here, blocks it, so do the threads it starts and the processes
    those spawn (Nanny -> AsyncProcess -> multiprocessing), also a worker the nanny starts
    again later. The command alone then sees Ctrl-C and stops the points in order
    (`stop_points`). A Ctrl-C meanwhile waits until the cluster is up."""
    import signal
    import threading

    if (not hasattr(signal, "pthread_sigmask")
            or threading.current_thread() is not threading.main_thread()):
        yield
        return
    # multiprocessing starts its resource tracker with SIGINT blocked and then unblocks it in
    # the thread that started it: from the loop thread (its first Queue), that undid the block
    # for every worker. Started here first, it is not started again.
    with contextlib.suppress(ImportError, OSError):
        from multiprocessing import resource_tracker

        resource_tracker.ensure_running()
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def prepare_folder(plan: SweepPlan, out: Path, text: str | None = None) -> None:
    """Create ``out`` and a folder per point; refuse a folder that holds another sweep.

    Raises:
        SweepError: A point folder there has other parameters (another sweep, or the file was
            edited): one line per such point.
    """
    from elastoflow.io import write_text_atomic

    points_dir = out / "points"
    points_dir.mkdir(parents=True, exist_ok=True)
    if text is not None:
        write_text_atomic(out / "sweep.toml", text)
    problems = []
    for point in plan.points:
        folder = points_dir / point.folder_name
        record = json.dumps({"point": point.index, "parameters": point.parameters},
                            sort_keys=True)
        path = folder / "parameters.json"
        if path.exists():
            try:
                same = json.loads(path.read_text()) == json.loads(record)
            except (OSError, ValueError):
                same = False
            if not same:
                problems.append(f"{out}/points/{point.folder_name}: holds a point with other "
                                f"parameters than {point.describe()}; use another output folder "
                                "(or remove this one) for a changed sweep")
            continue
        folder.mkdir(exist_ok=True)
        write_text_atomic(path, record + "\n")
    if problems:
        raise SweepError(problems)


def _pending_row(point: SweepPoint, out: Path, status: str = "pending",
                 message: str = "") -> dict[str, Any]:
    return {"point": point.index, "parameters": point.parameters, "status": status,
            "message": message, "wall_time [s]": math.nan, "steps": 0, "time [s]": math.nan,
            "attempts": 0, "resumed_from_step": 0, "worker": "",
            "folder": point.folder_name, "results": {}}


def _task(plan: SweepPlan, point: SweepPoint, out: Path, sweep: str = "") -> PointTask:
    snapshots = plan.spec.snapshots
    return PointTask(
        index=point.index, parameters=point.parameters, scene=point.scene, steps=point.steps,
        folder=str((out / "points" / point.folder_name).resolve()),
        results_after=plan.spec.run.results_after,
        snapshot_times=tuple(snapshots.times) if snapshots else (),
        snapshot_fields=tuple(snapshots.fields) if snapshots else (),
        probe_plot=plan.spec.run.probe_plot, sweep=sweep,
    )


def _stop(client: Any, token: str, futures: dict[Any, SweepPoint],
          rows: dict[int, dict[str, Any]]) -> None:
    """Stop the points of the sweep run ``token`` on every worker (`stop_points`: each saves a
    checkpoint at its next step; queued ones return as they start), wait for them at most
    `_STOP_WAIT` seconds, take their rows, and cancel what is left."""
    from distributed import wait

    unfinished = [future for future in futures if not future.done()]
    if unfinished:
        # A scheduler gone or unreachable: the points are left to the cluster, as below.
        with contextlib.suppress(Exception):
            client.run(stop_points, token, on_error="ignore")
        with contextlib.suppress(TimeoutError):
            wait(unfinished, timeout=_STOP_WAIT)
    for future, point in futures.items():
        if future.status != "finished":
            continue
        try:
            rows[point.index] = future.result()
        except Exception:  # noqa: BLE001 - KilledWorker, a lost connection: still pending
            continue
    client.cancel([future for future in futures if not future.done()])


def run_sweep(plan: SweepPlan, out: Path, client: Any, *, retry_failed: bool = False,
              on_progress: Callable[[SweepProgress], None] | None = None) -> SweepOutcome:
    """Run every point of ``plan`` not finished in ``out`` on the Dask ``client``.

    Writes the summary (Parquet) as points finish, at most every few seconds, and at the end;
    the Zarr store at the end. Ctrl-C (SIGINT, in the main thread) stops the running points at
    their next step (each saves a checkpoint there, `stop_points`), waits for them, writes the
    summary and returns with ``stopped`` set: running the sweep again goes on from there. A
    second Ctrl-C raises KeyboardInterrupt at once.

    Args:
        plan: The checked sweep (`plan_sweep`).
        out: Its folder (`prepare_folder` is called here).
        client: A `distributed.Client`.
        retry_failed: Run again the points that failed before (a blow-up is deterministic, so
            by default they are kept as they are).
        on_progress: Called with the counts whenever they change.
    """
    from distributed import as_completed

    prepare_folder(plan, out)
    warnings: list[str] = []
    rows: dict[int, dict[str, Any]] = {}
    pending: list[SweepPoint] = []
    for point in plan.points:
        folder = out / "points" / point.folder_name
        previous = read_result(folder)
        if previous is not None and (previous.get("status") == "done" or (
                previous.get("status") == "failed" and not retry_failed)):
            rows[point.index] = previous
        else:
            if previous is not None:
                (folder / "result.json").unlink(missing_ok=True)
                # A deterministic failure would only repeat from its last checkpoint.
                for old in (folder / "checkpoints").glob("checkpoint_*.npz"):
                    old.unlink()
            rows[point.index] = _pending_row(point, out)
            pending.append(point)
    progress = SweepProgress(total=len(plan.points))
    progress.skipped = sum(1 for row in rows.values() if row.get("status") == "done")
    progress.failed = sum(1 for row in rows.values() if row.get("status") == "failed")
    summary = out / "summary.parquet"
    names = plan.parameter_names

    def report() -> None:
        threads = sum(client.nthreads().values()) if remaining else 0
        progress.running = min(remaining, threads)
        progress.queued = remaining - progress.running
        progress.elapsed = _time.perf_counter() - began
        if finished_here and remaining:
            progress.eta = progress.elapsed / finished_here * remaining
        elif not remaining:
            progress.eta = 0.0
        if on_progress is not None:
            on_progress(progress)

    began = _time.perf_counter()
    remaining = len(pending)
    finished_here = 0
    token = uuid.uuid4().hex[:8]
    futures = {
        client.submit(run_point, _task(plan, point, out, token), pure=False,
                      key=f"elastoflow-{plan.spec.name}-point{point.index}-{token}"): point
        for point in pending
    }
    last_summary = _time.perf_counter()
    counted: set[int] = set()  # points whose rows the progress counts already
    report()
    completed = as_completed(list(futures))
    # The first Ctrl-C only asks the loop to stop: the summary below is never cut short (an
    # import or a Parquet write interrupted half way broke it, with a traceback).
    with _StopRequest() as stop:
        while remaining and not stop.requested:
            if not completed.has_ready():
                _time.sleep(_POLL)
                continue
            for future in completed.next_batch(block=False):
                point = futures[future]
                try:
                    row = future.result()
                except Exception as error:  # noqa: BLE001 - KilledWorker, a lost connection
                    row = _pending_row(point, out, "lost", f"{type(error).__name__}: {error}")
                    (out / "points" / point.folder_name / RUNNING_FILE).unlink(missing_ok=True)
                rows[point.index] = row
                counted.add(point.index)
                remaining -= 1
                finished_here += 1
                status = row.get("status")
                if status == "done":
                    progress.done += 1
                elif status == "failed":
                    progress.failed += 1
                else:
                    progress.lost += 1
            if _time.perf_counter() - last_summary > _SUMMARY_INTERVAL:
                write_summary(summary, [rows[i] for i in sorted(rows)], names)
                last_summary = _time.perf_counter()
            report()
        stopped = stop.requested and remaining > 0
        if stopped:
            progress.stopping = True
            report()
            _stop(client, token, {f: p for f, p in futures.items() if p.index not in counted},
                  rows)
            for point in futures.values():
                if point.index in counted:
                    continue
                if rows[point.index]["status"] == "pending":
                    # Ended on its worker before its result reached this loop and the
                    # cluster went away (or after the wait for the stopped points).
                    row = read_result(out / "points" / point.folder_name)
                    if row is not None:
                        rows[point.index] = row
                status = str(rows[point.index]["status"])
                if status in ("done", "failed", "lost"):
                    setattr(progress, status, getattr(progress, status) + 1)
        # Still under the stop request: a Ctrl-C now does not cut the files short.
        write_summary(summary, [rows[i] for i in sorted(rows)], names)
        zarr_path = None
        if plan.spec.snapshots is not None:
            from elastoflow.sweep._zarr import write_snapshots_zarr

            zarr_path = write_snapshots_zarr(out / ZARR_FILE, plan, rows, out, warnings)
    failed = [f"point {i}: {row.get('message', '')}" for i, row in sorted(rows.items())
              if row.get("status") in ("failed", "lost")]
    return SweepOutcome(rows, progress, summary, zarr_path, stopped, failed, warnings)
