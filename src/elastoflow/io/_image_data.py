"""3D fields as VTK image data (``.vti``) and a ParaView series (``.pvd``) of them.

A 3D MAC state is a uniform grid of cells: ParaView's ImageData holds it with no coordinates
at all (origin, spacing, extent), so a 128^3 snapshot is its arrays and a few hundred bytes
of XML. The files are VTK's XML format with the arrays appended raw (little-endian, 64-bit
block sizes), which ParaView, VTK and PyVista read; `read_image_data` reads them back for
tests and scripts without VTK. Every file is written atomically, the series file after each
snapshot, so a killed run leaves a series that opens with the snapshots written so far.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from elastoflow.fluid import FluidState3D
from elastoflow.grid import Grid3D
from elastoflow.io._atomic import write_bytes_atomic, write_text_atomic

_VTK_TYPES: dict[np.dtype, str] = {
    np.dtype(np.float64): "Float64", np.dtype(np.float32): "Float32",
    np.dtype(np.int32): "Int32", np.dtype(np.int64): "Int64", np.dtype(np.uint8): "UInt8"}
_NUMPY_TYPES: dict[str, np.dtype] = {name: dtype for dtype, name in _VTK_TYPES.items()}


def fluid_cell_fields_3d(grid: Grid3D, state: FluidState3D,
                         solid_cells: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """The cell-centred fields a viewer wants from a 3D state: ``pressure`` [Pa],
    ``velocity`` (the faces averaged to the centres, (nx, ny, nz, 3)) [m/s], ``speed``,
    ``vorticity`` (central differences of the centre velocity, one-sided at the ends)
    [1/s], ``dye``, and with ``solid_cells`` (bool, (nx, ny, nz): cell centres inside a
    body) ``solid`` (1 there, 0 elsewhere)."""
    u, v, w = state.velocity_x, state.velocity_y, state.velocity_z
    velocity = np.stack((0.5 * (u[1:] + u[:-1]), 0.5 * (v[:, 1:] + v[:, :-1]),
                         0.5 * (w[:, :, 1:] + w[:, :, :-1])), axis=-1)
    h = grid.h
    # d(component)/d(axis) for the three axes: each (nx, ny, nz); one-sided at the ends.
    derivative = [np.gradient(velocity[..., c], h, axis=(0, 1, 2)) if min(grid.shape_cells) > 1
                  else [np.zeros(grid.shape_cells)] * 3 for c in range(3)]
    vorticity = np.stack((derivative[2][1] - derivative[1][2],
                          derivative[0][2] - derivative[2][0],
                          derivative[1][0] - derivative[0][1]), axis=-1)
    fields = {"pressure": state.pressure, "velocity": velocity,
              "speed": np.sqrt((velocity**2).sum(axis=-1)), "vorticity": vorticity,
              "dye": state.dye}
    if solid_cells is not None:
        fields["solid"] = np.asarray(solid_cells).astype(np.uint8)
    return fields


def write_image_data(path: str | Path, grid: Grid3D, cell_fields: Mapping[str, np.ndarray],
                     *, time: float | None = None) -> None:
    """Write ``cell_fields`` (each (nx, ny, nz) or (nx, ny, nz, components)) on ``grid``'s
    cells to a ``.vti`` file, atomically; ``time`` [s] goes into the file's field data."""
    shape = grid.shape_cells
    arrays: list[tuple[str, np.ndarray, int]] = []
    for name, value in cell_fields.items():
        array = np.asarray(value)
        if array.dtype not in _VTK_TYPES:
            array = array.astype(np.float64)
        if array.shape[:3] != shape or array.ndim not in (3, 4):
            raise ValueError(f"cell field {name!r} shape {array.shape}: must be {shape} or "
                             f"{shape} + (components,)")
        components = 1 if array.ndim == 3 else array.shape[3]
        # VTK orders cells with x fastest: Fortran order over (i, j, k), components innermost.
        flat = np.ascontiguousarray(array.reshape(*shape, components).transpose(2, 1, 0, 3))
        arrays.append((name, flat.astype(flat.dtype.newbyteorder("<"), copy=False),
                       components))
    nx, ny, nz = shape
    ox, oy, oz = grid.origin
    extent = f"0 {nx} 0 {ny} 0 {nz}"
    lines = ['<?xml version="1.0"?>',
             '<VTKFile type="ImageData" version="1.0" byte_order="LittleEndian" '
             'header_type="UInt64">',
             f'  <ImageData WholeExtent="{extent}" Origin="{ox!r} {oy!r} {oz!r}" '
             f'Spacing="{grid.h!r} {grid.h!r} {grid.h!r}">']
    blocks: list[bytes] = []
    offset = 0
    if time is not None:
        lines.append("    <FieldData>")
        lines.append(f'      <DataArray type="Float64" Name="TimeValue" NumberOfTuples="1" '
                     f'format="appended" offset="{offset}"/>')
        lines.append("    </FieldData>")
        payload = np.array([time], dtype="<f8").tobytes()
        blocks.append(np.array([len(payload)], dtype="<u8").tobytes() + payload)
        offset += len(blocks[-1])
    lines.append(f'    <Piece Extent="{extent}">')
    lines.append("      <CellData>")
    for name, flat, components in arrays:
        lines.append(f'        <DataArray type="{_VTK_TYPES[flat.dtype.newbyteorder("=")]}" '
                     f'Name="{name}" NumberOfComponents="{components}" format="appended" '
                     f'offset="{offset}"/>')
        payload = flat.tobytes()
        blocks.append(np.array([len(payload)], dtype="<u8").tobytes() + payload)
        offset += len(blocks[-1])
    lines += ["      </CellData>", "    </Piece>", "  </ImageData>",
              '  <AppendedData encoding="raw">']
    head = ("\n".join(lines) + "\n   _").encode("ascii")
    tail = b"\n  </AppendedData>\n</VTKFile>\n"
    write_bytes_atomic(path, head + b"".join(blocks) + tail)


@dataclass(frozen=True)
class ImageData:
    """A ``.vti`` file read back: ``origin`` and ``spacing`` [m], ``cells`` (nx, ny, nz),
    ``time`` [s] (None if the file has none) and the cell arrays by name, each (nx, ny, nz)
    or (nx, ny, nz, components)."""

    origin: tuple[float, float, float]
    spacing: tuple[float, float, float]
    cells: tuple[int, int, int]
    time: float | None
    cell_data: dict[str, np.ndarray]


def read_image_data(path: str | Path) -> ImageData:
    """Read a ``.vti`` file written by `write_image_data` (raw appended data, UInt64
    headers)."""
    raw = Path(path).read_bytes()
    start = raw.index(b'<AppendedData encoding="raw">')
    marker = raw.index(b"_", start) + 1
    end = raw.rindex(b"</AppendedData>")
    # The binary block ends with the newline and spaces before the closing tag.
    data = raw[marker:end]
    root = ET.fromstring(raw[:start].decode("ascii") + "</VTKFile>")
    image = root.find("ImageData")
    if image is None:
        raise ValueError(f"{path}: not a VTK ImageData file")
    extent = [int(x) for x in image.attrib["WholeExtent"].split()]
    cells = (extent[1] - extent[0], extent[3] - extent[2], extent[5] - extent[4])
    origin = tuple(float(x) for x in image.attrib["Origin"].split())
    spacing = tuple(float(x) for x in image.attrib["Spacing"].split())

    def block(offset: int, dtype: np.dtype) -> np.ndarray:
        size = int(np.frombuffer(data, dtype="<u8", count=1, offset=offset)[0])
        return np.frombuffer(data, dtype=dtype.newbyteorder("<"), count=size // dtype.itemsize,
                             offset=offset + 8)

    time = None
    for array in image.iter("DataArray"):
        if array.attrib.get("Name") == "TimeValue":
            time = float(block(int(array.attrib["offset"]), np.dtype(np.float64))[0])
    cell_data: dict[str, np.ndarray] = {}
    piece_cells = image.find("Piece/CellData")
    for array in [] if piece_cells is None else piece_cells.iter("DataArray"):
        dtype = _NUMPY_TYPES[array.attrib["type"]]
        components = int(array.attrib.get("NumberOfComponents", "1"))
        values = block(int(array.attrib["offset"]), dtype)
        shaped = values.reshape(cells[2], cells[1], cells[0], components).transpose(2, 1, 0, 3)
        cell_data[array.attrib["Name"]] = np.ascontiguousarray(
            shaped[..., 0] if components == 1 else shaped).astype(dtype.newbyteorder("="))
    return ImageData(origin, spacing, cells, time, cell_data)  # type: ignore[arg-type]


class ImageDataSeries:
    """Snapshots ``<stem>_<step>.vti`` in ``folder`` and the ParaView collection
    ``<stem>.pvd`` listing them with their times, rewritten atomically after each one.

    Opening a folder that already holds the collection continues it (a resumed run): the
    entries at or after the first new step are dropped, so the series never lists a step
    twice or a snapshot of an abandoned future.
    """

    def __init__(self, folder: str | Path, grid: Grid3D, stem: str = "fluid") -> None:
        if not re.fullmatch(r"[A-Za-z0-9_\-]+", stem):
            raise ValueError(f"stem = {stem!r}: letters, digits, '_' and '-' only")
        self.folder = Path(folder)
        self.grid = grid
        self.stem = stem
        self.entries: list[tuple[float, str, int]] = self._existing()

    @property
    def collection(self) -> Path:
        return self.folder / f"{self.stem}.pvd"

    def _existing(self) -> list[tuple[float, str, int]]:
        if not self.collection.exists():
            return []
        root = ET.parse(self.collection).getroot()
        entries = []
        for item in root.iter("DataSet"):
            name = item.attrib["file"]
            match = re.search(r"_(\d+)\.vti$", name)
            if match:
                entries.append((float(item.attrib["timestep"]), name, int(match.group(1))))
        return entries

    def write(self, step: int, time: float, cell_fields: Mapping[str, np.ndarray]) -> Path:
        """Write the snapshot of ``step`` at ``time`` [s] and list it in the collection."""
        name = f"{self.stem}_{step:06d}.vti"
        path = self.folder / name
        write_image_data(path, self.grid, cell_fields, time=time)
        self.entries = [e for e in self.entries if e[2] < step] + [(float(time), name, step)]
        lines = ['<?xml version="1.0"?>',
                 '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
                 "  <Collection>"]
        lines += [f'    <DataSet timestep="{t!r}" group="" part="0" file="{n}"/>'
                  for t, n, _ in self.entries]
        lines += ["  </Collection>", "</VTKFile>"]
        write_text_atomic(self.collection, "\n".join(lines) + "\n")
        return path

