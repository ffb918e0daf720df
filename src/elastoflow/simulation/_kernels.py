"""Kernels of the step checks: one threaded pass per array where NumPy takes two or three
(``np.abs(a).max()`` and ``np.isfinite(a).all()`` each allocate a temporary of the array's
size)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from elastoflow._numba import serial_and_parallel

# Values per chunk of the threaded reduction (about 0.1 ms of work).
_CHUNK = 1 << 16


def _make_survey(loop):
    def kernel(values):
        size = values.size
        chunks = (size + _CHUNK - 1) // _CHUNK
        largest = np.zeros(chunks)
        bad = np.zeros(chunks, dtype=np.int64)
        for chunk in loop(chunks):
            high = 0.0
            count = 0
            for index in range(chunk * _CHUNK, min(size, (chunk + 1) * _CHUNK)):
                value = values[index]
                if math.isnan(value):
                    count += 1
                else:
                    high = max(high, abs(value))
            largest[chunk] = high
            bad[chunk] = count
        return largest.max() if chunks else 0.0, bad.sum()
    return kernel


_survey_serial, _survey_parallel = serial_and_parallel(_make_survey)


@njit(cache=True)
def survey(values):
    """``(largest |value| over the values that are not NaN, number of NaNs)`` of a flat
    float64 array: all are finite when the first is and the second is 0."""
    if values.size > 4 * _CHUNK:
        return _survey_parallel(values)
    return _survey_serial(values)
