"""Numba kernels of the 3D fluid on the MAC grid: advection (trilinear sampling with side
ghosts), the implicit viscosity system, the pressure equation and the projection.

Arrays are ``[i, j, k]`` (`elastoflow.grid.Grid3D`): u (nx+1, ny, nz), v (nx, ny+1, nz),
w (nx, ny, nz+1), cell fields (nx, ny, nz). Sides are numbered by `SIDE_*` (low then high
along x, y, z), and per-side arrays of length 6 follow that order. Kernels take plain arrays
and scalars only.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from elastoflow._numba import serial_and_parallel

# Side numbers: index = 2 * axis + (0 at the low end, 1 at the high end).
SIDE_LEFT, SIDE_RIGHT, SIDE_BOTTOM, SIDE_TOP, SIDE_BACK, SIDE_FRONT = range(6)

# How a sample beyond a side is made from the value just inside (``value`` is the side's):
GHOST_COPY = 0       # zero normal gradient (free slip, outflow)
GHOST_DIRICHLET = 1  # the mirror ``2 value - inside``: ``value`` holds halfway (no slip)
GHOST_VALUE = 2      # ``value`` itself (inflow dye)

# Below this many points a parallel region costs more than it saves.
PARALLEL_MINIMUM_3D = 16 * 16 * 16


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


@njit(cache=True, inline="always")
def _velocity_at(u, v, w, x, y, z, inv_h, modes, values):
    """Velocity [m/s] at position ``(x, y, z)`` [m] (relative to the origin); ``modes`` and
    ``values`` are (3, 6): the side ghosts of u, v and w."""
    return (
        _sample(u, x * inv_h, y * inv_h - 0.5, z * inv_h - 0.5, modes, values, 0),
        _sample(v, x * inv_h - 0.5, y * inv_h, z * inv_h - 0.5, modes, values, 1),
        _sample(w, x * inv_h - 0.5, y * inv_h - 0.5, z * inv_h, modes, values, 2),
    )


@njit(cache=True, inline="always")
def _clamp(value, low, high):
    return min(max(value, low), high)


@njit(cache=True, inline="always")
def _departure(u, v, w, x, y, z, dt, inv_h, lx, ly, lz, modes, values):
    """Departure point of the trajectory arriving at ``(x, y, z)`` after ``dt`` [s]: midpoint
    (RK2) back-trace, clamped into the domain."""
    ux, uy, uz = _velocity_at(u, v, w, x, y, z, inv_h, modes, values)
    xm = _clamp(x - 0.5 * dt * ux, 0.0, lx)
    ym = _clamp(y - 0.5 * dt * uy, 0.0, ly)
    zm = _clamp(z - 0.5 * dt * uz, 0.0, lz)
    um, vm, wm = _velocity_at(u, v, w, xm, ym, zm, inv_h, modes, values)
    return (_clamp(x - dt * um, 0.0, lx), _clamp(y - dt * vm, 0.0, ly),
            _clamp(z - dt * wm, 0.0, lz))


def _make_advect(loop):
    def kernel(u, v, w, source, out, offset_x, offset_y, offset_z, dt, h, velocity_modes,
               velocity_values, modes, values):
        m, n, l = out.shape
        inv_h = 1.0 / h
        lx = (u.shape[0] - 1) * h
        ly = (v.shape[1] - 1) * h
        lz = (w.shape[2] - 1) * h
        for i in loop(m):
            for j in range(n):
                for k in range(l):
                    x, y, z = _departure(u, v, w, (i + offset_x) * h, (j + offset_y) * h,
                                         (k + offset_z) * h, dt, inv_h, lx, ly, lz,
                                         velocity_modes, velocity_values)
                    out[i, j, k] = _sample(source, x * inv_h - offset_x, y * inv_h - offset_y,
                                           z * inv_h - offset_z, modes, values, 0)
    return kernel


_advect_serial, _advect_parallel = serial_and_parallel(_make_advect)


@njit(cache=True)
def advect_kernel_3d(u, v, w, source, out, offset_x, offset_y, offset_z, dt, h,
                     velocity_modes, velocity_values, modes, values):
    """Semi-Lagrangian transport of ``source`` by (u, v, w) over ``dt`` [s] into ``out``.

    ``source`` and ``out`` have the same shape; the point ``[i, j, k]`` sits at
    ``((i + offset_x) h, (j + offset_y) h, (k + offset_z) h)`` (offsets 0 or 0.5: u
    (0, .5, .5), v (.5, 0, .5), w (.5, .5, 0), cells (.5, .5, .5)). ``modes`` / ``values``
    (1, 6) are ``source``'s side ghosts, ``velocity_modes`` / ``velocity_values`` (3, 6) those
    of u, v, w. A negative ``dt`` traces forwards (MacCormack's backward step).
    """
    if out.size > PARALLEL_MINIMUM_3D:
        return _advect_parallel(u, v, w, source, out, offset_x, offset_y, offset_z, dt, h,
                                velocity_modes, velocity_values, modes, values)
    return _advect_serial(u, v, w, source, out, offset_x, offset_y, offset_z, dt, h,
                          velocity_modes, velocity_values, modes, values)


def _make_maccormack(loop):
    def kernel(u, v, w, source, forward, backward, out, offset_x, offset_y, offset_z, dt, h,
               velocity_modes, velocity_values, modes, values):
        m, n, l = out.shape
        inv_h = 1.0 / h
        lx = (u.shape[0] - 1) * h
        ly = (v.shape[1] - 1) * h
        lz = (w.shape[2] - 1) * h
        for i in loop(m):
            for j in range(n):
                for k in range(l):
                    corrected = (forward[i, j, k]
                                 + 0.5 * (source[i, j, k] - backward[i, j, k]))
                    # The departure point is traced again rather than stored: a trace costs
                    # less than writing and reading three more arrays of this size.
                    x, y, z = _departure(u, v, w, (i + offset_x) * h, (j + offset_y) * h,
                                         (k + offset_z) * h, dt, inv_h, lx, ly, lz,
                                         velocity_modes, velocity_values)
                    low, high = _corner_range(source, x * inv_h - offset_x,
                                              y * inv_h - offset_y, z * inv_h - offset_z,
                                              modes, values, 0)
                    out[i, j, k] = _clamp(corrected, low, high)
    return kernel


_maccormack_serial, _maccormack_parallel = serial_and_parallel(_make_maccormack)


@njit(cache=True)
def maccormack_kernel_3d(u, v, w, source, forward, backward, out, offset_x, offset_y,
                         offset_z, dt, h, velocity_modes, velocity_values, modes, values):
    """MacCormack's correction ``forward + (source - backward) / 2`` of the semi-Lagrangian
    result ``forward`` by its backward advection ``backward``, clamped to the range of the
    eight values of ``source`` around the departure point (Selle et al. 2008): no new
    extrema. Arguments as `advect_kernel_3d`."""
    if out.size > PARALLEL_MINIMUM_3D:
        return _maccormack_parallel(u, v, w, source, forward, backward, out, offset_x,
                                    offset_y, offset_z, dt, h, velocity_modes,
                                    velocity_values, modes, values)
    return _maccormack_serial(u, v, w, source, forward, backward, out, offset_x, offset_y,
                              offset_z, dt, h, velocity_modes, velocity_values, modes, values)


@njit(cache=True, inline="always")
def _is_fixed(index, size, fixed_low, fixed_high):
    return (index == 0 and fixed_low) or (index == size - 1 and fixed_high)


def _make_viscosity(loop):
    def kernel(f, c, axis, fixed_low, fixed_high, tangential_modes, tangential_values,
               diagonal, weights_x,
               weights_y, weights_z, rhs):
        m, n, l = f.shape
        size = f.shape[axis]
        for i in loop(m):
            for j in range(n):
                for k in range(l):
                    own = i if axis == 0 else (j if axis == 1 else k)
                    if i + 1 < m:
                        weights_x[i, j, k] = 0.0
                    if j + 1 < n:
                        weights_y[i, j, k] = 0.0
                    if k + 1 < l:
                        weights_z[i, j, k] = 0.0
                    rhs[i, j, k] = f[i, j, k]
                    if _is_fixed(own, size, fixed_low, fixed_high):
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
                        neighbour = ni if axis == 0 else (nj if axis == 1 else nk)
                        if along == axis and _is_fixed(neighbour, size, fixed_low, fixed_high):
                            # A held boundary face: its value moves to the right-hand side,
                            # which keeps the matrix symmetric.
                            d += c
                            r += c * f[ni, nj, nk]
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


@njit(cache=True)
def build_viscosity_system_3d(f, c, axis, fixed_low, fixed_high, tangential_modes,
                              tangential_values, diagonal, weights_x, weights_y, weights_z, rhs):
    """Assemble ``(I - nu dt lap) f = f*`` for one velocity component as a 7-point operator.

    Args:
        f: The component after advection, shape (m, n, l); holds the boundary values.
        c: ``nu dt / h^2``.
        axis: The component's own axis (0 u, 1 v, 2 w); its first and last planes are the
            boundary faces normal to it, held (Dirichlet) when ``fixed_low`` / ``fixed_high``.
        tangential_modes: (6,) ghost modes per side (`GHOST_COPY` or `GHOST_DIRICHLET`), read
            on the four sides along the other axes; ``tangential_values`` (6,) the walls'
            velocity component there (0 unless a wall moves).
        diagonal, weights_x, weights_y, weights_z, rhs: Outputs (the operator's arrays).
    """
    if f.size > PARALLEL_MINIMUM_3D:
        return _viscosity_parallel(f, c, axis, fixed_low, fixed_high, tangential_modes,
                                   tangential_values, diagonal, weights_x, weights_y, weights_z,
                                   rhs)
    return _viscosity_serial(f, c, axis, fixed_low, fixed_high, tangential_modes,
                             tangential_values, diagonal, weights_x, weights_y, weights_z, rhs)


def _make_viscosity_rhs(loop):
    def kernel(f, c, axis, fixed_low, fixed_high, tangential_modes, tangential_values, rhs):
        m, n, l = f.shape
        size = f.shape[axis]
        for i in loop(m):
            for j in range(n):
                for k in range(l):
                    own = i if axis == 0 else (j if axis == 1 else k)
                    value = f[i, j, k]
                    if not _is_fixed(own, size, fixed_low, fixed_high):
                        value += 2.0 * c * _wall_sum(i, j, k, m, n, l, axis, tangential_modes,
                                                     tangential_values)
                        if own == 1 and fixed_low:
                            value += c * (f[i - 1, j, k] if axis == 0 else (
                                f[i, j - 1, k] if axis == 1 else f[i, j, k - 1]))
                        if own == size - 2 and fixed_high:
                            value += c * (f[i + 1, j, k] if axis == 0 else (
                                f[i, j + 1, k] if axis == 1 else f[i, j, k + 1]))
                    rhs[i, j, k] = value
    return kernel


_viscosity_rhs_serial, _viscosity_rhs_parallel = serial_and_parallel(_make_viscosity_rhs)


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


@njit(cache=True)
def viscosity_rhs_3d(f, c, axis, fixed_low, fixed_high, tangential_modes, tangential_values,
                     rhs):
    """Only the right-hand side of `build_viscosity_system_3d` (its operator is known
    unchanged): ``f`` plus ``c`` times the held boundary faces next to a point plus ``2c``
    times the velocity of moving walls next to it."""
    if f.size > PARALLEL_MINIMUM_3D:
        return _viscosity_rhs_parallel(f, c, axis, fixed_low, fixed_high, tangential_modes,
                                       tangential_values, rhs)
    return _viscosity_rhs_serial(f, c, axis, fixed_low, fixed_high, tangential_modes,
                                 tangential_values, rhs)


def _make_pressure_rhs(loop):
    def kernel(u, v, w, scale, rhs):
        nx, ny, nz = rhs.shape
        for i in loop(nx):
            for j in range(ny):
                for k in range(nz):
                    flux = (u[i + 1, j, k] - u[i, j, k] + v[i, j + 1, k] - v[i, j, k]
                            + w[i, j, k + 1] - w[i, j, k])
                    rhs[i, j, k] = -scale * flux
    return kernel


_pressure_rhs_serial, _pressure_rhs_parallel = serial_and_parallel(_make_pressure_rhs)


@njit(cache=True)
def pressure_rhs_3d(u, v, w, scale, rhs):
    """``rhs = -scale * (sum of the six signed face velocities)`` per cell; with
    ``scale = rho h / dt`` that is ``-(rho h^2 / dt) div u``."""
    if rhs.size > PARALLEL_MINIMUM_3D:
        return _pressure_rhs_parallel(u, v, w, scale, rhs)
    return _pressure_rhs_serial(u, v, w, scale, rhs)


def _make_pressure_operator(loop):
    def kernel(outflow, diagonal, weights_x, weights_y, weights_z):
        nx, ny, nz = diagonal.shape
        for i in loop(nx):
            for j in range(ny):
                for k in range(nz):
                    d = 0.0
                    if i == 0 and outflow[SIDE_LEFT]:
                        d += 2.0
                    if i == nx - 1 and outflow[SIDE_RIGHT]:
                        d += 2.0
                    if j == 0 and outflow[SIDE_BOTTOM]:
                        d += 2.0
                    if j == ny - 1 and outflow[SIDE_TOP]:
                        d += 2.0
                    if k == 0 and outflow[SIDE_BACK]:
                        d += 2.0
                    if k == nz - 1 and outflow[SIDE_FRONT]:
                        d += 2.0
                    diagonal[i, j, k] = d
                    if i + 1 < nx:
                        weights_x[i, j, k] = 1.0
                    if j + 1 < ny:
                        weights_y[i, j, k] = 1.0
                    if k + 1 < nz:
                        weights_z[i, j, k] = 1.0
    return kernel


_pressure_operator_serial, _pressure_operator_parallel = serial_and_parallel(
    _make_pressure_operator)


@njit(cache=True)
def build_pressure_operator_3d(outflow, diagonal, weights_x, weights_y, weights_z):
    """``A p = -h^2 lap p`` on the cells: unit face weights, and ``2`` on the diagonal of a
    cell next to an outflow side (p = 0 halfway to the ghost); ``outflow`` is (6,) bool."""
    if diagonal.size > PARALLEL_MINIMUM_3D:
        return _pressure_operator_parallel(outflow, diagonal, weights_x, weights_y, weights_z)
    return _pressure_operator_serial(outflow, diagonal, weights_x, weights_y, weights_z)


def _make_subtract_gradient(loop):
    def kernel(u, v, w, p, scale, outflow):
        nx, ny, nz = p.shape
        # One loop per component; the side faces see the outflow ghost -p (p = 0 on the
        # side), or keep their velocity on walls and inflow sides.
        for i in loop(nx + 1):
            if (i == 0 and not outflow[SIDE_LEFT]) or (i == nx and not outflow[SIDE_RIGHT]):
                continue
            for j in range(ny):
                for k in range(nz):
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
                    if k == 0:
                        if not outflow[SIDE_BACK]:
                            continue
                        gradient = 2.0 * p[i, j, 0]
                    elif k == nz:
                        if not outflow[SIDE_FRONT]:
                            continue
                        gradient = -2.0 * p[i, j, nz - 1]
                    else:
                        gradient = p[i, j, k] - p[i, j, k - 1]
                    w[i, j, k] -= scale * gradient
    return kernel


_subtract_gradient_serial, _subtract_gradient_parallel = serial_and_parallel(
    _make_subtract_gradient)


@njit(cache=True)
def subtract_pressure_gradient_3d(u, v, w, p, scale, outflow):
    """``u -= scale * (p[i] - p[i-1])`` on every face (likewise v, w), ``scale = dt / (rho
    h)``; wall and inflow sides keep their normal velocity, outflow sides see the ghost
    ``-p`` (p = 0 on the side)."""
    if p.size > PARALLEL_MINIMUM_3D:
        return _subtract_gradient_parallel(u, v, w, p, scale, outflow)
    return _subtract_gradient_serial(u, v, w, p, scale, outflow)


def _make_divergence(loop):
    def kernel(u, v, w, inv_h, out):
        nx, ny, nz = out.shape
        for i in loop(nx):
            for j in range(ny):
                for k in range(nz):
                    out[i, j, k] = inv_h * (u[i + 1, j, k] - u[i, j, k] + v[i, j + 1, k]
                                            - v[i, j, k] + w[i, j, k + 1] - w[i, j, k])
    return kernel


_divergence_serial, _divergence_parallel = serial_and_parallel(_make_divergence)


@njit(cache=True)
def divergence_3d(u, v, w, inv_h, out):
    """Cell divergence [1/s] of the face velocities, ``out`` (nx, ny, nz)."""
    if out.size > PARALLEL_MINIMUM_3D:
        return _divergence_parallel(u, v, w, inv_h, out)
    return _divergence_serial(u, v, w, inv_h, out)


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
