"""Plane Poiseuille flow developing from a uniform inflow (analytic.json: poiseuille).

Channel of height H = 1 and length 4H, uniform inflow U = 1 on the left, outflow on the
right, no-slip walls, Re = U H / nu = 10. Downstream of the entrance region the steady
profile must be u = 6 U y (H - y) / H^2 (same flux, centreline 1.5 U).

Reproduce the numbers and plot of docs/validation_fluid.md:
    .venv/bin/python tests/validation/test_poiseuille.py docs/img
"""

from __future__ import annotations

import sys

import numpy as np
import pytest

from elastoflow.fluid import DomainBoundaries, FluidSolver, FluidState, Inflow, Outflow, WallNoSlip
from elastoflow.grid import Grid2D
from elastoflow.validation._report import step_to_steady

LENGTH = 4
REYNOLDS = 10.0


def run_poiseuille(n: int, *, incremental_pressure: bool = True, cfl: float = 4.0,
                   t_max: float = 40.0, tolerance: float = 1e-5) -> dict:
    """Steady channel flow with n cells across; profiles at x = 1, 2, 3 H."""
    grid = Grid2D(LENGTH * n, n, 1.0 / n)
    solver = FluidSolver(
        grid, density=1.0, viscosity=1.0 / REYNOLDS,
        boundaries=DomainBoundaries(Inflow(1.0), Outflow(), WallNoSlip(), WallNoSlip()),
        incremental_pressure=incremental_pressure,
    )
    state = FluidState.zeros(grid)
    steps, time, change = step_to_steady(solver, state, cfl * grid.h / 1.5, t_max, tolerance)
    y = (np.arange(n) + 0.5) / n
    exact = 6.0 * y * (1.0 - y)
    profiles = {x: state.velocity_x[x * n].copy() for x in (1, 2, 3)}
    errors = {x: float(np.abs(profile - exact).max() / 1.5) for x, profile in profiles.items()}
    return {"y": y, "exact": exact, "profiles": profiles, "errors": errors, "steps": steps,
            "time": time, "change": change}


@pytest.mark.slow
def test_poiseuille_profile_within_one_percent():
    result = run_poiseuille(64)
    assert result["change"] <= 1e-5
    assert result["errors"][3] < 0.01
    assert result["errors"][2] < 0.01


def main(output_directory: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(6, 4))
    for incremental in (True, False):
        for cfl in (1.0, 4.0):
            result = run_poiseuille(64, incremental_pressure=incremental, cfl=cfl)
            print(f"| {incremental} | {cfl} | {100 * result['errors'][1]:.3f} % | "
                  f"{100 * result['errors'][2]:.3f} % | {100 * result['errors'][3]:.3f} % | "
                  f"{result['steps']} |", flush=True)
            if cfl == 4.0:
                axis.plot(result["profiles"][3], result["y"],
                          label=f"x = 3H, incremental_pressure={incremental}, CFL {cfl}")
    axis.plot(result["exact"], result["y"], "k--", label="6 U y (H - y) / H²")
    axis.set_xlabel("u [m/s]")
    axis.set_ylabel("y [m]")
    axis.set_title("Poiseuille channel, Re 10, 64 cells across")
    axis.legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(f"{output_directory}/fluid_poiseuille.png", dpi=110)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else ".")
