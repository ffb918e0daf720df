"""Probes: time series sampled between steps, saved as CSV with a PNG plot."""

from __future__ import annotations

import csv
import io
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from elastoflow.io._atomic import atomic_path, write_text_atomic

Sampler = Callable[[Any, Any], list[float]]


def _node_displacement(body: int, node: int) -> tuple[list[str], Sampler]:
    def sample(sim: Any, report: Any) -> list[float]:
        b = sim.bodies[body]
        d = b.positions[node] - b.mesh.points[node]
        return [float(d[0]), float(d[1])]

    prefix = f"body{body}_node{node}_displacement"
    return [f"{prefix}_x [m]", f"{prefix}_y [m]"], sample


def _body_force(body: int) -> tuple[list[str], Sampler]:
    def sample(sim: Any, report: Any) -> list[float]:
        total = np.asarray(sim.body_forces[body]).sum(axis=0)
        return [float(total[0]), float(total[1])]

    return [f"body{body}_force_x [N/m]", f"body{body}_force_y [N/m]"], sample


def _kinetic_energy(body: int | None) -> tuple[list[str], Sampler]:
    if body is not None:
        def sample_body(sim: Any, report: Any) -> list[float]:
            b = sim.bodies[body]
            return [0.5 * float(np.dot(b.mass, (b.velocities**2).sum(axis=1)))]

        return [f"body{body}_kinetic_energy [J/m]"], sample_body

    def sample_fluid(sim: Any, report: Any) -> list[float]:
        state, h = sim.state, sim.grid.h
        density = sim.fluid_solver.density
        energy = 0.5 * density * h * h * (np.sum(state.velocity_x**2) + np.sum(state.velocity_y**2))
        return [float(energy)]

    return ["fluid_kinetic_energy [J/m]"], sample_fluid


def _pressure_iterations() -> tuple[list[str], Sampler]:
    def sample(sim: Any, report: Any) -> list[float]:
        return [float(report.pressure_iterations) if report is not None else float("nan")]

    return ["pressure_iterations"], sample


def _resolve_node(sim: Any, spec: Any) -> int:
    if spec.node is not None:
        return int(spec.node)
    points = sim.bodies[spec.body].mesh.points
    return int(np.argmin(np.linalg.norm(points - np.asarray(spec.point, float), axis=1)))


class ProbeRecorder:
    """Samples the probes of a scene after each step and writes ``probes.csv`` / ``probes.png``.

    Args:
        probes: `elastoflow.scenes.ProbeSpec` items (kind, body, node or point).
        simulation: The running `Simulation` (bodies are looked up once).
        path: CSV file; the plot goes beside it with suffix ``.png``.
        resume_step: Keep the rows of an existing CSV up to this step (a resumed run).
    """

    def __init__(self, probes: Sequence[Any], simulation: Any, path: str | Path,
                 resume_step: int | None = None) -> None:
        self.path = Path(path)
        self.columns: list[str] = ["step", "time [s]"]
        self._samplers: list[Sampler] = []
        makers: dict[str, Callable[[Any], tuple[list[str], Sampler]]] = {
            "node_displacement": lambda s: _node_displacement(s.body, _resolve_node(simulation, s)),
            "body_force": lambda s: _body_force(s.body),
            "kinetic_energy": lambda s: _kinetic_energy(s.body),
            "pressure_iterations": lambda s: _pressure_iterations(),
        }
        for spec in probes:
            names, sampler = makers[spec.kind](spec)
            self.columns.extend(names)
            self._samplers.append(sampler)
        self.rows: list[list[float]] = []
        if resume_step is not None and self.path.exists():
            self.rows = [row for row in read_probes(self.path)[1] if row[0] <= resume_step]

    def record(self, simulation: Any, report: Any = None) -> None:
        """Append one row: step, time and every probe's values."""
        row = [float(simulation.step_index), float(simulation.time)]
        for sampler in self._samplers:
            row.extend(sampler(simulation, report))
        self.rows.append(row)

    def write_csv(self) -> Path:
        """Write all rows so far (atomically)."""
        buffer = io.StringIO()
        writer = csv.writer(buffer)
        writer.writerow(self.columns)
        for row in self.rows:
            writer.writerow([int(row[0]), *(f"{v:.10g}" for v in row[1:])])
        write_text_atomic(self.path, buffer.getvalue())
        return self.path

    def plot(self) -> Path | None:
        """One panel per probe column against time, saved as PNG (matplotlib, Agg)."""
        if not self.rows or len(self.columns) <= 2:
            return None
        return plot_probes(self.columns, np.asarray(self.rows), self.path.with_suffix(".png"))


def read_probes(path: str | Path) -> tuple[list[str], list[list[float]]]:
    """Columns and rows of a probes CSV."""
    with open(path, newline="") as handle:
        reader = csv.reader(handle)
        columns = next(reader)
        rows = [[float(v) for v in row] for row in reader if row]
    return columns, rows


def plot_probes(columns: list[str], data: np.ndarray, path: str | Path) -> Path:
    """Plot every column after the first two (step, time) against time; PNG, atomically."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    names = columns[2:]
    figure, axes = plt.subplots(len(names), 1, figsize=(7, 1.8 * len(names) + 0.6), sharex=True,
                                squeeze=False)
    for k, name in enumerate(names):
        axis = axes[k, 0]
        axis.plot(data[:, 1], data[:, 2 + k], lw=1.2)
        axis.set_ylabel(name, fontsize=8)
        axis.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time [s]")
    figure.tight_layout()
    with atomic_path(path) as temporary:
        figure.savefig(temporary, dpi=100, format="png")
    plt.close(figure)
    return Path(path)


def write_rows_csv(path: str | Path, columns: list[str], rows: list[list[float]]) -> None:
    """A plain CSV of ``rows`` under ``columns`` (atomically)."""
    buffer = io.StringIO()
    csv.writer(buffer).writerows([columns, *rows])
    write_text_atomic(path, buffer.getvalue())
