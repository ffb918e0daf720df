"""Boundary study, speed and stability parts (issue 13).

**Speed.** The paper's claim for its boundary map: building it and classifying the grid from
it costs in proportion to the body's perimeter (the crossings of its boundary edges with the
grid lines, about perimeter / h, plus one pass over the edges), where the classification it
replaces tests every grid point against every element (`classify_points_brute_force`): grid
points times elements. The body is a disc of radius 0.3 m meshed with boundary edges as long
as its elements (`solid.mesh_from_polygon`, so the triangles grow as the square of the
boundary edges); each size is timed as a step does it: the map (`build_boundary_map`), then
each treatment's interior from it (`BoundaryCutCell`, `BoundaryStaircase`, reusing the last
result's arrays as a run does), and the brute-force classification of the same points, which
must agree with the map's (`classify_points`) point for point. Then the whole coupled step of
the built-in scenes with either treatment, through the `Simulation` API.

**Stability.** The bar in a jet (`bar_in_jet`) with the default, monolithic, coupling scheme
on a coarser grid and a shorter run than the scene's: the largest stable time step and the
lowest stable solid/fluid density ratio per boundary treatment, each by bisection (module
constants below; the page says what "stable" means).

Timings are measurements of this machine at the time of the run (shared, two cores): never
asserted.
"""

from __future__ import annotations

import csv
import io
import math
import re
import time as _time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from elastoflow.validation._turek_hron import model_2d
from elastoflow.validation._boundary_study import (
    _LABEL,
    TREATMENTS,
    _pyplot,
    _save,
    compose_section,
    observed_order,
    write_part,
)

if TYPE_CHECKING:
    from elastoflow.scenes import Scene
    from elastoflow.simulation import Simulation

SPEED_EDGES: tuple[int, ...] = (32, 64, 128, 256, 512)
"""Boundary edges of the disc."""
SPEED_CELLS: tuple[int, ...] = (64, 128, 256, 512)
"""Cells across the unit square."""
SPEED_RADIUS = 0.3
SPEED_CENTRE = (0.5123, 0.4871)
SPEED_REPEATS = 5
"""Each map and interior is timed this many times; the best counts."""
BRUTE_FORCE_LIMIT = 2.5e8
"""Grid points times triangles above which the brute force is not run (about 2 s here, 8 ns a test)."""
MAP_EDGES: tuple[int, ...] = (512, 4096, 32768)
"""Edges of the outline-only discs that time the map alone at large sizes."""
MAP_CELLS: tuple[int, ...] = (512, 4096, 32768)
"""Their grids: the map never allocates per grid point, so 32768^2 costs nothing to set up."""
STEP_SCENES: tuple[str, ...] = ("bar_in_jet", "windmill")
STEP_WARMUP = 10
STEP_COUNT = 20
STEP_REPEATS = 5


def disc_mesh(edges: int) -> Any:
    """A disc of radius `SPEED_RADIUS` with ``edges`` boundary edges, its elements as large
    as the boundary edges (a `solid.TriangleMesh`)."""
    from elastoflow.solid import mesh_from_polygon

    angles = 2.0 * np.pi * np.arange(edges) / edges
    polygon = np.column_stack((SPEED_CENTRE[0] + SPEED_RADIUS * np.cos(angles),
                               SPEED_CENTRE[1] + SPEED_RADIUS * np.sin(angles)))
    return mesh_from_polygon(polygon, element_size=2.0 * np.pi * SPEED_RADIUS / edges)


def _best(call: Callable[[], object], repeats: int) -> float:
    best = math.inf
    for _ in range(repeats):
        start = _time.perf_counter()
        call()
        best = min(best, _time.perf_counter() - start)
    return best


@dataclass(frozen=True)
class SpeedCase:
    """The boundary handling of one disc on one grid, timed.

    Attributes:
        edges: Boundary edges of the disc.
        triangles: Its triangles.
        cells: Cells across the unit square.
        crossings: Entries of the boundary map (x- and y-map together).
        map_seconds: `build_boundary_map` [s] (best of the repeats).
        cut_cell_seconds: `BoundaryCutCell.interior` from the map [s].
        staircase_seconds: `BoundaryStaircase.interior` from the map [s].
        classify_seconds: `classify_points` from the map [s] (the fill alone).
        brute_force_seconds: `classify_points_brute_force` against the triangles [s]; NaN
            where grid points times triangles exceed `BRUTE_FORCE_LIMIT`.
        disagreements: Grid points (cells, u and v points) whose solid flag or body differs
            between the brute force and the map's classification; -1 where not run.
    """

    edges: int
    triangles: int
    cells: int
    crossings: int
    map_seconds: float
    cut_cell_seconds: float
    staircase_seconds: float
    classify_seconds: float
    brute_force_seconds: float
    disagreements: int

    @property
    def grid_points(self) -> int:
        """Cell centres, u and v points."""
        n = self.cells
        return n * n + 2 * n * (n + 1)

    @property
    def step_seconds(self) -> dict[str, float]:
        """Map plus interior, what a step spends on the boundary, per treatment [s]."""
        return {"cut_cell": self.map_seconds + self.cut_cell_seconds,
                "staircase": self.map_seconds + self.staircase_seconds}


def speed_case(mesh: Any, cells: int, *, repeats: int = SPEED_REPEATS,
               brute_force_limit: float = BRUTE_FORCE_LIMIT) -> SpeedCase:
    """Time the map, both interiors and the brute force for ``mesh`` on ``cells``^2 cells."""
    from elastoflow.coupling import (
        BoundaryCutCell,
        BoundaryStaircase,
        build_boundary_map,
        classify_points,
        classify_points_brute_force,
    )
    from elastoflow.grid import Grid2D

    grid = Grid2D(cells, cells, 1.0 / cells)
    points = np.ascontiguousarray(mesh.points)
    # A rigid rotation, so that the velocities the two classifications interpolate differ
    # from point to point (and agree: both are exact for affine motion).
    velocities = np.column_stack((-(points[:, 1] - SPEED_CENTRE[1]),
                                  points[:, 0] - SPEED_CENTRE[0]))
    edges = mesh.boundary_edges
    bmap = build_boundary_map(grid, points, velocities, edges)
    map_seconds = _best(lambda: build_boundary_map(grid, points, velocities, edges), repeats)
    cut_cell, staircase = BoundaryCutCell(), BoundaryStaircase()
    cut_out = cut_cell.interior(grid, bmap)
    stair_out = staircase.interior(grid, bmap)
    cut_seconds = _best(lambda: cut_cell.interior(grid, bmap, out=cut_out), repeats)
    stair_seconds = _best(lambda: staircase.interior(grid, bmap, out=stair_out), repeats)
    classification = classify_points(grid, bmap)
    classify_seconds = _best(lambda: classify_points(grid, bmap, out=classification),
                             repeats)
    triangles = np.ascontiguousarray(mesh.triangles)
    n_points = cells * cells + 2 * cells * (cells + 1)
    brute_seconds, disagreements = math.nan, -1
    if n_points * triangles.shape[0] <= brute_force_limit:
        start = _time.perf_counter()
        brute = classify_points_brute_force(
            grid, points, velocities, edges, triangles=triangles,
            triangle_body=np.zeros(triangles.shape[0], dtype=np.int64))
        brute_seconds = _time.perf_counter() - start
        disagreements = classification_disagreements(classification, brute)
    crossings = int(bmap.x_coordinate.shape[0] + bmap.y_coordinate.shape[0])
    return SpeedCase(int(edges.shape[0]), int(triangles.shape[0]), cells, crossings,
                     map_seconds, cut_seconds, stair_seconds, classify_seconds, brute_seconds,
                     disagreements)


def classification_disagreements(first: Any, second: Any) -> int:
    """Grid points whose solid flag or body index differs between two `PointClassification`s
    (body indices compared on solid points only)."""
    count = 0
    for name in ("cells", "faces_x", "faces_y"):
        solid_a, solid_b = getattr(first, f"solid_{name}"), getattr(second, f"solid_{name}")
        body_a, body_b = getattr(first, f"body_{name}"), getattr(second, f"body_{name}")
        count += int(np.count_nonzero(solid_a != solid_b))
        count += int(np.count_nonzero(solid_a & solid_b & (body_a != body_b)))
    return count


@dataclass(frozen=True)
class MapCase:
    """The boundary map alone for a disc outline on a large grid, timed.

    Attributes:
        edges: Edges of the outline.
        cells: Cells across the unit square.
        crossings: Entries of the map.
        seconds: `build_boundary_map` [s], best of the repeats.
    """

    edges: int
    cells: int
    crossings: int
    seconds: float


def map_case(edges: int, cells: int, *, repeats: int = SPEED_REPEATS) -> MapCase:
    """Time `build_boundary_map` of a disc outline with ``edges`` edges on ``cells``^2."""
    from elastoflow.coupling import build_boundary_map
    from elastoflow.grid import Grid2D

    grid = Grid2D(cells, cells, 1.0 / cells)
    angles = 2.0 * np.pi * np.arange(edges) / edges
    points = np.column_stack((SPEED_CENTRE[0] + SPEED_RADIUS * np.cos(angles),
                              SPEED_CENTRE[1] + SPEED_RADIUS * np.sin(angles)))
    velocities = np.zeros_like(points)
    loop = np.arange(edges)
    outline = np.column_stack((loop, (loop + 1) % edges))
    bmap = build_boundary_map(grid, points, velocities, outline)
    seconds = _best(lambda: build_boundary_map(grid, points, velocities, outline), repeats)
    return MapCase(edges, cells, int(bmap.x_coordinate.shape[0] + bmap.y_coordinate.shape[0]),
                   seconds)


@dataclass(frozen=True)
class SceneStep:
    """The whole coupled step of a built-in scene with one treatment, timed.

    Attributes:
        scene: The built-in scene's name.
        treatment: "cut_cell" or "staircase".
        cells: Grid cells (nx, ny).
        triangles: Triangles of its bodies.
        step_seconds: Mean wall time of a step over the best of the repeats [s].
        boundary_seconds: The step's "map" phase (map and interior) over the same steps [s].
        brute_force_seconds: `classify_points_brute_force` of the same objects (bodies by
            their triangles, obstacles by their outlines) at the last step [s].
        disagreements: Grid points where it and the map's classification differ.
    """

    scene: str
    treatment: str
    cells: tuple[int, int]
    triangles: int
    step_seconds: float
    boundary_seconds: float
    brute_force_seconds: float
    disagreements: int


def _scene_with(name: str, **changes: Any) -> Scene:
    """The built-in scene ``name`` with the dotted keys of ``changes`` replaced
    (``coupling__boundary="staircase"``; ``bodies__0__material__density=...``)."""
    from elastoflow.scenes import Scene, get_scene, parse_scene

    data = get_scene(name).model_dump(exclude_none=True)
    for dotted, value in changes.items():
        keys = dotted.split("__")
        target: Any = data
        for key in keys[:-1]:
            target = target[int(key)] if isinstance(target, list) else target[key]
        target[keys[-1]] = value
    data.pop("source", None)
    scene = parse_scene(data, source=f"built-in scene {name!r}, modified")
    assert isinstance(scene, Scene)
    return scene


def _brute_force_of(simulation: Simulation) -> tuple[float, int]:
    """Brute-force classification of the simulation's objects now, and its disagreements
    with the map's."""
    from elastoflow.coupling import (
        build_boundary_map,
        classify_points,
        classify_points_brute_force,
    )

    model = model_2d(simulation)
    points, velocities, edges, edge_body = model.boundary_points(simulation.state)
    offsets = model.object_offsets()
    triangles = np.concatenate([body.mesh.triangles + offsets[k]
                                for k, body in enumerate(model.bodies)])
    triangle_body = np.concatenate([np.full(body.mesh.triangle_count, k, dtype=np.int64)
                                    for k, body in enumerate(model.bodies)])
    start = _time.perf_counter()
    brute = classify_points_brute_force(model.grid, points, velocities, edges, edge_body,
                                        triangles=triangles, triangle_body=triangle_body)
    seconds = _time.perf_counter() - start
    bmap = build_boundary_map(model.grid, points, velocities, edges, edge_body)
    return seconds, classification_disagreements(classify_points(model.grid, bmap), brute)


def scene_step(name: str, treatment: str, *, warmup: int = STEP_WARMUP,
               steps: int = STEP_COUNT, repeats: int = STEP_REPEATS,
               cells: int | None = None) -> SceneStep:
    """Time ``steps`` consecutive steps of the built-in scene ``name`` after ``warmup``, best
    of ``repeats`` such runs in a row (the flow keeps developing between them)."""
    from elastoflow.scenes import build_simulation

    changes: dict[str, Any] = {"coupling__boundary": treatment}
    if cells is not None:
        changes["domain__nx"] = cells
    scene = _scene_with(name, **changes)
    simulation = build_simulation(scene, warnings=[])
    for _ in range(warmup):
        simulation.step()
    best_step, best_boundary = math.inf, math.inf
    for _ in range(repeats):
        boundary = 0.0
        start = _time.perf_counter()
        for _ in range(steps):
            report = simulation.step()
            boundary += report.seconds_by_phase.get("map", 0.0)
        elapsed = (_time.perf_counter() - start) / steps
        if elapsed < best_step:
            best_step, best_boundary = elapsed, boundary / steps
    brute_seconds, disagreements = _brute_force_of(simulation)
    triangles = sum(body.mesh.triangle_count for body in model_2d(simulation).bodies)
    grid = simulation.grid
    return SceneStep(name, treatment, (grid.nx, grid.ny), int(triangles), best_step,
                     best_boundary, brute_seconds, disagreements)


@dataclass(frozen=True)
class SpeedStudy:
    """Every timing of the speed part.

    Attributes:
        cases: The disc at each size and grid.
        steps: The built-in scenes' whole steps.
        load: The machine's one-minute load average before and after the part.
        seconds: Wall time of the part [s].
    """

    cases: tuple[SpeedCase, ...]
    steps: tuple[SceneStep, ...]
    load: tuple[float, float] = (math.nan, math.nan)
    seconds: float = 0.0
    maps: tuple[MapCase, ...] = ()

    @property
    def edges(self) -> tuple[int, ...]:
        return tuple(dict.fromkeys(c.edges for c in self.cases))

    @property
    def cells(self) -> tuple[int, ...]:
        return tuple(dict.fromkeys(c.cells for c in self.cases))

    def case(self, edges: int, cells: int) -> SpeedCase:
        return next(c for c in self.cases if c.edges == edges and c.cells == cells)

    def fit(self, quantity: str) -> tuple[float, float]:
        """Exponents (a, b) of ``seconds ~ cells^a edges^b`` by least squares over the cases
        (``quantity``: "map", "cut_cell", "staircase" (each with the map), "brute_force")."""
        rows, values = [], []
        for c in self.cases:
            value = {"map": c.map_seconds, "brute_force": c.brute_force_seconds,
                     **c.step_seconds}[quantity]
            if math.isfinite(value) and value > 0.0:
                rows.append((1.0, math.log(c.cells), math.log(c.edges)))
                values.append(math.log(value))
        if len(rows) < 3:
            return math.nan, math.nan
        solution = np.linalg.lstsq(np.array(rows), np.array(values), rcond=None)[0]
        return float(solution[1]), float(solution[2])

    def brute_force_order(self) -> float:
        """Slope of the brute force's time against grid points times triangles."""
        run = [c for c in self.cases if math.isfinite(c.brute_force_seconds)]
        if len(run) < 2:
            return math.nan
        return observed_order([c.grid_points * c.triangles for c in run],
                              [c.brute_force_seconds for c in run])

    def map_order(self, *, large: bool = False) -> float:
        """Slope of the map's time against its crossings plus edges (``large``: over the
        outline-only discs on large grids)."""
        if large:
            return observed_order([m.crossings + m.edges for m in self.maps],
                                  [m.seconds for m in self.maps])
        return observed_order([c.crossings + c.edges for c in self.cases],
                              [c.map_seconds for c in self.cases])


def _load() -> float:
    try:
        import os

        return float(os.getloadavg()[0])
    except (OSError, AttributeError):
        return math.nan


def run_speed_study(edges: Sequence[int] = SPEED_EDGES, cells: Sequence[int] = SPEED_CELLS,
                    scenes: Sequence[str] = STEP_SCENES,
                    treatments: Sequence[str] = TREATMENTS, *,
                    repeats: int = SPEED_REPEATS, step_count: int = STEP_COUNT,
                    step_cells: int | None = None, map_edges: Sequence[int] = MAP_EDGES,
                    map_cells: Sequence[int] = MAP_CELLS) -> SpeedStudy:
    """`speed_case` for every disc and grid, `map_case` for every outline and large grid,
    `scene_step` for every scene and treatment."""
    start = _time.perf_counter()
    load_before = _load()
    # Compile every kernel before the first timing.
    speed_case(disc_mesh(min(edges)), min(cells), repeats=1)
    cases: list[SpeedCase] = []
    for count in edges:
        mesh = disc_mesh(count)
        cases.extend(speed_case(mesh, n, repeats=repeats) for n in cells)
    maps = tuple(map_case(count, n, repeats=repeats) for count in map_edges for n in map_cells)
    steps = tuple(scene_step(name, treatment, steps=step_count, cells=step_cells)
                  for name in scenes for treatment in treatments)
    return SpeedStudy(tuple(cases), steps, (load_before, _load()),
                      _time.perf_counter() - start, maps)


def speed_table(study: SpeedStudy) -> list[str]:
    """Markdown table: per disc and grid, the map, both treatments' boundary work per step
    and the brute force [ms], then the fitted exponents."""
    lines = ["| boundary edges | triangles | cells | crossings | map [ms] | map + cut cell [ms] "
             "| map + staircase [ms] | brute force [ms] | brute force / map + cut cell |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for c in study.cases:
        steps = c.step_seconds
        brute = (f"{1e3 * c.brute_force_seconds:.1f}" if math.isfinite(c.brute_force_seconds)
                 else "")
        ratio = (f"{c.brute_force_seconds / steps['cut_cell']:.0f}"
                 if math.isfinite(c.brute_force_seconds) else "")
        lines.append(f"| {c.edges} | {c.triangles} | {c.cells}^2 | {c.crossings} | "
                     f"{1e3 * c.map_seconds:.3f} | {1e3 * steps['cut_cell']:.3f} | "
                     f"{1e3 * steps['staircase']:.3f} | {brute} | {ratio} |")
    fits = {q: study.fit(q) for q in ("map", "cut_cell", "staircase", "brute_force")}
    lines.append("| fitted time ~ cells^a edges^b | | | | "
                 + " | ".join(f"a {a:.2f}, b {b:.2f}" for a, b in fits.values()) + " | |")
    return lines


def maps_table(study: SpeedStudy) -> list[str]:
    """Markdown table: the map alone at large sizes [ms], edges by rows, grids by columns."""
    if not study.maps:
        return []
    cells = tuple(dict.fromkeys(m.cells for m in study.maps))
    edges = tuple(dict.fromkeys(m.edges for m in study.maps))
    lines = ["| map alone [ms] (crossings) | " + " | ".join(f"{n}^2" for n in cells) + " |",
             "|---:|" + "---:|" * len(cells)]
    for count in edges:
        row = [m for m in study.maps if m.edges == count]
        lines.append(f"| {count} edges | " + " | ".join(
            f"{1e3 * m.seconds:.3f} ({m.crossings})" for m in row) + " |")
    return lines


def steps_table(study: SpeedStudy) -> list[str]:
    """Markdown table: the built-in scenes' whole step per treatment."""
    lines = ["| scene | cells | triangles | boundary | step [ms] | map + interior [ms] | "
             "brute-force classification [ms] |",
             "|---|---:|---:|---|---:|---:|---:|"]
    for s in study.steps:
        lines.append(f"| {s.scene} | {s.cells[0]}x{s.cells[1]} | {s.triangles} | "
                     f"{_LABEL[s.treatment]} | {1e3 * s.step_seconds:.2f} | "
                     f"{1e3 * s.boundary_seconds:.3f} | {1e3 * s.brute_force_seconds:.1f} |")
    return lines


def speed_csv(study: SpeedStudy) -> str:
    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(["kind", "case", "boundary edges", "triangles", "cells", "crossings",
                     "map [s]", "cut cell interior [s]", "staircase interior [s]",
                     "classify_points [s]", "brute force [s]", "disagreements",
                     "step [s]", "step's map phase [s]"])
    for c in study.cases:
        writer.writerow(["disc", "", c.edges, c.triangles, c.cells, c.crossings,
                         f"{c.map_seconds:.4e}", f"{c.cut_cell_seconds:.4e}",
                         f"{c.staircase_seconds:.4e}", f"{c.classify_seconds:.4e}",
                         f"{c.brute_force_seconds:.4e}", c.disagreements, "", ""])
    for m in study.maps:
        writer.writerow(["map only", "", m.edges, "", m.cells, m.crossings,
                         f"{m.seconds:.4e}", "", "", "", "", "", "", ""])
    for s in study.steps:
        writer.writerow(["scene", f"{s.scene} {s.treatment}", "", s.triangles,
                         f"{s.cells[0]}x{s.cells[1]}", "", "", "", "", "",
                         f"{s.brute_force_seconds:.4e}", s.disagreements,
                         f"{s.step_seconds:.4e}", f"{s.boundary_seconds:.4e}"])
    return text.getvalue()


def plot_speed(study: SpeedStudy, path: Path) -> None:
    """Left: time against cells per disc (map + cut cell solid, brute force dashed). Right:
    the map against its crossings plus edges and the brute force against grid points times
    triangles, each with a line of slope 1."""
    plt = _pyplot()
    figure, (left, right) = getattr(plt, "subplots")(1, 2, figsize=(9.0, 3.8))
    for k, count in enumerate(study.edges):
        cases = [study.case(count, n) for n in study.cells]
        color = f"C{k}"
        left.loglog([c.cells for c in cases], [c.step_seconds["cut_cell"] for c in cases],
                    "o-", color=color, lw=1.0, ms=3, label=f"{count} edges: map + cut cell")
        run = [c for c in cases if math.isfinite(c.brute_force_seconds)]
        if run:
            left.loglog([c.cells for c in run], [c.brute_force_seconds for c in run], "s--",
                        color=color, lw=1.0, ms=3, label=f"{count} edges: brute force")
    left.set_xticks(list(study.cells), [str(n) for n in study.cells])
    left.minorticks_off()
    left.set_xlabel("cells across")
    left.set_ylabel("seconds")
    left.set_title("Classification and boundary per step", fontsize=9)
    left.grid(alpha=0.3, which="both")
    left.legend(fontsize=5.5, ncol=2)
    work_map = np.array([c.crossings + c.edges for c in study.cases], dtype=float)
    right.loglog(work_map, [c.map_seconds for c in study.cases], "o", ms=3, color="C0",
                 label="map vs crossings + edges")
    if study.maps:
        right.loglog([m.crossings + m.edges for m in study.maps],
                     [m.seconds for m in study.maps], "^", ms=4, color="C2",
                     label="map alone, outlines on grids to 32768^2")
    run = [c for c in study.cases if math.isfinite(c.brute_force_seconds)]
    work_brute = np.array([c.grid_points * c.triangles for c in run], dtype=float)
    right.loglog(work_brute, [c.brute_force_seconds for c in run], "s", ms=3, color="C3",
                 label="brute force vs grid points x triangles")
    for work, seconds, color in ((work_map, [c.map_seconds for c in study.cases], "C0"),
                                 (work_brute, [c.brute_force_seconds for c in run], "C3")):
        if len(work):
            scale = float(np.median(np.asarray(seconds) / work))
            span = np.array([work.min(), work.max()])
            right.loglog(span, scale * span, ":", color=color, lw=0.8)
    right.set_xlabel("work (count)")
    right.set_ylabel("seconds")
    right.set_title("Each against its own work measure (dotted: slope 1)", fontsize=9)
    right.grid(alpha=0.3, which="both")
    right.legend(fontsize=7)
    _save(figure, path)


def speed_section(study: SpeedStudy, figure: str, table_csv: str) -> str:
    """The Markdown block of the speed part."""
    small, large = min(study.edges), max(study.edges)
    coarse, fine = min(study.cells), max(study.cells)
    map_fit, cut_fit, stair_fit, brute_fit = (study.fit(q) for q in
                                              ("map", "cut_cell", "staircase", "brute_force"))
    brute_run = [c for c in study.cases if math.isfinite(c.brute_force_seconds)]
    ratios = [c.brute_force_seconds / c.step_seconds["cut_cell"] for c in brute_run]
    map_times = [c.map_seconds for c in study.cases]
    disagreements = sum(c.disagreements for c in study.cases if c.disagreements > 0)
    disagreements += sum(s.disagreements for s in study.steps if s.disagreements > 0)
    compared = len(brute_run) + len(study.steps)
    largest = study.case(large, fine)
    steps = {(s.scene, s.treatment): s for s in study.steps}
    scene_lines = []
    for name in dict.fromkeys(s.scene for s in study.steps):
        cut, stair = steps.get((name, "cut_cell")), steps.get((name, "staircase"))
        if cut is None or stair is None:
            continue
        scene_lines.append(
            f"`{name}` ({cut.cells[0]}^2, {cut.triangles} triangles): "
            f"{1e3 * cut.step_seconds:.1f} ms a step with cut cells, "
            f"{1e3 * stair.step_seconds:.1f} ms with the staircase, of which the map and "
            f"interior {1e3 * cut.boundary_seconds:.2f} and {1e3 * stair.boundary_seconds:.2f}"
            f" ms ({100 * cut.boundary_seconds / cut.step_seconds:.1f} % and "
            f"{100 * stair.boundary_seconds / stair.step_seconds:.1f} %); the brute-force "
            f"classification of the same objects alone takes "
            f"{1e3 * cut.brute_force_seconds:.0f} ms")
    load = ", ".join(f"{value:.2f}" for value in study.load)
    paragraphs = [
        f"A disc of radius {SPEED_RADIUS:g} m meshed with {small} to {large} boundary edges "
        "(elements as large as the boundary edges, so the triangles grow as the square of the "
        f"edges) on {coarse}^2 to {fine}^2 cells of the unit square, rotating rigidly "
        "(`elastoflow.validation._boundary_speed.speed_case`). Timed as a step does it: the "
        "boundary map (`build_boundary_map`), then each treatment's interior from it "
        "(reusing the previous result's arrays, as a run does; the interior includes the "
        "classification by the map's scanline fill); against it the brute force "
        "(`classify_points_brute_force`: every cell centre, u and v point against every "
        f"triangle), run where grid points x triangles stays below {BRUTE_FORCE_LIMIT:.2g}. "
        f"Best of {SPEED_REPEATS} for the map and the interiors, one run of the brute force; "
        f"shared 2-core machine, load average {load} (before, after): the whole steps below "
        "are for the two treatments' ratio and the boundary's share, the idle machine's step "
        "times are in docs/benchmarks.md. The exponents in the last row are a least-squares "
        "fit of `log time` on `log cells` and `log edges`.",
        f"The map alone takes {1e3 * min(map_times):.2f} to {1e3 * max(map_times):.2f} ms "
        f"at every size of the first table (fit cells^{map_fit[0]:.2f} "
        f"edges^{map_fit[1]:.2f}; slope {study.map_order():.2f} against its crossings plus "
        "edges): it loops over the edges and their crossings and never visits a grid point, "
        "so at these sizes its fixed cost per call dominates. " + _large_maps(study)
        + "The boundary's whole work per step, the map and the "
        "treatment's interior, grows with the grid and not with the edges (cut cells "
        f"cells^{cut_fit[0]:.2f} edges^{cut_fit[1]:.2f}, staircase cells^{stair_fit[0]:.2f} "
        f"edges^{stair_fit[1]:.2f}): the interior classifies by the map's scanline fill, "
        "which writes every solid point, and resets and fills the box around the body, "
        f"and this disc covers {100 * math.pi * SPEED_RADIUS**2:.0f} % of the domain: its "
        "cost follows the body's area over h^2, not grid points x elements. The brute force "
        f"follows grid points x triangles (slope {study.brute_force_order():.2f} against that "
        f"product; fit cells^{brute_fit[0]:.2f} edges^{brute_fit[1]:.2f}, the triangles "
        f"growing as edges^2): {min(ratios):.0f} to {max(ratios):.0f} times the map and "
        f"cut-cell interior where both ran. At {large} edges on {fine}^2 the map and "
        f"interior take {1e3 * largest.step_seconds['cut_cell']:.1f} ms; the brute force "
        f"would take about {_extrapolate(study, largest):.0f} s there (its fit "
        f"extrapolated). Both classifications agree: {disagreements} differing grid points "
        f"over the {compared} comparisons (discs and scenes). Whole steps (warm, best of "
        f"{STEP_REPEATS} runs of {STEP_COUNT} steps): " + "; ".join(scene_lines) + ".",
        f"Data: [{Path(table_csv).name}]({table_csv}) (every timing, the brute force's "
        "disagreements). Test: `tests/validation/test_boundary_speed.py` (the part runs at "
        "a tiny size and the two classifications agree; timings are never asserted). The "
        f"whole part took {study.seconds:.1f} s.",
    ]
    table = [*speed_table(study), "", *maps_table(study), "", *steps_table(study)]
    if not study.maps:
        table = [*speed_table(study), "", *steps_table(study)]
    return compose_section("Speed: the boundary per step against perimeter and grid",
                           paragraphs, table, figure,
                           "boundary time against cells and against each method's work")


def _large_maps(study: SpeedStudy) -> str:
    """The second table in words."""
    if not study.maps:
        return ""
    largest = max(study.maps, key=lambda m: m.crossings + m.edges)
    per = 1e9 * largest.seconds / (largest.crossings + largest.edges)
    return (f"On outlines of up to {max(m.edges for m in study.maps)} edges on grids up to "
            f"{max(m.cells for m in study.maps)}^2 (second table) it follows the perimeter: "
            f"slope {study.map_order(large=True):.2f} against crossings plus edges, "
            f"{1e3 * largest.seconds:.1f} ms for {largest.crossings} crossings "
            f"({per:.0f} ns each) on a grid of {largest.cells}^2 cells that it never "
            "touches. ")


def _extrapolate(study: SpeedStudy, case: SpeedCase) -> float:
    """The brute force's time for ``case`` from its fit against grid points x triangles."""
    run = [c for c in study.cases if math.isfinite(c.brute_force_seconds)]
    if not run:
        return math.nan
    work = np.log([c.grid_points * c.triangles for c in run])
    slope, intercept = np.polyfit(work, np.log([c.brute_force_seconds for c in run]), 1)
    return float(np.exp(intercept + slope * math.log(case.grid_points * case.triangles)))


def write_speed_report(study: SpeedStudy, folder: str | Path) -> list[Path]:
    """Write ``speed.csv``, ``speed.png`` and the block ``speed`` of the page."""
    return write_part(folder, "speed", "speed", speed_csv(study),
                      lambda path: plot_speed(study, path),
                      lambda figure, table: speed_section(study, figure, table))


def speed_lines(study: SpeedStudy) -> list[str]:
    """What the command prints: both tables."""
    return [*speed_table(study), *maps_table(study), *steps_table(study)]


# -- stability: the bar in a jet ---------------------------------------------------------------

STABILITY_CELLS = 64
"""Cells across the bar-in-a-jet box (the scene has 256)."""
STABILITY_DURATION = 3.0
"""Simulated time of each run [s] (the scene runs 10 s)."""
STABILITY_MIN_STEPS = 40
"""Fewest steps of a run, so that a large dt still takes enough steps for a growing mode to
show (the run then goes past `STABILITY_DURATION`)."""
STABILITY_DT = 0.013
"""The scene's time step [s]; its multiples are bisected."""
SCENE_DENSITY_RATIO = 1.1
"""The scene's bar density over the fluid's."""
DT_FACTORS = (1.0, 64.0)
"""Bracket of dt / the scene's dt for the bisection."""
DENSITY_RATIOS = (1e-4, SCENE_DENSITY_RATIO)
"""Bracket of solid / fluid density for the bisection."""
EXPLICIT_DENSITY_MIN = 1e-2
"""Bottom of the explicit scheme's density bracket: its FEM substeps shrink as the square
root of the density (870 a step at 1e-2, 84000 at 1e-4), which would take most of the part."""
BISECTION_STEPS = 6
"""Bisections (in log) of each bracket."""
NO_CFL_LIMIT = 1.0e6
"""The runs' CFL limit: the scene's 20 is a blow-up detector for the semi-Lagrangian fluid,
which stays stable beyond it; the limits sought are the coupling's."""
MOTION_LIMIT = 0.5
"""Largest node displacement from rest [m] a stable run may reach (the bar is 0.5 m long)."""
EXPLICIT_RELAXATION = 0.1
"""Force relaxation of the explicit scheme's runs: what the scene's notes say it needs."""
COUPLINGS: tuple[tuple[str, str], ...] = (("monolithic", "traction"),
                                          ("explicit", "traction"),
                                          ("explicit", "momentum_exchange"))
"""(scheme, force model) pairs: the default scheme has one force model (its own pressure
solve's traction); the explicit scheme offers both."""


@dataclass(frozen=True)
class StabilityRun:
    """One run of the bar in a jet.

    Attributes:
        dt: Time step [s].
        density_ratio: Bar density over the fluid's.
        stable: Whether it finished without error and with bounded motion.
        reason: What stopped it ("" when stable).
        displacement: Largest node displacement from rest over the run [m].
        cfl: Largest Courant number ``max |u| dt / h`` over the run.
        steps: Steps taken.
        seconds: Wall time [s].
    """

    dt: float
    density_ratio: float
    stable: bool
    reason: str
    displacement: float
    cfl: float
    steps: int
    seconds: float


def bar_run(treatment: str, *, scheme: str = "monolithic", force_model: str = "traction",
            dt: float = STABILITY_DT, density_ratio: float = SCENE_DENSITY_RATIO,
            cells: int = STABILITY_CELLS, duration: float = STABILITY_DURATION) -> StabilityRun:
    """The bar in a jet on ``cells``^2 cells for ``duration`` at ``dt`` with a bar of
    ``density_ratio`` times the fluid's density, coupled by ``scheme`` and ``force_model``
    (the explicit scheme relaxed by `EXPLICIT_RELAXATION`, its FEM substeps "auto": the
    elements' stability bound, so that the solid's own explicit step does not set the
    limits)."""
    from elastoflow.scenes import SceneError, build_simulation
    from elastoflow.simulation import SimulationBlowUp
    from elastoflow.solid import SolidInversionError

    steps = max(STABILITY_MIN_STEPS, math.ceil(duration / dt - 1e-9))
    start = _time.perf_counter()
    changes: dict[str, Any] = {
        "coupling__boundary": treatment, "coupling__scheme": scheme, "domain__nx": cells,
        "time__dt": dt, "time__steps": steps, "time__duration": None,
        "time__cfl_limit": NO_CFL_LIMIT,
        "bodies__0__material__density": density_ratio * 1000.0,
    }
    if scheme == "explicit":
        changes.update(coupling__force_model=force_model,
                       coupling__force_relaxation=EXPLICIT_RELAXATION,
                       time__substeps="auto")
    try:
        simulation = build_simulation(_scene_with("bar_in_jet", **changes), warnings=[])
    except SceneError as error:
        return StabilityRun(dt, density_ratio, False, f"scene: {error}", math.nan, math.nan,
                            0, _time.perf_counter() - start)
    rest = simulation.state.bodies[0].positions.copy()
    largest, cfl, reason, taken = 0.0, 0.0, "", 0
    try:
        for taken in range(1, steps + 1):
            cfl = max(cfl, simulation.step().cfl)
            positions = simulation.state.bodies[0].positions
            largest = max(largest, float(np.abs(positions - rest).max()))
            if not largest <= MOTION_LIMIT:
                reason = f"moved {largest:.2f} m at step {taken}"
                break
    except (SimulationBlowUp, SolidInversionError, FloatingPointError, ValueError) as error:
        reason = _short(error)
    return StabilityRun(dt, density_ratio, reason == "", reason, largest, cfl, taken,
                        _time.perf_counter() - start)


def _short(error: Exception) -> str:
    """The error's first sentence, without the step and time it names."""
    text = str(error).splitlines()[0] if str(error) else type(error).__name__
    text = re.sub(r"^step \d+, t = [^:]*: ", "", text)
    text = re.sub(r"elastic body failed at step \d+, ", "", text)
    return text.split("; ")[0][:120]


@dataclass(frozen=True)
class StabilityLimit:
    """A bisection: the last stable and first unstable value and every run.

    Attributes:
        treatment: "cut_cell" or "staircase".
        scheme: "monolithic" or "explicit".
        force_model: "traction" or "momentum_exchange".
        quantity: "dt" or "density_ratio".
        stable: The bound found stable nearest the limit (NaN if none was).
        unstable: The bound found unstable nearest the limit (NaN if every run was stable).
        runs: Every run, in order.
    """

    treatment: str
    scheme: str
    force_model: str
    quantity: str
    stable: float
    unstable: float
    runs: tuple[StabilityRun, ...] = field(default_factory=tuple)

    @property
    def reason(self) -> str:
        """What stopped the unstable run nearest the limit."""
        for run in self.runs:
            value = run.dt if self.quantity == "dt" else run.density_ratio
            if not run.stable and value == self.unstable:
                return run.reason
        return ""


def bisect_limit(treatment: str, quantity: str, *, scheme: str = "monolithic",
                 force_model: str = "traction", bisections: int = BISECTION_STEPS,
                 cells: int = STABILITY_CELLS,
                 duration: float = STABILITY_DURATION) -> StabilityLimit:
    """Bisect (in log) the largest stable dt (``quantity = "dt"``, at the scene's density) or
    the lowest stable density ratio (``"density_ratio"``, at the scene's dt) inside the
    brackets `DT_FACTORS` and `DENSITY_RATIOS` (`EXPLICIT_DENSITY_MIN` for the explicit
    scheme)."""
    runs: list[StabilityRun] = []

    def run(value: float) -> bool:
        keys: dict[str, float] = ({"dt": value} if quantity == "dt"
                                  else {"density_ratio": value})
        result = bar_run(treatment, scheme=scheme, force_model=force_model, cells=cells,
                         duration=duration, **keys)
        runs.append(result)
        return result.stable

    if quantity == "dt":
        good, bad = STABILITY_DT * DT_FACTORS[0], STABILITY_DT * DT_FACTORS[1]
    else:
        good, bad = DENSITY_RATIOS[1], DENSITY_RATIOS[0]
        if scheme == "explicit":
            bad = max(bad, EXPLICIT_DENSITY_MIN)
    label = (treatment, scheme, force_model, quantity)
    if not run(good):
        return StabilityLimit(*label, math.nan, good, tuple(runs))
    if run(bad):
        return StabilityLimit(*label, bad, math.nan, tuple(runs))
    for _ in range(bisections):
        middle = math.sqrt(good * bad)
        if run(middle):
            good = middle
        else:
            bad = middle
    return StabilityLimit(*label, good, bad, tuple(runs))


@dataclass(frozen=True)
class StabilityStudy:
    """Both limits for each treatment and coupling, and the part's wall time [s]."""

    limits: tuple[StabilityLimit, ...]
    cells: int = STABILITY_CELLS
    duration: float = STABILITY_DURATION
    seconds: float = 0.0

    def limit(self, treatment: str, scheme: str, force_model: str,
              quantity: str) -> StabilityLimit:
        return next(item for item in self.limits
                    if (item.treatment, item.scheme, item.force_model, item.quantity)
                    == (treatment, scheme, force_model, quantity))

    @property
    def rows(self) -> tuple[tuple[str, str, str], ...]:
        """(treatment, scheme, force model) of every row."""
        return tuple(dict.fromkeys((item.treatment, item.scheme, item.force_model)
                                   for item in self.limits))


def run_stability_study(treatments: Sequence[str] = TREATMENTS,
                        couplings: Sequence[tuple[str, str]] = COUPLINGS, *,
                        bisections: int = BISECTION_STEPS, cells: int = STABILITY_CELLS,
                        duration: float = STABILITY_DURATION) -> StabilityStudy:
    """`bisect_limit` of dt and of the density ratio for every treatment and coupling."""
    start = _time.perf_counter()
    limits = tuple(bisect_limit(treatment, quantity, scheme=scheme, force_model=force_model,
                                bisections=bisections, cells=cells, duration=duration)
                   for scheme, force_model in couplings for treatment in treatments
                   for quantity in ("dt", "density_ratio"))
    return StabilityStudy(limits, cells, duration, _time.perf_counter() - start)


def _bound(value: float, scale: float = 1.0, digits: str = ".3g") -> str:
    return "none" if not math.isfinite(value) else f"{value * scale:{digits}}"


def _cell(text: str) -> str:
    return text.replace("|", "\\|") if text else ""


_COUPLING_LABEL = {("monolithic", "traction"): "monolithic (its pressure solve's traction)",
                   ("explicit", "traction"): f"explicit, traction, relaxed {EXPLICIT_RELAXATION:g}",
                   ("explicit", "momentum_exchange"):
                   f"explicit, momentum exchange, relaxed {EXPLICIT_RELAXATION:g}"}


def stability_table(study: StabilityStudy) -> list[str]:
    """Markdown table: per treatment and coupling, the largest stable dt and the lowest stable
    density ratio, each with the first unstable value and what stopped it."""
    lines = ["| boundary | coupling, force model | largest stable dt [s] | unstable at [s] | "
             "what stopped it | lowest stable density ratio | unstable at | "
             "what stopped it |",
             "|---|---|---:|---:|---|---:|---:|---|"]
    for treatment, scheme, model in study.rows:
        dt = study.limit(treatment, scheme, model, "dt")
        density = study.limit(treatment, scheme, model, "density_ratio")
        lines.append(f"| {_LABEL[treatment]} | {_COUPLING_LABEL.get((scheme, model), scheme)} "
                     f"| {_bound(dt.stable)} | {_bound(dt.unstable)} | "
                     f"{_cell(_what_stopped(dt.reason))} | {_bound(density.stable)} | "
                     f"{_bound(density.unstable)} | {_cell(_what_stopped(density.reason))} |")
    return lines


def stability_csv(study: StabilityStudy) -> str:
    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(["treatment", "scheme", "force model", "bisected", "dt [s]",
                     "density ratio", "stable", "largest displacement [m]", "largest CFL",
                     "steps", "reason", "seconds"])
    for item in study.limits:
        for r in item.runs:
            writer.writerow([item.treatment, item.scheme, item.force_model, item.quantity,
                             f"{r.dt:.6g}", f"{r.density_ratio:.6g}", int(r.stable),
                             f"{r.displacement:.4g}", f"{r.cfl:.3g}", r.steps, r.reason,
                             f"{r.seconds:.2f}"])
    return text.getvalue()


def plot_stability(study: StabilityStudy, path: Path) -> None:
    """Every run: largest displacement against dt (left) and density ratio (right), stable
    filled, unstable open."""
    plt = _pyplot()
    figure, axes = getattr(plt, "subplots")(1, 2, figsize=(8.5, 3.8))
    markers = "os^v<>"
    for axis, quantity, label in zip(axes, ("dt", "density_ratio"),
                                     ("dt [s]", "bar density / fluid density")):
        for k, (treatment, scheme, model) in enumerate(study.rows):
            item = study.limit(treatment, scheme, model, quantity)
            color = f"C{k}"
            marker = markers[k % len(markers)]
            for r in item.runs:
                x = r.dt if quantity == "dt" else r.density_ratio
                y = r.displacement if math.isfinite(r.displacement) else MOTION_LIMIT
                axis.loglog([x], [max(min(y, 2.0 * MOTION_LIMIT), 1e-4)], marker=marker, ls="",
                            color=color, mfc=color if r.stable else "none", ms=4)
            axis.plot([], [], marker=marker, ls="", color=color,
                      label=f"{_LABEL[treatment]}, {scheme}, {model}")
        axis.axhline(MOTION_LIMIT, color="0.5", ls=":", lw=0.8)
        axis.set_xlabel(label)
        axis.set_ylabel("largest displacement [m]")
        axis.grid(alpha=0.3, which="both")
    axes[1].legend(fontsize=5.5)
    figure.suptitle(f"Bar in a jet, {study.cells}^2 cells, {study.duration:g} s "
                    "(filled: stable, open: not)", fontsize=9)
    _save(figure, path)


def stability_section(study: StabilityStudy, figure: str, table_csv: str) -> str:
    """The Markdown block of the stability part."""
    runs = sum(len(item.runs) for item in study.limits)
    paragraphs = [
        f"The bar in a jet (`bar_in_jet`: a 5 x 50 cm rubber bar, 192 triangles, hanging in "
        f"a 1 m/s jet) on {study.cells}^2 cells instead of the scene's 256^2 and for "
        f"{study.duration:g} s instead of 10 s, so that the part's {runs} runs fit in a few "
        "minutes (`elastoflow.validation._boundary_speed.bar_run`). The default coupling "
        "scheme, monolithic, takes the force on the bodies from its own pressure solve "
        "(traction): the other force model, `coupling.force_model = "
        "\"momentum_exchange\"` (the paper's eq. 8), is refused with it by the scene check "
        "and belongs to the explicit scheme, whose rows are added for comparison (relaxed "
        f"{EXPLICIT_RELAXATION:g} as the scene's notes say it needs at this density, "
        "FEM substeps at their stability bound, `time.substeps = \"auto\"`). A run is "
        "stable when it reaches the end without the run's own checks stopping it "
        "(non-finite fields, an inverted element, a failed solve) and no node of the bar "
        f"moved more than {MOTION_LIMIT:g} m from rest; the "
        "scene's CFL limit of 20, a blow-up detector, is lifted so that the limits found are "
        f"the coupling's. Bisection in log, {BISECTION_STEPS} halvings of the bracket: dt "
        f"from {DT_FACTORS[0]:g} to {DT_FACTORS[1]:g} times the scene's {STABILITY_DT:g} s "
        f"(bar density {SCENE_DENSITY_RATIO:g} times the fluid's, the scene's), the density "
        f"ratio from {DENSITY_RATIOS[1]:g} down to {DENSITY_RATIOS[0]:g} (explicit: "
        f"{EXPLICIT_DENSITY_MIN:g}, its FEM substeps growing as 1 / sqrt(density)) at the "
        f"scene's dt. Each run lasts {study.duration:g} s or {STABILITY_MIN_STEPS} steps, "
        "whichever is longer. \"none\": no run of the bracket was unstable (or stable) on "
        "that side.",
        _stability_reading(study),
        f"Data: [{Path(table_csv).name}]({table_csv}) (every run: dt, density ratio, "
        "largest displacement and CFL number, steps, what stopped it). Test: "
        "`tests/validation/test_boundary_speed.py` (a short run at a tiny size). The whole "
        f"part took {study.seconds:.1f} s.",
    ]
    return compose_section("Stability: the bar in a jet", paragraphs, stability_table(study),
                           figure, "largest displacement of every run")


def _what_stopped(reason: str) -> str:
    """A run's reason in a few words."""
    if "implicit step" in reason and "det F" in reason:
        return "an element inverts in the implicit solid step"
    if "substep" in reason and "det F" in reason:
        return "an element inverts in an explicit FEM substep at its stability bound"
    return reason


def _stability_reading(study: StabilityStudy) -> str:
    """What limits each bound, from the runs."""
    top = STABILITY_DT * DT_FACTORS[1]
    dt_limits = [study.limit(*row, "dt") for row in study.rows]
    unstable_dt = [item for item in dt_limits if math.isfinite(item.unstable)]
    largest_cfl = max((r.cfl for item in dt_limits for r in item.runs
                       if math.isfinite(r.cfl)), default=math.nan)
    if unstable_dt:
        text = "Time step: " + "; ".join(
            f"{_LABEL[item.treatment]}, {item.scheme} {item.force_model.replace('_', ' ')} "
            f"stable up to {_bound(item.stable)} s ({_what_stopped(item.reason)} beyond)"
            for item in unstable_dt) + "; the other rows stable over the whole bracket."
    else:
        text = (f"Time step: no run was unstable in any row up to {top:.3g} s, "
                f"{DT_FACTORS[1]:g} times the scene's (CFL number up to {largest_cfl:.0f}): "
                "the semi-Lagrangian fluid, the implicit solid step of the monolithic scheme "
                "and the explicit scheme's relaxed force with substeps at the FEM's bound "
                "all stay bounded.")
    rows = []
    for treatment, scheme, model in study.rows:
        density = study.limit(treatment, scheme, model, "density_ratio")
        label = f"{_LABEL[treatment]}, {scheme} {model.replace('_', ' ')}"
        moved = max((r.displacement for item in (study.limit(treatment, scheme, model, "dt"),
                                                 density)
                     for r in item.runs if math.isfinite(r.displacement)), default=0.0)
        if moved == 0.0:
            rows.append(f"{label}: the bar never moves in any run (this force model gives "
                        "it next to no force with this boundary), so its row says nothing "
                        "about stability")
        elif not math.isfinite(density.unstable):
            rows.append(f"{label}: stable over the whole bracket")
        elif not math.isfinite(density.stable):
            rows.append(f"{label}: unstable already at the scene's density "
                        f"({_what_stopped(density.reason)})")
        else:
            rows.append(f"{label}: down to {density.stable:.3g} "
                        f"({_what_stopped(density.reason)} below)")
    text += " Density ratio: " + "; ".join(rows) + "."
    monolithic = {row[0]: study.limit(*row, "density_ratio").stable for row in study.rows
                  if row[1] == "monolithic"}
    if all(math.isfinite(monolithic.get(t, math.nan)) for t in TREATMENTS):
        lighter = monolithic["cut_cell"] / monolithic["staircase"]
        if lighter > 1.0:
            text += (f" With the monolithic scheme the staircase's bar goes {lighter:.0f} "
                     "times lighter than the cut cells' before an element inverts; why is "
                     f"not isolated here (the bar is {0.05 * study.cells:.1f} cells wide on "
                     "this grid).")
        else:
            text += (f" With the monolithic scheme the cut cells' bar goes {1 / lighter:.0f} "
                     "times lighter than the staircase's before an element inverts.")
    reference = {row: study.limit(*row, "dt").runs[0] for row in study.rows}
    loads = [f"{_LABEL[row[0]]} {reference[row].displacement:.3g} m"
             for row in study.rows if row[2] == "momentum_exchange"
             and reference[row].stable]
    traction = [f"{reference[row].displacement:.3g}" for row in study.rows
                if row[2] == "traction" and reference[row].stable]
    if loads and traction:
        text += (" The momentum-exchange rows are not comparable with the traction rows: at "
                 "the scene's dt and density it moves the bar by (largest node displacement) "
                 + ", ".join(loads) + f" against {', '.join(traction)} m with traction "
                 "(it sees little of the jet's force), so its bar is hardly loaded.")
    return text


def write_stability_report(study: StabilityStudy, folder: str | Path) -> list[Path]:
    """Write ``stability.csv``, ``stability.png`` and the block ``stability`` of the page."""
    return write_part(folder, "stability", "stability", stability_csv(study),
                      lambda path: plot_stability(study, path),
                      lambda figure, table: stability_section(study, figure, table))


def stability_lines(study: StabilityStudy) -> list[str]:
    """What the command prints: the table."""
    return stability_table(study)
