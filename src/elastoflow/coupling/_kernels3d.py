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

import numpy as np
from numba import njit

from elastoflow.coupling._area import segment_areas
from elastoflow.fluid._interior_kernels3d import _sample_bodies

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
def winding_along_lines(offsets, coordinate, sign, lines_v, line_u0, line_v0, count_u,
                        count_v, origin, h, count, out):
    """``out[i, j, k]`` = winding number at the points ``origin + (i + 1/2) h`` along the
    axis on the lines ``(line_u0 + 2 j, line_v0 + 2 k)``: the sum of the signs of the
    crossings before the point (a point exactly on a crossing counts it as passed).

    Args:
        offsets: Line offsets of the map (lines ``U * lines_v + V``).
        coordinate, sign: The crossings.
        lines_v: Number of half-grid lines along v.
        line_u0, line_v0: Half-grid index of the first line (1 for cell centres).
        count_u, count_v: Number of lines along u and v (step 2 in the half grid).
        origin: Grid origin along the axis [m].
        h: Cell side [m].
        count: Number of points along the axis.
        out: Winding numbers, int32, shape (count, count_u, count_v).
    """
    for j in range(count_u):
        for k in range(count_v):
            line = (line_u0 + 2 * j) * lines_v + line_v0 + 2 * k
            entry = offsets[line]
            end = offsets[line + 1]
            winding = 0
            for i in range(count):
                position = origin + (i + 0.5) * h
                while entry < end and coordinate[entry] <= position:
                    winding += sign[entry]
                    entry += 1
                out[i, j, k] = winding


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


@njit(cache=True)
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
    return np.array((su, sv, sw))


@njit(cache=True)
def traction_triangles(points, velocities, triangles, u, v, w, p, solid_u, solid_v, solid_w,
                       theta_u, theta_v, theta_w, cut_u, cut_v, cut_w, solid_cells, origin_x, origin_y, origin_z, h, density, mu, gravity_x,
                       gravity_y, gravity_z, distances, pressure_distances, force):
    """Add the fluid's traction force on every triangle to its three vertices' rows of
    ``force`` (P, 3): see `elastoflow.coupling.force_traction_3d` for the formula. Each
    triangle is cut into ``s^2`` similar pieces (``s`` its longest edge over h, rounded
    up), one sample at each piece's centroid, its force split by barycentric weights."""
    inv_h = 1.0 / h
    d0 = distances[0]
    d1 = distances[1]
    pressure_d0 = pressure_distances[0]
    pressure_d1 = pressure_distances[1]
    # Beyond the domain's sides the velocity samples copy the nearest inside value.
    modes = np.zeros((1, 6), dtype=np.int64)
    values = np.zeros((1, 6))
    for t in range(triangles.shape[0]):
        ia = triangles[t, 0]
        ib = triangles[t, 1]
        ic = triangles[t, 2]
        e1 = points[ib] - points[ia]
        e2 = points[ic] - points[ia]
        normal = np.cross(e1, e2)
        twice_area = np.sqrt(normal[0] ** 2 + normal[1] ** 2 + normal[2] ** 2)
        if twice_area == 0.0:
            continue
        n = normal / twice_area
        # Surface gradient of the wall velocity, L_ij = sum over vertices v_i dphi/dx_j, with
        # grad phi_a = n x (c - b) / 2A and cyclically.
        grad_a = np.cross(n, points[ic] - points[ib]) / twice_area
        grad_b = np.cross(n, points[ia] - points[ic]) / twice_area
        grad_c = np.cross(n, points[ib] - points[ia]) / twice_area
        surface = np.zeros((3, 3))
        for r in range(3):
            for q in range(3):
                surface[r, q] = (velocities[ia, r] * grad_a[q] + velocities[ib, r] * grad_b[q]
                                 + velocities[ic, r] * grad_c[q])
        trace = surface[0, 0] + surface[1, 1] + surface[2, 2]
        transposed_n = surface.T @ n
        longest = max(np.sqrt(e1 @ e1), np.sqrt(e2 @ e2),
                      np.sqrt((points[ic] - points[ib]) @ (points[ic] - points[ib])))
        s = max(1, int(np.ceil(longest * inv_h - 1e-9)))
        piece_area = 0.5 * twice_area / (s * s)
        for piece in range(s * s):
            # Pieces: upward (i + 1/3, j + 1/3) for i + j <= s - 1, then downward
            # (i + 2/3, j + 2/3) for i + j <= s - 2, enumerated row by row.
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
            j = index
            beta = (i + offset) / s
            gamma = (j + offset) / s
            alpha = 1.0 - beta - gamma
            x = points[ia] + beta * e1 + gamma * e2
            wall = alpha * velocities[ia] + beta * velocities[ib] + gamma * velocities[ic]
            rx = x[0] - origin_x
            ry = x[1] - origin_y
            rz = x[2] - origin_z
            traction = np.zeros(3)
            # Pressure over fluid cells at two distances, minus its hydrostatic part
            # rho g.x, then the quadratic with zero normal derivative at the wall through
            # them; one sample alone is carried at constant value.
            hydrostatic = density * (gravity_x * n[0] + gravity_y * n[1] + gravity_z * n[2])
            near, near_weight = _sample_fluid(
                p, (rx + pressure_d0 * n[0]) * inv_h - 0.5, (ry + pressure_d0 * n[1]) * inv_h
                - 0.5, (rz + pressure_d0 * n[2]) * inv_h - 0.5, solid_cells)
            far, far_weight = _sample_fluid(
                p, (rx + pressure_d1 * n[0]) * inv_h - 0.5, (ry + pressure_d1 * n[1]) * inv_h
                - 0.5, (rz + pressure_d1 * n[2]) * inv_h - 0.5, solid_cells)
            near -= pressure_d0 * hydrostatic
            far -= pressure_d1 * hydrostatic
            if near_weight > 0.0 and far_weight > 0.0:
                traction -= ((pressure_d1 ** 2 * near - pressure_d0 ** 2 * far)
                             / (pressure_d1 ** 2 - pressure_d0 ** 2)) * n
            elif near_weight > 0.0:
                traction -= near * n
            elif far_weight > 0.0:
                traction -= far * n
            if mu > 0.0:
                first = _velocity_sample(u, v, w, solid_u, solid_v, solid_w, theta_u, theta_v,
                                         theta_w, cut_u, cut_v, cut_w, rx + d0 * n[0],
                                         ry + d0 * n[1], rz + d0 * n[2], inv_h, modes,
                                         values) - wall
                second = _velocity_sample(u, v, w, solid_u, solid_v, solid_w, theta_u, theta_v,
                                          theta_w, cut_u, cut_v, cut_w, rx + d1 * n[0],
                                          ry + d1 * n[1], rz + d1 * n[2], inv_h, modes,
                                          values) - wall
                # One-sided second order through the wall value: u = g d + c d^2.
                normal_gradient = ((d1 * d1 * first - d0 * d0 * second)
                                   / (d0 * d1 * (d1 - d0)))
                tangential = normal_gradient - (normal_gradient @ n) * n
                # (grad u + grad u^T) n with grad u = L + g_n n^T and g_n.n = -tr L.
                traction += mu * (tangential + transposed_n - 2.0 * trace * n)
            piece_force = traction * piece_area
            for r in range(3):
                force[ia, r] += alpha * piece_force[r]
                force[ib, r] += beta * piece_force[r]
                force[ic, r] += gamma * piece_force[r]


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
def nearest_crossings(offsets, coordinate, triangle_of, weights, triangles, velocities,
                          component, axis, lines_v, line_u0, line_v0, count_u, count_v, origin,
                          shift, h, count, theta_low, theta_high, velocity_low, velocity_high):
    """For the points ``origin + (i + shift) h`` along the lines ``(line_u0 + 2 p, line_v0 +
    2 q)`` along ``axis``: the distance (fraction of h) to the nearest crossing below
    (strictly) and at or above each point within one spacing, and the ``component`` of the
    surface velocity there (barycentric in the crossing's triangle).

    Outputs are (x, y, z)-indexed and must come filled with ``inf`` (distances) and 0
    (velocities): only the points next to a crossing are written, so the cost follows the
    crossings, not the grid. A point's nearest crossing below is the last one before it, so
    the crossings are visited upwards for ``theta_low`` (a later one overwrites) and
    downwards for ``theta_high``.
    """
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
def inside_along_lines(offsets, coordinate, sign, triangle_of, weights, triangles,
                           velocities, component, axis, lines_v, line_u0, line_v0, count_u,
                           count_v, origin, shift, h, count, solid, velocity):
    """For the points ``origin + (i + shift) h`` along the lines ``(line_u0 + 2 p, line_v0 +
    2 q)`` along ``axis``: whether each lies inside a body (winding number > 0, a point
    exactly on a crossing counting it as passed) and, inside, the ``component`` of the body
    velocity interpolated linearly between the crossings before and after it on the line
    (METHOD.md §5.4: exact for rigid motion along the line).

    Outputs are (x, y, z)-indexed and must come filled with False and 0: lines without
    crossings are skipped (all their points are outside), and a line is left once its last
    crossing is passed.
    """
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
