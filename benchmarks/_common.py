"""Shared plumbing for benchmarks: machine description, JSON output, Markdown tables.

Benchmarks are measurements, never assertions. Each benchmark module exposes
``main(argv=None) -> list[dict]`` that prints a table and writes ``benchmarks/results/NAME.json``.
"""

from __future__ import annotations

import json
import math
import os
import platform
import subprocess
import tempfile
from pathlib import Path
from typing import Any

RESULTS_DIR = Path(__file__).resolve().parent / "results"


def commit() -> str:
    """The current git commit (with '-dirty' when the work tree has changes), or 'unknown'."""
    root = Path(__file__).resolve().parent.parent
    try:
        sha = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=root, capture_output=True, text=True,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"], cwd=root,
            capture_output=True, text=True, check=True,
        ).stdout.strip()
        return sha + ("-dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def machine() -> dict[str, Any]:
    """CPU model, core count, OS, Python, NumPy and Numba versions."""
    import numba
    import numpy

    cpu = platform.processor() or "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "numba_threads": numba.config.NUMBA_NUM_THREADS,
        "os": platform.platform(),
        "python": platform.python_version(),
        "numpy": numpy.__version__,
        "numba": numba.__version__,
    }


def write_results(name: str, rows: list[dict[str, Any]]) -> Path:
    """Write rows with commit and machine as ``results/NAME.json`` (temporary file, then rename)."""
    RESULTS_DIR.mkdir(parents=True, exist_ok=True)
    path = RESULTS_DIR / f"{name}.json"
    payload = {"benchmark": name, "commit": commit(), "machine": machine(), "results": rows}
    with tempfile.NamedTemporaryFile("w", dir=RESULTS_DIR, delete=False, suffix=".tmp") as f:
        json.dump(payload, f, indent=2)
        tmp = f.name
    os.replace(tmp, path)
    return path


def markdown_table(rows: list[dict[str, Any]], columns: list[str]) -> str:
    """A Markdown table of ``rows`` restricted to ``columns`` (floats to 4 significant digits)."""

    def fmt(value: Any) -> str:
        if isinstance(value, float):
            return f"{value:.4g}"
        return str(value)

    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    for row in rows:
        lines.append("| " + " | ".join(fmt(row.get(c, "")) for c in columns) + " |")
    return "\n".join(lines)


def versus_target(value: float, target: float, *, at_most: bool) -> str:
    """``'met'`` or the miss factor, e.g. ``'x1.6 over'`` (``at_most``) or ``'x1.6 under'``.

    Args:
        value: The measured figure.
        target: The issue's target for it.
        at_most: True when the target is an upper bound (times, shares, memory), False when it
            is a lower bound (steps/s, frames/s).
    """
    if math.isnan(value) or target <= 0.0:
        return "n/a"
    if at_most:
        return "met" if value <= target else f"x{value / target:.2f} over"
    return "met" if value >= target else f"x{target / max(value, 1e-300):.2f} under"


def run_child(module: str, args: list[str], env: dict[str, str] | None = None,
              timeout: float = 1800.0) -> dict[str, Any]:
    """Run ``python -m MODULE ARGS`` in a fresh process; its last stdout line is JSON.

    A fresh process per case keeps each case's peak memory (``ru_maxrss``) its own.
    """
    import sys

    root = Path(__file__).resolve().parent.parent
    child_env = dict(os.environ if env is None else env)
    child_env["PYTHONPATH"] = os.pathsep.join(
        p for p in (str(root), child_env.get("PYTHONPATH", "")) if p)
    done = subprocess.run([sys.executable, "-m", module, *args], cwd=root, env=child_env,
                          capture_output=True, text=True, timeout=timeout, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"{module} {' '.join(args)} failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def peak_memory_mb() -> float:
    """This process's peak resident memory [MB].

    Linux: ``VmHWM`` of ``/proc/self/status``, the high-water mark of this process's own
    address space; ``ru_maxrss`` is carried over ``exec`` from the process that started it, so
    a child started by a large parent (a pytest-xdist worker, or the runner after the 1024²
    fluid case) would report the parent's peak. Elsewhere ``ru_maxrss``.
    """
    import resource
    import sys

    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024 / 1e6
    except (OSError, ValueError, IndexError):
        pass
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / 1e6 if sys.platform == "darwin" else peak * 1024 / 1e6
