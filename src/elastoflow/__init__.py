"""elastoflow: fast two-way coupling of incompressible fluid and elastic bodies.

Implements Imamura, Harada & Kawaguchi, *Fast Coupling of Fluid and Deformable Bodies using
Boundary Mapping*: a MAC-grid stable-fluids solver, explicit FEM triangle meshes, and a boundary
map built from the bodies' boundary edges that classifies grid points, imposes cut-distance
boundary conditions and gives the fluid-to-solid force.
"""

import os

# Idle Numba threads (OpenMP layer, libgomp) spin GOMP_SPINCOUNT times before they sleep, and
# waking a sleeping thread costs ~50 us per parallel region on the project's 2-core VM, as much
# as a whole 256^2 pass. libgomp's default of 300 000 spins starves the working threads when
# the cores are shared (two processes on 2 cores: a 512^2 pressure solve 19 -> 950 ms); no
# spinning at all (OMP_WAIT_POLICY=PASSIVE) made every region pay the wake-up (bar_in_jet
# 14.7 ms a step against 9.2 with 1000 spins). 1000 spins keep a step's regions warm and cost
# ~1.5x, not 50x, when two simulations share two cores (docs/benchmarks.md). It must be set
# before the first parallel kernel runs, so it lives at the package root; an explicit user
# setting of either variable wins.
if "OMP_WAIT_POLICY" not in os.environ and "GOMP_SPINCOUNT" not in os.environ:
    os.environ["GOMP_SPINCOUNT"] = "1000"

__version__ = "0.1.0"

from elastoflow._api import frame, load

__all__ = ["__version__", "frame", "load"]
