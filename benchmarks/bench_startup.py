"""Start-up: from a fresh process to the end of the first step of ``bar_in_jet``.

(a) cold: the child's ``NUMBA_CACHE_DIR`` is a new empty folder, so every ``cache=True``
kernel the first step needs is compiled (as on a fresh install; without the variable Numba
caches in ``__pycache__`` beside the package's sources); (b) warm: the same command again, the
kernels now loaded from that cache. The clock starts in the parent just before the child is
started, and stops in the child at the end of its first step; the child also reports when its
imports and the scene's build ended. Targets: cold <= 20 s, warm <= 2 s.

Usage: ``python -m benchmarks startup [--quick]`` (``--quick``: the warm run only, against the
existing cache, for smoke tests).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import markdown_table, versus_target, write_results

TARGET_SECONDS = {"cold": 20.0, "warm": 2.0}

_CHILD = """
import json, time
import elastoflow.scenes as scenes
imported = time.time()
simulation = scenes.build_simulation(scenes.get_scene({scene!r}))
built = time.time()
simulation.step()
print(json.dumps({{"imported": imported, "built": built, "stepped": time.time()}}))
"""


def measure(cache: str, env: dict[str, str], scene: str = "bar_in_jet") -> dict[str, Any]:
    """One fresh process; seconds from its start to its imports, build and first step."""
    root = Path(__file__).resolve().parent.parent
    began = time.time()
    done = subprocess.run([sys.executable, "-c", _CHILD.format(scene=scene)], cwd=root, env=env,
                          capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"start-up child failed:\n{done.stderr[-2000:]}")
    marks = json.loads(done.stdout.strip().splitlines()[-1])
    row: dict[str, Any] = {
        "case": scene,
        "cache": cache,
        "seconds_to_first_step": marks["stepped"] - began,
        "seconds_imports": marks["imported"] - began,
        "seconds_build": marks["built"] - marks["imported"],
        "seconds_first_step": marks["stepped"] - marks["built"],
    }
    target = TARGET_SECONDS["cold" if cache.startswith("cold") else "warm"]
    row["target_seconds"] = target
    row["vs_target"] = versus_target(row["seconds_to_first_step"], target, at_most=True)
    return row


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    """Run the benchmark, print a Markdown table, write ``results/startup.json``."""
    args = list(sys.argv[1:] if argv is None else argv)
    rows = []
    if "--quick" in args:
        rows.append(measure("warm (existing cache)", dict(os.environ)))
    else:
        with tempfile.TemporaryDirectory(prefix="numba_cache_") as folder:
            env = dict(os.environ, NUMBA_CACHE_DIR=folder)
            rows.append(measure("cold (empty NUMBA_CACHE_DIR)", env))
            rows.append(measure("warm (same NUMBA_CACHE_DIR, 2nd run)", env))
    print(markdown_table(rows, ["case", "cache", "seconds_to_first_step", "seconds_imports",
                                "seconds_build", "seconds_first_step", "target_seconds",
                                "vs_target"]))
    path = write_results("startup", rows)
    print(f"\nwrote {path}")
    return rows


if __name__ == "__main__":
    main()
