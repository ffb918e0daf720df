"""One kernel body compiled twice: without threads and with them."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from numba import njit, prange


def serial_and_parallel(make: Callable[[Any], Callable[..., Any]], **options: Any) -> tuple[Any, Any]:
    """``(serial, parallel)`` Numba kernels from one body.

    ``make(loop)`` returns the kernel's Python function, whose outer loop is written
    ``for i in loop(m)``; the serial kernel gets ``range``, the parallel one ``prange`` and
    ``parallel=True``. Callers pick one by the size of the work (a parallel region does not
    pay on small grids).

    Why a factory rather than ``njit(parallel=...)`` applied twice to one function: Numba's
    disk cache keys an entry by signature, target machine, bytecode and closure values, not
    by the compile options, so the two would share one entry and one would run the other's
    code. Here the loop function is a closure value, which keeps the keys apart
    (tests/unit/test_numba_twins.py checks that both load their own code from the cache).

    Args:
        make: The factory.
        **options: Further `numba.njit` options for both (e.g. ``fastmath``).
    """
    return (njit(cache=True, **options)(make(range)),
            njit(cache=True, parallel=True, **options)(make(prange)))
