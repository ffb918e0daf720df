"""The free-surface step: a dam break at 256x128, and the same grid's single-phase step.

Case: Martin & Moyce's column (width a = 2.25 in, height 2 a) in a tank 8 a long and 4 a tall,
h = a / 32 (256x128 cells), water (nu = 1e-6, no-slip walls), semi-Lagrangian velocity
advection (chosen when the fluid's MacCormack step gained energy next to a free surface; the
free surface's MacCormack with its fallback, the scenes' default since, is not timed here;
the level set keeps MacCormack), dt at CFL 0.8 from the fastest face (at most
sqrt(0.8 h / g)). After warm-up steps that let the column
start falling, steps are timed; reported per step: total ms, ms per phase, pressure
iterations. The single-phase row is `FluidSolver.step` on the same grid, same solver options,
from the dam break's velocity with the whole box full of water (no level set, no
extrapolation, the open-box pressure operator): what the free surface adds. The two steps
alternate in the timed loop (each free-surface step followed by a single-phase one), so that
both see the same load on shared cores; ms per step are medians, phases means.

Usage: ``python -m benchmarks free_surface [--quick]`` or
``python benchmarks/bench_free_surface.py``. Run it with nothing else on the cores.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import markdown_table, write_results
from elastoflow.fluid import (
    DomainBoundaries,
    FluidSolver,
    FreeSurfaceSolver,
    level_set_box,
)
from elastoflow.grid import Grid2D

PHASES = ("level_set", "advection", "viscosity", "forces", "pressure", "extrapolation")
A = 2.25 * 0.0254


def _solvers(cells_per_width: int) -> tuple[FreeSurfaceSolver, FluidSolver]:
    h = A / cells_per_width
    grid = Grid2D(8 * cells_per_width, 4 * cells_per_width, h)

    def fluid() -> FluidSolver:
        return FluidSolver(grid, density=1000.0, viscosity=1e-6,
                           boundaries=DomainBoundaries.closed_box(), gravity=(0.0, -9.81),
                           advection="semi_lagrangian")

    return FreeSurfaceSolver(fluid()), fluid()


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    """Run the benchmark, print a Markdown table, write ``results/free_surface.json``.

    Args:
        argv: Options; ``--quick`` times fewer steps.

    Returns:
        One row for the free-surface step, one for the single-phase step.
    """
    args = list(sys.argv[1:] if argv is None else argv)
    quick = "--quick" in args
    warm_up, timed = (10, 20) if quick else (40, 100)
    solver, single = _solvers(32)
    grid = solver.grid
    state = solver.state(level_set_box(grid, (0.0, 0.0, A, 2 * A)))
    t = 0.0
    for _ in range(warm_up):
        dt = solver.stable_dt(state, 0.8, 1.0)
        solver.step(state, dt, t)
        t += dt
    # The single-phase step runs on the same grid from the dam break's velocity, the two
    # steps alternating, so that both see the same load on shared cores; per-step medians.
    fluid_state = state.fluid.copy()
    for _ in range(warm_up // 4):
        single.step(fluid_state, solver.stable_dt(state, 0.8, 1.0), 0.0)
    totals = dict.fromkeys(PHASES, 0.0)
    single_phases = ("advection", "viscosity", "forces", "pressure")
    single_totals = dict.fromkeys(single_phases, 0.0)
    iterations = single_iterations = 0
    free_seconds, single_seconds = [], []
    for _ in range(timed):
        dt = solver.stable_dt(state, 0.8, 1.0)
        before = time.perf_counter()
        report = solver.step(state, dt, t)
        free_seconds.append(time.perf_counter() - before)
        t += dt
        for phase in PHASES:
            totals[phase] += report.seconds_by_phase[phase]
        iterations += report.pressure_iterations
        before = time.perf_counter()
        single_report = single.step(fluid_state, dt, 0.0)
        single_seconds.append(time.perf_counter() - before)
        for phase in single_phases:
            single_totals[phase] += single_report.seconds_by_phase[phase]
        single_iterations += single_report.pressure_iterations
    rows: list[dict[str, Any]] = []
    row: dict[str, Any] = {
        "case": "dam_break", "size": f"{grid.nx}x{grid.ny}", "steps": timed,
        "ms_per_step": 1e3 * float(np.median(free_seconds)),
        "steps_per_s": 1.0 / float(np.median(free_seconds)),
        "pressure_iterations": iterations / timed, "simulated_time": t,
    }
    for phase in PHASES:
        row[f"ms_{phase}"] = 1e3 * totals[phase] / timed
    rows.append(row)
    row = {
        "case": "single_phase", "size": f"{grid.nx}x{grid.ny}", "steps": timed,
        "ms_per_step": 1e3 * float(np.median(single_seconds)),
        "steps_per_s": 1.0 / float(np.median(single_seconds)),
        "pressure_iterations": single_iterations / timed,
    }
    for phase in single_phases:
        row[f"ms_{phase}"] = 1e3 * single_totals[phase] / timed
    rows.append(row)
    ratio = rows[0]["ms_per_step"] / rows[1]["ms_per_step"]
    rows[0]["ratio_to_single_phase"] = ratio
    columns = ["case", "size", "ms_per_step", "steps_per_s", "ms_level_set", "ms_advection",
               "ms_viscosity", "ms_pressure", "ms_extrapolation", "pressure_iterations"]
    print(markdown_table(rows, columns))
    print(f"free-surface step / single-phase step: {ratio:.2f}")
    path = write_results("free_surface", rows)
    print(f"written {path}")
    return rows


if __name__ == "__main__":
    main()
