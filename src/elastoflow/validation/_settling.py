"""A sphere settling in a box of oil: ten Cate et al. (2002), case E1, from the library scene.

The scene ``sphere_settling`` (elastic sphere, monolithic coupling, closed no-slip box) is run
at a given number of cells per diameter; the sphere's velocity is its nodes' mean velocity
(mass-weighted: the lumped masses), its position the same mean of the nodes. Published: the
sphere reaches ``u_max = 0.036 m/s`` in the box (ten Cate's measurement; the unbounded
terminal velocity from the Abraham correlation is 0.038 m/s), then slows as it nears the
floor.

Run ``python -m elastoflow.validation._settling [cells per diameter ...] [--scheme explicit |
monolithic]`` to rewrite the settling block of ``docs/validation/three_d.md`` and its plot.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

# ../shared/reference/three_d.json, tencate2002_settling_sphere, case E1.
U_MAX_MEASURED = 0.035986
U_INFINITE = 0.038
DIAMETER = 0.015
# u_max is read while the gap to the floor exceeds this many diameters: ten Cate's sphere
# reaches its top speed above it and slows in the floor's lubrication region below.
FREE_GAP = 2.0


@dataclass
class SettlingRun:
    """One run: time [s], the sphere's settling speed [m/s], gap to the floor [m] (its
    centre of mass less the radius) and its lowest node's height above the floor [m] (wall
    contact keeps it >= 0)."""

    cells_per_diameter: float
    times: np.ndarray
    speeds: np.ndarray
    gaps: np.ndarray
    lowest: np.ndarray
    seconds: float
    cells: tuple[int, int, int]
    tetrahedra: int
    scheme: str
    failure: str | None = None
    """Why the run stopped early (a `SimulationBlowUp`'s message), None if it did not."""

    @property
    def _free(self) -> np.ndarray:
        """Steps more than two diameters above the floor (before the floor slows it)."""
        return self.gaps > FREE_GAP * DIAMETER

    @property
    def u_max(self) -> float:
        """The largest speed while more than two diameters above the floor."""
        return float(self.speeds[self._free].max())

    @property
    def late_rms(self) -> float:
        """Root mean square of the speed over the run's last half second [m/s] (at rest on
        the floor: near 0)."""
        late = self.times > self.times[-1] - 0.5
        return float(np.sqrt(np.mean(self.speeds[late] ** 2)))

    @property
    def time_of_u_max(self) -> float:
        free = np.flatnonzero(self._free)
        return float(self.times[free[int(np.argmax(self.speeds[free]))]])


def run_settling(cells_per_diameter: float = 6.0, duration: float = 4.0, dt: float = 0.01,
                 progress: Callable[[str], None] | None = None,
                 scheme: str | None = None, viscosity_factor: float = 1.0) -> SettlingRun:
    """The library scene at ``cells_per_diameter`` to ``duration`` [s] with step ``dt``, with
    its own coupling scheme or ``scheme`` ("explicit", "monolithic"), in an oil
    ``viscosity_factor`` times as viscous as ten Cate's.

    The box (100 x 160 x 100 mm) must be a whole number of cells: h = 20 mm / k, i.e. 0.75 k
    cells per diameter (4.5, 6, 7.5, 9, ...)."""
    from elastoflow.scenes import build_simulation, get_scene, parse_scene, scene_to_toml

    scene = get_scene("sphere_settling")
    import tomllib

    data = tomllib.loads(scene_to_toml(scene))
    h = DIAMETER / cells_per_diameter
    data["domain"]["h"] = h
    data["bodies"][0]["shape"]["element_size"] = h
    data["time"] = {"dt": dt, "duration": duration}
    data["outputs"] = {}
    data["fluid"]["viscosity"] *= viscosity_factor
    if scheme is not None:
        # The scheme alone: the scene's other coupling keys (its numerical damping) stay.
        data["coupling"] = {**data.get("coupling", {}), "scheme": scheme}
    from elastoflow.simulation import CoupledModel3D

    simulation = build_simulation(parse_scene(data, source="sphere_settling"))
    model = simulation.model
    assert isinstance(model, CoupledModel3D)
    body = model.bodies[0]
    mass = body.mass / body.mass.sum()
    radius = 0.5 * DIAMETER
    floor = float(simulation.grid.origin[1])
    steps = int(round(duration / dt))
    times, speeds, gaps, lowest = [0.0], [0.0], [], []
    state = simulation.state.bodies[0]
    gaps.append(float(mass @ state.positions[:, 1]) - radius - floor)
    lowest.append(float(state.positions[:, 1].min()) - floor)
    from elastoflow.validation._report import step_and_record

    def record(step: int) -> None:
        state = simulation.state.bodies[0]
        times.append(simulation.time)
        speeds.append(-float(mass @ state.velocities[:, 1]))
        gaps.append(float(mass @ state.positions[:, 1]) - radius - floor)
        lowest.append(float(state.positions[:, 1].min()) - floor)
        if progress is not None and (step % 20 == 0 or step == steps - 1):
            progress(f"D/h = {cells_per_diameter:g}: t = {times[-1]:.2f} s, u = "
                     f"{speeds[-1]:.4f} m/s, gap/D = {gaps[-1] / DIAMETER:.2f}")

    failure, seconds = step_and_record(simulation, steps, record)
    return SettlingRun(cells_per_diameter, np.array(times), np.array(speeds), np.array(gaps),
                       np.array(lowest), seconds, model.grid.shape_cells, body.mesh.tetrahedron_count,
                       simulation.scheme.name, failure)


def write_series(runs: list[SettlingRun], path: Path) -> None:
    """The runs' time series as CSV: resolution, t [s], speed [m/s], gap [m], lowest node's
    height [m]."""
    from elastoflow.io import write_rows_csv

    rows = [[run.cells_per_diameter, t, u, g, z] for run in runs
            for t, u, g, z in zip(run.times, run.speeds, run.gaps, run.lowest, strict=True)]
    write_rows_csv(path, ["cells_per_diameter", "t [s]", "speed [m/s]", "gap [m]",
                          "lowest node [m]"], rows)


def plot_settling(runs: list[SettlingRun], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
    for run in runs:
        label = f"D/h = {run.cells_per_diameter:g}, {run.scheme}"
        left.plot(run.times, run.speeds, label=label)
        right.plot(run.times, run.gaps / DIAMETER, label=label)
    left.axhline(U_MAX_MEASURED, color="k", linestyle="--", label="ten Cate u_max (0.036)")
    left.set_ylim(-0.06, 0.08)  # negative: upwards (a sphere chattering on the floor)
    left.axhline(U_INFINITE, color="grey", linestyle=":", label="u_inf (Abraham, 0.038)")
    left.set_xlabel("t [s]")
    left.set_ylabel("settling speed [m/s]")
    left.legend(fontsize=8)
    right.set_xlabel("t [s]")
    right.set_ylabel("gap to the floor / D")
    right.legend(fontsize=8)
    figure.suptitle("Sphere settling in a box, ten Cate et al. (2002) E1 (Re 1.5)")
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)


BEGIN, END = "<!-- settling:begin -->", "<!-- settling:end -->"


def settling_block(runs: list[SettlingRun], machine: str) -> str:
    lines = [BEGIN, "", "## A sphere settling in a box (ten Cate et al. 2002, E1)", "",
             "The library scene `sphere_settling`: a 15 mm elastic sphere (1120 kg/m^3, "
             "E = 100 kPa) released from rest 8 diameters above the floor of a closed "
             "100 x 160 x 100 mm box of oil (970 kg/m^3, 0.373 Pa s; Re 1.5), dt = 0.01 s, "
             "with the coupling scheme of each row (the scene's own: monolithic). The "
             "sphere's speed is its nodes' "
             "mass-weighted mean velocity. Published: ten Cate measured u_max = 0.0360 m/s "
             "in the box (u_inf = 0.038 m/s unbounded, from the Abraham correlation).", "",
             "u_max here is the largest speed while the sphere is more than two diameters "
             "above the floor (the series: `three_d_settling.csv`). The sphere lands on the "
             "floor through the wall contact (`coupling.wall_contact`, on by default): "
             "the lowest node's height over the run is never below 0. Whether it then "
             "rests: the speed's root mean square over the last half second (the scene's "
             "numerical damping 1 keeps it from chattering on its lowest node, "
             "docs/method_notes.md item 15).", "",
             "| D/h | scheme | cells | tetrahedra | u_max [m/s] | vs 0.0360 | at t [s] | "
             "end: t [s], gap/D | lowest node over the run / D | speed rms, last 0.5 s "
             "[m/s] | run time [s] |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for run in runs:
        nx, ny, nz = run.cells
        end = f"{run.times[-1]:.2f}, {run.gaps[-1] / DIAMETER:.2f}"
        if run.failure is not None:
            end += " (diverged)"
        lines.append(
            f"| {run.cells_per_diameter:g} | {run.scheme} | {nx}x{ny}x{nz} | {run.tetrahedra} | "
            f"{run.u_max:.4f} | {100 * (run.u_max / U_MAX_MEASURED - 1):+.1f} % | "
            f"{run.time_of_u_max:.2f} | {end} | {run.lowest.min() / DIAMETER:.3g} | "
            f"{run.late_rms:.2g} | {run.seconds:.0f} |")
    failures = [run for run in runs if run.failure is not None]
    if failures:
        lines += [""] + [f"D/h = {run.cells_per_diameter:g} stopped: {run.failure}"
                         for run in failures]
    schemes = sorted({run.scheme for run in runs})
    flag = f" --scheme {schemes[0]}" if len(schemes) == 1 else ""
    lines += ["", f"Machine: {machine}. Command: `python -m elastoflow.validation._settling "
              f"{' '.join(f'{r.cells_per_diameter:g}' for r in runs)}{flag}`.", "",
              "![settling](three_d_settling.png)", "", END]
    return "\n".join(lines)


def write_settling(runs: list[SettlingRun], folder: Path, machine: str) -> Path:
    plot_settling(runs, folder / "three_d_settling.png")
    write_series(runs, folder / "three_d_settling.csv")
    from elastoflow.validation._report import replace_block

    return replace_block(folder / "three_d.md", settling_block(runs, machine), BEGIN, END)


def main(argv: list[str]) -> None:
    import platform

    scheme = None
    if "--scheme" in argv:
        at = argv.index("--scheme")
        scheme = argv[at + 1]
        argv = argv[:at] + argv[at + 2:]
    resolutions = [float(a) for a in argv] or [6.0]
    machine = f"{platform.machine()}, {platform.processor() or 'cpu'}, 2 cores"
    runs = []
    for n in resolutions:
        runs.append(run_settling(n, progress=lambda line: print(line, flush=True),
                                 scheme=scheme))
        # Written after each run: a long study keeps what it has finished.
        print(write_settling(runs, Path("docs/validation"), machine), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
