"""Writers: atomic files, field snapshots that read back (npz, VTK, XDMF), closed extruded
meshes, probes CSV/PNG, checkpoints."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from types import SimpleNamespace

import meshio
import numpy as np
import pytest

from elastoflow.grid import Grid2D
from elastoflow.io import (
    FieldWriter,
    ProbeRecorder,
    atomic_path,
    extrude_polyline,
    extrude_surface,
    latest_checkpoint,
    load_checkpoint,
    read_probes,
    save_checkpoint,
    snapshot_arrays,
    write_extruded_meshes,
    write_text_atomic,
)
from elastoflow.scenes import ProbeSpec


def _square_mesh() -> tuple[np.ndarray, np.ndarray]:
    points = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.5]])
    triangles = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
    return points * 0.2 + 0.3, triangles


def _fake_simulation(grid: Grid2D) -> SimpleNamespace:
    rng = np.random.default_rng(1)
    points, triangles = _square_mesh()
    mass = np.full(len(points), 0.5)
    body = SimpleNamespace(
        mesh=SimpleNamespace(points=points, triangles=triangles), mass=mass,
        kinetic_energy=lambda s: 0.5 * float(np.dot(mass, (s.velocities**2).sum(axis=1))),
    )
    body_state = SimpleNamespace(positions=points + 0.01, velocities=rng.normal(size=points.shape))
    fluid = SimpleNamespace(
        velocity_x=rng.normal(size=grid.shape_faces_x), velocity_y=rng.normal(size=grid.shape_faces_y),
        pressure=rng.normal(size=grid.shape_cells), dye=rng.random(grid.shape_cells),
    )
    obstacle = SimpleNamespace(points_at=lambda t: np.array([[0.1, 0.1], [0.2, 0.1], [0.2, 0.2]]))

    def checkpoint() -> dict:
        return {"time": np.array(sim.time), "step_index": np.array(sim.step_index),
                "fluid.velocity_x": fluid.velocity_x.copy(),
                "bodies.0.positions": body_state.positions.copy()}

    def restore(data: dict) -> None:
        sim.time = float(data["time"])
        sim.step_index = int(data["step_index"])
        fluid.velocity_x[...] = data["fluid.velocity_x"]
        body_state.positions[...] = data["bodies.0.positions"]

    state = SimpleNamespace(fluid=fluid, bodies=[body_state])
    sim = SimpleNamespace(grid=grid, state=state, bodies=[body], obstacles=[obstacle], time=0.25,
                          step_index=7, body_forces=[np.ones((5, 2))], interior=None,
                          fluid_solver=SimpleNamespace(density=2.0), checkpoint=checkpoint,
                          restore=restore)
    return sim


def test_atomic_write_replaces_whole_file_and_leaves_no_temporary(tmp_path) -> None:
    target = tmp_path / "a.txt"
    write_text_atomic(target, "old")
    with pytest.raises(RuntimeError), atomic_path(target) as temporary:
        temporary.write_text("partial")
        raise RuntimeError("crash while writing")
    assert target.read_text() == "old"
    write_text_atomic(target, "new")
    assert target.read_text() == "new"
    assert [p.name for p in tmp_path.iterdir()] == ["a.txt"]


def test_a_write_abandoned_before_its_with_block_is_discarded_later(tmp_path) -> None:
    """A second Ctrl-C can land after the temporary is created but before the ``with`` body
    starts (inside contextlib's ``__enter__``): nothing will ever run that write's cleanup,
    so the session removes such leftovers when it closes."""
    from elastoflow.io._atomic import discard_unfinished_writes

    discard_unfinished_writes()
    finished = tmp_path / "finished.txt"
    write_text_atomic(finished, "kept")
    abandoned = atomic_path(tmp_path / "b.npz")
    temporary = abandoned.__enter__()  # and never __exit__, as after the interrupt
    assert temporary.exists()
    assert discard_unfinished_writes() == [temporary]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["finished.txt"]
    assert discard_unfinished_writes() == []


def test_fields_read_back_in_every_format(tmp_path) -> None:
    grid = Grid2D(6, 4, 0.25)
    sim = _fake_simulation(grid)
    writer = FieldWriter(tmp_path, grid, formats=("npz", "vtk", "xdmf"))
    for step in (0, 5):
        sim.step_index, sim.time = step, 0.1 * step
        writer.write(snapshot_arrays(grid, sim.state.fluid, list(zip(sim.bodies, sim.state.bodies)),
                                     sim.obstacles, time=sim.time,
                                     step=step))
    writer.close()
    assert not list(tmp_path.glob("*.tmp*")) and not list(tmp_path.glob(".*"))

    with np.load(tmp_path / "step_000005.npz") as data:
        assert {"velocity", "pressure", "dye", "solid", "vorticity", "time", "step",
                "body0_points", "body0_triangles", "obstacle0_points"} <= set(data.files)
        assert data["velocity"].shape == (6, 4, 2)
        np.testing.assert_array_equal(data["pressure"], sim.state.fluid.pressure)

    fluid = meshio.read(tmp_path / "fluid_000005.vtu")
    assert len(fluid.points) == 7 * 5
    pressure = fluid.cell_data["pressure"][0]
    np.testing.assert_allclose(pressure, sim.state.fluid.pressure.ravel())
    # Cell (i, j) of the VTK file has the centre of MAC cell (i, j).
    quad = fluid.cells[0].data[1 * 4 + 2]
    np.testing.assert_allclose(fluid.points[quad, :2].mean(axis=0), [1.5 * 0.25, 2.5 * 0.25])
    body = meshio.read(tmp_path / "body0_000005.vtu")
    np.testing.assert_allclose(body.points[:, :2], sim.state.bodies[0].positions)

    collection = ET.parse(tmp_path / "fluid.pvd").getroot()
    files = [d.get("file") for d in collection.iter("DataSet")]
    assert files == ["fluid_000000.vtu", "fluid_000005.vtu"]

    with meshio.xdmf.TimeSeriesReader(str(tmp_path / "fluid.xdmf")) as reader:
        reader.read_points_cells()
        times = []
        for k in range(reader.num_steps):
            t, _, cell_data = reader.read_data(k)
            times.append(t)
        np.testing.assert_allclose(cell_data["pressure"][0], sim.state.fluid.pressure.ravel())
    assert times == pytest.approx([0.0, 0.5])


def test_extruded_surface_is_closed_with_the_prism_volume() -> None:
    points, triangles = _square_mesh()
    thickness = 0.07
    vertices, faces = extrude_surface(points, triangles, thickness)
    edges = np.sort(np.concatenate((faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]])), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert np.all(counts == 2)
    a, b, c = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    volume = np.einsum("ij,ij->", a, np.cross(b, c)) / 6.0
    assert volume == pytest.approx(0.2 * 0.2 * thickness, rel=1e-12)


@pytest.mark.parametrize("file_format", ["obj", "ply"])
def test_extruded_mesh_files_read_back(tmp_path, file_format: str) -> None:
    points, triangles = _square_mesh()
    (path,) = write_extruded_meshes(tmp_path, 12, [(points, triangles)], 0.1, file_format)
    assert path.name == f"body0_000012.{file_format}"
    mesh = meshio.read(path)
    assert mesh.points.shape == (10, 3)
    assert sum(len(block.data) for block in mesh.cells) == 2 * 4 + 2 * 4


def test_rod_is_a_ribbon_in_mesh_files_and_lines_in_vtk(tmp_path) -> None:
    line = np.array([[0.1, 0.0], [0.1, 0.2], [0.2, 0.3]])
    vertices, faces = extrude_polyline(line, 0.1)
    a, b, c = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum()
    assert area == pytest.approx((0.2 + np.hypot(0.1, 0.1)) * 0.1, rel=1e-12)
    empty = np.zeros((0, 3), np.int64)
    (path,) = write_extruded_meshes(tmp_path, 3, [(line, empty)], 0.1, "obj")
    assert sum(len(block.data) for block in meshio.read(path).cells) == 4

    grid = Grid2D(4, 4, 0.25)
    rod = SimpleNamespace(mesh=SimpleNamespace(triangles=empty))
    state = SimpleNamespace(positions=line, velocities=np.zeros_like(line))
    fluid = _fake_simulation(grid).state.fluid
    writer = FieldWriter(tmp_path / "fields", grid, formats=("vtk",))
    writer.write(snapshot_arrays(grid, fluid, [(rod, state)], step=0))
    writer.close()
    body = meshio.read(tmp_path / "fields" / "body0_000000.vtu")
    assert body.cells[0].type == "line"
    np.testing.assert_array_equal(body.cells[0].data, [[0, 1], [1, 2]])


def _pool_with_a_drop(grid: Grid2D, depth: float) -> np.ndarray:
    x, y = grid.cell_centers()
    return np.minimum(y - depth, np.hypot(x - 0.8, y - 1.1) - 0.2)


def test_surface_polylines_in_vtk_and_xdmf(tmp_path) -> None:
    """The free surface's pieces (a pool and a drop) as line cells in ``surface_*.vtu`` /
    ``surface.pvd`` and as polyline grids in ``surface.xdmf``, the same points as the npz
    polylines; a snapshot with no surface is left out of both series; a resume keeps the
    earlier frames' entries."""
    import h5py

    from elastoflow.io._surface import surface_polylines

    grid = Grid2D(24, 20, 0.075)
    fluid = _fake_simulation(grid).state.fluid
    folder = tmp_path / "fields"
    writer = FieldWriter(folder, grid, formats=("npz", "vtk", "xdmf"), level_set=True)
    level_sets = {0: _pool_with_a_drop(grid, 0.5), 3: np.ones(grid.shape_cells),
                  6: _pool_with_a_drop(grid, 0.6)}
    for step, phi in level_sets.items():
        writer.write(snapshot_arrays(grid, fluid, time=0.1 * step, step=step, level_set=phi))
    writer.close()

    lines = surface_polylines(grid, level_sets[6])
    assert len(lines) == 2
    mesh = meshio.read(folder / "surface_000006.vtu")
    assert mesh.cells[0].type == "line"
    np.testing.assert_allclose(mesh.points[:, :2], np.concatenate(lines))
    assert np.all(mesh.points[:, 2] == 0.0)
    assert len(mesh.cells[0].data) == sum(len(line) - 1 for line in lines)
    pieces = mesh.cell_data["piece"][0]
    assert sorted(set(pieces.tolist())) == [0, 1]
    # Segments join consecutive points of one piece.
    segments = mesh.cells[0].data
    assert np.all(segments[:, 1] == segments[:, 0] + 1)
    assert not (folder / "surface_000003.vtu").exists()
    collection = ET.parse(folder / "surface.pvd").getroot()
    assert [d.get("file") for d in collection.iter("DataSet")] == [
        "surface_000000.vtu", "surface_000006.vtu"]

    root = ET.parse(folder / "surface.xdmf").getroot()
    grids = [g for g in root.iter("Grid") if g.get("GridType") == "Uniform"]
    assert [g.get("Name") for g in grids] == ["surface_000000", "surface_000006"]
    last = grids[-1]
    assert float(last.find("Time").get("Value")) == pytest.approx(0.6)
    topology = last.find("Topology")
    assert topology.get("TopologyType") == "Polyline"
    assert int(topology.get("NumberOfElements")) == len(segments)
    file_name, dataset = last.find("Geometry/DataItem").text.split(":")
    with h5py.File(folder / file_name, "r") as data:
        np.testing.assert_allclose(data[dataset][:], mesh.points)
        np.testing.assert_array_equal(
            data[topology.find("DataItem").text.split(":")[1]][:], segments)

    # A resume from step 3 drops step 6's surface files and entries.
    resumed = FieldWriter(folder, grid, formats=("vtk", "xdmf"), resume_step=3, level_set=True)
    resumed.write(snapshot_arrays(grid, fluid, time=0.4, step=4,
                                  level_set=_pool_with_a_drop(grid, 0.3)))
    resumed.close()
    assert not (folder / "surface_000006.vtu").exists()
    collection = ET.parse(folder / "surface.pvd").getroot()
    assert [d.get("file") for d in collection.iter("DataSet")] == [
        "surface_000000.vtu", "surface_000004.vtu"]
    root = ET.parse(folder / "surface.xdmf").getroot()
    assert [g.get("Name") for g in root.iter("Grid") if g.get("GridType") == "Uniform"] == [
        "surface_000000", "surface_000004"]


def test_probes_csv_and_plot(tmp_path) -> None:
    grid = Grid2D(6, 4, 0.25)
    sim = _fake_simulation(grid)
    specs = [ProbeSpec(kind="node_displacement", body=0, point=(0.4, 0.4)),
             ProbeSpec(kind="body_force", body=0), ProbeSpec(kind="kinetic_energy"),
             ProbeSpec(kind="kinetic_energy", body=0), ProbeSpec(kind="pressure_iterations")]
    recorder = ProbeRecorder(specs, sim, tmp_path / "probes.csv")
    for step in (1, 2, 3):
        sim.step_index = step
        recorder.record(sim, SimpleNamespace(pressure_iterations=10 + step))
    recorder.write_csv()
    assert recorder.plot() == tmp_path / "probes.png"
    columns, rows = read_probes(tmp_path / "probes.csv")
    assert len(columns) == 2 + 2 + 2 + 1 + 1 + 1 and len(rows) == 3
    row = dict(zip(columns, rows[-1]))
    assert row["body0_node4_displacement_x [m]"] == pytest.approx(0.01)
    assert row["body0_force_y [N/m]"] == pytest.approx(5.0)
    expected = 0.5 * 2.0 * 0.25**2 * (np.sum(sim.state.fluid.velocity_x**2) + np.sum(sim.state.fluid.velocity_y**2))
    assert row["fluid_kinetic_energy [J/m]"] == pytest.approx(expected, rel=1e-9)
    assert row["pressure_iterations"] == 13
    assert (tmp_path / "probes.png").read_bytes()[:4] == b"\x89PNG"
    resumed = ProbeRecorder(specs, sim, tmp_path / "probes.csv", resume_step=2)
    assert [r[0] for r in resumed.rows] == [1.0, 2.0]


def test_checkpoint_round_trip_and_latest(tmp_path) -> None:
    grid = Grid2D(6, 4, 0.25)
    sim = _fake_simulation(grid)
    saved_velocity = sim.state.fluid.velocity_x.copy()
    save_checkpoint(tmp_path / "checkpoint_00000007.npz", sim)
    sim.step_index = 12
    save_checkpoint(tmp_path / "checkpoint_00000012.npz", sim)
    sim.state.fluid.velocity_x[...] = 0.0
    assert latest_checkpoint(tmp_path).name == "checkpoint_00000012.npz"
    load_checkpoint(tmp_path / "checkpoint_00000007.npz", sim)
    assert sim.step_index == 7
    np.testing.assert_array_equal(sim.state.fluid.velocity_x, saved_velocity)
    assert latest_checkpoint(tmp_path / "missing") is None
