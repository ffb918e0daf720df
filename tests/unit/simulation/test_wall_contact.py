"""Wall contact in the coupled schemes: a box twice as dense as the water rests on the floor."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow import fluid, solid
from elastoflow.grid import Grid2D
from elastoflow.simulation import FreeSurfaceMonolithicCoupling, Simulation

H = 0.02


def _box(bottom: float) -> solid.ElasticBody:
    mesh = solid.mesh_rectangle(0.2, 0.1, element_size=H, origin=(0.2 + 0.3 * H, bottom))
    return solid.ElasticBody(mesh, solid.MaterialStVK(2000.0, 1e6, 0.3), gravity=(0.0, -9.81))


def _single_phase(bottom: float, contact=solid.WallContact(), coupling="monolithic"):
    grid = Grid2D(nx=30, ny=15, h=H)
    solver = fluid.FluidSolver(grid, density=1000.0, viscosity=1e-3,
                               boundaries=fluid.DomainBoundaries.closed_box(),
                               gravity=(0.0, -9.81))
    body = _box(bottom)
    dt = 0.25 * H / np.sqrt(9.81 * 0.1)
    return Simulation(grid, solver, bodies=[body], dt=dt, coupling=coupling,
                      contact=contact), body


def _energy(body, state) -> float:
    kinetic = 0.5 * float((body.mass[:, None] * state.velocities ** 2).sum())
    return kinetic + float(body.elastic_energy(state)) + 9.81 * float(
        body.mass @ state.positions[:, 1])


def test_monolithic_box_on_the_floor_stays_at_rest_on_it(step_above_floor):
    simulation, body = _single_phase(0.0)
    speeds = step_above_floor(simulation, 60)
    assert simulation.state.bodies[0].positions[:, 1].min() == 0.0
    # Settling of its elastic compression, no jitter: the speed dies out.
    assert speeds[-1] < 1e-4 and speeds[-1] < 0.2 * max(speeds)


def test_monolithic_box_without_contact_goes_below_the_floor():
    simulation, _ = _single_phase(0.0, contact=None)
    simulation.run(60)
    assert simulation.state.bodies[0].positions[:, 1].min() < -1e-5


def test_monolithic_box_dropped_near_the_floor_lands_and_rests():
    simulation, body = _single_phase(0.2 * H)
    for _ in range(120):
        simulation.step()
        assert simulation.state.bodies[0].positions[:, 1].min() >= 0.0
    energies = []
    for _ in range(40):
        simulation.step()
        state = simulation.state.bodies[0]
        assert state.positions[:, 1].min() >= 0.0
        energies.append(_energy(body, state))
    assert state.positions[:, 1].min() < 0.05 * H
    assert np.abs(state.velocities).max() < 0.02


def test_explicit_box_on_the_floor_stays_on_it():
    simulation, _ = _single_phase(0.0, coupling="explicit")
    for _ in range(20):
        simulation.step()
        assert simulation.state.bodies[0].positions[:, 1].min() >= 0.0


def test_free_surface_box_on_the_floor_rests_under_the_water(step_above_floor):
    grid = Grid2D(nx=30, ny=15, h=H)
    walls = fluid.DomainBoundaries(left=fluid.WallFreeSlip(), right=fluid.WallFreeSlip(),
                                   bottom=fluid.WallFreeSlip(), top=fluid.WallFreeSlip())
    solver = fluid.FluidSolver(grid, density=1000.0, viscosity=1e-3, boundaries=walls,
                               gravity=(0.0, -9.81), advection="semi_lagrangian")
    body = _box(0.0)
    dt = 0.25 * H / np.sqrt(9.81 * 0.1)
    simulation = Simulation(grid, solver, bodies=[body], dt=dt,
                            coupling=FreeSurfaceMonolithicCoupling(fluid.FreeSurfaceSolver(solver)),
                            level_set=fluid.level_set_below(grid, 0.16))
    speeds = step_above_floor(simulation, 60)
    assert simulation.state.bodies[0].positions[:, 1].min() == 0.0
    assert speeds[-1] < 1e-3
    # The water's force on it is its buoyancy, rho g V = 196.2 N/m, the bottom edge's depth
    # read down to the floor (read at the lowest cell centres, half a cell higher, it was
    # 176.3 N/m).
    force = simulation.state.body_forces[0].sum(axis=0)
    assert abs(force[0]) < 0.01
    assert force[1] == pytest.approx(1000.0 * 9.81 * 0.2 * 0.1, rel=0.005)


@pytest.mark.parametrize("friction", [-1.0, float("nan")])
def test_simulation_refuses_bad_friction(friction):
    with pytest.raises(ValueError, match="friction"):
        solid.WallContact(friction=friction)


def test_level_set_is_read_linearly_out_to_the_domain_sides():
    """A linear level set is read exactly anywhere in the domain, up to its sides and with the
    grid's origin away from zero; beyond the sides it takes the sides' values."""
    from elastoflow.simulation._free_surface_bodies import level_set_at

    grid = Grid2D(nx=6, ny=4, h=0.1, origin=(-0.3, 1.0))
    x, y = grid.cell_centers()
    phi = 0.3 * x - (y - 1.25)
    points = np.array([[-0.3, 1.0], [0.3, 1.4], [0.0, 1.2], [-0.25, 1.05], [0.5, 0.8]])
    exact = 0.3 * points[:, 0] - (points[:, 1] - 1.25)
    exact[-1] = 0.3 * 0.3 - (1.0 - 1.25)  # outside: the corner's value
    assert level_set_at(grid, phi, points) == pytest.approx(exact, abs=1e-12)
