"""Simulation: construction errors, bit-exact checkpoint/restore, blow-up detection."""

from __future__ import annotations

import math

import numpy as np
import pytest

from elastoflow import coupling, fluid, solid
from elastoflow.grid import Grid2D
from elastoflow.simulation import Simulation, SimulationBlowUp


def _solver(grid: Grid2D, gravity: tuple[float, float] = (0.0, -9.81)) -> fluid.FluidSolver:
    boundaries = fluid.DomainBoundaries(
        left=fluid.WallNoSlip(), right=fluid.WallNoSlip(), bottom=fluid.WallNoSlip(),
        top=fluid.Outflow(),
    )
    jet = fluid.Jet(region=(0.4, 0.05, 0.55, 0.1), velocity=(0.1, 0.8), dye=1.0)
    return fluid.FluidSolver(grid, density=1000.0, viscosity=1e-3, boundaries=boundaries,
                             jets=(jet,), gravity=gravity)


def _scene(force_model: str = "traction", substeps: int | str = "auto") -> Simulation:
    """A small coupled scene: a hanging bar in a jet beside a moving obstacle, 24 x 24 cells."""
    grid = Grid2D(nx=24, ny=24, h=1.0 / 24)
    mesh = solid.mesh_rectangle(0.08, 0.4, counts=(2, 8), origin=(0.46, 0.4))
    body = solid.ElasticBody(
        mesh, solid.MaterialStVK(3000.0, 5e4, 0.3, damping_lambda=1.0, damping_mu=1.0),
        fixed_nodes=solid.nodes_in_box(mesh, (0.45, 0.79, 0.55, 0.81)), gravity=(0.0, -9.81),
    )
    obstacle = coupling.obstacle_circle(
        (0.2, 0.5), 0.08, segments=24, motion=coupling.RigidMotion(velocity=(0.0, 0.1))
    )
    return Simulation(grid, _solver(grid), bodies=[body], obstacles=[obstacle], dt=0.02,
                      substeps=substeps, force_model=force_model)


@pytest.mark.parametrize("dt", [0.0, -0.01, math.nan, math.inf])
def test_bad_dt_is_rejected(dt: float) -> None:
    grid = Grid2D(nx=8, ny=8, h=0.125)
    with pytest.raises(ValueError, match="dt"):
        Simulation(grid, _solver(grid), dt=dt)


@pytest.mark.parametrize("force_model", ["pressure", "", "Traction"])
def test_bad_force_model_is_rejected(force_model: str) -> None:
    grid = Grid2D(nx=8, ny=8, h=0.125)
    with pytest.raises(ValueError, match="force_model"):
        Simulation(grid, _solver(grid), dt=0.01, force_model=force_model)  # type: ignore[arg-type]


@pytest.mark.parametrize("substeps", [0, -3, 2.5, "many"])
def test_bad_substeps_are_rejected(substeps: object) -> None:
    grid = Grid2D(nx=8, ny=8, h=0.125)
    with pytest.raises(ValueError, match="substeps"):
        Simulation(grid, _solver(grid), dt=0.01, substeps=substeps)  # type: ignore[arg-type]


@pytest.mark.parametrize("force_model", ["traction", "momentum_exchange"])
def test_checkpoint_restore_continues_bit_identically(force_model: str) -> None:
    reference = _scene(force_model)
    reference.run(4)
    saved = {key: value.copy() for key, value in reference.checkpoint().items()}
    reference.run(4)
    expected = reference.checkpoint()

    fresh = _scene(force_model)
    fresh.restore(saved)
    fresh.run(4)
    resumed = fresh.checkpoint()
    assert expected.keys() == resumed.keys()
    for key in expected:
        np.testing.assert_array_equal(resumed[key], expected[key], err_msg=key)

    # Going back in time on the same object gives the same continuation too.
    reference.restore(saved)
    reference.run(4)
    again = reference.checkpoint()
    for key in expected:
        np.testing.assert_array_equal(again[key], expected[key], err_msg=key)
    assert reference.step_index == 8 and reference.time == pytest.approx(8 * 0.02)


def test_restore_rejects_a_checkpoint_of_another_scene() -> None:
    simulation = _scene()
    data = simulation.checkpoint()
    del data["bodies.0.positions"]
    with pytest.raises(ValueError, match="checkpoint"):
        simulation.restore(data)


def test_non_finite_fluid_value_raises_blow_up_naming_the_step() -> None:
    simulation = _scene()
    simulation.run(2)
    simulation.state.fluid.velocity_y[10, 10] = np.nan
    with pytest.raises(SimulationBlowUp, match="step 3"):
        simulation.step()


def test_runaway_cfl_raises_blow_up_naming_the_step() -> None:
    simulation = _scene()
    simulation.step()
    # A speed that no projection can remove from a closed-off side: the jet region reset
    # keeps the rest, but the burst drives max |u| dt / h far past the limit.
    simulation.state.fluid.velocity_x[5:8, 15:18] = 1e4
    with pytest.raises(SimulationBlowUp, match=r"step 2.*CFL"):
        simulation.step()


def test_solid_failure_raises_blow_up_naming_the_step_and_body() -> None:
    """One substep where the stability bound asks for many: the bar inverts."""
    simulation = _scene(substeps=1)
    with pytest.raises(SimulationBlowUp, match=r"step \d+.*body 0"):
        simulation.run(50)


def test_the_2d_viscous_damping_blocks_hold_the_wall_weight_and_bound_the_tangential_terms(
) -> None:
    """On a straight side, a node's block is ``mu [(w L / h + 1) t t^T + 2 n n^T]``: the
    wall value's weight ``w / h`` in the traction's normal derivative over its share ``L`` of
    the outline, and the Gershgorin bound (``mu`` along t, ``2 mu`` along n) of the wall's own
    tangential derivative, which couples it to its neighbours."""
    from elastoflow.simulation._schemes import _WALL_WEIGHT, _viscous_damping

    mesh = solid.mesh_rectangle(1.0, 0.5, counts=(4, 2), origin=(0.0, 0.0))
    body = solid.ElasticBody(mesh, solid.MaterialStVK(1000.0, 1e6, 0.3))
    mu, h = 2.0, 0.1
    blocks = _viscous_damping(body, mesh.points, mu, h)
    bottom = int(np.flatnonzero(np.all(np.isclose(mesh.points, (0.5, 0.0)), axis=1))[0])
    side = 0.25
    np.testing.assert_allclose(blocks[bottom], mu * np.diag([_WALL_WEIGHT * side / h + 1.0, 2.0]))
    np.testing.assert_array_equal(blocks, np.transpose(blocks, (0, 2, 1)))
    assert np.linalg.eigvalsh(blocks).min() > -1e-12
    inside = np.setdiff1d(np.arange(mesh.point_count), mesh.boundary_edges.ravel())
    assert np.all(blocks[inside] == 0.0)
