"""The lid-driven cavity of Ghia, Ghia & Shin (1982): steady centreline profiles, and the
Re 1000 study of issue 11 (item 4).

Unit square, lid u = 1 on top, no-slip elsewhere, density 1, nu = 1 / Re; stepped from rest to
a steady state (the largest change of u per unit time below ``tolerance`` lid speeds). The
profiles are u(0.5, y) on the u points of the middle column and v(x, 0.5) on the v points of
the middle row, with the walls' values at the ends.

Ghia's Re 1000 tables are withheld from the project's reference file, so the Re 1000 study
measures the profiles against themselves: each resolution's profiles are sampled at the
points of Ghia's tables (`GHIA_Y`, `GHIA_X`: the coordinates every Re of the tables shares),
their differences between resolutions give the observed order, and a Richardson
extrapolation from the two finest grids gives the error left at each. The sampled values are
written as CSV, so that they can be compared with the published table directly.
``python -m elastoflow.validation._cavity [FOLDER]`` writes ``cavity_re1000.csv``, its plot and
the block in ``FOLDER/unsteady.md`` (default ``docs/validation``).
"""

from __future__ import annotations

import math
import sys
import time as _time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

# The interior points of Ghia's tables (every Re shares them): y of table I (u along x = 0.5)
# and x of table II (v along y = 0.5), from ../shared/reference/ghia_cavity.json.
GHIA_Y = np.array([0.0547, 0.0625, 0.0703, 0.1016, 0.1719, 0.2813, 0.4531, 0.5, 0.6172, 0.7344,
                   0.8516, 0.9531, 0.9609, 0.9688, 0.9766])
GHIA_X = np.array([0.0625, 0.0703, 0.0781, 0.0938, 0.1563, 0.2266, 0.2344, 0.5, 0.8047, 0.8594,
                   0.9063, 0.9453, 0.9531, 0.9609, 0.9688])
STUDY_CELLS: tuple[int, ...] = (64, 128, 256)
STUDY_ADVECTION: tuple[str, ...] = ("maccormack", "semi_lagrangian")
BEGIN, END = "<!-- cavity-re1000:begin -->", "<!-- cavity-re1000:end -->"


@dataclass(frozen=True)
class CavityRun:
    """One steady cavity flow.

    Attributes:
        cells: Cells across the cavity.
        reynolds: Re = U L / nu.
        advection: The fluid's advection scheme.
        y, u: u(0.5, y) on the middle column's u points, walls included (0 and 1).
        x, v: v(x, 0.5) on the middle row's v points, walls included (0 and 0).
        steps: Steps taken.
        time: Time reached [s].
        change: Largest change of u per unit time over the last check.
        seconds: Wall time of the run [s].
    """

    cells: int
    reynolds: float
    advection: str
    y: np.ndarray
    u: np.ndarray
    x: np.ndarray
    v: np.ndarray
    steps: int
    time: float
    change: float
    seconds: float

    def u_at(self, y: np.ndarray) -> np.ndarray:
        return np.interp(y, self.y, self.u)

    def v_at(self, x: np.ndarray) -> np.ndarray:
        return np.interp(x, self.x, self.v)


def run_cavity(cells: int, reynolds: float, advection: str = "maccormack", cfl: float = 1.0,
               t_max: float = 60.0, tolerance: float = 1e-4) -> CavityRun:
    """The steady cavity flow on a ``cells`` x ``cells`` grid (even), dt = ``cfl`` h."""
    from elastoflow.fluid import DomainBoundaries, FluidSolver, FluidState, WallMoving, WallNoSlip
    from elastoflow.grid import Grid2D
    from elastoflow.validation._report import step_to_steady

    if cells % 2:
        raise ValueError(f"cells = {cells}: must be even (the centrelines lie on grid lines)")
    began = _time.perf_counter()
    grid = Grid2D(cells, cells, 1.0 / cells)
    solver = FluidSolver(
        grid, density=1.0, viscosity=1.0 / reynolds,
        boundaries=DomainBoundaries(WallNoSlip(), WallNoSlip(), WallNoSlip(), WallMoving(1.0)),
        advection=advection,
    )
    state = FluidState.zeros(grid)
    steps, time, change = step_to_steady(solver, state, cfl * grid.h, t_max, tolerance)
    centres = (np.arange(cells) + 0.5) / cells
    ends = np.concatenate([[0.0], centres, [1.0]])
    return CavityRun(
        cells, float(reynolds), advection,
        ends, np.concatenate([[0.0], state.velocity_x[cells // 2], [1.0]]),
        ends.copy(), np.concatenate([[0.0], state.velocity_y[:, cells // 2], [0.0]]),
        steps, time, change, _time.perf_counter() - began,
    )


@dataclass(frozen=True)
class ConvergenceRow:
    """One scheme's profiles at Ghia's points, resolution against resolution."""

    advection: str
    cells: tuple[int, ...]
    difference_u: tuple[float, ...]  # RMS u(next) - u(this), consecutive grids
    difference_v: tuple[float, ...]
    order_u: float  # from the last two differences (nan with fewer than three grids)
    order_v: float
    error_u: tuple[float, ...]  # RMS against the Richardson extrapolation, per grid
    error_v: tuple[float, ...]


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(values**2)))


def convergence(runs: Sequence[CavityRun], y: np.ndarray, x: np.ndarray) -> ConvergenceRow:
    """Differences, observed order and Richardson errors of one scheme's runs (ascending
    ``cells``, each twice the one before) at the points ``y`` and ``x``."""
    us = [r.u_at(y) for r in runs]
    vs = [r.v_at(x) for r in runs]
    du = tuple(_rms(b - a) for a, b in zip(us, us[1:], strict=False))
    dv = tuple(_rms(b - a) for a, b in zip(vs, vs[1:], strict=False))

    def order(d: tuple[float, ...]) -> float:
        return math.log2(d[-2] / d[-1]) if len(d) >= 2 and d[-1] > 0.0 else math.nan

    def errors(profiles: list[np.ndarray], p: float) -> tuple[float, ...]:
        # Richardson from the two finest grids (order p, at least 1: a first-order
        # estimate where the observed order is lower or unknown).
        p = p if math.isfinite(p) and p > 1.0 else 1.0
        limit = profiles[-1] + (profiles[-1] - profiles[-2]) / (2.0**p - 1.0)
        return tuple(_rms(profile - limit) for profile in profiles)

    p_u, p_v = order(du), order(dv)
    return ConvergenceRow(runs[0].advection, tuple(r.cells for r in runs), du, dv, p_u, p_v,
                          errors(us, p_u) if len(us) > 1 else (math.nan,),
                          errors(vs, p_v) if len(vs) > 1 else (math.nan,))


def run_re1000_study(cells: Sequence[int] = STUDY_CELLS,
                     advection: Sequence[str] = STUDY_ADVECTION,
                     t_max: float = 150.0) -> list[CavityRun]:
    return [run_cavity(n, 1000, scheme, t_max=t_max) for scheme in advection for n in cells]


def _by_scheme(runs: Sequence[CavityRun]) -> dict[str, list[CavityRun]]:
    groups: dict[str, list[CavityRun]] = {}
    for r in runs:
        groups.setdefault(r.advection, []).append(r)
    return {k: sorted(v, key=lambda r: r.cells) for k, v in groups.items()}


def study_block(runs: Sequence[CavityRun], y: np.ndarray, x: np.ndarray) -> str:
    lines = [BEGIN, "", "## Ghia's cavity at Re 1000", "",
             "Generated by `python -m elastoflow.validation._cavity` "
             "(`elastoflow.validation._cavity`). The set-up of `docs/validation_fluid.md`'s "
             "cavity (unit square, lid speed 1, no-slip walls, dt = h), nu = 1e-3, stepped from "
             "rest until u changes by less than 1e-4 per unit time. Ghia's Re 1000 tables are "
             "withheld from the reference file, so the profiles are measured against each "
             "other at the points of Ghia's tables (15 along each centreline, the walls left "
             "out): the RMS difference between consecutive grids, the observed order from the "
             "last two differences, and the RMS difference from the Richardson extrapolation "
             "of the two finest grids (with the observed order, or 1 where it is lower). The "
             "sampled values are in `cavity_re1000.csv`, to be "
             "set beside the published table.", "",
             "| advection | cells | steps | t reached | last change | wall [s] |",
             "|---|---|---|---|---|---|"]
    for r in runs:
        lines.append(f"| {r.advection} | {r.cells}² | {r.steps} | {r.time:.1f} | "
                     f"{r.change:.1e} | {r.seconds:.0f} |")
    lines += ["", "| advection | grids | RMS difference u (consecutive) | order u | "
              "RMS difference v (consecutive) | order v | RMS from the extrapolation u | "
              "same, v |", "|---|---|---|---|---|---|---|---|"]
    for scheme, group in _by_scheme(runs).items():
        row = convergence(group, y, x)
        lines.append(
            f"| {scheme} | {' / '.join(f'{n}²' for n in row.cells)} | "
            f"{' / '.join(f'{d:.4f}' for d in row.difference_u)} | {row.order_u:.2f} | "
            f"{' / '.join(f'{d:.4f}' for d in row.difference_v)} | {row.order_v:.2f} | "
            f"{' / '.join(f'{e:.4f}' for e in row.error_u)} | "
            f"{' / '.join(f'{e:.4f}' for e in row.error_v)} |")
    lines += ["", "![cavity Re 1000](cavity_re1000.png)", "", END]
    return "\n".join(lines)


def write_csv(runs: Sequence[CavityRun], y: np.ndarray, x: np.ndarray, path: Path) -> Path:
    from elastoflow.io import write_text_atomic

    header = ["centreline,coordinate"] + [f"{r.advection}_{r.cells}" for r in runs]
    rows = [",".join(header)]
    for name, points, sample in (("u(0.5;y)", y, CavityRun.u_at), ("v(x;0.5)", x, CavityRun.v_at)):
        values = [sample(r, points) for r in runs]
        for k, point in enumerate(points):
            rows.append(",".join([name, f"{point:.4f}"] + [f"{v[k]:.5f}" for v in values]))
    write_text_atomic(path, "\n".join(rows) + "\n")
    return path


def _plot(runs: Sequence[CavityRun], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from elastoflow.io import atomic_path

    figure, (left, right) = plt.subplots(1, 2, figsize=(10, 4.2))
    styles = {"maccormack": "-", "semi_lagrangian": "--"}
    for r in runs:
        label = f"{r.advection} {r.cells}²"
        left.plot(r.u, r.y, styles.get(r.advection, ":"), lw=1, label=label)
        right.plot(r.x, r.v, styles.get(r.advection, ":"), lw=1, label=label)
    left.set_xlabel("u(0.5, y)")
    left.set_ylabel("y")
    right.set_xlabel("x")
    right.set_ylabel("v(x, 0.5)")
    left.legend(fontsize=7)
    figure.suptitle("Lid-driven cavity, Re = 1000")
    figure.tight_layout()
    with atomic_path(path) as temporary:
        figure.savefig(temporary, dpi=100)
    plt.close(figure)


def write_re1000_report(runs: Sequence[CavityRun], folder: str | Path) -> list[Path]:
    """``cavity_re1000.csv``, ``cavity_re1000.png`` and the block of ``unsteady.md``."""
    from elastoflow.validation._report import replace_block

    folder = Path(folder)
    y, x = GHIA_Y, GHIA_X
    csv = write_csv(runs, y, x, folder / "cavity_re1000.csv")
    figure = folder / "cavity_re1000.png"
    _plot(runs, figure)
    page = replace_block(folder / "unsteady.md", study_block(runs, y, x), BEGIN, END,
                         before=None)
    return [csv, figure, page]


def main(argv: Sequence[str]) -> None:
    folder = Path(argv[0]) if argv else Path("docs/validation")
    runs = run_re1000_study()
    for r in runs:
        print(f"{r.advection} {r.cells}: {r.steps} steps, t = {r.time:.1f}, change "
              f"{r.change:.1e}, {r.seconds:.0f} s", flush=True)
    for path in write_re1000_report(runs, folder):
        print(f"wrote {path}")


if __name__ == "__main__":
    main(sys.argv[1:])
