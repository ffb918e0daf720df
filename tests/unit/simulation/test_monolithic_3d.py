"""`MonolithicCoupling3D`: the strongly coupled step on tetrahedral bodies.

The pressure solve sees the bodies' inertia (`PressureCoupledBodies` on the 3D interface flux,
`PoissonSolverMGPCG3D.solve_coupled`), so bodies lighter than the fluid they displace are
stable, where the explicit scheme diverges."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow.coupling import (
    PressureCoupledBodies,
    build_boundary_map_3d,
    interface_flux_3d,
    interior_boundary_3d,
)
from elastoflow.fluid import DomainBoundaries3D, FluidSolver3D, Inflow, WallFreeSlip
from elastoflow.grid import Grid3D
from elastoflow.scenes import SceneError, build_simulation, parse_scene
from elastoflow.simulation import (
    ExplicitCoupling3D,
    MonolithicCoupling,
    MonolithicCoupling3D,
    Simulation,
    SimulationBlowUp,
)
from elastoflow.solid import ElasticBody3D, MaterialStVK, MidpointFem, mesh_box, mesh_sphere

GRAVITY = -9.81
GRID = Grid3D(12, 12, 12, 1.0 / 12)


def box_solver(grid: Grid3D = GRID) -> FluidSolver3D:
    return FluidSolver3D(grid, density=1000.0, viscosity=1e-3,
                         boundaries=DomainBoundaries3D.closed_box(),
                         gravity=(0.0, GRAVITY, 0.0))


def cube(ratio: float, stiffness: float = 1e6) -> ElasticBody3D:
    """A 0.3 m cube in the middle of the 1 m box, ``ratio`` times as dense as the water."""
    mesh = mesh_box((0.3, 0.3, 0.3), counts=(3, 3, 3), origin=(0.35, 0.35, 0.35))
    return ElasticBody3D(mesh, MaterialStVK(1000.0 * ratio, stiffness, 0.3),
                         gravity=(0.0, GRAVITY, 0.0))


def mean_velocity(simulation: Simulation) -> np.ndarray:
    """The body's momentum over its mass [m/s]."""
    body = simulation.model.bodies[0]
    velocities = simulation.state.bodies[0].velocities
    return np.asarray(body.mass @ velocities / body.mass.sum())


def run(ratio: float, steps: int, coupling: object = "monolithic",
        stiffness: float = 1e6) -> Simulation:
    solver = box_solver()
    simulation = Simulation(GRID, solver, state=solver.rest_state(),
                            bodies=[cube(ratio, stiffness)], dt=0.005,
                            coupling=coupling)  # type: ignore[arg-type]
    simulation.run(steps)
    return simulation


def test_a_neutrally_buoyant_cube_stays_at_rest() -> None:
    """A stiff cube as dense as the water: its weight and the exact buoyancy cancel. (A soft
    one, released unstressed into the hydrostatic pressure, squeezes and its centre of mass
    sways with the fluid it pushes: mm/s at E = 1 MPa.)"""
    simulation = run(1.0, 10, stiffness=1e9)
    assert isinstance(simulation.scheme, MonolithicCoupling3D)
    assert np.abs(mean_velocity(simulation)).max() < 1e-5
    report = simulation.last_report
    assert report is not None and report.pressure_residual <= 1e-6


@pytest.mark.parametrize("ratio", [0.1, 0.5, 3.0])
def test_light_and_heavy_cubes_are_stable_and_accelerate_with_their_added_mass(
        ratio: float) -> None:
    """From rest, ``(rho_s V + m_a) dv/dt = (rho_f - rho_s) V g``: with the added mass ``m_a =
    C rho_f V`` of a cube in a closed box between 0.5 (unbounded: 0.6-0.7) and 2, the speed
    after 0.05 s lies between the bounds that C gives (no drag yet: Re is small at first)."""
    simulation = run(ratio, 10)
    speed = mean_velocity(simulation)[1]
    time = simulation.time
    buoyancy = (1.0 - ratio) * -GRAVITY
    low, high = buoyancy / (ratio + 2.0) * time, buoyancy / (ratio + 0.5) * time
    assert min(low, high) < speed < max(low, high), (speed, low, high)


def test_the_explicit_scheme_diverges_where_the_monolithic_one_is_stable() -> None:
    """Density ratio 0.1: the explicit step's speed flips sign and triples every step
    (0.44, -0.60, 3.1, -8.6, 30 m/s) and an element inverts at step 6; the monolithic one
    rises smoothly."""
    with pytest.raises(SimulationBlowUp):
        run(0.1, 8, coupling="explicit")
    simulation = run(0.1, 20)
    assert mean_velocity(simulation)[1] > 0.3


def test_pressure_forces_on_a_sphere_at_rest_are_archimedes_exactly() -> None:
    """The hydrostatic part's exact surface integral replaces W's cell-centre one: the total
    is ``rho g V`` of the tetrahedral mesh to round-off, at any resolution."""
    grid = Grid3D(10, 10, 10, 0.1)
    mesh = mesh_sphere(0.27, 0.1, center=(0.52, 0.47, 0.5))
    body = ElasticBody3D(mesh, MaterialStVK(1000.0, 1e5, 0.3))
    positions = mesh.points
    bmap = build_boundary_map_3d(grid, positions, np.zeros_like(positions),
                                 body.boundary_triangles, np.zeros(
                                     body.boundary_triangles.shape[0], np.int64))
    interior = interior_boundary_3d(bmap)
    flux = interface_flux_3d(grid, bmap, interior, mesh.tetrahedra,
                             np.array([0, mesh.tetrahedra.shape[0]]))
    state = body.state()
    response = MidpointFem().response(body, state, 0.01)
    coupled = PressureCoupledBodies(flux, np.zeros_like(positions), [response],
                                    [0, positions.shape[0]], 1000.0, 0.01, bmap=bmap,
                                    gravity=(0.0, GRAVITY, 0.0))
    rhs = np.zeros(grid.shape_cells)
    coupled.add_to_rhs(rhs, 1.0, flux.active)
    _, y, _ = grid.cell_centers()
    # Any level: a uniform pressure exerts no net force.
    pressure = 1000.0 * GRAVITY * (y - 0.3) + 123.0
    closed = tuple(np.zeros(shape) for shape in (grid.shape_faces_x, grid.shape_faces_y,
                                                  grid.shape_faces_z))
    coupled.respond(pressure, flux.active, *closed)
    total = coupled.pressure_forces.sum(axis=0)
    expected = -1000.0 * GRAVITY * mesh.volume
    np.testing.assert_allclose(total, [0.0, expected, 0.0], atol=1e-9 * expected)
    with pytest.raises(ValueError, match="3 face arrays|expected 3"):
        coupled.respond(pressure, flux.active, *closed[:2])


def test_a_checkpoint_resumes_bit_for_bit() -> None:
    grid = Grid3D(12, 8, 8, 0.125)
    boundaries = DomainBoundaries3D.channel(Inflow(speed=1.0), walls=WallFreeSlip())

    def make() -> Simulation:
        solver = FluidSolver3D(grid, density=1.0, viscosity=0.01, boundaries=boundaries)
        mesh = mesh_box((0.3, 0.3, 0.3), counts=(2, 2, 2), origin=(0.35, 0.35, 0.35))
        light = ElasticBody3D(mesh, MaterialStVK(0.5, 20.0, 0.3))
        return Simulation(grid, solver, bodies=[light], dt=0.02, coupling="monolithic")

    simulation = make()
    simulation.state.fluid.velocity_x[...] = 1.0
    simulation.run(2)
    saved = simulation.checkpoint()
    simulation.run(2)
    resumed = make()
    resumed.restore(saved)
    resumed.run(2)
    np.testing.assert_array_equal(resumed.state.bodies[0].positions,
                                  simulation.state.bodies[0].positions)
    np.testing.assert_array_equal(resumed.state.fluid.pressure, simulation.state.fluid.pressure)
    # The flow pushes the light cube downstream.
    assert mean_velocity(simulation)[0] > 0.0


def test_scheme_choices_and_refusals() -> None:
    solver = box_solver()
    given = MonolithicCoupling(integrator=MidpointFem())
    simulation = Simulation(GRID, solver, bodies=[cube(1.0)], dt=0.005, coupling=given)
    assert isinstance(simulation.scheme, MonolithicCoupling3D)
    assert simulation.scheme.fem is given.fem
    with pytest.raises(ValueError, match="force_relaxation"):
        Simulation(GRID, solver, bodies=[cube(1.0)], dt=0.005, coupling="monolithic",
                   force_relaxation=0.5)
    with pytest.raises(ValueError, match="2D scheme"):
        from elastoflow.fluid import DomainBoundaries, FluidSolver
        from elastoflow.grid import Grid2D

        flat = Grid2D(4, 4, 0.25)
        Simulation(flat, FluidSolver(flat, density=1.0, viscosity=0.0,
                                     boundaries=DomainBoundaries.closed_box()),
                   coupling=MonolithicCoupling3D(), dt=0.01)
    assert isinstance(ExplicitCoupling3D(), ExplicitCoupling3D)


SCENE = {
    "domain": {"lx": 1.0, "ly": 1.0, "lz": 1.0, "h": 1.0 / 8},
    "fluid": {"density": 1000.0, "viscosity": 1e-6, "gravity": [0.0, -9.81, 0.0]},
    "bodies": [{"shape": {"type": "box", "box": [0.35, 0.35, 0.35, 0.65, 0.65, 0.65],
                          "divisions": [2, 2, 2]},
                "material": {"density": 500.0, "young_modulus": 1e6, "poisson_ratio": 0.3}}],
    "coupling": {"scheme": "monolithic"},
    "time": {"dt": 0.005, "duration": 0.01},
}


def test_a_scene_file_chooses_the_monolithic_scheme() -> None:
    simulation = build_simulation(parse_scene(SCENE, source="light.toml"))
    assert isinstance(simulation.scheme, MonolithicCoupling3D)
    simulation.run(2)
    assert mean_velocity(simulation)[1] > 0.0
    bad = {**SCENE, "coupling": {"scheme": "monolithic", "force_relaxation": 0.5}}
    with pytest.raises(SceneError, match="coupling"):
        build_simulation(parse_scene(bad, source="light.toml"))


def test_the_viscous_damping_blocks_hold_the_wall_weight_and_bound_the_surface_gradient(
) -> None:
    """Per surface triangle and corner, ``mu 1.5 / h (A / 3) (I - n n^T)`` (the wall value's
    weight in the traction's normal derivative) plus ``mu (l_1 + l_2) / 6 (I + n n^T)`` (the
    Gershgorin bound of the wall's own surface gradient): the traces sum to ``mu (1.5 / h * 2
    * area + 4 / 6 * 2 * edges)``; each block is symmetric positive semi-definite; on a flat
    face the normal direction keeps only the bound, twice the tangential bound."""
    from elastoflow.simulation._schemes3d import _viscous_damping

    body = cube(1.0)
    mu, h = 2.0, 0.1
    blocks = _viscous_damping(body, body.mesh.points, mu, h)
    corners = body.mesh.points[body.boundary_triangles]
    area = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0],
                                         corners[:, 2] - corners[:, 0]), axis=1).sum()
    edges = np.linalg.norm(np.roll(corners, -1, axis=1) - corners, axis=2).sum()
    assert np.trace(blocks, axis1=1, axis2=2).sum() == pytest.approx(
        mu * (1.5 / h * 2.0 * area + 4.0 / 6.0 * 2.0 * edges))
    np.testing.assert_allclose(blocks, np.transpose(blocks, (0, 2, 1)), atol=1e-12)
    assert np.linalg.eigvalsh(blocks).min() > -1e-12
    # A node inside the cube's top face (normal +y). (Until 2026-12-07 this looked for
    # (0.5, 0.65, 0.5), which is no node of this mesh, and so checked nothing.)
    top = np.flatnonzero(np.all(np.isclose(body.mesh.points, (0.45, 0.65, 0.45)), axis=1))
    assert top.size == 1
    block = blocks[top[0]]
    np.testing.assert_allclose(block @ np.array([0.0, 1.0, 0.0]), [0.0, block[1, 1], 0.0],
                               atol=1e-12)
    # It is a corner of four right triangles (legs 0.1 m at the node): the bound is mu (4 * 2
    # * 0.1) / 6 along the face, twice that across it; the wall weight adds mu 1.5 / h times
    # a third of their area (4 * 0.005 m^2) along the face.
    reach = mu * 4 * 2 * 0.1 / 6.0
    np.testing.assert_allclose(
        block, np.diag([reach + mu * 1.5 / h * 4 * 0.005 / 3.0, 2.0 * reach,
                        reach + mu * 1.5 / h * 4 * 0.005 / 3.0]), atol=1e-12)


@pytest.mark.parametrize("rule", ["midpoint", "energy_momentum", "newmark"])
def test_nodal_damping_is_implicit_and_leaves_a_steady_motion_alone(rule: str) -> None:
    """The rule's step with ``nodal_damping`` answers a small held force as its `response`
    says (the damping in the matrix), and a body moving steadily keeps moving: the force
    ``-C (v - v0)`` vanishes when the velocity does not change."""
    from elastoflow.solid import EnergyMomentumFem, NewmarkFem

    fem = {"midpoint": MidpointFem(), "energy_momentum": EnergyMomentumFem(0.1),
           "newmark": NewmarkFem(0.6)}[rule]
    body = ElasticBody3D(mesh_box((0.3, 0.3, 0.3), counts=(2, 2, 2)),
                         MaterialStVK(1000.0, 1e6, 0.3))
    damping = np.repeat(50.0 * np.eye(3)[None], body.point_count, axis=0)
    dt = 0.01
    state = body.state()
    response = fem.response(body, state, dt, damping)
    force = np.zeros((body.point_count, 3))
    force[:, 0] = 1e-6
    out = body.state()
    fem.advance(body, state, out, dt, force, response, nodal_damping=damping)
    mean_change = (out.positions - state.positions) / dt - state.velocities
    expected = response.velocity_change(force)
    # To the Newton tolerance (1e-10 of the body's size).
    np.testing.assert_allclose(mean_change, expected, atol=1e-4 * np.abs(expected).max())
    # The damping slows the answer: the same force without it moves the body further.
    plain = fem.response(body, state, dt).velocity_change(force)
    assert np.abs(plain).sum() > 1.2 * np.abs(mean_change).sum()
    moving = body.state()
    moving.velocities[:, 2] = 0.3
    after = body.state()
    fem.advance(body, moving, after, dt, np.zeros_like(force),
                fem.response(body, moving, dt, damping), nodal_damping=damping)
    np.testing.assert_allclose(after.velocities[:, 2], 0.3, rtol=1e-9)
