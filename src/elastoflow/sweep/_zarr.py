"""The fields of every point at chosen times in one Zarr store, an xarray Dataset."""

from __future__ import annotations

import shutil
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from elastoflow.sweep._worker import snapshot_path


def _coordinate(values: list[Any]) -> np.ndarray:
    """Parameter values as one array: numbers as float64, anything else as text."""
    if all(isinstance(v, int | float) and not isinstance(v, bool) for v in values):
        return np.asarray(values, dtype=np.float64)
    return np.asarray([str(v) for v in values], dtype=str)


def write_snapshots_zarr(path: Path, plan: Any, rows: Mapping[int, Mapping[str, Any]],
                         out: Path, warnings: list[str] | None = None) -> Path:
    """`_write_store` in this process: never through the sweep's cluster (a Client makes
    itself dask's default scheduler, also after it closed, in the same process)."""
    import dask

    with dask.config.set(scheduler="synchronous"):
        return _write_store(path, plan, rows, out, warnings)


def _write_store(path: Path, plan: Any, rows: Mapping[int, Mapping[str, Any]], out: Path,
                 warnings: list[str] | None = None) -> Path:
    """Write ``path`` (a Zarr store, format 2: readable by every Zarr library) from the snapshot files of the points in ``out``.

    The Dataset has one variable per field, dimensions ``(point, time, x, y)``, float32, NaN
    where a point has no snapshot (failed before that time, or not run); coordinates ``point``
    (the index), ``time`` (the requested times [s]), ``x``, ``y`` (cell centres [m]), one
    coordinate along ``point`` per varied parameter (named by its key path) and ``status``;
    ``snapshot_time`` (point, time) holds the time [s] each snapshot was actually taken.
    The store is written beside ``path`` and then swapped in, so a reader never sees half.
    A snapshot file that cannot be read, or lacks a field (taken before ``[snapshots]`` asked
    for it), gives NaN there and a line in ``warnings``.
    """
    import dask.array as da
    import xarray as xr

    spec = plan.spec.snapshots
    points = plan.points
    times = np.asarray(spec.times, dtype=np.float64)
    domain = points[0].scene.domain
    nx, ny = domain.cells
    h = domain.cell_size
    x0, y0 = (float(v) for v in getattr(domain, "origin", (0.0, 0.0)))
    n, t = len(points), len(times)
    dims = ("point", "time", "x", "y")
    chunks = (1, t, nx, ny)
    coords: dict[str, Any] = {
        "point": [p.index for p in points],
        "time": ("time", times, {"units": "s"}),
        "x": ("x", x0 + (np.arange(nx) + 0.5) * h, {"units": "m"}),
        "y": ("y", y0 + (np.arange(ny) + 0.5) * h, {"units": "m"}),
        "status": ("point", np.asarray([str(rows.get(p.index, {}).get("status", "pending"))
                                        for p in points])),
    }
    for name in plan.parameter_names:
        coords[name] = ("point", _coordinate([p.parameters.get(name) for p in points]))
    variables: dict[str, Any] = {
        name: (dims, da.full((n, t, nx, ny), np.nan, dtype=np.float32, chunks=chunks))
        for name in spec.fields
    }
    variables["snapshot_time"] = (("point", "time"), da.full((n, t), np.nan, chunks=(1, t)),
                                  {"units": "s"})
    template = xr.Dataset(variables, coords=coords,
                          attrs={"sweep": plan.spec.name, "source": str(plan.spec.source)})
    staging = path.with_name(f".{path.name}.tmp")
    shutil.rmtree(staging, ignore_errors=True)
    template.to_zarr(staging, mode="w", compute=False, consolidated=True, zarr_format=2)
    for position, point in enumerate(points):
        folder = out / "points" / point.folder_name
        files = [snapshot_path(folder, k) for k in range(t)]
        if not any(f.exists() for f in files):
            continue
        block = {name: np.full((1, t, nx, ny), np.nan, dtype=np.float32) for name in spec.fields}
        taken = np.full((1, t), np.nan)
        for k, file in enumerate(files):
            if not file.exists():
                continue
            try:
                with np.load(file, allow_pickle=False) as data:
                    arrays = {name: np.array(data[name]) for name in data.files}
            except Exception as error:  # noqa: BLE001 - numpy/zipfile fail in many ways
                if warnings is not None:
                    warnings.append(f"{file}: cannot be read ({type(error).__name__}: "
                                    f"{error}); its fields are NaN in {path.name}")
                continue
            missing = [name for name in spec.fields
                       if name not in arrays or arrays[name].shape != (nx, ny)]
            if missing and warnings is not None:
                warnings.append(f"{file}: holds no {', '.join(missing)} of {nx}x{ny} cells "
                                f"(taken before [snapshots] asked for it?): NaN in {path.name}; "
                                "run the sweep into a new folder to have them")
            for name in spec.fields:
                if name not in missing:
                    block[name][0, k] = arrays[name]
            if "time" in arrays and arrays["time"].shape == ():
                taken[0, k] = float(arrays["time"])
        region = xr.Dataset({**{name: (dims, block[name]) for name in spec.fields},
                             "snapshot_time": (("point", "time"), taken)})
        region.to_zarr(staging, region={"point": slice(position, position + 1)},
                       consolidated=True, zarr_format=2)
    old = path.with_name(f".{path.name}.old")
    shutil.rmtree(old, ignore_errors=True)
    if path.exists():
        path.rename(old)
    staging.rename(path)
    shutil.rmtree(old, ignore_errors=True)
    return path
