"""A stopped sweep (Ctrl-C: `stop_points` on every worker) stops its running points at their
next step with a checkpoint there and no ``result.json``, so that the next run of the sweep
resumes them from that step; points that start afterwards return at once."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import pandas as pd
import pytest

from elastoflow.sweep import parse_sweep, plan_sweep, run_point
from elastoflow.sweep import _worker
from elastoflow.sweep._engine import _task


@pytest.fixture(autouse=True)
def _no_stopped_sweeps(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(_worker, "_STOPPED", set())


def _task_of(tmp_path: Path, sweep: str) -> Any:
    plan = plan_sweep(parse_sweep({
        "scene": "cavity", "set": {"domain.nx": 8, "time.steps": 10},
        "grid": {"boundaries.top.velocity": [1.0]},
        "run": {"checkpoint_every": 3, "probe_plot": False}}, base_dir=tmp_path))
    return _task(plan, plan.points[0], tmp_path / "out", sweep)


def test_a_running_point_stops_at_its_next_step_and_resumes_from_it(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    task = _task_of(tmp_path, "run1")
    take = _worker._Snapshots.__call__

    def snapshots(self: Any, simulation: Any) -> None:
        take(self, simulation)
        if simulation.step_index == 4:
            _worker.stop_points("run1")

    monkeypatch.setattr(_worker._Snapshots, "__call__", snapshots)
    row = run_point(task)
    folder = Path(task.folder)
    assert row["status"] == "pending" and row["steps"] == 4
    assert row["message"] == "stopped at step 4" and row["results"] == {}
    assert not (folder / "result.json").exists()
    assert (folder / "checkpoints" / "checkpoint_00000004.npz").exists()
    assert pd.read_csv(folder / "probes.csv")["step"].tolist() == [1, 2, 3, 4]

    # Another run of the sweep (another token) resumes it from step 4, its record whole.
    again = run_point(replace(task, sweep="run2"))
    assert again["status"] == "done" and again["steps"] == 10
    assert again["resumed_from_step"] == 4 and again["attempts"] == 2
    assert pd.read_csv(folder / "probes.csv")["step"].tolist() == list(range(1, 11))
    assert not (folder / "running.json").exists()


def test_a_point_of_a_stopped_sweep_does_not_start(tmp_path: Path) -> None:
    task = _task_of(tmp_path, "run1")
    _worker.stop_points("run1")
    row = run_point(task)
    assert row["status"] == "pending" and row["steps"] == 0 and row["attempts"] == 0
    assert not Path(task.folder).exists()
    # A point of another run of the sweep, or of no sweep run, is not stopped.
    assert run_point(replace(task, sweep=""))["status"] == "done"
