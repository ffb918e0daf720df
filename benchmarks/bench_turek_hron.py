"""Turek-Hron study: every case at the chosen resolutions, quantities, run time and plots.

``python -m benchmarks turek_hron [--cases=FSI2,FSI3] [--resolutions=10,20] [--name=NAME]
[--quick] [--speed]`` writes ``benchmarks/results/NAME.json`` (default turek_hron; one row per run), and per run the plots and
quantities into ``docs/validation/turek-hron/`` (``<case>_n<N>.png`` / ``.json``) and the time
series into ``out/validation/`` (CSV, not kept in the repository). docs/validation/turek-hron.md
is written from these. ``--quick``: CFD1, CSM1 and FSI1 at N = 10 over 2 s (a smoke test). ``--reevaluate``: no runs;
the quantities, plots and JSON again from the time series in ``out/validation`` (after a
change to the evaluation). ``--speed``: no whole runs; per FSI case and resolution (default
FSI2 and FSI3 at N = 20) the cost of a step after ``--warmup`` steps (default 30), over
``--steps`` timed steps (default 200) with the traction probe every step as a run takes it,
split by phase, and the wall time that projects to t = 10 s (issue 12's headline:
``benchmarks/results/turek_hron_speed.json``). The first steps after rest cost less than the
developed oscillation (FSI3 at N = 20: 30.6 ms a step over steps 30-230, 47 ms on average
over a whole run), so the projection is a lower bound; the whole run's wall time
(``--cases=FSI3 --resolutions=20``) is the headline. ``--deflection``: no FSI runs; CFD1 with
its rigid flag bent into the cantilever's shape by ``--tips`` (mm at the trailing edge; per
resolution ``--tips-N=...`` overrides) at ``--resolutions`` (default 10,20,40) over
``--duration`` s (default 8): the lift on cylinder and flag and on the flag alone against the
deflection, which FSI1's steady u_y(A) balances (``benchmarks/results/turek_hron_deflection.json``).
``--placement``: ``--cases`` (default FSI1) at ``--resolutions`` (default 10,20), each on grids
of about the same h that place the flag differently: ``--cells-N=k1,k2,...`` cells across the
height (default: `cells_across` (N) - 3 to + 4, multiples of 41 left out), ``--duration``
(default the case's), ``--layers`` (default the case's); the final quantities per grid and
their mean, spread and standard deviation per resolution
(``benchmarks/results/turek_hron_placement.json``).
"""

from __future__ import annotations

import shutil
import time
from pathlib import Path
from typing import Any

import json

import numpy as np

from benchmarks._common import machine, markdown_table, write_results

DOCS = Path(__file__).resolve().parent.parent / "docs" / "validation" / "turek-hron"
SERIES = Path("out") / "validation"


def _option(argv: list[str], name: str, default: str) -> str:
    for item in argv:
        if item.startswith(f"--{name}="):
            return item.split("=", 1)[1]
    return default


def _reevaluate(name: str, resolution: int) -> Any:
    """A `Result` rebuilt from the CSV and JSON of an earlier run of this case."""
    from elastoflow.validation import default_setup, get_case
    from elastoflow.validation._turek_hron import evaluate

    stem = SERIES / f"{name.lower()}_n{resolution}"
    saved = json.loads(stem.with_suffix(".json").read_text())
    data = np.atleast_2d(np.loadtxt(stem.with_suffix(".csv"), delimiter=",", skiprows=1))
    case = get_case(name)
    setup = default_setup(case, resolution, duration=saved["duration"], dt=saved["dt"],
                          incremental_pressure=saved.get("incremental_pressure", False))
    # Records from before the CFD cases' balance columns hold the first quantities only.
    series = {key: data[:, k + 1] for k, key in enumerate(case.quantities)
              if k + 1 < data.shape[1]}
    cells = tuple(saved["cells"]) if saved["cells"] else None
    return evaluate(setup, data[:, 0], series, saved["wall_seconds"], cells,
                    saved["flag_elements"], saved["steps"])


TARGET_MINUTES = 10.0


def speed(argv: list[str]) -> list[dict[str, Any]]:
    """ms per coupled step of the FSI cases and the projected wall time to t = 10 s."""
    from elastoflow.validation import default_setup, get_case
    from elastoflow.validation._turek_hron import case_simulation

    from benchmarks._common import versus_target

    cases = _option(argv, "cases", "FSI2,FSI3").split(",")
    resolutions = [int(v) for v in _option(argv, "resolutions", "20").split(",")]
    warmup = int(_option(argv, "warmup", "30"))
    steps = int(_option(argv, "steps", "200"))
    rows: list[dict[str, Any]] = []
    for name in cases:
        for resolution in resolutions:
            setup = default_setup(get_case(name), resolution)
            simulation, _ = case_simulation(setup)
            for _ in range(warmup):
                simulation.step()
                simulation.traction_forces()
            phases: dict[str, float] = {}
            iterations = 0
            began = time.perf_counter()
            for _ in range(steps):
                report = simulation.step()
                simulation.traction_forces()
                iterations += report.pressure_iterations
                for phase, seconds in report.seconds_by_phase.items():
                    phases[phase] = phases.get(phase, 0.0) + seconds
            per_step = (time.perf_counter() - began) / steps
            to_ten = round(10.0 / setup.dt)
            minutes = per_step * to_ten / 60.0
            row: dict[str, Any] = {
                "case": name, "N": resolution,
                "grid": f"{simulation.grid.nx}x{simulation.grid.ny}", "dt [s]": setup.dt,
                "ms per step": 1e3 * per_step, "steps to t = 10 s": to_ten,
                "projected minutes to t = 10 s": minutes,
                "CG iterations": iterations / steps,
                "vs target": versus_target(minutes, TARGET_MINUTES, at_most=True),
            }
            for phase in ("advection", "viscosity", "pressure", "solid", "map",
                          "coupling_force"):
                row[f"ms {phase}"] = 1e3 * phases.get(phase, 0.0) / steps
            rows.append(row)
            print(f"{name} N={resolution}: {1e3 * per_step:.1f} ms a step, "
                  f"{minutes:.1f} min to t = 10 s", flush=True)
    columns = ["case", "N", "grid", "dt [s]", "ms per step", "steps to t = 10 s",
               "projected minutes to t = 10 s", "vs target", "CG iterations", "ms pressure",
               "ms advection", "ms viscosity", "ms solid", "ms map", "ms coupling_force"]
    print(markdown_table(rows, columns))
    write_results(_option(argv, "name", "turek_hron_speed"), rows)
    print(machine())
    return rows


DEFLECTION_TIPS = "0,0.25,0.5,1"
DEFLECTION_TIPS_FINE = "0,0.125,0.25,0.3,0.34,0.355,0.365,0.375,0.5,0.75,1,1.5,2"


def deflection(argv: list[str]) -> list[dict[str, Any]]:
    """How the steady lift answers the flag's deflection: CFD1's flow past the rigid flag
    bent by each tip deflection, the lift after ``--duration`` s (docs/method_notes.md item 9,
    FSI1's u_y(A))."""
    from elastoflow.validation import default_setup, get_case
    from elastoflow.validation._turek_hron import FLAG_LEFT, case_simulation

    resolutions = [int(v) for v in _option(argv, "resolutions", "10,20,40").split(",")]
    duration = float(_option(argv, "duration", "8"))
    rows: list[dict[str, Any]] = []
    for resolution in resolutions:
        default = DEFLECTION_TIPS_FINE if resolution == 10 else DEFLECTION_TIPS
        tips = [float(v) for v in
                _option(argv, f"tips-{resolution}", _option(argv, "tips", default)).split(",")]
        previous: tuple[float, float] | None = None
        for tip in tips:
            setup = default_setup(get_case("CFD1"), resolution, duration=duration)
            simulation, _ = case_simulation(setup, tip_deflection=tip * 1e-3)
            began = time.perf_counter()
            for _ in range(setup.steps):
                simulation.step()
            force = simulation.traction_forces()[0]
            points = simulation.model.obstacles[0].points_at(simulation.time)
            on_flag = points[:, 0] >= FLAG_LEFT - 1e-12
            lift = float(force[:, 1].sum())
            row: dict[str, Any] = {
                "N": resolution, "h [m]": setup.h, "tip deflection [mm]": tip,
                "tip deflection / h": tip * 1e-3 / setup.h, "t_end [s]": simulation.time,
                "drag [N/m]": float(force[:, 0].sum()), "lift [N/m]": lift,
                "flag lift [N/m]": float(force[on_flag, 1].sum()),
                "wall [s]": round(time.perf_counter() - began, 1),
            }
            if previous is not None and tip != previous[0]:
                row["dlift/dtip since the row before [N/m per mm]"] = (
                    (lift - previous[1]) / (tip - previous[0]))
            previous = (tip, lift)
            rows.append(row)
            print(f"N={resolution} tip {tip} mm: lift {lift:.4f} N/m "
                  f"({row['wall [s]']} s)", flush=True)
    columns = ["N", "tip deflection [mm]", "tip deflection / h", "drag [N/m]", "lift [N/m]",
               "flag lift [N/m]", "dlift/dtip since the row before [N/m per mm]", "wall [s]"]
    print(markdown_table(rows, columns))
    write_results(_option(argv, "name", "turek_hron_deflection"), rows)
    print(machine())
    return rows


def _placement_cells(resolution: int) -> list[int]:
    from elastoflow.validation import cells_across

    centre = cells_across(resolution)
    return [k for k in range(centre - 3, centre + 5) if k % 41 != 0]


def placement(argv: list[str]) -> list[dict[str, Any]]:
    """A case's final quantities on grids that put the flag at different places relative to
    the cells, at about the same h: how much of a resolution's answer is where the flag's
    faces fall (docs/method_notes.md item 9, FSI1's u_y(A))."""
    import dataclasses

    from elastoflow.analysis import PeriodicStatistics
    from elastoflow.validation import default_setup, get_case, run_setup
    from elastoflow.validation._turek_hron import FLAG_Y

    cases = _option(argv, "cases", "FSI1").split(",")
    resolutions = [int(v) for v in _option(argv, "resolutions", "10,20").split(",")]
    duration = _option(argv, "duration", "")
    layers = _option(argv, "layers", "")
    rows: list[dict[str, Any]] = []
    summaries: list[dict[str, Any]] = []
    for name in cases:
        for resolution in resolutions:
            given = _option(argv, f"cells-{resolution}", "")
            grids = ([int(v) for v in given.split(",")] if given
                     else _placement_cells(resolution))
            values: dict[str, list[float]] = {}
            for cells in grids:
                setup = default_setup(get_case(name), resolution, cells=cells,
                                      duration=float(duration) if duration else None)
                if layers:
                    setup = dataclasses.replace(setup, layers=int(layers))
                result = run_setup(setup)
                row: dict[str, Any] = {
                    "case": name, "N": resolution, "cells across": cells, "h [m]": setup.h,
                    "flag bottom in its cell": (FLAG_Y[0] / setup.h) % 1.0,
                    "flag top in its cell": (FLAG_Y[1] / setup.h) % 1.0,
                    "layers": setup.layers, "t_end [s]": float(result.time[-1]),
                    "wall [s]": round(result.seconds, 1),
                }
                for key, value in result.quantities.items():
                    number = value.mean if isinstance(value, PeriodicStatistics) else value
                    row[key] = float(number)
                    values.setdefault(key, []).append(float(number))
                if result.failure:
                    row["note"] = result.failure
                rows.append(row)
                print(f"{name} N={resolution} cells {cells}: "
                      + ", ".join(f"{k} {row[k]:.5g}" for k in values), flush=True)
            for key, series in values.items():
                array = np.asarray(series)
                summaries.append({"case": name, "N": resolution, "quantity": key,
                                  "grids": len(array), "mean": float(array.mean()),
                                  "min": float(array.min()), "max": float(array.max()),
                                  "std": float(array.std(ddof=1)) if len(array) > 1 else 0.0})
    columns = ["case", "N", "cells across", "flag bottom in its cell", "flag top in its cell",
               "ux_A", "uy_A", "drag", "lift", "wall [s]"]
    print(markdown_table(rows, columns))
    print(markdown_table(summaries, ["case", "N", "quantity", "grids", "mean", "min", "max",
                                     "std"]))
    write_results(_option(argv, "name", "turek_hron_placement"), rows + summaries)
    print(machine())
    return rows + summaries


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    from elastoflow.analysis import PeriodicStatistics
    from elastoflow.simulation import SimulationBlowUp
    from elastoflow.solid import SolidInversionError
    from elastoflow.validation import CASES, format_quantities, run_case, write_report

    argv = list(argv or [])
    if "--speed" in argv:
        return speed(argv)
    if "--deflection" in argv:
        return deflection(argv)
    if "--placement" in argv:
        return placement(argv)
    quick = "--quick" in argv
    cases = _option(argv, "cases", "CFD1,CSM1,FSI1" if quick else ",".join(CASES)).split(",")
    resolutions = [int(v) for v in _option(argv, "resolutions", "10").split(",")]
    rows: list[dict[str, Any]] = []
    for name in cases:
        for resolution in resolutions:
            began = time.perf_counter()
            try:
                if "--reevaluate" in argv:
                    result = _reevaluate(name, resolution)
                else:
                    result = run_case(name, resolution, duration=2.0 if quick else None)
            except (SimulationBlowUp, SolidInversionError) as error:
                print(f"{name} N={resolution}: failed: {error}", flush=True)
                rows.append({"case": name, "N": resolution, "note": f"failed: {error}",
                             "wall [s]": round(time.perf_counter() - began, 1)})
                continue
            wall = result.seconds if "--reevaluate" in argv else time.perf_counter() - began
            print(f"{name} N={resolution}: {wall:.1f} s", flush=True)
            for line in format_quantities(result):
                print(f"  {line}", flush=True)
            paths = write_report(result, SERIES)
            if not quick:
                DOCS.mkdir(parents=True, exist_ok=True)
                for path in paths:
                    if path.suffix in (".png", ".json"):
                        shutil.copyfile(path, DOCS / path.name)
            row: dict[str, Any] = {
                "case": name, "N": resolution, "h [m]": result.setup.h,
                "dt [s]": result.setup.dt, "t_end [s]": float(result.time[-1]),
                "steps": result.steps, "wall [s]": round(wall, 1),
                "cells": "x".join(map(str, result.cells)) if result.cells else "-",
                "flag elements": result.elements,
            }
            for key, value in result.quantities.items():
                if isinstance(value, PeriodicStatistics):
                    row[key] = f"{value.mean:.5g} ± {value.amplitude:.5g} [{value.frequency:.4g}]"
                else:
                    row[key] = f"{value:.5g}"
            if result.failure:
                row["note"] = result.failure
            rows.append(row)
    columns = ["case", "N", "cells", "dt [s]", "t_end [s]", "wall [s]", "ux_A", "uy_A", "drag",
               "lift", "drag_cv", "lift_cv", "note"]
    print(markdown_table(rows, columns))
    write_results(_option(argv, "name", "turek_hron"), rows)
    print(machine())
    return rows
