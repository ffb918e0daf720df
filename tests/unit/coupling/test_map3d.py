"""The 3D boundary map against brute-force ray casting, its degenerate alignments, and its
scaling."""

from __future__ import annotations

import numpy as np
import pytest
from coupling_surfaces import icosphere
from hypothesis import given, settings
from hypothesis import strategies as st

from elastoflow.coupling import build_boundary_map_3d, solid_cells_3d
from elastoflow.grid import Grid3D


def box_surface(low: np.ndarray, high: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned box: 8 corners and 12 outward triangles."""
    corners = np.array([[low[0] if i & 1 == 0 else high[0], low[1] if i & 2 == 0 else high[1],
                         low[2] if i & 4 == 0 else high[2]] for i in range(8)])
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    triangles = []
    for a, b, c, d in quads:
        triangles += [(a, b, c), (a, c, d)]
    triangles_array = np.array(triangles, dtype=np.int64)
    p = corners[triangles_array]
    normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    centre = 0.5 * (low + high)
    outward = np.einsum("ij,ij->i", normal, p.mean(axis=1) - centre) > 0.0
    triangles_array[~outward] = triangles_array[~outward][:, ::-1]
    return corners, triangles_array


def winding_brute_force(points: np.ndarray, triangles: np.ndarray,
                        queries: np.ndarray) -> np.ndarray:
    """Winding number of each query point by a ray in a fixed generic direction, tested
    against every triangle (Moller-Trumbore)."""
    direction = np.array([0.5773, 0.3129, 0.7543])
    direction /= np.linalg.norm(direction)
    a, b, c = (points[triangles[:, k]] for k in range(3))
    e1, e2 = b - a, c - a
    pvec = np.cross(direction, e2)
    det = np.einsum("ij,ij->i", e1, pvec)
    normal_dot = np.einsum("ij,j->i", np.cross(e1, e2), direction)
    winding = np.zeros(queries.shape[0], dtype=np.int64)
    for index, q in enumerate(queries):
        tvec = q - a
        u = np.einsum("ij,ij->i", tvec, pvec) / det
        qvec = np.cross(tvec, e1)
        v = (qvec @ direction) / det
        t = np.einsum("ij,ij->i", qvec, e2) / det
        hit = (u >= 0.0) & (v >= 0.0) & (u + v <= 1.0) & (t > 0.0)
        winding[index] = int(np.sign(normal_dot[hit]).sum())
    return winding


def _centres(grid: Grid3D) -> np.ndarray:
    x, y, z = grid.cell_centers()
    return np.column_stack([np.broadcast_to(c, grid.shape_cells).reshape(-1) for c in (x, y, z)])


def _check_lines_pair_up(bmap) -> None:
    """On every line the crossings alternate into and out of the (single) body: the winding
    after each distinct coordinate is 0 or 1 and ends at 0 (a line grazing the surface at a
    silhouette vertex or edge leaves and enters at one point, whose two coordinates, each
    from its own triangle, may differ by round-off)."""
    for crossings in bmap.lines:
        for line in range(crossings.offsets.shape[0] - 1):
            part = slice(crossings.offsets[line], crossings.offsets[line + 1])
            signs, where = crossings.sign[part], crossings.coordinate[part]
            if not signs.size:
                continue
            partial = np.cumsum(signs)
            last_of_group = np.append(where[1:] - where[:-1] > 1e-12, True)
            settled = partial[last_of_group]
            assert settled[-1] == 0 and settled.min() >= 0 and settled.max() <= 1, (
                crossings.axis, line, signs)


@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), subdivisions=st.integers(1, 3))
def test_cells_inside_a_random_closed_surface_match_brute_force(seed: int,
                                                                subdivisions: int) -> None:
    """A star-shaped surface (icosphere with random radii, rotated, anywhere in the grid,
    partly outside it): the map's inside cells are those brute-force ray casting finds."""
    rng = np.random.default_rng(seed)
    points, triangles = icosphere(subdivisions)
    radii = rng.uniform(0.6, 1.0, points.shape[0])
    rotation, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    centre = rng.uniform(0.2, 0.8, 3)
    scale = rng.uniform(0.15, 0.4)
    surface = centre + scale * (radii[:, None] * points) @ rotation.T
    grid = Grid3D(nx=14, ny=12, nz=10, h=1.0 / 12, origin=tuple(rng.uniform(-0.1, 0.1, 3)))
    bmap = build_boundary_map_3d(grid, surface, np.zeros_like(surface), triangles)
    inside = solid_cells_3d(bmap)
    expected = winding_brute_force(surface, triangles, _centres(grid)) > 0
    assert np.array_equal(inside.reshape(-1), expected)
    assert inside.any()
    _check_lines_pair_up(bmap)
    # Refilled into an earlier answer: reset everywhere, or in a box that holds its True
    # cells (here: the whole array's box).
    stale = np.ones(grid.shape_cells, dtype=np.bool_)
    assert solid_cells_3d(bmap, out=stale) is stale
    assert np.array_equal(stale, inside)
    stale[...] = True
    solid_cells_3d(bmap, out=stale, out_box=(0, 0, 0) + grid.shape_cells)
    assert np.array_equal(stale, inside)
    with pytest.raises(ValueError, match="out: float64 array of shape"):
        solid_cells_3d(bmap, out=np.zeros(grid.shape_cells))


def test_box_on_grid_lines_is_crossed_consistently() -> None:
    """A box whose faces lie on face planes and whose edges lie on grid lines: every line
    through its faces, edges and corners still crosses it an even number of times, in and
    out alternately (the symbolic perturbation), and exactly the cells inside are solid."""
    grid = Grid3D(nx=8, ny=8, nz=8, h=0.125)
    low, high = np.array([0.25, 0.25, 0.375]), np.array([0.75, 0.625, 0.75])
    corners, triangles = box_surface(low, high)
    bmap = build_boundary_map_3d(grid, corners, np.zeros_like(corners), triangles)
    _check_lines_pair_up(bmap)
    centres = _centres(grid).reshape(grid.shape_cells + (3,))
    expected = np.all((centres > low) & (centres < high), axis=-1)
    assert np.array_equal(solid_cells_3d(bmap), expected)
    # The x lines through half-grid positions over the box's y-z extent (y 0.25-0.625: U 4
    # to 10, z 0.375-0.75: V 6 to 12) cross it twice, those on its edges included; the
    # perturbation (+y, then +z) takes the lines on the low sides in and those on the high
    # sides out, as a line just beside them would be.
    crossings = bmap.lines[0]
    for position_u in range(3, 12):
        for position_v in range(5, 14):
            entries = crossings.line(position_u, position_v)
            inside = 4 <= position_u < 10 and 6 <= position_v < 12
            assert entries.stop - entries.start == (2 if inside else 0), (position_u,
                                                                          position_v)


def test_octahedron_with_vertices_and_edges_on_grid_lines() -> None:
    """Lines through the vertices (where four triangles meet) and along the edges' projections
    still pair up, and the inside cells match brute force."""
    grid = Grid3D(nx=8, ny=8, nz=8, h=0.125)
    # Vertices on half-grid positions; no cell centre on a face (|dx| + |dy| + |dz| is an odd
    # multiple of h/2 at the centres, the radius an even one).
    centre, radius = np.array([0.5, 0.5, 0.5]), 0.375
    points = centre + radius * np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0],
                                         [0, 0, 1], [0, 0, -1]], dtype=float)
    triangles = []
    for x in (0, 1):
        for y in (2, 3):
            for z in (4, 5):
                triangles.append((x, y, z))
    triangles_array = np.array(triangles, dtype=np.int64)
    p = points[triangles_array]
    normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    outward = np.einsum("ij,ij->i", normal, p.mean(axis=1) - centre) > 0.0
    triangles_array[~outward] = triangles_array[~outward][:, ::-1]
    bmap = build_boundary_map_3d(grid, points, np.zeros_like(points), triangles_array)
    _check_lines_pair_up(bmap)
    expected = winding_brute_force(points, triangles_array, _centres(grid)) > 0
    assert np.array_equal(solid_cells_3d(bmap).reshape(-1), expected)
    # The x line through the two x vertices (y = z = 0.5: U = V = 8) crosses at them.
    entries = bmap.lines[0].line(8, 8)
    assert np.allclose(bmap.lines[0].coordinate[entries], [0.125, 0.875])


def test_crossings_grow_four_times_when_the_grid_is_refined() -> None:
    """The number of crossings follows the surface's area in cells: x4 per refinement."""
    points, triangles = icosphere(5)
    surface = np.array([0.51, 0.49, 0.503]) + 0.3 * points
    counts = []
    for n in (16, 32, 64):
        grid = Grid3D(nx=n, ny=n, nz=n, h=1.0 / n)
        counts.append(build_boundary_map_3d(grid, surface, np.zeros_like(surface),
                                            triangles).crossing_count)
    ratios = np.array(counts[1:]) / np.array(counts[:-1])
    assert np.all(np.abs(ratios - 4.0) < 0.15), (counts, ratios)


def test_crossings_lie_on_their_triangles_and_carry_rigid_velocities_exactly() -> None:
    points, triangles = icosphere(2)
    surface = np.array([0.5, 0.45, 0.55]) + 0.3 * points
    spin, drift = np.array([0.3, -1.2, 0.7]), np.array([0.1, 0.2, -0.4])
    velocities = drift + np.cross(spin, surface)
    grid = Grid3D(nx=10, ny=10, nz=10, h=0.1)
    bmap = build_boundary_map_3d(grid, surface, velocities, triangles)
    for axis, crossings in enumerate(bmap.lines):
        u, v = (axis + 1) % 3, (axis + 2) % 3
        line = np.repeat(np.arange(crossings.lines_u * crossings.lines_v),
                         np.diff(crossings.offsets))
        position = np.empty((crossings.count, 3))
        position[:, axis] = crossings.coordinate
        position[:, u] = grid.origin[u] + (line // crossings.lines_v) * 0.5 * grid.h
        position[:, v] = grid.origin[v] + (line % crossings.lines_v) * 0.5 * grid.h
        corners = surface[triangles[crossings.triangle]]
        assert np.allclose(np.einsum("ck,ckd->cd", crossings.weights, corners), position,
                           rtol=0.0, atol=1e-12)
        assert crossings.weights.min() >= -1e-12
        assert np.allclose(bmap.crossing_velocities(axis), drift + np.cross(spin, position),
                           rtol=0.0, atol=1e-12)
        # Sorted along each line.
        for index in range(crossings.offsets.shape[0] - 1):
            assert np.all(np.diff(crossings.coordinate[
                crossings.offsets[index]:crossings.offsets[index + 1]]) >= 0.0)


@pytest.mark.parametrize(("points", "triangles", "message"), [
    (np.zeros((3, 2)), np.array([[0, 1, 2]]), "points: shape"),
    (np.zeros((3, 3)), np.array([[0, 1, 3]]), "triangles: indices"),
    (np.full((3, 3), np.nan), np.array([[0, 1, 2]]), "must be finite"),
])
def test_bad_input_is_refused_in_one_line(points, triangles, message) -> None:
    grid = Grid3D(nx=4, ny=4, nz=4, h=0.25)
    with pytest.raises(ValueError, match=message):
        build_boundary_map_3d(grid, points, np.zeros_like(points), triangles)


def test_face_fractions_of_a_box_are_its_exact_cross_sections() -> None:
    from elastoflow.coupling import face_open_fractions_3d

    grid = Grid3D(nx=8, ny=8, nz=8, h=0.125)
    low, high = np.array([0.23, 0.18, 0.33]), np.array([0.71, 0.64, 0.77])
    corners, triangles = box_surface(low, high)
    bmap = build_boundary_map_3d(grid, corners, np.zeros_like(corners), triangles)
    fractions = face_open_fractions_3d(bmap)
    edges = np.arange(9) * grid.h
    overlap = [np.clip(np.minimum(edges[1:], high[a]) - np.maximum(edges[:-1], low[a]), 0.0,
                       None) / grid.h for a in range(3)]
    for axis, open_fraction in enumerate(fractions):
        u, v = (axis + 1) % 3, (axis + 2) % 3
        crossed = (edges > low[axis]) & (edges <= high[axis])
        covered = crossed[:, None, None] * overlap[u][None, :, None] * overlap[v][None, None, :]
        expected = np.transpose(1.0 - covered, np.argsort((axis, u, v)))
        assert np.allclose(open_fraction, expected, rtol=0.0, atol=1e-12), axis


def test_face_fractions_move_continuously_with_the_body() -> None:
    from elastoflow.coupling import face_open_fractions_3d

    points, triangles = icosphere(3)
    grid = Grid3D(nx=10, ny=10, nz=10, h=0.1)
    results = []
    for shift in (0.0, 1e-9):
        surface = np.array([0.5, 0.5, 0.5 + shift]) + 0.3 * points  # vertices on planes
        bmap = build_boundary_map_3d(grid, surface, np.zeros_like(surface), triangles)
        results.append(face_open_fractions_3d(bmap))
    for before, after in zip(*results):
        assert np.abs(after - before).max() < 1e-6
        assert before.min() >= 0.0 and before.max() <= 1.0
    # A sphere's cross-section through its centre: the solid share of the plane z = 0.5.
    solid = (1.0 - results[0][2][:, :, 5]).sum() * grid.h**2
    assert abs(solid - np.pi * 0.09) < 0.02 * np.pi * 0.09


def test_face_fractions_refilled_in_the_boxes_equal_fresh_ones() -> None:
    # The interior reuses an earlier map's fraction arrays: reset inside that map's box,
    # computed inside the new one. Off-origin grid, the sphere moved by several cells.
    from elastoflow.coupling import face_open_fractions_3d
    from elastoflow.coupling._map3d import bodies_box_3d

    points, triangles = icosphere(3)
    grid = Grid3D(nx=16, ny=12, nz=14, h=0.1, origin=(-0.3, 0.2, 0.1))
    maps = [build_boundary_map_3d(grid, centre + 0.25 * points, np.zeros_like(points),
                                  triangles)
            for centre in (np.array([0.2, 0.7, 0.6]), np.array([0.9, 0.9, 0.85]))]
    first = face_open_fractions_3d(maps[0])
    fresh = face_open_fractions_3d(maps[1])
    refilled = face_open_fractions_3d(maps[1], out=first, out_box=bodies_box_3d(maps[0]))
    for fresh_one, refilled_one in zip(fresh, refilled, strict=True):
        np.testing.assert_array_equal(refilled_one, fresh_one)
        assert fresh_one.min() < 0.5
    i0, j0, k0, i1, j1, k1 = bodies_box_3d(maps[1])
    outside = np.ones(fresh[0].shape, dtype=bool)
    outside[i0:i1, j0:j1, k0:k1] = False
    assert np.all(fresh[0][outside] == 1.0)


def test_cut_distances_of_a_box_are_exact_and_carry_its_rigid_velocity() -> None:
    """Velocity points next to an off-grid box: the distance to its faces along each axis,
    and the surface velocity of a rigid motion there."""
    from elastoflow.coupling import cut_distances_3d

    grid = Grid3D(nx=8, ny=8, nz=8, h=0.125)
    low, high = np.array([0.23, 0.18, 0.33]), np.array([0.71, 0.64, 0.77])
    corners, triangles = box_surface(low, high)
    spin, drift = np.array([0.2, -0.5, 0.9]), np.array([0.3, 0.1, -0.2])
    bmap = build_boundary_map_3d(grid, corners, drift + np.cross(spin, corners), triangles)
    cuts = cut_distances_3d(bmap)
    h = grid.h
    for component, points in enumerate((grid.faces_x(), grid.faces_y(), grid.faces_z())):
        theta, velocity = cuts.theta[component], cuts.velocity[component]
        position = np.stack(np.broadcast_arrays(*points), axis=-1)
        for axis in range(3):
            across = [a for a in range(3) if a != axis]
            inside_across = np.all([(position[..., a] > low[a]) & (position[..., a] < high[a])
                                    for a in across], axis=0)
            s = position[..., axis]
            for direction, wall in ((0, low[axis]), (1, high[axis])):
                # The box's faces crossed by the line through each point, towards -axis
                # (direction 0) or +axis (1), within one spacing.
                ahead = [(s - w) / h if direction == 0 else (w - s) / h for w in (low[axis],
                                                                                  high[axis])]
                nearest = np.full(s.shape, np.inf)
                for distance in ahead:
                    hit = inside_across & (distance > 0.0) & (distance <= 1.0)
                    nearest = np.where(hit, np.minimum(nearest, distance), nearest)
                got = theta[2 * axis + direction]
                assert np.allclose(np.where(np.isfinite(nearest), got, 0.0),
                                   np.where(np.isfinite(nearest), nearest, 0.0), rtol=0.0,
                                   atol=1e-12), (component, axis, direction)
                assert np.array_equal(np.isfinite(got), np.isfinite(nearest)), (
                    component, axis, direction)
                # The crossing point and the rigid velocity's own component there.
                where = np.isfinite(nearest)
                crossing = position[where].copy()
                sign = -1.0 if direction == 0 else 1.0
                crossing[:, axis] += sign * nearest[where] * h
                rigid = drift + np.cross(spin, crossing)
                assert np.allclose(velocity[2 * axis + direction][where], rigid[:, component],
                                   rtol=0.0, atol=1e-12)
