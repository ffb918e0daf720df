"""The demo behind ``make demo``: the paper's bar in a jet (Fig. 6), written as a video.

Runs ``elastoflow run bar_in_jet`` for a few simulated seconds into ``out/demo`` and prints
where the video is. Pass other ``elastoflow run`` options after ``python -m elastoflow.demo``.
"""

from __future__ import annotations

import sys

DEMO_SCENE = "bar_in_jet"
DEMO_STEPS = 400
DEMO_OUT = "out/demo"


def demo_arguments(extra: list[str]) -> list[str]:
    """The ``elastoflow`` arguments of the demo. The folder is the demo's own, so a second
    ``make demo`` starts over (``--overwrite``) instead of stopping at the first run's
    checkpoints, unless the caller asks to ``--resume``."""
    args = ["run", DEMO_SCENE, "--steps", str(DEMO_STEPS), "--out", DEMO_OUT, *extra]
    if "--resume" not in extra and "--overwrite" not in extra:
        args.append("--overwrite")
    return args


def main(argv: list[str] | None = None) -> None:
    from elastoflow.cli import app

    extra = list(sys.argv[1:] if argv is None else argv)
    args = demo_arguments(extra)
    print(f"elastoflow demo: {' '.join(['elastoflow', *args])}", flush=True)
    app(args, prog_name="elastoflow")


if __name__ == "__main__":
    main()
