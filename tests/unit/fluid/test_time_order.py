"""Temporal order of the fluid step's options (`FluidSolver` advecting_velocity,
viscosity_scheme), each at a fixed grid on a problem whose spatial error is zero or known, so
that what is left as dt halves is the time error alone.

* Back-trace: a linear dye field c = x carried by a uniform velocity (u, v) that changes in
  time (v makes the trace two-dimensional; c does not vary along it). Bilinear
  sampling is exact for a linear field, so the error is the departure point's: tracing with
  u^n misses ``dt^2 U'/2`` per step (first order), with the velocity extrapolated to mid-step
  ``O(dt^3)`` (second order).
* Viscosity (and the BDF2 step): a Taylor-Green mode of tiny amplitude in a free-slip box (advection and pressure
  do nothing) is an eigenvector of the discrete Laplacian with eigenvalue ``lam``; its exact
  discrete decay is ``exp(nu lam t)``, backward Euler's ``(1 - nu dt lam)^-k``, Crank-Nicolson's
  ``((1 + nu dt lam / 2) / (1 - nu dt lam / 2))^k``, BDF2's that of its two-step recursion.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from elastoflow import fluid
from elastoflow.grid import Grid2D
from elastoflow.linalg import PoissonSolverMGPCG

END_TIME = 0.3
STEPS = (8, 16, 32, 64)


RATE = 5.0  # [1/s]: not a whole period in END_TIME, where a rectangle rule would be exact


def _speed(t: float) -> tuple[float, float]:
    return 1.0 + 0.5 * math.sin(RATE * t), 0.5 * math.cos(RATE * t)


def _displacement(t: float) -> tuple[float, float]:
    return t + 0.5 * (1.0 - math.cos(RATE * t)) / RATE, 0.5 * math.sin(RATE * t) / RATE


def _walls() -> fluid.DomainBoundaries:
    return fluid.DomainBoundaries(left=fluid.WallFreeSlip(), right=fluid.WallFreeSlip(),
                                  bottom=fluid.WallFreeSlip(), top=fluid.WallFreeSlip())


def trace_error(steps: int, advection: str, advecting_velocity: str) -> float:
    """Max error of the linear dye c = x after END_TIME in ``steps`` steps, in a long
    channel, over cells far from the sides whose ghosts would spoil the linear field."""
    h = 1.0 / 32
    grid = Grid2D(nx=192, ny=16, h=h)
    solver = fluid.FluidSolver(grid, density=1.0, viscosity=0.0, boundaries=_walls(),
                               advection=advection, advecting_velocity=advecting_velocity)
    state = fluid.FluidState.zeros(grid)
    x, _ = grid.cell_centers()
    state.dye[...] = x
    dt = END_TIME / steps
    for k in range(steps):
        # The velocity a step would have produced: uniform, at the step's start time.
        state.velocity_x[...], state.velocity_y[...] = _speed(k * dt)
        solver.advect(state, dt)
    exact = x - _displacement(END_TIME)[0]
    away = (x > 1.5) & (x < 2.5)
    return float(np.abs(state.dye - exact)[away].max())


def _orders(errors: list[float]) -> np.ndarray:
    return np.log2(np.array(errors[:-1]) / np.array(errors[1:]))


@pytest.mark.parametrize("advection", ["semi_lagrangian", "maccormack"])
def test_back_trace_with_extrapolated_velocity_is_second_order(advection):
    current = [trace_error(k, advection, "current") for k in STEPS]
    extrapolated = [trace_error(k, advection, "extrapolated") for k in STEPS]
    # Measured: 1.02, 1.01, 1.005 and 2.23, 2.13, 2.07 (the first step traces with u^n).
    assert np.all(np.abs(_orders(current) - 1.0) < 0.1), current
    assert np.all(np.abs(_orders(extrapolated) - 2.0) < 0.3), extrapolated
    assert _orders(extrapolated)[-1] > 1.9
    assert extrapolated[-1] < 0.01 * current[-1]


def _eigenvalue(h: float, k: float) -> float:
    return 2.0 * (2.0 * math.cos(k * h) - 2.0) / h**2


def decay_error(steps: int, viscosity_scheme: str, interior: bool = False) -> float:
    """Max error of a tiny Taylor-Green mode after END_TIME in ``steps`` steps against its
    exact discrete decay (``interior``: with an empty InteriorBoundary, the body path)."""
    n, nu, k = 16, 0.05, 1.0
    grid = Grid2D(nx=n, ny=n, h=math.pi / k / n)
    solver = fluid.FluidSolver(
        grid, density=1.0, viscosity=nu, boundaries=_walls(),
        viscosity_scheme=viscosity_scheme,
        viscosity_solver=PoissonSolverMGPCG(rtol=1e-12),
        pressure_solver=PoissonSolverMGPCG(rtol=1e-12),
    )
    state = fluid.FluidState.zeros(grid)
    amplitude = 1e-9
    xu, yu = grid.faces_x()
    xv, yv = grid.faces_y()
    mode_u = np.sin(k * xu) * np.cos(k * yu)
    mode_v = -np.cos(k * xv) * np.sin(k * yv)
    state.velocity_x[...] = amplitude * mode_u
    state.velocity_y[...] = amplitude * mode_v
    body = fluid.InteriorBoundary.empty(grid) if interior else None
    dt = END_TIME / steps
    for index in range(steps):
        solver.step(state, dt, index * dt, body)
    decay = math.exp(nu * _eigenvalue(grid.h, k) * END_TIME)
    return float(np.abs(state.velocity_x / amplitude - decay * mode_u).max())


def test_crank_nicolson_viscosity_is_second_order_and_backward_euler_first():
    euler = [decay_error(k, "backward_euler") for k in STEPS]
    crank = [decay_error(k, "crank_nicolson") for k in STEPS]
    # Measured: 0.998, 0.999, 1.000 and 1.996, 1.986, 1.934 (the last near round-off).
    assert np.all(np.abs(_orders(euler) - 1.0) < 0.05), euler
    assert np.all(np.abs(_orders(crank) - 2.0) < 0.1), crank


def test_bdf2_step_is_second_order():
    # The first step is backward Euler (no history), which keeps the global order 2.
    bdf2 = [decay_error(k, "bdf2") for k in STEPS]
    # Measured: 2.002, 2.001, 2.001.
    assert np.all(np.abs(_orders(bdf2) - 2.0) < 0.05), bdf2


def test_bdf2_needs_a_constant_step_and_a_history():
    _, solver, state = _vortex_solver("current", "bdf2")
    assert not solver._bdf2_history(state, 0.02, None)
    solver.step(state, 0.02)
    assert state.previous_dt == 0.02 and state.previous_velocity_x is not None
    assert solver._bdf2_history(state, 0.02, None)
    assert not solver._bdf2_history(state, 0.01, None)


def test_crank_nicolson_on_the_body_path_matches_the_plain_one():
    # An empty InteriorBoundary assembles the operator every step (no cache): same numbers.
    assert decay_error(16, "crank_nicolson", interior=True) == pytest.approx(
        decay_error(16, "crank_nicolson"), rel=1e-6)


def _vortex_solver(advecting_velocity: str, viscosity_scheme: str = "backward_euler"
                   ) -> tuple[Grid2D, fluid.FluidSolver, fluid.FluidState]:
    grid = Grid2D(nx=24, ny=24, h=math.pi / 24)
    solver = fluid.FluidSolver(grid, density=1.0, viscosity=0.01, boundaries=_walls(),
                               advection="maccormack", advecting_velocity=advecting_velocity,
                               viscosity_scheme=viscosity_scheme)
    state = fluid.FluidState.zeros(grid)
    xu, yu = grid.faces_x()
    xv, yv = grid.faces_y()
    state.velocity_x[...] = np.sin(xu) * np.cos(yu) + 0.3
    state.velocity_y[...] = -np.cos(xv) * np.sin(yv)
    state.dye[...] = 1.0
    return grid, solver, state


def test_first_extrapolated_step_is_the_plain_step_and_keeps_the_start_velocity():
    _, plain, state = _vortex_solver("current")
    _, extrapolated, other = _vortex_solver("extrapolated")
    start = state.velocity_x.copy()
    plain.step(state, 0.02)
    extrapolated.step(other, 0.02)
    for name in ("velocity_x", "velocity_y", "pressure", "dye"):
        np.testing.assert_array_equal(getattr(state, name), getattr(other, name))
    assert state.previous_velocity_x is None and state.previous_dt is None
    np.testing.assert_array_equal(other.previous_velocity_x, start)
    assert other.previous_dt == 0.02
    extrapolated.step(other, 0.02)
    plain.step(state, 0.02)
    assert not np.array_equal(state.velocity_x, other.velocity_x)


def test_extrapolated_run_resumes_bit_exactly_from_a_checkpoint():
    from elastoflow.simulation._state import CoupledState

    _, solver, state = _vortex_solver("extrapolated")
    for _ in range(3):
        solver.step(state, 0.02)
    saved = CoupledState(fluid=state.copy(), bodies=[]).to_arrays()
    assert "fluid.previous_velocity_x" in saved and "fluid.previous_dt" in saved
    for _ in range(2):
        solver.step(state, 0.02)
    resumed = CoupledState(fluid=fluid.FluidState.zeros(solver.grid), bodies=[])
    resumed.load_arrays(saved)
    assert resumed.fluid.previous_dt == 0.02
    for _ in range(2):
        solver.step(resumed.fluid, 0.02)
    for name in ("velocity_x", "velocity_y", "pressure", "previous_velocity_x"):
        np.testing.assert_array_equal(getattr(state, name), getattr(resumed.fluid, name))


def test_a_checkpoint_without_the_previous_velocity_restarts_with_the_plain_trace():
    from elastoflow.simulation._state import CoupledState

    _, solver, state = _vortex_solver("extrapolated")
    plain = CoupledState(fluid=state.copy(), bodies=[]).to_arrays()
    assert not any(key.startswith("fluid.previous") for key in plain)
    solver.step(state, 0.02)
    restarted = CoupledState(fluid=state.copy(), bodies=[])
    restarted.load_arrays(plain)
    assert restarted.fluid.previous_velocity_x is None
    copy = restarted.copy()
    copy.assign(CoupledState(fluid=state, bodies=[]))
    np.testing.assert_array_equal(copy.fluid.previous_velocity_x, state.previous_velocity_x)
    copy.assign(restarted)
    assert copy.fluid.previous_velocity_x is None and copy.fluid.previous_dt is None


def test_scene_keys_reach_the_solver_and_default_to_the_first_order_step():
    from elastoflow.scenes import SceneError, build_simulation, parse_scene

    base: dict = {"domain": {"lx": 1.0, "ly": 1.0, "nx": 16}, "time": {"dt": 0.01, "steps": 5}}
    solver = build_simulation(parse_scene({**base, "fluid": {
        "advecting_velocity": "extrapolated", "viscosity_scheme": "crank_nicolson"}}),
        warnings=[]).fluid_solver
    assert solver.advecting_velocity == "extrapolated"
    assert solver.viscosity_scheme == "crank_nicolson"
    default = build_simulation(parse_scene(base), warnings=[]).fluid_solver
    assert default.advecting_velocity == "current"
    assert default.viscosity_scheme == "backward_euler"
    with pytest.raises(SceneError, match="advecting_velocity"):
        parse_scene({**base, "fluid": {"advecting_velocity": "midpoint"}})
