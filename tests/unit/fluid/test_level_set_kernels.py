"""The level set's fast kernels give the values of the plain algorithms they replace, bitwise."""

from __future__ import annotations

import math

import numpy as np
import pytest

from elastoflow.fluid import GhostFluidProjection, RedistanceFastSweeping
from elastoflow.fluid import _level_set_kernels as kernels


def _sweep_row_by_row(distance: np.ndarray, fixed: np.ndarray, h: float, i_first: int,
                      i_step: int, j_first: int, j_step: int) -> None:
    """Zhao's Gauss-Seidel sweep in its plain order, row after row, on the unpadded grid."""
    nx, ny = distance.shape
    for ii in range(nx):
        i = i_first + i_step * ii
        for jj in range(ny):
            j = j_first + j_step * jj
            if fixed[i, j]:
                continue
            a = min(distance[i - 1, j] if i > 0 else math.inf,
                    distance[i + 1, j] if i + 1 < nx else math.inf)
            b = min(distance[i, j - 1] if j > 0 else math.inf,
                    distance[i, j + 1] if j + 1 < ny else math.inf)
            if abs(a - b) >= h:
                candidate = min(a, b) + h
            elif math.isnan(a - b):
                continue
            else:
                candidate = 0.5 * (a + b + math.sqrt(2.0 * h * h - (a - b) * (a - b)))
            if candidate < distance[i, j]:
                distance[i, j] = candidate


def _redistance_plainly(phi: np.ndarray, h: float, rounds: int) -> np.ndarray:
    """The fast-sweeping redistancing with the plain sweeps, from the kernel's own fixed
    cells (a zero-round redistancing gives their values)."""
    nx, ny = phi.shape
    start = np.empty_like(phi)
    fixed = np.zeros(phi.shape, dtype=np.bool_)
    RedistanceFastSweeping().redistance(phi, h, start, fixed)  # rounds >= 1: fixed cells only
    distance = np.where(fixed, np.abs(start), math.inf)
    for _ in range(rounds):
        for order in ((0, 1, 0, 1), (nx - 1, -1, 0, 1), (nx - 1, -1, ny - 1, -1),
                      (0, 1, ny - 1, -1)):
            _sweep_row_by_row(distance, fixed, h, *order)
    distance = np.where(np.isinf(distance), np.abs(phi), distance)
    return np.where(phi < 0.0, -distance, distance)


@pytest.mark.parametrize("shape", [(9, 7), (10, 7), (8, 12), (2, 5), (5, 2)])
@pytest.mark.parametrize("rounds", [1, 2])
def test_interleaved_sweeps_equal_the_row_by_row_order(shape: tuple[int, int],
                                                       rounds: int) -> None:
    """Two rows swept together, the second a cell behind, see the same neighbours as the
    row-by-row order: bitwise the same distances (two blobs of liquid, rough values)."""
    h = 0.1
    rng = np.random.default_rng(3)
    x, y = np.meshgrid(np.arange(shape[0]) * h, np.arange(shape[1]) * h, indexing="ij")
    phi = np.minimum(np.hypot(x - 0.2, y - 0.25) - 0.22, np.hypot(x - 0.7, y - 0.6) - 0.15)
    phi = phi * rng.uniform(0.5, 2.0, shape)
    if not np.any(phi < 0.0):
        phi[0, 0] = -0.01
    out = np.empty_like(phi)
    RedistanceFastSweeping(rounds=rounds).redistance(phi, h, out)
    expected = _redistance_plainly(phi, h, rounds)
    assert np.array_equal(out, expected)


def test_fused_maccormack_equals_the_three_passes() -> None:
    """`advect_cells_forward_range` + `maccormack_backward_correct` give bitwise the values
    of `advect_cells_semi_lagrangian` forward and back and `maccormack_correct`."""
    nx, ny = 23, 17
    rng = np.random.default_rng(7)
    x, y = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    phi = np.hypot(x - 9.3, y - 8.1) - 5.2 + 0.3 * rng.standard_normal((nx, ny))
    u = rng.uniform(-1.0, 1.5, (nx + 1, ny))
    v = rng.uniform(-1.2, 0.8, (nx, ny + 1))
    step = 1.7
    forward = np.empty_like(phi)
    backward = np.empty_like(phi)
    kernels.advect_cells_semi_lagrangian(phi, u, v, step, forward)
    kernels.advect_cells_semi_lagrangian(forward, u, v, -step, backward)
    kernels.maccormack_correct(phi, forward, backward, u, v, step, backward)
    fused_forward = np.empty_like(phi)
    low = np.empty_like(phi)
    high = np.empty_like(phi)
    out = np.empty_like(phi)
    spans = [np.empty(n, np.int64) for n in (nx + 1, nx + 1, nx, nx)]
    kernels.nonzero_spans(u, spans[0], spans[1])
    kernels.nonzero_spans(v, spans[2], spans[3])
    kernels.advect_cells_forward_range(phi, u, v, step, fused_forward, low, high, *spans)
    kernels.maccormack_backward_correct(phi, fused_forward, low, high, u, v, step, out, *spans)
    assert np.array_equal(fused_forward, forward)
    assert np.array_equal(out, backward)
    assert np.all(low <= out) and np.all(out <= high)


def test_the_level_set_in_still_air_is_not_traced_and_keeps_its_values() -> None:
    """With the velocity zero over part of the grid (-0.0 in it), the two passes give bitwise
    (sign bits included) the values of the semi-Lagrangian passes and the correction, which
    trace everywhere."""
    nx, ny = 23, 31
    rng = np.random.default_rng(9)
    x, y = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    phi = np.hypot(x - 9.3, y - 8.1) - 5.2 + 0.3 * rng.standard_normal((nx, ny))
    u = rng.uniform(-1.0, 1.5, (nx + 1, ny))
    v = rng.uniform(-1.2, 0.8, (nx, ny + 1))
    u[:, 14:] = 0.0
    v[:, 14:] = -0.0
    step = 1.7
    forward, backward = np.empty_like(phi), np.empty_like(phi)
    kernels.advect_cells_semi_lagrangian(phi, u, v, step, forward)
    kernels.advect_cells_semi_lagrangian(forward, u, v, -step, backward)
    kernels.maccormack_correct(phi, forward, backward, u, v, step, backward)
    spans = [np.empty(n, np.int64) for n in (nx + 1, nx + 1, nx, nx)]
    kernels.nonzero_spans(u, spans[0], spans[1])
    kernels.nonzero_spans(v, spans[2], spans[3])
    assert spans[1].max() == 14
    fused_forward, low, high, out = (np.empty_like(phi) for _ in range(4))
    kernels.advect_cells_forward_range(phi, u, v, step, fused_forward, low, high, *spans)
    kernels.maccormack_backward_correct(phi, fused_forward, low, high, u, v, step, out, *spans)
    assert np.array_equal(fused_forward.view(np.uint64), forward.view(np.uint64))
    assert np.array_equal(out.view(np.uint64), backward.view(np.uint64))


def test_the_ghost_fluid_operator_refuses_a_level_set_with_nan() -> None:
    """The operator skips the value checks (finite and >= 0 by construction), so its kernel
    counts the non-finite terms that a NaN in the level set makes."""
    projection = GhostFluidProjection()
    phi = np.full((6, 5), -0.5)
    phi[3, 2] = np.nan
    out = (np.zeros((6, 5)), np.zeros((5, 5)), np.zeros((6, 4)))
    with pytest.raises(ValueError, match="non-finite"):
        projection.operator(phi, out)
    phi[3, 2] = 0.3
    operator = projection.operator(phi, out)
    assert operator.diagonal[2, 2] > 0.0 and operator.weights_x[2, 2] == 0.0
