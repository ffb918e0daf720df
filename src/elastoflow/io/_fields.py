"""Field snapshots: NumPy ``.npz``, VTK (``.vtu`` + ``.pvd`` series) and XDMF + HDF5.

Every snapshot holds, at cell centres, velocity, pressure, dye, vorticity and the solid flag,
plus each body's current mesh. ParaView opens ``fluid.pvd`` / ``body0.pvd`` (or
``fluid.xdmf``) as a time series.
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from elastoflow.io._atomic import atomic_path, write_text_atomic
from elastoflow.render._fields import velocity_at_cells, vorticity_at_cells

FIELD_FORMATS: tuple[str, ...] = ("npz", "vtk", "xdmf")


def snapshot_arrays(grid: Any, state: Any, bodies: Sequence[Any] = (),
                    obstacles: Sequence[Any] = (), *, time: float = 0.0, step: int = 0,
                    solid_cells: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Everything a saved frame holds, as named arrays (the ``.npz`` keys).

    Keys: ``velocity`` (nx, ny, 2) [m/s] at cell centres, ``velocity_x`` (nx+1, ny),
    ``velocity_y`` (nx, ny+1), ``pressure``, ``dye``, ``vorticity`` [1/s], ``solid`` (bool), all
    (nx, ny) unless stated; ``time`` [s], ``step``, ``h`` [m], ``origin`` (2,);
    ``body{k}_points`` (n, 2) [m], ``body{k}_triangles`` (m, 3), ``body{k}_velocities`` (n, 2);
    ``obstacle{k}_points`` (p, 2) [m].
    """
    data: dict[str, np.ndarray] = {
        "velocity": velocity_at_cells(state),
        "velocity_x": np.array(state.velocity_x),
        "velocity_y": np.array(state.velocity_y),
        "pressure": np.array(state.pressure),
        "dye": np.array(state.dye),
        "vorticity": vorticity_at_cells(state, grid.h),
        "solid": (np.zeros(grid.shape_cells, dtype=np.bool_) if solid_cells is None
                  else np.array(solid_cells, dtype=np.bool_)),
        "time": np.array(float(time)),
        "step": np.array(int(step)),
        "h": np.array(float(grid.h)),
        "origin": np.asarray(grid.origin, dtype=np.float64),
    }
    for index, body in enumerate(bodies):
        data[f"body{index}_points"] = np.array(body.positions)
        data[f"body{index}_triangles"] = np.array(body.mesh.triangles)
        data[f"body{index}_velocities"] = np.array(body.velocities)
    for index, obstacle in enumerate(obstacles):
        data[f"obstacle{index}_points"] = np.array(obstacle.points_at(time))
    return data


def _cell_mesh(nx: int, ny: int, h: float, origin: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """Corner points ((nx+1)(ny+1), 3) and quads (nx ny, 4), cells in the order of ``[i, j]``
    arrays flattened in C order (i slowest)."""
    x = origin[0] + h * np.arange(nx + 1)
    y = origin[1] + h * np.arange(ny + 1)
    X, Y = np.meshgrid(x, y, indexing="ij")
    points = np.column_stack((X.ravel(), Y.ravel(), np.zeros(X.size)))
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    corner = (i * (ny + 1) + j).ravel()
    quads = np.column_stack((corner, corner + ny + 1, corner + ny + 2, corner + 1))
    return points, quads


def _cell_data(data: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    velocity = data["velocity"].reshape(-1, 2)
    return {
        "velocity": np.column_stack((velocity, np.zeros(len(velocity)))),
        "pressure": data["pressure"].ravel(),
        "dye": data["dye"].ravel(),
        "vorticity": data["vorticity"].ravel(),
        "solid": data["solid"].ravel().astype(np.int32),
    }


class FieldWriter:
    """Writes snapshots to ``folder`` in the chosen formats, every file atomically.

    Files: ``step_{step:06d}.npz``; ``fluid_{step:06d}.vtu``, ``body{k}_{step:06d}.vtu`` with the
    ``fluid.pvd`` / ``body{k}.pvd`` collections; ``fluid.xdmf`` + ``fluid.h5`` (finished by
    `close`; a resumed run writes ``fluid_from_{step}.xdmf``). ``index.json`` lists the saved steps and times (used to resume a series).

    Args:
        folder: Output folder (created).
        grid: The `Grid2D`.
        formats: Any of ``"npz"``, ``"vtk"``, ``"xdmf"``.
        resume_step: Keep the saved frames up to this step (a resumed run); None starts fresh.
    """

    def __init__(self, folder: str | Path, grid: Any, formats: Sequence[str] = ("npz",),
                 resume_step: int | None = None) -> None:
        unknown = [f for f in formats if f not in FIELD_FORMATS]
        if unknown:
            raise ValueError(f"field formats {unknown}: must be among {FIELD_FORMATS}")
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.grid = grid
        self.formats = tuple(dict.fromkeys(formats))
        self._points, self._quads = _cell_mesh(grid.nx, grid.ny, grid.h, grid.origin)
        self._index: list[tuple[int, float]] = []
        self._body_count = 0
        index_path = self.folder / "index.json"
        if resume_step is not None and index_path.exists():
            saved = json.loads(index_path.read_text())
            self._index = [(int(s), float(t)) for s, t in saved["frames"] if int(s) <= resume_step]
            self._body_count = int(saved.get("body_count", 0))
        self._xdmf: Any = None
        self._xdmf_folder: Path | None = None
        # A resumed run starts a new XDMF series rather than rewriting the earlier one.
        self.xdmf_name = "fluid" if not resume_step else f"fluid_from_{resume_step:06d}"

    def write(self, data: dict[str, np.ndarray]) -> None:
        """Save one snapshot (the arrays of `snapshot_arrays`)."""
        step, time = int(data["step"]), float(data["time"])
        self._body_count = sum(1 for k in data if k.endswith("_triangles"))
        if "npz" in self.formats:
            with atomic_path(self.folder / f"step_{step:06d}.npz") as temporary:
                np.savez_compressed(temporary, **data)  # type: ignore[arg-type]
        if "vtk" in self.formats:
            self._write_vtk(step, data)
        if "xdmf" in self.formats:
            self._write_xdmf(time, data)
        self._index = [(s, t) for s, t in self._index if s != step] + [(step, time)]
        if "vtk" in self.formats:
            self._write_collections()
        write_text_atomic(self.folder / "index.json", json.dumps(
            {"frames": self._index, "body_count": self._body_count, "formats": self.formats}))

    def _write_vtk(self, step: int, data: dict[str, np.ndarray]) -> None:
        import meshio

        fluid = meshio.Mesh(self._points, [("quad", self._quads)],
                            cell_data={k: [v] for k, v in _cell_data(data).items()})
        with atomic_path(self.folder / f"fluid_{step:06d}.vtu") as temporary:
            meshio.write(temporary, fluid, file_format="vtu")
        for k in range(self._body_count):
            points = data[f"body{k}_points"]
            zeros = np.zeros((len(points), 1))
            velocities = data[f"body{k}_velocities"]
            body = meshio.Mesh(np.hstack((points, zeros)),
                               [("triangle", data[f"body{k}_triangles"])],
                               point_data={"velocity": np.hstack((velocities, zeros))})
            with atomic_path(self.folder / f"body{k}_{step:06d}.vtu") as temporary:
                meshio.write(temporary, body, file_format="vtu")

    def _write_collections(self) -> None:
        names = ["fluid"] + [f"body{k}" for k in range(self._body_count)]
        for name in names:
            entries = "\n".join(
                f'    <DataSet timestep="{t:.9g}" part="0" file="{name}_{s:06d}.vtu"/>'
                for s, t in self._index
            )
            write_text_atomic(self.folder / f"{name}.pvd", (
                '<?xml version="1.0"?>\n'
                '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">\n'
                f"  <Collection>\n{entries}\n  </Collection>\n</VTKFile>\n"
            ))

    def _write_xdmf(self, time: float, data: dict[str, np.ndarray]) -> None:
        import h5py
        import meshio

        if self._xdmf is None:
            # The XDMF file names its HDF5 file, so both are written in a private folder and
            # moved into place together when the series is closed.
            self._xdmf_folder = self.folder / f".xdmf.{os.getpid()}.tmp"
            self._xdmf_folder.mkdir(exist_ok=True)
            self._xdmf = meshio.xdmf.TimeSeriesWriter(str(self._xdmf_folder / f"{self.xdmf_name}.xdmf"))
            # meshio's __enter__ would open the HDF5 file in the working directory; open it
            # beside the XDMF file instead (the XDMF refers to it by base name).
            self._xdmf.h5_filename = str(self._xdmf_folder / f"{self.xdmf_name}.h5")
            self._xdmf.h5_file = h5py.File(self._xdmf.h5_filename, "w")
            self._xdmf.write_points_cells(self._points, [("quad", self._quads)])
        self._xdmf.write_data(time, cell_data={k: [v] for k, v in _cell_data(data).items()})

    def close(self) -> None:
        """Finish the XDMF series (if any) and move it into place."""
        if self._xdmf is not None:
            self._xdmf.__exit__(None, None, None)
            self._xdmf = None
            assert self._xdmf_folder is not None
            for name in (f"{self.xdmf_name}.h5", f"{self.xdmf_name}.xdmf"):
                os.replace(self._xdmf_folder / name, self.folder / name)
            shutil.rmtree(self._xdmf_folder, ignore_errors=True)
            self._xdmf_folder = None


def saved_frames(folder: str | Path) -> list[Path]:
    """The ``step_*.npz`` snapshots in ``folder``, in step order."""
    return sorted(Path(folder).glob("step_*.npz"))
