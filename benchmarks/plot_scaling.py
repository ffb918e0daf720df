"""Plot the fluid step time against the number of cells from ``results/fluid.json``.

Usage: ``python benchmarks/plot_scaling.py [OUT.png]`` (default docs/img/benchmark_fluid_scaling.png),
after ``python -m benchmarks fluid``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

ROOT = Path(__file__).resolve().parent.parent


def main(out: Path = ROOT / "docs" / "img" / "benchmark_fluid_scaling.png") -> Path:
    data = json.loads((ROOT / "benchmarks" / "results" / "fluid.json").read_text())
    figure, axes = plt.subplots(figsize=(6, 4.2))
    for scheme in sorted({row["advection"] for row in data["results"]}):
        rows = [r for r in data["results"] if r["advection"] == scheme]
        cells = [int(r["size"].split("x")[0]) * int(r["size"].split("x")[1]) for r in rows]
        axes.loglog(cells, [r["ms_per_step"] for r in rows], "o-", label=scheme)
    reference = [256**2, 1024**2]
    first = min(r["ms_per_step"] for r in data["results"])
    axes.loglog(reference, [first, first * 16], "k--", lw=0.8, label="linear in cells")
    axes.loglog([256**2, 512**2, 1024**2], [4, 16, 70], "rx", label="targets")
    axes.set_xlabel("cells")
    axes.set_ylabel("ms per fluid step (to rtol 1e-6)")
    axes.set_title(f"fluid step, {data['machine']['cores']} cores, commit {data['commit']}")
    axes.grid(True, which="both", alpha=0.3)
    axes.legend()
    figure.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(out, dpi=110)
    print(f"wrote {out}")
    return out


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "docs" / "img" / "benchmark_fluid_scaling.png")
