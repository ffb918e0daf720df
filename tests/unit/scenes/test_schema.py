"""Scene validation: one line per problem naming key path, value and what is allowed."""

from __future__ import annotations

import tomllib

import pytest

from elastoflow.scenes import (
    Scene,
    SceneError,
    get_scene,
    list_scenes,
    load_scene,
    parse_scene,
    scene_to_toml,
    step_count,
    time_step,
)


def _minimal(**changes: object) -> dict:
    data: dict = {
        "domain": {"lx": 1.0, "ly": 0.5, "nx": 8},
        "time": {"dt": 0.1, "steps": 3},
    }
    data.update(changes)
    return data


def _problems(data: dict) -> list[str]:
    with pytest.raises(SceneError) as info:
        parse_scene(data)
    assert isinstance(info.value, ValueError)
    return info.value.problems


def test_minimal_scene_has_defaults() -> None:
    scene = parse_scene(_minimal())
    assert scene.domain.cells == (8, 4)
    assert scene.boundaries.left.type == "no_slip"
    assert time_step(scene) == 0.1 and step_count(scene) == 3


def test_unknown_key_names_path_and_allowed_keys() -> None:
    problems = _problems(_minimal(domain={"lx": 1.0, "ly": 1.0, "nx": 8, "nz": 4}))
    assert len(problems) == 1
    assert problems[0].startswith("domain.nz: unknown key")
    assert "lx, ly, nx, h" in problems[0]


def test_unknown_key_inside_tagged_union_lists_that_kind_keys() -> None:
    obstacle = {"shape": "circle", "center": [0.5, 0.25], "radius": 0.1, "radiuss": 2}
    (line,) = _problems(_minimal(obstacles=[obstacle]))
    assert line.startswith("obstacles.0.radiuss: unknown key")
    assert "radius" in line and "segments" in line


def test_wrong_type_names_value() -> None:
    (line,) = _problems(_minimal(fluid={"density": "heavy"}))
    assert line.startswith("fluid.density = 'heavy'")


def test_negative_size_names_value_and_bound() -> None:
    (line,) = _problems(_minimal(domain={"lx": -1.0, "ly": 1.0, "nx": 8}))
    assert line.startswith("domain.lx = -1.0") and "greater than 0" in line


def test_unknown_enum_values_list_allowed() -> None:
    problems = _problems(_minimal(
        boundaries={"left": "wall"},
        outputs={"video": {"view": "speeed"}},
        obstacles=[{"shape": "hexagon"}],
    ))
    joined = "\n".join(problems)
    assert len(problems) == 3
    assert "boundaries.left.type = 'wall'" in joined and "'outflow'" in joined
    assert "outputs.video.view = 'speeed'" in joined and "'vorticity'" in joined
    assert "obstacles.0.shape = 'hexagon'" in joined and "'circle'" in joined


def test_every_problem_reported_at_once() -> None:
    problems = _problems(_minimal(
        domain={"lx": 1.0, "ly": 1.0, "nx": 8, "extra": 1},
        fluid={"density": -1.0},
        time={"dt": 0.1},
    ))
    assert len(problems) == 3


def test_geometry_outside_domain() -> None:
    body = {
        "shape": {"type": "rectangle", "box": [0.9, 0.1, 1.2, 0.2], "divisions": [2, 2]},
        "material": {"density": 1000, "young_modulus": 1e5, "poisson_ratio": 0.3},
    }
    problems = _problems(_minimal(
        obstacles=[{"shape": "circle", "center": [0.05, 0.25], "radius": 0.1}], bodies=[body],
    ))
    assert len(problems) == 2
    assert problems[0].startswith("obstacles.0 = circle") and "inside the domain" in problems[0]
    assert problems[1].startswith("bodies.0.shape = rectangle") and "1.2" in problems[1]


def test_probe_referencing_missing_body() -> None:
    (line,) = _problems(_minimal(outputs={"probes": [{"kind": "body_force", "body": 0}]}))
    assert line.startswith("outputs.probes.0.body = 0")


def test_domain_must_hold_whole_cells() -> None:
    (line,) = _problems(_minimal(domain={"lx": 1.0, "ly": 0.33, "nx": 8}))
    assert line.startswith("domain") and "whole number" in line


def test_unknown_scene_name_lists_built_ins() -> None:
    with pytest.raises(SceneError) as info:
        get_scene("bar_in_jett")
    assert "bar_in_jett" in str(info.value) and "windmill" in str(info.value)


@pytest.mark.parametrize("name", list(list_scenes()))
def test_built_in_scene_round_trips_through_toml(name: str, tmp_path) -> None:
    scene = get_scene(name)
    assert scene.name == name
    text = scene_to_toml(scene)
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    again = load_scene(path)
    again.base_dir = again.source = None
    scene.source = None
    assert again == scene
    assert tomllib.loads(text)["name"] == name


def test_required_scenes_registered() -> None:
    assert {"bar_in_jet", "windmill", "cavity", "dfg_cylinder", "flag", "jet_in_box"} <= set(
        list_scenes()
    )


def test_paper_scenes_match_published_settings() -> None:
    bar = get_scene("bar_in_jet")
    assert bar.domain.cells == (256, 256) and bar.time.dt == 0.013 and bar.time.substeps == 35
    windmill = get_scene("windmill")
    assert windmill.domain.cells == (256, 256)
    assert windmill.time.dt == 0.05 and windmill.time.substeps == 100
    assert windmill.bodies[0].pivot == windmill.bodies[0].shape.center  # type: ignore[union-attr]


def test_load_scene_reports_toml_syntax_and_missing_file(tmp_path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[domain\nlx = 1")
    with pytest.raises(SceneError, match="not valid TOML"):
        load_scene(bad)
    with pytest.raises(SceneError, match="cannot read"):
        load_scene(tmp_path / "missing.toml")


def test_cfl_time_step_uses_characteristic_speed() -> None:
    scene = parse_scene(_minimal(
        time={"cfl": 0.5, "duration": 1.0},
        boundaries={"top": {"type": "moving", "velocity": 2.0}},
    ))
    assert time_step(scene) == pytest.approx(0.5 * 0.125 / 2.0)
    assert step_count(scene) == 32


def test_scene_is_a_model_with_forbidden_extras() -> None:
    assert Scene.model_config["extra"] == "forbid"
