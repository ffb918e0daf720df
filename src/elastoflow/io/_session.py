"""All outputs of one run, driven by a callback between steps (never inside the physics)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from elastoflow.io._atomic import write_text_atomic
from elastoflow.io._checkpoint import checkpoint_path, latest_checkpoint, save_checkpoint
from elastoflow.io._fields import FieldWriter, snapshot_arrays
from elastoflow.io._meshes import write_extruded_meshes
from elastoflow.io._probes import ProbeRecorder

KEEP_CHECKPOINTS = 3


class RangeTracker:
    """Colour range that only widens over a run, so the video's colours do not flicker."""

    def __init__(self) -> None:
        self.low = float("inf")
        self.high = float("-inf")

    def update(self, low: float, high: float) -> tuple[float, float]:
        self.low = min(self.low, low)
        self.high = max(self.high, high)
        return self.low, self.high


class OutputSession:
    """Video, field snapshots, extruded meshes, probes and checkpoints of one run.

    Call `after_step` after every step (it is a ``callback(simulation, report)``), and `close`
    at the end, also after an error or Ctrl-C: it finishes the video, writes the probes and a
    final checkpoint, so everything up to the last completed step is kept.

    Layout of ``out_dir``: ``scene.toml``, ``video.mp4`` (``video_from_{step}.mp4`` after a
    resume), ``fields/``, ``meshes/``, ``probes.csv`` + ``probes.png``, ``checkpoints/``.

    Args:
        scene: The `elastoflow.scenes.Scene` (its ``outputs`` say what to write).
        simulation: The `Simulation` being run.
        out_dir: Output folder (created).
        resumed: The simulation was restored from a checkpoint in ``out_dir``: keep earlier
            field frames and probe rows up to its step, start a new video segment.
    """

    def __init__(self, scene: Any, simulation: Any, out_dir: str | Path, *,
                 resumed: bool = False) -> None:
        from elastoflow.scenes import scene_to_toml

        self.scene = scene
        self.outputs = scene.outputs
        self.simulation = simulation
        self.out_dir = Path(out_dir)
        self.out_dir.mkdir(parents=True, exist_ok=True)
        write_text_atomic(self.out_dir / "scene.toml", scene_to_toml(scene))
        start = simulation.step_index
        resume_step = start if resumed else None
        self.written: list[Path] = []
        self._video: Any = None
        self._frame_image: Any = None
        self._range = RangeTracker()
        if self.outputs.video is not None:
            from elastoflow.render import VideoWriter

            name = f"video_from_{start:06d}.mp4" if resumed and start > 0 else "video.mp4"
            self._video = VideoWriter(self.out_dir / name, fps=self.outputs.video.fps)
        self._fields = None
        if self.outputs.fields is not None:
            self._fields = FieldWriter(self.out_dir / "fields", simulation.grid,
                                       self.outputs.fields.formats, resume_step=resume_step)
        self._probes = None
        if self.outputs.probes:
            self._probes = ProbeRecorder(self.outputs.probes, simulation,
                                         self.out_dir / "probes.csv", resume_step=resume_step)
        self._closed = False
        if not resumed:
            self._write_frame_outputs(None, force=True)

    # -- per step ------------------------------------------------------------------------

    def _due(self, spec: Any, step: int, force: bool) -> bool:
        return spec is not None and (force or step % spec.every == 0)

    def _write_frame_outputs(self, report: Any, force: bool = False, video: bool = True) -> None:
        sim, out = self.simulation, self.outputs
        step = sim.step_index
        if video and self._video is not None and self._due(out.video, step, force):
            # Drawn into the previous frame's array: the writer has converted that one already.
            self._frame_image = self.frame(out.video.view, out=self._frame_image)
            self._video.append(self._frame_image)
        if self._fields is not None and self._due(out.fields, step, force):
            interior = getattr(sim, "interior", None)
            self._fields.write(snapshot_arrays(
                sim.grid, sim.state, sim.bodies, sim.obstacles, time=sim.time, step=step,
                solid_cells=None if interior is None else interior.solid_cells,
            ))
        if out.meshes is not None and sim.bodies and self._due(out.meshes, step, force):
            write_extruded_meshes(self.out_dir / "meshes", step,
                                  [(b.positions, b.mesh.triangles) for b in sim.bodies],
                                  out.meshes.thickness, out.meshes.format)

    def frame(self, view: str, *, out: Any = None) -> Any:
        """The current picture (RGB array) in ``view``, colour range widening over the run.

        ``out``: an earlier frame's array to draw into (see `render_frame`).
        """
        from elastoflow.render import default_value_range, render_frame, view_values

        sim = self.simulation
        values = view_values(sim.grid, sim.state, view)
        low, high = default_value_range(values, view)
        return render_frame(sim.grid, sim.state, sim.bodies, sim.obstacles, view, sim.time,
                            value_range=self._range.update(low, high), values=values, out=out)

    def after_step(self, simulation: Any, report: Any) -> None:
        """The per-step callback: writes whatever is due at this step."""
        step = simulation.step_index
        self._write_frame_outputs(report)
        if self._probes is not None and step % self.outputs.probes_every == 0:
            self._probes.record(simulation, report)
        checkpoint = self.outputs.checkpoint
        if checkpoint is not None and step % checkpoint.every == 0:
            self.checkpoint()

    __call__ = after_step

    def checkpoint(self) -> Path:
        """Save a checkpoint now and drop all but the newest few."""
        folder = self.out_dir / "checkpoints"
        path = save_checkpoint(checkpoint_path(folder, self.simulation.step_index), self.simulation)
        for old in sorted(folder.glob("checkpoint_*.npz"))[:-KEEP_CHECKPOINTS]:
            old.unlink()
        return path

    # -- the end -------------------------------------------------------------------------

    def close(self, *, final_checkpoint: bool = True) -> list[Path]:
        """Finish every output; returns the main files written (video, probes, checkpoint)."""
        if self._closed:
            return self.written
        self._closed = True
        # The last state is always saved, also when the run stops between two output steps.
        self._write_frame_outputs(None, force=True, video=False)
        if self._video is not None:
            path = self._video.close()
            if path is not None:
                self.written.append(path)
        if self._fields is not None:
            self._fields.close()
            self.written.append(self._fields.folder)
        if self._probes is not None and self._probes.rows:
            self.written.append(self._probes.write_csv())
            plot = self._probes.plot()
            if plot is not None:
                self.written.append(plot)
        if self.outputs.meshes is not None and self.simulation.bodies:
            self.written.append(self.out_dir / "meshes")
        if final_checkpoint:
            self.written.append(self.checkpoint())
        return self.written

    @property
    def video_note(self) -> str | None:
        """Why the video is a GIF, if ffmpeg failed."""
        return None if self._video is None else self._video.fallback_reason


def find_resume_checkpoint(out_dir: str | Path) -> Path | None:
    """The newest checkpoint of a run in ``out_dir``, or None."""
    return latest_checkpoint(Path(out_dir) / "checkpoints")


def apply_output_overrides(scene: Any, *, video: bool | None = None,
                           fields: Sequence[str] | None = None, meshes: bool | None = None,
                           probes: bool | None = None, checkpoint_every: int | None = None,
                           view: str | None = None, every: int | None = None) -> Any:
    """A copy of ``scene`` with its outputs switched on/off as a command line asks.

    None leaves a setting as the scene has it; ``fields=[]`` switches fields off.
    """
    from elastoflow.scenes import CheckpointSpec, FieldsSpec, MeshesSpec, VideoSpec

    outputs = scene.outputs.model_copy(deep=True)
    if video is False:
        outputs.video = None
    elif video or view is not None:
        outputs.video = outputs.video or VideoSpec()
    if outputs.video is not None and view is not None:
        outputs.video.view = view  # type: ignore[assignment]
    if fields is not None:
        outputs.fields = FieldsSpec(formats=list(fields)) if fields else None  # type: ignore[arg-type]
    if meshes is False:
        outputs.meshes = None
    elif meshes:
        outputs.meshes = outputs.meshes or MeshesSpec()
    if probes is False:
        outputs.probes = []
    if checkpoint_every is not None:
        outputs.checkpoint = CheckpointSpec(every=checkpoint_every) if checkpoint_every > 0 else None
    if every is not None:
        for spec in (outputs.video, outputs.fields, outputs.meshes):
            if spec is not None:
                spec.every = every
    return scene.model_copy(update={"outputs": outputs})
