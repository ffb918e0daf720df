"""Banded Cholesky kernels (a solve and the inverse inside the band) and a `LowRankTerm`
whose block is such a factor's inverse, applied without forming it."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import linalg

from elastoflow.linalg import (
    BandedInverse,
    LowRankTerm,
    Operator5Point,
    PoissonSolverMGPCG,
    banded_sweep_layouts,
)
from elastoflow.linalg._banded import banded_selected_inverse, banded_solve_in_place


def _banded_spd(n: int, band: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A dense SPD matrix of half-band ``band`` and its upper banded Cholesky storage."""
    rng = np.random.default_rng(seed)
    half = band // 2
    g = np.zeros((n, n))
    for i in range(n):
        g[i, max(0, i - half): i + half + 1] = rng.standard_normal(min(n, i + half + 1)
                                                                   - max(0, i - half))
    matrix = g @ g.T + np.eye(n)
    storage = np.zeros((band + 1, n))
    for j in range(n):
        for i in range(max(0, j - band), j + 1):
            storage[band + i - j, j] = matrix[i, j]
    return matrix, linalg.cholesky_banded(storage, lower=False)


@pytest.mark.parametrize(("n", "band"), [(1, 0), (7, 6), (40, 10), (60, 4)])
def test_solve_and_selected_inverse_match_the_dense_inverse(n: int, band: int) -> None:
    matrix, factor = _banded_spd(n, band, n + band)
    columns, rows = banded_sweep_layouts(factor)
    inverse = np.linalg.inv(matrix)
    x = np.random.default_rng(1).standard_normal(n)
    solved = x.copy()
    banded_solve_in_place(columns, rows, solved)
    assert np.allclose(solved, inverse @ x, rtol=1e-12, atol=1e-14)
    # The band of the inverse, and wider than the factor's.
    width = min(n - 1, 2 * band + 3)
    selected = np.empty((n, width + 1))
    banded_selected_inverse(rows, selected)
    for i in range(n):
        for t in range(width + 1):
            expected = inverse[i, i + t] if i + t < n else 0.0
            assert selected[i, t] == pytest.approx(expected, rel=1e-10, abs=1e-14)


def _term_pair(shape: tuple[int, int], seed: int) -> tuple[LowRankTerm, LowRankTerm]:
    """The same ``C`` twice: ``M`` dense, and ``M`` as a dense block on some columns plus a
    banded inverse on the others (two bodies stacked into one factor, as the coupling does),
    held columns (slot -1 in both) answering nothing."""
    rng = np.random.default_rng(seed)
    m, n = shape
    k = 30
    offsets = [0]
    points = []
    for d in range(k):
        # Columns next to each other touch neighbouring points, like an interface's nodes.
        i, j = m // 4 + d // 3, n // 3 + d % 7
        chosen = np.unique([i * n + j, (i + 1) * n + j, i * n + j + 1])
        points.append(chosen)
        offsets.append(offsets[-1] + chosen.size)
    weights = rng.uniform(-1.0, 1.0, offsets[-1])
    first, factor_a = _banded_spd(12, 4, seed)
    second, factor_b = _banded_spd(10, 2, seed + 1)
    columns_a, rows_a = banded_sweep_layouts(factor_a)
    columns_b, rows_b = banded_sweep_layouts(factor_b)
    stacked_columns = np.zeros((22, 5))
    stacked_rows = np.zeros((22, 5))
    stacked_columns[:12], stacked_rows[:12] = columns_a, rows_a
    stacked_columns[12:, 2:], stacked_rows[12:, :3] = columns_b, rows_b
    band_slots = np.full(k, -1, np.int64)
    band_slots[:12] = rng.permutation(12)
    band_slots[12:22] = 12 + rng.permutation(10)
    dense_slots = np.full(k, -1, np.int64)
    dense_slots[22:28] = np.arange(6)
    g = rng.standard_normal((6, 6))
    block = g @ g.T
    full = np.zeros((k, k))
    inverse_a, inverse_b = np.linalg.inv(first), np.linalg.inv(second)
    for d in range(k):
        for e in range(k):
            p, q = band_slots[d], band_slots[e]
            if p >= 0 and q >= 0 and (p < 12) == (q < 12):
                full[d, e] = inverse_a[p, q] if p < 12 else inverse_b[p - 12, q - 12]
            if dense_slots[d] >= 0 and dense_slots[e] >= 0:
                full[d, e] = block[dense_slots[d], dense_slots[e]]
    arrays = (np.array(offsets, np.int64), np.concatenate(points).astype(np.int64), weights)
    dense = LowRankTerm(*arrays, full, 3.0)
    banded = LowRankTerm(*arrays, block, 3.0, dense_slots=dense_slots,
                         banded=BandedInverse(stacked_columns, stacked_rows, band_slots))
    return dense, banded


def test_banded_term_applies_and_solves_like_the_dense_one() -> None:
    shape = (24, 20)
    dense, banded = _term_pair(shape, 5)
    rng = np.random.default_rng(2)
    x = rng.standard_normal(shape)
    assert np.allclose(banded.apply(x), dense.apply(x), rtol=1e-12, atol=1e-12)
    # Columns meeting at a point lie up to 9 apart in the factor of band 4: the inverse's
    # band is widened to reach them, and the diagonal is exact.
    diagonal, outside = banded.diagonal_with_count(shape)
    assert outside == 0
    assert np.allclose(diagonal, dense.diagonal(shape), rtol=1e-12, atol=1e-14)
    diagonal_values = np.zeros(shape)
    diagonal_values[-1, :] = 2.0
    operator = Operator5Point(diagonal_values, rng.uniform(0.2, 1.0, (23, 20)),
                              rng.uniform(0.2, 1.0, (24, 19)))
    rhs = rng.standard_normal(shape)
    solver = PoissonSolverMGPCG(rtol=1e-10, max_iterations=500)
    with_band, report_band = solver.solve_coupled(operator, banded, rhs)
    with_dense, report_dense = solver.solve_coupled(operator, dense, rhs)
    assert report_band.converged and report_dense.converged
    assert np.allclose(with_band, with_dense, rtol=1e-8, atol=1e-9 * np.abs(with_dense).max())


def test_pairs_outside_the_band_are_counted_and_left_out() -> None:
    """Two columns meeting at one point further apart in the factor than the widest band
    the diagonal computes (4 times the factor's, 2 x 4 = 8 < 9 here): it leaves their
    product out and says so."""
    _, factor = _banded_spd(10, 1, 9)
    columns, rows = banded_sweep_layouts(factor)
    term = LowRankTerm(np.array([0, 1, 2], np.int64), np.array([5, 5], np.int64),
                       np.array([1.0, -1.0]), np.zeros((0, 0)), 1.0,
                       dense_slots=np.full(2, -1, np.int64),
                       banded=BandedInverse(columns, rows, np.array([0, 9], np.int64)))
    diagonal, outside = term.diagonal_with_count((2, 5))
    assert outside == 2
    upper = np.diag(rows[:, 0]) + np.diag(rows[:-1, 1], 1)
    inverse = np.linalg.inv(upper.T @ upper)
    assert diagonal.ravel()[5] == pytest.approx(inverse[0, 0] + inverse[9, 9], rel=1e-12)
