"""``coupling.boundary``: the staircase and dual-cell treatments run with both schemes,
reach the model from scene files and from the Python API, and the cut-cell default is the
same object path as before."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow import coupling, fluid, solid
from elastoflow.grid import Grid2D
from elastoflow.scenes import SceneError, build_simulation, parse_scene
from elastoflow.simulation import MonolithicCoupling, Simulation


def _simulation(boundary: str, scheme: str, force_model: str = "traction") -> Simulation:
    """A disc sinking in an open box beside a fixed obstacle, 32 x 32 cells."""
    grid = Grid2D(32, 32, 1.0 / 32)
    walls = fluid.DomainBoundaries(fluid.WallNoSlip(), fluid.WallNoSlip(), fluid.WallNoSlip(),
                                   fluid.Outflow())
    solver = fluid.FluidSolver(grid, density=1000.0, viscosity=1e-3, boundaries=walls,
                               gravity=(0.0, -9.81))
    angles = np.linspace(0.0, 2.0 * np.pi, 24, endpoint=False)
    mesh = solid.mesh_from_polygon(np.column_stack((0.43 + 0.13 * np.cos(angles),
                                                    0.61 + 0.13 * np.sin(angles))),
                                   element_size=0.06)
    body = solid.ElasticBody(mesh, solid.MaterialStVK(2000.0, 1e6, 0.3), gravity=(0.0, -9.81))
    obstacle = coupling.obstacle_rectangle((0.62, 0.12), (0.81, 0.33))
    return Simulation(grid, solver, bodies=[body], obstacles=[obstacle], dt=0.005,
                      coupling="monolithic" if scheme == "monolithic" else "explicit",
                      force_model=force_model, boundary=boundary)  # type: ignore[arg-type]


@pytest.mark.parametrize(("scheme", "force_model"), [
    ("explicit", "traction"), ("explicit", "momentum_exchange"), ("monolithic", "traction")])
def test_staircase_runs_with_each_scheme_and_force(scheme: str, force_model: str) -> None:
    simulation = _simulation("staircase", scheme, force_model)
    assert simulation.model.boundary.name == "staircase"
    for _ in range(3):
        simulation.step()
    interior = simulation.interior
    assert isinstance(interior, coupling.StaircaseInteriorBoundary)
    assert set(np.unique(interior.open_fraction_x)) <= {0.0, 1.0}
    assert np.isinf(interior.cut_theta_x).all()
    if scheme == "explicit":
        # Closed faces hold the body velocity the projection balanced the fluid against (the
        # monolithic scheme balances the bodies' new velocity, not these).
        divergence = simulation.fluid_solver.divergence(simulation.state.fluid, interior)
        assert np.abs(divergence[~interior.solid_cells]).max() < 1e-4
    # The disc sinks (denser than the fluid) and receives a force.
    start = simulation.bodies[0].state().positions
    assert simulation.state.bodies[0].positions[:, 1].mean() < start[:, 1].mean()
    assert np.abs(simulation.body_forces[0]).sum() > 0.0


@pytest.mark.parametrize("scheme", ["explicit", "monolithic"])
def test_dual_cell_runs_with_each_scheme_and_keeps_the_cut_cells_flags(scheme: str) -> None:
    simulation = _simulation("dual_cell", scheme)
    cut = _simulation("cut_cell", scheme)
    for _ in range(3):
        simulation.step()
        cut.step()
    interior = simulation.interior
    assert isinstance(interior, coupling.DualCellInteriorBoundary)
    # The flags and cut distances are the cut cells' (of its own, slightly different, run);
    # the weights are the dual cells' fluid shares: 1 - (covered area) / h^2.
    reference = coupling.interior_boundary_from_map(simulation.grid, simulation.boundary_map)
    np.testing.assert_array_equal(interior.solid_cells, reference.solid_cells)
    np.testing.assert_array_equal(interior.cut_theta_x, reference.cut_theta_x)
    assert not np.array_equal(interior.open_fraction_x, reference.open_fraction_x)
    assert interior.cover is not None
    covered = (1.0 - interior.open_fraction_x[1:-1]).sum() + (
        1.0 - interior.open_fraction_y[:, 1:-1]).sum()
    assert covered > 0.0
    if scheme == "explicit":
        # The obstacle is still and the disc's covered faces carry its velocity: the fluid
        # leaves the cells divergence free.
        divergence = simulation.fluid_solver.divergence(simulation.state.fluid, interior)
        assert np.abs(divergence[~interior.solid_cells]).max() < 1e-4
    start = simulation.bodies[0].state().positions
    assert simulation.state.bodies[0].positions[:, 1].mean() < start[:, 1].mean()
    if scheme == "monolithic":
        # Both treatments see the same disc: its sinking speed agrees to a few per cent
        # (the explicit scheme's first steps are its added-mass instability's, whatever the
        # treatment: the disc is only twice as dense as the water).
        sink = [s.state.bodies[0].velocities[:, 1].mean() for s in (simulation, cut)]
        assert sink[0] == pytest.approx(sink[1], rel=0.1)


def test_cut_cell_is_the_default_and_differs_from_staircase() -> None:
    grid = Grid2D(8, 8, 0.125)
    walls = fluid.DomainBoundaries(fluid.WallNoSlip(), fluid.WallNoSlip(), fluid.WallNoSlip(),
                                   fluid.WallNoSlip())
    solver = fluid.FluidSolver(grid, density=1.0, viscosity=0.0, boundaries=walls)
    assert Simulation(grid, solver, dt=0.1).model.boundary == coupling.BoundaryCutCell()
    cut = _simulation("cut_cell", "monolithic")
    stair = _simulation("staircase", "monolithic")
    cut.step()
    stair.step()
    assert not isinstance(cut.interior, coupling.StaircaseInteriorBoundary)
    assert not np.array_equal(cut.state.fluid.pressure, stair.state.fluid.pressure)
    with pytest.raises(ValueError, match="boundary"):
        Simulation(grid, solver, dt=0.1, boundary="voxel")


_BASE = {
    "domain": {"lx": 1.0, "ly": 1.0, "nx": 16},
    "fluid": {"density": 1000.0, "viscosity": 1e-3},
    "time": {"dt": 0.01, "steps": 2},
    "obstacles": [{"shape": "circle", "center": [0.5, 0.5], "radius": 0.2}],
}


@pytest.mark.parametrize("scheme", ["monolithic", "explicit"])
def test_scene_key_reaches_the_model(scheme: str) -> None:
    scene = parse_scene({**_BASE, "coupling": {"scheme": scheme, "boundary": "staircase"}})
    assert scene.coupling.boundary == "staircase"
    simulation = build_simulation(scene)
    assert isinstance(simulation.model.boundary, coupling.BoundaryStaircase)
    if scheme == "monolithic":
        assert isinstance(simulation.scheme, MonolithicCoupling)
    simulation.step()
    assert isinstance(simulation.interior, coupling.StaircaseInteriorBoundary)
    assert parse_scene(_BASE).coupling.boundary == "cut_cell"
    with pytest.raises(SceneError, match="boundary"):
        parse_scene({**_BASE, "coupling": {"boundary": "voxels"}})
    dual = build_simulation(parse_scene({**_BASE, "coupling": {"scheme": scheme,
                                                               "boundary": "dual_cell"}}))
    assert isinstance(dual.model.boundary, coupling.BoundaryDualCell)
    dual.step()
    assert isinstance(dual.interior, coupling.DualCellInteriorBoundary)
