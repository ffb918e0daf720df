"""Weighted Jacobi iteration: the paper's Poisson solver."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from elastoflow.linalg._kernels import jacobi_kernel, sum_of_squares_kernel
from elastoflow.linalg._operator import Operator5Point, SolveReport
from elastoflow.linalg._problem import _compatible_rhs, _initial_guess, _output


@dataclass(frozen=True)
class PoissonSolverJacobi:
    """Weighted Jacobi, ``x <- x + omega D^-1 (b - A x)`` with ``D = diagonal + sum of weights``.

    Guarantee: for ``0 < omega < 1`` the iteration converges for every operator of the contract
    (symmetric positive semi-definite, compatible right-hand side), but needs O(n^2) sweeps on an
    ``n x n`` grid; it stops at ``rtol`` or after ``max_iterations`` sweeps.

    Attributes:
        rtol: Relative residual tolerance ``|b - A x| / |b|``.
        max_iterations: Maximum number of sweeps.
        omega: Damping factor in (0, 1]; below 1 so that checkerboard modes of pure Neumann
            problems (eigenvalue 2 of ``D^-1 A``) are damped.
    """

    rtol: float = 1e-6
    max_iterations: int = 100_000
    omega: float = 0.9

    def __post_init__(self) -> None:
        if not (self.rtol > 0.0):
            raise ValueError(f"rtol: {self.rtol!r} is not allowed; expected > 0")
        if self.max_iterations < 0:
            raise ValueError(f"max_iterations: {self.max_iterations!r} is not allowed; expected >= 0")
        if not (0.0 < self.omega <= 1.0):
            raise ValueError(f"omega: {self.omega!r} is not allowed; expected in (0, 1]")

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
            x0: Optional initial guess, shape ``(m, n)``.
            out: Optional C-contiguous float64 array of shape ``(m, n)`` to receive ``x``
                (may be ``x0``); a new array otherwise.

        Returns:
            ``x`` (shape ``(m, n)``; 0 at inactive points, zero mean on singular components) and
            the report.
        """
        _output(out, operator.shape)
        b, null_space, incompatible = _compatible_rhs(operator, rhs)
        x = _initial_guess(operator, x0, null_space.active)
        norm_b = float(np.sqrt(sum_of_squares_kernel(b)))
        if norm_b == 0.0:
            x = _output(out, operator.shape)
            x[...] = 0.0
            return x, SolveReport(0, 0.0, incompatible <= self.rtol, incompatible)
        iterations, squared = jacobi_kernel(
            operator.diagonal, operator.weights_x, operator.weights_y, b, x, np.empty_like(x),
            self.omega, (self.rtol * norm_b) ** 2, self.max_iterations,
        )
        null_space.remove_means(x)
        if out is not None:
            out[...] = x
            x = out
        relative = float(np.sqrt(squared)) / norm_b
        return x, SolveReport(iterations, relative,
                              relative <= self.rtol and incompatible <= self.rtol, incompatible)

