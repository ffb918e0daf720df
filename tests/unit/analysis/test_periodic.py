"""Periodic statistics as the FSI benchmarks define them (mean, amplitude, frequency)."""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow.analysis import PeriodicStatistics, periodic_statistics


def test_sine_recovers_mean_amplitude_frequency() -> None:
    t = np.arange(0.0, 10.0, 0.002)
    stats = periodic_statistics(t, 0.3 + 2.0 * np.sin(2 * np.pi * 1.7 * t + 0.4))
    assert stats.mean == pytest.approx(0.3, abs=1e-8)
    assert stats.amplitude == pytest.approx(2.0, rel=1e-8)
    assert stats.frequency == pytest.approx(1.7, rel=1e-8)
    assert stats.end - stats.start == pytest.approx(1 / 1.7, rel=1e-6)


def test_coarse_sampling_peaks_refined_by_parabola() -> None:
    # 20 samples a period clip a peak by 1 - cos(pi/20) = 1.2 % unrefined.
    t = np.arange(0.0, 20.0, 0.05)
    stats = periodic_statistics(t, np.sin(2 * np.pi * t + 0.1))
    assert stats.amplitude == pytest.approx(1.0, abs=2e-3)


def test_harmonic_and_growing_transient() -> None:
    # A decaying start-up transient is ignored; a second harmonic keeps the fundamental.
    t = np.arange(0.0, 12.0, 0.001)
    signal = (np.sin(2 * np.pi * 2.0 * t) + 0.4 * np.sin(4 * np.pi * 2.0 * t)
              + 5.0 * np.exp(-3.0 * t))
    stats = periodic_statistics(t, signal)
    assert stats.frequency == pytest.approx(2.0, rel=1e-4)
    exact = signal[(t > 10.0) & (t < 10.5)]
    assert stats.maximum == pytest.approx(exact.max(), abs=1e-5)
    assert stats.minimum == pytest.approx(exact.min(), abs=1e-5)


def test_several_periods_window_and_format() -> None:
    t = np.arange(0.0, 10.0, 0.001)
    stats = periodic_statistics(t, np.cos(2 * np.pi * t), periods=3)
    assert stats.periods == 3
    assert stats.end - stats.start == pytest.approx(3.0, rel=1e-6)
    shown = PeriodicStatistics(mean=-0.0144, amplitude=0.0124, frequency=3.8, periods=1,
                               start=0.0, end=1.0, minimum=-0.0268, maximum=-0.002)
    assert shown.format(scale=1e3) == "-14.4 ± 12.4 [3.8]"


@pytest.mark.parametrize(
    ("time", "signal", "message"),
    [
        (np.arange(10.0), np.ones(10), "up-crossings"),
        (np.arange(10.0), np.ones(9), "one length"),
        (np.array([0.0, 1.0, 1.0, 2.0]), np.array([0.0, 1.0, 0.0, 1.0]), "increasing"),
        (np.arange(4.0), np.array([0.0, np.nan, 0.0, 1.0]), "finite"),
    ],
)
def test_bad_input_is_refused(time: np.ndarray, signal: np.ndarray, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        periodic_statistics(time, signal)


def test_wiggles_near_the_mid_level_are_no_periods() -> None:
    # A drag-like signal: fundamental 11 Hz with a 5th harmonic wiggling across the mid level.
    t = np.arange(0.0, 4.0, 0.0005)
    signal = 585.0 + 20.0 * np.sin(2 * np.pi * 11.0 * t) + 6.0 * np.sin(2 * np.pi * 55.0 * t)
    stats = periodic_statistics(t, signal)
    assert stats.frequency == pytest.approx(11.0, rel=1e-3)


def test_growth_tells_a_settled_oscillation_from_a_growing_one() -> None:
    t = np.arange(0.0, 10.0, 0.001)
    settled = periodic_statistics(t, np.sin(2 * np.pi * 2.0 * t))
    assert abs(settled.growth) < 1e-4
    growing = periodic_statistics(t, np.exp(0.2 * t) * np.sin(2 * np.pi * 2.0 * t))
    assert growing.growth == pytest.approx(np.exp(0.2 * 0.5) - 1.0, rel=0.05)
