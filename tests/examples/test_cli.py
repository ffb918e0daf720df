"""The ``elastoflow`` command end to end on tiny scenes (typer's CliRunner, in process)."""

from __future__ import annotations

import os
import signal
import xml.etree.ElementTree as ET
from pathlib import Path

import meshio
import numpy as np
import pytest
from typer.testing import CliRunner

from elastoflow.cli import app
from elastoflow.scenes import list_scenes, load_scene
from tiny_scene import tiny_scene

TINY_SCENE = tiny_scene()

runner = CliRunner()


def _invoke(*args: str):
    result = runner.invoke(app, [str(a) for a in args])
    text = result.output  # stdout and stderr together
    return result, text


@pytest.fixture()
def tiny(tmp_path) -> Path:
    path = tmp_path / "tiny.toml"
    path.write_text(TINY_SCENE)
    return path


def test_help_lists_commands_and_examples() -> None:
    result, text = _invoke("--help")
    assert result.exit_code == 0
    for word in ("run", "list", "validate", "view", "render", "bench", "dump", "warmup",
                 "Examples"):
        assert word in text


def test_list_shows_every_built_in_scene() -> None:
    result, text = _invoke("list")
    assert result.exit_code == 0
    for name in list_scenes():
        assert name in text


def test_validate_good_and_bad(tiny, tmp_path) -> None:
    result, text = _invoke("validate", tiny)
    assert result.exit_code == 0 and text.startswith("ok: tiny: 16x16 cells, 1 bodies")
    bad = tmp_path / "bad.toml"
    bad.write_text(TINY_SCENE.replace("lx = 1.0", "lx = -1.0\ncolour = 3"))
    result, text = _invoke("validate", bad)
    assert result.exit_code == 2
    lines = text.strip().splitlines()
    assert len(lines) == 2 and "Traceback" not in text
    assert any("domain.lx = -1.0" in line for line in lines)
    assert any("domain.colour: unknown key" in line for line in lines)
    result, text = _invoke("validate", "no_such_scene")
    assert result.exit_code == 2 and "unknown scene name" in text and "Traceback" not in text


def test_dump_writes_a_loadable_scene(tmp_path) -> None:
    target = tmp_path / "windmill.toml"
    result, _ = _invoke("dump", "windmill", "-o", target)
    assert result.exit_code == 0
    assert load_scene(target).name == "windmill"
    result, text = _invoke("dump", "cavity")
    assert result.exit_code == 0 and "[domain]" in text


def test_run_writes_video_fields_probes_and_render(tiny, tmp_path) -> None:
    out = tmp_path / "out"
    result, text = _invoke("run", tiny, "--out", out, "--fields", "npz,vtk", "--meshes",
                           "--every", "3", "--quiet")
    assert result.exit_code == 0, text
    assert (out / "video.mp4").stat().st_size > 0
    with np.load(out / "fields" / "step_000004.npz") as data:
        assert int(data["step"]) == 4 and data["velocity"].shape == (16, 16, 2)
    fluid = meshio.read(out / "fields" / "fluid_000004.vtu")
    assert fluid.cell_data["pressure"][0].shape == (256,)
    frames = [d.get("file") for d in ET.parse(out / "fields" / "body0.pvd").getroot().iter("DataSet")]
    # Every third step, and the last one.
    assert frames == [f"body0_{k:06d}.vtu" for k in (0, 3, 4)]
    assert meshio.read(out / "meshes" / "body0_000004.obj").points.shape[1] == 3
    header = (out / "probes.csv").read_text().splitlines()
    assert len(header) == 1 + 4 and header[0].startswith("step,time [s],body0_node1")
    assert (out / "probes.png").exists()
    assert (out / "checkpoints" / "checkpoint_00000004.npz").exists()
    assert not [p for p in out.rglob("*") if ".tmp" in p.name]

    result, text = _invoke("render", out, "--view", "vorticity")
    assert result.exit_code == 0, text
    assert (out / "render_vorticity.mp4").stat().st_size > 0


def test_resume_is_bit_for_bit(tiny, tmp_path) -> None:
    straight, split = tmp_path / "straight", tmp_path / "split"
    args = ("--no-video", "--no-probes", "--quiet")
    assert _invoke("run", tiny, "--out", straight, *args)[0].exit_code == 0
    assert _invoke("run", tiny, "--out", split, "--steps", "2", *args)[0].exit_code == 0
    result, text = _invoke("run", tiny, "--out", split, "--resume", *args)
    assert result.exit_code == 0 and "resuming from" in text
    with np.load(straight / "checkpoints" / "checkpoint_00000004.npz") as a, \
            np.load(split / "checkpoints" / "checkpoint_00000004.npz") as b:
        assert set(a.files) == set(b.files)
        for key in a.files:
            np.testing.assert_array_equal(a[key], b[key], err_msg=key)


def test_ctrl_c_stops_cleanly_and_says_how_to_resume(tiny, tmp_path, monkeypatch) -> None:
    from elastoflow.simulation import Simulation

    original = Simulation.step

    def step_then_interrupt(self):
        report = original(self)
        if self.step_index == 3:
            os.kill(os.getpid(), signal.SIGINT)
        return report

    monkeypatch.setattr(Simulation, "step", step_then_interrupt)
    out = tmp_path / "out"
    result, text = _invoke("run", tiny, "--out", out, "--steps", "10", "--quiet")
    assert result.exit_code == 130
    assert "stopped at step 3 of 10" in text and "--resume" in text
    assert (out / "checkpoints" / "checkpoint_00000003.npz").exists()
    assert (out / "video.mp4").stat().st_size > 0


def test_failed_run_exits_1_with_where(tiny, tmp_path, monkeypatch) -> None:
    from elastoflow.simulation import Simulation, SimulationBlowUp

    def blow_up(self):
        raise SimulationBlowUp("step 1, t = 0.02 s, body 0: element 3 inverted")

    monkeypatch.setattr(Simulation, "step", blow_up)
    result, text = _invoke("run", tiny, "--out", tmp_path / "out", "--quiet")
    assert result.exit_code == 1
    assert "run failed at step 1" in text and "body 0: element 3" in text
    assert "Traceback" not in text


def test_bad_options_exit_2(tiny, tmp_path) -> None:
    result, text = _invoke("run", tiny, "--out", tmp_path, "--fields", "csv")
    assert result.exit_code == 2 and "--fields" in text
    result, text = _invoke("run", tiny, "--out", tmp_path, "--resume")
    assert result.exit_code == 2 and "no checkpoint" in text


def test_bench_times_a_scene(tiny) -> None:
    result, text = _invoke("bench", tiny, "--steps", "2")
    assert result.exit_code == 0 and "steps/s" in text


def test_warmup_steps_the_named_scene_and_rejects_unknown_ones() -> None:
    result, text = _invoke("warmup", "cavity")
    assert result.exit_code == 0, text
    assert "cavity" in text and "kernels compiled and cached" in text
    result, text = _invoke("warmup", "no_such_scene")
    assert result.exit_code == 2 and "no_such_scene" in text and "Traceback" not in text
