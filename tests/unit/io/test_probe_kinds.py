"""Probe kinds that validation set-ups need: force and torque on any bodies and obstacles by
traction, pressure and velocity at a point, pressure differences; their checks."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

import elastoflow
from elastoflow.fluid import OPEN_MIN
from elastoflow.io import ProbeRecorder, read_probes
from elastoflow.scenes import ProbeSpec, Scene, SceneError, parse_scene, scene_to_toml
from elastoflow.scenes._errors import check_scene


def _channel(probes: list[dict], h: float = 0.02) -> Scene:
    return Scene.model_validate({
        "domain": {"lx": 1.0, "ly": 0.4, "h": h},
        "fluid": {"density": 1.0, "viscosity": 0.01},
        "boundaries": {"left": {"type": "inflow", "speed": 0.3, "profile": "parabolic"},
                       "right": "outflow", "bottom": "no_slip", "top": "no_slip"},
        "obstacles": [{"shape": "circle", "center": (0.3, 0.2), "radius": 0.05}],
        "time": {"dt": 0.02, "steps": 30, "substeps": 1},
        "outputs": {"probes": probes},
    })


def test_force_torque_pressure_velocity_on_a_cylinder_in_a_channel(tmp_path: Path) -> None:
    probes = [
        {"kind": "force", "obstacles": [0]},
        {"kind": "torque", "obstacles": [0], "about": (0.3, 0.2)},
        {"kind": "pressure", "point": (0.2, 0.2)},
        {"kind": "pressure_difference", "points": [(0.2, 0.2), (0.4, 0.2)]},
        {"kind": "velocity", "point": (0.05, 0.2)},
        {"kind": "velocity", "point": (0.05, 0.01)},
    ]
    scene = _channel(probes)
    simulation = elastoflow.load(scene)
    recorder = ProbeRecorder(scene.outputs.probes, simulation, tmp_path / "probes.csv")
    for _ in range(30):
        simulation.step()
        recorder.record(simulation)
    recorder.close()
    columns, rows = read_probes(tmp_path / "probes.csv")
    row = dict(zip(columns, rows[-1]))
    drag, lift = row["force_obstacle0_x [N/m]"], row["force_obstacle0_y [N/m]"]
    expected = simulation.traction_forces()[0].sum(axis=0)
    assert (drag, lift) == pytest.approx(tuple(expected), rel=1e-9)
    # The stream pushes the cylinder downstream; a symmetric set-up gives little lift.
    assert drag > 0.0 and abs(lift) < 0.1 * drag
    assert abs(row["torque_obstacle0 [N]"]) < 0.05 * drag * 0.05
    front, difference = row["pressure_(0.2,0.2) [Pa]"], row["pressure_(0.2,0.2)-(0.4,0.2) [Pa]"]
    assert difference > 0.0 and front > difference - front
    # Upstream, on the centre line, the parabolic inflow's peak; near the wall much less.
    centre = row["velocity_(0.05,0.2)_x [m/s]"]
    assert centre == pytest.approx(0.3, rel=0.1)
    assert row["velocity_(0.05,0.01)_x [m/s]"] < 0.2 * centre
    assert abs(row["velocity_(0.05,0.2)_y [m/s]"]) < 0.05 * centre


def test_pressure_and_velocity_interpolate_linear_fields_exactly(tmp_path: Path) -> None:
    scene = _channel([{"kind": "pressure", "point": (0.37, 0.13)},
                      {"kind": "velocity", "point": (0.51, 0.29)}])
    simulation = elastoflow.load(scene)
    grid, state = simulation.grid, simulation.state.fluid
    x, y = grid.cell_centers()
    state.pressure[...] = 3.0 * x - 2.0 * y + 1.0
    h = grid.h
    xu = np.arange(grid.nx + 1)[:, None] * h
    yu = (np.arange(grid.ny)[None, :] + 0.5) * h
    state.velocity_x[...] = 2.0 * xu + 5.0 * yu
    xv = (np.arange(grid.nx)[:, None] + 0.5) * h
    yv = np.arange(grid.ny + 1)[None, :] * h
    state.velocity_y[...] = -xv + 4.0 * yv
    recorder = ProbeRecorder(scene.outputs.probes, simulation, tmp_path / "probes.csv")
    recorder.record(simulation)
    recorder.close()
    _, rows = read_probes(tmp_path / "probes.csv")
    assert rows[0][2] == pytest.approx(3.0 * 0.37 - 2.0 * 0.13 + 1.0, rel=1e-12)
    assert rows[0][3] == pytest.approx(2.0 * 0.51 + 5.0 * 0.29, rel=1e-12)
    assert rows[0][4] == pytest.approx(-0.51 + 4.0 * 0.29, rel=1e-12)


BOX = (0.15, 0.05, 0.45, 0.35)


def _balance_run(scene: Scene, folder: Path, steps: int, resume_at: int | None = None
                 ) -> list[list[float]]:
    """Rows of a probes CSV over ``steps`` steps; with ``resume_at`` the recorder is made
    anew from the state at that step, as a resumed run makes it."""
    simulation = elastoflow.load(scene)
    recorder = ProbeRecorder(scene.outputs.probes, simulation, folder / "probes.csv")
    for step in range(1, steps + 1):
        report = simulation.step()
        recorder.observe(simulation)
        recorder.record(simulation, report)
        if step == resume_at:
            recorder.close()
            recorder = ProbeRecorder(scene.outputs.probes, simulation, folder / "probes.csv",
                                     resume_step=step)
    recorder.close()
    return read_probes(folder / "probes.csv")[1]


def test_momentum_balance_reads_the_cylinders_force_and_resumes_exactly(tmp_path: Path
                                                                        ) -> None:
    """The balance over a box around the cylinder (Re 3) on 5 cells per diameter gives the
    drag that the traction integral gives on 10 (measured: 0.05697 N/m after 30 steps
    against the traction's 0.05743 after 150 steps at h = 0.01; the traction at 5 cells per
    diameter reads 0.0469). With BDF2 steps, a recorder made anew mid-run (a resume) starts
    from the state's two velocities and continues the same."""
    probes = [{"kind": "force", "obstacles": [0]},
              {"kind": "momentum_balance", "obstacles": [0], "region": BOX}]
    for name in ("coarse", "fine", "a", "b"):
        (tmp_path / name).mkdir()
    coarse = np.asarray(_balance_run(_channel(probes), tmp_path / "coarse", 30))
    fine = np.asarray(_balance_run(_channel(probes, h=0.01), tmp_path / "fine", 150))
    assert np.isfinite(coarse[:, 4:]).all()
    assert coarse[-1, 4] == pytest.approx(fine[-1, 2], rel=0.02)
    assert abs(coarse[-1, 5]) < 1e-3 * coarse[-1, 4]  # a symmetric set-up: no lift
    scene = _channel(probes)
    scene = scene.model_copy(update={"fluid": scene.fluid.model_copy(
        update={"viscosity_scheme": "bdf2"})})
    straight = np.asarray(_balance_run(scene, tmp_path / "a", 30))
    resumed = np.asarray(_balance_run(scene, tmp_path / "b", 30, resume_at=12))
    np.testing.assert_array_equal(straight, resumed)


@pytest.mark.parametrize(
    ("probe", "message"),
    [
        ({"kind": "force"}, "needs bodies or obstacles"),
        ({"kind": "torque", "obstacles": [0]}, "needs about"),
        ({"kind": "pressure"}, "needs point"),
        ({"kind": "pressure_difference", "points": [(0.1, 0.1)]}, "two"),
        ({"kind": "momentum_balance", "obstacles": [0]}, "needs region"),
        ({"kind": "momentum_balance", "region": BOX}, "needs obstacles"),
        ({"kind": "momentum_balance", "obstacles": [0], "bodies": [0], "region": BOX},
         "no bodies"),
        ({"kind": "momentum_balance", "obstacles": [0], "region": (0.4, 0.0, 0.1, 0.3)},
         "x1 > x0"),
    ],
)
def test_incomplete_probes_are_refused(probe: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        ProbeSpec.model_validate(probe)


@pytest.mark.parametrize(
    ("probe", "message"),
    [
        ({"kind": "force", "obstacles": [3]}, "outputs.probes.0.obstacles = [3]: must be "
                                             "obstacle indices in 0..0"),
        ({"kind": "force", "bodies": [0]}, "outputs.probes.0.bodies = [0]: the scene has no "
                                          "bodies"),
        ({"kind": "pressure", "point": (2.0, 0.1)}, "outputs.probes.0.point = [2.0, 0.1]: must "
                                                   "lie inside the domain"),
        ({"kind": "momentum_balance", "obstacles": [0], "region": (0.15, 0.0, 0.45, 0.35)},
         "outputs.probes.0.region = [0.15, 0, 0.45, 0.35]: must lie inside the domain"),
        ({"kind": "momentum_balance", "obstacles": [0], "region": (0.15, 0.05, 0.3, 0.35)},
         "must hold obstacles.0 (bounds [0.25, 0.15, 0.35, 0.25]) two cells"),
    ],
)
def test_probes_naming_what_is_not_there_are_refused(probe: dict, message: str) -> None:
    problems = check_scene(_channel([probe]))
    assert any(message in line for line in problems), problems
    with pytest.raises(SceneError, match="outputs.probes.0"):
        parse_scene(tomllib.loads(scene_to_toml(_channel([probe]))))


def test_probe_statistics_json_final_and_periodic(tmp_path: Path) -> None:
    """The statistics file a run writes beside probes.csv: the final value of every column,
    and mean, amplitude and frequency where the column is periodic."""
    import json

    from elastoflow.io._probes import probe_statistics

    time = np.arange(0.0, 10.0, 0.01)
    data = np.column_stack([np.arange(len(time)), time, 2.0 + 0.5 * np.sin(2 * np.pi * 1.5 * time),
                            np.linspace(0.0, 1.0, len(time))])
    stats = probe_statistics(["step", "time [s]", "lift", "ramp"], data)
    assert stats["lift"]["mean"] == pytest.approx(2.0, abs=1e-3)
    assert stats["lift"]["amplitude"] == pytest.approx(0.5, rel=1e-3)
    assert stats["lift"]["frequency"] == pytest.approx(1.5, rel=1e-3)
    assert stats["ramp"] == {"final": 1.0}
    scene = _channel([{"kind": "force", "obstacles": [0]}])
    simulation = elastoflow.load(scene)
    recorder = ProbeRecorder(scene.outputs.probes, simulation, tmp_path / "probes.csv")
    for _ in range(3):
        simulation.step()
        recorder.record(simulation)
    path = recorder.write_statistics()
    recorder.close()
    assert path == tmp_path / "probes_statistics.json"
    written = json.loads(path.read_text())
    assert set(written) == {"force_obstacle0_x [N/m]", "force_obstacle0_y [N/m]"}


def test_pressure_inside_a_body_reads_only_cells_that_carry_a_pressure(tmp_path: Path
                                                                       ) -> None:
    """Points 1.2 cells inside the cylinder, in front and behind: the cells the body covers
    whole hold no pressure (0 after a solve), the probe extrapolates from those that do,
    exact for a linear field (it used to interpolate the zeros in)."""
    front, back = (0.262, 0.2), (0.338, 0.2)
    scene = _channel([{"kind": "pressure", "point": front},
                      {"kind": "pressure_difference", "points": [front, back]}], h=0.01)
    simulation = elastoflow.load(scene)
    simulation.step()
    interior = simulation.interior
    assert interior is not None
    grid, state = simulation.grid, simulation.state.fluid
    x, y = grid.cell_centers()
    state.pressure[...] = 3.0 * x - 2.0 * y + 1.0
    closed_x = interior.open_fraction_x < OPEN_MIN
    closed_y = interior.open_fraction_y < OPEN_MIN
    covered = closed_x[:-1] & closed_x[1:] & closed_y[:, :-1] & closed_y[:, 1:]
    assert covered[26, 19] and covered[26, 20] and not covered[25, 19]
    state.pressure[covered] = 0.0
    recorder = ProbeRecorder(scene.outputs.probes, simulation, tmp_path / "probes.csv")
    recorder.record(simulation)
    recorder.close()
    _, rows = read_probes(tmp_path / "probes.csv")
    assert rows[0][2] == pytest.approx(3.0 * 0.262 - 2.0 * 0.2 + 1.0, rel=1e-12)
    assert rows[0][3] == pytest.approx(3.0 * (0.262 - 0.338), rel=1e-12)


def test_a_momentum_balance_box_holds_only_its_still_obstacles() -> None:
    base = _channel([{"kind": "momentum_balance", "obstacles": [0], "region": BOX}])
    other = base.model_copy(update={"obstacles": [*base.obstacles, base.obstacles[0].model_copy(
        update={"center": (0.5, 0.2), "radius": 0.03})]})
    problems = check_scene(other)
    assert any("obstacles.1 is not in the probe's obstacles, and reaches within two cells"
               in line for line in problems), problems
    moving = base.model_copy(update={"obstacles": [base.obstacles[0].model_copy(
        update={"motion": {"velocity": (0.1, 0.0)}})]})
    problems = check_scene(moving)
    assert any("obstacles.0 moves" in line for line in problems), problems
