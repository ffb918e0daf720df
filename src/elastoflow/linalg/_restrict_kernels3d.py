"""Numba kernel of the V-cycle's restriction for a level read with one weight.

The restriction sums the residual ``b - A x`` of each fine point into its coarse point. A
fine row's residual is first written to a buffer of one row, then summed in pairs into the
coarse row: the residual's loop then runs over contiguous columns, and away from the sides
and the bodies' box it reads ``x`` with unsigned indices, one weight and one total
(`_kernels3d.inner_value_kernel_3d`), a loop the compiler vectorises; the totals at the
row's two ends come from a compact copy (`row_ends`). Computing it point by
point in the pair loop, with the sides' and the box's checks on every point, took 1.7x a
Gauss-Seidel sweep of the same level (4.3 against 2.6 ms at 128^3).

Kept apart from `_kernels3d` so that it compiles on its own; its sums are those of
`_kernels3d.restrict_residual_kernel_3d` to rounding, and in the same order.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from elastoflow._numba import serial_and_parallel
from elastoflow.linalg._kernels3d import (
    NOT_UNIFORM,
    STENCIL_PARALLEL_MINIMUM_3D,
    _coupled_sum,
    _inner_columns,
    _inner_row,
    _inner_values,
    _neighbour_values,
    _row_box,
)


@njit(cache=True, inline="always")
def _residual_sides(total, weight, x, b, row, i, j, k_from, k_to, m, n, l):
    for k in range(k_from, k_to):
        row[k] = (b[i, j, k] - total[i, j, k] * x[i, j, k]
                  + weight * _neighbour_values(x, i, j, k, m, n, l))


@njit(cache=True, inline="always")
def _residual_inner(total_value, weight, x, b, row, i, j, k_from, k_to):
    # Unsigned indices: see `_kernels3d._inner_values`.
    iu, ju = np.uint64(i), np.uint64(j)
    for k in range(np.uint64(k_from), np.uint64(k_to)):
        row[k] = (b[iu, ju, k] - total_value * x[iu, ju, k]
                  + weight * _inner_values(x, iu, ju, k))


@njit(cache=True, inline="always")
def _residual_uniform(total, total_value, weight, x, b, row, i, j, k_from, k_to, m, n, l):
    if total_value == NOT_UNIFORM or not _inner_row(i, j, m, n) or k_from >= k_to:
        _residual_sides(total, weight, x, b, row, i, j, k_from, k_to, m, n, l)
        return
    first, stop, resume = _inner_columns(k_from, k_to, 1, l)
    _residual_sides(total, weight, x, b, row, i, j, k_from, min(first, k_to), m, n, l)
    _residual_inner(total_value, weight, x, b, row, i, j, first, stop)
    _residual_sides(total, weight, x, b, row, i, j, resume, k_to, m, n, l)


@njit(cache=True, inline="always")
def _residual_weighted(total, weights_x, weights_y, weights_z, x, b, row, i, j, k_from, k_to,
                       m, n, l):
    # Inside the box: inactive points (total 0) add nothing.
    for k in range(k_from, k_to):
        t = total[i, j, k]
        row[k] = (b[i, j, k] - t * x[i, j, k]
                  + _coupled_sum(weights_x, weights_y, weights_z, x, i, j, k, m, n, l)
                  ) if t > 0.0 else 0.0


@njit(cache=True, inline="always")
def _residual_row_inner(total_value, side_total, weight, x, b, row, i, j, m, n, l):
    """A row with all four neighbour rows, outside the box: the total as one number away
    from the row's ends, and at its two ends from ``side_total``."""
    iu, ju = np.uint64(i), np.uint64(j)
    # Unsigned indices: see `_kernels3d._inner_values`.
    for k in range(np.uint64(1), np.uint64(l - 1)):
        row[k] = (b[iu, ju, k] - total_value * x[iu, ju, k]
                  + weight * _inner_values(x, iu, ju, k))
    for end in range(2):
        k = end * (l - 1)
        row[k] = (b[i, j, k] - side_total[i, j, end] * x[i, j, k]
                  + weight * _neighbour_values(x, i, j, k, m, n, l))


def _make_restrict(loop):
    def kernel(x, b, total, total_value, side_total, weight, coarse_b, weights_x, weights_y,
               weights_z, box):
        m, n, l = x.shape
        mc, nc, lc = coarse_b.shape
        pairs = l >> 1
        for ic in loop(mc):
            row = np.empty(l)
            for jc in range(nc):
                for kc in range(lc):
                    coarse_b[ic, jc, kc] = 0.0
                for i in range(2 * ic, min(2 * ic + 2, m)):
                    for j in range(2 * jc, min(2 * jc + 2, n)):
                        k0, k1 = _row_box(box, i, j, l)
                        if (k0 >= k1 and l > 2 and total_value != NOT_UNIFORM
                                and _inner_row(i, j, m, n)):
                            _residual_row_inner(total_value, side_total, weight, x, b, row,
                                                i, j, m, n, l)
                        else:
                            _residual_uniform(total, total_value, weight, x, b, row, i, j, 0,
                                              k0, m, n, l)
                            _residual_weighted(total, weights_x, weights_y, weights_z, x, b,
                                               row, i, j, k0, k1, m, n, l)
                            _residual_uniform(total, total_value, weight, x, b, row, i, j,
                                              max(k1, k0), l, m, n, l)
                        for kc in range(pairs):
                            coarse_b[ic, jc, kc] += row[2 * kc] + row[2 * kc + 1]
                        if l & 1:
                            coarse_b[ic, jc, lc - 1] += row[l - 1]
    return kernel


_restrict_serial, _restrict_parallel = serial_and_parallel(_make_restrict)


def row_ends(values: NDArray[np.float64]) -> NDArray[np.float64]:
    """``values``' first and last columns, ``(m, n, 2)``, contiguous: what the restriction
    reads at a row's two ends where it reads the rest as one number. Read from ``values``
    itself, each end is a cache line of its own that nothing else in the pass reads: a
    quarter of the restriction's time at 128^3 (1.76 against 1.24 ms). (A Gauss-Seidel
    sweep, whose stride-2 runs cost more a point, gained 2 % from the same.)"""
    return np.ascontiguousarray(values[:, :, [0, -1]])


def restrict_residual_uniform_kernel_3d(x: NDArray[np.float64], b: NDArray[np.float64],
                                        total: NDArray[np.float64], total_value: float,
                                        side_total: NDArray[np.float64], weight: float,
                                        coarse_b: NDArray[np.float64],
                                        weights_x: NDArray[np.float64],
                                        weights_y: NDArray[np.float64],
                                        weights_z: NDArray[np.float64],
                                        box: NDArray[np.int64]) -> None:
    """``coarse_b`` = the residual ``b - A x`` summed over each coarse point's fine points
    (`_kernels3d.restrict_residual_kernel_3d`), for an operator whose weights all equal
    ``weight`` outside ``box`` (`NO_BOX`: everywhere), with no shell: a level with coarse
    levels below it never has one (`_mgpcg3d._Level.set_uniform`). ``total_value``: the one
    value of ``total`` at the points with all six neighbours outside the box
    (`_kernels3d.inner_value_kernel_3d`), or `NOT_UNIFORM` (``total`` is then read
    everywhere); ``side_total``: `row_ends` of ``total`` (not read with `NOT_UNIFORM`)."""
    kernel = _restrict_parallel if x.size > STENCIL_PARALLEL_MINIMUM_3D else _restrict_serial
    kernel(x, b, total, total_value, side_total, weight, coarse_b, weights_x, weights_y,
           weights_z, box)
