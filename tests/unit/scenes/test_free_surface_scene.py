"""Scenes with a free surface (``[liquid]``): the initial level set, the time step, the
built simulation, its drawing and its checkpoint."""

from __future__ import annotations

import math

import numpy as np
import pytest

from elastoflow.render import render_frame
from elastoflow.render._frame import AIR_COLOR, SURFACE_COLOR
from elastoflow.scenes import SceneError, build_simulation, get_scene, parse_scene
from elastoflow.scenes._build import characteristic_speed, liquid_level_set, time_step


def _scene(**liquid: object) -> dict:
    return {"domain": {"lx": 1.0, "ly": 0.5, "nx": 32}, "fluid": {"gravity": (0.0, -9.81)},
            "liquid": liquid, "time": {"cfl": 0.5, "steps": 3}}


def test_level_set_is_the_union_of_boxes_and_the_layer_below_height() -> None:
    scene = parse_scene(_scene(boxes=[(0.0, 0.0, 0.25, 0.4)],
                               height="0.1 + 0.02 * cos(pi * x)"))
    sim = build_simulation(scene)
    phi = liquid_level_set(scene, sim.grid)
    x, y = sim.grid.cell_centers()
    inside = ((x < 0.25) & (y < 0.4)) | (y < 0.1 + 0.02 * np.cos(np.pi * x))
    far = np.abs(phi) > sim.grid.h  # cells whose side is not decided by sub-cell position
    np.testing.assert_array_equal((phi < 0.0)[far], inside[far])
    np.testing.assert_array_equal(sim.level_set, phi)
    assert sim.state.liquid_area == pytest.approx(0.25 * 0.4 + 0.75 * 0.1, rel=0.05)


def test_time_step_from_the_free_fall_speed() -> None:
    """cfl with a liquid: the speed of water falling from its top to the floor."""
    scene = parse_scene(_scene(boxes=[(0.0, 0.0, 0.25, 0.4)]))
    assert characteristic_speed(scene) == pytest.approx(math.sqrt(2 * 9.81 * 0.4))
    assert time_step(scene) == pytest.approx(0.5 * (1.0 / 32) / math.sqrt(2 * 9.81 * 0.4))


def test_water_that_covers_no_cell_is_refused() -> None:
    scene = parse_scene(_scene(boxes=[(0.0, 0.0, 0.01, 0.4)]))
    with pytest.raises(SceneError, match="liquid: no cell centre lies in the water"):
        build_simulation(scene)


def test_bodies_in_the_water_need_the_monolithic_coupling_and_an_area() -> None:
    """Elastic bodies with [liquid] build `FreeSurfaceMonolithicCoupling`; the explicit
    coupling and rods are refused in one line each."""
    from elastoflow.simulation import FreeSurfaceMonolithicCoupling

    data = _scene(boxes=[(0.0, 0.0, 0.25, 0.4)])
    data["bodies"] = [{"shape": {"type": "rectangle", "box": (0.5, 0.1, 0.6, 0.2),
                                 "divisions": (2, 2)},
                       "material": {"density": 500.0, "young_modulus": 1e5,
                                    "poisson_ratio": 0.3}}]
    sim = build_simulation(parse_scene(data, source="float.toml"))
    assert isinstance(sim.scheme, FreeSurfaceMonolithicCoupling)
    with pytest.raises(SceneError) as error:
        parse_scene({**data, "coupling": {"scheme": "explicit"}}, source="float.toml")
    assert error.value.problems == [
        'coupling.scheme = "explicit": bodies and obstacles in a liquid with a free surface '
        'need the strong coupling; must be "monolithic"']
    rod = {"shape": {"type": "rod", "points": [(0.7, 0.0), (0.7, 0.2)], "segments": 4},
           "material": {"density": 1000.0, "young_modulus": 1e6, "thickness": 0.01},
           "clamped": ["start"]}
    with pytest.raises(SceneError) as error:
        parse_scene({**data, "bodies": data["bodies"] + [rod]}, source="float.toml")
    assert error.value.problems == [
        "bodies.1: a rod in a liquid with a free surface is not supported yet (elastic bodies "
        "with an area only); remove it or the [liquid] table"]


def test_the_frame_draws_liquid_air_and_surface() -> None:
    sim = build_simulation(get_scene("sloshing"))
    sim.run(2)
    image = render_frame(sim.grid, sim.state.fluid, (), (), "speed", None, scale=4,
                         colorbar=False, level_set=sim.level_set)
    height = sim.grid.ny * 4
    column = image[:height, 2 * 4]            # a column of pixels near the left wall
    air = np.all(column == AIR_COLOR, axis=1)
    line = np.all(column == SURFACE_COLOR, axis=1)
    # Top to bottom: air, the surface line near y = 0.055 m (the crest at the left wall),
    # then liquid in the colour map's shades.
    rows = np.nonzero(line)[0]
    assert rows.size >= 1 and air[: rows[0]].all() and not air[rows[-1] + 1:].any()
    surface_y = (height - rows.mean()) / 4 * sim.grid.h
    assert surface_y == pytest.approx(0.055, abs=2 * sim.grid.h)


def test_checkpoint_round_trip_is_bit_exact() -> None:
    sim = build_simulation(get_scene("sloshing"))
    sim.run(3)
    saved = sim.checkpoint()
    assert {"level_set", "liquid_area"} <= set(saved)
    sim.run(3)
    after = sim.checkpoint()
    other = build_simulation(get_scene("sloshing"))
    other.restore(saved)
    other.run(3)
    again = other.checkpoint()
    assert set(again) == set(after)
    for key in after:
        np.testing.assert_array_equal(again[key], after[key], err_msg=key)


def test_kinetic_energy_probe_counts_the_liquid_only() -> None:
    """With a free surface the fluid's kinetic energy probe sums the faces with liquid on a
    side (`mark_liquid_faces`), not the extrapolated air velocities."""
    from elastoflow.fluid._level_set_kernels import mark_liquid_faces
    from elastoflow.io._probes import _kinetic_energy

    sim = build_simulation(get_scene("sloshing"))
    sim.run(3)
    _, sample = _kinetic_energy(None)
    fluid = sim.state.fluid
    valid_u = np.zeros(fluid.velocity_x.shape, dtype=np.int32)
    valid_v = np.zeros(fluid.velocity_y.shape, dtype=np.int32)
    mark_liquid_faces(sim.level_set, valid_u, valid_v)
    expected = 0.5 * 1000.0 * sim.grid.h ** 2 * (
        np.sum(fluid.velocity_x[valid_u == 1] ** 2) + np.sum(fluid.velocity_y[valid_v == 1] ** 2))
    assert sample(sim, None)[0] == pytest.approx(expected, rel=1e-12)
    everywhere = 0.5 * 1000.0 * sim.grid.h ** 2 * (
        np.sum(fluid.velocity_x ** 2) + np.sum(fluid.velocity_y ** 2))
    assert expected < everywhere


def test_flux_form_advection_is_refused_with_a_liquid() -> None:
    """The flux form has no air-side treatment: refused in one line by the scene and by the
    solver."""
    from elastoflow import fluid
    from elastoflow.grid import Grid2D

    data = _scene(boxes=[(0.0, 0.0, 0.25, 0.4)])
    data["fluid"] = {**data["fluid"], "advection": "upwind3"}
    with pytest.raises(SceneError) as error:
        parse_scene(data, source="pool.toml")
    assert error.value.problems == [
        'fluid.advection = "upwind3": not available with [liquid] (the flux form has no '
        'air-side treatment yet); must be "semi_lagrangian" or "maccormack"']
    grid = Grid2D(nx=8, ny=8, h=0.125)
    walls = fluid.DomainBoundaries(fluid.WallNoSlip(), fluid.WallNoSlip(), fluid.WallNoSlip(),
                                   fluid.WallNoSlip())
    solver = fluid.FluidSolver(grid, density=1.0, viscosity=0.0, boundaries=walls,
                               advection="upwind3")
    with pytest.raises(ValueError, match="advection 'upwind3' is not available"):
        fluid.FreeSurfaceSolver(solver)
