"""The output folder of a run: its name from a scene, one run at a time, leftovers of a kill."""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import IO

LOCK_NAME = ".elastoflow.lock"


class OutputFolderBusy(OSError):
    """Another run is writing to the output folder."""


def folder_name(name: str) -> str:
    """A scene name made safe as one folder name under the output root: ``.`` and ``..``
    components are dropped, the others joined by ``_``, characters outside
    ``[A-Za-z0-9_.-]`` become ``_`` and leading dots are dropped, so that a name from a scene
    file never leads out of the root (``"../../x"`` gives ``"x"``, ``"a/b"`` ``"a_b"``)."""
    parts = [part for part in re.split(r"[/\\]+", name) if part not in ("", ".", "..")]
    safe = re.sub(r"[^A-Za-z0-9_.-]+", "_", "_".join(parts)).lstrip(".")
    return safe or "scene"


def lock_output_folder(folder: str | Path) -> IO[str]:
    """Hold an exclusive lock on ``folder`` for this process (released when the returned file
    is closed, or when the process ends, also when it is killed).

    Raises:
        OutputFolderBusy: Another process holds it.
        OSError: The lock file cannot be created (a read-only folder).
    """
    path = Path(folder) / LOCK_NAME
    handle = open(path, "a")  # noqa: SIM115 - held open for the whole run
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows: no lock
        return handle
    try:
        fcntl.flock(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        handle.close()
        raise OutputFolderBusy(f"{folder}: another elastoflow run is writing there") from None
    handle.truncate(0)
    handle.write(f"{os.getpid()}\n")
    handle.flush()
    return handle
