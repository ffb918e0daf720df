from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np


@dataclass(frozen=True)
class PeriodicStatistics:
    """Mean, amplitude and frequency of a periodic signal over its last full periods.

    Turek & Hron (2006) define, over the last period, ``mean = (max + min) / 2``,
    ``amplitude = (max - min) / 2`` and ``frequency = 1 / period``.

    Attributes:
        mean: (max + min) / 2 over the last ``periods`` full periods.
        amplitude: (max - min) / 2 over the same window.
        frequency: Periods per second [Hz], from the up-crossings of the window.
        periods: Number of full periods the window holds.
        start: Start time of the window [s].
        end: End time of the window [s].
        minimum: Smallest value in the window.
        maximum: Largest value in the window.
        growth: Relative change of the amplitude from the ``periods`` periods before the
            window to the window (NaN when the record holds too few); a settled oscillation
            has ``|growth|`` near 0, a growing or decaying one does not.
    """

    mean: float
    amplitude: float
    frequency: float
    periods: int
    start: float
    end: float
    minimum: float
    maximum: float
    growth: float = float("nan")

    def as_dict(self) -> dict[str, float | int]:
        return asdict(self)

    def format(self, scale: float = 1.0, digits: int = 4) -> str:
        """``mean ± amplitude [frequency]``, the benchmark's notation (values times ``scale``)."""
        return (f"{self.mean * scale:.{digits}g} ± {self.amplitude * scale:.{digits}g} "
                f"[{self.frequency:.{digits}g}]")


def _up_crossings(time: np.ndarray, signal: np.ndarray, level: float,
                  hysteresis: float) -> np.ndarray:
    """Times where the signal crosses ``level`` upwards, linearly interpolated, counting a
    crossing only after the signal has been below ``level - hysteresis`` (a Schmitt trigger:
    small wiggles about the mid level, e.g. the drag's higher harmonics, are no periods)."""
    crossings = []
    armed = False
    low = level - hysteresis
    for k in range(len(signal) - 1):
        if signal[k] < low:
            armed = True
        if armed and signal[k] < level <= signal[k + 1]:
            fraction = (level - signal[k]) / (signal[k + 1] - signal[k])
            crossings.append(time[k] + fraction * (time[k + 1] - time[k]))
            armed = False
    return np.array(crossings)


def _extreme(time: np.ndarray, signal: np.ndarray, largest: bool) -> float:
    """Largest (or smallest) value, refined by a parabola through the extreme sample and its
    neighbours (sampling once per step otherwise clips peaks by O(dt^2))."""
    values = signal if largest else -signal
    k = int(np.argmax(values))
    best = float(values[k])
    if 0 < k < len(values) - 1:
        y0, y1, y2 = values[k - 1], values[k], values[k + 1]
        t0, t1, t2 = time[k - 1], time[k], time[k + 1]
        if np.isclose(t1 - t0, t2 - t1):
            curvature = y0 - 2.0 * y1 + y2
            if curvature < 0.0:
                best = float(y1 - 0.125 * (y2 - y0) ** 2 / curvature)
    return best if largest else -best


def periodic_statistics(time: np.ndarray, signal: np.ndarray, periods: int = 1,
                        window: float = 0.5) -> PeriodicStatistics:
    """Statistics of the last ``periods`` full periods of a sampled periodic signal.

    Periods are delimited by up-crossings of the mid level ``(max + min) / 2`` of the last
    ``window`` fraction of the record (each after the signal has been a quarter of the range
    below it, so that wiggles near the mid level do not count); the frequency is the number of periods between the first
    and last up-crossing of that part, over the time between them (several periods averaged,
    less sensitive to the sampling than one). Max and min are taken over the last ``periods``
    full periods.

    Args:
        time: Sample times [s], increasing, shape (n,).
        signal: Samples, shape (n,).
        periods: Full periods to take max and min over (the benchmark: 1).
        window: Fraction of the record, from its end, searched for periods.

    Raises:
        ValueError: Mismatched or non-finite input, or fewer than ``periods + 1`` up-crossings
            in the window (not periodic, or too short a record).
    """
    time = np.asarray(time, dtype=np.float64)
    signal = np.asarray(signal, dtype=np.float64)
    if time.ndim != 1 or time.shape != signal.shape:
        raise ValueError(f"time {time.shape} and signal {signal.shape}: must be 1D of one length")
    if not (np.isfinite(time).all() and np.isfinite(signal).all()):
        raise ValueError("time and signal: must be finite")
    if periods < 1:
        raise ValueError(f"periods = {periods!r}: must be >= 1")
    if not 0.0 < window <= 1.0:
        raise ValueError(f"window = {window!r}: must lie in (0, 1]")
    if len(time) < 3 or np.any(np.diff(time) <= 0.0):
        raise ValueError("time: must hold at least 3 strictly increasing samples")
    first = time[-1] - window * (time[-1] - time[0])
    part = time >= first
    t, s = time[part], signal[part]
    level = 0.5 * (s.max() + s.min())
    crossings = _up_crossings(t, s, level, 0.25 * (s.max() - s.min()))
    if len(crossings) < periods + 1:
        raise ValueError(
            f"{len(crossings)} up-crossings of the mid level in the last {window:.0%} of the "
            f"record ({t[0]:.4g}-{t[-1]:.4g} s): need {periods + 1} (not periodic, or run longer)"
        )
    frequency = (len(crossings) - 1) / (crossings[-1] - crossings[0])
    start, end = crossings[-periods - 1], crossings[-1]
    inside = (t >= start) & (t <= end)
    # The samples just outside the window take part in the parabola refinement.
    lo = max(int(np.flatnonzero(inside)[0]) - 1, 0)
    hi = min(int(np.flatnonzero(inside)[-1]) + 2, len(t))
    maximum = _extreme(t[lo:hi], s[lo:hi], largest=True)
    minimum = _extreme(t[lo:hi], s[lo:hi], largest=False)
    growth = float("nan")
    if len(crossings) >= 2 * periods + 1:
        before = (t >= crossings[-2 * periods - 1]) & (t <= start)
        previous = 0.5 * (s[before].max() - s[before].min())
        if previous > 0.0:
            growth = float(0.5 * (maximum - minimum) / previous - 1.0)
    return PeriodicStatistics(
        mean=0.5 * (maximum + minimum),
        amplitude=0.5 * (maximum - minimum),
        frequency=float(frequency),
        periods=int(periods),
        start=float(start),
        end=float(end),
        minimum=float(minimum),
        maximum=float(maximum),
        growth=growth,
    )
