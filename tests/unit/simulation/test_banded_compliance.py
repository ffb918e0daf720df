"""The strongly coupled step with bodies whose compliance enters the solve through their banded
factor (`linalg.BandedInverse`, stacked over bodies) gives the step of the dense compliance."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow import fluid, linalg, solid
from elastoflow.grid import Grid2D
from elastoflow.simulation import Simulation
from elastoflow.solid import StepResponse


def _simulation() -> Simulation:
    """Two clamped flaps of different widths (banded factors of different bands) and a small
    free disc (a dense inverse) in a channel, 48 x 32 cells."""
    grid = Grid2D(48, 32, 1.5 / 48)
    sides = fluid.DomainBoundaries(left=fluid.Inflow(0.5), right=fluid.Outflow(),
                                   bottom=fluid.WallNoSlip(), top=fluid.WallNoSlip())
    solver = fluid.FluidSolver(grid, density=1000.0, viscosity=1e-3, boundaries=sides,
                               pressure_solver=linalg.PoissonSolverMGPCG(rtol=1e-10))
    bodies = []
    for x0, width, columns in ((0.4, 0.08, 2), (0.9, 0.12, 3)):
        mesh = solid.mesh_rectangle(width, 0.5, counts=(columns, 12), origin=(x0, 0.0),
                                    pattern="crossed")
        bodies.append(solid.ElasticBody(mesh, solid.MaterialStVK(1200.0, 2e5, 0.3),
                                        fixed_nodes=np.flatnonzero(mesh.points[:, 1] < 1e-9)))
    angles = np.linspace(0.0, 2.0 * np.pi, 12, endpoint=False)
    disc = solid.mesh_from_polygon(np.column_stack((0.65 + 0.08 * np.cos(angles),
                                                    0.8 + 0.08 * np.sin(angles))),
                                   element_size=0.06)
    bodies.append(solid.ElasticBody(disc, solid.MaterialStVK(900.0, 1e6, 0.3)))
    return Simulation(grid, solver, bodies=bodies, dt=0.01, coupling="monolithic")


def test_banded_and_dense_compliance_give_the_same_steps(monkeypatch: pytest.MonkeyPatch
                                                         ) -> None:
    banded = _simulation()
    held = [body.state() for body in banded.bodies]
    responses = [body.response_at(state.positions, 0.01) for body, state in
                 zip(banded.bodies, held)]
    kinds = [response.compliance_factor(np.arange(4)) is not None for response in responses]
    assert kinds == [True, True, False]
    for _ in range(4):
        banded.step()
    monkeypatch.setattr(StepResponse, "compliance_factor", lambda self, dofs: None)
    dense = _simulation()
    for _ in range(4):
        dense.step()
    scale = np.abs(dense.state.fluid.velocity_x).max()
    assert np.abs(banded.state.fluid.velocity_x - dense.state.fluid.velocity_x).max() \
        < 1e-8 * scale
    for mine, theirs in zip(banded.state.bodies, dense.state.bodies):
        assert np.abs(mine.positions - theirs.positions).max() < 1e-12
        assert np.abs(mine.velocities - theirs.velocities).max() \
            < 1e-8 * max(np.abs(theirs.velocities).max(), 1e-12)
