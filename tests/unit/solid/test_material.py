"""Lamé parameters, wave speed and validation of MaterialStVK."""

from __future__ import annotations

import pytest

from elastoflow.solid import MaterialStVK


def test_plane_strain_lame_matches_turek_hron_csm1() -> None:
    material = MaterialStVK(1000.0, 1.4e6, 0.4)
    assert material.lame_mu == pytest.approx(5.0e5)
    assert material.lame_lambda == pytest.approx(2.0e6)
    assert material.dilatational_wave_speed == pytest.approx((3.0e6 / 1000.0) ** 0.5)
    assert material.bending_modulus == pytest.approx(1.4e6 / (1 - 0.16))


def test_plane_stress_uses_reduced_lambda() -> None:
    material = MaterialStVK(1000.0, 1.4e6, 0.4, plane="stress")
    lam, mu = 2.0e6, 5.0e5
    assert material.lame_lambda == pytest.approx(2 * lam * mu / (lam + 2 * mu))
    # In plane stress the 1D (uniaxial) modulus of the 2D model is E itself.
    lam2 = material.lame_lambda
    assert 4 * mu * (lam2 + mu) / (lam2 + 2 * mu) == pytest.approx(1.4e6)


def test_damping_time() -> None:
    material = MaterialStVK(1000.0, 1.4e6, 0.4, damping_lambda=2.0, damping_mu=0.5)
    assert material.damping_time == pytest.approx(3.0 / 3.0e6)


@pytest.mark.parametrize(
    "kwargs,field",
    [
        ({"density": 0.0}, "density"),
        ({"young_modulus": -1.0}, "young_modulus"),
        ({"poisson_ratio": 0.5}, "poisson_ratio"),
        ({"poisson_ratio": -1.0}, "poisson_ratio"),
        ({"damping_mu": -1.0}, "damping_mu"),
        ({"damping_lambda": float("nan")}, "damping_lambda"),
        ({"plane": "axisymmetric"}, "plane"),
    ],
)
def test_validation(kwargs: dict, field: str) -> None:
    arguments = {"density": 1000.0, "young_modulus": 1e6, "poisson_ratio": 0.3} | kwargs
    with pytest.raises(ValueError, match=f"material {field} = "):
        MaterialStVK(**arguments)
