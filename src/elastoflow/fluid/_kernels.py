"""Numba kernels of the fluid solver: sampling, advection, viscosity and pressure assembly.

Index conventions are those of `elastoflow.grid`. Domain sides are numbered 0: left, 1: right,
2: bottom, 3: top; cut directions 0: -x, 1: +x, 2: -y, 3: +y. Ghost modes of a field beyond a
side: 0 copies the inside value (zero normal gradient), 1 reflects about a boundary value
(``2 value - inside``, Dirichlet at the side), 2 takes the value itself (a ghost cell value).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from elastoflow._numba import serial_and_parallel

THETA_MIN = 1e-3
# Faces open by less than this count as closed: a sliver of a face would couple a cell that is
# practically inside a body to the fluid through a vanishing weight (ill-conditioned). Under a
# moving elastic body the solid fluxes around such a cell do not balance exactly, its pressure
# grows like that mismatch over A and the sliver face gets a velocity ~ 1/A: with 1e-6 a
# sinking disc produced 139 m/s on a face open by 6e-6 (tests/validation/
# test_coupling_buoyancy.py); 1e-2 bounds the amplification at 100.
OPEN_MIN = 1e-2
# Kernels over more points than this run in parallel; below, the work per thread is too small
# for the region's start (~1.5 us with the package's GOMP_SPINCOUNT; measured with the linear
# algebra's limit, `elastoflow.linalg._kernels.PARALLEL_MINIMUM`).
PARALLEL_MINIMUM = 96 * 96

# Which field an advection pass transports (`advect`).
FIELD_X = 0      # the x faces (nx+1, ny)
FIELD_Y = 1      # the y faces (nx, ny+1)
FIELD_CELLS = 2  # a cell-centred scalar (nx, ny): the dye
# What an advection pass writes (`advect`).
PASS_TRACE = 0              # the semi-Lagrangian sample at the departure point
PASS_TRACE_RANGE = 1        # the same, and the range of the four values around it
PASS_CORRECT = 2            # MacCormack's correction, clamped to that range
PASS_CORRECT_UNCLAMPED = 3  # the same correction, unclamped


@njit(cache=True, inline="always")
def _lerp(a: float, b: float, t: float) -> float:
    # a + t (b - a) returns a exactly when a == b, so constants survive interpolation.
    return a + t * (b - a)


@njit(cache=True, inline="always")
def _ghost(mode: int, value: float, inside: float) -> float:
    if mode == 0:
        return inside
    if mode == 1:
        return 2.0 * value - inside
    return value


@njit(cache=True)
def _field_value(f, i, j, modes, values):
    m, n = f.shape
    ic = min(max(i, 0), m - 1)
    jc = min(max(j, 0), n - 1)
    value = f[ic, jc]
    if i < 0:
        value = _ghost(modes[0], values[0], value)
    elif i >= m:
        value = _ghost(modes[1], values[1], value)
    if j < 0:
        value = _ghost(modes[2], values[2], value)
    elif j >= n:
        value = _ghost(modes[3], values[3], value)
    return value


@njit(cache=True, inline="always")
def _sample(f, fx, fy, modes, values):
    """Bilinear sample of ``f`` at index coordinates ``(fx, fy)`` with side ghosts: the
    value of `_sample_and_range` (inlined, its unused range is compiled away)."""
    return _sample_and_range(f, fx, fy, modes, values)[0]


@njit(cache=True)
def _body_ghost(theta, boundary_value, inside_value):
    # Ghost of METHOD.md §6, (phi_b - (1 - theta) phi_P) / theta, limited so that the ghost is
    # no farther from the boundary value than the fluid point is (theta >= 1/2 behaviour):
    # a tiny theta would otherwise extrapolate without bound.
    t = max(theta, THETA_MIN)
    ratio = min((1.0 - t) / t, 1.0)
    return boundary_value + ratio * (boundary_value - inside_value)


@njit(cache=True)
def _sample_across_bodies(f, fx, fy, modes, values, solid, theta, cut_velocity):
    """Bilinear sample with corners across a body boundary replaced by cut-distance ghosts.

    The reference corner P is the fluid corner of largest bilinear weight; its x and y
    neighbours are replaced when P's cut data shows a boundary between them, the diagonal
    corner when both paths to it are blocked.
    """
    m, n = f.shape
    i0 = int(math.floor(fx))
    j0 = int(math.floor(fy))
    a = fx - i0
    b = fy - j0
    best = -1
    best_weight = -1.0
    for k in range(4):
        ii = i0 + (k & 1)
        jj = j0 + (k >> 1)
        if ii < 0 or ii >= m or jj < 0 or jj >= n or solid[ii, jj]:
            continue
        wx = a if (k & 1) else 1.0 - a
        wy = b if (k >> 1) else 1.0 - b
        if wx * wy > best_weight:
            best_weight = wx * wy
            best = k
    if best < 0:
        return _sample(f, fx, fy, modes, values)
    pi = i0 + (best & 1)
    pj = j0 + (best >> 1)
    sx = -1 if (best & 1) else 1
    sy = -1 if (best >> 1) else 1
    ax = 1.0 - a if (best & 1) else a
    by = 1.0 - b if (best >> 1) else b
    dir_x = 1 if sx > 0 else 0
    dir_y = 3 if sy > 0 else 2
    xi = pi + sx
    yj = pj + sy
    in_x = 0 <= xi < m
    in_y = 0 <= yj < n

    value_p = f[pi, pj]
    value_x = _field_value(f, xi, pj, modes, values)
    value_y = _field_value(f, pi, yj, modes, values)
    value_d = _field_value(f, xi, yj, modes, values)

    replaced_x = False
    theta_x = theta[dir_x, pi, pj]
    if theta_x <= 1.0:
        value_x = _body_ghost(theta_x, cut_velocity[dir_x, pi, pj], value_p)
        replaced_x = True
    replaced_y = False
    theta_y = theta[dir_y, pi, pj]
    if theta_y <= 1.0:
        value_y = _body_ghost(theta_y, cut_velocity[dir_y, pi, pj], value_p)
        replaced_y = True

    if in_x and in_y:
        cut_x_to_d = theta[dir_y, xi, pj] <= 1.0 if not solid[xi, pj] else False
        cut_y_to_d = theta[dir_x, pi, yj] <= 1.0 if not solid[pi, yj] else False
        blocked = solid[xi, yj]
        if not blocked:
            blocked = (replaced_x or cut_x_to_d) and (replaced_y or cut_y_to_d)
        if blocked:
            if not replaced_x and cut_x_to_d:
                value_d = _body_ghost(
                    theta[dir_y, xi, pj], cut_velocity[dir_y, xi, pj], value_x
                )
            elif not replaced_y and cut_y_to_d:
                value_d = _body_ghost(
                    theta[dir_x, pi, yj], cut_velocity[dir_x, pi, yj], value_y
                )
            else:
                value_d = value_x + value_y - value_p
    return _lerp(_lerp(value_p, value_x, ax), _lerp(value_y, value_d, ax), by)


@njit(cache=True)
def near_regions(regions, near):
    """Mark the 2 x 2 index blocks that meet a box of ``regions`` (``InteriorBoundary.regions``).

    ``near[i + 1, j + 1]`` (bool, shape (nx+2, ny+2)) becomes True when one of the indices
    ``{i, i+1} x {j, j+1}`` (i, j >= -1; shared by cells, u and v points) lies in a box: only
    there may a bilinear stencil with lower corner (i, j) read body data. Cost: the mask plus
    the boxes' area.
    """
    near[:, :] = False
    m, n = near.shape
    for k in range(regions.shape[0]):
        # Lower corners i in [i_begin - 1, i_end - 1] meet [i_begin, i_end): rows i + 1.
        i_begin = max(regions[k, 0], 0)
        i_end = min(regions[k, 1] + 1, m)
        j_begin = max(regions[k, 2], 0)
        j_end = min(regions[k, 3] + 1, n)
        if regions[k, 0] < regions[k, 1] and regions[k, 2] < regions[k, 3]:
            for i in range(i_begin, i_end):
                for j in range(j_begin, j_end):
                    near[i, j] = True


@njit(cache=True, inline="always")
def _sample_with_bodies(f, fx, fy, modes, values, solid, theta, cut_velocity, near):
    """Bilinear sample that replaces corners across a body boundary by cut-distance ghosts.

    Fast path: a cell away from every region (``near``, see `near_regions`) or, near one,
    with no corner inside a body and no boundary on its four edges (each edge is seen from
    one of its ends) is plain bilinear interpolation; otherwise `_sample_across_bodies`.
    """
    m, n = f.shape
    i0 = int(math.floor(fx))
    j0 = int(math.floor(fy))
    if (
        0 <= i0 < m - 1 and 0 <= j0 < n - 1
        and (not near[i0 + 1, j0 + 1] or (
            not (solid[i0, j0] or solid[i0 + 1, j0] or solid[i0, j0 + 1] or solid[i0 + 1, j0 + 1])
            and theta[1, i0, j0] > 1.0 and theta[3, i0, j0] > 1.0
            and theta[0, i0 + 1, j0 + 1] > 1.0 and theta[2, i0 + 1, j0 + 1] > 1.0
        ))
    ):
        a = fx - i0
        b = fy - j0
        return _lerp(
            _lerp(f[i0, j0], f[i0 + 1, j0], a), _lerp(f[i0, j0 + 1], f[i0 + 1, j0 + 1], a), b
        )
    return _sample_across_bodies(f, fx, fy, modes, values, solid, theta, cut_velocity)


@njit(cache=True, inline="always")
def _sample_dye_with_bodies(f, fx, fy, modes, values, solid, near):
    """Bilinear sample over the fluid corners only (dye does not enter bodies).

    Corners away from every region (``near``, see `near_regions`) are fluid without reading
    ``solid``. Inlined (one caller): as a call it cost `_advect_cells` ~30 % over the plain
    sampling.
    """
    m, n = f.shape
    i0 = int(math.floor(fx))
    j0 = int(math.floor(fy))
    a = fx - i0
    b = fy - j0
    if (
        0 <= i0 < m - 1 and 0 <= j0 < n - 1
        and (not near[i0 + 1, j0 + 1] or not (
            solid[i0, j0] or solid[i0 + 1, j0] or solid[i0, j0 + 1] or solid[i0 + 1, j0 + 1]))
    ):
        # Away from bodies and sides (nearly every cell): plain bilinear interpolation.
        return _lerp(
            _lerp(f[i0, j0], f[i0 + 1, j0], a), _lerp(f[i0, j0 + 1], f[i0 + 1, j0 + 1], a), b
        )
    total = 0.0
    weight_sum = 0.0
    for k in range(4):
        ii = i0 + (k & 1)
        jj = j0 + (k >> 1)
        if 0 <= ii < m and 0 <= jj < n and solid[ii, jj]:
            continue
        w = (a if (k & 1) else 1.0 - a) * (b if (k >> 1) else 1.0 - b)
        total += w * _field_value(f, ii, jj, modes, values)
        weight_sum += w
    if weight_sum < 1e-12:
        return 0.0
    return total / weight_sum


@njit(cache=True, inline="always")
def _clamp(value, low, high):
    return min(max(value, low), high)


@njit(cache=True, inline="always")
def _velocity_at(u, v, x, y, inv_h, modes_u, values_u, modes_v, values_v):
    return (
        _sample(u, x * inv_h, y * inv_h - 0.5, modes_u, values_u),
        _sample(v, x * inv_h - 0.5, y * inv_h, modes_v, values_v),
    )


@njit(cache=True, inline="always")
def _trace_back(u, v, x, y, ux, uy, dt, inv_h, lx, ly, modes_u, values_u, modes_v, values_v):
    # Midpoint (RK2) back-trace; departure points are clamped into the domain.
    xm = _clamp(x - 0.5 * dt * ux, 0.0, lx)
    ym = _clamp(y - 0.5 * dt * uy, 0.0, ly)
    um, vm = _velocity_at(u, v, xm, ym, inv_h, modes_u, values_u, modes_v, values_v)
    return _clamp(x - dt * um, 0.0, lx), _clamp(y - dt * vm, 0.0, ly)


@njit(cache=True, inline="always")
def _velocity_at_bodies(
    u, v, x, y, inv_h, modes_u, values_u, modes_v, values_v,
    solid_x, theta_x, cut_x, solid_y, theta_y, cut_y, near,
):
    return (
        _sample_with_bodies(u, x * inv_h, y * inv_h - 0.5, modes_u, values_u, solid_x, theta_x,
                            cut_x, near),
        _sample_with_bodies(v, x * inv_h - 0.5, y * inv_h, modes_v, values_v, solid_y, theta_y,
                            cut_y, near),
    )


@njit(cache=True, inline="always")
def _trace_back_bodies(
    u, v, x, y, ux, uy, dt, inv_h, lx, ly, modes_u, values_u, modes_v, values_v,
    solid_x, theta_x, cut_x, solid_y, theta_y, cut_y, near,
):
    # The trace velocity is sampled with the cut-distance ghosts too, so that it does not
    # leak through thin bodies either.
    xm = _clamp(x - 0.5 * dt * ux, 0.0, lx)
    ym = _clamp(y - 0.5 * dt * uy, 0.0, ly)
    um, vm = _velocity_at_bodies(
        u, v, xm, ym, inv_h, modes_u, values_u, modes_v, values_v,
        solid_x, theta_x, cut_x, solid_y, theta_y, cut_y, near,
    )
    return _clamp(x - dt * um, 0.0, lx), _clamp(y - dt * vm, 0.0, ly)


@njit(cache=True, inline="always")
def _corner_range(f, fx, fy, modes, values):
    i0 = int(math.floor(fx))
    j0 = int(math.floor(fy))
    m, n = f.shape
    if 0 <= i0 < m - 1 and 0 <= j0 < n - 1:
        a, b = f[i0, j0], f[i0 + 1, j0]
        c, d = f[i0, j0 + 1], f[i0 + 1, j0 + 1]
        return min(min(a, b), min(c, d)), max(max(a, b), max(c, d))
    low = np.inf
    high = -np.inf
    for k in range(4):
        value = _field_value(f, i0 + (k & 1), j0 + (k >> 1), modes, values)
        low = min(low, value)
        high = max(high, value)
    return low, high


@njit(cache=True, inline="always")
def _sample_and_range(f, fx, fy, modes, values):
    """`_sample` and `_corner_range` together, from one read of the four values (bitwise
    both: the same interpolation, the same order of min and max)."""
    i0 = int(math.floor(fx))
    j0 = int(math.floor(fy))
    a = fx - i0
    b = fy - j0
    m, n = f.shape
    if 0 <= i0 < m - 1 and 0 <= j0 < n - 1:
        c00, c10 = f[i0, j0], f[i0 + 1, j0]
        c01, c11 = f[i0, j0 + 1], f[i0 + 1, j0 + 1]
        return (_lerp(_lerp(c00, c10, a), _lerp(c01, c11, a), b),
                min(min(c00, c10), min(c01, c11)), max(max(c00, c10), max(c01, c11)))
    c00 = _field_value(f, i0, j0, modes, values)
    c10 = _field_value(f, i0 + 1, j0, modes, values)
    c01 = _field_value(f, i0, j0 + 1, modes, values)
    c11 = _field_value(f, i0 + 1, j0 + 1, modes, values)
    low = min(min(min(min(np.inf, c00), c10), c01), c11)
    high = max(max(max(max(-np.inf, c00), c10), c01), c11)
    return _lerp(_lerp(c00, c10, a), _lerp(c01, c11, a), b), low, high


@njit(cache=True, inline="always")
def _write_advected(source, sampled, forward, out, low, high, i, j, fx, fy, modes, values,
                    pass_kind, sample, have_sample):
    """What ``pass_kind`` (see `advect`) makes of the departure point (fx, fy) of point
    (i, j), written into ``out`` (and with `PASS_TRACE_RANGE` the clamp's range into ``low``
    / ``high``); ``sample``: the value there read across bodies, when ``have_sample``."""
    if have_sample:
        value = sample
    elif pass_kind == PASS_TRACE_RANGE:
        value, low[i, j], high[i, j] = _sample_and_range(source, fx, fy, modes, values)
        out[i, j] = value
        return
    else:
        value = _sample(sampled, fx, fy, modes, values)
    if pass_kind >= PASS_CORRECT:
        corrected = forward[i, j] + 0.5 * (source[i, j] - value)
        out[i, j] = (_clamp(corrected, low[i, j], high[i, j]) if pass_kind == PASS_CORRECT
                     else corrected)
    else:
        out[i, j] = value
        if pass_kind == PASS_TRACE_RANGE:
            low[i, j], high[i, j] = _corner_range(source, fx, fy, modes, values)


# The three fields' kernels take their arrays bundled (`advect`'s arguments) and unpack them
# before the loop: a parallel loop's body cannot hold a tuple of arrays, so the inlined
# samplers below take them one by one.


def _make_advect_faces(axis):
    # x faces (axis 0) sit at (i h, (j + 1/2) h), y faces at ((i + 1/2) h, j h). With
    # ``axis`` a constant of each compiled kernel, its branches fold away.
    offset_x = 0.0 if axis == 0 else 0.5
    offset_y = 0.5 if axis == 0 else 0.0

    def kernel(velocity, source, out, dt, h, ghosts, has_interior, bodies, own, pass_kind,
               buffers):
        u, v = velocity
        modes_u, values_u, modes_v, values_v = ghosts
        solid_x, theta_x, cut_x, solid_y, theta_y, cut_y, near = bodies
        solid, body_velocity, modes, values = own
        theta, cut = (theta_x, cut_x) if axis == 0 else (theta_y, cut_y)
        forward, low, high = buffers
        inv_h = 1.0 / h
        lx = (u.shape[0] - 1) * h
        ly = (v.shape[1] - 1) * h
        sampled = forward if pass_kind >= PASS_CORRECT else source
        for i in prange(out.shape[0]):
            for j in range(out.shape[1]):
                if has_interior and solid[i, j]:
                    out[i, j] = body_velocity[i, j]
                    continue
                x = (i + offset_x) * h
                y = (j + offset_y) * h
                # The point's own component is its value; the other one is sampled.
                if axis == 0:
                    ux = u[i, j]
                    if has_interior:
                        uy = _sample_with_bodies(v, x * inv_h - 0.5, y * inv_h, modes_v,
                                                 values_v, solid_y, theta_y, cut_y, near)
                    else:
                        uy = _sample(v, x * inv_h - 0.5, y * inv_h, modes_v, values_v)
                else:
                    uy = v[i, j]
                    if has_interior:
                        ux = _sample_with_bodies(u, x * inv_h, y * inv_h - 0.5, modes_u,
                                                 values_u, solid_x, theta_x, cut_x, near)
                    else:
                        ux = _sample(u, x * inv_h, y * inv_h - 0.5, modes_u, values_u)
                if has_interior:
                    xb, yb = _trace_back_bodies(
                        u, v, x, y, ux, uy, dt, inv_h, lx, ly, modes_u, values_u, modes_v,
                        values_v, solid_x, theta_x, cut_x, solid_y, theta_y, cut_y, near,
                    )
                else:
                    xb, yb = _trace_back(u, v, x, y, ux, uy, dt, inv_h, lx, ly, modes_u,
                                         values_u, modes_v, values_v)
                fx = xb * inv_h - offset_x
                fy = yb * inv_h - offset_y
                value = 0.0
                if has_interior:
                    value = _sample_with_bodies(sampled, fx, fy, modes, values, solid, theta,
                                                cut, near)
                _write_advected(source, sampled, forward, out, low, high, i, j, fx, fy, modes,
                                values, pass_kind, value, has_interior)
    return kernel


_advect_x = njit(cache=True, parallel=True)(_make_advect_faces(0))
_advect_y = njit(cache=True, parallel=True)(_make_advect_faces(1))


@njit(cache=True, parallel=True)
def _advect_cells(velocity, source, out, dt, h, ghosts, has_interior, bodies, own, pass_kind,
                  buffers):
    u, v = velocity
    modes_u, values_u, modes_v, values_v = ghosts
    solid_x, theta_x, cut_x, solid_y, theta_y, cut_y, near = bodies
    solid_cells, modes_c, values_c = own[0], own[2], own[3]
    forward, low, high = buffers
    nx, ny = source.shape
    inv_h = 1.0 / h
    lx = nx * h
    ly = ny * h
    sampled = forward if pass_kind >= PASS_CORRECT else source
    for i in prange(nx):
        for j in range(ny):
            if has_interior and solid_cells[i, j]:
                out[i, j] = 0.0
                continue
            x = (i + 0.5) * h
            y = (j + 0.5) * h
            if has_interior:
                ux, uy = _velocity_at_bodies(
                    u, v, x, y, inv_h, modes_u, values_u, modes_v, values_v,
                    solid_x, theta_x, cut_x, solid_y, theta_y, cut_y, near,
                )
                xb, yb = _trace_back_bodies(
                    u, v, x, y, ux, uy, dt, inv_h, lx, ly, modes_u, values_u, modes_v, values_v,
                    solid_x, theta_x, cut_x, solid_y, theta_y, cut_y, near,
                )
            else:
                ux, uy = _velocity_at(u, v, x, y, inv_h, modes_u, values_u, modes_v, values_v)
                xb, yb = _trace_back(
                    u, v, x, y, ux, uy, dt, inv_h, lx, ly, modes_u, values_u, modes_v, values_v
                )
            fx = xb * inv_h - 0.5
            fy = yb * inv_h - 0.5
            value = 0.0
            if has_interior:
                value = _sample_dye_with_bodies(
                    sampled, fx, fy, modes_c, values_c, solid_cells, near
                )
            _write_advected(source, sampled, forward, out, low, high, i, j, fx, fy, modes_c,
                            values_c, pass_kind, value, has_interior)


@njit(cache=True)
def advect(velocity, source, out, field, dt, h, ghosts, has_interior, bodies, own, pass_kind,
           buffers):
    """Semi-Lagrangian transport of ``source`` by ``velocity`` = (u, v) over ``dt`` [s] into
    ``out``, with or without bodies inside: midpoint back-trace, bilinear sampling with side
    ghosts.

    Args:
        source, out: The transported field before and after, of the same shape. ``out``
            must not be ``source`` or ``buffers``' forward; with `PASS_CORRECT` and
            `PASS_CORRECT_UNCLAMPED` it may be ``buffers``' low or high (each point reads
            its own bounds before writing).
        field: Which field is transported: `FIELD_X` (x faces, (nx+1, ny)), `FIELD_Y` (y
            faces, (nx, ny+1)) or `FIELD_CELLS` (a cell-centred scalar, the dye).
        dt: The time step [s]; a negative one traces forwards (MacCormack's backward pass).
        h: Grid spacing [m].
        ghosts: ``(modes_u, values_u, modes_v, values_v)``: the side ghosts of u and v (each
            (4,): mode and value per side, module docstring).
        has_interior: Whether the body arrays are read.
        bodies: ``(solid_x, theta_x, cut_x, solid_y, theta_y, cut_y, near)``: the solid
            flags, cut fractions and cut velocities of the x- and y-faces, read only for
            samples whose stencil is marked in ``near`` (`near_regions`; all True when
            bodies may be anywhere).
        own: The transported field's own ``(solid, body_velocity, modes, values)``: points
            inside a body take ``body_velocity`` (dye: 0, across bodies it is averaged over
            its fluid corners only); ``modes`` / ``values`` its side ghosts, read for the
            dye only (a velocity component's are in ``ghosts``).
        pass_kind: `PASS_TRACE` samples ``source`` at the departure points;
            `PASS_TRACE_RANGE` (MacCormack's first pass) does the same and stores the range
            of the four ``source`` values around each departure point in ``buffers``' low /
            high; `PASS_CORRECT` (MacCormack's second pass, given ``-dt``) samples
            ``buffers``' forward, the first pass's result, at the departure points (the
            backward step's value ``backward``) and writes the correction ``forward +
            (source - backward) / 2`` clamped to ``[low, high]`` (Selle et al. 2008), so
            that no new extrema appear; `PASS_CORRECT_UNCLAMPED` writes the same correction
            unclamped. `PASS_TRACE_RANGE` then `PASS_CORRECT` give bitwise the values of a
            forward pass, a backward pass and a correction pass, with one back-trace fewer
            per point and no second read of the departure stencil.
        buffers: ``(forward, low, high)``, shaped like ``source``; not read with
            `PASS_TRACE`.
    """
    if field == FIELD_X:
        _advect_x(velocity, source, out, dt, h, ghosts, has_interior, bodies, own, pass_kind,
                  buffers)
    elif field == FIELD_Y:
        _advect_y(velocity, source, out, dt, h, ghosts, has_interior, bodies, own, pass_kind,
                  buffers)
    else:
        _advect_cells(velocity, source, out, dt, h, ghosts, has_interior, bodies, own,
                      pass_kind, buffers)


def _make_copy_into(loop):
    def kernel(source, target):
        m, n = source.shape
        for i in loop(m):
            for j in range(n):
                target[i, j] = source[i, j]
    return kernel


_copy_into_serial, _copy_into_parallel = serial_and_parallel(_make_copy_into)


@njit(cache=True)
def copy_into(source, target):
    """``target[...] = source`` in parallel."""
    if source.size > PARALLEL_MINIMUM:
        return _copy_into_parallel(source, target)
    return _copy_into_serial(source, target)


def _make_extrapolate_and_keep(loop):
    def kernel(current, previous, ratio, out):
        m, n = current.shape
        for i in loop(m):
            for j in range(n):
                now = current[i, j]
                out[i, j] = now + ratio * (now - previous[i, j])
                previous[i, j] = now
    return kernel


_extrapolate_and_keep_serial, _extrapolate_and_keep_parallel = serial_and_parallel(
    _make_extrapolate_and_keep)


@njit(cache=True)
def extrapolate_and_keep(current, previous, ratio, out):
    """``out = current + ratio (current - previous)``, then ``previous[...] = current``."""
    if current.size > PARALLEL_MINIMUM:
        return _extrapolate_and_keep_parallel(current, previous, ratio, out)
    return _extrapolate_and_keep_serial(current, previous, ratio, out)


@njit(cache=True, inline="always")
def _viscosity_row(f, c, axis, fixed_low, fixed_high, tangential_modes, tangential_values,
                   has_interior, solid, theta, cut_velocity, near, assemble_operator,
                   diagonal, weights_x, weights_y, rhs, i):
    m, n = f.shape
    for j in range(n):
        plain = 1 < i < m - 2 and 1 < j < n - 2
        if plain and has_interior:
            # The blocks {i, i+1} x {j-1, j} and {i-1, i} x {j, j+1} hold the point and its four
            # neighbours: away from every region none of them is solid or cut.
            plain = not (near[i + 1, j] or near[i, j + 1])
        if plain:
            # All four neighbours are free interior points: no boundary terms.
            rhs[i, j] = f[i, j]
            if assemble_operator:
                diagonal[i, j] = 1.0
                weights_x[i, j] = c
                weights_y[i, j] = c
            continue
        if _is_fixed(i, j, m, n, axis, fixed_low, fixed_high, has_interior, solid):
            rhs[i, j] = f[i, j]
            if assemble_operator:
                diagonal[i, j] = 1.0
                if i + 1 < m:
                    weights_x[i, j] = 0.0
                if j + 1 < n:
                    weights_y[i, j] = 0.0
            continue
        d = 1.0
        r = f[i, j]
        for direction in range(4):
            ni = i + (-1 if direction == 0 else (1 if direction == 1 else 0))
            nj = j + (-1 if direction == 2 else (1 if direction == 3 else 0))
            coupled = False
            if ni < 0 or ni >= m or nj < 0 or nj >= n:
                along = 0 if direction < 2 else 1
                if along != axis:
                    side = 0 if (direction == 0 or direction == 2) else 1
                    if tangential_modes[side] == 1:
                        d += 2.0 * c
                        r += 2.0 * c * tangential_values[side]
            elif has_interior and theta[direction, i, j] <= 1.0:
                t = max(theta[direction, i, j], THETA_MIN)
                d += c / t
                r += c * cut_velocity[direction, i, j] / t
            elif _is_fixed(ni, nj, m, n, axis, fixed_low, fixed_high, has_interior, solid):
                d += c
                r += c * f[ni, nj]
            elif has_interior and theta[direction ^ 1, ni, nj] <= 1.0:
                # Only the other side sees the cut: no coupling keeps the matrix symmetric.
                coupled = False
            else:
                coupled = True
            if not assemble_operator:
                continue
            if direction == 1 and ni < m:
                weights_x[i, j] = c if coupled else 0.0
            elif direction == 3 and nj < n:
                weights_y[i, j] = c if coupled else 0.0
        if assemble_operator:
            diagonal[i, j] = d
        rhs[i, j] = r


def _make_build_viscosity_system(loop):
    def kernel(f, c, axis, sides, has_interior, body, assemble_operator, operator, rhs):
        # Unpacked here: a parallel loop's body cannot hold a tuple of arrays.
        fixed_low, fixed_high, tangential_modes, tangential_values = sides
        solid, theta, cut_velocity, near = body
        diagonal, weights_x, weights_y = operator
        for i in loop(f.shape[0]):
            _viscosity_row(f, c, axis, fixed_low, fixed_high, tangential_modes, tangential_values,
                           has_interior, solid, theta, cut_velocity, near, assemble_operator,
                           diagonal, weights_x, weights_y, rhs, i)
    return kernel


(_build_viscosity_system_serial,
 _build_viscosity_system_parallel) = serial_and_parallel(_make_build_viscosity_system)


@njit(cache=True)
def build_viscosity_system(f, c, axis, sides, has_interior, body, assemble_operator, operator,
                           rhs):
    """Assemble ``(I - nu dt lap) f = f*`` for one velocity component as a 5-point operator
    (the 2D twin of `elastoflow.fluid._kernels3d.build_viscosity_system_3d`).

    Args:
        f: The component after advection, shape (m, n); holds the boundary values.
        c: ``nu dt / h^2``.
        axis: The component's own axis (0 for u, 1 for v); its first and last lines are the
            normal boundary faces.
        sides: ``(fixed_low, fixed_high, tangential_modes, tangential_values)``: whether
            those lines are held; the ghost modes (0 copy, 1 Dirichlet) of the two sides
            along the other axis, low then high, and their wall velocities.
        has_interior: Whether ``body`` is read.
        body: ``(solid, theta, cut_velocity, near)``: the component's solid flags, cut
            fractions and cut velocities, and the mask of `near_regions` (one covering
            everything when bodies may be anywhere): points whose neighbours all lie outside
            them take the no-body path.
        assemble_operator: False writes only ``rhs`` (the operator is known unchanged).
        operator: ``(diagonal, weights_x, weights_y)``: outputs.
        rhs: Output.
    """
    if f.size > PARALLEL_MINIMUM:
        return _build_viscosity_system_parallel(f, c, axis, sides, has_interior, body,
                                                assemble_operator, operator, rhs)
    return _build_viscosity_system_serial(f, c, axis, sides, has_interior, body,
                                          assemble_operator, operator, rhs)


@njit(cache=True)
def _is_fixed(i, j, m, n, axis, fixed_low, fixed_high, has_interior, solid):
    if axis == 0:
        if (i == 0 and fixed_low) or (i == m - 1 and fixed_high):
            return True
    else:
        if (j == 0 and fixed_low) or (j == n - 1 and fixed_high):
            return True
    return has_interior and solid[i, j]


@njit(cache=True, inline="always")
def _open(fraction):
    if fraction < OPEN_MIN:
        return 0.0
    return min(fraction, 1.0)


def _make_face_solid_velocity(loop):
    def kernel(solid, body_velocity, open_fraction, theta, cut_velocity, across_low, near, out):
        m, n = solid.shape
        for i in loop(m):
            for j in range(n):
                if not near[i + 1, j + 1]:
                    out[i, j] = 0.0
                elif solid[i, j] or open_fraction[i, j] == 0.0:
                    # A fluid point on a face closed all along: a thin body cuts the face's
                    # connection and says its velocity there.
                    out[i, j] = body_velocity[i, j]
                elif open_fraction[i, j] < 1.0:
                    t_low = theta[across_low, i, j]
                    t_high = theta[across_low + 1, i, j]
                    if t_low <= t_high and t_low <= 0.5:
                        out[i, j] = cut_velocity[across_low, i, j]
                    elif t_high <= 0.5:
                        out[i, j] = cut_velocity[across_low + 1, i, j]
                    else:
                        # No crossing along the face: the body only covers the face's dual
                        # cell (dual-cell weights), whose treatment says its velocity; 0
                        # with the others.
                        out[i, j] = body_velocity[i, j]
                else:
                    out[i, j] = 0.0
    return kernel


(_face_solid_velocity_serial,
 _face_solid_velocity_parallel) = serial_and_parallel(_make_face_solid_velocity)


@njit(cache=True)
def face_solid_velocity(solid, body_velocity, open_fraction, theta, cut_velocity, across_low,
                        near, out):
    """Body velocity component at every face that is not fully open, 0 elsewhere.

    Faces whose point is inside a body, or that are closed all along (open fraction exactly
    0: a body thinner than a cell cuts them), take ``body_velocity``; partly open faces with
    their point in fluid take the velocity at the nearer crossing along the face (directions
    ``across_low`` and ``across_low + 1``, within half a spacing), or ``body_velocity`` when
    there is none (0 but where the dual-cell treatment covers the face's dual cell). A point whose block
    ``near[i + 1, j + 1]`` (`near_regions`) is False is fully open: 0, body arrays unread.
    """
    if solid.size > PARALLEL_MINIMUM:
        return _face_solid_velocity_parallel(solid, body_velocity, open_fraction, theta,
                                             cut_velocity, across_low, near, out)
    return _face_solid_velocity_serial(solid, body_velocity, open_fraction, theta, cut_velocity,
                                       across_low, near, out)


def _make_pressure_rhs(loop):
    def kernel(u, v, scale, has_interior, open_x, open_y, solid_u, solid_v, rhs):
        nx, ny = rhs.shape
        for i in loop(nx):
            for j in range(ny):
                if has_interior:
                    a_east = _open(open_x[i + 1, j])
                    a_west = _open(open_x[i, j])
                    a_north = _open(open_y[i, j + 1])
                    a_south = _open(open_y[i, j])
                    flux = (
                        a_east * u[i + 1, j] + (1.0 - a_east) * solid_u[i + 1, j]
                        - a_west * u[i, j] - (1.0 - a_west) * solid_u[i, j]
                        + a_north * v[i, j + 1] + (1.0 - a_north) * solid_v[i, j + 1]
                        - a_south * v[i, j] - (1.0 - a_south) * solid_v[i, j]
                    )
                else:
                    flux = u[i + 1, j] - u[i, j] + v[i, j + 1] - v[i, j]
                rhs[i, j] = -scale * flux
    return kernel


_pressure_rhs_serial, _pressure_rhs_parallel = serial_and_parallel(_make_pressure_rhs)


@njit(cache=True)
def pressure_rhs(u, v, scale, has_interior, open_x, open_y, solid_u, solid_v, rhs):
    """``rhs = -scale * h * div(A w + (1 - A) u_s)`` per cell, ``scale = rho h / dt``.

    ``h * div`` is the sum of signed face fluxes; all faces, domain sides included, enter with
    their current values.
    """
    if rhs.size > PARALLEL_MINIMUM:
        return _pressure_rhs_parallel(u, v, scale, has_interior, open_x, open_y, solid_u, solid_v,
                                      rhs)
    return _pressure_rhs_serial(u, v, scale, has_interior, open_x, open_y, solid_u, solid_v, rhs)


def _make_build_pressure_operator(loop):
    def kernel(open_x, open_y, outflow, diagonal, weights_x, weights_y):
        nx, ny = diagonal.shape
        for i in loop(nx):
            for j in range(ny):
                d = 0.0
                if i == 0 and outflow[0]:
                    d += 2.0 * _open(open_x[0, j])
                if i == nx - 1 and outflow[1]:
                    d += 2.0 * _open(open_x[nx, j])
                if j == 0 and outflow[2]:
                    d += 2.0 * _open(open_y[i, 0])
                if j == ny - 1 and outflow[3]:
                    d += 2.0 * _open(open_y[i, ny])
                diagonal[i, j] = d
                if i + 1 < nx:
                    weights_x[i, j] = _open(open_x[i + 1, j])
                if j + 1 < ny:
                    weights_y[i, j] = _open(open_y[i, j + 1])
    return kernel


(_build_pressure_operator_serial,
 _build_pressure_operator_parallel) = serial_and_parallel(_make_build_pressure_operator)


@njit(cache=True)
def build_pressure_operator(open_x, open_y, outflow, diagonal, weights_x, weights_y):
    """Face weights = open fractions; an outflow side adds ``2 A`` (p = 0 on the side)."""
    if diagonal.size > PARALLEL_MINIMUM:
        return _build_pressure_operator_parallel(open_x, open_y, outflow, diagonal, weights_x,
                                                 weights_y)
    return _build_pressure_operator_serial(open_x, open_y, outflow, diagonal, weights_x, weights_y)


def _make_subtract_pressure_gradient(loop):
    def kernel(u, v, p, k, outflow, has_interior, open_x, open_y, solid_u, solid_v):
        nx, ny = p.shape
        for i in loop(nx + 1):
            for j in range(ny):
                if i == 0:
                    if not outflow[0]:
                        continue
                    gradient = 2.0 * p[0, j]
                elif i == nx:
                    if not outflow[1]:
                        continue
                    gradient = -p[nx - 1, j] - p[nx - 1, j]
                else:
                    gradient = p[i, j] - p[i - 1, j]
                if has_interior and _open(open_x[i, j]) == 0.0:
                    u[i, j] = solid_u[i, j]
                else:
                    u[i, j] -= k * gradient
        for i in loop(nx):
            for j in range(ny + 1):
                if j == 0:
                    if not outflow[2]:
                        continue
                    gradient = 2.0 * p[i, 0]
                elif j == ny:
                    if not outflow[3]:
                        continue
                    gradient = -2.0 * p[i, ny - 1]
                else:
                    gradient = p[i, j] - p[i, j - 1]
                if has_interior and _open(open_y[i, j]) == 0.0:
                    v[i, j] = solid_v[i, j]
                else:
                    v[i, j] -= k * gradient
    return kernel


(_subtract_pressure_gradient_serial,
 _subtract_pressure_gradient_parallel) = serial_and_parallel(_make_subtract_pressure_gradient)


@njit(cache=True)
def subtract_pressure_gradient(u, v, p, k, outflow, has_interior, open_x, open_y, solid_u,
                               solid_v):
    """``u = w - (dt/rho) grad p`` on faces with A > 0, ``u = u_s`` on closed faces.

    ``k = dt / (rho h)``. Wall and inflow sides keep their prescribed values; an outflow side
    uses the ghost pressure ``-p`` of its Dirichlet condition.
    """
    if p.size > PARALLEL_MINIMUM:
        return _subtract_pressure_gradient_parallel(u, v, p, k, outflow, has_interior, open_x,
                                                    open_y, solid_u, solid_v)
    return _subtract_pressure_gradient_serial(u, v, p, k, outflow, has_interior, open_x, open_y,
                                              solid_u, solid_v)


@njit(cache=True, parallel=True)
def divergence(u, v, h, has_weights, open_x, open_y, out):
    """Cell divergence ``div(A u)`` [1/s] (A = 1 without weights), shape (nx, ny)."""
    nx, ny = out.shape
    inv_h = 1.0 / h
    for i in prange(nx):
        for j in range(ny):
            if has_weights:
                flux = (
                    _open(open_x[i + 1, j]) * u[i + 1, j] - _open(open_x[i, j]) * u[i, j]
                    + _open(open_y[i, j + 1]) * v[i, j + 1] - _open(open_y[i, j]) * v[i, j]
                )
            else:
                flux = u[i + 1, j] - u[i, j] + v[i, j + 1] - v[i, j]
            out[i, j] = flux * inv_h


@njit(cache=True, parallel=True)
def add_body_forces(u, v, dye, dt, gravity_x, gravity_y, buoyancy):
    """Gravity on interior faces, and dye buoyancy ``buoyancy * dye`` upwards on y-faces."""
    nx1, ny = u.shape
    nx = nx1 - 1
    if gravity_x != 0.0:
        for i in prange(1, nx):
            for j in range(ny):
                u[i, j] += dt * gravity_x
    if gravity_y != 0.0 or buoyancy != 0.0:
        for i in prange(nx):
            for j in range(1, ny):
                v[i, j] += dt * (gravity_y + buoyancy * 0.5 * (dye[i, j - 1] + dye[i, j]))


@njit(cache=True)
def extrapolate_into(current, previous, ratio):
    """``current, previous = current + ratio (current - previous), current`` in place: the
    linear extrapolation of a field one step ahead, and the field it came from kept."""
    flat_current = current.reshape(-1)
    flat_previous = previous.reshape(-1)
    for k in range(flat_current.shape[0]):
        value = flat_current[k]
        flat_current[k] = value + ratio * (value - flat_previous[k])
        flat_previous[k] = value


@njit(cache=True)
def any_nonzero(values):
    """Whether any entry of ``values`` is not 0 (stops at the first)."""
    flat = values.reshape(-1)
    for k in range(flat.shape[0]):
        if flat[k] != 0.0:
            return True
    return False


@njit(cache=True)
def _in_pressure_equation(diagonal, weights_x, weights_y, i, j):
    """Whether cell (i, j) is a row of the pressure operator (a diagonal term or a link)."""
    nx, ny = diagonal.shape
    return (diagonal[i, j] > 0.0 or (i > 0 and weights_x[i - 1, j] > 0.0)
            or (i < nx - 1 and weights_x[i, j] > 0.0) or (j > 0 and weights_y[i, j - 1] > 0.0)
            or (j < ny - 1 and weights_y[i, j] > 0.0))


@njit(cache=True)
def extend_into_inactive(values, diagonal, weights_x, weights_y, layers):
    """Give the cells outside the pressure equation of this operator, up to ``layers`` cells
    from it, the mean of their neighbours already known (layer by layer), in place: the
    pressure a cell cleared by a moving body starts its first step from."""
    nx, ny = values.shape
    known = np.empty((nx, ny), np.bool_)
    for i in range(nx):
        for j in range(ny):
            known[i, j] = _in_pressure_equation(diagonal, weights_x, weights_y, i, j)
    fresh = np.zeros((nx, ny), np.bool_)
    for _ in range(layers):
        for i in range(nx):
            for j in range(ny):
                if known[i, j]:
                    continue
                total = 0.0
                count = 0
                if i > 0 and known[i - 1, j]:
                    total += values[i - 1, j]
                    count += 1
                if i < nx - 1 and known[i + 1, j]:
                    total += values[i + 1, j]
                    count += 1
                if j > 0 and known[i, j - 1]:
                    total += values[i, j - 1]
                    count += 1
                if j < ny - 1 and known[i, j + 1]:
                    total += values[i, j + 1]
                    count += 1
                if count:
                    values[i, j] = total / count
                    fresh[i, j] = True
        for i in range(nx):
            for j in range(ny):
                if fresh[i, j]:
                    known[i, j] = True
                    fresh[i, j] = False
