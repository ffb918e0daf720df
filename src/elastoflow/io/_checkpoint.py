"""Checkpoints: `Simulation.checkpoint()` arrays in one ``.npz``, written atomically, with
what a resume needs besides the state (the scene, the run's options, the video's colour range)
under keys starting with ``run_``."""

from __future__ import annotations

import json
import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from elastoflow.io._atomic import atomic_path

_NAME = re.compile(r"^checkpoint_(\d+)\.npz$")


def checkpoint_path(folder: str | Path, step: int) -> Path:
    """``folder/checkpoint_{step:08d}.npz``."""
    return Path(folder) / f"checkpoint_{step:08d}.npz"


def save_checkpoint(path: str | Path, simulation: Any, *,
                    state: Mapping[str, np.ndarray] | None = None,
                    run: Mapping[str, Any] | None = None) -> Path:
    """Write ``simulation.checkpoint()`` (or ``state``, arrays it returned earlier) to ``path``:
    a temporary file, flushed to the disk, then renamed.

    Args:
        path: The ``.npz`` file.
        simulation: The `Simulation`.
        state: Arrays of an earlier ``simulation.checkpoint()`` to save instead of the current
            state (the last good state of a failed run).
        run: Strings, numbers or arrays saved beside the state as ``run_{key}`` (the scene's
            TOML, the run's options as JSON); read back with `run_record`.
    """
    data = dict(simulation.checkpoint() if state is None else state)
    for key, value in (run or {}).items():
        data[f"run_{key}"] = np.asarray(value)
    with atomic_path(path) as temporary, open(temporary, "wb") as handle:
        np.savez(handle, **data)
        handle.flush()
        os.fsync(handle.fileno())
    return Path(path)


def run_record(data: Mapping[str, np.ndarray]) -> dict[str, Any]:
    """The ``run`` entries of a checkpoint read by `read_checkpoint`, without the ``run_``
    prefix: strings as ``str``, arrays as arrays; ``options`` (JSON) as a dict. Empty for a
    checkpoint written before the run record existed."""
    record: dict[str, Any] = {}
    for key, value in data.items():
        if key.startswith("run_"):
            record[key[4:]] = str(value) if value.dtype.kind == "U" else np.array(value)
    if "options" in record:
        try:
            record["options"] = json.loads(record["options"])
        except ValueError:
            record["options"] = {}
    return record


class CheckpointError(ValueError):
    """A checkpoint cannot be used: unreadable, damaged (truncated, corrupt, empty), or saved
    from another scene. The message names the file and says which."""


def damage(error: BaseException, path: str | Path | None = None) -> str:
    """What a failed ``np.load`` of an ``.npz`` (``path``, when given) says about the file,
    in a user's words."""
    if "allow_pickle" in str(error):
        # NumPy says this also of any file that is neither a zip nor an .npy. Never advise allow_pickle: loading pickles
        # from a file runs code from that file.
        try:
            with open(path, "rb") as handle:  # type: ignore[arg-type]
                start = handle.read(8)
        except (OSError, TypeError):
            start = b"\x80"
        # A pickle, or an .npz / .npy whose arrays hold Python objects (pickled inside).
        if start.startswith((b"\x80", b"PK", b"\x93NUMPY")):
            return "it holds pickled Python objects, which elastoflow never writes"
        return f"not a NumPy .npz file: it starts with {start!r}"
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
        raise CheckpointError(f"checkpoint {path} is damaged ({damage(error, path)})") from None
    missing = [key for key in ("time", "step_index") if key not in data]
    if missing:
        raise CheckpointError(f"checkpoint {path} is not an elastoflow checkpoint (no "
                              f"{', '.join(missing)})")
    for key, array in data.items():
        if array.dtype.kind in "fc" and not np.all(np.isfinite(array)):
            raise CheckpointError(f"checkpoint {path} holds non-finite values in {key}: it is "
                                  "damaged or was saved from a diverged state")
    return data


def load_checkpoint(path: str | Path, simulation: Any,
                    data: Mapping[str, np.ndarray] | None = None) -> None:
    """Restore ``simulation`` from a checkpoint file (bit-exact).

    ``data``: the file's arrays, if `read_checkpoint` has read them already.

    Raises:
        CheckpointError: The file is damaged (see `read_checkpoint`) or does not fit the
            simulation (other bodies, other grid).
    """
    if data is None:
        data = read_checkpoint(path)
    state = {key: value for key, value in data.items() if not key.startswith("run_")}
    try:
        simulation.restore(state)
    except (ValueError, KeyError, IndexError, TypeError) as error:
        raise CheckpointError(f"checkpoint {path} does not fit this scene: {error}") from None


def checkpoints_by_step(folder: str | Path) -> list[tuple[int, Path]]:
    """``(step, path)`` of every checkpoint in ``folder``, oldest first."""
    folder = Path(folder)
    if not folder.is_dir():
        return []
    return sorted((int(m.group(1)), p) for p in folder.iterdir() if (m := _NAME.match(p.name)))


def latest_checkpoint(folder: str | Path) -> Path | None:
    """The checkpoint with the highest step in ``folder``, or None."""
    found = checkpoints_by_step(folder)
    return found[-1][1] if found else None
