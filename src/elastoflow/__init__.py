"""elastoflow: fast two-way coupling of incompressible fluid and elastic bodies.

Implements Imamura, Harada & Kawaguchi, *Fast Coupling of Fluid and Deformable Bodies using
Boundary Mapping*: a MAC-grid stable-fluids solver, explicit FEM triangle meshes, and a boundary
map built from the bodies' boundary edges that classifies grid points, imposes cut-distance
boundary conditions and gives the fluid-to-solid force.
"""

import os

# With the OpenMP threading layer, idle Numba threads spin between parallel regions. When the
# cores are shared (other processes, pytest-xdist workers) the spinning threads starve the
# working ones: a 512^2 pressure solve took 2.4 s instead of 55 ms on 2 busy cores, and the
# threaded FEM kernel ran 5x slower than the serial one. Sleeping idle threads cost a few
# microseconds per region instead. It must be set before the first parallel kernel runs, so it
# lives at the package root; an explicit user setting wins.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

__version__ = "0.1.0"

from elastoflow._api import frame, load

__all__ = ["__version__", "frame", "load"]
