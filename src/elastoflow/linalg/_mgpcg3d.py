"""Conjugate gradient preconditioned by a geometric multigrid V-cycle, on 7-point operators.

The 3D twin of `PoissonSolverMGPCG`: same contract (`SolveReport`, inactive points, singular
components, true residual), its own kernels (`_kernels3d`). The levels are separate
``(m, n, l)`` arrays walked by a short Python loop (a handful of levels, a few kernel calls
each); the work per grid point is all in the kernels.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numba import get_num_threads
from numpy.typing import NDArray

from elastoflow.linalg._chebyshev_kernels3d import chebyshev_pass_kernel_3d
from elastoflow.linalg._kernels import (
    low_rank_add_dot_kernel,
    remove_component_means_kernel,
    semidefinite_cholesky_kernel,
)
from elastoflow.linalg._kernels3d import (
    BLACK,
    NO_BOX,
    NOT_UNIFORM,
    RED,
    SHELL_DEPTH,
    apply_dot_kernel_3d,
    apply_dot_uniform_kernel_3d,
    coarsen_kernel_3d,
    dense_matrix_kernel_3d,
    dense_solve_kernel,
    direction_kernel_3d,
    dot_kernel_3d,
    fill_kernel_3d,
    inner_value_kernel_3d,
    label_components_kernel_3d,
    load_operator_kernel_3d,
    masked_copy_kernel_3d,
    positive_differences_kernel_3d,
    prolong_add_all_kernel_3d,
    prolong_add_kernel_3d,
    residual_kernel_3d,
    residual_uniform_kernel_3d,
    restrict_residual_kernel_3d,
    sweep_kernel_3d,
    step_kernel_3d,
    uniform_box_kernel,
    uniform_weight_kernel,
)
from elastoflow.linalg._mgpcg import LowRankTerm
from elastoflow.linalg._operator import SolveReport
from elastoflow.linalg._operator3d import Operator7Point
from elastoflow.linalg._problem import _output, incompatibility
from elastoflow.linalg._restrict_kernels3d import row_ends, restrict_residual_uniform_kernel_3d

Shape3 = tuple[int, int, int]

# The coarsest level is solved by a dense semi-definite Cholesky factor: up to 4^3 points.
# With 8^3 the dense solve (0.3 ms) was a quarter of a V-cycle at 32^3; with 4^3 the
# iteration counts are the same (5 to 1e-6 at 16^3-64^3) and a solve at 16^3 / 32^3 / 64^3
# took 2 / 11-23 / 49-57 ms instead of 10 / 25-31 / 114-129 ms (load average ~3.5 on 2 cores).
_COARSEST_SIZE = 64
# Smallest ratio of diagonal to sum of weights at which the Jacobi-preconditioned Chebyshev
# iteration replaces MGPCG (implicit viscosity, I - nu dt lap with nu dt / h^2 <= 2/3):
# coarse levels would cost more to build and run than the few extra iterations they save.
# At 128^3 with nu dt / h^2 = 0.0128 (the benchmark's channel): 3 Chebyshev iterations
# (4 passes over 5 arrays each) against 3 MGPCG iterations (a V-cycle alone reads 8 arrays
# 6 times), and 2 Jacobi-preconditioned CG iterations, which took 1.6x the Chebyshev time
# (docs/benchmarks.md, 2026-12-06, fifth session).
_SMOOTHER_ONLY_DOMINANCE = 0.25
# A level's `side_total` where the restriction does not read it.
_NO_SIDES = np.zeros((0, 0, 2))


@dataclass
class _NullSpace3D:
    """Active points and the singular (pure Neumann) components of an operator."""

    active: NDArray[np.bool_]
    labels: NDArray[np.int64] | None
    singular: NDArray[np.bool_] | None
    count: int

    @property
    def has_singular(self) -> bool:
        return self.singular is not None and bool(self.singular.any())

    def remove_means(self, x: NDArray[np.float64]) -> float:
        """Make ``x`` zero-mean on every singular component (in place); return the 2-norm of
        what was removed."""
        if not self.has_singular:
            return 0.0
        assert self.labels is not None and self.singular is not None
        # The 2D kernel visits every point once: it runs on (m n, l) views unchanged.
        l = x.shape[-1]
        removed = remove_component_means_kernel(
            x.reshape(-1, l), self.labels.reshape(-1, l), self.singular, self.count
        )
        return float(np.sqrt(removed))


@dataclass
class _Level:
    """One level's operator (``total = diagonal + sum of weights``, its inverse, 0 at inactive
    points; ``uniform``: the one value of all its weights outside ``box``, or `NOT_UNIFORM`;
    ``box``: `NO_BOX` when they are all equal, else the box around the bodies and the shell
    along the sides, whose weights the kernels read from the arrays) and its correction ``x``
    and right-hand side ``b``."""

    diagonal: NDArray[np.float64]
    weights_x: NDArray[np.float64]
    weights_y: NDArray[np.float64]
    weights_z: NDArray[np.float64]
    total: NDArray[np.float64]
    inverse: NDArray[np.float64]
    x: NDArray[np.float64]
    b: NDArray[np.float64]
    uniform: float = NOT_UNIFORM
    box: NDArray[np.int64] = field(default_factory=lambda: NO_BOX)
    # With a uniform weight: the one value of ``total`` and of ``inverse`` where the
    # kernels read that weight without checks (`inner_value_kernel_3d`), or `NOT_UNIFORM`
    # (they then read the arrays everywhere). The restriction and the Chebyshev pass read
    # the total, the sweeps the inverse.
    inner_total: float = NOT_UNIFORM
    inner_inverse: float = NOT_UNIFORM
    # With ``inner_total``: its first and last columns (`row_ends`; the restriction reads
    # them at the rows' ends).
    side_total: NDArray[np.float64] = field(default_factory=lambda: _NO_SIDES)

    @classmethod
    def zeros(cls, shape: Shape3) -> _Level:
        m, n, l = shape
        return cls(np.zeros(shape), np.zeros((m - 1, n, l)), np.zeros((m, n - 1, l)),
                   np.zeros((m, n, l - 1)), np.zeros(shape), np.zeros(shape), np.zeros(shape),
                   np.zeros(shape))

    def set_uniform(self, shell_allowed: bool = False) -> None:
        """Find ``uniform`` and ``box`` for the weights just loaded: the one value of all
        of them, or of all outside a box holding at most half the level (the value of the
        first x-weight; the bodies' neighbourhood in the pressure operator with bodies), or
        with ``shell_allowed`` of all outside such a box and a shell of `SHELL_DEPTH` along
        the sides (a viscosity operator, whose held boundary planes have no weights; the
        restriction does not read a shell, so only a level with no coarse levels below it
        may have one). With ``shell_allowed`` the shell is tried first, with no pass for
        all weights equal: the viscosity's held planes make it the one that fits, and a
        level rebuilt every step (a body's) saves the passes that would not."""
        self._set_uniform(shell_allowed)
        self.inner_total = (inner_value_kernel_3d(self.total, self.box)
                            if self.uniform != NOT_UNIFORM else NOT_UNIFORM)
        self.side_total = (row_ends(self.total)
                           if self.inner_total != NOT_UNIFORM and not shell_allowed
                           else _NO_SIDES)
        # Only the sweeps read it: a level that may have a shell has no V-cycle (the
        # coupled solve loads the level again, without, before it builds one).
        self.inner_inverse = (inner_value_kernel_3d(self.inverse, self.box)
                              if self.uniform != NOT_UNIFORM and not shell_allowed
                              else NOT_UNIFORM)

    def _set_uniform(self, shell_allowed: bool) -> None:
        self.uniform = NOT_UNIFORM
        if not shell_allowed:
            self.uniform = float(uniform_weight_kernel(self.weights_x, self.weights_y,
                                                       self.weights_z))
        self.box = NO_BOX
        if self.uniform != NOT_UNIFORM or not self.weights_x.size:
            return
        m, n, l = self.total.shape
        size = m * n * l
        for shell in (SHELL_DEPTH, 0) if shell_allowed else (0,):
            # A shell of more than half the level (16^3 and less) saves too little.
            outside = size - max(m - 2 * shell, 0) * max(n - 2 * shell, 0) * max(
                l - 2 * shell, 0)
            if 2 * outside > size:
                continue
            candidate = float(self.weights_x[shell, shell, shell])
            if not candidate > 0.0:
                continue
            box = np.zeros(7, dtype=np.int64)
            differing = uniform_box_kernel(self.weights_x, self.weights_y, self.weights_z,
                                           candidate, shell, box)
            if not differing and not shell:
                self.uniform = candidate  # all weights equal
                return
            if int(np.prod(box[1:6:2] - box[0:6:2])) <= size // 2:
                self.uniform, self.box = candidate, box
                return

    def sweep(self, x: NDArray[np.float64], b: NDArray[np.float64], first: int,
              from_zero: bool, chunks: int) -> None:
        """One red-black Gauss-Seidel sweep on this level, colour ``first`` first;
        ``from_zero``: x is taken as 0 (and need not be filled); ``chunks``: the threads."""
        weight = self.uniform if self.inner_inverse != NOT_UNIFORM else NOT_UNIFORM
        sweep_kernel_3d(x, b, self.inverse, self.weights_x, self.weights_y, self.weights_z,
                        weight, self.inner_inverse, first, from_zero, chunks, self.box)

    def prolong(self, coarse_x: NDArray[np.float64], x: NDArray[np.float64]) -> None:
        """``x += P coarse_x`` at this level's active points (all of a uniform level)."""
        if self.uniform != NOT_UNIFORM and self.box is NO_BOX:
            prolong_add_all_kernel_3d(coarse_x, x)
        else:
            prolong_add_kernel_3d(coarse_x, self.inverse, x)

    def residual(self, x: NDArray[np.float64], b: NDArray[np.float64],
                 r: NDArray[np.float64]) -> float:
        """``r = b - A x``; returns ``|r|^2``."""
        if self.uniform != NOT_UNIFORM:
            return float(residual_uniform_kernel_3d(self.total, self.uniform, x, b, r,
                                                    self.diagonal, self.weights_x,
                                                    self.weights_y, self.weights_z, self.box))
        return float(residual_kernel_3d(self.diagonal, self.weights_x, self.weights_y,
                                        self.weights_z, x, b, r))

    def restrict(self, x: NDArray[np.float64], b: NDArray[np.float64],
                 coarse_b: NDArray[np.float64]) -> None:
        """``coarse_b`` = the residual of this level summed over each coarse point."""
        if self.uniform != NOT_UNIFORM:
            restrict_residual_uniform_kernel_3d(x, b, self.total, self.inner_total,
                                                self.side_total, self.uniform, coarse_b,
                                                self.weights_x, self.weights_y,
                                                self.weights_z, self.box)
        else:
            restrict_residual_kernel_3d(x, b, self.total, self.weights_x, self.weights_y,
                                        self.weights_z, coarse_b)


def _same_pattern(old: Operator7Point, new: Operator7Point) -> bool:
    """Whether two operators of one shape are positive at the same points, diagonal and
    weights; False when they share an array (one rewritten in place: nothing to compare)."""
    pairs = [(getattr(old, name), getattr(new, name))
             for name in ("diagonal", "weights_x", "weights_y", "weights_z")]
    if any(a is b or a.shape != b.shape for a, b in pairs):
        return False
    # One threaded pass per array (NumPy's two comparisons and the equality took ~1 ms for
    # the four arrays at 64³).
    return all(positive_differences_kernel_3d(a, b) == 0 for a, b in pairs)


def _level_shapes(shape: Shape3) -> list[Shape3]:
    """Halve every dimension (rounding up) until at most `_COARSEST_SIZE` points remain."""
    shapes = [shape]
    while np.prod(shapes[-1]) > _COARSEST_SIZE and max(shapes[-1]) > 1:
        m, n, l = shapes[-1]
        shapes.append(((m + 1) // 2, (n + 1) // 2, (l + 1) // 2))
    return shapes


class _Hierarchy3D:
    """Storage for one grid shape: the levels, the CG vectors, the coarsest factor."""

    def __init__(self, shape: Shape3, vectors: tuple[NDArray[np.float64], ...]) -> None:
        """``vectors``: five flat arrays of ``prod(shape)`` values for the CG vectors, which
        hierarchies of shapes with the same number of points share (`_vector_pool`); the
        iterate is the caller's output array."""
        self.shape = shape
        self.shapes = _level_shapes(shape)
        # The fine level's operator arrays are the operator's own (set in `prepare`).
        self.levels = [_Level.zeros(s) for s in self.shapes]
        self.active = np.zeros(shape, dtype=np.bool_)
        self.b, self.r, self.p, self.q, self.z = (v.reshape(shape) for v in vectors)
        coarse = int(np.prod(self.shapes[-1]))
        self.dense = np.zeros((coarse, coarse))
        self.factor = np.zeros((coarse, coarse))
        self.coarse = True
        # Without coarse levels (the Chebyshev iteration): the bound on the Jacobi iteration
        # matrix's row sums; whether every point is active; whether the last solve took an
        # odd number of iterations (its successor then starts in `p` to end in the output).
        self.spread = 0.0
        self.every_active = False
        self.odd = False
        self.null_space: _NullSpace3D | None = None
        # The operator the levels hold; kept alive so that its identity is not reused.
        self.operator: Operator7Point | None = None

    def prepare(self, operator: Operator7Point) -> _NullSpace3D:
        """Make the levels hold ``operator`` (kept while the same object comes back); return
        its active points and null space."""
        if self.null_space is not None and operator is self.operator:
            return self.null_space
        fine = self.levels[0]
        fine.diagonal, fine.weights_x = operator.diagonal, operator.weights_x
        fine.weights_y, fine.weights_z = operator.weights_y, operator.weights_z
        # A fresh mask each time: the previous null space may still be held by a caller.
        active = np.empty(self.shape, dtype=np.bool_)
        all_have_diagonal, dominance = load_operator_kernel_3d(
            fine.diagonal, fine.weights_x, fine.weights_y, fine.weights_z, fine.total,
            fine.inverse, active,
        )
        self.active = active
        # A strongly diagonal operator (implicit viscosity) needs no coarse correction.
        self.coarse = len(self.levels) == 1 or dominance < _SMOOTHER_ONLY_DOMINANCE
        # Row sums of D^-1 (D - A): sum of weights / (diagonal + sum of weights).
        self.spread = 1.0 / (1.0 + float(dominance))
        self.every_active = not self.coarse and bool(active.all())
        fine.set_uniform(shell_allowed=not self.coarse)
        if self.coarse:
            self._build()
        previous, kept = self.operator, self.null_space
        if (not all_have_diagonal and kept is not None and kept.labels is not None
                and previous is not None and _same_pattern(previous, operator)):
            # The same components as the last operator's (a body that moved within its
            # cells: the open fractions changed, no face opened or closed): its labels hold.
            self.null_space = _NullSpace3D(active, kept.labels, kept.singular, kept.count)
        else:
            self.null_space = self._analyse(operator, active, bool(all_have_diagonal))
        self.operator = operator
        return self.null_space

    def _build(self) -> None:
        """Fill the coarse levels from the fine one and factor the coarsest."""
        for fine, coarse in zip(self.levels[:-1], self.levels[1:], strict=True):
            coarsen_kernel_3d(fine.diagonal, fine.weights_x, fine.weights_y, fine.weights_z,
                              fine.total, coarse.diagonal, coarse.weights_x, coarse.weights_y,
                              coarse.weights_z)
            load_operator_kernel_3d(coarse.diagonal, coarse.weights_x, coarse.weights_y,
                                    coarse.weights_z, coarse.total, coarse.inverse,
                                    np.empty(coarse.total.shape, dtype=np.bool_))
            coarse.set_uniform()
        last = self.levels[-1]
        dense_matrix_kernel_3d(last.diagonal, last.weights_x, last.weights_y, last.weights_z,
                               self.dense)
        semidefinite_cholesky_kernel(self.dense, self.factor)

    @staticmethod
    def _analyse(operator: Operator7Point, active: NDArray[np.bool_],
                 all_have_diagonal: bool) -> _NullSpace3D:
        if all_have_diagonal:
            return _NullSpace3D(active, None, None, 0)
        labels = np.empty(operator.shape, dtype=np.int64)
        count, singular = label_components_kernel_3d(
            operator.diagonal, operator.weights_x, operator.weights_y, operator.weights_z,
            active, labels,
        )
        return _NullSpace3D(active, labels, singular, int(count))

    def precondition(self, r: NDArray[np.float64], z: NDArray[np.float64], sweeps: int) -> float:
        """``z = M r``; returns ``r . z``. One symmetric V-cycle."""
        self.v_cycle(r, z, sweeps)
        return float(dot_kernel_3d(r, z))

    def v_cycle(self, r: NDArray[np.float64], z: NDArray[np.float64], sweeps: int) -> None:
        """``z = M r``: one symmetric V-cycle (red-black Gauss-Seidel before, black-red
        after)."""
        levels = self.levels
        count = len(levels)
        chunks = get_num_threads()
        for index, level in enumerate(levels):
            x = z if index == 0 else level.x
            b = r if index == 0 else level.b
            if index == count - 1:
                dense_solve_kernel(self.factor, b, x)
                break
            for sweep in range(sweeps):
                level.sweep(x, b, RED, sweep == 0, chunks)
            if index < count - 1:
                level.restrict(x, b, levels[index + 1].b)
        for index in range(count - 2, -1, -1):
            level = levels[index]
            x = z if index == 0 else level.x
            b = r if index == 0 else level.b
            level.prolong(levels[index + 1].x, x)
            for _ in range(sweeps):
                level.sweep(x, b, BLACK, False, chunks)


@dataclass(frozen=True)
class PoissonSolverMGPCG3D:
    """Conjugate gradient preconditioned by one geometric multigrid V-cycle per iteration, on
    a 7-point operator (`Operator7Point`).

    The hierarchy halves each dimension (rounding up) down to at most 64 points, solved by a
    semi-definite Cholesky factorization (one unknown pinned per singular component). A coarse
    face weight is half the sum of the four fine faces it covers and the coarse diagonal sums
    the children's shared (volume) part and halves the sum of the rest (surface terms): the
    operator rediscretised at 2h, scaled to the summing restriction. Restriction is the
    transpose of piecewise-constant prolongation; smoothing is red-black Gauss-Seidel before
    and black-red after, so the preconditioner is symmetric positive definite on the active
    points and CG converges for every operator of the contract. An operator whose diagonal
    is at least a quarter of the sum of its weights everywhere (implicit viscosity) is
    solved by the Jacobi-preconditioned Chebyshev iteration instead, with no coarse levels
    and no inner products: its eigenvalue bounds follow from the row sums (Gershgorin), and
    each pass is one sweep (`chebyshev_pass_kernel_3d`).

    Guarantee: the same as `PoissonSolverMGPCG`: returns when the true relative residual is
    ``<= rtol`` or after ``max_iterations`` iterations; inactive points get 0; singular
    components get a compatible right-hand side and a zero-mean answer; the iteration count
    is nearly independent of the grid size (docs/architecture.md, section 3D, for the
    measured counts). Storage is allocated once per grid shape and reused, so one instance
    must not solve from several threads at once.

    Attributes:
        rtol: Relative residual tolerance ``|b - A x| / |b|``.
        max_iterations: Maximum number of CG (or Chebyshev) iterations.
        smoothing_sweeps: Red-black Gauss-Seidel sweeps before and after each coarse correction.
    """

    rtol: float = 1e-6
    max_iterations: int = 200
    smoothing_sweeps: int = 2
    _hierarchies: dict[Shape3, _Hierarchy3D] = field(
        default_factory=dict, init=False, repr=False, compare=False
    )
    # The CG vectors by number of points: the three velocity components of a cubic grid's
    # viscosity solves ((n+1) n^2 points each) share one set, solved one after the other;
    # 10 arrays fewer, ~80 MB per million cells.
    _vector_pool: dict[int, tuple[NDArray[np.float64], ...]] = field(
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

    def _hierarchy(self, shape: Shape3) -> _Hierarchy3D:
        hierarchy = self._hierarchies.get(shape)
        if hierarchy is None:
            size = shape[0] * shape[1] * shape[2]
            vectors = self._vector_pool.get(size)
            if vectors is None:
                vectors = tuple(np.zeros(size) for _ in range(5))
                self._vector_pool[size] = vectors
            hierarchy = _Hierarchy3D(shape, vectors)
            self._hierarchies[shape] = hierarchy
        return hierarchy

    def solve(
        self,
        operator: Operator7Point,
        rhs: NDArray[np.float64],
        x0: NDArray[np.float64] | None = None,
        out: NDArray[np.float64] | None = None,
    ) -> tuple[NDArray[np.float64], SolveReport]:
        """Solve ``A x = rhs``.

        Args:
            operator: The operator ``A`` on an ``(m, n, l)`` array.
            rhs: Right-hand side, shape ``(m, n, l)``.
            x0: Optional initial guess (warm start), shape ``(m, n, l)``.
            out: Optional C-contiguous float64 array of shape ``(m, n, l)`` to receive ``x``
                (may be ``x0``); a new array otherwise.

        Returns:
            ``x`` (shape ``(m, n, l)``; 0 at inactive points, zero mean on singular
            components) and the report.
        """
        shape = operator.shape
        _output(out, shape)  # type: ignore[arg-type]
        rhs, x0 = self._checked(shape, rhs, x0)
        hierarchy = self._hierarchy(shape)
        null_space = hierarchy.prepare(operator)
        # The right-hand side is read in place: not when the output overwrites it.
        if hierarchy.every_active and (out is None or not np.may_share_memory(rhs, out)):
            return self._solve_in_place(hierarchy, null_space, rhs, x0, out)
        if not hierarchy.coarse:
            return self._solve_prepared(
                hierarchy, null_space, rhs, x0, out,
                lambda x, threshold: self._chebyshev(hierarchy, null_space, x, x, hierarchy.b,
                                                     threshold))
        return self._solve_prepared(hierarchy, null_space, rhs, x0, out,
                                    lambda x, threshold: self._pcg(hierarchy, x, threshold))

    def solve_coupled(
        self,
        operator: Operator7Point,
        coupling: LowRankTerm,
        rhs: NDArray[np.float64],
        x0: NDArray[np.float64] | None = None,
        out: NDArray[np.float64] | None = None,
    ) -> tuple[NDArray[np.float64], SolveReport]:
        """Solve ``(A + C) x = rhs`` with ``A`` 7-point and ``C`` a `LowRankTerm` (the 3D
        twin of `PoissonSolverMGPCG.solve_coupled`: the strongly coupled pressure equation).

        CG preconditioned by one V-cycle of ``A + diag(C)``. ``C`` must touch only active
        points of ``A``; a singular component of ``A`` that ``C`` touches is made definite by
        it, the others are made compatible as in `solve`. Same report and guarantees as
        `solve`.
        """
        shape = operator.shape
        _output(out, shape)  # type: ignore[arg-type]
        rhs, x0 = self._checked(shape, rhs, x0)
        extra = coupling.diagonal(shape)
        preconditioned = Operator7Point.assembled(operator.diagonal + extra,
                                                  operator.weights_x, operator.weights_y,
                                                  operator.weights_z)
        hierarchy = self._hierarchy(shape)
        null_space = hierarchy.prepare(preconditioned)
        if not hierarchy.coarse:
            # A diagonally dominant A + diag(C) would get the Chebyshev iteration, whose
            # Gershgorin bounds do not hold for A + C: keep the V-cycle (with no shell: the
            # restriction does not read one).
            hierarchy.levels[0].set_uniform()
            hierarchy._build()
            hierarchy.coarse = True
        points = np.ascontiguousarray(coupling.points, dtype=np.int64)
        term = coupling.kernel_term()
        return self._solve_prepared(
            hierarchy, null_space, rhs, x0, out,
            lambda x, threshold: self._pcg_coupled(hierarchy, operator, points, term, x,
                                                   threshold))

    @staticmethod
    def _checked(shape: Shape3, rhs: NDArray[np.float64], x0: NDArray[np.float64] | None
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
        rhs = np.ascontiguousarray(rhs, dtype=np.float64)
        if rhs.shape != shape:
            raise ValueError(f"rhs: shape {rhs.shape} is not allowed; expected {shape}")
        if x0 is not None:
            x0 = np.ascontiguousarray(x0, dtype=np.float64)
            if x0.shape != shape:
                raise ValueError(f"x0: shape {x0.shape} is not allowed; expected {shape}")
        return rhs, x0

    def _solve_prepared(self, hierarchy: _Hierarchy3D, null_space: _NullSpace3D,
                        rhs: NDArray[np.float64], x0: NDArray[np.float64] | None,
                        out: NDArray[np.float64] | None,
                        iterate: Callable[[NDArray[np.float64], float], tuple[int, float]]
                        ) -> tuple[NDArray[np.float64], SolveReport]:
        """Load the right-hand side and the warm start on the active points, make a singular
        component's right-hand side compatible, run ``iterate`` (CG); the solution and the
        report."""
        shape = hierarchy.shape
        # The copies check finiteness (the probe): no pass of their own.
        squared_b, probe = masked_copy_kernel_3d(rhs, null_space.active, hierarchy.b)
        if not np.isfinite(probe):
            raise ValueError("rhs: values must be finite; got NaN or inf")
        incompatible = 0.0
        if null_space.has_singular:
            removed = null_space.remove_means(hierarchy.b)
            incompatible = incompatibility(removed, float(np.sqrt(squared_b)))
            squared_b = dot_kernel_3d(hierarchy.b, hierarchy.b)
        norm_b = float(np.sqrt(squared_b))
        # CG iterates on the output itself; x0 may be `out` (copied in place, masked).
        x = _output(out, shape)  # type: ignore[arg-type]
        if x0 is None:
            fill_kernel_3d(x, 0.0)
        else:
            _, probe = masked_copy_kernel_3d(x0, null_space.active, x)
            if not np.isfinite(probe):
                raise ValueError("x0: values must be finite; got NaN or inf")
        if norm_b == 0.0:
            x[...] = 0.0
            return x, SolveReport(0, 0.0, incompatible <= self.rtol, incompatible)
        threshold = (self.rtol * norm_b) ** 2
        iterations, squared = iterate(x, threshold)
        null_space.remove_means(x)
        relative = float(np.sqrt(squared)) / norm_b
        return x, SolveReport(int(iterations), relative,
                              relative <= self.rtol and incompatible <= self.rtol, incompatible)

    def _solve_in_place(self, hierarchy: _Hierarchy3D, null_space: _NullSpace3D,
                        rhs: NDArray[np.float64], x0: NDArray[np.float64] | None,
                        out: NDArray[np.float64] | None
                        ) -> tuple[NDArray[np.float64], SolveReport]:
        """`solve` by the Chebyshev iteration where every point is active (implicit
        viscosity), without the masked copies: the right-hand side is read where it is, a
        warm start that is the output stays there, and a non-finite input, which the first
        pass's residual shows, is traced to its array before anything is written to the
        output. The iteration starts in the buffer from which the last solve's number of
        passes would end in the output, so that in the usual case no copy follows."""
        shape = hierarchy.shape
        x = _output(out, shape)  # type: ignore[arg-type]
        squared_b = float(dot_kernel_3d(rhs, rhs))
        if not math.isfinite(squared_b):
            raise ValueError("rhs: values must be finite; got NaN or inf")
        if squared_b == 0.0:
            x[...] = 0.0
            return x, SolveReport(0, 0.0, True, 0.0)
        start = hierarchy.p if hierarchy.odd else x
        if x0 is None:
            fill_kernel_3d(start, 0.0)
        elif x0 is not start:
            _, probe = masked_copy_kernel_3d(x0, null_space.active, start)
            if not np.isfinite(probe):
                raise ValueError("x0: values must be finite; got NaN or inf")
        threshold = self.rtol**2 * squared_b
        iterations, squared = self._chebyshev(hierarchy, null_space, x, start, rhs, threshold)
        if not math.isfinite(squared) and x0 is start and not np.isfinite(x0).all():
            raise ValueError("x0: values must be finite; got NaN or inf")
        relative = math.sqrt(squared / squared_b)
        return x, SolveReport(int(iterations), relative, relative <= self.rtol, 0.0)

    def _chebyshev(self, hierarchy: _Hierarchy3D, null_space: _NullSpace3D,
                   x: NDArray[np.float64], start: NDArray[np.float64], b: NDArray[np.float64],
                   threshold: float) -> tuple[int, float]:
        """Jacobi-preconditioned Chebyshev iteration from ``start`` (``x`` or
        ``hierarchy.p``), the answer in ``x``, for an operator without coarse levels (the 3D
        twin of the 2D `chebyshev_kernel`): the eigenvalues of ``D^-1 A`` lie in
        ``[1 - spread, 1 + spread]`` (Gershgorin on the row sums), and each pass reduces the
        error by about ``(sqrt(k) - 1) / (sqrt(k) + 1)``, ``k = (1 + spread) / (1 - spread)``.
        Each pass measures the true residual of the iterate it steps from, so the iteration
        stops on ``|b - A x|^2 <= threshold`` as CG does; return ``(iterations,
        |b - A x|^2)``. A non-finite residual stops it at once: the first pass writes only
        the other buffer, so a non-finite input leaves ``start`` as it was."""
        fine = hierarchy.levels[0]
        # theta = 1 (the interval's centre), delta = spread (its half-width); a spread of 0
        # (no weights) would divide by 0 below, where a tiny one solves in one pass.
        spread = max(hierarchy.spread, 1e-30)
        sigma = 1.0 / spread
        rho_old = spread
        scale_old, scale_new = 0.0, 1.0
        current = start
        following = hierarchy.p if start is x else x
        iterations = 0
        while True:
            squared = float(chebyshev_pass_kernel_3d(
                fine.total, fine.inner_total, fine.uniform, current, b, following,
                scale_old, scale_new, fine.weights_x, fine.weights_y, fine.weights_z, fine.box))
            # The pass measured the residual of `current` before stepping to `following`.
            if (squared <= threshold or iterations >= self.max_iterations
                    or not math.isfinite(squared)):
                break
            current, following = following, current
            iterations += 1
            rho_new = 1.0 / (2.0 * sigma - rho_old)
            scale_old = rho_new * rho_old
            scale_new = 2.0 * rho_new / spread
            rho_old = rho_new
        if current is not x:
            masked_copy_kernel_3d(current, null_space.active, x)
        # The next solve of this shape likely takes as many passes.
        hierarchy.odd = iterations % 2 == 1
        return iterations, squared

    def _pcg(self, hierarchy: _Hierarchy3D, x: NDArray[np.float64],
             threshold: float) -> tuple[int, float]:
        """CG on ``x`` from its warm start; return ``(iterations, |b - A x|^2)`` with the true
        residual. Restarts from the true residual if the recursive one has drifted below the
        tolerance before the true one did."""
        b, r, p, q, z = hierarchy.b, hierarchy.r, hierarchy.p, hierarchy.q, hierarchy.z
        fine = hierarchy.levels[0]
        a = (fine.diagonal, fine.weights_x, fine.weights_y, fine.weights_z)
        iterations = 0
        pq = 1.0
        squared = fine.residual(x, b, r)
        while squared > threshold and iterations < self.max_iterations:
            rz = hierarchy.precondition(r, z, self.smoothing_sweeps)
            p[...] = z
            recursive = squared
            while recursive > threshold and iterations < self.max_iterations:
                if fine.uniform != NOT_UNIFORM:
                    pq = apply_dot_uniform_kernel_3d(fine.total, fine.uniform, p, q,
                                                     fine.diagonal, fine.weights_x,
                                                     fine.weights_y, fine.weights_z, fine.box)
                else:
                    pq = apply_dot_kernel_3d(*a, p, q)
                if not (pq > 0.0):
                    break
                alpha = rz / pq
                recursive = step_kernel_3d(x, r, p, q, alpha)
                iterations += 1
                if recursive <= threshold:
                    break
                rz_next = hierarchy.precondition(r, z, self.smoothing_sweeps)
                direction_kernel_3d(z, p, rz_next / rz)
                rz = rz_next
            squared = fine.residual(x, b, r)
            if not (pq > 0.0):
                break
        return iterations, squared

    def _pcg_coupled(self, hierarchy: _Hierarchy3D, operator: Operator7Point,
                     points: NDArray[np.int64], term: tuple, x: NDArray[np.float64],
                     threshold: float) -> tuple[int, float]:
        """`_pcg` for ``A + C``: the levels hold ``A + diag(C)`` (the preconditioner); the
        products and residuals take ``operator`` (A) and ``C`` (``points``, ``term`` as
        `LowRankTerm.kernel_term` bundles it)."""
        b, r, p, q, z = hierarchy.b, hierarchy.r, hierarchy.p, hierarchy.q, hierarchy.z
        a = (operator.diagonal, operator.weights_x, operator.weights_y, operator.weights_z)
        flat_x, flat_r, flat_p, flat_q = (v.reshape(-1) for v in (x, r, p, q))

        def true_residual() -> float:
            residual_kernel_3d(*a, x, b, r)
            low_rank_add_dot_kernel(flat_x, flat_r, flat_x, points, term, -1.0)
            # Summed afresh: an update of |r|^2 by differences cancels near the end.
            return float(dot_kernel_3d(r, r))

        iterations = 0
        pq = 1.0
        squared = true_residual()
        while squared > threshold and iterations < self.max_iterations:
            rz = hierarchy.precondition(r, z, self.smoothing_sweeps)
            p[...] = z
            recursive = squared
            while recursive > threshold and iterations < self.max_iterations:
                pq = float(apply_dot_kernel_3d(*a, p, q))
                pq += float(low_rank_add_dot_kernel(flat_p, flat_q, flat_p, points, term, 1.0))
                if not (pq > 0.0):
                    break
                alpha = rz / pq
                recursive = step_kernel_3d(x, r, p, q, alpha)
                iterations += 1
                if recursive <= threshold:
                    break
                rz_next = hierarchy.precondition(r, z, self.smoothing_sweeps)
                direction_kernel_3d(z, p, rz_next / rz)
                rz = rz_next
            squared = true_residual()
            if not (pq > 0.0):
                break
        return iterations, squared
