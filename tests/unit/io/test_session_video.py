"""OutputSession's video: one frame per step, in order, drawn into one reused array."""

from __future__ import annotations

from typing import Any

import numpy as np


def _bar_with_video(folder) -> tuple[Any, Any]:
    """bar_in_jet at 32 cells across with a video of every step and no other output: the
    simulation and its output session in ``folder``."""
    from elastoflow.io import OutputSession, apply_output_overrides
    from elastoflow.scenes import build_simulation, get_scene

    scene = get_scene("bar_in_jet")
    scene = scene.model_copy(update={"domain": scene.domain.model_copy(
        update={"nx": 32, "ny": None})})
    scene = apply_output_overrides(scene, video=True, fields=[], meshes=False, probes=False,
                                   checkpoint_every=0, every=1)
    simulation = build_simulation(scene)
    return simulation, OutputSession(scene, simulation, folder)


def test_session_video_has_every_step_in_order(tmp_path) -> None:
    import imageio.v2 as imageio

    from elastoflow.render import render_frame

    simulation, session = _bar_with_video(tmp_path)
    steps = 6
    expected = []
    for _ in range(steps):
        simulation.step()
        session.after_step(simulation, None)
        # The session's colour range only widens; drawn here with the range it used.
        expected.append(render_frame(
            simulation.grid, simulation.state.fluid, simulation.body_geometry(), simulation.obstacles,
            "speed", simulation.time,
            value_range=(session._range.low, session._range.high)))
    written = session.close(final_checkpoint=False)
    assert session.video_note is None and tmp_path / "video.mp4" in written
    reader = imageio.get_reader(tmp_path / "video.mp4")
    frames = [f for f in reader]
    reader.close()
    # The first frame is the initial state, then one per step.
    assert len(frames) == steps + 1
    for frame, reference in zip(frames[1:], expected, strict=True):
        # Lossy h264: compare each frame against its own step and against its neighbours;
        # it must be closest to its own.
        own = np.abs(frame.astype(float) - reference).mean()
        assert own < 1.5
    errors = np.array([[np.abs(f.astype(float) - r).mean() for r in expected]
                       for f in frames[1:]])
    assert np.all(np.argmin(errors, axis=1) == np.arange(steps))


def test_close_stops_an_orphaned_encoder_and_removes_its_temporary(tmp_path) -> None:
    """A second Ctrl-C while a segment's encoder was being started leaves ffmpeg running with
    its temporary and no writer to finish it (seen once in CI: ``video_parts/.current.<pid>
    .tmp.mp4`` after the run had exited). Closing the session kills such a writer and
    removes the file; the finished segments stay."""
    import subprocess
    import sys

    simulation, session = _bar_with_video(tmp_path)
    simulation.step()
    session.after_step(simulation, None)
    parts = tmp_path / "video_parts"
    stray = parts / ".current.99999.tmp.mp4"
    stray.write_bytes(b"half an mp4")
    # Stands in for the orphaned ffmpeg: its command line names the temporary.
    orphan = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)",
                               str(stray)])
    try:
        session.close(final_checkpoint=False, stopped=True)
        assert orphan.wait(timeout=10) != 0  # killed
    finally:
        if orphan.poll() is None:
            orphan.kill()
    assert not stray.exists()
    assert [p.name for p in parts.iterdir()] == ["upto_00000001.mp4"]
