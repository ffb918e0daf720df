"""build_simulation turns every built-in scene into physics objects that match the scene."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("elastoflow.simulation")

from elastoflow.scenes import (
    SceneError,
    build_simulation,
    get_scene,
    list_scenes,
    parse_scene,
    time_step,
)


@pytest.mark.parametrize("name", list(list_scenes()))
def test_built_in_scene_builds(name: str) -> None:
    scene = get_scene(name)
    sim = build_simulation(scene)
    assert sim.grid.shape_cells == scene.domain.cells
    assert sim.dt == time_step(scene)
    assert len(sim.bodies) == len(scene.bodies) and len(sim.obstacles) == len(scene.obstacles)
    assert sim.force_model == getattr(scene.coupling, "force_model", "traction")
    for body in sim.bodies:
        # The published substep count must be stable for the chosen material and mesh.
        if scene.time.substeps != "auto":
            assert sim.dt / scene.time.substeps <= body.stable_substep()


def test_paper_scene_bodies_have_the_published_size_and_constraints() -> None:
    bar = build_simulation(get_scene("bar_in_jet")).bodies[0]
    assert abs(len(bar.mesh.triangles) - 194) <= 10
    top = bar.mesh.points[:, 1].max()
    np.testing.assert_allclose(bar.mesh.points[bar.fixed_nodes, 1], top)
    assert len(bar.fixed_nodes) == 3
    windmill = build_simulation(get_scene("windmill")).bodies[0]
    assert abs(len(windmill.mesh.triangles) - 160) <= 16
    np.testing.assert_allclose(windmill.mesh.points[windmill.pivot_node], (0.62, 0.5), atol=1e-12)


def test_fixed_box_without_nodes_is_a_scene_error() -> None:
    data = {
        "domain": {"lx": 1.0, "ly": 1.0, "nx": 8},
        "time": {"dt": 0.1, "steps": 1},
        "bodies": [{
            "shape": {"type": "rectangle", "box": [0.4, 0.4, 0.6, 0.6], "divisions": [2, 2]},
            "material": {"density": 1000, "young_modulus": 1e4, "poisson_ratio": 0.3},
            "fixed": {"box": [0.1, 0.1, 0.2, 0.2]},
        }],
    }
    with pytest.raises(SceneError, match=r"bodies\.0\.fixed\.box = \[0\.1, 0\.1, 0\.2, 0\.2\]"):
        build_simulation(parse_scene(data))


def test_missing_mesh_file_is_a_scene_error(tmp_path) -> None:
    data = {
        "domain": {"lx": 1.0, "ly": 1.0, "nx": 8},
        "time": {"dt": 0.1, "steps": 1},
        "bodies": [{
            "shape": {"type": "mesh", "path": "nowhere.msh"},
            "material": {"density": 1000, "young_modulus": 1e4, "poisson_ratio": 0.3},
        }],
    }
    with pytest.raises(SceneError, match=r"bodies\.0\.shape\.path = 'nowhere\.msh'"):
        build_simulation(parse_scene(data, base_dir=tmp_path))


def test_mesh_file_and_polygon_shapes(tmp_path) -> None:
    import meshio

    points = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    meshio.write(tmp_path / "square.vtu", meshio.Mesh(points, [("triangle", [[0, 1, 2], [0, 2, 3]])]))
    material = {"density": 1000, "young_modulus": 1e4, "poisson_ratio": 0.3}
    data = {
        "domain": {"lx": 1.0, "ly": 1.0, "nx": 8},
        "time": {"dt": 0.01, "steps": 1},
        "bodies": [
            {"shape": {"type": "mesh", "path": "square.vtu", "scale": 0.2, "offset": [0.1, 0.1]},
             "material": material, "pivot": [0.3, 0.3]},
            {"shape": {"type": "polygon", "points": [[0.5, 0.5], [0.9, 0.5], [0.7, 0.9]],
                       "element_size": 0.1}, "material": material},
        ],
    }
    sim = build_simulation(parse_scene(data, base_dir=tmp_path))
    np.testing.assert_allclose(sim.bodies[0].mesh.points.max(axis=0), [0.3, 0.3])
    assert sim.bodies[0].pivot_node == 2
    assert sim.bodies[1].mesh.area == pytest.approx(0.08)


@pytest.mark.parametrize(
    ("keys", "integrator", "parameter"),
    [({}, "EnergyMomentumFem", ("damping", 0.1)),
     ({"numerical_damping": 0.3}, "EnergyMomentumFem", ("damping", 0.3)),
     ({"integrator": "newmark", "newmark_gamma": 0.6}, "NewmarkFem", ("gamma", 0.6)),
     ({"integrator": "midpoint"}, "MidpointFem", ("gamma", 0.5))],
)
def test_the_monolithic_scheme_takes_the_scenes_integrator(keys, integrator, parameter) -> None:
    scene = get_scene("bar_in_jet")
    coupling = scene.coupling.model_copy(update=keys)
    sim = build_simulation(scene.model_copy(update={"coupling": coupling}))
    assert type(sim.scheme.fem).__name__ == integrator
    assert getattr(sim.scheme.fem, parameter[0]) == parameter[1]


def test_an_unknown_integrator_is_one_line_naming_the_key() -> None:
    data = get_scene("bar_in_jet").model_dump(mode="json")
    data["coupling"]["integrator"] = "verlet"
    with pytest.raises(SceneError) as info:
        parse_scene(data)
    message = str(info.value)
    assert "coupling.integrator" in message and "verlet" in message and "newmark" in message
    assert "\n" not in message.strip()
