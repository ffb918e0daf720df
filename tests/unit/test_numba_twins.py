"""`elastoflow._numba.serial_and_parallel`: each twin loads its own code from the disk cache."""

from __future__ import annotations

import json
import os
import subprocess
import sys

_CHILD = """
import json, sys
import numpy as np
from numba.np.ufunc import parallel
from elastoflow.fluid._kernels import _copy_into_parallel, _copy_into_serial
source = np.arange(12.0).reshape(3, 4)
result = {}
for name in sys.argv[1:]:
    kernel = {"serial": _copy_into_serial, "parallel": _copy_into_parallel}[name]
    target = np.zeros_like(source)
    kernel(source, target)
    result[name] = {"equal": bool((target == source).all()),
                    "cache_hits": sum(kernel.stats.cache_hits.values()),
                    "threads_started": bool(parallel._is_initialized)}
print(json.dumps(result))
"""


def _run(cache: str, *names: str) -> dict:
    # Threads left to Numba: which twin starts them tells the twins apart.
    env = dict(os.environ, NUMBA_CACHE_DIR=cache, NUMBA_NUM_THREADS="2",
               ELASTOFLOW_LAZY_THREADS="1")
    done = subprocess.run([sys.executable, "-c", _CHILD, *names], env=env, capture_output=True,
                          text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_serial_and_parallel_twins_keep_their_own_cache_entries(tmp_path) -> None:
    cache = str(tmp_path / "numba_cache")
    first = _run(cache, "serial", "parallel")
    assert first["serial"]["cache_hits"] == 0 and first["parallel"]["cache_hits"] == 0
    # From the cache, the serial twin must not start the thread pool and the parallel one must:
    # had they shared one entry, one of them would run the other's code.
    serial = _run(cache, "serial")["serial"]
    assert serial == {"equal": True, "cache_hits": 1, "threads_started": False}
    parallel = _run(cache, "parallel")["parallel"]
    assert parallel == {"equal": True, "cache_hits": 1, "threads_started": True}


def test_threads_start_when_a_kernel_module_is_imported() -> None:
    """By default the pool is running as soon as a kernel module is imported, before any
    threaded call (a cached dispatcher's first threaded call from compiled code would find
    it stopped)."""
    child = ("from numba.np.ufunc import parallel\n"
             "import elastoflow.fluid._kernels\n"
             "print(bool(parallel._is_initialized))\n")
    env = {key: value for key, value in os.environ.items() if key != "ELASTOFLOW_LAZY_THREADS"}
    done = subprocess.run([sys.executable, "-c", child], env=env, capture_output=True,
                          text=True, check=True)
    assert done.stdout.strip().splitlines()[-1] == "True"
