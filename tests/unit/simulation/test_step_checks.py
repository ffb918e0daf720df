"""The step checks' reductions: the largest speed and the first non-finite value."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow.fluid import FluidState3D
from elastoflow.grid import Grid3D
from elastoflow.simulation._checks import check_fluid_finite, max_speed
from elastoflow.simulation._report import SimulationBlowUp


def test_max_speed_and_finiteness_check_name_the_bad_value() -> None:
    state = FluidState3D.zeros(Grid3D(nx=4, ny=3, nz=5, h=0.1))
    state.velocity_y[1, 2, 3] = -2.5
    assert max_speed(state) == 2.5
    check_fluid_finite(state, 1, 0.1)
    state.velocity_z[0, 1, 2] = np.inf
    assert max_speed(state) == np.inf
    with pytest.raises(SimulationBlowUp, match=r"velocity_z is not finite at index \(0, 1, 2\)"):
        check_fluid_finite(state, 1, 0.1)
    state.velocity_x[2, 0, 0] = np.nan
    assert np.isnan(max_speed(state))
