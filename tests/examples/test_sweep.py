"""``elastoflow sweep`` against a real Dask cluster: a ``dask scheduler`` and two ``dask worker``
processes started on localhost (not an in-process cluster), the command run as a user runs it.

Checks: every point's result (a blown-up point recorded with its message), the Parquet summary
and the Zarr store read back with pandas and xarray, a second run that skips finished points,
a worker killed with SIGKILL mid-point whose point resumes from its checkpoint on a worker and
completes with its whole probe record.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

pd = pytest.importorskip("pandas")
xr = pytest.importorskip("xarray")
distributed = pytest.importorskip("distributed")

SCENE = """
name = "cavity_{n}"
[domain]
lx = 1.0
ly = 1.0
nx = {n}
[fluid]
viscosity = 0.01
[boundaries]
top = {{ type = "moving", velocity = 1.0 }}
[time]
dt = 0.01
steps = {steps}
substeps = 1
[outputs]
probes = [{{ kind = "kinetic_energy" }}, {{ kind = "pressure_iterations" }}]
"""

_ENV = {**os.environ, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}


def _dask() -> str:
    return str(Path(sys.executable).parent / "dask")


@pytest.fixture()
def scheduler(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """The scheduler file of a scheduler and two single-thread workers on 127.0.0.1."""
    folder = tmp_path_factory.mktemp("dask")
    address_file = folder / "scheduler.json"
    log = open(folder / "cluster.log", "w")  # noqa: SIM115 - open for the fixture's lifetime
    processes = [subprocess.Popen(
        [_dask(), "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
         "--scheduler-file", str(address_file)], stdout=log, stderr=subprocess.STDOUT, env=_ENV)]
    try:
        deadline = time.monotonic() + 60
        while not address_file.exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        for k in range(2):
            processes.append(subprocess.Popen(
                [_dask(), "worker", "--scheduler-file", str(address_file), "--nthreads", "1",
                 "--nworkers", "1", "--no-dashboard", "--host", "127.0.0.1", "--name",
                 f"worker{k}", "--local-directory", str(folder / f"worker{k}")],
                stdout=log, stderr=subprocess.STDOUT, env=_ENV))
        with distributed.Client(scheduler_file=str(address_file), timeout="60s") as client:
            client.wait_for_workers(2, timeout=90)
        yield address_file
    finally:
        try:
            with distributed.Client(scheduler_file=str(address_file), timeout="10s") as client:
                client.shutdown()
        except (OSError, TimeoutError):
            pass
        for process in reversed(processes):
            if process.poll() is None:
                process.terminate()
        for process in reversed(processes):
            try:
                process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                process.kill()
        log.close()


def _sweep(folder: Path, steps: int, n: int, body: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "cavity.toml").write_text(SCENE.format(n=n, steps=steps))
    path = folder / "sweep.toml"
    path.write_text(f'name = "test"\nscene = "cavity.toml"\n{body}')
    return path


def _run(sweep: Path, out: Path, scheduler: Path, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "elastoflow.cli", "sweep", str(sweep), "--out", str(out),
         "--scheduler", str(scheduler), *extra], capture_output=True, text=True, env=_ENV,
        timeout=300)


def test_sweep_on_a_scheduler_and_two_worker_processes(tmp_path: Path, scheduler: Path) -> None:
    # One test, so that pytest-xdist never starts a second cluster in its other process.
    _results_summary_zarr_and_rerun(tmp_path / "results", scheduler)
    _worker_killed_mid_point_resumes_from_its_checkpoint(tmp_path / "killed", scheduler)


def _results_summary_zarr_and_rerun(tmp_path: Path, scheduler: Path) -> None:
    sweep = _sweep(tmp_path, steps=30, n=16, body="""
[[points]]
"fluid.viscosity" = 0.01
[[points]]
"fluid.viscosity" = 0.02
[[points]]
"fluid.viscosity" = 0.01
"boundaries.top.velocity" = 2.0
[[points]]
"fluid.viscosity" = 0.02
"boundaries.top.velocity" = 2.0
[[points]]
"fluid.viscosity" = 0.01
"time.dt" = 5.0
[run]
checkpoint_every = 10
probe_plot = false
[snapshots]
times = [0.1, 0.25]
fields = ["velocity_x", "vorticity"]
""")
    out = tmp_path / "out"
    first = _run(sweep, out, scheduler)
    # A blown-up point makes the sweep exit 1 after every other point finished.
    assert first.returncode == 1, first.stdout + first.stderr
    assert "4 of 5 points done, 1 failed, 0 lost" in first.stdout
    assert "point 4: step 1" in first.stderr and "CFL" in first.stderr

    summary = pd.read_parquet(out / "summary.parquet")
    assert summary["point"].tolist() == [0, 1, 2, 3, 4]
    assert summary["status"].tolist() == ["done"] * 4 + ["failed"]
    assert summary["fluid.viscosity"].tolist() == [0.01, 0.02, 0.01, 0.02, 0.01]
    assert summary["steps"].tolist()[:4] == [30] * 4
    assert (summary["wall_time [s]"] > 0).all()
    assert "CFL" in summary["message"][4]
    energy = summary["fluid_kinetic_energy_final [J/m]"]
    # A faster lid, more energy; early on, a more viscous fluid carries more of the lid's.
    assert energy[2] > energy[0] > 0.0 and energy[3] > energy[1] > energy[0]
    assert all(worker.startswith("tcp://127.0.0.1:") for worker in summary["worker"])
    for k in range(4):
        probes = pd.read_csv(out / "points" / f"point_{k:05d}" / "probes.csv")
        assert probes["fluid_kinetic_energy [J/m]"].iloc[-1] == pytest.approx(energy[k],
                                                                             rel=1e-8)

    fields = xr.open_zarr(out / "fields.zarr")
    assert fields["vorticity"].dims == ("point", "time", "x", "y")
    assert fields["vorticity"].shape == (5, 2, 16, 16)
    assert fields["time"].values.tolist() == [0.1, 0.25]
    assert fields["fluid.viscosity"].values.tolist() == [0.01, 0.02, 0.01, 0.02, 0.01]
    assert fields["status"].values.tolist() == ["done"] * 4 + ["failed"]
    assert np.isfinite(fields["velocity_x"].values[:4]).all()
    assert np.isnan(fields["velocity_x"].values[4]).all()
    np.testing.assert_allclose(fields["snapshot_time"].values[:4], [[0.1, 0.25]] * 4)
    with np.load(out / "points" / "point_00002" / "snapshots" / "snapshot_001.npz") as saved:
        np.testing.assert_array_equal(fields["vorticity"].values[2, 1],
                                      saved["vorticity"].astype(np.float32))

    # The same sweep again: nothing runs, nothing is rewritten.
    stamps = {p: p.stat().st_mtime_ns for p in out.glob("points/*/result.json")}
    second = _run(sweep, out, scheduler)
    assert second.returncode == 1
    assert "4/5 done (4 before), 1 failed, 0 running, 0 queued" in second.stderr
    assert "4 of 5 points done, 1 failed" in second.stdout
    assert {p: p.stat().st_mtime_ns for p in out.glob("points/*/result.json")} == stamps
    pd.testing.assert_frame_equal(pd.read_parquet(out / "summary.parquet"), summary)

    # An edited sweep in the same folder is refused, one line per changed point.
    sweep.write_text(sweep.read_text().replace('"fluid.viscosity" = 0.02', '"fluid.viscosity" = 0.03'))
    third = _run(sweep, out, scheduler)
    assert third.returncode == 2
    assert third.stderr.count("other parameters") == 2


def _worker_killed_mid_point_resumes_from_its_checkpoint(tmp_path: Path,
                                                         scheduler: Path) -> None:
    steps, every = 1200, 100
    sweep = _sweep(tmp_path, steps=steps, n=32, body=f"""
[grid]
"boundaries.top.velocity" = [0.5, 1.0, 1.5, 2.0]
[run]
checkpoint_every = {every}
probe_plot = false
""")
    out = tmp_path / "out"
    process = subprocess.Popen(
        [sys.executable, "-m", "elastoflow.cli", "sweep", str(sweep), "--out", str(out),
         "--scheduler", str(scheduler)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True, env=_ENV)
    killed: tuple[int, Path] | None = None
    deadline = time.monotonic() + 120
    try:
        while killed is None and time.monotonic() < deadline and process.poll() is None:
            for folder in sorted(out.glob("points/point_*")):
                running = folder / "running.json"
                saved = [int(p.stem.split("_")[1])
                         for p in (folder / "checkpoints").glob("checkpoint_*.npz")]
                if (running.exists() and not (folder / "result.json").exists()
                        and max(saved, default=0) > 0):
                    pid = json.loads(running.read_text())["pid"]
                    os.kill(pid, signal.SIGKILL)
                    killed = (pid, folder)
                    break
            time.sleep(0.05)
        stdout, stderr = process.communicate(timeout=300)
    finally:
        if process.poll() is None:
            process.kill()
    assert killed is not None, "no point was caught between a checkpoint and its end"
    assert process.returncode == 0, stdout + stderr
    assert "4 of 4 points done, 0 failed, 0 lost" in stdout

    summary = pd.read_parquet(out / "summary.parquet")
    assert (summary["status"] == "done").all() and (summary["steps"] == steps).all()
    row = summary[summary["folder"] == killed[1].name].iloc[0]
    assert row["attempts"] == 2
    assert 0 < row["resumed_from_step"] < steps and row["resumed_from_step"] % every == 0
    # The resumed point's probe record is whole: every step once, in order.
    probes = pd.read_csv(killed[1] / "probes.csv")
    assert probes["step"].tolist() == list(range(1, steps + 1))
    # and its result is the uninterrupted run's (resume is bit-exact): the same point again.
    assert not (killed[1] / "running.json").exists()
    others = summary[summary["folder"] != killed[1].name]
    assert (others["attempts"] == 1).all()


def test_example_study_checks_and_bad_points_exit_2(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from elastoflow.cli import app

    root = Path(__file__).resolve().parents[2]
    checked = CliRunner().invoke(app, ["sweep", str(root / "examples" / "sweep_strouhal.toml"),
                                       "--check"])
    assert checked.exit_code == 0, checked.output
    assert "ok: strouhal: 5 points" in checked.output
    assert "point 4 (fluid.viscosity = 0.005): 3750 steps" in checked.output

    bad = _sweep(tmp_path, steps=10, n=8, body='[grid]\n"fluid.viscosity" = [0.01, -1.0]\n')
    refused = CliRunner().invoke(app, ["sweep", str(bad), "--out", str(tmp_path / "out")])
    assert refused.exit_code == 2
    assert "point 1 (fluid.viscosity = -1.0)" in refused.output
    assert not (tmp_path / "out").exists()


def _gone(pid: int, group: bool = False) -> bool:
    try:
        (os.killpg if group else os.kill)(pid, 0)
    except ProcessLookupError:
        return True
    return False


def test_ctrl_c_stops_cleanly_and_the_printed_command_resumes(tmp_path: Path) -> None:
    """Ctrl-C in a terminal: SIGINT to the command's whole process group (the command and the
    local cluster's worker process). The sweep stops with exit 130, no traceback, the summary
    written (finished points done, the running one stopped at a step with a checkpoint, the
    queued one not started: both pending), every process gone, and the printed command
    resumes: finished points skipped, the stopped one from its step, the other from scratch.

    Deterministic: the long point is caught between a checkpoint and its end, its worker
    process frozen (SIGSTOP) before the SIGINT and let go (SIGCONT) only once the command says
    it is stopping; from then on the point runs only the few steps its own worker takes to read
    the stop, whatever the load on the machine. One worker: the points run in their order."""
    long_steps, every = 600, 50
    sweep = _sweep(tmp_path, steps=long_steps, n=32, body=f"""
[[points]]
"time.steps" = 20
[[points]]
"time.steps" = 20
"boundaries.top.velocity" = 2.0
[[points]]
"boundaries.top.velocity" = 0.5
[[points]]
"boundaries.top.velocity" = 1.5
[run]
checkpoint_every = {every}
probe_plot = false
""")
    out = tmp_path / "out"
    process = subprocess.Popen(
        [sys.executable, "-m", "elastoflow.cli", "sweep", str(sweep), "--out", str(out),
         "--workers", "1", "--no-dashboard"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True, env=_ENV, start_new_session=True)
    group = process.pid
    points = [out / "points" / f"point_{k:05d}" for k in range(4)]
    long = points[2]
    stderr_lines: list[str] = []
    reader = threading.Thread(target=lambda: stderr_lines.extend(iter(process.stderr.readline,
                                                                      "")), daemon=True)
    reader.start()

    def saved_steps(point: Path) -> list[int]:
        return [int(c.stem.split("_")[1])
                for c in (point / "checkpoints").glob("checkpoint_*.npz")]

    def worker_mid_run() -> int | None:
        """The pid running the long point once it has a checkpoint and no result."""
        if (long / "result.json").exists() or max(saved_steps(long), default=0) == 0:
            return None
        try:
            return int(json.loads((long / "running.json").read_text())["pid"])
        except (OSError, ValueError, KeyError):
            return None

    worker = None
    try:
        deadline = time.monotonic() + 120
        while worker is None and time.monotonic() < deadline and process.poll() is None:
            worker = worker_mid_run()
            time.sleep(0.01)
        assert worker is not None, f"the long point was not caught mid-run: {stderr_lines}"
        os.kill(worker, signal.SIGSTOP)
        if (long / "result.json").exists():
            pytest.fail("the long point ended before its worker was frozen")
        caught = max(saved_steps(long))
        os.killpg(group, signal.SIGINT)
        deadline = time.monotonic() + 60
        while not any(line.startswith("stopping:") for line in stderr_lines) and \
                time.monotonic() < deadline and process.poll() is None:
            time.sleep(0.01)
        os.kill(worker, signal.SIGCONT)
        stdout = process.stdout.read()
        process.wait(timeout=120)
        reader.join(timeout=10)
        stderr = "".join(stderr_lines)
        deadline = time.monotonic() + 60
        while not (_gone(group, group=True) and _gone(worker)) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert _gone(group, group=True), "processes of the sweep outlived it"
        assert _gone(worker), "the worker process outlived the sweep"
    finally:
        if worker is not None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(worker, signal.SIGCONT)
        if not _gone(group, group=True):
            os.killpg(group, signal.SIGKILL)
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == 130, stdout + stderr
    assert "Traceback" not in stdout + stderr, stderr
    assert "Exception" not in stderr, stderr
    summary = pd.read_parquet(out / "summary.parquet")
    assert summary["status"].tolist() == ["done", "done", "pending", "pending"]
    # The running point stopped at a step of its own, past the checkpoint it was caught
    # after, and saved it there; the queued one never started.
    stopped_at = int(summary["steps"][2])
    assert caught <= stopped_at < long_steps
    assert summary["message"][2] == f"stopped at step {stopped_at}"
    assert max(saved_steps(long)) == stopped_at
    assert summary["steps"][3] == 0 and not (points[3] / "checkpoints").exists()
    assert not any((p / "result.json").exists() for p in points[2:])
    assert stdout.count("resume with:") == 1
    command = stdout.split("resume with:\n", 1)[1].splitlines()[0].split()
    assert command[:3] == ["elastoflow", "sweep", str(sweep)]
    # The printed command keeps the cluster's options.
    assert command[3:] == ["--out", str(out), "--workers", "1", "--no-dashboard"]

    stamps = {p: (p / "result.json").stat().st_mtime_ns for p in points[:2]}
    again = subprocess.run([sys.executable, "-m", "elastoflow.cli", *command[1:]],
                           capture_output=True, text=True, env=_ENV, timeout=300)
    assert again.returncode == 0, again.stdout + again.stderr
    assert "4 of 4 points done, 0 failed, 0 lost" in again.stdout
    assert "(2 before)" in again.stderr
    assert {p: (p / "result.json").stat().st_mtime_ns for p in points[:2]} == stamps
    summary = pd.read_parquet(out / "summary.parquet")
    assert (summary["status"] == "done").all()
    assert summary["steps"].tolist() == [20, 20, long_steps, long_steps]
    assert summary["resumed_from_step"].tolist()[2:] == [stopped_at, 0]
    assert summary["attempts"].tolist()[2:] == [2, 1]
    for point in points[2:]:
        probes = pd.read_csv(point / "probes.csv")
        assert probes["step"].tolist() == list(range(1, long_steps + 1))
        assert not [p for p in point.rglob(".*") if ".tmp" in p.name]
        assert not (point / "running.json").exists()


def test_a_bad_scheduler_is_one_line_and_the_name_stays_under_out(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from typer.testing import CliRunner

    from elastoflow.cli import app

    work = tmp_path / "a" / "b"
    work.mkdir(parents=True)
    monkeypatch.chdir(work)
    sweep = _sweep(work, steps=3, n=8, body='[grid]\n"fluid.viscosity" = [0.01]\n')
    sweep.write_text(sweep.read_text().replace('name = "test"', 'name = "../../escape"'))
    (work / "empty.json").write_text("{}")
    (work / "binary.json").write_bytes(bytes(range(256)))
    for scheduler, says in (("missing.json", "no scheduler file missing.json"),
                            ("empty.json", "is not a Dask scheduler file"),
                            ("binary.json", "is not a Dask scheduler file"),
                            ("nonsense", "not a scheduler address")):
        result = CliRunner().invoke(app, ["sweep", str(sweep), "--scheduler", scheduler])
        assert result.exit_code == 1, result.output
        assert isinstance(result.exception, SystemExit), result.output
        errors = [line for line in result.output.splitlines() if line.startswith("error:")]
        assert len(errors) == 1 and says in errors[0], result.output
    # The sweep's name never leads out of out/: "../../escape" is out/escape.
    assert (work / "out" / "escape" / "points" / "point_00000").is_dir()
    assert not (tmp_path / "escape").exists() and not (work / "escape").exists()
