"""Numba kernels of the 5-point operator on ``(m, n)`` arrays: application, connected
components, null-space projection and the fused Jacobi sweep."""

from __future__ import annotations

import numpy as np
from numba import njit, prange, uint64

from elastoflow._numba import serial_and_parallel
from elastoflow.linalg._banded import banded_solve_in_place


@njit(cache=True, inline="always")
def _neighbour_sum(diagonal, weights_x, weights_y, x, i, j, m, n):
    """Return ``(D, sum w x_nb)`` at ``[i, j]``, with ``D = diagonal + sum w``."""
    total = diagonal[i, j]
    coupled = 0.0
    if i > 0:
        w = weights_x[i - 1, j]
        total += w
        coupled += w * x[i - 1, j]
    if i < m - 1:
        w = weights_x[i, j]
        total += w
        coupled += w * x[i + 1, j]
    if j > 0:
        w = weights_y[i, j - 1]
        total += w
        coupled += w * x[i, j - 1]
    if j < n - 1:
        w = weights_y[i, j]
        total += w
        coupled += w * x[i, j + 1]
    return total, coupled


@njit(cache=True, parallel=True)
def apply_operator_kernel(diagonal, weights_x, weights_y, x, out):
    m, n = x.shape
    for i in prange(m):
        for j in range(n):
            total, coupled = _neighbour_sum(diagonal, weights_x, weights_y, x, i, j, m, n)
            out[i, j] = total * x[i, j] - coupled


@njit(cache=True, parallel=True)
def active_mask_kernel(diagonal, weights_x, weights_y, active):
    """Mark active points; return whether every active point has a positive diagonal."""
    m, n = diagonal.shape
    missing = 0
    for i in prange(m):
        for j in range(n):
            is_active = diagonal[i, j] > 0.0
            if i > 0 and weights_x[i - 1, j] > 0.0:
                is_active = True
            if i < m - 1 and weights_x[i, j] > 0.0:
                is_active = True
            if j > 0 and weights_y[i, j - 1] > 0.0:
                is_active = True
            if j < n - 1 and weights_y[i, j] > 0.0:
                is_active = True
            active[i, j] = is_active
            if is_active and diagonal[i, j] <= 0.0:
                missing += 1
    return missing == 0


@njit(cache=True, inline="always")
def _find(parent, k):
    while parent[k] != k:
        parent[k] = parent[parent[k]]
        k = parent[k]
    return k


@njit(cache=True)
def label_components_kernel(diagonal, weights_x, weights_y, active, labels):
    """Label connected components of active points.

    Runs of points joined along y are the union-find nodes, so a find is only needed where the
    pair of runs joined along x changes. Writes ``labels`` (-1 at inactive points, else
    0..count-1) and returns ``(count, singular)`` where ``singular[c]`` says component ``c`` has
    no positive diagonal.
    """
    m, n = diagonal.shape
    parent = np.empty(m * n, dtype=np.int64)
    runs = 0
    for i in range(m):
        for j in range(n):
            if not active[i, j]:
                labels[i, j] = -1
                continue
            if j > 0 and weights_y[i, j - 1] > 0.0:
                run = labels[i, j - 1]
            else:
                run = runs
                parent[run] = run
                runs += 1
            labels[i, j] = run
            if i > 0 and weights_x[i - 1, j] > 0.0:
                below = labels[i - 1, j]
                if (j > 0 and weights_x[i - 1, j - 1] > 0.0 and labels[i, j - 1] == run
                        and labels[i - 1, j - 1] == below):
                    continue
                a = _find(parent, run)
                b = _find(parent, below)
                if a != b:
                    parent[max(a, b)] = min(a, b)
    run_label = np.full(runs, -1, dtype=np.int64)
    count = 0
    for run in range(runs):
        root = _find(parent, run)
        if run_label[root] < 0:
            run_label[root] = count
            count += 1
        run_label[run] = run_label[root]
    singular = np.ones(count, dtype=np.bool_)
    for i in range(m):
        for j in range(n):
            run = labels[i, j]
            if run >= 0:
                component = run_label[run]
                labels[i, j] = component
                if diagonal[i, j] > 0.0:
                    singular[component] = False
    return count, singular


@njit(cache=True)
def remove_component_means_kernel(x, labels, singular, count):
    """Subtract, on every singular component, the mean of ``x`` over that component; returns
    the squared 2-norm of what was removed (``sum over components of size * mean^2``)."""
    m, n = x.shape
    sums = np.zeros(count)
    sizes = np.zeros(count)
    for i in range(m):
        for j in range(n):
            c = labels[i, j]
            if c >= 0 and singular[c]:
                sums[c] += x[i, j]
                sizes[c] += 1.0
    removed = 0.0
    for c in range(count):
        if sizes[c] > 0.0:
            sums[c] /= sizes[c]
            removed += sizes[c] * sums[c] * sums[c]
    for i in range(m):
        for j in range(n):
            c = labels[i, j]
            if c >= 0 and singular[c]:
                x[i, j] -= sums[c]
    return removed


@njit(cache=True, inline="always")
def _jacobi_row(diagonal, weights_x, weights_y, rhs, x, x_next, omega, i, m, n):
    squared = 0.0
    for j in range(n):
        total, coupled = _neighbour_sum(diagonal, weights_x, weights_y, x, i, j, m, n)
        residual = rhs[i, j] - total * x[i, j] + coupled
        squared += residual * residual
        if total > 0.0:
            x_next[i, j] = x[i, j] + omega * residual / total
        else:
            x_next[i, j] = 0.0
    return squared


def _make_jacobi_sweep(loop):
    def kernel(diagonal, weights_x, weights_y, rhs, x, x_next, omega):
        m, n = x.shape
        squared = 0.0
        for i in loop(m):
            squared += _jacobi_row(diagonal, weights_x, weights_y, rhs, x, x_next, omega, i, m, n)
        return squared
    return kernel


_jacobi_sweep_serial, _jacobi_sweep_parallel = serial_and_parallel(_make_jacobi_sweep)


@njit(cache=True)
def jacobi_kernel(diagonal, weights_x, weights_y, rhs, x, x_next, omega, threshold,
                  max_iterations):
    """Weighted Jacobi sweeps ``x <- x + omega D^-1 (b - A x)`` until ``|b - A x|^2 <=
    threshold`` or ``max_iterations`` sweeps. Returns ``(sweeps, |b - A x|^2)``; the iterate
    ends in ``x``."""
    parallel = x.size >= 64 * 64
    current = x
    following = x_next
    iterations = 0
    while True:
        if parallel:
            squared = _jacobi_sweep_parallel(diagonal, weights_x, weights_y, rhs, current,
                                             following, omega)
        else:
            squared = _jacobi_sweep_serial(diagonal, weights_x, weights_y, rhs, current,
                                           following, omega)
        if squared <= threshold or iterations >= max_iterations:
            if iterations % 2 == 1:
                x[:, :] = current
            return iterations, squared
        current, following = following, current
        iterations += 1


# Multigrid-preconditioned CG on padded flat levels.
#
# Each level of ``m x n`` unknowns is stored flat with a ring of ghost points, index
# ``k = (i + 1) * (n + 2) + (j + 1)``. Ghost values and every weight to a ghost are 0, which
# makes the stencil loops branch-free. ``weights_x[k]`` couples ``k`` with ``k + n + 2`` (the
# +x neighbour), ``weights_y[k]`` couples ``k`` with ``k + 1``; ``total[k]`` is the diagonal
# plus the four weights and ``inverse[k]`` its inverse (0 at inactive points).

# Levels and vectors with more points than this run in parallel; below, the work per thread
# is too small for the region's start. With idle threads spinning briefly (the package sets
# GOMP_SPINCOUNT) a region starts in ~1.5 us; with sleeping threads it cost ~50 us, and the
# limit was 300^2. bar_in_jet at 256^2, ms per step with the fluid and solver limits at
# 300^2 / 128^2 / 96^2 / 64^2: 12.4 / 9.4-9.8 / 9.2 / 9.4-9.5.
PARALLEL_MINIMUM = 96 * 96
# Coarsening: the limit was 12^2 while the serial loop ran 10x slower than it does now (an
# inlined helper returning a tuple; 32^2 0.055 ms serial against 0.0075 threaded). Written
# out (`_coarsen_row`), CPU ms per coarse level serial / threaded at load 2: 128x64 0.046 /
# 0.089, 64x32 0.012 / 0.044, 16x8 0.0014 / 0.029; wall at 128^2 0.29 / 0.16, 256^2
# 0.75 / 0.76 (noisy, shared cores).
COARSEN_PARALLEL_MINIMUM = 128 * 128





def _make_pad_values_kernel(loop):
    def kernel(values, flat):
        m, n = values.shape
        stride = n + 2
        for i in loop(m):
            row = (i + 1) * stride + 1
            for j in range(n):
                flat[row + j] = values[i, j]
    return kernel


(_pad_values_kernel_serial,
 _pad_values_kernel_parallel) = serial_and_parallel(_make_pad_values_kernel)


@njit(cache=True)
def pad_values_kernel(values, flat):
    if values.size > PARALLEL_MINIMUM:
        return _pad_values_kernel_parallel(values, flat)
    return _pad_values_kernel_serial(values, flat)


def _make_unpad_values_kernel(loop):
    def kernel(flat, values):
        m, n = values.shape
        stride = n + 2
        for i in loop(m):
            row = (i + 1) * stride + 1
            for j in range(n):
                values[i, j] = flat[row + j]
    return kernel


(_unpad_values_kernel_serial,
 _unpad_values_kernel_parallel) = serial_and_parallel(_make_unpad_values_kernel)


@njit(cache=True)
def unpad_values_kernel(flat, values):
    if values.size > PARALLEL_MINIMUM:
        return _unpad_values_kernel_parallel(flat, values)
    return _unpad_values_kernel_serial(flat, values)


@njit(cache=True, inline="always")
def _coarsen_row(fine_diagonal, fine_weights_x, fine_weights_y, fine_total, coarse_diagonal,
                 coarse_weights_x, coarse_weights_y, coarse_total, coarse_inverse, row_c, n_c,
                 fine_row0, stride_f, stride_c):
    # Face weights are averaged over the two fine faces of a coarse face, so that the coarse
    # operator is the rediscretised one rather than the twice too stiff piecewise-constant
    # Galerkin operator. The diagonal mixes two kinds of terms: a volume term (Helmholtz
    # identity) present in every child, which adds up over the children, and boundary terms
    # (Dirichlet faces, cut faces), which like face weights are averaged. The part shared by
    # all active children is taken as volume, the rest as boundary.
    fine_row1 = fine_row0 + stride_f
    kc = (row_c + 1) * stride_c + 1
    for jc in range(n_c):
        k0 = fine_row0 + 2 * jc
        k1 = fine_row1 + 2 * jc
        coarse_sum = 0.0
        count = 0
        smallest = np.inf
        # The four children in this order (the sum's order); written out rather than through
        # an inlined helper returning a tuple, which compiled to a loop 10x slower (serial
        # 128x64: 0.45 -> 0.05 ms).
        for k in (k0, k0 + 1, k1, k1 + 1):
            if fine_total[k] > 0.0:
                coarse_sum += fine_diagonal[k]
                count += 1
                smallest = min(smallest, fine_diagonal[k])
        volume = count * smallest if count > 0 else 0.0
        diagonal = volume + 0.5 * (coarse_sum - volume)
        weight_x = 0.5 * (fine_weights_x[k1] + fine_weights_x[k1 + 1])
        weight_y = 0.5 * (fine_weights_y[k0 + 1] + fine_weights_y[k1 + 1])
        # The -x and -y coarse weights belong to other rows (other threads): recompute them.
        below = k1 - 2 * stride_f
        weight_minus_x = 0.5 * (fine_weights_x[below] + fine_weights_x[below + 1])
        weight_minus_y = 0.5 * (fine_weights_y[k0 - 1] + fine_weights_y[k1 - 1])
        coarse_diagonal[kc + jc] = diagonal
        coarse_weights_x[kc + jc] = weight_x
        coarse_weights_y[kc + jc] = weight_y
        value = diagonal + weight_x + weight_y + weight_minus_x + weight_minus_y
        coarse_total[kc + jc] = value
        coarse_inverse[kc + jc] = 1.0 / value if value > 0.0 else 0.0


def _make_coarsen(loop):
    def kernel(fine_diagonal, fine_weights_x, fine_weights_y, fine_total, coarse_diagonal,
               coarse_weights_x, coarse_weights_y, coarse_total, coarse_inverse, n_f, m_c, n_c):
        """Coarse level (diagonal, weights, totals, inverses) from the fine one."""
        stride_f = n_f + 2
        stride_c = n_c + 2
        for ic in loop(m_c):
            _coarsen_row(fine_diagonal, fine_weights_x, fine_weights_y, fine_total, coarse_diagonal,
                         coarse_weights_x, coarse_weights_y, coarse_total, coarse_inverse, ic, n_c,
                         (2 * ic + 1) * stride_f + 1, stride_f, stride_c)
    return kernel


coarsen_serial, coarsen_parallel = serial_and_parallel(_make_coarsen)


@njit(cache=True, inline="always")
def _smooth_row(x, b, inverse, weights_x, weights_y, row, start, n, stride):
    # Unsigned indices spare Numba's negative-index wraparound test on every access (about
    # twice as fast here).
    one = uint64(1)
    step = uint64(2)
    up = uint64(stride)
    k = uint64(row + start)
    end = uint64(row + n)
    while k < end:
        x[k] = inverse[k] * (b[k] + weights_x[k] * x[k + up] + weights_x[k - up] * x[k - up]
                             + weights_y[k] * x[k + one] + weights_y[k - one] * x[k - one])
        k += step


@njit(cache=True, inline="always")
def _first_smooth_row(x, b, inverse, row, start, n):
    # First half sweep from x = 0: points of this colour get D^-1 b, the others are set to 0
    # so that the level needs no separate clearing pass.
    step = uint64(2)
    end = uint64(row + n)
    k = uint64(row + start)
    while k < end:
        x[k] = inverse[k] * b[k]
        k += step
    k = uint64(row + 1 - start)
    while k < end:
        x[k] = 0.0
        k += step


@njit(cache=True, inline="always")
def _span(first, stop, ranged, i, n):
    """Columns ``[low, high)`` of row ``i`` that hold its active points: ``first[i]``,
    ``stop[i]`` when ``ranged``, else the whole row."""
    if ranged:
        return first[i], stop[i]
    return 0, n


@njit(cache=True, inline="always")
def _smooth_span(x, b, inverse, weights_x, weights_y, row, start, low, high, stride):
    # The row's points of colour ``start`` in columns [low, high): the row seen from column
    # ``low`` (the same loop as the whole row when low = 0, high = n).
    _smooth_row(x, b, inverse, weights_x, weights_y, row + low, (start + low) & 1, high - low,
                stride)


@njit(cache=True, inline="always")
def _sweep_rows(x, b, inverse, weights_x, weights_y, n, first_colour, from_zero, row_start,
                row_stop, first, stop, ranged):
    # One Gauss-Seidel sweep (first colour, then the other) over rows [row_start, row_stop) in a
    # single pass: the second colour of row i - 1 only needs the first colour of rows i - 2 ..
    # i, so it is updated right after row i. The second colour of the block's first and last
    # rows depends on rows of the neighbouring blocks and is left to _sweep_block_edges.
    # ``ranged``: only the columns [first[i], stop[i]) of each row (see `pcg_kernel`).
    stride = n + 2
    for i in range(row_start, row_stop):
        row = (i + 1) * stride + 1
        start = (i + first_colour) & 1
        low, high = _span(first, stop, ranged, i, n)
        if from_zero:
            _first_smooth_row(x, b, inverse, row + low, (start + low) & 1, high - low)
        else:
            _smooth_span(x, b, inverse, weights_x, weights_y, row, start, low, high, stride)
        if i - 1 > row_start:
            # Row i - 1's second colour starts where row i's first colour does.
            low, high = _span(first, stop, ranged, i - 1, n)
            _smooth_span(x, b, inverse, weights_x, weights_y, row - stride, start, low, high,
                         stride)


@njit(cache=True, inline="always")
def _sweep_block_edges(x, b, inverse, weights_x, weights_y, n, first_colour, row_start,
                       row_stop, first, stop, ranged):
    # Second-colour points of different rows are never neighbours, so the edge rows of all
    # blocks can be updated at once.
    stride = n + 2
    row = (row_start + 1) * stride + 1
    low, high = _span(first, stop, ranged, row_start, n)
    _smooth_span(x, b, inverse, weights_x, weights_y, row, (row_start + first_colour + 1) & 1,
                 low, high, stride)
    last = row_stop - 1
    if last > row_start:
        row = (last + 1) * stride + 1
        low, high = _span(first, stop, ranged, last, n)
        _smooth_span(x, b, inverse, weights_x, weights_y, row, (last + first_colour + 1) & 1,
                     low, high, stride)


@njit(cache=True, parallel=True)
def smooth_parallel(x, b, inverse, weights_x, weights_y, m, n, first_colour, from_zero, first,
                    stop, ranged):
    """Red-black Gauss-Seidel sweep, ``first_colour`` (points with ``(i + j) % 2 ==
    first_colour``) first; ``from_zero`` starts from ``x = 0``; ``ranged``: only the columns
    ``[first[i], stop[i])`` of each row i (`pcg_kernel`)."""
    blocks = min(max(m // 32, 1), 16)
    for block in prange(blocks):
        _sweep_rows(x, b, inverse, weights_x, weights_y, n, first_colour, from_zero,
                    block * m // blocks, (block + 1) * m // blocks, first, stop, ranged)
    for block in prange(blocks):
        _sweep_block_edges(x, b, inverse, weights_x, weights_y, n, first_colour,
                           block * m // blocks, (block + 1) * m // blocks, first, stop, ranged)


@njit(cache=True)
def smooth_serial(x, b, inverse, weights_x, weights_y, m, n, first_colour, from_zero, first,
                  stop, ranged):
    _sweep_rows(x, b, inverse, weights_x, weights_y, n, first_colour, from_zero, 0, m, first,
                stop, ranged)
    _sweep_block_edges(x, b, inverse, weights_x, weights_y, n, first_colour, 0, m, first, stop,
                       ranged)


@njit(cache=True, inline="always")
def _residual_at(x, b, total, weights_x, weights_y, k, up):
    """``(b - A x)[k]`` for unsigned ``k`` and row stride ``up``."""
    one = uint64(1)
    return (b[k] - total[k] * x[k] + weights_x[k] * x[k + up] + weights_x[k - up] * x[k - up]
            + weights_y[k] * x[k + one] + weights_y[k - one] * x[k - one])


@njit(cache=True, inline="always")
def _restrict_row(x, b, total, inverse, weights_x, weights_y, coarse_b, m, n, ic, n_c):
    # Restriction is the transpose of piecewise-constant prolongation: the coarse right-hand
    # side is the sum of the fine residuals of the (up to four) children. After a sweep ending
    # on colour 1 the residual there is zero except at inactive points (where it is b), so only
    # colour 0 needs the stencil. Ghost children contribute exact zeros.
    stride = n + 2
    stride_c = n_c + 2
    kc = (ic + 1) * stride_c + 1
    for jc in range(n_c):
        coarse_b[kc + jc] = 0.0
    for i in range(2 * ic, min(2 * ic + 2, m)):
        row = (i + 1) * stride + 1
        odd = i & 1
        up = uint64(stride)
        for jc in range(n_c):
            k = uint64(row + 2 * jc + odd)
            other = uint64(row + 2 * jc + 1 - odd)
            value = _residual_at(x, b, total, weights_x, weights_y, k, up)
            if inverse[other] == 0.0:
                value += b[other]
            coarse_b[kc + jc] += value


@njit(cache=True, inline="always")
def _restrict_row_spans(x, b, total, inverse, weights_x, weights_y, coarse_b, m, n, ic, n_c,
                        first, stop):
    # `_restrict_row` over the children in the columns [first[i], stop[i]) of their rows i: the
    # children outside hold no active point, and their terms were exact zeros (an inactive
    # point has b = 0, no diagonal and no weights), so the sums are the same.
    stride = n + 2
    stride_c = n_c + 2
    kc = (ic + 1) * stride_c + 1
    for jc in range(n_c):
        coarse_b[kc + jc] = 0.0
    for i in range(2 * ic, min(2 * ic + 2, m)):
        row = (i + 1) * stride + 1
        odd = i & 1
        up = uint64(stride)
        low = first[i]
        high = stop[i]
        for jc in range(low // 2, (high + 1) // 2):
            j = 2 * jc + odd
            j_other = 2 * jc + 1 - odd
            value = 0.0
            if low <= j < high:
                value = _residual_at(x, b, total, weights_x, weights_y, uint64(row + j), up)
            if low <= j_other < high and inverse[row + j_other] == 0.0:
                value += b[row + j_other]
            coarse_b[kc + jc] += value


def _make_restrict(loop):
    def kernel(x, b, total, inverse, weights_x, weights_y, coarse_b, m, n, m_c, n_c, first,
               stop, ranged):
        for ic in loop(m_c):
            if ranged:
                _restrict_row_spans(x, b, total, inverse, weights_x, weights_y, coarse_b, m, n,
                                    ic, n_c, first, stop)
            else:
                _restrict_row(x, b, total, inverse, weights_x, weights_y, coarse_b, m, n, ic,
                              n_c)
    return kernel


restrict_serial, restrict_parallel = serial_and_parallel(_make_restrict)


@njit(cache=True, inline="always")
def _prolong_row(coarse_x, x, i, n, n_c):
    one = uint64(1)
    row = uint64((i + 1) * (n + 2) + 1)
    kc = uint64((i // 2 + 1) * (n_c + 2) + 1)
    for jc in range(n // 2):
        value = coarse_x[kc]
        x[row] += value
        x[row + one] += value
        row += uint64(2)
        kc += one
    if n % 2 == 1:
        x[row] += coarse_x[kc]


def _make_prolong(loop):
    def kernel(coarse_x, x, m, n, n_c, first, stop, ranged):
        for i in loop(m):
            if ranged:
                # Only the row's active columns (the others are not read: `pcg_kernel`).
                row = (i + 1) * (n + 2) + 1
                kc = (i // 2 + 1) * (n_c + 2) + 1
                for j in range(first[i], stop[i]):
                    x[row + j] += coarse_x[kc + j // 2]
            else:
                _prolong_row(coarse_x, x, i, n, n_c)
    return kernel


prolong_serial, prolong_parallel = serial_and_parallel(_make_prolong)


@njit(cache=True)
def semidefinite_cholesky_kernel(matrix, factor):
    """Cholesky factor of a symmetric positive semi-definite matrix, in place in ``factor``.

    A pivot that vanishes (relative to its diagonal entry) marks a point of a singular
    component, or an inactive point; its column is zeroed, which pins that unknown to 0. The
    resulting solve ``x = E (A_kept)^-1 E^T b`` is symmetric positive semi-definite.
    """
    size = matrix.shape[0]
    factor[:, :] = matrix
    for k in range(size):
        pivot = factor[k, k]
        if not (pivot > 1e-6 * matrix[k, k] and matrix[k, k] > 0.0):
            for i in range(k, size):
                factor[i, k] = 0.0
            continue
        root = np.sqrt(pivot)
        factor[k, k] = root
        for i in range(k + 1, size):
            factor[i, k] /= root
        for j in range(k + 1, size):
            value = factor[j, k]
            if value != 0.0:
                for i in range(j, size):
                    factor[i, j] -= factor[i, k] * value


@njit(cache=True)
def coarse_solve_kernel(factor, b, x, m, n):
    """Solve the coarsest level with its semi-definite Cholesky factor (padded ``b``, ``x``)."""
    stride = n + 2
    size = m * n
    values = np.empty(size)
    for i in range(m):
        for j in range(n):
            values[i * n + j] = b[(i + 1) * stride + j + 1]
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
    for i in range(m):
        for j in range(n):
            x[(i + 1) * stride + j + 1] = values[i * n + j]


@njit(cache=True)
def build_coarse_levels_kernel(rows, cols, offsets, diagonal, weights_x, weights_y, total,
                               inverse, dense, factor):
    """Fill every coarse level from the loaded fine level (`coarsen_serial` or
    `coarsen_parallel` by size, level after level) and factor the coarsest one
    (`dense_matrix_kernel`, `semidefinite_cholesky_kernel`), in place: the same values as
    the calls one by one, for one dispatch instead of one per level (the free surface
    rebuilds its hierarchy every step)."""
    levels = rows.shape[0]
    for level in range(1, levels):
        fine_start = offsets[level - 1]
        start = offsets[level]
        stop = offsets[level + 1]
        m = rows[level]
        n = cols[level]
        if m * n > COARSEN_PARALLEL_MINIMUM:
            coarsen_parallel(diagonal[fine_start:start], weights_x[fine_start:start],
                             weights_y[fine_start:start], total[fine_start:start],
                             diagonal[start:stop], weights_x[start:stop],
                             weights_y[start:stop], total[start:stop], inverse[start:stop],
                             cols[level - 1], m, n)
        else:
            coarsen_serial(diagonal[fine_start:start], weights_x[fine_start:start],
                           weights_y[fine_start:start], total[fine_start:start],
                           diagonal[start:stop], weights_x[start:stop], weights_y[start:stop],
                           total[start:stop], inverse[start:stop], cols[level - 1], m, n)
    last = levels - 1
    start = offsets[last]
    stop = offsets[last + 1]
    dense_matrix_kernel(diagonal[start:stop], weights_x[start:stop], weights_y[start:stop],
                        rows[last], cols[last], dense)
    semidefinite_cholesky_kernel(dense, factor)


@njit(cache=True)
def v_cycle(levels, r, z, sweeps, first, last, ranged, fine_parallel):
    """Symmetric V-cycle ``z = M r``: red-black Gauss-Seidel before, black-red after.
    ``levels`` bundles the hierarchy (`_Hierarchy.levels`): rows, cols and offsets of every
    level, their diagonal, weights, totals and inverse totals, the levels' x and b, and the
    coarsest level's factor. ``ranged``: every level but the coarsest only in the columns
    ``[first[k + i], last[k + i])`` of each of its rows i, k the rows of the finer levels
    (`pcg_kernel`, `level_spans_kernel`); ``fine_parallel``: whether the finest level's
    sweeps, restriction and prolongation use the threads (they have no sums, so the values
    do not depend on it)."""
    (rows, cols, offsets, _, weights_x, weights_y, total, inverse, level_x, level_b,
     coarse_factor) = levels
    count = rows.shape[0]
    row_start = 0
    for level in range(count - 1):
        m = rows[level]
        n = cols[level]
        level_first = first[row_start:row_start + m] if ranged else first
        last_columns = last[row_start:row_start + m] if ranged else last
        row_start += m
        start = offsets[level]
        stop = offsets[level + 1]
        if level == 0:
            x = z
            b = r
        else:
            x = level_x[start:stop]
            b = level_b[start:stop]
        inv = inverse[start:stop]
        wx = weights_x[start:stop]
        wy = weights_y[start:stop]
        coarse_b = level_b[stop:offsets[level + 2]]
        if (fine_parallel if level == 0 else m * n > PARALLEL_MINIMUM):
            for sweep in range(sweeps):
                smooth_parallel(x, b, inv, wx, wy, m, n, 0, sweep == 0, level_first,
                                last_columns, ranged)
            restrict_parallel(x, b, total[start:stop], inv, wx, wy, coarse_b, m, n,
                              rows[level + 1], cols[level + 1], level_first, last_columns,
                              ranged)
        else:
            for sweep in range(sweeps):
                smooth_serial(x, b, inv, wx, wy, m, n, 0, sweep == 0, level_first,
                              last_columns, ranged)
            restrict_serial(x, b, total[start:stop], inv, wx, wy, coarse_b, m, n,
                            rows[level + 1], cols[level + 1], level_first, last_columns, ranged)
    coarsest = count - 1
    if coarsest == 0:
        coarse_solve_kernel(coarse_factor, r, z, rows[0], cols[0])
        return
    coarse_solve_kernel(coarse_factor, level_b[offsets[coarsest]:offsets[coarsest + 1]],
                        level_x[offsets[coarsest]:offsets[coarsest + 1]], rows[coarsest],
                        cols[coarsest])
    for level in range(count - 2, -1, -1):
        m = rows[level]
        n = cols[level]
        row_start -= m
        level_first = first[row_start:row_start + m] if ranged else first
        last_columns = last[row_start:row_start + m] if ranged else last
        start = offsets[level]
        stop = offsets[level + 1]
        if level == 0:
            x = z
            b = r
        else:
            x = level_x[start:stop]
            b = level_b[start:stop]
        inv = inverse[start:stop]
        wx = weights_x[start:stop]
        wy = weights_y[start:stop]
        coarse_x = level_x[stop:offsets[level + 2]]
        if (fine_parallel if level == 0 else m * n > PARALLEL_MINIMUM):
            prolong_parallel(coarse_x, x, m, n, cols[level + 1], level_first, last_columns,
                             ranged)
            for sweep in range(sweeps):
                smooth_parallel(x, b, inv, wx, wy, m, n, 1, False, level_first, last_columns,
                                ranged)
        else:
            prolong_serial(coarse_x, x, m, n, cols[level + 1], level_first, last_columns,
                           ranged)
            for sweep in range(sweeps):
                smooth_serial(x, b, inv, wx, wy, m, n, 1, False, level_first, last_columns,
                              ranged)


@njit(cache=True, inline="always")
def _residual_norm_row(x, b, total, weights_x, weights_y, r, i, n, low, high):
    up = uint64(n + 2)
    row = (i + 1) * (n + 2) + 1
    k = uint64(row + low)
    end = uint64(row + high)
    squared = 0.0
    while k < end:
        value = _residual_at(x, b, total, weights_x, weights_y, k, up)
        r[k] = value
        squared += value * value
        k += uint64(1)
    return squared


@njit(cache=True, inline="always")
def _dot_row(a, b, i, n, low, high):
    row = (i + 1) * (n + 2) + 1
    k = uint64(row + low)
    end = uint64(row + high)
    total = 0.0
    while k < end:
        total += a[k] * b[k]
        k += uint64(1)
    return total


@njit(cache=True, inline="always")
def _search_direction_row(z, p, q, total, weights_x, weights_y, beta, i, n, low, high):
    one = uint64(1)
    up = uint64(n + 2)
    row = (i + 1) * (n + 2) + 1
    k = uint64(row + low)
    end = uint64(row + high)
    product = 0.0
    if beta == 0.0:
        # First direction of a (re)start: p and q hold stale values of an earlier solve, which
        # are not read, so they need no clearing pass.
        while k < end:
            direction = z[k]
            image = (total[k] * direction - weights_x[k] * z[k + up]
                     - weights_x[k - up] * z[k - up] - weights_y[k] * z[k + one]
                     - weights_y[k - one] * z[k - one])
            p[k] = direction
            q[k] = image
            product += direction * image
            k += one
        return product
    while k < end:
        applied = (total[k] * z[k] - weights_x[k] * z[k + up] - weights_x[k - up] * z[k - up]
                   - weights_y[k] * z[k + one] - weights_y[k - one] * z[k - one])
        direction = z[k] + beta * p[k]
        image = applied + beta * q[k]
        p[k] = direction
        q[k] = image
        product += direction * image
        k += one
    return product


@njit(cache=True, inline="always")
def _step_row(x, r, p, q, alpha, i, n, low, high):
    row = (i + 1) * (n + 2) + 1
    k = uint64(row + low)
    end = uint64(row + high)
    squared = 0.0
    while k < end:
        x[k] += alpha * p[k]
        value = r[k] - alpha * q[k]
        r[k] = value
        squared += value * value
        k += uint64(1)
    return squared


def _make_residual_norm(loop):
    def kernel(x, b, total, weights_x, weights_y, r, m, n, first, stop, ranged):
        """``r = b - A x``; return ``|r|^2``."""
        squared = 0.0
        for i in loop(m):
            low, high = _span(first, stop, ranged, i, n)
            squared += _residual_norm_row(x, b, total, weights_x, weights_y, r, i, n, low, high)
        return squared
    return kernel


residual_norm_serial, residual_norm_parallel = serial_and_parallel(_make_residual_norm)


def _make_dot(loop):
    def kernel(a, b, m, n, first, stop, ranged):
        total = 0.0
        for i in loop(m):
            low, high = _span(first, stop, ranged, i, n)
            total += _dot_row(a, b, i, n, low, high)
        return total
    return kernel


dot_serial, dot_parallel = serial_and_parallel(_make_dot)


def _make_search_direction(loop):
    def kernel(z, p, q, total, weights_x, weights_y, beta, m, n, first, stop, ranged):
        """``p = z + beta p`` and ``q = A z + beta q`` (= ``A p``) in one pass; return ``p . q``."""
        product = 0.0
        for i in loop(m):
            low, high = _span(first, stop, ranged, i, n)
            product += _search_direction_row(z, p, q, total, weights_x, weights_y, beta, i, n,
                                             low, high)
        return product
    return kernel


search_direction_serial, search_direction_parallel = serial_and_parallel(_make_search_direction)


def _make_step(loop):
    def kernel(x, r, p, q, alpha, m, n, first, stop, ranged):
        """``x += alpha p``, ``r -= alpha q``; return ``|r|^2``."""
        squared = 0.0
        for i in loop(m):
            low, high = _span(first, stop, ranged, i, n)
            squared += _step_row(x, r, p, q, alpha, i, n, low, high)
        return squared
    return kernel


step_serial, step_parallel = serial_and_parallel(_make_step)


# The threaded or serial twin: threaded on a large level unless only a few points of it are
# worked on (``parallel``, chosen once per solve by `pcg_kernel`).
@njit(cache=True)
def _residual_norm(x, b, total, weights_x, weights_y, r, m, n, first, stop, ranged, parallel):
    if parallel:
        return residual_norm_parallel(x, b, total, weights_x, weights_y, r, m, n, first, stop,
                                      ranged)
    return residual_norm_serial(x, b, total, weights_x, weights_y, r, m, n, first, stop,
                                ranged)


@njit(cache=True)
def _dot(a, b, m, n, first, stop, ranged, parallel):
    if parallel:
        return dot_parallel(a, b, m, n, first, stop, ranged)
    return dot_serial(a, b, m, n, first, stop, ranged)


@njit(cache=True)
def _search_direction(z, p, q, total, weights_x, weights_y, beta, m, n, first, stop, ranged,
                      parallel):
    if parallel:
        return search_direction_parallel(z, p, q, total, weights_x, weights_y, beta, m, n,
                                         first, stop, ranged)
    return search_direction_serial(z, p, q, total, weights_x, weights_y, beta, m, n, first,
                                   stop, ranged)


@njit(cache=True)
def _step(x, r, p, q, alpha, m, n, first, stop, ranged, parallel):
    if parallel:
        return step_parallel(x, r, p, q, alpha, m, n, first, stop, ranged)
    return step_serial(x, r, p, q, alpha, m, n, first, stop, ranged)


@njit(cache=True)
def level_spans_kernel(rows, cols, offsets, total, first, stop):
    """The spans of `active_spans_kernel` for every level but the finest, from the levels'
    totals (a coarse point is active when its total is > 0: the sum of its diagonal and
    weights, all >= 0), after the finest level's rows in ``first`` / ``stop``."""
    row_start = rows[0]
    for level in range(1, rows.shape[0]):
        m = rows[level]
        n = cols[level]
        stride = n + 2
        for i in range(m):
            row = offsets[level] + (i + 1) * stride + 1
            low = 0
            while low < n and not total[row + low] > 0.0:
                low += 1
            high = n
            while high > low and not total[row + high - 1] > 0.0:
                high -= 1
            if low == high:
                low = high = 0
            first[row_start + i] = low
            stop[row_start + i] = high
        row_start += m


@njit(cache=True)
def active_spans_kernel(active, first, stop):
    """For each row i of the ``(m, n)`` mask ``active``, the smallest column range
    ``[first[i], stop[i])`` holding its active points (``0, 0`` when none); returns whether
    some row is not whole (``[0, n)``), that is whether the spans save work, and the spans'
    total size."""
    m, n = active.shape
    partial = False
    points = 0
    for i in range(m):
        low = 0
        while low < n and not active[i, low]:
            low += 1
        high = n
        while high > low and not active[i, high - 1]:
            high -= 1
        if low == high:
            low = high = 0
        first[i] = low
        stop[i] = high
        points += high - low
        if low != 0 or high != n:
            partial = True
    return partial, points


@njit(cache=True)
def pcg_kernel(levels, b, x, r, p, q, z, threshold, max_iterations, sweeps, first, stop,
               ranged, span_points):
    """Preconditioned CG on level 0 until ``|b - A x|^2 <= threshold`` (checked on the true
    residual), ``levels`` as in `v_cycle`. Returns ``(iterations, |b - A x|^2)``.

    ``ranged``: level 0 is worked on only in the columns ``[first[i], stop[i])`` of each row
    i, which hold every active point (`active_spans_kernel`), and the coarser levels on
    theirs (`level_spans_kernel`, after level 0's rows): a free surface's liquid fills a
    few per cent of its box. The values there are bitwise those of the whole level: an
    inactive point has b = 0, no diagonal and no weights, so in the whole-level iteration
    every vector is 0 there (up to the sign of zero), and its neighbours read it with weight
    0; outside the spans the vectors keep stale finite values, read only with weight 0, and x
    keeps its loaded 0. ``span_points``, the spans' total size, decides whether the V-cycle's
    finest level uses the threads (the CG's sums keep the whole level's choice, and so their
    order)."""
    rows, cols, offsets, _, weights_x, weights_y, total = levels[:7]
    m = rows[0]
    n = cols[0]
    size = offsets[1]
    d_total = total[:size]
    wx = weights_x[:size]
    wy = weights_y[:size]
    spans = (first, stop, ranged)
    # A few thousand points of liquid: the threads' start costs more than the work.
    fine_parallel = m * n > PARALLEL_MINIMUM and (not ranged or span_points > PARALLEL_MINIMUM)
    squared = _residual_norm(x, b, d_total, wx, wy, r, m, n, *spans, fine_parallel)
    iterations = 0
    while True:
        # The recursive residual drifts from b - A x; confirm convergence on the true one and
        # restart CG from it when they disagree.
        if squared <= threshold:
            squared = _residual_norm(x, b, d_total, wx, wy, r, m, n, *spans,
                                     fine_parallel)
            if squared <= threshold:
                break
        if iterations >= max_iterations:
            squared = _residual_norm(x, b, d_total, wx, wy, r, m, n, *spans,
                                     fine_parallel)
            break
        v_cycle(levels, r, z, sweeps, *spans, fine_parallel)
        rz = _dot(r, z, m, n, *spans, fine_parallel)
        beta = 0.0
        pq = 1.0
        while iterations < max_iterations:
            pq = _search_direction(z, p, q, d_total, wx, wy, beta, m, n, *spans,
                                   fine_parallel)
            if pq <= 0.0:
                break
            alpha = rz / pq
            squared = _step(x, r, p, q, alpha, m, n, *spans, fine_parallel)
            iterations += 1
            if squared <= threshold:
                break
            v_cycle(levels, r, z, sweeps, *spans, fine_parallel)
            rz_next = _dot(r, z, m, n, *spans, fine_parallel)
            beta = rz_next / rz
            rz = rz_next
        if pq <= 0.0:
            squared = _residual_norm(x, b, d_total, wx, wy, r, m, n, *spans,
                                     fine_parallel)
            break
    return iterations, squared


@njit(cache=True, inline="always")
def _chebyshev_row(x, x_next, direction, b, total, inverse, weights_x, weights_y, scale_old,
                   scale_new, i, n):
    up = uint64(n + 2)
    k = uint64((i + 1) * (n + 2) + 1)
    end = k + uint64(n)
    squared = 0.0
    while k < end:
        value = _residual_at(x, b, total, weights_x, weights_y, k, up)
        squared += value * value
        change = scale_new * inverse[k] * value
        if scale_old != 0.0:
            # The first pass must not read the stale (possibly non-finite) direction.
            change += scale_old * direction[k]
        direction[k] = change
        x_next[k] = x[k] + change
        k += uint64(1)
    return squared


def _make_chebyshev_sweep(loop):
    def kernel(x, x_next, direction, b, total, inverse, weights_x, weights_y, scale_old, scale_new,
               m, n):
        squared = 0.0
        for i in loop(m):
            squared += _chebyshev_row(x, x_next, direction, b, total, inverse, weights_x,
                                      weights_y, scale_old, scale_new, i, n)
        return squared
    return kernel


_chebyshev_sweep_serial, _chebyshev_sweep_parallel = serial_and_parallel(_make_chebyshev_sweep)


@njit(cache=True)
def chebyshev_kernel(rows, cols, offsets, total, inverse, weights_x, weights_y, b, x, x_other,
                     direction, spread, threshold, max_iterations):
    """Jacobi-preconditioned Chebyshev iteration on level 0 (Saad, *Iterative Methods for
    Sparse Linear Systems*, Alg. 12.1) for an operator whose Jacobi iteration matrix has
    row sums ``<= spread < 1``: the eigenvalues of ``D^-1 A`` then lie in
    ``[1 - spread, 1 + spread]`` (Gershgorin), and each iteration reduces the error by about
    ``(sqrt(k) - 1) / (sqrt(k) + 1)``, ``k = (1 + spread) / (1 - spread)``, with no inner
    products. Each pass computes the true residual of the current iterate, so the iteration
    stops on ``|b - A x|^2 <= threshold`` exactly as CG does.

    Returns ``(iterations, |b - A x|^2, whether the solution is in x_other)``.
    """
    m = rows[0]
    n = cols[0]
    size = offsets[1]
    d_total = total[:size]
    inv = inverse[:size]
    wx = weights_x[:size]
    wy = weights_y[:size]
    parallel = m * n > PARALLEL_MINIMUM
    current = x
    following = x_other
    in_other = False
    # theta = 1 (centre of the interval), delta = spread (its half-width), sigma = 1 / delta.
    sigma = 1.0 / spread
    rho_old = spread
    scale_old = 0.0
    scale_new = 1.0
    iterations = 0
    while True:
        if parallel:
            squared = _chebyshev_sweep_parallel(current, following, direction, b, d_total, inv,
                                                wx, wy, scale_old, scale_new, m, n)
        else:
            squared = _chebyshev_sweep_serial(current, following, direction, b, d_total, inv,
                                              wx, wy, scale_old, scale_new, m, n)
        # The pass measured the residual of `current` before stepping to `following`.
        if squared <= threshold or iterations >= max_iterations:
            return iterations, squared, in_other
        current, following = following, current
        in_other = not in_other
        iterations += 1
        rho_new = 1.0 / (2.0 * sigma - rho_old)
        scale_old = rho_new * rho_old
        scale_new = 2.0 * rho_new / spread
        rho_old = rho_new


@njit(cache=True)
def dense_matrix_kernel(diagonal, weights_x, weights_y, m, n, matrix):
    """The level's operator as a dense ``(m n, m n)`` matrix (unpadded row-major numbering)."""
    stride = n + 2
    matrix[:, :] = 0.0
    for i in range(m):
        for j in range(n):
            a = i * n + j
            k = (i + 1) * stride + j + 1
            matrix[a, a] += diagonal[k]
            if i < m - 1:
                w = weights_x[k]
                matrix[a, a] += w
                matrix[a + n, a + n] += w
                matrix[a, a + n] -= w
                matrix[a + n, a] -= w
            if j < n - 1:
                w = weights_y[k]
                matrix[a, a] += w
                matrix[a + 1, a + 1] += w
                matrix[a, a + 1] -= w
                matrix[a + 1, a] -= w


def _make_sum_of_squares_kernel(loop):
    def kernel(values):
        m, n = values.shape
        total = 0.0
        for i in loop(m):
            for j in range(n):
                total += values[i, j] * values[i, j]
        return total
    return kernel


(_sum_of_squares_kernel_serial,
 _sum_of_squares_kernel_parallel) = serial_and_parallel(_make_sum_of_squares_kernel)


@njit(cache=True)
def sum_of_squares_kernel(values):
    """``sum values^2`` over an ``(m, n)`` array (kept out of BLAS, whose threads spin)."""
    if values.size > PARALLEL_MINIMUM:
        return _sum_of_squares_kernel_parallel(values)
    return _sum_of_squares_kernel_serial(values)


# Reassociation lets the reductions vectorise; NaN and inf keep their IEEE behaviour (no
# nnan/ninf flags), which the finiteness probes ``sum(value * 0)`` rely on.
_REDUCTION_MATH = {"reassoc", "nsz"}


def _make_probe_minimum(loop):
    def kernel(values):
        m, n = values.shape
        probe = 0.0
        smallest = np.inf
        for i in loop(m):
            row_probe = 0.0
            row_smallest = np.inf
            for j in range(n):
                value = values[i, j]
                row_probe += value * 0.0
                row_smallest = min(row_smallest, value)
            probe += row_probe
            smallest = min(smallest, row_smallest)
        return probe, smallest
    return kernel


(_probe_minimum_serial,
 _probe_minimum_parallel) = serial_and_parallel(_make_probe_minimum, fastmath=_REDUCTION_MATH)


@njit(cache=True)
def _probe_minimum(values):
    """``(sum of values * 0, minimum)``: the sum is 0 exactly when every entry is finite."""
    if values.size > PARALLEL_MINIMUM:
        return _probe_minimum_parallel(values)
    return _probe_minimum_serial(values)


@njit(cache=True)
def _count_non_finite(values):
    m, n = values.shape
    bad = 0
    smallest = np.inf
    for i in range(m):
        for j in range(n):
            value = values[i, j]
            if not np.isfinite(value):
                bad += 1
            elif value < smallest:
                smallest = value
    return bad, smallest


@njit(cache=True)
def finite_minimum_kernel(values):
    """Return ``(number of non-finite entries, minimum of the finite ones)`` of an ``(m, n)``
    array; one vectorised parallel pass when all are finite (the usual case)."""
    probe, smallest = _probe_minimum(values)
    if probe == 0.0:
        return 0, smallest
    return _count_non_finite(values)








def _make_pad_masked_kernel(loop):
    def kernel(values, active, flat):
        m, n = values.shape
        stride = n + 2
        probe = 0.0
        squared = 0.0
        for i in loop(m):
            row = (i + 1) * stride + 1
            row_probe = 0.0
            row_squared = 0.0
            for j in range(n):
                value = values[i, j]
                row_probe += value * 0.0
                value = value if active[i, j] else 0.0
                flat[row + j] = value
                row_squared += value * value
            probe += row_probe
            squared += row_squared
        return probe != 0.0, squared
    return kernel


_pad_masked_kernel_serial, _pad_masked_kernel_parallel = serial_and_parallel(
    _make_pad_masked_kernel, fastmath=_REDUCTION_MATH)


@njit(cache=True)
def pad_masked_kernel(values, active, flat):
    """Copy ``values`` into the padded ``flat``, 0 at inactive points; return ``(whether
    some entry is not finite, sum of squares of the copied values)``."""
    if values.size > PARALLEL_MINIMUM:
        return _pad_masked_kernel_parallel(values, active, flat)
    return _pad_masked_kernel_serial(values, active, flat)



@njit(cache=True, inline="always")
def _load_operator_row(diagonal, weights_x, weights_y, diagonal_flat, weights_x_flat,
                       weights_y_flat, total_flat, inverse_flat, active, ratio, i, m, n):
    """One row of `load_operator_kernel`; returns (changed, missing diagonal, weak) counts and
    the row's largest ratio of weights to total (the Jacobi iteration matrix's row sum)."""
    row = (i + 1) * (n + 2) + 1
    changed = 0
    missing = 0
    weak = 0
    spread = 0.0
    for j in range(n):
        k = row + j
        value = diagonal[i, j]
        if diagonal_flat[k] != value:
            changed += 1
        diagonal_flat[k] = value
        # Summed in the same order as the level's own products, term by term.
        total = value
        if i < m - 1:
            weight = weights_x[i, j]
            total += weight
        else:
            weight = 0.0
        if weights_x_flat[k] != weight:
            changed += 1
        weights_x_flat[k] = weight
        if i > 0:
            total += weights_x[i - 1, j]
        if j < n - 1:
            weight = weights_y[i, j]
            total += weight
        else:
            weight = 0.0
        if weights_y_flat[k] != weight:
            changed += 1
        weights_y_flat[k] = weight
        if j > 0:
            total += weights_y[i, j - 1]
        total_flat[k] = total
        inverse_flat[k] = 1.0 / total if total > 0.0 else 0.0
        # All terms are >= 0, so a point has a positive term exactly when their sum does.
        is_active = total > 0.0
        active[i, j] = is_active
        if is_active and value <= 0.0:
            missing += 1
        if value < ratio * (total - value):
            weak += 1
        if is_active:
            spread = max(spread, (total - value) / total)
    return changed, missing, weak, spread


def _make_load_operator_kernel(loop):
    def kernel(diagonal, weights_x, weights_y, diagonal_flat, weights_x_flat, weights_y_flat,
               total_flat, inverse_flat, active, ratio):
        m, n = diagonal.shape
        changed = 0
        missing = 0
        weak = 0
        spreads = np.empty(m)
        for i in loop(m):
            row_changed, row_missing, row_weak, row_spread = _load_operator_row(
                diagonal, weights_x, weights_y, diagonal_flat, weights_x_flat, weights_y_flat,
                total_flat, inverse_flat, active, ratio, i, m, n,
            )
            spreads[i] = row_spread
            changed += row_changed
            missing += row_missing
            weak += row_weak
        return changed > 0, missing == 0, weak == 0, spreads.max()
    return kernel


(_load_operator_kernel_serial,
 _load_operator_kernel_parallel) = serial_and_parallel(_make_load_operator_kernel)


@njit(cache=True)
def load_operator_kernel(diagonal, weights_x, weights_y, diagonal_flat, weights_x_flat,
                         weights_y_flat, total_flat, inverse_flat, active, ratio):
    """Copy the operator into the padded level-0 arrays in one pass.

    Fills totals and inverses and the ``(m, n)`` active mask, and returns whether any value
    differed from what the level held, whether every active point has a positive diagonal,
    whether every diagonal is at least ``ratio`` times the point's sum of weights (one pass
    instead of the four that comparing, padding, marking and the dominance test took), and
    the largest ratio of a point's weights to its total over the active points, a bound on
    the spectral radius of the Jacobi iteration matrix ``D^-1 (D - A)``.
    """
    if diagonal.size > PARALLEL_MINIMUM:
        return _load_operator_kernel_parallel(diagonal, weights_x, weights_y, diagonal_flat,
                                              weights_x_flat, weights_y_flat, total_flat,
                                              inverse_flat, active, ratio)
    return _load_operator_kernel_serial(diagonal, weights_x, weights_y, diagonal_flat,
                                        weights_x_flat, weights_y_flat, total_flat,
                                        inverse_flat, active, ratio)


@njit(cache=True)
def _low_rank_image(v, cells, term):
    """``term.w = M (B^T v)`` for ``B^T`` in CSR (row d: entries offsets[d]:offsets[d+1]) and
    ``M`` the dense block on the columns with a dense slot plus the banded inverse on the
    columns with a band slot (see `LowRankTerm.kernel_term`)."""
    (offsets, weights, _, dense_slot, matrix, band_slot, columns, rows, y, w, dense_y,
     dense_w, work) = term
    k = offsets.shape[0] - 1
    for d in range(k):
        total = 0.0
        for e in range(offsets[d], offsets[d + 1]):
            total += weights[e] * v[cells[e]]
        y[d] = total
        w[d] = 0.0
    size = matrix.shape[0]
    if size:
        for d in range(k):
            if dense_slot[d] >= 0:
                dense_y[dense_slot[d]] = y[d]
        for a in range(size):
            total = 0.0
            for b in range(size):
                total += matrix[a, b] * dense_y[b]
            dense_w[a] = total
        for d in range(k):
            if dense_slot[d] >= 0:
                w[d] += dense_w[dense_slot[d]]
    if columns.shape[0]:
        work[:] = 0.0
        for d in range(k):
            if band_slot[d] >= 0:
                work[band_slot[d]] = y[d]
        banded_solve_in_place(columns, rows, work)
        for d in range(k):
            if band_slot[d] >= 0:
                w[d] += work[band_slot[d]]


@njit(cache=True)
def _add_low_rank(v, out, other, cells, term, sign):
    """``out += sign scale B M B^T v`` on the touched points; returns
    ``other . (scale B M B^T v)``."""
    _low_rank_image(v, cells, term)
    offsets, weights, scale = term[0], term[1], term[2]
    w = term[9]
    product = 0.0
    k = offsets.shape[0] - 1
    for d in range(k):
        for e in range(offsets[d], offsets[d + 1]):
            cell = cells[e]
            value = scale * weights[e] * w[d]
            out[cell] += sign * value
            product += other[cell] * value
    return product


@njit(cache=True)
def low_rank_apply_kernel(v, cells, term, out):
    """``out += scale B M B^T v`` (flat arrays)."""
    _add_low_rank(v, out, v, cells, term, 1.0)


@njit(cache=True)
def low_rank_add_dot_kernel(v, out, other, cells, term, sign):
    """``out += sign scale B M B^T v``; returns ``other . (scale B M B^T v)`` (flat arrays of
    any grid: the 3D coupled solve's step, whose loop is in Python)."""
    return _add_low_rank(v, out, other, cells, term, sign)


@njit(cache=True)
def pcg_low_rank_kernel(levels, b, x, r, p, q, z, threshold, max_iterations, sweeps,
                        term_cells, term, operator_total):
    """`pcg_kernel` for ``A + C``, ``C = scale B M B^T`` (``B^T`` in CSR over the padded points
    ``term_cells``, ``M`` symmetric positive semi-definite, `term` as `LowRankTerm.kernel_term`
    bundles it): the multigrid levels hold ``A + diag(C)``
    as the preconditioner, ``operator_total`` (padded) is ``A``'s own diagonal plus weights.
    Returns ``(iterations, |b - (A + C) x|^2)``."""
    rows, cols, offsets, _, weights_x, weights_y = levels[:6]
    m = rows[0]
    n = cols[0]
    size = offsets[1]
    d_total = operator_total
    wx = weights_x[:size]
    wy = weights_y[:size]
    # The whole level (no spans): C's columns may reach any point.
    spans = (rows, rows, False)
    fine_parallel = m * n > PARALLEL_MINIMUM
    _residual_norm(x, b, d_total, wx, wy, r, m, n, *spans, fine_parallel)
    _add_low_rank(x, r, x, term_cells, term, -1.0)
    # Summed afresh: an update of |r|^2 by differences cancels catastrophically near the end.
    squared = _dot(r, r, m, n, *spans, fine_parallel)
    iterations = 0
    while True:
        if squared <= threshold or iterations >= max_iterations:
            break
        v_cycle(levels, r, z, sweeps, *spans, fine_parallel)
        rz = _dot(r, z, m, n, *spans, fine_parallel)
        beta = 0.0
        pq = 1.0
        while iterations < max_iterations:
            pq = _search_direction(z, p, q, d_total, wx, wy, beta, m, n, *spans,
                                   fine_parallel)
            extra = _add_low_rank(z, q, p, term_cells, term, 1.0)
            pq += extra
            if pq <= 0.0:
                break
            alpha = rz / pq
            squared = _step(x, r, p, q, alpha, m, n, *spans, fine_parallel)
            iterations += 1
            if squared <= threshold:
                break
            v_cycle(levels, r, z, sweeps, *spans, fine_parallel)
            rz_next = _dot(r, z, m, n, *spans, fine_parallel)
            beta = rz_next / rz
            rz = rz_next
        # Confirm on the true residual; restart from it when the recursion drifted.
        _residual_norm(x, b, d_total, wx, wy, r, m, n, *spans, fine_parallel)
        _add_low_rank(x, r, x, term_cells, term, -1.0)
        squared = _dot(r, r, m, n, *spans, fine_parallel)
        if pq <= 0.0 or squared <= threshold:
            break
    return iterations, squared


@njit(cache=True)
def _entries_by_point(points, offsets, weights, size):
    """``B``'s entries grouped by point: (start of each point's entries, their column,
    their weight)."""
    k = offsets.shape[0] - 1
    count = np.zeros(size + 1, np.int64)
    for d in range(k):
        for e in range(offsets[d], offsets[d + 1]):
            count[points[e] + 1] += 1
    for c in range(size):
        count[c + 1] += count[c]
    fill = count[:-1].copy()
    rows = np.empty(offsets[k], np.int64)
    values = np.empty(offsets[k])
    for d in range(k):
        for e in range(offsets[d], offsets[d + 1]):
            c = points[e]
            rows[fill[c]] = d
            values[fill[c]] = weights[e]
            fill[c] += 1
    return count, rows, values


@njit(cache=True)
def low_rank_band_gap(points, term, size):
    """The largest distance in the banded factor between two banded columns of ``B`` that
    meet at one point: how wide the inverse's band must be for the diagonal to be exact."""
    offsets, weights, band_slot = term[0], term[1], term[5]
    count, rows, _ = _entries_by_point(points, offsets, weights, size)
    widest = 0
    for c in range(size):
        for a in range(count[c], count[c + 1]):
            sa = band_slot[rows[a]]
            if sa < 0:
                continue
            for b in range(count[c], count[c + 1]):
                sb = band_slot[rows[b]]
                if sb >= 0 and abs(sa - sb) > widest:
                    widest = abs(sa - sb)
    return widest


@njit(cache=True)
def low_rank_diagonal_kernel(points, term, selected, size, out):
    """``out[c] += scale sum_{d,e} B_cd M_de B_ce`` for ``B^T`` in CSR (rows d) over ``points``,
    ``out`` of ``size`` points: the entries of each point are gathered first, so the cost is
    the sum over points of (entries at the point)^2, not points x k^2. ``M`` is read from the
    dense block and, for the banded part, from ``selected`` (the inverse's entries up to its
    width, `banded_selected_inverse`); a pair of banded columns further apart than that
    counts as 0, and a point's total is kept >= 0. Returns the number of such pairs (0:
    exact)."""
    offsets, weights, scale, dense_slot, matrix, band_slot = term[:6]
    width = selected.shape[1] - 1
    count, rows, values = _entries_by_point(points, offsets, weights, size)
    outside = 0
    for c in range(size):
        total = 0.0
        for a in range(count[c], count[c + 1]):
            da = rows[a]
            for b in range(count[c], count[c + 1]):
                db = rows[b]
                entry = 0.0
                if dense_slot[da] >= 0 and dense_slot[db] >= 0:
                    entry = matrix[dense_slot[da], dense_slot[db]]
                elif band_slot[da] >= 0 and band_slot[db] >= 0:
                    low = min(band_slot[da], band_slot[db])
                    gap = abs(band_slot[da] - band_slot[db])
                    if gap <= width:
                        entry = selected[low, gap]
                    else:
                        outside += 1
                total += values[a] * entry * values[b]
        if total > 0.0:
            out[c] += scale * total
    return outside
