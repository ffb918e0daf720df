"""First bending frequency of a slender clamped cantilever vs Euler-Bernoulli.

Bar 1.0 x 0.05 m (aspect 20), plane stress (so the 2D beam modulus is E), clamped at x = 0,
started from rest shape with a small velocity in the shape of the first Euler-Bernoulli mode
(tip speed gives a tip amplitude of 1e-3 of the length: linear regime). The frequency is read
from the zero crossings of the tip's vertical displacement. Euler-Bernoulli neglects shear and
rotary inertia, which lower the frequency of an aspect-20 beam by about 0.4%; linear triangles
lock in bending, which raises it, and refinement removes that. Run as a script to print the
table of docs/validation_solid.md.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from elastoflow.solid import (
    ElasticBody,
    ExplicitFem,
    MaterialStVK,
    mesh_rectangle,
    nearest_node,
    nodes_in_box,
)

LENGTH, THICKNESS = 1.0, 0.05
MATERIAL = MaterialStVK(density=1000.0, young_modulus=1.0e7, poisson_ratio=0.3, plane="stress")
BETA_L = 1.8751040687  # first root of cos(bL) cosh(bL) = -1
FREQUENCY_COEFFICIENT = 0.5595912099683509  # (beta L)^2 / (2 pi)


def euler_bernoulli_frequency() -> float:
    """f_1 = 0.5596 sqrt(E I / (rho A L^4)) [Hz], I = t^3/12 and A = t per unit depth."""
    inertia = THICKNESS**3 / 12.0
    return FREQUENCY_COEFFICIENT * np.sqrt(
        MATERIAL.bending_modulus * inertia / (MATERIAL.density * THICKNESS * LENGTH**4)
    )


def mode_shape(x: np.ndarray) -> np.ndarray:
    z = BETA_L * x / LENGTH
    ratio = (np.cosh(BETA_L) + np.cos(BETA_L)) / (np.sinh(BETA_L) + np.sin(BETA_L))
    return np.cosh(z) - np.cos(z) - ratio * (np.sinh(z) - np.sin(z))


def tip_history(layers: int, periods: float = 2.2) -> tuple[np.ndarray, np.ndarray, int]:
    """Times [s] and tip y-displacement [m] over ``periods`` of f_1, and the element count."""
    cells_x = round(LENGTH / (THICKNESS / layers))
    mesh = mesh_rectangle(LENGTH, THICKNESS, counts=(cells_x, layers),
                          origin=(0.0, -THICKNESS / 2), pattern="crossed")
    clamp = nodes_in_box(mesh, (0.0, -THICKNESS, 0.0, THICKNESS))
    tip = nearest_node(mesh, (LENGTH, 0.0))
    f_reference = euler_bernoulli_frequency()
    velocities = np.zeros_like(mesh.points)
    tip_speed = 1e-3 * LENGTH * 2.0 * np.pi * f_reference
    velocities[:, 1] = tip_speed * mode_shape(mesh.points[:, 0]) / mode_shape(np.array(LENGTH))
    body = ElasticBody(mesh, MATERIAL, fixed_nodes=clamp, velocities=velocities)
    body_state = body.state()
    samples_per_period = 200
    dt = 1.0 / (f_reference * samples_per_period)
    count = int(periods * samples_per_period)
    tip_y = np.empty(count)
    for k in range(count):
        ExplicitFem("auto").advance(body, body_state, body_state, dt)
        tip_y[k] = body_state.positions[tip, 1]
    return dt * np.arange(1, count + 1), tip_y, mesh.triangle_count


def frequency_from_crossings(times: np.ndarray, signal: np.ndarray) -> float:
    """1 / (2 x mean spacing of the zero crossings) [Hz], crossings linearly interpolated."""
    i = np.flatnonzero(np.sign(signal[:-1]) * np.sign(signal[1:]) < 0.0)
    crossings = times[i] - signal[i] * (times[i + 1] - times[i]) / (signal[i + 1] - signal[i])
    assert crossings.size >= 3
    return float(1.0 / (2.0 * np.mean(np.diff(crossings))))


@pytest.mark.slow
def test_first_frequency_matches_euler_bernoulli() -> None:
    f_reference = euler_bernoulli_frequency()
    errors = []
    for layers in (2, 4, 6):
        times, tip_y, _ = tip_history(layers)
        errors.append(frequency_from_crossings(times, tip_y) / f_reference - 1.0)
    # Locking makes coarse meshes too stiff; refinement brings the frequency down toward f_1.
    assert errors[0] > errors[1] > errors[2]
    assert abs(errors[2]) < 0.03


def _main(argv: list[str]) -> None:
    """Print the table; ``--plot PATH`` draws the tip trace of the finest mesh."""
    f_reference = euler_bernoulli_frequency()
    print(f"Euler-Bernoulli f_1 = {f_reference:.5f} Hz")
    print("| layers | elements | f_1 [Hz] | error | wall [s] |")
    print("|---|---|---|---|---|")
    for layers in (2, 4, 6, 8):
        start = time.perf_counter()
        times, tip_y, elements = tip_history(layers)
        frequency = frequency_from_crossings(times, tip_y)
        print(f"| {layers} | {elements} | {frequency:.5f} | "
              f"{(frequency / f_reference - 1) * 100:+.2f}% | {time.perf_counter() - start:.1f} |",
              flush=True)
    if "--plot" in argv:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        figure, axes = plt.subplots(figsize=(6, 3))
        axes.plot(times, tip_y * 1e3, label="tip, 8 layers")
        # The start velocity gives a tip amplitude of 1e-3 L [m], i.e. L [mm].
        axes.plot(times, LENGTH * np.sin(2 * np.pi * f_reference * times), "k--",
                  label="Euler-Bernoulli $f_1$")
        axes.set_xlabel("time [s]")
        axes.set_ylabel("tip displacement [mm]")
        axes.legend(loc="upper right")
        figure.tight_layout()
        figure.savefig(argv[argv.index("--plot") + 1], dpi=120)


if __name__ == "__main__":
    import sys

    _main(sys.argv[1:])
