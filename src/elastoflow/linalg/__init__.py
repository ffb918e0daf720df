"""Poisson solvers behind one interface.

``Operator5Point(diagonal, weights_x, weights_y)`` describes a symmetric positive
semi-definite 5-point operator on an ``(m, n)`` array,
``(A x)[i, j] = diagonal[i, j] x[i, j] + sum_nb w (x[i, j] - x[nb])``; ``apply_operator``
computes ``A x``. Every solver has ``solve(operator, rhs, x0=None, out=None) -> (x,
SolveReport)`` (``out``: an array to receive ``x``, may be ``x0``) and guarantees:

* inactive points (zero diagonal and zero weights) get ``x = 0``; ``rhs`` there is ignored;
* on every singular (pure Neumann) connected component the right-hand side is made compatible
  by subtracting its mean there, and the returned ``x`` has zero mean there;
* ``SolveReport.residual`` is the true relative residual ``|b - A x| / |b|`` (2-norm) of the
  returned ``x`` for that compatible ``b`` (not a recursively updated estimate);
  ``SolveReport.incompatibility`` is the share of the given right-hand side that was removed to
  make it compatible (round-off for a consistent problem, order 1 for net inflow into a closed
  box); ``converged`` means both are ``<= rtol``, so an incompatible system is never reported
  converged; ``x0`` is a warm start (0 iterations when it already meets ``rtol``).

``PoissonSolverJacobi(rtol, max_iterations, omega)`` is the paper's solver: weighted Jacobi,
convergent for every such operator (``0 < omega < 1``), but it needs O(n^2) sweeps on an
``n x n`` grid, so in practice it stops at ``max_iterations`` on large grids.

``PoissonSolverMGPCG(rtol, max_iterations, smoothing_sweeps)`` (the default) is conjugate
gradient preconditioned by one geometric multigrid V-cycle (McAdams, Sifakis & Teran 2010
style): its preconditioner is symmetric positive definite on the active points, so CG
converges for every such operator, and its iteration count barely grows with the grid
(6-7 iterations to 1e-6 from 128^2 to 1024^2 on pressure problems with outflow, bodies with
fractional faces, or closed boxes). It keeps its multigrid levels and component analysis while
the operator is unchanged, so an operator's arrays must not be modified after construction.

In 3D: ``Operator7Point(diagonal, weights_x, weights_y, weights_z)`` on ``(m, n, l)`` arrays,
``apply_operator_3d``, and ``PoissonSolverMGPCG3D(rtol, max_iterations, smoothing_sweeps)``
with the same ``solve`` contract and `SolveReport`.
"""


from elastoflow.linalg._banded import banded_solve_in_place, banded_sweep_layouts
from elastoflow.linalg._jacobi import PoissonSolverJacobi
from elastoflow.linalg._mgpcg import BandedInverse, LowRankTerm, PoissonSolverMGPCG
from elastoflow.linalg._mgpcg3d import PoissonSolverMGPCG3D
from elastoflow.linalg._operator import Operator5Point, SolveReport, apply_operator
from elastoflow.linalg._operator3d import Operator7Point, apply_operator_3d

__all__ = [
    "BandedInverse",
    "LowRankTerm",
    "Operator5Point",
    "Operator7Point",
    "PoissonSolverJacobi",
    "PoissonSolverMGPCG",
    "PoissonSolverMGPCG3D",
    "SolveReport",
    "apply_operator",
    "apply_operator_3d",
    "banded_solve_in_place",
    "banded_sweep_layouts",
]
