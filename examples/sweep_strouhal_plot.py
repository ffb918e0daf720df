"""Plot the Strouhal study (examples/sweep_strouhal.toml) from its summary and fields.

    elastoflow sweep examples/sweep_strouhal.toml --out out/strouhal
    python examples/sweep_strouhal_plot.py out/strouhal [docs/img/sweep_strouhal.png]

Reads ``summary.parquet`` with pandas and ``fields.zarr`` with xarray, prints a Markdown table
and draws St(Re) against Williamson's (1988) fit of experiments, with the wakes below.

The scene's probe is the force of the fluid on the cylinder (traction integral); its lift (y)
oscillates at the shedding frequency f: St = f D / U.
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import xarray as xr  # noqa: E402

DIAMETER = 1.0  # [m], examples/cylinder_wake.toml
SPEED = 1.0  # [m/s]


def williamson(reynolds: np.ndarray) -> np.ndarray:
    """Williamson (1988), parallel shedding, 49 < Re < 178: St = -3.3265/Re + 0.1816 + 1.6e-4 Re."""
    return -3.3265 / reynolds + 0.1816 + 1.6e-4 * reynolds


def main(argv: list[str]) -> int:
    folder = Path(argv[0]) if argv else Path("out/strouhal")
    target = Path(argv[1]) if len(argv) > 1 else folder / "strouhal.png"
    summary = pd.read_parquet(folder / "summary.parquet")
    summary["Re"] = SPEED * DIAMETER / summary["fluid.viscosity"]
    summary["St"] = summary["force_obstacle0_y_frequency [Hz]"] * DIAMETER / SPEED
    summary["Williamson"] = williamson(summary["Re"].to_numpy())
    summary["error [%]"] = 100 * (summary["St"] / summary["Williamson"] - 1)
    print("| Re | St (elastoflow) | St (Williamson 1988) | difference | wall time [s] |")
    print("|---|---|---|---|---|")
    for _, row in summary.iterrows():
        print(f"| {row['Re']:.0f} | {row['St']:.4f} | {row['Williamson']:.4f} | "
              f"{row['error [%]']:+.1f} % | {row['wall_time [s]']:.0f} |")

    fields = xr.open_zarr(folder / "fields.zarr")
    vorticity = fields["vorticity"].isel(time=-1)
    count = vorticity.sizes["point"]
    columns = 3
    rows = (count + columns - 1) // columns
    figure = plt.figure(figsize=(10, 3.6 + 1.9 * rows))
    grid = figure.add_gridspec(1 + rows, columns, height_ratios=[3.2] + [1.7] * rows)
    axis = figure.add_subplot(grid[0, :])
    curve = np.linspace(50, 200, 200)
    axis.plot(curve, williamson(curve), "k-", lw=1, label="Williamson (1988), experiments")
    axis.plot(summary["Re"], summary["St"], "o", color="tab:red",
              label="elastoflow sweep, D/h = 10")
    axis.set_xlabel("Re = U D / ν")
    axis.set_ylabel("St = f D / U")
    axis.grid(alpha=0.3)
    axis.legend(loc="lower right")
    extent = (0.0, float(fields.x[-1] + fields.x[0]), 0.0, float(fields.y[-1] + fields.y[0]))
    for k in range(count):
        panel = figure.add_subplot(grid[1 + k // columns, k % columns])
        field = vorticity.isel(point=k)
        panel.imshow(field.T.values, origin="lower", cmap="RdBu_r", vmin=-3, vmax=3,
                     extent=extent, aspect="equal")
        panel.set_axis_off()
        reynolds = SPEED * DIAMETER / float(field["fluid.viscosity"])
        panel.set_title(f"Re = {reynolds:.0f}: vorticity at t = {float(field.time):.0f} s",
                        fontsize=8, loc="left")
    figure.tight_layout()
    figure.savefig(target, dpi=90)
    print(f"wrote {target}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
