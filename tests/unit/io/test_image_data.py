"""3D fields as VTK image data: values, cell order (x fastest) and time read back exactly; the
ParaView series lists each step once, also when a resumed run writes a step again."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest

from elastoflow.fluid import FluidState3D
from elastoflow.grid import Grid3D
from elastoflow.io import (
    ImageDataSeries,
    fluid_cell_fields_3d,
    read_image_data,
    write_image_data,
)

GRID = Grid3D(5, 4, 3, 0.25, origin=(1.0, -2.0, 0.5))


def test_cells_read_back_in_order_with_the_grids_geometry(tmp_path) -> None:
    rng = np.random.default_rng(3)
    scalar = rng.normal(size=GRID.shape_cells)
    vector = rng.normal(size=(*GRID.shape_cells, 3))
    flags = (scalar > 0).astype(np.uint8)
    path = tmp_path / "f.vti"
    write_image_data(path, GRID, {"p": scalar, "velocity": vector, "solid": flags}, time=0.125)
    image = read_image_data(path)
    assert image.cells == GRID.shape_cells
    assert image.origin == GRID.origin and image.spacing == (0.25, 0.25, 0.25)
    assert image.time == 0.125
    np.testing.assert_array_equal(image.cell_data["p"], scalar)
    np.testing.assert_array_equal(image.cell_data["velocity"], vector)
    np.testing.assert_array_equal(image.cell_data["solid"], flags)
    assert image.cell_data["solid"].dtype == np.uint8
    # VTK's order: the first cells of the appended block run along x.
    raw = path.read_bytes()
    offset = raw.index(b"_", raw.index(b"<AppendedData")) + 1
    header = ET.fromstring(raw[:raw.index(b"<AppendedData")].decode() + "</VTKFile>")
    p_offset = next(int(a.attrib["offset"]) for a in header.iter("DataArray")
                    if a.attrib["Name"] == "p")
    first = np.frombuffer(raw, "<f8", count=3, offset=offset + p_offset + 8)
    np.testing.assert_array_equal(first, scalar[:3, 0, 0])
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_a_field_of_the_wrong_shape_is_refused(tmp_path) -> None:
    with pytest.raises(ValueError, match="cell field 'p' shape"):
        write_image_data(tmp_path / "f.vti", GRID, {"p": np.zeros((5, 4))})


def test_fluid_fields_average_the_faces_and_take_the_curl() -> None:
    """A solid-body rotation about z, u = -omega (y - yc), v = omega (x - xc): the centre
    velocity is exact (the faces are linear) and the vorticity is 2 omega along z."""
    grid = Grid3D(6, 6, 4, 0.1)
    state = FluidState3D.zeros(grid)
    omega = 1.5
    h = grid.h
    y_u = (np.arange(grid.ny) + 0.5) * h
    x_v = (np.arange(grid.nx) + 0.5) * h
    state.velocity_x[...] = -omega * (y_u[None, :, None] - 0.3)
    state.velocity_y[...] = omega * (x_v[:, None, None] - 0.3)
    solid = np.zeros(grid.shape_cells, dtype=bool)
    solid[2, 2, 1] = True
    fields = fluid_cell_fields_3d(grid, state, solid_cells=solid)
    xc = (np.arange(grid.nx) + 0.5) * h
    np.testing.assert_allclose(fields["velocity"][..., 1],
                               np.broadcast_to(omega * (xc[:, None, None] - 0.3),
                                               grid.shape_cells), atol=1e-12)
    np.testing.assert_allclose(fields["vorticity"][..., 2], 2.0 * omega, atol=1e-12)
    np.testing.assert_allclose(fields["vorticity"][..., :2], 0.0, atol=1e-12)
    assert fields["solid"].sum() == 1 and fields["speed"].shape == grid.shape_cells


def test_series_lists_each_step_once_and_a_resume_drops_the_abandoned_future(tmp_path) -> None:
    fields = {"p": np.zeros(GRID.shape_cells)}
    series = ImageDataSeries(tmp_path, GRID)
    for step in (0, 10, 20):
        series.write(step, 0.01 * step, fields)
    # A run resumed from step 10 writes step 20 again (and then 30).
    resumed = ImageDataSeries(tmp_path, GRID)
    resumed.write(20, 0.2, fields)
    resumed.write(30, 0.3, fields)
    root = ET.parse(tmp_path / "fluid.pvd").getroot()
    listed = [(float(d.attrib["timestep"]), d.attrib["file"]) for d in root.iter("DataSet")]
    assert listed == [(0.0, "fluid_000000.vti"), (0.1, "fluid_000010.vti"),
                      (0.2, "fluid_000020.vti"), (0.3, "fluid_000030.vti")]
    assert read_image_data(tmp_path / "fluid_000030.vti").time == 0.3
    with pytest.raises(ValueError, match="stem"):
        ImageDataSeries(tmp_path, GRID, stem="a b")
