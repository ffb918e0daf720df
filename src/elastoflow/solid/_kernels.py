"""Numba kernels of the solid layer: mesh topology helpers and the explicit FEM substeps.

Index spaces: ``points``/``positions``/``velocities``/``mass`` are per node ``(n, ...)``;
``triangles``/``dm_inverse``/``rest_area`` are per element ``(m, ...)``.

The substep kernels run every substep of one ``advance`` call inside compiled code, so that a
small mesh (a few hundred triangles, tens of substeps per fluid step) pays no Python overhead per
substep. They return a status instead of raising, because Numba cannot raise rich exceptions:
``status[0]`` is 1 when a bad element was found, ``status[1]`` the number of substeps completed
when it was found (0: the state before the first substep), ``status[2]`` the element, and
``determinant[0]`` its det F.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from elastoflow import _numba  # noqa: F401  (starts Numba's threads: see _numba)

# Element count from which the threaded substep kernel is the default. Its two thread launches
# per substep cost more than they save on smaller meshes, and far more on a loaded machine
# (measured on a shared 2-core box: 200 elements 4 us serial vs 2.6 ms threaded per substep).
PARALLEL_ELEMENT_THRESHOLD = 20000


@njit(cache=True)
def chain_boundary_loops(
    edge_start: np.ndarray, edge_end: np.ndarray, point_count: int
) -> tuple[np.ndarray, np.ndarray, int, int]:
    """Chain directed boundary edges ``a -> b`` into closed loops.

    Returns:
        ``(order, loop_offsets, error_code, error_vertex)``: ``order`` holds the loop vertices
        one after another, loop ``k`` being ``order[loop_offsets[k]:loop_offsets[k+1]]``.
        ``error_code`` 0: fine; 1: ``error_vertex`` starts two boundary edges (two loops touch
        at one vertex); 2: the loop through ``error_vertex`` does not close.
    """
    edge_count = edge_start.shape[0]
    successor = np.full(point_count, -1, np.int64)
    for e in range(edge_count):
        a = edge_start[e]
        if successor[a] != -1:
            return np.zeros(0, np.int64), np.zeros(1, np.int64), 1, a
        successor[a] = edge_end[e]
    visited = np.zeros(point_count, np.bool_)
    order = np.empty(edge_count, np.int64)
    offsets = np.empty(edge_count + 1, np.int64)
    offsets[0] = 0
    loop_count = 0
    filled = 0
    for e in range(edge_count):
        start = edge_start[e]
        if visited[start]:
            continue
        vertex = start
        while True:
            visited[vertex] = True
            order[filled] = vertex
            filled += 1
            nxt = successor[vertex]
            if nxt == -1:
                return np.zeros(0, np.int64), np.zeros(1, np.int64), 2, vertex
            if nxt == start:
                break
            if visited[nxt]:
                return np.zeros(0, np.int64), np.zeros(1, np.int64), 2, vertex
            vertex = nxt
        loop_count += 1
        offsets[loop_count] = filled
    return order[:filled], offsets[: loop_count + 1], 0, -1


@njit(cache=True)
def _segments_cross(
    ax: float, ay: float, bx: float, by: float, cx: float, cy: float, dx: float, dy: float
) -> bool:
    """Closed segments ab and cd intersect (touching and collinear overlap included)."""
    d1 = (dx - cx) * (ay - cy) - (dy - cy) * (ax - cx)
    d2 = (dx - cx) * (by - cy) - (dy - cy) * (bx - cx)
    d3 = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
    d4 = (bx - ax) * (dy - ay) - (by - ay) * (dx - ax)
    if ((d1 > 0.0 and d2 < 0.0) or (d1 < 0.0 and d2 > 0.0)) and (
        (d3 > 0.0 and d4 < 0.0) or (d3 < 0.0 and d4 > 0.0)
    ):
        return True
    if d1 == 0.0 and min(cx, dx) <= ax <= max(cx, dx) and min(cy, dy) <= ay <= max(cy, dy):
        return True
    if d2 == 0.0 and min(cx, dx) <= bx <= max(cx, dx) and min(cy, dy) <= by <= max(cy, dy):
        return True
    if d3 == 0.0 and min(ax, bx) <= cx <= max(ax, bx) and min(ay, by) <= cy <= max(ay, by):
        return True
    return bool(d4 == 0.0 and min(ax, bx) <= dx <= max(ax, bx) and min(ay, by) <= dy <= max(ay, by))


@njit(cache=True)
def first_segment_intersection(
    starts: np.ndarray, ends: np.ndarray, loop_id: np.ndarray, previous: np.ndarray,
    following: np.ndarray,
) -> tuple[int, int]:
    """First pair of segments that intersect other than at a shared polygon vertex.

    Args:
        starts, ends: Segment end points [m], shape (k, 2).
        loop_id: Polygon of each segment, shape (k,).
        previous, following: Index of the segment before / after each one in its polygon,
            shape (k,); those neighbours share one vertex and are only checked for overlap.

    Returns:
        ``(i, j)`` with ``i < j``, or ``(-1, -1)`` when the outlines are simple and disjoint.
    """
    k = starts.shape[0]
    for i in range(k):
        for j in range(i + 1, k):
            ax, ay, bx, by = starts[i, 0], starts[i, 1], ends[i, 0], ends[i, 1]
            cx, cy, dx, dy = starts[j, 0], starts[j, 1], ends[j, 0], ends[j, 1]
            if loop_id[i] == loop_id[j] and (following[i] == j or previous[i] == j):
                # Adjacent segments share a vertex; they are bad only if they fold back.
                ux, uy, vx, vy = bx - ax, by - ay, dx - cx, dy - cy
                if ux * vy - uy * vx == 0.0 and ux * vx + uy * vy < 0.0:
                    return i, j
                continue
            if _segments_cross(ax, ay, bx, by, cx, cy, dx, dy):
                return i, j
    return -1, -1


@njit(cache=True)
def _element_force(
    positions: np.ndarray, velocities: np.ndarray, triangles: np.ndarray,
    dm_inverse: np.ndarray, rest_area: np.ndarray, element: int, lame_lambda: float,
    lame_mu: float, damping_lambda: float, damping_mu: float, rate_strain: float,
    out: np.ndarray,
) -> float:
    """Nodal forces ``-A0 P dF/dx`` of one element into ``out`` (3, 2); returns det F.

    ``rate_strain`` w adds ``w Fdot^T Fdot`` to the strain that gives the elastic stress: with
    positions at a step's midpoint, velocities ``(x1 - x0) / dt`` and ``w = dt^2 / 8`` the
    strain is the mean ``(E(F0) + E(F1)) / 2`` of the step's ends (Simo & Tarnow's
    energy-momentum stress; 0 elsewhere)."""
    i0, i1, i2 = triangles[element, 0], triangles[element, 1], triangles[element, 2]
    d00 = positions[i1, 0] - positions[i0, 0]
    d10 = positions[i1, 1] - positions[i0, 1]
    d01 = positions[i2, 0] - positions[i0, 0]
    d11 = positions[i2, 1] - positions[i0, 1]
    w00 = velocities[i1, 0] - velocities[i0, 0]
    w10 = velocities[i1, 1] - velocities[i0, 1]
    w01 = velocities[i2, 0] - velocities[i0, 0]
    w11 = velocities[i2, 1] - velocities[i0, 1]
    b00, b01 = dm_inverse[element, 0, 0], dm_inverse[element, 0, 1]
    b10, b11 = dm_inverse[element, 1, 0], dm_inverse[element, 1, 1]
    # F = Ds Dm^-1 and Fdot = Dsdot Dm^-1
    f00 = d00 * b00 + d01 * b10
    f01 = d00 * b01 + d01 * b11
    f10 = d10 * b00 + d11 * b10
    f11 = d10 * b01 + d11 * b11
    g00 = w00 * b00 + w01 * b10
    g01 = w00 * b01 + w01 * b11
    g10 = w10 * b00 + w11 * b10
    g11 = w10 * b01 + w11 * b11
    determinant = f00 * f11 - f01 * f10
    # Green strain E = (F^T F - I)/2 and its rate (Fdot^T F + F^T Fdot)/2
    e00 = 0.5 * (f00 * f00 + f10 * f10 - 1.0)
    e11 = 0.5 * (f01 * f01 + f11 * f11 - 1.0)
    e01 = 0.5 * (f00 * f01 + f10 * f11)
    if rate_strain != 0.0:
        e00 += rate_strain * (g00 * g00 + g10 * g10)
        e11 += rate_strain * (g01 * g01 + g11 * g11)
        e01 += rate_strain * (g00 * g01 + g10 * g11)
    r00 = g00 * f00 + g10 * f10
    r11 = g01 * f01 + g11 * f11
    r01 = 0.5 * (g00 * f01 + g10 * f11 + f00 * g01 + f10 * g11)
    trace_e = e00 + e11
    trace_r = r00 + r11
    s00 = lame_lambda * trace_e + 2.0 * lame_mu * e00 + damping_lambda * trace_r
    s00 += 2.0 * damping_mu * r00
    s11 = lame_lambda * trace_e + 2.0 * lame_mu * e11 + damping_lambda * trace_r
    s11 += 2.0 * damping_mu * r11
    s01 = 2.0 * lame_mu * e01 + 2.0 * damping_mu * r01
    # P = F S; forces on nodes 1, 2 are the columns of -A0 P Dm^-T, node 0 balances them.
    p00 = f00 * s00 + f01 * s01
    p01 = f00 * s01 + f01 * s11
    p10 = f10 * s00 + f11 * s01
    p11 = f10 * s01 + f11 * s11
    area = rest_area[element]
    h00 = -area * (p00 * b00 + p01 * b01)
    h01 = -area * (p00 * b10 + p01 * b11)
    h10 = -area * (p10 * b00 + p11 * b01)
    h11 = -area * (p10 * b10 + p11 * b11)
    out[1, 0] = h00
    out[1, 1] = h10
    out[2, 0] = h01
    out[2, 1] = h11
    out[0, 0] = -h00 - h01
    out[0, 1] = -h10 - h11
    return determinant


@njit(cache=True)
def internal_forces(
    positions: np.ndarray, velocities: np.ndarray, triangles: np.ndarray,
    dm_inverse: np.ndarray, rest_area: np.ndarray, lame_lambda: float, lame_mu: float,
    damping_lambda: float, damping_mu: float, rate_strain: float, forces: np.ndarray,
    determinants: np.ndarray,
) -> None:
    """Elastic plus Voigt damping nodal forces [N/m] into ``forces`` (n, 2), det F per
    element (``rate_strain``: `_element_force`)."""
    forces[:] = 0.0
    local = np.empty((3, 2))
    for e in range(triangles.shape[0]):
        determinants[e] = _element_force(
            positions, velocities, triangles, dm_inverse, rest_area, e, lame_lambda, lame_mu,
            damping_lambda, damping_mu, rate_strain, local,
        )
        for a in range(3):
            node = triangles[e, a]
            forces[node, 0] += local[a, 0]
            forces[node, 1] += local[a, 1]


@njit(cache=True)
def elastic_energy(
    positions: np.ndarray, triangles: np.ndarray, dm_inverse: np.ndarray, rest_area: np.ndarray,
    lame_lambda: float, lame_mu: float,
) -> float:
    """St. Venant-Kirchhoff strain energy ``sum A0 (lambda/2 tr(E)^2 + mu E:E)`` [J/m]."""
    total = 0.0
    for e in range(triangles.shape[0]):
        i0, i1, i2 = triangles[e, 0], triangles[e, 1], triangles[e, 2]
        d00 = positions[i1, 0] - positions[i0, 0]
        d10 = positions[i1, 1] - positions[i0, 1]
        d01 = positions[i2, 0] - positions[i0, 0]
        d11 = positions[i2, 1] - positions[i0, 1]
        f00 = d00 * dm_inverse[e, 0, 0] + d01 * dm_inverse[e, 1, 0]
        f01 = d00 * dm_inverse[e, 0, 1] + d01 * dm_inverse[e, 1, 1]
        f10 = d10 * dm_inverse[e, 0, 0] + d11 * dm_inverse[e, 1, 0]
        f11 = d10 * dm_inverse[e, 0, 1] + d11 * dm_inverse[e, 1, 1]
        e00 = 0.5 * (f00 * f00 + f10 * f10 - 1.0)
        e11 = 0.5 * (f01 * f01 + f11 * f11 - 1.0)
        e01 = 0.5 * (f00 * f01 + f10 * f11)
        trace = e00 + e11
        density = 0.5 * lame_lambda * trace * trace + lame_mu * (
            e00 * e00 + e11 * e11 + 2.0 * e01 * e01
        )
        total += rest_area[e] * density
    return total


@njit(cache=True)
def _update_nodes(
    positions: np.ndarray, velocities: np.ndarray, forces: np.ndarray,
    external_forces: np.ndarray, inverse_mass: np.ndarray, fixed: np.ndarray, dt: float,
    drag_factor: float,
) -> None:
    """Symplectic Euler for every node: ``v += dt f/m`` (with drag), ``x += dt v``."""
    for node in range(positions.shape[0]):
        if fixed[node]:
            velocities[node, 0] = 0.0
            velocities[node, 1] = 0.0
            continue
        w = inverse_mass[node]
        vx = velocities[node, 0] + dt * (forces[node, 0] + external_forces[node, 0]) * w
        vy = velocities[node, 1] + dt * (forces[node, 1] + external_forces[node, 1]) * w
        vx *= drag_factor
        vy *= drag_factor
        velocities[node, 0] = vx
        velocities[node, 1] = vy
        positions[node, 0] += dt * vx
        positions[node, 1] += dt * vy


@njit(cache=True)
def _first_bad_element(determinants: np.ndarray) -> int:
    for e in range(determinants.shape[0]):
        if not determinants[e] > 0.0:
            return e
    return -1


@njit(cache=True)
def element_determinants(
    positions: np.ndarray, triangles: np.ndarray, dm_inverse: np.ndarray,
    determinants: np.ndarray,
) -> None:
    for e in range(triangles.shape[0]):
        i0, i1, i2 = triangles[e, 0], triangles[e, 1], triangles[e, 2]
        d00 = positions[i1, 0] - positions[i0, 0]
        d10 = positions[i1, 1] - positions[i0, 1]
        d01 = positions[i2, 0] - positions[i0, 0]
        d11 = positions[i2, 1] - positions[i0, 1]
        det_ds = d00 * d11 - d01 * d10
        det_dm_inverse = (
            dm_inverse[e, 0, 0] * dm_inverse[e, 1, 1] - dm_inverse[e, 0, 1] * dm_inverse[e, 1, 0]
        )
        determinants[e] = det_ds * det_dm_inverse


@njit(cache=True)
def _advance_serial(state, mesh, material, external_forces, dt, substeps, outcome):
    """`advance` with the forces scattered to the nodes element by element."""
    positions, velocities = state
    triangles, dm_inverse, rest_area, inverse_mass, fixed = mesh
    lame_lambda, lame_mu, damping_lambda, damping_mu, velocity_damping = material
    status, determinant = outcome
    forces = np.empty_like(positions)
    determinants = np.empty(triangles.shape[0])
    drag_factor = 1.0 / (1.0 + velocity_damping * dt)
    status[:] = 0
    for s in range(substeps):
        internal_forces(
            positions, velocities, triangles, dm_inverse, rest_area, lame_lambda, lame_mu,
            damping_lambda, damping_mu, 0.0, forces, determinants,
        )
        bad = _first_bad_element(determinants)
        if bad >= 0:
            status[0] = 1
            status[1] = s
            status[2] = bad
            determinant[0] = determinants[bad]
            return
        _update_nodes(
            positions, velocities, forces, external_forces, inverse_mass, fixed, dt, drag_factor,
        )
    element_determinants(positions, triangles, dm_inverse, determinants)
    bad = _first_bad_element(determinants)
    if bad >= 0:
        status[0] = 1
        status[1] = substeps
        status[2] = bad
        determinant[0] = determinants[bad]


@njit(cache=True, parallel=True)
def _advance_parallel(state, mesh, material, external_forces, dt, substeps, adjacency,
                      outcome):
    """`advance` threaded over elements and then over nodes.

    Element forces go to a per-element buffer and each node gathers its own (``adjacency``:
    CSR of the elements around each node and the corner the node is in them), so no two
    threads write the same node.
    """
    positions, velocities = state
    triangles, dm_inverse, rest_area, inverse_mass, fixed = mesh
    lame_lambda, lame_mu, damping_lambda, damping_mu, velocity_damping = material
    node_offsets, node_elements, node_corners = adjacency
    status, determinant = outcome
    element_count = triangles.shape[0]
    node_count = positions.shape[0]
    element_forces = np.empty((element_count, 3, 2))
    determinants = np.empty(element_count)
    drag_factor = 1.0 / (1.0 + velocity_damping * dt)
    status[:] = 0
    for s in range(substeps):
        for e in prange(element_count):
            determinants[e] = _element_force(
                positions, velocities, triangles, dm_inverse, rest_area, e, lame_lambda,
                lame_mu, damping_lambda, damping_mu, 0.0, element_forces[e],
            )
        bad = _first_bad_element(determinants)
        if bad >= 0:
            status[0] = 1
            status[1] = s
            status[2] = bad
            determinant[0] = determinants[bad]
            return
        for node in prange(node_count):
            if fixed[node]:
                velocities[node, 0] = 0.0
                velocities[node, 1] = 0.0
                continue
            fx = external_forces[node, 0]
            fy = external_forces[node, 1]
            for k in range(node_offsets[node], node_offsets[node + 1]):
                fx += element_forces[node_elements[k], node_corners[k], 0]
                fy += element_forces[node_elements[k], node_corners[k], 1]
            w = inverse_mass[node]
            vx = (velocities[node, 0] + dt * fx * w) * drag_factor
            vy = (velocities[node, 1] + dt * fy * w) * drag_factor
            velocities[node, 0] = vx
            velocities[node, 1] = vy
            positions[node, 0] += dt * vx
            positions[node, 1] += dt * vy
    element_determinants(positions, triangles, dm_inverse, determinants)
    bad = _first_bad_element(determinants)
    if bad >= 0:
        status[0] = 1
        status[1] = substeps
        status[2] = bad
        determinant[0] = determinants[bad]


@njit(cache=True)
def advance(state, mesh, material, external_forces, dt, substeps, adjacency, parallel,
            outcome):
    """``substeps`` symplectic Euler substeps of size ``dt`` [s], in place.

    Args:
        state: ``(positions, velocities)`` (n, 2), advanced in place.
        mesh: ``(triangles, dm_inverse, rest_area, inverse_mass, fixed)``: ``inverse_mass``
            (n,) is 1 / (the inertia of each node); fixed nodes keep their place.
        material: ``(lame_lambda, lame_mu, damping_lambda, damping_mu, velocity_damping)``.
        external_forces: (n, 2) [N/m], every force but the internal ones (gravity included).
        adjacency: ``(node_offsets, node_elements, node_corners)``, the elements around each
            node (CSR) and the node's corner in them; read only with ``parallel``.
        parallel: Threaded over elements and nodes (else the forces are scattered serially).
        outcome: ``(status, determinant)``: a substep whose result holds an element with
            det F <= 0 or not finite stops the loop and sets ``status = (1, substeps
            completed, element)`` and ``determinant[0]`` to that det F; the positions are
            then those after that substep.
    """
    if parallel:
        _advance_parallel(state, mesh, material, external_forces, dt, substeps, adjacency,
                          outcome)
    else:
        _advance_serial(state, mesh, material, external_forces, dt, substeps, outcome)
