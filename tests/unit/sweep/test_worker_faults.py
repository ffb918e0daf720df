"""A point whose folder cannot be written (a full or read-only disk) is ``lost``, not
``failed``: no ``result.json``, so the next run of the sweep runs it again (a failed point is
kept as a deterministic result), and the worker never raises (Dask logged a traceback)."""

from __future__ import annotations

import errno
from pathlib import Path
from typing import Any

import pytest

from elastoflow.sweep import parse_sweep, plan_sweep, run_point
from elastoflow.sweep._engine import _task


def _plan(tmp_path: Path) -> Any:
    return plan_sweep(parse_sweep({
        "scene": "cavity", "set": {"domain.nx": 8, "time.steps": 6},
        "grid": {"boundaries.top.velocity": [1.0]},
        "run": {"checkpoint_every": 3, "probe_plot": False}}, base_dir=tmp_path))


def _full(*args: Any, **kwargs: Any) -> None:
    raise OSError(errno.ENOSPC, "No space left on device", "probes.csv")


@pytest.mark.parametrize("where", ["result", "probes"])
def test_a_full_disk_makes_the_point_lost_and_run_again(where: str, tmp_path: Path,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    from elastoflow.io import ProbeRecorder
    from elastoflow.sweep import _worker

    plan = _plan(tmp_path)
    task = _task(plan, plan.points[0], tmp_path / "out")
    if where == "result":
        original = _worker._write_json

        def write(path: Path, data: dict[str, Any]) -> None:
            if path.name == "result.json":
                _full()
            original(path, data)

        monkeypatch.setattr(_worker, "_write_json", write)
    else:
        monkeypatch.setattr(ProbeRecorder, "write_csv", _full)
    row = run_point(task)
    assert row["status"] == "lost"
    assert row["message"].startswith("cannot write its outputs: No space left on device")
    folder = Path(task.folder)
    assert not (folder / "result.json").exists() and not (folder / "running.json").exists()

    monkeypatch.undo()
    again = run_point(task)
    assert again["status"] == "done" and again["steps"] == 6
    assert (folder / "result.json").exists()


def test_a_folder_that_cannot_be_created_is_lost(tmp_path: Path) -> None:
    plan = _plan(tmp_path)
    (tmp_path / "out").write_text("a file where the sweep's folder should be")
    row = run_point(_task(plan, plan.points[0], tmp_path / "out"))
    assert row["status"] == "lost" and "cannot write its outputs" in row["message"]
