"""Taylor–Green vortex: kinetic energy decays as exp(-4 nu k^2 t) (analytic.json).

In the box [0, pi/k]^2 the vortex u = U sin(kx) cos(ky), v = -U cos(kx) sin(ky) meets
free-slip walls exactly, so the whole decay is physics plus the scheme's error.

Reproduce the numbers and plot of docs/validation_fluid.md:
    .venv/bin/python tests/validation/test_taylor_green.py docs/img
"""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest

from elastoflow.fluid import DomainBoundaries, FluidSolver, FluidState, WallFreeSlip
from elastoflow.grid import Grid2D

WAVENUMBER = 1.0
VISCOSITY = 0.1          # Re = U (pi/k) / nu ~ 31
DURATION = 1.05          # exp(-4 nu k^2 T) = 0.657: a third of the energy is lost
CFL = 1.0


def run_taylor_green(n: int, advection: str, viscosity: float = VISCOSITY,
                     duration: float = DURATION, cfl: float = CFL) -> dict:
    """Energy ratio history of the decaying vortex on an n x n grid."""
    grid = Grid2D(n, n, math.pi / WAVENUMBER / n)
    solver = FluidSolver(grid, density=1.0, viscosity=viscosity,
                         boundaries=DomainBoundaries(*(WallFreeSlip(),) * 4),
                         advection=advection)
    state = FluidState.zeros(grid)
    xu, yu = grid.faces_x()
    xv, yv = grid.faces_y()
    k = WAVENUMBER
    state.velocity_x[...] = np.sin(k * xu) * np.cos(k * yu)
    state.velocity_y[...] = -np.cos(k * xv) * np.sin(k * yv)

    def energy() -> float:
        return float((state.velocity_x**2).sum() + (state.velocity_y**2).sum())

    initial = energy()
    steps = math.ceil(duration / (cfl * grid.h))
    dt = duration / steps
    times, ratios = [0.0], [1.0]
    for index in range(steps):
        solver.step(state, dt, index * dt)
        times.append((index + 1) * dt)
        ratios.append(energy() / initial)
    exact = np.exp(-4.0 * viscosity * k**2 * np.array(times))
    return {"times": np.array(times), "ratios": np.array(ratios), "exact": exact,
            "error": float(ratios[-1] / exact[-1] - 1.0)}


@pytest.mark.slow
@pytest.mark.parametrize("advection", ["maccormack", "semi_lagrangian"])
def test_taylor_green_energy_decay(advection):
    coarse = run_taylor_green(64, advection)
    fine = run_taylor_green(128, advection)
    assert fine["exact"][-1] < 2.0 / 3.0
    assert abs(fine["error"]) < 0.02
    # First order in h at fixed CFL (dt ~ h): halving h must shrink the error clearly.
    assert abs(fine["error"]) < 0.7 * abs(coarse["error"])


def main(output_directory: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(6, 4))
    for advection in ("semi_lagrangian", "maccormack"):
        for n in (32, 64, 128):
            result = run_taylor_green(n, advection)
            print(f"| {advection} | {n} | {result['ratios'][-1]:.4f} | "
                  f"{result['exact'][-1]:.4f} | {100 * result['error']:+.2f} % |")
            if n in (32, 128):
                axis.plot(result["times"], result["ratios"], label=f"{advection} {n}²")
    axis.plot(result["times"], result["exact"], "k--", label="exp(-4 ν k² t)")
    axis.set_xlabel("t [s]")
    axis.set_ylabel("E(t) / E(0)")
    axis.set_title(f"Taylor–Green vortex, ν = {VISCOSITY}, CFL {CFL}")
    axis.legend()
    figure.tight_layout()
    figure.savefig(f"{output_directory}/fluid_taylor_green.png", dpi=110)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else ".")
