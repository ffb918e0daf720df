"""Elastic rods (`elastoflow.solid.RodBody`): forces, step matrix, cantilever, energy."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow import solid


def _rod(n: int = 9, **options: object) -> solid.RodBody:
    s = np.linspace(0.0, 1.0, n)
    points = np.stack([s, 0.1 * np.sin(2.0 * s)], axis=1)
    material = solid.MaterialRod(1000.0, 1e6, 0.02, damping_time=float(
        options.pop("damping_time", 0.0)))  # type: ignore[arg-type]
    return solid.RodBody(points, material, **options)  # type: ignore[arg-type]


def test_forces_are_minus_the_energy_gradient() -> None:
    rod = _rod(clamped=("start", "end"))
    rng = np.random.default_rng(1)
    x = rod.mesh.points + 0.03 * rng.standard_normal(rod.mesh.points.shape)
    still = np.zeros_like(x)
    forces = rod.forces_at(x, still)
    numeric = np.zeros_like(x)
    for node in range(x.shape[0]):
        for axis in range(2):
            step = np.zeros_like(x)
            step[node, axis] = 1e-6
            numeric[node, axis] = -(rod.elastic_energy(solid.BodyState(x + step, still))
                                    - rod.elastic_energy(solid.BodyState(x - step, still))
                                    ) / 2e-6
    assert np.abs(forces - numeric).max() < 1e-7 * np.abs(forces).max()


def test_rigid_motion_costs_nothing() -> None:
    """Objective: rotated and translated rest shape, spinning, no force and no energy."""
    rod = _rod(damping_time=0.05)
    angle = 0.7
    rotation = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    x = rod.mesh.points @ rotation.T + np.array([0.3, -2.0])
    v = 1.5 * np.stack([-x[:, 1], x[:, 0]], axis=1) + np.array([0.2, 0.1])
    assert np.abs(rod.forces_at(x, v)).max() < 1e-9
    assert abs(rod.elastic_energy(solid.BodyState(x, v))) < 1e-18


def test_step_matrix_at_rest_is_mass_plus_stiffness() -> None:
    """At the stress-free rest shape the step matrix is ``M + s^2 K`` with K the exact
    Hessian of the energy (by finite differences of the forces)."""
    rod = _rod(clamped=("start",))
    x = rod.mesh.points
    s = 1e-3
    response = rod.response_at(x, 0.0, s, 1.0)
    n = 2 * rod.point_count
    free = response.free
    inverse = np.zeros((free.size, free.size))
    for k in range(free.size):
        unit = np.zeros(n)
        unit[free[k]] = 1.0
        inverse[:, k] = response.solve(unit.reshape(-1, 2)).reshape(-1)[free]
    stiffness = np.zeros((n, n))
    for k in range(n):
        step = np.zeros(n)
        step[k] = 1e-7
        stiffness[:, k] = -(rod.forces_at((x.reshape(-1) + step).reshape(-1, 2), 0 * x)
                            - rod.forces_at((x.reshape(-1) - step).reshape(-1, 2), 0 * x)
                            ).reshape(-1) / 2e-7
    expected = (np.diag(np.repeat(rod.mass, 2)) + s * s * stiffness)[np.ix_(free, free)]
    assert np.abs(np.linalg.inv(inverse) - expected).max() < 1e-8 * np.abs(expected).max()


@pytest.mark.parametrize("options", [{"clamped": ("start",)}, {"pinned_nodes": (0, 5)}, {}])
def test_nodal_damping_blocks_enter_the_step_matrix(options: dict) -> None:
    """``response_at(..., nodal_damping=C)`` factors ``A + dt blockdiag(C)`` (the viscous
    traction's dependence on the rod's velocity, `simulation._schemes._viscous_damping`),
    held nodes left out: the difference of the two answers' inverses is ``dt C`` on the free
    degrees of freedom, the coupling of a node's x and y included."""
    rod = _rod(**options)
    rng = np.random.default_rng(3)
    blocks = rng.standard_normal((rod.point_count, 2, 2))
    blocks = np.einsum("nab,ncb->nac", blocks, blocks)
    x = rod.mesh.points + 0.01 * rng.standard_normal(rod.mesh.points.shape)
    dt = 0.01
    plain = rod.response_at(x, dt)
    damped = rod.response_at(x, dt, nodal_damping=blocks)
    free = plain.free
    assert free.size < 2 * rod.point_count or not options
    compliance = [response.compliance(free) / dt for response in (plain, damped)]
    difference = np.linalg.inv(compliance[1]) - np.linalg.inv(compliance[0])
    dense = np.zeros((2 * rod.point_count, 2 * rod.point_count))
    for node in range(rod.point_count):
        dense[2 * node:2 * node + 2, 2 * node:2 * node + 2] = blocks[node]
    expected = dt * dense[np.ix_(free, free)]
    assert np.abs(difference - expected).max() < 1e-7 * np.abs(expected).max()


@pytest.mark.parametrize("segments", [10, 20, 40])
def test_cantilever_under_uniform_load_bends_as_euler_bernoulli(segments: int) -> None:
    """Clamped at one end, loaded by its weight q = rho t g: tip deflection q L^4 / (8 EI)
    (small deflection, 1.5e-3 L). Measured: +1.0 % (10 segments), +0.25 % (20), +0.06 % (40):
    second order, the clamp's half-segment length share exact for the clamp's curvature."""
    length, thickness, young, density, g = 1.0, 0.01, 1e11, 1000.0, 10.0
    points = np.stack([np.linspace(0.0, length, segments + 1), np.zeros(segments + 1)], 1)
    material = solid.MaterialRod(density, young, thickness)
    rod = solid.RodBody(points, material, clamped=("start",), gravity=(0.0, -g))
    state = rod.state()
    solid.static_equilibrium(rod, state)
    expected = density * thickness * g * length**4 / (8.0 * material.flexural_rigidity)
    error = -state.positions[-1, 1] / expected - 1.0
    assert abs(error) < 0.03
    assert abs(error) < 1.2 * (10.0 / segments) ** 2 * 0.01


def test_free_rod_implicit_step_keeps_energy_and_momenta() -> None:
    """A free rod bent to an arc (segments at rest length), spinning at 2 rad/s and drifting,
    500 energy-momentum steps (dt 2 ms; axial omega dt ~ 8): total energy to 1e-8 (measured
    1.1e-8 at most), linear and angular momentum to 1e-8 (1.7e-9); the midpoint rule drifts
    by 6e-4 in energy."""
    n = 21
    s = np.linspace(0.0, 1.0, n)
    rod = solid.RodBody(np.stack([s, 0.0 * s], 1), solid.MaterialRod(1000.0, 1e7, 0.01))
    radius = 0.5
    angle = (s - 0.5) / radius
    x = np.stack([0.5 + radius * np.sin(angle), radius * (1.0 - np.cos(angle))], axis=1)
    centre = x.mean(axis=0)
    v = 2.0 * np.stack([-(x[:, 1] - centre[1]), x[:, 0] - centre[0]], axis=1) + [0.3, 0.1]
    state = solid.BodyState(x, v)

    def momenta(state: solid.BodyState) -> tuple[np.ndarray, float]:
        p, u = state.positions, state.velocities
        return ((rod.mass[:, None] * u).sum(axis=0),
                float(np.sum(rod.mass * (p[:, 0] * u[:, 1] - p[:, 1] * u[:, 0]))))

    energy = rod.total_energy(state)
    linear, angular = momenta(state)
    integrator = solid.EnergyMomentumFem(0.0)
    dt = 2e-3
    drift = 0.0
    for step in range(500):
        response = integrator.response(rod, state, dt)
        integrator.advance(rod, state, state, dt, np.zeros_like(x), response, step=step)
        drift = max(drift, abs(rod.total_energy(state) / energy - 1.0))
    end_linear, end_angular = momenta(state)
    assert drift < 1e-7
    assert np.abs(end_linear - linear).max() < 1e-8 * np.abs(linear).max()
    assert abs(end_angular / angular - 1.0) < 1e-8
