"""The multigrid hierarchy's rebuild in one kernel, and operators assembled by kernels."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow.linalg import Operator5Point, PoissonSolverMGPCG
from elastoflow.linalg._kernels import (
    build_coarse_levels_kernel,
    coarsen_parallel,
    coarsen_serial,
    dense_matrix_kernel,
    semidefinite_cholesky_kernel,
)


def _operator(shape: tuple[int, int], seed: int) -> Operator5Point:
    """Weights 1 or 0 (an irregular liquid region) and a few Dirichlet diagonal terms."""
    rng = np.random.default_rng(seed)
    m, n = shape
    diagonal = np.where(rng.random(shape) < 0.1, rng.uniform(1.0, 1000.0, shape), 0.0)
    weights_x = (rng.random((m - 1, n)) < 0.8).astype(np.float64)
    weights_y = (rng.random((m, n - 1)) < 0.8).astype(np.float64)
    return Operator5Point(diagonal, weights_x, weights_y)


@pytest.mark.parametrize("shape", [(64, 33), (37, 20), (5, 7)])
def test_one_kernel_builds_the_levels_the_calls_one_by_one_build(shape: tuple[int, int]) -> None:
    """`build_coarse_levels_kernel` gives bitwise the levels and factor of the serial and
    of the threaded coarsening called level by level."""
    solver = PoissonSolverMGPCG()
    operator = _operator(shape, 1)
    solver.solve(operator, np.ones(shape))
    hierarchy = solver._hierarchy(shape)
    built = [array.copy() for array in (hierarchy.diagonal, hierarchy.weights_x,
                                        hierarchy.weights_y, hierarchy.total, hierarchy.inverse)]
    factor = hierarchy.factor.copy()
    for coarsen in (coarsen_serial, coarsen_parallel):
        arrays = [array.copy() for array in built]
        fine = int(hierarchy.offsets[1])
        for array in arrays:
            array[fine:] = 0.0
        for level in range(1, len(hierarchy.rows)):
            a, b, c = (int(hierarchy.offsets[level - 1]), int(hierarchy.offsets[level]),
                       int(hierarchy.offsets[level + 1]))
            coarsen(*(array[a:b] for array in arrays[:4]), *(array[b:c] for array in arrays),
                    int(hierarchy.cols[level - 1]), int(hierarchy.rows[level]),
                    int(hierarchy.cols[level]))
        last = len(hierarchy.rows) - 1
        a, b = int(hierarchy.offsets[last]), int(hierarchy.offsets[last + 1])
        dense = np.zeros_like(hierarchy.dense)
        dense_matrix_kernel(arrays[0][a:b], arrays[1][a:b], arrays[2][a:b],
                            int(hierarchy.rows[last]), int(hierarchy.cols[last]), dense)
        own_factor = np.zeros_like(factor)
        semidefinite_cholesky_kernel(dense, own_factor)
        for mine, theirs in zip(arrays, built):
            assert np.array_equal(mine, theirs)
        assert np.array_equal(own_factor, factor)
    again = [array.copy() for array in built]
    build_coarse_levels_kernel(hierarchy.rows, hierarchy.cols, hierarchy.offsets, *again,
                               hierarchy.dense, hierarchy.factor)
    for mine, theirs in zip(again, built):
        assert np.array_equal(mine, theirs)


def test_an_assembled_operator_solves_as_a_checked_one() -> None:
    shape = (24, 17)
    checked = _operator(shape, 2)
    assembled = Operator5Point.assembled(checked.diagonal.copy(), checked.weights_x.copy(),
                                         checked.weights_y.copy())
    rhs = np.random.default_rng(3).standard_normal(shape)
    x, report = PoissonSolverMGPCG().solve(checked, rhs)
    y, other = PoissonSolverMGPCG().solve(assembled, rhs)
    assert np.array_equal(x, y)
    assert report == other


def test_an_assembled_operator_checks_its_shapes() -> None:
    with pytest.raises(ValueError, match="weights_x: shape"):
        Operator5Point.assembled(np.zeros((4, 3)), np.zeros((4, 3)), np.zeros((4, 2)))
    with pytest.raises(ValueError, match="weights_y: shape"):
        Operator5Point.assembled(np.zeros((4, 3)), np.zeros((3, 3)), np.zeros((4, 2), np.float32))
