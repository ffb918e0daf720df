"""A corpus of bad scenes through the command line: each must exit 2 with one ``error:`` line
per bad key, naming its key path, and no traceback, from `validate` and from `run` alike
(everything is refused before the first step, so the corpus costs no simulation).

The corpus: every built-in scene mutated key by key (wrong types, non-finite and out-of-range
values, unknown keys and kinds, absurd sizes, broken constraints), and hand-written scenes for
what mutations do not reach (ill-posed flow, geometry, mesh files, files that are not TOML).
"""

from __future__ import annotations

import copy
import json
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from elastoflow.cli import app
from elastoflow.scenes import _checks as checks
from elastoflow.scenes import get_scene, list_scenes, scene_to_toml

runner = CliRunner()


# --------------------------------------------------------------------------------------------
# TOML text from nested dicts (the scene files of the corpus)


def _value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {_value(v)}" for k, v in value.items()) + " }"
    raise TypeError(type(value))


def to_toml(data: dict[str, Any]) -> str:
    """Top-level scalars, then one table per dict, one ``[[name]]`` per list of dicts; deeper
    levels inline."""
    lines = [f"{k} = {_value(v)}" for k, v in data.items()
             if not isinstance(v, dict) and not (isinstance(v, list) and v and all(
                 isinstance(item, dict) for item in v))]
    for key, value in data.items():
        if isinstance(value, dict):
            lines += ["", f"[{key}]"] + [f"{k} = {_value(v)}" for k, v in value.items()]
        elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            for item in value:
                lines += ["", f"[[{key}]]"] + [f"{k} = {_value(v)}" for k, v in item.items()]
    return "\n".join(lines) + "\n"


def built_in(name: str) -> dict[str, Any]:
    return tomllib.loads(scene_to_toml(get_scene(name)))


def _set(data: dict[str, Any], path: str, value: Any, *, create: bool) -> bool:
    """Set ``a.b.0.c`` in nested dicts and lists; False when a parent does not exist, or the
    key itself unless ``create``."""
    *parents, last = path.split(".")
    node: Any = data
    for key in parents:
        if isinstance(node, list):
            if not key.isdigit() or int(key) >= len(node):
                return False
            node = node[int(key)]
        elif isinstance(node, dict) and key in node:
            node = node[key]
        else:
            return False
    if isinstance(node, list) and last.isdigit() and int(last) < len(node):
        node[int(last)] = value
    elif isinstance(node, dict) and (create or last in node):
        node[last] = value
    else:
        return False
    return True


# --------------------------------------------------------------------------------------------
# the corpus


@dataclass
class Case:
    id: str
    text: str | bytes
    keys: tuple[str, ...]
    """Key path each ``error:`` line must name, one line per key, in any order."""
    files: dict[str, str | bytes] | None = None


# (key path, bad value, key path the message must name; None: the same)
MUTATIONS: list[tuple[str, Any, str | None]] = [
    ("domain.lx", -1.0, None), ("domain.lx", 0.0, None), ("domain.lx", math.inf, None),
    ("domain.lx", math.nan, None), ("domain.lx", True, None), ("domain.lx", "1.0", None),
    ("domain.ly", [1.0], None),
    ("domain.nx", "256", None), ("domain.nx", 256.0, None), ("domain.nx", 1, None),
    ("domain.nx", -4, None), ("domain.nx", True, None), ("domain.nx", 1_000_000_000, None),
    ("domain.h", 1e-9, None),
    ("fluid.density", 0.0, None), ("fluid.density", -1000.0, None),
    ("fluid.density", math.inf, None), ("fluid.density", "water", None),
    ("fluid.viscosity", -1e-3, None), ("fluid.viscosity", math.nan, None),
    ("fluid.gravity", [0.0, math.nan], "fluid.gravity.1"), ("fluid.gravity", [0.0], None),
    ("fluid.gravity", [0.0, 1.0, 2.0], None), ("fluid.gravity", "down", None),
    ("fluid.gravity", [0.0, "x"], "fluid.gravity.1"),
    ("fluid.pressure_rtol", math.inf, None), ("fluid.pressure_rtol", 0.0, None),
    ("fluid.pressure_rtol", 2.0, None), ("fluid.pressure_solver", "cg", None),
    ("boundaries.left", "wall", "boundaries.left.type"),
    ("boundaries.left", {"type": "inflow"}, "boundaries.left.speed"),
    ("boundaries.top", {"type": "moving", "velocity": math.inf}, "boundaries.top.velocity"),
    ("boundaries.top", {"type": "inflow", "speed": 1.0, "ramp_time": -1.0},
     "boundaries.top.ramp_time"),
    ("time.dt", math.inf, None), ("time.dt", 0.0, None), ("time.dt", "0.01", None),
    ("time.substeps", 0, None), ("time.substeps", "many", None), ("time.substeps", 1.5, None),
    ("time.duration", -1.0, None), ("time.duration", 1e300, "time.duration"),
    ("coupling.alpha", 0.0, None), ("coupling.alpha", True, None),
    ("coupling.force_relaxation", 1.5, None), ("coupling.added_mass", math.inf, None),
    ("coupling.force_model", "magic", None),
    ("outputs.video.fps", 0, None), ("outputs.video.fps", "30", None),
    ("outputs.video.view", "velocity", None), ("outputs.checkpoint.every", 0, None),
    ("outputs.probes.0.kind", "temperature", None), ("outputs.probes.0.body", 7, None),
    ("bodies.0.material.poisson_ratio", 0.5, None),
    ("bodies.0.material.young_modulus", -1.0, None),
    ("bodies.0.material.density", math.nan, None),
    ("bodies.0.material.plane", "3d", None),
    ("bodies.0.shape.divisions", [0, 2], "bodies.0.shape.divisions.0"),
    ("bodies.0.shape.divisions", [2], "bodies.0.shape.divisions"),
    ("bodies.0.shape.divisions", [1_000_000, 1_000_000], "bodies.0.shape.divisions"),
    ("bodies.0.shape.box", [0.6, 0.4, 0.4, 0.8], "bodies.0.shape"),
    ("bodies.0.shape.box", [0.9, 0.4, 1.3, 0.8], "bodies.0.shape"),
    ("bodies.0.shape.element_size", 1e-7, "bodies.0.shape.element_size"),
    ("bodies.0.shape.blade_width", 0.2, "bodies.0.shape.blade_width"),
    ("bodies.0.shape.hub_radius", 0.5, "bodies.0.shape"),
    ("bodies.0.fixed", {"box": [0.0, 0.0, 0.01, 0.01]}, "bodies.0.fixed.box"),
    ("bodies.0.fixed", {"nodes": [100000]}, "bodies.0.fixed.nodes"),
    ("bodies.0.pivot", [0.05, 0.05], "bodies.0.pivot"),
    ("bodies.0.pivot", [2.0, 0.5], "bodies.0.pivot"),
    ("obstacles.0.radius", -0.05, None), ("obstacles.0.segments", 3, None),
    ("obstacles.0.segments", 1_000_000_000, None),
    ("obstacles.0.center", [5.0, 0.2], "obstacles.0"),
    ("obstacles.0.shape", "hexagon", None),
    ("obstacles.0.box", [0.3, 0.74, 0.06, 0.78], "obstacles.0"),
    ("jets.0.region", [0.5, 0.1, 0.4, 0.2], "jets.0.region"),
    ("jets.0.region", [0.9, 0.1, 1.5, 0.2], "jets.0.region"),
    ("jets.0.velocity", [math.inf, 0.0], "jets.0.velocity.0"),
    ("jets.0.dye", -1.0, None),
    ("name", 3, None),
]

# The 3D scenes' own mutations (points of three, boxes of six); the 2D ones whose value is
# not a 2D point or box apply to them too.
MUTATIONS_3D: list[tuple[str, Any, str | None]] = [
    ("domain.lz", -1.0, None), ("domain.lz", 0.3333, "lz must be a whole number"),
    ("fluid.gravity", [0.0, math.nan, 0.0], "fluid.gravity.1"),
    ("fluid.gravity", [0.0, 1.0], None), ("fluid.gravity", [0.0, "x", 0.0], "fluid.gravity.1"),
    ("fluid.initial_velocity", [1.0, 0.0], None),
    ("boundaries.front", "wall", "boundaries.front.type"),
    ("boundaries.back", {"type": "moving", "velocity": [0.0, 0.0, 1.0]},
     "boundaries.back.velocity"),
    ("bodies.0.shape.divisions", [0, 2, 2], "bodies.0.shape.divisions.0"),
    ("bodies.0.shape.box", [0.6, 0.4, 0.4, 0.5, 0.8, 0.8], "bodies.0.shape.box"),
    ("bodies.0.shape.box", [0.9, 0.4, 0.4, 100.0, 0.8, 0.8], "bodies.0.shape"),
    ("bodies.0.fixed", {"box": [0.0, 0.0, 0.0, 0.01, 0.01, 0.01]}, "bodies.0.fixed.box"),
    ("obstacles.0.center", [50.0, 0.2, 0.0], "obstacles.0"),
    ("obstacles.0.shape", "circle", None),
    ("jets.0.region", [0.5, 0.1, 0.5, 0.4, 0.2, 0.6], "jets.0.region"),
    ("jets.0.velocity", [math.inf, 0.0, 0.0], "jets.0.velocity.0"),
    ("outputs.video.axis", "w", None), ("outputs.video.at", 100.0, None),
    ("coupling.scheme", "partitioned", None),
]


def _two_d_only(value: Any) -> bool:
    """Whether a mutation's value has the shape of a 2D point or box."""
    return isinstance(value, list) and len(value) in (1, 2, 3, 4)

# Keys that no scene has: each must be reported as an unknown key.
UNKNOWN_KEYS = ["domain.colour", "fluid.viscosty", "boundaries.front", "time.dtt", "extra",
                "outputs.videos", "coupling.alpha_"]


def mutated_cases() -> list[Case]:
    cases = []
    for name in list_scenes():
        original = built_in(name)
        three_d = "lz" in original["domain"]
        mutations = ([m for m in MUTATIONS if not _two_d_only(m[1])] + MUTATIONS_3D
                     if three_d else MUTATIONS)
        for path, value, key in mutations:
            data = copy.deepcopy(original)
            if _set(data, path, value, create=False):
                cases.append(Case(f"{name}:{path}={_value(value)}", to_toml(data),
                                  (key or path,)))
        for path in UNKNOWN_KEYS if name in ("bar_in_jet", "dfg_cylinder") else ():
            data = copy.deepcopy(original)
            if _set(data, path, 1, create=True):
                cases.append(Case(f"{name}:{path}", to_toml(data), (f"{path}: unknown key",)))
    return cases


MATERIAL = {"density": 1000.0, "young_modulus": 1e5, "poisson_ratio": 0.3}


def scene(**tables: Any) -> dict[str, Any]:
    data: dict[str, Any] = {
        "domain": {"lx": 1.0, "ly": 1.0, "nx": 32},
        "time": {"dt": 0.01, "steps": 5},
    }
    data.update(tables)
    return data


def rectangle(box: list[float], divisions: tuple[int, int] = (4, 4), **extra: Any) -> dict:
    return {"shape": {"type": "rectangle", "box": box, "divisions": list(divisions)},
            "material": MATERIAL, **extra}


def polygon_body(points: list[list[float]]) -> dict:
    return {"shape": {"type": "polygon", "points": points}, "material": MATERIAL}


def mesh_body(path: str) -> dict:
    return {"shape": {"type": "mesh", "path": path}, "material": MATERIAL}


OBJ_BAD_INDEX = "v 0.4 0.4 0\nv 0.6 0.4 0\nv 0.6 0.6 0\nf 1 2 3\nf 1 3 9\n"


def hand_written_cases() -> list[Case]:
    def case(id_: str, data: dict[str, Any], *keys: str, **files: str | bytes) -> Case:
        return Case(id_, to_toml(data), keys, files or None)

    closed_dfg = built_in("dfg_cylinder")
    closed_dfg["boundaries"]["right"] = "no_slip"
    inflow = {"type": "inflow", "speed": 1.0}
    return [
        Case("not-utf8", b"name = \"x\"\n\xff\xfe\x00binary", ("not a text file",)),
        Case("binary", bytes(range(256)), ("not a text file",)),
        Case("nul-byte", "name = \"x\"\x00\n", ("not a text file",)),
        Case("not-toml", "[domain\nlx = 1\n", ("not valid TOML",)),
        Case("empty", "", ("domain", "time")),
        case("closed-dfg-net-inflow", closed_dfg, "boundaries.left.speed"),
        case("closed-four-inflows", scene(boundaries={
            "left": inflow, "right": inflow, "bottom": inflow, "top": inflow}), "boundaries"),
        case("closed-inflow-moving-lid", scene(boundaries={
            "left": inflow, "top": {"type": "moving", "velocity": 1.0}}),
            "boundaries.left.speed"),
        case("closed-ramps-differ", scene(boundaries={
            "left": {**inflow, "ramp_time": 1.0}, "right": {**inflow, "speed": -1.0}}),
            "boundaries"),
        case("body-entirely-outside", scene(bodies=[rectangle([1.2, 0.2, 1.4, 0.4])]),
             "bodies.0.shape"),
        case("body-partly-outside", scene(bodies=[rectangle([0.9, 0.2, 1.1, 0.4])]),
             "bodies.0.shape"),
        case("bodies-overlap", scene(bodies=[rectangle([0.2, 0.2, 0.6, 0.6]),
                                              rectangle([0.4, 0.4, 0.8, 0.8])]),
             "bodies.1.shape"),
        case("body-inside-body", scene(bodies=[rectangle([0.2, 0.2, 0.8, 0.8]),
                                                rectangle([0.4, 0.4, 0.6, 0.6])]),
             "bodies.1.shape"),
        case("body-crosses-obstacle", scene(
            obstacles=[{"shape": "circle", "center": [0.5, 0.5], "radius": 0.15}],
            bodies=[rectangle([0.2, 0.45, 0.8, 0.55], (12, 2))]), "bodies.0.shape"),
        case("body-inside-obstacle", scene(
            obstacles=[{"shape": "rectangle", "box": [0.1, 0.1, 0.9, 0.9]}],
            bodies=[rectangle([0.4, 0.4, 0.6, 0.6])]), "bodies.0.shape"),
        case("obstacle-covers-domain", scene(
            obstacles=[{"shape": "rectangle", "box": [0.0, 0.0, 1.0, 1.0]}]), "obstacles"),
        case("jet-inside-body", scene(
            bodies=[rectangle([0.3, 0.3, 0.7, 0.7])],
            jets=[{"region": [0.4, 0.4, 0.5, 0.5], "velocity": [0.0, 1.0]}]),
            "jets.0.region"),
        case("jet-inside-obstacle", scene(
            obstacles=[{"shape": "circle", "center": [0.5, 0.5], "radius": 0.2}],
            jets=[{"region": [0.45, 0.45, 0.55, 0.55], "velocity": [1.0, 0.0]}]),
            "jets.0.region"),
        case("pivot-far-from-body", scene(bodies=[rectangle([0.4, 0.4, 0.6, 0.6],
                                                           pivot=[0.9, 0.9])]),
             "bodies.0.pivot"),
        case("moving-obstacle-leaves", scene(obstacles=[{
            "shape": "circle", "center": [0.5, 0.5], "radius": 0.1,
            "motion": {"velocity": [1.0, 0.0]}}], time={"dt": 0.01, "steps": 100}),
            "obstacles.0.motion"),
        case("rotating-obstacle-leaves", scene(obstacles=[{
            "shape": "rectangle", "box": [0.02, 0.35, 0.98, 0.65],
            "motion": {"angular_velocity": 2.0}}], time={"dt": 0.01, "steps": 100}),
            "obstacles.0.motion"),
        case("body-thinner-than-a-cell", scene(bodies=[rectangle([0.2, 0.5, 0.8, 0.51],
                                                                (20, 1))]),
             "bodies.0.shape"),
        case("polygon-self-intersecting", scene(bodies=[polygon_body(
            [[0.2, 0.2], [0.8, 0.8], [0.8, 0.2], [0.2, 0.8]])]), "bodies.0.shape.points"),
        case("polygon-repeated-vertex", scene(bodies=[polygon_body(
            [[0.2, 0.2], [0.8, 0.2], [0.8, 0.2], [0.5, 0.8]])]), "bodies.0.shape.points.2"),
        case("polygon-collinear", scene(bodies=[polygon_body(
            [[0.2, 0.2], [0.5, 0.5], [0.8, 0.8]])]), "bodies.0.shape.points"),
        case("obstacle-polygon-crossing", scene(obstacles=[{"shape": "polygon", "points": [
            [0.2, 0.2], [0.8, 0.8], [0.8, 0.2], [0.2, 0.8]]}]), "obstacles.0.points"),
        case("probe-node-out-of-range", scene(
            bodies=[rectangle([0.4, 0.4, 0.6, 0.6])],
            outputs={"probes": [{"kind": "node_displacement", "body": 0, "node": 999}]}),
            "outputs.probes.0.node"),
        case("probe-point-far", scene(
            bodies=[rectangle([0.4, 0.4, 0.6, 0.6])],
            outputs={"probes": [{"kind": "node_displacement", "body": 0,
                                 "point": [0.9, 0.1]}]}),
            "outputs.probes.0.point"),
        case("cfl-without-speed", scene(time={"cfl": 0.5, "steps": 5}), "time.cfl"),
        case("mesh-missing", scene(bodies=[mesh_body("nowhere.msh")]), "bodies.0.shape.path"),
        case("mesh-is-a-folder", scene(bodies=[mesh_body("folder.msh")]),
             "bodies.0.shape.path", **{"folder.msh/keep": ""}),
        case("mesh-unknown-extension", scene(bodies=[mesh_body("body.xyz")]),
             "bodies.0.shape.path", **{"body.xyz": "1 2 3\n"}),
        case("mesh-vertex-out-of-range", scene(bodies=[mesh_body("bad.obj")]),
             "bodies.0.shape.path", **{"bad.obj": OBJ_BAD_INDEX}),
        case("mesh-damaged", scene(bodies=[mesh_body("damaged.vtu")]),
             "bodies.0.shape.path", **{"damaged.vtu": "<VTKFile><Piece"}),
        case("mesh-empty", scene(bodies=[mesh_body("empty.msh")]),
             "bodies.0.shape.path", **{"empty.msh": ""}),
    ]


CASES = mutated_cases() + hand_written_cases()


def test_the_corpus_is_large() -> None:
    assert len(CASES) >= 100
    assert len({case.id for case in CASES}) == len(CASES)


def _write(case: Case, folder: Path) -> Path:
    for name, content in (case.files or {}).items():
        target = folder / name
        target.parent.mkdir(parents=True, exist_ok=True)
        if name.endswith("/keep"):
            continue
        (target.write_bytes if isinstance(content, bytes) else target.write_text)(content)
    path = folder / "scene.toml"
    (path.write_bytes if isinstance(case.text, bytes) else path.write_text)(case.text)
    return path


def _errors(result: Any) -> list[str]:
    assert result.exception is None or isinstance(result.exception, SystemExit), (
        repr(result.exception))
    assert "Traceback" not in result.output
    assert result.exit_code == 2, result.output
    for internal in INTERNAL_WORDS:
        assert internal not in result.output, (internal, result.output)
    return [line for line in result.output.splitlines() if line.startswith("error:")]


# Words of the code, not of the scene file, that once leaked into messages.
INTERNAL_WORDS = ("constrained-int", "literal[", "FluidSolver", "WallMoving", "Input should",
                  "allow_pickle", "cannot convert float", "Aborted")


@pytest.mark.parametrize("case", CASES, ids=[case.id for case in CASES])
def test_bad_scene_is_refused_with_one_line_per_key(case: Case, tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    from elastoflow.simulation import Simulation

    def no_stepping(self: Any) -> None:
        raise AssertionError("a bad scene reached the first step")

    # `run` takes the scene's own step count, as `validate` does; nothing may be stepped.
    monkeypatch.setattr(Simulation, "step", no_stepping)
    # The same memory on every machine and between the two commands.
    monkeypatch.setattr(checks, "available_memory", lambda: 16 * 2**30)
    path = _write(case, tmp_path)
    checked = _errors(runner.invoke(app, ["validate", str(path)]))
    assert len(checked) == len(case.keys), checked
    for key in case.keys:
        assert sum(key in line for line in checked) >= 1, (key, checked)
    # Every line names the file.
    assert all(str(path) in line for line in checked), checked
    out = tmp_path / "out"
    ran = _errors(runner.invoke(app, ["run", str(path), "--out", str(out), "--quiet",
                                      "--no-video"]))
    assert ran == checked
    assert not out.exists()
