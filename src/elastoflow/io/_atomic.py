"""Atomic file writing: a temporary file in the same folder, then ``os.replace``; and the
removal of the temporaries a killed run leaves behind."""

from __future__ import annotations

import contextlib
import os
import re
import secrets
import shutil
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

TEMPORARY_MARKER = ".tmp"

# The names of every temporary elastoflow writes: ``.{stem}.{...}.tmp{suffix}`` files (atomic
# writes, video encoder output) and ``.xdmf.{pid}.tmp`` folders (XDMF series of versions before
# the series became a stream). Nothing else in an output folder starts with a dot and holds
# ``.tmp``.
_TEMPORARY_NAME = re.compile(r"^\..+\.tmp(\.[A-Za-z0-9]+)?$")

# The temporaries each thread has created and not yet renamed or deleted. A second Ctrl-C
# raises KeyboardInterrupt between any two bytecodes, also where `atomic_path` cannot clean
# up after itself (after the file is created but before its ``try``, or inside contextlib's
# ``__enter__``, where the ``with`` has not started); `discard_unfinished_writes` removes those.
# Registered before the file exists, so that no window is left. Per thread: runs in threads
# of one process must not delete each other's writes in flight.
_UNFINISHED: dict[int, set[Path]] = {}


def _create_exclusive(directory: Path, prefix: str, suffix: str) -> Path:
    """Create a new empty file ``directory/prefix<random>suffix`` with mode 0666 less the
    umask (``tempfile.mkstemp`` would make it 0600, and the rename would keep that)."""
    unfinished = _UNFINISHED.setdefault(threading.get_ident(), set())
    while True:
        path = directory / f"{prefix}{os.getpid()}.{secrets.token_hex(4)}{suffix}"
        unfinished.add(path)
        try:
            handle = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:
            unfinished.discard(path)
            continue
        os.close(handle)
        return path


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` (same suffix, so format-sniffing writers work);
    on normal exit it replaces ``path``, on an exception it is deleted.

    Readers therefore see either the old file or the complete new one, never a partial file.
    The file gets the permissions of any new file (0666 less the umask).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = _create_exclusive(path.parent, f".{path.stem}.",
                                  f"{TEMPORARY_MARKER}{path.suffix}")
    try:
        yield temporary
        os.replace(temporary, path)
    except Exception as error:
        # A Ctrl-C inside a writer can surface as the writer's own error on the way out
        # (np.savez: zipfile's close refuses while the interrupted entry's handle is open,
        # "Can't close the ZIP file while there is an open writing handle"): the user asked
        # to stop, so the interrupt is what propagates, not a failed run.
        interrupt = _interrupt_behind(error)
        if interrupt is not None:
            raise interrupt from None
        raise
    finally:
        temporary.unlink(missing_ok=True)
        _UNFINISHED.get(threading.get_ident(), set()).discard(temporary)


def discard_unfinished_writes() -> list[Path]:
    """Delete the temporaries of this thread's atomic writes that an interrupt abandoned
    (none exist once every write has ended normally or by an exception it could handle);
    returns those that were there. Call it only when no write of this thread is in flight."""
    removed = []
    for path in sorted(_UNFINISHED.pop(threading.get_ident(), set())):
        if path.exists():
            path.unlink(missing_ok=True)
            removed.append(path)
    return removed


def _interrupt_behind(error: BaseException) -> KeyboardInterrupt | None:
    """The KeyboardInterrupt that ``error`` was raised while handling, if any."""
    seen: set[int] = set()
    current: BaseException | None = error
    while current is not None and id(current) not in seen:
        if isinstance(current, KeyboardInterrupt):
            return current
        seen.add(id(current))
        current = current.__cause__ or current.__context__
    return None


def write_bytes_atomic(path: str | Path, data: bytes, *, sync: bool = False) -> None:
    """Write ``data`` to ``path`` atomically; ``sync``: flush it to the disk before the
    rename (so that it survives a power cut, not only a killed process)."""
    with atomic_path(path) as temporary, open(temporary, "wb") as handle:
        handle.write(data)
        if sync:
            handle.flush()
            os.fsync(handle.fileno())


def write_text_atomic(path: str | Path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    write_bytes_atomic(path, text.encode("utf-8"))


def is_temporary(path: Path) -> bool:
    """Whether ``path`` is named like a temporary elastoflow writes (see `remove_temporaries`)."""
    return bool(_TEMPORARY_NAME.match(path.name))


def writers_of_temporaries(folder: str | Path) -> list[int]:
    """Process ids of this user's processes whose command line names a temporary under
    ``folder`` (Linux ``/proc``; empty elsewhere): the video encoder (ffmpeg) of a run that
    was killed, which goes on finishing its file after the run is gone and would create it
    again after `remove_temporaries`."""
    proc = Path("/proc")
    if not proc.is_dir():
        return []
    root = os.path.realpath(folder)
    found = []
    for entry in proc.iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            if entry.stat().st_uid != os.getuid():
                continue
            arguments = (entry / "cmdline").read_bytes().split(b"\0")[1:]
            if not any(TEMPORARY_MARKER.encode() in a for a in arguments):
                continue
            cwd = os.readlink(entry / "cwd")
        except OSError:
            continue
        for raw in arguments:
            path = os.path.realpath(os.path.join(cwd, os.fsdecode(raw))) if raw else ""
            if path.startswith(root + os.sep) and _TEMPORARY_NAME.match(os.path.basename(path)):
                found.append(int(entry.name))
                break
    return found


def _stop_writers(folder: Path, wait: float = 10.0) -> None:
    """Kill the `writers_of_temporaries` of ``folder`` and wait until they are gone (or
    zombies), so that none of them writes a temporary after it was removed."""
    import signal
    import time

    pids = writers_of_temporaries(folder)
    for pid in pids:
        with contextlib.suppress(OSError):
            os.kill(pid, signal.SIGKILL)
    deadline = time.monotonic() + wait
    for pid in pids:
        while time.monotonic() < deadline:
            try:
                state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
            except (OSError, IndexError):
                break
            if state in ("Z", "X"):
                break
            time.sleep(0.01)


def remove_temporaries(folder: str | Path) -> list[Path]:
    """Delete every temporary file and folder under ``folder`` left by a run that was killed
    (``.video.<pid>.tmp.mp4``, ``.fluid_000010.<pid>.<random>.tmp.vtu``, ``.xdmf.<pid>.tmp/``);
    returns what was removed. Only for a folder no other run is writing to (see
    `lock_output_folder`): processes still writing a temporary there (the orphaned video
    encoder of a killed run) are killed first."""
    removed: list[Path] = []
    folder = Path(folder)
    if not folder.is_dir():
        return removed
    _stop_writers(folder)
    for root, directories, files in os.walk(folder):
        for name in list(directories):
            if _TEMPORARY_NAME.match(name):
                shutil.rmtree(Path(root) / name, ignore_errors=True)
                removed.append(Path(root) / name)
                directories.remove(name)
        for name in files:
            if _TEMPORARY_NAME.match(name):
                (Path(root) / name).unlink(missing_ok=True)
                removed.append(Path(root) / name)
    return removed
