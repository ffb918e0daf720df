"""The coupled scenes: steps per second, time by phase, peak memory, against the issue's targets.

Cases: the paper's ``bar_in_jet`` (Fig. 6: 256², dt 0.013 s, 35 substeps, 192 elements) and
``windmill`` (Fig. 7: 256², dt 0.05 s, 100 substeps, ~160 elements), and ``large_512``: 512²
with five elastic bars hanging in a wide jet and a circular obstacle below them (momentum
exchange). Each case runs in a fresh process (so that ``ru_maxrss`` is its own peak
memory; this includes the Python, NumPy and Numba runtime, measured alone as ``baseline``),
is stepped a few times to compile and settle, then timed over ``--steps`` steps (default 100).

Reported per step: ms, steps/s, ms per phase (``Simulation.step``'s own clocks: map =
boundary map + classification + InteriorBoundary together; advection; viscosity; forces;
pressure with its MGPCG iterations; coupling_force; solid = FEM), and the map and the
classification timed apart: after each timed step (outside the step's clock) the benchmark
calls ``build_boundary_map`` and ``interior_boundary_from_map`` itself on the simulation's
current boundary arrays. Targets (2-core CPU): bar_in_jet >= 250 steps/s, windmill >= 200,
map + classification < 5 % of a step, peak memory < 300 MB at 512².

Usage: ``python -m benchmarks scenes [--steps N] [--warmup N] [--cases a,b] [--quick]``.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import (
    markdown_table,
    peak_memory_mb,
    run_child,
    versus_target,
    write_results,
)

PAPER_STEPS_PER_SECOND = {"bar_in_jet": 13.62, "windmill": 9.0}
TARGET_STEPS_PER_SECOND = {"bar_in_jet": 250.0, "windmill": 200.0}
TARGET_MAP_SHARE = 0.05
TARGET_MEMORY_MB_512 = 300.0
CASES = ("bar_in_jet", "windmill", "large_512")
PHASES = ("map", "advection", "viscosity", "forces", "pressure", "coupling_force", "solid")


def large_scene(n: int = 512) -> Any:
    """Five rubber bars (4 cm x 36 cm, 120 triangles each) fixed at their tops in a 1 m/s jet
    that spans most of the floor, with a circular obstacle in the jet; ``n``² cells.

    Bar material as in ``bar_in_jet``; dt = 0.0065 s (CFL ~3.3 at 512² for the 1 m/s jet; ~12
    once the flow between the bars has sped up) with 18 FEM substeps (3.6e-4 s, below the bars'
    stable substep of ~4.8e-4 s). Momentum exchange (eq. 8): the relaxed traction (0.05 or 0.1,
    bar density 1100 or 3000) diverged within 10-33 steps at 512²; eq. 8 stays stable for
    150 steps and more.
    """
    from elastoflow.scenes import parse_scene

    bars = []
    for center in (0.18, 0.34, 0.5, 0.66, 0.82):
        x0, x1 = round(center - 0.02, 6), round(center + 0.02, 6)
        bars.append({
            "name": f"bar_{center}",
            "shape": {"type": "rectangle", "box": (x0, 0.44, x1, 0.80), "divisions": (2, 30)},
            "material": {"density": 1100.0, "young_modulus": 6.0e4, "poisson_ratio": 0.3,
                         "damping_lambda": 5.0, "damping_mu": 5.0},
            "fixed": {"box": (x0 - 0.01, 0.795, x1 + 0.01, 0.805)},
        })
    return parse_scene({
        "name": "large_512",
        "domain": {"lx": 1.0, "ly": 1.0, "nx": n},
        "fluid": {"density": 1000.0, "viscosity": 1e-4},
        "boundaries": {"left": "no_slip", "right": "no_slip", "bottom": "no_slip",
                       "top": "outflow"},
        "jets": [{"region": (0.08, 0.04, 0.92, 0.10), "velocity": (0.0, 1.0), "dye": 1.0}],
        "obstacles": [{"shape": "circle", "center": (0.42, 0.26), "radius": 0.05}],
        "bodies": bars,
        "time": {"dt": 0.0065, "steps": 1000, "substeps": 18},
        "coupling": {"scheme": "explicit", "force_model": "momentum_exchange"},
    })


def scene(name: str, size: int | None = None) -> Any:
    """The scene of case ``name`` (``size`` overrides the grid, for quick checks only)."""
    from elastoflow.scenes import get_scene

    if name == "large_512":
        return large_scene(size or 512)
    chosen = get_scene(name)
    if size is not None:
        chosen = chosen.model_copy(update={"domain": chosen.domain.model_copy(
            update={"nx": size, "ny": None})})
    return chosen


def measure(name: str, steps: int, warmup: int = 10, size: int | None = None) -> dict[str, Any]:
    """Time ``steps`` coupled steps of case ``name`` after ``warmup`` steps."""
    from elastoflow.coupling import build_boundary_map, interior_boundary_from_map
    from elastoflow.scenes import build_simulation

    simulation = build_simulation(scene(name, size))
    for _ in range(warmup):
        simulation.step()
    totals = dict.fromkeys(PHASES, 0.0)
    iterations = 0
    stepping = map_seconds = classification_seconds = 0.0
    interior = None
    clock = time.perf_counter
    for _ in range(steps):
        began = clock()
        report = simulation.step()
        stepping += clock() - began
        iterations += report.pressure_iterations
        for phase, seconds in report.seconds_by_phase.items():
            totals[phase] = totals.get(phase, 0.0) + seconds
        # The split the step's own clock does not make: the same calls, on the same state,
        # into this benchmark's own buffers (the simulation is not touched).
        points, velocities, edges, edge_body = simulation.model.boundary_points(
            simulation.state)
        began = clock()
        bmap = build_boundary_map(simulation.grid, points, velocities, edges, edge_body)
        map_seconds += clock() - began
        began = clock()
        interior = interior_boundary_from_map(simulation.grid, bmap, out=interior)
        classification_seconds += clock() - began
    ms_per_step = 1e3 * stepping / steps
    row: dict[str, Any] = {
        "case": name,
        "grid": f"{simulation.grid.nx}x{simulation.grid.ny}",
        "bodies": len(simulation.bodies),
        "obstacles": len(simulation.obstacles),
        "elements": sum(b.mesh.triangle_count for b in simulation.bodies),
        "substeps": report.substeps[0] if report.substeps else 0,
        "steps": steps,
        "ms_per_step": ms_per_step,
        "steps_per_s": steps / stepping,
        "paper_steps_per_s": PAPER_STEPS_PER_SECOND.get(name, float("nan")),
        "pressure_iterations": iterations / steps,
    }
    row["speedup_vs_paper"] = row["steps_per_s"] / row["paper_steps_per_s"]
    for phase in PHASES:
        row[f"{phase}_ms"] = 1e3 * totals.get(phase, 0.0) / steps
    row["map_share"] = row["map_ms"] / ms_per_step
    row["boundary_map_ms"] = 1e3 * map_seconds / steps
    row["classification_ms"] = 1e3 * classification_seconds / steps
    row["boundary_map_share"] = row["boundary_map_ms"] / ms_per_step
    row["classification_share"] = row["classification_ms"] / ms_per_step
    return row


def _child(args: list[str]) -> None:
    """``--child CASE``: one case in this process; prints its row as JSON on the last line."""
    name = args[args.index("--child") + 1]
    if name == "baseline":
        import numba  # noqa: F401 - the runtime every case carries

        import elastoflow.coupling
        import elastoflow.scenes
        import elastoflow.simulation  # noqa: F401

        row: dict[str, Any] = {"case": "baseline (imports only)"}
    else:
        size = int(args[args.index("--size") + 1]) if "--size" in args else None
        row = measure(name, int(args[args.index("--steps") + 1]),
                      int(args[args.index("--warmup") + 1]), size)
    row["peak_memory_mb"] = peak_memory_mb()
    print(json.dumps(row))


def _add_targets(row: dict[str, Any]) -> None:
    target = TARGET_STEPS_PER_SECOND.get(row["case"])
    row["target_steps_per_s"] = target if target else "-"
    row["steps_per_s_vs_target"] = (versus_target(row["steps_per_s"], target, at_most=False)
                                    if target else "-")
    share = row["boundary_map_share"] + row["classification_share"]
    row["map_and_classification_share"] = share
    row["share_vs_5pct"] = versus_target(share, TARGET_MAP_SHARE, at_most=True)
    row["step_map_share_vs_5pct"] = versus_target(row["map_share"], TARGET_MAP_SHARE,
                                                  at_most=True)
    row["memory_vs_300mb"] = (versus_target(row["peak_memory_mb"], TARGET_MEMORY_MB_512,
                                            at_most=True)
                              if row["grid"].startswith("512") else "-")


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    """Run the benchmark, print Markdown tables, write ``results/scenes.json``.

    Args:
        argv: ``--steps N`` timed steps (default 100, 30 with ``--quick``), ``--warmup N``
            (default 10), ``--cases a,b`` (default all), ``--size N`` (grid override, for
            smoke tests only).
    """
    args = list(sys.argv[1:] if argv is None else argv)
    if "--child" in args:
        _child(args)
        return []
    steps = 30 if "--quick" in args else 100
    if "--steps" in args:
        steps = int(args[args.index("--steps") + 1])
    warmup = int(args[args.index("--warmup") + 1]) if "--warmup" in args else 10
    cases = args[args.index("--cases") + 1].split(",") if "--cases" in args else list(CASES)
    extra = ["--size", args[args.index("--size") + 1]] if "--size" in args else []
    baseline = run_child("benchmarks.bench_scenes", ["--child", "baseline"])
    rows = []
    for name in cases:
        row = run_child("benchmarks.bench_scenes", ["--child", name, "--steps", str(steps),
                                                    "--warmup", str(warmup), *extra])
        _add_targets(row)
        rows.append(row)
        print(f"{name}: {row['ms_per_step']:.2f} ms/step", flush=True)
    print(markdown_table(rows, [
        "case", "grid", "bodies", "elements", "substeps", "ms_per_step", "steps_per_s",
        "target_steps_per_s", "steps_per_s_vs_target", "speedup_vs_paper",
        "pressure_iterations", "peak_memory_mb", "memory_vs_300mb"]))
    print()
    print(markdown_table(rows, ["case", *[f"{p}_ms" for p in PHASES]]))
    print()
    print(markdown_table(rows, [
        "case", "boundary_map_ms", "classification_ms", "boundary_map_share",
        "classification_share", "map_and_classification_share", "share_vs_5pct", "map_ms",
        "map_share", "step_map_share_vs_5pct"]))
    print(f"\nbaseline peak memory (Python + NumPy + Numba + elastoflow imported, nothing "
          f"built): {baseline['peak_memory_mb']:.1f} MB")
    path = write_results("scenes", [*rows, baseline])
    print(f"\nwrote {path}")
    return rows


if __name__ == "__main__":
    main()
