"""The coupled scenes at their published settings: steps per second and time by phase.

Cases: the paper's ``bar_in_jet`` (Fig. 6: 256², dt 0.013 s, 35 substeps, 192 elements) and
``windmill`` (Fig. 7: 256², dt 0.05 s, 100 substeps, ~160 elements). Each scene is built,
stepped a few times to compile and settle, then timed over ``--steps`` steps (default 100).
Reported per step: total ms, steps/s, ms per phase (map = boundary map + classification +
InteriorBoundary; advection; viscosity; forces; pressure; coupling_force; solid), pressure
iterations, and the speed-up over the paper's 13.6 and 9.0 steps/s (Core 2 Duo 3.0 GHz).

Usage: ``python -m benchmarks scenes [--steps N] [--quick]``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import markdown_table, write_results

PAPER_STEPS_PER_SECOND = {"bar_in_jet": 13.62, "windmill": 9.0}
PHASES = ("map", "advection", "viscosity", "forces", "pressure", "coupling_force", "solid")


def measure(name: str, steps: int, warmup: int = 10) -> dict[str, Any]:
    """Time ``steps`` coupled steps of the built-in scene ``name`` after ``warmup`` steps."""
    from elastoflow.scenes import build_simulation, get_scene

    simulation = build_simulation(get_scene(name))
    for _ in range(warmup):
        simulation.step()
    totals = dict.fromkeys(PHASES, 0.0)
    iterations = 0
    start = time.perf_counter()
    for _ in range(steps):
        report = simulation.step()
        iterations += report.pressure_iterations
        for phase, seconds in report.seconds_by_phase.items():
            totals[phase] = totals.get(phase, 0.0) + seconds
    elapsed = time.perf_counter() - start
    row: dict[str, Any] = {
        "case": name,
        "grid": f"{simulation.grid.nx}x{simulation.grid.ny}",
        "elements": sum(b.mesh.triangle_count for b in simulation.bodies),
        "substeps": report.substeps[0] if report.substeps else 0,
        "steps": steps,
        "ms_per_step": 1e3 * elapsed / steps,
        "steps_per_s": steps / elapsed,
        "paper_steps_per_s": PAPER_STEPS_PER_SECOND.get(name, float("nan")),
        "pressure_iterations": iterations / steps,
    }
    row["speedup_vs_paper"] = row["steps_per_s"] / row["paper_steps_per_s"]
    for phase in PHASES:
        row[f"{phase}_ms"] = 1e3 * totals.get(phase, 0.0) / steps
    row["map_share"] = totals["map"] / elapsed
    return row


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    """Run the benchmark, print a Markdown table, write ``results/scenes.json``."""
    args = list(sys.argv[1:] if argv is None else argv)
    steps = 30 if "--quick" in args else 100
    if "--steps" in args:
        steps = int(args[args.index("--steps") + 1])
    rows = [measure(name, steps) for name in PAPER_STEPS_PER_SECOND]
    columns = ["case", "grid", "elements", "substeps", "ms_per_step", "steps_per_s",
               "speedup_vs_paper", "pressure_iterations", "map_share",
               *[f"{p}_ms" for p in PHASES]]
    print(markdown_table(rows, columns))
    path = write_results("scenes", rows)
    print(f"\nwrote {path}")
    return rows


if __name__ == "__main__":
    main()
