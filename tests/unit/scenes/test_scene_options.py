"""The scene options of issue 11 item 2, each on its own: the numerical choices (viscosity
solver and tolerance, CFL limit) reach the objects they configure; the domain's origin shifts
everything; an initial velocity (uniform or expressions) is sampled on the face centres;
rectangles mesh in either pattern; bodies are held where they touch an obstacle. Each bad value
is one line naming the key path, the value and what is allowed."""

from __future__ import annotations

import inspect
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from elastoflow.scenes import (
    SceneError,
    build_simulation,
    load_scene,
    memory_estimate,
    parse_scene,
    scene_to_toml,
    time_step,
)
from elastoflow.scenes import _geometry as geometry
from elastoflow.scenes._build import build_grid, initial_velocity

MATERIAL = {"density": 1000.0, "young_modulus": 1e5, "poisson_ratio": 0.3}


def scene_data(**tables: Any) -> dict[str, Any]:
    data: dict[str, Any] = {"domain": {"lx": 1.0, "ly": 1.0, "nx": 16},
                            "time": {"dt": 0.01, "steps": 5}}
    data.update(tables)
    return data


def rectangle(box: list[float], divisions: tuple[int, int] = (4, 4), **extra: Any) -> dict:
    shape = {"type": "rectangle", "box": box, "divisions": list(divisions)}
    shape.update(extra.pop("shape", {}))
    return {"shape": shape, "material": MATERIAL, **extra}


def problems(data: dict[str, Any], *, build: bool = False) -> list[str]:
    with pytest.raises(SceneError) as info:
        scene = parse_scene(data)
        if build:
            build_simulation(scene, warnings=[])
    return info.value.problems


def only(data: dict[str, Any], *, build: bool = False) -> str:
    found = problems(data, build=build)
    assert len(found) == 1, found
    return found[0]


def fluid_state(sim: Any) -> Any:
    """The simulation's fluid state."""
    return sim.state.fluid


# --------------------------------------------------------------------------------------------
# numerical choices


def test_solver_choices_and_tolerances_reach_the_fluid_solver() -> None:
    from elastoflow.linalg import PoissonSolverJacobi, PoissonSolverMGPCG

    sim = build_simulation(parse_scene(scene_data(fluid={
        "pressure_solver": "jacobi", "pressure_rtol": 1e-5,
        "viscosity_solver": "jacobi", "viscosity_rtol": 1e-4,
        "advection": "maccormack", "incremental_pressure": True,
    })), warnings=[])
    solver = sim.fluid_solver
    assert isinstance(solver.pressure_solver, PoissonSolverJacobi)
    assert solver.pressure_solver.rtol == 1e-5
    assert isinstance(solver.viscosity_solver, PoissonSolverJacobi)
    assert solver.viscosity_solver.rtol == 1e-4
    assert solver.advection == "maccormack" and solver.incremental_pressure is True
    default = build_simulation(parse_scene(scene_data()), warnings=[]).fluid_solver
    assert isinstance(default.viscosity_solver, PoissonSolverMGPCG)
    assert default.viscosity_solver.rtol == 1e-6


def test_the_default_advection_is_the_flux_form_and_maccormack_with_a_liquid() -> None:
    """Left out, ``fluid.advection`` is "upwind3" (the scheme that reproduces DFG 2D-2), and
    "maccormack" with [liquid], which the flux form does not serve; a choice written in the
    file is kept; the saved scene names the scheme it ran with."""
    single = parse_scene(scene_data())
    assert single.fluid.advection == "upwind3"
    assert build_simulation(single, warnings=[]).fluid_solver.advection == "upwind3"
    assert 'advection = "upwind3"' in scene_to_toml(single)
    liquid = parse_scene(scene_data(liquid={"boxes": [[0.0, 0.0, 0.5, 0.5]]}))
    assert liquid.fluid.advection == "maccormack"
    for chosen in ("semi_lagrangian", "maccormack", "upwind3"):
        assert parse_scene(scene_data(fluid={"advection": chosen})).fluid.advection == chosen
    explicit = only(scene_data(fluid={"advection": "upwind3"},
                               liquid={"boxes": [[0.0, 0.0, 0.5, 0.5]]}))
    assert 'fluid.advection = "upwind3": not available with [liquid]' in explicit


def test_viscosity_tolerance_changes_the_solve() -> None:
    """A loose viscosity tolerance takes fewer iterations than a tight one on the same flow."""
    from elastoflow.fluid import FluidState

    iterations = []
    for rtol in (1e-10, 0.5):
        scene = parse_scene(scene_data(fluid={
            "viscosity": 0.05, "viscosity_rtol": rtol,
            "initial_velocity": {"x": "sin(pi*x)*sin(2*pi*y)", "y": 0.0}}))
        sim = build_simulation(scene, warnings=[])
        start = fluid_state(sim)
        state = FluidState(start.velocity_x.copy(), start.velocity_y.copy(),
                           start.pressure.copy(), start.dye.copy())
        iterations.append(sim.fluid_solver.step(state, sim.dt).viscosity_iterations)
    assert iterations[0] > iterations[1] >= 0


@pytest.mark.parametrize(("fluid", "line"), [
    ({"viscosity_solver": "cg"}, "fluid.viscosity_solver = 'cg': must be 'mgpcg' or 'jacobi'"),
    ({"viscosity_rtol": 0.0}, "fluid.viscosity_rtol = 0.0: must be greater than 0"),
    ({"viscosity_rtol": 1.0}, "fluid.viscosity_rtol = 1.0: must be less than 1"),
    ({"viscosity_rtol": float("nan")}, "fluid.viscosity_rtol = nan: must be a finite number"),
    ({"viscosity_rtol": "1e-6"}, "fluid.viscosity_rtol = '1e-6': must be a number"),
])
def test_bad_viscosity_solver_choices(fluid: dict, line: str) -> None:
    assert only(scene_data(fluid=fluid)) == line


def test_cfl_limit_reaches_the_simulation_and_stops_the_run() -> None:
    from elastoflow.simulation import Simulation, SimulationBlowUp

    data = scene_data(fluid={"initial_velocity": [1.0, 0.0]},
                      boundaries={"left": "outflow", "right": "outflow"},
                      time={"dt": 0.01, "steps": 5, "cfl_limit": 0.05})
    sim = build_simulation(parse_scene(data), warnings=[])
    # u = 1 m/s, dt = 0.01 s, h = 1/16 m: Courant number 0.16 > 0.05.
    with pytest.raises(SimulationBlowUp, match="exceeds the limit 0.05"):
        sim.step()
    data["time"]["cfl_limit"] = 1.0
    build_simulation(parse_scene(data), warnings=[]).step()
    # Left out, the limit is the simulation's own default.
    default = inspect.signature(Simulation).parameters["cfl_limit"].default
    assert parse_scene(scene_data()).time.cfl_limit == default


@pytest.mark.parametrize(("time", "line"), [
    ({"cfl_limit": 0.0}, "time.cfl_limit = 0.0: must be greater than 0"),
    ({"cfl_limit": float("inf")}, "time.cfl_limit = inf: must be a finite number"),
    ({"cfl_limit": True}, "time.cfl_limit = true: must be a number"),
])
def test_bad_cfl_limit(time: dict, line: str) -> None:
    assert only(scene_data(time={"dt": 0.01, "steps": 5, **time})) == line


def test_cfl_at_or_above_the_limit_is_refused() -> None:
    data = scene_data(boundaries={"left": {"type": "inflow", "speed": 1.0}, "right": "outflow"},
                      time={"cfl": 3.0, "steps": 5, "cfl_limit": 3.0})
    line = only(data)
    assert line.startswith("time.cfl = 3: must be below time.cfl_limit = 3")
    data["time"]["cfl_limit"] = 3.5
    assert time_step(parse_scene(data)) == pytest.approx(3.0 / 16)


# --------------------------------------------------------------------------------------------
# initial velocity


def test_uniform_initial_velocity_fills_every_face() -> None:
    sim = build_simulation(parse_scene(scene_data(
        fluid={"initial_velocity": [0.25, -0.5]})), warnings=[])
    state = fluid_state(sim)
    assert np.all(state.velocity_x == 0.25) and np.all(state.velocity_y == -0.5)
    at_rest = fluid_state(build_simulation(parse_scene(scene_data()), warnings=[]))
    assert not at_rest.velocity_x.any() and not at_rest.velocity_y.any()


def test_initial_velocity_expressions_are_sampled_at_the_face_centres() -> None:
    data = scene_data(domain={"lx": 1.0, "ly": 0.5, "nx": 8, "origin": [2.0, -1.0]},
                      fluid={"initial_velocity": {"x": "x + 10*y", "y": "where(x < 2.5, 1, -1)"}})
    scene = parse_scene(data)
    grid = build_grid(scene)
    u, v = initial_velocity(scene, grid)
    xu, yu = grid.faces_x()
    xv, _ = grid.faces_y()
    assert u.shape == (9, 4) and v.shape == (8, 5)
    np.testing.assert_allclose(u, xu + 10.0 * yu, rtol=0, atol=1e-14)
    assert xu[0, 0] == 2.0 and yu[0, 0] == -1.0 + 0.5 * 0.125
    np.testing.assert_array_equal(v, np.where(xv < 2.5, 1.0, -1.0))
    state = fluid_state(build_simulation(scene, warnings=[]))
    np.testing.assert_array_equal(state.velocity_x, u)
    np.testing.assert_array_equal(state.velocity_y, v)


def test_expression_grammar() -> None:
    from elastoflow.scenes._expression import Expression

    x = np.array([0.0, 0.5, 1.0])
    y = np.array([1.0, 2.0, 3.0])
    cases = {
        "2**3 - 8 % 3": np.full(3, 6.0),
        "-x + +y": y - x,
        "1 if x > 0.2 else 0": np.array([0.0, 1.0, 1.0]),
        "(x > 0.2) and not (y > 2.5)": np.array([0.0, 1.0, 0.0]),
        "0.1 < x <= 1": np.array([0.0, 1.0, 1.0]),
        "hypot(3, 4) + min(x, 0.5) + atan2(0, 1)": 5.0 + np.minimum(x, 0.5),
        "e**0 * pi / pi": np.ones(3),
    }
    for text, expected in cases.items():
        np.testing.assert_allclose(Expression(text).evaluate({"x": x, "y": y}), expected,
                                   err_msg=text)
    # Float arithmetic throughout: a huge power overflows instead of computing a big integer.
    assert np.isinf(Expression("9**9**9").evaluate({"x": x, "y": y})).all()


@pytest.mark.parametrize(("value", "line"), [
    ([1.0], "fluid.initial_velocity = [1.0]: must be [ux, uy] (two numbers) or a table "
            "{ x = ..., y = ... }"),
    ("fast", "fluid.initial_velocity = 'fast': must be a table"),
    ({"x": True}, "fluid.initial_velocity.x = true: must be a number or a string"),
    ({"x": float("inf")}, "fluid.initial_velocity.x = inf: must be a finite number"),
    ({"z": 1.0}, "fluid.initial_velocity.z: unknown key (allowed keys: x, y)"),
    ({"x": "sin(pi*x"}, "fluid.initial_velocity.x = 'sin(pi*x': does not parse at column 4"),
    ({"y": "u0 * y"}, "fluid.initial_velocity.y = 'u0 * y': unknown name 'u0' (variables: x, "
                      "y; constants: pi, e)"),
    ({"x": "cbrt(x)"}, "fluid.initial_velocity.x = 'cbrt(x)': unknown function in 'cbrt(x)'"),
    ({"x": "sin(x, y)"}, "fluid.initial_velocity.x = 'sin(x, y)': 'sin(x, y)': sin takes 1 "
                         "argument, got 2"),
    ({"x": "__import__('os').system('ls')"}, "fluid.initial_velocity.x = "),
    ({"x": "x.real"}, "fluid.initial_velocity.x = 'x.real': 'x.real' is not allowed"),
    ({"x": "[x][0]"}, "fluid.initial_velocity.x = '[x][0]': '[x][0]' is not allowed"),
    ({"x": "'a'"}, "fluid.initial_velocity.x = \"'a'\": \"'a'\" is not a number"),
    ({"x": "sin"}, "fluid.initial_velocity.x = 'sin': 'sin' is a function"),
    ({"x": "x" + " + x" * 300}, "fluid.initial_velocity.x = 'x + x + x"),
])
def test_bad_initial_velocity(value: Any, line: str) -> None:
    found = only(scene_data(fluid={"initial_velocity": value}))
    assert found.startswith(line), found


def test_expression_that_is_not_finite_is_refused_when_built(tmp_path: Path) -> None:
    path = tmp_path / "scene.toml"
    path.write_text('[domain]\nlx = 1.0\nly = 1.0\nnx = 8\n\n[fluid]\n'
                    'initial_velocity = { x = "1 / (x - 0.5)", y = "sqrt(y - 2)" }\n\n'
                    '[time]\ndt = 0.01\nsteps = 1\n')
    scene = load_scene(path)
    with pytest.raises(SceneError) as info:
        build_simulation(scene, warnings=[])
    (line,) = str(info.value).splitlines()
    assert line.startswith(f"{path}: fluid.initial_velocity.x = '1 / (x - 0.5)': is inf at "
                           "(x, y) = (0.5, 0.0625)")
    assert "must be finite on every x-face" in line


def test_initial_speed_is_a_characteristic_speed() -> None:
    uniform = parse_scene(scene_data(fluid={"initial_velocity": [0.0, 2.0]},
                                     time={"cfl": 0.5, "steps": 5}))
    assert time_step(uniform) == pytest.approx(0.5 / 16 / 2.0)
    vortex = parse_scene(scene_data(
        fluid={"initial_velocity": {"x": "sin(pi*x)*cos(pi*y)", "y": "-cos(pi*x)*sin(pi*y)"}},
        time={"cfl": 0.5, "steps": 5}))
    u, v = initial_velocity(vortex, build_grid(vortex))
    speed = max(np.abs(u).max(), np.abs(v).max())
    assert 0.99 < speed <= 1.0
    assert time_step(vortex) == pytest.approx(0.5 / 16 / speed)


def test_new_keys_round_trip_through_toml() -> None:
    import tomllib

    data = scene_data(
        domain={"lx": 1.0, "ly": 1.0, "nx": 16, "origin": [-0.5, 0.25]},
        fluid={"initial_velocity": {"x": "sin(pi*x)", "y": 0.5}, "viscosity_rtol": 1e-7,
               "viscosity_solver": "jacobi"},
        obstacles=[{"shape": "circle", "name": "post", "center": [0.0, 0.75], "radius": 0.1}],
        bodies=[rectangle([0.1, 0.7, 0.4, 0.8], (6, 2), shape={"pattern": "crossed"},
                          fixed={"obstacle": "post", "tolerance": 0.01})],
        time={"dt": 0.01, "steps": 5, "cfl_limit": 5.0},
    )
    scene = parse_scene(data)
    again = parse_scene(tomllib.loads(scene_to_toml(scene)))
    assert again == scene
    assert again.fluid.initial_velocity is not None
    assert again.fluid.initial_velocity.x == "sin(pi*x)"


# --------------------------------------------------------------------------------------------
# the domain's origin


def test_origin_moves_the_grid_and_the_domain_checks() -> None:
    shifted = scene_data(domain={"lx": 1.0, "ly": 1.0, "nx": 16, "origin": [10.0, -2.0]},
                         bodies=[rectangle([10.4, -1.6, 10.6, -1.4])])
    sim = build_simulation(parse_scene(shifted), warnings=[])
    assert sim.grid.origin == (10.0, -2.0)
    # The same body in the unshifted domain's coordinates is now outside.
    outside = scene_data(domain={"lx": 1.0, "ly": 1.0, "nx": 16, "origin": [10.0, -2.0]},
                         bodies=[rectangle([0.4, 0.4, 0.6, 0.6])])
    assert only(outside) == ("bodies.0.shape = rectangle with bounds [0.4, 0.4, 0.6, 0.6]: must "
                             "lie inside the domain [10, 11] x [-2, -1]")


@pytest.mark.parametrize(("tables", "key"), [
    ({"jets": [{"region": [0.1, 0.1, 0.2, 0.2], "velocity": [0.0, 1.0]}]}, "jets.0.region"),
    ({"obstacles": [{"shape": "circle", "center": [0.5, 0.5], "radius": 0.1}]}, "obstacles.0"),
    ({"outputs": {"probes": [{"kind": "pressure", "point": [0.5, 0.5]}]}},
     "outputs.probes.0.point"),
])
def test_positions_outside_a_shifted_domain_are_refused(tables: dict, key: str) -> None:
    line = only(scene_data(domain={"lx": 1.0, "ly": 1.0, "nx": 16, "origin": [3.0, 3.0]},
                           **tables))
    assert line.startswith(key) and line.endswith("must lie inside the domain [3, 4] x [3, 4]")


@pytest.mark.parametrize(("origin", "line"), [
    ([1.0], "domain.origin = [1.0]: too few items (needs 2)"),
    ([0.0, float("nan")], "domain.origin.1 = nan: must be a finite number"),
    ([0.0, "0"], "domain.origin.1 = '0': must be a number"),
    ([1e300, 0.0], "domain.origin = [1e+300, 0.0]: puts the domain 1e+300 m from 0"),
])
def test_bad_origin(origin: list, line: str) -> None:
    found = only(scene_data(domain={"lx": 1.0, "ly": 1.0, "nx": 16, "origin": origin}))
    assert found.startswith(line), found


def test_geometry_checks_follow_the_origin() -> None:
    origin = [-3.0, 5.0]
    domain = {"lx": 1.0, "ly": 1.0, "nx": 16, "origin": origin}
    covering = scene_data(domain=domain, obstacles=[{"shape": "rectangle",
                                                     "box": [-3.0, 5.0, -2.0, 6.0]}])
    assert only(covering, build=True).startswith("obstacles: the obstacles and bodies cover")
    jet_in_body = scene_data(domain=domain, bodies=[rectangle([-2.7, 5.3, -2.3, 5.7])],
                             jets=[{"region": [-2.6, 5.4, -2.5, 5.5], "velocity": [0.0, 1.0]}])
    assert only(jet_in_body, build=True).startswith(
        "jets.0.region = [-2.6, 5.4, -2.5, 5.5]: reaches inside a body or obstacle (at "
        "[-2.594, 5.406])")
    jet_beside = scene_data(domain=domain, bodies=[rectangle([-2.7, 5.3, -2.3, 5.7])],
                            jets=[{"region": [-2.95, 5.05, -2.85, 5.15],
                                   "velocity": [0.0, 1.0]}])
    build_simulation(parse_scene(jet_beside), warnings=[])


def test_cell_centres_inside_with_origin() -> None:
    square = np.array([[10.25, 20.25], [10.75, 20.25], [10.75, 20.75], [10.25, 20.75]])
    mask = geometry.cell_centres_inside(*geometry.polygon_edges(square), 4, 4, 0.25,
                                        origin=(10.0, 20.0))
    expected = np.zeros((4, 4), dtype=bool)
    expected[1:3, 1:3] = True
    np.testing.assert_array_equal(mask, expected)


def _translated(shift: tuple[float, float]) -> dict[str, Any]:
    """A small coupled scene (inflow, obstacle, jet, clamped body, probes), every position
    moved by ``shift``."""
    sx, sy = shift

    def at(x: float, y: float) -> list[float]:
        return [x + sx, y + sy]

    return scene_data(
        domain={"lx": 1.0, "ly": 0.5, "nx": 32, "origin": at(0.0, 0.0)},
        fluid={"density": 1.0, "viscosity": 1e-3,
               "initial_velocity": {"x": f"0.2 + 0.1*sin(2*pi*(y - {sy}))", "y": 0.0}},
        boundaries={"left": {"type": "inflow", "speed": 0.3}, "right": "outflow"},
        obstacles=[{"shape": "circle", "name": "post", "center": at(0.3, 0.25),
                    "radius": 0.06}],
        jets=[{"region": at(0.05, 0.05) + at(0.1, 0.1), "velocity": [0.0, 0.5]}],
        bodies=[rectangle(at(0.36, 0.23) + at(0.6, 0.27), (12, 2),
                          fixed={"obstacle": "post", "tolerance": 0.001})],
        time={"dt": 0.01, "steps": 3},
        outputs={"probes": [{"kind": "pressure", "point": at(0.8, 0.2)},
                            {"kind": "velocity", "point": at(0.8, 0.3)}]},
    )


def test_a_translated_scene_gives_the_same_run() -> None:
    """Moving the whole scene with the domain's origin changes no field, force or frame."""
    import elastoflow

    runs = []
    for shift in ((0.0, 0.0), (3.0, -1.5)):
        sim = build_simulation(parse_scene(_translated(shift)), warnings=[])
        for _ in range(3):
            sim.step()
        runs.append(sim)
    a, b = (fluid_state(sim) for sim in runs)
    for name in ("velocity_x", "velocity_y", "pressure", "dye"):
        np.testing.assert_allclose(getattr(b, name), getattr(a, name), rtol=1e-9, atol=1e-9,
                                   err_msg=name)
    assert runs[0].bodies[0].fixed_nodes.tolist() == runs[1].bodies[0].fixed_nodes.tolist()
    np.testing.assert_allclose(runs[1].body_forces[0], runs[0].body_forces[0], rtol=1e-7,
                               atol=1e-9)
    frames = [elastoflow.frame(sim, view="speed") for sim in runs]
    assert np.mean(frames[0] != frames[1]) < 1e-3


def test_probes_and_field_files_use_the_origin(tmp_path: Path) -> None:
    from elastoflow.io import _fields

    scene = parse_scene(_translated((3.0, -1.5)))
    sim = build_simulation(scene, warnings=[])
    arrays = _fields.snapshot_arrays(sim.grid, fluid_state(sim))
    np.testing.assert_array_equal(arrays["origin"], [3.0, -1.5])
    points, _ = _fields._cell_mesh(sim.grid.nx, sim.grid.ny, sim.grid.h, sim.grid.origin)
    np.testing.assert_allclose(points.min(axis=0)[:2], [3.0, -1.5])
    np.testing.assert_allclose(points.max(axis=0)[:2], [4.0, -1.0])


# --------------------------------------------------------------------------------------------
# rectangle meshing patterns


def test_rectangle_patterns() -> None:
    from elastoflow.solid import mesh_rectangle

    bodies = [rectangle([0.2, 0.2, 0.5, 0.3], (6, 2)),
              rectangle([0.2, 0.6, 0.5, 0.7], (6, 2), shape={"pattern": "crossed"})]
    scene = parse_scene(scene_data(bodies=bodies))
    sim = build_simulation(scene, warnings=[])
    default, crossed = (body.mesh for body in sim.bodies)
    assert default.triangle_count == 24 and default.point_count == 21
    assert crossed.triangle_count == 48 and crossed.point_count == 21 + 12
    assert crossed.area == pytest.approx(0.03) and default.area == pytest.approx(0.03)
    # The default is today's mesh, node for node.
    today = mesh_rectangle(0.5 - 0.2, 0.3 - 0.2, counts=(6, 2), origin=(0.2, 0.2))
    np.testing.assert_array_equal(default.points, today.points)
    np.testing.assert_array_equal(default.triangles, today.triangles)
    # The memory estimate counts the crossed pattern's elements.
    _, parts = memory_estimate(scene)
    assert "~24 elements" in parts[1][0] and "~48 elements" in parts[2][0]


def test_unknown_pattern() -> None:
    line = only(scene_data(bodies=[rectangle([0.2, 0.2, 0.5, 0.3],
                                             shape={"pattern": "union_jack"})]))
    assert line == ("bodies.0.shape.pattern = 'union_jack': must be 'alternating' or "
                    "'crossed'")


# --------------------------------------------------------------------------------------------
# bodies clamped to an obstacle


def _flag(fixed: dict[str, Any], *, name: str | None = "cylinder",
          motion: dict | None = None) -> dict[str, Any]:
    """A flag [x_arc, 0.6] x [0.19, 0.21] whose left end meets a circle of radius 0.05 about
    (0.2, 0.2), as in Turek and Hron's set-up."""
    left = 0.2 + (0.05**2 - 0.01**2) ** 0.5
    circle: dict[str, Any] = {"shape": "circle", "center": [0.2, 0.2], "radius": 0.05}
    if name is not None:
        circle["name"] = name
    if motion is not None:
        circle["motion"] = motion
    return scene_data(
        domain={"lx": 105 * 0.41 / 42, "ly": 0.41, "h": 0.41 / 42},
        obstacles=[{"shape": "rectangle", "box": [0.8, 0.05, 0.85, 0.1]}, circle],
        bodies=[rectangle([left, 0.19, 0.6, 0.21], (35, 4), fixed=fixed)],
    )


def test_body_clamped_along_the_obstacle_outline() -> None:
    sim = build_simulation(parse_scene(_flag({"obstacle": "cylinder", "tolerance": 0.0011})),
                           warnings=[])
    body = sim.bodies[0]
    points = body.mesh.points
    # The left column of nodes (within 1 mm of the circle: the middle one lies 1 mm inside).
    left = np.flatnonzero(points[:, 0] < points[:, 0].min() + 1e-12)
    assert body.fixed_nodes.tolist() == left.tolist() and len(left) == 5
    by_index = build_simulation(parse_scene(_flag({"obstacle": 1, "tolerance": 0.0011})),
                                warnings=[])
    assert by_index.bodies[0].fixed_nodes.tolist() == left.tolist()
    # Tighter than the middle nodes' depth: only the corners on the circle are held.
    corners = build_simulation(parse_scene(_flag({"obstacle": 1, "tolerance": 1e-6})),
                               warnings=[])
    assert len(corners.bodies[0].fixed_nodes) == 2
    # The default tolerance, a quarter cell (2.4 mm), holds the left column too.
    default = build_simulation(parse_scene(_flag({"obstacle": "cylinder"})), warnings=[])
    assert default.bodies[0].fixed_nodes.tolist() == left.tolist()


def test_obstacle_selection_adds_to_box_and_nodes() -> None:
    fixed = {"obstacle": "cylinder", "tolerance": 0.0011, "nodes": [40],
             "box": [0.59, 0.18, 0.61, 0.22]}
    body = build_simulation(parse_scene(_flag(fixed)), warnings=[]).bodies[0]
    points = body.mesh.points
    expected = set(np.flatnonzero(points[:, 0] < points[:, 0].min() + 1e-12).tolist())
    expected |= set(np.flatnonzero(points[:, 0] > 0.59).tolist()) | {40}
    assert set(body.fixed_nodes.tolist()) == expected


def test_polygon_obstacle_outline_selection() -> None:
    data = scene_data(obstacles=[{"shape": "polygon", "name": "wall",
                                  "points": [[0.1, 0.1], [0.3, 0.1], [0.3, 0.9], [0.1, 0.9]]}],
                      bodies=[rectangle([0.3, 0.4, 0.7, 0.6], (8, 4),
                                        fixed={"obstacle": "wall", "tolerance": 1e-9})])
    body = build_simulation(parse_scene(data), warnings=[]).bodies[0]
    np.testing.assert_allclose(body.mesh.points[body.fixed_nodes, 0], 0.3)
    assert len(body.fixed_nodes) == 5


@pytest.mark.parametrize(("fixed", "kwargs", "line"), [
    ({"obstacle": "cylindre"}, {},
     "bodies.0.fixed.obstacle = 'cylindre': must name an obstacle (names: 'cylinder')"),
    ({"obstacle": "cylinder"}, {"name": None},
     "bodies.0.fixed.obstacle = 'cylinder': no obstacle has a name; give one "
     "(obstacles.N.name) or use its index"),
    ({"obstacle": 2}, {}, "bodies.0.fixed.obstacle = 2: must be an obstacle index in 0..1"),
    ({"obstacle": -1}, {}, "bodies.0.fixed.obstacle = -1: must be"),
    ({"obstacle": 1.0}, {}, "bodies.0.fixed.obstacle = 1.0: must be"),
    ({"obstacle": "cylinder"}, {"motion": {"angular_velocity": 1.0}},
     "bodies.0.fixed.obstacle = 'cylinder': obstacles.1 moves (it has a motion); nodes can be "
     "held only on an obstacle that stays still"),
    ({"box": [0.2, 0.18, 0.3, 0.22], "tolerance": 0.01}, {},
     "bodies.0.fixed.tolerance = 0.01: applies to the nodes on an obstacle; give obstacle"),
    ({"obstacle": "cylinder", "tolerance": 0.0}, {},
     "bodies.0.fixed.tolerance = 0.0: must be greater than 0"),
    ({"obstacle": "cylinder", "tolerance": "1mm"}, {},
     "bodies.0.fixed.tolerance = '1mm': must be a number"),
])
def test_bad_obstacle_clamp(fixed: dict, kwargs: dict, line: str) -> None:
    found = only(_flag(fixed, **kwargs))
    assert found.startswith(line), found


def test_clamp_that_holds_no_node_is_refused_when_built() -> None:
    data = _flag({"obstacle": 0, "tolerance": 0.001})
    assert only(data, build=True) == (
        "bodies.0.fixed.obstacle = 0: no node of the body's mesh lies within 0.001 m of "
        "obstacles.0's outline (the nearest is 0.2193 m away); the body must touch the "
        "obstacle where it is clamped")


def test_obstacle_names_must_be_unique_and_refer_nowhere_without_obstacles() -> None:
    twice = scene_data(obstacles=[
        {"shape": "circle", "name": "post", "center": [0.3, 0.5], "radius": 0.05},
        {"shape": "circle", "name": "post", "center": [0.7, 0.5], "radius": 0.05}])
    assert only(twice) == ("obstacles.1.name = 'post': already the name of obstacles.0; names "
                           "must be unique")
    none = scene_data(bodies=[rectangle([0.4, 0.4, 0.6, 0.6], fixed={"obstacle": 0})])
    assert only(none) == "bodies.0.fixed.obstacle = 0: the scene has no obstacles"


def test_clamped_flag_example_builds_with_every_option() -> None:
    path = Path(__file__).resolve().parents[3] / "examples" / "clamped_flag.toml"
    scene = load_scene(path)
    sim = build_simulation(scene, warnings=[])
    assert sim.grid.origin == (-0.2, -0.2) and (sim.grid.nx, sim.grid.ny) == (257, 42)
    body = sim.bodies[0]
    assert body.mesh.triangle_count == 4 * 35 * 4
    points = body.mesh.points
    assert body.fixed_nodes.tolist() == np.flatnonzero(points[:, 0] < 0.0490).tolist()
    assert len(body.fixed_nodes) == 5
    u = fluid_state(sim).velocity_x
    assert u.max() == pytest.approx(0.3, rel=1e-3) and u.min() >= 0.0


@pytest.mark.parametrize(("tables", "key"), [
    ({"fluid": {"initial_velocity": {"x": "u0 * y"}}}, "fluid.initial_velocity.x"),
    ({"fluid": {"initial_velocity": {"x": "log(x - 0.5)"}}}, "fluid.initial_velocity.x"),
    ({"fluid": {"viscosity_rtol": 2.0}}, "fluid.viscosity_rtol"),
    ({"time": {"dt": 0.01, "steps": 5, "cfl_limit": -1.0}}, "time.cfl_limit"),
    ({"domain": {"lx": 1.0, "ly": 1.0, "nx": 16, "origin": [0.0]}}, "domain.origin"),
    ({"bodies": [rectangle([0.4, 0.4, 0.6, 0.6], shape={"pattern": "diagonal"})]},
     "bodies.0.shape.pattern"),
    ({"obstacles": [{"shape": "circle", "name": "post", "center": [0.2, 0.2],
                     "radius": 0.05}],
      "bodies": [rectangle([0.4, 0.4, 0.6, 0.6], fixed={"obstacle": "post"})]},
     "bodies.0.fixed.obstacle"),
])
def test_command_line_names_the_file_and_key_in_one_line(tables: dict, key: str,
                                                         tmp_path: Path) -> None:
    """`elastoflow validate` refuses each new kind of bad value, at parse or build time, with
    exit 2 and one ``error:`` line naming the file and the key, no traceback."""
    from typer.testing import CliRunner

    from elastoflow.cli import app

    lines = []
    for name, value in scene_data(**tables).items():
        lines.append(f"[{name}]")
        lines += [f"{k} = {_toml(v)}" for k, v in value.items()] if isinstance(value, dict) \
            else []
        if isinstance(value, list):
            lines.pop()
            for item in value:
                lines.append(f"[[{name}]]")
                lines += [f"{k} = {_toml(v)}" for k, v in item.items()]
    path = tmp_path / "scene.toml"
    path.write_text("\n".join(lines) + "\n")
    result = CliRunner().invoke(app, ["validate", str(path)])
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    errors = [line for line in result.output.splitlines() if line.startswith("error:")]
    assert len(errors) == 1, result.output
    assert f"{path}: {key}" in errors[0], errors[0]


def _toml(value: Any) -> str:
    if isinstance(value, str):
        return '"' + value + '"'
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {_toml(v)}" for k, v in value.items()) + " }"
    return repr(value)


def test_the_default_advection_does_not_change_a_shared_fluid_table() -> None:
    """Through the Python API one FluidSpec may serve two scenes: each gets its own default
    and the table given stays as it was."""
    from elastoflow.scenes import Scene
    from elastoflow.scenes._schema import FluidSpec

    shared = FluidSpec()
    base = scene_data()
    with_liquid = Scene.model_validate({**base, "fluid": shared,
                                        "liquid": {"boxes": [[0.0, 0.0, 0.5, 0.5]]}})
    single = Scene.model_validate({**base, "fluid": shared})
    assert with_liquid.fluid.advection == "maccormack"
    assert single.fluid.advection == "upwind3"
    assert shared.advection is None
