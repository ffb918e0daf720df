"""The demo behind ``make demo`` can be run again: it starts over in its own folder."""

from __future__ import annotations

from elastoflow.demo import DEMO_OUT, demo_arguments


def test_demo_starts_over_in_its_own_folder_unless_resumed() -> None:
    args = demo_arguments([])
    assert args[:2] == ["run", "bar_in_jet"] and DEMO_OUT in args and "--overwrite" in args
    assert "--overwrite" not in demo_arguments(["--resume"])
    assert demo_arguments(["--overwrite"]).count("--overwrite") == 1
