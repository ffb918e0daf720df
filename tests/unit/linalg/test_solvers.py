"""Operator application and both Poisson solvers against an independent scipy.sparse reference."""

from __future__ import annotations

import numpy as np
import pytest
from chebyshev_bound import chebyshev_bound
from scipy import sparse
from scipy.sparse.csgraph import connected_components
from scipy.sparse.linalg import spsolve

from elastoflow.linalg import (
    Operator5Point,
    PoissonSolverJacobi,
    PoissonSolverMGPCG,
    SolveReport,
    apply_operator,
)


def sparse_matrix(operator: Operator5Point) -> sparse.csr_matrix:
    """The operator assembled face by face as a sparse matrix (row-major numbering)."""
    m, n = operator.shape
    index = np.arange(m * n).reshape(m, n)
    rows, cols, values = [index.ravel()], [index.ravel()], [operator.diagonal.ravel()]
    for weights, first, second in (
        (operator.weights_x, index[:-1, :], index[1:, :]),
        (operator.weights_y, index[:, :-1], index[:, 1:]),
    ):
        a, b, w = first.ravel(), second.ravel(), weights.ravel()
        rows += [a, b, a, b]
        cols += [a, b, b, a]
        values += [w, w, -w, -w]
    return sparse.csr_matrix(
        (np.concatenate(values), (np.concatenate(rows), np.concatenate(cols))), shape=(m * n, m * n)
    )


def reference_solve(operator: Operator5Point, rhs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Solution and compatible right-hand side by a direct solve, one point pinned per singular
    component (components found by scipy's graph routines)."""
    matrix = sparse_matrix(operator)
    size = matrix.shape[0]
    diagonal = operator.diagonal.ravel()
    coupling = matrix.copy()
    coupling.setdiag(0.0)
    coupling.eliminate_zeros()
    active = (diagonal > 0) | (np.diff(coupling.indptr) > 0)
    _, labels = connected_components(coupling, directed=False)
    b = np.where(active, rhs.ravel(), 0.0)
    keep = active.copy()
    singular_components = []
    for label in np.unique(labels[active]):
        members = (labels == label) & active
        if not np.any(diagonal[members] > 0):
            singular_components.append(members)
            b[members] -= b[members].mean()
            keep[np.flatnonzero(members)[0]] = False
    x = np.zeros(size)
    reduced = matrix[keep][:, keep].tocsc()
    if reduced.shape[0]:
        x[keep] = spsolve(reduced, b[keep])
    for members in singular_components:
        x[members] -= x[members].mean()
    return x.reshape(operator.shape), b.reshape(operator.shape)


def random_operator(
    shape: tuple[int, int], seed: int, *, dirichlet: bool = True, walls: bool = True
) -> Operator5Point:
    """Fractional weights, some closed faces, an inactive block, optional Dirichlet diagonal."""
    rng = np.random.default_rng(seed)
    m, n = shape
    weights_x = rng.uniform(0.1, 1.0, (m - 1, n))
    weights_y = rng.uniform(0.1, 1.0, (m, n - 1))
    if walls:
        weights_x[rng.random(weights_x.shape) < 0.1] = 0.0
        weights_y[rng.random(weights_y.shape) < 0.1] = 0.0
    diagonal = np.zeros(shape)
    if dirichlet:
        diagonal[-1, :] = 2.0
        diagonal[rng.random(shape) < 0.05] = rng.uniform(0.1, 1.0)
    i0, j0 = m // 3, n // 3
    i1, j1 = i0 + max(1, m // 4), j0 + max(1, n // 4)
    diagonal[i0:i1, j0:j1] = 0.0
    weights_x[max(i0 - 1, 0):i1, j0:j1] = 0.0
    weights_y[i0:i1, max(j0 - 1, 0):j1] = 0.0
    return Operator5Point(diagonal, weights_x, weights_y)


def true_relative_residual(operator: Operator5Point, x: np.ndarray, b: np.ndarray) -> float:
    residual = b.ravel() - sparse_matrix(operator) @ x.ravel()
    return float(np.linalg.norm(residual) / np.linalg.norm(b))


SOLVERS = [
    pytest.param(lambda rtol: PoissonSolverJacobi(rtol=rtol, max_iterations=400_000), id="jacobi"),
    pytest.param(lambda rtol: PoissonSolverMGPCG(rtol=rtol), id="mgpcg"),
]


@pytest.mark.parametrize("seed", range(3))
def test_apply_operator_matches_sparse_matrix(seed: int) -> None:
    operator = random_operator((9, 7), seed)
    x = np.random.default_rng(seed + 10).standard_normal((9, 7))
    expected = (sparse_matrix(operator) @ x.ravel()).reshape(9, 7)
    out = np.empty((9, 7))
    result = apply_operator(operator, x, out=out)
    assert result is out
    np.testing.assert_allclose(result, expected, rtol=1e-13, atol=1e-13)


@pytest.mark.parametrize("make_solver", SOLVERS)
@pytest.mark.parametrize(
    ("shape", "seed", "dirichlet"),
    [((9, 7), 0, True), ((16, 16), 1, True), ((13, 5), 2, True), ((1, 11), 3, True),
     ((12, 10), 4, False), ((17, 9), 5, False)],
)
def test_solver_matches_direct_solve(make_solver, shape, seed, dirichlet) -> None:
    operator = random_operator(shape, seed, dirichlet=dirichlet)
    rhs = np.random.default_rng(seed + 100).standard_normal(shape)
    expected, b = reference_solve(operator, rhs)
    x, report = make_solver(1e-10).solve(operator, rhs)
    assert isinstance(report, SolveReport)
    assert report.residual <= 1e-10
    # Random right-hand sides on pure Neumann components are incompatible: the part removed
    # is reported, and such a solve is not "converged" for the system as given.
    coupled = operator.diagonal > 0.0
    coupled[:-1, :] |= operator.weights_x > 0.0
    coupled[1:, :] |= operator.weights_x > 0.0
    coupled[:, :-1] |= operator.weights_y > 0.0
    coupled[:, 1:] |= operator.weights_y > 0.0
    given = np.where(coupled, rhs, 0.0)
    removed = np.linalg.norm(given - b) / np.linalg.norm(given)
    assert report.incompatibility == pytest.approx(removed, rel=1e-6, abs=1e-14)
    assert report.converged == (removed <= 1e-10)
    np.testing.assert_allclose(x, expected, atol=1e-7 * np.abs(expected).max())
    assert report.residual == pytest.approx(true_relative_residual(operator, x, b), rel=1e-3,
                                            abs=1e-14)


@pytest.mark.parametrize("shape", [(8, 8), (15, 6)])
def test_jacobi_and_mgpcg_reach_the_same_pressure(shape) -> None:
    operator = random_operator(shape, 7)
    rhs = np.random.default_rng(8).standard_normal(shape)
    x_jacobi, report_jacobi = PoissonSolverJacobi(rtol=1e-8).solve(operator, rhs)
    x_mgpcg, report_mgpcg = PoissonSolverMGPCG(rtol=1e-8).solve(operator, rhs)
    assert report_jacobi.converged and report_mgpcg.converged
    assert report_jacobi.iterations > report_mgpcg.iterations
    np.testing.assert_allclose(x_jacobi, x_mgpcg, atol=1e-5 * np.abs(x_mgpcg).max())


@pytest.mark.parametrize("make_solver", SOLVERS)
def test_singular_neumann_problem(make_solver) -> None:
    shape = (14, 11)
    rng = np.random.default_rng(3)
    operator = Operator5Point(
        np.zeros(shape), rng.uniform(0.2, 1.0, (13, 11)), rng.uniform(0.2, 1.0, (14, 10))
    )
    rhs = rng.standard_normal(shape) + 5.0  # incompatible: nonzero mean
    x, report = make_solver(1e-6).solve(operator, rhs)
    compatible = rhs - rhs.mean()
    # The compatible part is solved to rtol, but the system as given has no solution: the
    # report must not say converged, and says how much of the right-hand side was removed.
    assert report.residual <= 1e-6
    assert not report.converged
    removed = np.sqrt(rhs.size) * abs(rhs.mean())
    assert report.incompatibility == pytest.approx(removed / np.linalg.norm(rhs), rel=1e-12)
    assert abs(x.mean()) <= 1e-12 * np.abs(x).max()
    assert true_relative_residual(operator, x, compatible) <= 1e-6
    expected, _ = reference_solve(operator, rhs)
    np.testing.assert_allclose(x, expected, atol=1e-4 * np.abs(expected).max())


@pytest.mark.parametrize("make_solver", SOLVERS)
def test_round_off_mean_still_converges(make_solver) -> None:
    # A consistent right-hand side (zero mean up to round-off, as the divergence of a closed
    # box) keeps converged = True with an incompatibility at round-off level.
    shape = (14, 11)
    rng = np.random.default_rng(5)
    operator = Operator5Point(
        np.zeros(shape), rng.uniform(0.2, 1.0, (13, 11)), rng.uniform(0.2, 1.0, (14, 10))
    )
    rhs = rng.standard_normal(shape)
    rhs -= rhs.mean()
    x, report = make_solver(1e-8).solve(operator, rhs)
    assert report.converged
    assert report.incompatibility <= 1e-14
    # A constant right-hand side is all incompatible: nothing is left to solve, and that is
    # not convergence either.
    x, report = make_solver(1e-6).solve(operator, np.full(shape, 2.0))
    assert not report.converged and report.incompatibility == pytest.approx(1.0)
    assert np.all(x == 0.0)


@pytest.mark.parametrize("make_solver", SOLVERS)
def test_non_singular_problem_has_no_incompatibility(make_solver) -> None:
    operator = random_operator((12, 9), 21)
    _, report = make_solver(1e-6).solve(operator, np.random.default_rng(22).standard_normal((12, 9)))
    assert report.converged and report.incompatibility == 0.0


@pytest.mark.parametrize("make_solver", SOLVERS)
def test_two_disconnected_components(make_solver) -> None:
    # Closed faces make three components: rows 0-1 and rows 3-5 are pure Neumann, rows 6-12
    # have a Dirichlet row; row 2 is cut off from everything and has no diagonal: inactive.
    shape = (13, 9)
    weights_x = np.ones((12, 9))
    weights_y = np.ones((13, 8))
    weights_x[5, :] = 0.0
    weights_x[1:3, :] = 0.0
    weights_y[2, :] = 0.0
    diagonal = np.zeros(shape)
    diagonal[-1, :] = 1.0
    operator = Operator5Point(diagonal, weights_x, weights_y)
    rhs = np.random.default_rng(4).standard_normal(shape) + 1.0
    x, report = make_solver(1e-8).solve(operator, rhs)
    expected, b = reference_solve(operator, rhs)
    # The two Neumann components got a right-hand side with a nonzero mean: solved for its
    # compatible part, reported as not converged.
    assert report.residual <= 1e-8 and not report.converged
    assert report.incompatibility > 0.1
    assert np.all(x[2, :] == 0.0)
    scale = np.abs(x).max()
    assert abs(x[:2].mean()) < 1e-9 * scale
    assert abs(x[3:6].mean()) < 1e-9 * scale
    assert abs(x[6:].mean()) > 1e-3 * scale
    np.testing.assert_allclose(x, expected, atol=1e-6 * np.abs(expected).max())
    assert true_relative_residual(operator, x, b) <= 1e-8


def test_mgpcg_on_a_channel_sized_grid_and_viscosity_operator() -> None:
    solver = PoissonSolverMGPCG()
    operator = random_operator((220, 41), 11)
    rhs = np.random.default_rng(12).standard_normal((220, 41))
    x, report = solver.solve(operator, rhs)
    expected, b = reference_solve(operator, rhs)
    assert report.converged
    assert true_relative_residual(operator, x, b) == pytest.approx(report.residual, rel=1e-3)
    np.testing.assert_allclose(x, expected, atol=1e-4 * np.abs(expected).max())
    # Implicit viscosity of u on (nx + 1, ny): identity plus nu dt / h^2 couplings.
    viscosity = Operator5Point(np.ones((221, 41)), np.full((220, 41), 3.0), np.full((221, 40), 3.0))
    rhs = np.random.default_rng(13).standard_normal((221, 41))
    x, report = solver.solve(viscosity, rhs)
    expected, _ = reference_solve(viscosity, rhs)
    assert report.converged
    np.testing.assert_allclose(x, expected, atol=1e-5 * np.abs(expected).max())


@pytest.mark.parametrize("make_solver", SOLVERS)
def test_warm_start(make_solver) -> None:
    operator = random_operator((12, 12), 21)
    rhs = np.random.default_rng(22).standard_normal((12, 12))
    solver = make_solver(1e-6)
    x, cold = solver.solve(operator, rhs)
    _, warm = solver.solve(operator, rhs, x0=x)
    assert warm.iterations == 0 and warm.converged
    assert cold.iterations > 0


@pytest.mark.parametrize(
    "solver", [PoissonSolverJacobi(max_iterations=3), PoissonSolverMGPCG(max_iterations=1)],
    ids=["jacobi", "mgpcg"],
)
def test_iteration_limit_reports_true_residual(solver) -> None:
    operator = random_operator((40, 40), 31)
    rhs = np.random.default_rng(32).standard_normal((40, 40))
    x, report = solver.solve(operator, rhs)
    _, b = reference_solve(operator, rhs)
    assert not report.converged
    assert report.iterations == solver.max_iterations
    assert report.residual == pytest.approx(true_relative_residual(operator, x, b), rel=1e-9)


@pytest.mark.parametrize("make_solver", SOLVERS)
def test_zero_rhs_gives_zero(make_solver) -> None:
    operator = random_operator((6, 5), 1)
    x, report = make_solver(1e-6).solve(operator, np.zeros((6, 5)))
    assert np.all(x == 0.0) and report == SolveReport(0, 0.0, True)


def test_bad_input_raises() -> None:
    with pytest.raises(ValueError, match="weights_x"):
        Operator5Point(np.zeros((4, 3)), np.ones((4, 3)), np.ones((4, 2)))
    with pytest.raises(ValueError, match="diagonal"):
        Operator5Point(-np.ones((4, 3)), np.ones((3, 3)), np.ones((4, 2)))
    operator = Operator5Point(np.ones((4, 3)), np.ones((3, 3)), np.ones((4, 2)))
    with pytest.raises(ValueError, match="rhs"):
        PoissonSolverMGPCG().solve(operator, np.ones((3, 4)))
    with pytest.raises(ValueError, match="rtol"):
        PoissonSolverJacobi(rtol=0.0)


def flow_problem(size: int, body: bool) -> tuple[Operator5Point, np.ndarray]:
    """Pressure-like problem on the unit square: smooth right-hand side, outflow (Dirichlet) on
    the right side; with ``body`` a disc of closed cells with fractional faces around it."""
    centres = (np.arange(size) + 0.5) / size
    faces = np.arange(1, size) / size
    x, y = np.meshgrid(centres, centres, indexing="ij")
    rhs = np.cos(3 * np.pi * x) * np.sin(2 * np.pi * y) + x**2
    diagonal = np.zeros((size, size))
    diagonal[-1, :] = 2.0
    weights_x = np.ones((size - 1, size))
    weights_y = np.ones((size, size - 1))
    if body:
        def open_fraction(px: np.ndarray, py: np.ndarray) -> np.ndarray:
            signed = np.hypot(px - 0.4, py - 0.55) - 0.15
            return np.clip(0.5 + signed * size, 0.0, 1.0)

        weights_x = open_fraction(*np.meshgrid(faces, centres, indexing="ij"))
        weights_y = open_fraction(*np.meshgrid(centres, faces, indexing="ij"))
        rhs = rhs * (np.hypot(x - 0.4, y - 0.55) > 0.15)
    return Operator5Point(diagonal, weights_x, weights_y), rhs


@pytest.mark.parametrize("body", [False, True], ids=["smooth", "body"])
def test_mgpcg_iterations_nearly_independent_of_grid_size(body: bool) -> None:
    solver = PoissonSolverMGPCG(rtol=1e-6)
    counts = []
    for size in (128, 512):
        operator, rhs = flow_problem(size, body)
        _, report = solver.solve(operator, rhs)
        assert report.converged
        counts.append(report.iterations)
    assert counts[1] <= 1.5 * counts[0], counts


@pytest.mark.parametrize("seed", range(4))
def test_singular_components_match_scipy_graph_components(seed: int) -> None:
    from elastoflow.linalg._problem import _analyse

    rng = np.random.default_rng(seed)
    shape = (23, 17)
    weights_x = np.where(rng.random((22, 17)) < 0.45, 0.0, 1.0)
    weights_y = np.where(rng.random((23, 16)) < 0.45, 0.0, 1.0)
    diagonal = np.where(rng.random(shape) < 0.03, 1.0, 0.0)
    operator = Operator5Point(diagonal, weights_x, weights_y)
    null_space = _analyse(operator)
    coupling = sparse_matrix(Operator5Point(np.zeros(shape), weights_x, weights_y))
    coupling.setdiag(0.0)
    coupling.eliminate_zeros()
    active = (diagonal.ravel() > 0) | (np.diff(coupling.indptr) > 0)
    _, expected = connected_components(coupling, directed=False)
    labels = null_space.labels.ravel()
    assert np.array_equal(labels >= 0, active)
    # Same partition: the map between label sets is one-to-one on active points.
    pairs = set(zip(labels[active].tolist(), expected[active].tolist(), strict=True))
    assert len(pairs) == null_space.count == len(set(expected[active].tolist()))
    for label, component in pairs:
        members = expected == component
        assert null_space.singular[label] == (not np.any(diagonal.ravel()[members] > 0))


def test_mgpcg_with_nearly_closed_faces() -> None:
    # Cut faces that are open by 1e-9 or less leave cells nearly cut off from the flow: the
    # preconditioner must stay positive definite for CG to converge.
    operator, rhs = flow_problem(128, body=True)
    rng = np.random.default_rng(5)
    weights = []
    for original in (operator.weights_x, operator.weights_y):
        w = original.copy()
        picked = (w > 0) & (w < 1) & (rng.random(w.shape) < 0.3)
        w[picked] = 1e-9 * rng.random(int(picked.sum()))
        weights.append(w)
    nearly_closed = Operator5Point(operator.diagonal, *weights)
    x, report = PoissonSolverMGPCG(rtol=1e-8).solve(nearly_closed, rhs)
    _, b = reference_solve(nearly_closed, rhs)
    assert report.converged and report.iterations <= 30
    assert true_relative_residual(nearly_closed, x, b) <= 1e-8


def test_non_finite_input_raises() -> None:
    weights_x = np.ones((3, 3))
    weights_x[1, 2] = np.nan
    with pytest.raises(ValueError, match="weights_x"):
        Operator5Point(np.zeros((4, 3)), weights_x, np.ones((4, 2)))
    operator = Operator5Point(np.ones((4, 3)), np.ones((3, 3)), np.ones((4, 2)))
    rhs = np.ones((4, 3))
    rhs[0, 0] = np.inf
    for solver in (PoissonSolverJacobi(), PoissonSolverMGPCG()):
        with pytest.raises(ValueError, match="rhs"):
            solver.solve(operator, rhs)
        with pytest.raises(ValueError, match="x0"):
            solver.solve(operator, np.ones((4, 3)), x0=rhs)


def test_mgpcg_reuses_levels_only_for_the_same_operator() -> None:
    """One solver instance across operators of one shape: a changed operator (a new object
    with other values) is rebuilt, the same object or equal values reuse the levels; every
    answer matches the direct solve. The diagonally dominant (Gauss-Seidel-only) case and a
    singular one are both included."""
    shape = (40, 33)
    rng = np.random.default_rng(41)
    dominant = Operator5Point(np.ones(shape), np.full((39, 33), 0.5), np.full((40, 32), 0.5))
    neumann = random_operator(shape, 42, dirichlet=False, walls=False)
    solver = PoissonSolverMGPCG(rtol=1e-10)
    for operator in (dominant, neumann, dominant, Operator5Point(
            dominant.diagonal.copy(), dominant.weights_x.copy(), dominant.weights_y.copy()),
            neumann):
        rhs = rng.standard_normal(shape)
        x, report = solver.solve(operator, rhs)
        expected, _ = reference_solve(operator, rhs)
        assert report.residual <= 1e-10
        assert report.converged == (report.incompatibility <= 1e-10)
        np.testing.assert_allclose(x, expected, atol=1e-7 * np.abs(expected).max())


@pytest.mark.parametrize("make_solver", SOLVERS)
def test_solution_into_out(make_solver) -> None:
    operator = random_operator((10, 8), 51)
    rhs = np.random.default_rng(52).standard_normal((10, 8))
    solver = make_solver(1e-8)
    expected, _ = solver.solve(operator, rhs)
    out = np.full((10, 8), 7.0)
    x, report = solver.solve(operator, rhs, x0=out, out=out)
    assert x is out and report.converged
    np.testing.assert_allclose(out, expected, atol=1e-6 * np.abs(expected).max())
    with pytest.raises(ValueError, match="out"):
        solver.solve(operator, rhs, out=np.empty((10, 8), dtype=np.float32))
    with pytest.raises(ValueError, match="out"):
        solver.solve(operator, rhs, out=np.empty((8, 10)))


def dominant_operator(shape: tuple[int, int], seed: int, c: float) -> Operator5Point:
    """Implicit-viscosity-like ``I - c L``: weights c (x) and in [c/2, c] (y), closed faces,
    fixed points with a large diagonal (Dirichlet rows, cut-distance terms)."""
    rng = np.random.default_rng(seed)
    m, n = shape
    diagonal = np.ones(shape)
    diagonal[0, :] = diagonal[-1, :] = 1e3
    diagonal[rng.random(shape) < 0.03] = 50.0
    weights_x = np.full((m - 1, n), c)
    weights_y = rng.uniform(0.5 * c, c, (m, n - 1))
    weights_x[rng.random(weights_x.shape) < 0.05] = 0.0
    return Operator5Point(diagonal, weights_x, weights_y)


@pytest.mark.parametrize("c", [0.01, 0.085, 0.33, 1.0])
@pytest.mark.parametrize("warm", [False, True])
def test_chebyshev_iteration_for_dominant_operators(c: float, warm: bool) -> None:
    """Diagonal >= a quarter of the weights: the Chebyshev iteration solves it, to the direct
    solution, within the iteration count that its Gershgorin interval guarantees."""
    shape = (41, 37)
    operator = dominant_operator(shape, 41, c)
    rhs = np.random.default_rng(42).standard_normal(shape)
    expected, b = reference_solve(operator, rhs)
    x0 = expected + 0.01 * np.random.default_rng(43).standard_normal(shape) if warm else None
    solver = PoissonSolverMGPCG(rtol=1e-8)
    x, report = solver.solve(operator, rhs, x0=x0)
    assert not solver._hierarchies[shape].coarse, "expected the Chebyshev path"
    assert report.converged
    assert true_relative_residual(operator, x, b) == pytest.approx(report.residual, rel=1e-6)
    np.testing.assert_allclose(x, expected, atol=1e-7 * np.abs(expected).max())
    start = np.zeros(shape) if x0 is None else x0
    _, passes = chebyshev_bound(sparse_matrix(operator), b, start, 1e-8)
    assert report.iterations <= passes


def test_chebyshev_iteration_without_weights_is_exact() -> None:
    diagonal = np.random.default_rng(5).uniform(0.5, 4.0, (9, 7))
    operator = Operator5Point(diagonal, np.zeros((8, 7)), np.zeros((9, 6)))
    rhs = np.random.default_rng(6).standard_normal((9, 7))
    x, report = PoissonSolverMGPCG().solve(operator, rhs)
    assert report.converged and report.iterations <= 1
    np.testing.assert_allclose(x, rhs / diagonal, rtol=1e-12)


@pytest.mark.parametrize("make_solver", [PoissonSolverJacobi, PoissonSolverMGPCG])
def test_a_solve_calls_no_blas(make_solver, monkeypatch: pytest.MonkeyPatch) -> None:
    """No solve goes through NumPy's BLAS (here: `np.linalg.norm`, `np.dot`), which keeps
    threads of its own beside Numba's: one `np.linalg.norm` of the right-hand side per Jacobi
    solve made every phase of the DFG 2D-2 scene with ``viscosity_solver = "jacobi"`` twice
    as slow on 2 cores (pressure 15 -> 28 ms a step, advection 12 -> 19 ms; 2026-12-07)."""

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("BLAS called")

    operator = random_operator((40, 30), 3)
    rhs = np.random.default_rng(3).standard_normal(operator.shape)
    monkeypatch.setattr(np.linalg, "norm", refuse)
    monkeypatch.setattr(np, "dot", refuse)
    x, report = make_solver(rtol=1e-8).solve(operator, rhs)
    assert report.converged and np.isfinite(x).all()
