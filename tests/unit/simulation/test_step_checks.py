"""The step checks' array survey against NumPy."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow.fluid import FluidState3D
from elastoflow.grid import Grid3D
from elastoflow.simulation._checks import check_fluid_finite, max_speed
from elastoflow.simulation._kernels import survey
from elastoflow.simulation._report import SimulationBlowUp


@pytest.mark.parametrize("size", [0, 1, 1000, 5 * 65536 + 7])
def test_survey_finds_numpy_s_largest_magnitude(size: int) -> None:
    values = np.random.default_rng(size).standard_normal(size)
    largest, nans = survey(values)
    assert nans == 0
    assert largest == (np.abs(values).max() if size else 0.0)


def test_survey_counts_nans_and_keeps_infinities() -> None:
    values = np.zeros(300_000)
    values[7] = -np.inf
    values[123_456] = np.nan
    values[299_999] = np.nan
    assert survey(values) == (np.inf, 2)


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
