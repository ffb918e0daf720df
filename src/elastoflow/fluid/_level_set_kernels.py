"""Numba kernels of the level-set free surface: ghost-fluid pressure, level-set transport,
redistancing, volume, velocity extrapolation.

Index conventions are those of `elastoflow.grid`: the level set ``phi`` lives in the cells,
shape (nx, ny), liquid where ``phi < 0``, air where ``phi >= 0``; u on x-faces (nx+1, ny), v on
y-faces (nx, ny+1). Positions inside the kernels are in cell-index units: the centre of cell
``(i, j)`` is at ``(i, j)``, so ``u[i, j]`` is at ``(i - 1/2, j)`` and ``v[i, j]`` at
``(i, j - 1/2)``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from elastoflow import _numba  # noqa: F401  (starts Numba's threads: see _numba)
from elastoflow.fluid import _kernels as fluid_kernels

# Per-axis crossing fraction of a liquid cell's centre to the interface, as the fraction of
# the spacing h. 1e-3 is the fluid's cut-cell floor for bodies (`fluid._kernels.THETA_MIN`):
# a clamped theta changes the liquid cell's pressure by at most theta_min h |grad p| (the
# pressure there is ~theta h |grad p| anyway), while 1/theta_min = 1000 on the diagonal is
# what the multigrid-CG handles without more iterations (measured in
# docs/validation/free_surface.md). Mantaflow clamps at 1e-4, Bridson's book at 1e-2.
THETA_MIN_DEFAULT = 1e-3


@njit(cache=True, inline="always")
def interface_fraction(phi_liquid: float, phi_air: float, theta_min: float) -> float:
    """Fraction theta in [theta_min, 1] of the spacing from a liquid point (phi < 0) to the
    zero of the linear interpolant towards an air point (phi >= 0)."""
    theta = phi_liquid / (phi_liquid - phi_air)
    if theta < theta_min:
        return theta_min
    if theta > 1.0:
        return 1.0
    return theta


@njit(cache=True)
def build_free_surface_operator(phi, theta_min, diagonal, weights_x, weights_y):
    """Ghost-fluid pressure operator (Gibou et al. 2002): ``A p = -h^2 lap p`` on liquid cells.

    Two liquid cells are coupled with weight 1; a liquid cell next to an air cell gets
    ``1 / theta`` on its diagonal (p = 0 at the interface, a fraction theta of the spacing
    away); air cells are inactive (all zero); domain sides are walls (no term). The operator is
    symmetric and diagonally dominant, positive definite on every liquid region that touches
    air. Returns the number of diagonal terms that are not finite (a level set holding NaN):
    the weights are 0 or 1 and the rest finite and >= 0 by construction.
    """
    nx, ny = phi.shape
    bad = 0
    for i in range(nx):
        for j in range(ny):
            diagonal[i, j] = 0.0
            if i + 1 < nx:
                weights_x[i, j] = 0.0
            if j + 1 < ny:
                weights_y[i, j] = 0.0
    for i in range(nx):
        for j in range(ny):
            here = phi[i, j]
            if here >= 0.0:
                continue
            d = 0.0
            if i + 1 < nx:
                if phi[i + 1, j] < 0.0:
                    weights_x[i, j] = 1.0
                else:
                    d += 1.0 / interface_fraction(here, phi[i + 1, j], theta_min)
            if i > 0 and phi[i - 1, j] >= 0.0:
                d += 1.0 / interface_fraction(here, phi[i - 1, j], theta_min)
            if j + 1 < ny:
                if phi[i, j + 1] < 0.0:
                    weights_y[i, j] = 1.0
                else:
                    d += 1.0 / interface_fraction(here, phi[i, j + 1], theta_min)
            if j > 0 and phi[i, j - 1] >= 0.0:
                d += 1.0 / interface_fraction(here, phi[i, j - 1], theta_min)
            diagonal[i, j] = d
            if not math.isfinite(d):
                bad += 1
    return bad


@njit(cache=True)
def liquid_bounds(phi):
    """The liquid's bounding box in cells: ``(i0, i1, j0, j1)``, the cells with ``phi < 0``
    lying in rows ``i0 <= i < i1`` and columns ``j0 <= j < j1``; (0, 0, 0, 0) without any."""
    nx, ny = phi.shape
    i0, i1, j0, j1 = nx, 0, ny, 0
    for i in range(nx):
        row_low = ny
        row_high = -1
        for j in range(ny):
            if phi[i, j] < 0.0:
                row_low = min(row_low, j)
                row_high = j
        if row_high >= 0:
            i0 = min(i0, i)
            i1 = i + 1
            j0 = min(j0, row_low)
            j1 = max(j1, row_high + 1)
    if i1 == 0:
        return 0, 0, 0, 0
    return i0, i1, j0, j1


@njit(cache=True, inline="always")
def _face_gradient(p_low, p_high, phi_low, phi_high, surface_low, surface_high, theta_min):
    """``(p_high - p_low)`` across one face, with the ghost-fluid value on an air side: the
    surface a fraction theta away holds the liquid cell's ``surface_*`` pressure (0 for an
    inviscid surface); the second result says whether the face has liquid on a side."""
    low_liquid = phi_low < 0.0
    high_liquid = phi_high < 0.0
    if low_liquid and high_liquid:
        return p_high - p_low, True
    if low_liquid:
        return (surface_low - p_low) / interface_fraction(phi_low, phi_high, theta_min), True
    if high_liquid:
        return (p_high - surface_high) / interface_fraction(phi_high, phi_low, theta_min), True
    return 0.0, False


@njit(cache=True, parallel=True)
def subtract_free_surface_gradient(u, v, p, phi, surface, k, theta_min, valid_u, valid_v):
    """``u -= (dt / rho) grad p`` on faces with liquid on a side, with the ghost pressure of
    ``build_free_surface_operator``; ``k = dt / (rho h)``; ``surface`` [Pa], shape (nx, ny):
    the pressure the surface holds next to each liquid cell (zeros: p = 0).

    Marks ``valid_u`` / ``valid_v`` (int32, face shapes) 1 on the faces solved and on the wall
    faces of liquid cells, 0 elsewhere (the faces `extrapolate_faces` fills). Wall faces keep
    their values.
    """
    nx, ny = phi.shape
    for i in prange(nx + 1):
        for j in range(ny):
            if i == 0:
                valid_u[i, j] = 1 if phi[0, j] < 0.0 else 0
                continue
            if i == nx:
                valid_u[i, j] = 1 if phi[nx - 1, j] < 0.0 else 0
                continue
            gradient, solved = _face_gradient(p[i - 1, j], p[i, j], phi[i - 1, j], phi[i, j],
                                              surface[i - 1, j], surface[i, j], theta_min)
            if solved:
                u[i, j] -= k * gradient
                valid_u[i, j] = 1
            else:
                valid_u[i, j] = 0
    for i in prange(nx):
        for j in range(ny + 1):
            if j == 0:
                valid_v[i, j] = 1 if phi[i, 0] < 0.0 else 0
                continue
            if j == ny:
                valid_v[i, j] = 1 if phi[i, ny - 1] < 0.0 else 0
                continue
            gradient, solved = _face_gradient(p[i, j - 1], p[i, j], phi[i, j - 1], phi[i, j],
                                              surface[i, j - 1], surface[i, j], theta_min)
            if solved:
                v[i, j] -= k * gradient
                valid_v[i, j] = 1
            else:
                valid_v[i, j] = 0


@njit(cache=True)
def add_surface_pressure(phi, surface, theta_min, rhs):
    """``rhs += surface / theta`` for each air neighbour of a liquid cell: the Dirichlet value
    ``surface`` [Pa] of the ghost-fluid condition moved to the right-hand side."""
    nx, ny = phi.shape
    for i in range(nx):
        for j in range(ny):
            here = phi[i, j]
            value = surface[i, j]
            if here >= 0.0 or value == 0.0:
                continue
            total = 0.0
            if i + 1 < nx and phi[i + 1, j] >= 0.0:
                total += 1.0 / interface_fraction(here, phi[i + 1, j], theta_min)
            if i > 0 and phi[i - 1, j] >= 0.0:
                total += 1.0 / interface_fraction(here, phi[i - 1, j], theta_min)
            if j + 1 < ny and phi[i, j + 1] >= 0.0:
                total += 1.0 / interface_fraction(here, phi[i, j + 1], theta_min)
            if j > 0 and phi[i, j - 1] >= 0.0:
                total += 1.0 / interface_fraction(here, phi[i, j - 1], theta_min)
            rhs[i, j] += value * total


@njit(cache=True)
def surface_normal_stress(u, v, phi, h, dynamic_viscosity, out):
    """``2 mu n . grad(u) . n`` [Pa] at each liquid cell next to air (0 elsewhere), shape
    (nx, ny): the pressure a viscous free surface holds (its normal stress balance
    ``-p + 2 mu du_n/dn = 0``), with n from central differences of phi and the velocity
    gradient at the cell centre (u_x, v_y from the cell's faces; u_y, v_x from the face
    averages of the neighbouring rows and columns)."""
    nx, ny = phi.shape
    for i in range(nx):
        for j in range(ny):
            out[i, j] = 0.0
            if phi[i, j] >= 0.0 or not _is_interface(phi, i, j):
                continue
            i0, i1 = max(i - 1, 0), min(i + 1, nx - 1)
            j0, j1 = max(j - 1, 0), min(j + 1, ny - 1)
            gx = (phi[i1, j] - phi[i0, j]) / (i1 - i0)
            gy = (phi[i, j1] - phi[i, j0]) / (j1 - j0)
            norm = math.sqrt(gx * gx + gy * gy)
            if norm == 0.0:
                continue
            nxv, nyv = gx / norm, gy / norm
            ux = (u[i + 1, j] - u[i, j]) / h
            vy = (v[i, j + 1] - v[i, j]) / h
            uy = 0.5 * ((u[i, j1] + u[i + 1, j1]) - (u[i, j0] + u[i + 1, j0])) / ((j1 - j0) * h)
            vx = 0.5 * ((v[i1, j] + v[i1, j + 1]) - (v[i0, j] + v[i0, j + 1])) / ((i1 - i0) * h)
            out[i, j] = 2.0 * dynamic_viscosity * (
                nxv * nxv * ux + nxv * nyv * (uy + vx) + nyv * nyv * vy)


@njit(cache=True)
def mark_liquid_faces(phi, valid_u, valid_v):
    """``valid_*`` = 1 on faces with liquid on a side (as `subtract_free_surface_gradient`
    marks them), 0 elsewhere; for extrapolating a velocity that was not projected."""
    nx, ny = phi.shape
    for i in range(nx + 1):
        for j in range(ny):
            low = i > 0 and phi[i - 1, j] < 0.0
            high = i < nx and phi[i, j] < 0.0
            valid_u[i, j] = 1 if (low or high) else 0
    for i in range(nx):
        for j in range(ny + 1):
            low = j > 0 and phi[i, j - 1] < 0.0
            high = j < ny and phi[i, j] < 0.0
            valid_v[i, j] = 1 if (low or high) else 0


@njit(cache=True, inline="always")
def _is_side(i, j, m, n, side_axis):
    if side_axis == 0:
        return i == 0 or i == m - 1
    return j == 0 or j == n - 1


@njit(cache=True, inline="always")
def _try_reach(f, valid, i, j, layer, side_axis, frontier, count):
    """Give the point (i, j), if not valid and not on a side, the mean of its neighbours
    valid before ``layer``; append it to ``frontier``; return the new count."""
    m, n = f.shape
    if valid[i, j] != 0 or _is_side(i, j, m, n, side_axis):
        return count
    total = 0.0
    reached = 0
    if i > 0 and 0 < valid[i - 1, j] <= layer:
        total += f[i - 1, j]
        reached += 1
    if i + 1 < m and 0 < valid[i + 1, j] <= layer:
        total += f[i + 1, j]
        reached += 1
    if j > 0 and 0 < valid[i, j - 1] <= layer:
        total += f[i, j - 1]
        reached += 1
    if j + 1 < n and 0 < valid[i, j + 1] <= layer:
        total += f[i, j + 1]
        reached += 1
    if reached == 0:
        return count
    f[i, j] = total / reached
    # Marked at once, so that a point is appended once; neighbours of this layer read only
    # points valid at earlier layers (<= layer), not this one's (layer + 1).
    valid[i, j] = layer + 1
    frontier[count, 0] = i
    frontier[count, 1] = j
    return count + 1


@njit(cache=True)
def extrapolate_faces(f, valid, layers, side_axis, frontier, previous):
    """Extend ``f`` from its valid points into the others, one layer at a time.

    A point not valid that has valid 4-neighbours (valid before this layer) takes their mean
    and becomes valid at this layer; after ``layers`` layers the points still not reached are
    set to 0 (air far from the liquid, never sampled by a back-trace shorter than ``layers``
    cells). Points on the domain sides normal to ``side_axis`` (0: the first index's ends, for
    u; 1: the second's, for v) hold wall values and are never written. After the first layer
    only the neighbours of the last layer are visited (a breadth-first front), so the cost is
    one pass over the grid plus the band.

    Args:
        f: Face values, shape (m, n), in place.
        valid: int32 (m, n), 1 where ``f`` is known, 0 elsewhere; on return the layer at which
            each point was reached (``layers + 1`` for the unreached ones).
        layers: Number of layers to extend.
        side_axis: Which index's ends are domain sides.
        frontier: int64 scratch, shape (m n, 2).
        previous: int64 scratch, shape (m n, 2).
    """
    m, n = f.shape
    count = 0
    for i in range(m):
        for j in range(n):
            count = _try_reach(f, valid, i, j, 1, side_axis, frontier, count)
    for layer in range(2, layers + 1):
        if count == 0:
            break
        last = count
        for k in range(last):
            previous[k, 0] = frontier[k, 0]
            previous[k, 1] = frontier[k, 1]
        count = 0
        for k in range(last):
            i = previous[k, 0]
            j = previous[k, 1]
            if i > 0:
                count = _try_reach(f, valid, i - 1, j, layer, side_axis, frontier, count)
            if i + 1 < m:
                count = _try_reach(f, valid, i + 1, j, layer, side_axis, frontier, count)
            if j > 0:
                count = _try_reach(f, valid, i, j - 1, layer, side_axis, frontier, count)
            if j + 1 < n:
                count = _try_reach(f, valid, i, j + 1, layer, side_axis, frontier, count)
    for i in range(m):
        for j in range(n):
            if valid[i, j] == 0 and not _is_side(i, j, m, n, side_axis):
                f[i, j] = 0.0
                valid[i, j] = layers + 1


@njit(cache=True, parallel=True)
def extrapolate_faces_pair(u, valid_u, v, valid_v, layers, scratch):
    """`extrapolate_faces` of u (``side_axis`` 0) and v (1) at once, one per thread: the two
    are independent and each is a serial breadth-first front, so the pair takes the time of
    the longer one (bitwise the two calls). ``scratch``: int64, shape (4, m n, 2), the
    fronts of u then of v."""
    for k in prange(2):
        if k == 0:
            extrapolate_faces(u, valid_u, layers, 0, scratch[0], scratch[1])
        else:
            extrapolate_faces(v, valid_v, layers, 1, scratch[2], scratch[3])


# -- the velocity's MacCormack correction ----------------------------------------------------

@njit(cache=True, inline="always")
def _reads_ghost(fx, fy, m, n):
    """Whether a bilinear sample of an (m, n) array at index coordinates (fx, fy) reads a
    point beyond the array's ends: a domain side's ghost value."""
    i0 = int(math.floor(fx))
    j0 = int(math.floor(fy))
    return i0 < 0 or j0 < 0 or i0 + 1 >= m or j0 + 1 >= n


@njit(cache=True, inline="always")
def _reads_air(fx, fy, liquid):
    """Whether a bilinear sample at (fx, fy) reads a point whose ``liquid`` mark is 0 (points
    beyond the ends are taken at the nearest end)."""
    m, n = liquid.shape
    i0 = int(math.floor(fx))
    j0 = int(math.floor(fy))
    for k in range(4):
        i = min(max(i0 + (k & 1), 0), m - 1)
        j = min(max(j0 + (k >> 1), 0), n - 1)
        if liquid[i, j] == 0:
            return True
    return False


@njit(cache=True, inline="always")
def _face_departure(u, v, i, j, axis, dt, h, inv_h, lx, ly, modes_u, values_u, modes_v,
                    values_v):
    """Departure point of face ``(i, j)`` of ``axis`` (0: x-faces, 1: y-faces) over ``dt``,
    in index coordinates of that component's array: the expressions of
    `elastoflow.fluid._kernels.advect` (x and y faces) without bodies, so that
    the values are bitwise theirs."""
    if axis == 0:
        x = i * h
        y = (j + 0.5) * h
        uy = fluid_kernels._sample(v, x * inv_h - 0.5, y * inv_h, modes_v, values_v)
        xb, yb = fluid_kernels._trace_back(u, v, x, y, u[i, j], uy, dt, inv_h, lx, ly,
                                           modes_u, values_u, modes_v, values_v)
        return xb * inv_h, yb * inv_h - 0.5
    x = (i + 0.5) * h
    y = j * h
    ux = fluid_kernels._sample(u, x * inv_h, y * inv_h - 0.5, modes_u, values_u)
    xb, yb = fluid_kernels._trace_back(u, v, x, y, ux, v[i, j], dt, inv_h, lx, ly,
                                       modes_u, values_u, modes_v, values_v)
    return xb * inv_h - 0.5, yb * inv_h


@njit(cache=True)
def _component(u, v, axis, h, modes_u, values_u, modes_v, values_v):
    """Component ``axis`` (0: u, 1: v) with its side ghosts, and the constants
    `_face_departure` takes: ``(f, modes, values, 1 / h, lx, ly)``."""
    inv_h = 1.0 / h
    lx = (u.shape[0] - 1) * h
    ly = u.shape[1] * h
    if axis == 0:
        return u, modes_u, values_u, inv_h, lx, ly
    return v, modes_v, values_v, inv_h, lx, ly


# Beyond the nonzero values' hull of a row, this many rows and columns: the back-trace of a
# face whose surroundings hold zeros stays on the face (nothing moves it) and reads the
# values within one index of it; two keep a margin.
_STILL_MARGIN = 2
_NO_SPAN = 1 << 40


@njit(cache=True)
def nonzero_spans(f, low, high):
    """For each row i of ``f``, the hull ``[low[i], high[i])`` of the columns holding a value
    other than 0 (NaN counts); ``low = 2^40``, ``high = -2^40`` for a row of zeros."""
    m, n = f.shape
    for i in range(m):
        first = 0
        while first < n and f[i, first] == 0.0:
            first += 1
        if first == n:
            low[i] = _NO_SPAN
            high[i] = -_NO_SPAN
            continue
        last = n
        while f[i, last - 1] == 0.0:
            last -= 1
        low[i] = first
        high[i] = last


@njit(cache=True, inline="always")
def _moving_columns(low_u, high_u, low_v, high_v, i):
    """Hull of the columns near which a face of row ``i`` may read a value other than 0
    (rows ``i - 2 .. i + 2`` of u and of v, widened by `_STILL_MARGIN`)."""
    begin = _NO_SPAN
    end = -_NO_SPAN
    for row in range(max(i - _STILL_MARGIN, 0), min(i + _STILL_MARGIN + 1, low_u.shape[0])):
        begin = min(begin, low_u[row])
        end = max(end, high_u[row])
    for row in range(max(i - _STILL_MARGIN, 0), min(i + _STILL_MARGIN + 1, low_v.shape[0])):
        begin = min(begin, low_v[row])
        end = max(end, high_v[row])
    return begin - _STILL_MARGIN, end + _STILL_MARGIN


@njit(cache=True, parallel=True)
def advect_faces_forward_range(velocity, axis, dt, h, ghosts, liquid, air, out, spans):
    """MacCormack's first pass for the free surface's velocity (`FreeSurfaceSolver.advect`):
    the component ``axis`` (0: u, 1: v) carried by (u, v) over ``dt`` [s] into ``forward``
    (the semi-Lagrangian step of `elastoflow.fluid._kernels.advect`, bitwise), and
    into ``low`` / ``high`` the range of its four values around the departure point, which
    `maccormack_faces_backward_correct` clamps to.

    Where the correction is dropped for the semi-Lagrangian value by this pass's own
    sample, the range is left empty (``low = inf``, ``high = -inf``), and the second pass
    neither traces nor corrects there:

    * the departure point's stencil reads beyond the array's ends, a domain side's ghost
      value. A no-slip wall's ghost is the reflection ``-u``: liquid falling onto the floor
      has its backward step read it while its forward step does not, and the "correction"
      accelerates the flow along the floor (the dam break gained 60 % of its energy by
      T = 7; docs/method_notes.md item 12);
    * with ``air``: the point itself, or a point of the stencil, has no liquid on either side
      (``liquid`` 0, int32 marks of the step's starting level set): air values are
      extrapolated afresh every step, not carried, so the two steps' difference there is not
      the transport's error (a drop falling into a pool gained energy from them).

    ``velocity``: ``(u, v)``; ``ghosts``: ``(modes_u, values_u, modes_v, values_v)``, the
    components' side ghosts as in `elastoflow.fluid._kernels.advect`; ``out``: ``(forward,
    low, high)``; ``spans``: ``(low_u, high_u, low_v, high_v)``, the `nonzero_spans` of u
    and v. With ``air``, an air face (whose
    correction is dropped anyway) in still surroundings, beyond them by `_STILL_MARGIN` rows
    and columns and as far from the sides, is not traced: its semi-Lagrangian value is
    +0.0 (interpolating zeros gives +0.0 whatever their signs), which it gets directly. Most
    of a dam break's air is still: the velocity is extrapolated 5 faces into it and zero
    beyond.
    """
    # Unpacked here: a parallel loop's body cannot hold a tuple of arrays.
    u, v = velocity
    modes_u, values_u, modes_v, values_v = ghosts
    forward, low, high = out
    low_u, high_u, low_v, high_v = spans
    f, modes, values, inv_h, lx, ly = _component(u, v, axis, h, modes_u, values_u, modes_v,
                                                 values_v)
    m, n = f.shape
    for i in prange(m):
        still_row = air and _STILL_MARGIN <= i < m - _STILL_MARGIN
        begin, end = _moving_columns(low_u, high_u, low_v, high_v, i)
        for j in range(n):
            if (still_row and (j < begin or j >= end) and _STILL_MARGIN <= j < n - _STILL_MARGIN
                    and liquid[i, j] == 0):
                forward[i, j] = 0.0
                low[i, j] = np.inf
                high[i, j] = -np.inf
                continue
            fx, fy = _face_departure(u, v, i, j, axis, dt, h, inv_h, lx, ly, modes_u,
                                     values_u, modes_v, values_v)
            forward[i, j], bottom, top = fluid_kernels._sample_and_range(f, fx, fy, modes,
                                                                         values)
            if _reads_ghost(fx, fy, m, n) or (air and (liquid[i, j] == 0
                                                       or _reads_air(fx, fy, liquid))):
                bottom = np.inf
                top = -np.inf
            low[i, j] = bottom
            high[i, j] = top


@njit(cache=True, parallel=True)
def maccormack_faces_backward_correct(velocity, axis, dt, h, ghosts, first_pass, out):
    """MacCormack's second pass for the free surface's velocity, after
    `advect_faces_forward_range` over the same ``dt`` [s]: ``backward`` = ``forward`` carried
    back over ``-dt``, and ``out = forward + (f - backward) / 2`` clamped to ``[low, high]``
    (Selle et al. 2008), ``f`` the component ``axis`` of (u, v); ``out = forward`` where the
    range is empty (the first pass's fallback) or where the backward departure point's
    stencil reads a domain side's ghost. Bitwise the values of a backward semi-Lagrangian
    pass and a correction pass (the three-pass form before 2026-12-03), with one back-trace
    per point fewer and none at the fallback points. ``velocity`` and ``ghosts`` as in
    `advect_faces_forward_range`; ``first_pass``: its ``(forward, low, high)``. ``out`` may
    be ``low`` or ``high`` (each point reads its own bounds first), not ``u``, ``v`` or
    ``forward``."""
    u, v = velocity
    modes_u, values_u, modes_v, values_v = ghosts
    forward, low, high = first_pass
    f, modes, values, inv_h, lx, ly = _component(u, v, axis, h, modes_u, values_u, modes_v,
                                                 values_v)
    m, n = f.shape
    for i in prange(m):
        for j in range(n):
            first = forward[i, j]
            bottom = low[i, j]
            top = high[i, j]
            if bottom > top:
                out[i, j] = first
                continue
            fx, fy = _face_departure(u, v, i, j, axis, -dt, h, inv_h, lx, ly, modes_u,
                                     values_u, modes_v, values_v)
            if _reads_ghost(fx, fy, m, n):
                out[i, j] = first
                continue
            backward = fluid_kernels._sample(forward, fx, fy, modes, values)
            corrected = first + 0.5 * (f[i, j] - backward)
            out[i, j] = min(max(corrected, bottom), top)


# -- level-set transport ---------------------------------------------------------------------

@njit(cache=True, inline="always")
def _sample_clamped(f, x, y):
    """Bilinear sample of ``f`` at index coordinates (x, y), clamped to the array (constant
    extension beyond its ends: a wall sees zero normal gradient of the level set)."""
    m, n = f.shape
    x = min(max(x, 0.0), m - 1.0)
    y = min(max(y, 0.0), n - 1.0)
    i = min(int(x), m - 2)
    j = min(int(y), n - 2)
    tx = x - i
    ty = y - j
    low = f[i, j] + tx * (f[i + 1, j] - f[i, j])
    high = f[i, j + 1] + tx * (f[i + 1, j + 1] - f[i, j + 1])
    return low + ty * (high - low)


@njit(cache=True, inline="always")
def _range_around(f, x, y):
    """Minimum and maximum of the four values that a clamped bilinear sample at (x, y) reads."""
    m, n = f.shape
    x = min(max(x, 0.0), m - 1.0)
    y = min(max(y, 0.0), n - 1.0)
    i = min(int(x), m - 2)
    j = min(int(y), n - 2)
    a, b, c, d = f[i, j], f[i + 1, j], f[i, j + 1], f[i + 1, j + 1]
    return min(min(a, b), min(c, d)), max(max(a, b), max(c, d))


@njit(cache=True, inline="always")
def _departure(u, v, x, y, step):
    """Departure point of the cell point (x, y) by the midpoint rule over ``step = dt / h``
    (negative: forwards in time), in cell-index units."""
    ux = _sample_clamped(u, x + 0.5, y)
    uy = _sample_clamped(v, x, y + 0.5)
    xm = x - 0.5 * step * ux
    ym = y - 0.5 * step * uy
    ux = _sample_clamped(u, xm + 0.5, ym)
    uy = _sample_clamped(v, xm, ym + 0.5)
    return x - step * ux, y - step * uy


@njit(cache=True, parallel=True)
def advect_cells_semi_lagrangian(phi, u, v, step, out):
    """``out = phi`` at the departure points (midpoint back-trace over ``step = dt / h``
    [cells per (m/s)], bilinear sampling): one semi-Lagrangian step of a cell field."""
    nx, ny = phi.shape
    for i in prange(nx):
        for j in range(ny):
            xd, yd = _departure(u, v, float(i), float(j), step)
            out[i, j] = _sample_clamped(phi, xd, yd)


@njit(cache=True, parallel=True)
def maccormack_correct(phi, forward, backward, u, v, step, out):
    """MacCormack's corrected value ``forward + (phi - backward) / 2`` (Selle et al. 2008),
    clamped to the range of the four values of ``phi`` around the departure point (no new
    extrema). ``forward`` is phi carried over ``step``, ``backward`` is ``forward`` carried
    back over ``-step``; ``out`` may be ``backward``."""
    nx, ny = phi.shape
    for i in prange(nx):
        for j in range(ny):
            xd, yd = _departure(u, v, float(i), float(j), step)
            low, high = _range_around(phi, xd, yd)
            value = forward[i, j] + 0.5 * (phi[i, j] - backward[i, j])
            out[i, j] = min(max(value, low), high)


@njit(cache=True, inline="always")
def _cell_departure(u, v, i, j, step, still_row, begin, end, ny):
    """`_departure` of cell (i, j); in still surroundings (``still_row``, the columns outside
    ``[begin, end)`` from `_moving_columns`, two cells from the sides) the cell itself: a
    trace through zeros ends where it started, exactly (x - step * 0 = x)."""
    if still_row and (j < begin or j >= end) and _STILL_MARGIN <= j < ny - _STILL_MARGIN:
        return float(i), float(j)
    return _departure(u, v, float(i), float(j), step)


@njit(cache=True, parallel=True)
def advect_cells_forward_range(phi, u, v, step, forward, low, high, low_u, high_u, low_v,
                               high_v):
    """MacCormack's first pass: ``forward = phi`` at the departure points (as
    `advect_cells_semi_lagrangian`), and into ``low`` / ``high`` the range of the four
    values of ``phi`` around each departure point, which `maccormack_backward_correct`
    clamps to: one back-trace per point where `maccormack_correct` traced again.
    ``low_u`` ... ``high_v``: `nonzero_spans` of u and v; in still air the departure point
    is the cell itself without a trace (the same values)."""
    nx, ny = phi.shape
    for i in prange(nx):
        still_row = _STILL_MARGIN <= i < nx - _STILL_MARGIN
        begin, end = _moving_columns(low_u, high_u, low_v, high_v, i)
        for j in range(ny):
            xd, yd = _cell_departure(u, v, i, j, step, still_row, begin, end, ny)
            forward[i, j] = _sample_clamped(phi, xd, yd)
            low[i, j], high[i, j] = _range_around(phi, xd, yd)


@njit(cache=True, parallel=True)
def maccormack_backward_correct(phi, forward, low, high, u, v, step, out, low_u, high_u, low_v,
                                high_v):
    """MacCormack's second and third passes in one: ``backward`` = ``forward`` carried back
    over ``-step``, and ``out = forward + (phi - backward) / 2`` clamped to ``[low, high]``
    (from `advect_cells_forward_range`); the same values as `advect_cells_semi_lagrangian`
    then `maccormack_correct`. ``out`` must not be ``forward``; it may be ``low`` or ``high``.
    ``low_u`` ... ``high_v`` as in `advect_cells_forward_range`."""
    nx, ny = phi.shape
    for i in prange(nx):
        still_row = _STILL_MARGIN <= i < nx - _STILL_MARGIN
        begin, end = _moving_columns(low_u, high_u, low_v, high_v, i)
        for j in range(ny):
            xd, yd = _cell_departure(u, v, i, j, -step, still_row, begin, end, ny)
            backward = _sample_clamped(forward, xd, yd)
            value = forward[i, j] + 0.5 * (phi[i, j] - backward)
            out[i, j] = min(max(value, low[i, j]), high[i, j])


# -- redistancing ----------------------------------------------------------------------------

@njit(cache=True, inline="always")
def _is_interface(phi, i, j):
    nx, ny = phi.shape
    liquid = phi[i, j] < 0.0
    if i > 0 and (phi[i - 1, j] < 0.0) != liquid:
        return True
    if i + 1 < nx and (phi[i + 1, j] < 0.0) != liquid:
        return True
    if j > 0 and (phi[i, j - 1] < 0.0) != liquid:
        return True
    if j + 1 < ny and (phi[i, j + 1] < 0.0) != liquid:
        return True
    return False


@njit(cache=True, inline="always")
def _gradient_norm(phi, i, j, h):
    """|grad phi| by central differences (one-sided on the domain's edge).

    Measured alternatives, in the dam break at a / 16 without volume correction (area change
    at T = 9.5, after the surge has run up the far wall): these central differences +8.5 %;
    with |grad phi| floored at 0.5 +20 %; per axis the largest of the central and one-sided
    differences (Russo & Smereka 2000) +318 %. Thin sheets, one or two cells thick, decide
    it; the global volume correction removes the drift whichever is used.
    """
    nx, ny = phi.shape
    i0, i1 = max(i - 1, 0), min(i + 1, nx - 1)
    j0, j1 = max(j - 1, 0), min(j + 1, ny - 1)
    gx = (phi[i1, j] - phi[i0, j]) / ((i1 - i0) * h)
    gy = (phi[i, j1] - phi[i, j0]) / ((j1 - j0) * h)
    return math.sqrt(gx * gx + gy * gy)


@njit(cache=True, inline="always")
def _eikonal_update(a, b, h):
    """The upwind solution of ``|grad d| = 1`` at a cell whose smaller neighbour distances
    are ``a`` along x and ``b`` along y (inf: none). Two infinite ones give NaN, which
    never replaces a distance."""
    if abs(a - b) >= h:
        return min(a, b) + h
    return 0.5 * (a + b + math.sqrt(2.0 * h * h - (a - b) * (a - b)))


@njit(cache=True, inline="always")
def _sweep_cell(distance, fixed, h, k, stride):
    """One Gauss-Seidel update of the padded point ``k`` (rows of ``stride``), unless fixed."""
    if not fixed[k]:
        candidate = _eikonal_update(min(distance[k - stride], distance[k + stride]),
                                    min(distance[k - 1], distance[k + 1]), h)
        if candidate < distance[k]:
            distance[k] = candidate


@njit(cache=True)
def _sweep(distance, fixed, h, nx, ny, i_first, i_step, j_first, j_step):
    """One Gauss-Seidel sweep of the padded ``distance`` (rows ``i_first, i_first + i_step,
    ...``, each in the order ``j_first, j_first + j_step, ...``; border inf and fixed).

    Two rows at a time, the second one cell behind the first: cell (i + i_step, j) is
    updated after (i, j) and (i + i_step, j - j_step), as in the row-by-row order, and
    before (i + i_step, j + j_step), which (i, j + j_step) does not read; every cell sees
    the same neighbour values as row by row (the same result, bitwise), while the two
    rows' chains of dependent updates overlap in the processor."""
    stride = ny + 2
    for pair in range(0, nx, 2):
        k = (i_first + i_step * pair + 1) * stride + 1 + j_first
        if pair + 1 == nx:
            for jj in range(ny):
                _sweep_cell(distance, fixed, h, k + j_step * jj, stride)
            continue
        below = k + i_step * stride
        _sweep_cell(distance, fixed, h, k, stride)
        for jj in range(1, ny):
            _sweep_cell(distance, fixed, h, k + j_step * jj, stride)
            _sweep_cell(distance, fixed, h, below + j_step * (jj - 1), stride)
        _sweep_cell(distance, fixed, h, below + j_step * (ny - 1), stride)


@njit(cache=True, inline="always")
def _crossing_distance(phi, i, j, h):
    """The nearest zero crossing of ``phi`` from cell (i, j) along the four grid directions
    [m] (linear interpolation towards each neighbour on the other side: the ``theta h`` of
    the ghost-fluid projection); inf if there is none."""
    nx, ny = phi.shape
    here = phi[i, j]
    liquid = here < 0.0
    best = np.inf
    for direction in range(4):
        ni, nj = i, j
        if direction == 0:
            ni = i - 1
        elif direction == 1:
            ni = i + 1
        elif direction == 2:
            nj = j - 1
        else:
            nj = j + 1
        if ni < 0 or nj < 0 or ni >= nx or nj >= ny:
            continue
        other = phi[ni, nj]
        if (other < 0.0) != liquid:
            distance = h * here / (here - other)
            if distance < best:
                best = distance
    return best


@njit(cache=True)
def redistance_fast_sweeping(phi, h, rounds, out, distance, fixed, bound_by_crossings=True):
    """Signed distance to the zero level of ``phi`` [m] by fast sweeping (Zhao 2005).

    Cells next to the interface (a 4-neighbour on the other side) keep their zero crossing:
    they become ``phi / |grad phi|`` (central differences), which leaves a signed distance
    unchanged to round-off; where that would deepen them (|grad phi| < 1) at most the distance
    to their nearest crossing along a grid direction (``bound_by_crossings``;
    `_crossing_distance`). Without that bound a sheet one or two cells thick, whose central
    differences across it nearly cancel (|grad phi| ~ 0), was rescaled to many cells' depth:
    the sheet thickened, and the global volume correction took the area back along the whole
    surface (docs/validation/free_surface.md). The bound applied also where |grad phi| >= 1
    moved smooth surfaces more: the standing wave's frequency error at 32 / 64 cells grew from
    -1.16 / -0.66 % to -1.22 / -0.70 % (-1.18 / -0.68 % as it is). The others take the first-order upwind distance from them, by
    Gauss-Seidel sweeps in the four diagonal orders, ``rounds`` times (one round is exact for
    a straight interface); signs are those of ``phi``. The whole grid is swept: leaving
    the cells farther than 8 h from the surface at their advected values (a narrow band,
    5.2 -> 1.2 ms at 256x128) let stale values far from the surface turn into liquid in the
    dam break's splash (+720 % of the liquid area without volume correction, against +8.5 %).

    Args:
        phi: Level set [m], shape (nx, ny).
        h: Cell side [m].
        rounds: Rounds of four sweeps.
        out: Result [m], shape (nx, ny), not ``phi``.
        distance: float64 scratch of the grid padded by one cell on each side, flat,
            ``(nx + 2) (ny + 2)``: the sweeps read their neighbours without bounds tests
            (the border holds inf; 3.5x faster sweeps than on the unpadded array, 256x128).
        fixed: bool scratch of the same shape.
    """
    nx, ny = phi.shape
    stride = ny + 2
    for k in range(stride):
        distance[k] = np.inf
        fixed[k] = True
        distance[(nx + 1) * stride + k] = np.inf
        fixed[(nx + 1) * stride + k] = True
    flat = phi.ravel()
    for i in range(nx):
        row = (i + 1) * stride
        distance[row] = np.inf
        fixed[row] = True
        distance[row + ny + 1] = np.inf
        fixed[row + ny + 1] = True
        # The cells next to the interface (`_is_interface`), marked first in a pass of its
        # own without the rescaling's work in the loop (init 0.51 -> 0.11 ms at 256x128).
        base = i * ny
        for j in range(ny):
            q = base + j
            liquid = flat[q] < 0.0
            interface = False
            if i > 0:
                interface |= (flat[q - ny] < 0.0) != liquid
            if i + 1 < nx:
                interface |= (flat[q + ny] < 0.0) != liquid
            if j > 0:
                interface |= (flat[q - 1] < 0.0) != liquid
            if j + 1 < ny:
                interface |= (flat[q + 1] < 0.0) != liquid
            distance[row + j + 1] = np.inf
            fixed[row + j + 1] = interface
        for j in range(ny):
            k = row + j + 1
            if fixed[k]:
                norm = _gradient_norm(phi, i, j, h)
                # A flat spot (|grad phi| ~ 0 at a crossing) cannot be rescaled: keep phi.
                value = abs(phi[i, j] / norm if norm > 1e-12 / h else phi[i, j])
                if bound_by_crossings and norm < 1.0:
                    value = min(value, _crossing_distance(phi, i, j, h))
                distance[k] = value
    for _ in range(rounds):
        _sweep(distance, fixed, h, nx, ny, 0, 1, 0, 1)
        _sweep(distance, fixed, h, nx, ny, nx - 1, -1, 0, 1)
        _sweep(distance, fixed, h, nx, ny, nx - 1, -1, ny - 1, -1)
        _sweep(distance, fixed, h, nx, ny, 0, 1, ny - 1, -1)
    for i in range(nx):
        row = (i + 1) * stride + 1
        for j in range(ny):
            # No surface reaches this cell (a grid all liquid or all air, or a region the
            # sweeps did not reach): keep phi rather than an infinite distance.
            value = distance[row + j]
            if value == np.inf:
                value = abs(phi[i, j])
            out[i, j] = -value if phi[i, j] < 0.0 else value


# -- volume ----------------------------------------------------------------------------------

@njit(cache=True)
def liquid_area(phi, h):
    """Liquid area [m^2] as the sum of cell fractions ``clamp(1/2 - phi / h, 0, 1) h^2``, and
    the number of cells on the ramp (``|phi| < h / 2``, where the area changes with phi).

    The fraction is exact for a straight interface along a grid line; it is the measure the
    global volume correction keeps.
    """
    nx, ny = phi.shape
    total = 0.0
    ramp = 0
    for i in range(nx):
        for j in range(ny):
            fraction = 0.5 - phi[i, j] / h
            if fraction >= 1.0:
                total += 1.0
            elif fraction > 0.0:
                total += fraction
                ramp += 1
    return total * h * h, ramp


# -- viscosity with a stress-free surface ------------------------------------------------------

@njit(cache=True)
def stress_free_ghosts(u, v, valid_u, valid_v, ghost_u, ghost_v):
    """Velocities of the air faces next to the liquid that make the surface's shear stress
    ``du/dy + dv/dx`` zero (Harlow & Welch 1965's free-surface condition, one face at a time).

    An air u-face above a liquid u-face takes ``u_below - (v_right - v_left)`` (the v faces
    at the corner between them), below one ``u_above + (v_right - v_left)``; an air v-face
    right of a liquid v-face ``v_left - (u_above - u_below)``, left of one
    ``v_right + (u_above - u_below)``. Along the normal (an air u-face beside a liquid u-face)
    the neighbour's value is taken. Several liquid neighbours: the mean. Other faces: their
    own value.
    """
    m, n = u.shape
    for i in range(m):
        for j in range(n):
            ghost_u[i, j] = u[i, j]
            if valid_u[i, j] == 1 or i == 0 or i == m - 1:
                continue
            total = 0.0
            count = 0
            if j > 0 and valid_u[i, j - 1] == 1:
                total += u[i, j - 1] - (v[i, j] - v[i - 1, j])
                count += 1
            if j + 1 < n and valid_u[i, j + 1] == 1:
                total += u[i, j + 1] + (v[i, j + 1] - v[i - 1, j + 1])
                count += 1
            if valid_u[i - 1, j] == 1:
                total += u[i - 1, j]
                count += 1
            if valid_u[i + 1, j] == 1:
                total += u[i + 1, j]
                count += 1
            if count > 0:
                ghost_u[i, j] = total / count
    m, n = v.shape
    for i in range(m):
        for j in range(n):
            ghost_v[i, j] = v[i, j]
            if valid_v[i, j] == 1 or j == 0 or j == n - 1:
                continue
            total = 0.0
            count = 0
            if i > 0 and valid_v[i - 1, j] == 1:
                total += v[i - 1, j] - (u[i, j] - u[i, j - 1])
                count += 1
            if i + 1 < m and valid_v[i + 1, j] == 1:
                total += v[i + 1, j] + (u[i + 1, j] - u[i + 1, j - 1])
                count += 1
            if valid_v[i, j - 1] == 1:
                total += v[i, j - 1]
                count += 1
            if valid_v[i, j + 1] == 1:
                total += v[i, j + 1]
                count += 1
            if count > 0:
                ghost_v[i, j] = total / count


@njit(cache=True)
def build_liquid_viscosity(f, valid, ghost, c, side_axis, wall_low, wall_high,
                           wall_value_low, wall_value_high, diagonal, weights_x, weights_y,
                           rhs):
    """``(I - c lap) f_new = f`` on the liquid's faces of one velocity component (backward
    Euler, ``c = nu dt / h^2``), as an `Operator5Point` over the face array.

    Unknowns: faces with ``valid == 1`` that are not on the domain sides normal to
    ``side_axis`` (those hold the wall's normal velocity). A neighbour that is an air face
    enters with its ``ghost`` value (`stress_free_ghosts`), a side face with its value, and
    beyond a tangential wall the reflection ``2 U - f`` where ``wall_* = 2`` (no slip, wall
    velocity ``wall_value_*``) or nothing where ``wall_* = 0`` (free slip); low / high are
    the ends of the other index. Air faces are inactive (the solver returns 0 there).
    """
    m, n = f.shape
    diagonal[...] = 0.0
    weights_x[...] = 0.0
    weights_y[...] = 0.0
    rhs[...] = 0.0
    for i in range(m):
        for j in range(n):
            if valid[i, j] != 1:
                continue
            if (side_axis == 0 and (i == 0 or i == m - 1)) or (
                    side_axis == 1 and (j == 0 or j == n - 1)):
                continue
            d = 1.0
            r = f[i, j]
            for direction in range(4):
                ni, nj = i, j
                if direction == 0:
                    ni = i - 1
                elif direction == 1:
                    ni = i + 1
                elif direction == 2:
                    nj = j - 1
                else:
                    nj = j + 1
                if ni < 0 or nj < 0 or ni >= m or nj >= n:
                    # Beyond a tangential wall (the other index's ends).
                    low = ni < 0 or nj < 0
                    factor = wall_low if low else wall_high
                    value = wall_value_low if low else wall_value_high
                    d += factor * c
                    r += factor * c * value
                    continue
                on_side = (side_axis == 0 and (ni == 0 or ni == m - 1)) or (
                    side_axis == 1 and (nj == 0 or nj == n - 1))
                if on_side:
                    d += c
                    r += c * f[ni, nj]
                elif valid[ni, nj] == 1:
                    if direction == 1:
                        weights_x[i, j] = c
                    elif direction == 3:
                        weights_y[i, j] = c
                else:
                    d += c
                    r += c * ghost[ni, nj]
            diagonal[i, j] = d
            rhs[i, j] = r


# -- viscosity with the full stress tensor (variational) ---------------------------------------

@njit(cache=True, inline="always")
def _fraction(phi_value, h):
    """Liquid fraction ``clamp(1/2 - phi / h, 0, 1)`` of a control volume around a point."""
    value = 0.5 - phi_value / h
    if value < 0.0:
        return 0.0
    if value > 1.0:
        return 1.0
    return value


@njit(cache=True)
def stress_viscosity_weights(phi, h, slip_left, slip_right, slip_bottom, slip_top,
                             mass_floor, w_cell, w_node, mass_u, mass_v):
    """Weights of the variational viscosity (Batty & Bridson 2008) on a level set.

    ``w_cell`` (nx, ny): the liquid fraction of each cell (where ``e_xx``, ``e_yy`` live);
    ``w_node`` (nx+1, ny+1): that of each cell corner (``e_xy``), from the mean phi of the
    cells around it, halved on a side (half its control volume is inside), 0 on a free-slip
    side (no shear there) and at the four corners (only fixed values meet there);
    ``mass_u`` / ``mass_v`` (face shapes): the liquid fraction of each face's control
    volume, at least ``mass_floor`` on faces that a weighted strain sample reads, and -1
    where the face is not an unknown (the domain sides' normal faces; faces in the air that
    no weighted sample reads). ``slip_*`` = 1 for a wall that holds the tangential velocity
    (no-slip, moving), 0 for free slip.
    """
    nx, ny = phi.shape
    for i in range(nx):
        for j in range(ny):
            w_cell[i, j] = _fraction(phi[i, j], h)
    for i in range(nx + 1):
        for j in range(ny + 1):
            total = 0.0
            count = 0
            for di in range(2):
                for dj in range(2):
                    ci, cj = i - 1 + di, j - 1 + dj
                    if 0 <= ci < nx and 0 <= cj < ny:
                        total += phi[ci, cj]
                        count += 1
            weight = _fraction(total / count, h)
            on_x = i == 0 or i == nx
            on_y = j == 0 or j == ny
            if on_x and on_y:
                weight = 0.0
            elif on_x:
                weight *= 0.5 * (slip_left if i == 0 else slip_right)
            elif on_y:
                weight *= 0.5 * (slip_bottom if j == 0 else slip_top)
            w_node[i, j] = weight
    for i in range(nx + 1):
        for j in range(ny):
            if i == 0 or i == nx:
                mass_u[i, j] = -1.0
                continue
            mass = _fraction(0.5 * (phi[i - 1, j] + phi[i, j]), h)
            read = (w_cell[i - 1, j] > 0.0 or w_cell[i, j] > 0.0 or w_node[i, j] > 0.0
                    or w_node[i, j + 1] > 0.0)
            if mass > 0.0 or read:
                mass_u[i, j] = max(mass, mass_floor)
            else:
                mass_u[i, j] = -1.0
    for i in range(nx):
        for j in range(ny + 1):
            if j == 0 or j == ny:
                mass_v[i, j] = -1.0
                continue
            mass = _fraction(0.5 * (phi[i, j - 1] + phi[i, j]), h)
            read = (w_cell[i, j - 1] > 0.0 or w_cell[i, j] > 0.0 or w_node[i, j] > 0.0
                    or w_node[i + 1, j] > 0.0)
            if mass > 0.0 or read:
                mass_v[i, j] = max(mass, mass_floor)
            else:
                mass_v[i, j] = -1.0


@njit(cache=True)
def _strain_gradient(u, v, w_cell, w_node, walls, out_u, out_v):
    """Gradient of ``E = sum_cells w (du_x^2 + dv_y^2) + sum_nodes w (du_y + dv_x)^2 / 2``
    (differences along one spacing) with respect to every face velocity, into ``out_*``.
    Beyond a side the tangential velocity's ghost is the reflection ``2 U - f`` with
    ``walls = (U_left, U_right, U_bottom, U_top)`` (zeros for the linear part)."""
    nx, ny = w_cell.shape
    out_u[...] = 0.0
    out_v[...] = 0.0
    _strain_gradient_box(u, v, w_cell, w_node, walls, out_u, out_v, 0, nx, 0, ny)


@njit(cache=True, inline="always")
def _strain_gradient_cell(u, v, w_cell, out_u, out_v, i, j):
    """The cell (i, j)'s terms of `_strain_gradient` (its weight is not 0)."""
    w = w_cell[i, j]
    a = 2.0 * w * (u[i + 1, j] - u[i, j])
    out_u[i + 1, j] += a
    out_u[i, j] -= a
    b = 2.0 * w * (v[i, j + 1] - v[i, j])
    out_v[i, j + 1] += b
    out_v[i, j] -= b


@njit(cache=True, inline="always")
def _strain_gradient_node(u, v, w_node, walls, out_u, out_v, i, j, nx, ny):
    """The corner (i, j)'s terms of `_strain_gradient` (its weight is not 0)."""
    w = w_node[i, j]
    # du/dy at the corner: u[i, j] above, u[i, j - 1] below (ghost beyond a side).
    if j == 0:
        du, d_above, d_below = 2.0 * (u[i, 0] - walls[2]), 2.0, 0.0
    elif j == ny:
        du, d_above, d_below = 2.0 * (walls[3] - u[i, ny - 1]), 0.0, -2.0
    else:
        du, d_above, d_below = u[i, j] - u[i, j - 1], 1.0, -1.0
    if i == 0:
        dv, d_right, d_left = 2.0 * (v[0, j] - walls[0]), 2.0, 0.0
    elif i == nx:
        dv, d_right, d_left = 2.0 * (walls[1] - v[nx - 1, j]), 0.0, -2.0
    else:
        dv, d_right, d_left = v[i, j] - v[i - 1, j], 1.0, -1.0
    s = w * (du + dv)
    if j < ny:
        out_u[i, j] += s * d_above
    if j > 0:
        out_u[i, j - 1] += s * d_below
    if i < nx:
        out_v[i, j] += s * d_right
    if i > 0:
        out_v[i - 1, j] += s * d_left


@njit(cache=True, inline="always")
def _strain_gradient_box(u, v, w_cell, w_node, walls, out_u, out_v, i0, i1, j0, j1):
    """`_strain_gradient` over the cells [i0, i1) x [j0, j1) and their corners, added into
    ``out_*`` (which the caller zeroed on the box's faces); every weighted sample must be
    in the box (`_weighted_box`)."""
    nx, ny = w_cell.shape
    for i in range(i0, i1):
        for j in range(j0, j1):
            if w_cell[i, j] != 0.0:
                _strain_gradient_cell(u, v, w_cell, out_u, out_v, i, j)
    for i in range(i0, i1 + 1):
        for j in range(j0, j1 + 1):
            if w_node[i, j] != 0.0:
                _strain_gradient_node(u, v, w_node, walls, out_u, out_v, i, j, nx, ny)


@njit(cache=True, inline="always")
def _strain_gradient_listed(u, v, w_cell, w_node, walls, out_u, out_v, cells, nodes):
    """`_strain_gradient_box` over the weighted cells and corners listed (in the box's row
    order, so the same sums)."""
    nx, ny = w_cell.shape
    for k in range(cells.shape[0]):
        _strain_gradient_cell(u, v, w_cell, out_u, out_v, cells[k, 0], cells[k, 1])
    for k in range(nodes.shape[0]):
        _strain_gradient_node(u, v, w_node, walls, out_u, out_v, nodes[k, 0], nodes[k, 1],
                              nx, ny)


@njit(cache=True)
def _weighted_box(w_cell, w_node):
    """The smallest box of cells [i0, i1) x [j0, j1) that holds every cell with a weight and
    the four cells around every corner with one (empty: i0 >= i1)."""
    nx, ny = w_cell.shape
    i0, i1, j0, j1 = nx, 0, ny, 0
    for i in range(nx):
        for j in range(ny):
            if w_cell[i, j] > 0.0:
                i0, i1 = min(i0, i), max(i1, i + 1)
                j0, j1 = min(j0, j), max(j1, j + 1)
    for i in range(nx + 1):
        for j in range(ny + 1):
            if w_node[i, j] > 0.0:
                i0, i1 = min(i0, max(i - 1, 0)), max(i1, min(i + 1, nx))
                j0, j1 = min(j0, max(j - 1, 0)), max(j1, min(j + 1, ny))
    return i0, i1, j0, j1


@njit(cache=True)
def _stress_diagonal(w_cell, w_node, mass_u, mass_v, c, diag_u, diag_v):
    nx, ny = w_cell.shape
    for i in range(nx + 1):
        for j in range(ny):
            if mass_u[i, j] < 0.0:
                diag_u[i, j] = 1.0
                continue
            d = 0.0
            if i > 0:
                d += 2.0 * w_cell[i - 1, j]
            if i < nx:
                d += 2.0 * w_cell[i, j]
            d += w_node[i, j] * (4.0 if j == 0 else 1.0)
            d += w_node[i, j + 1] * (4.0 if j + 1 == ny else 1.0)
            diag_u[i, j] = mass_u[i, j] + c * d
    for i in range(nx):
        for j in range(ny + 1):
            if mass_v[i, j] < 0.0:
                diag_v[i, j] = 1.0
                continue
            d = 0.0
            if j > 0:
                d += 2.0 * w_cell[i, j - 1]
            if j < ny:
                d += 2.0 * w_cell[i, j]
            d += w_node[i, j] * (4.0 if i == 0 else 1.0)
            d += w_node[i + 1, j] * (4.0 if i + 1 == nx else 1.0)
            diag_v[i, j] = mass_v[i, j] + c * d


@njit(cache=True)
def _listed(values, i0, i1, j0, j1, nonzero):
    """The points (i, j) of [i0, i1) x [j0, j1) with ``values != 0`` (``nonzero``) or
    ``values >= 0`` (else), in row order, shape (k, 2)."""
    count = 0
    for i in range(i0, i1):
        for j in range(j0, j1):
            if (values[i, j] != 0.0) if nonzero else (values[i, j] >= 0.0):
                count += 1
    points = np.empty((count, 2), dtype=np.int64)
    k = 0
    for i in range(i0, i1):
        for j in range(j0, j1):
            if (values[i, j] != 0.0) if nonzero else (values[i, j] >= 0.0):
                points[k, 0] = i
                points[k, 1] = j
                k += 1
    return points


@njit(cache=True)
def solve_stress_viscosity(u, v, w_cell, w_node, mass_u, mass_v, c, walls, rtol, max_iterations,
                           scratch):
    """Backward-Euler viscosity with the full stress tensor, in place (Batty & Bridson 2008):
    the new velocity minimises ``sum m (u - u_old)^2 / 2 + c E(u)`` over the unknown faces
    (``mass_* >= 0``; `stress_viscosity_weights`, `_strain_gradient`), ``c = nu dt / h^2``;
    so ``(M + c K) x = -c grad E(u_old)`` for the change x, by conjugate gradients with the
    diagonal as preconditioner, to ``|r| <= rtol |b|``, over the box of the weighted
    samples only. The other faces keep their values. Natural boundary condition at the
    surface: zero viscous traction ``2 mu e . n``. Returns the iterations."""
    (x_u, x_v, r_u, r_v, z_u, z_v, p_u, p_v, q_u, q_v, d_u, d_v) = scratch
    i0, i1, j0, j1 = _weighted_box(w_cell, w_node)
    if i0 >= i1 or j0 >= j1:
        return 0
    # The box's faces: u [i0, i1] x [j0, j1), v [i0, i1) x [j0, j1].
    zeros = np.zeros(4)
    for i in range(i0, i1 + 1):
        for j in range(j0, j1):
            r_u[i, j] = 0.0
            q_u[i, j] = 0.0
    for i in range(i0, i1):
        for j in range(j0, j1 + 1):
            r_v[i, j] = 0.0
            q_v[i, j] = 0.0
    _strain_gradient_box(u, v, w_cell, w_node, walls, r_u, r_v, i0, i1, j0, j1)
    _stress_diagonal(w_cell, w_node, mass_u, mass_v, c, d_u, d_v)
    b_norm2 = 0.0
    rz = 0.0
    for i in range(i0, i1 + 1):
        for j in range(j0, j1):
            x_u[i, j] = 0.0
            if mass_u[i, j] < 0.0:
                r_u[i, j] = 0.0
                p_u[i, j] = 0.0
                continue
            r = -c * r_u[i, j]
            r_u[i, j] = r
            p_u[i, j] = r / d_u[i, j]
            b_norm2 += r * r
            rz += r * p_u[i, j]
    for i in range(i0, i1):
        for j in range(j0, j1 + 1):
            x_v[i, j] = 0.0
            if mass_v[i, j] < 0.0:
                r_v[i, j] = 0.0
                p_v[i, j] = 0.0
                continue
            r = -c * r_v[i, j]
            r_v[i, j] = r
            p_v[i, j] = r / d_v[i, j]
            b_norm2 += r * r
            rz += r * p_v[i, j]
    if b_norm2 == 0.0:
        return 0
    # The unknown faces, listed in the box's row order: the vector loops below visit only
    # them, in the order the box loops did (the same sums, bitwise), and not the box's air
    # (the splash's box is the whole grid with a few per cent of it liquid: 2.4 -> 1 ms).
    unknown_u = _listed(mass_u, i0, i1 + 1, j0, j1, False)
    unknown_v = _listed(mass_v, i0, i1, j0, j1 + 1, False)
    cells = _listed(w_cell, i0, i1, j0, j1, True)
    nodes = _listed(w_node, i0, i1 + 1, j0, j1 + 1, True)
    tolerance2 = rtol * rtol * b_norm2
    iterations = 0
    for _ in range(max_iterations):
        iterations += 1
        # q = (M + c K) p on the unknowns (p is 0 elsewhere). The strain's samples write
        # only unknown faces (a face a weighted sample reads has a mass), so only those
        # need clearing; the others keep the 0 the box's clearing above gave them.
        for k in range(unknown_u.shape[0]):
            q_u[unknown_u[k, 0], unknown_u[k, 1]] = 0.0
        for k in range(unknown_v.shape[0]):
            q_v[unknown_v[k, 0], unknown_v[k, 1]] = 0.0
        _strain_gradient_listed(p_u, p_v, w_cell, w_node, zeros, q_u, q_v, cells, nodes)
        pq = 0.0
        for k in range(unknown_u.shape[0]):
            i, j = unknown_u[k, 0], unknown_u[k, 1]
            q = mass_u[i, j] * p_u[i, j] + c * q_u[i, j]
            q_u[i, j] = q
            pq += p_u[i, j] * q
        for k in range(unknown_v.shape[0]):
            i, j = unknown_v[k, 0], unknown_v[k, 1]
            q = mass_v[i, j] * p_v[i, j] + c * q_v[i, j]
            q_v[i, j] = q
            pq += p_v[i, j] * q
        alpha = rz / pq
        r_norm2 = 0.0
        rz_new = 0.0
        for k in range(unknown_u.shape[0]):
            i, j = unknown_u[k, 0], unknown_u[k, 1]
            x_u[i, j] += alpha * p_u[i, j]
            r = r_u[i, j] - alpha * q_u[i, j]
            r_u[i, j] = r
            z_u[i, j] = r / d_u[i, j]
            r_norm2 += r * r
            rz_new += r * z_u[i, j]
        for k in range(unknown_v.shape[0]):
            i, j = unknown_v[k, 0], unknown_v[k, 1]
            x_v[i, j] += alpha * p_v[i, j]
            r = r_v[i, j] - alpha * q_v[i, j]
            r_v[i, j] = r
            z_v[i, j] = r / d_v[i, j]
            r_norm2 += r * r
            rz_new += r * z_v[i, j]
        if r_norm2 <= tolerance2:
            break
        beta = rz_new / rz
        rz = rz_new
        for k in range(unknown_u.shape[0]):
            i, j = unknown_u[k, 0], unknown_u[k, 1]
            p_u[i, j] = z_u[i, j] + beta * p_u[i, j]
        for k in range(unknown_v.shape[0]):
            i, j = unknown_v[k, 0], unknown_v[k, 1]
            p_v[i, j] = z_v[i, j] + beta * p_v[i, j]
    for k in range(unknown_u.shape[0]):
        i, j = unknown_u[k, 0], unknown_u[k, 1]
        u[i, j] += x_u[i, j]
    for k in range(unknown_v.shape[0]):
        i, j = unknown_v[k, 0], unknown_v[k, 1]
        v[i, j] += x_v[i, j]
    return iterations
