"""MGPCG on the active spans of each row (a free surface's liquid in a few per cent of its
box): the solution and iterations of the whole-level iteration, also after a solve whose
active points were elsewhere (stale values outside the spans). Bitwise where both run their
sums on the same threads; where the spans are too small for threads on a large level, the
CG's sums run serially and the solutions agree to round-off."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow.linalg import Operator5Point, PoissonSolverMGPCG
from elastoflow.linalg._kernels import active_spans_kernel


def _liquid_operator(active: np.ndarray) -> Operator5Point:
    """Weight 1 between two active points, a ghost-fluid-like diagonal term (1 / theta) on
    active points next to an inactive one; inactive points have no terms."""
    m, n = active.shape
    weights_x = (active[:-1, :] & active[1:, :]).astype(np.float64)
    weights_y = (active[:, :-1] & active[:, 1:]).astype(np.float64)
    rng = np.random.default_rng(4)
    neighbours = np.zeros((m, n))
    neighbours[:-1, :] += weights_x
    neighbours[1:, :] += weights_x
    neighbours[:, :-1] += weights_y
    neighbours[:, 1:] += weights_y
    edge = active & (neighbours < 4)
    diagonal = np.where(edge, rng.uniform(1.0, 20.0, (m, n)), 0.0)
    return Operator5Point(diagonal, weights_x, weights_y)


def _dam_break_like(shape: tuple[int, int], depth: int, film: int) -> np.ndarray:
    """A layer on the floor (columns < depth) and a film up the far side (the last rows)."""
    active = np.zeros(shape, dtype=np.bool_)
    active[:, :depth] = True
    active[-film:, :] = True
    active[5:9, depth:depth + 3] = True   # a drop above the layer
    return active


def _solve_both(solver: PoissonSolverMGPCG, operator: Operator5Point, rhs: np.ndarray
                ) -> tuple[np.ndarray, int, np.ndarray, int]:
    x_spans, report_spans = solver.solve(operator, rhs)
    hierarchy = solver._hierarchy(operator.shape)
    assert hierarchy.ranged
    hierarchy.ranged = False   # the same operator object: the levels are kept as they are
    x_whole, report_whole = solver.solve(operator, rhs)
    return x_spans, report_spans.iterations, x_whole, report_whole.iterations


@pytest.mark.parametrize(("shape", "depth", "film", "bitwise"), [
    ((128, 96), 6, 3, False),    # spans below the threads' limit: the fine level serial
    ((160, 128), 70, 4, True),   # spans above it: threaded
    ((37, 21), 4, 2, True),      # a serial level throughout
])
def test_the_spans_give_the_whole_levels_values(shape: tuple[int, int], depth: int,
                                                film: int, bitwise: bool) -> None:
    active = _dam_break_like(shape, depth, film)
    operator = _liquid_operator(active)
    rhs = np.where(active, np.random.default_rng(2).standard_normal(shape), 0.0)
    solver = PoissonSolverMGPCG()
    # Stale values first: a solve with the liquid elsewhere leaves them outside the spans.
    other = np.zeros(shape, dtype=np.bool_)
    other[shape[0] // 3:, shape[1] // 2:] = True
    solver.solve(_liquid_operator(other), np.where(other, 1.0, 0.0))
    x_spans, iterations_spans, x_whole, iterations_whole = _solve_both(solver, operator, rhs)
    assert iterations_spans == iterations_whole > 1
    if bitwise:
        assert np.array_equal(x_spans, x_whole)
    else:
        scale = float(np.abs(x_whole).max())
        np.testing.assert_allclose(x_spans, x_whole, rtol=0.0, atol=1e-12 * scale)
    assert np.all(x_spans[~active] == 0.0)
    fresh, _ = PoissonSolverMGPCG().solve(operator, rhs)
    assert np.array_equal(fresh, x_spans)


def test_active_spans() -> None:
    active = np.zeros((4, 6), dtype=np.bool_)
    active[0, 2] = active[0, 4] = True
    active[2, :] = True
    first = np.empty(4, dtype=np.int64)
    stop = np.empty(4, dtype=np.int64)
    partial, points = active_spans_kernel(active, first, stop)
    assert partial and points == 3 + 6
    assert first.tolist() == [2, 0, 0, 0] and stop.tolist() == [5, 0, 6, 0]
    partial, points = active_spans_kernel(np.ones((3, 2), dtype=np.bool_), first, stop)
    assert not partial and points == 6


def test_a_non_finite_solve_clears_the_vectors() -> None:
    """NaN left outside the spans (read with weight 0, but 0 * NaN is NaN) would spoil every
    later solve: a solve that ends non-finite zeroes the vectors, and the next one is clean."""
    shape = (64, 48)
    active = _dam_break_like(shape, 5, 2)
    operator = _liquid_operator(active)
    rhs = np.where(active, 1.0, 0.0)
    solver = PoissonSolverMGPCG(max_iterations=20)
    expected, _ = solver.solve(operator, rhs)
    hierarchy = solver._hierarchy(shape)
    for array in (hierarchy.r, hierarchy.z, hierarchy.p, hierarchy.q, hierarchy.level_x,
                  hierarchy.level_b):
        array[:] = np.nan
    spoiled, report = solver.solve(operator, rhs)
    assert not np.isfinite(report.residual)
    again, report = solver.solve(operator, rhs)
    assert report.converged and np.array_equal(again, expected)
