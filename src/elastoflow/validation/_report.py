"""What a validation run prints and writes: the benchmark's table, CSV, PNG and JSON."""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from elastoflow.analysis import PeriodicStatistics
from elastoflow.io import write_text_atomic
from elastoflow.validation._turek_hron import BALANCE_OF, REFERENCE, UNITS, Result

def step_and_record(simulation: Any, steps: int, record: Callable[[int], None]
                    ) -> tuple[str | None, float]:
    """Step ``simulation`` ``steps`` times, calling ``record(step)`` after each, and stop at
    a `SimulationBlowUp`: a study keeps what it measured before the failure. Returns the
    failure's message (None when all steps ran) and the seconds the steps took."""
    import time

    from elastoflow.simulation import SimulationBlowUp

    began = time.perf_counter()
    for step in range(steps):
        try:
            simulation.step()
        except SimulationBlowUp as error:
            return str(error), time.perf_counter() - began
        record(step)
    return None, time.perf_counter() - began


_LABELS = {"ux_A": "u_x(A)", "uy_A": "u_y(A)", "drag": "drag", "lift": "lift",
           "drag_cv": "drag, balance", "lift_cv": "lift, balance",
           "ux_tip": "u_x(tip)", "uy_tip": "u_y(tip)"}


def step_to_steady(solver: Any, state: Any, dt: float, t_max: float, tolerance: float
                   ) -> tuple[int, float, float]:
    """Step a fluid-only ``solver`` from ``state`` until u changes by less than ``tolerance``
    per unit time (checked every half time unit) or ``t_max`` is reached; returns the steps
    taken, the time reached and the last change."""
    check_every = max(1, round(0.5 / dt))
    previous = state.velocity_x.copy()
    time, steps, change = 0.0, 0, float("inf")
    while time < t_max and change > tolerance:
        solver.step(state, dt, time)
        time += dt
        steps += 1
        if steps % check_every == 0:
            change = float(np.abs(state.velocity_x - previous).max()) / (check_every * dt)
            previous[...] = state.velocity_x
    return steps, time, change


def describe(result: Result) -> str:
    """One line: case, resolution, grid, scheme, step and wall time."""
    s = result.setup
    where = (f"{result.cells[0]}x{result.cells[1]} cells (h = {s.h:g} m)"
             if result.cells is not None else f"solid only ({s.layers} element layers)")
    scheme = f", {s.scheme} coupling" if s.case.kind == "FSI" else ""
    if s.incremental_pressure:
        scheme += ", incremental pressure"
    end = float(result.time[-1]) if len(result.time) else 0.0
    if s.case.kind == "CSM" and not s.case.periodic:
        stepping = f"static equilibrium by Newton's method ({result.steps} iterations)"
    else:
        stepping = f"dt = {s.dt:.4g} s, t = 0-{end:.4g} s ({result.steps} steps)"
    return (f"{s.case.benchmark} {s.case.name}, resolution {s.resolution}: {where}, "
            f"{result.elements} solid elements{scheme}, {stepping}, {result.seconds:.1f} s wall")


def format_quantities(result: Result) -> list[str]:
    """The benchmark's quantities in its own units and notation, one per line."""
    lines = []
    reference = REFERENCE.get(result.setup.case.name, {})
    for key, value in result.quantities.items():
        scale, unit = UNITS[key]
        label = f"{_LABELS[key]} [{unit}]"
        if isinstance(value, PeriodicStatistics):
            text = value.format(scale=scale)
            if abs(value.growth) > 0.02:
                text += (f"   (amplitude {100 * value.growth:+.1f} % from the period before: "
                         "not settled, or not strictly periodic)")
        else:
            text = f"{value * scale:.5g}"
            if key in result.drift:
                text += f"   (change over the last 10 %: {result.drift[key] * scale:+.3g})"
        published = reference.get(BALANCE_OF.get(key, key))
        if published is not None and key in result.errors:
            text += (f"   reference {published * scale:.5g}, "
                     f"error {100.0 * result.errors[key]:+.2f} %")
        lines.append(f"{label:<20} {text}")
    if result.failure is not None:
        lines.append(f"not evaluated: {result.failure}")
    return lines


def quantities_json(result: Result) -> dict[str, Any]:
    """The run and its quantities as JSON-ready data (SI units)."""
    s = result.setup
    quantities: dict[str, Any] = {}
    for key, value in result.quantities.items():
        quantities[key] = (value.as_dict() if isinstance(value, PeriodicStatistics)
                           else {"value": value, "drift": result.drift.get(key)})
        if key in result.errors:
            quantities[key]["reference"] = REFERENCE[s.case.name][BALANCE_OF.get(key, key)]
            quantities[key]["relative_error"] = result.errors[key]
    return {
        "benchmark": s.case.benchmark,
        "case": s.case.name,
        "resolution": s.resolution,
        "h": s.h,
        "dt": s.dt,
        "duration": float(result.time[-1]) if len(result.time) else 0.0,
        "steps": result.steps,
        "scheme": s.scheme if s.case.kind == "FSI" else None,
        "incremental_pressure": s.incremental_pressure,
        "cells": list(result.cells) if result.cells is not None else None,
        "flag_elements": result.elements,
        "wall_seconds": result.seconds,
        "quantities": quantities,
        "failure": result.failure,
    }


def write_report(result: Result, folder: str | Path, *, json_file: bool = True) -> list[Path]:
    """Write ``<case>_n<resolution>.csv`` (time series), ``.png`` (plots) and, with
    ``json_file``, ``.json`` (quantities) into ``folder``; each file appears whole or not at
    all. Returns the paths written."""
    stem = f"{result.setup.case.name.lower()}_n{result.setup.resolution}"
    units = {key: "m" if key.startswith("u") else "N/m" for key in result.series}
    return write_series_report(
        folder, stem, result.time, result.series, [f"{key} [{units[key]}]" for key in units],
        lambda path: _plot(result, path), quantities_json(result) if json_file else None,
    )


def write_series_report(folder: str | Path, stem: str, time: Any, series: dict[str, Any],
                        headers: list[str], plot: Callable[[Path], None],
                        quantities: dict[str, Any] | None) -> list[Path]:
    """A benchmark run's files in ``folder``: ``<stem>.csv`` (the time series under
    ``headers``), ``<stem>.png`` (drawn by ``plot``) and, given ``quantities``,
    ``<stem>.json``; each appears whole or not at all. Returns the paths written."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(["time [s]"] + headers)
    for k, t in enumerate(time):
        writer.writerow([f"{t:.9g}"] + [f"{series[key][k]:.9g}" for key in series])
    paths = [folder / f"{stem}.csv", folder / f"{stem}.png"]
    write_text_atomic(paths[0], text.getvalue())
    plot(paths[1])
    if quantities is not None:
        paths.append(folder / f"{stem}.json")
        write_text_atomic(paths[2], json.dumps(quantities, indent=2) + "\n")
    return paths


def _plot(result: Result, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from elastoflow.io import atomic_path

    keys = list(result.series)
    rows = math.ceil(len(keys) / 2)
    figure, axes = plt.subplots(rows, min(len(keys), 2), figsize=(10, 3.2 * rows),
                                squeeze=False)
    for axis, key in zip(axes.ravel(), keys):
        scale, unit = UNITS[key]
        axis.plot(result.time, np.asarray(result.series[key]) * scale, lw=0.8)
        value = result.quantities.get(key)
        if isinstance(value, PeriodicStatistics):
            axis.axvspan(value.start, value.end, color="0.9", zorder=0,
                         label="last period")
            axis.legend(loc="upper left", fontsize=8)
        axis.set_xlabel("t [s]")
        axis.set_ylabel(f"{_LABELS[key]} [{unit}]")
        axis.grid(alpha=0.3)
    for axis in axes.ravel()[len(keys):]:
        axis.set_visible(False)
    figure.suptitle(describe(result), fontsize=8)
    figure.tight_layout()
    with atomic_path(path) as temporary:
        figure.savefig(temporary, dpi=110, format="png")
    plt.close(figure)


def replace_block(page: Path, block: str, begin: str, end: str,
                  before: str | None = "\n## Notes") -> Path:
    """Put ``block`` (which starts with ``begin`` and ends with ``end``) into the Markdown
    ``page``: in place of the text between those markers, else before the ``before`` heading,
    else at the end; written atomically (a study's page is never left half written)."""
    from elastoflow.io import write_text_atomic

    text = page.read_text()
    if begin in text and end in text:
        head, rest = text.split(begin, 1)
        text = head + block + rest.split(end, 1)[1]
    elif before is not None and before in text:
        text = text.replace(before, "\n" + block + "\n" + before, 1)
    else:
        text = text.rstrip("\n") + "\n\n" + block + "\n"
    write_text_atomic(page, text)
    return page
