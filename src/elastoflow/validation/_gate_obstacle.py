"""Free surface with elastic bodies (issue 15, item 5): Antoci's rubber gate and Walhorn's
elastic obstacle, from the library scenes ``elastic_gate`` and ``dam_break_obstacle``.

* ``gate``: Antoci, Gallati & Sibilla (2007). A water column released through a rubber gate
  clamped at its top; the displacement of the gate's free end (its mid-thickness node).
* ``obstacle``: Walhorn et al. (2005). A dam break onto an elastic wall clamped to the floor;
  the displacement of the wall's upstream top corner.

The published curves (Antoci's measured gate tip, the reference curves of Walhorn's obstacle)
are withheld from this project (../shared/reference/free_surface.json, "withheld"), so the
page gives each run's curve, its peak, and its difference from the finest run, with the
liquid's area change over the run (issue 15 asks for less than 0.5 % over a dam break).

Run ``python -m elastoflow.validation._gate_obstacle [gate|obstacle ...]`` to rewrite the block
of ``docs/validation/free_surface.md`` and its plot ``gate_obstacle.png``.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

# Cells across the water column: a whole number and four tenths keeps the bodies' clamped
# faces off the grid lines (the scenes' docstrings).
RESOLUTIONS: dict[str, tuple[float, ...]] = {
    "gate": (40.4, 60.4, 80.4),
    "obstacle": (30.4, 41.4, 61.4),
}
TITLES = {"gate": "Antoci's rubber gate: the free end (mid-thickness)",
          "obstacle": "Walhorn's elastic obstacle: the upstream top corner"}


@dataclass
class TipRun:
    """One run: times [s], the probed node's displacement [m] (k, 2), the liquid's area."""

    case: str
    cells_across: float
    cell_size: float
    dt: float
    times: np.ndarray
    displacements: np.ndarray
    water_areas: np.ndarray
    seconds: float
    cells: tuple[int, int]
    elements: int
    failure: str | None = None

    @property
    def peak(self) -> tuple[float, float]:
        """The first swing's largest x displacement [m] and its time [s]. The first swing
        ends where the displacement falls below half its largest value so far, once that
        value is a fifth of the run's largest (before the surge arrives the body only
        quivers): later swings, driven by the splash thrown back from the far wall (which
        differs from grid to grid), can be larger and would otherwise take the peak's
        place."""
        x = self.displacements[:, 0]
        highest = np.maximum.accumulate(x)
        fallen = np.flatnonzero((highest >= 0.2 * x.max()) & (x < 0.5 * highest))
        end = int(fallen[0]) if fallen.size else x.shape[0]
        index = int(np.argmax(x[:end]))
        return float(x[index]), float(self.times[index])

    @property
    def area_change(self) -> float:
        """The liquid's relative area change from the first step to the end of the run (the
        area before the first step is measured without the bodies' open fractions, which the
        map makes in the first step, so it is not comparable)."""
        return float((self.water_areas[-1] - self.water_areas[1]) / self.water_areas[1])

    def difference_from(self, finest: TipRun, until: float = np.inf) -> float:
        """The largest |x displacement - the finest run's| over the common times up to
        ``until`` [s] [m]."""
        end = min(self.times[-1], finest.times[-1], until)
        times = np.linspace(0.0, end, 400)
        mine = np.interp(times, self.times, self.displacements[:, 0])
        theirs = np.interp(times, finest.times, finest.displacements[:, 0])
        return float(np.abs(mine - theirs).max())


def case_data(case: str, cells_across: float) -> dict:
    """The library scene of ``case`` ("gate" or "obstacle") as data at that resolution."""
    from elastoflow.scenes import dam_break_obstacle_data, elastic_gate_data

    if case == "gate":
        return elastic_gate_data(cells_across)
    if case == "obstacle":
        return dam_break_obstacle_data(cells_across)
    raise ValueError(f"case = {case!r}: must be 'gate' or 'obstacle'")


def run_case(case: str, cells_across: float, duration: float | None = None,
             progress: Callable[[str], None] | None = None) -> TipRun:
    """Run the scene of ``case`` at ``cells_across`` cells across the column to ``duration``
    [s] (default: the scene's), or until a `SimulationBlowUp`."""
    from elastoflow.fluid._free_surface_bodies import FreeSurfaceBodiesWorkspace, water_area
    from elastoflow.grid import Grid2D
    from elastoflow.scenes import build_simulation, parse_scene
    from elastoflow.solid import ElasticBody
    from elastoflow.validation._report import step_and_record

    data = case_data(case, cells_across)
    if duration is not None:
        data["time"]["duration"] = duration
    probe = data["outputs"]["probes"][0]["point"]
    data["outputs"] = {}
    data["name"] = f"{case} at {cells_across:g} cells across"
    simulation = build_simulation(parse_scene(data, source=data["name"]))
    grid = simulation.grid
    body = simulation.bodies[0]
    assert isinstance(grid, Grid2D) and isinstance(body, ElasticBody)
    rest = body.mesh.points
    node = int(np.argmin(np.linalg.norm(rest - np.asarray(probe), axis=1)))
    workspace = FreeSurfaceBodiesWorkspace(grid)

    def area() -> float:
        boundary = simulation.state.boundary
        interior = None if boundary is None else boundary.interior
        level_set = simulation.level_set
        assert level_set is not None
        return float(water_area(level_set, interior, grid.h, workspace))

    steps = int(round(data["time"]["duration"] / simulation.dt))
    times, displacements, areas = [0.0], [np.zeros(2)], [area()]

    def record(step: int) -> None:
        times.append(simulation.time)
        displacements.append(simulation.state.bodies[0].positions[node] - rest[node])
        areas.append(area())
        if progress is not None and (step % 200 == 0 or step == steps - 1):
            d = 1000.0 * displacements[-1]
            progress(f"{case} {cells_across:g}: t = {times[-1]:.3f} s, tip moved "
                     f"({d[0]:.2f}, {d[1]:.2f}) mm")

    failure, seconds = step_and_record(simulation, steps, record)
    return TipRun(case, cells_across, float(grid.h), float(simulation.dt),
                  np.array(times), np.array(displacements), np.array(areas), seconds,
                  grid.shape_cells, body.mesh.triangle_count, failure)


def plot_runs(runs: list[TipRun], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from elastoflow.io import atomic_path

    cases = [case for case in RESOLUTIONS if any(run.case == case for run in runs)]
    figure, axes = plt.subplots(len(cases), 2, figsize=(11, 3.6 * len(cases)), squeeze=False)
    for row, case in zip(axes, cases, strict=True):
        for component, axis in enumerate(row):
            for run in (r for r in runs if r.case == case):
                axis.plot(run.times, 1000.0 * run.displacements[:, component],
                          label=f"h = {1000 * run.cell_size:.2f} mm")
            axis.set_xlabel("t [s]")
            axis.set_ylabel(f"{'xy'[component]} displacement [mm]")
            axis.set_title(TITLES[case], fontsize=9)
            axis.legend(fontsize=8)
    figure.tight_layout()
    with atomic_path(path) as temporary:
        figure.savefig(temporary, dpi=110, format="png")
    plt.close(figure)


BEGIN, END = "<!-- gate-obstacle:begin -->", "<!-- gate-obstacle:end -->"
SETUPS = {
    "gate": ("**Antoci's rubber gate** (`elastic_gate`; Antoci, Gallati & Sibilla 2007): "
             "water 0.1 m wide and 0.14 m tall behind a rubber gate 5 mm thick (1100 kg/m^3, "
             "E = 10 MPa, Poisson 0.4, plane strain), clamped at its top to a rigid wall, its "
             "lower 79 mm free and 2.5 mm above the floor; no-slip tank about 0.5 x 0.2 m, "
             "MacCormack advection, CFL 0.5 on sqrt(2 g H). The probe: the gate's free end at "
             "mid-thickness."),
    "obstacle": ("**Walhorn's elastic obstacle** (`dam_break_obstacle`; Walhorn et al. 2005): "
                 "a column 0.146 m wide and 0.292 m tall in a 0.584 m square tank, an elastic "
                 "wall 12 mm thick and 80 mm tall (2500 kg/m^3, E = 1 MPa, Poisson 0) clamped "
                 "to the floor at x = 0.292 m; same numerics. The probe: the wall's upstream "
                 "top corner."),
}


NOTES = """\
**What the numbers say.** The gate converges: its first swing agrees within 0.5 mm between
the two finest grids (peak 36.9 and 37.1 mm at 0.11-0.12 s, the tip 10.9 mm up), and from
0.25 s on it holds open at 23-24 mm with the water running out under it. The obstacle's
first bending under the surge converges the same way (peak 46.0-47.2 mm at 0.23-0.24 s,
within 1.1 mm of the finest run over the first swing); after about 0.45 s the water thrown
back from the far wall falls onto it, and that splash differs from grid to grid, so the
runs part (53-67 mm apart over the whole second; the finest run swings to 58 mm at 0.81 s
and back to -38 mm at 0.91 s): no pointwise convergence is to be expected there, only of
the first swing. That phase is sensitive: a change in how the level set is read at the
floor (half a cell deep, where the obstacle's clamped base meets it; 2026-12-03) left
every number up to the first swing as it was and moved the finest run's later swings,
which were 36-39 mm from the coarser runs before. The published curves being withheld, the set-up
choices on which codes differ are stated instead: the gate's Poisson ratio (0.4 here; 0.47
and 0.49 elsewhere), its Young's modulus (10 MPa, as CoCoNuT; SPHinXsys' code units suggest
7.8 MPa), plane strain, and the 2.5 mm clearance under it (SPHinXsys has none); the
obstacle's density (2500 kg/m^3; solids4foam 2700)."""

MESH_NOTE = """\
**The solid's mesh.** Linear triangles are stiff in bending unless several span the
thickness, so the bodies' meshes are fixed finer than the fluid's cells (measured once with
`run_case` and the scene's `divisions` overridden): the gate's peak x displacement to 0.12 s at
40.4 cells across the column is 30.9 / 35.0 / 35.9 mm with 2 x 32 / 4 x 64 / 8 x 128 elements
(4 x 32: 33.2 mm), and the obstacle's to 0.4 s at 30.4 cells is 42.2 / 45.6 / 45.1 mm with
3 x 23 / 6 x 40 / 12 x 80. The scenes use 8 x 128 and 6 x 40."""


def block(runs: list[TipRun], machine: str) -> str:
    lines = [BEGIN, "", "## A rubber gate and an elastic obstacle in a dam break", "",
             "Generated by `python -m elastoflow.validation._gate_obstacle` "
             "(`elastoflow.validation._gate_obstacle`), both with the strong coupling with the "
             "free surface (`FreeSurfaceMonolithicCoupling`) at three resolutions. The "
             "published curves (Antoci's measured gate tip; the reference curves of Walhorn's "
             "obstacle) are withheld from this project, so the error stated is against the "
             "finest run: the largest difference of the x displacement over the first swing "
             "(to 0.1 s after the finest run's first peak; the first swing ends where the "
             "displacement falls below half its largest value so far) and over the whole "
             "run. "
             "The liquid's area (weighted by the cells' open fractions) changes from the first "
             "step to the end by the amount in the table; the level set's global volume "
             "correction is on, as in every free-surface scene.", ""]
    for case in RESOLUTIONS:
        mine = [run for run in runs if run.case == case]
        if not mine:
            continue
        finest = min(mine, key=lambda run: run.cell_size)
        lines += [SETUPS[case], "",
                  "| cells across the column | h [mm] | grid | elements | steps | first peak x [mm] "
                  "| at t [s] | max abs(x - finest) [mm]: first swing | whole run | "
                  "liquid area change | run time [s] |",
                  "|---|---|---|---|---|---|---|---|---|---|---|"]
        for run in mine:
            peak, when = run.peak
            nx, ny = run.cells
            # The first swing: to 0.1 s after the finest run's peak.
            swing = finest.peak[1] + 0.1
            difference = ("— | —" if run is finest
                          else f"{1000 * run.difference_from(finest, swing):.2f} | "
                               f"{1000 * run.difference_from(finest):.2f}")
            lines.append(
                f"| {run.cells_across:g} | {1000 * run.cell_size:.2f} | {nx}x{ny} | "
                f"{run.elements} | {len(run.times) - 1} | {1000 * peak:.2f} | {when:.3f} | "
                f"{difference} | {100 * run.area_change:+.2f} % | {run.seconds:.0f} |"
                + (f" (stopped at t = {run.times[-1]:.3f} s)" if run.failure else ""))
        lines.append("")
    for run in runs:
        if run.failure is not None:
            lines += [f"{run.case} at {run.cells_across:g} stopped: {run.failure}", ""]
    lines += [NOTES, "", MESH_NOTE, "", f"Machine: {machine}.", "",
              "![gate and obstacle](gate_obstacle.png)", "", END]
    return "\n".join(lines)


def write_block(runs: list[TipRun], folder: Path, machine: str) -> Path:
    """The plot and the block of ``folder / free_surface.md`` (replaced between its markers,
    else appended)."""
    plot_runs(runs, folder / "gate_obstacle.png")
    from elastoflow.validation._report import replace_block

    return replace_block(folder / "free_surface.md", block(runs, machine), BEGIN, END,
                         before=None)


def main(argv: list[str]) -> None:
    import platform

    cases = argv or list(RESOLUTIONS)
    machine = f"{platform.machine()}, {platform.processor() or 'cpu'}, 2 cores"
    runs: list[TipRun] = []
    for case in cases:
        for cells in RESOLUTIONS[case]:
            runs.append(run_case(case, cells, progress=lambda line: print(line, flush=True)))
            # Written after each run: a long study keeps what it has finished.
            print(write_block(runs, Path("docs/validation"), machine), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
