"""Discrete identities of the 3D explicit FEM: rigid motion, momenta, patch test, masses,
energy gradient, the stable substep and inversion errors."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow.solid import (
    BodyState,
    ElasticBody,
    ElasticBody3D,
    ExplicitFem,
    MaterialStVK,
    SolidInversionError,
    mesh_box,
    mesh_cylinder,
    mesh_rectangle,
    mesh_sphere,
    nodes_in_box_3d,
)

MATERIAL = MaterialStVK(1000.0, 1.0e6, 0.3)
DAMPED = MaterialStVK(1000.0, 1.0e6, 0.3, damping_lambda=20.0, damping_mu=20.0)


@pytest.fixture(scope="module")
def cylinder():
    return mesh_cylinder(0.1, 0.3, 0.08)


def random_rotation(seed: int) -> np.ndarray:
    q, r = np.linalg.qr(np.random.default_rng(seed).standard_normal((3, 3)))
    q *= np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def test_zero_force_at_rest_and_under_rigid_motion(cylinder) -> None:
    body = ElasticBody3D(cylinder, DAMPED)
    state = body.state()
    scale = DAMPED.young_modulus * cylinder.element_size**2
    assert np.abs(body.internal_forces(state)).max() < 1e-12 * scale
    rotation = random_rotation(1)
    state.positions[:] = cylinder.points @ rotation.T + [0.3, -1.0, 2.0]
    # A rigid velocity field (spin plus drift) costs no Voigt force either.
    state.velocities[:] = np.cross([0.4, -1.0, 2.0], state.positions) + [1.0, 0.5, -0.2]
    assert np.abs(body.internal_forces(state)).max() < 1e-10 * scale
    assert body.elastic_energy(state) < 1e-12 * scale * cylinder.element_size


def test_internal_forces_conserve_momentum_and_angular_momentum(cylinder) -> None:
    body = ElasticBody3D(cylinder, DAMPED)
    rng = np.random.default_rng(2)
    state = BodyState(cylinder.points + 0.01 * rng.standard_normal(cylinder.points.shape),
                      rng.standard_normal(cylinder.points.shape))
    forces = body.internal_forces(state)
    size = np.abs(forces).max()
    assert size > 1.0
    np.testing.assert_allclose(forces.sum(axis=0), 0.0, atol=1e-12 * size * len(forces))
    torque = np.cross(state.positions, forces).sum(axis=0)
    np.testing.assert_allclose(torque, 0.0, atol=1e-12 * size * len(forces))


def test_patch_test_linear_field_gives_constant_strain_and_stress() -> None:
    mesh = mesh_sphere(1.0, 0.5)
    body = ElasticBody3D(mesh, MATERIAL)
    gradient = np.array([[1.02, 0.01, -0.03], [0.02, 0.97, 0.01], [0.0, 0.04, 1.05]])
    state = body.state()
    state.positions[:] = mesh.points @ gradient.T + [1.0, 2.0, 3.0]
    np.testing.assert_allclose(body.deformation_gradients(state),
                               np.broadcast_to(gradient, (mesh.tetrahedron_count, 3, 3)),
                               atol=1e-12)
    strain = 0.5 * (gradient.T @ gradient - np.eye(3))
    lam, mu = MATERIAL.lame_lambda, MATERIAL.lame_mu
    stress = lam * np.trace(strain) * np.eye(3) + 2.0 * mu * strain
    assert lam == pytest.approx(1e6 * 0.3 / (1.3 * 0.4))
    np.testing.assert_allclose(body.second_piola_kirchhoff_stress(state),
                               np.broadcast_to(stress, (mesh.tetrahedron_count, 3, 3)),
                               rtol=1e-10, atol=1e-9 * mu)
    # Uniform stress: interior nodes feel no force; on the boundary the internal forces
    # balance the traction P N dA (P = F S, on the rest surface; a third of each face to its
    # nodes) that would hold the body in this state.
    forces = body.internal_forces(state)
    boundary = np.unique(mesh.boundary_triangles)
    interior = np.setdiff1d(np.arange(mesh.point_count), boundary)
    assert interior.size > 0
    assert np.abs(forces[interior]).max() < 1e-9 * np.abs(forces).max()
    faces = mesh.boundary_triangles
    normals_area = 0.5 * np.cross(mesh.points[faces[:, 1]] - mesh.points[faces[:, 0]],
                                  mesh.points[faces[:, 2]] - mesh.points[faces[:, 0]])
    traction = -normals_area @ (gradient @ stress).T / 3.0
    expected = np.zeros_like(forces)
    for corner in range(3):
        np.add.at(expected, faces[:, corner], traction)
    np.testing.assert_allclose(forces, expected, atol=1e-9 * np.abs(expected).max())


def test_forces_are_minus_energy_gradient() -> None:
    mesh = mesh_box((0.2, 0.1, 0.1), counts=(2, 1, 1))
    body = ElasticBody3D(mesh, MATERIAL)
    rng = np.random.default_rng(3)
    state = BodyState(mesh.points + 0.01 * rng.standard_normal(mesh.points.shape),
                      np.zeros(mesh.points.shape))
    forces = body.internal_forces(state)
    eps = 1e-7
    gradient = np.zeros_like(forces)
    for k in range(forces.size):
        shifted = state.copy()
        shifted.positions.flat[k] += eps
        up = body.elastic_energy(shifted)
        shifted.positions.flat[k] -= 2 * eps
        gradient.flat[k] = (up - body.elastic_energy(shifted)) / (2 * eps)
    np.testing.assert_allclose(forces, -gradient, atol=1e-6 * np.abs(forces).max())


@pytest.mark.parametrize("maker", [
    lambda: mesh_box((0.3, 0.2, 0.1), 0.05),
    lambda: mesh_cylinder(0.1, 0.2, 0.05),
    lambda: mesh_sphere(0.1, 0.05),
])
def test_lumped_mass_sums_to_body_mass(maker) -> None:
    mesh = maker()
    body = ElasticBody3D(mesh, MATERIAL)
    assert body.mass.sum() == pytest.approx(MATERIAL.density * mesh.volume, rel=1e-12)
    assert np.all(body.mass > 0.0)


def test_free_fall_and_fixed_nodes() -> None:
    mesh = mesh_box((0.2, 0.05, 0.05), counts=(4, 1, 1))
    gravity = (0.0, 0.0, -9.81)
    falling = ElasticBody3D(mesh, MATERIAL, gravity=gravity)
    state = falling.state()
    report = ExplicitFem("auto").advance(falling, state, state, 0.01)
    # Uniform acceleration: no strain, every node falls g t^2 / 2 up to the Euler O(dt_s).
    drop = mesh.points[:, 2] - state.positions[:, 2]
    np.testing.assert_allclose(drop, drop[0], rtol=0, atol=1e-12)
    assert drop[0] == pytest.approx(0.5 * 9.81 * 0.01**2 * (1 + 1 / report.substeps),
                                    rel=1e-9)
    held = nodes_in_box_3d(mesh, (0.0, 0.0, 0.0, 0.0, 0.05, 0.05))
    clamped = ElasticBody3D(mesh, MATERIAL, fixed_nodes=held, gravity=gravity)
    state = clamped.state()
    for step in range(5):
        ExplicitFem("auto").advance(clamped, state, state, 0.01, step=step)
    np.testing.assert_array_equal(state.positions[held], mesh.points[held])
    assert state.positions[:, 2].min() < mesh.points[:, 2].min()


def test_energy_conserved_without_damping() -> None:
    mesh = mesh_box((0.1, 0.1, 0.1), counts=(2, 2, 2))
    rng = np.random.default_rng(4)
    body = ElasticBody3D(mesh, MATERIAL,
                         velocities=0.2 * rng.standard_normal(mesh.points.shape))
    state = body.state()
    start = body.total_energy(state)
    # Symplectic Euler keeps a nearby energy: bounded error O(dt_s), no drift.
    energies = []
    for _ in range(50):
        ExplicitFem(4).advance(body, state, state, 0.25 * body.stable_substep() * 4)
        energies.append(body.total_energy(state))
    assert max(abs(e - start) for e in energies) < 0.05 * start
    damped = ElasticBody3D(mesh, DAMPED, velocities=body.state().velocities)
    state = damped.state()
    # Voigt damping: the energy falls from one sample to the next (every 5 steps, longer than
    # the undamped fluctuation of a step), to 0.78 of the start after 40 steps.
    first = previous = damped.total_energy(state)
    for _ in range(8):
        for _ in range(5):
            ExplicitFem("auto").advance(damped, state, state, 1e-4)
        current = damped.total_energy(state)
        assert current < previous
        previous = current
    assert previous < 0.85 * first


def test_serial_and_parallel_kernels_agree(cylinder) -> None:
    serial_body = ElasticBody3D(cylinder, DAMPED, parallel=False)
    parallel_body = ElasticBody3D(cylinder, DAMPED, parallel=True)
    rng = np.random.default_rng(5)
    forces = rng.standard_normal((cylinder.point_count, 3))
    states = []
    for body in (serial_body, parallel_body):
        state = body.state()
        ExplicitFem(7).advance(body, state, state, 1e-4, forces)
        states.append(state)
    np.testing.assert_allclose(states[1].positions, states[0].positions, rtol=0, atol=1e-14)
    np.testing.assert_allclose(states[1].velocities, states[0].velocities, rtol=1e-12,
                               atol=1e-13)


def critical_substep(body: ElasticBody3D) -> float:
    """2 / omega_max of the linearised body at rest (finite-difference stiffness)."""
    mesh = body.mesh
    size = 3 * mesh.point_count
    state = body.state()
    stiffness = np.zeros((size, size))
    eps = 1e-7
    for k in range(size):
        state.positions[:] = mesh.points
        state.positions.flat[k] += eps
        up = body.internal_forces(state).ravel()
        state.positions.flat[k] -= 2 * eps
        stiffness[:, k] = -(up - body.internal_forces(state).ravel()) / (2 * eps)
    scale = 1.0 / np.sqrt(np.repeat(body.mass, 3))
    symmetric = 0.5 * (stiffness + stiffness.T) * scale[:, None] * scale[None, :]
    return 2.0 / np.sqrt(np.linalg.eigvalsh(symmetric).max())


@pytest.mark.parametrize("poisson_ratio", [0.0, 0.45])
def test_stability_estimate_is_conservative(poisson_ratio: float) -> None:
    material = MaterialStVK(1000.0, 1e6, poisson_ratio)
    # Measured ratios (critical / estimate): box 0.96-0.98, slender box 0.93-0.96, cylinder
    # 1.03-1.06, sphere 1.25-1.41 for nu 0 to 0.45; "auto" (0.5) keeps a margin of 1.8.
    for mesh in (mesh_box((0.1, 0.1, 0.1), counts=(3, 3, 3)),
                 mesh_box((0.2, 0.02, 0.02), counts=(10, 1, 1)),
                 mesh_cylinder(0.05, 0.1, 0.04), mesh_sphere(0.05, 0.04)):
        body = ElasticBody3D(mesh, material)
        ratio = critical_substep(body) / body.stable_substep(safety=1.0)
        assert 0.9 <= ratio < 1.5


def test_auto_substeps_stable_where_three_times_blows_up() -> None:
    mesh = mesh_box((0.1, 0.1, 0.5), counts=(2, 2, 10))
    material = MaterialStVK(1000.0, 1.0e6, 0.3, damping_mu=1.0)
    top = nodes_in_box_3d(mesh, (0.0, 0.0, 0.5, 0.1, 0.1, 0.5))
    dt = 0.01
    stable = ElasticBody3D(mesh, material, fixed_nodes=top, gravity=(0.0, 0.0, -9.81))
    state = stable.state()
    report = ExplicitFem("auto").advance(stable, state, state, dt)
    assert report.substep_dt <= stable.stable_substep() * (1 + 1e-12)
    assert (report.substeps - 1) * stable.stable_substep() < dt
    for step in range(1, 30):
        ExplicitFem("auto").advance(stable, state, state, dt, step=step)
    assert np.all(np.isfinite(state.positions))
    assert stable.determinants_at(state.positions).min() > 0.9

    unstable = ElasticBody3D(mesh, material, fixed_nodes=top, gravity=(0.0, 0.0, -9.81))
    state = unstable.state()
    substeps = max(1, report.substeps // 3)
    before = state.positions.copy()
    with pytest.raises(SolidInversionError,
                       match=r"step \d+, substep \d+ of .*element \d+") as info:
        for step in range(30):
            before = state.positions.copy()
            ExplicitFem(substeps).advance(unstable, state, state, dt, step=step)
    error = info.value
    assert 0 <= error.element < mesh.tetrahedron_count
    assert error.positions.shape == (mesh.point_count, 3)
    np.testing.assert_array_equal(state.positions, before)


def test_inverted_start_names_the_element() -> None:
    mesh = mesh_box((0.1, 0.1, 0.1), counts=(1, 1, 1))
    positions = mesh.points.copy()
    positions[7] = [-0.05, -0.05, -0.05]  # pull a corner through the opposite one
    body = ElasticBody3D(mesh, MATERIAL, positions=positions)
    bad = int(np.flatnonzero(body.determinants_at(positions) <= 0.0)[0])
    state = body.state()
    with pytest.raises(SolidInversionError, match=f"substep 0 of 1 .*element {bad} has det F"):
        ExplicitFem(1).advance(body, state, state, 1e-6)


def test_bad_input_is_rejected() -> None:
    mesh = mesh_box((0.2, 0.1, 0.1), counts=(2, 1, 1))
    body = ElasticBody3D(mesh, MATERIAL)
    state = body.state()
    with pytest.raises(ValueError, match=r"external_forces shape \(12, 2\): must be \(12, 3\)"):
        ExplicitFem(1).advance(body, state, state, 0.01, np.zeros((12, 2)))
    with pytest.raises(ValueError, match="fixed_nodes contains 99"):
        ElasticBody3D(mesh, MATERIAL, fixed_nodes=[99])
    with pytest.raises(ValueError, match="gravity = .*three finite numbers"):
        ElasticBody3D(mesh, MATERIAL, gravity=(0.0, -9.81))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="plane = 'stress'"):
        ElasticBody3D(mesh, MaterialStVK(1000.0, 1e6, 0.3, plane="stress"))
    with pytest.raises(ValueError, match=r"positions shape \(12, 2\)"):
        ElasticBody3D(mesh, MATERIAL, positions=np.zeros((12, 2)))
    with pytest.raises(ValueError, match=r"positions shape \(12, 2\): must be \(12, 3\)"):
        body.check_state(BodyState(np.zeros((12, 2)), np.zeros((12, 2))))
    # The 2D body still takes (n, 2) forces through the shared integrator.
    flat = ElasticBody(mesh_rectangle(0.2, 0.1, counts=(2, 1)), MATERIAL)
    flat_state = flat.state()
    with pytest.raises(ValueError, match=r"must be \(6, 2\)"):
        ExplicitFem(1).advance(flat, flat_state, flat_state, 0.01, np.zeros((6, 3)))
