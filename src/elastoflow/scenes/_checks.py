"""Well-posedness checks of a scene, before anything is stepped.

Three stages, each naming the key path, the value and what is allowed:

* `check_flow` and `check_outlines` (part of `parse_scene`): a closed domain whose inflows do
  not balance, polygons with a repeated vertex or crossing edges, windmill blades that do not
  fit their hub;
* `check_memory` (first thing `build_simulation` does, before allocating anything): the memory
  the grid and the meshes will take, against the memory available;
* `check_built` (after the meshes and obstacles are built, before the `Simulation`): bodies and
  obstacles inside the domain and not overlapping, bodies resolved by the grid, jets in the
  fluid, pivots and probes on their bodies, moving obstacles staying inside the domain.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from elastoflow.scenes import _geometry as geometry
from elastoflow.scenes._schema3d import Scene3D
from elastoflow.scenes._schema import (
    CircleObstacleSpec,
    InflowSpec,
    OutflowSpec,
    PolygonObstacleSpec,
    PolygonShapeSpec,
    RectangleShapeSpec,
    RodBodySpec,
    RodShapeSpec,
    Scene,
    WindmillShapeSpec,
)

MIN_CELLS_ACROSS = 1.0
"""A body thinner than this many cells everywhere is refused: no face of the grid lies wholly
inside it, so the fluid flows through it (its open face fractions stay above 0)."""

RESOLVED_CELLS_ACROSS = 3.0
"""Below this many cells across, a part of a body gets a warning: the pressure jump and the
velocity gradients across it are carried by one or two cells, so forces and leakage are off."""

OVERLAP_CELLS = 0.25
"""Bodies and obstacles may overlap by up to this many cells (the fluid cannot see less): a
flag clamped on a cylinder cuts into the cylinder's polygon by a sliver."""

BYTES_PER_CELL = 700
"""Memory per grid cell [bytes] of a stepping simulation with its outputs: measured 520-540 at
256^2 to 1024^2 (process high-water mark, cavity scene), rounded up for bodies and video."""

BYTES_PER_ELEMENT = 1000
"""Memory per triangle [bytes]: mesh, element data, forces and substep buffers, with margin."""

BYTES_PER_OUTLINE_POINT = 200
"""Memory per obstacle outline vertex [bytes] (its edges in the boundary map, with margin)."""

BYTES_RUNTIME = 200 * 2**20
"""Python, NumPy, Numba and the package itself, before anything is built (measured ~110 MB)."""


# --------------------------------------------------------------------------------------------
# the domain's sides


def _side_flux(spec: Any, length: float, cells: int) -> float:
    """Discrete volume flux [m^2/s] into the domain through one inflow side, as the fluid
    samples the profile (at the face centres)."""
    if spec.profile == "uniform":
        return float(spec.speed) * length
    # The mean of 4 s (1 - s) over the face centres s = (k + 1/2) / n, in closed form (no
    # array: this runs before the memory check).
    return float(spec.speed) * (2.0 / 3.0 + 1.0 / (3.0 * float(cells) ** 2)) * length


def check_flow(scene: Scene) -> list[str]:
    """A closed domain (no outflow side) must take in as much as it lets out: the fluid is
    incompressible, so a net inflow has no solution (the pressure solve would only remove the
    mean of the divergence and the run would be silently wrong)."""
    b = scene.boundaries
    sides = {"left": b.left, "right": b.right, "bottom": b.bottom, "top": b.top}
    if any(isinstance(spec, OutflowSpec) for spec in sides.values()):
        return []
    nx, ny = scene.domain.cells
    lengths = {"left": (scene.domain.ly, ny), "right": (scene.domain.ly, ny),
               "bottom": (scene.domain.lx, nx), "top": (scene.domain.lx, nx)}
    inflows = {name: spec for name, spec in sides.items()
               if isinstance(spec, InflowSpec) and spec.speed != 0.0}
    if not inflows:
        return []
    fluxes = {name: _side_flux(spec, *lengths[name]) for name, spec in inflows.items()}
    net = sum(fluxes.values())
    scale = sum(abs(q) for q in fluxes.values())
    problems = []
    detail = ", ".join(f"{name} {q:.6g}" for name, q in fluxes.items())
    if abs(net) > 1e-9 * scale:
        if len(inflows) == 1:
            ((name, spec),) = inflows.items()
            key = f"boundaries.{name}.speed = {spec.speed:g}"
        else:
            key = "boundaries = " + ", ".join(f"{name} inflow {spec.speed:g} m/s"
                                              for name, spec in inflows.items())
        problems.append(
            f"{key}: the domain is closed (no outflow side) and takes in a net {net:.6g} m^2/s "
            f"(flux per side: {detail}); an incompressible fluid needs the inflows to sum to "
            'zero: make a side "outflow" or balance the speeds'
        )
    ramps = {spec.ramp_time for spec in inflows.values()}
    if len(inflows) > 1 and len(ramps) > 1:
        problems.append(
            "boundaries: the inflow sides of a closed domain must share one ramp_time (got "
            + ", ".join(f"{name}.ramp_time = {spec.ramp_time:g}" for name, spec in inflows.items())
            + "): while they ramp differently the net inflow is not zero"
        )
    return problems


def check_numerics(scene: Scene) -> list[str]:
    """Numerical choices that contradict each other: a Courant number at or above the limit
    at which the run stops as diverged."""
    time = scene.time
    if time.cfl is not None and time.cfl >= time.cfl_limit:
        return [(f"time.cfl = {time.cfl:g}: must be below time.cfl_limit = "
                 f"{time.cfl_limit:g} (the run stops as diverged above it as soon as the flow "
                 "reaches the characteristic speed); lower cfl or raise cfl_limit")]
    return []


def check_rods(scene: Scene) -> list[str]:
    """Rods need the monolithic scheme and the cut-cell boundary: the explicit scheme's
    substeps cannot advance a rod (its bending modes would need substeps of O(h^2)), and the
    staircase boundary flags cells by their centres, which a line of zero thickness never
    covers, so the fluid would flow through it."""
    problems = []
    for index, body in enumerate(scene.bodies):
        if not isinstance(body, RodBodySpec):
            continue
        if scene.coupling.scheme == "explicit":
            problems.append(
                f"bodies.{index}.shape = rod: needs coupling.scheme = \"monolithic\" (the "
                "explicit scheme advances triangle bodies only); leave coupling.scheme out or "
                "set it \"monolithic\"")
        elif scene.coupling.boundary == "staircase":
            problems.append(
                f"bodies.{index}.shape = rod: needs coupling.boundary = \"cut_cell\" (the "
                "staircase boundary flags cells by their centres, which a rod never covers, so "
                "the fluid would flow through it)")
    return problems


def check_liquid(scene: Scene) -> list[str]:
    """A scene with a free surface (``[liquid]``): walls on every side, a whole-pressure
    projection, the water's boxes inside the domain; elastic bodies and obstacles only with
    the monolithic coupling (`elastoflow.simulation.FreeSurfaceMonolithicCoupling`: floating
    bodies are lighter than the water they displace), no rods and no jets yet."""
    liquid = scene.liquid
    if liquid is None:
        return []
    problems = []
    if scene.jets:
        problems.append(
            f"jets: {len(scene.jets)} given with [liquid]; a free surface with jets is not "
            "supported yet; remove the jets or the [liquid] table")
    if (scene.bodies or scene.obstacles) and scene.coupling.scheme != "monolithic":
        problems.append(
            f'coupling.scheme = "{scene.coupling.scheme}": bodies and obstacles in a '
            'liquid with a free surface need the strong coupling; must be "monolithic"')
    for index, body in enumerate(scene.bodies):
        if isinstance(body, RodBodySpec):
            problems.append(
                f"bodies.{index}: a rod in a liquid with a free surface is not supported yet "
                "(elastic bodies with an area only); remove it or the [liquid] table")
    b = scene.boundaries
    for name, side in (("left", b.left), ("right", b.right), ("bottom", b.bottom),
                       ("top", b.top)):
        if isinstance(side, InflowSpec | OutflowSpec):
            problems.append(
                f"boundaries.{name} = {side.type}: a scene with [liquid] needs walls on every "
                "side; must be \"no_slip\", \"free_slip\" or \"moving\"")
    if scene.fluid.incremental_pressure:
        problems.append("fluid.incremental_pressure = true: not available with [liquid] (the "
                        "free surface's projection solves for the whole pressure); set it false")
    if scene.fluid.viscosity_scheme == "bdf2":
        problems.append('fluid.viscosity_scheme = "bdf2": not available with [liquid]; must be '
                        '"backward_euler" or "crank_nicolson"')
    if scene.fluid.advection == "upwind3":
        problems.append('fluid.advection = "upwind3": not available with [liquid] (the flux '
                        'form has no air-side treatment yet); must be "semi_lagrangian" or '
                        '"maccormack"')
    x0, y0, x1, y1 = scene.domain.bounds
    for index, box in enumerate(liquid.boxes):
        if box[0] < x0 or box[1] < y0 or box[2] > x1 or box[3] > y1:
            problems.append(
                f"liquid.boxes.{index} = [{', '.join(f'{c:g}' for c in box)}]: must lie inside "
                f"the domain [{x0:g}, {x1:g}] x [{y0:g}, {y1:g}]")
    if isinstance(liquid.height, int | float) and not y0 < liquid.height <= y1:
        problems.append(f"liquid.height = {liquid.height:g}: must lie in ({y0:g}, {y1:g}], "
                        "above the domain's bottom and not above its top")
    return problems


# --------------------------------------------------------------------------------------------
# polygons and shapes written in the scene


def _closed_points(points: Sequence[tuple[float, float]]) -> np.ndarray:
    polygon = np.asarray(points, dtype=np.float64)
    if len(polygon) > 3 and np.array_equal(polygon[0], polygon[-1]):
        polygon = polygon[:-1]
    return polygon


def _polygon_problems(key: str, points: Sequence[tuple[float, float]]) -> list[str]:
    polygon = _closed_points(points)
    first: dict[tuple[float, float], int] = {}
    for index, vertex in enumerate(map(tuple, polygon.tolist())):
        if vertex in first:
            return [(f"{key}.{index} = [{vertex[0]:g}, {vertex[1]:g}]: repeats vertex "
                    f"{first[vertex]}; a polygon lists each vertex once (the first is not "
                    "repeated at the end, except as an exact closing copy)")]
        first[vertex] = index
    extent = float(np.max(np.ptp(polygon, axis=0)))
    spread = np.linalg.svd(polygon - polygon.mean(axis=0), compute_uv=False)
    if spread[-1] <= 1e-12 * max(extent, 1e-300) * np.sqrt(len(polygon)):
        return [(f"{key} = {_points_text(polygon)}: the polygon encloses no area (its vertices "
                 "are on one line)")]
    crossing = geometry.self_crossing(polygon)
    if crossing is not None:
        i, j = crossing
        count = len(polygon)
        return [(f"{key}: edge {i} (vertices {i} -> {(i + 1) % count}) and edge {j} (vertices "
                f"{j} -> {(j + 1) % count}) cross or touch; the outline must be a simple "
                "polygon (no edge may meet another except its neighbours at shared vertices)")]
    return []


def _rod_problems(key: str, points: Sequence[tuple[float, float]]) -> list[str]:
    line = np.asarray(points, dtype=np.float64)
    repeated = np.flatnonzero(np.all(line[1:] == line[:-1], axis=1))
    if repeated.size:
        k = int(repeated[0])
        return [(f"{key}.{k + 1} = [{line[k, 0]:g}, {line[k, 1]:g}]: repeats point {k}; "
                 "consecutive points of a rod must differ")]
    return []


def _points_text(polygon: np.ndarray) -> str:
    text = "[" + ", ".join(f"[{x:g}, {y:g}]" for x, y in polygon.tolist()) + "]"
    return text if len(text) <= 60 else text[:57] + "..."


def check_outlines(scene: Scene) -> list[str]:
    """Polygons (bodies and obstacles) that are simple, and windmills whose blades fit."""
    problems: list[str] = []
    for index, obstacle in enumerate(scene.obstacles):
        if isinstance(obstacle, PolygonObstacleSpec):
            problems += _polygon_problems(f"obstacles.{index}.points", obstacle.points)
    for index, body in enumerate(scene.bodies):
        shape = body.shape
        if isinstance(shape, PolygonShapeSpec):
            problems += _polygon_problems(f"bodies.{index}.shape.points", shape.points)
        elif isinstance(shape, RodShapeSpec):
            problems += _rod_problems(f"bodies.{index}.shape.points", shape.points)
        elif isinstance(shape, WindmillShapeSpec):
            half = 0.5 * shape.blade_width
            root = math.asin(half / shape.hub_radius) if half < shape.hub_radius else math.inf
            if not 2.0 * root * shape.blades < 2.0 * math.pi * 0.9:
                problems.append(
                    f"bodies.{index}.shape.blade_width = {shape.blade_width:g}: {shape.blades} "
                    f"blades this wide do not fit on a hub of radius {shape.hub_radius:g} with a "
                    "gap between them (the roots may take up 90 % of the hub's circumference)"
                )
    return problems


# --------------------------------------------------------------------------------------------
# memory


def available_memory() -> int | None:
    """Memory this process may still use [bytes]: the system's available memory, or the
    control group's limit minus its use when that is lower; None when unknown."""
    candidates = []
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                candidates.append(int(line.split()[1]) * 1024)
    except (OSError, ValueError, IndexError):
        pass
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        if limit != "max":
            used = int(Path("/sys/fs/cgroup/memory.current").read_text().strip())
            candidates.append(max(0, int(limit) - used))
    except (OSError, ValueError):
        pass
    if not candidates:
        try:
            candidates.append(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
        except (ValueError, OSError, AttributeError):
            return None
    return min(candidates)


def _mesh_elements(shape: Any) -> float:
    """Rough element count of a body shape before meshing it (0 when unknown: a mesh file)."""
    if isinstance(shape, RectangleShapeSpec):
        return float(shape.triangles_per_cell) * shape.divisions[0] * shape.divisions[1]
    size = getattr(shape, "element_size", None)
    if isinstance(shape, WindmillShapeSpec):
        size = 0.5 * shape.blade_width if size is None else size
        area = (math.pi * shape.hub_radius**2
                + shape.blades * (shape.radius - shape.hub_radius) * shape.blade_width)
    elif isinstance(shape, PolygonShapeSpec) and size is not None:
        polygon = _closed_points(shape.points)
        area = abs(0.5 * float(np.sum(polygon[:, 0] * np.roll(polygon[:, 1], -1)
                                      - np.roll(polygon[:, 0], -1) * polygon[:, 1])))
    else:
        return 0.0
    # Triangle's quality meshes hold about 1.5 times the equilateral count.
    element_area = math.sqrt(3.0) / 4.0 * size * size
    return 1.5 * area / element_area if element_area > 0.0 else math.inf


def memory_estimate(scene: Scene | Scene3D) -> tuple[float, list[tuple[str, float]]]:
    """Memory a run of ``scene`` needs [bytes], and each part's share: ``(key path as
    written, bytes)`` for the grid, each body's mesh and each obstacle's outline (3D: the
    grid and the bodies together)."""
    if isinstance(scene, Scene3D):
        from elastoflow.scenes._build3d import memory_estimate_3d, memory_parts_3d

        return memory_estimate_3d(scene), memory_parts_3d(scene)
    nx, ny = scene.domain.cells
    grid_key = (f"domain.nx = {scene.domain.nx}" if scene.domain.nx is not None
                else f"domain.h = {scene.domain.h:g}")
    parts: list[tuple[str, float]] = [
        (f"{grid_key} ({nx} x {ny} cells)", float(nx + 1) * float(ny + 1) * BYTES_PER_CELL)
    ]
    for index, body in enumerate(scene.bodies):
        elements = _mesh_elements(body.shape)
        if isinstance(body.shape, RodShapeSpec):
            # A rod's node costs about what a triangle does (its band and the map's edges).
            elements = float(body.shape.segments or len(body.shape.points))
            key = f"bodies.{index}.shape.segments = {body.shape.segments}"
        elif isinstance(body.shape, RectangleShapeSpec):
            key = f"bodies.{index}.shape.divisions = {list(body.shape.divisions)}"
        else:
            key = f"bodies.{index}.shape.element_size = {getattr(body.shape, 'element_size', None)}"
        parts.append((f"{key} (~{elements:.3g} elements)", elements * BYTES_PER_ELEMENT))
    for index, obstacle in enumerate(scene.obstacles):
        points = (obstacle.segments if isinstance(obstacle, CircleObstacleSpec)
                  else len(getattr(obstacle, "points", ())) or 4)
        parts.append((f"obstacles.{index}", float(points) * BYTES_PER_OUTLINE_POINT))
    return BYTES_RUNTIME + sum(b for _, b in parts), parts


def _bytes_text(count: float) -> str:
    for unit, size in (("EB", 2.0**60), ("PB", 2.0**50), ("TB", 2.0**40), ("GB", 2.0**30),
                       ("MB", 2.0**20)):
        if count >= size:
            return f"{count / size:.3g} {unit}"
    return f"{count / 2**10:.3g} kB"


def check_memory(scene: Scene, available: int | None = None) -> list[str]:
    """One problem when the run would need more memory than is available (``available``
    [bytes]; default: `available_memory`), naming the part that takes most of it."""
    total, parts = memory_estimate(scene)
    if available is None:
        available = available_memory()
    if available is None or total <= available:
        return []
    key, share = max(parts, key=lambda part: part[1])
    this = "" if share >= 0.9 * total else f" ({_bytes_text(share)} for this)"
    return [(f"{key}: the run would need about {_bytes_text(total)} of memory{this}, more than "
             f"the {_bytes_text(available)} available; use fewer cells or elements")]


# --------------------------------------------------------------------------------------------
# the built geometry


def _loops(mesh: Any) -> tuple[np.ndarray, np.ndarray]:
    """Boundary edges of a mesh as start and end points, shapes (k, 2)."""
    edges = mesh.boundary_edges
    return mesh.points[edges[:, 0]], mesh.points[edges[:, 1]]


def _inscribed_width(mesh: Any, starts: np.ndarray, ends: np.ndarray) -> float:
    """Twice the largest distance from a node, element centroid or edge midpoint of the mesh
    to its boundary [m]: the diameter of about its largest inscribed circle."""
    corners = mesh.points[mesh.triangles]
    samples = np.concatenate([
        mesh.points, corners.mean(axis=1),
        0.5 * (corners + np.roll(corners, -1, axis=1)).reshape(-1, 2),
    ])
    return 2.0 * float(geometry.distance_to_segments(_thinned(samples), starts, ends).max())


MAX_SAMPLES = 20_000
"""Most interior points of one body a geometry check looks at (every k-th beyond that): the
checks compare them with every boundary edge, and a mesh that large is fine everywhere."""


def _thinned(points: np.ndarray) -> np.ndarray:
    return points[::max(1, len(points) // MAX_SAMPLES)]


def _boundary_samples(starts: np.ndarray, ends: np.ndarray, spacing: float) -> np.ndarray:
    """Points along the edges at most ``spacing`` apart, end points included, shape (p, 2)."""
    length = np.linalg.norm(ends - starts, axis=1)
    pieces = np.maximum(1, np.ceil(length / spacing)).astype(np.int64)
    owner = np.repeat(np.arange(len(starts)), pieces)
    offset = np.arange(owner.size) - np.repeat(np.cumsum(pieces) - pieces, pieces)
    t = (offset / pieces[owner])[:, None]
    return starts[owner] + t * (ends[owner] - starts[owner])


def _overlap_depth(samples: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> float:
    """How deep [m] the deepest of ``samples`` lies inside the region the edges bound (0 when
    none is inside)."""
    inside = geometry.points_in_polygons(samples, starts, ends)
    if not inside.any():
        return 0.0
    return float(geometry.distance_to_segments(samples[inside], starts, ends).max())


def _overlap(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray],
             inner_a: np.ndarray, inner_b: np.ndarray, spacing: float, tolerance: float) -> bool:
    """Whether two regions overlap by more than ``tolerance`` [m]: a point of one (on its
    outline every ``spacing`` [m], or inside it: ``inner_a``, ``inner_b``) lies that deep inside
    the other. Touching, or a sliver thinner than ``tolerance`` (a flag clamped on the polygon
    of a round cylinder), is no overlap."""
    samples_a = np.concatenate([_boundary_samples(*a, spacing), inner_a])
    samples_b = np.concatenate([_boundary_samples(*b, spacing), inner_b])
    return (_overlap_depth(samples_a, *b) > tolerance
            or _overlap_depth(samples_b, *a) > tolerance)


def _inner_points(polygon_or_mesh: Any) -> np.ndarray:
    """Points inside a region: element centroids of a mesh, nothing more for a polygon (its
    outline samples suffice)."""
    if hasattr(polygon_or_mesh, "triangles"):
        return _thinned(polygon_or_mesh.points[polygon_or_mesh.triangles].mean(axis=1))
    return np.zeros((0, 2))


def _edges_on_grid_lines(starts: np.ndarray, ends: np.ndarray, grid: Any) -> np.ndarray:
    """Indices of axis-parallel edges that lie on a grid line (cell faces or centres) to within
    1e-6 of a cell: the half-grid lines the boundary map crosses. Edges on the domain's own
    sides are left out: the faces there are the walls, closed whatever the body does (a reed
    clamped to the floor)."""
    h = grid.h
    origin = np.asarray(grid.origin, dtype=np.float64)
    found = []
    for axis in (0, 1):
        # Edges parallel to the other axis: constant coordinate along ``axis``.
        flat = np.abs(ends[:, axis] - starts[:, axis]) <= 1e-6 * h
        position = 2.0 * (0.5 * (starts[:, axis] + ends[:, axis]) - origin[axis]) / h
        on = flat & (np.abs(position - np.round(position)) <= 2e-6)
        side = 2 * (grid.nx if axis == 0 else grid.ny)
        on &= (np.round(position) != 0) & (np.round(position) != side)
        found.append(np.flatnonzero(on))
    return np.unique(np.concatenate(found))


def _fmt_point(point: Sequence[float]) -> str:
    return f"[{point[0]:.4g}, {point[1]:.4g}]"


def check_built(scene: Scene, grid: Any, meshes: Sequence[Any], obstacles: Sequence[Any],
                *, steps: int, dt: float) -> tuple[list[str], list[str]]:
    """Problems and warnings of the built geometry (rest meshes, obstacle outlines at t = 0).

    Args:
        scene: The scene.
        grid: Its `Grid2D`.
        meshes: Each body's rest `TriangleMesh`, in scene order.
        obstacles: Each obstacle (`elastoflow.coupling.Obstacle`), in scene order.
        steps: Fluid steps the run will take (moving obstacles must stay inside until then).
        dt: Fluid step [s].

    Returns:
        ``(problems, warnings)``, one line each.
    """
    from elastoflow.scenes._errors import domain_text

    problems: list[str] = []
    warnings: list[str] = []
    h = grid.h
    x0, y0 = (float(c) for c in grid.origin)
    x1, y1 = x0 + grid.lx, y0 + grid.ly
    tolerance = 1e-9 * max(grid.lx, grid.ly, abs(x0), abs(y0), abs(x1), abs(y1))
    inside_text = f"must lie inside the domain {domain_text(scene)}"

    def outside(points: np.ndarray) -> np.ndarray:
        return ((points[:, 0] < x0 - tolerance) | (points[:, 0] > x1 + tolerance)
                | (points[:, 1] < y0 - tolerance) | (points[:, 1] > y1 + tolerance))

    outlines = [_loops(mesh) for mesh in meshes]
    for index, mesh in enumerate(meshes):
        key = f"bodies.{index}.shape"
        away = outside(mesh.points)
        if away.any():
            low, high = mesh.points.min(axis=0), mesh.points.max(axis=0)
            how = "entirely" if away.all() else "partly"
            problems.append(f"{key} = {scene.bodies[index].shape.type} with bounds "
                            f"[{low[0]:g}, {low[1]:g}, {high[0]:g}, {high[1]:g}]: the body is "
                            f"{how} outside the domain; it {inside_text}")
            continue
        starts, ends = outlines[index]
        if mesh.triangle_count == 0:
            # A rod: zero thickness by design, blocked by the thin-body cuts.
            continue
        width = _inscribed_width(mesh, starts, ends)
        if width < MIN_CELLS_ACROSS * h:
            problems.append(
                f"{key} = {scene.bodies[index].shape.type}: the body is at most {width:.3g} m "
                f"= {width / h:.2f} cells across, thinner than {MIN_CELLS_ACROSS:g} cell "
                f"(h = {h:.4g} m): the fluid would flow through it; refine the grid "
                "(domain.nx or domain.h) or thicken the body")
            continue
        middle, widths = geometry.ray_thickness(starts, ends)
        thinnest = int(np.argmin(widths))
        if widths[thinnest] < RESOLVED_CELLS_ACROSS * h:
            warnings.append(
                f"{key}: the body is only {widths[thinnest] / h:.2f} cells across near "
                f"{_fmt_point(middle[thinnest])} ({widths[thinnest]:.3g} m, h = {h:.4g} m); "
                f"the method needs about {RESOLVED_CELLS_ACROSS:g} cells across a body to "
                "resolve the pressure and the flow around it (forces and leakage will be off)")

    for index, (starts, ends) in enumerate(outlines):
        # A free body leaves a line at once; a clamped one keeps the edges near its clamp on it.
        if scene.bodies[index].fixed is None or not len(starts):
            continue
        on_line = _edges_on_grid_lines(starts, ends, grid)
        if on_line.size:
            a, b = starts[on_line[0]], ends[on_line[0]]
            warnings.append(
                f"bodies.{index}.shape: {on_line.size} boundary edges of this clamped body lie "
                f"on grid lines (e.g. "
                f"{_fmt_point(a)}-{_fmt_point(b)}, h = {h:.4g} m); the faces along them flip "
                "between fluid and solid with the smallest motion, which shakes the body and "
                "its force from step to step (docs/method_notes.md item 9); shift the body or "
                "change h so that its edges lie off the lines")

    for first in range(len(meshes)):
        for second in range(first + 1, len(meshes)):
            if _overlap(outlines[first], outlines[second], _inner_points(meshes[first]),
                        _inner_points(meshes[second]), 0.25 * h, OVERLAP_CELLS * h):
                problems.append(f"bodies.{second}.shape: overlaps bodies.{first}.shape at rest; "
                                "bodies must not overlap")

    polygons = [obstacle.points_at(0.0) for obstacle in obstacles]
    for index, polygon in enumerate(polygons):
        edges = geometry.polygon_edges(polygon)
        for body_index, mesh in enumerate(meshes):
            if _overlap(outlines[body_index], edges, _inner_points(mesh), _inner_points(polygon),
                        0.25 * h, OVERLAP_CELLS * h):
                problems.append(f"bodies.{body_index}.shape: crosses or lies inside obstacles."
                                f"{index} at rest; a body must lie in the fluid, outside every "
                                "obstacle")

    covered = np.zeros((grid.nx, grid.ny), dtype=bool)
    regions = [geometry.polygon_edges(p) for p in polygons] + outlines
    for starts, ends in regions:
        covered |= geometry.cell_centres_inside(starts, ends, grid.nx, grid.ny, h,
                                                origin=(x0, y0))
    if regions and covered.all():
        problems.append(f"obstacles: the obstacles and bodies cover every one of the "
                        f"{grid.nx} x {grid.ny} cells; no fluid is left to simulate")

    for index, jet in enumerate(scene.jets):
        jx0, jy0, jx1, jy1 = (a - b for a, b in zip(jet.region, (x0, y0, x0, y0), strict=True))
        i = np.arange(grid.nx)
        j = np.arange(grid.ny)
        in_x = i[((i + 0.5) * h >= jx0 - 1e-12) & ((i + 0.5) * h <= jx1 + 1e-12)]
        in_y = j[((j + 0.5) * h >= jy0 - 1e-12) & ((j + 0.5) * h <= jy1 + 1e-12)]
        if in_x.size == 0 or in_y.size == 0:
            warnings.append(f"jets.{index}.region = {list(jet.region)}: holds no cell centre "
                            f"(h = {h:.4g} m), so the jet only sets the faces inside it")
            continue
        hit = covered[np.ix_(in_x, in_y)]
        if hit.any():
            a, b = np.argwhere(hit)[0]
            where = (x0 + (in_x[a] + 0.5) * h, y0 + (in_y[b] + 0.5) * h)
            problems.append(f"jets.{index}.region = {list(jet.region)}: reaches inside a body or "
                            f"obstacle (at {_fmt_point(where)}); a jet must blow in the fluid")

    for index, body in enumerate(scene.bodies):
        if body.pivot is None or index >= len(meshes):
            continue
        mesh = meshes[index]
        pivot = np.asarray(body.pivot, dtype=np.float64)
        distance = float(np.linalg.norm(mesh.points - pivot, axis=1).min())
        if distance > h and not geometry.points_in_polygons(pivot[None, :], *outlines[index])[0]:
            problems.append(f"bodies.{index}.pivot = {list(body.pivot)}: lies {distance:.3g} m "
                            f"from the body's nearest node; the pivot must lie on the body "
                            f"(inside it or within one cell, {h:.4g} m, of a node)")

    for index, probe in enumerate(scene.outputs.probes):
        if probe.body is None or probe.body >= len(meshes):
            continue
        mesh = meshes[probe.body]
        if probe.node is not None and probe.node >= mesh.point_count:
            problems.append(f"outputs.probes.{index}.node = {probe.node}: body {probe.body} has "
                            f"nodes 0..{mesh.point_count - 1}")
        if probe.point is not None:
            distance = float(np.linalg.norm(mesh.points - np.asarray(probe.point), axis=1).min())
            if distance > h:
                problems.append(f"outputs.probes.{index}.point = {list(probe.point)}: lies "
                                f"{distance:.3g} m from body {probe.body}'s nearest node; it must "
                                f"lie within one cell ({h:.4g} m) of a node")

    for index, obstacle in enumerate(obstacles):
        spec = scene.obstacles[index]
        if spec.motion is None:
            continue
        leaves = _leaving_time(obstacle, spec.motion, steps, dt, outside)
        if leaves is not None:
            problems.append(f"obstacles.{index}.motion: the obstacle leaves the domain at "
                            f"t = {leaves:.4g} s (step {max(math.ceil(leaves / dt - 1e-9), 1)} "
                            f"of {steps}); a moving obstacle {inside_text} for the whole run")
    return problems, warnings


def _leaving_time(obstacle: Any, motion: Any, steps: int, dt: float,
                  outside: Any) -> float | None:
    """When a moving obstacle first has a vertex outside the domain during the run, or None.
    A translation is checked at its end and timed exactly along its straight path (the first
    sample outside would name the end of the run); a rotation at the samples of
    `_motion_times`."""
    samples = _motion_times(motion, steps, dt)
    if motion.angular_velocity != 0.0:
        for time in samples:
            if outside(obstacle.points_at(float(time))).any():
                return float(time)
        return None
    if not (outside(obstacle.points_at(0.0)).any()
            or outside(obstacle.points_at(float(samples[-1]))).any()):
        return None
    start = obstacle.points_at(0.0)
    velocity = np.asarray(motion.velocity, dtype=np.float64)
    # The path is a straight line: step along it to the first sample outside, then halve.
    low, high = 0.0, float(samples[-1])
    if outside(start).any():
        return 0.0
    for _ in range(60):
        middle = 0.5 * (low + high)
        if outside(start + velocity * middle).any():
            high = middle
        else:
            low = middle
    return high


def _motion_times(motion: Any, steps: int, dt: float) -> np.ndarray:
    """Times [s] at which to look at a moving obstacle over the run: both ends for a pure
    translation (its path is a straight line), otherwise at least every 1/16 turn and every
    step up to 4096 samples."""
    end = steps * dt
    if motion.angular_velocity == 0.0:
        return np.array([0.0, end])
    turns = abs(motion.angular_velocity) * end / (2.0 * math.pi)
    count = int(min(max(steps, 16 * turns, 2), 4096))
    return np.linspace(0.0, end, count + 1)
