"""The library scene `flag_3d`: a light flag set above the flutter threshold, by its numbers."""

from __future__ import annotations

import pytest

from elastoflow.scenes import build_simulation, get_scene
from elastoflow.validation._flag_3d import flag_numbers, scene_data


def test_the_flag_is_light_and_above_the_flutter_threshold() -> None:
    """M* = rho_f L / (rho_s h) = 1 and U* = U L sqrt(rho_s h / B) = 20, twice the threshold
    of ~10 that Eloy et al. (2008) give at M* = 1 for an aspect ratio near 1."""
    numbers = flag_numbers(scene_data())
    assert numbers.mass_ratio == pytest.approx(1.0, rel=1e-6)
    assert numbers.reduced_velocity == pytest.approx(20.0, rel=1e-3)
    # Setting U* through E leaves M* alone and scales E as 1 / U*^2.
    slower = scene_data(10.0)
    assert flag_numbers(slower).reduced_velocity == pytest.approx(10.0, rel=1e-9)
    assert flag_numbers(slower).mass_ratio == pytest.approx(1.0, rel=1e-6)
    own = scene_data()["bodies"][0]["material"]["young_modulus"]
    assert slower["bodies"][0]["material"]["young_modulus"] == pytest.approx(4.0 * own, rel=1e-3)


def test_the_flag_is_monolithic_and_its_mirror_symmetry_is_broken() -> None:
    from elastoflow.simulation import MonolithicCoupling3D

    scene = get_scene("flag_3d")
    flag_box = scene.bodies[0].shape.box  # type: ignore[union-attr]
    flag_middle = 0.5 * (flag_box[2] + flag_box[5])
    assert flag_middle == pytest.approx(0.5 * scene.domain.lz)
    pole = scene.obstacles[0]
    assert pole.center[2] != pytest.approx(flag_middle, abs=1e-3)  # type: ignore[union-attr]
    simulation = build_simulation(scene)
    assert isinstance(simulation.scheme, MonolithicCoupling3D)
    simulation.run(2)
    report = simulation.last_report
    assert report is not None and report.pressure_residual <= 1e-6
