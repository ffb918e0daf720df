"""The free-surface step: the `dam_break` scene as it runs, and against the single-phase step.

Case: the library's `dam_break` scene (Martin & Moyce's column, a = 2.25 in, 2 a tall, in a
tank 8 a x 4 a, 256x128 cells, water, no-slip walls, MacCormack velocity advection with the
free surface's wall-and-air fallback, the level set redistanced every step, the scene's
fixed dt = 1/1677 s), loaded with `elastoflow.load` as a user would.

Two measurements, CPU time (both threads) beside wall time, because the 2-core machine is
shared and wall times follow the load:

* the scene stepped to t = 1 s (1677 steps; ``--quick``: 300): ms per step, steps/s;
* the free-surface step against the single-phase step of the same solver options on the same
  grid (`FluidSolver.step`, from the dam break's velocity with the whole box full of water),
  at two moments: after 300 steps (the surge on the floor: the liquid's bounding box, on
  which the pressure is solved, is a quarter of the grid) and after 800 (the run-up on the
  far wall: the box is the whole grid, the worst case). Rounds of 100 steps (``--quick``:
  20) alternate the two steps so that both see the same load; medians of the rounds.

Usage: ``python -m benchmarks free_surface [--quick]`` or
``python benchmarks/bench_free_surface.py``. Run it with nothing else on the cores.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import elastoflow
from benchmarks._common import markdown_table, write_results
from elastoflow.scenes import get_scene

PHASES = ("level_set", "advection", "viscosity", "forces", "pressure", "extrapolation")


def _load_average() -> float:
    try:
        return os.getloadavg()[0]
    except OSError:
        return float("nan")


def _scene_row(steps: int | None) -> dict[str, Any]:
    """The scene from t = 0 for ``steps`` steps (None: to t = 1 s), after one warm-up step."""
    simulation = elastoflow.load(get_scene("dam_break"))
    simulation.step()
    iterations = []
    totals = dict.fromkeys(PHASES, 0.0)
    loads = [_load_average()]
    cpu, wall = time.process_time(), time.perf_counter()
    while (simulation.time < 1.0 - 1e-12) if steps is None else (len(iterations) < steps):
        report = simulation.step()
        iterations.append(report.pressure_iterations)
        for phase in PHASES:
            totals[phase] += report.seconds_by_phase.get(phase, 0.0)
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    loads.append(_load_average())
    count = len(iterations)
    row: dict[str, Any] = {
        "case": f"dam_break scene, {count} steps to t = {simulation.time:.3f} s",
        "steps": count, "ms_per_step": 1e3 * wall / count, "steps_per_s": count / wall,
        "cpu_ms_per_step": 1e3 * cpu / count, "pressure_iterations": float(np.mean(iterations)),
        "load_average": f"{min(loads):.1f}-{max(loads):.1f}",
    }
    for phase in PHASES:
        row[f"ms_{phase}"] = 1e3 * totals[phase] / count
    return row


def _ratio_rows(warm_up: int, rounds: int, steps: int) -> list[dict[str, Any]]:
    """Free-surface and single-phase steps alternating in rounds, after ``warm_up`` steps."""
    simulation = elastoflow.load(get_scene("dam_break"))
    simulation.run(warm_up)
    single_solver = elastoflow.load(get_scene("dam_break")).fluid_solver
    fluid = simulation.state.fluid.copy()
    dt = simulation.dt
    for _ in range(3):
        single_solver.step(fluid, dt, 0.0)
    measured: dict[str, list[tuple[float, float]]] = {"free_surface": [], "single_phase": []}
    iterations: dict[str, list[int]] = {"free_surface": [], "single_phase": []}
    loads = [_load_average()]
    for _ in range(rounds):
        cpu, wall = time.process_time(), time.perf_counter()
        for _ in range(steps):
            iterations["free_surface"].append(simulation.step().pressure_iterations)
        measured["free_surface"].append((time.process_time() - cpu, time.perf_counter() - wall))
        cpu, wall = time.process_time(), time.perf_counter()
        for _ in range(steps):
            iterations["single_phase"].append(single_solver.step(fluid, dt, 0.0)
                                              .pressure_iterations)
        measured["single_phase"].append((time.process_time() - cpu, time.perf_counter() - wall))
    loads.append(_load_average())
    rows = []
    for case, values in measured.items():
        cpu = float(np.median([value[0] for value in values])) / steps
        wall = float(np.median([value[1] for value in values])) / steps
        rows.append({
            "case": f"{case}, steps {warm_up}-{warm_up + rounds * steps}",
            "steps": rounds * steps, "ms_per_step": 1e3 * wall, "steps_per_s": 1.0 / wall,
            "cpu_ms_per_step": 1e3 * cpu,
            "pressure_iterations": float(np.mean(iterations[case])),
            "load_average": f"{min(loads):.1f}-{max(loads):.1f}",
        })
    rows[0]["ratio_cpu"] = rows[0]["cpu_ms_per_step"] / rows[1]["cpu_ms_per_step"]
    rows[0]["ratio_wall"] = rows[0]["ms_per_step"] / rows[1]["ms_per_step"]
    return rows


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    """Run the benchmark, print a Markdown table, write ``results/free_surface.json``.

    Args:
        argv: Options; ``--quick`` times fewer steps.

    Returns:
        The scene's row, then a free-surface and a single-phase row per moment.
    """
    args = list(sys.argv[1:] if argv is None else argv)
    quick = "--quick" in args
    rows = [_scene_row(300 if quick else None)]
    rounds, steps = (1, 20) if quick else (3, 100)
    for warm_up in (300, 800):
        rows += _ratio_rows(warm_up, rounds, steps)
    columns = ["case", "ms_per_step", "steps_per_s", "cpu_ms_per_step", "pressure_iterations",
               "ratio_cpu", "ratio_wall", "load_average"]
    for row in rows:
        for column in columns:
            row.setdefault(column, "")
    print(markdown_table(rows, columns))
    print("phases of the scene's step (ms, wall): " + ", ".join(
        f"{phase} {rows[0][f'ms_{phase}']:.2f}" for phase in PHASES))
    path = write_results("free_surface", rows)
    print(f"written {path}")
    return rows


if __name__ == "__main__":
    main()
