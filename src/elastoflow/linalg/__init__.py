"""Poisson solvers behind one interface.

``Operator5Point`` describes a symmetric positive semi-definite 5-point operator
``(A x)[i, j] = diagonal[i, j] x[i, j] + sum_nb w (x[i, j] - x[nb])``. Every solver has
``solve(operator, rhs, x0=None) -> (x, SolveReport)`` and guarantees:

* inactive points (zero diagonal and zero weights) get ``x = 0``;
* on every singular (pure Neumann) connected component the right-hand side is made compatible
  by subtracting its mean there, and the returned ``x`` has zero mean there;
* ``SolveReport.residual`` is the true relative residual ``|b - A x| / |b|`` of the returned
  ``x`` for that compatible ``b``, and ``converged`` means it is ``<= rtol``.

``PoissonSolverJacobi`` (the paper's solver) converges for every such operator, slowly: O(n^2)
sweeps on an ``n x n`` grid. ``PoissonSolverMGPCG`` (the default) is conjugate gradient
preconditioned by a geometric multigrid V-cycle.
"""

from elastoflow.linalg._jacobi import PoissonSolverJacobi
from elastoflow.linalg._mgpcg import PoissonSolverMGPCG
from elastoflow.linalg._operator import Operator5Point, SolveReport, apply_operator

__all__ = [
    "Operator5Point",
    "PoissonSolverJacobi",
    "PoissonSolverMGPCG",
    "SolveReport",
    "apply_operator",
]
