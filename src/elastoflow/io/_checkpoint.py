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


class CheckpointError(ValueError):
    """A checkpoint cannot be used: unreadable, damaged (truncated, corrupt, empty), or saved
    from another scene. The message names the file and says which."""


def damage(error: BaseException) -> str:
    """What a failed ``np.load`` of an ``.npz`` says about the file, in a user's words."""
    if "allow_pickle" in str(error):
        # Never advise allow_pickle: loading pickles from a file runs code from that file.
        return "it holds pickled Python objects, which elastoflow never writes"
    return f"truncated or corrupt: {type(error).__name__}: {error}"


def read_checkpoint(path: str | Path) -> dict[str, np.ndarray]:
    """Every array of a checkpoint file, read in full (so that a damaged file fails here).

    Raises:
        CheckpointError: The file cannot be read, is not a complete checkpoint, or holds
            non-finite values.
    """
    path = Path(path)
    try:
        size = path.stat().st_size
        if size == 0:
            raise CheckpointError(f"checkpoint {path} is empty (0 bytes): it was never written "
                                  "completely")
        with np.load(path, allow_pickle=False) as archive:
            data = {key: np.array(archive[key]) for key in archive.files}
    except CheckpointError:
        raise
    except OSError as error:
        raise CheckpointError(f"cannot read checkpoint {path}: {error.strerror or error}") from None
    except Exception as error:  # noqa: BLE001 - numpy/zipfile fail with many exception types
        raise CheckpointError(f"checkpoint {path} is damaged ({damage(error)})") from None
    missing = [key for key in ("time", "step_index") if key not in data]
    if missing:
        raise CheckpointError(f"checkpoint {path} is not an elastoflow checkpoint (no "
                              f"{', '.join(missing)})")
    for key, array in data.items():
        if array.dtype.kind in "fc" and not np.all(np.isfinite(array)):
            raise CheckpointError(f"checkpoint {path} holds non-finite values in {key}: it is "
                                  "damaged or was saved from a diverged state")
    return data


def load_checkpoint(path: str | Path, simulation: Any) -> None:
    """Restore ``simulation`` from a checkpoint file (bit-exact).

    Raises:
        CheckpointError: The file is damaged (see `read_checkpoint`) or does not fit the
            simulation (other bodies, other grid).
    """
    data = read_checkpoint(path)
    try:
        simulation.restore(data)
    except (ValueError, KeyError, IndexError, TypeError) as error:
        raise CheckpointError(f"checkpoint {path} does not fit this scene: {error}") from None


def latest_checkpoint(folder: str | Path) -> Path | None:
    """The checkpoint with the highest step in ``folder``, or None."""
    folder = Path(folder)
    if not folder.is_dir():
        return None
    found = [(int(m.group(1)), p) for p in folder.iterdir() if (m := _NAME.match(p.name))]
    return max(found)[1] if found else None
