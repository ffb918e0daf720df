"""`Simulation` on a 3D grid: the same model / state / scheme design as in 2D."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow.coupling import (
    Obstacle3D,
    RigidMotion3D,
    obstacle_box,
    obstacle_cylinder,
    obstacle_sphere,
)
from elastoflow.fluid import (
    DomainBoundaries,
    DomainBoundaries3D,
    FluidSolver,
    FluidSolver3D,
    FluidState3D,
    Inflow,
    WallFreeSlip,
)
from elastoflow.grid import Grid2D, Grid3D
from elastoflow.simulation import (
    CoupledModel3D,
    ExplicitCoupling3D,
    Simulation,
    SimulationBlowUp,
)
from elastoflow.solid import ElasticBody3D, MaterialStVK, mesh_box

GRID = Grid3D(12, 8, 8, 0.125)


def channel_solver(grid: Grid3D = GRID) -> FluidSolver3D:
    free = WallFreeSlip()
    boundaries = DomainBoundaries3D.channel(Inflow(speed=1.0), walls=free)
    return FluidSolver3D(grid, density=1.0, viscosity=0.01, boundaries=boundaries)


def stream(grid: Grid3D = GRID) -> FluidState3D:
    state = FluidState3D.zeros(grid)
    state.velocity_x[...] = 1.0
    return state


def soft_cube(gravity: float = 0.0) -> ElasticBody3D:
    mesh = mesh_box((0.3, 0.3, 0.3), counts=(2, 2, 2), origin=(0.35, 0.35, 0.35))
    return ElasticBody3D(mesh, MaterialStVK(1500.0, 2e4, 0.3), gravity=(0.0, gravity, 0.0))


def test_a_fluid_only_run_is_the_fluid_solver_bit_for_bit() -> None:
    solver = channel_solver()
    reference = stream()
    simulation = Simulation(GRID, channel_solver(), state=stream(), dt=0.05)
    for step in range(3):
        solver.step(reference, 0.05, step * 0.05)
        simulation.step()
    for name in ("velocity_x", "velocity_y", "velocity_z", "pressure"):
        np.testing.assert_array_equal(getattr(simulation.state.fluid, name),
                                      getattr(reference, name))
    assert simulation.dimension == 3
    assert isinstance(simulation.model, CoupledModel3D)
    assert simulation.time == pytest.approx(0.15)


def test_a_fixed_sphere_is_pushed_downstream_and_stays_symmetric() -> None:
    sphere = obstacle_sphere((0.6, 0.5, 0.5), 0.2, 0.06)
    simulation = Simulation(GRID, channel_solver(), state=stream(), obstacles=[sphere],
                            dt=0.05)
    simulation.run(4)
    assert simulation.boundary_map is not None and simulation.interior is not None
    force = simulation.traction_forces()[0].sum(axis=0)
    assert force[0] > 0.0
    assert abs(force[1]) < 0.05 * force[0] and abs(force[2]) < 0.05 * force[0]
    # The sphere holds the fluid inside it at rest.
    assert simulation.interior.solid_cells.sum() > 0


def test_a_body_moves_with_the_flow_and_a_checkpoint_resumes_bit_for_bit() -> None:
    simulation = Simulation(GRID, channel_solver(), state=stream(), bodies=[soft_cube()],
                            dt=0.02)
    simulation.run(2)
    saved = simulation.checkpoint()
    simulation.run(2)
    resumed = Simulation(GRID, channel_solver(), bodies=[soft_cube()], dt=0.02)
    resumed.restore(saved)
    resumed.run(2)
    np.testing.assert_array_equal(resumed.state.bodies[0].positions,
                                  simulation.state.bodies[0].positions)
    np.testing.assert_array_equal(resumed.state.fluid.velocity_z,
                                  simulation.state.fluid.velocity_z)
    # Drag pushes the cube downstream.
    moved = simulation.state.bodies[0].positions - soft_cube().state().positions
    assert moved[:, 0].mean() > 0.0
    assert simulation.body_forces[0].shape == (soft_cube().point_count, 3)
    positions, triangles = simulation.body_geometry()[0]
    assert triangles.shape[1] == 3 and positions.shape[1] == 3


def test_a_moving_obstacle_carries_its_velocity_into_the_fluid() -> None:
    grid = Grid3D(8, 8, 8, 0.125)
    box = obstacle_box((0.3, 0.3, 0.3), (0.7, 0.7, 0.7), 0.1,
                       motion=RigidMotion3D(velocity=(0.0, 0.0, 0.5)))
    simulation = Simulation(grid, FluidSolver3D(
        grid, density=1.0, viscosity=0.0, boundaries=DomainBoundaries3D.closed_box()),
        obstacles=[box], dt=0.01)
    simulation.step()
    assert simulation.interior is not None
    # Faces wholly inside (no open part) take the box's velocity.
    inside = simulation.interior.solid_faces_z & (simulation.interior.open_fraction_z == 0.0)
    assert inside.sum() == 12
    np.testing.assert_allclose(simulation.state.fluid.velocity_z[inside], 0.5)


def test_obstacle_motion_and_shapes() -> None:
    motion = RigidMotion3D(velocity=(1.0, 0.0, 0.0), angular_velocity=(0.0, 0.0, 2.0))
    box = obstacle_box((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), 0.5, motion=motion)
    assert box.volume == pytest.approx(1.0)
    t = 0.3
    points = box.points_at(t)
    # Rigid: distances between vertices are kept.
    np.testing.assert_allclose(np.linalg.norm(points[1:] - points[0], axis=1),
                               np.linalg.norm(box.points[1:] - box.points[0], axis=1))
    # The velocity is the time derivative of the positions.
    eps = 1e-6
    numeric = (box.points_at(t + eps) - box.points_at(t - eps)) / (2 * eps)
    np.testing.assert_allclose(box.velocities_at(t), numeric, atol=1e-6)
    for axis in range(3):
        cylinder = obstacle_cylinder((0.0, 0.0, 0.0), 0.5, 2.0, 0.2, axis=axis)
        extent = cylinder.points.max(axis=0) - cylinder.points.min(axis=0)
        assert extent[axis] == pytest.approx(2.0)
        assert cylinder.volume == pytest.approx(np.pi * 0.25 * 2.0, rel=0.03)
    # A clockwise surface is turned outward.
    flipped = Obstacle3D(box.points, box.triangles[:, ::-1])
    assert flipped.volume == pytest.approx(1.0)
    with pytest.raises(ValueError, match="closed"):
        Obstacle3D(box.points, box.triangles[1:])


def test_2d_only_options_are_refused_in_3d_in_one_line() -> None:
    solver = channel_solver()
    cases = {
        "coupling": dict(coupling="partitioned"),
        "force_model": dict(force_model="momentum_exchange"),
        "boundary": dict(boundary="staircase"),
        "added_mass": dict(added_mass=1.0),
        "level_set": dict(level_set=np.zeros((12, 8, 8))),
    }
    for name, option in cases.items():
        with pytest.raises(ValueError, match=name):
            Simulation(GRID, solver, dt=0.01, **option)  # type: ignore[arg-type]
    flat = Grid2D(4, 4, 0.25)
    solver_2d = FluidSolver(flat, density=1.0, viscosity=0.0,
                            boundaries=DomainBoundaries.closed_box())
    with pytest.raises(ValueError, match="FluidSolver3D"):
        Simulation(GRID, solver_2d, dt=0.01)
    with pytest.raises(ValueError, match="2D scheme"):
        Simulation(flat, solver_2d, coupling=ExplicitCoupling3D(), dt=0.01)


def test_a_diverging_3d_run_keeps_the_last_good_state() -> None:
    simulation = Simulation(GRID, channel_solver(), state=stream(), dt=0.05, cfl_limit=0.3)
    with pytest.raises(SimulationBlowUp, match="step 1"):
        simulation.step()
    assert simulation.step_index == 0
    np.testing.assert_array_equal(simulation.state.fluid.velocity_x, stream().velocity_x)


def test_the_api_draws_a_3d_simulation_through_a_plane() -> None:
    import elastoflow

    sphere = obstacle_sphere((0.6, 0.5, 0.5), 0.2, 0.06)
    simulation = Simulation(GRID, channel_solver(), state=stream(), obstacles=[sphere],
                            bodies=[soft_cube()], dt=0.05)
    simulation.step()
    image = elastoflow.frame(simulation, "speed", axis="z", position=0.5)
    assert image.ndim == 3 and image.dtype == np.uint8
    flat = elastoflow.frame(simulation, "pressure", axis="x")
    assert flat.shape != image.shape  # a y-z plane of 8 x 8 cells against x-y's 12 x 8
