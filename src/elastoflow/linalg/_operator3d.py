"""The 7-point operator on ``(m, n, l)`` arrays and its application."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from elastoflow.linalg._kernels import finite_minimum_kernel
from elastoflow.linalg._kernels3d import apply_operator_kernel_3d


def _check_values(name: str, array: NDArray[np.float64]) -> None:
    if not array.size:
        return
    # The 2D probe on a (m n, l) view: it only looks at values.
    bad, smallest = finite_minimum_kernel(array.reshape(-1, array.shape[-1]))
    if bad or smallest < 0.0:
        raise ValueError(
            f"{name}: values must be finite and >= 0; got {bad} non-finite, minimum {smallest!r}"
        )


@dataclass(frozen=True)
class Operator7Point:
    """A symmetric 7-point operator on an ``(m, n, l)`` array of unknowns.

    ``(A x)[i, j, k] = diagonal[i, j, k] x[i, j, k] + sum over neighbours nb of
    w (x[i, j, k] - x[nb])``, where the weight between ``[i, j, k]`` and ``[i+1, j, k]`` is
    ``weights_x[i, j, k]``, towards ``[i, j+1, k]`` ``weights_y[i, j, k]`` and towards
    ``[i, j, k+1]`` ``weights_z[i, j, k]``. A point with zero diagonal and zero weights is
    inactive. A connected component (through positive weights) with no positive diagonal is
    singular: its null space is the constant on the component. The 3D twin of
    `Operator5Point`, with the same contract.

    The arrays must not be changed after construction (build a new operator instead): solvers
    keep data derived from the last operator they solved with and recognise it by identity.

    Attributes:
        diagonal: Extra diagonal term (Dirichlet contributions, Helmholtz identity), shape
            ``(m, n, l)``, >= 0.
        weights_x: Couplings along x, shape ``(m-1, n, l)``, >= 0.
        weights_y: Couplings along y, shape ``(m, n-1, l)``, >= 0.
        weights_z: Couplings along z, shape ``(m, n, l-1)``, >= 0.
    """

    diagonal: NDArray[np.float64]
    weights_x: NDArray[np.float64]
    weights_y: NDArray[np.float64]
    weights_z: NDArray[np.float64]

    def __post_init__(self) -> None:
        diagonal = np.ascontiguousarray(self.diagonal, dtype=np.float64)
        if diagonal.ndim != 3 or min(diagonal.shape) < 1:
            raise ValueError(
                f"diagonal: shape {diagonal.shape} is not allowed; expected a non-empty "
                "(m, n, l) array"
            )
        m, n, l = diagonal.shape
        expected = {"weights_x": (m - 1, n, l), "weights_y": (m, n - 1, l),
                    "weights_z": (m, n, l - 1)}
        arrays = {"diagonal": diagonal}
        for name, shape in expected.items():
            array = np.ascontiguousarray(getattr(self, name), dtype=np.float64)
            if array.shape != shape:
                raise ValueError(f"{name}: shape {array.shape} is not allowed; expected {shape}")
            arrays[name] = array
        for name, array in arrays.items():
            _check_values(name, array)
            object.__setattr__(self, name, array)

    @classmethod
    def assembled(cls, diagonal: NDArray[np.float64], weights_x: NDArray[np.float64],
                  weights_y: NDArray[np.float64], weights_z: NDArray[np.float64]
                  ) -> Operator7Point:
        """An operator over arrays that a library kernel has just assembled (C-contiguous
        float64, >= 0 by construction): the shapes are checked, the values are not read.
        The constructor's pass over the values costs ~1 ms an operator at 64³, and a coupled
        3D step builds four (the pressure and the three viscosity operators around the
        bodies); a non-finite value, which only a non-finite input could give, still shows
        in the solve's residual and the step's finiteness check."""
        arrays = (diagonal, weights_x, weights_y, weights_z)
        if diagonal.ndim != 3 or not all(
                a.dtype == np.float64 and a.flags.c_contiguous for a in arrays):
            return cls(*arrays)
        m, n, l = diagonal.shape
        if (weights_x.shape, weights_y.shape, weights_z.shape) != (
                (m - 1, n, l), (m, n - 1, l), (m, n, l - 1)):
            return cls(*arrays)
        operator = object.__new__(cls)
        for name, array in zip(("diagonal", "weights_x", "weights_y", "weights_z"), arrays,
                               strict=True):
            object.__setattr__(operator, name, array)
        return operator

    @property
    def shape(self) -> tuple[int, int, int]:
        """Shape ``(m, n, l)`` of the unknowns."""
        m, n, l = self.diagonal.shape
        return (int(m), int(n), int(l))


def apply_operator_3d(
    operator: Operator7Point, x: NDArray[np.float64], out: NDArray[np.float64] | None = None
) -> NDArray[np.float64]:
    """Compute ``A x``.

    Args:
        operator: The operator ``A``.
        x: Values at the points, shape ``(m, n, l)``.
        out: Optional float64 C-contiguous output array of shape ``(m, n, l)``.

    Returns:
        ``A x``, shape ``(m, n, l)`` (``out`` when given).
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
    apply_operator_kernel_3d(operator.diagonal, operator.weights_x, operator.weights_y,
                             operator.weights_z, np.ascontiguousarray(x), out)
    return out
