"""Turek-Hron study: every case at the chosen resolutions, quantities, run time and plots.

``python -m benchmarks turek_hron [--cases=FSI2,FSI3] [--resolutions=10,20] [--name=NAME]
[--quick]`` writes ``benchmarks/results/NAME.json`` (default turek_hron; one row per run), and per run the plots and
quantities into ``docs/validation/turek-hron/`` (``<case>_n<N>.png`` / ``.json``) and the time
series into ``out/validation/`` (CSV, not kept in the repository). docs/validation/turek-hron.md
is written from these. ``--quick``: CFD1, CSM1 and FSI1 at N = 10 over 2 s (a smoke test).
"""

from __future__ import annotations

import shutil
import time
from pathlib import Path
from typing import Any

from benchmarks._common import machine, markdown_table, write_results

DOCS = Path(__file__).resolve().parent.parent / "docs" / "validation" / "turek-hron"
SERIES = Path("out") / "validation"


def _option(argv: list[str], name: str, default: str) -> str:
    for item in argv:
        if item.startswith(f"--{name}="):
            return item.split("=", 1)[1]
    return default


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    from elastoflow.analysis import PeriodicStatistics
    from elastoflow.simulation import SimulationBlowUp
    from elastoflow.solid import SolidInversionError
    from elastoflow.validation import CASES, format_quantities, run_case, write_report

    argv = list(argv or [])
    quick = "--quick" in argv
    cases = _option(argv, "cases", "CFD1,CSM1,FSI1" if quick else ",".join(CASES)).split(",")
    resolutions = [int(v) for v in _option(argv, "resolutions", "10").split(",")]
    rows: list[dict[str, Any]] = []
    for name in cases:
        for resolution in resolutions:
            began = time.perf_counter()
            try:
                result = run_case(name, resolution, duration=2.0 if quick else None)
            except (SimulationBlowUp, SolidInversionError) as error:
                print(f"{name} N={resolution}: failed: {error}", flush=True)
                rows.append({"case": name, "N": resolution, "note": f"failed: {error}",
                             "wall [s]": round(time.perf_counter() - began, 1)})
                continue
            wall = time.perf_counter() - began
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
               "lift", "note"]
    print(markdown_table(rows, columns))
    write_results(_option(argv, "name", "turek_hron"), rows)
    print(machine())
    return rows
