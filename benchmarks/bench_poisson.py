"""Poisson solve time and iteration count at 128^2 .. 1024^2 to a relative residual of 1e-6.

Cases (unit square, ``n x n`` cells, smooth right-hand side):

* ``outflow``: pressure-like operator, all faces open, Dirichlet (outflow) on the right side;
* ``body``: the same with a disc of closed cells and fractional open faces around it;
* ``closed``: closed box (pure Neumann, singular);
* ``viscosity``: implicit viscosity of ``u`` on ``(n+1, n)``, diagonal 1, weights 10.

Time is the whole ``solve`` call, the minimum over repeats after one warm-up solve:
``time_ms`` solves the same operator again (the solver keeps its multigrid levels and
null-space analysis, as for the fluid's constant operators), ``new_solver_ms`` uses a new solver
each time (allocation and setup of the hierarchy, null-space analysis and the CG iterations).

Usage: ``python -m benchmarks poisson [--quick] [--threads=N]`` or
``python benchmarks/bench_poisson.py [--quick] [--threads=N]``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import numba
import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import markdown_table, write_results
from elastoflow.linalg import Operator5Point, PoissonSolverMGPCG


def _problem(case: str, size: int) -> tuple[Operator5Point, np.ndarray]:
    centres = (np.arange(size) + 0.5) / size
    faces = np.arange(1, size) / size
    x, y = np.meshgrid(centres, centres, indexing="ij")
    rhs = np.cos(3 * np.pi * x) * np.sin(2 * np.pi * y) + x**2
    if case == "viscosity":
        xu, yu = np.meshgrid(np.arange(size + 1) / size, centres, indexing="ij")
        operator = Operator5Point(
            np.ones((size + 1, size)), np.full((size, size), 10.0), np.full((size + 1, size - 1), 10.0)
        )
        return operator, np.sin(np.pi * xu) * np.cos(np.pi * yu)
    diagonal = np.zeros((size, size))
    if case != "closed":
        diagonal[-1, :] = 2.0
    weights_x = np.ones((size - 1, size))
    weights_y = np.ones((size, size - 1))
    if case == "body":
        def open_fraction(px: np.ndarray, py: np.ndarray) -> np.ndarray:
            return np.clip(0.5 + (np.hypot(px - 0.4, py - 0.55) - 0.15) * size, 0.0, 1.0)

        weights_x = open_fraction(*np.meshgrid(faces, centres, indexing="ij"))
        weights_y = open_fraction(*np.meshgrid(centres, faces, indexing="ij"))
        rhs = rhs * (np.hypot(x - 0.4, y - 0.55) > 0.15)
    return Operator5Point(diagonal, weights_x, weights_y), rhs


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    """Run the benchmark, print a Markdown table, write ``results/poisson.json``.

    Args:
        argv: Options; ``--quick`` limits sizes to 128 and 256; ``--threads=N`` sets the Numba
            thread count (default: Numba's).

    Returns:
        One row per (case, size): iterations, residual, time [ms], time per iteration [ms].
    """
    args = list(sys.argv[1:] if argv is None else argv)
    sizes = (128, 256) if "--quick" in args else (128, 256, 512, 1024)
    for arg in args:
        if arg.startswith("--threads="):
            numba.set_num_threads(int(arg.split("=", 1)[1]))
    rows: list[dict[str, Any]] = []
    solver = PoissonSolverMGPCG(rtol=1e-6)
    for case in ("outflow", "body", "closed", "viscosity"):
        for size in sizes:
            operator, rhs = _problem(case, size)
            solver.solve(operator, rhs)
            repeats = 10 if size <= 256 else (5 if size <= 512 else 3)
            best = best_new = np.inf
            for _ in range(repeats):
                start = time.perf_counter()
                _, report = solver.solve(operator, rhs)
                best = min(best, time.perf_counter() - start)
                start = time.perf_counter()
                PoissonSolverMGPCG(rtol=1e-6).solve(operator, rhs)
                best_new = min(best_new, time.perf_counter() - start)
            rows.append({
                "case": case,
                "size": f"{size}x{size}",
                "threads": numba.get_num_threads(),
                "iterations": report.iterations,
                "residual": report.residual,
                "time_ms": best * 1e3,
                "new_solver_ms": best_new * 1e3,
                "ms_per_iteration": best * 1e3 / max(report.iterations, 1),
            })
    print(markdown_table(rows, ["case", "size", "threads", "iterations", "residual", "time_ms",
                                "new_solver_ms", "ms_per_iteration"]))
    write_results("poisson", rows)
    return rows


if __name__ == "__main__":
    main()
