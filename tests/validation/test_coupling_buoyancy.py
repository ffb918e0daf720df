"""Fluid forces under gravity (METHOD.md §7): a body as dense as the fluid stays put, a body
twice as dense starts to sink at ``(1 - rho_f / rho_s) g``.

A stiff elastic disc (E = 1e7 Pa, so that its shape changes by far less than a cell) in still
water in a closed box, under gravity. Over the first step the fluid is at rest and the body too,
so the projection gives exactly the hydrostatic pressure: the traction integral returns the
buoyancy ``rho_f A g`` and the body accelerates at ``(1 - rho_f / rho_s) g``. After that the
fluid answers the body's acceleration with its added mass; explicit coupling applies that
answer one step late (see `sinking_history` and docs/validation_coupling.md).
"""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow import coupling, fluid, solid
from elastoflow.grid import Grid2D
from elastoflow.simulation import Simulation

GRAVITY = 9.81
FLUID_DENSITY = 1000.0
RADIUS = 0.1
DT = 0.005


def _disc_in_box(body_density: float, force_model: str, cells: int = 64,
                 added_mass: float = 0.0) -> tuple[Simulation, solid.ElasticBody]:
    grid = Grid2D(nx=cells, ny=cells, h=1.0 / cells)
    boundaries = fluid.DomainBoundaries(
        left=fluid.WallNoSlip(), right=fluid.WallNoSlip(), bottom=fluid.WallNoSlip(),
        top=fluid.WallNoSlip(),
    )
    solver = fluid.FluidSolver(grid, density=FLUID_DENSITY, viscosity=1e-3,
                               boundaries=boundaries, gravity=(0.0, -GRAVITY))
    outline = coupling.obstacle_circle((0.5, 0.5), RADIUS, segments=48).polygon
    mesh = solid.mesh_from_polygon(outline, element_size=0.03)
    body = solid.ElasticBody(mesh, solid.MaterialStVK(body_density, 1e7, 0.3),
                             gravity=(0.0, -GRAVITY))
    simulation = Simulation(grid, solver, bodies=[body], dt=DT, force_model=force_model,
                            added_mass=added_mass)
    return simulation, body


def sinking_history(body_density: float, force_model: str, steps: int, added_mass: float = 0.0
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Centre-of-mass vertical velocity after each step [m/s] and displacement [m], (steps,)."""
    simulation, body = _disc_in_box(body_density, force_model, added_mass=added_mass)
    mass = body.mass
    body_state = simulation.state.bodies[0]
    start = (mass @ body_state.positions) / mass.sum()
    velocity, displacement = np.zeros(steps), np.zeros(steps)
    for k in range(steps):
        simulation.step()
        velocity[k] = (mass @ body_state.velocities)[1] / mass.sum()
        displacement[k] = ((mass @ body_state.positions) / mass.sum() - start)[1]
    return velocity, displacement


@pytest.mark.slow
@pytest.mark.parametrize(("steps", "added_mass"), [(10, 0.0), (30, 1.0)])
def test_neutrally_buoyant_disc_stays_put_with_traction(steps: int, added_mass: float) -> None:
    """Bound: the centre moves by less than 1% of the free-fall distance, i.e. the mean
    unbalanced acceleration is below 0.01 g.

    Plain explicit coupling (added_mass = 0) only over 10 steps: at rho_s = rho_f the fluid's
    one-step-late answer to the disc's acceleration (C_a ~ 1) is amplified, by about 1.15 per
    step here, and the acceleration oscillates with growing amplitude (0.3 g by step 10, g by
    step 20). With the Simulation's added-mass stabilisation it stays put over 30 steps."""
    _, displacement = sinking_history(FLUID_DENSITY, "traction", steps, added_mass)
    free_fall = 0.5 * GRAVITY * (steps * DT) ** 2
    assert abs(displacement[-1]) < 0.01 * free_fall, (
        f"moved {displacement[-1]:.3g} m, {abs(displacement[-1]) / free_fall:.3g} of free fall")


@pytest.mark.slow
def test_heavy_disc_starts_sinking_at_reduced_gravity_with_traction() -> None:
    """First step within 10% of (1 - rho_f/rho_s) g; then 30 steps (0.15 s, about a cell of
    travel, faces of every open fraction swept) without blowing up."""
    velocity, _ = sinking_history(2.0 * FLUID_DENSITY, "traction", 30)
    expected = -(1.0 - 0.5) * GRAVITY
    acceleration = velocity[0] / DT
    assert abs(acceleration - expected) < 0.1 * abs(expected), f"a = {acceleration:.4g} m/s^2"
    assert np.isfinite(velocity).all() and velocity[-1] < 0.0


@pytest.mark.slow
def test_momentum_exchange_misses_buoyancy() -> None:
    """The paper's eq. (8) sees no hydrostatic pressure (METHOD.md §7): a neutrally buoyant
    body sinks, and a heavy one starts to sink faster than (1 - rho_f/rho_s) g."""
    steps = 10
    _, displacement = sinking_history(FLUID_DENSITY, "momentum_exchange", steps)
    free_fall = 0.5 * GRAVITY * (steps * DT) ** 2
    assert displacement[-1] < -0.5 * free_fall
    velocity, _ = sinking_history(2.0 * FLUID_DENSITY, "momentum_exchange", 1)
    expected = -0.5 * GRAVITY
    assert abs(velocity[0] / DT - expected) > 0.5 * abs(expected)


def _report(plot: bool) -> None:
    """Acceleration history of the centre of mass for both models (docs/validation_coupling.md):
    ``python tests/validation/test_coupling_buoyancy.py [--plot]``."""
    steps = 30
    physical = -(2.0 - 1.0) / (2.0 + 1.0) * GRAVITY  # C_a = 1 for a circle
    histories = {}
    for model in ("traction", "momentum_exchange"):
        for density in (FLUID_DENSITY, 2.0 * FLUID_DENSITY):
            try:
                velocity, displacement = sinking_history(density, model, steps)
            except Exception as error:  # noqa: BLE001 - a report of what happened
                print(f"{model}, rho_s = {density:g}: {error}")
                continue
            acceleration = np.diff(np.concatenate([[0.0], velocity])) / DT
            histories[(model, density)] = acceleration
            print(f"{model}, rho_s = {density:g}: a/g per step "
                  f"{np.array2string(acceleration[:12] / GRAVITY, precision=3)}; "
                  f"mean over {steps} steps {velocity[-1] / (steps * DT) / GRAVITY:.4f} g; "
                  f"displacement after 10 steps {displacement[9]:.3g} m")
    print(f"physical with added mass (C_a = 1), rho_s = 2 rho_f: {physical / GRAVITY:.4f} g")
    if plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        figure, axis = plt.subplots(figsize=(7, 4))
        for (model, density), acceleration in histories.items():
            axis.plot(np.arange(1, len(acceleration) + 1), acceleration / GRAVITY, "o-", ms=3,
                      label=f"{model}, rho_s/rho_f = {density / FLUID_DENSITY:g}")
        axis.axhline(-0.5, color="grey", ls="--", lw=0.8, label="(1 - rho_f/rho_s) g, first step")
        axis.axhline(physical / GRAVITY, color="k", ls=":", lw=0.8,
                     label="(rho_s - rho_f)/(rho_s + rho_f) g")
        axis.set_ylim(-1.6, 1.6)
        axis.set_xlabel("step (dt = 5 ms)")
        axis.set_ylabel("a_y / g of the centre of mass")
        axis.legend(fontsize=7)
        figure.tight_layout()
        from pathlib import Path

        out = Path(__file__).resolve().parents[2] / "docs" / "img" / "coupling_buoyancy.png"
        figure.savefig(out, dpi=110)
        print(f"wrote {out}")


if __name__ == "__main__":
    import sys

    _report("--plot" in sys.argv)
