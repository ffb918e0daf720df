"""Start-up: from a fresh process to the end of the first step of ``bar_in_jet``.

(a) cold: the child's ``NUMBA_CACHE_DIR`` is a new empty folder, so every ``cache=True``
kernel the first step needs is compiled (as on a fresh install; without the variable Numba
caches in ``__pycache__`` beside the package's sources); (b) warm: the same command again, the
kernels now loaded from that cache; (c) installed: a new empty cache filled by
``elastoflow warmup`` (what ``make`` runs after installing; its own time is reported as
``seconds_warmup``), then the same command. The clock starts in the parent just before the child is
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
    target = TARGET_SECONDS["warm" if cache.startswith("warm") else "cold"]
    row["target_seconds"] = target
    row["vs_target"] = versus_target(row["seconds_to_first_step"], target, at_most=True)
    return row


def measure_warmup(env: dict[str, str]) -> float:
    """Seconds of ``elastoflow warmup`` in a fresh process with ``env``."""
    began = time.time()
    done = subprocess.run([sys.executable, "-m", "elastoflow.cli", "warmup"], env=env,
                          capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"elastoflow warmup failed:\n{done.stderr[-2000:]}")
    return time.time() - began


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
        with tempfile.TemporaryDirectory(prefix="numba_cache_") as folder:
            env = dict(os.environ, NUMBA_CACHE_DIR=folder)
            seconds_warmup = measure_warmup(env)
            row = measure("installed (empty NUMBA_CACHE_DIR + elastoflow warmup)", env)
            row["seconds_warmup"] = seconds_warmup
            rows.append(row)
    print(markdown_table(rows, ["case", "cache", "seconds_to_first_step", "seconds_imports",
                                "seconds_build", "seconds_first_step", "target_seconds",
                                "vs_target", "seconds_warmup"]))
    path = write_results("startup", rows)
    print(f"\nwrote {path}")
    return rows


if __name__ == "__main__":
    main()
