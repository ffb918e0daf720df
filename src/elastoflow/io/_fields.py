"""Field snapshots: NumPy ``.npz``, VTK (``.vtu`` + ``.pvd`` series) and XDMF + HDF5.

Every snapshot holds, at cell centres, velocity, pressure, dye, vorticity and the solid flag,
plus each body's current mesh. ParaView opens ``fluid.pvd`` / ``body0.pvd`` (or
``fluid.xdmf``, read with the XDMF3 reader) as a time series; a free surface's lines are
``surface.pvd`` / ``surface.xdmf`` beside them.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from elastoflow.io._atomic import atomic_path, write_text_atomic
from elastoflow.io._surface import pack_polylines, surface_polylines
from elastoflow.render._fields import velocity_at_cells, vorticity_at_cells

FIELD_FORMATS: tuple[str, ...] = ("npz", "vtk", "xdmf")


def snapshot_arrays(grid: Any, state: Any, bodies: Sequence[tuple[Any, Any]] = (),
                    obstacles: Sequence[Any] = (), *, time: float = 0.0, step: int = 0,
                    solid_cells: np.ndarray | None = None,
                    level_set: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Everything a saved frame holds, as named arrays (the ``.npz`` keys).

    Keys: ``velocity`` (nx, ny, 2) [m/s] at cell centres, ``velocity_x`` (nx+1, ny),
    ``velocity_y`` (nx, ny+1), ``pressure``, ``dye``, ``vorticity`` [1/s], ``solid`` (bool), all
    (nx, ny) unless stated; ``time`` [s], ``step``, ``h`` [m], ``origin`` (2,);
    ``body{k}_points`` (n, 2) [m], ``body{k}_triangles`` (m, 3), ``body{k}_velocities`` (n, 2);
    ``obstacle{k}_points`` (p, 2) [m]. A rod has no triangles (m = 0): its points are its
    polyline in order (VTK: line cells). With a free surface also ``level_set`` (nx, ny) [m],
    liquid where negative (VTK and XDMF: a cell field of that name), and the surface as
    polylines, ``surface_points`` (k, 2) [m] with ``surface_offsets`` (n + 1,) (piece i is
    ``surface_points[surface_offsets[i]:surface_offsets[i + 1]]``; VTK and XDMF: the
    polylines as line segments with a cell field ``piece``, `FieldWriter`).

    ``state`` is the fluid state, ``bodies`` a (model, `elastoflow.solid.BodyState`) pair
    per body.
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
    if level_set is not None:
        data["level_set"] = np.array(level_set, dtype=np.float64)
        points, offsets = pack_polylines(surface_polylines(grid, level_set))
        data["surface_points"] = points
        data["surface_offsets"] = offsets
    for index, (body, body_state) in enumerate(bodies):
        data[f"body{index}_points"] = np.array(body_state.positions)
        data[f"body{index}_triangles"] = np.array(body.mesh.triangles)
        data[f"body{index}_velocities"] = np.array(body_state.velocities)
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
    cells = {
        "velocity": np.column_stack((velocity, np.zeros(len(velocity)))),
        "pressure": data["pressure"].ravel(),
        "dye": data["dye"].ravel(),
        "vorticity": data["vorticity"].ravel(),
        "solid": data["solid"].ravel().astype(np.int32),
    }
    if "level_set" in data:
        cells["level_set"] = data["level_set"].ravel()
    return cells


def surface_segments(data: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A snapshot's surface polylines as line segments: points (k, 3) [m] (z = 0), segments
    (m, 2) (indices into the points, consecutive points of a piece) and each segment's piece
    (m,); empty arrays when the snapshot has none."""
    points = np.asarray(data["surface_points"], dtype=np.float64).reshape(-1, 2)
    offsets = np.asarray(data["surface_offsets"], dtype=np.int64)
    starts, pieces = [], []
    for piece in range(len(offsets) - 1):
        first = np.arange(offsets[piece], offsets[piece + 1] - 1, dtype=np.int64)
        starts.append(first)
        pieces.append(np.full(len(first), piece, dtype=np.int32))
    first = np.concatenate(starts) if starts else np.zeros(0, dtype=np.int64)
    return (np.column_stack((points, np.zeros(len(points)))),
            np.column_stack((first, first + 1)).astype(np.int64),
            np.concatenate(pieces) if pieces else np.zeros(0, dtype=np.int32))


_XDMF_TAIL = "  </Grid>\n</Domain>\n</Xdmf>\n"
_XDMF_ATTRIBUTES = (("velocity", "Vector", 3), ("pressure", "Scalar", 0), ("dye", "Scalar", 0),
                    ("vorticity", "Scalar", 0), ("solid", "Scalar", 0))
_STEP_FILE = re.compile(r"^(?:step|fluid|surface|body\d+)_(\d{6,})\.(?:npz|vtu|h5)$")


class FieldWriter:
    """Writes snapshots to ``folder`` in the chosen formats; every file is complete at any time.

    Files: ``step_{step:06d}.npz``; ``fluid_{step:06d}.vtu``, ``body{k}_{step:06d}.vtu`` with the
    ``fluid.pvd`` / ``body{k}.pvd`` collections; ``fluid.xdmf`` naming ``fluid_mesh.h5`` (the
    cells) and one ``fluid_{step:06d}.h5`` per snapshot (the fields). With a free surface
    (snapshots with ``surface_points``) also ``surface_{step:06d}.vtu`` (its polylines as line
    cells, cell field ``piece``) with ``surface.pvd``, and ``surface.xdmf`` (a temporal
    collection of polyline grids, one per snapshot, whose points and segments are in that
    snapshot's ``fluid_{step:06d}.h5``, rewritten whole at each snapshot); a snapshot whose
    level set has no zero contour is left out of both surface series (a grid of no points is
    not readable by every reader). ``index.json`` lists the saved steps and times. Each data file is written atomically; ``fluid.xdmf`` is a stream: a
    snapshot is added with one write that puts its entry where the closing tags were and the
    closing tags after it, so the file is complete XML between any two writes, also after the
    process is killed. A resumed run (``resume_step``) drops the files of later steps and
    continues the same series.

    Args:
        folder: Output folder (created).
        grid: The `Grid2D`.
        formats: Any of ``"npz"``, ``"vtk"``, ``"xdmf"``.
        resume_step: Keep the saved frames up to this step and delete later ones (a resumed
            run); None starts fresh.
        level_set: The snapshots hold a free surface's ``level_set`` (the XDMF series names
            it among its cell fields).
    """

    def __init__(self, folder: str | Path, grid: Any, formats: Sequence[str] = ("npz",),
                 resume_step: int | None = None, level_set: bool = False) -> None:
        unknown = [f for f in formats if f not in FIELD_FORMATS]
        if unknown:
            raise ValueError(f"field formats {unknown}: must be among {FIELD_FORMATS}")
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.grid = grid
        self.formats = tuple(dict.fromkeys(formats))
        self._attributes = _XDMF_ATTRIBUTES + ((("level_set", "Scalar", 0),) if level_set
                                               else ())
        self._points, self._quads = _cell_mesh(grid.nx, grid.ny, grid.h, grid.origin)
        self._index: list[tuple[int, float]] = []
        self._body_count = 0
        # Snapshots with a surface: (step, time, points, segments).
        self._surfaces: list[tuple[int, float, int, int]] = []
        index_path = self.folder / "index.json"
        if resume_step is not None:
            if index_path.exists():
                try:
                    saved = json.loads(index_path.read_text())
                    self._index = [(int(s), float(t)) for s, t in saved["frames"]
                                   if int(s) <= resume_step]
                    self._body_count = int(saved.get("body_count", 0))
                    self._surfaces = [(int(s), float(t), int(k), int(m))
                                      for s, t, k, m in saved.get("surfaces", [])
                                      if int(s) <= resume_step]
                except (ValueError, KeyError, TypeError):
                    self._index = []
                    self._surfaces = []
            for path in self.folder.iterdir():
                match = _STEP_FILE.match(path.name)
                if match and int(match.group(1)) > resume_step:
                    path.unlink()
        self.xdmf_name = "fluid"
        self._xdmf: int | None = None
        self._xdmf_steps: list[int] = []
        self._xdmf_size = 0
        if "xdmf" in self.formats:
            self._start_xdmf()

    # -- XDMF ----------------------------------------------------------------------------

    def _start_xdmf(self) -> None:
        """Write the mesh file and the XDMF file of the snapshots kept so far; open the stream."""
        import h5py

        with atomic_path(self.folder / f"{self.xdmf_name}_mesh.h5") as temporary, \
                h5py.File(temporary, "w") as mesh:
            mesh.create_dataset("points", data=self._points)
            mesh.create_dataset("quads", data=self._quads)
        kept = [(s, t) for s, t in self._index if (self.folder / self._xdmf_data(s)).exists()]
        self._xdmf_steps = [s for s, _ in kept]
        text = self._xdmf_head() + "".join(self._xdmf_entry(s, t) for s, t in kept) + _XDMF_TAIL
        path = self.folder / f"{self.xdmf_name}.xdmf"
        write_text_atomic(path, text)
        self._xdmf = os.open(path, os.O_WRONLY)
        self._xdmf_size = os.fstat(self._xdmf).st_size

    def _xdmf_data(self, step: int) -> str:
        return f"{self.xdmf_name}_{step:06d}.h5"

    def _xdmf_head(self) -> str:
        nx, ny = self.grid.nx, self.grid.ny
        mesh = f"{self.xdmf_name}_mesh.h5"
        return (
            '<?xml version="1.0"?>\n'
            '<Xdmf xmlns:xi="http://www.w3.org/2003/XInclude" Version="3.0">\n<Domain>\n'
            '  <Grid Name="mesh" GridType="Uniform">\n'
            '    <Geometry GeometryType="XYZ"><DataItem DataType="Float" '
            f'Dimensions="{len(self._points)} 3" Format="HDF" Precision="8">{mesh}:/points'
            "</DataItem></Geometry>\n"
            f'    <Topology TopologyType="Quadrilateral" NumberOfElements="{nx * ny}">'
            f'<DataItem DataType="Int" Dimensions="{nx * ny} 4" Format="HDF" Precision="8">'
            f"{mesh}:/quads</DataItem></Topology>\n"
            "  </Grid>\n"
            '  <Grid Name="TimeSeries" GridType="Collection" CollectionType="Temporal">\n'
        )

    def _xdmf_entry(self, step: int, time: float) -> str:
        cells = self.grid.nx * self.grid.ny
        data = self._xdmf_data(step)
        lines = [f'    <Grid Name="step_{step:06d}">',
                 '      <xi:include xpointer="xpointer(//Grid[@Name=&quot;mesh&quot;]/*[self::'
                 'Topology or self::Geometry])"/>',
                 f'      <Time Value="{time!r}"/>']
        for name, kind, width in self._attributes:
            dimensions = f"{cells} {width}" if width else f"{cells}"
            number = ('DataType="Int" Precision="4"' if name == "solid"
                      else 'DataType="Float" Precision="8"')
            lines.append(f'      <Attribute Name="{name}" AttributeType="{kind}" Center="Cell">'
                         f'<DataItem {number} Dimensions="{dimensions}" Format="HDF">'
                         f"{data}:/{name}</DataItem></Attribute>")
        lines.append("    </Grid>\n")
        return "\n".join(lines)

    def _write_xdmf(self, step: int, time: float, data: dict[str, np.ndarray]) -> None:
        import h5py

        with atomic_path(self.folder / self._xdmf_data(step)) as temporary, \
                h5py.File(temporary, "w") as snapshot:
            for name, values in _cell_data(data).items():
                snapshot.create_dataset(name, data=values)
            if "surface_points" in data:
                points, segments, pieces = surface_segments(data)
                snapshot.create_dataset("surface_points", data=points)
                snapshot.create_dataset("surface_segments", data=segments)
                snapshot.create_dataset("surface_piece", data=pieces)
        if self._xdmf is None:
            raise ValueError(f"{self.folder}: the field writer is closed")
        if self._xdmf_steps and step <= self._xdmf_steps[-1]:
            # The same step again (or an earlier one): rewrite the series without it.
            self._index = [(s, t) for s, t in self._index if s < step]
            os.close(self._xdmf)
            self._xdmf = None
            self._start_xdmf()
            assert self._xdmf is not None
        # One write replaces the closing tags with the entry and the closing tags.
        offset = self._xdmf_size - len(_XDMF_TAIL)
        chunk = (self._xdmf_entry(step, time) + _XDMF_TAIL).encode("utf-8")
        try:
            written = os.pwrite(self._xdmf, chunk, offset)
            if written != len(chunk):
                raise OSError(errno.ENOSPC, "short write", str(self.folder / f"{self.xdmf_name}.xdmf"))
        except OSError:
            # Put the closing tags back where they were (those bytes need no new space).
            with contextlib.suppress(OSError):
                os.pwrite(self._xdmf, _XDMF_TAIL.encode("utf-8"), offset)
                os.ftruncate(self._xdmf, self._xdmf_size)
            raise
        self._xdmf_size = offset + len(chunk)
        self._xdmf_steps.append(step)

    def _write_surface_xdmf(self) -> None:
        """``surface.xdmf``: one polyline grid per kept snapshot with a surface (its points
        and segments in the snapshot's HDF5 file), written whole and atomically."""
        entries = []
        for step, time, points, segments in self._surfaces:
            if segments == 0 or not (self.folder / self._xdmf_data(step)).exists():
                continue
            data = self._xdmf_data(step)
            entries.append(
                f'    <Grid Name="surface_{step:06d}" GridType="Uniform">\n'
                f'      <Time Value="{time!r}"/>\n'
                '      <Geometry GeometryType="XYZ"><DataItem DataType="Float" '
                f'Dimensions="{points} 3" Format="HDF" Precision="8">{data}:/surface_points'
                "</DataItem></Geometry>\n"
                f'      <Topology TopologyType="Polyline" NodesPerElement="2" '
                f'NumberOfElements="{segments}"><DataItem DataType="Int" '
                f'Dimensions="{segments} 2" Format="HDF" Precision="8">'
                f"{data}:/surface_segments</DataItem></Topology>\n"
                '      <Attribute Name="piece" AttributeType="Scalar" Center="Cell">'
                f'<DataItem DataType="Int" Precision="4" Dimensions="{segments}" Format="HDF">'
                f"{data}:/surface_piece</DataItem></Attribute>\n"
                "    </Grid>\n")
        write_text_atomic(self.folder / "surface.xdmf", (
            '<?xml version="1.0"?>\n<Xdmf Version="3.0">\n<Domain>\n'
            '  <Grid Name="surface" GridType="Collection" CollectionType="Temporal">\n'
            + "".join(entries) + "  </Grid>\n</Domain>\n</Xdmf>\n"))

    # -- snapshots -----------------------------------------------------------------------

    def write(self, data: dict[str, np.ndarray]) -> None:
        """Save one snapshot (the arrays of `snapshot_arrays`)."""
        step, time = int(data["step"]), float(data["time"])
        self._body_count = sum(1 for k in data if k.endswith("_triangles"))
        surface = "surface_points" in data
        if surface:
            points, segments, _ = surface_segments(data)
            self._surfaces = [entry for entry in self._surfaces if entry[0] < step] + [
                (step, time, len(points), len(segments))]
        if "npz" in self.formats:
            with atomic_path(self.folder / f"step_{step:06d}.npz") as temporary:
                np.savez_compressed(temporary, **data)  # type: ignore[arg-type]
        if "vtk" in self.formats:
            self._write_vtk(step, data)
        if "xdmf" in self.formats:
            self._write_xdmf(step, time, data)
            if surface or self._surfaces:
                self._write_surface_xdmf()
        self._index = [(s, t) for s, t in self._index if s != step] + [(step, time)]
        if "vtk" in self.formats:
            self._write_collections()
        write_text_atomic(self.folder / "index.json", json.dumps(
            {"frames": self._index, "body_count": self._body_count, "formats": self.formats,
             "surfaces": self._surfaces}))

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
            triangles = data[f"body{k}_triangles"]
            if len(triangles):
                cells = [("triangle", triangles)]
            else:
                # A rod: its polyline as line cells, which ParaView draws (and tubes).
                first = np.arange(len(points) - 1)
                cells = [("line", np.column_stack((first, first + 1)))]
            body = meshio.Mesh(np.hstack((points, zeros)), cells,
                               point_data={"velocity": np.hstack((velocities, zeros))})
            with atomic_path(self.folder / f"body{k}_{step:06d}.vtu") as temporary:
                meshio.write(temporary, body, file_format="vtu")
        if "surface_points" in data:
            points, segments, pieces = surface_segments(data)
            if len(segments):
                surface = meshio.Mesh(points, [("line", segments)],
                                      cell_data={"piece": [pieces]})
                with atomic_path(self.folder / f"surface_{step:06d}.vtu") as temporary:
                    meshio.write(temporary, surface, file_format="vtu")

    def _write_collections(self) -> None:
        names = ["fluid"] + [f"body{k}" for k in range(self._body_count)]
        if self._surfaces:
            names.append("surface")
        for name in names:
            frames = (self._index if name != "surface"
                      else [(s, t) for s, t, _, segments in self._surfaces if segments])
            entries = "\n".join(
                f'    <DataSet timestep="{t:.9g}" part="0" file="{name}_{s:06d}.vtu"/>'
                for s, t in frames
            )
            write_text_atomic(self.folder / f"{name}.pvd", (
                '<?xml version="1.0"?>\n'
                '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">\n'
                f"  <Collection>\n{entries}\n  </Collection>\n</VTKFile>\n"
            ))

    @property
    def steps(self) -> list[int]:
        """The steps saved so far (with those kept from before a resume)."""
        return [s for s, _ in self._index]

    def sync(self) -> None:
        """Put the XDMF series on the disk (fsync); the other files are complete once renamed."""
        if self._xdmf is not None:
            os.fsync(self._xdmf)

    def close(self) -> None:
        """Sync and close the XDMF series (idempotent)."""
        if self._xdmf is not None:
            try:
                self.sync()
            finally:
                os.close(self._xdmf)
                self._xdmf = None


def saved_frames(folder: str | Path) -> list[Path]:
    """The ``step_*.npz`` snapshots in ``folder``, in step order."""
    return sorted(Path(folder).glob("step_*.npz"))
