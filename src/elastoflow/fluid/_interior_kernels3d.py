"""The 3D fluid's body-aware sampling, for the coupling's kernels.

The kernels of the 3D fluid with and without bodies are one set, in
`elastoflow.fluid._kernels3d`; this module only keeps the import path of the trilinear
sample with cut-distance ghosts that `elastoflow.coupling._kernels3d` uses for the traction.
"""

from __future__ import annotations

from elastoflow.fluid._kernels3d import _sample_bodies

__all__ = ["_sample_bodies"]
