"""One fluid step (advection + implicit viscosity + projection to 1e-6) at 256², 512², 1024².

Case: a jet of speed 1 m/s blowing dyed fluid upwards from the bottom of a 1 m box (no-slip
walls, outflow at the top), water-like viscosity 1e-6 m²/s scaled to 1e-4, dt at CFL 1
(dt = h / 1 m/s). After warm-up steps that let the jet develop, each size is timed over
several steps; reported per step: total ms, ms per phase, pressure CG iterations, viscosity
iterations. Both advection schemes are timed.

Usage: ``python -m benchmarks fluid [--quick]`` or ``python benchmarks/bench_fluid.py``.
Run it with nothing else on the cores: the package lets idle threads spin briefly between
parallel regions (see docs/benchmarks.md), which is fastest alone and slower when shared.
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
    FluidState,
    Jet,
    Outflow,
    WallNoSlip,
)
from elastoflow.grid import Grid2D

PHASES = ("advection", "viscosity", "forces", "pressure")


def _jet_case(n: int, advection: str) -> tuple[FluidSolver, FluidState, float]:
    grid = Grid2D(n, n, 1.0 / n)
    jet = Jet(region=(0.45, 0.0, 0.55, 0.05), velocity=(0.0, 1.0), dye=1.0)
    solver = FluidSolver(
        grid, density=1000.0, viscosity=1e-4,
        boundaries=DomainBoundaries(WallNoSlip(), WallNoSlip(), WallNoSlip(), Outflow()),
        jets=(jet,), advection=advection,
    )
    return solver, FluidState.zeros(grid), grid.h


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    """Run the benchmark, print a Markdown table, write ``results/fluid.json``.

    Args:
        argv: Options; ``--quick`` runs 256² and 512² only, with fewer steps.

    Returns:
        One row per (size, advection scheme).
    """
    args = list(sys.argv[1:] if argv is None else argv)
    quick = "--quick" in args
    sizes = (256, 512) if quick else (256, 512, 1024)
    rows: list[dict[str, Any]] = []
    for advection in ("semi_lagrangian", "maccormack"):
        for n in sizes:
            solver, state, dt = _jet_case(n, advection)
            warm_up = 10 if quick else {256: 60, 512: 40, 1024: 20}[n]
            timed = 5 if quick else {256: 20, 512: 10, 1024: 5}[n]
            for index in range(warm_up):
                solver.step(state, dt, index * dt)
            totals = dict.fromkeys(PHASES, 0.0)
            pressure_iterations = viscosity_iterations = 0
            start = time.perf_counter()
            for index in range(warm_up, warm_up + timed):
                report = solver.step(state, dt, index * dt)
                for phase in PHASES:
                    totals[phase] += report.seconds_by_phase[phase]
                pressure_iterations += report.pressure_iterations
                viscosity_iterations += report.viscosity_iterations
            elapsed = time.perf_counter() - start
            row: dict[str, Any] = {
                "case": "jet_in_box",
                "advection": advection,
                "size": f"{n}x{n}",
                "steps": timed,
                "ms_per_step": 1e3 * elapsed / timed,
                "steps_per_s": timed / elapsed,
            }
            for phase in PHASES:
                row[f"ms_{phase}"] = 1e3 * totals[phase] / timed
            row["pressure_iterations"] = pressure_iterations / timed
            row["viscosity_iterations"] = viscosity_iterations / timed
            row["max_speed"] = float(max(np.abs(state.velocity_x).max(),
                                         np.abs(state.velocity_y).max()))
            rows.append(row)
            print(f"{advection} {n}²: {row['ms_per_step']:.1f} ms/step", flush=True)
    columns = ["advection", "size", "ms_per_step", "ms_advection", "ms_viscosity", "ms_forces",
               "ms_pressure", "pressure_iterations", "viscosity_iterations"]
    print(markdown_table(rows, columns))
    path = write_results("fluid", rows)
    print(f"written {path}")
    return rows


if __name__ == "__main__":
    main()
