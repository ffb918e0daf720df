"""One 3D fluid step (advection + implicit viscosity + projection to 1e-6) at 32³, 64³, 128³.

Case: a square channel of side 1 m along x, parabolic inflow of peak speed 1 m/s on the left,
outflow on the right, no-slip walls, density 1000 kg/m³, viscosity 1e-4 m²/s, dt at CFL 1
(dt = h / 1 m/s), started from `FluidSolver3D.rest_state()`. After warm-up steps each size is
timed over a few steps; reported per step: total ms, ms per phase, ns per cell, the process's
CPU time (all threads: on shared cores the wall time measures the others' load too), the
fastest step, the 1-minute load average when timing started and ended, the Numba thread
count, pressure and viscosity iterations; and the process's peak resident memory above its
level after a 16³ warm-up run (Numba kernels loaded), per million cells. Each size runs in its own process, so
that the peaks do not mix.

Usage: ``python -m benchmarks three_d [--quick]`` (``--quick``: 32³ and 64³ only).
Run it with nothing else on the cores (see docs/benchmarks.md).
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import markdown_table, write_results

PHASES = ("advection", "forces", "viscosity", "pressure")
ROOT = Path(__file__).resolve().parent.parent


def _resident_mb() -> float:
    """Current resident set size [MB] (Linux)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return float(line.split()[1]) / 1024.0
    return float("nan")


def _channel(n: int, advection: str) -> tuple[Any, Any, float]:
    from elastoflow.fluid._boundaries import Inflow
    from elastoflow.fluid._boundaries3d import DomainBoundaries3D
    from elastoflow.fluid._solver3d import FluidSolver3D
    from elastoflow.grid import Grid3D

    grid = Grid3D(n, n, n, 1.0 / n)
    solver = FluidSolver3D(
        grid, density=1000.0, viscosity=1e-4,
        boundaries=DomainBoundaries3D.channel(Inflow(1.0, profile="parabolic")),
        advection=advection,
    )
    return solver, solver.rest_state(), grid.h


def measure(n: int, advection: str, warm_up: int, timed: int) -> dict[str, Any]:
    """Time ``timed`` steps at ``n``³ after ``warm_up`` steps (run in a fresh process)."""
    from numba import get_num_threads

    solver, state, dt = _channel(16, advection)
    solver.step(state, dt)
    baseline = _resident_mb()
    solver, state, dt = _channel(n, advection)
    for index in range(warm_up):
        solver.step(state, dt, index * dt)
    totals = dict.fromkeys(PHASES, 0.0)
    pressure_iterations = viscosity_iterations = 0
    load = os.getloadavg()[0]
    start = time.perf_counter()
    cpu_start = time.process_time()
    step_seconds = []
    for index in range(warm_up, warm_up + timed):
        step_start = time.perf_counter()
        report = solver.step(state, dt, index * dt)
        step_seconds.append(time.perf_counter() - step_start)
        for phase in PHASES:
            totals[phase] += report.seconds_by_phase[phase]
        pressure_iterations += report.pressure_iterations
        viscosity_iterations += report.viscosity_iterations
    elapsed = time.perf_counter() - start
    cpu = time.process_time() - cpu_start
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    cells = n**3
    row: dict[str, Any] = {
        "case": "channel_3d", "advection": advection, "size": f"{n}^3", "cells": cells,
        "steps": timed, "ms_per_step": 1e3 * elapsed / timed,
        "ns_per_cell": 1e9 * elapsed / timed / cells,
        # CPU time of all threads: on cores shared with other work the wall time measures
        # the load as much as the code; this measures the work.
        "cpu_ms_per_step": 1e3 * cpu / timed, "load_average_1min": load,
        # The fastest step: the least disturbed by other work on shared cores.
        "ms_per_step_min": 1e3 * min(step_seconds),
        "load_average_1min_end": os.getloadavg()[0], "numba_threads": get_num_threads(),
    }
    for phase in PHASES:
        row[f"ms_{phase}"] = 1e3 * totals[phase] / timed
    row["pressure_iterations"] = pressure_iterations / timed
    row["viscosity_iterations"] = viscosity_iterations / timed
    row["peak_mb"] = peak - baseline
    row["mb_per_million_cells"] = (peak - baseline) / (cells / 1e6)
    return row


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    """Run the benchmark, print a Markdown table, write ``results/three_d.json``."""
    args = list(sys.argv[1:] if argv is None else argv)
    quick = "--quick" in args
    sizes = (32, 64) if quick else (32, 64, 128)
    rows: list[dict[str, Any]] = []
    for n in sizes:
        warm_up, timed = {32: (5, 10), 64: (3, 5), 128: (2, 3)}[n]
        code = ("import json, sys; from benchmarks.bench_three_d import measure; "
                f"print(json.dumps(measure({n}, 'semi_lagrangian', {warm_up}, {timed})))")
        output = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                                text=True, check=True).stdout
        row = json.loads(output.strip().splitlines()[-1])
        rows.append(row)
        print(f"{n}³: {row['ms_per_step']:.1f} ms/step, {row['ns_per_cell']:.0f} ns/cell, "
              f"{row['mb_per_million_cells']:.0f} MB per million cells", flush=True)
    columns = ["size", "ms_per_step", "ms_per_step_min", "cpu_ms_per_step", "load_average_1min",
               "ns_per_cell", "ms_advection", "ms_viscosity", "ms_pressure",
               "pressure_iterations", "viscosity_iterations", "peak_mb", "mb_per_million_cells"]
    print(markdown_table(rows, columns))
    path = write_results("three_d", rows)
    print(f"written {path}")
    return rows


if __name__ == "__main__":
    main()
