"""Run every benchmark: ``python -m benchmarks [NAME ...] [--options ...]``
(``python -m benchmarks [NAME ...] --help`` describes them and runs nothing).

Each ``benchmarks/bench_NAME.py`` module exposes ``main(argv) -> list[dict]``; it prints its own
table and writes ``benchmarks/results/NAME.json``. Timings are measurements, never assertions.
"""

from __future__ import annotations

import importlib
import pkgutil
import sys
from pathlib import Path


def available() -> list[str]:
    """Names of the benchmark modules, without the ``bench_`` prefix."""
    here = Path(__file__).resolve().parent
    return sorted(
        m.name.removeprefix("bench_")
        for m in pkgutil.iter_modules([str(here)])
        if m.name.startswith("bench_")
    )


def main(argv: list[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    # Names come first; everything from the first option on goes to the benchmarks, values
    # included (``coupling --steps 100``: 100 is the option's value, not a benchmark).
    first_option = next((k for k, a in enumerate(args) if a.startswith("-")), len(args))
    options = args[first_option:]
    names = args[:first_option] or available()
    unknown = sorted(set(names) - set(available()))
    if unknown:
        print(f"benchmark {unknown[0]!r}: unknown; available: {', '.join(available())}")
        return 2
    if "-h" in options or "--help" in options:
        # Help runs nothing: each named benchmark's own description (its options included).
        print(__doc__.strip())
        for name in names:
            module = importlib.import_module(f"benchmarks.bench_{name}")
            print(f"\n## {name}\n\n{(module.__doc__ or '').strip()}")
        return 0
    for name in names:
        print(f"\n## {name}\n", flush=True)
        module = importlib.import_module(f"benchmarks.bench_{name}")
        module.main(options)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
