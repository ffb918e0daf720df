"""DFG 2D-2's quantities from a run of ``examples/dfg_2d_2.toml``, against the published bounds.

    elastoflow run examples/dfg_2d_2.toml --out out/dfg_2d_2
    python examples/dfg_2d_2_quantities.py out/dfg_2d_2

Reads the run's ``probes.csv`` (the force on the cylinder and the pressure difference between
its front and back points), turns the force into coefficients (``2 F / (rho U^2 D)``,
rho = 1 kg/m^3, U = 1 m/s, D = 0.1 m) and evaluates St, c_D max, c_L max and Δp as the
benchmark defines them (`elastoflow.validation.dfg_quantities`), once with each force probe
the run has: the traction integral on the cylinder (``force``) and the momentum balance over
a box around it (``momentum_balance``, the scheme's own force; the traction reads the lift
low by a first-order error, docs/validation/unsteady.md). The validation command
(``elastoflow validate dfg-2d-2``) reads Δp by its own extrapolation to the surface points;
the probe interpolates the field there.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from elastoflow.io import read_probes
from elastoflow.validation import dfg_quantities

DENSITY, MEAN_SPEED, DIAMETER = 1.0, 1.0, 0.1
BOUNDS = {"strouhal": ("St", 0.2950, 0.3050), "drag_max": ("c_D max", 3.2200, 3.2400),
          "lift_max": ("c_L max", 0.9900, 1.0100), "delta_p": ("Δp [Pa]", 2.4600, 2.5000)}


FORCES = {"traction": "force_obstacle0", "momentum_balance": "balance_obstacle0"}


def main(folder: str | Path) -> dict[str, dict[str, float]]:
    """Print the four quantities of the run in ``folder`` with the bounds, for each force
    probe it has; return them by force ("traction", "momentum_balance")."""
    columns, rows = read_probes(Path(folder) / "probes.csv")
    data = dict(zip(columns, np.asarray(rows, dtype=np.float64).T, strict=True))
    scale = 2.0 / (DENSITY * MEAN_SPEED**2 * DIAMETER)
    difference = next(name for name in columns if name.startswith("pressure_("))
    results = {}
    for force, prefix in FORCES.items():
        if f"{prefix}_x [N/m]" not in data:
            continue
        quantities = dfg_quantities(data["time [s]"], scale * data[f"{prefix}_x [N/m]"],
                                    scale * data[f"{prefix}_y [N/m]"], data[difference],
                                    MEAN_SPEED)
        print(f"forces by the {force.replace('_', ' ')}:")
        for key, (label, low, high) in BOUNDS.items():
            value = quantities[key]
            verdict = "inside" if low <= value <= high else "outside"
            print(f"  {label:9} {value:.4f}   bounds {low:.4f}-{high:.4f}   {verdict}")
        results[force] = quantities
    return results


if __name__ == "__main__":
    if len(sys.argv) != 2:
        raise SystemExit("usage: python examples/dfg_2d_2_quantities.py RUN_FOLDER")
    main(sys.argv[1])
