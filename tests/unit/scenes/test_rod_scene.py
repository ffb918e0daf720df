"""Rods in scene files: ``shape = {type = "rod", ...}`` validated with one-line errors, built
as `elastoflow.solid.RodBody`, refused by the explicit scheme and the staircase boundary."""

from __future__ import annotations

import copy
import tomllib

import numpy as np
import pytest

from elastoflow import solid
from elastoflow.scenes import (
    RodBodySpec,
    SceneError,
    build_simulation,
    parse_scene,
    scene_to_toml,
)

ROD = {
    "name": "reed",
    "shape": {"type": "rod", "points": [[0.52, 0.0], [0.52, 0.2], [0.6, 0.3]], "segments": 12},
    "material": {"density": 800.0, "young_modulus": 2.0e6, "thickness": 0.01},
    "clamped": ["start"],
}
BASE = {"domain": {"lx": 1.0, "ly": 0.5, "nx": 32}, "time": {"dt": 0.01, "steps": 2}}


def _scene(body: dict | None = None, **sections: dict) -> dict:
    data = copy.deepcopy(BASE)
    data["bodies"] = [copy.deepcopy(ROD if body is None else body)]
    data.update(sections)
    return data


def _problems(data: dict) -> list[str]:
    with pytest.raises(SceneError) as caught:
        parse_scene(data)
    return caught.value.problems


def test_rod_builds_with_its_material_clamp_and_equal_segments() -> None:
    scene = parse_scene(_scene())
    assert isinstance(scene.bodies[0], RodBodySpec)
    rod = build_simulation(scene).bodies[0]
    assert isinstance(rod, solid.RodBody)
    assert rod.point_count == 13 and list(rod.fixed_nodes) == [0]
    total = 0.2 + np.hypot(0.08, 0.1)
    # Nodes at equal arc length: every chord is total / 12 but the one across the corner.
    lengths = np.sort(rod.rest_lengths)
    np.testing.assert_allclose(lengths[1:], total / 12, rtol=1e-12)
    assert lengths[0] < total / 12
    np.testing.assert_allclose(rod.mesh.points[[0, -1]], [[0.52, 0.0], [0.6, 0.3]])
    # E t and E t^3 / 12 per unit depth; mass per length rho t.
    assert rod.material.stretch_stiffness == pytest.approx(2.0e4)
    assert rod.material.flexural_rigidity == pytest.approx(2.0e6 * 1e-6 / 12)
    assert rod.mass.sum() == pytest.approx(800.0 * 0.01 * rod.rest_lengths.sum())


def test_rod_without_segments_keeps_its_points_and_round_trips_through_toml() -> None:
    body = copy.deepcopy(ROD)
    del body["shape"]["segments"]
    body["clamped"] = ["start", "end"]
    body["material"]["bending_stiffness"] = 0.5
    scene = parse_scene(_scene(body))
    rod = build_simulation(scene).bodies[0]
    np.testing.assert_array_equal(rod.mesh.points, ROD["shape"]["points"])
    assert list(rod.fixed_nodes) == [0, 2] and rod.material.flexural_rigidity == 0.5
    again = parse_scene(tomllib.loads(scene_to_toml(scene)))
    assert again.bodies == scene.bodies


@pytest.mark.parametrize(("change", "expected"), [
    ({"fixed": {"box": [0, 0, 1, 1]}},
     "bodies.0.fixed: unknown key (allowed keys: name, shape, material, clamped)"),
    ({"clamped": ["middle"]}, "bodies.0.clamped.0 = 'middle': must be 'start' or 'end'"),
    ({"clamped": ["end", "end"]}, "bodies.0.clamped = ['end', 'end']: lists an end twice"),
    ({"material": {"density": 800.0, "young_modulus": 2.0e6}},
     "bodies.0.material.thickness: missing (required)"),
    ({"material": {"density": 800.0, "young_modulus": 2.0e6, "thickness": 0.01,
                   "poisson_ratio": 0.3}}, "bodies.0.material.poisson_ratio: unknown key"),
    ({"material": {"density": 800.0, "young_modulus": 2.0e6, "thickness": -0.01}},
     "bodies.0.material.thickness = -0.01: must be"),
    ({"shape": {"type": "rod", "points": [[0.5, 0.0]]}},
     "bodies.0.shape.points = [[0.5, 0.0]]: must have at least 2 items"),
    ({"shape": {"type": "rod", "points": [[0.5, 0.0], [0.5, 0.0], [0.5, 0.2]]}},
     "bodies.0.shape.points.1 = [0.5, 0]: repeats point 0"),
    ({"shape": {"type": "rod", "points": [[0.5, 0.0], [0.5, 0.2]], "segments": 0}},
     "bodies.0.shape.segments = 0: must be"),
    ({"shape": {"type": "rod", "points": [[0.5, 0.0], [0.5, 0.9]]}},
     "bodies.0.shape = rod with bounds [0.5, 0, 0.5, 0.9]: must lie inside the domain"),
])
def test_bad_rod_keys_are_one_line_naming_the_key(change: dict, expected: str) -> None:
    body = {**copy.deepcopy(ROD), **change}
    problems = _problems(_scene(body))
    assert any(line.startswith(expected) for line in problems), problems
    assert all("\n" not in line for line in problems)


def test_unknown_shape_type_lists_rod_among_the_kinds() -> None:
    body = {**copy.deepcopy(ROD), "shape": {"type": "rodd", "points": [[0.5, 0.0], [0.5, 0.2]]}}
    assert any("bodies.0.shape.type = 'rodd': unknown kind (allowed: 'rectangle', "
               "'windmill', 'polygon', 'mesh', 'rod')" in line for line in _problems(_scene(body)))


def test_explicit_scheme_and_staircase_boundary_refuse_rods() -> None:
    problems = _problems(_scene(coupling={"scheme": "explicit"}))
    assert problems == ['bodies.0.shape = rod: needs coupling.scheme = "monolithic" (the '
                        'explicit scheme advances triangle bodies only); leave '
                        'coupling.scheme out or set it "monolithic"']
    problems = _problems(_scene(coupling={"boundary": "staircase"}))
    assert len(problems) == 1
    assert problems[0].startswith('bodies.0.shape = rod: needs coupling.boundary = "cut_cell"')


def test_rod_crossing_an_obstacle_is_refused_when_built() -> None:
    data = _scene(obstacles=[{"shape": "circle", "center": [0.52, 0.1], "radius": 0.05}])
    with pytest.raises(SceneError, match=r"bodies\.0\.shape: crosses or lies inside obstacles\.0"):
        build_simulation(parse_scene(data))


def test_rod_scene_steps_and_bends_in_a_stream() -> None:
    data = _scene(boundaries={"left": {"type": "inflow", "speed": 0.5}, "right": "outflow"})
    data["bodies"][0]["shape"] = {"type": "rod", "points": [[0.52, 0.0], [0.52, 0.3]],
                                  "segments": 8}
    sim = build_simulation(parse_scene(data))
    sim.run(3)
    tip = sim.state.bodies[0].positions[-1]
    assert tip[0] > 0.52 and np.isfinite(sim.state.fluid.pressure).all()
