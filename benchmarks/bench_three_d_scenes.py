"""Coupled steps of the 3D library scenes, with the time of each phase.

Each scene runs in its own process: a few warm-up steps, then ``--steps`` timed ones (default
10; ``--quick``: 2 after 1 warm-up, on the scene's grid coarsened to ``--size`` cells along x
when given, for smoke tests only). Reported per step: wall ms and its fastest step, the
process's CPU ms (all threads: on shared cores the wall time also measures the others' load),
the phases the step's clock splits (map and interior, advection, forces, viscosity,
pressure, the traction force, the bodies' substeps), the 1-minute load average, and against
issue 16's target for ``bar_in_jet_3d`` (20 coupled steps/s at 64³ on the 2-core machine).

Usage: ``python -m benchmarks three_d_scenes [--steps N] [--cases a,b] [--quick]``.
Run it with nothing else on the cores (docs/benchmarks.md).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import markdown_table, write_results

CASES = ("bar_in_jet_3d", "sphere_drag", "flag_3d", "sphere_settling", "elastic_block_3d")
PHASES = ("map", "advection", "forces", "viscosity", "pressure", "coupling_force", "solid")
TARGET_STEPS_PER_SECOND = {"bar_in_jet_3d": 20.0}
ROOT = Path(__file__).resolve().parent.parent


def measure(name: str, warm_up: int, timed: int, size: int | None = None) -> dict[str, Any]:
    """Time ``timed`` coupled steps of the library scene ``name`` after ``warm_up`` ones."""
    import tomllib

    from elastoflow.scenes import build_simulation, get_scene, parse_scene, scene_to_toml

    scene = get_scene(name)
    if size is not None:
        data = tomllib.loads(scene_to_toml(scene))
        domain = data["domain"]
        domain.pop("nx", None)
        domain["h"] = domain["lx"] / size
        scene = parse_scene(data, source=f"{name} at nx = {size}")
    simulation = build_simulation(scene, warnings=[])
    for _ in range(warm_up):
        simulation.step()
    totals = dict.fromkeys(PHASES, 0.0)
    iterations = 0
    fastest = float("inf")
    load_start = os.getloadavg()[0]
    cpu_start = time.process_time()
    wall_start = time.perf_counter()
    for _ in range(timed):
        began = time.perf_counter()
        report = simulation.step()
        fastest = min(fastest, time.perf_counter() - began)
        iterations += report.pressure_iterations
        for phase, seconds in report.seconds_by_phase.items():
            totals[phase] = totals.get(phase, 0.0) + seconds
    wall = time.perf_counter() - wall_start
    cpu = time.process_time() - cpu_start
    grid = simulation.grid
    row: dict[str, Any] = {
        "case": name,
        "grid": "x".join(str(n) for n in grid.shape_cells),
        "tetrahedra": sum(body.mesh.tetrahedron_count for body in simulation.bodies),
        "obstacles": len(simulation.obstacles),
        "substeps": report.substeps[0] if report.substeps else 0,
        "ms_per_step": 1e3 * wall / timed,
        "ms_per_step_min": 1e3 * fastest,
        "cpu_ms_per_step": 1e3 * cpu / timed,
        "steps_per_s": timed / wall,
        "pressure_iterations": iterations / timed,
        "load_average_1min": f"{load_start:.1f}-{os.getloadavg()[0]:.1f}",
    }
    for phase in PHASES:
        row[f"ms_{phase}"] = 1e3 * totals.get(phase, 0.0) / timed
    target = TARGET_STEPS_PER_SECOND.get(name)
    row["target_steps_per_s"] = target if target is not None else float("nan")
    return row


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    """Run the benchmark, print Markdown tables, write ``results/three_d_scenes.json``."""
    args = list(sys.argv[1:] if argv is None else argv)
    quick = "--quick" in args
    warm_up, timed = (1, 2) if quick else (3, 10)
    if "--steps" in args:
        timed = int(args[args.index("--steps") + 1])
    cases = args[args.index("--cases") + 1].split(",") if "--cases" in args else list(CASES)
    size = int(args[args.index("--size") + 1]) if "--size" in args else None
    rows: list[dict[str, Any]] = []
    for name in cases:
        code = ("import json; from benchmarks.bench_three_d_scenes import measure; "
                f"print(json.dumps(measure({name!r}, {warm_up}, {timed}, {size!r})))")
        output = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                                text=True, check=True).stdout
        row = json.loads(output.strip().splitlines()[-1])
        rows.append(row)
        print(f"{name}: {row['ms_per_step']:.0f} ms/step ({row['steps_per_s']:.2f} steps/s)",
              flush=True)
    print(markdown_table(rows, ["case", "grid", "tetrahedra", "obstacles", "substeps",
                                "ms_per_step", "ms_per_step_min", "cpu_ms_per_step",
                                "steps_per_s", "target_steps_per_s", "pressure_iterations",
                                "load_average_1min"]))
    print()
    print(markdown_table(rows, ["case", *[f"ms_{phase}" for phase in PHASES]]))
    path = write_results("three_d_scenes", rows)
    print(f"written {path}")
    return rows


if __name__ == "__main__":
    main()
