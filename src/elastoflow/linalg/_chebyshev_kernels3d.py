"""Numba kernels of the Jacobi-preconditioned Chebyshev iteration on 7-point operators.

One pass of the iteration (Saad, *Iterative Methods for Sparse Linear Systems*, Alg. 12.1,
in its three-term form) reads the iterate ``x_k`` with its neighbours, the one before it
``x_{k-1}`` and ``b``, and writes ``x_{k+1}`` over ``x_{k-1}``: one sweep over four arrays
and the operator's totals, with no inner products, where a CG iteration with the same
preconditioner takes four passes (product and dot, step, Jacobi, direction). For the
strongly diagonal operators that take it (implicit viscosity) it needs one or two passes
more than CG takes iterations, and each costs a third of one.

The operator is read with one weight outside a box and a shell along the sides (the
viscosity operator's held side planes; `_kernels3d.uniform_box_kernel`), the arrays inside
them;
or with the arrays everywhere (`NOT_UNIFORM`). The variant is picked in Python, so that only
the ones a run uses are compiled (the one with the box, about two minutes).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from elastoflow._numba import serial_and_parallel
from elastoflow.linalg._kernels3d import (
    _REDUCTION_MATH,
    NOT_UNIFORM,
    STENCIL_PARALLEL_MINIMUM_3D,
    _coupled_sum,
    _inner_columns,
    _inner_row,
    _inner_values,
    _neighbour_values,
    _row_spans,
)


@njit(cache=True, inline="always")
def _next(value, total, current, before, scale_old, scale_new):
    """``x_{k+1}`` at one point from the residual ``value`` of ``x_k = current`` and
    ``x_{k-1} = before``; the first pass (``scale_old == 0``) does not use ``before``, which
    may hold anything (even NaN) then."""
    change = scale_new * value / total
    if scale_old != 0.0:
        change += scale_old * (current - before)
    return current + change


@njit(cache=True, inline="always")
def _run_inner(total_value, factor, weight, x, b, other, scale_old, i, j, k_from, k_to, plane):
    # Unsigned indices: see `_kernels3d._inner_values`. The total is the one value of the
    # points away from the sides outside the box (`_kernels3d.inner_value_kernel_3d`), ``factor`` is
    # ``scale_new / total_value``: one array and one division less a point.
    iu, ju = np.uint64(i), np.uint64(j)
    for k in range(np.uint64(k_from), np.uint64(k_to)):
        current = x[iu, ju, k]
        value = b[iu, ju, k] - total_value * current + weight * _inner_values(x, iu, ju, k)
        change = factor * value
        if scale_old != 0.0:
            change += scale_old * (current - other[iu, ju, k])
        other[iu, ju, k] = current + change
        plane += value * value
    return plane


@njit(cache=True, inline="always")
def _weighted_next(total, x, b, other, scale_old, scale_new, i, j, k, coupled):
    """``(x_{k+1}, residual)`` at a point of a weighted run; inactive points (no diagonal,
    no weights) stay 0, as the masked loads left them."""
    t = total[i, j, k]
    current = x[i, j, k]
    value = b[i, j, k] - t * current + coupled
    following = _next(value, t, current, other[i, j, k], scale_old, scale_new) if t > 0.0 else 0.0
    return following, value


@njit(cache=True, inline="always")
def _run_weighted_sides(total, weights_x, weights_y, weights_z, x, b, other, scale_old,
                        scale_new, i, j, k_from, k_to, m, n, l, plane):
    for k in range(k_from, k_to):
        coupled = _coupled_sum(weights_x, weights_y, weights_z, x, i, j, k, m, n, l)
        following, value = _weighted_next(total, x, b, other, scale_old, scale_new, i, j, k,
                                          coupled)
        other[i, j, k] = following
        plane += value * value
    return plane


@njit(cache=True, inline="always")
def _run_weighted_inner(total, weights_x, weights_y, weights_z, x, b, other, scale_old,
                        scale_new, i, j, k_from, k_to, plane):
    # Unsigned indices, all six neighbours there: the shell's rows away from the sides (a
    # tenth of a 128^3 viscosity level) ran at 6x a uniform point's cost with the checks.
    iu, ju = np.uint64(i), np.uint64(j)
    one = np.uint64(1)
    for k in range(np.uint64(k_from), np.uint64(k_to)):
        coupled = (weights_x[iu - one, ju, k] * x[iu - one, ju, k]
                   + weights_x[iu, ju, k] * x[iu + one, ju, k]
                   + weights_y[iu, ju - one, k] * x[iu, ju - one, k]
                   + weights_y[iu, ju, k] * x[iu, ju + one, k]
                   + weights_z[iu, ju, k - one] * x[iu, ju, k - one]
                   + weights_z[iu, ju, k] * x[iu, ju, k + one])
        following, value = _weighted_next(total, x, b, other, scale_old, scale_new, iu, ju, k,
                                          coupled)
        other[iu, ju, k] = following
        plane += value * value
    return plane


@njit(cache=True, inline="always")
def _run_weighted(total, weights_x, weights_y, weights_z, x, b, other, scale_old, scale_new,
                  i, j, k_from, k_to, m, n, l, plane):
    if not _inner_row(i, j, m, n) or k_from >= k_to:
        return _run_weighted_sides(total, weights_x, weights_y, weights_z, x, b, other,
                                   scale_old, scale_new, i, j, k_from, k_to, m, n, l, plane)
    first, stop, resume = _inner_columns(k_from, k_to, 1, l)
    plane = _run_weighted_sides(total, weights_x, weights_y, weights_z, x, b, other, scale_old,
                                scale_new, i, j, k_from, min(first, k_to), m, n, l, plane)
    plane = _run_weighted_inner(total, weights_x, weights_y, weights_z, x, b, other, scale_old,
                                scale_new, i, j, first, stop, plane)
    return _run_weighted_sides(total, weights_x, weights_y, weights_z, x, b, other, scale_old,
                               scale_new, i, j, resume, k_to, m, n, l, plane)



@njit(cache=True, inline="always")
def _run_sides(total, weight, x, b, other, scale_old, scale_new, i, j, k_from, k_to, m, n, l,
               plane):
    for k in range(k_from, k_to):
        t = total[i, j, k]
        current = x[i, j, k]
        value = b[i, j, k] - t * current + weight * _neighbour_values(x, i, j, k, m, n, l)
        other[i, j, k] = _next(value, t, current, other[i, j, k], scale_old, scale_new)
        plane += value * value
    return plane


@njit(cache=True, inline="always")
def _run(total, total_value, factor, weight, x, b, other, scale_old, scale_new, i, j, k_from,
         k_to, m, n, l, plane):
    # A run from a column not known to be 0: the columns with all six neighbours take the
    # unsigned indices, the others the checked reads (as `_kernels3d._sweep_run_uniform`).
    if not _inner_row(i, j, m, n) or k_from >= k_to:
        return _run_sides(total, weight, x, b, other, scale_old, scale_new, i, j, k_from, k_to,
                          m, n, l, plane)
    first, stop, resume = _inner_columns(k_from, k_to, 1, l)
    plane = _run_sides(total, weight, x, b, other, scale_old, scale_new, i, j, k_from,
                       min(first, k_to), m, n, l, plane)
    plane = _run_inner(total_value, factor, weight, x, b, other, scale_old, i, j, first, stop,
                       plane)
    return _run_sides(total, weight, x, b, other, scale_old, scale_new, i, j, resume, k_to, m,
                      n, l, plane)


def _make_pass(loop, weighted):
    # ``weighted`` is a closure constant: each variant compiles without the other's branch.
    # A row is five runs (`_row_spans`): the arrays, the one weight, the arrays (the box),
    # the one weight, the arrays. Written out, each run split at the sides: the parallel
    # variant takes about two minutes to compile. Two shorter forms compiled in 30 s and
    # ran 15-30 % slower (a loop over the five runs; rows away from the sides taking the
    # unchecked runs directly, measured in one process at 64^3 and 128^3).
    def kernel(total, total_value, weight, x, b, other, scale_old, scale_new, weights_x,
               weights_y, weights_z, box):
        m, n, l = x.shape
        factor = scale_new / total_value
        squared = 0.0
        for i in loop(m):
            plane = 0.0
            for j in range(n):
                if weighted:
                    plane = _run_weighted(total, weights_x, weights_y, weights_z, x, b, other,
                                          scale_old, scale_new, i, j, 0, l, m, n, l, plane)
                    continue
                ka, kb, kc, kd = _row_spans(box, i, j, m, n, l)
                plane = _run_weighted(total, weights_x, weights_y, weights_z, x, b, other,
                                      scale_old, scale_new, i, j, 0, ka, m, n, l, plane)
                plane = _run(total, total_value, factor, weight, x, b, other, scale_old,
                             scale_new, i, j, ka, kb, m, n, l, plane)
                plane = _run_weighted(total, weights_x, weights_y, weights_z, x, b, other,
                                      scale_old, scale_new, i, j, kb, kc, m, n, l, plane)
                plane = _run(total, total_value, factor, weight, x, b, other, scale_old,
                             scale_new, i, j, kc, kd, m, n, l, plane)
                plane = _run_weighted(total, weights_x, weights_y, weights_z, x, b, other,
                                      scale_old, scale_new, i, j, kd, l, m, n, l, plane)
            squared += plane
        return squared
    return kernel


_pass_serial, _pass_parallel = serial_and_parallel(
    lambda loop: _make_pass(loop, False), fastmath=_REDUCTION_MATH)
_pass_weighted_serial, _pass_weighted_parallel = serial_and_parallel(
    lambda loop: _make_pass(loop, True), fastmath=_REDUCTION_MATH)


def chebyshev_pass_kernel_3d(total: NDArray[np.float64], total_value: float, weight: float,
                             x: NDArray[np.float64], b: NDArray[np.float64],
                             other: NDArray[np.float64], scale_old: float, scale_new: float,
                             weights_x: NDArray[np.float64], weights_y: NDArray[np.float64],
                             weights_z: NDArray[np.float64], box: NDArray[np.int64]) -> float:
    """One Chebyshev pass: ``other = x + scale_new D^-1 (b - A x) + scale_old (x - other)``
    (``scale_old == 0``: ``other`` is not read), with ``D = total = diagonal + sum of
    weights``; returns ``|b - A x|^2``, the residual of ``x``, not of the new iterate.

    The operator is read with ``weight`` outside ``box`` and its shell, the weights'
    arrays inside, and ``total_value`` for ``total`` at the points away from the sides
    outside them (`_kernels3d.inner_value_kernel_3d`); with either `NOT_UNIFORM`, with the arrays
    everywhere. Inactive points (``total == 0``) get 0. Picked here, not in a compiled
    dispatcher, so that only the variants used compile."""
    parallel = x.size > STENCIL_PARALLEL_MINIMUM_3D
    if weight == NOT_UNIFORM or total_value == NOT_UNIFORM:
        kernel = _pass_weighted_parallel if parallel else _pass_weighted_serial
    else:
        kernel = _pass_parallel if parallel else _pass_serial
    return float(kernel(total, total_value, weight, x, b, other, scale_old, scale_new,
                        weights_x, weights_y, weights_z, box))
