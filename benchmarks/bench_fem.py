"""Explicit FEM substeps per second for a paper-sized bar (~200 triangles) and a large mesh.

Cases (St. Venant-Kirchhoff with Voigt damping, gravity, one end fixed, a constant external
force, the state kept away from rest so that every element does real work):

* ``bar``: 4 x 24 cells, 192 triangles (the paper's bar has 194);
* ``block``: 100 x 100 cells, 20000 triangles; run with the serial and with the threaded kernel.

Each timing is one ``ExplicitFem.advance`` call of many substeps (after a warm-up call that
compiles), best of three; reported as substeps per second and nanoseconds per element-substep.

Usage: ``python -m benchmarks fem [--quick]`` or ``python benchmarks/bench_fem.py``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import markdown_table, write_results
from elastoflow.solid import (
    BodyState,
    ElasticBody,
    ExplicitFem,
    MaterialStVK,
    mesh_rectangle,
    nodes_in_box,
)

MATERIAL = MaterialStVK(1000.0, 1.0e6, 0.3, damping_lambda=1.0, damping_mu=1.0)


def _body(counts: tuple[int, int], parallel: bool) -> tuple[ElasticBody, BodyState]:
    mesh = mesh_rectangle(0.02 * counts[0] / 4, 0.2 * counts[1] / 24, counts=counts)
    top = nodes_in_box(mesh, (0.0, mesh.points[:, 1].max(), mesh.points[:, 0].max(),
                              mesh.points[:, 1].max()))
    body = ElasticBody(mesh, MATERIAL, fixed_nodes=top, gravity=(0.0, -9.81), parallel=parallel)
    state = body.state()
    state.positions[:, 0] += 0.01 * np.sin(mesh.points[:, 1] / mesh.points[:, 1].max())
    return body, state


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    """Run the benchmark, print a Markdown table, write ``results/fem.json``.

    Args:
        argv: Options; ``--quick`` runs fewer substeps.

    Returns:
        One row per (case, kernel): triangles, nodes, substeps timed, substeps/s, ns per
        element-substep.
    """
    args = list(sys.argv[1:] if argv is None else argv)
    quick = "--quick" in args
    rows: list[dict[str, Any]] = []
    for case, counts, kernels, substeps in (
        ("bar", (4, 24), (False,), 20000 if quick else 200000),
        ("block", (100, 100), (False, True), 100 if quick else 1000),
    ):
        for parallel in kernels:
            body, state = _body(counts, parallel)
            forces = np.full((body.mesh.point_count, 2), 1e-6)
            dt_s = body.stable_substep()
            ExplicitFem(2).advance(body, state, state, dt_s * 2, forces)
            best = np.inf
            for _ in range(3):
                start = time.perf_counter()
                ExplicitFem(substeps).advance(body, state, state, dt_s * substeps, forces)
                best = min(best, time.perf_counter() - start)
            rate = substeps / best
            rows.append({
                "case": case,
                "kernel": "threaded" if parallel else "serial",
                "triangles": body.mesh.triangle_count,
                "nodes": body.mesh.point_count,
                "substeps": substeps,
                "substeps_per_s": rate,
                "ns_per_element_substep": best / (substeps * body.mesh.triangle_count) * 1e9,
            })
    print(markdown_table(rows, ["case", "kernel", "triangles", "nodes", "substeps",
                                "substeps_per_s", "ns_per_element_substep"]))
    write_results("fem", rows)
    return rows


if __name__ == "__main__":
    main()
