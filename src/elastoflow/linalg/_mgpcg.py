"""Conjugate gradient preconditioned by a geometric multigrid V-cycle."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from elastoflow.linalg._banded import banded_selected_inverse
from elastoflow.linalg._kernels import (
    active_spans_kernel,
    build_coarse_levels_kernel,
    chebyshev_kernel,
    level_spans_kernel,
    load_operator_kernel,
    low_rank_apply_kernel,
    low_rank_band_gap,
    low_rank_diagonal_kernel,
    pad_masked_kernel,
    pad_values_kernel,
    pcg_kernel,
    pcg_low_rank_kernel,
    sum_of_squares_kernel,
    unpad_values_kernel,
)
from elastoflow.linalg._operator import Operator5Point, SolveReport
from elastoflow.linalg._problem import _analyse, _NullSpace, _output, incompatibility

_COARSEST_SIZE = 32
# Smallest ratio of diagonal term to sum of weights, over all points, for which the
# Jacobi-preconditioned Chebyshev iteration beats MGPCG. Measured on I + c L at 256^2 (warm
# start from a 2 % perturbation, rtol 1e-6), ms per solve Chebyshev / MGPCG (iterations):
# c = 0.085: 0.45 (5) / 0.63 (1), c = 0.33: 0.52 (7) / 0.99 (2), c = 1: 0.78 (13) / 0.96 (2),
# c = 2: 1.07 (19) / 0.97 (2), c = 4: 1.60 (29) / 1.40 (3) (ratio = 1 / (4 c)). At ratio
# 1/4 the Jacobi row sums are <= 0.8, and each Chebyshev iteration divides the error by ~2.
_SMOOTHER_ONLY_DOMINANCE = 0.25


@dataclass(frozen=True)
class BandedInverse:
    """``(U^T U)^-1`` of an upper triangular banded ``U``, for some of a `LowRankTerm`'s
    columns: applied by two sweeps (`banded_solve_in_place`), never formed.

    Attributes:
        columns: ``U`` along its columns, ``columns[i, t] = U[i - b + t, i]``, (N, b + 1).
        rows: ``U`` along its rows, ``rows[i, t] = U[i, i + t]``, (N, b + 1).
        slots: For each of the term's k columns, its position in ``U`` or -1, int64, (k,).
    """

    columns: NDArray[np.float64]
    rows: NDArray[np.float64]
    slots: NDArray[np.int64]


_NO_INDEX = np.zeros(0, np.int64)
_NO_MATRIX = np.zeros((0, 0))
_NO_BAND = np.zeros((0, 1))
# How many times its own band the inverse's band may be widened for an exact diagonal (see
# `LowRankTerm.diagonal_with_count`): Turek-Hron's flag at 20 cells per diameter needs 38
# against a band of 25.
_WIDEST_BAND = 4
# ... and while the selected inverse's work n b w stays below this: a 3D body's banded
# factor is wide (the settling sphere at 6 cells per diameter: n = 2337, b = 431), where
# pairs of columns meeting at a cell can lie n apart; the diagonal is then approximate
# (only the preconditioner reads it) instead of costing seconds a step (2.1 s there, for
# the band alone).
_DIAGONAL_WORK_LIMIT = 2.0e8
# Above this work for the band alone (n b^2), only each column's own entry: the elastic
# block of elastic_block_3d (2295 dofs) spent 240 of its 478 ms a step in the band's
# selected inverse; with its own entries only, 210 ms a step and 8-9 CG iterations instead
# of 8. 2D bodies (Turek-Hron's flag: n b^2 ~ 1e6) stay exact.
_EXACT_DIAGONAL_LIMIT = 5.0e7


@dataclass(frozen=True)
class LowRankTerm:
    """A symmetric positive semi-definite term ``C = scale B M B^T`` added to a 5-point
    operator on ``(m, n)`` points (or a 7-point one on ``(m, n, l)``): ``B`` sparse with few
    touched points, ``M`` block diagonal with a small dense block and a `BandedInverse` (a
    body's compliance through its factor).

    Attributes:
        offsets: CSR row offsets of ``B^T`` (one row per column of ``B``), int64, (k+1,).
        points: Flat point index (C order: ``i * n + j``, ``(i * n + j) * l + k``) of each
            entry, int64.
        weights: ``B``'s value of each entry.
        matrix: The dense block of ``M``, symmetric positive semi-definite: (k, k) over every
            column when ``dense_slots`` is None, else over the columns it names.
        scale: ``scale`` >= 0.
        dense_slots: For each column, its row in ``matrix`` or -1 (None: all, in order).
        banded: The banded block, on the columns its ``slots`` name (disjoint from the
            dense block's).
    """

    offsets: NDArray[np.int64]
    points: NDArray[np.int64]
    weights: NDArray[np.float64]
    matrix: NDArray[np.float64]
    scale: float
    dense_slots: NDArray[np.int64] | None = None
    banded: BandedInverse | None = None

    @property
    def columns(self) -> int:
        return int(self.offsets.shape[0] - 1)

    def kernel_term(self) -> tuple:
        """The arrays the kernels read, bundled (with scratch space): offsets, weights,
        scale, dense slots, dense block, band slots, ``U`` by columns and by rows, and the
        scratch vectors."""
        k = self.columns
        dense = (np.arange(k, dtype=np.int64) if self.dense_slots is None
                 else np.ascontiguousarray(self.dense_slots, dtype=np.int64))
        matrix = np.ascontiguousarray(self.matrix, dtype=np.float64)
        if matrix.size == 0:
            matrix = _NO_MATRIX
        if self.banded is None:
            band_slots, columns, rows = np.full(k, -1, np.int64), _NO_BAND, _NO_BAND
        else:
            band_slots = np.ascontiguousarray(self.banded.slots, dtype=np.int64)
            columns = np.ascontiguousarray(self.banded.columns, dtype=np.float64)
            rows = np.ascontiguousarray(self.banded.rows, dtype=np.float64)
        return (np.ascontiguousarray(self.offsets, dtype=np.int64),
                np.ascontiguousarray(self.weights, dtype=np.float64), float(self.scale),
                dense, matrix, band_slots, columns, rows, np.zeros(k), np.zeros(k),
                np.zeros(matrix.shape[0]), np.zeros(matrix.shape[0]),
                np.zeros(columns.shape[0]))

    def diagonal(self, shape: tuple[int, ...]) -> NDArray[np.float64]:
        """``diag(C)`` as an (m, n) array (see `diagonal_with_count` for when it is not
        exact)."""
        return self.diagonal_with_count(shape)[0]

    def diagonal_with_count(self, shape: tuple[int, ...]) -> tuple[NDArray[np.float64], int]:
        """``diag(C)`` and the number of pairs of banded columns meeting at a point whose
        entry of the inverse was not computed (0: exact). The banded part's entries come from
        the inverse's band widened as far as such pairs reach, up to ``_WIDEST_BAND`` times
        the factor's band (cost ``n b w``); pairs further apart count as 0, which only the
        preconditioner reads (it needs an approximation of the diagonal, kept >= 0)."""
        out = np.zeros(math.prod(shape))
        points = np.ascontiguousarray(self.points, dtype=np.int64)
        term = self.kernel_term()
        selected = _NO_BAND
        if self.banded is not None and self.banded.rows.shape[0]:
            rows = np.ascontiguousarray(self.banded.rows)
            gap = low_rank_band_gap(points, term, out.shape[0])
            n, band = rows.shape[0], rows.shape[1]
            if n * band * band > _EXACT_DIAGONAL_LIMIT:
                # Even the band's own entries cost too much: each column's own entry only,
                # as 1 / (U^T U)_ii (a lower bound of the inverse's; the off-diagonal
                # pairs count as outside).
                columns = np.ascontiguousarray(self.banded.columns)
                selected = (1.0 / np.einsum("ij,ij->i", columns, columns))[:, None]
            else:
                affordable = int(_DIAGONAL_WORK_LIMIT // max(n * band, 1))
                width = max(band - 1, min(gap, _WIDEST_BAND * band, n - 1, affordable))
                selected = np.empty((rows.shape[0], width + 1))
                banded_selected_inverse(rows, selected)
        outside = low_rank_diagonal_kernel(points, term, selected, out.shape[0], out)
        return out.reshape(shape), int(outside)

    def apply(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """``C x`` for ``x`` of the operator's shape ((m, n), or (m, n, l) in 3D)."""
        flat = np.ascontiguousarray(x, dtype=np.float64).reshape(-1)
        out = np.zeros(flat.shape[0])
        low_rank_apply_kernel(flat, np.ascontiguousarray(self.points, dtype=np.int64),
                              self.kernel_term(), out)
        return out.reshape(np.shape(x))


class _Hierarchy:
    """Padded storage of every level and the iteration vectors for one grid shape.

    The fine level and the vectors the Chebyshev iteration uses are allocated at once; the
    coarse levels and the CG-only vectors when an operator first needs them, so that a
    diagonally dominant operator (implicit viscosity) costs 9 instead of 20 grid-sized arrays.
    """

    def __init__(self, shape: tuple[int, int]) -> None:
        rows = [shape[0]]
        cols = [shape[1]]
        while rows[-1] * cols[-1] > _COARSEST_SIZE:
            rows.append((rows[-1] + 1) // 2)
            cols.append((cols[-1] + 1) // 2)
        sizes = [(m + 2) * (n + 2) for m, n in zip(rows, cols)]
        self.rows = np.array(rows, dtype=np.int64)
        self.cols = np.array(cols, dtype=np.int64)
        self.offsets = np.concatenate(([0], np.cumsum(sizes))).astype(np.int64)
        fine_size = sizes[0]
        self.diagonal, self.weights_x, self.weights_y, self.total, self.inverse = (
            np.zeros(fine_size) for _ in range(5))
        self.level_x = self.level_b = self.r = self.z = np.zeros(0)
        self.b, self.x, self.p, self.q = (np.zeros(fine_size) for _ in range(4))
        coarse_size = rows[-1] * cols[-1]
        self.dense = np.zeros((coarse_size, coarse_size))
        self.factor = np.zeros((coarse_size, coarse_size))
        self.values = np.zeros(shape)
        self.coarse = True
        self.spread = 1.0
        self.null_space: _NullSpace | None = None
        # Per row of each level (the finest first), the columns [first, stop) that hold its
        # active points, and whether some fine row is not whole: the CG then works on those
        # spans only (`pcg_kernel`).
        self.first = np.zeros(int(sum(rows)), dtype=np.int64)
        self.stop = np.zeros(int(sum(rows)), dtype=np.int64)
        self.ranged = False
        self.span_points = shape[0] * shape[1]
        # The operator the levels hold; kept alive so that its identity is not reused.
        self.operator: Operator5Point | None = None

    def levels(self) -> tuple:
        """The hierarchy's arrays as the kernels take them (`v_cycle`)."""
        return (self.rows, self.cols, self.offsets, self.diagonal, self.weights_x,
                self.weights_y, self.total, self.inverse, self.level_x, self.level_b,
                self.factor)

    def _allocate_levels(self) -> None:
        """Grow the level arrays to hold every level (the fine level's values are kept)."""
        total_size = int(self.offsets[-1])
        if self.level_x.size == total_size:
            return
        for name in ("diagonal", "weights_x", "weights_y", "total", "inverse"):
            fine = getattr(self, name)
            grown = np.zeros(total_size)
            grown[:fine.size] = fine
            setattr(self, name, grown)
        self.level_x = np.zeros(total_size)
        self.level_b = np.zeros(total_size)
        self.r = np.zeros(self.b.size)
        self.z = np.zeros(self.b.size)

    def clear_vectors(self) -> None:
        """Zero the iteration vectors and the levels' x and b."""
        for array in (self.r, self.z, self.p, self.q, self.level_x, self.level_b):
            array[:] = 0.0

    def _level(self, array: NDArray[np.float64], level: int) -> NDArray[np.float64]:
        return array[self.offsets[level]:self.offsets[level + 1]]

    def prepare(self, operator: Operator5Point) -> _NullSpace:
        """Make the levels hold ``operator``; return its active points and null space.

        The levels of the previous operator are kept when ``operator`` is the same object
        (its arrays are not changed after construction, by contract) or has the same values
        (a new operator of unchanged bodies). Loading the fine level compares the values as it
        copies them, so a changed operator costs no extra pass for the comparison.
        """
        if self.null_space is not None and operator is self.operator:
            return self.null_space
        # A fresh mask each time: the previous null space may still be held by a caller.
        active = np.empty(operator.shape, dtype=np.bool_)
        changed, all_have_diagonal, dominant, spread = load_operator_kernel(
            operator.diagonal, operator.weights_x, operator.weights_y,
            self._level(self.diagonal, 0), self._level(self.weights_x, 0),
            self._level(self.weights_y, 0), self._level(self.total, 0),
            self._level(self.inverse, 0), active, _SMOOTHER_ONLY_DOMINANCE,
        )
        if self.null_space is not None and not changed:
            self.operator = operator
            return self.null_space
        self.null_space = None
        # A wider interval is still a valid bound; this keeps the recurrence finite for an
        # operator with no weights at all.
        self.spread = max(float(spread), 1e-3)
        partial, points = active_spans_kernel(active, self.first, self.stop)
        self.ranged, self.span_points = bool(partial), int(points)
        self._build(dominant)
        self.null_space = _analyse(operator, active, all_have_diagonal)
        self.operator = operator
        return self.null_space

    def _build(self, dominant: bool) -> None:
        """Fill the coarse levels from the loaded fine level and factor the coarsest one."""
        levels = len(self.rows)
        # An operator with a strong diagonal (implicit viscosity, I - nu dt lap, up to
        # nu dt / h^2 = 1) needs no coarse correction: the Chebyshev iteration reduces every
        # error mode by a known factor per pass, at a fraction of a V-cycle's cost and with no
        # coarse levels to build.
        self.coarse = levels == 1 or not dominant
        if not self.coarse:
            return
        self._allocate_levels()
        build_coarse_levels_kernel(self.rows, self.cols, self.offsets, self.diagonal,
                                   self.weights_x, self.weights_y, self.total, self.inverse,
                                   self.dense, self.factor)
        if self.ranged:
            level_spans_kernel(self.rows, self.cols, self.offsets, self.total, self.first,
                               self.stop)


def _load(hierarchy: _Hierarchy, null_space: _NullSpace, rhs: NDArray[np.float64],
          x0: NDArray[np.float64] | None) -> tuple[float, float]:
    """Pad ``rhs`` into ``hierarchy.b``, compatible on singular components, and the warm
    start ``x0`` (or zeros) into ``hierarchy.x``; return the norm of the compatible rhs and
    the share removed to make it compatible (`incompatibility`)."""
    if x0 is None:
        hierarchy.x[:] = 0.0
    elif pad_masked_kernel(np.asarray(x0, dtype=np.float64), null_space.active,
                           hierarchy.x)[0]:
        raise ValueError("x0: values must be finite; got NaN or inf")
    bad, squared_b = pad_masked_kernel(rhs, null_space.active, hierarchy.b)
    if bad:
        raise ValueError("rhs: values must be finite; got NaN or inf")
    incompatible = 0.0
    if null_space.has_singular:
        unpad_values_kernel(hierarchy.b, hierarchy.values)
        removed = null_space.remove_means(hierarchy.values)
        incompatible = incompatibility(removed, float(np.sqrt(squared_b)))
        pad_values_kernel(hierarchy.values, hierarchy.b)
        squared_b = sum_of_squares_kernel(hierarchy.values)
    return float(np.sqrt(squared_b)), incompatible


@dataclass(frozen=True)
class PoissonSolverMGPCG:
    """Conjugate gradient preconditioned by one geometric multigrid V-cycle per iteration.

    The hierarchy halves each dimension (rounding up) down to at most 32 points, where the
    problem is solved by a semi-definite Cholesky factorization (one unknown pinned per
    singular component). Coarse face weights are the average of the two fine faces; the
    coarse diagonal sums the part of the children's diagonal that all active children share
    (a volume term such as the Helmholtz identity) and averages the rest (boundary terms such
    as Dirichlet outflow or cut faces). Restriction is the transpose of piecewise-constant
    prolongation; smoothing is red-black Gauss-Seidel before and black-red after. The
    preconditioner is therefore symmetric positive definite on the active points, and CG
    converges for every operator of the contract. An operator whose diagonal term is at least a
    quarter of the sum of its weights at every point (implicit viscosity up to
    ``nu dt / h^2 = 1``) is solved instead by the Jacobi-preconditioned Chebyshev iteration,
    whose eigenvalue bounds follow from the Jacobi row sums (Gershgorin), which is cheaper
    there: one pass per iteration and no coarse levels. The levels and the component analysis
    are kept while the same operator (or one with equal values) is solved again.

    Guarantee: returns when the true relative residual is ``<= rtol`` or after
    ``max_iterations`` iterations; the MGPCG iteration count is nearly independent of the grid
    size (6-7 to 1e-6 from 128^2 to 1024^2 on pressure problems), the Chebyshev count depends
    only on the diagonal dominance. Storage is allocated once per grid shape and reused, so
    one instance must not solve from several threads at once.

    Attributes:
        rtol: Relative residual tolerance ``|b - A x| / |b|``.
        max_iterations: Maximum number of CG (or Chebyshev) iterations.
        smoothing_sweeps: Red-black Gauss-Seidel sweeps before and after each coarse correction.
    """

    rtol: float = 1e-6
    max_iterations: int = 200
    smoothing_sweeps: int = 2
    _hierarchies: dict[tuple[int, int], _Hierarchy] = field(
        default_factory=dict, init=False, repr=False, compare=False
    )

    def __post_init__(self) -> None:
        if not (self.rtol > 0.0):
            raise ValueError(f"rtol: {self.rtol!r} is not allowed; expected > 0")
        if self.max_iterations < 0:
            raise ValueError(f"max_iterations: {self.max_iterations!r} is not allowed; expected >= 0")
        if self.smoothing_sweeps < 1:
            raise ValueError(
                f"smoothing_sweeps: {self.smoothing_sweeps!r} is not allowed; expected >= 1"
            )

    def _hierarchy(self, shape: tuple[int, int]) -> _Hierarchy:
        """The storage for ``shape``, allocated on first use."""
        hierarchy = self._hierarchies.get(shape)
        if hierarchy is None:
            hierarchy = _Hierarchy(shape)
            self._hierarchies[shape] = hierarchy
        return hierarchy

    def solve(
        self,
        operator: Operator5Point,
        rhs: NDArray[np.float64],
        x0: NDArray[np.float64] | None = None,
        out: NDArray[np.float64] | None = None,
    ) -> tuple[NDArray[np.float64], SolveReport]:
        """Solve ``A x = rhs``.

        Args:
            operator: The operator ``A`` on an ``(m, n)`` array.
            rhs: Right-hand side, shape ``(m, n)``.
            x0: Optional initial guess (warm start), shape ``(m, n)``.
            out: Optional C-contiguous float64 array of shape ``(m, n)`` to receive ``x``
                (may be ``x0``); a new array otherwise.

        Returns:
            ``x`` (shape ``(m, n)``; 0 at inactive points, zero mean on singular components) and
            the report.
        """
        _output(out, operator.shape)
        rhs = np.asarray(rhs, dtype=np.float64)
        if rhs.shape != operator.shape:
            raise ValueError(f"rhs: shape {rhs.shape} is not allowed; expected {operator.shape}")
        if x0 is not None:
            x0 = np.asarray(x0, dtype=np.float64)
            if x0.shape != operator.shape:
                raise ValueError(f"x0: shape {x0.shape} is not allowed; expected {operator.shape}")
        hierarchy = self._hierarchy(operator.shape)
        null_space = hierarchy.prepare(operator)
        norm_b, incompatible = _load(hierarchy, null_space, rhs, x0)
        if norm_b == 0.0:
            x = _output(out, operator.shape)
            x[...] = 0.0
            return x, SolveReport(0, 0.0, incompatible <= self.rtol, incompatible)
        threshold = (self.rtol * norm_b) ** 2
        solution = hierarchy.x
        if not hierarchy.coarse:
            iterations, squared, in_other = chebyshev_kernel(
                hierarchy.rows, hierarchy.cols, hierarchy.offsets, hierarchy.total,
                hierarchy.inverse, hierarchy.weights_x, hierarchy.weights_y, hierarchy.b,
                hierarchy.x, hierarchy.p, hierarchy.q, hierarchy.spread, threshold,
                self.max_iterations,
            )
            if in_other:
                solution = hierarchy.p
        else:
            iterations, squared = pcg_kernel(
                hierarchy.levels(), hierarchy.b, hierarchy.x, hierarchy.r, hierarchy.p,
                hierarchy.q, hierarchy.z, threshold, self.max_iterations, self.smoothing_sweeps,
                hierarchy.first, hierarchy.stop, hierarchy.ranged, hierarchy.span_points,
            )
            if not math.isfinite(squared):
                # Outside the spans the vectors keep their values, read with weight 0: a
                # NaN or inf left there would spread to every later solve.
                hierarchy.clear_vectors()
        x = _output(out, operator.shape)
        unpad_values_kernel(solution, x)
        null_space.remove_means(x)
        relative = float(np.sqrt(squared)) / norm_b
        return x, SolveReport(int(iterations), relative,
                              relative <= self.rtol and incompatible <= self.rtol, incompatible)

    def solve_coupled(
        self,
        operator: Operator5Point,
        coupling: LowRankTerm,
        rhs: NDArray[np.float64],
        x0: NDArray[np.float64] | None = None,
        out: NDArray[np.float64] | None = None,
    ) -> tuple[NDArray[np.float64], SolveReport]:
        """Solve ``(A + C) x = rhs`` with ``A`` 5-point and ``C`` a `LowRankTerm`.

        Conjugate gradient preconditioned by one V-cycle of ``A + diag(C)``, in one compiled
        loop like `solve`: the strongly coupled pressure equation, whose ``C`` (the bodies'
        inertia seen through the cut faces) is dense on the cut cells of each body and zero
        elsewhere. ``C`` must touch only active points of ``A``; a singular component of
        ``A`` that ``C`` touches is made definite by it, the others are made compatible as in
        `solve`. Same report and guarantees as `solve` for this operator.
        """
        _output(out, operator.shape)
        rhs = np.asarray(rhs, dtype=np.float64)
        if rhs.shape != operator.shape:
            raise ValueError(f"rhs: shape {rhs.shape} is not allowed; expected {operator.shape}")
        n = operator.shape[1]
        extra = coupling.diagonal(operator.shape)
        preconditioned = Operator5Point(
            operator.diagonal + extra, operator.weights_x, operator.weights_y
        )
        hierarchy = self._hierarchy(operator.shape)
        null_space = hierarchy.prepare(preconditioned)
        if not hierarchy.coarse:
            # The V-cycle needs the coarse levels even where the Chebyshev iteration would do.
            hierarchy._build(False)
        norm_b, incompatible = _load(hierarchy, null_space, rhs, x0)
        if norm_b == 0.0:
            x = _output(out, operator.shape)
            x[...] = 0.0
            return x, SolveReport(0, 0.0, incompatible <= self.rtol, incompatible)
        # The operator's own diagonal-plus-weights, padded (the levels hold A + diag(C)).
        padded_extra = np.zeros_like(hierarchy.b)
        pad_values_kernel(extra, padded_extra)
        operator_total = hierarchy.total[:hierarchy.b.size] - padded_extra
        padded_points = (coupling.points // n + 1) * (n + 2) + coupling.points % n + 1
        threshold = (self.rtol * norm_b) ** 2
        iterations, squared = pcg_low_rank_kernel(
            hierarchy.levels(), hierarchy.b, hierarchy.x, hierarchy.r, hierarchy.p,
            hierarchy.q, hierarchy.z, threshold, self.max_iterations, self.smoothing_sweeps,
            padded_points.astype(np.int64), coupling.kernel_term(), operator_total,
        )
        x = _output(out, operator.shape)
        unpad_values_kernel(hierarchy.x, x)
        null_space.remove_means(x)
        relative = float(np.sqrt(max(squared, 0.0))) / norm_b
        return x, SolveReport(int(iterations), relative,
                              relative <= self.rtol and incompatible <= self.rtol, incompatible)
