"""``PoissonSolverMGPCG.solve_coupled``: a 5-point operator plus a low-rank SPD term."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import sparse

from elastoflow.linalg import LowRankTerm, Operator5Point, PoissonSolverMGPCG


def _matrix(operator: Operator5Point) -> np.ndarray:
    m, n = operator.shape
    index = np.arange(m * n).reshape(m, n)
    a = sparse.diags(operator.diagonal.ravel()).tolil()
    for weights, first, second in ((operator.weights_x, index[:-1, :], index[1:, :]),
                                   (operator.weights_y, index[:, :-1], index[:, 1:])):
        for w, i, j in zip(weights.ravel(), first.ravel(), second.ravel()):
            a[i, i] += w
            a[j, j] += w
            a[i, j] -= w
            a[j, i] -= w
    return a.toarray()


def _term(shape: tuple[int, int], rank: int, seed: int, scale: float) -> LowRankTerm:
    """A term touching a ring of points in the middle, as a body does."""
    rng = np.random.default_rng(seed)
    m, n = shape
    points = []
    offsets = [0]
    for _ in range(rank):
        i, j = rng.integers(m // 4, 3 * m // 4), rng.integers(n // 4, 3 * n // 4)
        chosen = np.unique((i + rng.integers(-1, 2, 3)) * n + (j + rng.integers(-1, 2, 3)))
        points.append(chosen)
        offsets.append(offsets[-1] + chosen.shape[0])
    weights = rng.uniform(-1.0, 1.0, offsets[-1])
    factor = rng.standard_normal((rank, rank))
    return LowRankTerm(np.array(offsets, np.int64), np.concatenate(points).astype(np.int64),
                       weights, factor @ factor.T / rank, scale)


@pytest.mark.parametrize("scale", [0.1, 10.0, 1000.0])
@pytest.mark.parametrize("closed", [False, True])
def test_solve_coupled_matches_a_dense_solve(scale: float, closed: bool) -> None:
    """A Dirichlet side (outflow) or a closed box (singular fluid block made definite by the
    term, which then fixes the level), any weight of the term against the fluid block."""
    shape = (24, 20)
    rng = np.random.default_rng(3)
    diagonal = np.zeros(shape)
    if not closed:
        diagonal[-1, :] = 2.0
    operator = Operator5Point(diagonal, rng.uniform(0.2, 1.0, (23, 20)),
                              rng.uniform(0.2, 1.0, (24, 19)))
    term = _term(shape, 12, 4, scale)
    basis = np.eye(480).reshape(480, *shape)
    dense = _matrix(operator) + np.stack([term.apply(e).ravel() for e in basis], axis=1)
    rhs = rng.standard_normal(shape)
    if closed:
        # The term alone makes the closed box definite only in the directions it touches;
        # keep the test to a compatible right-hand side.
        rhs -= rhs.mean()
    solver = PoissonSolverMGPCG(rtol=1e-10, max_iterations=500)
    x, report = solver.solve_coupled(operator, term, rhs)
    assert report.converged
    residual = rhs.ravel() - dense @ x.ravel()
    assert np.linalg.norm(residual) <= 1e-8 * np.linalg.norm(rhs)


def test_diagonal_and_apply_agree() -> None:
    shape = (10, 12)
    term = _term(shape, 6, 5, 2.0)
    basis = np.eye(120).reshape(120, *shape)
    dense = np.stack([term.apply(e).ravel() for e in basis], axis=1)
    assert np.allclose(dense, dense.T)
    assert np.allclose(np.diag(dense), term.diagonal(shape).ravel())
    assert np.linalg.eigvalsh(dense).min() > -1e-12
