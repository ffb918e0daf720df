"""MacCormack's velocity advection in two passes (forward with the clamp's range, then
backward and corrected) gives bitwise the values of the three passes it replaced: forward,
backward, correction. The reference below is those three passes written out in Python over
the kernels' own sampling and back-trace functions, on grids small enough to loop over."""

from __future__ import annotations

import math

import numpy as np
import pytest

from elastoflow.fluid import _kernels as fluid_kernels
from elastoflow.fluid import _level_set_kernels as kernels

_sample = fluid_kernels._sample.py_func
_trace_back = fluid_kernels._trace_back.py_func
_corner_range = fluid_kernels._corner_range.py_func

# Ghost modes and values of the four sides: a no-slip wall reflects u about 0 (mode 1), a
# free-slip one copies it (mode 0), a given value (mode 2).
_MODES_U = np.array([1, 2, 0, 1], dtype=np.int64)
_VALUES_U = np.array([0.0, 0.3, 0.0, -0.2])
_MODES_V = np.array([0, 1, 1, 2], dtype=np.int64)
_VALUES_V = np.array([0.0, 0.1, 0.0, 0.25])


def _departure(u, v, i, j, axis, dt, h):
    """Departure point of face (i, j) in index coordinates, as the kernels trace it."""
    inv_h = 1.0 / h
    lx = (u.shape[0] - 1) * h
    ly = u.shape[1] * h
    if axis == 0:
        x, y = i * h, (j + 0.5) * h
        uy = _sample(v, x * inv_h - 0.5, y * inv_h, _MODES_V, _VALUES_V)
        xb, yb = _trace_back(u, v, x, y, u[i, j], uy, dt, inv_h, lx, ly, _MODES_U, _VALUES_U,
                             _MODES_V, _VALUES_V)
        return xb * inv_h, yb * inv_h - 0.5
    x, y = (i + 0.5) * h, j * h
    ux = _sample(u, x * inv_h, y * inv_h - 0.5, _MODES_U, _VALUES_U)
    xb, yb = _trace_back(u, v, x, y, ux, v[i, j], dt, inv_h, lx, ly, _MODES_U, _VALUES_U,
                         _MODES_V, _VALUES_V)
    return xb * inv_h - 0.5, yb * inv_h


def _reads_ghost(fx, fy, m, n):
    i0, j0 = math.floor(fx), math.floor(fy)
    return i0 < 0 or j0 < 0 or i0 + 1 >= m or j0 + 1 >= n


def _reads_air(fx, fy, liquid):
    m, n = liquid.shape
    i0, j0 = math.floor(fx), math.floor(fy)
    return any(liquid[min(max(i0 + di, 0), m - 1), min(max(j0 + dj, 0), n - 1)] == 0
               for di in (0, 1) for dj in (0, 1))


def _three_passes(u, v, axis, dt, h, liquid=None, limited=True):
    """Forward, backward and corrected values of component ``axis``; with ``liquid`` the
    free surface's fallback (the forward value where a sample reads a side's ghost, at air
    faces and where the forward stencil reads one)."""
    f = u if axis == 0 else v
    modes, values = (_MODES_U, _VALUES_U) if axis == 0 else (_MODES_V, _VALUES_V)
    m, n = f.shape
    forward = np.empty_like(f)
    departures = {}
    for i in range(m):
        for j in range(n):
            departures[i, j] = _departure(u, v, i, j, axis, dt, h)
            forward[i, j] = _sample(f, *departures[i, j], modes, values)
    out = np.empty_like(f)
    for i in range(m):
        for j in range(n):
            back = _departure(u, v, i, j, axis, -dt, h)
            backward = _sample(forward, *back, modes, values)
            fx, fy = departures[i, j]
            if liquid is not None and (
                    _reads_ghost(fx, fy, m, n) or _reads_ghost(*back, m, n)
                    or liquid[i, j] == 0 or _reads_air(fx, fy, liquid)):
                out[i, j] = forward[i, j]
                continue
            corrected = forward[i, j] + 0.5 * (f[i, j] - backward)
            if limited:
                low, high = _corner_range(f, fx, fy, modes, values)
                corrected = min(max(corrected, low), high)
            out[i, j] = corrected
    return forward, out


def _velocity(nx: int, ny: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.uniform(-1.0, 1.5, (nx + 1, ny)), rng.uniform(-1.2, 0.8, (nx, ny + 1))


@pytest.mark.parametrize("limited", [True, False])
def test_the_fluid_kernels_two_passes_equal_the_three(limited: bool) -> None:
    """`advect` of the x and y faces with `PASS_TRACE_RANGE` then `PASS_CORRECT`
    (`PASS_TRACE` then `PASS_CORRECT_UNCLAMPED` without the limiter)."""
    nx, ny, h, dt = 11, 9, 0.1, 0.13
    u, v = _velocity(nx, ny, 5)
    no_solid, no_theta = np.zeros((1, 1), dtype=np.bool_), np.full((4, 1, 1), np.inf)
    no_cut, no_values = np.zeros((4, 1, 1)), np.zeros((1, 1))
    near = np.ones((nx + 2, ny + 2), dtype=np.bool_)
    ghosts = (_MODES_U, _VALUES_U, _MODES_V, _VALUES_V)
    bodies = (no_solid, no_theta, no_cut, no_solid, no_theta, no_cut, near)
    first, second = ((fluid_kernels.PASS_TRACE_RANGE, fluid_kernels.PASS_CORRECT) if limited
                     else (fluid_kernels.PASS_TRACE, fluid_kernels.PASS_CORRECT_UNCLAMPED))
    for axis, field in enumerate((fluid_kernels.FIELD_X, fluid_kernels.FIELD_Y)):
        f = u if axis == 0 else v
        own = (no_solid, no_values, ghosts[2 * axis], ghosts[2 * axis + 1])
        forward, low, high = (np.empty_like(f) for _ in range(3))
        fluid_kernels.advect((u, v), f, forward, field, dt, h, ghosts, False, bodies, own,
                             first, (f, low, high))
        fluid_kernels.advect((u, v), f, low, field, -dt, h, ghosts, False, bodies, own, second,
                             (forward, low, high))
        expected_forward, expected = _three_passes(u, v, axis, dt, h, limited=limited)
        np.testing.assert_array_equal(forward, expected_forward)
        np.testing.assert_array_equal(low, expected)


@pytest.mark.parametrize(("air", "still"), [(True, False), (False, False), (True, True),
                                            (False, True)])
def test_the_free_surface_two_passes_equal_the_three(air: bool, still: bool) -> None:
    """`advect_faces_forward_range` then `maccormack_faces_backward_correct`, with the
    fallback at sides' ghosts and (``air``) at air faces and next to them; ``still``: the
    velocity is zero in the upper part, whose air faces are not traced (sign bits equal)."""
    nx, ny, h, dt = 12, 20, 0.1, 0.15
    u, v = _velocity(nx, ny, 8)
    if still:
        u[:, 11:] = 0.0
        v[:, 11:] = -0.0
        v[4, 15] = 0.0
    spans = (np.empty(nx + 1, np.int64), np.empty(nx + 1, np.int64), np.empty(nx, np.int64),
             np.empty(nx, np.int64))
    kernels.nonzero_spans(u, spans[0], spans[1])
    kernels.nonzero_spans(v, spans[2], spans[3])
    for axis in (0, 1):
        f = u if axis == 0 else v
        liquid = np.ones(f.shape, dtype=np.int32)
        liquid[:, f.shape[1] // 2:] = 0
        liquid[3, 1] = 0
        forward, low, high = (np.empty_like(f) for _ in range(3))
        ghosts = (_MODES_U, _VALUES_U, _MODES_V, _VALUES_V)
        kernels.advect_faces_forward_range((u, v), axis, dt, h, ghosts, liquid, air,
                                           (forward, low, high), spans)
        kernels.maccormack_faces_backward_correct((u, v), axis, dt, h, ghosts,
                                                  (forward, low, high), low)
        expected_forward, expected = _three_passes(
            u, v, axis, dt, h, liquid=liquid if air else np.ones_like(liquid))
        np.testing.assert_array_equal(forward.view(np.uint64), expected_forward.view(np.uint64))
        np.testing.assert_array_equal(low.view(np.uint64), expected.view(np.uint64))
        # The fallback is exercised, and so is the correction.
        assert np.any(low == forward) and np.any(low != forward)
