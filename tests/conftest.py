"""Test-session settings shared by every test directory."""

import os

# pytest-xdist runs one process per core. Numba's default of one thread per core in each of
# them would put two threads on every core, and threads that spin between parallel regions
# (the package's GOMP_SPINCOUNT) then wait on each other: the suite took 63 s instead of 41 s
# on 2 cores. One thread per worker still runs the parallel kernels' code. It must be set
# before Numba is imported.
if os.environ.get("PYTEST_XDIST_WORKER") and "NUMBA_NUM_THREADS" not in os.environ:
    os.environ["NUMBA_NUM_THREADS"] = "1"
