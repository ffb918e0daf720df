"""Plain paths outside ``InteriorBoundary.regions``: advection, the viscosity system and the
faces' body velocities (and so whole fluid steps) must equal, bit for bit, the body-aware
results computed with ``regions=None``."""

from __future__ import annotations

import copy
import dataclasses

import numpy as np
import pytest

import elastoflow
from elastoflow.coupling import build_boundary_map, interior_boundary_from_map
from elastoflow.fluid import (
    DomainBoundaries,
    FluidSolver,
    Inflow,
    InteriorBoundary,
    Outflow,
    WallNoSlip,
)
from elastoflow.grid import Grid2D


def _results(solver, state, dt, interior):
    """Advected u, v, dye, the viscosity operator and right-hand side of both components, and
    the body velocities of the faces."""
    state = copy.deepcopy(state)
    solver.advect(state, dt, interior)
    results = [state.velocity_x, state.velocity_y, state.dye]
    for axis, f in ((0, state.velocity_x), (1, state.velocity_y)):
        operator, rhs = solver._viscosity_operator(f, axis, dt, interior)
        results += [operator.diagonal.copy(), operator.weights_x.copy(),
                    operator.weights_y.copy(), rhs.copy()]
    return results + [values.copy() for values in solver._solid_face_velocities(interior)]


def _assert_regions_change_nothing(solver, state, dt, interior, label):
    assert interior.regions is not None
    with_regions = _results(solver, state, dt, interior)
    anywhere = _results(solver, state, dt, dataclasses.replace(interior, regions=None))
    for index, (a, b) in enumerate(zip(with_regions, anywhere)):
        assert np.array_equal(a, b), f"result {index} differs with regions ({label})"
    # The comparison must involve the bodies: claiming no body anywhere changes the result.
    nowhere = dataclasses.replace(interior, regions=np.zeros((0, 4), dtype=np.int64))
    assert any(not np.array_equal(a, b)
               for a, b in zip(with_regions, _results(solver, state, dt, nowhere)))


def _tight(interior):
    """Boxes shrunk to the non-empty points inside each of ``interior.regions``: kernels that
    look one index too far or too near now see a body point at the very edge of a box."""
    nx, ny = interior.solid_cells.shape
    busy = np.zeros((nx + 1, ny + 1), dtype=bool)
    for name, empty in (("solid_cells", False), ("solid_faces_x", False),
                        ("solid_faces_y", False), ("velocity_faces_x", 0.0),
                        ("velocity_faces_y", 0.0), ("open_fraction_x", 1.0),
                        ("open_fraction_y", 1.0)):
        array = getattr(interior, name)
        busy[:array.shape[0], :array.shape[1]] |= array != empty
    for name, empty in (("cut_theta_x", np.inf), ("cut_theta_y", np.inf),
                        ("cut_velocity_x", 0.0), ("cut_velocity_y", 0.0)):
        array = getattr(interior, name)
        busy[:array.shape[1], :array.shape[2]] |= (array != empty).any(axis=0)
    boxes = []
    for i_begin, i_end, j_begin, j_end in interior.regions:
        i, j = np.nonzero(busy[max(i_begin, 0):i_end, max(j_begin, 0):j_end])
        if i.size:
            boxes.append([i.min() + max(i_begin, 0), i.max() + max(i_begin, 0) + 1,
                          j.min() + max(j_begin, 0), j.max() + max(j_begin, 0) + 1])
    return np.array(boxes, dtype=np.int64).reshape(-1, 4)


def _ellipse(center, radius, turn, count=21):
    angles = np.linspace(0.0, 2.0 * np.pi, count, endpoint=False) + turn
    return np.column_stack([center[0] + 1.5 * radius * np.cos(angles),
                            center[1] + 0.6 * radius * np.sin(angles)])


@pytest.mark.parametrize("advection", ["semi_lagrangian", "maccormack"])
def test_moving_bodies_give_bitwise_the_same_results(advection):
    # One body in the middle, one across the bottom edge (its box clipped to the grid) and
    # one next to the outflow side (stencils reaching the side ghosts), in a fast swirling
    # flow: departure points land on both sides of every box edge.
    grid = Grid2D(40, 32, 1.0 / 40.0)
    boundaries = DomainBoundaries(left=Inflow(1.0), right=Outflow(), bottom=WallNoSlip(),
                                  top=WallNoSlip())
    solver = FluidSolver(grid, density=1.0, viscosity=1e-3, boundaries=boundaries,
                         advection=advection)
    rng = np.random.default_rng(7)
    state = elastoflow.fluid.FluidState.zeros(grid)
    x, y = grid.faces_x()
    state.velocity_x[...] = 1.0 + 0.5 * np.sin(9.0 * y) + 0.3 * rng.standard_normal(x.shape)
    x, y = grid.faces_y()
    state.velocity_y[...] = 0.6 * np.cos(7.0 * x) + 0.3 * rng.standard_normal(x.shape)
    state.dye[...] = rng.random(grid.shape_cells)
    dt = 2.5 * grid.h
    interior = None
    for step in range(4):
        t = 0.05 * step
        polygons = [_ellipse((0.35 + t, 0.4), 0.09, 3.0 * t),
                    _ellipse((0.6, 0.02 + 0.1 * t), 0.07, 0.0),
                    _ellipse((0.955, 0.6 - t), 0.05, 1.0)]
        points = np.concatenate(polygons)
        velocities = np.tile([0.4, -0.3], (len(points), 1))
        starts = np.cumsum([0] + [len(p) for p in polygons])
        edges = np.concatenate([
            np.stack([np.arange(len(p)), (np.arange(len(p)) + 1) % len(p)], axis=1) + s
            for p, s in zip(polygons, starts)])
        edge_body = np.concatenate([np.full(len(p), k) for k, p in enumerate(polygons)])
        bmap = build_boundary_map(grid, points, velocities, edges, edge_body)
        interior = interior_boundary_from_map(grid, bmap, out=interior)
        assert len(interior.regions) == 3
        _assert_regions_change_nothing(solver, state, dt, interior, f"step {step}")
        tight = dataclasses.replace(interior, regions=_tight(interior))
        _assert_regions_change_nothing(solver, state, dt, tight, f"step {step}, tight")
        anywhere = copy.deepcopy(state)
        solver.step(anywhere, dt, t, dataclasses.replace(interior, regions=None))
        solver.step(state, dt, t, interior)
        for name in ("velocity_x", "velocity_y", "dye", "pressure"):
            assert np.array_equal(getattr(state, name), getattr(anywhere, name)), name


@pytest.mark.parametrize("advection", ["semi_lagrangian", "maccormack"])
def test_one_point_boxes_around_speckled_body_data(advection):
    # Isolated points carry body data in every array (solid, cut in all four directions), each
    # with the one-point box around it, some on the sides of the grid: any sample or stencil
    # that touches such a point must leave the plain path, whichever corner touches it.
    grid = Grid2D(24, 20, 1.0 / 24.0)
    solver = FluidSolver(grid, density=1.0, viscosity=2e-3, boundaries=DomainBoundaries(
        left=Inflow(1.0), right=Outflow(), bottom=WallNoSlip(), top=WallNoSlip()),
        advection=advection)
    rng = np.random.default_rng(11)
    interior = InteriorBoundary.empty(grid)
    points = [(0, 5), (grid.nx, 9), (7, 0), (13, grid.ny), (grid.nx - 1, grid.ny - 1)]
    points += [(int(i), int(j)) for i, j in zip(rng.integers(1, grid.nx - 1, 14),
                                                rng.integers(1, grid.ny - 1, 14))]
    for i, j in points:
        for solid, velocity, fraction, theta, cut in (
            (interior.solid_faces_x, interior.velocity_faces_x, interior.open_fraction_x,
             interior.cut_theta_x, interior.cut_velocity_x),
            (interior.solid_faces_y, interior.velocity_faces_y, interior.open_fraction_y,
             interior.cut_theta_y, interior.cut_velocity_y),
        ):
            if i < solid.shape[0] and j < solid.shape[1]:
                solid[i, j] = rng.random() < 0.5
                velocity[i, j] = rng.standard_normal() if solid[i, j] else 0.0
                fraction[i, j] = rng.random()
                theta[:, i, j] = rng.uniform(0.05, 1.0, 4)
                cut[:, i, j] = rng.standard_normal(4)
        if i < grid.nx and j < grid.ny:
            interior.solid_cells[i, j] = True
    interior = dataclasses.replace(
        interior, regions=np.array([[i, i + 1, j, j + 1] for i, j in points], dtype=np.int64))
    state = elastoflow.fluid.FluidState.zeros(grid)
    state.velocity_x[...] = 0.5 + rng.standard_normal(grid.shape_faces_x)
    state.velocity_y[...] = rng.standard_normal(grid.shape_faces_y)
    state.dye[...] = rng.random(grid.shape_cells)
    _assert_regions_change_nothing(solver, state, 1.5 * grid.h, interior, "speckles")


def test_bar_in_jet_gives_bitwise_the_same_results():
    # The paper scene on its 256^2 grid (the parallel kernel twins), body moving.
    simulation = elastoflow.load("bar_in_jet")
    for step in range(6):
        simulation.step()
        if step % 2:
            interior = simulation.interior
            area = sum((b[1] - b[0]) * (b[3] - b[2]) for b in interior.regions)
            assert 0 < area < 0.2 * simulation.grid.nx * simulation.grid.ny
            for regions in (interior.regions, _tight(interior)):
                _assert_regions_change_nothing(
                    simulation.fluid_solver, simulation.state.fluid, simulation.dt,
                    dataclasses.replace(interior, regions=regions), f"step {step}")
