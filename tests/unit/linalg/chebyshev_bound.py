"""The Jacobi-preconditioned Chebyshev iteration's convergence bound, for the 2D and 3D
solver tests."""

from __future__ import annotations

import numpy as np
from scipy import sparse


def chebyshev_bound(matrix: sparse.spmatrix, rhs: np.ndarray, start: np.ndarray,
                    rtol: float) -> tuple[float, int]:
    """``(spread, passes)``: the largest Jacobi row sum ``s`` of ``matrix`` (its Gershgorin
    bound) and the most iterations that reach ``|r| <= rtol |rhs|`` from ``start``.

    Rate bound: ``r_k = D^1/2 p_k(D^-1/2 A D^-1/2) D^-1/2 r_0`` with ``|p_k| <= 2 q^k`` on
    ``[1 - s, 1 + s]``, ``q = (sqrt(k) - 1) / (sqrt(k) + 1)``, ``k = (1 + s) / (1 - s)``;
    the diagonal scaling costs at most ``sqrt(max D / min D)``."""
    total = matrix.diagonal()
    spread = float(np.max((abs(matrix).sum(axis=1).A1 - total) / total))
    kappa = (1.0 + spread) / (1.0 - spread)
    q = (np.sqrt(kappa) - 1.0) / (np.sqrt(kappa) + 1.0)
    r0 = np.linalg.norm(rhs.ravel() - matrix @ start.ravel())
    amplification = 2.0 * np.sqrt(total.max() / total.min())
    bound = np.log(rtol * np.linalg.norm(rhs) / (amplification * r0)) / np.log(q)
    return spread, int(np.ceil(bound))
