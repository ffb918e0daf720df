"""Numba kernels of the 5-point operator on ``(m, n)`` arrays: application, connected
components, null-space projection and the fused Jacobi sweep."""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True, inline="always")
def _neighbour_sum(diagonal, weights_x, weights_y, x, i, j, m, n):
    """Return ``(D, sum w x_nb)`` at ``[i, j]``, with ``D = diagonal + sum w``."""
    total = diagonal[i, j]
    coupled = 0.0
    if i > 0:
        w = weights_x[i - 1, j]
        total += w
        coupled += w * x[i - 1, j]
    if i < m - 1:
        w = weights_x[i, j]
        total += w
        coupled += w * x[i + 1, j]
    if j > 0:
        w = weights_y[i, j - 1]
        total += w
        coupled += w * x[i, j - 1]
    if j < n - 1:
        w = weights_y[i, j]
        total += w
        coupled += w * x[i, j + 1]
    return total, coupled


@njit(cache=True, parallel=True)
def apply_operator_kernel(diagonal, weights_x, weights_y, x, out):
    m, n = x.shape
    for i in prange(m):
        for j in range(n):
            total, coupled = _neighbour_sum(diagonal, weights_x, weights_y, x, i, j, m, n)
            out[i, j] = total * x[i, j] - coupled


@njit(cache=True, parallel=True)
def active_mask_kernel(diagonal, weights_x, weights_y, active):
    """Mark active points; return whether every active point has a positive diagonal."""
    m, n = diagonal.shape
    missing = 0
    for i in prange(m):
        for j in range(n):
            is_active = diagonal[i, j] > 0.0
            if i > 0 and weights_x[i - 1, j] > 0.0:
                is_active = True
            if i < m - 1 and weights_x[i, j] > 0.0:
                is_active = True
            if j > 0 and weights_y[i, j - 1] > 0.0:
                is_active = True
            if j < n - 1 and weights_y[i, j] > 0.0:
                is_active = True
            active[i, j] = is_active
            if is_active and diagonal[i, j] <= 0.0:
                missing += 1
    return missing == 0


@njit(cache=True, inline="always")
def _find(parent, k):
    while parent[k] != k:
        parent[k] = parent[parent[k]]
        k = parent[k]
    return k


@njit(cache=True)
def label_components_kernel(diagonal, weights_x, weights_y, active, labels):
    """Label connected components of active points (raster scan with union-find).

    Writes ``labels`` (-1 at inactive points, else 0..count-1) and returns
    ``(count, singular)`` where ``singular[c]`` says component ``c`` has no positive diagonal.
    """
    m, n = diagonal.shape
    parent = np.arange(m * n)
    for i in range(m):
        for j in range(n):
            if not active[i, j]:
                continue
            k = i * n + j
            if i > 0 and weights_x[i - 1, j] > 0.0:
                a = _find(parent, k)
                b = _find(parent, k - n)
                if a != b:
                    parent[max(a, b)] = min(a, b)
            if j > 0 and weights_y[i, j - 1] > 0.0:
                a = _find(parent, k)
                b = _find(parent, k - 1)
                if a != b:
                    parent[max(a, b)] = min(a, b)
    root_label = np.full(m * n, -1, dtype=np.int64)
    count = 0
    for i in range(m):
        for j in range(n):
            if not active[i, j]:
                labels[i, j] = -1
                continue
            root = _find(parent, i * n + j)
            if root_label[root] < 0:
                root_label[root] = count
                count += 1
            labels[i, j] = root_label[root]
    singular = np.ones(count, dtype=np.bool_)
    for i in range(m):
        for j in range(n):
            c = labels[i, j]
            if c >= 0 and diagonal[i, j] > 0.0:
                singular[c] = False
    return count, singular


@njit(cache=True)
def remove_component_means_kernel(x, labels, singular, count):
    """Subtract, on every singular component, the mean of ``x`` over that component."""
    m, n = x.shape
    sums = np.zeros(count)
    sizes = np.zeros(count)
    for i in range(m):
        for j in range(n):
            c = labels[i, j]
            if c >= 0 and singular[c]:
                sums[c] += x[i, j]
                sizes[c] += 1.0
    for c in range(count):
        if sizes[c] > 0.0:
            sums[c] /= sizes[c]
    for i in range(m):
        for j in range(n):
            c = labels[i, j]
            if c >= 0 and singular[c]:
                x[i, j] -= sums[c]


@njit(cache=True, parallel=True)
def jacobi_sweep_kernel(diagonal, weights_x, weights_y, rhs, x, x_next, omega):
    """One weighted Jacobi sweep ``x_next = x + omega D^-1 (b - A x)``; return ``|b - A x|^2``."""
    m, n = x.shape
    squared = 0.0
    for i in prange(m):
        for j in range(n):
            total, coupled = _neighbour_sum(diagonal, weights_x, weights_y, x, i, j, m, n)
            residual = rhs[i, j] - total * x[i, j] + coupled
            squared += residual * residual
            if total > 0.0:
                x_next[i, j] = x[i, j] + omega * residual / total
            else:
                x_next[i, j] = 0.0
    return squared
