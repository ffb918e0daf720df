"""Turek-Hron CSM1: static deflection of the elastic flag under gravity (StVK, plane strain).

The flag [0.249, 0.6] x [0.19, 0.21] is clamped where it meets the cylinder (its left end follows
the circle of radius 0.05 about (0.2, 0.2)); gravity 2 m/s^2 pulls it down. The explicit solver
reaches the static state by dynamic relaxation: a mass-proportional drag at the critical rate
of the first bending mode (2 omega_1 from Euler-Bernoulli; only the speed of settling depends on
it, not the answer). Run as a script to print the convergence table of docs/validation_solid.md.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import pytest

from elastoflow.solid import (
    ElasticBody,
    ExplicitFem,
    MaterialStVK,
    TriangleMesh,
    mesh_rectangle,
    nearest_node,
)

REFERENCE_FILE = Path("/work/shared/reference/turek_hron.json")
CENTER, RADIUS = np.array([0.2, 0.2]), 0.05
X_LEFT, X_RIGHT, Y_LOW, THICKNESS = 0.24898979485566358, 0.6, 0.19, 0.02
# Published CSM1 displacement of point A [m] (Turek & Hron 2006; also in the reference file).
REFERENCE_DISPLACEMENT = np.array([-0.007187, -0.0661])


def flag_mesh(layers: int) -> TriangleMesh:
    """Crossed structured mesh with ``layers`` cells through the thickness, square cells.

    The left column of nodes is moved onto the cylinder's circle and the shift fades linearly
    to zero at the free end, so the elements stay nearly square.
    """
    length = X_RIGHT - X_LEFT
    cells_x = round(length / (THICKNESS / layers))
    mesh = mesh_rectangle(length, THICKNESS, counts=(cells_x, layers), origin=(X_LEFT, Y_LOW),
                          pattern="crossed")
    points = mesh.points.copy()
    arc = CENTER[0] + np.sqrt(RADIUS**2 - (points[:, 1] - CENTER[1]) ** 2)
    points[:, 0] += (arc - X_LEFT) * (X_RIGHT - points[:, 0]) / length
    return TriangleMesh(points, mesh.triangles)


def static_displacement(layers: int) -> tuple[np.ndarray, int, float]:
    """Displacement of A [m] at rest under gravity, element count, simulated time [s]."""
    material = MaterialStVK(density=1000.0, young_modulus=1.4e6, poisson_ratio=0.4)
    mesh = flag_mesh(layers)
    on_cylinder = np.linalg.norm(mesh.points - CENTER, axis=1) <= RADIUS * (1 + 1e-9)
    point_a = nearest_node(mesh, (0.6, 0.2))
    assert np.allclose(mesh.points[point_a], [0.6, 0.2])
    free_length = X_RIGHT - (CENTER[0] + RADIUS)
    omega_1 = (1.8751040687 / free_length) ** 2 * np.sqrt(
        material.bending_modulus * THICKNESS**2 / (12.0 * material.density)
    )
    body = ElasticBody(mesh, material, fixed_nodes=np.flatnonzero(on_cylinder),
                       gravity=(0.0, -2.0), velocity_damping=2.0 * omega_1)
    body_state = body.state()
    chunk, elapsed = 0.05, 0.0
    previous = np.zeros(2)
    while elapsed < 10.0:
        ExplicitFem("auto").advance(body, body_state, body_state, chunk)
        elapsed += chunk
        displacement = body_state.positions[point_a] - mesh.points[point_a]
        # Settled: A moves less than 1e-6 m (1.5e-5 of the deflection) in 0.05 s.
        if np.abs(displacement - previous).max() < 1e-6:
            break
        previous = displacement
    return displacement, mesh.triangle_count, elapsed


@pytest.mark.slow
def test_csm1_point_a_converges_to_reference() -> None:
    if REFERENCE_FILE.exists():
        csm1 = json.loads(REFERENCE_FILE.read_text())["results_turek_hron_2006"]["CSM1"]
        np.testing.assert_allclose([csm1["ux_A"], csm1["uy_A"]], REFERENCE_DISPLACEMENT)
    errors = []
    for layers in (2, 4, 8):
        displacement, _, elapsed = static_displacement(layers)
        assert elapsed < 10.0
        errors.append(np.abs(displacement / REFERENCE_DISPLACEMENT - 1.0))
    errors = np.array(errors)
    # Error falls with refinement in both components, and the finest mesh is within 3% in y.
    assert np.all(np.diff(errors, axis=0) < 0.0)
    assert errors[-1, 1] < 0.03
    # Linear triangles converge at second order in displacement; allow some pre-asymptotics.
    order = np.log2(errors[-2, 1] / errors[-1, 1])
    assert order > 1.5


def _main(argv: list[str]) -> None:
    """Print the convergence table; ``--layers 2,4,8``; ``--plot PATH`` draws error vs h."""
    layers_list = [2, 4, 8]
    if "--layers" in argv:
        layers_list = [int(v) for v in argv[argv.index("--layers") + 1].split(",")]
    print("| layers | elements | u_x(A) [mm] | u_y(A) [mm] | error x | error y | wall [s] |")
    print("|---|---|---|---|---|---|---|")
    errors = []
    for layers in layers_list:
        start = time.perf_counter()
        displacement, elements, _ = static_displacement(layers)
        error = displacement / REFERENCE_DISPLACEMENT - 1.0
        errors.append(np.abs(error))
        print(f"| {layers} | {elements} | {displacement[0] * 1e3:.4f} | "
              f"{displacement[1] * 1e3:.3f} | {error[0] * 100:+.2f}% | {error[1] * 100:+.2f}% | "
              f"{time.perf_counter() - start:.1f} |", flush=True)
    if "--plot" in argv:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        h = THICKNESS / np.array(layers_list)
        e = np.array(errors)
        figure, axes = plt.subplots(figsize=(5, 4))
        axes.loglog(h * 1e3, e[:, 0], "o-", label="$u_x(A)$")
        axes.loglog(h * 1e3, e[:, 1], "s-", label="$u_y(A)$")
        axes.loglog(h * 1e3, e[-1, 1] * (h / h[-1]) ** 2, "k--", label="slope 2")
        axes.set_xticks(h * 1e3, [f"{v:g}" for v in h * 1e3])
        axes.minorticks_off()
        axes.set_xlabel("cell side h [mm]")
        axes.set_ylabel("relative error vs Turek-Hron")
        axes.set_title("CSM1, crossed linear triangles")
        axes.legend()
        figure.tight_layout()
        figure.savefig(argv[argv.index("--plot") + 1], dpi=120)


if __name__ == "__main__":
    import sys

    _main(sys.argv[1:])
