"""`remove_temporaries` after a kill: a process still writing a temporary (the video encoder
of the killed run, which finishes its file after its parent is gone) is stopped first, so that
it cannot create the temporary again once it was removed."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from elastoflow.io import remove_temporaries
from elastoflow.io._atomic import writers_of_temporaries

pytestmark = pytest.mark.skipif(not Path("/proc/self/cmdline").exists(),
                                reason="finds the writers through /proc")

_LATE_WRITER = ("import sys, time\n"
                "time.sleep(600)\n"
                "open(sys.argv[1], 'w').write('written after the cleanup')\n")


def _writer(target: str, cwd: Path) -> subprocess.Popen[bytes]:
    """A process that names ``target`` on its command line and writes it much later, in its
    own session like an orphaned encoder."""
    return subprocess.Popen([sys.executable, "-c", _LATE_WRITER, target], cwd=cwd,
                            start_new_session=True)


def test_a_process_still_writing_a_temporary_is_stopped_before_the_cleanup(
        tmp_path: Path) -> None:
    out = tmp_path / "out"
    parts = out / "video_parts"
    parts.mkdir(parents=True)
    leftover = parts / ".current.4242.tmp.mp4"
    leftover.write_bytes(b"partial")
    elsewhere = tmp_path / "other"
    elsewhere.mkdir()
    # Named relative to its working directory, as the encoder of a run started in out/'s
    # parent names it.
    inside = _writer("out/video_parts/.current.4242.tmp.mp4", tmp_path)
    outside = _writer(str(elsewhere / ".current.4243.tmp.mp4"), tmp_path)
    try:
        assert writers_of_temporaries(out) == [inside.pid]
        removed = remove_temporaries(out)
        assert removed == [leftover]
        assert inside.wait(timeout=60) == -9
        assert not leftover.exists()
        # A writer of another folder is not this run's business.
        assert outside.poll() is None
    finally:
        for process in (inside, outside):
            if process.poll() is None:
                process.kill()
            process.wait()


def test_a_process_naming_a_finished_file_is_not_a_writer(tmp_path: Path) -> None:
    (tmp_path / "video.mp4").write_bytes(b"done")
    reader = _writer(str(tmp_path / "video.mp4"), tmp_path)
    try:
        assert writers_of_temporaries(tmp_path) == []
        remove_temporaries(tmp_path)
        assert reader.poll() is None
    finally:
        reader.kill()
        reader.wait()


def test_a_ctrl_c_inside_a_writer_stays_a_ctrl_c_and_leaves_no_temporary(
        tmp_path: Path) -> None:
    """np.savez interrupted mid-entry fails again in zipfile's close ("Can't close the ZIP
    file while there is an open writing handle"), raised while handling the interrupt: the
    atomic write re-raises the interrupt (the run then stops with exit 130 and its resume
    command, not as a failed run) and removes its temporary; a plain error stays itself."""
    from elastoflow.io._atomic import atomic_path

    target = tmp_path / "checkpoint.npz"
    with pytest.raises(KeyboardInterrupt):
        with atomic_path(target) as temporary:
            temporary.write_bytes(b"partial")
            try:
                raise KeyboardInterrupt
            except KeyboardInterrupt:
                raise ValueError("Can't close the ZIP file while there is an open writing "
                                 "handle on it.") from None
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(ValueError, match="disk says no"):
        with atomic_path(target):
            raise ValueError("disk says no")
    assert list(tmp_path.iterdir()) == []
