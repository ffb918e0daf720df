from __future__ import annotations

import math

import numpy as np
import pytest

from elastoflow.coupling import (
    RigidMotion,
    build_boundary_map,
    force_momentum_exchange,
    force_traction,
    interior_boundary_from_map,
    obstacle_circle,
    obstacle_rectangle,
    polygon_signed_area,
)
from elastoflow.grid import Grid2D

DENSITY = 1000.0
GRAVITY = 9.81


def _setup(grid, obstacle):
    bmap = build_boundary_map(grid, obstacle.points_at(0.0), obstacle.velocities_at(0.0),
                              obstacle.edges)
    return bmap, interior_boundary_from_map(grid, bmap)


def _still(grid):
    return np.zeros(grid.shape_faces_x), np.zeros(grid.shape_faces_y)


def _hydrostatic(grid, depth=1.0):
    _, y = grid.cell_centers()
    return DENSITY * GRAVITY * (depth - y)


def test_hydrostatic_pressure_gives_archimedes_force_with_gravity_carry():
    grid = Grid2D(32, 32, 1.0 / 32.0)
    body = obstacle_circle((0.5, 0.45), 0.2, 50)
    bmap, interior = _setup(grid, body)
    force = force_traction(grid, bmap, *_still(grid), _hydrostatic(grid), DENSITY, 1e-3,
                           interior, gravity=(0.0, -GRAVITY)).sum(axis=0)
    weight = DENSITY * GRAVITY * polygon_signed_area(body.polygon)
    np.testing.assert_allclose(force, [0.0, weight], rtol=0, atol=1e-9 * weight)


def test_hydrostatic_force_without_gravity_carry_converges_with_h():
    body = obstacle_circle((0.5, 0.45), 0.2, 128)
    weight = DENSITY * GRAVITY * polygon_signed_area(body.polygon)
    errors = []
    for n in (32, 64, 128):
        grid = Grid2D(n, n, 1.0 / n)
        bmap, interior = _setup(grid, body)
        force = force_traction(grid, bmap, *_still(grid), _hydrostatic(grid), DENSITY, 0.0,
                               interior).sum(axis=0)
        assert abs(force[0]) < 1e-9 * weight
        errors.append(abs(force[1] / weight - 1.0))
    # Sampling 1.5 h off the wall misses the hydrostatic increment: first order in h.
    assert errors[-1] < 0.1
    assert errors[0] / errors[1] > 1.8 and errors[1] / errors[2] > 1.8, errors


def test_uniform_pressure_gives_zero_net_force():
    grid = Grid2D(32, 32, 1.0 / 32.0)
    body = obstacle_circle((0.4, 0.55), 0.17, 37)
    bmap, interior = _setup(grid, body)
    pressure = np.full(grid.shape_cells, 1.0e5)
    force = force_traction(grid, bmap, *_still(grid), pressure, DENSITY, 1e-3, interior)
    assert np.abs(force).max() > 1e2
    np.testing.assert_allclose(force.sum(axis=0), 0.0, atol=1e-9 * 1e5)


@pytest.mark.parametrize("wall_speed", [0.0, 0.3])
def test_linear_shear_gives_analytic_viscous_traction(wall_speed):
    grid = Grid2D(32, 32, 1.0 / 32.0)
    # A plate across the whole domain; the fluid slides over both faces at shear rate gamma.
    y0, y1, gamma, viscosity = 0.4, 0.57, 3.0, 2.0e-3
    plate = obstacle_rectangle((0.0, y0), (grid.lx, y1), motion=RigidMotion((wall_speed, 0.0)))
    bmap, interior = _setup(grid, plate)
    _, y = grid.faces_x()
    velocity_x = wall_speed + gamma * (np.maximum(y - y1, 0.0) + np.maximum(y0 - y, 0.0))
    velocity_y = np.zeros(grid.shape_faces_y)
    force = force_traction(grid, bmap, velocity_x, velocity_y, np.zeros(grid.shape_cells),
                           DENSITY, viscosity, interior).sum(axis=0)
    mu = DENSITY * viscosity
    np.testing.assert_allclose(force, [2.0 * mu * gamma * grid.lx, 0.0], rtol=1e-12,
                               atol=1e-12 * mu * gamma)


def _odd_lines_through(lo, hi, h):
    centres = (np.arange(round(1.0 / h)) + 0.5) * h
    return int(np.sum((centres >= lo) & (centres < hi)))


@pytest.mark.parametrize("stream", [0.7, -1.3])
def test_momentum_exchange_of_uniform_stream_on_fixed_body(stream):
    grid = Grid2D(32, 32, 1.0 / 32.0)
    x0, y0, x1, y1 = 0.31, 0.27, 0.62, 0.71
    bmap, _ = _setup(grid, obstacle_rectangle((x0, y0), (x1, y1)))
    dt, alpha = 0.01, 0.5
    velocity_x = np.full(grid.shape_faces_x, stream)
    velocity_y = np.zeros(grid.shape_faces_y)
    force = force_momentum_exchange(grid, bmap, velocity_x, velocity_y, DENSITY, dt, alpha)
    per_crossing = alpha * DENSITY * grid.h**2 * stream / dt
    # Each row through u points that meets the body has two crossings, each handing over
    # alpha rho h^2 U / dt in the stream direction.
    rows = _odd_lines_through(y0, y1, grid.h)
    np.testing.assert_allclose(force.sum(axis=0), [2 * rows * per_crossing, 0.0], rtol=1e-12)
    assert np.sign(force.sum(axis=0)[0]) == np.sign(stream)

    velocity_y = np.full(grid.shape_faces_y, stream)
    force = force_momentum_exchange(grid, bmap, np.zeros(grid.shape_faces_x), velocity_y,
                                    DENSITY, dt, alpha)
    columns = _odd_lines_through(x0, x1, grid.h)
    np.testing.assert_allclose(force.sum(axis=0), [0.0, 2 * columns * per_crossing], rtol=1e-12)


def test_momentum_exchange_reads_the_fluid_side_and_vanishes_for_matching_motion():
    grid = Grid2D(32, 32, 1.0 / 32.0)
    body = obstacle_rectangle((0.31, 0.27), (0.62, 0.71), motion=RigidMotion((0.4, -0.2)))
    bmap, interior = _setup(grid, body)
    # Fluid moving with the body: no exchange, whatever the velocity inside the body says.
    velocity_x = np.where(interior.solid_faces_x, 100.0, 0.4)
    velocity_y = np.where(interior.solid_faces_y, -100.0, -0.2)
    force = force_momentum_exchange(grid, bmap, velocity_x, velocity_y, DENSITY, 0.01)
    np.testing.assert_allclose(force, 0.0, atol=1e-9)


def test_forces_split_by_edge_parameter_conserve_the_total():
    grid = Grid2D(32, 32, 1.0 / 32.0)
    body = obstacle_circle((0.5, 0.5), 0.23, 21)
    bmap, _ = _setup(grid, body)
    x, y = grid.faces_x()
    velocity_x = np.sin(3 * x) * np.cos(2 * y)
    x, y = grid.faces_y()
    velocity_y = np.cos(x) * y
    force = force_momentum_exchange(grid, bmap, velocity_x, velocity_y, DENSITY, 0.01)
    # Recompute eq. (8) entry by entry in Python from the same map: the nodal split by t must
    # add up to the same total.
    h = grid.h
    total = 0.0
    for J in range(1, 2 * grid.ny, 2):
        part = bmap.row(J)
        for c, s, u_s in zip(bmap.x_coordinate[part], bmap.x_sign[part],
                             bmap.x_velocity[part, 0], strict=True):
            i = math.ceil(c / h) - 1 if s > 0 else math.ceil(c / h)
            total += 0.5 * DENSITY * h * h * (velocity_x[i, J // 2] - u_s) / 0.01
    np.testing.assert_allclose(force[:, 0].sum(), total, rtol=1e-12)
    assert abs(total) > 0.0


def test_bad_input_raises():
    grid = Grid2D(8, 8, 0.125)
    bmap, interior = _setup(grid, obstacle_circle((0.5, 0.5), 0.2, 12))
    u, v = _still(grid)
    with pytest.raises(ValueError, match="velocity_x"):
        force_momentum_exchange(grid, bmap, np.zeros((8, 8)), v, DENSITY, 0.01)
    with pytest.raises(ValueError, match="dt"):
        force_momentum_exchange(grid, bmap, u, v, DENSITY, 0.0)
    with pytest.raises(ValueError, match="pressure"):
        force_traction(grid, bmap, u, v, np.zeros((9, 8)), DENSITY, 0.0, interior)
    with pytest.raises(ValueError, match="viscosity"):
        force_traction(grid, bmap, u, v, np.zeros((8, 8)), DENSITY, -1.0, interior)
    with pytest.raises(ValueError, match="grid"):
        force_traction(Grid2D(8, 8, 0.1), bmap, u, v, np.zeros((8, 8)), DENSITY, 0.0)
    for distances in ((), (1.5, -1.0), (math.inf,)):
        with pytest.raises(ValueError, match="sample_distances"):
            force_traction(grid, bmap, u, v, np.zeros((8, 8)), DENSITY, 0.0, interior,
                           sample_distances=distances)


def test_hydrostatic_force_does_not_depend_on_where_the_pressure_is_sampled():
    """With the gravity carry the hydrostatic pressure is exact at any sample distance."""
    grid = Grid2D(32, 32, 1.0 / 32.0)
    body = obstacle_circle((0.5, 0.45), 0.2, 50)
    bmap, interior = _setup(grid, body)
    weight = DENSITY * GRAVITY * polygon_signed_area(body.polygon)
    for first in (1.0, 1.5, 2.5):
        force = force_traction(grid, bmap, *_still(grid), _hydrostatic(grid), DENSITY, 1e-3,
                               interior, gravity=(0.0, -GRAVITY),
                               sample_distances=(first, first + 1.0)).sum(axis=0)
        np.testing.assert_allclose(force, [0.0, weight], rtol=0, atol=1e-9 * weight)


def test_rotating_cylinder_in_couette_flow_gets_the_analytic_torque():
    # Circular Couette flow between a cylinder of radius r1 rotating at omega and a fixed
    # one of radius r2: u_theta = a r + b / r, torque on the inner one -4 pi mu b.
    r1, r2, omega, viscosity = 0.2, 0.45, 2.0, 1e-3
    center = np.array([0.5, 0.5])
    b = omega * r1**2 * r2**2 / (r2**2 - r1**2)
    a = -omega * r1**2 / (r2**2 - r1**2)
    exact = -4.0 * np.pi * DENSITY * viscosity * b

    def flow(x, y):
        dx, dy = x - center[0], y - center[1]
        r = np.hypot(dx, dy)
        speed = np.where(r >= r1, a * r + b / r, omega * r)
        return -speed * dy / r, speed * dx / r

    errors = []
    for n in (32, 64):
        grid = Grid2D(n, n, 1.0 / n)
        body = obstacle_circle(tuple(center), r1, 256, motion=RigidMotion(angular_velocity=omega))
        bmap, interior = _setup(grid, body)
        velocity_x, _ = flow(*grid.faces_x())
        _, velocity_y = flow(*grid.faces_y())
        force = force_traction(grid, bmap, velocity_x, velocity_y, np.zeros(grid.shape_cells),
                               DENSITY, viscosity, interior)
        arm = bmap.points - center
        torque = np.sum(arm[:, 0] * force[:, 1] - arm[:, 1] * force[:, 0])
        np.testing.assert_allclose(force.sum(axis=0), 0.0, atol=1e-9 * abs(exact))
        errors.append(abs(torque / exact - 1.0))
    assert errors[1] < 0.02 and errors[1] < 0.6 * errors[0], errors
