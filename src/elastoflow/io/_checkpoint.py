"""Checkpoints: `Simulation.checkpoint()` arrays in one ``.npz``, written atomically."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

from elastoflow.io._atomic import atomic_path

_NAME = re.compile(r"^checkpoint_(\d+)\.npz$")


def checkpoint_path(folder: str | Path, step: int) -> Path:
    """``folder/checkpoint_{step:08d}.npz``."""
    return Path(folder) / f"checkpoint_{step:08d}.npz"


def save_checkpoint(path: str | Path, simulation: Any) -> Path:
    """Write ``simulation.checkpoint()`` to ``path`` (temporary file, then rename)."""
    data = simulation.checkpoint()
    with atomic_path(path) as temporary, open(temporary, "wb") as handle:
        np.savez(handle, **data)
    return Path(path)


def load_checkpoint(path: str | Path, simulation: Any) -> None:
    """Restore ``simulation`` from a checkpoint file (bit-exact)."""
    with np.load(path) as archive:
        simulation.restore({key: archive[key] for key in archive.files})


def latest_checkpoint(folder: str | Path) -> Path | None:
    """The checkpoint with the highest step in ``folder``, or None."""
    folder = Path(folder)
    if not folder.is_dir():
        return None
    found = [(int(m.group(1)), p) for p in folder.iterdir() if (m := _NAME.match(p.name))]
    return max(found)[1] if found else None
