"""Flutter onset of the library scene `flag_3d` on a coarser grid (48x24x24, ~25 s).

The scene at 64x32x32 flutters at U* = 20 with a tip amplitude of 2.6 cm at 0.40 Hz and
only quivers (2.8 mm at 1.1 Hz) at U* = 6 (docs/validation/three_d.md, "A flag flutters").
Here, in the first 4 s, the trailing edge's first swing across the stream (growing out of the
pole's 1 cm offset while the inflow ramps up to 2 s) must be followed by a larger one the other
way, without an element squashed. Measured on this grid: -0.78 cm, then +1.64 cm; at
U* = 6 the same run gives -0.24 cm, then a drift to +0.50 cm, no swing.
"""

from __future__ import annotations

import numpy as np
import pytest

from elastoflow.validation._flag_3d import run_flag, scene_data


# 0.08 m is 1.9 cells here: warned thin, measured anyway.
@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:bodies.0.*thin")
def test_the_flag_starts_to_flutter() -> None:
    data = scene_data()
    data["domain"]["nx"] = 48
    run = run_flag(data, duration=4.0)
    assert run.failure is None
    z = run.displacements[:, 2]
    first = int(np.argmin(z))
    assert z[first] < -0.005, f"first swing {100 * z[first]:.2f} cm"
    assert z[first:].max() > 1.5 * abs(z[first]), (
        f"second swing {100 * z[first:].max():.2f} cm after {100 * z[first]:.2f} cm")
    assert run.smallest_volume_ratio > 0.8
