"""``coupling.scheme`` in scene files: the default, and the keys that belong to the explicit
scheme refused with the monolithic one."""

from __future__ import annotations

import pytest

from elastoflow.scenes import SceneError, get_scene, parse_scene
from elastoflow.simulation import ExplicitCoupling, MonolithicCoupling

_BASE = {
    "domain": {"lx": 1.0, "ly": 1.0, "nx": 16},
    "fluid": {"density": 1000.0, "viscosity": 1e-3},
    "time": {"dt": 0.01, "steps": 2},
}


def test_default_scheme_is_monolithic_and_built_scenes_follow_it() -> None:
    scene = parse_scene(_BASE)
    assert scene.coupling.scheme == "monolithic"
    assert get_scene("bar_in_jet").coupling.scheme == "monolithic"


@pytest.mark.parametrize("coupling", [
    {"force_relaxation": 0.5},
    {"added_mass": 1.0},
    {"force_model": "momentum_exchange"},
    {"scheme": "monolithic", "force_relaxation": 0.1},
])
def test_explicit_keys_are_refused_with_the_monolithic_scheme(coupling: dict) -> None:
    with pytest.raises(SceneError) as error:
        parse_scene({**_BASE, "coupling": coupling})
    message = str(error.value)
    assert "coupling" in message and "explicit" in message
    assert len(message.strip().splitlines()) == 1


def test_explicit_scheme_takes_its_keys() -> None:
    scene = parse_scene({**_BASE, "coupling": {"scheme": "explicit", "force_relaxation": 0.2,
                                               "force_model": "momentum_exchange"}})
    assert scene.coupling.scheme == "explicit"


@pytest.mark.parametrize(("name", "scheme"), [("explicit", ExplicitCoupling),
                                              ("monolithic", MonolithicCoupling)])
def test_simulation_gets_the_scheme(name: str, scheme: type) -> None:
    from elastoflow.scenes import build_simulation

    simulation = build_simulation(parse_scene({**_BASE, "coupling": {"scheme": name}}))
    assert isinstance(simulation.scheme, scheme)
    simulation.step()


def test_unknown_scheme_is_refused() -> None:
    with pytest.raises(SceneError, match="coupling.scheme"):
        parse_scene({**_BASE, "coupling": {"scheme": "implicit"}})


@pytest.mark.parametrize("advection", ["semi_lagrangian", "maccormack"])
def test_fluid_numerics_reach_the_solver(advection: str) -> None:
    from elastoflow.scenes import build_simulation

    scene = parse_scene({**_BASE, "fluid": {"advection": advection,
                                            "incremental_pressure": True}})
    simulation = build_simulation(scene)
    assert simulation.fluid_solver.advection == advection
    assert simulation.fluid_solver.incremental_pressure is True


def test_unknown_advection_is_refused() -> None:
    with pytest.raises(SceneError, match="fluid.advection"):
        parse_scene({**_BASE, "fluid": {"advection": "weno"}})


@pytest.mark.parametrize("scheme", ["monolithic", "explicit"])
def test_incremental_pressure_runs_with_a_coupled_body(scheme: str) -> None:
    from elastoflow.scenes import build_simulation

    body = {"shape": {"type": "rectangle", "box": [0.4, 0.4, 0.6, 0.6], "divisions": [4, 4]},
            "material": {"density": 500.0, "young_modulus": 1e5, "poisson_ratio": 0.3}}
    scene = parse_scene({**_BASE, "fluid": {"density": 1000.0, "viscosity": 1e-3,
                                            "gravity": [0.0, -9.81],
                                            "incremental_pressure": True},
                         "bodies": [body], "coupling": {"scheme": scheme}})
    simulation = build_simulation(scene)
    assert simulation.fluid_solver.incremental_pressure is True
    simulation.run(2)
    # Lighter than the water: it starts to rise.
    assert simulation.state.bodies[0].velocities[:, 1].mean() > 0.0


def test_wall_contact_is_on_by_default_and_takes_its_friction() -> None:
    from elastoflow.scenes import build_simulation
    from elastoflow.solid import WallContact

    simulation = build_simulation(parse_scene(_BASE))
    assert simulation.model.contact == WallContact(friction=0.3)
    simulation = build_simulation(parse_scene({**_BASE, "coupling": {"wall_friction": 0.0}}))
    assert simulation.model.contact == WallContact(friction=0.0)
    simulation = build_simulation(parse_scene({**_BASE, "coupling": {"wall_contact": False}}))
    assert simulation.model.contact is None


@pytest.mark.parametrize(("coupling", "expected"), [
    ({"wall_friction": -0.5}, "coupling.wall_friction"),
    ({"wall_friction": "high"}, "coupling.wall_friction"),
    ({"wall_contact": "yes"}, "coupling.wall_contact"),
    ({"wall_contact": False, "wall_friction": 0.5}, "wall_friction needs wall_contact"),
])
def test_bad_wall_contact_keys_are_refused_in_one_line(coupling: dict, expected: str) -> None:
    with pytest.raises(SceneError) as error:
        parse_scene({**_BASE, "coupling": coupling})
    message = str(error.value)
    assert expected in message
    assert len(message.strip().splitlines()) == 1
