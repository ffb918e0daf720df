"""Preparation shared by the solvers: inactive points and the constant null spaces."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from elastoflow.linalg._kernels import (
    active_mask_kernel,
    finite_minimum_kernel,
    label_components_kernel,
    remove_component_means_kernel,
    sum_of_squares_kernel,
)
from elastoflow.linalg._operator import Operator5Point


@dataclass
class _NullSpace:
    """Active points and the singular (pure Neumann) components of an operator."""

    active: NDArray[np.bool_]
    labels: NDArray[np.int64] | None
    singular: NDArray[np.bool_] | None
    count: int

    @property
    def has_singular(self) -> bool:
        return self.singular is not None and bool(self.singular.any())

    def remove_means(self, x: NDArray[np.float64]) -> float:
        """Make ``x`` zero-mean on every singular component (in place); returns the 2-norm of
        what was removed."""
        if self.has_singular:
            assert self.labels is not None and self.singular is not None
            removed = remove_component_means_kernel(x, self.labels, self.singular, self.count)
            return float(np.sqrt(removed))
        return 0.0


def _analyse(
    operator: Operator5Point,
    active: NDArray[np.bool_] | None = None,
    all_have_diagonal: bool = False,
) -> _NullSpace:
    """Active points and singular components of ``operator``.

    ``active`` (shape ``(m, n)``) with ``all_have_diagonal`` may be given when already known
    (the multigrid solver computes both while loading the operator); the array is kept.
    """
    if active is None:
        active = np.empty(operator.shape, dtype=np.bool_)
        all_have_diagonal = active_mask_kernel(
            operator.diagonal, operator.weights_x, operator.weights_y, active
        )
    if all_have_diagonal:
        return _NullSpace(active, None, None, 0)
    labels = np.empty(operator.shape, dtype=np.int64)
    count, singular = label_components_kernel(
        operator.diagonal, operator.weights_x, operator.weights_y, active, labels
    )
    return _NullSpace(active, labels, singular, int(count))


def _compatible_rhs(
    operator: Operator5Point, rhs: NDArray[np.float64]
) -> tuple[NDArray[np.float64], _NullSpace, float]:
    """Copy of ``rhs`` zeroed at inactive points and zero-mean on singular components, and its
    incompatibility (see `incompatibility`)."""
    rhs = np.asarray(rhs, dtype=np.float64)
    if rhs.shape != operator.shape:
        raise ValueError(f"rhs: shape {rhs.shape} is not allowed; expected {operator.shape}")
    if rhs.size and finite_minimum_kernel(np.ascontiguousarray(rhs))[0]:
        raise ValueError("rhs: values must be finite; got NaN or inf")
    null_space = _analyse(operator)
    b = np.where(null_space.active, rhs, 0.0)
    # Not np.linalg.norm: that is BLAS (OpenBLAS, with threads of its own beside Numba's);
    # with it every phase of a step that used this solver ran at half speed (2 cores).
    norm = float(np.sqrt(sum_of_squares_kernel(b)))
    removed = null_space.remove_means(b)
    return b, null_space, incompatibility(removed, norm)


def incompatibility(removed: float, norm: float) -> float:
    """``|removed| / |b|``: the share of the right-hand side ``b`` (2-norm, on the active
    points) that lay in the null space of a singular operator and was removed to solve; 0 when
    ``b`` is 0."""
    return removed / norm if norm > 0.0 else 0.0


def _initial_guess(
    operator: Operator5Point, x0: NDArray[np.float64] | None, active: NDArray[np.bool_]
) -> NDArray[np.float64]:
    if x0 is None:
        return np.zeros(operator.shape)
    x0 = np.asarray(x0, dtype=np.float64)
    if x0.shape != operator.shape:
        raise ValueError(f"x0: shape {x0.shape} is not allowed; expected {operator.shape}")
    if x0.size and finite_minimum_kernel(np.ascontiguousarray(x0))[0]:
        raise ValueError("x0: values must be finite; got NaN or inf")
    return np.where(active, x0, 0.0)


def _output(out: NDArray[np.float64] | None, shape: tuple[int, int]) -> NDArray[np.float64]:
    """``out`` checked to be a C-contiguous float64 array of ``shape``, or a new array."""
    if out is None:
        return np.empty(shape)
    if (not isinstance(out, np.ndarray) or out.shape != shape or out.dtype != np.float64
            or not out.flags.c_contiguous or not out.flags.writeable):
        raise ValueError(
            f"out: {type(out).__name__} of shape {getattr(out, 'shape', None)} is not allowed; "
            f"expected a writeable C-contiguous float64 array of shape {shape}"
        )
    return out
