"""The body's implicit step and its linear answer to a force (the strongly coupled scheme)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import sparse

from elastoflow.solid import (
    BodyState,
    ElasticBody,
    MaterialStVK,
    NewmarkFem,
    mesh_rectangle,
    nodes_in_box,
)
from elastoflow.solid._response import response_triplets

MATERIAL = MaterialStVK(1000.0, 1.0e5, 0.3)


def _tangent(body: ElasticBody, body_state: BodyState) -> np.ndarray:
    mesh, m = body.mesh, body.material
    count = 36 * mesh.triangle_count
    rows = np.empty(count, np.int64)
    cols = np.empty(count, np.int64)
    values = np.empty(count)
    response_triplets(body_state.positions, mesh.triangles, body.dm_inverse, body.rest_area,
                      m.lame_lambda, m.lame_mu, m.lame_lambda, m.lame_mu, 1.0, rows, cols, values)
    size = 2 * mesh.point_count
    return sparse.coo_matrix((values, (rows, cols)), shape=(size, size)).toarray()


def test_tangent_stiffness_is_the_derivative_of_the_internal_forces() -> None:
    """Under stretch (no compressive stress to clamp) the assembled K is -d f / d x."""
    mesh = mesh_rectangle(0.1, 0.3, counts=(2, 4))
    body = ElasticBody(mesh, MATERIAL)
    body_state = body.state()
    rng = np.random.default_rng(1)
    body_state.positions[:] = mesh.points @ np.diag([1.1, 1.2]) + 1e-4 * rng.standard_normal(
        mesh.points.shape)
    stiffness = _tangent(body, body_state)
    start = body_state.positions.copy()
    numeric = np.zeros_like(stiffness)
    eps = 1e-7
    for k in range(stiffness.shape[1]):
        body_state.positions[:] = start
        body_state.positions.reshape(-1)[k] += eps
        plus = body.internal_forces(body_state).reshape(-1)
        body_state.positions.reshape(-1)[k] -= 2 * eps
        minus = body.internal_forces(body_state).reshape(-1)
        numeric[:, k] = -(plus - minus) / (2 * eps)
    assert np.abs(stiffness - numeric).max() < 1e-6 * np.abs(numeric).max()
    assert np.allclose(stiffness, stiffness.T, atol=1e-9 * np.abs(stiffness).max())


def test_tangent_stays_positive_semidefinite_under_compression() -> None:
    mesh = mesh_rectangle(0.1, 0.3, counts=(2, 4))
    body = ElasticBody(mesh, MATERIAL)
    body_state = body.state()
    body_state.positions[:] = mesh.points @ np.array([[0.7, 0.1], [0.05, 0.8]])
    eigenvalues = np.linalg.eigvalsh(0.5 * (_tangent(body, body_state) + _tangent(body, body_state).T))
    assert eigenvalues.min() > -1e-9 * eigenvalues.max()


def test_response_to_a_uniform_force_is_rigid_translation() -> None:
    """K and D vanish on rigid motion: a force proportional to the masses moves every node
    alike, dv = dt f / m, whatever the deformation."""
    mesh = mesh_rectangle(0.1, 0.3, counts=(3, 6))
    body = ElasticBody(mesh, MaterialStVK(800.0, 1e6, 0.3, damping_mu=5.0))
    body_state = body.state()
    body_state.positions[:] = mesh.points @ np.array([[1.05, 0.02], [0.0, 0.97]])
    dt = 0.01
    force = body.mass[:, None] * np.array([2.0, -3.0])
    change = body.step_response(body_state, dt).velocity_change(force)
    assert np.allclose(change, dt * np.array([2.0, -3.0]), rtol=1e-9, atol=1e-12)


def test_held_nodes_do_not_answer_and_compliance_is_symmetric() -> None:
    mesh = mesh_rectangle(0.1, 0.3, counts=(2, 6))
    fixed = nodes_in_box(mesh, (-1.0, 0.29, 1.0, 1.0))
    body = ElasticBody(mesh, MATERIAL, fixed_nodes=fixed)
    body_state = body.state()
    response = body.step_response(body_state, 0.005)
    rng = np.random.default_rng(2)
    change = response.velocity_change(rng.standard_normal(mesh.points.shape))
    assert np.all(change[fixed] == 0.0)
    dofs = np.arange(2 * mesh.point_count)
    compliance = response.compliance(dofs)
    assert np.allclose(compliance, compliance.T)
    assert np.linalg.eigvalsh(compliance).min() > -1e-12
    force = rng.standard_normal(mesh.points.shape)
    assert np.allclose(compliance @ force.reshape(-1), response.velocity_change(force).reshape(-1))


def test_newmark_step_is_exact_for_free_fall() -> None:
    mesh = mesh_rectangle(0.1, 0.1, counts=(2, 2))
    body = ElasticBody(mesh, MATERIAL, gravity=(0.0, -9.81), velocities=np.tile([1.0, 0.5],
                                                                                (9, 1)))
    body_state = body.state()
    dt = 0.02
    start = body_state.positions.copy()
    NewmarkFem().advance(body, body_state, body_state, dt, np.zeros_like(start),
                         NewmarkFem().response(body, body_state, dt))
    assert np.allclose(body_state.positions - start, [1.0 * dt, 0.5 * dt - 0.5 * 9.81 * dt * dt])
    assert np.allclose(body_state.velocities, [1.0, 0.5 - 9.81 * dt])


@pytest.mark.parametrize("dt", [1e-3, 2e-2])
def test_newmark_keeps_the_energy_of_a_free_vibration(dt: float) -> None:
    """The average-acceleration rule conserves the energy of a linear system at any step; for
    a small StVK vibration the energy drifts by well under 1 % over 200 steps, also at a
    step 20x past the explicit substep (2e-2 s against 9e-4 s)."""
    mesh = mesh_rectangle(0.05, 0.3, counts=(2, 8))
    fixed = nodes_in_box(mesh, (-1.0, -1.0, 1.0, 1e-9))
    body = ElasticBody(mesh, MATERIAL, fixed_nodes=fixed)
    body_state = body.state()
    body_state.velocities[:, 0] = 0.05 * mesh.points[:, 1] / 0.3
    body_state.velocities[fixed] = 0.0
    energy = body.total_energy(body_state)
    for _ in range(200):
        fem = NewmarkFem()
        fem.advance(body, body_state, body_state, dt, np.zeros_like(body_state.positions),
                    fem.response(body, body_state, dt))
    assert abs(body.total_energy(body_state) - energy) < 5e-3 * energy


def _take_path(path: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Make the step response take one factorization: "dense", "banded_layout" (the
    default), "banded" (the general path's banded Cholesky) or "sparse_lu"."""
    from elastoflow.solid import _response

    if path != "banded_layout":
        monkeypatch.setattr(_response, "_DENSE_BELOW", 10**9)
    if path in ("banded", "sparse_lu"):
        monkeypatch.setattr(_response, "_DENSE_LIMIT", 0)
    if path == "sparse_lu":
        monkeypatch.setattr(_response, "_BANDED_WORK_LIMIT", 0.0)


@pytest.mark.parametrize("path", ["dense", "banded_layout", "banded", "sparse_lu"])
def test_every_factorization_gives_the_same_answer(path: str,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """Dense inverse (small bodies), the banded Cholesky assembled through the body's banded
    layout (the default above ``_DENSE_BELOW`` free dofs), the banded Cholesky of the general
    path and SuperLU agree to round-off on solve, velocity_change and compliance."""
    from elastoflow.solid import _response

    mesh = mesh_rectangle(0.35, 0.02, counts=(35, 2), pattern="crossed")
    fixed = nodes_in_box(mesh, (-1.0, -1.0, 1e-9, 1.0))

    def response_of(body_state_positions: np.ndarray) -> _response.StepResponse:
        body = ElasticBody(mesh, MATERIAL, fixed_nodes=fixed)
        body_state = body.state()
        body_state.positions[:] = body_state_positions
        return body.step_response(body_state, 0.005)

    positions = mesh.points @ np.array([[1.01, 0.03], [0.0, 0.99]])
    with monkeypatch.context() as patch:
        patch.setattr(_response, "_DENSE_BELOW", 10**9)
        reference = response_of(positions)
    assert reference._inverse is not None
    _take_path(path, monkeypatch)
    response = response_of(positions)
    assert (response._banded is not None) == path.startswith("banded")
    assert (response._factor is not None) == (path == "sparse_lu")
    rng = np.random.default_rng(3)
    force = rng.standard_normal(mesh.points.shape)
    scale = np.abs(reference.solve(force)).max()
    assert np.abs(response.solve(force) - reference.solve(force)).max() < 1e-10 * scale
    assert np.allclose(response.velocity_change(force), reference.velocity_change(force),
                       rtol=1e-9, atol=1e-12 * scale)
    dofs = np.flatnonzero(rng.random(2 * mesh.point_count) < 0.3)
    assert np.allclose(response.compliance(dofs), reference.compliance(dofs), rtol=1e-9,
                       atol=1e-12 * np.abs(reference.compliance(dofs)).max())
    factor = response.compliance_factor(dofs)
    assert (factor is not None) == path.startswith("banded")
    if factor is not None:
        # The factor's inverse, read at the dofs' positions, is the compliance; held dofs
        # have no position.
        columns, rows, positions = factor
        inverse = np.zeros((columns.shape[0], columns.shape[0]))
        for i in range(columns.shape[0]):
            inverse[i, i:i + rows.shape[1]] = rows[i, : columns.shape[0] - i]
        inverse = np.linalg.inv(inverse.T @ inverse)
        movable = positions >= 0
        held = np.zeros(mesh.point_count, bool)
        held[fixed] = True
        assert np.all(movable == ~np.repeat(held, 2)[dofs])
        expected = reference.compliance(dofs)[np.ix_(movable, movable)]
        got = inverse[np.ix_(positions[movable], positions[movable])]
        assert np.allclose(got, expected, rtol=1e-9, atol=1e-12 * np.abs(expected).max())


@pytest.mark.parametrize("path", ["dense", "banded_layout", "banded", "sparse_lu"])
def test_nodal_damping_blocks_enter_the_step_matrix_on_every_path(
        path: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """``response_at(..., nodal_damping=C)`` factors ``A + dt blockdiag(C)`` (the viscous
    traction's dependence on the body's velocity, `simulation._schemes._viscous_damping`),
    held nodes left out, on each factorization path: the difference of the two answers'
    inverses is ``dt C`` on the free degrees of freedom."""
    mesh = mesh_rectangle(0.35, 0.02, counts=(35, 2), pattern="crossed")
    fixed = nodes_in_box(mesh, (-1.0, -1.0, 1e-9, 1.0))
    _take_path(path, monkeypatch)
    rng = np.random.default_rng(5)
    blocks = rng.standard_normal((mesh.point_count, 2, 2))
    blocks = np.einsum("nab,ncb->nac", blocks, blocks)
    dt = 0.005
    body = ElasticBody(mesh, MATERIAL, fixed_nodes=fixed)
    positions = mesh.points @ np.array([[1.01, 0.03], [0.0, 0.99]])
    plain = body.response_at(positions, dt)
    damped = body.response_at(positions, dt, nodal_damping=blocks)
    assert (damped._banded is not None) == path.startswith("banded")
    free = np.flatnonzero(~np.repeat(np.isin(np.arange(mesh.point_count), fixed), 2))
    compliance = [response.compliance(free) / dt for response in (plain, damped)]
    difference = np.linalg.inv(compliance[1]) - np.linalg.inv(compliance[0])
    expected = dt * sparse.block_diag(list(blocks)).toarray()[np.ix_(free, free)]
    assert np.abs(difference - expected).max() < 1e-7 * np.abs(expected).max()


def _spinning_vibrating_disc(density: float) -> tuple[ElasticBody, BodyState]:
    from elastoflow.solid import mesh_from_polygon

    angles = np.linspace(0.0, 2.0 * np.pi, 48, endpoint=False)
    outline = 0.1 * np.column_stack([np.cos(angles), np.sin(angles)])
    mesh = mesh_from_polygon(outline, element_size=0.03)
    radius = mesh.points - mesh.points.mean(axis=0)
    spin = 2.0 * np.column_stack([-radius[:, 1], radius[:, 0]])
    shake = 0.05 * np.random.default_rng(4).standard_normal(radius.shape)
    body = ElasticBody(mesh, MaterialStVK(density, 1e6, 0.3), velocities=spin + shake)
    return body, body.state()


def _angular_momentum(body: ElasticBody, state: BodyState) -> float:
    x, v = state.positions, state.velocities
    return float(np.sum(body.mass * (x[:, 0] * v[:, 1] - x[:, 1] * v[:, 0])))


def test_midpoint_rule_keeps_linear_and_angular_momentum_exactly() -> None:
    """A free disc spinning at 2 rad/s and shaken at 5 cm/s (stiff modes far past the step:
    omega dt ~ 50): the implicit midpoint rule keeps both momenta to the Newton tolerance
    over 100 steps (measured 1.2e-7 relative); Newmark's rule with forces at the ends changes
    the angular momentum by 3.7e-4 (gamma 0.55), the drift that spins up discs in a fluid."""
    from elastoflow.solid import MidpointFem

    dt = 0.005
    for fem, bound in ((MidpointFem(), 1e-6), (NewmarkFem(0.55), None)):
        body, state = _spinning_vibrating_disc(30.0)
        momentum = body.mass @ state.velocities
        spin = _angular_momentum(body, state)
        for _ in range(100):
            fem.advance(body, state, state, dt, np.zeros_like(state.positions),
                        fem.response(body, state, dt))
        np.testing.assert_allclose(body.mass @ state.velocities, momentum, atol=1e-10)
        change = abs(_angular_momentum(body, state) - spin) / abs(spin)
        if bound is not None:
            assert change < bound, change
        else:
            assert change > 1e-4, "Newmark's rule was expected to drift"


def test_midpoint_rule_answers_a_held_force_like_average_acceleration() -> None:
    """Its `response` is Newmark's average-acceleration matrix, and a linear step (small
    displacements) moves the mean velocity by exactly ``dt/2 A^-1 f``."""
    from elastoflow.solid import MidpointFem

    mesh = mesh_rectangle(0.05, 0.3, counts=(2, 8))
    fixed = nodes_in_box(mesh, (-1.0, -1.0, 1.0, 1e-9))
    body = ElasticBody(mesh, MATERIAL, fixed_nodes=fixed)
    state = body.state()
    dt = 0.01
    midpoint, newmark = MidpointFem(), NewmarkFem(0.5)
    force = np.zeros_like(state.positions)
    force[-1] = [1e-4, 0.0]
    np.testing.assert_allclose(midpoint.response(body, state, dt).velocity_change(force),
                               newmark.response(body, state, dt).velocity_change(force))
    out = body.state()
    midpoint.advance(body, state, out, dt, force, midpoint.response(body, state, dt))
    mean = (out.positions - state.positions) / dt
    expected = midpoint.response(body, state, dt).velocity_change(force)
    np.testing.assert_allclose(mean, expected, rtol=1e-5, atol=1e-5 * np.abs(expected).max())


def test_energy_momentum_rule_keeps_energy_and_both_momenta() -> None:
    """The spinning, shaken disc with large rotations (omega dt ~ 50 in its stiff modes): the
    energy-momentum rule keeps the total energy and both momenta to the Newton tolerance over
    200 steps (measured 2.2e-10 relative); the plain midpoint rule keeps the momenta but not
    the energy (5.7e-3: its midpoint stress is not the mean of the ends)."""
    from elastoflow.solid import EnergyMomentumFem, MidpointFem

    dt = 0.005
    drift = {}
    for fem in (EnergyMomentumFem(tolerance=1e-13), MidpointFem(tolerance=1e-13)):
        body, state = _spinning_vibrating_disc(30.0)
        energy = body.total_energy(state)
        momentum = body.mass @ state.velocities
        spin = _angular_momentum(body, state)
        for _ in range(200):
            fem.advance(body, state, state, dt, np.zeros_like(state.positions),
                        fem.response(body, state, dt))
        np.testing.assert_allclose(body.mass @ state.velocities, momentum, atol=1e-10)
        assert abs(_angular_momentum(body, state) - spin) < 1e-7 * abs(spin)
        drift[type(fem).__name__] = abs(body.total_energy(state) - energy) / energy
    assert drift["EnergyMomentumFem"] < 1e-8, drift
    assert drift["MidpointFem"] > 100 * drift["EnergyMomentumFem"], drift
