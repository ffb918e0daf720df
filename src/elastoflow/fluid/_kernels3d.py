"""Numba kernels of the 3D fluid on the MAC grid, with or without bodies inside
(`InteriorBoundary3D`): advection (trilinear sampling with side ghosts, and cut-distance
ghosts across a body boundary), the implicit viscosity system, the pressure equation and the
projection.

One kernel per phase, as in 2D (`elastoflow.fluid._kernels`): a ``has_interior`` flag says
whether the body arrays are read, and without bodies the solver passes stand-ins for them
(open fractions 1 where they are read anyway; `NO_BODIES_BOXES` for the samples).

Arrays are ``[i, j, k]`` (`elastoflow.grid.Grid3D`): u (nx+1, ny, nz), v (nx, ny+1, nz),
w (nx, ny, nz+1), cell fields (nx, ny, nz). Sides are numbered by `SIDE_*` (low then high
along x, y, z), and per-side arrays of length 6 follow that order; cut directions are
0 -x, 1 +x, 2 -y, 3 +y, 4 -z, 5 +z. The 2D kernels' constants apply unchanged (`OPEN_MIN`:
faces open by less than 1 % count closed; `THETA_MIN`: the smallest cut fraction used in a
stencil). Kernels take plain arrays, scalars and tuples of them only.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from elastoflow._numba import serial_and_parallel
from elastoflow.fluid._kernels import OPEN_MIN, THETA_MIN

# Side numbers: index = 2 * axis + (0 at the low end, 1 at the high end).
SIDE_LEFT, SIDE_RIGHT, SIDE_BOTTOM, SIDE_TOP, SIDE_BACK, SIDE_FRONT = range(6)

# How a sample beyond a side is made from the value just inside (``value`` is the side's):
GHOST_COPY = 0       # zero normal gradient (free slip, outflow)
GHOST_DIRICHLET = 1  # the mirror ``2 value - inside``: ``value`` holds halfway (no slip)
GHOST_VALUE = 2      # ``value`` itself (inflow dye)

# Below this many points a parallel region costs more than it saves.
PARALLEL_MINIMUM_3D = 16 * 16 * 16

# Which field an advection pass transports (`advect_3d`): where its points sit, and its row
# of the solid boxes.
FIELD_U, FIELD_V, FIELD_W, FIELD_CELLS = range(4)

# What an advection pass writes (`advect_3d`):
PASS_TRACE = 0    # the semi-Lagrangian sample at the departure point
PASS_CORRECT = 1  # MacCormack's clamped correction of the forward pass by the backward one

# The solid boxes (`solid_box`) of u, v, w and the cells without bodies: every sample misses
# them, so that no body array is read.
NO_BODIES_BOXES = np.array([[2**62, -(2**62)] * 3] * 4, dtype=np.int64)


@njit(cache=True, inline="always")
def _lerp(a, b, t):
    # a + t (b - a) returns a exactly when a == b, so constants survive interpolation.
    return a + t * (b - a)


@njit(cache=True, inline="always")
def _ghost(mode, value, inside):
    if mode == GHOST_COPY:
        return inside
    if mode == GHOST_DIRICHLET:
        return 2.0 * value - inside
    return value


@njit(cache=True)
def _field_value(f, i, j, k, modes, values, row):
    """``f[i, j, k]``, or a ghost made from the nearest inside value beyond a side, with the
    modes and values of ``modes[row]`` / ``values[row]`` (read in place: a row view would
    cost a reference count per sample)."""
    m, n, l = f.shape
    value = f[min(max(i, 0), m - 1), min(max(j, 0), n - 1), min(max(k, 0), l - 1)]
    if i < 0:
        value = _ghost(modes[row, SIDE_LEFT], values[row, SIDE_LEFT], value)
    elif i >= m:
        value = _ghost(modes[row, SIDE_RIGHT], values[row, SIDE_RIGHT], value)
    if j < 0:
        value = _ghost(modes[row, SIDE_BOTTOM], values[row, SIDE_BOTTOM], value)
    elif j >= n:
        value = _ghost(modes[row, SIDE_TOP], values[row, SIDE_TOP], value)
    if k < 0:
        value = _ghost(modes[row, SIDE_BACK], values[row, SIDE_BACK], value)
    elif k >= l:
        value = _ghost(modes[row, SIDE_FRONT], values[row, SIDE_FRONT], value)
    return value


@njit(cache=True, inline="always")
def _sample(f, fx, fy, fz, modes, values, row):
    """Trilinear sample of ``f`` at index coordinates ``(fx, fy, fz)`` with side ghosts."""
    i0 = int(math.floor(fx))
    j0 = int(math.floor(fy))
    k0 = int(math.floor(fz))
    a = fx - i0
    b = fy - j0
    c = fz - k0
    m, n, l = f.shape
    if 0 <= i0 < m - 1 and 0 <= j0 < n - 1 and 0 <= k0 < l - 1:
        low = _lerp(_lerp(f[i0, j0, k0], f[i0 + 1, j0, k0], a),
                    _lerp(f[i0, j0 + 1, k0], f[i0 + 1, j0 + 1, k0], a), b)
        high = _lerp(_lerp(f[i0, j0, k0 + 1], f[i0 + 1, j0, k0 + 1], a),
                     _lerp(f[i0, j0 + 1, k0 + 1], f[i0 + 1, j0 + 1, k0 + 1], a), b)
        return _lerp(low, high, c)
    return _sample_near_side(f, i0, j0, k0, a, b, c, modes, values, row)


@njit(cache=True)
def _sample_near_side(f, i0, j0, k0, a, b, c, modes, values, row):
    """`_sample` when a corner lies beyond a side. Per axis, the two corner indices clamped
    into the array and the affine ghost map (value = a * inside + b) of each, composed x,
    then y, then z as in `_field_value`: computed once per axis instead of once per corner.
    Not inlined, so that the inlined fast path stays small."""
    m, n, l = f.shape
    ia, aia, bia = _axis_corner(i0, m, modes[row, SIDE_LEFT], values[row, SIDE_LEFT],
                                modes[row, SIDE_RIGHT], values[row, SIDE_RIGHT])
    ib, aib, bib = _axis_corner(i0 + 1, m, modes[row, SIDE_LEFT], values[row, SIDE_LEFT],
                                modes[row, SIDE_RIGHT], values[row, SIDE_RIGHT])
    ja, aja, bja = _axis_corner(j0, n, modes[row, SIDE_BOTTOM], values[row, SIDE_BOTTOM],
                                modes[row, SIDE_TOP], values[row, SIDE_TOP])
    jb, ajb, bjb = _axis_corner(j0 + 1, n, modes[row, SIDE_BOTTOM], values[row, SIDE_BOTTOM],
                                modes[row, SIDE_TOP], values[row, SIDE_TOP])
    ka, aka, bka = _axis_corner(k0, l, modes[row, SIDE_BACK], values[row, SIDE_BACK],
                                modes[row, SIDE_FRONT], values[row, SIDE_FRONT])
    kb, akb, bkb = _axis_corner(k0 + 1, l, modes[row, SIDE_BACK], values[row, SIDE_BACK],
                                modes[row, SIDE_FRONT], values[row, SIDE_FRONT])
    low = _lerp(
        _lerp(_corner(f, ia, aia, bia, ja, aja, bja, ka, aka, bka),
              _corner(f, ib, aib, bib, ja, aja, bja, ka, aka, bka), a),
        _lerp(_corner(f, ia, aia, bia, jb, ajb, bjb, ka, aka, bka),
              _corner(f, ib, aib, bib, jb, ajb, bjb, ka, aka, bka), a), b)
    high = _lerp(
        _lerp(_corner(f, ia, aia, bia, ja, aja, bja, kb, akb, bkb),
              _corner(f, ib, aib, bib, ja, aja, bja, kb, akb, bkb), a),
        _lerp(_corner(f, ia, aia, bia, jb, ajb, bjb, kb, akb, bkb),
              _corner(f, ib, aib, bib, jb, ajb, bjb, kb, akb, bkb), a), b)
    return _lerp(low, high, c)


@njit(cache=True, inline="always")
def _ghost_map(mode, value):
    """``(a, b)`` with ``ghost = a * inside + b`` for a ghost ``mode`` (see `_ghost`)."""
    if mode == GHOST_COPY:
        return 1.0, 0.0
    if mode == GHOST_DIRICHLET:
        return -1.0, 2.0 * value
    return 0.0, value


@njit(cache=True, inline="always")
def _axis_corner(index, size, mode_low, value_low, mode_high, value_high):
    """``index`` clamped into ``[0, size)`` and the ghost map ``(a, b)`` that applies there
    (``(1, 0)`` inside)."""
    if index < 0:
        a, b = _ghost_map(mode_low, value_low)
        return 0, a, b
    if index >= size:
        a, b = _ghost_map(mode_high, value_high)
        return size - 1, a, b
    return index, 1.0, 0.0


@njit(cache=True, inline="always")
def _corner(f, i, ai, bi, j, aj, bj, k, ak, bk):
    return ((f[i, j, k] * ai + bi) * aj + bj) * ak + bk


@njit(cache=True, inline="always")
def _corner_range(f, fx, fy, fz, modes, values, row):
    """Smallest and largest of the eight values around index coordinates ``(fx, fy, fz)``.

    Inside the array (nearly every point) the eight values are read directly; near a side
    `_corner_range_near_side` makes the ghosts."""
    i0 = int(math.floor(fx))
    j0 = int(math.floor(fy))
    k0 = int(math.floor(fz))
    m, n, l = f.shape
    if 0 <= i0 < m - 1 and 0 <= j0 < n - 1 and 0 <= k0 < l - 1:
        c0 = f[i0, j0, k0]
        c1 = f[i0 + 1, j0, k0]
        c2 = f[i0, j0 + 1, k0]
        c3 = f[i0 + 1, j0 + 1, k0]
        c4 = f[i0, j0, k0 + 1]
        c5 = f[i0 + 1, j0, k0 + 1]
        c6 = f[i0, j0 + 1, k0 + 1]
        c7 = f[i0 + 1, j0 + 1, k0 + 1]
        low = min(min(min(c0, c1), min(c2, c3)), min(min(c4, c5), min(c6, c7)))
        high = max(max(max(c0, c1), max(c2, c3)), max(max(c4, c5), max(c6, c7)))
        return low, high
    return _corner_range_near_side(f, i0, j0, k0, modes, values, row)


@njit(cache=True)
def _corner_range_near_side(f, i0, j0, k0, modes, values, row):
    """`_corner_range` when a corner lies beyond a side: corner by corner with ghosts."""
    low = math.inf
    high = -math.inf
    for corner in range(8):
        value = _field_value(f, i0 + (corner & 1), j0 + ((corner >> 1) & 1),
                             k0 + (corner >> 2), modes, values, row)
        low = min(low, value)
        high = max(high, value)
    return low, high


# -- bodies in the samples ---------------------------------------------------------------------


@njit(cache=True, inline="always")
def _open(fraction):
    if fraction < OPEN_MIN:
        return 0.0
    return min(fraction, 1.0)


@njit(cache=True, inline="always")
def _body_ghost(theta, boundary_value, inside_value):
    # METHOD.md §6's ghost (u_b - (1 - t) u_P) / t, limited as in 2D so that it lies no
    # farther from the boundary value than the fluid point does.
    t = max(theta, THETA_MIN)
    ratio = min((1.0 - t) / t, 1.0)
    return boundary_value + ratio * (boundary_value - inside_value)


@njit(cache=True, inline="always")
def _inside(i, j, k, m, n, l):
    return 0 <= i < m and 0 <= j < n and 0 <= k < l


@njit(cache=True)
def _corner_with_bodies(f, i0, j0, k0, corner, modes, values, row, solid, theta, cut_velocity):
    """The value of corner ``corner`` (bits: +x, +y, +z) of the cell at ``(i0, j0, k0)``: a
    solid corner is replaced by the mean of the cut-distance ghosts seen from its fluid
    neighbours along the cell's edges (kept, i.e. its body velocity, when none sees it)."""
    m, n, l = f.shape
    ii = i0 + (corner & 1)
    jj = j0 + ((corner >> 1) & 1)
    kk = k0 + (corner >> 2)
    if not _inside(ii, jj, kk, m, n, l):
        # Beyond a side: a side ghost, never solid.
        return _field_value(f, ii, jj, kk, modes, values, row)
    value = f[ii, jj, kk]
    if not solid[ii, jj, kk]:
        return value
    total = 0.0
    count = 0
    for bit in range(3):
        other = corner ^ (1 << bit)
        oi = i0 + (other & 1)
        oj = j0 + ((other >> 1) & 1)
        ok = k0 + (other >> 2)
        if not _inside(oi, oj, ok, m, n, l) or solid[oi, oj, ok]:
            continue
        direction = 2 * bit + ((corner >> bit) & 1)
        t = theta[direction, oi, oj, ok]
        if t <= 1.0:
            total += _body_ghost(t, cut_velocity[direction, oi, oj, ok], f[oi, oj, ok])
            count += 1
    if count > 0:
        return total / count
    return value


@njit(cache=True, inline="always")
def _any_solid(solid, i0, j0, k0):
    return (solid[i0, j0, k0] or solid[i0 + 1, j0, k0] or solid[i0, j0 + 1, k0]
            or solid[i0 + 1, j0 + 1, k0] or solid[i0, j0, k0 + 1] or solid[i0 + 1, j0, k0 + 1]
            or solid[i0, j0 + 1, k0 + 1] or solid[i0 + 1, j0 + 1, k0 + 1])


@njit(cache=True)
def solid_box(solid, out, region):
    """Index bounds ``(i_low, i_high, j_low, j_high, k_low, k_high)`` (inclusive) of the
    True entries of ``solid`` into ``out`` (int64, (6,)); an empty box (low > high) when
    there are none. Only ``region`` ``(i0, j0, k0, i1, j1, k1)`` (ends exclusive, clipped
    to the array; `WHOLE_REGION`: all of it) is read: the caller knows ``solid`` False
    outside it (an `InteriorBoundary3D`'s box)."""
    m, n, l = solid.shape
    out[0] = m
    out[1] = -1
    out[2] = n
    out[3] = -1
    out[4] = l
    out[5] = -1
    for i in range(max(region[0], 0), min(region[3], m)):
        for j in range(max(region[1], 0), min(region[4], n)):
            for k in range(max(region[2], 0), min(region[5], l)):
                if solid[i, j, k]:
                    out[0] = min(out[0], i)
                    out[1] = max(out[1], i)
                    out[2] = min(out[2], j)
                    out[3] = max(out[3], j)
                    out[4] = min(out[4], k)
                    out[5] = max(out[5], k)


@njit(cache=True, inline="always")
def _clear_of(boxes, row, i0, j0, k0):
    """Whether the cell of corners ``(i0, j0, k0)`` + {0, 1}^3 misses the box of solid
    points ``boxes[row]`` (`solid_box`): then no corner is solid, without reading the flags.
    (Read in place: a row view would cost a reference count per sample.)"""
    return (i0 + 1 < boxes[row, 0] or i0 > boxes[row, 1] or j0 + 1 < boxes[row, 2]
            or j0 > boxes[row, 3] or k0 + 1 < boxes[row, 4] or k0 > boxes[row, 5])


@njit(cache=True, inline="always")
def _sample_bodies(f, fx, fy, fz, modes, values, row, solid, theta, cut_velocity, boxes,
                   box_row, is_dye, want_range):
    """Trilinear sample of ``f`` at index coordinates ``(fx, fy, fz)`` with bodies:
    ``(value, low, high)``, low / high the range of the corner values used. With
    ``want_range`` (MacCormack's clamp, which needs the range only) the value may be left
    0; without it low and high are 0. A velocity component replaces solid corners by
    cut-distance ghosts (`_corner_with_bodies`); dye (``is_dye``) drops them and
    renormalises. A sample whose cell misses the box ``boxes[box_row]`` (`NO_BODIES_BOXES`:
    every sample) is the plain one, `_sample` or `_corner_range`, inlined; the rest is a
    call."""
    i0 = int(math.floor(fx))
    j0 = int(math.floor(fy))
    k0 = int(math.floor(fz))
    m, n, l = f.shape
    if _clear_of(boxes, box_row, i0, j0, k0):
        # Away from the bodies (nearly every sample): the plain sampling, sides included.
        if want_range:
            low, high = _corner_range(f, fx, fy, fz, modes, values, row)
            return 0.0, low, high
        return _sample(f, fx, fy, fz, modes, values, row), 0.0, 0.0
    if (0 <= i0 < m - 1 and 0 <= j0 < n - 1 and 0 <= k0 < l - 1
            and not _any_solid(solid, i0, j0, k0)):
        a = fx - i0
        b = fy - j0
        c = fz - k0
        low = 0.0
        high = 0.0
        if want_range:
            low = math.inf
            high = -math.inf
            for corner in range(8):
                value = f[i0 + (corner & 1), j0 + ((corner >> 1) & 1), k0 + (corner >> 2)]
                low = min(low, value)
                high = max(high, value)
        bottom = _lerp(_lerp(f[i0, j0, k0], f[i0 + 1, j0, k0], a),
                       _lerp(f[i0, j0 + 1, k0], f[i0 + 1, j0 + 1, k0], a), b)
        top = _lerp(_lerp(f[i0, j0, k0 + 1], f[i0 + 1, j0, k0 + 1], a),
                    _lerp(f[i0, j0 + 1, k0 + 1], f[i0 + 1, j0 + 1, k0 + 1], a), b)
        return _lerp(bottom, top, c), low, high
    return _sample_bodies_near(f, fx, fy, fz, modes, values, row, solid, theta, cut_velocity,
                               is_dye, want_range)


@njit(cache=True)
def _sample_bodies_near(f, fx, fy, fz, modes, values, row, solid, theta, cut_velocity, is_dye,
                        want_range):
    """`_sample_bodies` near a body or a side: corner by corner."""
    i0 = int(math.floor(fx))
    j0 = int(math.floor(fy))
    k0 = int(math.floor(fz))
    a = fx - i0
    b = fy - j0
    c = fz - k0
    m, n, l = f.shape
    low = math.inf
    high = -math.inf
    total = 0.0
    weight_sum = 0.0
    for corner in range(8):
        ii = i0 + (corner & 1)
        jj = j0 + ((corner >> 1) & 1)
        kk = k0 + (corner >> 2)
        weight = ((a if corner & 1 else 1.0 - a) * (b if (corner >> 1) & 1 else 1.0 - b)
                  * (c if corner >> 2 else 1.0 - c))
        if is_dye:
            if not _inside(ii, jj, kk, m, n, l):
                value = _field_value(f, ii, jj, kk, modes, values, row)
            elif solid[ii, jj, kk]:
                continue
            else:
                value = f[ii, jj, kk]
        else:
            value = _corner_with_bodies(f, i0, j0, k0, corner, modes, values, row, solid,
                                        theta, cut_velocity)
        total += weight * value
        weight_sum += weight
        low = min(low, value)
        high = max(high, value)
    if weight_sum < 1e-12:
        return 0.0, 0.0, 0.0
    if not want_range:
        low = 0.0
        high = 0.0
    return total / weight_sum, low, high


# -- advection ---------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _velocity_at(u, v, w, x, y, z, inv_h, modes, values, solid_u, solid_v, solid_w, theta_u,
                 theta_v, theta_w, cut_u, cut_v, cut_w, boxes):
    """Velocity [m/s] at position ``(x, y, z)`` [m] (relative to the origin); ``modes`` and
    ``values`` are (3, 6): the side ghosts of u, v and w; the body arrays as in `advect_3d`.
    (Arrays one by one: a parallel loop's body cannot hold a tuple of arrays.)"""
    su, _, _ = _sample_bodies(u, x * inv_h, y * inv_h - 0.5, z * inv_h - 0.5, modes, values, 0,
                              solid_u, theta_u, cut_u, boxes, 0, False, False)
    sv, _, _ = _sample_bodies(v, x * inv_h - 0.5, y * inv_h, z * inv_h - 0.5, modes, values, 1,
                              solid_v, theta_v, cut_v, boxes, 1, False, False)
    sw, _, _ = _sample_bodies(w, x * inv_h - 0.5, y * inv_h - 0.5, z * inv_h, modes, values, 2,
                              solid_w, theta_w, cut_w, boxes, 2, False, False)
    return su, sv, sw


@njit(cache=True, inline="always")
def _clamp(value, low, high):
    return min(max(value, low), high)


@njit(cache=True, inline="always")
def _midpoint(x, y, z, ux, uy, uz, dt, lx, ly, lz):
    """Midpoint of the back-trace from ``(x, y, z)`` with arrival velocity ``(ux, uy, uz)``
    over ``dt`` [s] (RK2), clamped into the domain."""
    return (_clamp(x - 0.5 * dt * ux, 0.0, lx), _clamp(y - 0.5 * dt * uy, 0.0, ly),
            _clamp(z - 0.5 * dt * uz, 0.0, lz))


@njit(cache=True, inline="always")
def _departure(x, y, z, um, vm, wm, dt, lx, ly, lz):
    """Departure point of the trajectory arriving at ``(x, y, z)`` after ``dt`` [s] from the
    velocity ``(um, vm, wm)`` sampled at its `_midpoint`, clamped into the domain. The
    midpoint's samples see the bodies: the trace does not leak through them either."""
    return (_clamp(x - dt * um, 0.0, lx), _clamp(y - dt * vm, 0.0, ly),
            _clamp(z - dt * wm, 0.0, lz))


@njit(cache=True, inline="always")
def _velocity_at_point(u, v, w, i, j, k, field, has_interior, boxes):
    """``(found, ux, uy, uz)``: the velocity [m/s] at point ``[i, j, k]`` of ``field``, from
    the values around it when they all lie inside the arrays and, with bodies, outside the
    solid boxes; else ``found`` is False (sample it with `_velocity_at`).

    The trilinear sample with the point's own fractions (0 or 1/2 per axis), written out:
    the field's own component is its value, the others the mean of 4 (faces) or 2 (cells)
    values, lerped in the order of `_sample`, which gives its value exactly where the
    coordinates are (h a power of 2), and to rounding otherwise. Saves 3 of an advected
    point's 7 trilinear samples."""
    if field == FIELD_U:
        if not 1 <= i <= u.shape[0] - 2 or (has_interior and not (
                _clear_of(boxes, 0, i, j, k) and _clear_of(boxes, 1, i - 1, j, k)
                and _clear_of(boxes, 2, i - 1, j, k))):
            return False, 0.0, 0.0, 0.0
        return (True, u[i, j, k],
                _lerp(_lerp(v[i - 1, j, k], v[i, j, k], 0.5),
                      _lerp(v[i - 1, j + 1, k], v[i, j + 1, k], 0.5), 0.5),
                _lerp(_lerp(w[i - 1, j, k], w[i, j, k], 0.5),
                      _lerp(w[i - 1, j, k + 1], w[i, j, k + 1], 0.5), 0.5))
    if field == FIELD_V:
        if not 1 <= j <= v.shape[1] - 2 or (has_interior and not (
                _clear_of(boxes, 0, i, j - 1, k) and _clear_of(boxes, 1, i, j, k)
                and _clear_of(boxes, 2, i, j - 1, k))):
            return False, 0.0, 0.0, 0.0
        return (True,
                _lerp(_lerp(u[i, j - 1, k], u[i + 1, j - 1, k], 0.5),
                      _lerp(u[i, j, k], u[i + 1, j, k], 0.5), 0.5),
                v[i, j, k],
                _lerp(_lerp(w[i, j - 1, k], w[i, j, k], 0.5),
                      _lerp(w[i, j - 1, k + 1], w[i, j, k + 1], 0.5), 0.5))
    if field == FIELD_W:
        if not 1 <= k <= w.shape[2] - 2 or (has_interior and not (
                _clear_of(boxes, 0, i, j, k - 1) and _clear_of(boxes, 1, i, j, k - 1)
                and _clear_of(boxes, 2, i, j, k))):
            return False, 0.0, 0.0, 0.0
        return (True,
                _lerp(_lerp(u[i, j, k - 1], u[i + 1, j, k - 1], 0.5),
                      _lerp(u[i, j, k], u[i + 1, j, k], 0.5), 0.5),
                _lerp(_lerp(v[i, j, k - 1], v[i, j + 1, k - 1], 0.5),
                      _lerp(v[i, j, k], v[i, j + 1, k], 0.5), 0.5),
                w[i, j, k])
    if has_interior and not (_clear_of(boxes, 0, i, j, k) and _clear_of(boxes, 1, i, j, k)
                             and _clear_of(boxes, 2, i, j, k)):
        return False, 0.0, 0.0, 0.0
    return (True, _lerp(u[i, j, k], u[i + 1, j, k], 0.5), _lerp(v[i, j, k], v[i, j + 1, k], 0.5),
            _lerp(w[i, j, k], w[i, j, k + 1], 0.5))


@njit(cache=True, inline="always")
def _block_clear(boxes, row, i0, i1, j0, j1, k0, k1):
    """Whether the points ``[i0, i1] x [j0, j1] x [k0, k1]`` (inclusive) miss the box of
    solid points ``boxes[row]`` (`solid_box`)."""
    return (i1 < boxes[row, 0] or i0 > boxes[row, 1] or j1 < boxes[row, 2]
            or j0 > boxes[row, 3] or k1 < boxes[row, 4] or k0 > boxes[row, 5])


@njit(cache=True, inline="always")
def _pair(f, i, j, k, di, dj, dk):
    """``f[i, j, k] + f[i + di, j + dj, k + dk]``."""
    return f[i, j, k] + f[i + di, j + dj, k + dk]


@njit(cache=True, inline="always")
def _quad(f, i, j, k, di1, dj1, dk1, di2, dj2, dk2):
    """``f`` summed over the 4 points ``[i, j, k] + {0, d1} + {0, d2}``, pairwise (exact for
    equal values, so that a uniform flow's trace stays exact)."""
    return _pair(f, i, j, k, di1, dj1, dk1) + _pair(f, i + di2, j + dj2, k + dk2, di1, dj1, dk1)


# The advective acceleration (u . grad) u at a point for `_taylor_motion`. A component at its
# own points: centred differences over 2h. At another field's point a component is the mean
# of the 2 or 4 values around it; along an axis where those values straddle the point, the
# difference of the two means over h, and along the others the difference of the means one
# point either side over 2h (all second order). The stencils reach one point either way:
# their bounds and solid boxes are checked first.


@njit(cache=True, inline="always")
def _taylor_face(f, g, q, rows, i, j, k, ea, eb, ec, inv_h, has_interior, boxes):
    """`_taylor_motion` at point ``[i, j, k]`` of the face field ``f`` normal to axis A,
    ``g`` and ``q`` the components along axes B and C; ``ea``, ``eb``, ``ec`` the unit
    index steps along A, B, C (literal at each call, so the compiler folds them) and
    ``rows`` their rows of ``boxes``. Returns the velocity and acceleration along (A, B, C).
    """
    ai, aj, ak = ea
    bi, bj, bk = eb
    ci, cj, ck = ec
    if not (1 <= i <= f.shape[0] - 2 and 1 <= j <= f.shape[1] - 2
            and 1 <= k <= f.shape[2] - 2):
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    if has_interior and not (
            _block_clear(boxes, rows[0], i - 1, i + 1, j - 1, j + 1, k - 1, k + 1)
            and _block_clear(boxes, rows[1], i - ai - ci, i + bi + ci, j - aj - cj,
                             j + bj + cj, k - ak - ck, k + bk + ck)
            and _block_clear(boxes, rows[2], i - ai - bi, i + bi + ci, j - aj - bj,
                             j + bj + cj, k - ak - bk, k + bk + ck)):
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    half = 0.5 * inv_h
    eighth = 0.125 * inv_h
    # g's and q's cells around the point start one point back along A.
    gi, gj, gk = i - ai, j - aj, k - ak
    va = f[i, j, k]
    vb = 0.25 * _quad(g, gi, gj, gk, ai, aj, ak, bi, bj, bk)
    vc = 0.25 * _quad(q, gi, gj, gk, ai, aj, ak, ci, cj, ck)
    acc_a = (va * (f[i + ai, j + aj, k + ak] - f[i - ai, j - aj, k - ak])
             + vb * (f[i + bi, j + bj, k + bk] - f[i - bi, j - bj, k - bk])
             + vc * (f[i + ci, j + cj, k + ck] - f[i - ci, j - cj, k - ck])) * half
    acc_b = ((va * (_pair(g, i, j, k, bi, bj, bk) - _pair(g, gi, gj, gk, bi, bj, bk))
              + vb * (_pair(g, gi + bi, gj + bj, gk + bk, ai, aj, ak)
                      - _pair(g, gi, gj, gk, ai, aj, ak))) * half
             + vc * (_quad(g, gi + ci, gj + cj, gk + ck, ai, aj, ak, bi, bj, bk)
                     - _quad(g, gi - ci, gj - cj, gk - ck, ai, aj, ak, bi, bj, bk)) * eighth)
    acc_c = ((va * (_pair(q, i, j, k, ci, cj, ck) - _pair(q, gi, gj, gk, ci, cj, ck))
              + vc * (_pair(q, gi + ci, gj + cj, gk + ck, ai, aj, ak)
                      - _pair(q, gi, gj, gk, ai, aj, ak))) * half
             + vb * (_quad(q, gi + bi, gj + bj, gk + bk, ai, aj, ak, ci, cj, ck)
                     - _quad(q, gi - bi, gj - bj, gk - bk, ai, aj, ak, ci, cj, ck)) * eighth)
    return True, va, vb, vc, acc_a, acc_b, acc_c


@njit(cache=True, inline="always")
def _taylor_cells(u, v, w, i, j, k, inv_h, has_interior, boxes):
    if not (1 <= i <= u.shape[0] - 3 and 1 <= j <= v.shape[1] - 3
            and 1 <= k <= w.shape[2] - 3):
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    if has_interior and not (_block_clear(boxes, 0, i, i + 1, j - 1, j + 1, k - 1, k + 1)
                             and _block_clear(boxes, 1, i - 1, i + 1, j, j + 1, k - 1, k + 1)
                             and _block_clear(boxes, 2, i - 1, i + 1, j - 1, j + 1, k, k + 1)):
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    quarter = 0.25 * inv_h
    ux = 0.5 * _pair(u, i, j, k, 1, 0, 0)
    uy = 0.5 * _pair(v, i, j, k, 0, 1, 0)
    uz = 0.5 * _pair(w, i, j, k, 0, 0, 1)
    ax = ux * (u[i + 1, j, k] - u[i, j, k]) * inv_h + (
        uy * (_pair(u, i, j + 1, k, 1, 0, 0) - _pair(u, i, j - 1, k, 1, 0, 0))
        + uz * (_pair(u, i, j, k + 1, 1, 0, 0) - _pair(u, i, j, k - 1, 1, 0, 0))) * quarter
    ay = uy * (v[i, j + 1, k] - v[i, j, k]) * inv_h + (
        ux * (_pair(v, i + 1, j, k, 0, 1, 0) - _pair(v, i - 1, j, k, 0, 1, 0))
        + uz * (_pair(v, i, j, k + 1, 0, 1, 0) - _pair(v, i, j, k - 1, 0, 1, 0))) * quarter
    az = uz * (w[i, j, k + 1] - w[i, j, k]) * inv_h + (
        ux * (_pair(w, i + 1, j, k, 0, 0, 1) - _pair(w, i - 1, j, k, 0, 0, 1))
        + uy * (_pair(w, i, j + 1, k, 0, 0, 1) - _pair(w, i, j - 1, k, 0, 0, 1))) * quarter
    return True, ux, uy, uz, ax, ay, az


@njit(cache=True, inline="always")
def _taylor_motion(u, v, w, i, j, k, field, inv_h, has_interior, boxes):
    """``(found, ux, uy, uz, ax, ay, az)``: the velocity [m/s] at point ``[i, j, k]`` of
    ``field`` and its advective acceleration ``(u . grad) u`` [m/s^2] there, by centred
    differences over the point's neighbours; ``found`` is False where they do not all lie
    inside the arrays and, with bodies, outside the solid boxes (then trace by samples)."""
    x_step = (1, 0, 0)
    y_step = (0, 1, 0)
    z_step = (0, 0, 1)
    if field == FIELD_U:
        return _taylor_face(u, v, w, (0, 1, 2), i, j, k, x_step, y_step, z_step, inv_h,
                            has_interior, boxes)
    if field == FIELD_V:
        found, vy, vx, vz, ay, ax, az = _taylor_face(v, u, w, (1, 0, 2), i, j, k, y_step,
                                                     x_step, z_step, inv_h, has_interior,
                                                     boxes)
        return found, vx, vy, vz, ax, ay, az
    if field == FIELD_W:
        found, vz, vx, vy, az, ax, ay = _taylor_face(w, u, v, (2, 0, 1), i, j, k, z_step,
                                                     x_step, y_step, inv_h, has_interior,
                                                     boxes)
        return found, vx, vy, vz, ax, ay, az
    return _taylor_cells(u, v, w, i, j, k, inv_h, has_interior, boxes)


def _make_advect(loop):
    def kernel(velocity, source, out, correction, field, dt, h, ghosts, has_interior, bodies,
               own, pass_kind):
        u, v, w = velocity
        forward, backward = correction
        offset_x = 0.0 if field == FIELD_U else 0.5
        offset_y = 0.0 if field == FIELD_V else 0.5
        offset_z = 0.0 if field == FIELD_W else 0.5
        is_dye = field == FIELD_CELLS
        velocity_modes, velocity_values, modes, values = ghosts
        solid, theta, cut_velocity, body_value = own
        # Unpacked here: a parallel loop's body cannot hold a tuple of arrays.
        solid_u, solid_v, solid_w = bodies[0]
        theta_u, theta_v, theta_w = bodies[1]
        cut_u, cut_v, cut_w = bodies[2]
        boxes = bodies[3]
        correct = pass_kind == PASS_CORRECT
        m, n, l = out.shape
        inv_h = 1.0 / h
        reach = 0.5 * abs(dt)
        lx = (u.shape[0] - 1) * h
        ly = (v.shape[1] - 1) * h
        lz = (w.shape[2] - 1) * h
        for i in loop(m):
            # A line of points goes through the trace in three passes (the departure point
            # from the point's neighbours, or else the midpoint; the midpoints' sampled
            # velocity and departure points; the sample), the points' positions kept in
            # these buffers between them. Within a pass the points are independent, so the
            # processor overlaps their work; one point's chain of dependent samples at a
            # time left it waiting (about 15 % of the time).
            xs = np.empty(l)
            ys = np.empty(l)
            zs = np.empty(l)
            traced = np.empty(l, dtype=np.bool_)
            x = (i + offset_x) * h
            for j in range(n):
                y = (j + offset_y) * h
                for k in range(l):
                    if has_interior and solid[i, j, k]:
                        continue
                    z = (k + offset_z) * h
                    # Where the midpoint lies among the point's own neighbours, its velocity
                    # is their Taylor expansion u - (dt / 2) (u . grad) u: the same second
                    # order as sampling it, without three trilinear samples (the trace took
                    # two thirds of the advection's time).
                    taylor, ux, uy, uz, ax, ay, az = _taylor_motion(u, v, w, i, j, k, field,
                                                                    inv_h, has_interior,
                                                                    boxes)
                    traced[k] = taylor and max(abs(ux), abs(uy), abs(uz)) * reach <= h
                    if traced[k]:
                        xs[k], ys[k], zs[k] = _departure(x, y, z, ux - 0.5 * dt * ax,
                                                         uy - 0.5 * dt * ay,
                                                         uz - 0.5 * dt * az, dt, lx, ly, lz)
                        continue
                    found, ux, uy, uz = _velocity_at_point(u, v, w, i, j, k, field,
                                                           has_interior, boxes)
                    if not found:
                        ux, uy, uz = _velocity_at(u, v, w, x, y, z, inv_h, velocity_modes,
                                                  velocity_values, solid_u, solid_v, solid_w,
                                                  theta_u, theta_v, theta_w, cut_u, cut_v,
                                                  cut_w, boxes)
                    xs[k], ys[k], zs[k] = _midpoint(x, y, z, ux, uy, uz, dt, lx, ly, lz)
                for k in range(l):
                    if (has_interior and solid[i, j, k]) or traced[k]:
                        continue
                    um, vm, wm = _velocity_at(u, v, w, xs[k], ys[k], zs[k], inv_h,
                                              velocity_modes, velocity_values, solid_u,
                                              solid_v, solid_w, theta_u, theta_v, theta_w,
                                              cut_u, cut_v, cut_w, boxes)
                    z = (k + offset_z) * h
                    xs[k], ys[k], zs[k] = _departure(x, y, z, um, vm, wm, dt, lx, ly, lz)
                for k in range(l):
                    if has_interior and solid[i, j, k]:
                        out[i, j, k] = 0.0 if is_dye else body_value[i, j, k]
                        continue
                    # The departure point is traced again by the correcting pass rather than
                    # stored: a trace costs less than writing and reading three more arrays
                    # of this size.
                    value, low, high = _sample_bodies(
                        source, xs[k] * inv_h - offset_x, ys[k] * inv_h - offset_y,
                        zs[k] * inv_h - offset_z, modes, values, 0, solid, theta,
                        cut_velocity, boxes, field, is_dye, correct)
                    if correct:
                        corrected = (forward[i, j, k]
                                     + 0.5 * (source[i, j, k] - backward[i, j, k]))
                        out[i, j, k] = _clamp(corrected, low, high)
                    else:
                        out[i, j, k] = value
    return kernel


_advect_serial, _advect_parallel = serial_and_parallel(_make_advect)


@njit(cache=True)
def advect_3d(velocity, source, out, correction, field, dt, h, ghosts, has_interior, bodies,
              own, pass_kind):
    """Semi-Lagrangian transport of ``source`` by ``velocity`` = (u, v, w) over ``dt`` [s]
    into ``out``, with or without bodies inside.

    The departure point is the midpoint (RK2) back-trace ``x - dt u(x - dt u / 2)``. The
    midpoint's velocity is ``u - (dt / 2) (u . grad) u`` from centred differences over the
    point's neighbours (`_taylor_motion`) where the midpoint lies within a cell of the point
    and the neighbours within the arrays and clear of the solid boxes; elsewhere it is
    sampled, seeing the bodies. Both are exact for a linear velocity field.

    Args:
        source, out: The transported field before and after, of the same shape.
        correction: ``(forward, backward)``: with ``pass_kind`` `PASS_CORRECT`, this step's
            semi-Lagrangian result and its advection by ``-dt``; ``out`` is then MacCormack's
            ``forward + (source - backward) / 2``, clamped to the range of the eight values
            of ``source`` around the departure point (Selle et al. 2008: no new extrema).
            Not read with `PASS_TRACE` (the plain sample).
        field: Which field is transported: `FIELD_U`, `FIELD_V`, `FIELD_W` or `FIELD_CELLS`
            (dye). Its point ``[i, j, k]`` sits at ``((i + ox) h, (j + oy) h, (k + oz) h)``
            (u (0, .5, .5), v (.5, 0, .5), w (.5, .5, 0), cells (.5, .5, .5)), and its row of
            ``bodies``' boxes is ``field``.
        dt: The time step [s]; a negative one traces forwards (MacCormack's backward pass).
        h: Grid spacing [m].
        ghosts: ``(velocity_modes, velocity_values, modes, values)``: the side ghosts (3, 6)
            of u, v, w and (1, 6) of ``source``.
        has_interior: Whether ``own``'s solid flags are read (points inside a body take
            ``body_value``, dye 0).
        bodies: ``(solid_faces, cut_theta, cut_velocity, boxes)``: per velocity component
            the solid flags, cut fractions and cut velocities (tuples of three), and the
            `solid_box` (4, 6) int64 of u, v, w and the cells. A sample whose cell misses
            its field's box reads no body array: without bodies `NO_BODIES_BOXES` and
            stand-ins.
        own: ``(solid, theta, cut_velocity, body_value)`` of the transported field; a
            velocity component's samples replace solid corners by cut-distance ghosts, dye
            is averaged over its fluid corners only.
        pass_kind: `PASS_TRACE` or `PASS_CORRECT`.
    """
    if out.size > PARALLEL_MINIMUM_3D:
        return _advect_parallel(velocity, source, out, correction, field, dt, h, ghosts,
                                has_interior, bodies, own, pass_kind)
    return _advect_serial(velocity, source, out, correction, field, dt, h, ghosts,
                          has_interior, bodies, own, pass_kind)


# -- viscosity ---------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _is_fixed(index, size, fixed_low, fixed_high):
    return (index == 0 and fixed_low) or (index == size - 1 and fixed_high)


@njit(cache=True, inline="always")
def _wall_sum(i, j, k, m, n, l, axis, modes, values):
    """Sum of the wall velocities (mirror ghosts) of the sides along the other axes that the
    point ``[i, j, k]`` touches."""
    total = 0.0
    for along in range(3):
        if along == axis:
            continue
        index = i if along == 0 else (j if along == 1 else k)
        size = m if along == 0 else (n if along == 1 else l)
        if index == 0 and modes[2 * along] == GHOST_DIRICHLET:
            total += values[2 * along]
        if index == size - 1 and modes[2 * along + 1] == GHOST_DIRICHLET:
            total += values[2 * along + 1]
    return total


@njit(cache=True, inline="always")
def _known_operator_rhs(f, c, axis, fixed_low, fixed_high, modes, values, i, j, k):
    """The right-hand side at ``[i, j, k]`` without bodies, in closed form: ``f`` plus ``c``
    times the held boundary faces next to it plus ``2c`` times the velocity of the moving
    walls next to it."""
    m, n, l = f.shape
    size = f.shape[axis]
    own = i if axis == 0 else (j if axis == 1 else k)
    value = f[i, j, k]
    if not _is_fixed(own, size, fixed_low, fixed_high):
        value += 2.0 * c * _wall_sum(i, j, k, m, n, l, axis, modes, values)
        if own == 1 and fixed_low:
            value += c * (f[i - 1, j, k] if axis == 0 else (
                f[i, j - 1, k] if axis == 1 else f[i, j, k - 1]))
        if own == size - 2 and fixed_high:
            value += c * (f[i + 1, j, k] if axis == 0 else (
                f[i, j + 1, k] if axis == 1 else f[i, j, k + 1]))
    return value


def _make_viscosity(loop):
    def kernel(f, c, axis, sides, has_interior, body, assemble_operator, operator, rhs,
               region):
        fixed_low, fixed_high, tangential_modes, tangential_values = sides
        solid, theta, cut_velocity = body
        diagonal, weights_x, weights_y, weights_z = operator
        i0, j0, k0, i1, j1, k1 = region[0], region[1], region[2], region[3], region[4], region[5]
        m, n, l = f.shape
        size = f.shape[axis]
        for i in loop(m):
            for j in range(n):
                # The line's points [plain_from, plain_to) touch no side and no held face:
                # their right-hand side is the value itself and, outside the region, the
                # operator is already in place (nearly every point). Found once a line, not
                # tested point by point.
                plain_from, plain_to = l, l
                if (0 < i < m - 1 and 0 < j < n - 1 and (axis != 0 or 1 < i < size - 2)
                        and (axis != 1 or 1 < j < size - 2)):
                    plain_from = 2 if axis == 2 else 1
                    plain_to = max(l - 2 if axis == 2 else l - 1, plain_from)
                region_from, region_to = plain_to, plain_to
                if assemble_operator and i0 <= i < i1 and j0 <= j < j1:
                    region_from = min(max(k0, plain_from), plain_to)
                    region_to = min(max(k1, region_from), plain_to)
                for k in range(l):
                    if plain_from <= k < region_from or region_to <= k < plain_to:
                        rhs[i, j, k] = f[i, j, k]
                        continue
                    if not (assemble_operator and i0 <= i < i1 and j0 <= j < j1
                            and k0 <= k < k1):
                        # Next to a side, outside the region: the operator is in place (or
                        # not asked for) and no body is near, so the right-hand side is the
                        # sides' closed form.
                        rhs[i, j, k] = _known_operator_rhs(
                            f, c, axis, fixed_low, fixed_high, tangential_modes,
                            tangential_values, i, j, k)
                        continue
                    own = i if axis == 0 else (j if axis == 1 else k)
                    if i + 1 < m:
                        weights_x[i, j, k] = 0.0
                    if j + 1 < n:
                        weights_y[i, j, k] = 0.0
                    if k + 1 < l:
                        weights_z[i, j, k] = 0.0
                    rhs[i, j, k] = f[i, j, k]
                    if _is_fixed(own, size, fixed_low, fixed_high) or (
                            has_interior and solid[i, j, k]):
                        # Held: a side face, or a point inside a body (its body velocity).
                        diagonal[i, j, k] = 1.0
                        continue
                    d = 1.0
                    r = f[i, j, k]
                    for direction in range(6):
                        along = direction >> 1
                        # int64 throughout: prange's index may be unsigned, and unsigned plus
                        # signed would make the neighbour's index a float.
                        step = np.int64(1) if direction & 1 else np.int64(-1)
                        ni = np.int64(i) + step if along == 0 else np.int64(i)
                        nj = np.int64(j) + step if along == 1 else np.int64(j)
                        nk = np.int64(k) + step if along == 2 else np.int64(k)
                        if ni < 0 or ni >= m or nj < 0 or nj >= n or nk < 0 or nk >= l:
                            # Beyond a side along another axis: a wall's mirror ghost
                            # (2 v_wall - inside) adds 2c and 2c v_wall; a zero-gradient
                            # ghost adds nothing.
                            if along != axis and tangential_modes[direction] == GHOST_DIRICHLET:
                                d += 2.0 * c
                                r += 2.0 * c * tangential_values[direction]
                            continue
                        if has_interior and theta[direction, i, j, k] <= 1.0:
                            # A body boundary at t h (METHOD.md §6, Gibou et al. 2002): the
                            # ghost enters the diagonal and right-hand side only.
                            t = max(theta[direction, i, j, k], THETA_MIN)
                            d += c / t
                            r += c * cut_velocity[direction, i, j, k] / t
                            continue
                        neighbour = ni if axis == 0 else (nj if axis == 1 else nk)
                        if (along == axis and _is_fixed(neighbour, size, fixed_low, fixed_high)
                                ) or (has_interior and solid[ni, nj, nk]):
                            # A held neighbour (boundary face or inside a body): its value
                            # moves to the right-hand side, which keeps the matrix symmetric.
                            d += c
                            r += c * f[ni, nj, nk]
                            continue
                        if has_interior and theta[direction ^ 1, ni, nj, nk] <= 1.0:
                            # Only the neighbour sees a cut: no coupling keeps the matrix
                            # symmetric.
                            continue
                        if step == 1:
                            if along == 0:
                                weights_x[i, j, k] = c
                            elif along == 1:
                                weights_y[i, j, k] = c
                            else:
                                weights_z[i, j, k] = c
                    diagonal[i, j, k] = d
                    rhs[i, j, k] = r
    return kernel


_viscosity_serial, _viscosity_parallel = serial_and_parallel(_make_viscosity)


# `build_viscosity_system_3d`'s region when the whole operator is assembled.
WHOLE_REGION = np.array([0, 0, 0, 2**62, 2**62, 2**62], dtype=np.int64)


@njit(cache=True)
def build_viscosity_system_3d(f, c, axis, sides, has_interior, body, assemble_operator,
                              operator, rhs, region):
    """Assemble ``(I - nu dt lap) f = f*`` for one velocity component as a 7-point operator.

    Args:
        f: The component after advection, shape (m, n, l); holds the boundary values.
        c: ``nu dt / h^2``.
        axis: The component's own axis (0 u, 1 v, 2 w).
        sides: ``(fixed_low, fixed_high, tangential_modes, tangential_values)``: whether the
            first and last planes along ``axis`` (the boundary faces normal to it) are held
            (Dirichlet); (6,) ghost modes per side (`GHOST_COPY` or `GHOST_DIRICHLET`), read
            on the four sides along the other axes, and (6,) the walls' velocity component
            there (0 unless a wall moves).
        has_interior: Whether ``body`` = ``(solid, theta, cut_velocity)`` (the component's
            solid flags, cut fractions and cut velocities) is read: points inside a body are
            held at their value (the body velocity); a neighbour across a body boundary at
            ``t h`` is replaced by the no-slip ghost, which adds ``c / t`` to the diagonal
            and ``c u_b / t`` to the right-hand side; a connection is dropped when either end
            sees a cut, so that the operator stays symmetric.
        assemble_operator: False writes only ``rhs``, for an operator known unchanged
            (without bodies only; ``operator`` is not read).
        operator: ``(diagonal, weights_x, weights_y, weights_z)``: outputs.
        rhs: Output.
        region: ``(i0, j0, k0, i1, j1, k1)`` int64 (ends exclusive): with
            ``assemble_operator``, the operator is written only inside this box (the
            right-hand side everywhere): the caller's ``operator`` already holds the right
            values elsewhere (the same ``c`` and sides, and no body there, so that the
            right-hand side there takes the sides' terms only); `WHOLE_REGION`: everywhere.
    """
    if f.size > PARALLEL_MINIMUM_3D:
        return _viscosity_parallel(f, c, axis, sides, has_interior, body, assemble_operator,
                                   operator, rhs, region)
    return _viscosity_serial(f, c, axis, sides, has_interior, body, assemble_operator,
                             operator, rhs, region)


# -- pressure ----------------------------------------------------------------------------------


def _make_pressure_operator(loop):
    def kernel(open_fractions, outflow, operator):
        open_x, open_y, open_z = open_fractions
        diagonal, weights_x, weights_y, weights_z = operator
        nx, ny, nz = diagonal.shape
        for i in loop(nx):
            for j in range(ny):
                for k in range(nz):
                    d = 0.0
                    if i == 0 and outflow[SIDE_LEFT]:
                        d += 2.0 * _open(open_x[0, j, k])
                    if i == nx - 1 and outflow[SIDE_RIGHT]:
                        d += 2.0 * _open(open_x[nx, j, k])
                    if j == 0 and outflow[SIDE_BOTTOM]:
                        d += 2.0 * _open(open_y[i, 0, k])
                    if j == ny - 1 and outflow[SIDE_TOP]:
                        d += 2.0 * _open(open_y[i, ny, k])
                    if k == 0 and outflow[SIDE_BACK]:
                        d += 2.0 * _open(open_z[i, j, 0])
                    if k == nz - 1 and outflow[SIDE_FRONT]:
                        d += 2.0 * _open(open_z[i, j, nz])
                    diagonal[i, j, k] = d
                    if i + 1 < nx:
                        weights_x[i, j, k] = _open(open_x[i + 1, j, k])
                    if j + 1 < ny:
                        weights_y[i, j, k] = _open(open_y[i, j + 1, k])
                    if k + 1 < nz:
                        weights_z[i, j, k] = _open(open_z[i, j, k + 1])
    return kernel


_pressure_operator_serial, _pressure_operator_parallel = serial_and_parallel(
    _make_pressure_operator)


@njit(cache=True)
def build_pressure_operator_3d(open_fractions, outflow, operator):
    """``A p = -h^2 div(A grad p)`` on the cells into ``operator`` = ``(diagonal, weights_x,
    weights_y, weights_z)``: face weights are the open fractions ``open_fractions`` = (x, y,
    z) (0 below `OPEN_MIN`; all 1 without bodies), an outflow side (``outflow`` (6,) bool)
    adds ``2 A`` to the diagonal (p = 0 halfway to the ghost). Weights in [0, 1]: the
    operator stays symmetric positive semi-definite; a cell with all faces closed is
    inactive."""
    if operator[0].size > PARALLEL_MINIMUM_3D:
        return _pressure_operator_parallel(open_fractions, outflow, operator)
    return _pressure_operator_serial(open_fractions, outflow, operator)


@njit(cache=True)
def _nearest_solid_value(solid, body_velocity, i, j, k):
    """``body_velocity`` at the nearest solid point among the 26 neighbours of ``(i, j, k)``
    (0 when none is solid)."""
    m, n, l = solid.shape
    best = 4
    value = 0.0
    for di in range(-1, 2):
        for dj in range(-1, 2):
            for dk in range(-1, 2):
                a, b, c = i + di, j + dj, k + dk
                distance = di * di + dj * dj + dk * dk
                if (0 < distance < best and 0 <= a < m and 0 <= b < n and 0 <= c < l
                        and solid[a, b, c]):
                    best = distance
                    value = body_velocity[a, b, c]
    return value


def _make_face_solid_velocity(loop):
    def kernel(solid, body_velocity, open_fraction, theta, cut_velocity, axis, out):
        m, n, l = solid.shape
        for i in loop(m):
            for j in range(n):
                for k in range(l):
                    fraction = open_fraction[i, j, k]
                    if solid[i, j, k] or fraction == 0.0:
                        out[i, j, k] = body_velocity[i, j, k]
                    elif fraction < 1.0:
                        # The nearest crossing, first in the face's plane, then along its
                        # normal, within one spacing.
                        best = math.inf
                        value = 0.0
                        for direction in range(6):
                            if direction >> 1 == axis:
                                continue
                            t = theta[direction, i, j, k]
                            if t <= 1.0 and t < best:
                                best = t
                                value = cut_velocity[direction, i, j, k]
                        if best == math.inf:
                            for direction in range(2 * axis, 2 * axis + 2):
                                t = theta[direction, i, j, k]
                                if t <= 1.0 and t < best:
                                    best = t
                                    value = cut_velocity[direction, i, j, k]
                        if best == math.inf:
                            value = _nearest_solid_value(solid, body_velocity, i, j, k)
                        out[i, j, k] = value
                    else:
                        out[i, j, k] = 0.0
    return kernel


_face_solid_velocity_serial, _face_solid_velocity_parallel = serial_and_parallel(
    _make_face_solid_velocity)


@njit(cache=True)
def face_solid_velocity_3d(solid, body_velocity, open_fraction, theta, cut_velocity, axis,
                           out):
    """Body velocity component ``u_s`` at every face that is not fully open, 0 elsewhere.

    Points inside a body and faces closed all along take ``body_velocity``; partly open
    faces with their point in fluid take the velocity at the nearest crossing in the face's
    plane within one spacing, else along its normal; else (a body clipping a corner of the
    face square, seen by no line through the point: a sliver, 0.4 % of the face at most on a
    sphere of radius 3.3 h) the body velocity at the nearest solid neighbour point (0 when
    none). Geometry only: the same u_s before and after a projection."""
    if solid.size > PARALLEL_MINIMUM_3D:
        return _face_solid_velocity_parallel(solid, body_velocity, open_fraction, theta,
                                             cut_velocity, axis, out)
    return _face_solid_velocity_serial(solid, body_velocity, open_fraction, theta,
                                       cut_velocity, axis, out)


def _make_pressure_rhs(loop):
    def kernel(velocity, scale, has_interior, open_fractions, solid_velocity, rhs):
        u, v, w = velocity
        open_x, open_y, open_z = open_fractions
        solid_u, solid_v, solid_w = solid_velocity
        nx, ny, nz = rhs.shape
        for i in loop(nx):
            for j in range(ny):
                for k in range(nz):
                    if has_interior:
                        a_e = _open(open_x[i + 1, j, k])
                        a_w = _open(open_x[i, j, k])
                        a_n = _open(open_y[i, j + 1, k])
                        a_s = _open(open_y[i, j, k])
                        a_f = _open(open_z[i, j, k + 1])
                        a_b = _open(open_z[i, j, k])
                        flux = (a_e * u[i + 1, j, k] + (1.0 - a_e) * solid_u[i + 1, j, k]
                                - a_w * u[i, j, k] - (1.0 - a_w) * solid_u[i, j, k]
                                + a_n * v[i, j + 1, k] + (1.0 - a_n) * solid_v[i, j + 1, k]
                                - a_s * v[i, j, k] - (1.0 - a_s) * solid_v[i, j, k]
                                + a_f * w[i, j, k + 1] + (1.0 - a_f) * solid_w[i, j, k + 1]
                                - a_b * w[i, j, k] - (1.0 - a_b) * solid_w[i, j, k])
                    else:
                        flux = (u[i + 1, j, k] - u[i, j, k] + v[i, j + 1, k] - v[i, j, k]
                                + w[i, j, k + 1] - w[i, j, k])
                    rhs[i, j, k] = -scale * flux
    return kernel


_pressure_rhs_serial, _pressure_rhs_parallel = serial_and_parallel(_make_pressure_rhs)


@njit(cache=True)
def pressure_rhs_3d(velocity, scale, has_interior, open_fractions, solid_velocity, rhs):
    """``rhs = -scale * h div u`` per cell (``h div u``: the sum of the six signed face
    fluxes of ``velocity`` = (u, v, w), per unit area), with ``has_interior`` of
    ``A u + (1 - A) u_s`` (``open_fractions`` A and ``solid_velocity`` u_s, tuples of three;
    Batty et al. 2007). ``scale = rho h / dt`` gives the pressure equation's right-hand side
    ``-(rho h^2 / dt) div u``; ``scale = -1 / h`` the divergence [1/s]."""
    if rhs.size > PARALLEL_MINIMUM_3D:
        return _pressure_rhs_parallel(velocity, scale, has_interior, open_fractions,
                                      solid_velocity, rhs)
    return _pressure_rhs_serial(velocity, scale, has_interior, open_fractions, solid_velocity,
                                rhs)


def _make_subtract_gradient(loop):
    def kernel(velocity, p, scale, outflow, has_interior, open_fractions, solid_velocity):
        u, v, w = velocity
        open_x, open_y, open_z = open_fractions
        solid_u, solid_v, solid_w = solid_velocity
        nx, ny, nz = p.shape
        # One loop per component; the side faces see the outflow ghost -p (p = 0 on the
        # side), or keep their velocity on walls and inflow sides.
        for i in loop(nx + 1):
            if (i == 0 and not outflow[SIDE_LEFT]) or (i == nx and not outflow[SIDE_RIGHT]):
                continue
            for j in range(ny):
                for k in range(nz):
                    if has_interior and _open(open_x[i, j, k]) == 0.0:
                        u[i, j, k] = solid_u[i, j, k]
                        continue
                    if i == 0:
                        gradient = 2.0 * p[0, j, k]
                    elif i == nx:
                        gradient = -2.0 * p[nx - 1, j, k]
                    else:
                        gradient = p[i, j, k] - p[i - 1, j, k]
                    u[i, j, k] -= scale * gradient
        for i in loop(nx):
            for j in range(ny + 1):
                if (j == 0 and not outflow[SIDE_BOTTOM]) or (j == ny and not outflow[SIDE_TOP]):
                    continue
                for k in range(nz):
                    if has_interior and _open(open_y[i, j, k]) == 0.0:
                        v[i, j, k] = solid_v[i, j, k]
                        continue
                    if j == 0:
                        gradient = 2.0 * p[i, 0, k]
                    elif j == ny:
                        gradient = -2.0 * p[i, ny - 1, k]
                    else:
                        gradient = p[i, j, k] - p[i, j - 1, k]
                    v[i, j, k] -= scale * gradient
        for i in loop(nx):
            for j in range(ny):
                for k in range(nz + 1):
                    if (k == 0 and not outflow[SIDE_BACK]) or (
                            k == nz and not outflow[SIDE_FRONT]):
                        continue
                    if has_interior and _open(open_z[i, j, k]) == 0.0:
                        w[i, j, k] = solid_w[i, j, k]
                        continue
                    if k == 0:
                        gradient = 2.0 * p[i, j, 0]
                    elif k == nz:
                        gradient = -2.0 * p[i, j, nz - 1]
                    else:
                        gradient = p[i, j, k] - p[i, j, k - 1]
                    w[i, j, k] -= scale * gradient
    return kernel


_subtract_gradient_serial, _subtract_gradient_parallel = serial_and_parallel(
    _make_subtract_gradient)


@njit(cache=True)
def subtract_pressure_gradient_3d(velocity, p, scale, outflow, has_interior, open_fractions,
                                  solid_velocity):
    """``u -= scale * (p[i] - p[i-1])`` on every face of ``velocity`` = (u, v, w) (likewise
    v, w), ``scale = dt / (rho h)``; wall and inflow sides keep their normal velocity,
    outflow sides see the ghost ``-p`` (p = 0 on the side). With ``has_interior``, faces
    whose ``open_fractions`` is 0 (below `OPEN_MIN`) take ``solid_velocity`` u_s instead
    (tuples of three)."""
    if p.size > PARALLEL_MINIMUM_3D:
        return _subtract_gradient_parallel(velocity, p, scale, outflow, has_interior,
                                           open_fractions, solid_velocity)
    return _subtract_gradient_serial(velocity, p, scale, outflow, has_interior, open_fractions,
                                     solid_velocity)


# -- forces and copies -------------------------------------------------------------------------


def _make_copy(loop):
    def kernel(source, target):
        m, n, l = source.shape
        for i in loop(m):
            for j in range(n):
                for k in range(l):
                    target[i, j, k] = source[i, j, k]
    return kernel


_copy_serial, _copy_parallel = serial_and_parallel(_make_copy)


@njit(cache=True)
def copy_into_3d(source, target):
    """``target[...] = source`` (threaded on large arrays)."""
    if source.size > PARALLEL_MINIMUM_3D:
        return _copy_parallel(source, target)
    return _copy_serial(source, target)


def _make_update(loop):
    def kernel(source, target):
        m, n, l = source.shape
        changed = 0
        for i in loop(m):
            plane = 0
            for j in range(n):
                for k in range(l):
                    value = source[i, j, k]
                    if target[i, j, k] != value:
                        plane += 1
                        target[i, j, k] = value
            changed += plane
        return changed
    return kernel


_update_serial, _update_parallel = serial_and_parallel(_make_update)


@njit(cache=True)
def update_into_3d(source, target):
    """``target[...] = source``; returns how many values differed before (one pass, where
    a comparison and then a copy take three)."""
    if source.size > PARALLEL_MINIMUM_3D:
        return _update_parallel(source, target)
    return _update_serial(source, target)


def _make_add(loop):
    def kernel(target, value):
        m, n, l = target.shape
        for i in loop(m):
            for j in range(n):
                for k in range(l):
                    target[i, j, k] += value
    return kernel


_add_serial, _add_parallel = serial_and_parallel(_make_add)


@njit(cache=True)
def add_constant_3d(target, value):
    """``target += value`` (a uniform acceleration times dt)."""
    if target.size > PARALLEL_MINIMUM_3D:
        return _add_parallel(target, value)
    return _add_serial(target, value)


def _make_buoyancy(loop):
    def kernel(v, dye, scale):
        nx, ny, nz = dye.shape
        for i in loop(nx):
            for j in range(1, ny):
                for k in range(nz):
                    v[i, j, k] += scale * 0.5 * (dye[i, j - 1, k] + dye[i, j, k])
    return kernel


_buoyancy_serial, _buoyancy_parallel = serial_and_parallel(_make_buoyancy)


@njit(cache=True)
def add_buoyancy_3d(v, dye, scale):
    """``v += scale * dye`` on the interior y-faces (dye averaged from the two cells), with
    ``scale = dt * buoyancy``: dye buoyancy upwards, along +y."""
    if dye.size > PARALLEL_MINIMUM_3D:
        return _buoyancy_parallel(v, dye, scale)
    return _buoyancy_serial(v, dye, scale)
