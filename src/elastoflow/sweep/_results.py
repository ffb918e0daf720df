"""Scalar results of one point from its probe time series; the summary table of a sweep."""

from __future__ import annotations

import json
import math
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

_UNIT = re.compile(r"^(?P<name>.*?)\s*\[(?P<unit>[^\]]*)\]$")

RESULT_FILE = "result.json"
"""Written last into a point's folder: the point is finished (done or failed)."""

STATUSES = ("done", "failed", "lost", "pending")
"""done: ran to its end; failed: the run stopped with an error (blow-up, bad state), its
message kept; lost: its workers died too often, or the engine gave up on it (retried by the
next run of the sweep); pending: not run yet (the sweep was stopped)."""


def _split_unit(column: str) -> tuple[str, str]:
    match = _UNIT.match(column)
    return (match["name"], match["unit"]) if match else (column, "")


def scalar_results(columns: Sequence[str], rows: Sequence[Sequence[float]],
                   after: float = 0.0) -> dict[str, float]:
    """Final value, and mean, amplitude and frequency where periodic, of every probe column.

    Columns ``NAME [UNIT]`` give ``NAME_final [UNIT]``, ``NAME_mean [UNIT]``,
    ``NAME_amplitude [UNIT]`` and ``NAME_frequency [Hz]``; the last three come from
    `elastoflow.analysis.periodic_statistics` over the samples at ``time >= after`` and are NaN
    where the signal is not periodic there (or there are too few samples).

    Args:
        columns: The probes CSV header: ``step``, ``time [s]``, then the probe columns.
        rows: Its rows.
        after: Start of the part of the record the statistics see [s].
    """
    from elastoflow.analysis import periodic_statistics

    data = np.asarray(rows, dtype=np.float64).reshape(len(rows), len(columns))
    results: dict[str, float] = {}
    if len(columns) <= 2:
        return results
    time = data[:, 1]
    late = time >= after
    for k, column in enumerate(columns[2:], start=2):
        name, unit = _split_unit(column)
        suffix = f" [{unit}]" if unit else ""
        signal = data[:, k]
        results[f"{name}_final{suffix}"] = float(signal[-1]) if len(signal) else math.nan
        stats = None
        try:
            stats = periodic_statistics(time[late], signal[late])
        except ValueError:
            pass
        results[f"{name}_mean{suffix}"] = stats.mean if stats else math.nan
        results[f"{name}_amplitude{suffix}"] = stats.amplitude if stats else math.nan
        results[f"{name}_frequency [Hz]"] = stats.frequency if stats else math.nan
    return results


def read_result(folder: Path) -> dict[str, Any] | None:
    """The ``result.json`` of a point folder, or None when missing or unreadable."""
    try:
        return dict(json.loads((folder / RESULT_FILE).read_text()))
    except (OSError, ValueError):
        return None


def _kind(value: Any) -> str:
    if isinstance(value, bool):
        return "bool"
    if isinstance(value, int | float):
        return "number"
    return "text" if isinstance(value, str) else "json"


def _parameter_column(values: list[Any]) -> list[Any]:
    """One parameter's values as cells of one Parquet type: as they are when all are numbers,
    all text or all booleans (missing ones None), else all as text (``"auto"`` and ``10`` of
    ``time.substeps`` become ``auto`` and ``10``; Parquet holds one type per column)."""
    kinds = {_kind(v) for v in values if v is not None}
    if len(kinds) <= 1 and kinds != {"json"}:
        return list(values)
    return [None if v is None else v if isinstance(v, str) else json.dumps(v) for v in values]


def summary_frame(rows: Sequence[dict[str, Any]], parameter_names: Sequence[str]) -> Any:
    """The summary as a pandas DataFrame, one row per point.

    Columns: ``point``, the parameters (named by key path), ``status``, ``message``,
    ``wall_time [s]``, ``steps``, ``time [s]``, ``attempts``, ``resumed_from_step``,
    ``worker``, ``folder``, then the scalar results (sorted by name).
    """
    import pandas as pd

    fixed = ["point", *parameter_names, "status", "message", "wall_time [s]", "steps",
             "time [s]", "attempts", "resumed_from_step", "worker", "folder"]
    results = sorted({key for row in rows for key in row.get("results", {})})
    columns = {name: _parameter_column([row["parameters"].get(name) for row in rows])
               for name in parameter_names}
    table = []
    for position, row in enumerate(rows):
        line = {"point": row["point"]}
        line.update({name: columns[name][position] for name in parameter_names})
        line.update({key: row.get(key) for key in fixed[len(parameter_names) + 1:]})
        line.update({key: row.get("results", {}).get(key, math.nan) for key in results})
        table.append(line)
    frame = pd.DataFrame(table, columns=[*fixed, *results])
    for column in ("wall_time [s]", "time [s]", *results):
        frame[column] = pd.to_numeric(frame[column], errors="coerce").astype("float64")
    for column in ("steps", "attempts", "resumed_from_step"):
        frame[column] = frame[column].astype("Int64")
    for column in ("status", "message", "worker", "folder"):
        frame[column] = frame[column].astype("string")
    return frame


def write_summary(path: Path, rows: Sequence[dict[str, Any]],
                  parameter_names: Sequence[str]) -> Path:
    """Write the summary table as Parquet (temporary file, then rename)."""
    from elastoflow.io import atomic_path

    frame = summary_frame(rows, parameter_names)
    with atomic_path(path) as temporary:
        frame.to_parquet(temporary, index=False)
    return path
