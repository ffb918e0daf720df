"""Numba kernels of the 3D fluid with bodies inside (`InteriorBoundary3D`): the weighted
pressure operator and projection, the viscosity with cut-distance ghosts, and advection whose
samples replace values across a body boundary by cut-distance ghosts.

Index conventions and side numbers as in `elastoflow.fluid._kernels3d`; cut directions
0 -x, 1 +x, 2 -y, 3 +y, 4 -z, 5 +z. The 2D kernels' constants apply unchanged
(`OPEN_MIN`: faces open by less than 1 % count closed; `THETA_MIN`: the smallest cut
fraction used in a stencil).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from elastoflow._numba import serial_and_parallel
from elastoflow.fluid._kernels import OPEN_MIN, THETA_MIN
from elastoflow.fluid._kernels3d import (
    GHOST_DIRICHLET,
    PARALLEL_MINIMUM_3D,
    SIDE_BACK,
    SIDE_BOTTOM,
    SIDE_FRONT,
    SIDE_LEFT,
    SIDE_RIGHT,
    SIDE_TOP,
    _corner_range,
    _field_value,
    _lerp,
    _sample,
)


@njit(cache=True, inline="always")
def _open(fraction):
    if fraction < OPEN_MIN:
        return 0.0
    return min(fraction, 1.0)


# -- pressure --------------------------------------------------------------------------------


def _make_pressure_operator(loop):
    def kernel(open_x, open_y, open_z, outflow, diagonal, weights_x, weights_y, weights_z):
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
def build_pressure_operator_bodies_3d(open_x, open_y, open_z, outflow, diagonal, weights_x,
                                      weights_y, weights_z):
    """``A p = -h^2 div(A grad p)``: face weights are the open fractions (0 below
    `OPEN_MIN`), an outflow side adds ``2 A``. Weights in [0, 1]: the operator stays
    symmetric positive semi-definite; a cell with all faces closed is inactive."""
    if diagonal.size > PARALLEL_MINIMUM_3D:
        return _pressure_operator_parallel(open_x, open_y, open_z, outflow, diagonal,
                                           weights_x, weights_y, weights_z)
    return _pressure_operator_serial(open_x, open_y, open_z, outflow, diagonal, weights_x,
                                     weights_y, weights_z)


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
    def kernel(u, v, w, scale, open_x, open_y, open_z, solid_u, solid_v, solid_w, rhs):
        nx, ny, nz = rhs.shape
        for i in loop(nx):
            for j in range(ny):
                for k in range(nz):
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
                    rhs[i, j, k] = -scale * flux
    return kernel


_pressure_rhs_serial, _pressure_rhs_parallel = serial_and_parallel(_make_pressure_rhs)


@njit(cache=True)
def pressure_rhs_bodies_3d(u, v, w, scale, open_x, open_y, open_z, solid_u, solid_v, solid_w,
                           rhs):
    """``rhs = -scale * h^2 div(A u* + (1 - A) u_s)`` per cell, ``scale = rho h / dt``
    (Batty et al. 2007)."""
    if rhs.size > PARALLEL_MINIMUM_3D:
        return _pressure_rhs_parallel(u, v, w, scale, open_x, open_y, open_z, solid_u, solid_v,
                                      solid_w, rhs)
    return _pressure_rhs_serial(u, v, w, scale, open_x, open_y, open_z, solid_u, solid_v,
                                solid_w, rhs)


def _make_subtract_gradient(loop):
    def kernel(u, v, w, p, scale, outflow, open_x, open_y, open_z, solid_u, solid_v, solid_w):
        nx, ny, nz = p.shape
        for i in loop(nx + 1):
            if (i == 0 and not outflow[SIDE_LEFT]) or (i == nx and not outflow[SIDE_RIGHT]):
                continue
            for j in range(ny):
                for k in range(nz):
                    if _open(open_x[i, j, k]) == 0.0:
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
                    if _open(open_y[i, j, k]) == 0.0:
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
                    if _open(open_z[i, j, k]) == 0.0:
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
def subtract_pressure_gradient_bodies_3d(u, v, w, p, scale, outflow, open_x, open_y, open_z,
                                         solid_u, solid_v, solid_w):
    """``u -= scale * grad p`` on faces with ``A > 0`` (``scale = dt / (rho h)``), ``u = u_s``
    on closed faces; sides as `subtract_pressure_gradient_3d`."""
    if p.size > PARALLEL_MINIMUM_3D:
        return _subtract_gradient_parallel(u, v, w, p, scale, outflow, open_x, open_y, open_z,
                                           solid_u, solid_v, solid_w)
    return _subtract_gradient_serial(u, v, w, p, scale, outflow, open_x, open_y, open_z,
                                     solid_u, solid_v, solid_w)


# -- viscosity -------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _is_fixed(index, size, fixed_low, fixed_high):
    return (index == 0 and fixed_low) or (index == size - 1 and fixed_high)


def _make_viscosity(loop):
    def kernel(f, c, axis, fixed_low, fixed_high, tangential_modes, tangential_values, solid,
               theta, cut_velocity, diagonal, weights_x, weights_y, weights_z, rhs):
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
                    if _is_fixed(own, size, fixed_low, fixed_high) or solid[i, j, k]:
                        # Held: a side face, or a point inside a body (its body velocity).
                        diagonal[i, j, k] = 1.0
                        continue
                    d = 1.0
                    r = f[i, j, k]
                    for direction in range(6):
                        along = direction >> 1
                        step = np.int64(1) if direction & 1 else np.int64(-1)
                        ni = np.int64(i) + step if along == 0 else np.int64(i)
                        nj = np.int64(j) + step if along == 1 else np.int64(j)
                        nk = np.int64(k) + step if along == 2 else np.int64(k)
                        if ni < 0 or ni >= m or nj < 0 or nj >= n or nk < 0 or nk >= l:
                            if along != axis and tangential_modes[direction] == GHOST_DIRICHLET:
                                d += 2.0 * c
                                r += 2.0 * c * tangential_values[direction]
                            continue
                        t = theta[direction, i, j, k]
                        if t <= 1.0:
                            # A body boundary at t h (METHOD.md §6, Gibou et al. 2002): the
                            # ghost enters the diagonal and right-hand side only.
                            t = max(t, THETA_MIN)
                            d += c / t
                            r += c * cut_velocity[direction, i, j, k] / t
                            continue
                        neighbour = ni if axis == 0 else (nj if axis == 1 else nk)
                        if (along == axis and _is_fixed(neighbour, size, fixed_low, fixed_high)
                                ) or solid[ni, nj, nk]:
                            d += c
                            r += c * f[ni, nj, nk]
                            continue
                        if theta[direction ^ 1, ni, nj, nk] <= 1.0:
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


@njit(cache=True)
def build_viscosity_system_bodies_3d(f, c, axis, fixed_low, fixed_high, tangential_modes,
                                     tangential_values, solid, theta, cut_velocity, diagonal,
                                     weights_x, weights_y, weights_z, rhs):
    """`build_viscosity_system_3d` with bodies: points inside a body are held at their value
    (the body velocity); a neighbour across a body boundary at ``t h`` is replaced by the
    no-slip ghost, which adds ``c / t`` to the diagonal and ``c u_b / t`` to the right-hand
    side; the operator stays symmetric (a connection is dropped when either end sees a
    cut)."""
    if f.size > PARALLEL_MINIMUM_3D:
        return _viscosity_parallel(f, c, axis, fixed_low, fixed_high, tangential_modes,
                                   tangential_values, solid, theta, cut_velocity, diagonal,
                                   weights_x, weights_y, weights_z, rhs)
    return _viscosity_serial(f, c, axis, fixed_low, fixed_high, tangential_modes,
                             tangential_values, solid, theta, cut_velocity, diagonal, weights_x,
                             weights_y, weights_z, rhs)


# -- advection -------------------------------------------------------------------------------


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
    value = _field_value(f, ii, jj, kk, modes, values, row)
    if not (_inside(ii, jj, kk, m, n, l) and solid[ii, jj, kk]):
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
def solid_box(solid, out):
    """Index bounds ``(i_low, i_high, j_low, j_high, k_low, k_high)`` (inclusive) of the
    True entries of ``solid`` into ``out`` (int64, (6,)); an empty box (low > high) when
    there are none."""
    m, n, l = solid.shape
    out[0] = m
    out[1] = -1
    out[2] = n
    out[3] = -1
    out[4] = l
    out[5] = -1
    for i in range(m):
        for j in range(n):
            for k in range(l):
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
    0; without it low and high are 0. A velocity component replaces solid corners by cut-distance
    ghosts (`_corner_with_bodies`); dye (``is_dye``) drops them and renormalises. The plain
    case (no corner solid or beyond a side) is inlined; the rest is a call."""
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
            if _inside(ii, jj, kk, m, n, l) and solid[ii, jj, kk]:
                continue
            value = _field_value(f, ii, jj, kk, modes, values, row)
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


@njit(cache=True, inline="always")
def _velocity_at_bodies(u, v, w, x, y, z, inv_h, modes, values, solid_u, solid_v, solid_w,
                        theta_u, theta_v, theta_w, cut_u, cut_v, cut_w, boxes):
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


def _make_advect_bodies(loop):
    def kernel(u, v, w, source, out, forward, backward, offset_x, offset_y, offset_z, dt, h,
               velocity_modes, velocity_values, modes, values, solid_u, solid_v, solid_w,
               theta_u, theta_v, theta_w, cut_u, cut_v, cut_w, solid, theta, cut_velocity,
               body_value, boxes, own_box, is_dye, correct):
        m, n, l = out.shape
        inv_h = 1.0 / h
        lx = (u.shape[0] - 1) * h
        ly = (v.shape[1] - 1) * h
        lz = (w.shape[2] - 1) * h
        for i in loop(m):
            for j in range(n):
                for k in range(l):
                    if solid[i, j, k]:
                        out[i, j, k] = 0.0 if is_dye else body_value[i, j, k]
                        continue
                    x = (i + offset_x) * h
                    y = (j + offset_y) * h
                    z = (k + offset_z) * h
                    # Midpoint back-trace with the body-aware velocity: it does not leak
                    # through a body either.
                    ux, uy, uz = _velocity_at_bodies(u, v, w, x, y, z, inv_h, velocity_modes,
                                                     velocity_values, solid_u, solid_v,
                                                     solid_w, theta_u, theta_v, theta_w, cut_u,
                                                     cut_v, cut_w, boxes)
                    xm = _clamp(x - 0.5 * dt * ux, 0.0, lx)
                    ym = _clamp(y - 0.5 * dt * uy, 0.0, ly)
                    zm = _clamp(z - 0.5 * dt * uz, 0.0, lz)
                    um, vm, wm = _velocity_at_bodies(u, v, w, xm, ym, zm, inv_h, velocity_modes,
                                                     velocity_values, solid_u, solid_v,
                                                     solid_w, theta_u, theta_v, theta_w, cut_u,
                                                     cut_v, cut_w, boxes)
                    xb = _clamp(x - dt * um, 0.0, lx)
                    yb = _clamp(y - dt * vm, 0.0, ly)
                    zb = _clamp(z - dt * wm, 0.0, lz)
                    value, low, high = _sample_bodies(
                        source, xb * inv_h - offset_x, yb * inv_h - offset_y,
                        zb * inv_h - offset_z, modes, values, 0, solid, theta, cut_velocity,
                        boxes, own_box, is_dye, correct)
                    if correct:
                        # MacCormack: forward + (source - backward) / 2, clamped to the
                        # range of the (ghosted) values around the departure point.
                        corrected = (forward[i, j, k]
                                     + 0.5 * (source[i, j, k] - backward[i, j, k]))
                        out[i, j, k] = _clamp(corrected, low, high)
                    else:
                        out[i, j, k] = value
    return kernel


_advect_bodies_serial, _advect_bodies_parallel = serial_and_parallel(_make_advect_bodies)


@njit(cache=True)
def advect_bodies_3d(u, v, w, source, out, forward, backward, offset_x, offset_y, offset_z, dt,
                     h, velocity_modes, velocity_values, modes, values, solid_u, solid_v,
                     solid_w, theta_u, theta_v, theta_w, cut_u, cut_v, cut_w, solid, theta,
                     cut_velocity, body_value, boxes, own_box, is_dye, correct):
    """Semi-Lagrangian transport of ``source`` into ``out`` with bodies inside.

    Points inside a body (``solid``) take ``body_value`` (dye: 0). The trace samples u, v, w
    with cut-distance ghosts for their corners inside bodies (their solid flags, cut
    fractions and cut velocities ``solid_u``, ``theta_u``, ``cut_u``, ...); so does the
    sample of a velocity component (``solid``, ``theta``, ``cut_velocity`` are its own),
    while dye (``is_dye``) is averaged over its fluid corners only. With ``correct`` the
    output is MacCormack's clamped correction of ``forward`` (this step's result) by
    ``backward`` (its advection by -dt). Offsets, ghosts and ``dt`` as in
    `advect_kernel_3d`. ``boxes`` (4, 6) int64 holds the `solid_box` of u, v, w and the
    cells; ``own_box`` the row of the transported field's own.
    """
    if out.size > PARALLEL_MINIMUM_3D:
        return _advect_bodies_parallel(u, v, w, source, out, forward, backward, offset_x,
                                       offset_y, offset_z, dt, h, velocity_modes,
                                       velocity_values, modes, values, solid_u, solid_v,
                                       solid_w, theta_u, theta_v, theta_w, cut_u, cut_v, cut_w,
                                       solid, theta, cut_velocity, body_value, boxes, own_box,
                                       is_dye, correct)
    return _advect_bodies_serial(u, v, w, source, out, forward, backward, offset_x, offset_y,
                                 offset_z, dt, h, velocity_modes, velocity_values, modes, values,
                                 solid_u, solid_v, solid_w, theta_u, theta_v, theta_w, cut_u,
                                 cut_v, cut_w, solid, theta, cut_velocity, body_value, boxes,
                                 own_box, is_dye, correct)
