"""Kernels of the 3D boundary map: crossings of surface triangles with grid lines.

The lines parallel to one axis ``a`` are indexed by their half-grid position ``(U, V)`` in the
two other axes ``u = (a + 1) % 3``, ``v = (a + 2) % 3`` (the line through ``u = origin_u +
U h/2``, ``v = origin_v + V h/2``). A triangle crosses the line when the line's point ``q``
lies inside the triangle's projection onto the (u, v) plane.

Points on a projected edge or vertex are decided by a symbolic perturbation of ``q`` (Edelsbrunner
& Muecke's simulation of simplicity): ``q + (d, d e)`` for infinitesimal ``d >> d e > 0``. Each
edge function is evaluated with the edge's endpoints in a canonical order (lower point index
first), so that the two triangles sharing an edge see the same value to the last bit, and
an exactly zero value takes the sign of the perturbation. A line through an edge or a vertex
therefore crosses exactly the triangles that the perturbed line crosses: a closed surface is
crossed an even number of times, entering and leaving alternately.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from elastoflow._numba import serial_and_parallel
from elastoflow.coupling._area import segment_areas
from elastoflow.fluid._kernels3d import _sample_bodies

# A box of solid points that covers every index: the samples read the solid flags.
_EVERYWHERE = np.array([[-(2**62), 2**62, -(2**62), 2**62, -(2**62), 2**62]], dtype=np.int64)

# A crossing's sign: walking the line towards +a, the line enters or leaves a body there.
ENTERING = 1
LEAVING = -1


@njit(cache=True, inline="always")
def _edge_sign(p0u: float, p0v: float, p1u: float, p1v: float, qu: float, qv: float
               ) -> tuple[float, int]:
    """``(value, sign)`` of the edge function ``(p1 - p0) x (q - p0)`` with ``q`` perturbed
    by ``(d, d e)``: the value as computed, its sign (never 0 for a proper edge)."""
    value = (p1u - p0u) * (qv - p0v) - (p1v - p0v) * (qu - p0u)
    if value > 0.0:
        return value, 1
    if value < 0.0:
        return value, -1
    # d/dd of (p1 - p0) x (q + (d, d e) - p0) = (p1u - p0u) e - (p1v - p0v): the v term
    # leads unless the edge is parallel to u.
    if p1v != p0v:
        return value, 1 if p1v < p0v else -1
    if p1u != p0u:
        return value, 1 if p1u > p0u else -1
    return value, 0


@njit(cache=True, inline="always")
def _oriented_edge(points, i, j, u, v, qu, qv) -> tuple[float, int]:
    """The edge function of i -> j at q, computed in the canonical order (lower index first)
    and turned to i -> j (exact negation)."""
    if i < j:
        return _edge_sign(points[i, u], points[i, v], points[j, u], points[j, v], qu, qv)
    value, sign = _edge_sign(points[j, u], points[j, v], points[i, u], points[i, v], qu, qv)
    return -value, -sign


@njit(cache=True)
def triangle_crossings(points, triangles, axis, origin_u, origin_v, half, lines_u, lines_v,
                       fill, line_count, line_of, coordinate, triangle_of, weights, sign):
    """Every crossing of the triangles with the lines parallel to ``axis``.

    Args:
        points: Vertex positions (P, 3).
        triangles: Vertex indices (T, 3), outward orientation.
        axis: 0, 1 or 2.
        origin_u, origin_v: Grid origin along u and v [m].
        half: Half the cell side [m].
        lines_u, lines_v: Number of half-grid lines along u and v (2 n + 1).
        fill: False: only count (``line_count[L]`` per line ``L = U * lines_v + V``);
            True: also write each crossing into the next free slot of its line
            (``line_of`` holds the next free slot of each line on entry).
        line_count: Crossings per line (incremented), int64, (lines_u * lines_v,).
        line_of: Next free slot per line (fill only).
        coordinate: Coordinate along ``axis`` [m] of each crossing (fill only).
        triangle_of: Triangle of each crossing (fill only).
        weights: Barycentric weights of the crossing in its triangle, (C, 3) (fill only).
        sign: ``ENTERING`` or ``LEAVING`` (fill only), int8.
    """
    u = (axis + 1) % 3
    v = (axis + 2) % 3
    for t in range(triangles.shape[0]):
        a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        # Twice the projected signed area: the outward normal's component along the axis.
        area = ((points[b, u] - points[a, u]) * (points[c, v] - points[a, v])
                - (points[b, v] - points[a, v]) * (points[c, u] - points[a, u]))
        if area == 0.0:
            continue  # parallel to the axis: no transversal crossing
        orientation = 1 if area > 0.0 else -1
        low_u = min(points[a, u], points[b, u], points[c, u])
        high_u = max(points[a, u], points[b, u], points[c, u])
        low_v = min(points[a, v], points[b, v], points[c, v])
        high_v = max(points[a, v], points[b, v], points[c, v])
        first_u = max(int(np.ceil((low_u - origin_u) / half)), 0)
        last_u = min(int(np.floor((high_u - origin_u) / half)), lines_u - 1)
        first_v = max(int(np.ceil((low_v - origin_v) / half)), 0)
        last_v = min(int(np.floor((high_v - origin_v) / half)), lines_v - 1)
        for line_u in range(first_u, last_u + 1):
            qu = origin_u + line_u * half
            for line_v in range(first_v, last_v + 1):
                qv = origin_v + line_v * half
                e_bc, s_bc = _oriented_edge(points, b, c, u, v, qu, qv)
                if s_bc != orientation:
                    continue
                e_ca, s_ca = _oriented_edge(points, c, a, u, v, qu, qv)
                if s_ca != orientation:
                    continue
                e_ab, s_ab = _oriented_edge(points, a, b, u, v, qu, qv)
                if s_ab != orientation:
                    continue
                line = line_u * lines_v + line_v
                if fill:
                    slot = line_of[line]
                    line_of[line] += 1
                    wa = e_bc / area
                    wb = e_ca / area
                    wc = 1.0 - wa - wb
                    weights[slot, 0] = wa
                    weights[slot, 1] = wb
                    weights[slot, 2] = wc
                    coordinate[slot] = (wa * points[a, axis] + wb * points[b, axis]
                                        + wc * points[c, axis])
                    triangle_of[slot] = t
                    # An outward normal along +axis: walking towards +axis leaves the body.
                    sign[slot] = LEAVING if orientation > 0 else ENTERING
                line_count[line] += 1


@njit(cache=True)
def sort_lines(offsets, coordinate, triangle_of, weights, sign):
    """Sort each line's crossings by coordinate, leaving before entering on ties, in place."""
    for line in range(offsets.shape[0] - 1):
        begin, end = offsets[line], offsets[line + 1]
        if end - begin < 2:
            continue
        keys = np.empty(end - begin)
        for k in range(begin, end):
            keys[k - begin] = coordinate[k]
        order = np.argsort(keys, kind="mergesort")
        # Ties (a silhouette edge: the line grazes two triangles at one point) leave first.
        for k in range(1, order.shape[0]):
            m = k
            while (m > 0 and keys[order[m]] == keys[order[m - 1]]
                   and sign[begin + order[m]] < sign[begin + order[m - 1]]):
                order[m], order[m - 1] = order[m - 1], order[m]
                m -= 1
        c = coordinate[begin:end].copy()
        t = triangle_of[begin:end].copy()
        w = weights[begin:end].copy()
        s = sign[begin:end].copy()
        for k in range(order.shape[0]):
            coordinate[begin + k] = c[order[k]]
            triangle_of[begin + k] = t[order[k]]
            weights[begin + k, :] = w[order[k], :]
            sign[begin + k] = s[order[k]]


@njit(cache=True)
def solid_along_lines(offsets, coordinate, sign, lines_v, line_u0, line_v0, count_u,
                      count_v, origin, h, count, out):
    """``out[i, j, k]`` = True where the point ``origin + (i + 1/2) h`` along the axis on the
    line ``(line_u0 + 2 j, line_v0 + 2 k)`` lies inside a body: winding number (the sum of
    the signs of the crossings before it; a point exactly on a crossing counts it as passed)
    > 0.

    Args:
        offsets: Line offsets of the map (lines ``U * lines_v + V``).
        coordinate, sign: The crossings.
        lines_v: Number of half-grid lines along v.
        line_u0, line_v0: Half-grid index of the first line (1 for cell centres).
        count_u, count_v: Number of lines along u and v (step 2 in the half grid).
        origin: Grid origin along the axis [m].
        h: Cell side [m].
        count: Number of points along the axis.
        out: bool, shape (count, count_u, count_v), filled with False: lines without
            crossings are skipped (all their points are outside), and a line is left once
            its last crossing is passed.
    """
    for j in range(count_u):
        for k in range(count_v):
            line = (line_u0 + 2 * j) * lines_v + line_v0 + 2 * k
            entry = offsets[line]
            end = offsets[line + 1]
            winding = 0
            for i in range(count):
                if entry == end and winding <= 0:
                    break
                position = origin + (i + 0.5) * h
                while entry < end and coordinate[entry] <= position:
                    winding += sign[entry]
                    entry += 1
                if winding > 0:
                    out[i, j, k] = True


@njit(cache=True, inline="always")
def _plane_point(points, i, j, axis, level, out, slot):
    """Where edge i-j meets the plane ``x_axis = level``, computed from the lower point index
    first, so that both triangles sharing the edge get the same point to the last bit."""
    if i > j:
        i, j = j, i
    t = (level - points[i, axis]) / (points[j, axis] - points[i, axis])
    for d in range(3):
        out[slot, d] = points[i, d] + t * (points[j, d] - points[i, d])


@njit(cache=True)
def plane_sections(points, triangles, axis, origin, h, planes, fill, per_plane, next_slot,
                   segments):
    """The segments in which the triangles cut the planes ``x_axis = origin + p h``,
    ``p = 0 .. planes - 1``, oriented so that the body's cross-section lies on their left in
    the plane's (u, v) coordinates (``u = (axis + 1) % 3``, ``v = (axis + 2) % 3``).

    A vertex on a plane counts as above it (a symbolic shift of the plane downwards), so that
    every triangle is cut consistently with its neighbours and the sections close.

    Args:
        fill: False: only count per plane; True: write ``(au, av, bu, bv)`` into
            ``segments[next_slot[p]]`` and advance it.
    """
    u = (axis + 1) % 3
    v = (axis + 2) % 3
    corner = np.empty((2, 3))
    for t in range(triangles.shape[0]):
        a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        low = min(points[a, axis], points[b, axis], points[c, axis])
        high = max(points[a, axis], points[b, axis], points[c, axis])
        # Planes with low < level <= high cut the triangle (vertices on a plane are above it).
        first = max(int(np.floor((low - origin) / h)) + 1, 0)
        last = min(int(np.floor((high - origin) / h)), planes - 1)
        if last < first:
            continue
        # The outward normal's (u, v) part, for the orientation.
        e1 = points[b] - points[a]
        e2 = points[c] - points[a]
        normal_u = e1[v] * e2[axis] - e1[axis] * e2[v]
        normal_v = e1[axis] * e2[u] - e1[u] * e2[axis]
        for p in range(first, last + 1):
            level = origin + p * h
            if level <= low or level > high:
                continue
            count = 0
            for k in range(3):
                i = triangles[t, k]
                j = triangles[t, (k + 1) % 3]
                if (points[i, axis] >= level) != (points[j, axis] >= level):
                    if count < 2:
                        _plane_point(points, i, j, axis, level, corner, count)
                    count += 1
            if count != 2:
                continue
            if fill:
                slot = next_slot[p]
                next_slot[p] += 1
                du = corner[1, u] - corner[0, u]
                dv = corner[1, v] - corner[0, v]
                # Inside on the left: the left normal (-dv, du) points against the outward
                # normal.
                if -dv * normal_u + du * normal_v > 0.0:
                    segments[slot, 0], segments[slot, 1] = corner[1, u], corner[1, v]
                    segments[slot, 2], segments[slot, 3] = corner[0, u], corner[0, v]
                else:
                    segments[slot, 0], segments[slot, 1] = corner[0, u], corner[0, v]
                    segments[slot, 2], segments[slot, 3] = corner[1, u], corner[1, v]
            per_plane[p] += 1


@njit(cache=True)
def section_areas(segments, offsets, origin_u, origin_v, h, out):
    """``out[p, i, j]`` += area of plane p's section (``segments[offsets[p]:offsets[p+1]]``)
    inside square (i, j) of the plane."""
    for p in range(offsets.shape[0] - 1):
        if offsets[p + 1] > offsets[p]:
            segment_areas(segments[offsets[p]:offsets[p + 1]], origin_u, origin_v, h,
                          out.shape[1], out.shape[2], out[p])


@njit(cache=True)
def open_fractions_from_areas(solid, area, axis, start, out):
    """``out[x, y, z] = clip(1 - solid[p, u, v] / area, 0, 1)`` over the region of ``out``
    that ``solid`` covers: the open fraction of each face normal to ``axis``, from the
    solid area of its square (`section_areas`, indexed (plane, u, v) from ``start``'s
    (x, y, z) corner, u, v the axes after ``axis`` in cyclic order), in (x, y, z) order."""
    sizes = [0, 0, 0]
    sizes[axis] = solid.shape[0]
    sizes[(axis + 1) % 3] = solid.shape[1]
    sizes[(axis + 2) % 3] = solid.shape[2]
    for i in range(sizes[0]):
        for j in range(sizes[1]):
            for k in range(sizes[2]):
                if axis == 0:
                    s = solid[i, j, k]
                elif axis == 1:
                    s = solid[j, k, i]
                else:
                    s = solid[k, i, j]
                out[start[0] + i, start[1] + j, start[2] + k] = min(max(1.0 - s / area, 0.0),
                                                                    1.0)


@njit(cache=True)
def fill_box(out, box, value):
    """``out[i0:i1, j0:j1, k0:k1] = value`` for ``box = (i0, j0, k0, i1, j1, k1)``, the ends
    clipped to the array."""
    for i in range(box[0], min(box[3], out.shape[0])):
        for j in range(box[1], min(box[4], out.shape[1])):
            for k in range(box[2], min(box[5], out.shape[2])):
                out[i, j, k] = value


# Smallest cut distance [fraction of h] reported: a crossing exactly at a point is at
# distance 0, which the fluid's stencils (divided by theta) cannot take.
THETA_FLOOR = 1e-9


@njit(cache=True, inline="always")
def _crossing_velocity(triangles, velocities, t, weights, e, component):
    return (weights[e, 0] * velocities[triangles[t, 0], component]
            + weights[e, 1] * velocities[triangles[t, 1], component]
            + weights[e, 2] * velocities[triangles[t, 2], component])


@njit(cache=True)
def _sample_fluid(f, fx, fy, fz, solid):
    """Trilinear sample of ``f`` at index coordinates ``(fx, fy, fz)`` over its corners that
    lie in the array and outside bodies (``solid`` False), weights renormalised:
    ``(value, weight sum)``; the weight sum is 0 when no corner is fluid."""
    m, n, l = f.shape
    i0 = int(np.floor(fx))
    j0 = int(np.floor(fy))
    k0 = int(np.floor(fz))
    a = fx - i0
    b = fy - j0
    c = fz - k0
    total = 0.0
    weight_sum = 0.0
    for corner in range(8):
        i = i0 + (corner & 1)
        j = j0 + ((corner >> 1) & 1)
        k = k0 + (corner >> 2)
        if i < 0 or i >= m or j < 0 or j >= n or k < 0 or k >= l or solid[i, j, k]:
            continue
        weight = ((a if corner & 1 else 1.0 - a) * (b if (corner >> 1) & 1 else 1.0 - b)
                  * (c if corner >> 2 else 1.0 - c))
        total += weight * f[i, j, k]
        weight_sum += weight
    if weight_sum < 1e-12:
        return 0.0, 0.0
    return total / weight_sum, weight_sum


@njit(cache=True, inline="always")
def _velocity_sample(u, v, w, solid_u, solid_v, solid_w, theta_u, theta_v, theta_w, cut_u,
                     cut_v, cut_w, x, y, z, inv_h, modes, values):
    """The three velocity components at ``(x, y, z)`` (relative to the grid origin), corners
    inside bodies replaced by the cut-distance ghosts of the fluid's advection (no slip at
    the crossing), so that a sample near the wall sees the wall's value where it is."""
    su, _, _ = _sample_bodies(u, x * inv_h, y * inv_h - 0.5, z * inv_h - 0.5, modes, values, 0,
                              solid_u, theta_u, cut_u, _EVERYWHERE, 0, False, False)
    sv, _, _ = _sample_bodies(v, x * inv_h - 0.5, y * inv_h, z * inv_h - 0.5, modes, values, 0,
                              solid_v, theta_v, cut_v, _EVERYWHERE, 0, False, False)
    sw, _, _ = _sample_bodies(w, x * inv_h - 0.5, y * inv_h - 0.5, z * inv_h, modes, values, 0,
                              solid_w, theta_w, cut_w, _EVERYWHERE, 0, False, False)
    return su, sv, sw


@njit(cache=True, inline="always")
def _piece_position(piece, s):
    """Barycentric ``(beta, gamma)`` of the centroid of piece ``piece`` of a triangle cut
    into ``s^2`` similar pieces: upward ones (i + 1/3, j + 1/3) / s for i + j <= s - 1, then
    downward ones (i + 2/3, j + 2/3) / s for i + j <= s - 2, row by row."""
    up_count = s * (s + 1) // 2
    if piece < up_count:
        index = piece
        offset = 1.0 / 3.0
        rows = s
    else:
        index = piece - up_count
        offset = 2.0 / 3.0
        rows = s - 1
    i = 0
    while index >= rows - i:
        index -= rows - i
        i += 1
    return (i + offset) / s, (index + offset) / s


def _make_traction(loop):
    def kernel(surface, fluid, bodies, settings, out):
        points, velocities, triangles = surface
        u, v, w, p = fluid
        solid_u, solid_v, solid_w = bodies[0]
        theta_u, theta_v, theta_w = bodies[1]
        cut_u, cut_v, cut_w = bodies[2]
        solid_cells = bodies[3]
        (origin_x, origin_y, origin_z, h, density, mu, gravity_x, gravity_y, gravity_z, d0, d1,
         pressure_d0, pressure_d1) = settings
        inv_h = 1.0 / h
        # Beyond the domain's sides the velocity samples copy the nearest inside value.
        modes = np.zeros((1, 6), dtype=np.int64)
        values = np.zeros((1, 6))
        for t in loop(triangles.shape[0]):
            for r in range(3):
                for q in range(3):
                    out[t, r, q] = 0.0
            ia = triangles[t, 0]
            ib = triangles[t, 1]
            ic = triangles[t, 2]
            ax, ay, az = points[ia, 0], points[ia, 1], points[ia, 2]
            e1x, e1y, e1z = points[ib, 0] - ax, points[ib, 1] - ay, points[ib, 2] - az
            e2x, e2y, e2z = points[ic, 0] - ax, points[ic, 1] - ay, points[ic, 2] - az
            # The edge from b to c.
            e3x, e3y, e3z = e2x - e1x, e2y - e1y, e2z - e1z
            nx_, ny_, nz_ = _cross(e1x, e1y, e1z, e2x, e2y, e2z)
            twice_area = math.sqrt(nx_ * nx_ + ny_ * ny_ + nz_ * nz_)
            if twice_area == 0.0:
                continue
            nx_ /= twice_area
            ny_ /= twice_area
            nz_ /= twice_area
            # Surface gradient of the wall velocity, L_rq = sum over vertices v_r dphi/dx_q,
            # with grad phi_a = n x (c - b) / 2A and cyclically.
            gax, gay, gaz = _cross(nx_, ny_, nz_, e3x, e3y, e3z)
            gbx, gby, gbz = _cross(nx_, ny_, nz_, -e2x, -e2y, -e2z)
            gcx, gcy, gcz = _cross(nx_, ny_, nz_, e1x, e1y, e1z)
            trace = 0.0
            tnx = 0.0
            tny = 0.0
            tnz = 0.0
            for r in range(3):
                va = velocities[ia, r]
                vb = velocities[ib, r]
                vc = velocities[ic, r]
                lx = (va * gax + vb * gbx + vc * gcx) / twice_area
                ly = (va * gay + vb * gby + vc * gcy) / twice_area
                lz = (va * gaz + vb * gbz + vc * gcz) / twice_area
                trace += lx if r == 0 else (ly if r == 1 else lz)
                normal_r = nx_ if r == 0 else (ny_ if r == 1 else nz_)
                # (L^T n)_q = sum_r L_rq n_r.
                tnx += lx * normal_r
                tny += ly * normal_r
                tnz += lz * normal_r
            longest = max(math.sqrt(e1x * e1x + e1y * e1y + e1z * e1z),
                          math.sqrt(e2x * e2x + e2y * e2y + e2z * e2z),
                          math.sqrt(e3x * e3x + e3y * e3y + e3z * e3z))
            s = max(1, int(math.ceil(longest * inv_h - 1e-9)))
            piece_area = 0.5 * twice_area / (s * s)
            hydrostatic = density * (gravity_x * nx_ + gravity_y * ny_ + gravity_z * nz_)
            for piece in range(s * s):
                beta, gamma = _piece_position(piece, s)
                alpha = 1.0 - beta - gamma
                rx = ax + beta * e1x + gamma * e2x - origin_x
                ry = ay + beta * e1y + gamma * e2y - origin_y
                rz = az + beta * e1z + gamma * e2z - origin_z
                # Pressure over fluid cells at two distances, minus its hydrostatic part
                # rho g.x, then the quadratic with zero normal derivative at the wall
                # through them; one sample alone is carried at constant value.
                near, near_weight = _sample_fluid(
                    p, (rx + pressure_d0 * nx_) * inv_h - 0.5,
                    (ry + pressure_d0 * ny_) * inv_h - 0.5,
                    (rz + pressure_d0 * nz_) * inv_h - 0.5, solid_cells)
                far, far_weight = _sample_fluid(
                    p, (rx + pressure_d1 * nx_) * inv_h - 0.5,
                    (ry + pressure_d1 * ny_) * inv_h - 0.5,
                    (rz + pressure_d1 * nz_) * inv_h - 0.5, solid_cells)
                near -= pressure_d0 * hydrostatic
                far -= pressure_d1 * hydrostatic
                wall_pressure = 0.0
                if near_weight > 0.0 and far_weight > 0.0:
                    wall_pressure = ((pressure_d1 ** 2 * near - pressure_d0 ** 2 * far)
                                     / (pressure_d1 ** 2 - pressure_d0 ** 2))
                elif near_weight > 0.0:
                    wall_pressure = near
                elif far_weight > 0.0:
                    wall_pressure = far
                fx = -wall_pressure * nx_
                fy = -wall_pressure * ny_
                fz = -wall_pressure * nz_
                if mu > 0.0:
                    wx = (alpha * velocities[ia, 0] + beta * velocities[ib, 0]
                          + gamma * velocities[ic, 0])
                    wy = (alpha * velocities[ia, 1] + beta * velocities[ib, 1]
                          + gamma * velocities[ic, 1])
                    wz = (alpha * velocities[ia, 2] + beta * velocities[ib, 2]
                          + gamma * velocities[ic, 2])
                    f1x, f1y, f1z = _velocity_sample(
                        u, v, w, solid_u, solid_v, solid_w, theta_u, theta_v, theta_w, cut_u,
                        cut_v, cut_w, rx + d0 * nx_, ry + d0 * ny_, rz + d0 * nz_, inv_h, modes,
                        values)
                    f2x, f2y, f2z = _velocity_sample(
                        u, v, w, solid_u, solid_v, solid_w, theta_u, theta_v, theta_w, cut_u,
                        cut_v, cut_w, rx + d1 * nx_, ry + d1 * ny_, rz + d1 * nz_, inv_h, modes,
                        values)
                    # One-sided second order through the wall value: u = g d + c d^2.
                    scale = 1.0 / (d0 * d1 * (d1 - d0))
                    gx = (d1 * d1 * (f1x - wx) - d0 * d0 * (f2x - wx)) * scale
                    gy = (d1 * d1 * (f1y - wy) - d0 * d0 * (f2y - wy)) * scale
                    gz = (d1 * d1 * (f1z - wz) - d0 * d0 * (f2z - wz)) * scale
                    along = gx * nx_ + gy * ny_ + gz * nz_
                    # (grad u + grad u^T) n with grad u = L + g_n n^T and g_n.n = -tr L.
                    fx += mu * (gx - along * nx_ + tnx - 2.0 * trace * nx_)
                    fy += mu * (gy - along * ny_ + tny - 2.0 * trace * ny_)
                    fz += mu * (gz - along * nz_ + tnz - 2.0 * trace * nz_)
                fx *= piece_area
                fy *= piece_area
                fz *= piece_area
                for vertex in range(3):
                    weight = alpha if vertex == 0 else (beta if vertex == 1 else gamma)
                    out[t, vertex, 0] += weight * fx
                    out[t, vertex, 1] += weight * fy
                    out[t, vertex, 2] += weight * fz
    return kernel


_traction_serial, _traction_parallel = serial_and_parallel(_make_traction)

# Fewer triangles than this: one thread (the per-triangle work is a few microseconds).
TRACTION_PARALLEL_MINIMUM = 64


@njit(cache=True, inline="always")
def _cross(ax, ay, az, bx, by, bz):
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


@njit(cache=True)
def traction_triangles(surface, fluid, bodies, settings, force):
    """Add the fluid's traction force on every triangle to its three vertices' rows of
    ``force`` (P, 3): see `elastoflow.coupling.force_traction_3d` for the formula. Each
    triangle is cut into ``s^2`` similar pieces (``s`` its longest edge over h, rounded
    up), one sample at each piece's centroid, its force split by barycentric weights.

    Args:
        surface: ``(points (P, 3), velocities (P, 3), triangles (T, 3))`` of the map.
        fluid: ``(u, v, w, p)``: face velocities and cell pressure.
        bodies: ``((solid_u, solid_v, solid_w), (theta_u, theta_v, theta_w), (cut_u, cut_v,
            cut_w), solid_cells)``: the interior's flags, cut fractions and cut velocities.
        settings: ``(origin_x, origin_y, origin_z, h, density, mu, gravity_x, gravity_y,
            gravity_z, d0, d1, pressure_d0, pressure_d1)``: the grid, the fluid, and the
            velocity and pressure sample distances [m] along the normal.
        force: (P, 3), added to.
    """
    triangles = surface[2]
    per_triangle = np.empty((triangles.shape[0], 3, 3))
    # Each triangle's vertex forces in parallel, summed to the vertices in triangle order
    # afterwards (the same sum whatever the thread count).
    if triangles.shape[0] >= TRACTION_PARALLEL_MINIMUM:
        _traction_parallel(surface, fluid, bodies, settings, per_triangle)
    else:
        _traction_serial(surface, fluid, bodies, settings, per_triangle)
    for t in range(triangles.shape[0]):
        for vertex in range(3):
            row = triangles[t, vertex]
            for r in range(3):
                force[row, r] += per_triangle[t, vertex, r]


@njit(cache=True, inline="always")
def _xyz(axis, i, p, q):
    """The (x, y, z) index of the point ``i`` along a line along ``axis`` at ``(p, q)`` in
    the two other axes ``((axis + 1) % 3, (axis + 2) % 3)``."""
    if axis == 0:
        return i, p, q
    if axis == 1:
        return q, i, p
    return p, q, i


@njit(cache=True)
def nearest_crossings(crossings, surface, component, lines, points, out):
    """For the points along a family of lines: the distance (fraction of h) to the nearest
    crossing below (strictly) and at or above each point within one spacing, and the
    ``component`` of the surface velocity there (barycentric in the crossing's triangle).

    Args:
        crossings: ``(offsets, coordinate, sign, triangle, weights)`` of the lines along
            ``axis`` (`CrossingLines3D`'s arrays; ``sign`` is not read here).
        surface: ``(triangles, velocities)`` of the map.
        component: The velocity component sampled.
        lines: ``(axis, lines_v, line_u0, line_v0, count_u, count_v)``: the lines ``(line_u0
            + 2 p, line_v0 + 2 q)``, p < count_u, q < count_v, in half-grid units across
            ``axis`` (``lines_v`` lines per row of the map's table).
        points: ``(origin, shift, h, count)``: the points ``origin + (i + shift) h``, i <
            count, along each line.
        out: ``(theta_low, theta_high, velocity_low, velocity_high)``, (x, y, z)-indexed;
            they must come filled with ``inf`` (distances) and 0 (velocities): only the
            points next to a crossing are written, so the cost follows the crossings, not
            the grid. A point's nearest crossing below is the last one before it, so the
            crossings are visited upwards for ``theta_low`` (a later one overwrites) and
            downwards for ``theta_high``.
    """
    offsets, coordinate, _, triangle_of, weights = crossings
    triangles, velocities = surface
    axis, lines_v, line_u0, line_v0, count_u, count_v = lines
    origin, shift, h, count = points
    theta_low, theta_high, velocity_low, velocity_high = out
    for p in range(count_u):
        for q in range(count_v):
            line = (line_u0 + 2 * p) * lines_v + line_v0 + 2 * q
            begin = offsets[line]
            end = offsets[line + 1]
            for e in range(begin, end):
                c = coordinate[e]
                # The first point strictly above the crossing, and the next one (one spacing
                # away to rounding).
                i = int(np.floor((c - origin) / h - shift)) + 1
                while i > 0 and origin + (i - 1 + shift) * h > c:
                    i -= 1
                while origin + (i + shift) * h <= c:
                    i += 1
                for point in (i, i + 1):
                    if 0 <= point < count:
                        distance = (origin + (point + shift) * h - c) / h
                        if distance <= 1.0:
                            x, y, z = _xyz(axis, point, p, q)
                            theta_low[x, y, z] = max(distance, THETA_FLOOR)
                            velocity_low[x, y, z] = _crossing_velocity(
                                triangles, velocities, triangle_of[e], weights, e, component)
            for e in range(end - 1, begin - 1, -1):
                c = coordinate[e]
                # The last point at or below the crossing, and the one before it when the
                # crossing sits exactly on a point (one spacing away).
                i = int(np.floor((c - origin) / h - shift))
                while origin + (i + 1 + shift) * h <= c:
                    i += 1
                while i >= 0 and origin + (i + shift) * h > c:
                    i -= 1
                for point in (i, i - 1):
                    if 0 <= point < count:
                        distance = (c - (origin + (point + shift) * h)) / h
                        if distance <= 1.0:
                            x, y, z = _xyz(axis, point, p, q)
                            theta_high[x, y, z] = max(distance, THETA_FLOOR)
                            velocity_high[x, y, z] = _crossing_velocity(
                                triangles, velocities, triangle_of[e], weights, e, component)


@njit(cache=True)
def inside_along_lines(crossings, surface, component, lines, points, out):
    """For the points along a family of lines: whether each lies inside a body (winding
    number > 0, a point exactly on a crossing counting it as passed) and, inside, the
    ``component`` of the body velocity interpolated linearly between the crossings before
    and after it on the line (METHOD.md §5.4: exact for rigid motion along the line).

    ``crossings``, ``surface``, ``lines`` and ``points`` as in `nearest_crossings`; ``out``:
    ``(solid, velocity)``, (x, y, z)-indexed, which must come filled with False and 0: lines
    without crossings are skipped (all their points are outside), and a line is left once
    its last crossing is passed.
    """
    offsets, coordinate, sign, triangle_of, weights = crossings
    triangles, velocities = surface
    axis, lines_v, line_u0, line_v0, count_u, count_v = lines
    origin, shift, h, count = points
    solid, velocity = out
    for p in range(count_u):
        for q in range(count_v):
            line = (line_u0 + 2 * p) * lines_v + line_v0 + 2 * q
            begin = offsets[line]
            end = offsets[line + 1]
            if begin == end:
                continue
            entry = begin
            winding = 0
            for i in range(count):
                position = origin + (i + shift) * h
                while entry < end and coordinate[entry] <= position:
                    winding += sign[entry]
                    entry += 1
                if entry == end and winding <= 0:
                    break
                if winding > 0:
                    x, y, z = _xyz(axis, i, p, q)
                    solid[x, y, z] = True
                    if entry > begin and entry < end:
                        before = entry - 1
                        low = _crossing_velocity(triangles, velocities, triangle_of[before],
                                                 weights, before, component)
                        high = _crossing_velocity(triangles, velocities, triangle_of[entry],
                                                  weights, entry, component)
                        span = coordinate[entry] - coordinate[before]
                        t = (position - coordinate[before]) / span if span > 0.0 else 0.5
                        velocity[x, y, z] = low + t * (high - low)


# The most vertices a tetrahedron's plane section (4) keeps after clipping to a square: each
# of the square's four sides adds at most one.
_CLIPPED_MAX = 8
# A plane cuts a tetrahedron in at most four edges.
_SECTION_MAX = 4
# Corners of a tetrahedron.
_CORNERS = 4


# Columns of `tetrahedron_sections`' values.
SECTION_WEIGHT = 0
SECTION_SLOPE_U = 1
SECTION_SLOPE_V = 2
SECTION_AREA = 3
SECTION_MOMENT_U = 4
SECTION_MOMENT_V = 5
SECTION_COLUMNS = 6


@njit(cache=True, inline="always")
def _edge_vector(points, tetrahedra, t, k, d):
    """Component d of the edge from corner 0 to corner k of tetrahedron t."""
    return points[tetrahedra[t, k], d] - points[tetrahedra[t, 0], d]


@njit(cache=True, inline="always")
def _tetrahedron_volume6(points, tetrahedra, t):
    """Six times the signed volume ``((b - a) x (c - a)).(d - a)``."""
    e1x, e1y, e1z = (_edge_vector(points, tetrahedra, t, 1, 0),
                     _edge_vector(points, tetrahedra, t, 1, 1),
                     _edge_vector(points, tetrahedra, t, 1, 2))
    e2x, e2y, e2z = (_edge_vector(points, tetrahedra, t, 2, 0),
                     _edge_vector(points, tetrahedra, t, 2, 1),
                     _edge_vector(points, tetrahedra, t, 2, 2))
    e3x, e3y, e3z = (_edge_vector(points, tetrahedra, t, 3, 0),
                     _edge_vector(points, tetrahedra, t, 3, 1),
                     _edge_vector(points, tetrahedra, t, 3, 2))
    return (e1x * (e2y * e3z - e2z * e3y) - e1y * (e2x * e3z - e2z * e3x)
            + e1z * (e2x * e3y - e2y * e3x))


@njit(cache=True)
def _barycentric_gradients(points, tetrahedra, t, out):
    """``out[c]``: the gradient [1/m] of corner c's barycentric function in tetrahedron t
    (not flat): ``grad lambda_1 = (e2 x e3) / 6V`` and cyclically, corner 0's minus their
    sum."""
    volume6 = _tetrahedron_volume6(points, tetrahedra, t)
    for k in range(3):
        # lambda_{k+1} is 0 on the face opposite corner k+1: its gradient is that face's
        # normal (e_{k+2} x e_{k+3}) over 6V.
        b = (k + 1) % 3 + 1
        c = (k + 2) % 3 + 1
        bx, by, bz = (_edge_vector(points, tetrahedra, t, b, 0),
                      _edge_vector(points, tetrahedra, t, b, 1),
                      _edge_vector(points, tetrahedra, t, b, 2))
        cx, cy, cz = (_edge_vector(points, tetrahedra, t, c, 0),
                      _edge_vector(points, tetrahedra, t, c, 1),
                      _edge_vector(points, tetrahedra, t, c, 2))
        out[k + 1, 0] = (by * cz - bz * cy) / volume6
        out[k + 1, 1] = (bz * cx - bx * cz) / volume6
        out[k + 1, 2] = (bx * cy - by * cx) / volume6
    for d in range(3):
        out[0, d] = -(out[1, d] + out[2, d] + out[3, d])


@njit(cache=True, inline="always")
def _tetrahedron_sign(points, tetrahedra, t):
    """Sign of the tetrahedron's volume: +1, -1, or 0 when flat."""
    volume6 = _tetrahedron_volume6(points, tetrahedra, t)
    if volume6 > 0.0:
        return 1.0
    if volume6 < 0.0:
        return -1.0
    return 0.0


@njit(cache=True)
def tetrahedron_section_bound(points, tetrahedra, axis, origin, h, counts, wanted,
                              face_offset):
    """An upper bound of the entries `tetrahedron_sections` writes: per tetrahedron, four per
    wanted face square inside its bounding box in each plane it crosses."""
    u = (axis + 1) % 3
    v = (axis + 2) % 3
    shape_y = counts[1] + (1 if axis == 1 else 0)
    shape_z = counts[2] + (1 if axis == 2 else 0)
    total = 0
    for t in range(tetrahedra.shape[0]):
        low, high = np.inf, -np.inf
        low_u, high_u = np.inf, -np.inf
        low_v, high_v = np.inf, -np.inf
        for k in range(_CORNERS):
            q = tetrahedra[t, k]
            low, high = min(low, points[q, axis]), max(high, points[q, axis])
            low_u, high_u = min(low_u, points[q, u]), max(high_u, points[q, u])
            low_v, high_v = min(low_v, points[q, v]), max(high_v, points[q, v])
        first = max(int(np.floor((low - origin[axis]) / h)) + 1, 0)
        last = min(int(np.floor((high - origin[axis]) / h)), counts[axis])
        first_u = max(int(np.floor((low_u - origin[u]) / h)), 0)
        last_u = min(int(np.floor((high_u - origin[u]) / h)), counts[u] - 1)
        first_v = max(int(np.floor((low_v - origin[v]) / h)), 0)
        last_v = min(int(np.floor((high_v - origin[v]) / h)), counts[v] - 1)
        for p in range(first, last + 1):
            for iu in range(first_u, last_u + 1):
                for iv in range(first_v, last_v + 1):
                    x, y, z = _xyz(axis, p, iu, iv)
                    if wanted[face_offset + (x * shape_y + y) * shape_z + z]:
                        total += _CORNERS
    return total


@njit(cache=True, inline="always")
def _edge_section(points, tetrahedra, t, i, j, axis, u, v, level, section, weights, slot):
    """Where the edge between corners i and j of tetrahedron t meets the plane: its (u, v)
    in ``section[slot]`` and its corner weights in ``weights[slot]``, computed from the lower
    point index first (the same point, to the last bit, in every tetrahedron that shares the
    edge)."""
    if tetrahedra[t, i] > tetrahedra[t, j]:
        i, j = j, i
    p, q = tetrahedra[t, i], tetrahedra[t, j]
    s = (level - points[p, axis]) / (points[q, axis] - points[p, axis])
    section[slot, 0] = points[p, u] + s * (points[q, u] - points[p, u])
    section[slot, 1] = points[p, v] + s * (points[q, v] - points[p, v])
    for k in range(_CORNERS):
        weights[slot, k] = 0.0
    weights[slot, i] = 1.0 - s
    weights[slot, j] = s


@njit(cache=True, inline="always")
def _clip_half(count, section, weights, out_section, out_weights, coordinate, bound, keep_below):
    """Sutherland-Hodgman: the convex polygon ``section[:count]`` (with its vertices' corner
    weights, interpolated along the cut edges) clipped to ``x_coordinate <= bound``
    (``keep_below``) or ``>= bound``; returns the new vertex count."""
    kept = 0
    for k in range(count):
        n = (k + 1) % count
        a = section[k, coordinate] - bound
        b = section[n, coordinate] - bound
        if not keep_below:
            a, b = -a, -b
        if a <= 0.0:
            out_section[kept, 0] = section[k, 0]
            out_section[kept, 1] = section[k, 1]
            for q in range(_CORNERS):
                out_weights[kept, q] = weights[k, q]
            kept += 1
        if (a < 0.0 < b) or (b < 0.0 < a):
            s = a / (a - b)
            out_section[kept, 0] = section[k, 0] + s * (section[n, 0] - section[k, 0])
            out_section[kept, 1] = section[k, 1] + s * (section[n, 1] - section[k, 1])
            out_section[kept, coordinate] = bound
            for q in range(_CORNERS):
                out_weights[kept, q] = weights[k, q] + s * (weights[n, q] - weights[k, q])
            kept += 1
    return kept


@njit(cache=True)
def tetrahedron_sections(points, tetrahedra, axis, origin, h, counts, face_offset, wanted,
                         rows, columns, values, start):
    """The flux weights of the tetrahedra's sections in the face planes normal to ``axis``.

    Each plane ``x_axis = origin + p h`` (``p = 0 .. counts[axis]``) cuts a tetrahedron in a
    triangle or quadrilateral on which the velocity is linear (the corners' barycentric
    weights); clipped to each face square it meets, the piece ``Q`` adds to that face's row,
    for each corner ``c``, ``sign * int_Q lambda_c dA / h^2`` on column ``3 c + axis``
    (``sign`` that of the tetrahedron's volume: negative ones subtract, so that signed cones
    over a closed surface add up to its inside). A vertex on a plane counts as above it (the
    convention of `plane_sections`), so the pieces add up to the sections the open fractions
    are computed from.

    Args:
        points: Node positions [m], (P, 3).
        tetrahedra: Corner node indices, int64, (T, 4); flat ones are skipped.
        axis: 0, 1 or 2: the faces' normal.
        origin: Grid origin [m], (3,).
        h: Cell side [m].
        counts: Cells along x, y, z, int64, (3,).
        face_offset: Flat index of this axis' first face (x faces, then y, then z).
        wanted: Per flat face index, whether to write its pieces (the others, e.g. deep
            inside a body, are skipped before clipping), bool.
        rows, columns: Outputs: flat face index and ``3 node + axis`` of each entry, from
            ``start`` on (`tetrahedron_section_bound` fits).
        values: Output, (E, `SECTION_COLUMNS`): per entry its weight (`SECTION_WEIGHT`:
            the integral above [-]), the same integral's change per unit shift [1/m] of the
            point where the corner's function is read (`SECTION_SLOPE_U`, `SECTION_SLOPE_V`:
            ``sign area grad lambda_c / h^2`` in the plane), and on the piece's first entry
            its signed area over h^2 (`SECTION_AREA`) and first moments over h^2 [m]
            (`SECTION_MOMENT_U`, `SECTION_MOMENT_V`; 0 on its other entries).
        start: First free entry.

    Returns:
        The next free entry.
    """
    u = (axis + 1) % 3
    v = (axis + 2) % 3
    shape_y = counts[1] + (1 if axis == 1 else 0)
    shape_z = counts[2] + (1 if axis == 2 else 0)
    section = np.empty((_SECTION_MAX, 2))
    section_weights = np.empty((_SECTION_MAX, _CORNERS))
    clip_a = np.empty((_CLIPPED_MAX, 2))
    clip_b = np.empty((_CLIPPED_MAX, 2))
    weights_a = np.empty((_CLIPPED_MAX, _CORNERS))
    weights_b = np.empty((_CLIPPED_MAX, _CORNERS))
    integral = np.empty(_CORNERS)
    gradients = np.empty((_CORNERS, 3))
    above = np.empty(_CORNERS, np.bool_)
    order = np.empty(_CORNERS, np.int64)
    entry = start
    inv_area = 1.0 / (h * h)
    for t in range(tetrahedra.shape[0]):
        sign = _tetrahedron_sign(points, tetrahedra, t)
        if sign == 0.0:
            continue
        low, high = np.inf, -np.inf
        for k in range(_CORNERS):
            low = min(low, points[tetrahedra[t, k], axis])
            high = max(high, points[tetrahedra[t, k], axis])
        first = max(int(np.floor((low - origin[axis]) / h)) + 1, 0)
        last = min(int(np.floor((high - origin[axis]) / h)), counts[axis])
        if last < first:
            continue
        # Formed on the first piece written: most of a body's tetrahedra lie deep inside.
        have_gradients = False
        for p in range(first, last + 1):
            level = origin[axis] + p * h
            if level <= low or level > high:
                continue
            above_count = 0
            for k in range(_CORNERS):
                above[k] = points[tetrahedra[t, k], axis] >= level
                if above[k]:
                    above_count += 1
            if above_count == 0 or above_count == _CORNERS:
                continue
            # Corners above first, then those below.
            n_above = 0
            for k in range(_CORNERS):
                if above[k]:
                    order[n_above] = k
                    n_above += 1
            n_below = n_above
            for k in range(_CORNERS):
                if not above[k]:
                    order[n_below] = k
                    n_below += 1
            if above_count == 2:
                # Around the quadrilateral: (a0 b0) (a0 b1) (a1 b1) (a1 b0).
                a0, a1, b0, b1 = order[0], order[1], order[2], order[3]
                _edge_section(points, tetrahedra, t, a0, b0, axis, u, v, level, section,
                              section_weights, 0)
                _edge_section(points, tetrahedra, t, a0, b1, axis, u, v, level, section,
                              section_weights, 1)
                _edge_section(points, tetrahedra, t, a1, b1, axis, u, v, level, section,
                              section_weights, 2)
                _edge_section(points, tetrahedra, t, a1, b0, axis, u, v, level, section,
                              section_weights, 3)
                count = 4
            else:
                # One corner alone on its side: a triangle on its three edges.
                alone = order[0] if above_count == 1 else order[3]
                count = 0
                for k in range(_CORNERS):
                    if k != alone:
                        _edge_section(points, tetrahedra, t, alone, k, axis, u, v, level,
                                      section, section_weights, count)
                        count += 1
            low_u, high_u = np.inf, -np.inf
            low_v, high_v = np.inf, -np.inf
            for k in range(count):
                low_u, high_u = min(low_u, section[k, 0]), max(high_u, section[k, 0])
                low_v, high_v = min(low_v, section[k, 1]), max(high_v, section[k, 1])
            first_u = max(int(np.floor((low_u - origin[u]) / h)), 0)
            last_u = min(int(np.floor((high_u - origin[u]) / h)), counts[u] - 1)
            first_v = max(int(np.floor((low_v - origin[v]) / h)), 0)
            last_v = min(int(np.floor((high_v - origin[v]) / h)), counts[v] - 1)
            for iu in range(first_u, last_u + 1):
                u0 = origin[u] + iu * h
                for iv in range(first_v, last_v + 1):
                    v0 = origin[v] + iv * h
                    x, y, z = _xyz(axis, p, iu, iv)
                    face = face_offset + (x * shape_y + y) * shape_z + z
                    if not wanted[face]:
                        continue
                    kept = _clip_half(count, section, section_weights, clip_a, weights_a, 0,
                                      u0, False)
                    kept = _clip_half(kept, clip_a, weights_a, clip_b, weights_b, 0, u0 + h,
                                      True)
                    kept = _clip_half(kept, clip_b, weights_b, clip_a, weights_a, 1, v0,
                                      False)
                    kept = _clip_half(kept, clip_a, weights_a, clip_b, weights_b, 1, v0 + h,
                                      True)
                    if kept < 3:
                        continue
                    # A fan from the first vertex: a linear weight integrates to each
                    # triangle's area times the mean of its corners.
                    area = 0.0
                    moment_u = 0.0
                    moment_v = 0.0
                    for q in range(_CORNERS):
                        integral[q] = 0.0
                    for k in range(1, kept - 1):
                        piece = 0.5 * ((clip_b[k, 0] - clip_b[0, 0])
                                       * (clip_b[k + 1, 1] - clip_b[0, 1])
                                       - (clip_b[k + 1, 0] - clip_b[0, 0])
                                       * (clip_b[k, 1] - clip_b[0, 1]))
                        area += piece
                        moment_u += piece * (clip_b[0, 0] + clip_b[k, 0]
                                             + clip_b[k + 1, 0]) / 3.0
                        moment_v += piece * (clip_b[0, 1] + clip_b[k, 1]
                                             + clip_b[k + 1, 1]) / 3.0
                        for q in range(_CORNERS):
                            integral[q] += piece * (weights_b[0, q] + weights_b[k, q]
                                                    + weights_b[k + 1, q]) / 3.0
                    if area == 0.0:
                        continue
                    # The section's vertex order may run either way round.
                    scale = sign * inv_area if area > 0.0 else -sign * inv_area
                    if not have_gradients:
                        _barycentric_gradients(points, tetrahedra, t, gradients)
                        have_gradients = True
                    for q in range(_CORNERS):
                        rows[entry] = face
                        columns[entry] = 3 * tetrahedra[t, q] + axis
                        values[entry, SECTION_WEIGHT] = scale * integral[q]
                        values[entry, SECTION_SLOPE_U] = scale * area * gradients[q, u]
                        values[entry, SECTION_SLOPE_V] = scale * area * gradients[q, v]
                        # The piece's own area and moments once, on its first entry.
                        once = scale if q == 0 else 0.0
                        values[entry, SECTION_AREA] = once * area
                        values[entry, SECTION_MOMENT_U] = once * moment_u
                        values[entry, SECTION_MOMENT_V] = once * moment_v
                        entry += 1
    return entry


@njit(cache=True)
def pressure_cells_3d(open_x, open_y, open_z, open_min, out):
    """``out[i, j, k]``: cell (i, j, k) has an interior face open by ``open_min`` (the
    pressure equation has it)."""
    nx, ny, nz = out.shape
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                out[i, j, k] = ((i >= 1 and open_x[i, j, k] >= open_min)
                                or (i <= nx - 2 and open_x[i + 1, j, k] >= open_min)
                                or (j >= 1 and open_y[i, j, k] >= open_min)
                                or (j <= ny - 2 and open_y[i, j + 1, k] >= open_min)
                                or (k >= 1 and open_z[i, j, k] >= open_min)
                                or (k <= nz - 2 and open_z[i, j, k + 1] >= open_min))


@njit(cache=True)
def group_by_row(rows, columns, values, row_count):
    """Triplets grouped by row with one counting pass over the row range (the faces of a
    grid: no sort): ``(rows ascending that occur, indptr, columns, values)``, each row's
    entries in their given order (`elastoflow.coupling._interface._merge_segments` then
    sorts and sums them)."""
    count = np.zeros(row_count + 1, np.int64)
    for e in range(rows.shape[0]):
        count[rows[e] + 1] += 1
    used = 0
    for r in range(row_count):
        if count[r + 1] > 0:
            used += 1
    ids = np.empty(used, np.int64)
    indptr = np.zeros(used + 1, np.int64)
    slot_of = np.empty(row_count, np.int64)
    k = 0
    for r in range(row_count):
        if count[r + 1] > 0:
            ids[k] = r
            slot_of[r] = k
            indptr[k + 1] = indptr[k] + count[r + 1]
            k += 1
    fill = indptr[:-1].copy()
    grouped_columns = np.empty(rows.shape[0], np.int64)
    grouped_values = np.empty(rows.shape[0])
    for e in range(rows.shape[0]):
        k = slot_of[rows[e]]
        grouped_columns[fill[k]] = columns[e]
        grouped_values[fill[k]] = values[e]
        fill[k] += 1
    return ids, indptr, grouped_columns, grouped_values
