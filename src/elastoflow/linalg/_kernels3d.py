"""Numba kernels of the 7-point operator on ``(m, n, l)`` arrays: application, operator
loading, connected components, and the pieces of the multigrid V-cycle and of conjugate
gradient (red-black Gauss-Seidel, residual restriction, prolongation, fused vector updates).

Every kernel takes plain arrays and scalars (no Python objects), so that it can be retargeted
to a GPU later. The outer loop runs over ``i``; the twins from `serial_and_parallel` are
picked by `PARALLEL_MINIMUM_3D`. Pointwise kernels that do not care about the dimension
(finiteness probes, component means) are the 2D ones, called on ``(m * n, l)`` views.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from elastoflow._numba import serial_and_parallel

# Below this many points a parallel region costs more than it saves (a 16^3 level).
PARALLEL_MINIMUM_3D = 16 * 16 * 16
# The stencil kernels (sweep, residual, restriction, product) take their threaded twin down
# to an 8^3 level: their serial twins, indexing with signed neighbour offsets, compile to
# code 3-25x slower than the threaded ones run on one thread (16^3: a sweep 88 against 15
# us, the weighted residual 191 against 8; measured on the kernels alone), which is more
# than a parallel region's start costs. The pointwise kernels keep `PARALLEL_MINIMUM_3D`.
STENCIL_PARALLEL_MINIMUM_3D = 4 * 4 * 4
# Gauss-Seidel colours: a point (i, j, k) is red when i + j + k is even.
RED = 0
BLACK = 1
# Operators whose face weights are all equal (the pressure operator without bodies, and its
# coarse levels) are applied with that one number: the weight arrays are half the memory
# traffic of a Gauss-Seidel sweep, and the sweeps are memory-bound.
NOT_UNIFORM = -1.0
# A level whose weights are all equal outside a box around the bodies (the pressure operator
# with bodies) is applied with that one number outside the box and with its arrays inside:
# ``box`` (int64, 7) holds ``i0, i1, j0, j1, k0, k1`` (half-open) and a shell depth ``s``:
# the points within ``s`` of a side are applied with the arrays too. The shell is what lets
# a viscosity operator take the one weight: its held boundary planes (a wall's normal
# velocity, an inflow) are cut off from their neighbours, so the weights to them are 0
# (`SHELL_DEPTH`). ``NO_BOX`` is empty with no shell.
NO_BOX = np.zeros(7, dtype=np.int64)
# The shell depth that covers held boundary planes: the plane itself and the next one, whose
# weight to it is 0.
SHELL_DEPTH = 2


@njit(cache=True, inline="always")
def _row_box(box, i, j, l):
    """The columns ``[k0, k1)`` of row ``(i, j)`` inside ``box`` (``(l, l)`` when none); the
    shell is not read (`restrict_residual_uniform_kernel_3d`)."""
    if box[0] <= i < box[1] and box[2] <= j < box[3]:
        return box[4], box[5]
    return l, l


@njit(cache=True, inline="always")
def _row_spans(box, i, j, m, n, l):
    """Row ``(i, j)``'s columns split by ``box``: ``(ka, kb, kc, kd)``, applied with the
    arrays on ``[0, ka)``, ``[kb, kc)`` and ``[kd, l)``, with the one weight on ``[ka, kb)``
    and ``[kc, kd)`` (`NO_BOX`: ``(0, l, l, l)``, the whole row with the one weight)."""
    s = box[6]
    if i < s or i >= m - s or j < s or j >= n - s:
        return l, l, l, l
    ka = s
    kd = l - s
    kb = kd
    kc = kd
    if box[0] <= i < box[1] and box[2] <= j < box[3]:
        kb = min(max(box[4], ka), kd)
        kc = min(max(box[5], kb), kd)
    return ka, kb, kc, kd


@njit(cache=True, inline="always")
def _neighbour_sum(diagonal, weights_x, weights_y, weights_z, x, i, j, k, m, n, l):
    """Return ``(D, sum w x_nb)`` at ``[i, j, k]``, with ``D = diagonal + sum w``."""
    total = diagonal[i, j, k]
    coupled = 0.0
    if i > 0:
        w = weights_x[i - 1, j, k]
        total += w
        coupled += w * x[i - 1, j, k]
    if i < m - 1:
        w = weights_x[i, j, k]
        total += w
        coupled += w * x[i + 1, j, k]
    if j > 0:
        w = weights_y[i, j - 1, k]
        total += w
        coupled += w * x[i, j - 1, k]
    if j < n - 1:
        w = weights_y[i, j, k]
        total += w
        coupled += w * x[i, j + 1, k]
    if k > 0:
        w = weights_z[i, j, k - 1]
        total += w
        coupled += w * x[i, j, k - 1]
    if k < l - 1:
        w = weights_z[i, j, k]
        total += w
        coupled += w * x[i, j, k + 1]
    return total, coupled


@njit(cache=True, inline="always")
def _coupled_sum(weights_x, weights_y, weights_z, x, i, j, k, m, n, l):
    """``sum w x_nb`` at ``[i, j, k]`` (the totals are precomputed for the V-cycle)."""
    coupled = 0.0
    if i > 0:
        coupled += weights_x[i - 1, j, k] * x[i - 1, j, k]
    if i < m - 1:
        coupled += weights_x[i, j, k] * x[i + 1, j, k]
    if j > 0:
        coupled += weights_y[i, j - 1, k] * x[i, j - 1, k]
    if j < n - 1:
        coupled += weights_y[i, j, k] * x[i, j + 1, k]
    if k > 0:
        coupled += weights_z[i, j, k - 1] * x[i, j, k - 1]
    if k < l - 1:
        coupled += weights_z[i, j, k] * x[i, j, k + 1]
    return coupled


def _make_apply(loop):
    def kernel(diagonal, weights_x, weights_y, weights_z, x, out):
        m, n, l = x.shape
        for i in loop(m):
            for j in range(n):
                for k in range(l):
                    total, coupled = _neighbour_sum(diagonal, weights_x, weights_y, weights_z,
                                                    x, i, j, k, m, n, l)
                    out[i, j, k] = total * x[i, j, k] - coupled
    return kernel


_apply_serial, _apply_parallel = serial_and_parallel(_make_apply)


@njit(cache=True)
def apply_operator_kernel_3d(diagonal, weights_x, weights_y, weights_z, x, out):
    """``out = A x`` for the 7-point operator, all arrays ``(m, n, l)`` (weights one shorter
    along their axis)."""
    if x.size > STENCIL_PARALLEL_MINIMUM_3D:
        return _apply_parallel(diagonal, weights_x, weights_y, weights_z, x, out)
    return _apply_serial(diagonal, weights_x, weights_y, weights_z, x, out)


def _make_load(loop):
    def kernel(diagonal, weights_x, weights_y, weights_z, total, inverse, active, dominance,
               missing):
        m, n, l = diagonal.shape
        for i in loop(m):
            # A minimum per plane: no min-reduction across threads.
            smallest = np.inf
            # Active points without a positive diagonal (a pure-Neumann component's).
            without = 0
            for j in range(n):
                for k in range(l):
                    d = diagonal[i, j, k]
                    off = 0.0
                    if i > 0:
                        off += weights_x[i - 1, j, k]
                    if i < m - 1:
                        off += weights_x[i, j, k]
                    if j > 0:
                        off += weights_y[i, j - 1, k]
                    if j < n - 1:
                        off += weights_y[i, j, k]
                    if k > 0:
                        off += weights_z[i, j, k - 1]
                    if k < l - 1:
                        off += weights_z[i, j, k]
                    t = d + off
                    total[i, j, k] = t
                    is_active = t > 0.0
                    active[i, j, k] = is_active
                    inverse[i, j, k] = 1.0 / t if is_active else 0.0
                    if is_active:
                        smallest = min(smallest, d / off if off > 0.0 else np.inf)
                        if d <= 0.0:
                            without += 1
            dominance[i] = smallest
            missing[i] = without
    return kernel


_load_serial, _load_parallel = serial_and_parallel(_make_load)


@njit(cache=True)
def load_operator_kernel_3d(diagonal, weights_x, weights_y, weights_z, total, inverse, active):
    """Fill ``total = diagonal + sum of weights``, its inverse (0 at inactive points) and the
    ``active`` mask; return ``(whether every active point has a positive diagonal, the
    smallest ratio diagonal / sum of weights over active points)``."""
    m = diagonal.shape[0]
    dominance = np.empty(m)
    missing = np.empty(m, dtype=np.int64)
    if diagonal.size > PARALLEL_MINIMUM_3D:
        _load_parallel(diagonal, weights_x, weights_y, weights_z, total, inverse, active,
                       dominance, missing)
    else:
        _load_serial(diagonal, weights_x, weights_y, weights_z, total, inverse, active,
                     dominance, missing)
    all_have_diagonal = missing.sum() == 0
    return all_have_diagonal, dominance.min()


def _make_same_sign(loop):
    def kernel(a, b):
        m, n, l = a.shape
        differing = 0
        for i in loop(m):
            plane = 0
            for j in range(n):
                for k in range(l):
                    if (a[i, j, k] > 0.0) != (b[i, j, k] > 0.0):
                        plane += 1
            differing += plane
        return differing
    return kernel


_same_sign_serial, _same_sign_parallel = serial_and_parallel(_make_same_sign)


@njit(cache=True)
def positive_differences_kernel_3d(a, b):
    """How many points of two arrays of one shape are positive in one and not the other."""
    if a.size > PARALLEL_MINIMUM_3D:
        return _same_sign_parallel(a, b)
    return _same_sign_serial(a, b)


@njit(cache=True, inline="always")
def _find(parent, k):
    while parent[k] != k:
        parent[k] = parent[parent[k]]
        k = parent[k]
    return k


@njit(cache=True, inline="always")
def _union(parent, a, b):
    ra = _find(parent, a)
    rb = _find(parent, b)
    if ra != rb:
        parent[max(ra, rb)] = min(ra, rb)


@njit(cache=True)
def label_components_kernel_3d(diagonal, weights_x, weights_y, weights_z, active, labels):
    """Label the connected components (through positive weights) of the active points.

    Writes ``labels`` (-1 at inactive points, else 0..count-1) and returns ``(count,
    singular)``, ``singular[c]`` saying component ``c`` has no positive diagonal.
    """
    m, n, l = diagonal.shape
    parent = np.arange(m * n * l)
    for i in range(m):
        for j in range(n):
            for k in range(l):
                if not active[i, j, k]:
                    continue
                flat = (i * n + j) * l + k
                if i + 1 < m and weights_x[i, j, k] > 0.0:
                    _union(parent, flat, flat + n * l)
                if j + 1 < n and weights_y[i, j, k] > 0.0:
                    _union(parent, flat, flat + l)
                if k + 1 < l and weights_z[i, j, k] > 0.0:
                    _union(parent, flat, flat + 1)
    root_label = np.full(m * n * l, -1, dtype=np.int64)
    count = 0
    for i in range(m):
        for j in range(n):
            for k in range(l):
                if not active[i, j, k]:
                    labels[i, j, k] = -1
                    continue
                root = _find(parent, (i * n + j) * l + k)
                if root_label[root] < 0:
                    root_label[root] = count
                    count += 1
                labels[i, j, k] = root_label[root]
    singular = np.ones(count, dtype=np.bool_)
    for i in range(m):
        for j in range(n):
            for k in range(l):
                c = labels[i, j, k]
                if c >= 0 and diagonal[i, j, k] > 0.0:
                    singular[c] = False
    return count, singular


def _make_coarsen(loop):
    def kernel(fine_diagonal, fine_weights_x, fine_weights_y, fine_weights_z, fine_total,
               diagonal, weights_x, weights_y, weights_z):
        m, n, l = fine_diagonal.shape
        mc, nc, lc = diagonal.shape
        for ic in loop(mc):
            for jc in range(nc):
                for kc in range(lc):
                    # The volume part of the children's diagonal (the smallest one, shared by
                    # all active children: a Helmholtz identity) adds up under the summing
                    # restriction; the rest (Dirichlet sides) is a surface term and, like the
                    # face weights, scales by half the sum (rediscretisation at 2h of an
                    # operator scaled by h^2, restricted by summing 8 children).
                    count = 0
                    smallest = np.inf
                    summed = 0.0
                    for a in range(2):
                        i = 2 * ic + a
                        if i >= m:
                            continue
                        for b in range(2):
                            j = 2 * jc + b
                            if j >= n:
                                continue
                            for c in range(2):
                                k = 2 * kc + c
                                if k >= l or fine_total[i, j, k] <= 0.0:
                                    continue
                                count += 1
                                d = fine_diagonal[i, j, k]
                                summed += d
                                smallest = min(smallest, d)
                    if count > 0:
                        diagonal[ic, jc, kc] = count * smallest + 0.5 * (summed - count * smallest)
                    else:
                        diagonal[ic, jc, kc] = 0.0
                    if ic + 1 < mc:
                        w = 0.0
                        for b in range(2):
                            for c in range(2):
                                j = 2 * jc + b
                                k = 2 * kc + c
                                if j < n and k < l:
                                    w += fine_weights_x[2 * ic + 1, j, k]
                        weights_x[ic, jc, kc] = 0.5 * w
                    if jc + 1 < nc:
                        w = 0.0
                        for a in range(2):
                            for c in range(2):
                                i = 2 * ic + a
                                k = 2 * kc + c
                                if i < m and k < l:
                                    w += fine_weights_y[i, 2 * jc + 1, k]
                        weights_y[ic, jc, kc] = 0.5 * w
                    if kc + 1 < lc:
                        w = 0.0
                        for a in range(2):
                            for b in range(2):
                                i = 2 * ic + a
                                j = 2 * jc + b
                                if i < m and j < n:
                                    w += fine_weights_z[i, j, 2 * kc + 1]
                        weights_z[ic, jc, kc] = 0.5 * w
    return kernel


_coarsen_serial, _coarsen_parallel = serial_and_parallel(_make_coarsen)


@njit(cache=True)
def coarsen_kernel_3d(fine_diagonal, fine_weights_x, fine_weights_y, fine_weights_z,
                      fine_total, diagonal, weights_x, weights_y, weights_z):
    """The next coarser level's operator: each coarse point covers up to 2 x 2 x 2 fine
    points; a coarse face weight is half the sum of the (up to four) fine faces it covers."""
    if diagonal.size > PARALLEL_MINIMUM_3D // 8:
        return _coarsen_parallel(fine_diagonal, fine_weights_x, fine_weights_y, fine_weights_z,
                                 fine_total, diagonal, weights_x, weights_y, weights_z)
    return _coarsen_serial(fine_diagonal, fine_weights_x, fine_weights_y, fine_weights_z,
                           fine_total, diagonal, weights_x, weights_y, weights_z)


def _make_restrict(loop):
    def kernel(x, b, total, weights_x, weights_y, weights_z, coarse_b):
        m, n, l = x.shape
        mc, nc, lc = coarse_b.shape
        # One coarse plane per task, filled by walking its (up to two) fine planes in memory
        # order: the residual is computed once per fine point and added to its parent.
        for ic in loop(mc):
            for jc in range(nc):
                for kc in range(lc):
                    coarse_b[ic, jc, kc] = 0.0
            for i in range(2 * ic, min(2 * ic + 2, m)):
                for j in range(n):
                    jc = j >> 1
                    # The two children along k summed first: one update of the coarse
                    # value per pair, not a chain of two.
                    for kc in range(lc):
                        pair = 0.0
                        for k in range(2 * kc, min(2 * kc + 2, l)):
                            t = total[i, j, k]
                            if t > 0.0:
                                coupled = _coupled_sum(weights_x, weights_y, weights_z, x, i,
                                                       j, k, m, n, l)
                                pair += b[i, j, k] - t * x[i, j, k] + coupled
                        coarse_b[ic, jc, kc] += pair
    return kernel


_restrict_serial, _restrict_parallel = serial_and_parallel(_make_restrict)


@njit(cache=True)
def restrict_residual_kernel_3d(x, b, total, weights_x, weights_y, weights_z, coarse_b):
    """``coarse_b`` = the residual ``b - A x`` summed over each coarse point's children (the
    transpose of piecewise-constant prolongation)."""
    if x.size > STENCIL_PARALLEL_MINIMUM_3D:
        return _restrict_parallel(x, b, total, weights_x, weights_y, weights_z, coarse_b)
    return _restrict_serial(x, b, total, weights_x, weights_y, weights_z, coarse_b)


def _make_prolong(loop):
    def kernel(coarse_x, inverse, x):
        m, n, l = x.shape
        for i in loop(m):
            for j in range(n):
                for k in range(l):
                    if inverse[i, j, k] != 0.0:
                        x[i, j, k] += coarse_x[i >> 1, j >> 1, k >> 1]
    return kernel


_prolong_serial, _prolong_parallel = serial_and_parallel(_make_prolong)


@njit(cache=True)
def prolong_add_kernel_3d(coarse_x, inverse, x):
    """``x += P coarse_x`` (piecewise constant) at the active points (``inverse != 0``)."""
    if x.size > PARALLEL_MINIMUM_3D:
        return _prolong_parallel(coarse_x, inverse, x)
    return _prolong_serial(coarse_x, inverse, x)


def _make_prolong_all(loop):
    def kernel(coarse_x, x):
        m, n, l = x.shape
        for i in loop(m):
            for j in range(n):
                for k in range(l):
                    x[i, j, k] += coarse_x[i >> 1, j >> 1, k >> 1]
    return kernel


_prolong_all_serial, _prolong_all_parallel = serial_and_parallel(_make_prolong_all)


@njit(cache=True)
def prolong_add_all_kernel_3d(coarse_x, x):
    """`prolong_add_kernel_3d` where every point is active (a uniform-weight level): the
    inverse is not read."""
    if x.size > PARALLEL_MINIMUM_3D:
        return _prolong_all_parallel(coarse_x, x)
    return _prolong_all_serial(coarse_x, x)


@njit(cache=True)
def dense_matrix_kernel_3d(diagonal, weights_x, weights_y, weights_z, matrix):
    """The operator as a dense matrix over flat indices ``(i n + j) l + k``."""
    m, n, l = diagonal.shape
    matrix[:, :] = 0.0
    for i in range(m):
        for j in range(n):
            for k in range(l):
                a = (i * n + j) * l + k
                matrix[a, a] += diagonal[i, j, k]
                if i + 1 < m:
                    _add_coupling(matrix, a, a + n * l, weights_x[i, j, k])
                if j + 1 < n:
                    _add_coupling(matrix, a, a + l, weights_y[i, j, k])
                if k + 1 < l:
                    _add_coupling(matrix, a, a + 1, weights_z[i, j, k])


@njit(cache=True, inline="always")
def _add_coupling(matrix, a, b, w):
    matrix[a, a] += w
    matrix[b, b] += w
    matrix[a, b] -= w
    matrix[b, a] -= w


@njit(cache=True)
def dense_solve_kernel(factor, b, x):
    """Solve with a semi-definite Cholesky factor (`semidefinite_cholesky_kernel`); pinned
    unknowns (zero pivot) get 0. ``b`` and ``x`` are the level's ``(m, n, l)`` arrays."""
    size = factor.shape[0]
    values = b.ravel().copy()
    for a in range(size):
        value = values[a]
        for p in range(a):
            value -= factor[a, p] * values[p]
        values[a] = value / factor[a, a] if factor[a, a] > 0.0 else 0.0
    for a in range(size - 1, -1, -1):
        if factor[a, a] > 0.0:
            value = values[a]
            for p in range(a + 1, size):
                value -= factor[p, a] * values[p]
            values[a] = value / factor[a, a]
        else:
            values[a] = 0.0
    flat = x.ravel()
    for a in range(size):
        flat[a] = values[a]


def _make_fill(loop):
    def kernel(x, value):
        m, n, l = x.shape
        for i in loop(m):
            for j in range(n):
                for k in range(l):
                    x[i, j, k] = value
    return kernel


_fill_serial, _fill_parallel = serial_and_parallel(_make_fill)


@njit(cache=True)
def fill_kernel_3d(x, value):
    """``x[...] = value`` (threaded on large arrays)."""
    if x.size > PARALLEL_MINIMUM_3D:
        return _fill_parallel(x, value)
    return _fill_serial(x, value)


# Conjugate gradient's vector work, fused so that each vector is read once per iteration.
# Reassociation lets the reductions vectorise.
_REDUCTION_MATH = {"reassoc", "nsz"}


def _make_residual(loop):
    def kernel(diagonal, weights_x, weights_y, weights_z, x, b, r):
        m, n, l = x.shape
        squared = 0.0
        for i in loop(m):
            plane = 0.0
            for j in range(n):
                for k in range(l):
                    total, coupled = _neighbour_sum(diagonal, weights_x, weights_y, weights_z,
                                                    x, i, j, k, m, n, l)
                    value = b[i, j, k] - total * x[i, j, k] + coupled
                    r[i, j, k] = value
                    plane += value * value
            squared += plane
        return squared
    return kernel


_residual_serial, _residual_parallel = serial_and_parallel(_make_residual,
                                                           fastmath=_REDUCTION_MATH)


@njit(cache=True)
def residual_kernel_3d(diagonal, weights_x, weights_y, weights_z, x, b, r):
    """``r = b - A x``; returns ``|r|^2``."""
    if x.size > STENCIL_PARALLEL_MINIMUM_3D:
        return _residual_parallel(diagonal, weights_x, weights_y, weights_z, x, b, r)
    return _residual_serial(diagonal, weights_x, weights_y, weights_z, x, b, r)


@njit(cache=True, inline="always")
def _residual_run_sides(total, weight, x, b, r, i, j, k_from, k_to, m, n, l, plane):
    for k in range(k_from, k_to):
        value = (b[i, j, k] - total[i, j, k] * x[i, j, k]
                 + weight * _neighbour_values(x, i, j, k, m, n, l))
        r[i, j, k] = value
        plane += value * value
    return plane


@njit(cache=True, inline="always")
def _residual_weighted_run(diagonal, weights_x, weights_y, weights_z, x, b, r, i, j, k_from,
                           k_to, m, n, l, plane):
    for k in range(k_from, k_to):
        d, coupled = _neighbour_sum(diagonal, weights_x, weights_y, weights_z, x, i, j, k, m,
                                    n, l)
        value = b[i, j, k] - d * x[i, j, k] + coupled
        r[i, j, k] = value
        plane += value * value
    return plane


def _make_residual_uniform(loop):
    def kernel(total, weight, x, b, r, diagonal, weights_x, weights_y, weights_z, box):
        m, n, l = x.shape
        squared = 0.0
        for i in loop(m):
            plane = 0.0
            for j in range(n):
                # From a literal column 0, whose first column the compiler peels (see
                # `_inner_values`).
                kb, kc = _row_box(box, i, j, l)
                plane = _residual_run_sides(total, weight, x, b, r, i, j, 0, kb, m, n, l, plane)
                plane = _residual_weighted_run(diagonal, weights_x, weights_y, weights_z, x,
                                               b, r, i, j, kb, kc, m, n, l, plane)
                plane = _residual_run_sides(total, weight, x, b, r, i, j, kc, l, m, n, l, plane)
            squared += plane
        return squared
    return kernel


_residual_uniform_serial, _residual_uniform_parallel = serial_and_parallel(
    _make_residual_uniform, fastmath=_REDUCTION_MATH)


@njit(cache=True)
def residual_uniform_kernel_3d(total, weight, x, b, r, diagonal, weights_x, weights_y,
                               weights_z, box):
    """`residual_kernel_3d` for an operator whose weights all equal ``weight`` outside
    ``box`` (`NO_BOX`: everywhere; a box without a shell), with its ``total = diagonal +
    sum of weights``: 1 operator array read instead of 4 there, the operator's own arrays
    inside."""
    if x.size > STENCIL_PARALLEL_MINIMUM_3D:
        return _residual_uniform_parallel(total, weight, x, b, r, diagonal, weights_x,
                                          weights_y, weights_z, box)
    return _residual_uniform_serial(total, weight, x, b, r, diagonal, weights_x, weights_y,
                                    weights_z, box)


def _make_apply_dot(loop):
    def kernel(diagonal, weights_x, weights_y, weights_z, p, q):
        m, n, l = p.shape
        dot = 0.0
        for i in loop(m):
            plane = 0.0
            for j in range(n):
                for k in range(l):
                    total, coupled = _neighbour_sum(diagonal, weights_x, weights_y, weights_z,
                                                    p, i, j, k, m, n, l)
                    value = total * p[i, j, k] - coupled
                    q[i, j, k] = value
                    plane += value * p[i, j, k]
            dot += plane
        return dot
    return kernel


_apply_dot_serial, _apply_dot_parallel = serial_and_parallel(_make_apply_dot,
                                                             fastmath=_REDUCTION_MATH)


@njit(cache=True)
def apply_dot_kernel_3d(diagonal, weights_x, weights_y, weights_z, p, q):
    """``q = A p``; returns ``p . q``."""
    if p.size > STENCIL_PARALLEL_MINIMUM_3D:
        return _apply_dot_parallel(diagonal, weights_x, weights_y, weights_z, p, q)
    return _apply_dot_serial(diagonal, weights_x, weights_y, weights_z, p, q)


def _make_step(loop):
    def kernel(x, r, p, q, alpha):
        m, n, l = x.shape
        squared = 0.0
        for i in loop(m):
            plane = 0.0
            for j in range(n):
                for k in range(l):
                    x[i, j, k] += alpha * p[i, j, k]
                    value = r[i, j, k] - alpha * q[i, j, k]
                    r[i, j, k] = value
                    plane += value * value
            squared += plane
        return squared
    return kernel


_step_serial, _step_parallel = serial_and_parallel(_make_step, fastmath=_REDUCTION_MATH)


@njit(cache=True)
def step_kernel_3d(x, r, p, q, alpha):
    """``x += alpha p``, ``r -= alpha q``; returns ``|r|^2``."""
    if x.size > PARALLEL_MINIMUM_3D:
        return _step_parallel(x, r, p, q, alpha)
    return _step_serial(x, r, p, q, alpha)


def _make_dot(loop):
    def kernel(a, b):
        m, n, l = a.shape
        dot = 0.0
        for i in loop(m):
            plane = 0.0
            for j in range(n):
                for k in range(l):
                    plane += a[i, j, k] * b[i, j, k]
            dot += plane
        return dot
    return kernel


_dot_serial, _dot_parallel = serial_and_parallel(_make_dot, fastmath=_REDUCTION_MATH)


@njit(cache=True)
def dot_kernel_3d(a, b):
    """``a . b`` over ``(m, n, l)`` arrays."""
    if a.size > PARALLEL_MINIMUM_3D:
        return _dot_parallel(a, b)
    return _dot_serial(a, b)


def _make_direction(loop):
    def kernel(z, p, beta):
        m, n, l = z.shape
        for i in loop(m):
            for j in range(n):
                for k in range(l):
                    p[i, j, k] = z[i, j, k] + beta * p[i, j, k]
    return kernel


_direction_serial, _direction_parallel = serial_and_parallel(_make_direction)


@njit(cache=True)
def direction_kernel_3d(z, p, beta):
    """``p = z + beta p``."""
    if z.size > PARALLEL_MINIMUM_3D:
        return _direction_parallel(z, p, beta)
    return _direction_serial(z, p, beta)


def _make_masked_copy(loop):
    def kernel(values, active, out):
        m, n, l = values.shape
        squared = 0.0
        probe = 0.0
        for i in loop(m):
            plane = 0.0
            plane_probe = 0.0
            for j in range(n):
                for k in range(l):
                    given = values[i, j, k]
                    # 0 for a finite value, NaN for inf or NaN (active or not).
                    plane_probe += given * 0.0
                    value = given if active[i, j, k] else 0.0
                    out[i, j, k] = value
                    plane += value * value
            squared += plane
            probe += plane_probe
        return squared, probe
    return kernel


_masked_copy_serial, _masked_copy_parallel = serial_and_parallel(_make_masked_copy,
                                                                 fastmath=_REDUCTION_MATH)


@njit(cache=True)
def masked_copy_kernel_3d(values, active, out):
    """``out = values`` at active points, 0 elsewhere (``out`` may be ``values``); returns
    ``(|out|^2, probe)``, ``probe`` 0 when every value (active or not) is finite, NaN
    otherwise: the finiteness check comes with the copy."""
    if values.size > PARALLEL_MINIMUM_3D:
        return _masked_copy_parallel(values, active, out)
    return _masked_copy_serial(values, active, out)


@njit(cache=True)
def uniform_weight_kernel(weights_x, weights_y, weights_z):
    """The common value of all weights when they are equal and positive, else `NOT_UNIFORM`."""
    value = NOT_UNIFORM
    for weights in (weights_x, weights_y, weights_z):
        for w in weights.ravel():
            if value == NOT_UNIFORM:
                value = w
            if w != value or w <= 0.0:
                return NOT_UNIFORM
    return value


@njit(cache=True, parallel=True)
def uniform_box_kernel(weights_x, weights_y, weights_z, weight, shell, box):
    """Write into ``box`` (int64, 7: ``i0, i1, j0, j1, k0, k1``, half-open, and ``shell``)
    the smallest box holding every point one of whose weights differs from ``weight``,
    leaving out the weights between two points within ``shell`` of a side (whose rows are
    applied with the arrays anyway); returns how many weights differ there (0: the box is
    empty). Outside the box and the shell the operator is applied with ``weight`` alone
    (`sweep_kernel_3d` and the `*_uniform_kernel_3d` kernels)."""
    m = weights_y.shape[0]
    n = weights_x.shape[1]
    l = weights_x.shape[2]
    # Per plane i: the rows and columns of its differing weights (the x-weights of plane i
    # also touch plane i + 1: added below).
    low_j = np.full(m, n, dtype=np.int64)
    high_j = np.full(m, -1, dtype=np.int64)
    low_k = np.full(m, l, dtype=np.int64)
    high_k = np.full(m, -1, dtype=np.int64)
    count_x = np.zeros(m, dtype=np.int64)
    count_yz = np.zeros(m, dtype=np.int64)
    for i in prange(m):
        # Counts and bounds in locals, stored once a plane: written per point into the
        # arrays they made the pass 5x slower (0.66 ms at 64^3, 5.4 at 128^3).
        along_x_count = 0
        along_yz_count = 0
        j_low, j_high, k_low, k_high = n, -1, l, -1
        i_shell = i < shell or i >= m - shell
        next_i_shell = i + 1 < shell or i + 1 >= m - shell
        for j in range(n):
            j_shell = j < shell or j >= n - shell
            next_j_shell = j + 1 < shell or j + 1 >= n - shell
            for k in range(l):
                along_x = i < m - 1 and weights_x[i, j, k] != weight
                along_y = j < n - 1 and weights_y[i, j, k] != weight
                along_z = k < l - 1 and weights_z[i, j, k] != weight
                if not (along_x or along_y or along_z):
                    continue
                k_shell = k < shell or k >= l - shell
                if i_shell or j_shell or k_shell:
                    # Both ends within the shell: left out.
                    along_x = along_x and not (next_i_shell or j_shell or k_shell)
                    along_y = along_y and not (i_shell or next_j_shell or k_shell)
                    along_z = along_z and not (i_shell or j_shell or k + 1 < shell
                                               or k + 1 >= l - shell)
                    if not (along_x or along_y or along_z):
                        continue
                along_x_count += 1 if along_x else 0
                along_yz_count += (1 if along_y else 0) + (1 if along_z else 0)
                j_low = min(j_low, j)
                j_high = max(j_high, j + 1 if along_y else j)
                k_low = min(k_low, k)
                k_high = max(k_high, k + 1 if along_z else k)
        count_x[i] = along_x_count
        count_yz[i] = along_yz_count
        low_j[i] = j_low
        high_j[i] = j_high
        low_k[i] = k_low
        high_k[i] = k_high
    box[:] = 0
    box[6] = shell
    total = 0
    i0, i1, j0, j1, k0, k1 = m, -1, n, -1, l, -1
    for i in range(m):
        total += count_x[i] + count_yz[i]
        if high_j[i] < 0:
            continue
        i0 = min(i0, i)
        # Plane i's x-weights join it to plane i + 1.
        i1 = max(i1, i + 1 if count_x[i] else i)
        j0 = min(j0, low_j[i])
        j1 = max(j1, high_j[i])
        k0 = min(k0, low_k[i])
        k1 = max(k1, high_k[i])
    if total:
        box[0], box[1], box[2], box[3], box[4], box[5] = i0, i1 + 1, j0, j1 + 1, k0, k1 + 1
    return total


@njit(cache=True, inline="always")
def _inner_row(i, j, m, n):
    """Whether row ``(i, j)`` has all four neighbour rows."""
    return 0 < i < m - 1 and 0 < j < n - 1


@njit(cache=True, inline="always")
def _inner_columns(k_from, k_to, step, l):
    """``range(k_from, k_to, step)`` split at the sides: ``(first, stop, resume)``, its
    columns ``1 <= k <= l - 2`` being ``range(first, stop, step)``, those before
    ``range(k_from, min(first, k_to), step)`` and those after ``range(resume, k_to, step)``."""
    first = k_from
    if first < 1:
        first += step * ((1 - first + step - 1) // step)
    stop = max(min(k_to, l - 1), first)
    resume = first + step * ((stop - first + step - 1) // step)
    return first, stop, resume


@njit(cache=True, inline="always")
def _inner_values(x, iu, ju, k):
    """`_neighbour_values` at a point with all six neighbours, in the same order (so the
    same sum), from unsigned indices: with signed ones Numba wraps negative indices around,
    a select on every read that keeps the loop from vectorising (measured: a uniform
    residual over 129 x 128 x 128 took 6.0 ms with the loop from a column not known to be
    > 0, 2.0 from column 0, whose first iteration the compiler peels)."""
    one = np.uint64(1)
    return (x[iu - one, ju, k] + x[iu + one, ju, k] + x[iu, ju - one, k] + x[iu, ju + one, k]
            + x[iu, ju, k - one] + x[iu, ju, k + one])


@njit(cache=True, inline="always")
def _neighbour_values(x, i, j, k, m, n, l):
    """Sum of ``x`` over the in-range neighbours of ``[i, j, k]``."""
    summed = 0.0
    if i > 0:
        summed += x[i - 1, j, k]
    if i < m - 1:
        summed += x[i + 1, j, k]
    if j > 0:
        summed += x[i, j - 1, k]
    if j < n - 1:
        summed += x[i, j + 1, k]
    if k > 0:
        summed += x[i, j, k - 1]
    if k < l - 1:
        summed += x[i, j, k + 1]
    return summed


@njit(cache=True, inline="always")
def _sweep_run_sides(x, b, inverse, weight, i, j, k_from, k_to, m, n, l):
    for k in range(k_from, k_to, 2):
        x[i, j, k] = (b[i, j, k] + weight * _neighbour_values(x, i, j, k, m, n, l)
                      ) * inverse[i, j, k]


@njit(cache=True, inline="always")
def _sweep_run_inner(x, b, inverse_value, weight, i, j, k_from, k_to):
    # ``inverse_value``: the one value of the inverse here (`inner_value_kernel_3d`): the
    # sweep reads x and b only, a third less than with the inverse's array.
    iu, ju = np.uint64(i), np.uint64(j)
    for k in range(np.uint64(k_from), np.uint64(k_to), np.uint64(2)):
        x[iu, ju, k] = (b[iu, ju, k] + weight * _inner_values(x, iu, ju, k)) * inverse_value


@njit(cache=True, inline="always")
def _sweep_run_uniform(x, b, inverse, inverse_value, weight, i, j, k_from, k_to, m, n, l):
    if not _inner_row(i, j, m, n) or k_from >= k_to:
        _sweep_run_sides(x, b, inverse, weight, i, j, k_from, k_to, m, n, l)
        return
    first, stop, resume = _inner_columns(k_from, k_to, 2, l)
    _sweep_run_sides(x, b, inverse, weight, i, j, k_from, min(first, k_to), m, n, l)
    _sweep_run_inner(x, b, inverse_value, weight, i, j, first, stop)
    _sweep_run_sides(x, b, inverse, weight, i, j, resume, k_to, m, n, l)


@njit(cache=True, inline="always")
def _sweep_run_weighted(x, b, inverse, weights_x, weights_y, weights_z, i, j, k_from, k_to,
                        m, n, l):
    for k in range(k_from, k_to, 2):
        inv = inverse[i, j, k]
        if inv == 0.0:
            x[i, j, k] = 0.0
            continue
        coupled = _coupled_sum(weights_x, weights_y, weights_z, x, i, j, k, m, n, l)
        x[i, j, k] = (b[i, j, k] + coupled) * inv


@njit(cache=True, inline="always")
def _half_sweep_plane(x, b, inverse, weights_x, weights_y, weights_z, weight, inverse_value, i,
                      colour, from_zero, box):
    """The points of ``colour`` on plane ``i``: ``x = (b + sum w x_nb) / D`` (0 where
    inactive), with the one ``weight`` outside ``box`` and its shell unless it is
    `NOT_UNIFORM`;
    ``from_zero``: x is 0 everywhere before, so the plane becomes ``b / D`` on ``colour``
    and 0 on the other."""
    m, n, l = x.shape
    for j in range(n):
        start = (colour + i + j) & 1
        if from_zero:
            for k in range(l):
                x[i, j, k] = b[i, j, k] * inverse[i, j, k] if (k & 1) == start else 0.0
        elif weight != NOT_UNIFORM:
            ka, kb, kc, kd = _row_spans(box, i, j, m, n, l)
            # Each segment from the first column of this colour at or after its start.
            _sweep_run_weighted(x, b, inverse, weights_x, weights_y, weights_z, i, j, start,
                                ka, m, n, l)
            _sweep_run_uniform(x, b, inverse, inverse_value, weight, i, j,
                               ka + ((start - ka) & 1), kb, m, n, l)
            _sweep_run_weighted(x, b, inverse, weights_x, weights_y, weights_z, i, j,
                                kb + ((start - kb) & 1), kc, m, n, l)
            _sweep_run_uniform(x, b, inverse, inverse_value, weight, i, j,
                               kc + ((start - kc) & 1), kd, m, n, l)
            _sweep_run_weighted(x, b, inverse, weights_x, weights_y, weights_z, i, j,
                                kd + ((start - kd) & 1), l, m, n, l)
        else:
            _sweep_run_weighted(x, b, inverse, weights_x, weights_y, weights_z, i, j, start,
                                l, m, n, l)


def _make_sweep(loop):
    def kernel(x, b, inverse, weights_x, weights_y, weights_z, weight, inverse_value, first,
               from_zero, chunks, box):
        m = x.shape[0]
        second = 1 - first
        size = (m + chunks - 1) // chunks
        # Each chunk of planes walks its planes once: the first colour on plane i, then the
        # second on plane i - 1, whose neighbours of the first colour are all new by then.
        # The second colour on a chunk's end planes needs the neighbouring chunk's first
        # colour: it waits for the second loop.
        for c in loop(chunks):
            start = c * size
            stop = min(start + size, m)
            for i in range(start, stop + 1):
                if i < stop:
                    _half_sweep_plane(x, b, inverse, weights_x, weights_y, weights_z, weight,
                                      inverse_value, i, first, from_zero, box)
                plane = i - 1
                if plane < start or (plane == start and start > 0) or (
                        plane == stop - 1 and stop < m):
                    continue
                _half_sweep_plane(x, b, inverse, weights_x, weights_y, weights_z, weight,
                                  inverse_value, plane, second, False, box)
        for c in loop(chunks):
            start = c * size
            stop = min(start + size, m)
            if start >= stop:
                continue
            if start > 0:
                _half_sweep_plane(x, b, inverse, weights_x, weights_y, weights_z, weight,
                                  inverse_value, start, second, False, box)
            if stop < m and (stop - 1 != start or start == 0):
                _half_sweep_plane(x, b, inverse, weights_x, weights_y, weights_z, weight,
                                  inverse_value, stop - 1, second, False, box)
    return kernel


_sweep_serial, _sweep_parallel = serial_and_parallel(_make_sweep)


@njit(cache=True)
def sweep_kernel_3d(x, b, inverse, weights_x, weights_y, weights_z, weight, inverse_value,
                    first, from_zero, chunks, box):
    """One red-black Gauss-Seidel sweep on ``A x = b``: the points of colour ``first`` (`RED`:
    i + j + k even, `BLACK`: odd) get ``x = (b + sum w x_nb) / D``, then those of the other
    colour; ``weight``: the one value of all weights outside ``box`` and its shell (`NO_BOX`:
    of all), or `NOT_UNIFORM` (then the weight arrays are read everywhere);
    ``inverse_value``: with a uniform weight, the one value of ``inverse`` at the points
    with all six neighbours outside the box (`inner_value_kernel_3d`; the caller takes the
    weighted path where there is none); ``from_zero``: x starts at 0 (not read; no fill
    needed); ``chunks``:
    the number of plane ranges walked in parallel (the thread count: `numba.get_num_threads`
    from the caller, which a cached kernel cannot call).

    Both colours in one walk over the planes (the second one plane behind the first), which
    reads the arrays once instead of twice; the result is exactly that of the two half
    sweeps one after the other.
    """
    if x.size > STENCIL_PARALLEL_MINIMUM_3D:
        return _sweep_parallel(x, b, inverse, weights_x, weights_y, weights_z, weight,
                               inverse_value, first, from_zero, chunks, box)
    return _sweep_serial(x, b, inverse, weights_x, weights_y, weights_z, weight, inverse_value,
                         first, from_zero, 1, box)


def _make_inner_value(loop):
    def kernel(values, box, found):
        m, n, l = values.shape
        for i in loop(m):
            # Per plane: the one value, NaN where the plane has no such point, or
            # NOT_UNIFORM (no reduction across threads). A running minimum and maximum, which
            # vectorise, where comparing each value with the first did not (0.13 ms for a
            # 64^3 level).
            low = np.inf
            high = -np.inf
            for j in range(n):
                if not _inner_row(i, j, m, n):
                    continue
                ka, kb, kc, kd = _row_spans(box, i, j, m, n, l)
                for k in range(max(ka, 1), min(kb, l - 1)):
                    low = min(low, values[i, j, k])
                    high = max(high, values[i, j, k])
                for k in range(max(kc, 1), min(kd, l - 1)):
                    low = min(low, values[i, j, k])
                    high = max(high, values[i, j, k])
            found[i] = np.nan if low > high else (low if low == high else NOT_UNIFORM)
    return kernel


_inner_value_serial, _inner_value_parallel = serial_and_parallel(_make_inner_value)


def inner_value_kernel_3d(values, box):
    """The one value of ``values`` (a level's total or inverse) at the points that the
    uniform runs read without checks (all six neighbours there, outside ``box`` and its
    shell), or `NOT_UNIFORM` when they differ or there are none: the sweep and the
    Chebyshev pass then read one number there instead of an array. For the pressure it is
    the sum of the six weights; for the viscosity ``1 + 6 c``, the walls' ghosts and the
    bodies' cuts changing the diagonal only in the shell and the box. Called from Python
    (a few kernel calls and a NumPy reduction over the planes)."""
    found = np.empty(values.shape[0])
    if values.size > STENCIL_PARALLEL_MINIMUM_3D:
        _inner_value_parallel(values, box, found)
    else:
        _inner_value_serial(values, box, found)
    values = found[~np.isnan(found)]
    if not values.size or not (values == values[0]).all() or values[0] <= 0.0:
        return NOT_UNIFORM
    return float(values[0])


@njit(cache=True, inline="always")
def _apply_dot_run_sides(total, weight, p, q, i, j, k_from, k_to, m, n, l, plane):
    for k in range(k_from, k_to):
        value = (total[i, j, k] * p[i, j, k]
                 - weight * _neighbour_values(p, i, j, k, m, n, l))
        q[i, j, k] = value
        plane += value * p[i, j, k]
    return plane


@njit(cache=True, inline="always")
def _apply_dot_weighted_run(diagonal, weights_x, weights_y, weights_z, p, q, i, j, k_from,
                            k_to, m, n, l, plane):
    for k in range(k_from, k_to):
        d, coupled = _neighbour_sum(diagonal, weights_x, weights_y, weights_z, p, i, j, k, m,
                                    n, l)
        value = d * p[i, j, k] - coupled
        q[i, j, k] = value
        plane += value * p[i, j, k]
    return plane


def _make_apply_dot_uniform(loop):
    def kernel(total, weight, p, q, diagonal, weights_x, weights_y, weights_z, box):
        m, n, l = p.shape
        dot = 0.0
        for i in loop(m):
            plane = 0.0
            for j in range(n):
                kb, kc = _row_box(box, i, j, l)
                plane = _apply_dot_run_sides(total, weight, p, q, i, j, 0, kb, m, n, l, plane)
                plane = _apply_dot_weighted_run(diagonal, weights_x, weights_y, weights_z, p,
                                                q, i, j, kb, kc, m, n, l, plane)
                plane = _apply_dot_run_sides(total, weight, p, q, i, j, kc, l, m, n, l, plane)
            dot += plane
        return dot
    return kernel


_apply_dot_uniform_serial, _apply_dot_uniform_parallel = serial_and_parallel(
    _make_apply_dot_uniform, fastmath=_REDUCTION_MATH)


@njit(cache=True)
def apply_dot_uniform_kernel_3d(total, weight, p, q, diagonal, weights_x, weights_y,
                                weights_z, box):
    """`apply_dot_kernel_3d` for an operator whose weights all equal ``weight`` outside
    ``box`` (`NO_BOX`: everywhere; a box without a shell), with its ``total = diagonal +
    sum of weights``."""
    if p.size > STENCIL_PARALLEL_MINIMUM_3D:
        return _apply_dot_uniform_parallel(total, weight, p, q, diagonal, weights_x,
                                           weights_y, weights_z, box)
    return _apply_dot_uniform_serial(total, weight, p, q, diagonal, weights_x, weights_y,
                                     weights_z, box)
