"""Files and folders the command line cannot use: a clear error (exit 2), never a traceback.

Damaged checkpoints on --resume, damaged field snapshots for render, --out naming a file or an
unwritable folder, dump onto a folder. Nothing here steps a simulation.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from elastoflow.cli import app
from elastoflow.io import CheckpointError, read_checkpoint, save_checkpoint, snapshot_arrays
from elastoflow.scenes import build_simulation, get_scene, load_scene

runner = CliRunner()

TINY_SCENE = """
name = "tiny"
[domain]
lx = 1.0
ly = 1.0
nx = 16
[boundaries]
top = "outflow"
[[bodies]]
shape = { type = "rectangle", box = [0.4, 0.4, 0.6, 0.8], divisions = [2, 4] }
material = { density = 1000.0, young_modulus = 1e4, poisson_ratio = 0.3 }
[time]
dt = 0.02
steps = 4
"""


@pytest.fixture()
def tiny(tmp_path: Path) -> Path:
    path = tmp_path / "tiny.toml"
    path.write_text(TINY_SCENE)
    return path


@pytest.fixture()
def no_stepping(monkeypatch: pytest.MonkeyPatch) -> None:
    from elastoflow.simulation import Simulation

    def refuse(self: Any) -> None:
        raise AssertionError("stepped")

    monkeypatch.setattr(Simulation, "step", refuse)


def _refused(*args: Any) -> str:
    result = runner.invoke(app, [str(a) for a in args])
    assert result.exception is None or isinstance(result.exception, SystemExit)
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    errors = [line for line in result.output.splitlines() if line.startswith("error:")]
    assert len(errors) == 1, result.output
    return errors[0]


def _good_checkpoint(tiny: Path, path: Path) -> None:
    save_checkpoint(path, build_simulation(load_scene(tiny), warnings=[]))


def _damaged(good: bytes, how: str) -> bytes:
    if how == "empty":
        return b""
    if how == "truncated":
        return good[: len(good) // 2]
    if how == "corrupt":
        middle = len(good) // 2
        return good[:middle] + bytes(b ^ 0xFF for b in good[middle:middle + 64]) + good[
            middle + 64:]
    return b"not a zip file at all"


@pytest.mark.parametrize("how", ["empty", "truncated", "corrupt", "garbage"])
def test_resume_from_a_damaged_checkpoint(how: str, tiny: Path, tmp_path: Path,
                                          no_stepping: None) -> None:
    folder = tmp_path / "out" / "checkpoints"
    _good_checkpoint(tiny, folder / "checkpoint_00000002.npz")
    good = (folder / "checkpoint_00000002.npz").read_bytes()
    (folder / "checkpoint_00000004.npz").write_bytes(_damaged(good, how))
    line = _refused("run", tiny, "--out", tmp_path / "out", "--resume", "--quiet")
    assert "checkpoint_00000004.npz" in line
    assert ("empty" if how == "empty" else "damaged") in line
    assert "move it away to resume from checkpoint_00000002.npz" in line


def test_resume_from_a_checkpoint_of_another_scene(tiny: Path, tmp_path: Path,
                                                   no_stepping: None) -> None:
    folder = tmp_path / "out" / "checkpoints"
    save_checkpoint(folder / "checkpoint_00000002.npz",
                    build_simulation(get_scene("cavity"), warnings=[]))
    line = _refused("run", tiny, "--out", tmp_path / "out", "--resume", "--quiet")
    assert "does not fit this scene" in line and "run again without --resume" in line


def test_read_checkpoint_refuses_non_finite_and_pickled_contents(tmp_path: Path) -> None:
    nan = tmp_path / "nan.npz"
    np.savez(nan, time=np.array(np.nan), step_index=np.array(3))
    with pytest.raises(CheckpointError, match="non-finite values in time"):
        read_checkpoint(nan)
    pickled = tmp_path / "pickled.npz"
    np.savez(pickled, time=np.array(0.0), step_index=np.array(0),
             extra=np.array([{"a": 1}], dtype=object))
    with pytest.raises(CheckpointError) as info:
        read_checkpoint(pickled)
    assert "pickled Python objects" in str(info.value)
    assert "allow_pickle" not in str(info.value)
    foreign = tmp_path / "foreign.npz"
    np.savez(foreign, a=np.zeros(3))
    with pytest.raises(CheckpointError, match="not an elastoflow checkpoint"):
        read_checkpoint(foreign)


@pytest.mark.parametrize("how", ["empty", "truncated", "garbage"])
def test_render_of_a_damaged_snapshot(how: str, tiny: Path, tmp_path: Path) -> None:
    simulation = build_simulation(load_scene(tiny), warnings=[])
    fields = tmp_path / "out" / "fields"
    fields.mkdir(parents=True)
    arrays = snapshot_arrays(simulation.grid, simulation.state.fluid,
                             list(zip(simulation.bodies, simulation.state.bodies)),
                             simulation.obstacles, time=0.0, step=0)
    np.savez(fields / "step_000000.npz", **arrays)
    good = (fields / "step_000000.npz").read_bytes()
    (fields / "step_000001.npz").write_bytes(_damaged(good, how))
    line = _refused("render", tmp_path / "out")
    assert "step_000001.npz is damaged" in line and "delete it" in line
    assert not list((tmp_path / "out").glob("render_*"))


def test_out_naming_a_file(tiny: Path, tmp_path: Path, no_stepping: None) -> None:
    target = tmp_path / "taken"
    target.write_text("mine")
    line = _refused("run", tiny, "--out", target, "--quiet")
    assert "--out" in line and "is a file" in line
    assert target.read_text() == "mine"


def test_out_in_an_unwritable_folder(tiny: Path, tmp_path: Path, no_stepping: None,
                                     monkeypatch: pytest.MonkeyPatch) -> None:
    def denied(*args: Any, **kwargs: Any) -> None:
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(tempfile, "TemporaryFile", denied)
    line = _refused("run", tiny, "--out", tmp_path / "out", "--quiet")
    assert "cannot write there (Permission denied)" in line


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0,
                    reason="root writes into read-only folders")
def test_out_in_a_read_only_folder(tiny: Path, tmp_path: Path, no_stepping: None) -> None:
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        line = _refused("run", tiny, "--out", locked / "out", "--quiet")
    finally:
        locked.chmod(0o700)
    assert "cannot write there" in line


def test_dump_onto_a_folder(tmp_path: Path) -> None:
    line = _refused("dump", "cavity", "-o", tmp_path)
    assert "is a folder" in line


def test_validate_prints_warnings_and_ok(tmp_path: Path) -> None:
    path = tmp_path / "thin.toml"
    path.write_text(TINY_SCENE.replace("box = [0.4, 0.4, 0.6, 0.8]", "box = [0.4, 0.4, 0.5, 0.8]"))
    result = runner.invoke(app, ["validate", str(path)])
    assert result.exit_code == 0, result.output
    lines = result.output.strip().splitlines()
    assert lines[0].startswith(f"warning: {path}: bodies.0.shape: the body is only 1.60 cells")
    assert lines[1].startswith("ok: tiny: 16x16 cells, 1 bodies (16 elements)")


def test_a_full_disk_during_a_run_is_an_error_not_a_traceback(
        tiny: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import errno

    from elastoflow.io import FieldWriter

    original = FieldWriter.write
    calls = {"count": 0}

    def fill_up(self: Any, arrays: Any) -> Any:
        calls["count"] += 1
        if calls["count"] >= 3:
            raise OSError(errno.ENOSPC, "No space left on device", "step.npz")
        return original(self, arrays)

    monkeypatch.setattr(FieldWriter, "write", fill_up)
    result = runner.invoke(app, ["run", str(tiny), "--out", str(tmp_path / "out"), "--quiet",
                                 "--no-video", "--fields", "npz", "--every", "1"])
    assert result.exit_code == 1, result.output
    assert isinstance(result.exception, SystemExit)
    errors = [line for line in result.output.splitlines() if line.startswith("error:")]
    # Only the field writer fails here: the checkpoint of the last good step is written.
    assert len(errors) == 1, result.output
    assert errors[0].startswith("error: run failed at step") and "No space left" in errors[0]
    assert "note: the last good state is saved in" in result.output
    assert "Traceback" not in result.output
