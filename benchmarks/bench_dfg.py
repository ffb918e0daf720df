"""DFG 2D-1 drag and lift against grid refinement, with both fluid-to-solid force estimates.

Runs ``run_dfg`` of tests/validation/test_coupling_dfg.py (the cylinder as a static obstacle
in the boundary map, traction integral and the paper's momentum exchange read from the same
run) at h = 0.41/31 .. 0.41/164, 3 s of simulated time from the Poiseuille profile, CFL 0.5 on
the peak inflow speed; and the same with the staircase baseline (faces fully open or closed, no
cut distances). Prints a Markdown table, writes ``benchmarks/results/dfg.json`` and, with
``--plot``, ``docs/img/coupling_dfg_convergence.png`` and ``docs/img/coupling_dfg_history.png``.

Usage: ``python -m benchmarks dfg [--quick] [--plot]`` (``--quick``: up to 0.41/62).
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from typing import Any

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import markdown_table, write_results

ROOT = Path(__file__).resolve().parent.parent


def _dfg_module() -> Any:
    path = ROOT / "tests" / "validation" / "test_coupling_dfg.py"
    spec = importlib.util.spec_from_file_location("_dfg_validation", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def _plot(rows: list[dict[str, Any]], histories: dict[int, np.ndarray], reference: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    h = np.array([r["h"] for r in rows])
    figure, axes = plt.subplots(1, 2, figsize=(10, 4))
    axes[0].loglog(h, [abs(r["c_D traction"] - reference["c_D"]) / reference["c_D"] for r in rows],
                   "o-", label="traction")
    axes[0].loglog(h, [abs(r["c_D momentum exchange"] - reference["c_D"]) / reference["c_D"]
                       for r in rows], "s-", label="momentum exchange (eq. 8)")
    axes[0].loglog(h, 0.05 * (h / h[0]) ** 2, "k:", label="h^2")
    axes[0].axhline(0.05, color="grey", lw=0.8)
    axes[0].set_xlabel("h [m]")
    axes[0].set_ylabel("|c_D - c_D,ref| / c_D,ref")
    axes[0].legend()
    axes[0].set_title("DFG 2D-1 drag error")
    for n, history in histories.items():
        axes[1].plot(history[:, 0], history[:, 1], label=f"h = 0.41/{n}")
    axes[1].axhline(reference["c_D"], color="k", lw=0.8, ls="--", label="reference")
    axes[1].set_ylim(reference["c_D"] * 0.9, reference["c_D"] * 1.05)
    axes[1].set_xlabel("t [s]")
    axes[1].set_ylabel("c_D (traction)")
    axes[1].legend(fontsize=8)
    axes[1].set_title("approach to steady state")
    figure.tight_layout()
    out = ROOT / "docs" / "img" / "coupling_dfg_convergence.png"
    figure.savefig(out, dpi=110)
    print(f"wrote {out}")


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    args = list(sys.argv[1:] if argv is None else argv)
    dfg = _dfg_module()
    reference = dfg.reference_2d1()
    resolutions = (31, 41, 62) if "--quick" in args else (31, 41, 62, 82, 123, 164)
    rows, histories = [], {}
    for n in resolutions:
        result = dfg.run_dfg(n, end_time=3.0)
        histories[n] = result.history
        stairs = dfg.run_dfg(n, end_time=3.0, staircase=True)
        rows.append({
            "h": result.h, "cells": f"0.41/{n}", "steps": result.steps,
            "c_D traction": result.drag_traction, "c_L traction": result.lift_traction,
            "c_D momentum exchange": result.drag_momentum_exchange,
            "c_L momentum exchange": result.lift_momentum_exchange,
            "delta_p": result.delta_p,
            "c_D error": (result.drag_traction - reference["c_D"]) / reference["c_D"],
            "c_D drift (last 0.5 s)": result.drift, "seconds": result.seconds,
            "c_D staircase": stairs.drag_traction, "c_L staircase": stairs.lift_traction,
            "delta_p staircase": stairs.delta_p,
        })
        print(f"h = 0.41/{n}: c_D = {result.drag_traction:.4f} ({result.seconds:.1f} s)",
              flush=True)
    print(markdown_table(rows, list(rows[0])))
    print(f"reference: c_D = {reference['c_D']}, c_L = {reference['c_L']}, "
          f"delta_p = {reference['delta_p']}")
    write_results("dfg", rows)
    if "--plot" in args:
        _plot(rows, histories, reference)
    return rows


if __name__ == "__main__":
    main()
