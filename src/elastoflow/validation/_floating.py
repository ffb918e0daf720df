"""Bodies in water with a free surface (issue 15, item 2): Archimedes' draft and sinking.

A stiff elastic box (width 2 H, height H, E = 1 MPa) in a tank of water (0.8 x 0.4 m, water
0.2 m deep, free-slip walls, kinematic viscosity 1e-3 m^2/s, which damps the heave over
seconds), stepped by `FreeSurfaceMonolithicCoupling`:

* `run_floating` with ``density_ratio = 0.5``: the box is released at rest with its bottom
  ``release_draft`` below the surface (not the equilibrium), heaves and settles. Archimedes:
  at rest the draft ``d`` (surface height beside the box minus its bottom) is
  ``(rho_s / rho_f) H``. The measured draft is its mean over the last second; the surface
  height is the mean over the columns farther than ``H`` from the box.
* the same with ``density_ratio = 2``: the box sinks (its bottom's speed and the gap to the
  floor over time).

Run ``python -m elastoflow.validation._floating [cells per height ...]`` to rewrite the
floating block of ``docs/validation/free_surface.md`` and its plot ``floating.png``.
"""

from __future__ import annotations

import sys
import time as _time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

GRAVITY = 9.81
WATER_DENSITY = 1000.0
VISCOSITY = 1e-3
TANK = (0.8, 0.4)
WATER_DEPTH = 0.2
BODY_HEIGHT = 0.1
BODY_WIDTH = 0.2
YOUNG_MODULUS = 1e6


@dataclass
class FloatingRun:
    """One run: the box's bottom, the surface beside it and the water's area over time."""

    cells_per_height: int
    density_ratio: float
    dt: float
    times: np.ndarray
    bottoms: np.ndarray
    """Height [m] of the box's bottom (its nodes' mass-weighted mean minus H / 2)."""
    surfaces: np.ndarray
    """Mean surface height [m] over the columns farther than H from the box."""
    water_areas: np.ndarray
    seconds: float
    cells: tuple[int, int]
    iterations: np.ndarray
    failure: str | None = None

    @property
    def drafts(self) -> np.ndarray:
        return self.surfaces - self.bottoms

    def settled_draft(self, window: float = 2.0) -> float:
        """The mean draft [m] over the last ``window`` seconds."""
        last = self.times >= self.times[-1] - window
        return float(self.drafts[last].mean())

    def draft_spread(self, window: float = 2.0) -> float:
        """Peak-to-peak of the draft [m] over the last ``window`` seconds."""
        last = self.times >= self.times[-1] - window
        return float(np.ptp(self.drafts[last]))

    @property
    def archimedes(self) -> float:
        return self.density_ratio * BODY_HEIGHT


def build_floating(cells_per_height: int, density_ratio: float, *,
                   release_draft: float | None = None, dt: float | None = None):
    """The simulation of one box in the tank (`elastoflow.simulation.Simulation`) and the
    box's body; ``release_draft`` [m]: the bottom's depth below the surface at release
    (default: three quarters of Archimedes' draft, capped at the box's height)."""
    from elastoflow import fluid, solid
    from elastoflow.grid import Grid2D
    from elastoflow.simulation import FreeSurfaceMonolithicCoupling, Simulation

    h = BODY_HEIGHT / cells_per_height
    grid = Grid2D(nx=int(round(TANK[0] / h)), ny=int(round(TANK[1] / h)), h=h)
    walls = fluid.DomainBoundaries(left=fluid.WallFreeSlip(), right=fluid.WallFreeSlip(),
                                   bottom=fluid.WallFreeSlip(), top=fluid.WallFreeSlip())
    solver = fluid.FluidSolver(grid, density=WATER_DENSITY, viscosity=VISCOSITY,
                               boundaries=walls, gravity=(0.0, -GRAVITY),
                               advection="semi_lagrangian")
    surface = fluid.FreeSurfaceSolver(solver)
    if release_draft is None:
        release_draft = min(0.75 * density_ratio * BODY_HEIGHT, BODY_HEIGHT)
    bottom = WATER_DEPTH - release_draft
    mesh = solid.mesh_rectangle(BODY_WIDTH, BODY_HEIGHT, element_size=h,
                                origin=(0.5 * TANK[0] - 0.5 * BODY_WIDTH, bottom))
    body = solid.ElasticBody(
        mesh, solid.MaterialStVK(density_ratio * WATER_DENSITY, YOUNG_MODULUS, 0.3),
        gravity=(0.0, -GRAVITY))
    if dt is None:
        dt = 0.25 * h / np.sqrt(GRAVITY * BODY_HEIGHT)
    simulation = Simulation(grid, solver, bodies=[body], dt=dt,
                            coupling=FreeSurfaceMonolithicCoupling(surface),
                            level_set=fluid.level_set_below(grid, WATER_DEPTH))
    return simulation, body


def _surface_away_from(simulation, left: float, right: float) -> float:
    from elastoflow.fluid import FreeSurfaceState
    from elastoflow.validation._free_surface import surface_heights

    grid = simulation.grid
    state = FreeSurfaceState(simulation.state.fluid, simulation.level_set, 0.0)
    heights = surface_heights(state, grid)
    x = grid.origin[0] + (np.arange(grid.nx) + 0.5) * grid.h
    far = (x < left - BODY_HEIGHT) | (x > right + BODY_HEIGHT)
    return float(heights[far].mean())


def run_floating(cells_per_height: int, density_ratio: float = 0.5, duration: float = 4.0,
                 *, release_draft: float | None = None, dt: float | None = None,
                 progress: Callable[[str], None] | None = None) -> FloatingRun:
    """Run the box to ``duration`` [s] (or until a `SimulationBlowUp`)."""
    from elastoflow.fluid._free_surface_bodies import FreeSurfaceBodiesWorkspace, water_area
    from elastoflow.simulation import SimulationBlowUp

    simulation, body = build_floating(cells_per_height, density_ratio,
                                      release_draft=release_draft, dt=dt)
    weights = body.mass / body.mass.sum()
    workspace = FreeSurfaceBodiesWorkspace(simulation.grid)

    def measure() -> tuple[float, float, float]:
        positions = simulation.state.bodies[0].positions
        bottom = float(weights @ positions[:, 1]) - 0.5 * BODY_HEIGHT
        surface = _surface_away_from(simulation, float(positions[:, 0].min()),
                                     float(positions[:, 0].max()))
        boundary = simulation.state.boundary
        interior = None if boundary is None else boundary.interior
        area = water_area(simulation.level_set, interior, simulation.grid.h, workspace)
        return bottom, surface, area

    times, bottoms, surfaces, areas, iterations = [0.0], [], [], [], [0]
    first = measure()
    bottoms.append(first[0])
    surfaces.append(first[1])
    areas.append(np.nan)
    steps = int(round(duration / simulation.dt))
    failure = None
    began = _time.perf_counter()
    for step in range(steps):
        try:
            report = simulation.step()
        except SimulationBlowUp as error:
            failure = str(error)
            break
        bottom, surface, area = measure()
        times.append(simulation.time)
        bottoms.append(bottom)
        surfaces.append(surface)
        areas.append(area)
        iterations.append(report.pressure_iterations)
        if progress is not None and step % 100 == 0:
            progress(f"H/h = {cells_per_height}, ratio {density_ratio:g}: t = {times[-1]:.2f} "
                     f"s, draft = {surface - bottom:.5f} m, CG {report.pressure_iterations}")
    return FloatingRun(cells_per_height, density_ratio, float(simulation.dt), np.array(times),
                       np.array(bottoms), np.array(surfaces), np.array(areas),
                       _time.perf_counter() - began, simulation.grid.shape_cells,
                       np.array(iterations), failure)


def plot_floating(floating: list[FloatingRun], sinking: list[FloatingRun], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, (left, right) = plt.subplots(1, 2, figsize=(11, 4))
    for run in floating:
        left.plot(run.times, run.drafts / BODY_HEIGHT, label=f"H/h = {run.cells_per_height}")
    if floating:
        ratio = floating[0].density_ratio
        left.axhline(ratio, color="k", linestyle="--", label=f"Archimedes ({ratio:g} H)")
        left.axhspan(ratio - 0.01, ratio + 0.01, color="grey", alpha=0.2, label="+-1 % of H")
    left.set_xlabel("t [s]")
    left.set_ylabel("draft / H")
    left.set_title("box of density 0.5 released at 3/4 of its draft")
    left.legend(fontsize=8)
    for run in sinking:
        right.plot(run.times, (run.bottoms - run.bottoms[0]) / BODY_HEIGHT,
                   label=f"H/h = {run.cells_per_height}, ratio {run.density_ratio:g}")
    right.set_xlabel("t [s]")
    right.set_ylabel("bottom's displacement / H")
    right.set_title("box of density 2: sinks")
    right.legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)


BEGIN, END = "<!-- floating:begin -->", "<!-- floating:end -->"
NOTES = """\
What the numbers say: the heave converges with the grid (the two curves of the plot lie on
each other) and decays slowly: by 6 s the box still bobs by about +-2 % of H (the waves it
sends out come back from the tank's walls; nu = 1e-3 damps them over seconds, nu = 1e-2 made
the explicit viscous traction invert an element at 0.6 s). Its mean draft over the last 2 s
is within 0.2 % of H of Archimedes' at both resolutions, and a box placed at Archimedes'
draft stays there (H/h = 10, 3 s: mean draft over the last 2 s 0.5001 H). Without the exact
hydrostatic integral below the surface (`FreeSurfaceCoupledBodies`; the interface flux W
alone applies a cut cell's centre pressure to the whole flat bottom) the same run settles at
0.5106 H, 1.06 % of H too deep. The level set inside the box is the value
just outside its nearest face, extended inwards (`carry_level_set_across_bodies`; a linear
extrapolation put wrong-signed values inside the heaving box and carried water onto its top,
and the harmonic extension used until 2026-12-03 left a film on the dry face of a gate that
holds water on one side). The sinking box's start, 2.6-2.7 m/s^2, means an added mass of
about 31 kg/m, that of a flat plate of the box's width (pi rho (W/2)^2 = 31.4 kg/m); it then
rests on the floor (wall contact, docs/method_notes.md item 15).

A box of density 0.3 released 5 cm under the surface rises through it and carries a layer of
water on its top, which then runs off both edges. Earlier pages called the layer a fault
("should drain off in a few tenths of a second"). Measured (2026-12-03, H/h = 10, area of
the layer over the box per metre of depth; `/tmp` script, not a library command): 5.3e-3 m^2
(2.6 cm deep) when the top clears the surface at 0.4 s, 3.0e-3 m^2 at 0.9 s, 0.9e-3 m^2
(4 mm) at 1.3 s, before the bobbing box dips and wets its top again. Over 0.4-0.9 s that is
4.5e-3 m^2/s off the two edges (nu = 1e-6 instead of 1e-3: 4.8e-3; H/h = 20: 3.7e-3). A
layer ending at an edge drains as a dam break over a dry bed: the flow at the edge is
critical, depth 4/9 h0 at speed 2/3 sqrt(g h0), flux (8/27) sqrt(g) h0^(3/2) per edge
(Ritter); with the layer's mean depth over that half second, 2.0 cm, that is 5.3e-3
m^2/s for the two edges, and the layer would take about 1.7 s to thin from 2.6 cm to 5 mm
at that flux. The layer here drains at 70-90 % of that flux and thins to 4 mm in 0.9 s (the
box's bobbing helps): its slow drainage is the physics of a thin layer on a flat top, not a
fault. A box dropped in from above stays dry on top (the tests)."""


def sinking_acceleration(run: FloatingRun, duration: float = 0.05) -> float:
    """The bottom's mean acceleration [m/s^2] over the first ``duration`` [s] (from rest:
    ``2 s / t^2``)."""
    early = np.flatnonzero(run.times <= duration)[-1]
    return float(2.0 * (run.bottoms[early] - run.bottoms[0]) / run.times[early] ** 2)


def floating_block(floating: list[FloatingRun], sinking: list[FloatingRun],
                   machine: str) -> str:
    lines = [BEGIN, "", "## Bodies in the water: Archimedes' draft, a body that sinks", "",
             "Generated by `python -m elastoflow.validation._floating` "
             "(`elastoflow.validation._floating`). A stiff elastic box (width 2 H, height "
             f"H = {BODY_HEIGHT:g} m, E = {YOUNG_MODULUS:g} Pa) in a tank {TANK[0]:g} m x "
             f"{TANK[1]:g} m with water {WATER_DEPTH:g} m deep, free-slip walls, nu = "
             f"{VISCOSITY:g} m^2/s, `FreeSurfaceMonolithicCoupling` (semi-Lagrangian "
             "advection, dt = h / (4 sqrt(g H))). The draft is the mean surface height over the "
             "columns more than H from the box minus the box's bottom (its nodes' mass-weighted "
             "mean height minus H / 2).", "",
             "**Floating** (density 0.5 of the water's; released at rest with 3/4 of its "
             "draft under water). Archimedes: draft = 0.5 H. Settled draft: the mean over the "
             "last 2 s; the residual bobbing: its peak-to-peak there.", "",
             "| H/h | grid | steps | settled draft / H | error (of H) | peak-to-peak / H | "
             "water area change | max CG | run time [s] |",
             "|---|---|---|---|---|---|---|---|---|"]
    for run in floating:
        nx, ny = run.cells
        area = run.water_areas[1:]
        change = (area[-1] - area[0]) / area[0]
        lines.append(
            f"| {run.cells_per_height} | {nx}x{ny} | {len(run.times) - 1} | "
            f"{run.settled_draft() / BODY_HEIGHT:.4f} | "
            f"{100 * (run.settled_draft() - run.archimedes) / BODY_HEIGHT:+.2f} % | "
            f"{run.draft_spread() / BODY_HEIGHT:.4f} | {change:.1e} | "
            f"{int(run.iterations.max())} | {run.seconds:.0f} |"
            + (" (stopped)" if run.failure else ""))
    lines += ["", "**Sinking** (density 2; released at rest just under the surface). Its "
              "bottom's mean acceleration over the first 0.05 s against potential flow's "
              "start, (rho_s - rho_f) / (rho_s + C_a rho_f) g, which for this box lies below "
              "the no-added-mass bound g / 2:", "",
              "| H/h | acceleration [m/s^2] | g / 2 | bottom moved by t = end [H] |",
              "|---|---|---|---|"]
    for run in sinking:
        lines.append(
            f"| {run.cells_per_height} | {-sinking_acceleration(run):.3f} | "
            f"{0.5 * GRAVITY:.3f} | {(run.bottoms[-1] - run.bottoms[0]) / BODY_HEIGHT:+.3f} "
            f"(t = {run.times[-1]:.2f} s) |")
    failures = [run for run in floating + sinking if run.failure]
    lines += [""] + [f"H/h = {run.cells_per_height}, ratio {run.density_ratio:g} stopped: "
                     f"{run.failure}" for run in failures]
    lines += ["", f"Machine: {machine}.", "", "![floating](floating.png)", "", NOTES, "", END]
    return "\n".join(lines)


def write_floating(floating: list[FloatingRun], sinking: list[FloatingRun], folder: Path,
                   machine: str) -> Path:
    """The plot and the block of ``folder / free_surface.md`` (replaced between its markers,
    else appended)."""
    plot_floating(floating, sinking, folder / "floating.png")
    from elastoflow.validation._report import replace_block

    return replace_block(folder / "free_surface.md", floating_block(floating, sinking, machine),
                         BEGIN, END, before=None)


def main(argv: list[str]) -> None:
    import platform

    resolutions = [int(a) for a in argv] or [10, 20]
    machine = f"{platform.machine()}, {platform.processor() or 'cpu'}, 2 cores"

    def progress(line: str) -> None:
        print(line, flush=True)

    sinking = [run_floating(n, 2.0, duration=0.15, release_draft=BODY_HEIGHT,
                            progress=progress) for n in resolutions]
    floating: list[FloatingRun] = []
    for n in resolutions:
        floating.append(run_floating(n, 0.5, duration=6.0, progress=progress))
        print(write_floating(floating, sinking, Path("docs/validation"), machine), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
