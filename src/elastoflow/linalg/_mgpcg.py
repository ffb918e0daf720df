"""Conjugate gradient preconditioned by a geometric multigrid V-cycle."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from elastoflow.linalg._kernels import apply_operator_kernel
from elastoflow.linalg._operator import Operator5Point, SolveReport
from elastoflow.linalg._problem import _compatible_rhs, _initial_guess


@dataclass(frozen=True)
class PoissonSolverMGPCG:
    """Multigrid-preconditioned conjugate gradient.

    Attributes:
        rtol: Relative residual tolerance ``|b - A x| / |b|``.
        max_iterations: Maximum number of CG iterations.
    """

    rtol: float = 1e-6
    max_iterations: int = 200

    def __post_init__(self) -> None:
        if not (self.rtol > 0.0):
            raise ValueError(f"rtol: {self.rtol!r} is not allowed; expected > 0")
        if self.max_iterations < 0:
            raise ValueError(f"max_iterations: {self.max_iterations!r} is not allowed; expected >= 0")

    def solve(
        self,
        operator: Operator5Point,
        rhs: NDArray[np.float64],
        x0: NDArray[np.float64] | None = None,
    ) -> tuple[NDArray[np.float64], SolveReport]:
        """Solve ``A x = rhs``.

        Args:
            operator: The operator ``A`` on an ``(m, n)`` array.
            rhs: Right-hand side, shape ``(m, n)``.
            x0: Optional initial guess, shape ``(m, n)``.

        Returns:
            ``x`` (shape ``(m, n)``; 0 at inactive points, zero mean on singular components) and
            the report.
        """
        b, null_space = _compatible_rhs(operator, rhs)
        x = _initial_guess(operator, x0, null_space.active)
        norm_b = float(np.linalg.norm(b))
        if norm_b == 0.0:
            return np.zeros(operator.shape), SolveReport(0, 0.0, True)
        d, wx, wy = operator.diagonal, operator.weights_x, operator.weights_y
        total = d.copy()
        total[:-1] += wx
        total[1:] += wx
        total[:, :-1] += wy
        total[:, 1:] += wy
        inverse = np.where(total > 0.0, 1.0 / np.where(total > 0.0, total, 1.0), 0.0)
        q = np.empty_like(x)
        apply_operator_kernel(d, wx, wy, x, q)
        r = b - q
        z = inverse * r
        p = z.copy()
        rz = float(np.vdot(r, z))
        iterations = 0
        while iterations < self.max_iterations:
            if np.linalg.norm(r) <= self.rtol * norm_b:
                break
            apply_operator_kernel(d, wx, wy, p, q)
            alpha = rz / float(np.vdot(p, q))
            x += alpha * p
            r -= alpha * q
            z = inverse * r
            rz_next = float(np.vdot(r, z))
            p = z + (rz_next / rz) * p
            rz = rz_next
            iterations += 1
        null_space.remove_means(x)
        apply_operator_kernel(d, wx, wy, x, q)
        relative = float(np.linalg.norm(b - q) / norm_b)
        return x, SolveReport(iterations, relative, relative <= self.rtol)
