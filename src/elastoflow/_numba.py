"""One kernel body compiled twice: without threads and with them."""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

from numba import njit, prange


def _start_threads() -> None:
    """Start Numba's thread pool now, when a kernel module is imported.

    Why: Numba starts its threads when a threaded kernel is first called from Python. A
    cached kernel that branches to a threaded twin (`serial_and_parallel`'s dispatchers, e.g.
    `pressure_rhs`) makes that first threaded call from compiled code, where nothing starts
    them: with a warm disk cache it segfaulted when it was the process's first threaded
    call (a ghost-fluid projection before any step). Starting them costs ~20 ms once.
    ``ELASTOFLOW_LAZY_THREADS=1`` leaves them to Numba (tests/unit/test_numba_twins.py
    tells the twins apart by which one starts them).
    """
    if os.environ.get("ELASTOFLOW_LAZY_THREADS") == "1":
        return
    try:
        from numba.np.ufunc import parallel
    except ImportError:  # pragma: no cover - a Numba without the threaded backend
        return
    launch = getattr(parallel, "_launch_threads", None)
    if launch is not None:
        launch()


_start_threads()


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
