"""A tetrahedral cantilever against Euler-Bernoulli: first frequency and static deflection.

The set-up and the reference are those of `elastoflow.validation._solid3d` (steel-like beam
1 x 0.1 x 0.1 m, clamped at x = 0; docs/validation/three_d_solid.md). Linear tetrahedra lock
in bending, so coarse meshes are too stiff: the frequency comes out high and the deflection
low, and both errors shrink with refinement. Measured: k = 2 cells across: +21.1 % and
-32.5 %; k = 3: +9.8 % and -17.7 % (slopes 1.9 and 1.5).
"""

from __future__ import annotations

import pytest

from elastoflow.validation._solid3d import (
    euler_bernoulli_deflection,
    euler_bernoulli_frequency,
    run_cantilever_3d,
)


def test_euler_bernoulli_references() -> None:
    # f_1 = 0.5596 sqrt(E b^2 / (12 rho L^4)), delta = 3 rho g L^4 / (2 E b^2).
    assert euler_bernoulli_frequency() == pytest.approx(81.538, rel=1e-4)
    assert euler_bernoulli_deflection() == pytest.approx(1.5 * 7850 * 9.81 / (200e9 * 0.01),
                                                         rel=1e-12)


def test_coarse_cantilevers_lock_and_converge() -> None:
    coarse = run_cantilever_3d(2)
    finer = run_cantilever_3d(3)
    # Stated bounds: too stiff, within 25 % / 35 % at 2 cells across, 12 % / 20 % at 3.
    assert 0.0 < coarse.frequency_error < 0.25
    assert -0.35 < coarse.deflection_error < 0.0
    assert 0.0 < finer.frequency_error < 0.12
    assert -0.20 < finer.deflection_error < 0.0
    # Refinement reduces both errors at about second order (locking ~ h^2).
    assert finer.frequency_error < 0.6 * coarse.frequency_error
    assert abs(finer.deflection_error) < 0.7 * abs(coarse.deflection_error)
    # The relaxation reached the static state; the free vibration stayed linear.
    assert coarse.relaxation_change < 1e-6 and finer.relaxation_change < 1e-6
    assert abs(coarse.tip).max() < 1.5e-4
