"""Kernels of the step checks: one threaded pass per array instead of NumPy's two
reductions and a temporary mask."""

from __future__ import annotations

import numpy as np
from numba import njit

from elastoflow._numba import serial_and_parallel

# Arrays above this many values are read by the threads.
PARALLEL_MINIMUM = 32 * 32 * 32
# The flat array's blocks, each a thread's share of the reduction.
_BLOCKS = 64


def _make_magnitude(loop):
    def kernel(flat, tops, probes):
        size = flat.shape[0]
        for block in loop(_BLOCKS):
            start = block * size // _BLOCKS
            stop = (block + 1) * size // _BLOCKS
            top = 0.0
            probe = 0.0
            for index in range(start, stop):
                value = flat[index]
                top = max(top, abs(value))
                # 0 for a finite value, NaN for a NaN or an infinity: the sum is 0 only
                # when every value is finite, whatever max makes of a NaN.
                probe += value * 0.0
            tops[block] = top
            probes[block] = probe
    return kernel


_magnitude_serial, _magnitude_parallel = serial_and_parallel(
    _make_magnitude, fastmath={"reassoc"})


@njit(cache=True)
def magnitude_and_probe(values):
    """``(largest |value|, probe)`` of a C-contiguous float array; ``probe`` is 0 exactly
    when every value is finite (NaN otherwise), and only then is the largest meaningful."""
    flat = values.reshape(-1)
    tops = np.zeros(_BLOCKS)
    probes = np.zeros(_BLOCKS)
    if flat.shape[0] > PARALLEL_MINIMUM:
        _magnitude_parallel(flat, tops, probes)
    else:
        _magnitude_serial(flat, tops, probes)
    return tops.max(), probes.sum()
