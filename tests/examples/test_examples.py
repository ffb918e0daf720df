"""Every example runs headless for a few steps and does what it says."""

from __future__ import annotations

import csv
import importlib.util
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest
from typer.testing import CliRunner

from elastoflow.cli import app
from elastoflow.io import ProbeRecorder, read_probes
from elastoflow.scenes import build_simulation, load_scene

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def test_reeds_scene_validates_and_runs(tmp_path):
    path = EXAMPLES / "reeds_in_a_channel.toml"
    result = CliRunner().invoke(app, ["validate", str(path)])
    assert result.exit_code == 0, result.output
    result = CliRunner().invoke(
        app, ["run", str(path), "--steps", "4", "--out", str(tmp_path / "reeds"), "--quiet"]
    )
    assert result.exit_code == 0, result.output
    assert (tmp_path / "reeds" / "video.mp4").stat().st_size > 0
    sim = build_simulation(load_scene(path))
    assert len(sim.bodies) == 3 and len(sim.obstacles) == 1


def test_notebook_api_example_writes_a_frame(tmp_path):
    spec = importlib.util.spec_from_file_location("notebook_api", EXAMPLES / "notebook_api.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    out = module.main(steps=3, out=tmp_path / "frame.png")
    frame = iio.imread(out)
    assert frame.ndim == 3 and frame.shape[2] == 3
    assert np.ptp(frame) > 0


def test_free_surface_dam_break_example_writes_a_picture(tmp_path):
    spec = importlib.util.spec_from_file_location("free_surface_dam_break",
                                                  EXAMPLES / "free_surface_dam_break.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    out = module.main(steps=3, out=tmp_path / "dam_break.png")
    frame = iio.imread(out)
    assert frame.ndim == 3 and np.ptp(frame) > 0


def test_three_d_jet_example_writes_a_video_and_image_data(tmp_path):
    from elastoflow.io import read_image_data

    spec = importlib.util.spec_from_file_location("three_d_jet", EXAMPLES / "three_d_jet.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    out = module.main(steps=8, out=tmp_path / "jet", every=4)
    frames = iio.imread(out / "video.mp4")
    assert frames.shape[0] == 9 and np.ptp(frames[-1]) > 0
    last = read_image_data(out / "fields" / "fluid_000008.vti")
    assert last.cells == (32, 48, 32) and last.cell_data["dye"].max() > 0.5
    assert last.cell_data["velocity"][..., 1].max() > 0.1  # the jet pushes upwards
    assert "fluid_000004.vti" in (out / "fields" / "fluid.pvd").read_text()


def test_dfg_2d_2_scene_file_is_the_validation_set_up(tmp_path):
    """The scene file alone sets up DFG 2D-2 as `elastoflow validate dfg-2d-2` does (channel,
    cylinder, inflow, fluid, numerics, start): at 10 cells per diameter its drag follows the
    validation driver's step by step. And it runs from the command line with its probes."""
    from elastoflow.validation import run_dfg

    path = EXAMPLES / "dfg_2d_2.toml"
    result = CliRunner().invoke(app, ["validate", str(path)])
    assert result.exit_code == 0, result.output
    scene = load_scene(path)
    # The file names no advection scheme: the default, the flux form, is the one compared.
    assert "advection =" not in path.read_text()
    assert scene.fluid.advection == "upwind3"
    coarse = scene.model_copy(update={
        "domain": scene.domain.model_copy(update={"h": 0.01}),
        "time": scene.time.model_copy(update={"dt": 0.01 / 3.0}),
        "obstacles": [scene.obstacles[0].model_copy(update={"segments": 126})],
        "outputs": scene.outputs.model_copy(update={"video": None}),
    })
    simulation = build_simulation(coarse)
    recorder = ProbeRecorder(coarse.outputs.probes, simulation, tmp_path / "probes.csv")
    steps = 60
    for _ in range(steps):
        report = simulation.step()
        recorder.observe(simulation)
        recorder.record(simulation, report)
    recorder.close()
    columns, rows = read_probes(tmp_path / "probes.csv")
    data = dict(zip(columns, np.asarray(rows).T, strict=True))
    reference = run_dfg(10, duration=steps * 0.01 / 3.0, advection="upwind3",
                        viscosity_scheme="bdf2", advecting_velocity="extrapolated",
                        incremental_pressure=True)
    coefficient = 2.0 / (1.0 * 1.0**2 * 0.1)  # 2 F / (rho U^2 D)
    np.testing.assert_allclose(coefficient * data["force_obstacle0_x [N/m]"][-20:],
                               reference.series["drag"][-20:], rtol=1e-3)
    # The momentum balance over the validation driver's box (1.5 diameters from the centre),
    # with BDF2's time derivative: the driver's drag_cv and lift_cv.
    np.testing.assert_allclose(coefficient * data["balance_obstacle0_x [N/m]"][-20:],
                               reference.series["drag_cv"][-20:], rtol=1e-3)
    np.testing.assert_allclose(coefficient * data["balance_obstacle0_y [N/m]"][-20:],
                               reference.series["lift_cv"][-20:], atol=2e-3)
    result = CliRunner().invoke(app, ["run", str(path), "--steps", "3", "--out",
                                      str(tmp_path / "dfg"), "--quiet"])
    assert result.exit_code == 0, result.output
    header = (tmp_path / "dfg" / "probes.csv").read_text().splitlines()[0]
    assert "force_obstacle0_x" in header and "pressure_(0.15,0.2)-(0.25,0.2)" in header
    assert "balance_obstacle0_y [N/m]" in header


def test_dfg_2d_2_quantities_script_evaluates_the_benchmark_from_probes(tmp_path, capsys):
    """The script reads a run's probes.csv and evaluates the benchmark's definitions: on
    sampled sinusoids of known frequency, peaks and phase it returns them."""
    spec = importlib.util.spec_from_file_location("dfg_2d_2_quantities",
                                                  EXAMPLES / "dfg_2d_2_quantities.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    time = np.arange(1, 8001) * 1e-3
    phase = 2.0 * np.pi * 3.0 * time  # f = 3 Hz: St = D f / U = 0.3
    rows = np.column_stack([np.arange(1, 8001), time,
                            (3.2 + 0.03 * np.sin(2.0 * phase)) / 20.0,  # c_D = 20 F
                            np.sin(phase) / 20.0,
                            2.45 + 0.03 * np.sin(phase),
                            (3.21 + 0.03 * np.sin(2.0 * phase)) / 20.0,
                            1.05 * np.sin(phase) / 20.0])
    with open(tmp_path / "probes.csv", "w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(["step", "time [s]", "force_obstacle0_x [N/m]",
                         "force_obstacle0_y [N/m]", "pressure_(0.15,0.2)-(0.25,0.2) [Pa]",
                         "balance_obstacle0_x [N/m]", "balance_obstacle0_y [N/m]"])
        writer.writerows(rows.tolist())
    both = module.main(tmp_path)
    assert both["momentum_balance"]["lift_max"] == pytest.approx(1.05, rel=1e-4)
    assert both["momentum_balance"]["drag_max"] == pytest.approx(3.24, rel=1e-4)
    quantities = both["traction"]
    assert quantities["strouhal"] == pytest.approx(0.3, rel=1e-3)
    assert quantities["drag_max"] == pytest.approx(3.23, rel=1e-4)
    assert quantities["lift_max"] == pytest.approx(1.0, rel=1e-4)
    # Half a period after the lift's maximum the difference is at its minimum.
    assert quantities["delta_p"] == pytest.approx(2.42, rel=1e-4)
    assert "c_L max" in capsys.readouterr().out
