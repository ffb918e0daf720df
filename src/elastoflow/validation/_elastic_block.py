"""A soft block clamped to a channel's floor, bent by the flow: Richter's 3D benchmark in the
form solids4foam ships, from the library scene ``elastic_block_3d``.

The block is as dense as the water, so only the monolithic coupling runs it. Published (the
solids4foam tutorial's README, citing Tukovic et al. 2018, Fig. 28): point A on the block's
upstream face moves by (14.63, 5.0, -0.447) mm at steady state. Their solid is neo-Hookean;
ours is St. Venant-Kirchhoff, the same law to first order in the strain (the block's strains
are a few per cent).

Run ``python -m elastoflow.validation._elastic_block [cell size in mm ...]`` to rewrite the
block's section of ``docs/validation/three_d.md`` and its plot.
"""

from __future__ import annotations

import sys
import time as _time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

# ../shared/reference/three_d.json, richter_3d_elastic_block_in_channel,
# modified_form_solids4foam.expected_steady_displacement_point_A_m.
PUBLISHED_A = np.array([0.01463, 0.005, -0.000447])
# The last stretch of the run over which the displacement is averaged [s].
STEADY_WINDOW = 1.0


@dataclass
class BlockRun:
    """One run: times [s] and point A's displacement [m], (k, 3)."""

    cell_size: float
    times: np.ndarray
    displacements: np.ndarray
    seconds: float
    cells: tuple[int, int, int]
    tetrahedra: int
    failure: str | None = None

    @property
    def steady(self) -> np.ndarray:
        """Mean displacement over the last `STEADY_WINDOW` seconds, (3,)."""
        window = self.times >= self.times[-1] - STEADY_WINDOW
        return np.asarray(self.displacements[window].mean(axis=0))

    @property
    def swing(self) -> float:
        """Peak-to-peak x displacement over the same window [m]: how far from steady."""
        window = self.times >= self.times[-1] - STEADY_WINDOW
        return float(np.ptp(self.displacements[window, 0]))


def run_block(cell_size: float = 0.025, duration: float = 5.0, dt: float = 0.02,
              progress: Callable[[str], None] | None = None) -> BlockRun:
    """The library scene with cells (and elements) of ``cell_size`` [m] to ``duration`` [s]."""
    import tomllib

    from elastoflow.scenes import build_simulation, get_scene, parse_scene, scene_to_toml
    from elastoflow.scenes._library import ELASTIC_BLOCK_3D
    from elastoflow.simulation import SimulationBlowUp

    data = tomllib.loads(scene_to_toml(get_scene("elastic_block_3d")))
    data["domain"]["h"] = cell_size
    data["bodies"][0]["shape"]["element_size"] = cell_size
    data["time"] = {"dt": dt, "duration": duration}
    data["outputs"] = {}
    from elastoflow.simulation import CoupledModel3D

    simulation = build_simulation(parse_scene(data, source="elastic_block_3d"))
    model = simulation.model
    assert isinstance(model, CoupledModel3D)
    body = model.bodies[0]
    rest = body.mesh.points
    point = int(np.argmin(np.linalg.norm(rest - np.asarray(ELASTIC_BLOCK_3D["point_a"]), axis=1)))
    steps = int(round(duration / dt))
    times, displacements = [0.0], [np.zeros(3)]
    began = _time.perf_counter()
    failure = None
    for step in range(steps):
        try:
            simulation.step()
        except SimulationBlowUp as error:
            failure = str(error)
            break
        times.append(simulation.time)
        displacements.append(simulation.state.bodies[0].positions[point] - rest[point])
        if progress is not None and (step % 25 == 0 or step == steps - 1):
            d = 1000.0 * displacements[-1]
            progress(f"h = {cell_size:g} m: t = {times[-1]:.2f} s, A moved ({d[0]:.2f}, "
                     f"{d[1]:.2f}, {d[2]:.3f}) mm")
    return BlockRun(cell_size, np.array(times), np.array(displacements),
                    _time.perf_counter() - began, model.grid.shape_cells,
                    body.mesh.tetrahedron_count, failure)


def plot_block(runs: list[BlockRun], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(1, 3, figsize=(13, 4))
    for component, axis in enumerate(axes):
        for run in runs:
            axis.plot(run.times, 1000.0 * run.displacements[:, component],
                      label=f"h = {1000 * run.cell_size:g} mm")
        axis.axhline(1000.0 * PUBLISHED_A[component], color="k", linestyle="--",
                     label="solids4foam steady")
        axis.set_xlabel("t [s]")
        axis.set_ylabel(f"point A, {'xyz'[component]} displacement [mm]")
        axis.legend(fontsize=8)
    figure.suptitle("Elastic block in a channel (Richter 3D, solids4foam form), point A")
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)


BEGIN, END = "<!-- elastic-block:begin -->", "<!-- elastic-block:end -->"


def block_section(runs: list[BlockRun], machine: str) -> str:
    lines = [BEGIN, "", "## A soft block bent by a channel flow (Richter 3D, solids4foam form)", "",
             "The library scene `elastic_block_3d`: a 0.1 x 0.2 x 0.4 m block (E = 10 kPa, "
             "Poisson 0.4, 1000 kg/m^3: as dense as the water) clamped to the floor of a "
             "1.5 x 0.4 x 0.8 m channel, paraboloid inflow of 0.3 m/s at the centre reached "
             "in 1 s (Re 60 on the block's height), monolithic coupling, dt = 0.02 s. "
             "Published (solids4foam's tutorial, Tukovic et al. 2018 Fig. 28; neo-Hookean "
             "solid, ours St. Venant-Kirchhoff): point A (0.45, 0.15, -0.15) m, here "
             "z + 0.4, moves by (14.63, 5.0, -0.447) mm at steady state. Our numbers: the "
             f"mean over the last {STEADY_WINDOW:g} s of the run, and the x swing there.", "",
             "| h [mm] | cells | tetrahedra | A: x [mm] | vs 14.63 | y [mm] | z [mm] | "
             "x swing [mm] | t end [s] | run time [s] |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for run in runs:
        nx, ny, nz = run.cells
        mean = 1000.0 * run.steady
        end = f"{run.times[-1]:.2f}" + (" (diverged)" if run.failure else "")
        lines.append(
            f"| {1000 * run.cell_size:g} | {nx}x{ny}x{nz} | {run.tetrahedra} | {mean[0]:.2f} | "
            f"{100 * (mean[0] / (1000 * PUBLISHED_A[0]) - 1):+.1f} % | {mean[1]:.2f} | "
            f"{mean[2]:.3f} | {1000 * run.swing:.2f} | {end} | {run.seconds:.0f} |")
    for run in runs:
        if run.failure is not None:
            lines += ["", f"h = {run.cell_size:g} m stopped: {run.failure}"]
    lines += ["", f"Machine: {machine}. Command: `python -m elastoflow.validation._elastic_block "
              f"{' '.join(f'{1000 * r.cell_size:g}' for r in runs)}`.", "",
              "![elastic block](three_d_elastic_block.png)", "", END]
    return "\n".join(lines)


def write_block(runs: list[BlockRun], folder: Path, machine: str) -> Path:
    plot_block(runs, folder / "three_d_elastic_block.png")
    from elastoflow.validation._report import replace_block

    return replace_block(folder / "three_d.md", block_section(runs, machine), BEGIN, END)


def main(argv: list[str]) -> None:
    import platform

    sizes = [float(a) / 1000.0 for a in argv] or [0.025]
    machine = f"{platform.machine()}, {platform.processor() or 'cpu'}, 2 cores"
    runs = []
    for size in sizes:
        runs.append(run_block(size, progress=lambda line: print(line, flush=True)))
        # Written after each run: a long study keeps what it has finished.
        print(write_block(runs, Path("docs/validation"), machine), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
