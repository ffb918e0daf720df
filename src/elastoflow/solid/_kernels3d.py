"""Numba kernels of 3D elastic bodies: linear tetrahedra, St. Venant-Kirchhoff with Voigt
damping, and the explicit substeps (the 3D twins of `elastoflow.solid._kernels`).

Index spaces: ``positions``/``velocities``/``forces``/``inverse_mass``/``fixed`` are per node
``(n, ...)``; ``tetrahedra``/``dm_inverse``/``rest_volume`` per element ``(m, ...)``.

Per element, with ``Ds = [x1 - x0, x2 - x0, x3 - x0]`` and ``Dm`` its rest value:
``F = Ds Dm^-1``, ``E = (F^T F - I) / 2``, ``Edot = (Fdot^T F + F^T Fdot) / 2``,
``S = lambda tr(E) I + 2 mu E + lambda' tr(Edot) I + 2 mu' Edot``, ``P = F S``; the forces on
nodes 1-3 are the columns of ``-V0 P Dm^-T`` and node 0 takes minus their sum, so each
element's forces sum to zero (momentum) and its moment vanishes (``P F^T`` is symmetric:
angular momentum).

The substep kernels return a status instead of raising, as in 2D: ``status[0]`` is 1 when a
bad element was found, ``status[1]`` the substeps completed when it was found, ``status[2]``
the element, and ``determinant[0]`` its det F.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from elastoflow import _numba  # noqa: F401  (starts Numba's threads: see _numba)

# Element count from which the threaded substep kernel is the default (see ElasticBody3D).
# Measured on the shared 2-core box under load (the cantilever meshes, per substep): 400 tets
# 34 us serial vs 205 us threaded, 3200 tets 336 vs 573 us, 10800 tets 1.03 vs 1.30 ms; the
# threads' launch costs more than they save up to there, as in 2D, so the same threshold.
PARALLEL_ELEMENT_THRESHOLD_3D = 20000


@njit(cache=True)
def _edges(values: np.ndarray, tetrahedra: np.ndarray, element: int) -> tuple[
        float, float, float, float, float, float, float, float, float]:
    """``[v1 - v0, v2 - v0, v3 - v0]`` of one element as a row-major 3x3 tuple (columns are
    the edges)."""
    i0, i1, i2, i3 = (tetrahedra[element, 0], tetrahedra[element, 1], tetrahedra[element, 2],
                      tetrahedra[element, 3])
    return (values[i1, 0] - values[i0, 0], values[i2, 0] - values[i0, 0],
            values[i3, 0] - values[i0, 0],
            values[i1, 1] - values[i0, 1], values[i2, 1] - values[i0, 1],
            values[i3, 1] - values[i0, 1],
            values[i1, 2] - values[i0, 2], values[i2, 2] - values[i0, 2],
            values[i3, 2] - values[i0, 2])


@njit(cache=True)
def _times_dm_inverse(
    d: tuple[float, float, float, float, float, float, float, float, float],
    dm_inverse: np.ndarray, element: int,
) -> tuple[float, float, float, float, float, float, float, float, float]:
    """``D Dm^-1`` of one element, row-major 3x3 tuples in and out (F from Ds, Fdot from its
    rate). Scalars rather than small arrays: the compiled loop keeps them in registers."""
    b00, b01, b02 = dm_inverse[element, 0, 0], dm_inverse[element, 0, 1], dm_inverse[element, 0, 2]
    b10, b11, b12 = dm_inverse[element, 1, 0], dm_inverse[element, 1, 1], dm_inverse[element, 1, 2]
    b20, b21, b22 = dm_inverse[element, 2, 0], dm_inverse[element, 2, 1], dm_inverse[element, 2, 2]
    return (d[0] * b00 + d[1] * b10 + d[2] * b20, d[0] * b01 + d[1] * b11 + d[2] * b21,
            d[0] * b02 + d[1] * b12 + d[2] * b22,
            d[3] * b00 + d[4] * b10 + d[5] * b20, d[3] * b01 + d[4] * b11 + d[5] * b21,
            d[3] * b02 + d[4] * b12 + d[5] * b22,
            d[6] * b00 + d[7] * b10 + d[8] * b20, d[6] * b01 + d[7] * b11 + d[8] * b21,
            d[6] * b02 + d[7] * b12 + d[8] * b22)


@njit(cache=True)
def _determinant(f: tuple[float, float, float, float, float, float, float, float, float],
                 ) -> float:
    return (f[0] * (f[4] * f[8] - f[5] * f[7]) - f[1] * (f[3] * f[8] - f[5] * f[6])
            + f[2] * (f[3] * f[7] - f[4] * f[6]))


@njit(cache=True)
def _green_strain(f: tuple[float, float, float, float, float, float, float, float, float],
                  ) -> tuple[float, float, float, float, float, float]:
    """``E = (F^T F - I) / 2`` as (E00, E11, E22, E01, E02, E12)."""
    return (0.5 * (f[0] * f[0] + f[3] * f[3] + f[6] * f[6] - 1.0),
            0.5 * (f[1] * f[1] + f[4] * f[4] + f[7] * f[7] - 1.0),
            0.5 * (f[2] * f[2] + f[5] * f[5] + f[8] * f[8] - 1.0),
            0.5 * (f[0] * f[1] + f[3] * f[4] + f[6] * f[7]),
            0.5 * (f[0] * f[2] + f[3] * f[5] + f[6] * f[8]),
            0.5 * (f[1] * f[2] + f[4] * f[5] + f[7] * f[8]))


@njit(cache=True)
def _element_force(
    positions: np.ndarray, velocities: np.ndarray, tetrahedra: np.ndarray,
    dm_inverse: np.ndarray, rest_volume: np.ndarray, element: int, lame_lambda: float,
    lame_mu: float, damping_lambda: float, damping_mu: float, rate_strain: float,
    out: np.ndarray,
) -> float:
    """Nodal forces ``-V0 P dF/dx`` of one element into ``out`` (4, 3) [N]; returns det F.

    ``rate_strain`` w adds ``w Fdot^T Fdot`` to the strain of the elastic stress: at a step's
    midpoint with velocities ``(x1 - x0) / dt`` and ``w = dt^2 / 8`` that is the mean
    ``(E(F0) + E(F1)) / 2`` of the step's ends (Simo & Tarnow's energy-momentum stress, as in
    2D; 0 elsewhere)."""
    f = _times_dm_inverse(_edges(positions, tetrahedra, element), dm_inverse, element)
    g = _times_dm_inverse(_edges(velocities, tetrahedra, element), dm_inverse, element)
    e00, e11, e22, e01, e02, e12 = _green_strain(f)
    if rate_strain != 0.0:
        e00 += rate_strain * (g[0] * g[0] + g[3] * g[3] + g[6] * g[6])
        e11 += rate_strain * (g[1] * g[1] + g[4] * g[4] + g[7] * g[7])
        e22 += rate_strain * (g[2] * g[2] + g[5] * g[5] + g[8] * g[8])
        e01 += rate_strain * (g[0] * g[1] + g[3] * g[4] + g[6] * g[7])
        e02 += rate_strain * (g[0] * g[2] + g[3] * g[5] + g[6] * g[8])
        e12 += rate_strain * (g[1] * g[2] + g[4] * g[5] + g[7] * g[8])
    # Strain rate Edot = (Fdot^T F + F^T Fdot) / 2.
    r00 = g[0] * f[0] + g[3] * f[3] + g[6] * f[6]
    r11 = g[1] * f[1] + g[4] * f[4] + g[7] * f[7]
    r22 = g[2] * f[2] + g[5] * f[5] + g[8] * f[8]
    r01 = 0.5 * (g[0] * f[1] + g[3] * f[4] + g[6] * f[7] + f[0] * g[1] + f[3] * g[4]
                 + f[6] * g[7])
    r02 = 0.5 * (g[0] * f[2] + g[3] * f[5] + g[6] * f[8] + f[0] * g[2] + f[3] * g[5]
                 + f[6] * g[8])
    r12 = 0.5 * (g[1] * f[2] + g[4] * f[5] + g[7] * f[8] + f[1] * g[2] + f[4] * g[5]
                 + f[7] * g[8])
    volumetric = lame_lambda * (e00 + e11 + e22) + damping_lambda * (r00 + r11 + r22)
    two_mu, two_damping_mu = 2.0 * lame_mu, 2.0 * damping_mu
    s00 = volumetric + two_mu * e00 + two_damping_mu * r00
    s11 = volumetric + two_mu * e11 + two_damping_mu * r11
    s22 = volumetric + two_mu * e22 + two_damping_mu * r22
    s01 = two_mu * e01 + two_damping_mu * r01
    s02 = two_mu * e02 + two_damping_mu * r02
    s12 = two_mu * e12 + two_damping_mu * r12
    # P = F S, then H = -V0 P Dm^-T: column c of H is the force on node c + 1.
    volume = rest_volume[element]
    for row in range(3):
        a0, a1, a2 = f[3 * row], f[3 * row + 1], f[3 * row + 2]
        p0 = a0 * s00 + a1 * s01 + a2 * s02
        p1 = a0 * s01 + a1 * s11 + a2 * s12
        p2 = a0 * s02 + a1 * s12 + a2 * s22
        total = 0.0
        for c in range(3):
            h = -volume * (p0 * dm_inverse[element, c, 0] + p1 * dm_inverse[element, c, 1]
                           + p2 * dm_inverse[element, c, 2])
            out[c + 1, row] = h
            total += h
        out[0, row] = -total
    return _determinant(f)


@njit(cache=True)
def internal_forces_3d(
    positions: np.ndarray, velocities: np.ndarray, tetrahedra: np.ndarray,
    dm_inverse: np.ndarray, rest_volume: np.ndarray, lame_lambda: float, lame_mu: float,
    damping_lambda: float, damping_mu: float, rate_strain: float, forces: np.ndarray,
    determinants: np.ndarray,
) -> None:
    """Elastic plus Voigt damping nodal forces [N] into ``forces`` (n, 3), det F per element
    into ``determinants`` (m,) (``rate_strain``: `_element_force`)."""
    forces[:] = 0.0
    local = np.empty((4, 3))
    for e in range(tetrahedra.shape[0]):
        determinants[e] = _element_force(
            positions, velocities, tetrahedra, dm_inverse, rest_volume, e, lame_lambda,
            lame_mu, damping_lambda, damping_mu, rate_strain, local,
        )
        for a in range(4):
            node = tetrahedra[e, a]
            for r in range(3):
                forces[node, r] += local[a, r]


@njit(cache=True)
def elastic_energy_3d(
    positions: np.ndarray, tetrahedra: np.ndarray, dm_inverse: np.ndarray,
    rest_volume: np.ndarray, lame_lambda: float, lame_mu: float,
) -> float:
    """St. Venant-Kirchhoff strain energy ``sum V0 (lambda/2 tr(E)^2 + mu E:E)`` [J]."""
    total = 0.0
    for e in range(tetrahedra.shape[0]):
        f = _times_dm_inverse(_edges(positions, tetrahedra, e), dm_inverse, e)
        e00, e11, e22, e01, e02, e12 = _green_strain(f)
        trace = e00 + e11 + e22
        squares = e00 * e00 + e11 * e11 + e22 * e22 + 2.0 * (e01 * e01 + e02 * e02 + e12 * e12)
        total += rest_volume[e] * (0.5 * lame_lambda * trace * trace + lame_mu * squares)
    return total


@njit(cache=True)
def element_determinants_3d(
    positions: np.ndarray, tetrahedra: np.ndarray, dm_inverse: np.ndarray,
    determinants: np.ndarray,
) -> None:
    """det F of each element into ``determinants`` (m,)."""
    for e in range(tetrahedra.shape[0]):
        determinants[e] = _determinant(
            _times_dm_inverse(_edges(positions, tetrahedra, e), dm_inverse, e))


@njit(cache=True)
def _first_bad_element(determinants: np.ndarray) -> int:
    for e in range(determinants.shape[0]):
        if not determinants[e] > 0.0:
            return e
    return -1


@njit(cache=True)
def _update_node(
    positions: np.ndarray, velocities: np.ndarray, node: int, fx: float, fy: float, fz: float,
    inverse_mass: np.ndarray, dt: float, drag_factor: float,
) -> None:
    """Symplectic Euler for one free node: ``v += dt f / m`` (with drag), ``x += dt v``."""
    w = dt * inverse_mass[node]
    vx = (velocities[node, 0] + w * fx) * drag_factor
    vy = (velocities[node, 1] + w * fy) * drag_factor
    vz = (velocities[node, 2] + w * fz) * drag_factor
    velocities[node, 0] = vx
    velocities[node, 1] = vy
    velocities[node, 2] = vz
    positions[node, 0] += dt * vx
    positions[node, 1] += dt * vy
    positions[node, 2] += dt * vz


@njit(cache=True)
def _report_bad(determinants: np.ndarray, substep: int, status: np.ndarray,
                determinant: np.ndarray) -> bool:
    bad = _first_bad_element(determinants)
    if bad < 0:
        return False
    status[0] = 1
    status[1] = substep
    status[2] = bad
    determinant[0] = determinants[bad]
    return True


@njit(cache=True)
def _advance_serial_3d(state, mesh, material, external_forces, dt, substeps, outcome):
    """`advance_3d` with the forces scattered to the nodes element by element."""
    positions, velocities = state
    tetrahedra, dm_inverse, rest_volume, inverse_mass, fixed = mesh
    lame_lambda, lame_mu, damping_lambda, damping_mu, velocity_damping = material
    status, determinant = outcome
    forces = np.empty_like(positions)
    determinants = np.empty(tetrahedra.shape[0])
    drag_factor = 1.0 / (1.0 + velocity_damping * dt)
    status[:] = 0
    for s in range(substeps):
        internal_forces_3d(
            positions, velocities, tetrahedra, dm_inverse, rest_volume, lame_lambda, lame_mu,
            damping_lambda, damping_mu, 0.0, forces, determinants,
        )
        if _report_bad(determinants, s, status, determinant):
            return
        for node in range(positions.shape[0]):
            if fixed[node]:
                velocities[node, :] = 0.0
                continue
            _update_node(
                positions, velocities, node, forces[node, 0] + external_forces[node, 0],
                forces[node, 1] + external_forces[node, 1],
                forces[node, 2] + external_forces[node, 2], inverse_mass, dt, drag_factor,
            )
    element_determinants_3d(positions, tetrahedra, dm_inverse, determinants)
    _report_bad(determinants, substeps, status, determinant)


@njit(cache=True, parallel=True)
def _advance_parallel_3d(state, mesh, material, external_forces, dt, substeps, adjacency,
                         outcome):
    """`advance_3d` threaded over elements, then over nodes.

    Element forces go to a per-element buffer and each node gathers its own (``adjacency``:
    the elements around each node and the node's corner in them, CSR), so no two threads
    write the same node.
    """
    positions, velocities = state
    tetrahedra, dm_inverse, rest_volume, inverse_mass, fixed = mesh
    lame_lambda, lame_mu, damping_lambda, damping_mu, velocity_damping = material
    node_offsets, node_elements, node_corners = adjacency
    status, determinant = outcome
    element_count = tetrahedra.shape[0]
    node_count = positions.shape[0]
    element_forces = np.empty((element_count, 4, 3))
    determinants = np.empty(element_count)
    drag_factor = 1.0 / (1.0 + velocity_damping * dt)
    status[:] = 0
    for s in range(substeps):
        for e in prange(element_count):
            determinants[e] = _element_force(
                positions, velocities, tetrahedra, dm_inverse, rest_volume, e, lame_lambda,
                lame_mu, damping_lambda, damping_mu, 0.0, element_forces[e],
            )
        if _report_bad(determinants, s, status, determinant):
            return
        for node in prange(node_count):
            if fixed[node]:
                velocities[node, :] = 0.0
                continue
            fx = external_forces[node, 0]
            fy = external_forces[node, 1]
            fz = external_forces[node, 2]
            for k in range(node_offsets[node], node_offsets[node + 1]):
                fx += element_forces[node_elements[k], node_corners[k], 0]
                fy += element_forces[node_elements[k], node_corners[k], 1]
                fz += element_forces[node_elements[k], node_corners[k], 2]
            _update_node(positions, velocities, node, fx, fy, fz, inverse_mass, dt,
                         drag_factor)
    element_determinants_3d(positions, tetrahedra, dm_inverse, determinants)
    _report_bad(determinants, substeps, status, determinant)


@njit(cache=True)
def advance_3d(state, mesh, material, external_forces, dt, substeps, adjacency, parallel,
               outcome):
    """``substeps`` symplectic Euler substeps of size ``dt`` [s], in place: the 3D twin of
    `elastoflow.solid._kernels.advance` (``mesh``: ``(tetrahedra, dm_inverse, rest_volume,
    inverse_mass, fixed)``; ``state`` and ``external_forces`` (n, 3), the forces in N). A
    substep whose result holds an element with det F <= 0 or not finite stops the loop and
    sets the status (module docstring)."""
    if parallel:
        _advance_parallel_3d(state, mesh, material, external_forces, dt, substeps, adjacency,
                             outcome)
    else:
        _advance_serial_3d(state, mesh, material, external_forces, dt, substeps, outcome)


# Triplets per element of the step matrix: a 12 x 12 block (4 nodes x 3 components).
MATRIX_TRIPLETS_3D = 144


@njit(cache=True)
def _stress_positive_part(s: np.ndarray) -> None:
    """Replace the symmetric 3x3 ``s`` in place by its positive part (negative eigenvalues
    set to 0). The principal minors decide first, so a positive semi-definite stress (the
    common case) costs no eigen-decomposition."""
    m01 = s[0, 0] * s[1, 1] - s[0, 1] * s[0, 1]
    m02 = s[0, 0] * s[2, 2] - s[0, 2] * s[0, 2]
    m12 = s[1, 1] * s[2, 2] - s[1, 2] * s[1, 2]
    det = (s[0, 0] * m12 - s[0, 1] * (s[0, 1] * s[2, 2] - s[1, 2] * s[0, 2])
           + s[0, 2] * (s[0, 1] * s[1, 2] - s[1, 1] * s[0, 2]))
    if (s[0, 0] >= 0.0 and s[1, 1] >= 0.0 and s[2, 2] >= 0.0 and m01 >= 0.0 and m02 >= 0.0
            and m12 >= 0.0 and det >= 0.0):
        return
    values, vectors = np.linalg.eigh(s)
    for r in range(3):
        for c in range(3):
            total = 0.0
            for k in range(3):
                if values[k] > 0.0:
                    total += values[k] * vectors[r, k] * vectors[c, k]
            s[r, c] = total


@njit(cache=True)
def _element_matrix(
    positions: np.ndarray, tetrahedra: np.ndarray, dm_inverse: np.ndarray,
    rest_volume: np.ndarray, element: int, material_lambda: float, material_mu: float,
    stress_lambda: float, stress_mu: float, stress_scale: float, clamp: bool,
    gradients: np.ndarray, pushed: np.ndarray, stress: np.ndarray, out: np.ndarray,
) -> None:
    """The 12 x 12 element matrix (row and column ``3 corner + component``) into ``out``.

    With ``g_a`` the gradient of corner a's shape function (rows of ``Dm^-1``, corner 0 minus
    their sum) and ``u_a = F g_a``, block (b, a) is

        V0 [stress_scale (g_a . S g_b) I + lambda_m u_b u_a^T
            + mu_m ((g_a . g_b) F F^T + u_a u_b^T)],

    the derivative of the forces ``f_b = -V0 F S g_b`` on corner b by the position of corner
    a, negated: the stress (geometric) term from ``dF S``, the material terms from
    ``F dS(sym(F^T dF))`` with the constants (``lambda_m``, ``mu_m``) =
    (``material_lambda``, ``material_mu``). ``S`` is the St. Venant-Kirchhoff stress of the
    constants (``stress_lambda``, ``stress_mu``), with its negative eigenvalues set to 0 when
    ``clamp`` (positive semi-definite for any deformation). The same form with the Voigt
    constants and no stress term is the damping matrix ``-df/dv``. Blocks (a, b) are written
    as the transposes of (b, a), so the matrix is symmetric to the last bit."""
    f = _times_dm_inverse(_edges(positions, tetrahedra, element), dm_inverse, element)
    for c in range(3):
        gradients[c + 1, 0] = dm_inverse[element, c, 0]
        gradients[c + 1, 1] = dm_inverse[element, c, 1]
        gradients[c + 1, 2] = dm_inverse[element, c, 2]
    for k in range(3):
        gradients[0, k] = -(gradients[1, k] + gradients[2, k] + gradients[3, k])
    for a in range(4):
        for r in range(3):
            pushed[a, r] = (f[3 * r] * gradients[a, 0] + f[3 * r + 1] * gradients[a, 1]
                            + f[3 * r + 2] * gradients[a, 2])
    e00, e11, e22, e01, e02, e12 = _green_strain(f)
    trace = e00 + e11 + e22
    stress[0, 0] = stress_lambda * trace + 2.0 * stress_mu * e00
    stress[1, 1] = stress_lambda * trace + 2.0 * stress_mu * e11
    stress[2, 2] = stress_lambda * trace + 2.0 * stress_mu * e22
    stress[0, 1] = stress[1, 0] = 2.0 * stress_mu * e01
    stress[0, 2] = stress[2, 0] = 2.0 * stress_mu * e02
    stress[1, 2] = stress[2, 1] = 2.0 * stress_mu * e12
    if clamp:
        _stress_positive_part(stress)
    volume = rest_volume[element]
    for b in range(4):
        for a in range(b + 1):
            geometric = 0.0
            shape_product = 0.0
            for r in range(3):
                shape_product += gradients[a, r] * gradients[b, r]
                for c in range(3):
                    geometric += gradients[a, r] * stress[r, c] * gradients[b, c]
            geometric *= stress_scale
            for k in range(3):
                for d in range(3):
                    # (F F^T)_kd
                    stretch = f[3 * k] * f[3 * d] + f[3 * k + 1] * f[3 * d + 1] + f[
                        3 * k + 2] * f[3 * d + 2]
                    value = (material_lambda * pushed[b, k] * pushed[a, d]
                             + material_mu * (shape_product * stretch
                                              + pushed[a, k] * pushed[b, d]))
                    if k == d:
                        value += geometric
                    value *= volume
                    out[3 * b + k, 3 * a + d] = value
                    out[3 * a + d, 3 * b + k] = value


@njit(cache=True)
def step_matrix_triplets_3d(
    positions: np.ndarray, tetrahedra: np.ndarray, dm_inverse: np.ndarray,
    rest_volume: np.ndarray, material_lambda: float, material_mu: float,
    stress_lambda: float, stress_mu: float, stress_scale: float, clamp: bool,
    rows: np.ndarray, cols: np.ndarray, values: np.ndarray,
) -> None:
    """Element matrices of a linear combination of the tangent stiffness and the damping
    matrix (`_element_matrix`) as COO triplets, ``MATRIX_TRIPLETS_3D`` per element, into
    ``rows``/``cols``/``values`` (m * 144,); degree of freedom ``3 node + component``.

    ``dt D + s^2 K`` of a step: ``material_lambda = dt lambda' + s^2 lambda`` (likewise mu),
    ``stress_lambda``/``stress_mu`` the elastic constants, ``stress_scale = s^2``. The
    tangent stiffness ``K = -df/dx``: (lambda, mu, lambda, mu, 1); the damping matrix
    ``D = -df/dv``: (lambda', mu', 0, 0, 0). The entry order is fixed (element, then row,
    then column of its block), so a body can map each triplet to its place in an assembled
    pattern once."""
    gradients = np.empty((4, 3))
    pushed = np.empty((4, 3))
    stress = np.empty((3, 3))
    local = np.empty((12, 12))
    for e in range(tetrahedra.shape[0]):
        _element_matrix(positions, tetrahedra, dm_inverse, rest_volume, e, material_lambda,
                        material_mu, stress_lambda, stress_mu, stress_scale, clamp,
                        gradients, pushed, stress, local)
        base = MATRIX_TRIPLETS_3D * e
        for i in range(12):
            row = 3 * tetrahedra[e, i // 3] + i % 3
            for j in range(12):
                index = base + 12 * i + j
                rows[index] = row
                cols[index] = 3 * tetrahedra[e, j // 3] + j % 3
                values[index] = local[i, j]


@njit(cache=True)
def step_matrix_scatter_3d(
    positions: np.ndarray, tetrahedra: np.ndarray, dm_inverse: np.ndarray,
    rest_volume: np.ndarray, material_lambda: float, material_mu: float,
    stress_lambda: float, stress_mu: float, stress_scale: float, clamp: bool,
    target: np.ndarray, data: np.ndarray,
) -> None:
    """`step_matrix_triplets_3d`'s values summed straight into an assembled pattern:
    ``data[target[k]] += value k`` (``target[k] < 0``: left out), ``data`` zeroed first.
    Each entry sums its elements in element order, so entries (i, j) and (j, i) are equal to
    the last bit."""
    gradients = np.empty((4, 3))
    pushed = np.empty((4, 3))
    stress = np.empty((3, 3))
    local = np.empty((12, 12))
    data[:] = 0.0
    for e in range(tetrahedra.shape[0]):
        _element_matrix(positions, tetrahedra, dm_inverse, rest_volume, e, material_lambda,
                        material_mu, stress_lambda, stress_mu, stress_scale, clamp,
                        gradients, pushed, stress, local)
        base = MATRIX_TRIPLETS_3D * e
        for i in range(12):
            for j in range(12):
                where = target[base + 12 * i + j]
                if where >= 0:
                    data[where] += local[i, j]
