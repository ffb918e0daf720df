"""Wall contact of 2D bodies: the per-node kernels, the held response, the held implicit step."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow.solid import (
    ElasticBody,
    EnergyMomentumFem,
    HeldResponse,
    MaterialStVK,
    WallBox,
    WallContact,
    hold_response,
    mesh_rectangle,
    project_onto_box,
    wall_hold,
)

BOX = WallBox((0.0, 0.0), (1.0, 2.0), (True, True, True, True))


def test_node_below_floor_is_projected_onto_it_and_loses_its_normal_velocity():
    positions = np.array([[0.5, -0.01], [0.5, 0.3]])
    velocities = np.array([[0.2, -1.0], [0.2, -1.0]])
    moved = project_onto_box(BOX, positions, velocities, np.zeros(2, bool), 0.0, 0.5)
    assert moved == 1
    assert positions[0].tolist() == [0.5, 0.0]
    assert velocities[0].tolist() == [0.2, 0.0]  # tangential kept without friction
    assert positions[1].tolist() == [0.5, 0.3] and velocities[1].tolist() == [0.2, -1.0]


def test_coulomb_friction_removes_mu_times_the_normal_change_and_never_reverses():
    positions = np.array([[0.5, -0.01], [0.5, -0.01], [-0.1, 1.0]])
    velocities = np.array([[0.5, -1.0], [-0.05, -1.0], [-2.0, 0.3]])
    project_onto_box(BOX, positions, velocities, np.zeros(3, bool), 0.3, 0.5)
    # 0.5 - 0.3 * 1.0; the position follows by 0.5 s per m/s of tangential change.
    assert velocities[0].tolist() == pytest.approx([0.2, 0.0], abs=1e-15)
    assert positions[0].tolist() == pytest.approx([0.5 - 0.5 * 0.3, 0.0], abs=1e-15)
    assert velocities[1].tolist() == [0.0, 0.0]  # stuck: friction exceeds |v_t|
    # Left wall: normal change 2, friction up to 0.6 stops the tangential 0.3.
    assert positions[2].tolist() == pytest.approx([0.0, 1.0 - 0.5 * 0.3], abs=1e-15)
    assert velocities[2].tolist() == [0.0, 0.0]


def test_every_side_and_corners_and_node_moving_away_keeps_its_velocity():
    positions = np.array([[1.2, 2.5], [-0.3, -0.2], [0.5, -0.1]])
    velocities = np.array([[1.0, 1.0], [-1.0, -1.0], [0.0, 0.7]])
    project_onto_box(BOX, positions, velocities, np.zeros(3, bool), 0.0, 0.5)
    assert positions.tolist() == [[1.0, 2.0], [0.0, 0.0], [0.5, 0.0]]
    assert velocities.tolist() == [[0.0, 0.0], [0.0, 0.0], [0.0, 0.7]]


def test_open_sides_and_fixed_nodes_are_left_alone():
    box = WallBox((0.0, 0.0), (1.0, 2.0), (False, False, True, True))
    positions = np.array([[-0.2, 0.5], [0.5, -0.2]])
    velocities = np.array([[-1.0, 0.0], [0.0, -1.0]])
    project_onto_box(box, positions, velocities, np.array([False, True]), 0.3, 0.5)
    assert positions.tolist() == [[-0.2, 0.5], [0.5, -0.2]]
    assert velocities.tolist() == [[-1.0, 0.0], [0.0, -1.0]]


def test_hold_marks_components_pressing_on_a_wall_with_their_reaction_impulse():
    positions = np.array([[0.5, 0.0], [0.5, 0.0], [0.5, 0.0], [0.5, 0.1], [1.0, 1.0]])
    velocities = np.array([[0.0, 0.0], [0.0, 0.0], [0.0, 0.2], [0.0, 0.0], [0.0, 0.0]])
    forces = np.array([[1.0, -4.0], [0.0, 3.0], [0.0, -4.0], [0.0, -4.0], [2.0, 0.0]])
    mass = np.full(5, 2.0)
    hold = wall_hold(BOX, positions, velocities, forces, mass, np.zeros(5, bool), 0.1)
    assert hold.count == 2
    assert hold.held.tolist() == [[False, True], [False, False], [False, False],
                                  [False, False], [True, False]]
    assert hold.impulse[0].tolist() == [0.0, pytest.approx(0.2)]
    assert hold.impulse[4].tolist() == [pytest.approx(0.1), 0.0]


def test_wall_contact_refuses_negative_friction():
    with pytest.raises(ValueError, match="friction"):
        WallContact(friction=-0.1)


def _body(gravity=(0.0, -9.81)):
    mesh = mesh_rectangle(0.2, 0.1, counts=(6, 3), origin=(0.1, 0.0))
    return ElasticBody(mesh, MaterialStVK(2000.0, 1e6, 0.3), gravity=gravity)


def test_held_response_equals_the_matrix_without_the_held_rows():
    body = _body()
    state = body.state()
    response = body.response_at(state.positions, 1e-3)
    held = np.zeros((body.point_count, 2), bool)
    held[state.positions[:, 1] == 0.0, 1] = True
    constrained = HeldResponse(response, held)
    force = np.random.default_rng(0).normal(size=(body.point_count, 2))
    change = constrained.velocity_change(force)
    assert np.all(change[held] == 0.0)
    # Against the dense matrix with the held rows and columns removed.
    size = 2 * body.point_count
    matrix = np.linalg.inv(np.column_stack([
        response.solve(np.eye(size)[k].reshape(-1, 2)).reshape(-1) for k in range(size)]))
    free = np.flatnonzero(~held.reshape(-1))
    expected = np.zeros(size)
    expected[free] = 1e-3 * np.linalg.solve(matrix[np.ix_(free, free)],
                                            force.reshape(-1)[free])
    assert np.allclose(change.reshape(-1), expected, rtol=1e-9, atol=1e-15)
    dofs = np.arange(0, size, 3)
    compliance = constrained.compliance(dofs)
    columns = np.column_stack([constrained.velocity_change(np.eye(size)[k].reshape(-1, 2))
                               .reshape(-1) for k in dofs])
    assert np.allclose(compliance, columns[dofs], rtol=1e-9, atol=1e-15)
    assert hold_response(response, np.zeros_like(held)) is response


def test_body_on_the_floor_held_by_the_implicit_step_stays_on_it_at_rest():
    body = _body()
    state = body.state()
    rule = EnergyMomentumFem(0.1)
    box = WallBox((0.0, 0.0), (1.0, 1.0), (True, True, True, True))
    dt = 1e-3
    energies = []
    for _ in range(200):
        forces = body.forces_at(state.positions, state.velocities) + body.mass[:, None] * body.gravity
        hold = wall_hold(box, state.positions, state.velocities, forces, body.mass,
                         body.fixed_mask, dt)
        response = hold_response(rule.response(body, state, dt), hold.held)
        rule.advance(body, state, state, dt, np.zeros_like(state.positions), response,
                     hold=hold.held)
        project_onto_box(box, state.positions, state.velocities, body.fixed_mask, 0.3,
                         0.0, hold.impulse)
        assert state.positions[:, 1].min() >= 0.0
        energies.append(0.5 * float((body.mass[:, None] * state.velocities ** 2).sum())
                        + float(body.elastic_energy(state))
                        - float(body.mass @ state.positions[:, 1]) * body.gravity[1])
    # Settles under its weight (vibrating, damped by the rule's 0.1 dt): the energy only
    # falls.
    assert np.all(np.diff(energies) <= 1e-13 * abs(energies[0]))
    assert energies[-1] < energies[0]
    assert state.positions[:, 1].min() == 0.0


# -- 3D: the same kernels on (n, 3) nodal arrays ----------------------------------------------

BOX_3D = WallBox((0.0, 0.0, 0.0), (1.0, 2.0, 1.5), (True,) * 6)


def test_3d_node_beyond_each_side_is_put_back_and_loses_its_normal_velocity():
    positions = np.array([[-0.1, 1.0, 0.5], [1.1, 1.0, 0.5], [0.5, -0.1, 0.5],
                          [0.5, 2.1, 0.5], [0.5, 1.0, -0.1], [0.5, 1.0, 1.6],
                          [1.2, -0.3, 1.7], [0.5, 1.0, 0.7]])
    velocities = np.array([[-1.0, 0.2, 0.3], [1.0, 0.2, 0.3], [0.2, -1.0, 0.3],
                           [0.2, 1.0, 0.3], [0.2, 0.3, -1.0], [0.2, 0.3, 1.0],
                           [1.0, -1.0, 1.0], [0.4, -0.5, 0.6]])
    moved = project_onto_box(BOX_3D, positions, velocities, np.zeros(8, bool), 0.0, 0.5)
    assert moved == 9  # the corner node counts once per wall
    assert positions.tolist() == [[0.0, 1.0, 0.5], [1.0, 1.0, 0.5], [0.5, 0.0, 0.5],
                                  [0.5, 2.0, 0.5], [0.5, 1.0, 0.0], [0.5, 1.0, 1.5],
                                  [1.0, 0.0, 1.5], [0.5, 1.0, 0.7]]
    assert velocities.tolist() == [[0.0, 0.2, 0.3], [0.0, 0.2, 0.3], [0.2, 0.0, 0.3],
                                   [0.2, 0.0, 0.3], [0.2, 0.3, 0.0], [0.2, 0.3, 0.0],
                                   [0.0, 0.0, 0.0], [0.4, -0.5, 0.6]]


def test_3d_friction_shortens_the_velocity_in_the_walls_plane_keeping_its_direction():
    # Floor: normal change 1; friction 0.3 takes 0.3 off the length 0.5 of (0.3, 0, -0.4).
    positions = np.array([[0.5, -0.01, 0.5], [0.5, -0.01, 0.5]])
    velocities = np.array([[0.3, -1.0, -0.4], [0.03, -1.0, 0.04]])
    project_onto_box(BOX_3D, positions, velocities, np.zeros(2, bool), 0.3, 0.5)
    assert velocities[0] == pytest.approx([0.12, 0.0, -0.16], abs=1e-15)
    assert positions[0] == pytest.approx([0.5 - 0.5 * 0.18, 0.0, 0.5 + 0.5 * 0.24], abs=1e-15)
    assert velocities[1].tolist() == [0.0, 0.0, 0.0]  # stuck: friction exceeds |v_t|
    # The held reaction counts too, on a node that did not cross.
    positions = np.array([[0.5, 0.0, 0.5]])
    velocities = np.array([[0.0, 0.0, 0.5]])
    impulse = np.array([[0.0, 1.0, 0.0]])
    project_onto_box(BOX_3D, positions, velocities, np.zeros(1, bool), 0.3, 0.0, impulse)
    assert velocities[0] == pytest.approx([0.0, 0.0, 0.2], abs=1e-15)


def test_3d_hold_marks_pressing_components_on_any_wall():
    positions = np.array([[0.5, 0.0, 0.5], [0.5, 0.0, 0.5], [0.5, 1.0, 1.5],
                          [0.5, 1.0, 0.7]])
    velocities = np.zeros((4, 3))
    forces = np.array([[1.0, -2.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0],
                       [0.0, -1.0, 0.0]])
    mass = np.array([1.0, 1.0, 2.0, 1.0])
    hold = wall_hold(BOX_3D, positions, velocities, forces, mass, np.zeros(4, bool), 0.1)
    assert hold.count == 2
    assert hold.held.tolist() == [[False, True, False], [False, False, False],
                                  [False, False, True], [False, False, False]]
    assert hold.impulse[0, 1] == pytest.approx(0.2) and hold.impulse[2, 2] == pytest.approx(0.15)


def test_2d_walls_refuse_3d_nodes_and_boxes_check_their_sizes():
    with pytest.raises(ValueError, match="3D"):
        wall_hold(BOX_3D, np.zeros((1, 2)), np.zeros((1, 2)), np.zeros((1, 2)), np.ones(1),
                  np.zeros(1, bool), 0.1)
    with pytest.raises(ValueError, match="2D"):
        project_onto_box(BOX, np.zeros((1, 3)), np.zeros((1, 3)), np.zeros(1, bool), 0.0, 0.0)
    with pytest.raises(ValueError, match="sides"):
        WallBox((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), (True,) * 4)
    assert BOX_3D.size == 2.0 and BOX_3D.dimension == 3
    assert BOX_3D.near(np.array([[0.5, 1.0, 1.49]]), 0.02)
    assert not BOX_3D.near(np.array([[0.5, 1.0, 1.4]]), 0.02)
