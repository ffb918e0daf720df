"""Kernels on a banded Cholesky factor: a solve with one right-hand side and the entries of
the inverse inside the band (Takahashi's recursion).

A strongly coupled pressure solve needs ``M = (U^T U)^-1`` (a body's compliance) only through
products ``M y`` inside conjugate gradient and the few entries of ``M`` that the
preconditioner's diagonal reads. Forming ``M`` densely on the interface's degrees of freedom
costs one solve per degree of freedom (about 20 ms a step for Turek-Hron's flag at 20 cells
per diameter: 600 columns); a product costs one solve, ``4 n b`` operations, and the entries
inside the band cost ``n b^2`` once.

The factor ``U`` (upper triangular, half-band ``b``) is given twice, laid out for the two
sweeps so that both read contiguous memory: ``columns[i, t] = U[i - b + t, i]`` and
``rows[i, t] = U[i, i + t]`` (zero outside the matrix).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def banded_solve_in_place(columns: np.ndarray, rows: np.ndarray, x: np.ndarray) -> None:
    """``x <- (U^T U)^-1 x``."""
    n = columns.shape[0]
    band = columns.shape[1] - 1
    for i in range(n):
        total = x[i]
        first = max(0, i - band)
        for k in range(first, i):
            total -= columns[i, band + k - i] * x[k]
        x[i] = total / columns[i, band]
    for i in range(n - 1, -1, -1):
        total = x[i]
        last = min(band, n - 1 - i)
        for t in range(1, last + 1):
            total -= rows[i, t] * x[i + t]
        x[i] = total / rows[i, 0]


@njit(cache=True)
def banded_selected_inverse(rows: np.ndarray, out: np.ndarray) -> None:
    """``out[i, t] = Z[i, i + t]`` for ``Z = (U^T U)^-1`` and ``0 <= t <= w``, ``w + 1 =
    out.shape[1]`` at least the band ``b + 1`` (exact; entries past the matrix's end are 0).

    Takahashi's equations: ``U Z = U^-T`` is lower triangular with diagonal ``1 / U_ii``,
    so on and above the diagonal ``Z_ij = (delta_ij / U_ii - sum_{k > i} U_ik Z_kj) / U_ii``;
    the sum runs over ``U``'s band, and for ``j <= i + w`` it reads entries of ``Z`` at most
    ``w - 1`` apart in later rows, which are already known. Cost ``n b w``.
    """
    n = rows.shape[0]
    band = rows.shape[1] - 1
    width = out.shape[1] - 1
    out[:, :] = 0.0
    # The same entries by columns, ``by_column[j, j - k] = Z[k, j]``: the sum below walks
    # down column j for k <= j, contiguous here instead of one row of ``out`` per term
    # (10x faster for the wide bands of 3D bodies; the same arithmetic).
    by_column = np.zeros_like(out)
    for i in range(n - 1, -1, -1):
        last = min(band, n - 1 - i)
        diagonal = rows[i, 0]
        # Off the diagonal first (they read only rows after i), then the diagonal, which
        # reads this row's off-diagonal entries through symmetry.
        for t in range(min(width, n - 1 - i), 0, -1):
            j = i + t
            total = 0.0
            for s in range(1, last + 1):
                k = i + s
                if k <= j:
                    total += rows[i, s] * by_column[j, j - k]
                else:
                    total += rows[i, s] * out[j, k - j]
            out[i, t] = -total / diagonal
            by_column[j, t] = out[i, t]
        total = 0.0
        for s in range(1, last + 1):
            total += rows[i, s] * out[i, s]
        out[i, 0] = (1.0 / diagonal - total) / diagonal
        by_column[i, 0] = out[i, 0]


def banded_sweep_layouts(storage: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(columns, rows)`` of an upper factor in LAPACK's banded storage ``(b + 1, n)``
    (``storage[b + i - j, j] = U[i, j]``)."""
    band, n = storage.shape[0] - 1, storage.shape[1]
    columns = np.ascontiguousarray(storage.T)
    rows = np.zeros((n, band + 1))
    for t in range(band + 1):
        # U[i, i + t] sits at storage[band - t, i + t].
        rows[: n - t, t] = storage[band - t, t:]
    return columns, rows
