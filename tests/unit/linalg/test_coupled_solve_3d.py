"""``PoissonSolverMGPCG3D.solve_coupled``: a 7-point operator plus a low-rank SPD term (the 3D
strongly coupled pressure equation)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import sparse

from elastoflow.linalg import LowRankTerm, Operator7Point, PoissonSolverMGPCG3D


def _matrix(operator: Operator7Point) -> np.ndarray:
    shape = operator.shape
    size = int(np.prod(shape))
    index = np.arange(size).reshape(shape)
    a = sparse.diags(operator.diagonal.ravel()).tolil()
    pairs = ((operator.weights_x, index[:-1], index[1:]),
             (operator.weights_y, index[:, :-1], index[:, 1:]),
             (operator.weights_z, index[:, :, :-1], index[:, :, 1:]))
    for weights, first, second in pairs:
        for w, i, j in zip(weights.ravel(), first.ravel(), second.ravel(), strict=True):
            a[i, i] += w
            a[j, j] += w
            a[i, j] -= w
            a[j, i] -= w
    return a.toarray()


def _term(shape: tuple[int, int, int], rank: int, seed: int, scale: float) -> LowRankTerm:
    """A term touching clusters of points in the middle, as a body's cut cells do."""
    rng = np.random.default_rng(seed)
    m, n, l = shape
    points = []
    offsets = [0]
    for _ in range(rank):
        centre = [int(rng.integers(s // 4, 3 * s // 4)) for s in shape]
        near = [np.clip(c + rng.integers(-1, 2, 3), 0, s - 1) for c, s in zip(centre, shape,
                                                                              strict=True)]
        chosen = np.unique((near[0] * n + near[1]) * l + near[2])
        points.append(chosen)
        offsets.append(offsets[-1] + chosen.shape[0])
    weights = rng.uniform(-1.0, 1.0, offsets[-1])
    factor = rng.standard_normal((rank, rank))
    return LowRankTerm(np.array(offsets, np.int64), np.concatenate(points).astype(np.int64),
                       weights, factor @ factor.T / rank, scale)


@pytest.mark.parametrize("scale", [0.1, 10.0, 1000.0])
@pytest.mark.parametrize("closed", [False, True])
def test_solve_coupled_matches_a_dense_solve(scale: float, closed: bool) -> None:
    """A Dirichlet side or a closed box (singular fluid block), any weight of the term."""
    shape = (10, 9, 8)
    size = int(np.prod(shape))
    rng = np.random.default_rng(3)
    diagonal = np.zeros(shape)
    if not closed:
        diagonal[-1] = 2.0
    operator = Operator7Point(diagonal, rng.uniform(0.2, 1.0, (9, 9, 8)),
                              rng.uniform(0.2, 1.0, (10, 8, 8)),
                              rng.uniform(0.2, 1.0, (10, 9, 7)))
    term = _term(shape, 10, 4, scale)
    basis = np.eye(size).reshape(size, *shape)
    dense = _matrix(operator) + np.stack([term.apply(e).ravel() for e in basis], axis=1)
    rhs = rng.standard_normal(shape)
    if closed:
        rhs -= rhs.mean()
    solver = PoissonSolverMGPCG3D(rtol=1e-10, max_iterations=500)
    x, report = solver.solve_coupled(operator, term, rhs)
    assert report.converged
    residual = rhs.ravel() - dense @ x.ravel()
    assert np.linalg.norm(residual) <= 1e-8 * np.linalg.norm(rhs)
    # Without the term it is the plain solve, and a warm start into ``out`` works.
    empty = LowRankTerm(np.zeros(1, np.int64), np.zeros(0, np.int64), np.zeros(0),
                        np.zeros((0, 0)), scale)
    out = np.zeros(shape)
    plain, _ = solver.solve(operator, rhs)
    coupled, report = solver.solve_coupled(operator, empty, rhs, x0=out, out=out)
    assert coupled is out and report.converged
    assert np.allclose(coupled, plain, atol=1e-8 * np.abs(plain).max())


def test_iterations_stay_flat_as_the_grid_grows() -> None:
    """The multigrid preconditioner keeps working with the term: a unit-weight Laplacian
    with an outflow side and a heavy term, 8^3 to 32^3."""
    counts = []
    for n in (8, 16, 32):
        shape = (n, n, n)
        diagonal = np.zeros(shape)
        diagonal[-1] = 2.0
        operator = Operator7Point(diagonal, np.ones((n - 1, n, n)), np.ones((n, n - 1, n)),
                                  np.ones((n, n, n - 1)))
        term = _term(shape, 12, 7, 100.0)
        rhs = np.random.default_rng(1).standard_normal(shape)
        _, report = PoissonSolverMGPCG3D(rtol=1e-8).solve_coupled(operator, term, rhs)
        assert report.converged
        counts.append(report.iterations)
    assert max(counts) <= 2 * min(counts) + 4, counts


def test_diagonal_and_apply_agree_in_3d() -> None:
    shape = (6, 5, 4)
    size = int(np.prod(shape))
    term = _term(shape, 6, 5, 2.0)
    basis = np.eye(size).reshape(size, *shape)
    dense = np.stack([term.apply(e).ravel() for e in basis], axis=1)
    assert np.allclose(dense, dense.T)
    assert np.allclose(np.diag(dense), term.diagonal(shape).ravel())


def test_a_strongly_diagonal_operator_with_held_planes_keeps_no_shell_in_its_v_cycle() -> None:
    """Held planes (weights 0 to them) and a dominant diagonal: `solve` alone takes the one
    weight outside a shell along the sides, which the V-cycle's restriction does not read;
    the coupled solve builds the V-cycle, so its fine level must keep no shell."""
    from scipy.sparse.linalg import spsolve

    shape = (24, 20, 22)
    c = 0.05
    diagonal = np.ones(shape) + 6.0 * c
    weights = [np.full((23, 20, 22), c), np.full((24, 19, 22), c), np.full((24, 20, 21), c)]
    weights[1][:, 0, :] = weights[1][:, -1, :] = 0.0
    diagonal[:, 0, :] = diagonal[:, -1, :] = 1.0
    operator = Operator7Point(diagonal, *weights)
    term = _term(shape, 3, 5, 10.0)
    rhs = np.random.default_rng(6).standard_normal(shape)
    solver = PoissonSolverMGPCG3D(rtol=1e-11)
    plain, report = solver.solve(operator, rhs)
    assert report.converged and solver._hierarchy(shape).levels[0].box[6] == 2
    x, report = solver.solve_coupled(operator, term, rhs)
    assert report.converged
    assert solver._hierarchy(shape).levels[0].box[6] == 0
    size = int(np.prod(shape))
    index = np.arange(size).reshape(shape)
    a = sparse.diags(diagonal.ravel()).tolil()
    pairs = ((weights[0], index[:-1], index[1:]), (weights[1], index[:, :-1], index[:, 1:]),
             (weights[2], index[:, :, :-1], index[:, :, 1:]))
    rows, cols, values = [], [], []
    for w, first, second in pairs:
        f, g, v = first.ravel(), second.ravel(), w.ravel()
        rows += [f, g, f, g]
        cols += [f, g, g, f]
        values += [v, v, -v, -v]
    a = (sparse.diags(diagonal.ravel()) + sparse.csr_matrix(
        (np.concatenate(values), (np.concatenate(rows), np.concatenate(cols))),
        shape=(size, size))).tocsc()
    np.testing.assert_allclose(plain.ravel(), spsolve(a, rhs.ravel()), rtol=0,
                               atol=1e-8 * np.abs(plain).max())
    columns = term.offsets.shape[0] - 1
    coupling = sparse.csr_matrix(
        (term.weights, (term.points, np.repeat(np.arange(columns), np.diff(term.offsets)))),
        shape=(size, columns))
    full = (a + term.scale * coupling @ sparse.csr_matrix(term.matrix) @ coupling.T).tocsc()
    np.testing.assert_allclose(x.ravel(), spsolve(full, rhs.ravel()), rtol=0,
                               atol=1e-8 * np.abs(x).max())
