"""``elastoflow run`` and ``validate`` on a tiny 3D scene: every output, then a resume."""

from __future__ import annotations

import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import meshio
import numpy as np
from typer.testing import CliRunner

from elastoflow.cli import app
from elastoflow.io import read_image_data, read_probes

SCENE = Path(__file__).with_name("tiny3d.toml")
runner = CliRunner()


def _invoke(*args: object) -> tuple[int, str]:
    result = runner.invoke(app, [str(a) for a in args])
    return result.exit_code, result.output


def test_validate_counts_3d_cells() -> None:
    code, text = _invoke("validate", SCENE)
    assert code == 0, text
    assert text.startswith("ok: tiny3d: 12x8x8 cells, 1 bodies (")


def test_a_3d_run_writes_every_output_and_resumes(tmp_path: Path) -> None:
    scene = tmp_path / "tiny3d.toml"
    shutil.copy(SCENE, scene)
    out = tmp_path / "out"
    code, text = _invoke("run", scene, "--out", out, "--quiet")
    assert code == 0, text
    fields = out / "fields"
    snapshots = sorted(p.name for p in fields.glob("fluid_*.vti"))
    assert snapshots == [f"fluid_{s:06d}.vti" for s in (0, 2, 4, 6)]
    image = read_image_data(fields / "fluid_000006.vti")
    assert image.cell_data["velocity"].shape == (12, 8, 8, 3)
    assert image.cell_data["solid"].sum() > 0
    body = meshio.read(fields / "body0_000006.vtu")
    assert body.cells_dict["tetra"].shape[1] == 4
    assert body.point_data["velocity"].shape == (len(body.points), 3)
    listed = [e.attrib["file"] for e in ET.parse(fields / "fluid.pvd").getroot().iter("DataSet")]
    assert listed == snapshots
    surface = meshio.read(out / "meshes" / "body0_000006.obj")
    assert surface.cells_dict["triangle"].shape[1] == 3
    columns, rows = read_probes(out / "probes.csv")
    assert "force_obstacle0_z [N]" in columns and len(rows) == 6
    force_x = np.array([row[columns.index("force_obstacle0_x [N]")] for row in rows])
    assert (force_x > 0.0).all()  # the stream pushes the sphere downstream
    assert (out / "video.mp4").stat().st_size > 0
    first = [row[:] for row in rows]

    code, text = _invoke("run", scene, "--out", out, "--resume", "--steps", 9, "--quiet")
    assert code == 0, text
    columns, rows = read_probes(out / "probes.csv")
    assert [int(row[0]) for row in rows] == list(range(1, 10))
    assert rows[:6] == first
    listed = [e.attrib["file"] for e in ET.parse(fields / "body0.pvd").getroot().iter("DataSet")]
    assert listed[-2:] == ["body0_000008.vtu", "body0_000009.vtu"]


def test_2d_field_formats_are_refused_for_a_3d_scene(tmp_path: Path) -> None:
    code, text = _invoke("run", SCENE, "--out", tmp_path / "out", "--fields", "npz")
    assert code == 2
    assert text.strip() == ("error: --fields = 'npz': a 3D scene's formats are vti (comma "
                            "separated) or 'none'")
