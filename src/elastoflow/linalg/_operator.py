"""The 5-point operator, its application, and the report every solver returns."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from elastoflow.linalg._kernels import apply_operator_kernel, finite_minimum_kernel


@dataclass(frozen=True)
class SolveReport:
    """Outcome of one linear solve.

    Attributes:
        iterations: Iterations performed (CG iterations or Jacobi sweeps).
        residual: Final true relative residual ``|b - A x| / |b|`` (2-norm), where ``b`` is the
            right-hand side after inactive points are zeroed and singular components are made
            compatible. 0 when ``b`` is 0.
        converged: Whether ``residual <= rtol`` and ``incompatibility <= rtol``: the returned
            ``x`` solves the system as given to within ``rtol``, not only its compatible part.
        incompatibility: ``|b0 - b| / |b0|``, the share of the given right-hand side ``b0``
            (on the active points) that lay in the null space of a singular component and was
            removed: round-off size for a consistent problem (a closed box with zero net flux),
            large for an ill-posed one (net inflow into a closed box), whose solution then
            does not satisfy the system as given. 0 for a non-singular operator.
    """

    iterations: int
    residual: float
    converged: bool
    incompatibility: float = 0.0


@dataclass(frozen=True)
class Operator5Point:
    """A symmetric 5-point operator on an ``(m, n)`` array of unknowns.

    ``(A x)[i, j] = diagonal[i, j] x[i, j] + sum over neighbours nb of w (x[i, j] - x[nb])``,
    where the weight between ``[i, j]`` and ``[i+1, j]`` is ``weights_x[i, j]`` and between
    ``[i, j]`` and ``[i, j+1]`` is ``weights_y[i, j]``. A point with zero diagonal and zero
    weights is inactive. A connected component (through positive weights) with no positive
    diagonal is singular: its null space is the constant on the component.

    The arrays must not be changed after construction (build a new operator instead): solvers
    keep data derived from the last operator they solved with and recognise it by identity.

    Attributes:
        diagonal: Extra diagonal term (Dirichlet contributions, Helmholtz identity), shape
            ``(m, n)``, >= 0.
        weights_x: Couplings along x, shape ``(m-1, n)``, >= 0.
        weights_y: Couplings along y, shape ``(m, n-1)``, >= 0.
    """

    diagonal: NDArray[np.float64]
    weights_x: NDArray[np.float64]
    weights_y: NDArray[np.float64]

    def __post_init__(self) -> None:
        diagonal = np.ascontiguousarray(self.diagonal, dtype=np.float64)
        if diagonal.ndim != 2 or diagonal.shape[0] < 1 or diagonal.shape[1] < 1:
            raise ValueError(
                f"diagonal: shape {diagonal.shape} is not allowed; expected a non-empty (m, n) array"
            )
        m, n = diagonal.shape
        weights_x = np.ascontiguousarray(self.weights_x, dtype=np.float64)
        weights_y = np.ascontiguousarray(self.weights_y, dtype=np.float64)
        if weights_x.shape != (m - 1, n):
            raise ValueError(f"weights_x: shape {weights_x.shape} is not allowed; expected {(m - 1, n)}")
        if weights_y.shape != (m, n - 1):
            raise ValueError(f"weights_y: shape {weights_y.shape} is not allowed; expected {(m, n - 1)}")
        for name, array in (("diagonal", diagonal), ("weights_x", weights_x), ("weights_y", weights_y)):
            if not array.size:
                continue
            bad, smallest = finite_minimum_kernel(array)
            if bad or smallest < 0.0:
                raise ValueError(
                    f"{name}: values must be finite and >= 0; got {bad} non-finite, "
                    f"minimum {smallest!r}"
                )
        object.__setattr__(self, "diagonal", diagonal)
        object.__setattr__(self, "weights_x", weights_x)
        object.__setattr__(self, "weights_y", weights_y)

    @classmethod
    def assembled(cls, diagonal: NDArray[np.float64], weights_x: NDArray[np.float64],
                  weights_y: NDArray[np.float64]) -> Operator5Point:
        """The operator of arrays that a compiled kernel has just filled, whose values are
        finite and >= 0 by construction: only the shapes, dtype and layout are checked, not
        the values (three passes over the grid; the free surface assembles a new operator
        every step). The arrays are used as they are, not copied."""
        m, n = diagonal.shape
        for name, array, shape in (("diagonal", diagonal, (m, n)),
                                   ("weights_x", weights_x, (m - 1, n)),
                                   ("weights_y", weights_y, (m, n - 1))):
            if (array.shape != shape or array.dtype != np.float64
                    or not array.flags.c_contiguous):
                raise ValueError(f"{name}: shape {array.shape} dtype {array.dtype} is not "
                                 f"allowed; expected C-contiguous float64 of shape {shape}")
        if m < 1 or n < 1:
            raise ValueError(f"diagonal: shape {diagonal.shape} is not allowed; expected a "
                             "non-empty (m, n) array")
        operator = object.__new__(cls)
        object.__setattr__(operator, "diagonal", diagonal)
        object.__setattr__(operator, "weights_x", weights_x)
        object.__setattr__(operator, "weights_y", weights_y)
        return operator

    @property
    def shape(self) -> tuple[int, int]:
        """Shape ``(m, n)`` of the unknowns."""
        return (int(self.diagonal.shape[0]), int(self.diagonal.shape[1]))


def apply_operator(
    operator: Operator5Point, x: NDArray[np.float64], out: NDArray[np.float64] | None = None
) -> NDArray[np.float64]:
    """Compute ``A x``.

    Args:
        operator: The operator ``A``.
        x: Values at the points, shape ``(m, n)``.
        out: Optional float64 C-contiguous output array of shape ``(m, n)``.

    Returns:
        ``A x``, shape ``(m, n)`` (``out`` when given).
    """
    x = np.asarray(x, dtype=np.float64)
    if x.shape != operator.shape:
        raise ValueError(f"x: shape {x.shape} is not allowed; expected {operator.shape}")
    if out is None:
        out = np.empty(operator.shape, dtype=np.float64)
    elif out.shape != operator.shape or out.dtype != np.float64 or not out.flags.c_contiguous:
        raise ValueError(
            f"out: shape {out.shape} dtype {out.dtype} is not allowed; expected C-contiguous "
            f"float64 of shape {operator.shape}"
        )
    apply_operator_kernel(
        operator.diagonal, operator.weights_x, operator.weights_y, np.ascontiguousarray(x), out
    )
    return out
