"""Discrete identities of the explicit FEM: patch test, rigid motion, energy, constraints."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow.solid import (
    BodyState,
    ElasticBody,
    ExplicitFem,
    MaterialStVK,
    SolidInversionError,
    mesh_from_polygon,
    mesh_rectangle,
    mesh_windmill,
    nodes_in_box,
)

MATERIAL = MaterialStVK(1000.0, 1.0e6, 0.3)
DAMPED = MaterialStVK(1000.0, 1.0e6, 0.3, damping_lambda=20.0, damping_mu=20.0)


@pytest.fixture(scope="module")
def unstructured():
    return mesh_from_polygon([[0, 0], [1, 0], [1.2, 0.8], [0.1, 1.0]], element_size=0.2)


def rotation(angle: float) -> np.ndarray:
    return np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])


def test_zero_force_at_rest(unstructured) -> None:
    body = ElasticBody(unstructured, DAMPED)
    body_state = body.state()
    # Zero up to the round-off of F = Ds Dm^-1 (Dm^-1 is a computed inverse).
    scale = DAMPED.young_modulus * unstructured.element_size
    assert np.abs(body.internal_forces(body_state)).max() < 1e-13 * scale
    assert body.elastic_energy(body_state) < 1e-24 * DAMPED.young_modulus * unstructured.area


def test_rigid_rotation_and_translation_give_zero_force(unstructured) -> None:
    r = rotation(np.pi / 2)
    positions = unstructured.points @ r.T + np.array([3.0, -2.0])
    # Rigid spin about an arbitrary point: Edot = 0, so Voigt damping gives no force either.
    omega = 2.0
    velocities = omega * (positions - [1.0, 1.0]) @ rotation(np.pi / 2).T + [0.5, 0.1]
    body = ElasticBody(unstructured, DAMPED, positions=positions, velocities=velocities)
    body_state = body.state()
    scale = MATERIAL.young_modulus * unstructured.element_size
    assert np.abs(body.internal_forces(body_state)).max() < 1e-12 * scale
    assert body.elastic_energy(body_state) < 1e-12 * MATERIAL.young_modulus * unstructured.area


def test_patch_test_uniform_stress(unstructured) -> None:
    """x = A X + b: every element has the exact StVK stress; forces are the boundary traction."""
    a = np.array([[1.05, 0.1], [-0.03, 0.97]])
    body = ElasticBody(unstructured, MATERIAL, positions=unstructured.points @ a.T + [0.2, 0.1])
    body_state = body.state()
    e = 0.5 * (a.T @ a - np.eye(2))
    s = MATERIAL.lame_lambda * np.trace(e) * np.eye(2) + 2 * MATERIAL.lame_mu * e
    p_exact = a @ s
    p = body.first_piola_kirchhoff_stress(body_state)
    np.testing.assert_allclose(p, np.broadcast_to(p_exact, p.shape), rtol=0,
                               atol=1e-10 * np.abs(p_exact).max())
    # f_i = -sum over boundary edges at i of P n L / 2 (div P = 0 inside).
    expected = np.zeros_like(unstructured.points)
    for a_node, b_node in unstructured.boundary_edges:
        d = unstructured.points[b_node] - unstructured.points[a_node]
        outward_times_length = np.array([d[1], -d[0]])
        expected[a_node] -= 0.5 * p_exact @ outward_times_length
        expected[b_node] -= 0.5 * p_exact @ outward_times_length
    np.testing.assert_allclose(body.internal_forces(body_state), expected, rtol=0,
                               atol=1e-9 * np.abs(expected).max())


def test_forces_are_minus_energy_gradient(unstructured) -> None:
    rng = np.random.default_rng(1)
    positions = unstructured.points + 0.01 * rng.standard_normal(unstructured.points.shape)
    body = ElasticBody(unstructured, MATERIAL, positions=positions)
    body_state = body.state()
    forces = body.internal_forces(body_state)
    eps = 1e-7
    for node, axis in [(0, 0), (5, 1), (unstructured.point_count - 1, 0)]:
        body_state.positions[node, axis] += eps
        up = body.elastic_energy(body_state)
        body_state.positions[node, axis] -= 2 * eps
        down = body.elastic_energy(body_state)
        body_state.positions[node, axis] += eps
        assert -(up - down) / (2 * eps) == pytest.approx(forces[node, axis], rel=1e-5, abs=1e-3)


def test_lumped_mass_and_free_fall() -> None:
    mesh = mesh_rectangle(0.2, 0.1, counts=(4, 2))
    body = ElasticBody(mesh, MATERIAL, gravity=(0.0, -9.81))
    body_state = body.state()
    assert body.mass.sum() == pytest.approx(1000.0 * 0.02, rel=1e-12)
    report = ExplicitFem(10).advance(body, body_state, body_state, 0.01)
    np.testing.assert_allclose(body_state.velocities, np.broadcast_to([0.0, -0.0981], (mesh.point_count, 2)),
                               atol=1e-12)
    assert report.substeps == 10
    assert report.substep_dt == pytest.approx(1e-3)


def test_external_force_changes_momentum_exactly() -> None:
    mesh = mesh_rectangle(0.2, 0.1, counts=(4, 2))
    body = ElasticBody(mesh, MATERIAL)
    body_state = body.state()
    forces = np.zeros((mesh.point_count, 2))
    forces[0] = [3.0, -1.0]
    forces[-1] = [0.0, 2.0]
    ExplicitFem("auto").advance(body, body_state, body_state, 1e-3, forces)
    momentum = (body.mass[:, None] * body_state.velocities).sum(axis=0)
    np.testing.assert_allclose(momentum, forces.sum(axis=0) * 1e-3, rtol=1e-10)


def test_added_mass_slows_response_but_not_gravity_pull() -> None:
    mesh = mesh_rectangle(0.2, 0.1, counts=(4, 2))
    body = ElasticBody(mesh, MATERIAL, gravity=(0.0, -9.81))
    body_state = body.state()
    added = 3.0 * body.mass
    forces = np.zeros((mesh.point_count, 2))
    forces[:, 0] = 0.4 * body.mass
    ExplicitFem(10).advance(body, body_state, body_state, 0.01, forces, added_mass=added)
    # (m + 3m) a = F + m g: a quarter of both accelerations.
    np.testing.assert_allclose(body_state.velocities[:, 0], 0.25 * 0.4 * 0.01, rtol=1e-9)
    np.testing.assert_allclose(body_state.velocities[:, 1], -0.25 * 9.81 * 0.01, rtol=1e-9)
    with pytest.raises(ValueError, match="added_mass"):
        ExplicitFem(1).advance(body, body_state, body_state, 0.01, added_mass=-added)


def stretched_body(material: MaterialStVK) -> ElasticBody:
    mesh = mesh_rectangle(1.0, 0.2, counts=(10, 2))
    x = mesh.points
    # A smooth stretch and bend, so that the energy sits in the low modes.
    positions = x + 0.01 * np.column_stack([np.sin(np.pi * x[:, 0]), x[:, 0] ** 2])
    return ElasticBody(mesh, material, positions=positions)


def leapfrog_energies(body: ElasticBody, body_state: BodyState, substeps: int) -> np.ndarray:
    """Energy at each substep with the scheme's own kinetic energy.

    Symplectic Euler is leapfrog with the stored velocity at half steps; its energy at step n is
    ``W(x_n) + 1/2 sum m v_{n-1/2} . v_{n+1/2}``, which it conserves up to O(dt^2) without a
    secular drift (the plain ``1/2 m v^2`` oscillates by O(omega dt) in the stiff modes).
    """
    dt_s = body.stable_substep()
    ExplicitFem(1).advance(body, body_state, body_state, dt_s)
    energies = []
    for _ in range(substeps):
        elastic = body.elastic_energy(body_state)
        previous = body_state.velocities.copy()
        ExplicitFem(1).advance(body, body_state, body_state, dt_s)
        kinetic = 0.5 * np.sum(body.mass[:, None] * previous * body_state.velocities)
        energies.append(elastic + kinetic)
    return np.array(energies)


def test_energy_conserved_without_damping() -> None:
    body = stretched_body(MATERIAL)
    body_state = body.state()
    start = body.total_energy(body_state)
    energies = leapfrog_energies(body, body_state, 1000)
    drift = np.abs(energies - energies[0]).max() / energies[0]
    assert drift < 0.01
    assert energies[0] == pytest.approx(start, rel=0.05)
    assert body.kinetic_energy(body_state) > 0.05 * energies[0]


def test_damping_dissipates_energy_monotonically() -> None:
    body = stretched_body(DAMPED)
    energies = leapfrog_energies(body, body.state(), 1000)
    assert np.all(np.diff(energies) < 0.0)
    assert energies[-1] < 0.5 * energies[0]


def test_fixed_nodes_stay_and_pivot_lets_body_turn() -> None:
    mesh = mesh_rectangle(0.1, 0.5, counts=(2, 10), origin=(0.0, -0.5))
    top = nodes_in_box(mesh, (0.0, 0.0, 0.1, 0.0))
    body = ElasticBody(mesh, MATERIAL, fixed_nodes=top, gravity=(0.0, -9.81))
    body_state = body.state()
    for step in range(20):
        ExplicitFem("auto").advance(body, body_state, body_state, 2e-3, step=step)
    np.testing.assert_array_equal(body_state.positions[top], mesh.points[top])
    assert body_state.positions[:, 1].min() < -0.5

    windmill = mesh_windmill(0.05, 3, 0.2, 0.04, element_size=0.03)
    spin = 5.0
    velocities = spin * windmill.points @ rotation(np.pi / 2).T
    body = ElasticBody(windmill, MATERIAL, pivot_node=0, velocities=velocities)
    body_state = body.state()
    for _ in range(50):
        ExplicitFem("auto").advance(body, body_state, body_state, 1e-3)
    np.testing.assert_array_equal(body_state.positions[0], [0.0, 0.0])
    turned = np.arctan2(body_state.positions[1:, 1], body_state.positions[1:, 0]) - np.arctan2(
        windmill.points[1:, 1], windmill.points[1:, 0])
    turned = np.angle(np.exp(1j * turned))
    assert np.median(turned) == pytest.approx(spin * 0.05, rel=0.02)
    assert body.elastic_energy(body_state) < 1e-3 * body.kinetic_energy(body_state)


def test_serial_and_parallel_kernels_agree() -> None:
    body_serial = stretched_body(DAMPED)
    body_parallel = stretched_body(DAMPED)
    body_parallel.parallel = True
    forces = np.full((body_serial.mesh.point_count, 2), 0.3)
    serial, parallel = body_serial.state(), body_parallel.state()
    for body, state in ((body_serial, serial), (body_parallel, parallel)):
        ExplicitFem(7).advance(body, state, state, 1e-4, forces)
    np.testing.assert_allclose(parallel.positions, serial.positions, rtol=0, atol=1e-14)
    np.testing.assert_allclose(parallel.velocities, serial.velocities, rtol=1e-12, atol=1e-14)


def critical_substep(body: ElasticBody) -> float:
    """2 / omega_max of the linearised body at rest (finite-difference stiffness)."""
    mesh = body.mesh
    n = mesh.point_count
    body_state = body.state()
    stiffness = np.zeros((2 * n, 2 * n))
    eps = 1e-7
    for k in range(2 * n):
        body_state.positions[:] = mesh.points
        body_state.positions.flat[k] += eps
        up = body.internal_forces(body_state).ravel()
        body_state.positions.flat[k] -= 2 * eps
        stiffness[:, k] = -(up - body.internal_forces(body_state).ravel()) / (2 * eps)
    body_state.positions[:] = mesh.points
    omega_squared = np.linalg.eigvals(stiffness / np.repeat(body.mass, 2)[:, None]).real.max()
    return 2.0 / np.sqrt(omega_squared)


@pytest.mark.parametrize("poisson_ratio", [0.0, 0.45])
def test_stability_estimate_is_conservative(unstructured, poisson_ratio: float) -> None:
    material = MaterialStVK(1000.0, 1e6, poisson_ratio)
    for mesh in (unstructured, mesh_rectangle(1.0, 0.3, counts=(5, 2))):
        body = ElasticBody(mesh, material)
        ratio = critical_substep(body) / body.stable_substep(safety=1.0)
        # safety 0.5 then keeps a margin of 1.8 or more; 3x the "auto" substep is past critical.
        assert 0.9 <= ratio < 1.5


def test_auto_substeps_stable_where_three_times_blows_up() -> None:
    mesh = mesh_rectangle(0.1, 0.5, counts=(2, 10))
    material = MaterialStVK(1000.0, 1.0e6, 0.3, damping_mu=1.0)
    top = nodes_in_box(mesh, (0.0, 0.5, 0.1, 0.5))
    dt = 0.01
    stable = ElasticBody(mesh, material, fixed_nodes=top, gravity=(0.0, -9.81))
    stable_state = stable.state()
    report = ExplicitFem("auto").advance(stable, stable_state, stable_state, dt)
    assert report.substep_dt <= stable.stable_substep() * (1 + 1e-12)
    assert (report.substeps - 1) * stable.stable_substep() < dt
    for step in range(1, 30):
        ExplicitFem("auto").advance(stable, stable_state, stable_state, dt, step=step)
    assert np.all(np.isfinite(stable_state.positions))
    assert stable.deformation_determinants(stable_state).min() > 0.9

    unstable = ElasticBody(mesh, material, fixed_nodes=top, gravity=(0.0, -9.81))
    unstable_state = unstable.state()
    n_sub = max(1, report.substeps // 3)
    before = unstable_state.positions.copy()
    with pytest.raises(SolidInversionError, match=r"step \d+, substep \d+ of .*element \d+") as info:
        for step in range(30):
            before = unstable_state.positions.copy()
            ExplicitFem(n_sub).advance(unstable, unstable_state, unstable_state, dt, step=step)
    error = info.value
    assert 0 <= error.element < mesh.triangle_count
    assert error.step is not None and error.substep >= 1
    # The body keeps the last good state: finite, as before the failing call.
    np.testing.assert_array_equal(unstable_state.positions, before)


def test_bad_input_is_rejected() -> None:
    mesh = mesh_rectangle(0.2, 0.1, counts=(2, 1))
    body = ElasticBody(mesh, MATERIAL)
    body_state = body.state()
    with pytest.raises(ValueError, match="n_sub = 0"):
        ExplicitFem(0).advance(body, body_state, body_state, 0.01)
    with pytest.raises(ValueError, match="external_forces shape"):
        ExplicitFem(1).advance(body, body_state, body_state, 0.01, np.zeros((2, 2)))
    forces = np.zeros((mesh.point_count, 2))
    forces[3, 1] = np.nan
    with pytest.raises(ValueError, match="external_forces at node 3 is not finite"):
        ExplicitFem(1).advance(body, body_state, body_state, 0.01, forces)
    with pytest.raises(ValueError, match="fixed_nodes contains 99"):
        ElasticBody(mesh, MATERIAL, fixed_nodes=[99])
