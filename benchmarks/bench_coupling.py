"""Cost of the coupling schemes on the paper's scenes: explicit (relaxed) against monolithic.

``python -m benchmarks coupling [--quick] [--steps N] [--size N] [--scenes=bar_in_jet,windmill]``:
for each scene and scheme, ms per coupled step and per phase, and pressure iterations, over
``steps`` steps after a warm-up, both schemes in the same process, stepped in alternating
blocks (kernels compiled before timing). ``--size`` sets the cells along x (default: each
scene's own). Target (issue 12): the monolithic step at most 1.5x the explicit one.
"""

from __future__ import annotations

import sys
import time
from typing import Any

from benchmarks._common import markdown_table, versus_target, write_results

TARGET_RATIO = 1.5


def _simulation(scheme: str, size: int | None, name: str = "bar_in_jet") -> Any:
    import elastoflow
    from elastoflow.scenes import CouplingSpec, get_scene

    scene = get_scene(name)
    coupling = (CouplingSpec(scheme="explicit", force_model="traction", force_relaxation=0.1)
                if scheme == "explicit" else CouplingSpec(scheme="monolithic"))
    update: dict[str, Any] = {"coupling": coupling}
    if size is not None:
        update["domain"] = scene.domain.model_copy(update={"nx": size})
    return elastoflow.load(scene.model_copy(update=update))


def measure(steps: int, warmup: int, size: int | None, block: int = 10,
            name: str = "bar_in_jet") -> list[dict[str, Any]]:
    """Both schemes, stepped in alternating blocks of ``block`` steps so that they see the
    same machine load (timed one after the other, a load that came or went between the two
    halves moved the ratio between 1.25 and 2.08 within a minute)."""
    schemes = ("explicit", "monolithic")
    simulations = {scheme: _simulation(scheme, size, name) for scheme in schemes}
    for simulation in simulations.values():
        for _ in range(warmup):
            simulation.step()
    phases: dict[str, dict[str, float]] = {scheme: {} for scheme in schemes}
    iterations = dict.fromkeys(schemes, 0)
    elapsed = dict.fromkeys(schemes, 0.0)
    done = 0
    while done < steps:
        count = min(block, steps - done)
        for scheme in schemes:
            simulation = simulations[scheme]
            start = time.perf_counter()
            for _ in range(count):
                report = simulation.step()
                iterations[scheme] += report.pressure_iterations
                for phase, seconds in report.seconds_by_phase.items():
                    phases[scheme][phase] = phases[scheme].get(phase, 0.0) + seconds
            elapsed[scheme] += time.perf_counter() - start
        done += count
    rows = []
    for scheme in schemes:
        row: dict[str, Any] = {
            "case": f"{name} {scheme}", "size": simulations[scheme].grid.nx, "steps": steps,
            "ms_per_step": 1e3 * elapsed[scheme] / steps,
            "pressure_iterations": iterations[scheme] / steps,
        }
        for phase in ("advection", "viscosity", "pressure", "solid", "map", "coupling_force"):
            row[f"ms_{phase}"] = 1e3 * phases[scheme].get(phase, 0.0) / steps
        rows.append(row)
    return rows


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    """Run the benchmark, print a Markdown table, write ``results/coupling.json``."""
    args = list(sys.argv[1:] if argv is None else argv)
    quick = "--quick" in args
    steps = int(args[args.index("--steps") + 1]) if "--steps" in args else (20 if quick else 200)
    size = int(args[args.index("--size") + 1]) if "--size" in args else None
    scenes = ["bar_in_jet", "windmill"]
    for arg in args:
        if arg.startswith("--scenes="):
            scenes = arg.split("=", 1)[1].split(",")
    warmup = 3 if quick else 20
    rows = []
    for name in scenes:
        pair = measure(steps, warmup, size, name=name)
        ratio = pair[1]["ms_per_step"] / pair[0]["ms_per_step"]
        pair[1]["ratio_to_explicit"] = ratio
        pair[1]["target_ratio"] = TARGET_RATIO
        pair[1]["vs_target"] = versus_target(ratio, TARGET_RATIO, at_most=True)
        rows += pair
    print(markdown_table(rows, [
        "case", "size", "ms_per_step", "pressure_iterations", "ms_advection", "ms_viscosity",
        "ms_pressure", "ms_solid", "ms_map", "ms_coupling_force", "ratio_to_explicit",
        "target_ratio", "vs_target"]))
    path = write_results("coupling", rows)
    print(f"\nwrote {path}")
    return rows


if __name__ == "__main__":
    main()
