"""The 7-point operator and PoissonSolverMGPCG3D: the 2D solvers' contract in 3D, checked
against a direct sparse solve."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import sparse
from chebyshev_bound import chebyshev_bound
from scipy.sparse.linalg import spsolve

from elastoflow.linalg import (
    Operator7Point,
    PoissonSolverMGPCG3D,
    SolveReport,
    apply_operator_3d,
)
from elastoflow.linalg._chebyshev_kernels3d import chebyshev_pass_kernel_3d
from elastoflow.linalg._kernels3d import (
    BLACK,
    NO_BOX,
    NOT_UNIFORM,
    RED,
    _sweep_parallel,
    _sweep_serial,
    apply_dot_kernel_3d,
    apply_dot_uniform_kernel_3d,
    inner_value_kernel_3d,
    load_operator_kernel_3d,
    residual_kernel_3d,
    residual_uniform_kernel_3d,
    restrict_residual_kernel_3d,
    uniform_box_kernel,
    uniform_weight_kernel,
)
from elastoflow.linalg._restrict_kernels3d import restrict_residual_uniform_kernel_3d, row_ends


def laplacian(n: int, outflow: bool = False, shape: tuple[int, int, int] | None = None,
              diagonal: float = 0.0) -> Operator7Point:
    """Unit weights on an (m, n, l) box; ``outflow`` adds the Dirichlet term 2 on the last
    x plane (p = 0 on that side)."""
    m, n_, l = shape if shape is not None else (n, n, n)
    d = np.full((m, n_, l), diagonal)
    if outflow:
        d[-1] += 2.0
    return Operator7Point(d, np.ones((m - 1, n_, l)), np.ones((m, n_ - 1, l)),
                          np.ones((m, n_, l - 1)))


def random_operator(shape: tuple[int, int, int], seed: int) -> Operator7Point:
    rng = np.random.default_rng(seed)
    m, n, l = shape
    return Operator7Point(
        rng.uniform(0.0, 0.2, shape) * (rng.random(shape) < 0.1),
        rng.uniform(0.1, 2.0, (m - 1, n, l)), rng.uniform(0.1, 2.0, (m, n - 1, l)),
        rng.uniform(0.1, 2.0, (m, n, l - 1)))


def body_operator(shape: tuple[int, int, int], seed: int,
                  box: tuple[int, int, int, int, int, int]) -> Operator7Point:
    """Unit weights (Dirichlet on the last x plane) except the weights touching the points
    of ``box`` (half-open), which are random, a third of them 0, and some of its points
    inactive: the pressure operator around a body."""
    rng = np.random.default_rng(seed)
    base = laplacian(0, outflow=True, shape=shape)
    arrays = [base.diagonal.copy(), base.weights_x.copy(), base.weights_y.copy(),
              base.weights_z.copy()]
    i0, i1, j0, j1, k0, k1 = box
    inside = np.zeros(shape, dtype=bool)
    inside[i0:i1, j0:j1, k0:k1] = True
    for axis, weights in enumerate(arrays[1:]):
        low = [slice(None)] * 3
        high = [slice(None)] * 3
        low[axis], high[axis] = slice(None, -1), slice(1, None)
        touched = inside[tuple(low)] | inside[tuple(high)]
        values = rng.uniform(0.1, 1.0, weights.shape) * (rng.random(weights.shape) > 0.3)
        weights[touched] = values[touched]
    return Operator7Point(*arrays)


def held_planes_operator(shape: tuple[int, int, int], axis: int, seed: int,
                         box: tuple[int, int, int, int, int, int] | None = None,
                         c: float = 0.05) -> Operator7Point:
    """Implicit viscosity ``I - c lap`` of a velocity component whose first and last planes
    along ``axis`` are held (diagonal 1, no weights: a wall's normal velocity, an inflow),
    with walls' ghosts on the diagonal of the other sides' planes; with ``box``, random
    weights around a body as in `body_operator`."""
    m, n, l = shape
    diagonal = np.ones(shape) + 6.0 * c
    weights = [np.full((m - 1, n, l), c), np.full((m, n - 1, l), c), np.full((m, n, l - 1), c)]
    for along, w in enumerate(weights):
        first = [slice(None)] * 3
        last = [slice(None)] * 3
        first[along], last[along] = 0, -1
        if along == axis:
            w[tuple(first)] = 0.0
            w[tuple(last)] = 0.0
            diagonal[tuple(first)] = 1.0
            diagonal[tuple(last)] = 1.0
    if box is not None:
        rng = np.random.default_rng(seed)
        i0, i1, j0, j1, k0, k1 = box
        inside = np.zeros(shape, dtype=bool)
        inside[i0:i1, j0:j1, k0:k1] = True
        for along, w in enumerate(weights):
            low = [slice(None)] * 3
            high = [slice(None)] * 3
            low[along], high[along] = slice(None, -1), slice(1, None)
            touched = inside[tuple(low)] | inside[tuple(high)]
            values = rng.uniform(0.0, 2.0 * c, w.shape) * (rng.random(w.shape) > 0.3)
            w[touched] = values[touched]
    return Operator7Point(diagonal, *weights)


def everything_differs(weights_x: np.ndarray, weights_y: np.ndarray, weights_z: np.ndarray,
                       weight: float, shell: int, box: np.ndarray) -> int:
    """A stand-in for `uniform_box_kernel` that finds every weight differing: the box is
    the whole level, so the solver keeps the weighted kernels."""
    box[:] = [0, weights_y.shape[0], 0, weights_x.shape[1], 0, weights_x.shape[2], shell]
    return weights_x.size + weights_y.size + weights_z.size


def sparse_matrix(operator: Operator7Point) -> sparse.csr_matrix:
    """The operator assembled face by face (row-major numbering)."""
    m, n, l = operator.shape
    index = np.arange(m * n * l).reshape(m, n, l)
    rows, cols, values = [index.ravel()], [index.ravel()], [operator.diagonal.ravel()]
    for weights, first, second in (
        (operator.weights_x, index[:-1], index[1:]),
        (operator.weights_y, index[:, :-1], index[:, 1:]),
        (operator.weights_z, index[:, :, :-1], index[:, :, 1:]),
    ):
        a, b, w = first.ravel(), second.ravel(), weights.ravel()
        rows += [a, b, a, b]
        cols += [a, b, b, a]
        values += [w, w, -w, -w]
    size = m * n * l
    return sparse.csr_matrix(
        (np.concatenate(values), (np.concatenate(rows), np.concatenate(cols))), shape=(size, size))


def test_apply_matches_the_assembled_matrix_and_is_symmetric() -> None:
    operator = random_operator((5, 4, 6), seed=1)
    rng = np.random.default_rng(2)
    x, y = rng.standard_normal((2, 5, 4, 6))
    ax = apply_operator_3d(operator, x)
    np.testing.assert_allclose(ax.ravel(), sparse_matrix(operator) @ x.ravel(), atol=1e-12)
    assert np.dot(y.ravel(), ax.ravel()) == pytest.approx(
        np.dot(x.ravel(), apply_operator_3d(operator, y).ravel()), rel=1e-12)


def test_solution_matches_a_direct_solve() -> None:
    operator = random_operator((12, 9, 10), seed=3)
    operator.diagonal[0, 0, 0] = 1.0  # at least one Dirichlet point: non-singular
    rhs = np.random.default_rng(4).standard_normal(operator.shape)
    x, report = PoissonSolverMGPCG3D(rtol=1e-10).solve(operator, rhs)
    reference = spsolve(sparse_matrix(operator).tocsc(), rhs.ravel()).reshape(operator.shape)
    assert report.converged and report.residual <= 1e-10
    np.testing.assert_allclose(x, reference, atol=1e-7 * np.abs(reference).max())


def test_report_gives_the_true_residual() -> None:
    operator = laplacian(16, outflow=True)
    rhs = np.random.default_rng(5).standard_normal(operator.shape)
    x, report = PoissonSolverMGPCG3D(rtol=1e-6).solve(operator, rhs)
    true = np.linalg.norm(rhs - apply_operator_3d(operator, x)) / np.linalg.norm(rhs)
    assert report.residual == pytest.approx(true, rel=1e-6)
    assert true <= 1e-6 and report.converged and report.incompatibility == 0.0


def test_closed_box_is_made_compatible_and_answers_zero_mean() -> None:
    operator = laplacian(16)
    rng = np.random.default_rng(6)
    rhs = rng.standard_normal(operator.shape)
    rhs -= rhs.mean()
    x, report = PoissonSolverMGPCG3D().solve(operator, rhs)
    assert report.converged and report.incompatibility < 1e-12
    assert abs(x.mean()) < 1e-12
    # Net inflow into a closed box: solved for its compatible part, never reported converged.
    x, report = PoissonSolverMGPCG3D().solve(operator, rhs + 1.0)
    assert not report.converged and report.incompatibility > 0.5
    assert report.residual <= 1e-6


def test_inactive_points_get_zero_and_components_are_separate() -> None:
    # A wall plane of inactive points splits the box into a closed part (singular) and a part
    # with a Dirichlet point.
    operator = random_operator((10, 8, 8), seed=7)
    for array in (operator.diagonal, operator.weights_y, operator.weights_z):
        array[5] = 0.0
    operator.weights_x[4:6] = 0.0
    operator.diagonal[:5] = 0.0
    operator.diagonal[9, 0, 0] = 1.0
    rhs = np.random.default_rng(8).standard_normal(operator.shape)
    x, report = PoissonSolverMGPCG3D().solve(operator, rhs)
    assert np.all(x[5] == 0.0)
    assert abs(x[:5].mean()) < 1e-12
    compatible = rhs.copy()
    compatible[5] = 0.0
    compatible[:5] -= compatible[:5].mean()
    residual = compatible - apply_operator_3d(operator, x)
    assert np.linalg.norm(residual) <= 1e-6 * np.linalg.norm(compatible)
    assert report.residual <= 1e-6 and 0.0 < report.incompatibility < 1.0


def test_warm_start_from_the_solution_takes_no_iteration_and_out_may_be_x0() -> None:
    operator = laplacian(16, outflow=True)
    rhs = np.random.default_rng(9).standard_normal(operator.shape)
    solver = PoissonSolverMGPCG3D(rtol=1e-8)
    x, _ = solver.solve(operator, rhs)
    again = x.copy()
    result, report = PoissonSolverMGPCG3D(rtol=1e-6).solve(operator, rhs, x0=again, out=again)
    assert result is again and report.iterations == 0
    np.testing.assert_allclose(again, x)


def test_strongly_diagonal_operator_is_solved_without_coarse_levels() -> None:
    # Implicit viscosity, I - c lap with c = nu dt / h^2 = 0.5.
    base = laplacian(16)
    operator = Operator7Point(np.ones(base.shape), 0.5 * base.weights_x, 0.5 * base.weights_y,
                              0.5 * base.weights_z)
    rhs = np.random.default_rng(10).standard_normal(operator.shape)
    solver = PoissonSolverMGPCG3D()
    x, report = solver.solve(operator, rhs)
    assert not solver._hierarchies[operator.shape].coarse
    # Jacobi-preconditioned Chebyshev: 17 iterations at nu dt / h^2 = 0.5.
    assert report.converged and report.iterations <= 20
    assert np.linalg.norm(rhs - apply_operator_3d(operator, x)) <= 1e-6 * np.linalg.norm(rhs)


@pytest.mark.parametrize("outflow", [False, True])
def test_iteration_count_is_flat_in_grid_size(outflow: bool) -> None:
    counts = []
    for n in (16, 32):
        operator = laplacian(n, outflow=outflow)
        grid = (np.arange(n) + 0.5) / n
        x, y, z = np.meshgrid(grid, grid, grid, indexing="ij")
        rhs = np.sin(3 * x) * np.cos(5 * y) * np.cos(2 * np.pi * z) + 0.1 * x * y
        if not outflow:
            rhs -= rhs.mean()
        _, report = PoissonSolverMGPCG3D().solve(operator, rhs)
        assert report.converged
        counts.append(report.iterations)
    assert counts[1] <= counts[0] + 1 and counts[1] <= 8


def test_odd_and_flat_shapes() -> None:
    operator = laplacian(0, outflow=True, shape=(3, 17, 40))
    rhs = np.random.default_rng(11).standard_normal(operator.shape)
    x, report = PoissonSolverMGPCG3D().solve(operator, rhs)
    assert report.converged
    assert np.linalg.norm(rhs - apply_operator_3d(operator, x)) <= 1e-6 * np.linalg.norm(rhs)


def test_zero_rhs_returns_zero() -> None:
    operator = laplacian(8, outflow=True)
    x, report = PoissonSolverMGPCG3D().solve(operator, np.zeros(operator.shape))
    assert report == SolveReport(0, 0.0, True, 0.0) and not x.any()


def test_invalid_input_is_refused() -> None:
    operator = laplacian(4)
    solver = PoissonSolverMGPCG3D()
    with pytest.raises(ValueError, match="rhs"):
        solver.solve(operator, np.zeros((4, 4, 5)))
    bad = np.zeros(operator.shape)
    bad[1, 1, 1] = np.nan
    with pytest.raises(ValueError, match="rhs"):
        solver.solve(operator, bad)
    with pytest.raises(ValueError, match="x0"):
        solver.solve(operator, np.zeros(operator.shape), x0=bad)
    with pytest.raises(ValueError, match="out"):
        solver.solve(operator, np.zeros(operator.shape), out=np.zeros((4, 4)))
    with pytest.raises(ValueError, match="weights_z"):
        Operator7Point(np.zeros((4, 4, 4)), np.ones((3, 4, 4)), np.ones((4, 3, 4)),
                       np.ones((4, 4, 4)))
    with pytest.raises(ValueError, match="weights_x"):
        Operator7Point(np.zeros((4, 4, 4)), -np.ones((3, 4, 4)), np.ones((4, 3, 4)),
                       np.ones((4, 4, 3)))
    with pytest.raises(ValueError, match="rtol"):
        PoissonSolverMGPCG3D(rtol=0.0)


def test_shapes_of_equal_size_share_vectors_without_mixing_answers() -> None:
    # The three velocity components of a cubic grid: (n+1) n n, n (n+1) n, n n (n+1).
    solver = PoissonSolverMGPCG3D(rtol=1e-10)
    operators = [laplacian(0, outflow=True, shape=shape)
                 for shape in ((9, 8, 8), (8, 9, 8), (8, 8, 9))]
    rng = np.random.default_rng(12)
    rhs = [rng.standard_normal(op.shape) for op in operators]
    for _ in range(2):
        for operator, b in zip(operators, rhs, strict=True):
            x, report = solver.solve(operator, b)
            alone, _ = PoissonSolverMGPCG3D(rtol=1e-10).solve(operator, b)
            assert report.converged
            np.testing.assert_array_equal(x, alone)
    assert len(solver._vector_pool) == 1 and len(solver._hierarchies) == 3


@pytest.mark.parametrize("kind", ["uniform", "weighted", "boxed", "shelled"])
def test_a_sweep_is_its_two_half_sweeps_however_the_planes_are_split(kind: str) -> None:
    # The fused red-black sweep walks chunks of planes, the second colour one plane behind:
    # it must give the two half sweeps one after the other, for any split into chunks; with
    # a box, the weights' arrays inside it and the one weight outside.
    # Odd and even row lengths: the rows' last columns are of either colour.
    shape = {"shelled": (11, 8, 9), "uniform": (10, 7, 6)}.get(kind, (11, 6, 5))
    operator = {"uniform": lambda: laplacian(0, outflow=True, shape=shape),
                "weighted": lambda: random_operator(shape, 4),
                "boxed": lambda: body_operator(shape, 4, (3, 7, 1, 4, 2, 4)),
                "shelled": lambda: held_planes_operator(shape, 1, 4, (4, 8, 3, 5, 2, 7))
                }[kind]()
    a = (operator.diagonal, operator.weights_x, operator.weights_y, operator.weights_z)
    total, inverse = np.empty(shape), np.empty(shape)
    load_operator_kernel_3d(*a, total, inverse, np.empty(shape, dtype=np.bool_))
    weight = uniform_weight_kernel(*a[1:])
    assert (weight == 1.0) == (kind == "uniform")
    box = NO_BOX
    if kind in ("boxed", "shelled"):
        weight = 1.0 if kind == "boxed" else 0.05
        shell = 2 if kind == "shelled" else 0
        box = np.zeros(7, dtype=np.int64)
        assert uniform_box_kernel(*a[1:], weight, shell, box) > 0
    # The inverse is one number where the uniform runs read without checks.
    inverse_value = inner_value_kernel_3d(inverse, box) if kind != "weighted" else NOT_UNIFORM
    assert (inverse_value == NOT_UNIFORM) == (kind == "weighted")
    rng = np.random.default_rng(5)
    b, start = rng.standard_normal(shape), rng.standard_normal(shape)
    colour = np.indices(shape).sum(axis=0) % 2
    for first, from_zero in ((RED, False), (BLACK, False), (RED, True)):
        expected = np.zeros(shape) if from_zero else start.copy()
        for half in (first, 1 - first):
            coupled = total * expected - apply_operator_3d(operator, expected)
            expected = np.where(colour == half, (b + coupled) * inverse, expected)
        swept = []
        for chunks in (1, 2, 3, 4, 11, 20):
            x = start.copy()
            sweep = _sweep_serial if chunks == 1 else _sweep_parallel
            sweep(x, b, inverse, *a[1:], weight, inverse_value, first, from_zero, chunks, box)
            swept.append(x)
        np.testing.assert_allclose(swept[0], expected, rtol=1e-13, atol=1e-13)
        for x in swept[1:]:
            np.testing.assert_array_equal(x, swept[0])


def test_the_box_holds_every_point_of_a_differing_weight() -> None:
    # The box is the smallest one holding both ends of every weight that differs from the
    # one value: checked against the ends found with numpy.
    shape = (9, 7, 8)
    operator = body_operator(shape, 2, (2, 5, 3, 6, 1, 4))
    a = (operator.weights_x, operator.weights_y, operator.weights_z)
    ends = np.zeros(shape, dtype=bool)
    for axis, weights in enumerate(a):
        differ = weights != 1.0
        low = [slice(None)] * 3
        high = [slice(None)] * 3
        low[axis], high[axis] = slice(None, -1), slice(1, None)
        ends[tuple(low)] |= differ
        ends[tuple(high)] |= differ
    where = np.argwhere(ends)
    box = np.zeros(7, dtype=np.int64)
    count = uniform_box_kernel(*a, 1.0, 0, box)
    assert count == sum(int(np.count_nonzero(w != 1.0)) for w in a)
    expected = [v for axis in range(3)
                for v in (where[:, axis].min(), where[:, axis].max() + 1)]
    assert list(box) == expected + [0]
    # All weights equal: no box.
    plain = laplacian(0, shape=shape)
    assert uniform_box_kernel(plain.weights_x, plain.weights_y, plain.weights_z, 1.0, 0,
                              box) == 0
    assert list(box) == [0] * 7


def test_the_shell_leaves_out_only_the_weights_between_two_of_its_points() -> None:
    # Held planes along y: their weights (0) join points of the shell only and are left
    # out; a body's weights, and a differing weight from the shell to a point inside it,
    # make the box.
    shape = (12, 10, 11)
    operator = held_planes_operator(shape, 1, 0)
    a = (operator.weights_x, operator.weights_y, operator.weights_z)
    box = np.zeros(7, dtype=np.int64)
    assert uniform_box_kernel(*a, 0.05, 0, box) > 0
    assert uniform_box_kernel(*a, 0.05, 2, box) == 0
    assert list(box) == [0] * 6 + [2]
    # The weight from the shell's point (5, 1, 4) to the inside point (5, 2, 4) is read by
    # the inside point's row: it must be in the box.
    operator.weights_y[5, 1, 4] = 0.01
    assert uniform_box_kernel(*a, 0.05, 2, box) == 1
    assert list(box) == [5, 6, 1, 3, 4, 5, 2]
    # Zero weights one plane further in (from y = 2 to 3) are outside the shell but where
    # both of their ends lie in the shell along x or z: 8 x 7 of the 12 x 11 count.
    operator.weights_y[5, 1, 4] = 0.05
    operator.weights_y[:, 2, :] = 0.0
    assert uniform_box_kernel(*a, 0.05, 2, box) == 8 * 7
    assert list(box) == [2, 10, 2, 4, 2, 9, 2]


def test_the_boxed_kernels_are_the_weighted_ones_to_round_off() -> None:
    # Residual, product and restriction with the one weight outside the box and the arrays
    # inside give the weighted kernels' values (the sums differ only in rounding).
    shape = (12, 9, 10)
    operator, weight = body_operator(shape, 7, (4, 9, 2, 6, 3, 8)), 1.0
    a = (operator.diagonal, operator.weights_x, operator.weights_y, operator.weights_z)
    total, inverse = np.empty(shape), np.empty(shape)
    load_operator_kernel_3d(*a, total, inverse, np.empty(shape, dtype=np.bool_))
    box = np.zeros(7, dtype=np.int64)
    uniform_box_kernel(*a[1:], weight, 0, box)
    rng = np.random.default_rng(1)
    x, b = rng.standard_normal(shape), rng.standard_normal(shape)
    x[total == 0.0] = 0.0
    r_weighted, r_boxed = np.empty(shape), np.empty(shape)
    squared = residual_kernel_3d(*a, x, b, r_weighted)
    assert residual_uniform_kernel_3d(total, weight, x, b, r_boxed, *a, box) == pytest.approx(
        squared, rel=1e-13)
    np.testing.assert_allclose(r_boxed, r_weighted, rtol=1e-13, atol=1e-13)
    q_weighted, q_boxed = np.empty(shape), np.empty(shape)
    dot = apply_dot_kernel_3d(*a, x, q_weighted)
    assert apply_dot_uniform_kernel_3d(total, weight, x, q_boxed, *a, box) == pytest.approx(
        dot, rel=1e-13)
    np.testing.assert_allclose(q_boxed, q_weighted, rtol=1e-13, atol=1e-13)
    coarse = tuple((s + 1) // 2 for s in shape)
    c_weighted, c_boxed = np.empty(coarse), np.empty(coarse)
    restrict_residual_kernel_3d(x, b, total, *a[1:], c_weighted)
    restrict_residual_uniform_kernel_3d(x, b, total, NOT_UNIFORM, row_ends(total), weight,
                                        c_boxed, *a[1:], box)
    np.testing.assert_allclose(c_boxed, c_weighted, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("shape", [(12, 9, 10), (11, 8, 9), (9, 10, 7)])
@pytest.mark.parametrize("boxed", [True, False])
def test_the_restriction_reads_the_inner_total_as_one_number(
        shape: tuple[int, int, int], boxed: bool) -> None:
    # Away from the sides and the box the total is one number: read so, the restriction is
    # bitwise the one that reads the array, and the weighted kernel's to round-off (odd
    # sizes: a coarse point with one fine point along an axis).
    if boxed:
        operator = body_operator(shape, 3, (3, 8, 2, 6, 3, 5))
    else:
        operator = laplacian(0, outflow=True, shape=shape)
    a = (operator.diagonal, operator.weights_x, operator.weights_y, operator.weights_z)
    total, inverse = np.empty(shape), np.empty(shape)
    load_operator_kernel_3d(*a, total, inverse, np.empty(shape, dtype=np.bool_))
    box = NO_BOX.copy()
    if boxed:
        uniform_box_kernel(*a[1:], 1.0, 0, box)
    total_value = inner_value_kernel_3d(total, box)
    assert total_value == 6.0
    rng = np.random.default_rng(2)
    x, b = rng.standard_normal(shape), rng.standard_normal(shape)
    x[total == 0.0] = 0.0
    coarse = tuple((s + 1) // 2 for s in shape)
    read, one, weighted = np.empty(coarse), np.empty(coarse), np.empty(coarse)
    sides = row_ends(total)
    restrict_residual_uniform_kernel_3d(x, b, total, NOT_UNIFORM, sides, 1.0, read, *a[1:], box)
    restrict_residual_uniform_kernel_3d(x, b, total, total_value, sides, 1.0, one, *a[1:], box)
    restrict_residual_kernel_3d(x, b, total, *a[1:], weighted)
    np.testing.assert_array_equal(one, read)
    np.testing.assert_allclose(one, weighted, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("kind", ["uniform", "weighted", "boxed", "shelled"])
@pytest.mark.parametrize("first", [True, False])
def test_a_chebyshev_pass_is_its_formula_however_the_operator_is_read(kind: str,
                                                                       first: bool) -> None:
    # other <- x + s_new (b - A x) / D + s_old (x - other), the residual of x returned; the
    # first pass (s_old = 0) must not read `other` (NaN there); inactive points get 0.
    shape = (13, 9, 10)
    operator = {"uniform": lambda: laplacian(0, outflow=True, shape=shape, diagonal=0.5),
                "weighted": lambda: random_operator(shape, 4),
                "boxed": lambda: body_operator(shape, 4, (3, 7, 1, 4, 2, 6)),
                "shelled": lambda: held_planes_operator(shape, 1, 4, (4, 8, 3, 5, 2, 7))
                }[kind]()
    a = (operator.diagonal, operator.weights_x, operator.weights_y, operator.weights_z)
    if kind == "boxed":
        # One point of the box cut off from everything: inactive.
        i, j, k = 5, 2, 3
        a[0][i, j, k] = a[1][i - 1, j, k] = a[1][i, j, k] = a[2][i, j - 1, k] = 0.0
        a[2][i, j, k] = a[3][i, j, k - 1] = a[3][i, j, k] = 0.0
    total, inverse = np.empty(shape), np.empty(shape)
    active = np.empty(shape, dtype=np.bool_)
    load_operator_kernel_3d(*a, total, inverse, active)
    weight, box = uniform_weight_kernel(*a[1:]), NO_BOX
    if kind in ("boxed", "shelled"):
        weight = 1.0 if kind == "boxed" else 0.05
        box = np.zeros(7, dtype=np.int64)
        assert uniform_box_kernel(*a[1:], weight, 2 if kind == "shelled" else 0, box) > 0
        assert box[6] == (2 if kind == "shelled" else 0)
    assert (weight == NOT_UNIFORM) == (kind == "weighted")
    assert (kind == "boxed") == (not active.all())
    rng = np.random.default_rng(8)
    x, b = rng.standard_normal(shape), rng.standard_normal(shape)
    x[~active] = 0.0
    b[~active] = 0.0
    before = np.full(shape, np.nan) if first else rng.standard_normal(shape)
    scale_old, scale_new = (0.0, 1.0) if first else (0.3, 1.7)
    residual = b - apply_operator_3d(operator, x)
    expected = x + scale_new * np.divide(residual, total, out=np.zeros(shape), where=active)
    if not first:
        expected += scale_old * (x - before)
    expected[~active] = 0.0
    # The total's one value where the pass reads the one weight: 6 w + 0.5 (uniform), 6 w
    # (boxed), 1 + 12 c (shelled: `held_planes_operator`'s diagonal holds 1 + 6 c).
    total_value = inner_value_kernel_3d(total, box)
    if kind != "weighted":
        assert total_value == pytest.approx(
            {"uniform": 6.5, "boxed": 6.0, "shelled": 1.6}[kind], abs=1e-14)
    for value in {total_value, NOT_UNIFORM}:
        other = before.copy()
        squared = chebyshev_pass_kernel_3d(total, value, weight, x, b, other, scale_old,
                                           scale_new, *a[1:], box)
        assert squared == pytest.approx(float(np.sum(residual**2)), rel=1e-12)
        np.testing.assert_allclose(other, expected, rtol=1e-13, atol=1e-13)


@pytest.mark.parametrize("c", [0.01, 0.085, 0.5])
@pytest.mark.parametrize("warm", [False, True])
def test_the_chebyshev_iteration_keeps_its_gershgorin_rate(c: float, warm: bool) -> None:
    # I - c lap with held planes and a body's random weights: the solve takes no coarse
    # levels, reaches the direct solution, and stops within the count its interval
    # guarantees: r_k = D^1/2 p_k(D^-1/2 A D^-1/2) D^-1/2 r_0 with |p_k| <= 2 q^k on
    # [1 - s, 1 + s], s the largest Jacobi row sum.
    shape = (17, 14, 15)
    operator = held_planes_operator(shape, 0, 3, (5, 10, 4, 9, 6, 11), c=c)
    rhs = np.random.default_rng(21).standard_normal(shape)
    matrix = sparse_matrix(operator)
    expected = spsolve(matrix.tocsc(), rhs.ravel()).reshape(shape)
    x0 = expected + 0.01 * np.random.default_rng(22).standard_normal(shape) if warm else None
    solver = PoissonSolverMGPCG3D(rtol=1e-9)
    x, report = solver.solve(operator, rhs, x0=x0)
    assert not solver._hierarchies[shape].coarse
    assert report.converged
    true = np.linalg.norm(rhs - apply_operator_3d(operator, x)) / np.linalg.norm(rhs)
    assert true == pytest.approx(report.residual, rel=1e-6)
    np.testing.assert_allclose(x, expected, rtol=0, atol=1e-8 * np.abs(expected).max())
    start = np.zeros(shape) if x0 is None else x0
    spread, passes = chebyshev_bound(matrix, rhs, start, 1e-9)
    assert spread == pytest.approx(solver._hierarchies[shape].spread, rel=1e-12)
    assert report.iterations <= passes


def test_the_chebyshev_iteration_without_weights_is_exact() -> None:
    shape = (9, 7, 8)
    diagonal = np.random.default_rng(5).uniform(0.5, 4.0, shape)
    operator = Operator7Point(diagonal, np.zeros((8, 7, 8)), np.zeros((9, 6, 8)),
                              np.zeros((9, 7, 7)))
    rhs = np.random.default_rng(6).standard_normal(shape)
    x, report = PoissonSolverMGPCG3D().solve(operator, rhs)
    assert report.converged and report.iterations <= 1
    np.testing.assert_allclose(x, rhs / diagonal, rtol=1e-12)


def test_a_body_operator_solves_with_its_box(monkeypatch: pytest.MonkeyPatch) -> None:
    # The solver finds the box on the fine level and solves to its tolerance; the answer is
    # the one the weighted kernels give everywhere (the box's search switched off).
    shape = (16, 12, 14)
    operator = body_operator(shape, 3, (5, 10, 3, 8, 4, 9))
    rhs = np.random.default_rng(4).standard_normal(shape)
    solver = PoissonSolverMGPCG3D(rtol=1e-10)
    x, report = solver.solve(operator, rhs)
    assert report.converged
    level = solver._hierarchy(shape).levels[0]
    assert level.uniform == 1.0 and level.box is not NO_BOX
    import elastoflow.linalg._mgpcg3d as module

    monkeypatch.setattr(module, "uniform_box_kernel", everything_differs)
    weighted = PoissonSolverMGPCG3D(rtol=1e-10)
    y, other = weighted.solve(operator, rhs)
    assert other.converged
    assert weighted._hierarchy(shape).levels[0].uniform == NOT_UNIFORM
    np.testing.assert_allclose(x, y, rtol=0, atol=1e-8 * np.abs(y).max())


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_a_viscosity_operator_with_held_planes_solves_with_its_shell(
        monkeypatch: pytest.MonkeyPatch, axis: int) -> None:
    # Held planes make the weights to them 0: the fine level takes the one weight outside
    # the shell (and a body's box) and gives the weighted kernels' answer.
    shape = (24, 20, 22)
    operator = held_planes_operator(shape, axis, 2, (8, 14, 6, 12, 9, 15))
    rhs = np.random.default_rng(9).standard_normal(shape)
    solver = PoissonSolverMGPCG3D(rtol=1e-12)
    x, report = solver.solve(operator, rhs)
    assert report.converged
    level = solver._hierarchy(shape).levels[0]
    # The weights touching the body's points reach one point beyond them.
    assert level.uniform == 0.05 and list(level.box[:6]) == [7, 15, 5, 13, 8, 16]
    assert level.box[6] == 2
    # The passes read the total there as one number too (1 + 12 c: see the operator).
    assert level.inner_total == pytest.approx(1.6, abs=1e-14)
    expected = spsolve(sparse_matrix(operator).tocsc(), rhs.ravel()).reshape(shape)
    np.testing.assert_allclose(x, expected, rtol=0, atol=1e-10 * np.abs(expected).max())
    import elastoflow.linalg._mgpcg3d as module

    monkeypatch.setattr(module, "uniform_box_kernel", everything_differs)
    weighted = PoissonSolverMGPCG3D(rtol=1e-12)
    y, other = weighted.solve(operator, rhs)
    assert weighted._hierarchy(shape).levels[0].uniform == NOT_UNIFORM
    np.testing.assert_allclose(x, y, rtol=0, atol=1e-10 * np.abs(y).max())


def test_an_assembled_operator_is_the_checked_one_and_wrong_shapes_are_refused() -> None:
    # The library's kernels build operators through `Operator7Point.assembled`, which skips
    # the pass over the values but not the shapes.
    operator = random_operator((5, 4, 3), 8)
    arrays = (operator.diagonal, operator.weights_x, operator.weights_y, operator.weights_z)
    assembled = Operator7Point.assembled(*arrays)
    for name in ("diagonal", "weights_x", "weights_y", "weights_z"):
        assert getattr(assembled, name) is getattr(operator, name)
    x = np.random.default_rng(2).standard_normal((5, 4, 3))
    np.testing.assert_array_equal(apply_operator_3d(assembled, x),
                                  apply_operator_3d(operator, x))
    with pytest.raises(ValueError, match="weights_y: shape"):
        Operator7Point.assembled(arrays[0], arrays[1], arrays[1], arrays[3])
    with pytest.raises(ValueError, match="values must be finite"):
        Operator7Point.assembled(arrays[0].astype(np.float32), arrays[1], arrays[2],
                                 np.full_like(arrays[3], np.nan))


def test_the_components_are_kept_while_the_positive_pattern_holds() -> None:
    # A body moving within its cells changes the open fractions, not which faces are open:
    # the components (and the singular ones) of the last operator are reused; a face that
    # closes makes them labelled afresh. The answers are those of a fresh solver.
    shape = (10, 8, 9)
    first = body_operator(shape, 6, (3, 7, 2, 6, 3, 7))
    arrays = [first.diagonal, first.weights_x, first.weights_y, first.weights_z]
    scaled = Operator7Point(*[a * 1.5 for a in arrays])
    closed_weights = first.weights_y.copy()
    closed_weights[4, 3, 4] = 0.0
    closed = Operator7Point(first.diagonal.copy(), first.weights_x.copy(), closed_weights,
                            first.weights_z.copy())
    assert first.weights_y[4, 3, 4] > 0.0
    rhs = np.random.default_rng(9).standard_normal(shape)
    solver = PoissonSolverMGPCG3D(rtol=1e-10)
    solver.solve(first, rhs)
    hierarchy = solver._hierarchy(shape)
    labels = hierarchy.null_space.labels
    assert labels is not None  # not every point has a diagonal: the components were labelled
    x, report = solver.solve(scaled, rhs)
    assert report.converged and hierarchy.null_space.labels is labels
    y, _ = PoissonSolverMGPCG3D(rtol=1e-10).solve(scaled, rhs)
    np.testing.assert_allclose(x, y, rtol=0, atol=1e-9 * np.abs(y).max())
    x, report = solver.solve(closed, rhs)
    assert report.converged and hierarchy.null_space.labels is not labels
    y, _ = PoissonSolverMGPCG3D(rtol=1e-10).solve(closed, rhs)
    np.testing.assert_allclose(x, y, rtol=0, atol=1e-9 * np.abs(y).max())


def test_the_inner_columns_split_a_run_into_its_sides_and_the_rest_exactly() -> None:
    # `_inner_columns` splits range(k_from, k_to, step) into the columns before 1, those in
    # [1, l - 2] (read with unsigned indices, no side checks) and those after: the three
    # ranges together are the run, in order, and the middle one holds exactly its inner
    # columns.
    from elastoflow.linalg._kernels3d import _inner_columns

    for l in range(1, 9):
        for step in (1, 2):
            for k_from in range(0, l + 1):
                for k_to in range(k_from, l + 1):
                    first, stop, resume = _inner_columns(k_from, k_to, step, l)
                    head = list(range(k_from, min(first, k_to), step))
                    inner = list(range(first, stop, step))
                    tail = list(range(resume, k_to, step))
                    assert head + inner + tail == list(range(k_from, k_to, step))
                    assert all(1 <= k <= l - 2 for k in inner)
                    assert all(not 1 <= k <= l - 2 for k in head + tail)


def test_the_in_place_chebyshev_solve_keeps_the_contract() -> None:
    # Every point active: the right-hand side is read where it is and a warm start that is
    # the output stays there. An odd pass count makes the next solve start in the other
    # buffer (no copy at the end), with bitwise the answer of a fresh solver; an output that
    # is the right-hand side, and non-finite inputs, are handled as by the masked path.
    shape = (12, 10, 11)
    operator = held_planes_operator(shape, 2, 5, (3, 8, 2, 7, 4, 9), c=0.2)
    rhs = np.random.default_rng(31).standard_normal(shape)
    start = rhs + 0.01 * np.random.default_rng(32).standard_normal(shape)
    # A tolerance that takes an odd number of passes.
    rtol = next(r for r in (1e-8, 5e-9, 2e-9, 1e-9, 5e-10)
                if PoissonSolverMGPCG3D(rtol=r).solve(operator, rhs, x0=start)[1].iterations % 2)
    solver = PoissonSolverMGPCG3D(rtol=rtol)
    answers = []
    for _ in range(3):
        out = start.copy()
        x, report = solver.solve(operator, rhs, x0=out, out=out)
        assert x is out and report.converged
        answers.append(x)
    assert report.iterations % 2 == 1 and solver._hierarchies[shape].odd
    fresh, _ = PoissonSolverMGPCG3D(rtol=rtol).solve(operator, rhs, x0=start.copy())
    for x in answers:
        np.testing.assert_array_equal(x, fresh)
    aliased = rhs.copy()
    x, report = PoissonSolverMGPCG3D(rtol=1e-8).solve(operator, aliased, out=aliased)
    assert report.converged
    np.testing.assert_allclose(apply_operator_3d(operator, x), rhs, rtol=0, atol=1e-6)
    bad = start.copy()
    bad[4, 5, 6] = np.inf
    kept = bad.copy()
    # A fresh solver starts in the output: the warm start is read in place, its inf found
    # by the first pass; the others copy it (probed) into the other buffer.
    for user, x0 in ((PoissonSolverMGPCG3D(), bad), (solver, bad), (solver, bad.copy())):
        with pytest.raises(ValueError, match="x0: values must be finite"):
            user.solve(operator, rhs, x0=x0, out=bad)
        np.testing.assert_array_equal(bad, kept)
    with pytest.raises(ValueError, match="rhs: values must be finite"):
        solver.solve(operator, bad, x0=start.copy())


def test_the_inner_total_is_found_only_where_it_is_one_value() -> None:
    # The viscosity operator's total is one value away from the sides and the body; a point
    # there with another diagonal makes it not uniform; one in the shell or the box does not.
    shape = (14, 12, 13)
    operator = held_planes_operator(shape, 0, 2, (5, 9, 4, 8, 5, 9), c=0.1)
    a = (operator.diagonal, operator.weights_x, operator.weights_y, operator.weights_z)
    total, inverse = np.empty(shape), np.empty(shape)
    load_operator_kernel_3d(*a, total, inverse, np.empty(shape, dtype=np.bool_))
    box = np.zeros(7, dtype=np.int64)
    uniform_box_kernel(*a[1:], 0.1, 2, box)
    assert inner_value_kernel_3d(total, box) == pytest.approx(2.2, abs=1e-14)
    for point, uniform in (((1, 5, 5), True), ((6, 6, 6), True), ((11, 2, 10), False)):
        changed = total.copy()
        changed[point] += 0.25
        assert (inner_value_kernel_3d(changed, box) != NOT_UNIFORM) == uniform
