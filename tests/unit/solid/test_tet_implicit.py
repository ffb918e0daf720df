"""Implicit steps of tetrahedral bodies: the tangent and damping matrices against finite
differences, the step matrix's assembly, the response's contract, energy and momenta of the
implicit rules, stability far above the explicit limit, and a cantilever against
Euler-Bernoulli (and against the explicit FEM's numbers on the same mesh)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import sparse

from elastoflow.solid import (
    BodyState,
    ElasticBody,
    ElasticBody3D,
    EnergyMomentumFem,
    MaterialStVK,
    MidpointFem,
    NewmarkFem,
    StepResponse3D,
    mesh_box,
    mesh_rectangle,
    nodes_in_box,
    nodes_in_box_3d,
    static_equilibrium,
)
from elastoflow.solid._implicit3d import StepMatrixLayout3D, step_matrix_3d
from elastoflow.validation._solid3d import (
    LENGTH,
    MATERIAL as STEEL,
    SIDE,
    cantilever_mesh,
    euler_bernoulli_deflection,
    euler_bernoulli_frequency,
    frequency_from_crossings,
    mode_shape,
)

MATERIAL = MaterialStVK(1000.0, 1.0e6, 0.3)
DAMPED = MaterialStVK(1000.0, 1.0e6, 0.3, damping_lambda=20.0, damping_mu=30.0)


def random_rotation(seed: int) -> np.ndarray:
    q, r = np.linalg.qr(np.random.default_rng(seed).standard_normal((3, 3)))
    q *= np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def small_block() -> ElasticBody3D:
    return ElasticBody3D(mesh_box((0.2, 0.1, 0.1), counts=(2, 1, 1)), DAMPED)


def test_tangent_and_damping_matrices_match_finite_differences() -> None:
    body = small_block()
    rng = np.random.default_rng(0)
    x = body.mesh.points + 0.02 * rng.standard_normal(body.mesh.points.shape)
    v = rng.standard_normal(x.shape)
    still = np.zeros_like(x)
    stiffness = body.stiffness_matrix(x)
    damping = body.damping_matrix(x)
    assert isinstance(stiffness, sparse.csr_matrix) and stiffness.shape == (x.size, x.size)
    k, d = stiffness.toarray(), damping.toarray()
    k_fd, d_fd = np.zeros_like(k), np.zeros_like(d)
    h = 1e-6
    for j in range(x.size):
        e = np.zeros(x.size)
        e[j] = h
        e = e.reshape(-1, 3)
        k_fd[:, j] = -(body.forces_at(x + e, still) - body.forces_at(x - e, still)).ravel()
        d_fd[:, j] = -(body.forces_at(x, v + e) - body.forces_at(x, v - e)).ravel()
    k_fd /= 2.0 * h
    d_fd /= 2.0 * h
    # Central differences: O(h^2) truncation, round-off ~ |f| eps / h.
    assert np.abs(k - k_fd).max() < 1e-7 * np.abs(k).max()
    assert np.abs(d - d_fd).max() < 1e-6 * np.abs(d).max()
    assert np.abs(k - k.T).max() < 1e-13 * np.abs(k).max()
    # The damping matrix is positive semi-definite; both have the six rigid motions at rest.
    assert np.linalg.eigvalsh(d).min() > -1e-10 * np.abs(d).max()
    rest = body.stiffness_matrix(body.mesh.points).toarray()
    assert np.sum(np.abs(np.linalg.eigvalsh(rest)) < 1e-9 * np.abs(rest).max()) == 6


def test_clamped_tangent_is_semidefinite_and_exact_under_tension() -> None:
    body = small_block()
    rng = np.random.default_rng(1)
    compressed = 0.8 * body.mesh.points + 0.01 * rng.standard_normal(body.mesh.points.shape)
    clamped = body.stiffness_matrix(compressed, clamp_compression=True).toarray()
    exact = body.stiffness_matrix(compressed).toarray()
    scale = np.abs(exact).max()
    assert np.linalg.eigvalsh(exact).min() < -1e-6 * scale
    assert np.linalg.eigvalsh(clamped).min() > -1e-10 * scale
    # Stretched in all directions and rotated: the stress is positive definite, nothing to
    # clamp.
    stretched = (body.mesh.points * [1.1, 1.05, 1.02]) @ random_rotation(2).T
    np.testing.assert_allclose(
        body.stiffness_matrix(stretched, clamp_compression=True).toarray(),
        body.stiffness_matrix(stretched).toarray(), rtol=0.0, atol=1e-12 * scale)


def test_step_matrix_is_mass_damping_and_clamped_stiffness_on_free_dofs() -> None:
    mesh = mesh_box((0.2, 0.1, 0.1), counts=(3, 2, 2))
    fixed = nodes_in_box_3d(mesh, (0.0, -1.0, -1.0, 0.0, 1.0, 1.0))
    body = ElasticBody3D(mesh, DAMPED, fixed_nodes=fixed, velocity_damping=3.0)
    rng = np.random.default_rng(3)
    x = mesh.points + 0.01 * rng.standard_normal(mesh.points.shape)
    dt, s = 1e-3, 2e-3
    layout = StepMatrixLayout3D.build(body)
    matrix = step_matrix_3d(body, x, dt, s, layout)
    free = layout.free
    expected = (sparse.diags(np.repeat(body.mass * (1.0 + dt * 3.0), 3))
                + dt * body.damping_matrix(x)
                + s * s * body.stiffness_matrix(x, clamp_compression=True)).toarray()
    expected = expected[np.ix_(free, free)]
    np.testing.assert_allclose(matrix.toarray(), expected, rtol=0.0,
                               atol=1e-12 * np.abs(expected).max())
    assert (matrix != matrix.T).nnz == 0
    assert free.size == 3 * (mesh.point_count - fixed.size)


@pytest.mark.parametrize("rule", [NewmarkFem(), MidpointFem(), EnergyMomentumFem(0.1)])
def test_response_to_a_small_force_is_the_steps_velocity_change(rule) -> None:
    # Linear case: from the rest shape at rest, a small force held over one step. The step's
    # velocity change is twice the response's mean-velocity answer.
    mesh = mesh_box((0.3, 0.05, 0.05), counts=(6, 1, 1))
    fixed = nodes_in_box_3d(mesh, (0.0, -1.0, -1.0, 0.0, 1.0, 1.0))
    body = ElasticBody3D(mesh, DAMPED, fixed_nodes=fixed)
    state = body.state()
    dt = 20.0 * body.stable_substep()
    force = np.random.default_rng(4).standard_normal((mesh.point_count, 3)) * 1e-6
    response = rule.response(body, state, dt)
    assert isinstance(response, StepResponse3D)
    out = body.state()
    rule.advance(body, state, out, dt, force, response)
    change = 2.0 * response.velocity_change(force)
    assert np.abs(change).max() > 0.0
    np.testing.assert_allclose(out.velocities, change, rtol=0.0,
                               atol=1e-6 * np.abs(change).max())
    np.testing.assert_allclose(out.positions - state.positions, 0.5 * dt * change, rtol=0.0,
                               atol=1e-6 * dt * np.abs(change).max())
    assert np.all(out.velocities[fixed] == 0.0)
    # The compliance is dt/2 A^-1 on the asked degrees of freedom, symmetric.
    dofs = np.array([3 * 20 + 2, 3 * 27, 3 * fixed[0] + 1, 3 * 13 + 1])
    compliance = response.compliance(dofs)
    unit = np.zeros((mesh.point_count, 3))
    unit[27, 0] = 1.0
    np.testing.assert_allclose(compliance[:, 1], response.velocity_change(unit).ravel()[dofs],
                               rtol=1e-12, atol=0.0)
    np.testing.assert_allclose(compliance, compliance.T, rtol=0.0, atol=1e-15)


def vibrating_block(material: MaterialStVK, amplitude: float) -> tuple[ElasticBody3D,
                                                                       BodyState]:
    mesh = mesh_box((0.1, 0.1, 0.1), counts=(2, 2, 2))
    rng = np.random.default_rng(5)
    body = ElasticBody3D(mesh, material)
    state = body.state()
    state.positions += amplitude * 0.1 * rng.standard_normal(state.positions.shape)
    state.velocities[:] = amplitude * 30.0 * rng.standard_normal(state.positions.shape)
    # No net momentum: the body vibrates about a fixed centre.
    state.velocities -= state.velocities.mean(axis=0)
    return body, state


def test_newmark_average_acceleration_keeps_the_energy_of_small_vibrations() -> None:
    # Strains of about 1e-6: the rule keeps the energy of linear vibrations exactly; the
    # strain's quadratic part makes it fluctuate by about 4 x the strain (measured 4.1e-4,
    # 4.1e-5, 4.1e-6 at amplitudes 1e-4, 1e-5, 1e-6), without drift.
    body, state = vibrating_block(MATERIAL, 1e-6)
    energy = body.total_energy(state)
    rule = NewmarkFem(0.5)
    dt = 10.0 * body.stable_substep()
    energies = []
    for k in range(200):
        rule.advance(body, state, state, dt, np.zeros_like(state.positions),
                     rule.response(body, state, dt), step=k)
        energies.append(body.total_energy(state))
    assert np.abs(np.array(energies) / energy - 1.0).max() < 1e-5
    # gamma > 1/2 damps them.
    damped = NewmarkFem(0.7)
    for _ in range(20):
        damped.advance(body, state, state, dt, np.zeros_like(state.positions),
                       damped.response(body, state, dt))
    assert body.total_energy(state) < 0.9 * energy


def spinning_block() -> tuple[ElasticBody3D, BodyState]:
    mesh = mesh_box((0.2, 0.1, 0.05), counts=(4, 2, 1))
    body = ElasticBody3D(mesh, MATERIAL)
    state = body.state()
    centre = mesh.points.mean(axis=0)
    rng = np.random.default_rng(6)
    # A fast spin about a tilted axis, a drift, and a deformation that sets it vibrating.
    state.velocities[:] = (np.cross([1.5, 10.0, 20.0], state.positions - centre)
                           + [0.3, -0.2, 0.1] + 0.05 * rng.standard_normal(state.positions.shape))
    state.positions += 0.001 * rng.standard_normal(state.positions.shape)
    return body, state


def momenta(body: ElasticBody3D, state: BodyState) -> tuple[np.ndarray, np.ndarray]:
    momentum = body.mass[:, None] * state.velocities
    return momentum.sum(axis=0), np.cross(state.positions, momentum).sum(axis=0)


@pytest.mark.parametrize("rule", [MidpointFem(1e-12, 40),
                                  EnergyMomentumFem(tolerance=1e-12, max_iterations=40)])
def test_midpoint_rules_keep_momentum_and_angular_momentum_of_a_spinning_body(rule) -> None:
    body, state = spinning_block()
    momentum, angular = momenta(body, state)
    energy = body.total_energy(state)
    # 10 x the explicit limit: 0.09 rad a step, 5.3 rad in all.
    dt = 10.0 * body.stable_substep()
    for k in range(60):
        rule.advance(body, state, state, dt, np.zeros_like(state.positions),
                     rule.response(body, state, dt), step=k)
        new_momentum, new_angular = momenta(body, state)
        np.testing.assert_allclose(new_momentum, momentum, rtol=0.0,
                                   atol=1e-9 * np.abs(momentum).max())
        np.testing.assert_allclose(new_angular, angular, rtol=0.0,
                                   atol=1e-9 * np.abs(angular).max())
    assert body.deformation_determinants(state).min() > 0.5
    if isinstance(rule, EnergyMomentumFem):
        # Simo & Tarnow: the energy too, to the Newton tolerance, in large rotations.
        assert abs(body.total_energy(state) / energy - 1.0) < 1e-7


def test_energy_momentum_keeps_the_energy_of_large_vibrations() -> None:
    # Strains of about 0.5 %, where Newmark's energy fluctuates by about 4 x the strain
    # (above), 10 x the explicit limit.
    body, state = vibrating_block(MATERIAL, 0.003)
    energy = body.total_energy(state)
    rule = EnergyMomentumFem(tolerance=1e-12, max_iterations=40)
    dt = 10.0 * body.stable_substep()
    for k in range(100):
        rule.advance(body, state, state, dt, np.zeros_like(state.positions),
                     rule.response(body, state, dt), step=k)
    assert abs(body.total_energy(state) / energy - 1.0) < 1e-7


def test_stable_far_above_the_explicit_limit() -> None:
    # A cantilever released under gravity (tip sag 0.4 % of its length) at 500 x the
    # explicit substep, its first period in 6 steps: the implicit rules stay bounded (average
    # acceleration keeps the energy, the damped ones lose it) and settle.
    mesh = mesh_box((0.3, 0.04, 0.04), counts=(8, 1, 1))
    fixed = nodes_in_box_3d(mesh, (0.0, -1.0, -1.0, 0.0, 1.0, 1.0))
    body = ElasticBody3D(mesh, MATERIAL, fixed_nodes=fixed, gravity=(0.0, -1.0, 0.0))
    dt = 500.0 * body.stable_substep()
    zero = np.zeros((mesh.point_count, 3))
    for rule in (NewmarkFem(0.5), NewmarkFem(0.6), EnergyMomentumFem(0.1)):
        state = body.state()
        start = body.total_energy(state)
        energies = []
        for k in range(60):
            rule.advance(body, state, state, dt, zero, rule.response(body, state, dt), step=k)
            energies.append(body.total_energy(state))
        assert np.all(np.isfinite(energies))
        # Never above the start (released from rest under gravity: energy only falls).
        assert max(energies) < start + 1e-6 * abs(start)
    # The damped rules end near the static state.
    static = body.state()
    static_equilibrium(body, static)
    tip = nodes_in_box_3d(mesh, (0.3, -1.0, -1.0, 0.3, 1.0, 1.0))
    sag = static.positions[tip, 1].mean() - mesh.points[tip, 1].mean()
    assert sag < 0.0
    assert abs(state.positions[tip, 1].mean() - mesh.points[tip, 1].mean() - sag) < 0.5 * abs(sag)


def test_one_rule_for_both_dimensions_checks_the_forces_shape() -> None:
    # One rule object advances a 2D and a 3D body; the forces must have the body's dimension.
    mesh = mesh_rectangle(0.2, 0.02, counts=(10, 2))
    body = ElasticBody(mesh, MATERIAL, fixed_nodes=nodes_in_box(mesh, (0.0, 0.0, 0.0, 0.02)),
                       gravity=(0.0, -9.81))
    body3d = small_block()
    dt = 1e-3
    for rule in (NewmarkFem(), MidpointFem(), EnergyMomentumFem(0.1)):
        for model, wrong in ((body, 3), (body3d, 2)):
            state = model.state()
            response = rule.response(model, state, dt)
            with pytest.raises(ValueError, match=rf"shape \({model.point_count}, {5 - wrong}\)"):
                rule.advance(model, state, state, dt, np.zeros((model.point_count, wrong)),
                             response)
            rule.advance(model, state, state, dt, np.zeros((model.point_count, 5 - wrong)),
                         response)
            assert np.all(np.isfinite(state.positions))
    with pytest.raises(ValueError, match="shape"):
        static_equilibrium(body3d, body3d.state(), np.zeros((body3d.point_count, 2)))


def test_reuse_strain_builds_every_call_for_2d_bodies() -> None:
    mesh = mesh_rectangle(0.2, 0.02, counts=(10, 2))
    body = ElasticBody(mesh, MATERIAL, fixed_nodes=nodes_in_box(mesh, (0.0, 0.0, 0.0, 0.02)))
    rule = NewmarkFem(reuse_strain=1.0)
    state = body.state()
    assert rule.response(body, state, 1e-3) is not rule.response(body, state, 1e-3)
    assert rule.factors.built == 2


@pytest.mark.parametrize(("across", "explicit_frequency", "explicit_deflection"),
                         [(2, 98.768, 39.0055e-6), (3, 89.565, 47.5419e-6)])
def test_cantilever_static_deflection_and_frequency(across: int, explicit_frequency: float,
                                                    explicit_deflection: float) -> None:
    # The validation beam (elastoflow.validation._solid3d) with 2 and 3 cells across (400
    # and 1350 tetrahedra). The explicit FEM measured on these meshes (docs/validation/
    # three_d_solid.md): locking makes them too stiff against Euler-Bernoulli, by +21 % /
    # -32 % and +10 % / -18 %. The implicit step reproduces the static deflection to 4
    # digits (measured: 39.0055, 47.5419 um) and the frequency with 40 steps a period, 100
    # and 150 x the explicit substep, 0.2 % low (measured 98.566, 89.408 Hz): average
    # acceleration lengthens the period by (omega dt)^2 / 12 = 0.2 %.
    mesh = cantilever_mesh(across)
    clamp = nodes_in_box_3d(mesh, (0.0, -SIDE, -SIDE, 0.0, SIDE, SIDE))
    tip = nodes_in_box_3d(mesh, (LENGTH, -SIDE, -SIDE, LENGTH, SIDE, SIDE))
    sagging = ElasticBody3D(mesh, STEEL, fixed_nodes=clamp, gravity=(0.0, 0.0, -9.81))
    state = sagging.state()
    static_equilibrium(sagging, state)
    deflection = mesh.points[tip, 2].mean() - state.positions[tip, 2].mean()
    assert deflection == pytest.approx(explicit_deflection, rel=1e-4)
    assert -0.35 < deflection / euler_bernoulli_deflection() - 1.0 < 0.0

    f_reference = euler_bernoulli_frequency()
    velocities = np.zeros_like(mesh.points)
    velocities[:, 2] = (1e-4 * LENGTH * 2.0 * np.pi * f_reference * mode_shape(mesh.points[:, 0])
                        / mode_shape(np.array(LENGTH)))
    body = ElasticBody3D(mesh, STEEL, fixed_nodes=clamp, velocities=velocities)
    state = body.state()
    samples = 40
    dt = 1.0 / (f_reference * 1.2 * samples)
    assert dt > 100.0 * body.stable_substep()
    rule = NewmarkFem(0.5)
    zero = np.zeros_like(mesh.points)
    count = int(2.2 * 1.2 * samples)
    tip_z = np.empty(count)
    for k in range(count):
        rule.advance(body, state, state, dt, zero, rule.response(body, state, dt), step=k)
        tip_z[k] = state.positions[tip, 2].mean() - mesh.points[tip, 2].mean()
    frequency = frequency_from_crossings(dt * np.arange(1, count + 1), tip_z)
    assert -4e-3 < frequency / explicit_frequency - 1.0 < 0.0
    assert 0.0 < frequency / f_reference - 1.0 < 0.25


@pytest.mark.parametrize("rule_class", [NewmarkFem, EnergyMomentumFem])
def test_reused_factor_gives_the_same_steps(rule_class) -> None:
    # A vibrating cantilever (tip speed 2 mm/s) at 50 x the explicit substep: reusing the
    # factor while strains move by less than 3e-4 changes Newton's path, not the step it
    # converges to.
    mesh = mesh_box((0.3, 0.04, 0.04), counts=(8, 1, 1))
    fixed = nodes_in_box_3d(mesh, (0.0, -1.0, -1.0, 0.0, 1.0, 1.0))
    velocities = np.zeros_like(mesh.points)
    velocities[:, 1] = 0.002 * mesh.points[:, 0] ** 2 / 0.09
    body = ElasticBody3D(mesh, DAMPED, fixed_nodes=fixed, velocities=velocities)
    dt = 50.0 * body.stable_substep()
    zero = np.zeros_like(mesh.points)
    fresh = rule_class(tolerance=1e-13, max_iterations=40)
    reusing = rule_class(tolerance=1e-13, max_iterations=40, reuse_strain=3e-4)
    a, b = body.state(), body.state()
    for k in range(40):
        fresh.advance(body, a, a, dt, zero, fresh.response(body, a, dt), step=k)
        reusing.advance(body, b, b, dt, zero, reusing.response(body, b, dt), step=k)
    assert np.abs(a.positions - mesh.points).max() > 1e-5
    np.testing.assert_allclose(b.positions, a.positions, rtol=0.0, atol=1e-13)
    np.testing.assert_allclose(b.velocities, a.velocities, rtol=0.0, atol=1e-10)
    assert fresh.factors.built == 40
    # Measured: 7 factorizations in 40 steps.
    assert 1 < reusing.factors.built < 12
    # The reused response is the one built: same object while the strain stays put.
    assert reusing.response(body, b, dt) is reusing.response(body, b, dt)
    assert reusing.response(body, b, 2.0 * dt) is not reusing.response(body, b, dt)


@pytest.mark.parametrize("factor", ["dense", "banded", "superlu"])
def test_every_factor_solves_the_step_matrix(factor, monkeypatch) -> None:
    import scipy.sparse.linalg as sparse_linalg

    import elastoflow.solid._implicit3d as implicit3d

    if factor == "dense":
        monkeypatch.setattr(implicit3d, "_DENSE_LIMIT_3D", 10**6)
    elif factor == "superlu":
        monkeypatch.setattr(implicit3d, "_banded_cholesky", lambda matrix, work_limit: None)
    mesh = mesh_box((0.3, 0.1, 0.1), counts=(6, 3, 3))
    fixed = nodes_in_box_3d(mesh, (0.0, -1.0, -1.0, 0.0, 1.0, 1.0))
    body = ElasticBody3D(mesh, DAMPED, fixed_nodes=fixed)
    rng = np.random.default_rng(7)
    positions = mesh.points + 0.003 * rng.standard_normal(mesh.points.shape)
    dt = 1e-3
    response = body.response_at(positions, dt, 2.0 * dt, 0.5 * dt)
    assert isinstance(response, StepResponse3D)
    assert (response._inverse is not None) == (factor == "dense")
    assert (response._banded is not None) == (factor == "banded")
    assert (response._factor is not None) == (factor == "superlu")
    layout = StepMatrixLayout3D.build(body)
    matrix = step_matrix_3d(body, positions, dt, 2.0 * dt, layout)
    force = rng.standard_normal(mesh.points.shape)
    expected = np.zeros(force.size)
    expected[layout.free] = sparse_linalg.spsolve(matrix.tocsc(), force.ravel()[layout.free])
    scale = np.abs(expected).max()
    np.testing.assert_allclose(response.solve(force).ravel(), expected, rtol=0.0,
                               atol=1e-10 * scale)
    np.testing.assert_allclose(response.velocity_change(force).ravel(), 0.5 * dt * expected,
                               rtol=0.0, atol=1e-10 * dt * scale)
    dofs = np.array([5, 3 * fixed[1], 100, 7, 250])
    compliance = response.compliance(dofs)
    unit = np.zeros(force.size)
    unit[100] = 1.0
    column = np.zeros(force.size)
    column[layout.free] = sparse_linalg.spsolve(matrix.tocsc(), unit[layout.free])
    np.testing.assert_allclose(compliance[:, 2], 0.5 * dt * column[dofs], rtol=1e-9,
                               atol=1e-12 * np.abs(column).max() * dt)
    np.testing.assert_allclose(compliance, compliance.T, rtol=0.0,
                               atol=1e-12 * np.abs(compliance).max())
    assert np.all(compliance[1] == 0.0)
