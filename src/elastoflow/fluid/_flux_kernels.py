"""Numba kernels of the flux-form advection (``advection="upwind3"``).

The velocity is transported by a frozen advecting velocity ``a`` (the step's current or
extrapolated velocity, divergence-free): ``du/dt = -div(a u)`` on each component's own MAC
control volume, with the fluxes at the volume's faces (cell centres along the component's own
axis, grid nodes across it). The transported value at each flux point is the upwind-biased
third-order interpolation of the four points along the line (``(-q_-1 + 5 q_0 + 2 q_1) / 6``
with ``q_-1`` upwind), the advecting velocity the average of its two neighbours. Time is
integrated by the three-stage strong-stability-preserving Runge-Kutta scheme (Shu & Osher
1988). With ``a`` fixed and divergence-free, a uniform field stays exactly uniform and the
discrete transport conserves momentum in the open grid.

Bodies: a neighbour across a cut (a body boundary between two points along a line, the
interior boundary's cut fractions ``theta`` and cut velocities) is replaced by the cut-distance
ghost of the semi-Lagrangian kernels (`_kernels._body_ghost`), and a stencil that would reach
past a cut falls back to the central average of its two nearest values. Points inside bodies
keep the body's velocity. Side ghosts as in `_kernels` (module docstring there).

Index conventions: those of `elastoflow.grid` and `_kernels` (cut directions 0: -x, 1: +x,
2: -y, 3: +y).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from elastoflow.fluid._kernels import FIELD_X, _body_ghost, _field_value

# The largest advective CFL number, (max|a_x| + max|a_y|) dt / h, of one Runge-Kutta stage
# sequence; a longer step is split into equal sub-steps. SSP-RK3 with the third-order upwind-
# biased flux is linearly stable to a CFL number of about 1.6 along one axis; 1.2 for the sum
# over both keeps a margin, and lets DFG 2D-2 at its CFL 0.5 on the inflow peak (a sum of
# about 1.07 near the cylinder) take one sequence per step.
CFL_LIMIT = 1.2


@njit(cache=True, inline="always")
def _direction(di, dj):
    if di < 0:
        return 0
    if di > 0:
        return 1
    if dj < 0:
        return 2
    return 3


@njit(cache=True, inline="always")
def _walk(f, i, j, di, dj, steps, has_interior, theta, cut, modes, values):
    """The value ``steps`` (1 or 2) points from fluid point (i, j) along (di, dj), and
    whether it was reached: at a cut on the way the cut-distance ghost of the last point
    before it is returned instead, reached only if that was the last step."""
    m, n = f.shape
    direction = _direction(di, dj)
    ci = np.int64(i)
    cj = np.int64(j)
    for step in range(steps):
        if has_interior and 0 <= ci < m and 0 <= cj < n:
            t = theta[direction, ci, cj]
            if t <= 1.0:
                return _body_ghost(t, cut[direction, ci, cj], f[ci, cj]), step == steps - 1
        ni = ci + di
        nj = cj + dj
        if ni < 0 or ni >= m or nj < 0 or nj >= n:
            return _field_value(f, i + di * steps, j + dj * steps, modes, values), True
        ci = ni
        cj = nj
    return f[ci, cj], True


@njit(cache=True, inline="always")
def _upwind_from_here(behind, here, there):
    """The third-order value at the midpoint of ``here`` and ``there`` when ``here`` is
    upwind (``behind`` the point on its other side)."""
    return (-behind + 5.0 * here + 2.0 * there) / 6.0


@njit(cache=True, inline="always")
def _upwind_from_there(here, there, beyond):
    """The same when ``there`` is upwind (``beyond`` the point past it)."""
    return (2.0 * here + 5.0 * there - beyond) / 6.0


@njit(cache=True, inline="always")
def _flux_value(f, i, j, di, dj, a, has_interior, theta, cut, modes, values):
    """The transported value at the midpoint between (i, j) and its neighbour along
    (di, dj), for the advecting velocity ``a`` there (positive along the axis)."""
    here = f[i, j]
    there, reached = _walk(f, i, j, di, dj, 1, has_interior, theta, cut, modes, values)
    central = 0.5 * (here + there)
    if not reached:
        return central
    if (a >= 0.0) == (di + dj > 0):
        # Upwind is behind (i, j): the point on its other side.
        behind, reached = _walk(f, i, j, -di, -dj, 1, has_interior, theta, cut, modes, values)
        if not reached:
            return central
        return _upwind_from_here(behind, here, there)
    beyond, reached = _walk(f, i, j, di, dj, 2, has_interior, theta, cut, modes, values)
    if not reached:
        return central
    return _upwind_from_there(here, there, beyond)


@njit(cache=True, inline="always")
def _line_flux(f_behind2, f_behind, here, f_next, f_next2, a_back, a_front):
    """``a_front q_front - a_back q_back`` along one line of plain fluid: the flux
    difference of a point whose two neighbours on each side are in the array and far from
    every body, each value as `_flux_value` gives it there (bitwise)."""
    if a_back >= 0.0:
        back = _upwind_from_there(here, f_behind, f_behind2)
    else:
        back = _upwind_from_here(f_next, here, f_behind)
    if a_front >= 0.0:
        front = _upwind_from_here(f_behind, here, f_next)
    else:
        front = _upwind_from_there(here, f_next, f_next2)
    return back, front


@njit(cache=True, inline="always")
def _value(f, i, j, modes, values):
    """``f[i, j]``, or its side ghost outside the array (`_kernels._field_value`)."""
    m, n = f.shape
    if 0 <= i < m and 0 <= j < n:
        return f[i, j]
    return _field_value(f, i, j, modes, values)


def _make_stage(axis):
    # x faces (axis 0) sit at (i h, (j + 1/2) h), y faces at ((i + 1/2) h, j h): the fluxes
    # along the own axis at cell centres, across it at grid nodes.
    def kernel(advecting, field, start, out, dt, weight, h, ghosts, has_interior, body):
        a_x, a_y = advecting
        modes_u, values_u, modes_v, values_v = ghosts
        solid, theta, cut, body_velocity, near = body
        own = a_x if axis == 0 else a_y
        modes = modes_u if axis == 0 else modes_v
        values = values_u if axis == 0 else values_v
        m, n = field.shape
        inv_h = 1.0 / h
        for i_ in prange(m):
            i = np.int64(i_)
            for j in range(n):
                # Fast path: two points of room to each side and no body data within one
                # point (the only body data the general path reads): plain upwind fluxes.
                if (2 <= i < m - 2 and 2 <= j < n - 2
                        and not (has_interior and (near[i, j] or near[i + 1, j]
                                                   or near[i, j + 1] or near[i + 1, j + 1]))):
                    if axis == 0:
                        a_w = 0.5 * (own[i, j] + own[i - 1, j])
                        a_e = 0.5 * (own[i, j] + own[i + 1, j])
                        a_s = 0.5 * (a_y[i - 1, j] + a_y[i, j])
                        a_n = 0.5 * (a_y[i - 1, j + 1] + a_y[i, j + 1])
                    else:
                        a_s = 0.5 * (own[i, j] + own[i, j - 1])
                        a_n = 0.5 * (own[i, j] + own[i, j + 1])
                        a_w = 0.5 * (a_x[i, j - 1] + a_x[i, j])
                        a_e = 0.5 * (a_x[i + 1, j - 1] + a_x[i + 1, j])
                    here = field[i, j]
                    q_w, q_e = _line_flux(field[i - 2, j], field[i - 1, j], here,
                                          field[i + 1, j], field[i + 2, j], a_w, a_e)
                    q_s, q_n = _line_flux(field[i, j - 2], field[i, j - 1], here,
                                          field[i, j + 1], field[i, j + 2], a_s, a_n)
                    # The general path's order of summation: -x and -y, then +x and +y
                    # (its own axis first each time).
                    if axis == 0:
                        total = -1.0 * a_w * q_w
                        total += -1.0 * a_s * q_s
                        total += a_e * q_e
                        total += a_n * q_n
                    else:
                        total = -1.0 * a_s * q_s
                        total += -1.0 * a_w * q_w
                        total += a_n * q_n
                        total += a_e * q_e
                    out[i, j] = (weight * start[i, j]
                                 + (1.0 - weight) * (field[i, j] - dt * inv_h * total))
                    continue
                if has_interior and solid[i, j]:
                    out[i, j] = body_velocity[i, j]
                    continue
                total = 0.0
                for k in range(2):
                    s = 2 * k - 1
                    di = s if axis == 0 else 0
                    dj = s if axis == 1 else 0
                    # Along the own axis: the advecting component's mean of the two points.
                    next_a, _ = _walk(own, i, j, di, dj, 1, has_interior, theta, cut, modes,
                                      values)
                    a = 0.5 * (own[i, j] + next_a)
                    total += s * a * _flux_value(field, i, j, di, dj, a, has_interior, theta,
                                                 cut, modes, values)
                    # Across it: the other component's mean of the two faces at the node.
                    if axis == 0:
                        jj = j + 1 if s > 0 else j
                        a = 0.5 * (_value(a_y, i - 1, jj, modes_v, values_v)
                                   + _value(a_y, i, jj, modes_v, values_v))
                        total += s * a * _flux_value(field, i, j, 0, s, a, has_interior,
                                                     theta, cut, modes, values)
                    else:
                        ii = i + 1 if s > 0 else i
                        a = 0.5 * (_value(a_x, ii, j - 1, modes_u, values_u)
                                   + _value(a_x, ii, j, modes_u, values_u))
                        total += s * a * _flux_value(field, i, j, s, 0, a, has_interior,
                                                     theta, cut, modes, values)
                out[i, j] = (weight * start[i, j]
                             + (1.0 - weight) * (field[i, j] - dt * inv_h * total))
    return kernel


# Threaded at every size: a serial compilation of this body (``range`` for ``prange``, no
# ``parallel``) measured 25-30 times slower than the threaded one run on a single thread
# (DFG 2D-2's x faces: 6.0 against 0.22 ms on 221 x 41, 24.3 against 0.85 ms on 441 x 82;
# NUMBA_NUM_THREADS=1), so it has no serial twin.
_stage_x = njit(cache=True, parallel=True)(_make_stage(0))
_stage_y = njit(cache=True, parallel=True)(_make_stage(1))


@njit(cache=True)
def runge_kutta_stage(advecting, field, start, out, axis, dt, weight, h, ghosts, has_interior,
                      body):
    """One SSP-RK3 stage of one velocity component: ``out = weight start + (1 - weight)
    (field + dt L(field))`` with ``L(q) = -div(a q)`` [m/s^2] on the component's faces.

    Args:
        advecting: ``(a_x, a_y)``: the advecting velocity on the x and y faces [m/s].
        field: The stage's value of the transported component, shape of its faces
            (`FIELD_X`: (nx+1, ny), `FIELD_Y`: (nx, ny+1)); ``start`` the step's (or
            sub-step's) value, ``out`` the result, the same shape. ``out`` must not be
            ``field``; it may be ``start``.
        axis: Which component it is (`FIELD_X` or `FIELD_Y`).
        dt: The (sub-)step [s]; weight: Shu & Osher's weight of ``start`` (0, 3/4, 1/3).
        h: Grid spacing [m].
        ghosts: ``(modes_u, values_u, modes_v, values_v)``: the side ghosts of u and v.
        has_interior: Whether ``body`` is read.
        body: ``(solid, theta, cut, body_velocity, near)``: of the component's faces,
            inside a body, cut fractions and cut velocities (4, m, n) per direction, and the
            body's velocity, which the points inside take; and the blocks that may meet a
            body (`_kernels.near_regions`, shape (nx+2, ny+2)), outside which a point takes
            the fast path of plain fluxes.
    """
    if axis == FIELD_X:
        return _stage_x(advecting, field, start, out, dt, weight, h, ghosts, has_interior,
                        body)
    return _stage_y(advecting, field, start, out, dt, weight, h, ghosts, has_interior, body)


@njit(cache=True)
def largest_magnitude(values):
    """``max |values|`` over a 2D array (0 for an empty one)."""
    m, n = values.shape
    largest = 0.0
    for i in range(m):
        for j in range(n):
            largest = max(largest, abs(values[i, j]))
    return largest
