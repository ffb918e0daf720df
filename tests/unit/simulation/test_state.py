"""Model / State / Scheme: a state checkpoints by its fields, a scheme never changes the state
it starts from, and a failed step leaves the simulation at its last good state."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow import coupling, fluid, solid
from elastoflow.grid import Grid2D
from elastoflow.simulation import (
    CoupledState,
    ExplicitCoupling,
    MonolithicCoupling,
    Simulation,
    SimulationBlowUp,
)


def _simulation(coupling_name: str = "explicit") -> Simulation:
    grid = Grid2D(nx=24, ny=24, h=1.0 / 24)
    boundaries = fluid.DomainBoundaries(left=fluid.WallNoSlip(), right=fluid.WallNoSlip(),
                                        bottom=fluid.WallNoSlip(), top=fluid.Outflow())
    jet = fluid.Jet(region=(0.4, 0.05, 0.55, 0.1), velocity=(0.1, 0.8), dye=1.0)
    solver = fluid.FluidSolver(grid, density=1000.0, viscosity=1e-3, boundaries=boundaries,
                               jets=(jet,))
    mesh = solid.mesh_rectangle(0.08, 0.4, counts=(2, 8), origin=(0.46, 0.4))
    body = solid.ElasticBody(
        mesh, solid.MaterialStVK(3000.0, 5e4, 0.3, damping_lambda=1.0, damping_mu=1.0),
        fixed_nodes=solid.nodes_in_box(mesh, (0.45, 0.79, 0.55, 0.81)),
    )
    obstacle = coupling.obstacle_circle((0.2, 0.5), 0.08, segments=24,
                                        motion=coupling.RigidMotion(velocity=(0.0, 0.1)))
    return Simulation(grid, solver, bodies=[body], obstacles=[obstacle], dt=0.02,
                      coupling=coupling_name)


def _arrays(state: CoupledState) -> dict[str, np.ndarray]:
    return {key: value.copy() for key, value in state.to_arrays().items()}


def test_a_state_saves_every_field_by_its_path() -> None:
    simulation = _simulation()
    assert set(simulation.checkpoint()) == {
        "fluid.velocity_x", "fluid.velocity_y", "fluid.pressure", "fluid.dye",
        "bodies.0.positions", "bodies.0.velocities", "time", "step_index",
        "body_forces.0", "previous_velocities.0",
    }


def test_a_checkpoint_of_the_earlier_key_names_restores_the_same_state() -> None:
    simulation = _simulation()
    simulation.run(3)
    saved = _arrays(simulation.state)
    legacy = {"time": saved["time"], "step_index": saved["step_index"],
              "body0_positions": saved["bodies.0.positions"],
              "body0_velocities": saved["bodies.0.velocities"],
              "body0_previous_velocities": saved["previous_velocities.0"],
              "body0_forces": saved["body_forces.0"]}
    legacy.update({f"fluid_{name}": saved[f"fluid.{name}"]
                   for name in ("velocity_x", "velocity_y", "pressure", "dye")})
    fresh = _simulation()
    fresh.restore(legacy)
    for key, value in _arrays(fresh.state).items():
        np.testing.assert_array_equal(value, saved[key], err_msg=key)


@pytest.mark.parametrize("scheme", [ExplicitCoupling(), MonolithicCoupling()])
def test_a_scheme_leaves_the_state_it_starts_from_untouched(
        scheme: ExplicitCoupling | MonolithicCoupling) -> None:
    simulation = _simulation()
    simulation.run(2)
    state_in = simulation.state
    before = _arrays(state_in)
    state_out = state_in.copy()
    report = scheme.step(simulation.model, state_in, state_out, simulation.dt)
    for key, value in _arrays(state_in).items():
        np.testing.assert_array_equal(value, before[key], err_msg=key)
    assert report.step == state_out.step_index == 3
    assert state_out.time == pytest.approx(3 * simulation.dt)
    assert not np.array_equal(state_out.bodies[0].positions, before["bodies.0.positions"])


@pytest.mark.parametrize("coupling_name", ["explicit", "monolithic"])
def test_the_state_is_one_object_and_a_failed_step_keeps_the_last_good_one(
        coupling_name: str) -> None:
    simulation = _simulation(coupling_name)
    state = simulation.state
    velocity_x = state.fluid.velocity_x
    simulation.run(2)
    assert simulation.state is state and state.fluid.velocity_x is velocity_x
    state.fluid.velocity_x[10, 10] = np.nan
    good = _arrays(state)
    with pytest.raises(SimulationBlowUp, match="step 3"):
        simulation.step()
    for key, value in _arrays(simulation.state).items():
        np.testing.assert_array_equal(value, good[key], err_msg=key)
    assert simulation.step_index == 2


def test_a_check_rejects_the_new_state_before_it_becomes_current() -> None:
    calls = []

    def reject_step_2(model, state, dt, report) -> None:  # type: ignore[no-untyped-def]
        calls.append(report.step)
        if report.step == 2:
            raise SimulationBlowUp("step 2: rejected by the test's check")

    simulation = _simulation()
    simulation.checks.append(reject_step_2)
    simulation.step()
    good = _arrays(simulation.state)
    with pytest.raises(SimulationBlowUp, match="rejected"):
        simulation.step()
    assert calls == [1, 2] and simulation.step_index == 1
    for key, value in _arrays(simulation.state).items():
        np.testing.assert_array_equal(value, good[key], err_msg=key)
