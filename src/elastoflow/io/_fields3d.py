"""Snapshots of a 3D run for ParaView: the fluid as VTK image data, the bodies as
tetrahedral meshes, each a series that ParaView opens as one animated object."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from elastoflow.io._atomic import write_text_atomic
from elastoflow.io._image_data import ImageDataSeries, fluid_cell_fields_3d
from elastoflow.io._meshes import write_tetrahedral_mesh

_STEP_FILE = re.compile(r".*_(\d{6,})\.(vti|vtu)$")


class FieldWriter3D:
    """``fields/fluid_<step>.vti`` with ``fluid.pvd``, and per body ``body<k>_<step>.vtu``
    (its tetrahedra at their positions, with the node velocities) with ``body<k>.pvd``.

    Every file is written atomically and each series after each snapshot, so a killed run
    leaves series that open with the snapshots written so far. A resumed run (``resume_step``)
    deletes the snapshots after that step and continues the series.
    """

    def __init__(self, folder: str | Path, grid: Any, *, body_count: int = 0,
                 resume_step: int | None = None) -> None:
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        if resume_step is not None:
            for path in self.folder.iterdir():
                match = _STEP_FILE.match(path.name)
                if match and int(match.group(1)) > resume_step:
                    path.unlink()
        self.grid = grid
        self._fluid = ImageDataSeries(self.folder, grid, "fluid")
        self._bodies: list[list[tuple[float, str, int]]] = [
            self._existing(f"body{k}") for k in range(body_count)]

    def _existing(self, stem: str) -> list[tuple[float, str, int]]:
        collection = self.folder / f"{stem}.pvd"
        if not collection.exists():
            return []
        entries = []
        for match in re.finditer(r'timestep="([^"]+)"[^>]*file="([^"]+_(\d+)\.vtu)"',
                                 collection.read_text()):
            entries.append((float(match.group(1)), match.group(2), int(match.group(3))))
        return entries

    def write(self, simulation: Any) -> None:
        """The snapshot of the simulation's current step."""
        import numpy as np

        step, time = int(simulation.step_index), float(simulation.time)
        interior = simulation.interior
        self._fluid.write(step, time, fluid_cell_fields_3d(
            self.grid, simulation.state.fluid,
            None if interior is None else interior.solid_cells))
        for index, (body, state) in enumerate(zip(simulation.bodies, simulation.state.bodies)):
            name = f"body{index}_{step:06d}.vtu"
            write_tetrahedral_mesh(self.folder / name, body.mesh, state.positions,
                                   point_data={"velocity": np.asarray(state.velocities)})
            entries = [e for e in self._bodies[index] if e[2] < step] + [(time, name, step)]
            self._bodies[index] = entries
            lines = ['<?xml version="1.0"?>',
                     '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
                     "  <Collection>"]
            lines += [f'    <DataSet timestep="{t!r}" group="" part="0" file="{n}"/>'
                      for t, n, _ in entries]
            lines += ["  </Collection>", "</VTKFile>"]
            write_text_atomic(self.folder / f"body{index}.pvd", "\n".join(lines) + "\n")

    def sync(self) -> None:
        """Nothing to flush: every file is complete once written."""

    def close(self) -> None:
        """Nothing to close (see `sync`)."""
