"""Each well-posedness rule of the scene checks on its own (elastoflow.scenes._checks and the
strict schema): what it refuses, what it lets through, and what its message names."""

from __future__ import annotations

import tracemalloc
from typing import Any

import numpy as np
import pytest

from elastoflow.scenes import (
    DomainSpec,
    SceneError,
    build_simulation,
    get_scene,
    load_scene,
    memory_estimate,
    parse_scene,
)
from elastoflow.scenes import _checks as checks
from elastoflow.scenes import _geometry as geometry

MATERIAL = {"density": 1000.0, "young_modulus": 1e5, "poisson_ratio": 0.3}


def scene_data(**tables: Any) -> dict[str, Any]:
    data: dict[str, Any] = {"domain": {"lx": 1.0, "ly": 1.0, "nx": 32},
                            "time": {"dt": 0.01, "steps": 10}}
    data.update(tables)
    return data


def rectangle(box: list[float], divisions: tuple[int, int] = (4, 4), **extra: Any) -> dict:
    return {"shape": {"type": "rectangle", "box": box, "divisions": list(divisions)},
            "material": MATERIAL, **extra}


def problems(data: dict[str, Any], *, build: bool = False) -> list[str]:
    """The one-line problems of a scene: from parsing, or from building it too."""
    with pytest.raises(SceneError) as info:
        scene = parse_scene(data)
        if build:
            build_simulation(scene, warnings=[])
    return info.value.problems


def builds(data: dict[str, Any]) -> list[str]:
    """The warnings of a scene that must build."""
    warnings: list[str] = []
    build_simulation(parse_scene(data), warnings=warnings)
    return warnings


# --------------------------------------------------------------------------------------------
# strict values


@pytest.mark.parametrize(("table", "key", "value", "expected"), [
    ("domain", "nx", "32", "domain.nx = '32': must be an integer"),
    ("domain", "nx", 32.0, "domain.nx = 32.0: must be an integer"),
    ("domain", "lx", True, "domain.lx = true: must be a number"),
    ("domain", "lx", float("inf"), "domain.lx = inf: must be a finite number"),
    ("time", "dt", float("nan"), "time.dt = nan: must be a finite number"),
    ("time", "substeps", 0, "time.substeps = 0: must be an integer greater than 0 or 'auto'"),
])
def test_values_are_taken_as_written(table: str, key: str, value: Any, expected: str) -> None:
    data = scene_data()
    data[table] = {**data[table], key: value}
    (line,) = problems(data)
    assert line == expected


def test_an_integer_is_a_float_and_tables_accept_lists_for_pairs() -> None:
    scene = parse_scene(scene_data(domain={"lx": 1, "ly": 1, "nx": 32},
                                   fluid={"gravity": [0, -9]}))
    assert scene.domain.lx == 1.0 and scene.fluid.gravity == (0.0, -9.0)


@pytest.mark.parametrize(("tables", "expected"), [
    ({"fluid": {"gravity": [1.0]}}, "fluid.gravity = [1.0]: too few items (needs 2)"),
    ({"jets": [0, 0]}, "jets: items 0, 1 = 0, 0: must be a table"),
    ({"fluid": {"gravity": [0.0, -9.8, 1.0]}},
     "fluid.gravity = [0.0, -9.8, 1.0]: too many items"),
])
def test_one_line_per_array_key(tables: dict, expected: str) -> None:
    (line,) = problems(scene_data(**tables))
    assert line == expected


@pytest.mark.parametrize("rtol", [float("inf"), 0.0, -1e-6, 1.0])
def test_pressure_rtol_is_finite_positive_and_below_one(rtol: float) -> None:
    (line,) = problems(scene_data(fluid={"pressure_rtol": rtol}))
    assert line.startswith("fluid.pressure_rtol = ")


def test_no_internal_names_in_messages() -> None:
    lines = problems(scene_data(time={"dt": 0.01, "steps": 10, "substeps": "x"},
                                boundaries={"top": {"type": "moving", "velocity": float("inf")}},
                                coupling={"alpha": True}))
    assert len(lines) == 3
    for line in lines:
        for internal in ("constrained", "literal[", "WallMoving", "FluidSolver", "Input should"):
            assert internal not in line


def test_non_utf8_scene_file(tmp_path) -> None:
    path = tmp_path / "bad.toml"
    path.write_bytes(b'name = "x"\n\xff\xfe')
    with pytest.raises(SceneError, match=r"not a text file in UTF-8 \(byte 0xff at line 2"):
        load_scene(path)


# --------------------------------------------------------------------------------------------
# the domain's sides


INFLOW = {"type": "inflow", "speed": 1.0}


def test_closed_domain_with_net_inflow_is_refused() -> None:
    (line,) = problems(scene_data(boundaries={"left": INFLOW}))
    assert line.startswith("boundaries.left.speed = 1: the domain is closed")
    assert "net 1 m^2/s" in line and '"outflow"' in line


@pytest.mark.parametrize("boundaries", [
    {"left": INFLOW, "right": "outflow"},
    {"left": INFLOW, "right": {"type": "inflow", "speed": -1.0}},
    {"bottom": {**INFLOW, "profile": "parabolic"},
     "top": {"type": "inflow", "speed": -1.0, "profile": "parabolic"}},
    {"top": {"type": "moving", "velocity": 1.0}},
])
def test_balanced_or_open_domains_pass(boundaries: dict) -> None:
    parse_scene(scene_data(boundaries=boundaries))


def test_parabolic_flux_is_the_discrete_one() -> None:
    # A parabolic profile sampled at 32 face centres carries (2/3 + 1/(3 * 32^2)) of its peak:
    # a uniform inflow of 2/3 does not balance it.
    (line,) = problems(scene_data(boundaries={
        "left": {**INFLOW, "profile": "parabolic"},
        "right": {"type": "inflow", "speed": -2.0 / 3.0}}))
    assert line.startswith("boundaries = left inflow 1 m/s, right inflow -0.666667 m/s")


def test_inflows_of_a_closed_domain_must_ramp_alike() -> None:
    (line,) = problems(scene_data(boundaries={
        "left": {**INFLOW, "ramp_time": 1.0}, "right": {"type": "inflow", "speed": -1.0}}))
    assert "ramp_time" in line and "left.ramp_time = 1" in line


# --------------------------------------------------------------------------------------------
# outlines written in the scene


def polygon(points: list[list[float]]) -> dict:
    return {"shape": {"type": "polygon", "points": points}, "material": MATERIAL}


def test_repeated_vertex_is_named_as_such() -> None:
    (line,) = problems(scene_data(bodies=[polygon(
        [[0.2, 0.2], [0.8, 0.2], [0.8, 0.2], [0.5, 0.8]])]))
    assert line.startswith("bodies.0.shape.points.2 = [0.8, 0.2]: repeats vertex 1")


def test_closing_copy_of_the_first_vertex_is_accepted() -> None:
    square = [[0.3, 0.3], [0.7, 0.3], [0.7, 0.7], [0.3, 0.7]]
    sim = build_simulation(parse_scene(scene_data(
        bodies=[polygon([*square, square[0]])],
        obstacles=[{"shape": "polygon", "points": [[0.05, 0.05], [0.1, 0.05], [0.1, 0.1],
                                                   [0.05, 0.05]]}])), warnings=[])
    assert sim.bodies[0].mesh.area == pytest.approx(0.16)
    assert len(sim.obstacles[0].points_at(0.0)) == 3


def test_crossing_edges_and_collinear_outlines() -> None:
    (line,) = problems(scene_data(obstacles=[{"shape": "polygon", "points": [
        [0.2, 0.2], [0.8, 0.8], [0.8, 0.2], [0.2, 0.8]]}]))
    assert line.startswith("obstacles.0.points: edge 0") and "cross" in line
    (line,) = problems(scene_data(bodies=[polygon([[0.2, 0.2], [0.5, 0.5], [0.8, 0.8]])]))
    assert "encloses no area" in line


def test_windmill_blades_must_fit_the_hub() -> None:
    shape = {"type": "windmill", "center": [0.5, 0.5], "radius": 0.3, "hub_radius": 0.05,
             "blade_width": 0.09, "blades": 4}
    (line,) = problems(scene_data(bodies=[{"shape": shape, "material": MATERIAL}]))
    assert line.startswith("bodies.0.shape.blade_width = 0.09")


# --------------------------------------------------------------------------------------------
# memory


def test_memory_is_checked_before_anything_is_allocated() -> None:
    data = scene_data(domain={"lx": 1.0, "ly": 1.0, "nx": 1_000_000_000})
    scene = parse_scene(data)
    tracemalloc.start()
    try:
        with pytest.raises(SceneError) as info:
            build_simulation(scene)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    (line,) = info.value.problems
    assert line.startswith("domain.nx = 1000000000 (1000000000 x 1000000000 cells)")
    assert "EB of memory" in line and "available" in line
    assert peak < 10 * 2**20


def test_flux_check_allocates_nothing_on_a_huge_grid() -> None:
    data = scene_data(domain={"lx": 1.0, "ly": 1.0, "nx": 1_000_000_000},
                      boundaries={"left": {**INFLOW, "profile": "parabolic"}})
    tracemalloc.start()
    try:
        (line,) = problems(data)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert line.startswith("boundaries.left.speed = 1: the domain is closed")
    assert peak < 10 * 2**20


def test_memory_estimate_against_a_given_limit() -> None:
    scene = parse_scene(scene_data(domain={"lx": 1.0, "ly": 1.0, "nx": 512}))
    total, parts = memory_estimate(scene)
    assert total == pytest.approx(checks.BYTES_RUNTIME + 513**2 * checks.BYTES_PER_CELL)
    assert parts[0][0].startswith("domain.nx = 512")
    assert checks.check_memory(scene, available=int(total) + 1) == []
    (line,) = checks.check_memory(scene, available=100 * 2**20)
    assert "more than the 100 MB available" in line


def test_huge_meshes_are_estimated_before_meshing() -> None:
    scene = parse_scene(scene_data(bodies=[rectangle([0.4, 0.4, 0.6, 0.6], (100_000, 100_000))]))
    (line,) = checks.check_memory(scene, available=2**34)
    assert line.startswith("bodies.0.shape.divisions = [100000, 100000] (~2e+10 elements)")


def test_available_memory_is_known_here() -> None:
    available = checks.available_memory()
    assert available is None or available > 0


# --------------------------------------------------------------------------------------------
# the built geometry


def test_body_outside_the_domain_from_a_mesh_file(tmp_path) -> None:
    import meshio

    points = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    meshio.write(tmp_path / "square.vtu", meshio.Mesh(points, [("triangle", [[0, 1, 2],
                                                                             [0, 2, 3]])]))
    body = {"shape": {"type": "mesh", "path": "square.vtu", "scale": 0.2, "offset": [0.9, 0.1]},
            "material": MATERIAL}
    with pytest.raises(SceneError) as info:
        build_simulation(parse_scene(scene_data(bodies=[body]), base_dir=tmp_path), warnings=[])
    (line,) = info.value.problems
    assert line.startswith("bodies.0.shape = mesh with bounds [0.9, 0.1, 1.1, 0.3]")
    assert "partly outside" in line


def test_thin_bodies_refused_below_one_cell_warned_below_three() -> None:
    h = 1.0 / 32
    (line,) = problems(scene_data(bodies=[rectangle([0.2, 0.5, 0.8, 0.5 + 0.8 * h], (20, 1))]),
                       build=True)
    assert line.startswith("bodies.0.shape = rectangle: the body is at most")
    assert "0.80 cells across" in line
    (warning,) = builds(scene_data(bodies=[rectangle([0.2, 0.5, 0.8, 0.5 + 2 * h], (20, 2))]))
    assert warning.startswith("bodies.0.shape: the body is only 2.00 cells across")
    assert builds(scene_data(bodies=[rectangle([0.2, 0.5, 0.8, 0.5 + 4 * h], (20, 4))])) == []


def test_the_flag_clamped_on_its_cylinder_is_no_overlap_but_is_warned_thin() -> None:
    warnings: list[str] = []
    build_simulation(get_scene("flag"), warnings=warnings)
    assert len(warnings) == 1 and "2.05 cells across" in warnings[0]


@pytest.mark.parametrize(("bodies", "obstacles", "expected"), [
    ([rectangle([0.2, 0.2, 0.6, 0.6]), rectangle([0.5, 0.5, 0.8, 0.8])], [],
     "bodies.1.shape: overlaps bodies.0.shape"),
    ([rectangle([0.2, 0.45, 0.8, 0.55], (12, 2))],
     [{"shape": "rectangle", "box": [0.45, 0.1, 0.55, 0.9]}],
     "bodies.0.shape: crosses or lies inside obstacles.0"),
    ([rectangle([0.4, 0.4, 0.6, 0.6])], [{"shape": "circle", "center": [0.5, 0.5],
                                          "radius": 0.3}],
     "bodies.0.shape: crosses or lies inside obstacles.0"),
    ([], [{"shape": "rectangle", "box": [0.0, 0.0, 1.0, 0.5]},
          {"shape": "rectangle", "box": [0.0, 0.5, 1.0, 1.0]}],
     "obstacles: the obstacles and bodies cover every one of the 32 x 32 cells"),
])
def test_overlaps_and_no_fluid(bodies: list, obstacles: list, expected: str) -> None:
    (line,) = problems(scene_data(bodies=bodies, obstacles=obstacles), build=True)
    assert line.startswith(expected)


def test_touching_bodies_do_not_overlap() -> None:
    assert builds(scene_data(bodies=[rectangle([0.2, 0.2, 0.5, 0.6]),
                                     rectangle([0.5, 0.2, 0.8, 0.6])])) == []


def test_jet_inside_a_body_is_refused_and_beside_it_accepted() -> None:
    body = rectangle([0.3, 0.3, 0.7, 0.7])
    (line,) = problems(scene_data(bodies=[body], boundaries={"top": "outflow"}, jets=[
        {"region": [0.6, 0.1, 0.65, 0.35], "velocity": [0.0, 1.0]}]), build=True)
    assert line.startswith("jets.0.region = [0.6, 0.1, 0.65, 0.35]: reaches inside a body")
    builds(scene_data(bodies=[body], boundaries={"top": "outflow"},
                      jets=[{"region": [0.4, 0.1, 0.6, 0.25], "velocity": [0.0, 1.0]}]))


def test_pivot_and_probe_points_on_their_body() -> None:
    body = rectangle([0.4, 0.4, 0.6, 0.6], pivot=[0.5, 0.62])  # within one cell of a node
    builds(scene_data(bodies=[body]))
    (line,) = problems(scene_data(bodies=[rectangle([0.4, 0.4, 0.6, 0.6], pivot=[0.5, 0.8])]),
                       build=True)
    assert line.startswith("bodies.0.pivot = [0.5, 0.8]: lies 0.2 m from")
    (line,) = problems(scene_data(bodies=[rectangle([0.4, 0.4, 0.6, 0.6])], outputs={
        "probes": [{"kind": "node_displacement", "body": 0, "node": 25}]}), build=True)
    assert line == "outputs.probes.0.node = 25: body 0 has nodes 0..24"


@pytest.mark.parametrize(("motion", "steps", "leaves"), [
    ({"velocity": [1.0, 0.0]}, 30, False),
    ({"velocity": [1.0, 0.0]}, 40, True),
    ({"angular_velocity": 3.0, "center": [0.2, 0.5]}, 100, True),
    ({"angular_velocity": 3.0, "center": [0.5, 0.5]}, 2, False),
])
def test_moving_obstacle_must_stay_inside_for_the_whole_run(motion: dict, steps: int,
                                                            leaves: bool) -> None:
    data = scene_data(obstacles=[{"shape": "rectangle", "box": [0.5, 0.4, 0.65, 0.6],
                                  "motion": motion}],
                      time={"dt": 0.01, "steps": steps})
    if not leaves:
        builds(data)
        return
    (line,) = problems(data, build=True)
    assert line.startswith("obstacles.0.motion: the obstacle leaves the domain at t = ")


def test_a_longer_run_is_checked_for_the_steps_it_will_take() -> None:
    scene = parse_scene(scene_data(obstacles=[{
        "shape": "circle", "center": [0.5, 0.5], "radius": 0.1,
        "motion": {"velocity": [1.0, 0.0]}}], time={"dt": 0.01, "steps": 10}))
    build_simulation(scene, warnings=[])
    # Its right edge reaches the wall at t = 0.4 s and is past it at the next step.
    with pytest.raises(SceneError, match=r"leaves the domain at t = 0.4 s \(step 41 of 100\)"):
        build_simulation(scene, steps=100, warnings=[])


def test_warnings_go_to_python_warnings_without_a_list() -> None:
    data = scene_data(bodies=[rectangle([0.2, 0.5, 0.8, 0.5 + 2.0 / 32], (20, 2))])
    with pytest.warns(UserWarning, match="2.00 cells across"):
        build_simulation(parse_scene(data))


# --------------------------------------------------------------------------------------------
# the geometry helpers against brute force


def test_cell_centres_inside_match_point_in_polygon() -> None:
    rng = np.random.default_rng(1)
    angles = np.sort(rng.uniform(0, 2 * np.pi, 12))
    radii = rng.uniform(0.2, 0.45, 12)
    outline = np.column_stack((0.5 + radii * np.cos(angles), 0.5 + radii * np.sin(angles)))
    starts, ends = geometry.polygon_edges(outline)
    mask = geometry.cell_centres_inside(starts, ends, 40, 40, 1.0 / 40)
    centres = (np.stack(np.meshgrid(np.arange(40), np.arange(40), indexing="ij"), -1) + 0.5) / 40
    inside = geometry.points_in_polygons(centres.reshape(-1, 2), starts, ends).reshape(40, 40)
    np.testing.assert_array_equal(mask, inside)
    assert 0 < mask.sum() < 1600


def test_ray_thickness_of_a_rectangle_is_its_width_and_length() -> None:
    box = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 0.5], [0.0, 0.5]])
    _, widths = geometry.ray_thickness(*geometry.polygon_edges(box))
    np.testing.assert_allclose(widths, [0.5, 2.0, 0.5, 2.0])


def test_self_crossing_finds_crossing_and_touching_edges() -> None:
    assert geometry.self_crossing(np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)) is None
    assert geometry.self_crossing(np.array([[0, 0], [1, 1], [1, 0], [0, 1]], float)) == (0, 2)
    # Vertex 4 lies on edge 1 (a pinched outline).
    pinched = np.array([[0, 0], [2, 0], [2, 2], [1, 2], [2, 1], [0, 2]], float)
    assert geometry.self_crossing(pinched) is not None


def test_a_name_that_looks_like_a_path_is_read_as_a_file(tmp_path) -> None:
    from elastoflow.scenes import resolve_scene

    for name in (str(tmp_path / "missing.tml"), "folder/scene"):
        with pytest.raises(SceneError, match="cannot read scene file: No such file"):
            resolve_scene(name)
    with pytest.raises(SceneError, match="unknown scene name"):
        resolve_scene("bar_in_jett")


def test_body_edges_on_grid_lines_are_warned_about() -> None:
    """A body whose long edges lie on grid lines (here the flag on h = 0.01) is warned about,
    the same body half a cell off is not (docs/method_notes.md item 9)."""
    from elastoflow.scenes import get_scene

    aligned = get_scene("flag").model_copy(deep=True)
    aligned.domain = DomainSpec(lx=2.5, ly=0.41, h=0.01)
    warnings: list[str] = []
    build_simulation(aligned, steps=1, warnings=warnings)
    assert any("lie on grid lines" in line and "[0.249, 0.19]" in line for line in warnings)
    warnings = []
    build_simulation(get_scene("flag"), steps=1, warnings=warnings)
    assert not any("grid lines" in line for line in warnings)


def test_clamped_edges_on_the_domain_walls_are_not_warned_about() -> None:
    """The reeds of examples/reeds_in_a_channel.toml stand on the floor: their bottom edges lie
    on y = 0, a wall whose faces are closed whatever the reeds do, so no grid-line warning."""
    from pathlib import Path

    from elastoflow.scenes import load_scene

    example = Path(__file__).resolve().parents[3] / "examples" / "reeds_in_a_channel.toml"
    warnings: list[str] = []
    build_simulation(load_scene(example), steps=1, warnings=warnings)
    assert not any("grid lines" in line for line in warnings), warnings
