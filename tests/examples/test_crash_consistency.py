"""Crash consistency of `elastoflow run` (issue 10, items 3, 6, 7, 8): after SIGKILL or SIGINT
at a random step, a failed step, a full disk or a damaged checkpoint, the output folder holds
only complete files, and ``--resume`` removes the leftovers and continues every output (video,
probes, fields in npz, VTK and XDMF, meshes) to the same result as a run never interrupted.

The kills run the command in a subprocess; everything else runs in process (CliRunner).
"""

from __future__ import annotations

import errno
import json
import os
import random
import shlex
import signal
import subprocess
import sys
import time
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from elastoflow.cli import app
from elastoflow.io import read_checkpoint, read_probes
from tiny_scene import tiny_scene

runner = CliRunner()

STEPS = 40
SCENE = tiny_scene(steps=STEPS, checkpoint_every=5)

OPTIONS = ("--fields", "npz,vtk,xdmf", "--meshes", "--every", "2", "--quiet")


@pytest.fixture()
def scene(tmp_path: Path) -> Path:
    path = tmp_path / "tiny.toml"
    path.write_text(SCENE)
    return path


def _run(*args: Any) -> tuple[int, str]:
    result = runner.invoke(app, [str(a) for a in args])
    assert "Traceback" not in result.output, result.output
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise result.exception
    return result.exit_code, result.output


@pytest.fixture(scope="module")
def straight(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The same scene and options, run without interruption."""
    folder = tmp_path_factory.mktemp("straight")
    (folder / "tiny.toml").write_text(SCENE)
    code, text = _run("run", folder / "tiny.toml", "--out", folder / "out", *OPTIONS)
    assert code == 0, text
    return folder / "out"


# -- what a complete output folder is ------------------------------------------------------

def _is_temporary(path: Path) -> bool:
    return path.name.startswith(".") and ".tmp" in path.name


def _temporaries(out: Path) -> list[Path]:
    return [p for p in out.rglob("*") if _is_temporary(p)]


def _assert_complete(out: Path) -> None:
    """Every file that is not a temporary reads back whole.

    Temporaries are told by name as the walk meets them, not from a list taken before it:
    the ffmpeg child of a killed run outlives it for a moment and may still create its
    temporary video part (seen in CI: ``video_parts/.current.<pid>.tmp.mp4`` appearing
    after the list was taken)."""
    import h5py
    import imageio.v2 as imageio
    import meshio

    for path in out.rglob("*"):
        if (_is_temporary(path) or any(_is_temporary(p) for p in path.parents)
                or path.is_dir()):
            continue
        suffix = path.suffix
        if suffix == ".npz" and path.parent.name == "checkpoints":
            read_checkpoint(path)
        elif suffix == ".npz":
            with np.load(path) as data:
                for key in data.files:
                    data[key]
        elif suffix == ".vtu":
            meshio.read(path)
        elif suffix == ".h5":
            with h5py.File(path, "r") as handle:
                for key in handle:
                    handle[key][()]
        elif suffix in (".xdmf", ".pvd"):
            ET.parse(path)
        elif suffix == ".csv":
            lines = path.read_text().split("\n")
            assert lines[-1] == "", f"{path}: last row cut short"
            width = len(lines[0].split(","))
            assert all(len(line.split(",")) == width for line in lines[1:-1]), path
        elif suffix == ".json":
            json.loads(path.read_text())
        elif suffix == ".toml":
            tomllib.loads(path.read_text())
        elif suffix == ".mp4":
            reader = imageio.get_reader(path)
            assert reader.count_frames() > 0, path
            reader.close()
        elif suffix == ".obj":
            meshio.read(path)


def _frames(video: Path) -> int:
    import imageio.v2 as imageio

    reader = imageio.get_reader(video)
    count = reader.count_frames()
    reader.close()
    return count


def _xdmf_times(path: Path) -> list[float]:
    import meshio

    with meshio.xdmf.TimeSeriesReader(str(path)) as reader:
        reader.read_points_cells()
        return [reader.read_data(k)[0] for k in range(reader.num_steps)]


def _assert_same_outputs(out: Path, reference: Path) -> None:
    """Every output of ``out`` equals that of the uninterrupted run (bit for bit where the
    format allows: probes, snapshots, the final checkpoint)."""
    assert not _temporaries(out)
    assert read_probes(out / "probes.csv") == read_probes(reference / "probes.csv")
    names = sorted(p.name for p in (reference / "fields").iterdir())
    assert sorted(p.name for p in (out / "fields").iterdir()) == names
    assert sorted(p.name for p in (out / "meshes").iterdir()) == sorted(
        p.name for p in (reference / "meshes").iterdir())
    for name in ("fluid.pvd", "body0.pvd"):
        assert (out / "fields" / name).read_text() == (reference / "fields" / name).read_text()
    times = _xdmf_times(out / "fields" / "fluid.xdmf")
    assert times == _xdmf_times(reference / "fields" / "fluid.xdmf")
    assert len(set(times)) == len(times)
    last = f"checkpoint_{STEPS:08d}.npz"
    a, b = read_checkpoint(out / "checkpoints" / last), read_checkpoint(
        reference / "checkpoints" / last)
    for key in a:
        if not key.startswith("run_"):
            np.testing.assert_array_equal(a[key], b[key], err_msg=key)
    with np.load(out / "fields" / f"step_{STEPS:06d}.npz") as x, \
            np.load(reference / "fields" / f"step_{STEPS:06d}.npz") as y:
        np.testing.assert_array_equal(x["pressure"], y["pressure"])
    # The video has one frame per saved step, none repeated (a frame every 2 steps + step 0).
    assert _frames(out / "video.mp4") == _frames(reference / "video.mp4") == STEPS // 2 + 1


# -- kills and interrupts -------------------------------------------------------------------

def _start(scene: Path, out: Path, *extra: str) -> subprocess.Popen[str]:
    environment = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen(
        [sys.executable, "-m", "elastoflow.cli", "run", str(scene), "--out", str(out),
         *OPTIONS, *extra],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=environment)


def _wait_for_step(process: subprocess.Popen[str], probes: Path, step: int) -> None:
    """Until the probes (a stream, one row per step) reach ``step``."""
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        if process.poll() is not None:
            raise AssertionError(f"the run ended before step {step}: {process.communicate()[0]}")
        if probes.exists() and probes.read_text().count("\n") - 1 >= step:
            return
        time.sleep(0.005)
    raise AssertionError(f"step {step} not reached")


@pytest.mark.parametrize("seed", [1, pytest.param(2, marks=pytest.mark.slow),
                                  pytest.param(3, marks=pytest.mark.slow)])
def test_sigkill_at_a_random_step_then_resume(seed: int, scene: Path, tmp_path: Path,
                                              straight: Path) -> None:
    step = random.Random(seed).randrange(2, STEPS - 4)
    out = tmp_path / "out"
    process = _start(scene, out)
    _wait_for_step(process, out / "probes.csv", step)
    process.kill()
    process.wait()
    # Killed: only complete files besides temporaries; the probes hold every step taken.
    _assert_complete(out)
    rows = read_probes(out / "probes.csv")[1]
    assert [int(r[0]) for r in rows] == list(range(1, len(rows) + 1)) and len(rows) >= step

    code, text = _run("run", scene, "--out", out, "--resume", "--quiet")
    assert code == 0, text
    assert "resuming from" in text
    _assert_same_outputs(out, straight)


@pytest.mark.parametrize("twice", [False, pytest.param(True, marks=pytest.mark.slow)],
                         ids=["once", "twice"])
def test_sigint_then_the_printed_resume_command(twice: bool, scene: Path, tmp_path: Path,
                                                straight: Path) -> None:
    step = random.Random(7 + twice).randrange(3, STEPS - 4)
    out = tmp_path / "out"
    process = _start(scene, out)
    _wait_for_step(process, out / "probes.csv", step)
    process.send_signal(signal.SIGINT)
    if twice:
        time.sleep(0.002)
        process.send_signal(signal.SIGINT)
    text = process.communicate(timeout=120)[0]
    assert process.returncode == 130, text
    assert "Traceback" not in text
    _assert_complete(out)
    assert not _temporaries(out)
    # The resume command carries the options of the run (--fields, --meshes, --every).
    command = shlex.split(text.split("resume with:\n", 1)[1].splitlines()[0])
    assert command[:2] == ["elastoflow", "run"] and "--resume" in command
    for option in ("--fields", "npz,vtk,xdmf", "--meshes", "--every", "2"):
        assert option in command
    code, text = _run(*command[1:], "--quiet")
    assert code == 0, text
    _assert_same_outputs(out, straight)


def test_resume_without_options_keeps_those_of_the_run(scene: Path, tmp_path: Path,
                                                       straight: Path) -> None:
    out = tmp_path / "out"
    code, text = _run("run", scene, "--out", out, *OPTIONS, "--steps", "12")
    assert code == 0, text
    # Nothing but --resume: the stored options (fields, meshes, every 2) apply.
    code, text = _run("run", scene, "--out", out, "--resume", "--quiet")
    assert code == 0, text
    _assert_same_outputs(out, straight)


# -- a failed step ----------------------------------------------------------------------------

def test_a_blow_up_keeps_the_last_good_step_and_saves_it(scene: Path, tmp_path: Path,
                                                          straight: Path,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    from elastoflow.simulation import Simulation, SimulationBlowUp

    original = Simulation.step

    def diverge_at_step_7(self: Simulation) -> Any:
        if self.step_index == 6:
            original(self)
            self.state.fluid.velocity_x[...] = np.nan  # the diverged state a blow-up leaves
            self.state.fluid.pressure[...] = 1e30
            for body in self.state.bodies:
                body.positions[...] += 1.0
            raise SimulationBlowUp("step 7, t = 0.14 s: fluid velocity_x is not finite")
        return original(self)

    monkeypatch.setattr(Simulation, "step", diverge_at_step_7)
    out = tmp_path / "out"
    code, text = _run("run", scene, "--out", out, *OPTIONS)
    assert code == 1
    assert "error: run failed at step 7" in text
    last_good = out / "checkpoints" / "checkpoint_00000006.npz"
    assert f"the last good state is saved in {last_good}" in text
    assert "--force-resume" in text
    _assert_complete(out)
    assert not _temporaries(out)
    # The last good step's files are those of the uninterrupted run; nothing was written from
    # the diverged state, and the saved state is the good one.
    for name in ("step_000006.npz", "fluid_000006.vtu", "fluid_000006.h5"):
        assert (out / "fields" / name).read_bytes() == (straight / "fields" / name).read_bytes()
    assert not (out / "fields" / "step_000007.npz").exists()
    times = _xdmf_times(out / "fields" / "fluid.xdmf")
    assert len(times) == len(set(times)) == 4  # steps 0, 2, 4, 6
    good = read_checkpoint(last_good)
    assert int(good["step_index"]) == 6 and np.isfinite(good["fluid.velocity_x"]).all()
    assert [int(r[0]) for r in read_probes(out / "probes.csv")[1]] == list(range(1, 7))

    # A rerun from there (the cause fixed) repeats no frame and no row.
    monkeypatch.setattr(Simulation, "step", original)
    code, text = _run("run", scene, "--out", out, "--resume", "--quiet")
    assert code == 0, text
    _assert_same_outputs(out, straight)


# -- full and read-only disks ---------------------------------------------------------------

def test_a_full_disk_keeps_the_probes_and_the_checkpoint_before(
        scene: Path, tmp_path: Path, straight: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """ENOSPC from step 8 on, for every kind of write (fields, probes, checkpoints)."""
    from elastoflow.io import FieldWriter, ProbeRecorder
    from elastoflow.io import _session

    full = {"now": False}

    def refuse_when_full(original: Any) -> Any:
        def write(*args: Any, **kwargs: Any) -> Any:
            if full["now"]:
                raise OSError(errno.ENOSPC, "No space left on device")
            return original(*args, **kwargs)
        return write

    monkeypatch.setattr(FieldWriter, "write", refuse_when_full(FieldWriter.write))
    monkeypatch.setattr(ProbeRecorder, "_append", refuse_when_full(ProbeRecorder._append))
    monkeypatch.setattr(_session, "save_checkpoint", refuse_when_full(_session.save_checkpoint))
    from elastoflow.simulation import Simulation

    original = Simulation.step

    def fill_at_step_8(self: Simulation) -> Any:
        report = original(self)
        full["now"] = full["now"] or self.step_index >= 8
        return report

    monkeypatch.setattr(Simulation, "step", fill_at_step_8)
    out = tmp_path / "out"
    code, text = _run("run", scene, "--out", out, *OPTIONS)
    assert code == 1
    errors = [line for line in text.splitlines() if line.startswith("error:")]
    assert errors[0].startswith("error: run failed at step 8") and "No space left" in errors[0]
    assert all("No space left" in line for line in errors) and len(errors) <= 2
    assert "the last good state is saved in" in text and "checkpoint_00000005.npz" in text
    _assert_complete(out)
    assert not _temporaries(out)
    assert [int(r[0]) for r in read_probes(out / "probes.csv")[1]] == list(range(1, 8))
    assert int(read_checkpoint(out / "checkpoints" / "checkpoint_00000005.npz")["step_index"]) == 5

    # Space freed: the run resumes from the checkpoint before and ends as if never stopped.
    monkeypatch.setattr(Simulation, "step", original)
    full["now"] = False
    code, text = _run("run", scene, "--out", out, "--resume", "--quiet")
    assert code == 0, text
    _assert_same_outputs(out, straight)


def _mount_tmpfs(folder: Path, size: str) -> bool:
    if not hasattr(os, "geteuid") or os.geteuid() != 0:
        return False
    folder.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(folder)],
                          capture_output=True, check=False)
    return done.returncode == 0


@pytest.mark.slow
def test_a_real_full_tmpfs(scene: Path, tmp_path: Path) -> None:
    """The same on a 600 kB tmpfs that fills during the run (where the machine lets us
    mount one)."""
    disk = tmp_path / "disk"
    if not _mount_tmpfs(disk, "600k"):
        pytest.skip("cannot mount a tmpfs here")
    try:
        out = disk / "out"
        code, text = _run("run", scene, "--out", out, *OPTIONS)
        assert code == 1, text
        errors = [line for line in text.splitlines() if line.startswith("error:")]
        assert errors and all("No space left" in line for line in errors), text
        _assert_complete(out)
        assert not _temporaries(out)
        rows = read_probes(out / "probes.csv")[1]
        assert [int(r[0]) for r in rows] == list(range(1, len(rows) + 1))
        newest = sorted((out / "checkpoints").glob("checkpoint_*.npz"))
        assert newest and int(read_checkpoint(newest[-1])["step_index"]) <= len(rows)
    finally:
        subprocess.run(["umount", str(disk)], check=False)


def test_a_read_only_output_folder_on_resume(scene: Path, tmp_path: Path,
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    import tempfile

    out = tmp_path / "out"
    assert _run("run", scene, "--out", out, "--steps", "5", "--quiet", "--no-video")[0] == 0

    def read_only(*args: Any, **kwargs: Any) -> None:
        raise OSError(errno.EROFS, "Read-only file system")

    monkeypatch.setattr(tempfile, "TemporaryFile", read_only)
    result = runner.invoke(app, ["run", str(scene), "--out", str(out), "--resume", "--quiet"])
    assert result.exit_code == 2
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and "cannot write there (Read-only file system)" in lines[0], lines


# -- the output folder -------------------------------------------------------------------------

def test_a_changed_scene_is_refused_unless_forced(scene: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert _run("run", scene, "--out", out, "--steps", "5", "--quiet", "--no-video")[0] == 0
    changed = tmp_path / "changed.toml"
    changed.write_text(SCENE.replace("viscosity = 1e-3", "viscosity = 1.0"))
    result = runner.invoke(app, ["run", str(changed), "--out", str(out), "--resume",
                                 "--steps", "8", "--quiet"])
    assert result.exit_code == 2
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and "fluid.viscosity: 0.001 -> 1.0" in lines[0]
    assert "--force-resume" in lines[0]
    code, text = _run("run", changed, "--out", out, "--resume", "--force-resume", "--steps", "8",
                      "--quiet")
    assert code == 0 and "resuming from" in text, text


def test_a_fresh_run_never_deletes_later_checkpoints_silently(scene: Path,
                                                              tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert _run("run", scene, "--out", out, "--steps", "15", "--quiet", "--no-video")[0] == 0
    before = sorted(p.name for p in (out / "checkpoints").iterdir())
    assert before == ["checkpoint_00000005.npz", "checkpoint_00000010.npz",
                      "checkpoint_00000015.npz"]
    result = runner.invoke(app, ["run", str(scene), "--out", str(out), "--steps", "5",
                                 "--quiet", "--no-video"])
    assert result.exit_code == 2
    assert "holds checkpoints of an earlier run (the newest at step 15)" in result.output
    assert sorted(p.name for p in (out / "checkpoints").iterdir()) == before
    code, text = _run("run", scene, "--out", out, "--steps", "5", "--quiet", "--no-video",
                      "--overwrite")
    assert code == 0, text
    assert sorted(p.name for p in (out / "checkpoints").iterdir()) == [
        "checkpoint_00000000.npz", "checkpoint_00000005.npz"]


def test_a_scene_name_never_leads_out_of_the_output_root(tmp_path: Path,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    work = tmp_path / "a" / "b"
    work.mkdir(parents=True)
    path = work / "escape.toml"
    path.write_text(SCENE.replace('name = "tiny"', 'name = "../../x"'))
    monkeypatch.chdir(work)
    code, text = _run("run", path, "--steps", "2", "--quiet", "--no-video")
    assert code == 0, text
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a"]
    assert sorted(p.name for p in (tmp_path / "a").iterdir()) == ["b"]
    assert (work / "out" / "x" / "probes.csv").exists()


def test_files_honour_the_umask(scene: Path, tmp_path: Path) -> None:
    previous = os.umask(0o022)
    try:
        out = tmp_path / "out"
        code, text = _run("run", scene, "--out", out, "--steps", "2", "--fields", "npz,xdmf",
                          "--quiet")
        assert code == 0, text
    finally:
        os.umask(previous)
    files = [p for p in out.rglob("*") if p.is_file()]
    assert files
    assert {oct(p.stat().st_mode & 0o777) for p in files} == {oct(0o644)}


def test_leftovers_of_a_kill_are_removed_on_resume(scene: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert _run("run", scene, "--out", out, "--steps", "5", "--quiet", *OPTIONS[:5])[0] == 0
    leftovers = [out / "video_parts" / ".current.4242.tmp.mp4",
                 out / "fields" / ".fluid_000006.4242.ab12cd34.tmp.vtu",
                 out / "fields" / ".xdmf.4242.tmp" / "fluid.h5", out / ".probes.1.2.tmp.csv"]
    for path in leftovers:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(b"partial")
    code, text = _run("run", scene, "--out", out, "--resume", "--steps", "8", "--quiet")
    assert code == 0, text
    assert "removed 4 temporary files left by an interrupted run" in text
    assert not _temporaries(out)


# -- compiling -------------------------------------------------------------------------------

def test_a_run_that_must_compile_says_so(scene: Path, tmp_path: Path,
                                         monkeypatch: pytest.MonkeyPatch) -> None:
    import elastoflow._warmup

    monkeypatch.setattr(elastoflow._warmup, "kernels_need_compiling", lambda: True)
    code, text = _run("run", scene, "--out", tmp_path / "out", "--steps", "2", "--no-video")
    assert code == 0, text
    assert text.startswith("compiling kernels (first run, about a minute")


def test_an_empty_kernel_cache_is_seen(tmp_path: Path) -> None:
    code = ("from elastoflow._warmup import kernels_need_compiling as k; "
            "print(k())")
    fresh = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           env={**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}, check=True)
    assert fresh.stdout.strip() == "True", fresh.stderr
