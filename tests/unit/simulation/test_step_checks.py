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


@pytest.mark.parametrize("shape", [(7, 5), (40, 33, 29)])
def test_magnitude_and_probe_match_numpy_on_both_paths(shape: tuple[int, ...]) -> None:
    """The serial kernel (small arrays) and the threaded one: the largest magnitude equals
    NumPy's, and one non-finite value anywhere, the last included, makes the probe non-zero."""
    from elastoflow.simulation._kernels import magnitude_and_probe

    values = np.random.default_rng(3).standard_normal(shape)
    top, probe = magnitude_and_probe(values)
    assert top == np.abs(values).max() and probe == 0.0
    size = values.size
    for flat_index in (0, size // 3, size - 1):
        for bad in (np.nan, np.inf, -np.inf):
            spoiled = values.copy()
            spoiled.reshape(-1)[flat_index] = bad
            assert not np.isfinite(magnitude_and_probe(spoiled)[1])
