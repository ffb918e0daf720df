"""The Python API in a script: load a scene, step it, read fields and bodies, save a frame.

    python examples/notebook_api.py            # writes out/notebook_api.png
"""

from __future__ import annotations

import sys
from pathlib import Path

import imageio.v3 as iio
import numpy as np

import elastoflow


def main(steps: int = 100, out: Path = Path("out/notebook_api.png")) -> Path:
    sim = elastoflow.load("bar_in_jet")
    nodes = sim.state.bodies[0].positions  # the same array for the whole run
    tip = int(np.argmin(nodes[:, 1]))
    start = nodes[tip].copy()
    for _ in range(steps):
        report = sim.step()
    moved = nodes[tip] - start
    fluid = sim.state.fluid
    speed = np.hypot(fluid.velocity_x[:-1] + fluid.velocity_x[1:],
                     fluid.velocity_y[:, :-1] + fluid.velocity_y[:, 1:]) / 2
    print(f"t = {sim.time:.3f} s after {sim.step_index} steps; pressure solve: "
          f"{report.pressure_iterations} iterations, residual {report.pressure_residual:.1e}")
    print(f"bar tip moved by ({moved[0]:+.4f}, {moved[1]:+.4f}) m; max speed {speed.max():.3f} m/s")
    out.parent.mkdir(parents=True, exist_ok=True)
    iio.imwrite(out, elastoflow.frame(sim, view="vorticity"))
    print(f"wrote {out}")
    return out


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 100)
