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

# Element count from which the threaded substep kernel is the default (see ElasticBody3D).
# Measured on the shared 2-core box (docs/validation/three_d_solid.md): the threaded kernel
# only pays from tens of thousands of tetrahedra, as in 2D.
PARALLEL_ELEMENT_THRESHOLD_3D = 20000

# Elements per chunk of the threaded kernel: each chunk owns its scratch arrays.
_CHUNK = 256


@njit(cache=True)
def _deformation(
    positions: np.ndarray, tetrahedra: np.ndarray, dm_inverse: np.ndarray, element: int,
    f: np.ndarray,
) -> float:
    """``F = Ds Dm^-1`` of one element into ``f`` (3, 3); returns det F."""
    i0 = tetrahedra[element, 0]
    for r in range(3):
        for c in range(3):
            total = 0.0
            for k in range(3):
                total += (positions[tetrahedra[element, k + 1], r] - positions[i0, r]) * (
                    dm_inverse[element, k, c]
                )
            f[r, c] = total
    return (f[0, 0] * (f[1, 1] * f[2, 2] - f[1, 2] * f[2, 1])
            - f[0, 1] * (f[1, 0] * f[2, 2] - f[1, 2] * f[2, 0])
            + f[0, 2] * (f[1, 0] * f[2, 1] - f[1, 1] * f[2, 0]))


@njit(cache=True)
def _element_force(
    positions: np.ndarray, velocities: np.ndarray, tetrahedra: np.ndarray,
    dm_inverse: np.ndarray, rest_volume: np.ndarray, element: int, lame_lambda: float,
    lame_mu: float, damping_lambda: float, damping_mu: float, scratch: np.ndarray,
    out: np.ndarray,
) -> float:
    """Nodal forces ``-V0 P dF/dx`` of one element into ``out`` (4, 3) [N]; returns det F.

    ``scratch`` (4, 3, 3) holds F, Fdot, S and P."""
    f = scratch[0]
    g = scratch[1]
    s = scratch[2]
    p = scratch[3]
    determinant = _deformation(positions, tetrahedra, dm_inverse, element, f)
    _deformation(velocities, tetrahedra, dm_inverse, element, g)
    trace_e = 0.0
    trace_r = 0.0
    for a in range(3):
        for b in range(3):
            ftf = 0.0
            rate = 0.0
            for k in range(3):
                ftf += f[k, a] * f[k, b]
                rate += g[k, a] * f[k, b] + f[k, a] * g[k, b]
            strain = 0.5 * ftf
            if a == b:
                strain -= 0.5
                trace_e += strain
                trace_r += 0.5 * rate
            # S is assembled below from the strain (E) and its rate (Edot) stored in s and p.
            s[a, b] = strain
            p[a, b] = 0.5 * rate
    for a in range(3):
        for b in range(3):
            value = 2.0 * lame_mu * s[a, b] + 2.0 * damping_mu * p[a, b]
            if a == b:
                value += lame_lambda * trace_e + damping_lambda * trace_r
            s[a, b] = value
    # P = F S, then H = -V0 P Dm^-T: column c of H is the force on node c + 1.
    for r in range(3):
        for c in range(3):
            total = 0.0
            for k in range(3):
                total += f[r, k] * s[k, c]
            p[r, c] = total
    volume = rest_volume[element]
    for r in range(3):
        out[0, r] = 0.0
    for c in range(3):
        for r in range(3):
            total = 0.0
            for k in range(3):
                total += p[r, k] * dm_inverse[element, c, k]
            out[c + 1, r] = -volume * total
            out[0, r] += volume * total
    return determinant


@njit(cache=True)
def internal_forces_3d(
    positions: np.ndarray, velocities: np.ndarray, tetrahedra: np.ndarray,
    dm_inverse: np.ndarray, rest_volume: np.ndarray, lame_lambda: float, lame_mu: float,
    damping_lambda: float, damping_mu: float, forces: np.ndarray, determinants: np.ndarray,
) -> None:
    """Elastic plus Voigt damping nodal forces [N] into ``forces`` (n, 3), det F per element
    into ``determinants`` (m,)."""
    forces[:] = 0.0
    local = np.empty((4, 3))
    scratch = np.empty((4, 3, 3))
    for e in range(tetrahedra.shape[0]):
        determinants[e] = _element_force(
            positions, velocities, tetrahedra, dm_inverse, rest_volume, e, lame_lambda,
            lame_mu, damping_lambda, damping_mu, scratch, local,
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
    f = np.empty((3, 3))
    total = 0.0
    for e in range(tetrahedra.shape[0]):
        _deformation(positions, tetrahedra, dm_inverse, e, f)
        trace = 0.0
        squares = 0.0
        for a in range(3):
            for b in range(3):
                strain = 0.0
                for k in range(3):
                    strain += f[k, a] * f[k, b]
                strain *= 0.5
                if a == b:
                    strain -= 0.5
                    trace += strain
                squares += strain * strain
        total += rest_volume[e] * (0.5 * lame_lambda * trace * trace + lame_mu * squares)
    return total


@njit(cache=True)
def element_determinants_3d(
    positions: np.ndarray, tetrahedra: np.ndarray, dm_inverse: np.ndarray,
    determinants: np.ndarray,
) -> None:
    """det F of each element into ``determinants`` (m,)."""
    f = np.empty((3, 3))
    for e in range(tetrahedra.shape[0]):
        determinants[e] = _deformation(positions, tetrahedra, dm_inverse, e, f)


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
def advance_serial_3d(
    positions: np.ndarray, velocities: np.ndarray, tetrahedra: np.ndarray,
    dm_inverse: np.ndarray, rest_volume: np.ndarray, inverse_mass: np.ndarray,
    fixed: np.ndarray, external_forces: np.ndarray, lame_lambda: float, lame_mu: float,
    damping_lambda: float, damping_mu: float, velocity_damping: float, dt: float,
    substeps: int, status: np.ndarray, determinant: np.ndarray,
) -> None:
    """``substeps`` symplectic Euler substeps of size ``dt`` [s], in place; serial scatter.

    ``external_forces`` (n, 3) [N] holds every force but the internal ones (gravity included).
    A substep whose result holds an element with det F <= 0 or not finite stops the loop and
    sets the status (module docstring).
    """
    forces = np.empty_like(positions)
    determinants = np.empty(tetrahedra.shape[0])
    drag_factor = 1.0 / (1.0 + velocity_damping * dt)
    status[:] = 0
    for s in range(substeps):
        internal_forces_3d(
            positions, velocities, tetrahedra, dm_inverse, rest_volume, lame_lambda, lame_mu,
            damping_lambda, damping_mu, forces, determinants,
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
def advance_parallel_3d(
    positions: np.ndarray, velocities: np.ndarray, tetrahedra: np.ndarray,
    dm_inverse: np.ndarray, rest_volume: np.ndarray, inverse_mass: np.ndarray,
    fixed: np.ndarray, external_forces: np.ndarray, lame_lambda: float, lame_mu: float,
    damping_lambda: float, damping_mu: float, velocity_damping: float, dt: float,
    substeps: int, status: np.ndarray, determinant: np.ndarray, node_offsets: np.ndarray,
    node_elements: np.ndarray, node_corners: np.ndarray,
) -> None:
    """Same as :func:`advance_serial_3d`, threaded over chunks of elements, then over nodes.

    Element forces go to a per-element buffer and each node gathers its own (CSR
    ``node_offsets``, ``node_elements``, ``node_corners``: the elements around each node and
    the node's corner in them), so no two threads write the same node.
    """
    element_count = tetrahedra.shape[0]
    node_count = positions.shape[0]
    chunk_count = (element_count + _CHUNK - 1) // _CHUNK
    element_forces = np.empty((element_count, 4, 3))
    determinants = np.empty(element_count)
    drag_factor = 1.0 / (1.0 + velocity_damping * dt)
    status[:] = 0
    for s in range(substeps):
        for chunk in prange(chunk_count):
            scratch = np.empty((4, 3, 3))
            for e in range(chunk * _CHUNK, min(element_count, (chunk + 1) * _CHUNK)):
                determinants[e] = _element_force(
                    positions, velocities, tetrahedra, dm_inverse, rest_volume, e,
                    lame_lambda, lame_mu, damping_lambda, damping_mu, scratch,
                    element_forces[e],
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
