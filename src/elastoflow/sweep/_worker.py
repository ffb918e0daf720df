"""One point of a sweep, run on a worker: the normal run outputs, resumable, with its result.

`run_point` is what the engine sends to the workers. It never raises for a run that fails:
a blow-up is a result (status ``failed`` with the message), so that the engine does not run it
again elsewhere. A worker that dies mid-run is another matter: the engine gives the point to
another worker, and `run_point` resumes it from the newest checkpoint in its folder.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import socket
import time as _time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from elastoflow.sweep._results import RESULT_FILE, read_result, scalar_results

RUNNING_FILE = "running.json"
"""In a point's folder while it runs: process id, host, worker and attempt (left by a point
that was stopped or killed: the next attempt counts on from it)."""

_STOPPED: set[str] = set()
"""The sweep runs (`PointTask.sweep`) told to stop in this process (`stop_points`)."""


def stop_points(sweep: str) -> None:
    """Stop this process's points of the sweep run ``sweep`` at their next step (each saves a
    checkpoint and returns ``pending``) and return at once from any that starts later.

    Sent to every worker by ``client.run`` when the sweep is stopped (Ctrl-C): Dask cannot
    interrupt a running task, and a worker closed with its task still running either waits
    for it or is killed after a timeout, losing the work since the last checkpoint."""
    _STOPPED.add(sweep)


@dataclass(frozen=True)
class PointTask:
    """All a worker needs to run one point (pickled to the worker).

    Attributes:
        index: The point's index in the sweep.
        parameters: Its varied parameters, key path -> value.
        scene: Its `elastoflow.scenes.Scene`, outputs set by the sweep (checkpoints on).
        steps: Fluid steps to run.
        folder: Its output folder (absolute; every worker must see the same file system).
        results_after: Statistics from this time on [s].
        snapshot_times: Times [s] at which to keep fields for the Zarr store (may be empty).
        snapshot_fields: Which fields (`SNAPSHOT_FIELDS`).
        numba_threads: Numba threads the run may use on its worker.
        probe_plot: Draw ``probes.png``.
        sweep: Which run of the sweep sent it (`stop_points`); empty: never stopped.
    """

    index: int
    parameters: dict[str, Any]
    scene: Any
    steps: int
    folder: str
    results_after: float = 0.0
    snapshot_times: tuple[float, ...] = ()
    snapshot_fields: tuple[str, ...] = ()
    numba_threads: int = 1
    probe_plot: bool = True
    sweep: str = ""


def _write_json(path: Path, data: dict[str, Any]) -> None:
    from elastoflow.io import write_text_atomic

    write_text_atomic(path, json.dumps(data, indent=1, allow_nan=True) + "\n")


def _worker_name() -> str:
    try:
        from distributed import get_worker

        return str(get_worker().address)
    except (ImportError, ValueError):
        return f"{socket.gethostname()}:{os.getpid()}"


def snapshot_path(folder: Path, k: int) -> Path:
    return folder / "snapshots" / f"snapshot_{k:03d}.npz"


def _snapshot(simulation: Any, names: tuple[str, ...]) -> dict[str, Any]:
    """The chosen fields at cell centres, shape (nx, ny) each."""
    from elastoflow.io import snapshot_arrays

    interior = getattr(simulation, "interior", None)
    data = snapshot_arrays(simulation.grid, simulation.state.fluid, time=simulation.time,
                           step=simulation.step_index,
                           solid_cells=None if interior is None else interior.solid_cells)
    at_cells = {"velocity_x": data["velocity"][..., 0], "velocity_y": data["velocity"][..., 1],
                "pressure": data["pressure"], "dye": data["dye"], "vorticity": data["vorticity"],
                "solid": data["solid"]}
    kept = {name: np.asarray(at_cells[name]) for name in names}
    kept["time"] = np.array(simulation.time)
    kept["step"] = np.array(simulation.step_index)
    return kept


class _Snapshots:
    """Saves the fields at the first step at or after each requested time, once each."""

    def __init__(self, task: PointTask, folder: Path, dt: float) -> None:
        self.times = task.snapshot_times
        self.names = task.snapshot_fields
        self.folder = folder
        self.tolerance = 1e-6 * dt

    def __call__(self, simulation: Any) -> None:
        from elastoflow.io import atomic_path

        for k, moment in enumerate(self.times):
            path = snapshot_path(self.folder, k)
            if simulation.time >= moment - self.tolerance and not path.exists():
                path.parent.mkdir(parents=True, exist_ok=True)
                with atomic_path(path) as temporary, open(temporary, "wb") as handle:
                    np.savez(handle, **_snapshot(simulation, self.names))


def _start(folder: Path) -> int:
    """Mark the point as running; returns which attempt this is (1 for the first)."""
    folder.mkdir(parents=True, exist_ok=True)
    attempt = 1
    try:
        attempt = int(json.loads((folder / RUNNING_FILE).read_text())["attempt"]) + 1
    except (OSError, ValueError, KeyError, TypeError):
        pass
    _write_json(folder / RUNNING_FILE, {"pid": os.getpid(), "host": socket.gethostname(),
                                        "worker": _worker_name(), "attempt": attempt,
                                        "started": _time.time()})
    return attempt


def run_point(task: PointTask) -> dict[str, Any]:
    """Run one point to its end (or its failure) and return its result row.

    Writes the normal run outputs into ``task.folder`` (``scene.toml``, ``probes.csv``,
    checkpoints, and fields, meshes or video when the sweep asks), the snapshots for the Zarr
    store, and last ``result.json`` (the same dict as returned). Resumes from the newest
    checkpoint in the folder, as ``elastoflow run --resume`` does.

    Returns:
        ``point``, ``parameters``, ``status`` (done, failed, lost when its folder cannot
        be written, or pending when the sweep was stopped, `stop_points`: no ``result.json``
        for these two, the next run of the sweep runs them again), ``message``,
        ``wall_time [s]``, ``steps``, ``time [s]``, ``attempts``, ``resumed_from_step``,
        ``worker``, ``folder``, ``results`` (`scalar_results` of the probes).
    """
    from elastoflow.io import remove_temporaries

    folder = Path(task.folder)
    if task.sweep in _STOPPED:
        return _stopped(task, folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with _folder_lock(folder, task.sweep):
            if task.sweep in _STOPPED:
                return _stopped(task, folder)
            previous = read_result(folder)
            if previous is not None and previous.get("status") == "done":
                return previous
            # What a killed run of this point was writing when it died.
            remove_temporaries(folder)
            return _run_locked(task, folder)
    except OSError as error:
        # The folder cannot be written (a full or read-only disk): not the point's result.
        return _lost(task, folder, error)


def _lost(task: PointTask, folder: Path, error: OSError, row: dict[str, Any] | None = None
          ) -> dict[str, Any]:
    """The row of a point that could not write its outputs: ``lost``, so that the next run of
    the sweep runs it again (no ``result.json``), the error kept as its message."""
    where = f" ({error.filename})" if error.filename else ""
    lost = dict(row) if row is not None else {
        "point": task.index, "parameters": task.parameters, "wall_time [s]": math.nan,
        "steps": 0, "time [s]": math.nan, "attempts": 1, "resumed_from_step": 0,
        "worker": _worker_name(), "folder": folder.name, "results": {}}
    lost.update(status="lost", message=f"cannot write its outputs: {error.strerror or error}"
                f"{where}")
    with contextlib.suppress(OSError):
        (folder / RUNNING_FILE).unlink(missing_ok=True)
    return lost


def _stopped(task: PointTask, folder: Path) -> dict[str, Any]:
    """The row of a point that the stopped sweep never started."""
    return {"point": task.index, "parameters": task.parameters, "status": "pending",
            "message": "", "wall_time [s]": math.nan, "steps": 0, "time [s]": math.nan,
            "attempts": 0, "resumed_from_step": 0, "worker": "", "folder": folder.name,
            "results": {}}


@contextlib.contextmanager
def _folder_lock(folder: Path, sweep: str = "") -> Iterator[None]:
    """The output folder's lock (`elastoflow.io.lock_output_folder`, as ``elastoflow run``
    takes it), waited for: a run of the same point still going (a sweep quit with a second
    Ctrl-C and started again while a remote cluster finishes its tasks, or an ``elastoflow run
    --resume`` in the folder) is never run over. The kernel drops the lock of a killed
    process. Not waited for once the sweep run ``sweep`` is stopped."""
    from elastoflow.io import OutputFolderBusy, lock_output_folder

    lock = None
    while lock is None:
        try:
            lock = lock_output_folder(folder)
        except OutputFolderBusy:
            if sweep in _STOPPED:
                # The caller sees the stop and leaves the folder alone.
                break
            _time.sleep(1.0)
    try:
        yield
    finally:
        if lock is not None:
            lock.close()


def _run_locked(task: PointTask, folder: Path) -> dict[str, Any]:
    began = _time.perf_counter()
    attempt = _start(folder)
    try:
        import numba

        most = int(getattr(numba.config, "NUMBA_NUM_THREADS", 1))
        numba.set_num_threads(max(1, min(task.numba_threads, most)))
    except (ImportError, ValueError):
        pass
    row: dict[str, Any] = {
        "point": task.index, "parameters": task.parameters, "status": "failed", "message": "",
        "wall_time [s]": math.nan, "steps": 0, "time [s]": 0.0, "attempts": attempt,
        "resumed_from_step": 0, "worker": _worker_name(), "folder": folder.name, "results": {},
    }
    try:
        _run(task, folder, row)
    except OSError as error:
        # A full or read-only disk is no result of the point: it runs again next time.
        row["wall_time [s]"] = _time.perf_counter() - began
        return _lost(task, folder, error, row)
    except Exception as error:  # noqa: BLE001 - every failure of a point is its result
        message = str(error).splitlines()[0] if str(error) else ""
        row["status"] = "failed"
        row["message"] = f"{type(error).__name__}: {message}" if not message.startswith(
            "step") else message
    row["wall_time [s]"] = _time.perf_counter() - began
    if row["status"] == "pending":
        # Stopped: no result.json, so the next run of the sweep resumes it from the
        # checkpoint just saved; running.json stays for its attempt count.
        return row
    try:
        _write_json(folder / RESULT_FILE, row)
    except OSError as error:
        return _lost(task, folder, error, row)
    (folder / RUNNING_FILE).unlink(missing_ok=True)
    return row


def _run(task: PointTask, folder: Path, row: dict[str, Any]) -> None:
    from elastoflow.io import (
        CheckpointError,
        OutputSession,
        ProbeRecorder,
        apply_output_overrides,
        find_resume_checkpoint,
        load_checkpoint,
    )
    from elastoflow.scenes import build_simulation, scene_to_toml, time_step

    scene = task.scene
    simulation = build_simulation(scene, steps=task.steps, warnings=[])
    checkpoint = find_resume_checkpoint(folder)
    resumed = False
    if checkpoint is not None:
        try:
            load_checkpoint(checkpoint, simulation)
            resumed = True
        except CheckpointError:
            # A checkpoint cut short by the kill: start over rather than give up the point.
            simulation = build_simulation(scene, steps=task.steps, warnings=[])
    row["resumed_from_step"] = simulation.step_index
    # The probes are recorded here rather than by the session: their CSV is written before
    # each checkpoint, so a point resumed after its worker was killed keeps its whole record.
    # Saved with every checkpoint as `run` saves it, so that ``elastoflow run
    # FOLDER/scene.toml --out FOLDER --resume`` can also continue a point by hand.
    record = {"scene": scene_to_toml(scene), "options": json.dumps({"steps": task.steps})}
    session = OutputSession(apply_output_overrides(scene, probes=False), simulation, folder,
                            resumed=resumed, run=record)
    recorder = ProbeRecorder(scene.outputs.probes, simulation, folder / "probes.csv",
                             resume_step=simulation.step_index if resumed else None)
    snapshots = _Snapshots(task, folder, time_step(scene))
    checkpoint_every = scene.outputs.checkpoint.every
    failure: BaseException | None = None
    stopped = False
    try:
        snapshots(simulation)
        while simulation.step_index < task.steps:
            if task.sweep in _STOPPED:
                stopped = True
                break
            report = simulation.step()
            step = simulation.step_index
            recorder.observe(simulation)
            if step % scene.outputs.probes_every == 0:
                recorder.record(simulation, report)
            snapshots(simulation)
            if step % checkpoint_every == 0 and recorder.rows:
                recorder.write_csv()
            session.after_step(simulation, report)
    except Exception as error:  # noqa: BLE001 - recorded, outputs closed, then re-raised
        failure = error
    finally:
        # After a failed step, back to the last step whose outputs were all written, as `run`.
        recovered = failure is not None and session.recover()
        if stopped and recorder.rows:
            # Before the checkpoint, as at every checkpoint: a kill between the two then
            # costs no probe rows on resume.
            recorder.write_csv()
        session.close(final_checkpoint=failure is None or recovered, failed=failure is not None,
                      stopped=stopped)
        if recorder.rows and not stopped:
            recorder.write_csv()
            if task.probe_plot:
                recorder.plot()
        close = getattr(recorder, "close", None)  # the streaming recorder holds its file open
        if close is not None:
            close()
    row["steps"] = simulation.step_index
    row["time [s]"] = simulation.time
    if stopped:
        # Statistics of part of the record would pass for the point's: none until it is done.
        row["status"] = "pending"
        row["message"] = f"stopped at step {simulation.step_index}"
        return
    if recorder.rows:
        row["results"] = scalar_results(recorder.columns, recorder.rows, task.results_after)
    if failure is not None:
        raise failure
    row["status"] = "done"
