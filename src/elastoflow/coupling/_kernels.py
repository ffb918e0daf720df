"""Numba kernels of the boundary map, the classification, the cut data and the forces.

Every kernel works on one family of half-grid lines of one map. A line is a row ``J`` of the
x-map (``y = J h/2``, coordinates along x) or a column ``I`` of the y-map (``x = I h/2``,
coordinates along y). Entries of line ``L`` are ``offsets[L]:offsets[L+1]`` of the entry arrays,
sorted by coordinate. Grid points on a line sit at half-grid index ``point_start + 2 k``; the
``point_first`` flag says whether an output array is indexed ``[k, l]`` (x-map rows, where the
point index is ``i``) or ``[l, k]`` (y-map columns, where the line index is ``i``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# Sorting a line switches from insertion sort to a merge sort above this many entries.
_INSERTION_SORT_LIMIT = 32

# A grid point lying exactly on the boundary has a cut distance of 0; the contract asks for a
# fraction in (0, 1], so it is floored here (the fluid guards small fractions further).
THETA_FLOOR = 1.0e-6


@njit(cache=True)
def _line_range(across_a: float, across_b: float, line_count: int) -> tuple[int, int]:
    """Half-open range of lines crossed by an edge, in half-cell units: lo <= L < hi."""
    lo = min(across_a, across_b)
    hi = max(across_a, across_b)
    first = max(math.ceil(lo), 0)
    last = min(math.ceil(hi) - 1, line_count - 1)
    return first, last


@njit(cache=True)
def build_axis_map(
    along: np.ndarray,
    across: np.ndarray,
    velocities: np.ndarray,
    edges: np.ndarray,
    origin_across: float,
    half_h: float,
    line_count: int,
    entering_when_decreasing: bool,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One map (x-map or y-map): count pass, prefix sum, fill pass, per-line sort.

    Args:
        along: Point coordinate along the lines [m], shape (P,).
        across: Point coordinate across the lines [m], shape (P,).
        velocities: Point velocities [m/s], shape (P, 2).
        edges: Boundary edges (a, b), body on the left of a->b, shape (E, 2).
        origin_across: Coordinate of line 0 [m].
        half_h: Line spacing h/2 [m].
        line_count: Number of lines.
        entering_when_decreasing: True for the x-map (an edge going down has the body on +x),
            False for the y-map (an edge going right has the body on +y).

    Returns:
        offsets (line_count+1,), coordinate (C,), edge (C,), parameter (C,),
        velocity (C, 2), sign (C,) int8.
    """
    edge_count = edges.shape[0]
    scaled = np.empty(along.shape[0])
    for p in range(along.shape[0]):
        scaled[p] = (across[p] - origin_across) / half_h

    counts = np.zeros(line_count + 1, dtype=np.int64)
    for e in range(edge_count):
        sa = scaled[edges[e, 0]]
        sb = scaled[edges[e, 1]]
        if sa == sb:
            continue
        first, last = _line_range(sa, sb, line_count)
        for line in range(first, last + 1):
            counts[line + 1] += 1
    offsets = np.cumsum(counts)
    total = offsets[line_count]

    coordinate = np.empty(total)
    edge_index = np.empty(total, dtype=np.int64)
    parameter = np.empty(total)
    velocity = np.empty((total, 2))
    sign = np.empty(total, dtype=np.int8)
    cursor = offsets[:line_count].copy()
    for e in range(edge_count):
        a = edges[e, 0]
        b = edges[e, 1]
        sa = scaled[a]
        sb = scaled[b]
        if sa == sb:
            continue
        decreasing = sb < sa
        entering = decreasing == entering_when_decreasing
        first, last = _line_range(sa, sb, line_count)
        for line in range(first, last + 1):
            t = (line - sa) / (sb - sa)
            t = min(max(t, 0.0), 1.0)
            slot = cursor[line]
            cursor[line] += 1
            coordinate[slot] = along[a] + t * (along[b] - along[a])
            edge_index[slot] = e
            parameter[slot] = t
            velocity[slot, 0] = (1.0 - t) * velocities[a, 0] + t * velocities[b, 0]
            velocity[slot, 1] = (1.0 - t) * velocities[a, 1] + t * velocities[b, 1]
            sign[slot] = 1 if entering else -1

    for line in range(line_count):
        # Lines of 0 or 2 crossings (most of them) are handled here: a call per line costs
        # more than the sort itself.
        count = offsets[line + 1] - offsets[line]
        if count == 2:
            i = offsets[line]
            j = i + 1
            if coordinate[j] < coordinate[i] or (coordinate[j] == coordinate[i]
                                                 and sign[j] < sign[i]):
                coordinate[i], coordinate[j] = coordinate[j], coordinate[i]
                edge_index[i], edge_index[j] = edge_index[j], edge_index[i]
                parameter[i], parameter[j] = parameter[j], parameter[i]
                velocity[i, 0], velocity[j, 0] = velocity[j, 0], velocity[i, 0]
                velocity[i, 1], velocity[j, 1] = velocity[j, 1], velocity[i, 1]
                sign[i], sign[j] = sign[j], sign[i]
        elif count > 2:
            _sort_line(offsets[line], offsets[line + 1], coordinate, edge_index, parameter,
                       velocity, sign)
    return offsets, coordinate, edge_index, parameter, velocity, sign


@njit(cache=True)
def _before(ca: float, sa: int, cb: float, sb: int) -> bool:
    # Ties put a leaving crossing first so that two bodies touching along a line keep the
    # winding number in {0, 1}.
    return ca < cb or (ca == cb and sa < sb)


@njit(cache=True)
def _sort_line(
    begin: int,
    end: int,
    coordinate: np.ndarray,
    edge_index: np.ndarray,
    parameter: np.ndarray,
    velocity: np.ndarray,
    sign: np.ndarray,
) -> None:
    """Sort entries begin:end in place by (coordinate, sign)."""
    n = end - begin
    if n < 2:
        return
    if n > _INSERTION_SORT_LIMIT:
        order = np.argsort(coordinate[begin:end], kind="mergesort")
        coordinate[begin:end] = coordinate[begin:end][order]
        edge_index[begin:end] = edge_index[begin:end][order]
        parameter[begin:end] = parameter[begin:end][order]
        sign[begin:end] = sign[begin:end][order]
        velocity[begin:end, 0] = velocity[begin:end, 0][order]
        velocity[begin:end, 1] = velocity[begin:end, 1][order]
    # Insertion sort: the whole sort for short lines, the tie fix-up after the merge sort.
    for k in range(begin + 1, end):
        c = coordinate[k]
        e = edge_index[k]
        t = parameter[k]
        vx = velocity[k, 0]
        vy = velocity[k, 1]
        s = sign[k]
        m = k - 1
        while m >= begin and _before(c, s, coordinate[m], sign[m]):
            coordinate[m + 1] = coordinate[m]
            edge_index[m + 1] = edge_index[m]
            parameter[m + 1] = parameter[m]
            velocity[m + 1, 0] = velocity[m, 0]
            velocity[m + 1, 1] = velocity[m, 1]
            sign[m + 1] = sign[m]
            m -= 1
        coordinate[m + 1] = c
        edge_index[m + 1] = e
        parameter[m + 1] = t
        velocity[m + 1, 0] = vx
        velocity[m + 1, 1] = vy
        sign[m + 1] = s


@njit(cache=True)
def _point_position(origin_along: float, half_h: float, point_start: int, k: int) -> float:
    """Coordinate [m] of point k of a line; every kernel uses this one formula."""
    return origin_along + (point_start + 2 * k) * half_h


@njit(cache=True)
def _first_point_at_or_after(
    value: float, origin_along: float, half_h: float, point_start: int
) -> int:
    """Smallest k (unclipped) with point position >= value, exact for the position formula."""
    k = math.ceil(((value - origin_along) / half_h - point_start) * 0.5)
    while _point_position(origin_along, half_h, point_start, k - 1) >= value:
        k -= 1
    while _point_position(origin_along, half_h, point_start, k) < value:
        k += 1
    return k


@njit(cache=True)
def classify_lines(
    offsets: np.ndarray,
    coordinate: np.ndarray,
    sign: np.ndarray,
    edge_index: np.ndarray,
    velocity: np.ndarray,
    edge_body: np.ndarray,
    line_start: int,
    line_count_out: int,
    point_start: int,
    point_count: int,
    origin_along: float,
    half_h: float,
    component: int,
    solid_out: np.ndarray,
    body_out: np.ndarray,
    velocity_out: np.ndarray,
) -> None:
    """Scanline fill of x-map rows: solid flag, body id and body velocity, outputs [k, l].

    A point at x is solid when the winding number of the crossings at coordinates <= x is
    non-zero (for a simple, consistently oriented loop this is the parity rule; it also
    survives a loop given clockwise). Each solid span [c_m, c_m+1) is filled in one go, so the
    cost is the number of crossings plus the number of solid points. Inside a span the body
    velocity is interpolated linearly between the span's two crossings (exact for rigid
    motion). ``component < 0`` skips the velocity, an empty ``body_out`` the body ids.
    """
    for l in range(line_count_out):
        line = line_start + 2 * l
        begin = offsets[line]
        end = offsets[line + 1]
        winding = 0
        for c in range(begin, end):
            winding += sign[c]
            if winding == 0:
                continue
            k = max(_first_point_at_or_after(coordinate[c], origin_along, half_h, point_start), 0)
            has_next = c + 1 < end
            while k < point_count:
                x = _point_position(origin_along, half_h, point_start, k)
                if has_next and x >= coordinate[c + 1]:
                    break
                solid_out[k, l] = True
                if body_out.shape[0] > 0:
                    body_out[k, l] = edge_body[edge_index[c]]
                if component >= 0:
                    value = velocity[c, component]
                    if has_next:
                        width = coordinate[c + 1] - coordinate[c]
                        if width > 0.0:
                            w = (x - coordinate[c]) / width
                            value = (1.0 - w) * value + w * velocity[c + 1, component]
                    velocity_out[k, l] = value
                k += 1


@njit(cache=True)
def cut_lines(
    offsets: np.ndarray,
    coordinate: np.ndarray,
    velocity: np.ndarray,
    component: int,
    line_start: int,
    line_count_out: int,
    point_start: int,
    point_count: int,
    origin_along: float,
    h: float,
    point_first: bool,
    theta_minus: np.ndarray,
    theta_plus: np.ndarray,
    velocity_minus: np.ndarray,
    velocity_plus: np.ndarray,
) -> None:
    """Cut fractions towards the lower and upper neighbour along a line.

    Windows are half-open like the classification (a point at x sees crossings <= x as behind
    it): towards minus the nearest crossing at or behind x counts if it lies in (x - h, x],
    towards plus the nearest crossing ahead if it lies in (x, x + h]. Only the one or two
    points next to each crossing are visited. Outputs that see no crossing are left untouched
    (the caller fills them with inf and 0).
    """
    half_h = 0.5 * h
    for l in range(line_count_out):
        line = line_start + 2 * l
        begin = offsets[line]
        end = offsets[line + 1]
        for c in range(begin, end):
            first = _first_point_at_or_after(coordinate[c], origin_along, half_h, point_start)
            # Points for which c is the last crossing at or behind them: minus direction.
            k = max(first, 0)
            while k < point_count:
                x = _point_position(origin_along, half_h, point_start, k)
                if c + 1 < end and x >= coordinate[c + 1]:
                    break
                d = x - coordinate[c]
                if d >= h:
                    break
                theta = max(d / h, THETA_FLOOR)
                if point_first:
                    theta_minus[k, l] = theta
                    velocity_minus[k, l] = velocity[c, component]
                else:
                    theta_minus[l, k] = theta
                    velocity_minus[l, k] = velocity[c, component]
                k += 1
            # Points for which c is the first crossing ahead of them: plus direction. Among
            # crossings at one coordinate the first in the sorted order is that one.
            if c > begin and coordinate[c - 1] == coordinate[c]:
                continue
            k = min(first - 1, point_count - 1)
            while k >= 0:
                x = _point_position(origin_along, half_h, point_start, k)
                if c > begin and x < coordinate[c - 1]:
                    break
                d = coordinate[c] - x
                if d > h:
                    break
                theta = max(d / h, THETA_FLOOR)
                if point_first:
                    theta_plus[k, l] = theta
                    velocity_plus[k, l] = velocity[c, component]
                else:
                    theta_plus[l, k] = theta
                    velocity_plus[l, k] = velocity[c, component]
                k -= 1


@njit(cache=True)
def open_fraction_lines(
    offsets: np.ndarray,
    coordinate: np.ndarray,
    sign: np.ndarray,
    line_start: int,
    line_count_out: int,
    point_count: int,
    origin_along: float,
    h: float,
    point_first: bool,
    open_out: np.ndarray,
) -> None:
    """Open (fluid) fraction of the segments [k h, (k+1) h] along each line.

    ``open_out`` must hold 1 on entry; the solid length of every solid span is subtracted.
    """
    extent = point_count * h
    for l in range(line_count_out):
        line = line_start + 2 * l
        begin = offsets[line]
        end = offsets[line + 1]
        winding = 0
        for c in range(begin, end - 1):
            winding += sign[c]
            if winding == 0:
                continue
            a = max(coordinate[c] - origin_along, 0.0)
            b = min(coordinate[c + 1] - origin_along, extent)
            if b <= a:
                continue
            k0 = min(int(a / h), point_count - 1)
            k1 = min(int(b / h), point_count - 1)
            for k in range(k0, k1 + 1):
                lo = max(a, k * h)
                hi = min(b, (k + 1) * h)
                if hi > lo:
                    if point_first:
                        open_out[k, l] = max(open_out[k, l] - (hi - lo) / h, 0.0)
                    else:
                        open_out[l, k] = max(open_out[l, k] - (hi - lo) / h, 0.0)


@njit(cache=True)
def momentum_exchange_lines(crossings, edges, family, field, solid, coefficient, force_out):
    """Paper eq. (8) along lines through velocity points of one component.

    For each crossing the first velocity point of that component on the fluid side (the side
    the edge orientation says is fluid) that is not solid gives ``coefficient * (u_P - u_s)``,
    split between the edge's nodes by the edge parameter. With cut cells that is the point
    next to the crossing; a staircase boundary closes the faces of the cells its centres put
    inside, so the fluid point can lie a face further out. ``solid`` has the field's shape
    (or is empty: nothing solid). A crossing whose fluid point lies beyond another crossing (a
    sliver thinner than the point's distance) is skipped.

    Args:
        crossings: ``(offsets, coordinate, sign, edge_index, parameter, velocity)`` of the
            map's lines along the component's axis.
        edges: The map's edges.
        family: ``(component, line_start, line_count, face_count, origin_along, h,
            point_first)``: lines ``line_start + 2 l``, ``l < line_count``, through the
            component's points, ``face_count`` of them along each; ``point_first``: the
            field is indexed (point along the line, line).
        field: The velocity component.
        force_out: (P, 2) [N/m], added to.
    """
    offsets, coordinate, sign, edge_index, parameter, velocity = crossings
    component, line_start, line_count_out, face_count, origin_along, h, point_first = family
    check = solid.size > 0
    for l in range(line_count_out):
        line = line_start + 2 * l
        begin = offsets[line]
        end = offsets[line + 1]
        for c in range(begin, end):
            s = (coordinate[c] - origin_along) / h
            if sign[c] > 0:
                # Entering: fluid on the minus side; the point exactly at the crossing is solid.
                k = math.ceil(s) - 1
                while check and 0 <= k < face_count and (
                        solid[k, l] if point_first else solid[l, k]):
                    k -= 1
                if c > begin and coordinate[c - 1] > origin_along + k * h:
                    continue
            else:
                k = math.ceil(s)
                while check and 0 <= k < face_count and (
                        solid[k, l] if point_first else solid[l, k]):
                    k += 1
                if c + 1 < end and coordinate[c + 1] <= origin_along + k * h:
                    continue
            if k < 0 or k >= face_count:
                continue
            fluid_value = field[k, l] if point_first else field[l, k]
            f = coefficient * (fluid_value - velocity[c, component])
            t = parameter[c]
            e = edge_index[c]
            force_out[edges[e, 0], component] += (1.0 - t) * f
            force_out[edges[e, 1], component] += t * f


@njit(cache=True)
def _sample_fluid(
    field: np.ndarray,
    solid: np.ndarray,
    fx: float,
    fy: float,
    x0: float,
    y0: float,
    h: float,
    gravity_x: float,
    gravity_y: float,
    density: float,
) -> tuple[float, bool]:
    """Bilinear sample at index-space position (fx, fy) over fluid, in-range points only.

    Weights of solid or out-of-range points are dropped and the rest renormalised. The value
    sampled is ``field - density * gravity . x`` (x of each stencil point, whose index (i, j)
    sits at ``(x0 + i h, y0 + j h)``), which removes a hydrostatic part before interpolating.
    """
    i0 = math.floor(fx)
    j0 = math.floor(fy)
    wx = fx - i0
    wy = fy - j0
    total_weight = 0.0
    total = 0.0
    for di in range(2):
        i = i0 + di
        if i < 0 or i >= field.shape[0]:
            continue
        weight_x = wx if di == 1 else 1.0 - wx
        for dj in range(2):
            j = j0 + dj
            if j < 0 or j >= field.shape[1]:
                continue
            if solid[i, j]:
                continue
            weight = weight_x * (wy if dj == 1 else 1.0 - wy)
            if weight <= 0.0:
                continue
            hydrostatic = density * (gravity_x * (x0 + i * h) + gravity_y * (y0 + j * h))
            total += weight * (field[i, j] - hydrostatic)
            total_weight += weight
    if total_weight <= 1.0e-12:
        return 0.0, False
    return total / total_weight, True


@njit(cache=True)
def _sample_velocity(
    velocity_x: np.ndarray,
    velocity_y: np.ndarray,
    solid_faces_x: np.ndarray,
    solid_faces_y: np.ndarray,
    x: float,
    y: float,
    origin_x: float,
    origin_y: float,
    h: float,
) -> tuple[float, float, bool]:
    """Fluid velocity (u, v) [m/s] at (x, y) from fluid faces only; False if either fails."""
    u, found_u = _sample_fluid(velocity_x, solid_faces_x, (x - origin_x) / h,
                               (y - origin_y) / h - 0.5, origin_x, origin_y + 0.5 * h, h,
                               0.0, 0.0, 0.0)
    v, found_v = _sample_fluid(velocity_y, solid_faces_y, (x - origin_x) / h - 0.5,
                               (y - origin_y) / h, origin_x + 0.5 * h, origin_y, h,
                               0.0, 0.0, 0.0)
    return u, v, found_u and found_v


@njit(cache=True)
def traction_edges(boundary, fluid, solid, grid, constants, distances, force_out):
    """Traction integral (-p n + mu (grad u + grad u^T) n) ds along every edge, see
    ``force_traction`` for the estimate. Sub-segments no longer than h, midpoint rule.

    Args:
        boundary: ``(points, velocities, edges)`` of the map.
        fluid: ``(velocity_x, velocity_y, pressure)``.
        solid: ``(solid_faces_x, solid_faces_y, solid_cells)``: samples skip these points.
        grid: ``(origin_x, origin_y, h)``.
        constants: ``(density, dynamic_viscosity, gravity_x, gravity_y)``.
        distances: Distances [m] along the normal of the velocity (and pressure) samples.
        force_out: (P, 2) [N/m], added to.
    """
    points, velocities, edges = boundary
    velocity_x, velocity_y, pressure = fluid
    solid_faces_x, solid_faces_y, solid_cells = solid
    origin_x, origin_y, h = grid
    density, dynamic_viscosity, gravity_x, gravity_y = constants
    for e in range(edges.shape[0]):
        a = edges[e, 0]
        b = edges[e, 1]
        dx = points[b, 0] - points[a, 0]
        dy = points[b, 1] - points[a, 1]
        length = math.sqrt(dx * dx + dy * dy)
        if length <= 0.0:
            continue
        # Body on the left of a->b: the outward normal (into the fluid) is on the right.
        nx = dy / length
        ny = -dx / length
        tx = dx / length
        ty = dy / length
        # Derivative of the wall velocity along the edge [1/s] (linear between the nodes).
        tangential_x = (velocities[b, 0] - velocities[a, 0]) / length
        tangential_y = (velocities[b, 1] - velocities[a, 1]) / length
        pieces = max(1, math.ceil(length / h))
        ds = length / pieces
        for q in range(pieces):
            t = (q + 0.5) / pieces
            xq = points[a, 0] + t * dx
            yq = points[a, 1] + t * dy
            wall_u = (1.0 - t) * velocities[a, 0] + t * velocities[b, 0]
            wall_v = (1.0 - t) * velocities[a, 1] + t * velocities[b, 1]

            wall_pressure = 0.0
            for m in range(distances.shape[0]):
                xs = xq + distances[m] * nx
                ys = yq + distances[m] * ny
                value, found = _sample_fluid(
                    pressure, solid_cells, (xs - origin_x) / h - 0.5, (ys - origin_y) / h - 0.5,
                    origin_x + 0.5 * h, origin_y + 0.5 * h, h, gravity_x, gravity_y, density)
                if found:
                    wall_pressure = value + density * (gravity_x * xq + gravity_y * yq)
                    break

            traction_x = -wall_pressure * nx
            traction_y = -wall_pressure * ny
            if dynamic_viscosity > 0.0:
                for m in range(distances.shape[0]):
                    delta = distances[m]
                    u1, v1, found = _sample_velocity(
                        velocity_x, velocity_y, solid_faces_x, solid_faces_y,
                        xq + delta * nx, yq + delta * ny, origin_x, origin_y, h)
                    if not found:
                        continue
                    # One-sided normal derivative g_n: second order from two samples (delta
                    # and delta + h), first order when the second is not in the fluid.
                    far = delta + h
                    u2, v2, found_far = _sample_velocity(
                        velocity_x, velocity_y, solid_faces_x, solid_faces_y,
                        xq + far * nx, yq + far * ny, origin_x, origin_y, h)
                    if found_far:
                        scale = 1.0 / (delta * far * (far - delta))
                        normal_x = (far * far * (u1 - wall_u) - delta * delta * (u2 - wall_u)) \
                            * scale
                        normal_y = (far * far * (v1 - wall_v) - delta * delta * (v2 - wall_v)) \
                            * scale
                    else:
                        normal_x = (u1 - wall_u) / delta
                        normal_y = (v1 - wall_v) / delta
                    # grad u = g_t t^T + g_n n^T: g_t, the derivative along the wall, is the
                    # wall's own (no slip). The normal-normal strain comes from continuity,
                    # du_n/dn = -du_t/dt.
                    shear = (normal_x * tx + normal_y * ty
                             + tangential_x * nx + tangential_y * ny)
                    stretch = tangential_x * tx + tangential_y * ty
                    traction_x += dynamic_viscosity * (shear * tx - 2.0 * stretch * nx)
                    traction_y += dynamic_viscosity * (shear * ty - 2.0 * stretch * ny)
                    break

            force_out[a, 0] += (1.0 - t) * traction_x * ds
            force_out[a, 1] += (1.0 - t) * traction_y * ds
            force_out[b, 0] += t * traction_x * ds
            force_out[b, 1] += t * traction_y * ds


@njit(cache=True)
def reconcile_cuts_y(
    solid: np.ndarray,
    velocity_faces: np.ndarray,
    theta: np.ndarray,
    cut_velocity: np.ndarray,
    boxes: np.ndarray,
) -> None:
    """Give every point whose ±y neighbour differs in solid flag a cut in that direction.

    Flags come from the x-map and the ±y cuts from the y-map. For an edge nearly parallel to
    a column and passing through its points, rounding can place the two maps' crossings on
    different sides of a point (a 1e-16 disagreement); the fluid relies on a fluid point next
    to a solid one having a finite cut, so such a pair gets theta = 1 (the boundary at the
    neighbour) with the body velocity of whichever point is solid.

    Only points in the index boxes (i_begin, i_end, j_begin, j_end), shape (K, 4), clipped to
    the array, are visited: boxes holding every solid point and one point more towards +y and
    -y suffice. Overlapping boxes are harmless (a second visit changes nothing).
    """
    ni, nj = solid.shape
    for box in range(boxes.shape[0]):
        _reconcile_box(solid, velocity_faces, theta, cut_velocity, max(boxes[box, 0], 0),
                       min(boxes[box, 1], ni), max(boxes[box, 2], 0), min(boxes[box, 3], nj))


@njit(cache=True)
def _reconcile_box(
    solid: np.ndarray,
    velocity_faces: np.ndarray,
    theta: np.ndarray,
    cut_velocity: np.ndarray,
    i_begin: int,
    i_end: int,
    j_begin: int,
    j_end: int,
) -> None:
    for i in range(i_begin, i_end):
        for j in range(j_begin, j_end - 1):
            if solid[i, j] == solid[i, j + 1]:
                continue
            value = velocity_faces[i, j] if solid[i, j] else velocity_faces[i, j + 1]
            if theta[3, i, j] == np.inf:
                theta[3, i, j] = 1.0
                cut_velocity[3, i, j] = value
            if theta[2, i, j + 1] == np.inf:
                theta[2, i, j + 1] = 1.0
                cut_velocity[2, i, j + 1] = value


@njit(cache=True)
def _index_range(low: float, high: float, origin: float, h: float, limit: int) -> tuple[int, int]:
    """Half-open index range [begin, end) within [0, limit) of grid points (integer or
    half-integer multiples of h from ``origin``) within 2 h of the coordinates [low, high]."""
    q_low = (low - origin) / h - 3.0
    q_high = (high - origin) / h + 3.0
    begin = 0 if q_low <= 0.0 else (limit if q_low >= limit else int(q_low))
    end = 0 if q_high <= 0.0 else (limit if q_high >= limit else int(q_high) + 1)
    return begin, end


@njit(cache=True)
def _extend_along(
    offsets: np.ndarray,
    coordinate: np.ndarray,
    sign: np.ndarray,
    edge_index: np.ndarray,
    edge_group: np.ndarray,
    origin_across: float,
    half_h: float,
    along_bounds: np.ndarray,
    across_bounds: np.ndarray,
) -> bool:
    """Grow each group's bounds [low, high] by what one map's lines may write; False on NaN."""
    for line in range(offsets.shape[0] - 1):
        begin = offsets[line]
        end = offsets[line + 1]
        across = origin_across + line * half_h
        winding = 0
        for c in range(begin, end):
            value = coordinate[c]
            if math.isnan(value):
                return False
            group = edge_group[edge_index[c]]
            across_bounds[group, 0] = min(across_bounds[group, 0], across)
            across_bounds[group, 1] = max(across_bounds[group, 1], across)
            along_bounds[group, 0] = min(along_bounds[group, 0], value)
            winding += sign[c]
            # The span after a crossing is filled (and attributed) from that crossing to the
            # next one, or to the line's end when the winding never returns to 0.
            if winding == 0:
                reach = value
            elif c + 1 < end:
                reach = coordinate[c + 1]
            else:
                reach = math.inf
            along_bounds[group, 1] = max(along_bounds[group, 1], reach)
    return True


@njit(cache=True)
def touched_boxes(
    x_offsets: np.ndarray,
    x_coordinate: np.ndarray,
    x_sign: np.ndarray,
    x_edge: np.ndarray,
    y_offsets: np.ndarray,
    y_coordinate: np.ndarray,
    y_sign: np.ndarray,
    y_edge: np.ndarray,
    edge_group: np.ndarray,
    group_count: int,
    origin_x: float,
    origin_y: float,
    h: float,
    nx: int,
    ny: int,
) -> np.ndarray:
    """Index boxes, one per edge group (body), that hold every grid point (cell, u or v,
    clipped to 0 <= i <= nx, 0 <= j <= ny) the classification, open-fraction, cut and
    reconcile kernels may write for this map.

    Those kernels write only points within h of a crossing along its line, or in the span
    from a crossing to the next one (or to the line's end, for a winding that never returns
    to 0, as an open chain leaves), which is charged to the crossing's group. A margin of 2 h
    more covers the half-cell offsets of the point families and reconcile's neighbour.
    Cost: lines plus crossings.

    Args:
        edge_group: Group index in [0, group_count) of each edge, shape (E,).

    Returns:
        Boxes (i_begin, i_end, j_begin, j_end), half-open, int64, shape (K, 4): the non-empty
        ones only; the whole grid as one box when a coordinate is NaN.
    """
    half_h = 0.5 * h
    # Columns 0/1: x low/high [m]; columns 2/3: y low/high [m].
    bounds = np.empty((group_count, 4))
    bounds[:, 0] = math.inf
    bounds[:, 1] = -math.inf
    bounds[:, 2] = math.inf
    bounds[:, 3] = -math.inf
    whole = np.array([[0, nx + 1, 0, ny + 1]], dtype=np.int64)
    if not _extend_along(x_offsets, x_coordinate, x_sign, x_edge, edge_group, origin_y, half_h,
                         bounds[:, 0:2], bounds[:, 2:4]):
        return whole
    if not _extend_along(y_offsets, y_coordinate, y_sign, y_edge, edge_group, origin_x, half_h,
                         bounds[:, 2:4], bounds[:, 0:2]):
        return whole
    boxes = np.empty((group_count, 4), dtype=np.int64)
    count = 0
    for group in range(group_count):
        if bounds[group, 0] > bounds[group, 1] or bounds[group, 2] > bounds[group, 3]:
            continue
        i_begin, i_end = _index_range(bounds[group, 0], bounds[group, 1], origin_x, h, nx + 1)
        j_begin, j_end = _index_range(bounds[group, 2], bounds[group, 3], origin_y, h, ny + 1)
        if i_begin >= i_end or j_begin >= j_end:
            continue
        boxes[count, 0] = i_begin
        boxes[count, 1] = i_end
        boxes[count, 2] = j_begin
        boxes[count, 3] = j_end
        count += 1
    return boxes[:count].copy()


@njit(cache=True)
def reset_boxes(
    boxes: np.ndarray,
    solid_cells: np.ndarray,
    solid_faces_x: np.ndarray,
    solid_faces_y: np.ndarray,
    velocity_faces_x: np.ndarray,
    velocity_faces_y: np.ndarray,
    open_fraction_x: np.ndarray,
    open_fraction_y: np.ndarray,
    cut_theta_x: np.ndarray,
    cut_theta_y: np.ndarray,
    cut_velocity_x: np.ndarray,
    cut_velocity_y: np.ndarray,
) -> None:
    """Empty state (fluid, fully open, nothing cut) in each index box (i_begin, i_end,
    j_begin, j_end), shape (K, 4), of every interior-boundary array (clipped to its shape)."""
    for box in range(boxes.shape[0]):
        i_begin, i_end = boxes[box, 0], boxes[box, 1]
        j_begin, j_end = boxes[box, 2], boxes[box, 3]
        _fill_box(solid_cells, i_begin, i_end, j_begin, j_end, False)
        _fill_box(solid_faces_x, i_begin, i_end, j_begin, j_end, False)
        _fill_box(solid_faces_y, i_begin, i_end, j_begin, j_end, False)
        _fill_box(velocity_faces_x, i_begin, i_end, j_begin, j_end, 0.0)
        _fill_box(velocity_faces_y, i_begin, i_end, j_begin, j_end, 0.0)
        _fill_box(open_fraction_x, i_begin, i_end, j_begin, j_end, 1.0)
        _fill_box(open_fraction_y, i_begin, i_end, j_begin, j_end, 1.0)
        for d in range(4):
            _fill_box(cut_theta_x[d], i_begin, i_end, j_begin, j_end, np.inf)
            _fill_box(cut_theta_y[d], i_begin, i_end, j_begin, j_end, np.inf)
            _fill_box(cut_velocity_x[d], i_begin, i_end, j_begin, j_end, 0.0)
            _fill_box(cut_velocity_y[d], i_begin, i_end, j_begin, j_end, 0.0)


@njit(cache=True)
def _fill_box(array: np.ndarray, i_begin: int, i_end: int, j_begin: int, j_end: int,
              value: float) -> None:
    """array[i_begin:i_end, j_begin:j_end] = value, the box clipped to the array."""
    j_start = max(j_begin, 0)
    j_stop = min(j_end, array.shape[1])
    if j_start >= j_stop:
        return
    for i in range(max(i_begin, 0), min(i_end, array.shape[0])):
        array[i, j_start:j_stop] = value
