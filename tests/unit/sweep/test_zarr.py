"""The Zarr store from the points' snapshot files: one that cannot be read or lacks a field
(taken before the sweep file asked for it) is NaN there with a warning, not a traceback at the
end of the sweep after every point had run."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

xr = pytest.importorskip("xarray")
pytest.importorskip("zarr")

from elastoflow.sweep import parse_sweep, plan_sweep  # noqa: E402
from elastoflow.sweep._zarr import write_snapshots_zarr  # noqa: E402

N = 8


def test_unreadable_or_older_snapshots_are_nan_with_a_warning(tmp_path: Path) -> None:
    plan = plan_sweep(parse_sweep({
        "scene": "cavity", "set": {"domain.nx": N, "time.steps": 4, "domain.origin": [2.0, -1.0]},
        "grid": {"boundaries.top.velocity": [0.5, 1.0, 1.5]},
        "snapshots": {"times": [0.0], "fields": ["velocity_x", "vorticity"]}},
        base_dir=tmp_path), build=False)
    out = tmp_path / "out"
    files = []
    for k in range(3):
        file = out / "points" / f"point_{k:05d}" / "snapshots" / "snapshot_000.npz"
        file.parent.mkdir(parents=True)
        files.append(file)
    np.savez(files[0], velocity_x=np.full((N, N), 1.0), vorticity=np.full((N, N), 2.0),
             time=np.array(0.0), step=np.array(0))
    np.savez(files[1], velocity_x=np.full((N, N), 3.0), time=np.array(0.0), step=np.array(0))
    files[2].write_bytes(b"PK\x03\x04 cut short")
    rows = {k: {"status": "done"} for k in range(3)}
    warnings: list[str] = []
    path = write_snapshots_zarr(out / "fields.zarr", plan, rows, out, warnings)
    import dask

    # Read in this process, whatever scheduler an earlier test's Client left configured.
    with dask.config.set(scheduler="synchronous"):
        data = xr.open_zarr(path).load()
    assert (data["velocity_x"].values[0] == 1.0).all() and (data["vorticity"].values[0] == 2).all()
    assert (data["velocity_x"].values[1] == 3.0).all()
    assert np.isnan(data["vorticity"].values[1]).all()
    assert np.isnan(data["velocity_x"].values[2]).all()
    assert len(warnings) == 2
    # Cell centres in the domain's coordinates, its origin included.
    np.testing.assert_allclose(data["x"].values, 2.0 + (np.arange(N) + 0.5) / N)
    np.testing.assert_allclose(data["y"].values, -1.0 + (np.arange(N) + 0.5) / N)
    assert str(files[1]) in warnings[0] and "holds no vorticity" in warnings[0]
    assert str(files[2]) in warnings[1] and "cannot be read" in warnings[1]
