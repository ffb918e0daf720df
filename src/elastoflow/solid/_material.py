from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class MaterialStVK:
    """St. Venant-Kirchhoff solid with Voigt (Kelvin-Voigt) viscous damping, in 2D.

    Second Piola-Kirchhoff stress ``S = lambda tr(E) I + 2 mu E + lambda' tr(Edot) I +
    2 mu' Edot`` with Green strain ``E = (F^T F - I)/2`` (METHOD §4).

    Attributes:
        density: Mass density rho_s [kg/m^3] (per unit depth: mass per area).
        young_modulus: Young's modulus E [Pa].
        poisson_ratio: Poisson's ratio nu, in (-1, 0.5).
        damping_lambda: Viscous counterpart lambda' of lambda [Pa s], >= 0.
        damping_mu: Viscous counterpart mu' of mu [Pa s], >= 0.
        plane: ``"strain"`` (thick body, the default and the Turek-Hron convention) or
            ``"stress"`` (thin plate; lambda becomes 2 lambda mu / (lambda + 2 mu)).
    """

    density: float
    young_modulus: float
    poisson_ratio: float
    damping_lambda: float = 0.0
    damping_mu: float = 0.0
    plane: str = "strain"

    def __post_init__(self) -> None:
        for name in ("density", "young_modulus"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0.0):
                raise ValueError(f"material {name} = {value!r}: must be finite and > 0")
        if not (-1.0 < self.poisson_ratio < 0.5):
            raise ValueError(
                f"material poisson_ratio = {self.poisson_ratio!r}: must lie in (-1, 0.5)"
            )
        for name in ("damping_lambda", "damping_mu"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0.0):
                raise ValueError(f"material {name} = {value!r}: must be finite and >= 0")
        if self.plane not in ("strain", "stress"):
            raise ValueError(f"material plane = {self.plane!r}: must be 'strain' or 'stress'")

    @property
    def lame_mu(self) -> float:
        """Shear modulus mu = E / (2 (1 + nu)) [Pa]."""
        return self.young_modulus / (2.0 * (1.0 + self.poisson_ratio))

    @property
    def lame_lambda(self) -> float:
        """First Lamé parameter of the 2D model [Pa].

        Plane strain: ``E nu / ((1 + nu)(1 - 2 nu))``; plane stress: ``E nu / (1 - nu^2)``.
        """
        e, nu = self.young_modulus, self.poisson_ratio
        if self.plane == "stress":
            return e * nu / (1.0 - nu * nu)
        return e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))

    @property
    def bending_modulus(self) -> float:
        """Modulus of a slender beam in this 2D model [Pa]: E (stress), E / (1 - nu^2) (strain)."""
        if self.plane == "stress":
            return self.young_modulus
        return self.young_modulus / (1.0 - self.poisson_ratio**2)

    @property
    def dilatational_wave_speed(self) -> float:
        """P-wave speed ``sqrt((lambda + 2 mu) / rho)`` [m/s] of the 2D model."""
        return float(np.sqrt((self.lame_lambda + 2.0 * self.lame_mu) / self.density))

    @property
    def damping_time(self) -> float:
        """Voigt relaxation time ``(lambda' + 2 mu') / (lambda + 2 mu)`` [s] of P-waves."""
        return (self.damping_lambda + 2.0 * self.damping_mu) / (
            self.lame_lambda + 2.0 * self.lame_mu
        )
