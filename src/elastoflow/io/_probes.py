"""Probes: time series sampled between steps, saved as CSV with a PNG plot."""

from __future__ import annotations

import contextlib
import csv
import itertools
import json
import errno
import io
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from elastoflow.io._atomic import atomic_path, write_text_atomic

Sampler = Callable[[Any, Any], list[float]]


def _axes(dimension: int) -> str:
    return "xyz"[:dimension]


def _force_unit(dimension: int) -> str:
    """Forces of a 2D run are per metre of depth."""
    return "N" if dimension == 3 else "N/m"


def _node_displacement(body: int, node: int, dimension: int) -> tuple[list[str], Sampler]:
    def sample(sim: Any, report: Any) -> list[float]:
        d = sim.state.bodies[body].positions[node] - sim.bodies[body].mesh.points[node]
        return [float(value) for value in d]

    prefix = f"body{body}_node{node}_displacement"
    return [f"{prefix}_{axis} [m]" for axis in _axes(dimension)], sample


def _body_force(body: int, dimension: int) -> tuple[list[str], Sampler]:
    def sample(sim: Any, report: Any) -> list[float]:
        total = np.asarray(sim.body_forces[body]).sum(axis=0)
        return [float(value) for value in total]

    unit = _force_unit(dimension)
    return [f"body{body}_force_{axis} [{unit}]" for axis in _axes(dimension)], sample


def _kinetic_energy(body: int | None) -> tuple[list[str], Sampler]:
    if body is not None:
        def sample_body(sim: Any, report: Any) -> list[float]:
            return [sim.bodies[body].kinetic_energy(sim.state.bodies[body])]

        return [f"body{body}_kinetic_energy [J/m]"], sample_body

    def sample_fluid(sim: Any, report: Any) -> list[float]:
        state, h = sim.state.fluid, sim.grid.h
        density = sim.fluid_solver.density
        level_set = getattr(sim, "level_set", None)
        if level_set is None:
            squares = np.sum(state.velocity_x**2) + np.sum(state.velocity_y**2)
        else:
            # A free surface: the faces with liquid on a side (the air's velocity is only
            # extrapolated).
            liquid = np.asarray(level_set) < 0.0
            faces_x = np.zeros(state.velocity_x.shape, dtype=bool)
            faces_x[:-1] |= liquid
            faces_x[1:] |= liquid
            faces_y = np.zeros(state.velocity_y.shape, dtype=bool)
            faces_y[:, :-1] |= liquid
            faces_y[:, 1:] |= liquid
            squares = (np.sum(state.velocity_x[faces_x] ** 2)
                       + np.sum(state.velocity_y[faces_y] ** 2))
        return [float(0.5 * density * h * h * squares)]

    return ["fluid_kinetic_energy [J/m]"], sample_fluid


def _pressure_iterations() -> tuple[list[str], Sampler]:
    def sample(sim: Any, report: Any) -> list[float]:
        return [float(report.pressure_iterations) if report is not None else float("nan")]

    return ["pressure_iterations"], sample


def _targets(spec: Any) -> tuple[list[int], list[int], str]:
    label = "+".join([f"body{i}" for i in spec.bodies] + [f"obstacle{i}" for i in spec.obstacles])
    return list(spec.bodies), list(spec.obstacles), label


def _traction_on(sim: Any, bodies: list[int], obstacles: list[int]
                 ) -> list[tuple[np.ndarray, np.ndarray]]:
    """(points, nodal forces) of each chosen object, the fluid's traction on it."""
    forces = sim.traction_forces()
    count = len(sim.bodies)
    chosen = [(sim.state.bodies[i].positions, forces[i]) for i in bodies]
    chosen += [(sim.obstacles[i].points_at(sim.time), forces[count + i]) for i in obstacles]
    return chosen


def _force(spec: Any, dimension: int) -> tuple[list[str], Sampler]:
    bodies, obstacles, label = _targets(spec)

    def sample(sim: Any, report: Any) -> list[float]:
        total = np.zeros(dimension)
        for _, force in _traction_on(sim, bodies, obstacles):
            total += force.sum(axis=0)
        return [float(value) for value in total]

    unit = _force_unit(dimension)
    return [f"force_{label}_{axis} [{unit}]" for axis in _axes(dimension)], sample


def _torque(spec: Any) -> tuple[list[str], Sampler]:
    bodies, obstacles, label = _targets(spec)
    about = np.asarray(spec.about, dtype=np.float64)

    def sample(sim: Any, report: Any) -> list[float]:
        total = 0.0
        for points, force in _traction_on(sim, bodies, obstacles):
            arm = points - about
            total += float(np.sum(arm[:, 0] * force[:, 1] - arm[:, 1] * force[:, 0]))
        return [total]

    return [f"torque_{label} [N]"], sample


def _interpolate(values: np.ndarray, corner: Sequence[float] | np.ndarray, h: float,
                 point: Any) -> float:
    """``values`` sampled at ``corner + index h`` (2D or 3D), interpolated (bi- or
    trilinearly) at ``point``, clamped to the samples."""
    lower, weights = [], []
    for axis in range(values.ndim):
        f = min(max((point[axis] - corner[axis]) / h, 0.0), values.shape[axis] - 1.0)
        i = max(min(int(f), values.shape[axis] - 2), 0)
        lower.append(i)
        weights.append(f - i)
    total = 0.0
    for offsets in itertools.product((0, 1), repeat=values.ndim):
        weight = 1.0
        for offset, t in zip(offsets, weights, strict=True):
            weight *= t if offset else 1.0 - t
        total += weight * float(values[tuple(i + o for i, o in zip(lower, offsets, strict=True))])
    return total


def _cells_with_pressure(interior: Any, cells: np.ndarray) -> np.ndarray:
    """Which of ``cells`` (index rows, shape (k, d)) carry a pressure: a cell some face of
    which is open (`fluid.OPEN_MIN` or more, as the projection counts it). A body covering
    every face of a cell takes it out of the pressure solve, which leaves 0 there."""
    from elastoflow.fluid import OPEN_MIN

    keep = np.zeros(len(cells), dtype=np.bool_)
    for axis in range(cells.shape[1]):
        fraction = getattr(interior, f"open_fraction_{'xyz'[axis]}")
        for offset in (0, 1):
            faces = cells.copy()
            faces[:, axis] += offset
            keep |= fraction[tuple(faces.T)] >= OPEN_MIN
    return keep


def _pressure_at(sim: Any, point: Any) -> float:
    """The pressure at ``point``: bi- or trilinear in the cells around it; where one of them
    carries no pressure (a body covers all its faces), the least-squares linear fit to the
    cells that do in the 4 x 4 (x 4) block around the point, extrapolated to it (exact for a
    linear field, as the boundary-layer pressure nearly is across a cell); NaN where none do."""
    grid = sim.grid
    corner = np.array([float(c) + 0.5 * grid.h for c in grid.origin])
    pressure = sim.state.fluid.pressure
    interior = getattr(sim, "interior", None)
    if interior is None:
        return _interpolate(pressure, corner, grid.h, point)
    shape = np.array(pressure.shape)
    where = (np.asarray(point, dtype=np.float64) - corner) / grid.h
    lower = np.clip(np.floor(where).astype(np.int64), 0, shape - 2)
    block = np.array(list(itertools.product((0, 1), repeat=len(shape)))) + lower
    if _cells_with_pressure(interior, block).all():
        return _interpolate(pressure, corner, grid.h, point)
    offsets = np.array(list(itertools.product((-1, 0, 1, 2), repeat=len(shape))))
    cells = offsets + lower
    cells = cells[((cells >= 0) & (cells < shape)).all(axis=1)]
    cells = cells[_cells_with_pressure(interior, cells)]
    if len(cells) == 0:
        return float("nan")
    values = pressure[tuple(cells.T)]
    design = np.column_stack([np.ones(len(cells)), cells - where])
    if np.linalg.matrix_rank(design) < design.shape[1]:
        return float(values.mean())
    coefficients = np.linalg.lstsq(design, values, rcond=None)[0]
    return float(coefficients[0])


def _point_name(point: Any) -> str:
    return "(" + ",".join(f"{value:g}" for value in point) + ")"


def _pressure(spec: Any) -> tuple[list[str], Sampler]:
    point = tuple(spec.point)

    def sample(sim: Any, report: Any) -> list[float]:
        return [_pressure_at(sim, point)]

    return [f"pressure_{_point_name(point)} [Pa]"], sample


def _pressure_difference(spec: Any) -> tuple[list[str], Sampler]:
    first, second = (tuple(p) for p in spec.points)

    def sample(sim: Any, report: Any) -> list[float]:
        return [_pressure_at(sim, first) - _pressure_at(sim, second)]

    return [f"pressure_{_point_name(first)}-{_point_name(second)} [Pa]"], sample


def _velocity(spec: Any, dimension: int) -> tuple[list[str], Sampler]:
    point = tuple(spec.point)
    names = ("velocity_x", "velocity_y", "velocity_z")[:dimension]

    def sample(sim: Any, report: Any) -> list[float]:
        grid, state = sim.grid, sim.state.fluid
        h = grid.h
        values = []
        for axis, name in enumerate(names):
            # Each component sits on the faces normal to its axis: cell centres elsewhere.
            corner = [float(c) + (0.0 if k == axis else 0.5 * h)
                      for k, c in enumerate(grid.origin)]
            values.append(_interpolate(getattr(state, name), corner, h, point))
        return values

    name = _point_name(point)
    return [f"velocity_{name}_{axis} [m/s]" for axis in _axes(dimension)], sample


class _MomentumBalanceProbe:
    """``momentum_balance``: the force on the box's obstacles after every step
    (`elastoflow.fluid.MomentumBalance`, which needs every step's momentum: `observe`), the
    last one at each sample. A resumed run starts from the state's previous and current
    velocity, so that its forces are those of the run it continues."""

    def __init__(self, spec: Any, simulation: Any) -> None:
        from elastoflow.fluid import BoxCells, MomentumBalance

        solver, grid = simulation.fluid_solver, simulation.grid
        x0, y0, x1, y1 = (float(c) for c in spec.region)
        self.balance = MomentumBalance(
            grid, BoxCells.around(grid, (x0, y0), (x1, y1)), solver.density, solver.viscosity,
            bdf2=solver.viscosity_scheme == "bdf2", gravity=solver.gravity)
        fluid = simulation.state.fluid
        momenta = [self.balance.momentum(fluid.velocity_x, fluid.velocity_y)]
        if fluid.previous_velocity_x is not None and fluid.previous_velocity_y is not None:
            momenta.insert(0, self.balance.momentum(fluid.previous_velocity_x,
                                                    fluid.previous_velocity_y))
        self.balance.start(momenta, simulation.dt)
        self.last = [float("nan"), float("nan")]
        _, _, self.label = _targets(spec)

    def observe(self, sim: Any) -> None:
        fluid, interior = sim.state.fluid, sim.interior
        solid = None if interior is None else (interior.solid_faces_x, interior.solid_faces_y)
        self.last = list(self.balance.force(fluid.velocity_x, fluid.velocity_y,
                                            fluid.pressure, sim.dt, solid))

    def __call__(self, sim: Any, report: Any) -> list[float]:
        return list(self.last)

    def columns(self) -> list[str]:
        return [f"balance_{self.label}_{axis} [N/m]" for axis in "xy"]


def _resolve_node(sim: Any, spec: Any) -> int:
    if spec.node is not None:
        return int(spec.node)
    points = sim.bodies[spec.body].mesh.points
    return int(np.argmin(np.linalg.norm(points - np.asarray(spec.point, float), axis=1)))


class ProbeRecorder:
    """Samples the probes of a scene after each step into ``probes.csv``, a stream: each row is
    appended with one ``write`` as it is taken, so a killed run leaves a CSV of complete rows up
    to its last step; `sync` (at every checkpoint) puts them on the disk. A write that fails
    (a full disk) is undone to the last complete row before the error is raised. `plot` draws
    ``probes.png`` at the end.

    Args:
        probes: `elastoflow.scenes.ProbeSpec` items (kind, body, node or point).
        simulation: The running `Simulation` (bodies are looked up once).
        path: CSV file; the plot goes beside it with suffix ``.png``.
        resume_step: Keep the rows of an existing CSV up to this step (a resumed run); rows
            after it, and a last row cut short by a kill, are dropped. An existing CSV with
            other columns is kept as ``probes_until_{step}.csv``. None starts a new CSV.
    """

    def __init__(self, probes: Sequence[Any], simulation: Any, path: str | Path,
                 resume_step: int | None = None) -> None:
        self.path = Path(path)
        self.columns: list[str] = ["step", "time [s]"]
        self._samplers: list[Sampler] = []
        self._observers: list[_MomentumBalanceProbe] = []
        dimension = int(getattr(simulation, "dimension", 2))
        makers: dict[str, Callable[[Any], tuple[list[str], Sampler]]] = {
            "node_displacement": lambda s: _node_displacement(
                s.body, _resolve_node(simulation, s), dimension),
            "body_force": lambda s: _body_force(s.body, dimension),
            "force": lambda s: _force(s, dimension),
            "torque": _torque,
            "pressure": _pressure,
            "pressure_difference": _pressure_difference,
            "velocity": lambda s: _velocity(s, dimension),
            "kinetic_energy": lambda s: _kinetic_energy(s.body),
            "pressure_iterations": lambda s: _pressure_iterations(),
        }
        for spec in probes:
            sampler: Sampler
            if spec.kind == "momentum_balance":
                observer = _MomentumBalanceProbe(spec, simulation)
                self._observers.append(observer)
                names, sampler = observer.columns(), observer
            else:
                names, sampler = makers[spec.kind](spec)
            self.columns.extend(names)
            self._samplers.append(sampler)
        self.rows: list[list[float]] = []
        if resume_step is not None and self.path.exists():
            columns, rows = _read_complete_rows(self.path)
            if columns == self.columns:
                self.rows = [row for row in rows if row[0] <= resume_step]
            else:
                os.replace(self.path, self.path.with_name(
                    f"{self.path.stem}_until_{resume_step:06d}{self.path.suffix}"))
        write_text_atomic(self.path, "".join(
            [_line(self.columns)] + [self._format(row) for row in self.rows]))
        self._handle: int | None = os.open(self.path, os.O_WRONLY | os.O_APPEND)
        self._size = os.fstat(self._handle).st_size

    @staticmethod
    def _format(row: list[float]) -> str:
        return _line([str(int(row[0])), *(f"{v:.10g}" for v in row[1:])])

    def observe(self, simulation: Any) -> None:
        """Called after every step, sampled or not: the probes that need each step's fields
        (the momentum balance's time derivative) take them here."""
        for observer in self._observers:
            observer.observe(simulation)

    def record(self, simulation: Any, report: Any = None) -> None:
        """Append one row: step, time and every probe's values."""
        row = [float(simulation.step_index), float(simulation.time)]
        for sampler in self._samplers:
            row.extend(sampler(simulation, report))
        self._append(self._format(row).encode("utf-8"))
        self.rows.append(row)

    def _append(self, data: bytes) -> None:
        if self._handle is None:
            raise ValueError(f"{self.path}: the probe recorder is closed")
        try:
            written = os.write(self._handle, data)
            if written != len(data):
                raise OSError(errno.ENOSPC, "short write", str(self.path))
        except OSError as error:
            # Undo a partial row: the file must end with a complete one. Shrinking a file needs
            # no free space.
            with contextlib.suppress(OSError):
                os.ftruncate(self._handle, self._size)
            if not error.filename:
                error.filename = str(self.path)
            raise
        self._size += written

    def sync(self) -> None:
        """Put every row recorded so far on the disk (fsync)."""
        if self._handle is not None:
            os.fsync(self._handle)

    def write_csv(self) -> Path:
        """Make sure every row so far is in the CSV (on the disk); returns its path."""
        self.sync()
        return self.path

    def close(self) -> None:
        """Sync and close the CSV (idempotent)."""
        if self._handle is not None:
            try:
                self.sync()
            finally:
                os.close(self._handle)
                self._handle = None

    def write_statistics(self) -> Path | None:
        """``probes_statistics.json`` beside the CSV: every column's final value, and its mean,
        amplitude, frequency and growth over the last period where it is periodic in the last
        half of the run (`probe_statistics`)."""
        if not self.rows or len(self.columns) <= 2:
            return None
        path = self.path.with_name(f"{self.path.stem}_statistics.json")
        data = probe_statistics(self.columns, np.asarray(self.rows))
        write_text_atomic(path, json.dumps(data, indent=2, allow_nan=True) + "\n")
        return path

    def plot(self) -> Path | None:
        """One panel per probe column against time, saved as PNG (matplotlib, Agg)."""
        if not self.rows or len(self.columns) <= 2:
            return None
        return plot_probes(self.columns, np.asarray(self.rows), self.path.with_suffix(".png"))


def probe_statistics(columns: Sequence[str], data: np.ndarray) -> dict[str, dict[str, float]]:
    """Per probe column (after ``step`` and ``time``): ``final`` and, where the last half of
    the record is periodic, ``mean``, ``amplitude``, ``frequency`` [Hz] and ``growth`` as
    `elastoflow.analysis.periodic_statistics` defines them (Turek & Hron's definitions)."""
    from elastoflow.analysis import periodic_statistics

    data = np.atleast_2d(np.asarray(data, dtype=np.float64))
    time = data[:, 1]
    result: dict[str, dict[str, float]] = {}
    for k, name in enumerate(columns[2:], start=2):
        signal = data[:, k]
        entry: dict[str, float] = {"final": float(signal[-1])}
        try:
            stats = periodic_statistics(time, signal)
        except ValueError:
            pass
        else:
            entry.update(mean=stats.mean, amplitude=stats.amplitude, frequency=stats.frequency,
                         growth=stats.growth)
        result[name] = entry
    return result


def _line(values: Sequence[str]) -> str:
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerow(values)
    return buffer.getvalue()


def _read_complete_rows(path: Path) -> tuple[list[str], list[list[float]]]:
    """Columns and rows of a probes CSV, without a last row cut short (no line end, or fewer
    values than columns) or any row that does not parse."""
    text = path.read_text(encoding="utf-8", errors="replace")
    lines = text.split("\n")
    complete = lines[:-1]  # the piece after the last line end is not a complete row
    if not complete:
        return [], []
    columns = next(csv.reader([complete[0]]))
    rows = []
    for values in csv.reader(complete[1:]):
        if len(values) != len(columns):
            continue
        try:
            rows.append([float(v) for v in values])
        except ValueError:
            continue
    return columns, rows


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
