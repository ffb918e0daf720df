"""Issue 12's force smoothness: the force on moving bodies step by step, with each boundary
treatment (docs/method_notes.md item 9).

Cases: a heavy disc coasting across the grid (``disc``), the preCICE perpendicular flap at
about 10 and 20 cells per metre over 3 s (``flap10``, ``flap20``) and Turek-Hron FSI2 at
N = 10 from 9 to 12 s (``fsi2``). Each runs the monolithic scheme and records the scheme's
own force on the body after every step (`CoupledState.body_forces`), the force the body
moves with. Measures over the case's window: the largest step-to-step change, its 99th
percentile, and the noise: the root mean square of the force less a 15-step cubic
Savitzky-Golay fit (what is left when the smooth signal, however fast, is taken out).
``elastoflow validate force-smoothness`` writes ``docs/validation/force_smoothness.md``.
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
    """

    case: str
    boundary: str
    component: str
    time: np.ndarray
    force: np.ndarray
    seconds: float

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
        from scipy.signal import savgol_filter

        residual = self.force - savgol_filter(self.force, FIT_WINDOW, FIT_ORDER)
        return float(np.sqrt(np.mean(residual**2)))


def coasting_disc(boundary: str, steps: int = 150, warmup: int = 50) -> ForceRun:
    """A disc (R = 0.1 m = 9.6 cells, 1000 times denser than the water) started at 0.2 m/s
    through water at rest (nu = 1e-3: Re 40), 192 x 96 cells, dt = 0.01 s: it crosses 29
    cells in 150 steps; the drag over the steps after ``warmup``."""
    from elastoflow import coupling, fluid, solid
    from elastoflow.grid import Grid2D
    from elastoflow.simulation import Simulation

    n = 96
    grid = Grid2D(nx=2 * n, ny=n, h=1.0 / n)
    walls = fluid.DomainBoundaries(left=fluid.WallNoSlip(), right=fluid.WallNoSlip(),
                                   bottom=fluid.WallNoSlip(), top=fluid.WallNoSlip())
    solver = fluid.FluidSolver(grid, density=1000.0, viscosity=1e-3, boundaries=walls,
                               advection="maccormack")
    outline = coupling.obstacle_circle((0.5, 0.5), 0.1, segments=48).polygon
    mesh = solid.mesh_from_polygon(outline, element_size=0.03)
    body = solid.ElasticBody(mesh, solid.MaterialStVK(1.0e6, 1.0e9, 0.3))
    simulation = Simulation(grid, solver, bodies=[body], dt=0.01, coupling="monolithic",
                            boundary=boundary)
    simulation.state.bodies[0].velocities[:, 0] = 0.2
    return _record("disc", boundary, "drag", simulation, steps, warmup * 0.01)


def _record(case: str, boundary: str, component: str, simulation: Any, steps: int,
            start: float) -> ForceRun:
    axis = 0 if component == "drag" else 1
    began = _time.perf_counter()
    times, forces = [], []
    for _ in range(steps):
        simulation.step()
        if simulation.time > start + 1e-12:
            times.append(simulation.time)
            forces.append(float(simulation.state.body_forces[0][:, axis].sum()))
    return ForceRun(case, boundary, component, np.array(times), np.array(forces),
                    _time.perf_counter() - began)


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
    figure.tight_layout()
    from elastoflow.io import atomic_path

    with atomic_path(path) as temporary:
        figure.savefig(temporary, dpi=90)
    plt.close(figure)


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
    write_text_atomic(path, "\n".join(lines))
    return [path, figure]
