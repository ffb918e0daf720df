"""Issue 12's force smoothness: the force on moving bodies step by step, with each boundary
treatment (docs/method_notes.md item 9).

Cases: a heavy disc coasting across the grid (``disc``), the preCICE perpendicular flap at
about 10 and 20 cells per metre over 3 s (``flap10``, ``flap20``) and Turek-Hron FSI2 at
N = 10 from 9 to 12 s (``fsi2``). Each runs the monolithic scheme and records the scheme's
own force on the body after every step (`CoupledState.body_forces`), the force the body
moves with. Measures over the case's window: the largest step-to-step change, its 99th
percentile, and the noise: the root mean square of the force less a 15-step cubic
Savitzky-Golay fit (what is left when the smooth signal, however fast, is taken out).
``elastoflow validate force-smoothness`` writes ``docs/validation/force_smoothness.md``;
``elastoflow validate force-smoothness refinement`` adds the disc refined in h and dt together
and in dt alone, and a coasting square in dt alone (`disc_refinement`), with the noise split
into its part locked to the body's place in the grid and the rest.
"""

from __future__ import annotations

import math
import time as _time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from elastoflow.io import write_text_atomic

CASES: tuple[str, ...] = ("disc", "flap10", "flap20", "fsi2")
# Phase bins of `ForceRun.grid_locked_split`: at the refinement's smallest step the disc
# moves 0.048 of a cell a step, so each bin of 0.05 cell holds about one step per cell.
PHASE_BINS = 20
BOUNDARIES: tuple[str, ...] = ("cut_cell", "dual_cell")
FIT_WINDOW = 15
FIT_ORDER = 3


@dataclass(frozen=True)
class ForceRun:
    """One case with one treatment: the force component measured after each step.

    Attributes:
        case: One of `CASES`.
        boundary: The boundary treatment.
        component: "drag" (x) or "lift" (y): what the case measures.
        time: Time after each step in the window [s].
        force: The scheme's force on the body (that component) [N/m], same length.
        seconds: Wall time of the whole run [s].
        position: The body's mean node position along x after each step [m], same length
            (what `grid_locked_split` bins by).
    """

    case: str
    boundary: str
    component: str
    time: np.ndarray
    force: np.ndarray
    seconds: float
    position: np.ndarray | None = None

    @property
    def mean(self) -> float:
        return float(self.force.mean())

    @property
    def largest_jump(self) -> float:
        return float(np.abs(np.diff(self.force)).max())

    @property
    def p99_jump(self) -> float:
        return float(np.percentile(np.abs(np.diff(self.force)), 99))

    @property
    def noise(self) -> float:
        """Root mean square of the force less its `FIT_WINDOW`-step cubic Savitzky-Golay
        fit [N/m]."""
        return self.noise_over(FIT_WINDOW)

    def noise_over(self, window: int) -> float:
        """Root mean square of the force less its cubic Savitzky-Golay fit over ``window``
        steps (odd) [N/m]."""
        from scipy.signal import savgol_filter

        residual = self.force - savgol_filter(self.force, window, FIT_ORDER)
        return float(np.sqrt(np.mean(residual**2)))

    def grid_locked_split(self, window: int, h: float,
                          bins: int = PHASE_BINS) -> tuple[float, float]:
        """The noise over ``window`` split into the part locked to the body's place in the
        grid and the rest [N/m], both root mean squares.

        A body translating along x meets the same geometry in the grid after every cell
        ``h`` of travel, so whatever depends only on where the outline cuts the grid
        repeats with the position's phase ``(x / h) mod 1``: the residual's mean over each
        of ``bins`` phase bins is that part. It holds both a smooth dependence of the force
        on the body's place in the grid (a discretization error, which converges with h)
        and the jumps at the steps where the outline crosses a line of points, which come
        at the same phase every cell. What is left about those means is the part that does
        not repeat with the position."""
        from scipy.signal import savgol_filter

        if self.position is None:
            raise ValueError(f"{self.case}: the run recorded no positions")
        residual = self.force - savgol_filter(self.force, window, FIT_ORDER)
        phase = np.floor(np.mod(self.position / h, 1.0) * bins).astype(np.int64)
        phase = np.minimum(phase, bins - 1)
        counts = np.bincount(phase, minlength=bins)
        means = np.bincount(phase, weights=residual, minlength=bins) / np.maximum(counts, 1)
        locked = means[phase]
        return (float(np.sqrt(np.mean(locked**2))),
                float(np.sqrt(np.mean((residual - locked) ** 2))))


def coasting_disc(boundary: str, steps: int = 150, warmup: int = 50, *, cells: int = 96,
                  dt: float = 0.01, incremental_pressure: bool = False) -> ForceRun:
    """A disc (R = 0.1 m, 1000 times denser than the water) started at 0.2 m/s through water
    at rest (nu = 1e-3: Re 40) in a 2 m x 1 m box of 2 ``cells`` x ``cells`` (96: R = 9.6
    cells; dt = 0.01 s: it crosses 29 cells in 150 steps); the drag over the steps after
    ``warmup``; ``incremental_pressure``: the fluid's pressure-correction form."""
    from elastoflow import coupling

    outline = coupling.obstacle_circle((0.5, 0.5), 0.1, segments=48).polygon
    return _coasting("disc", outline, boundary, steps, warmup, cells, dt, incremental_pressure)


def coasting_square(boundary: str, steps: int = 150, warmup: int = 50, *, cells: int = 96,
                    dt: float = 0.01) -> ForceRun:
    """`coasting_disc`'s set-up with a square of side 0.2 m instead of the disc, its sides
    along the grid (the centre 0.3 h and 0.25 h off a u point, so that no side lies on a
    line of points): its front face crosses a whole column of velocity points at once, so
    the force's answer to each crossing stands out from the rest, where the disc's many
    crossings overlap."""
    h = 1.0 / cells
    cx, cy, half = 0.5 + 0.3 * h, 0.5 + 0.25 * h, 0.1
    outline = np.array([[cx - half, cy - half], [cx + half, cy - half],
                        [cx + half, cy + half], [cx - half, cy + half]])
    return _coasting("square", outline, boundary, steps, warmup, cells, dt, False)


def _coasting(case: str, outline: np.ndarray, boundary: str, steps: int, warmup: int,
              cells: int, dt: float, incremental_pressure: bool) -> ForceRun:
    from elastoflow import fluid, solid
    from elastoflow.grid import Grid2D
    from elastoflow.simulation import Simulation

    n = cells
    grid = Grid2D(nx=2 * n, ny=n, h=1.0 / n)
    walls = fluid.DomainBoundaries(left=fluid.WallNoSlip(), right=fluid.WallNoSlip(),
                                   bottom=fluid.WallNoSlip(), top=fluid.WallNoSlip())
    solver = fluid.FluidSolver(grid, density=1000.0, viscosity=1e-3, boundaries=walls,
                               advection="maccormack", incremental_pressure=incremental_pressure)
    mesh = solid.mesh_from_polygon(outline, element_size=0.03)
    body = solid.ElasticBody(mesh, solid.MaterialStVK(1.0e6, 1.0e9, 0.3))
    simulation = Simulation(grid, solver, bodies=[body], dt=dt, coupling="monolithic",
                            boundary=boundary)
    simulation.state.bodies[0].velocities[:, 0] = 0.2
    return _record(case, boundary, "drag", simulation, steps, warmup * dt)


def _record(case: str, boundary: str, component: str, simulation: Any, steps: int,
            start: float) -> ForceRun:
    axis = 0 if component == "drag" else 1
    began = _time.perf_counter()
    times, forces, positions = [], [], []
    for _ in range(steps):
        simulation.step()
        if simulation.time > start + 1e-12:
            times.append(simulation.time)
            forces.append(float(simulation.state.body_forces[0][:, axis].sum()))
            positions.append(float(simulation.state.bodies[0].positions[:, 0].mean()))
    return ForceRun(case, boundary, component, np.array(times), np.array(forces),
                    _time.perf_counter() - began, np.array(positions))


def flap(boundary: str, resolution: int, duration: float = 3.0) -> ForceRun:
    """The perpendicular flap (`run_flap`'s set-up), the drag over the last two thirds."""
    from elastoflow.validation._perpendicular_flap import flap_setup, flap_simulation

    setup = flap_setup(resolution, duration=duration, boundary=boundary)
    simulation, _, _ = flap_simulation(setup)
    return _record(f"flap{resolution}", boundary, "drag", simulation, setup.steps,
                   duration / 3.0)


def fsi2(boundary: str, resolution: int = 10, duration: float = 12.0,
         start: float = 9.0) -> ForceRun:
    """Turek-Hron FSI2 (`run_case`'s set-up), the flag's lift from ``start`` on."""
    from elastoflow.validation._turek_hron import case_simulation, default_setup, get_case

    setup = default_setup(get_case("FSI2"), resolution, duration=duration, boundary=boundary)
    simulation, _ = case_simulation(setup)
    return _record("fsi2", boundary, "lift", simulation, setup.steps, start)


RUNNERS: dict[str, Callable[[str], ForceRun]] = {
    "disc": coasting_disc,
    "flap10": lambda boundary: flap(boundary, 10),
    "flap20": lambda boundary: flap(boundary, 20),
    "fsi2": fsi2,
}


@dataclass(frozen=True)
class ForceSmoothnessStudy:
    runs: tuple[ForceRun, ...]

    def run(self, case: str, boundary: str) -> ForceRun:
        return next(r for r in self.runs if r.case == case and r.boundary == boundary)

    @property
    def cases(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(r.case for r in self.runs))

    @property
    def boundaries(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(r.boundary for r in self.runs))


def run_force_smoothness(cases: Sequence[str] = CASES,
                         boundaries: Sequence[str] = BOUNDARIES) -> ForceSmoothnessStudy:
    """Every case with every treatment."""
    unknown = [c for c in cases if c not in RUNNERS]
    if unknown:
        raise ValueError(f"case = {unknown[0]!r}: must be one of {', '.join(CASES)}")
    return ForceSmoothnessStudy(tuple(RUNNERS[c](b) for c in cases for b in boundaries))


_DESCRIPTION = {
    "disc": "heavy disc coasting 29 cells (192x96, 100 steps after 50)",
    "flap10": "perpendicular flap, N = 10, 1-3 s (drag)",
    "flap20": "perpendicular flap, N = 20, 1-3 s (drag)",
    "fsi2": "Turek-Hron FSI2, N = 10, 9-12 s (lift)",
}


def force_smoothness_table(study: ForceSmoothnessStudy) -> list[str]:
    lines = ["| case | treatment | mean [N/m] | largest jump | 99th percentile | noise (rms) | "
             "wall time [s] |", "|---|---|---|---|---|---|---|"]
    for case in study.cases:
        for boundary in study.boundaries:
            r = study.run(case, boundary)
            lines.append(f"| {_DESCRIPTION[case]} | {boundary} | {r.mean:.2f} | "
                         f"{r.largest_jump:.3g} | {r.p99_jump:.3g} | {r.noise:.3g} | "
                         f"{r.seconds:.0f} |")
    return lines


def _save_figure(figure: Any, path: Path) -> None:
    """Lay out ``figure``, write it to ``path`` whole or not at all, and close it."""
    import matplotlib.pyplot as plt

    from elastoflow.io import atomic_path

    figure.tight_layout()
    with atomic_path(path) as temporary:
        figure.savefig(temporary, dpi=90)
    plt.close(figure)


def _plot(study: ForceSmoothnessStudy, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cases = study.cases
    figure, axes = plt.subplots(len(cases), 1, figsize=(9, 2.6 * len(cases)), squeeze=False)
    colours = {"cut_cell": "C3", "dual_cell": "C0", "staircase": "C2"}
    for axis, case in zip(axes[:, 0], cases, strict=True):
        for boundary in study.boundaries:
            r = study.run(case, boundary)
            window = r.time <= r.time[0] + (r.time[-1] - r.time[0]) / 3.0
            axis.plot(r.time[window], r.force[window], color=colours.get(boundary, "k"),
                      lw=0.8, label=boundary)
        axis.set_title(_DESCRIPTION[case], fontsize=9)
        axis.set_ylabel(f"{study.run(case, study.boundaries[0]).component} [N/m]")
        axis.legend(fontsize=8)
    axes[-1, 0].set_xlabel("time [s] (the first third of each window)")
    _save_figure(figure, path)


def write_force_smoothness_report(study: ForceSmoothnessStudy, folder: str | Path
                                  ) -> list[Path]:
    """``force_smoothness.md`` and its plot in ``folder``."""
    folder = Path(folder)
    figure = folder / "force_smoothness.png"
    _plot(study, figure)
    lines = ["# Force smoothness (issue 12)", "",
             "The monolithic scheme's own force on a moving body after every step, with the "
             "cut-cell and the dual-cell boundary treatments (docs/method_notes.md item 9). "
             "Noise: the root mean square of the force less a "
             f"{FIT_WINDOW}-step cubic Savitzky-Golay fit. Command: `elastoflow validate "
             "force-smoothness --out docs/validation` (module "
             "`elastoflow.validation._force_smoothness`).", "",
             *force_smoothness_table(study), "", f"![force against time]({figure.name})", ""]
    ratios = []
    for case in study.cases:
        if {"cut_cell", "dual_cell"} <= set(study.boundaries):
            cut, dual = study.run(case, "cut_cell"), study.run(case, "dual_cell")
            if cut.noise > 0.0 and math.isfinite(dual.noise):
                ratios.append(f"{case} {dual.noise / cut.noise:.2f}")
    if ratios:
        lines += [f"Noise with the dual cells over the cut cells': {', '.join(ratios)}.", ""]
    path = folder / "force_smoothness.md"
    # The refinement study is written by its own command: keep its block.
    old = path.read_text() if path.exists() else ""
    if REFINEMENT_BEGIN in old and REFINEMENT_END in old:
        block = old.split(REFINEMENT_BEGIN, 1)[1].split(REFINEMENT_END, 1)[0]
        lines += [REFINEMENT_BEGIN + block + REFINEMENT_END, ""]
    write_text_atomic(path, "\n".join(lines))
    return [path, figure]


# The disc refined: in h and dt together (the CFL number fixed at 0.19) and in dt alone.
REFINEMENT_BEGIN, REFINEMENT_END = "<!-- refinement:begin -->", "<!-- refinement:end -->"
JOINT_CELLS: tuple[int, ...] = (48, 96, 192)
DT_ALONE: tuple[float, ...] = (0.01, 0.005, 0.0025)
_DISC_DT_AT_96 = 0.01
_DISC_WINDOW = (0.5, 1.5)  # [s]: the drag after the start-up, as in `coasting_disc`'s default


@dataclass(frozen=True)
class RefinementRun:
    """The coasting disc at one grid and time step.

    Attributes:
        series: "h and dt" (the CFL number fixed) or "dt alone" (96 cells).
        cells: Cells across the 1 m of the box (the disc's radius is ``cells / 10``).
        dt: Time step [s].
        run: The drag after each step from 0.5 s to 1.5 s.
    """

    series: str
    cells: int
    dt: float
    run: ForceRun

    @property
    def window(self) -> int:
        """The fit's window in steps: `FIT_WINDOW` steps at 96 cells and dt = 0.01 s, the
        same distance travelled (2.9 cells) at every grid and time step."""
        steps = round(FIT_WINDOW * (_DISC_DT_AT_96 * 96 / self.cells) / self.dt)
        return steps if steps % 2 else steps + 1

    @property
    def noise(self) -> float:
        """Noise of the drag [N/m] over `window`."""
        return self.run.noise_over(self.window)


def disc_refinement(boundaries: Sequence[str] = BOUNDARIES,
                    joint: Sequence[int] = JOINT_CELLS,
                    dts: Sequence[float] = DT_ALONE,
                    square_dts: Sequence[float] = DT_ALONE) -> tuple[RefinementRun, ...]:
    """The coasting disc with each treatment: at ``joint`` cells with dt = 0.96 s / cells
    (h and dt together), and at 96 cells with each of ``dts`` (dt alone; the run at
    dt = 0.01 s is shared with the first series when both hold it); then the coasting square
    at 96 cells with each of ``square_dts``."""
    runs: list[RefinementRun] = []
    for boundary in boundaries:
        done: dict[tuple[int, float], ForceRun] = {}

        def disc(cells: int, dt: float, boundary: str = boundary,
                 done: dict[tuple[int, float], ForceRun] = done) -> ForceRun:
            key = (cells, round(dt, 12))
            if key not in done:
                done[key] = coasting_disc(boundary, round(_DISC_WINDOW[1] / dt),
                                          round(_DISC_WINDOW[0] / dt), cells=cells, dt=dt)
            return done[key]

        for cells in joint:
            dt = _DISC_DT_AT_96 * 96 / cells
            runs.append(RefinementRun("h and dt", cells, dt, disc(cells, dt)))
        for dt in dts:
            runs.append(RefinementRun("dt alone", 96, dt, disc(96, dt)))
    for boundary in boundaries:
        for dt in square_dts:
            square = coasting_square(boundary, round(_DISC_WINDOW[1] / dt),
                                     round(_DISC_WINDOW[0] / dt), cells=96, dt=dt)
            runs.append(RefinementRun("square, dt alone", 96, dt, square))
    return tuple(runs)


def refinement_table(runs: Sequence[RefinementRun]) -> list[str]:
    """One row per run: the drag, its largest step-to-step change and its noise, both as a
    share of the drag, and the noise's exponent against the row above in the same series
    (noise ~ h^p with h and dt refined together; noise ~ dt^p with dt alone); then the noise
    split into its part locked to the body's place in the grid and the rest
    (`ForceRun.grid_locked_split`), where the run recorded positions."""
    lines = ["| series | treatment | cells (R/h) | dt [s] | mean drag [N/m] | largest jump | "
             "noise (rms) | order | locked to the grid / the rest | wall time [s] |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    previous: RefinementRun | None = None
    for r in runs:
        share = abs(r.run.mean)
        order = ""
        if (previous is not None and previous.series == r.series
                and previous.run.boundary == r.run.boundary and r.noise > 0.0):
            ratio = r.cells / previous.cells if r.series == "h and dt" else previous.dt / r.dt
            order = f"{math.log(previous.noise / r.noise) / math.log(ratio):.2f}"
        split = ""
        if r.run.position is not None:
            locked, rest = r.run.grid_locked_split(r.window, 1.0 / r.cells)
            split = f"{100 * locked / share:.2f} / {100 * rest / share:.2f} %"
        lines.append(f"| {r.series} | {r.run.boundary} | {r.cells} ({r.cells / 10:g}) | "
                     f"{r.dt:g} | {r.run.mean:.3f} | {100 * r.run.largest_jump / share:.2f} % | "
                     f"{100 * r.noise / share:.2f} % | {order} | {split} | "
                     f"{r.run.seconds:.0f} |")
        previous = r
    return lines


REFINEMENT_FIGURE = "force_smoothness_refinement.png"
# What the figure shows of each run: this many cells of travel from the window's start.
_FIGURE_CELLS = 4.0
_SQUARE_HALF_SIDE = 0.1  # [m], `coasting_square`'s


def _positions(r: RefinementRun) -> np.ndarray:
    if r.run.position is None:
        raise ValueError(f"{r.run.case}: the run recorded no positions")
    return r.run.position


def _plot_refinement(runs: Sequence[RefinementRun], path: Path) -> bool:
    """The dual cells' drag against the distance travelled, at each step of the "dt alone"
    series, the disc above and the square below (its front face's crossings of the columns
    of v points dotted); False, and nothing written, when there are no such runs."""
    panels = [[r for r in runs if r.series == series and r.run.boundary == "dual_cell"
               and r.run.position is not None]
              for series in ("dt alone", "square, dt alone")]
    panels = [panel for panel in panels if panel]
    if not panels:
        return False
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(len(panels), 1, figsize=(9, 3.0 * len(panels)), squeeze=False)
    for axis, panel in zip(axes[:, 0], panels, strict=True):
        h = 1.0 / panel[0].cells
        start = float(_positions(panel[0])[0])
        for r in panel:
            cells = (_positions(r) - start) / h
            shown = cells <= _FIGURE_CELLS
            axis.plot(cells[shown], r.run.force[shown], lw=0.8, marker=".", ms=2,
                      label=f"dt = {r.dt:g} s")
        if panel[0].run.case == "square":
            front = (start + _SQUARE_HALF_SIDE) / h
            first = math.ceil(front - 0.5) + 0.5
            for column in np.arange(first, front + _FIGURE_CELLS, 1.0):
                axis.axvline(column - front, color="0.6", lw=0.6, ls=":")
            axis.set_title("square (dotted: its front face passes a column of v points)",
                           fontsize=9)
        else:
            axis.set_title("disc", fontsize=9)
        axis.set_ylabel("drag [N/m]")
        axis.legend(fontsize=8)
    axes[-1, 0].set_xlabel("cells travelled from 0.5 s (dual cells, 96 cells, MacCormack)")
    _save_figure(figure, path)
    return True


def refinement_block(runs: Sequence[RefinementRun], figure: str | None = None) -> str:
    """The Markdown section of the refinement study, between its markers (with ``figure``,
    the file name of `_plot_refinement`'s figure beside the page)."""
    shown = [] if figure is None else [f"![drag against the distance travelled]({figure})", ""]
    return "\n".join([
        REFINEMENT_BEGIN, "", "## The coasting disc refined, and a coasting square", "",
        "The disc of the table above (R = 0.1 m, 0.2 m/s, Re 40) over 0.5-1.5 s, refined in h "
        "and dt together (the CFL number fixed at 0.19, the body's 48-sided outline the same) "
        "and in dt alone at 96 cells. Noise: as above, the fit's window spanning the same "
        "distance travelled (2.9 cells) in every run. Order: p in noise ~ h^p (h and dt) or "
        "noise ~ dt^p (dt alone), from the row above. The square (`coasting_square`: side "
        "0.2 m, sides along the grid, the same speed and fluid; R/h: its half side) crosses "
        "a whole column of velocity points with its front face at once. Locked to the grid: "
        "the noise's part that repeats with the body's place in the grid, the residual's "
        f"mean over {PHASE_BINS} bins of the phase (x / h) mod 1 (a smooth dependence on "
        "where the outline cuts the grid, and the jumps where it crosses a line of points, "
        "which come at the same phase every cell); the rest: what is left about those "
        "means, which does not repeat (docs/method_notes.md item 9). Command: `elastoflow "
        "validate force-smoothness refinement --out docs/validation`.", "",
        *refinement_table(runs), "", *shown, REFINEMENT_END])


def write_refinement_report(runs: Sequence[RefinementRun], folder: str | Path) -> Path:
    """The refinement block in ``folder / force_smoothness.md`` (created if missing), and
    its figure beside it where the runs hold the "dt alone" series."""
    from elastoflow.validation._report import replace_block

    page = Path(folder) / "force_smoothness.md"
    if not page.exists():
        write_text_atomic(page, "# Force smoothness (issue 12)\n")
    figure = REFINEMENT_FIGURE if _plot_refinement(runs, page.parent / REFINEMENT_FIGURE) else None
    return replace_block(page, refinement_block(runs, figure), REFINEMENT_BEGIN,
                         REFINEMENT_END, before=None)
