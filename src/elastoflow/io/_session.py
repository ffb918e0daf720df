"""All outputs of one run, driven by a callback between steps (never inside the physics)."""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from elastoflow.io._atomic import (
    discard_unfinished_writes,
    is_temporary,
    remove_temporaries,
    write_text_atomic,
)
from elastoflow.io._checkpoint import (
    checkpoint_path,
    checkpoints_by_step,
    latest_checkpoint,
    save_checkpoint,
)
from elastoflow.io._fields import FieldWriter, snapshot_arrays
from elastoflow.io._fields3d import FieldWriter3D
from elastoflow.io._meshes import write_extruded_meshes, write_surface_meshes
from elastoflow.io._probes import ProbeRecorder
from elastoflow.io._surface import surface_polylines, write_surface_mesh

KEEP_CHECKPOINTS = 3
_MESH_FILE = re.compile(r"^(?:body\d+|surface)_(\d{6,})\.(?:obj|ply)$")


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
    at the end, also after an error or Ctrl-C: it finishes the video, the probes and a final
    checkpoint, so everything up to the last completed step is kept. After a failed step (or
    a failed output), call `recover` before `close`: it puts the simulation back to the state
    after the last step whose outputs were all written, so that the final checkpoint holds a
    good state and no file is written from a diverged one.

    Every output is complete at any time and continues on resume: a checkpoint at step s is
    taken after every output of step s is written (the video segment cut, probes and XDMF
    synced), and a session resumed from it drops what later steps had written (probe rows,
    snapshots, meshes, video segments) and appends to the same files.

    Layout of ``out_dir``: ``scene.toml``, ``video.mp4`` (joined at the end from
    ``video_parts/``), ``fields/``, ``meshes/``, ``probes.csv`` + ``probes.png``,
    ``checkpoints/``.

    Args:
        scene: The `elastoflow.scenes.Scene` (its ``outputs`` say what to write).
        simulation: The `Simulation` being run.
        out_dir: Output folder (created).
        resumed: The simulation was restored from a checkpoint in ``out_dir``: keep the
            outputs up to its step, drop later ones, continue the same files.
        run: Saved in every checkpoint (see `save_checkpoint`): the scene's TOML and the run's
            options, read back on resume; ``video_range`` ([low, high]) restores the video's
            colour range.
    """

    def __init__(self, scene: Any, simulation: Any, out_dir: str | Path, *,
                 resumed: bool = False, run: Mapping[str, Any] | None = None) -> None:
        from elastoflow.scenes import scene_to_toml

        self.scene = scene
        self.outputs = scene.outputs
        self.simulation = simulation
        self.out_dir = Path(out_dir)
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self.run = dict(run or {})
        write_text_atomic(self.out_dir / "scene.toml", scene_to_toml(scene))
        start = simulation.step_index
        resume_step = start if resumed else None
        self.written: list[Path] = []
        self.last_checkpoint: Path | None = None
        self._video: Any = None
        self._frame_image: Any = None
        self._orientation: tuple[float, float] | None = None
        self._range = RangeTracker()
        saved_range = self.run.pop("video_range", None)
        if resumed and saved_range is not None:
            self._range.update(float(saved_range[0]), float(saved_range[1]))
        # The step each frame output was last written at: never twice for one step.
        self._written_at: dict[str, int] = {}
        if self.outputs.video is not None:
            from elastoflow.render import SegmentedVideo

            self._video = SegmentedVideo(self.out_dir / "video.mp4", fps=self.outputs.video.fps,
                                         resume_step=resume_step)
        self.three_d = getattr(simulation, "dimension", 2) == 3
        self._fields: FieldWriter | FieldWriter3D | None = None
        if self.outputs.fields is not None and self.three_d:
            self._fields = FieldWriter3D(self.out_dir / "fields", simulation.grid,
                                         body_count=len(simulation.bodies),
                                         resume_step=resume_step)
        elif self.outputs.fields is not None:
            self._fields = FieldWriter(
                self.out_dir / "fields", simulation.grid, self.outputs.fields.formats,
                resume_step=resume_step,
                level_set=getattr(simulation, "level_set", None) is not None)
        if resume_step is not None:
            _drop_later_meshes(self.out_dir / "meshes", resume_step)
        self._probes = None
        if self.outputs.probes:
            self._probes = ProbeRecorder(self.outputs.probes, simulation,
                                         self.out_dir / "probes.csv", resume_step=resume_step)
        self._closed = False
        self._last_good: dict[str, Any] | None = None
        if resumed:
            for name in ("video", "fields", "meshes"):
                self._written_at[name] = start
        else:
            self._write_frame_outputs(None, force=True)
            if self.outputs.checkpoint is not None:
                # A run killed before its first periodic checkpoint can be resumed too.
                self.checkpoint()
        self._remember_good()

    # -- per step ------------------------------------------------------------------------

    def _due(self, name: str, spec: Any, step: int, force: bool) -> bool:
        return (spec is not None and self._written_at.get(name) != step
                and (force or step % spec.every == 0))

    def _write_frame_outputs(self, report: Any, force: bool = False, video: bool = True) -> None:
        sim, out = self.simulation, self.outputs
        step = sim.step_index
        if isinstance(self._fields, FieldWriter3D) and self._due("fields", out.fields, step,
                                                                  force):
            self._fields.write(sim)
            self._written_at["fields"] = step
        elif self._fields is not None and self._due("fields", out.fields, step, force):
            interior = getattr(sim, "interior", None)
            self._fields.write(snapshot_arrays(
                sim.grid, sim.state.fluid, list(zip(sim.bodies, sim.state.bodies)),
                sim.obstacles, time=sim.time, step=step,
                solid_cells=None if interior is None else interior.solid_cells,
                level_set=getattr(sim, "level_set", None),
            ))
            self._written_at["fields"] = step
        level_set = getattr(sim, "level_set", None)
        if (out.meshes is not None and (sim.bodies or level_set is not None)
                and self._due("meshes", out.meshes, step, force)):
            folder = self.out_dir / "meshes"
            if self.three_d:
                write_surface_meshes(folder, step, sim.body_geometry(), out.meshes.format)
            else:
                write_extruded_meshes(folder, step, sim.body_geometry(), out.meshes.thickness,
                                      out.meshes.format)
            if level_set is not None:
                write_surface_mesh(folder / f"surface_{step:06d}.{out.meshes.format}",
                                   surface_polylines(sim.grid, level_set),
                                   out.meshes.thickness, out.meshes.format)
            self._written_at["meshes"] = step
        if video and self._video is not None and self._due("video", out.video, step, force):
            # Drawn into the previous frame's array: the writer has converted that one already.
            # Last of the outputs: a frame in the video is never undone by a later failure.
            self._frame_image = self.frame(out.video.view, out=self._frame_image)
            self._video.append(self._frame_image)
            self._written_at["video"] = step

    def frame(self, view: str, *, out: Any = None) -> Any:
        """The current picture (RGB array) in ``view``, colour range widening over the run.

        ``out``: an earlier frame's array to draw into (see `render_frame`).
        """
        from elastoflow.render import (
            default_value_range,
            liquid_values,
            render_frame,
            view_values,
        )

        sim = self.simulation
        if self.three_d:
            return self._frame_3d(view, out)
        values = view_values(sim.grid, sim.state.fluid, view)
        level_set = getattr(sim, "level_set", None)
        shown = values if level_set is None else liquid_values(values, level_set)
        low, high = default_value_range(shown, view)
        return render_frame(sim.grid, sim.state.fluid, sim.body_geometry(), sim.obstacles,
                            view, sim.time,
                            value_range=self._range.update(low, high), values=values, out=out,
                            level_set=level_set)

    def _frame_3d(self, view: str, out: Any) -> Any:
        """A 3D run's picture, as ``outputs.video.style`` says: the scene in perspective with
        the video's slice (``"3d"``), or the slice alone with the bodies and obstacles cut by
        it (``"slice"``)."""
        from elastoflow.render import (
            default_value_range,
            layer_values,
            render_scene_3d,
            render_slice_3d,
            scene_orientation,
        )

        sim, video = self.simulation, self.outputs.video
        axis = video.axis if video is not None else "z"
        position = video.at if video is not None else None
        style = video.style if video is not None else "3d"
        grid = sim.grid
        k = "xyz".index(axis)
        low_edge = grid.origin[k]
        if position is None:
            position = low_edge + 0.5 * grid.shape_cells[k] * grid.h
        index = min(int((position - low_edge) / grid.h), grid.shape_cells[k] - 1)
        values = layer_values(grid, sim.state.fluid, k, index, view)
        low, high = default_value_range(values, view)
        value_range = self._range.update(low, high)
        if style == "3d":
            obstacles = [(obstacle.points_at(sim.time), obstacle.triangles)
                         for obstacle in sim.obstacles]
            surfaces = sim.body_geometry()
            if self._orientation is None:
                # Chosen once: the camera stays put when a body crosses the slice.
                azimuth, elevation = scene_orientation(axis, position, (*surfaces, *obstacles))
                if video is not None and video.azimuth is not None:
                    azimuth = video.azimuth
                if video is not None and video.elevation is not None:
                    elevation = video.elevation
                self._orientation = (azimuth, elevation)
            azimuth, elevation = self._orientation
            return render_scene_3d(grid, sim.state.fluid, axis=axis, position=position,
                                   view=view, surfaces=surfaces, obstacles=obstacles,
                                   time=sim.time, values=values, value_range=value_range,
                                   azimuth=azimuth, elevation=elevation, out=out)
        solids = [(state.positions, body.mesh.tetrahedra)
                  for body, state in zip(sim.bodies, sim.state.bodies)]
        for obstacle in sim.obstacles:
            solid = obstacle.solid_at(sim.time)
            if solid is not None:
                solids.append(solid)
        return render_slice_3d(grid, sim.state.fluid, axis=axis, position=position, view=view,
                               bodies=solids, time=sim.time, values=values,
                               value_range=value_range, out=out)

    def after_step(self, simulation: Any, report: Any) -> None:
        """The per-step callback: writes whatever is due at this step."""
        step = simulation.step_index
        if self._probes is not None:
            self._probes.observe(simulation)
            if step % self.outputs.probes_every == 0:
                self._probes.record(simulation, report)
        self._write_frame_outputs(report)
        checkpoint = self.outputs.checkpoint
        if checkpoint is not None and step % checkpoint.every == 0:
            self.checkpoint()
        self._remember_good()

    __call__ = after_step

    def _remember_good(self) -> None:
        # Every output of this step is written: this is the state `recover` goes back to.
        self._last_good = self.simulation.checkpoint()

    def recover(self) -> bool:
        """Put the simulation back to the state after the last step whose outputs were all
        written (after a failed step or output); returns whether it did."""
        if self._last_good is None:
            return False
        self.simulation.restore(self._last_good)
        return True

    def checkpoint(self) -> Path:
        """Make every output complete up to now (cut the video segment, sync probes and
        XDMF), then save a checkpoint and drop all but the newest few."""
        step = self.simulation.step_index
        if self._video is not None:
            self._video.cut(step)
        if self._probes is not None:
            self._probes.sync()
        if self._fields is not None:
            self._fields.sync()
        run = dict(self.run)
        if np.isfinite([self._range.low, self._range.high]).all():
            run["video_range"] = np.array([self._range.low, self._range.high])
        folder = self.out_dir / "checkpoints"
        path = save_checkpoint(checkpoint_path(folder, step), self.simulation, run=run)
        self.last_checkpoint = path
        older = [p for s, p in checkpoints_by_step(folder) if s < step]
        for old in older[:max(0, len(older) - (KEEP_CHECKPOINTS - 1))]:
            old.unlink()
        return path

    # -- the end -------------------------------------------------------------------------

    def close(self, *, final_checkpoint: bool = True, failed: bool = False,
              stopped: bool = False) -> list[Path]:
        """Finish every output; returns the main files written (video, probes, checkpoint).

        ``failed``: the run failed (after `recover`): no output is drawn from the current
        state, only the checkpoint is saved. ``stopped``: the run was interrupted and will be
        resumed: fields and meshes keep their ``every`` schedule (no snapshot of the stop step
        off it, which an uninterrupted run would not have), the checkpoint is saved. Every part is attempted; the first `OSError`
        (a full or read-only disk) is raised at the end.
        """
        if self._closed:
            return self.written
        self._closed = True
        # A Ctrl-C that stopped a write mid-way can leave its temporary behind.
        discard_unfinished_writes()
        errors: list[OSError] = []

        def attempt(action: Any) -> Any:
            try:
                return action()
            except OSError as error:
                errors.append(error)
                return None

        sim = self.simulation
        if not failed and not stopped:
            # The last state is always saved, also when the run ends between output steps.
            attempt(lambda: self._write_frame_outputs(None, force=True, video=False))
        if self._video is not None:
            attempt(lambda: self._video.cut(sim.step_index))
            # A second Ctrl-C while a segment's encoder was being started (ffmpeg running,
            # its writer not yet kept) leaves the encoder's temporary behind, and the
            # orphaned ffmpeg finishes it after the run has gone; stop it and remove it.
            parts = self._video.parts
            if parts.is_dir() and any(is_temporary(p) for p in parts.iterdir()):
                attempt(lambda: remove_temporaries(parts))
        for closable in (self._probes, self._fields):
            if closable is not None:
                attempt(closable.close)
        if final_checkpoint and not errors:
            path = attempt(self.checkpoint)
            if path is not None:
                self.written.append(path)
        if self._video is not None:
            video = attempt(lambda: self._video.close(sim.step_index))
            if video is not None:
                self.written.insert(0, video)
        if self._fields is not None:
            self.written.append(self._fields.folder)
        if self._probes is not None and self._probes.rows:
            self.written.append(self._probes.path)
            plot = attempt(self._probes.plot)
            if plot is not None:
                self.written.append(plot)
            statistics = attempt(self._probes.write_statistics)
            if statistics is not None:
                self.written.append(statistics)
        if self.outputs.meshes is not None and (
                sim.bodies or getattr(sim, "level_set", None) is not None):
            self.written.append(self.out_dir / "meshes")
        if errors:
            raise errors[0]
        return self.written

    @property
    def video_note(self) -> str | None:
        """Why the video is a GIF or left in segments, if ffmpeg failed."""
        return None if self._video is None else self._video.fallback_reason


def _drop_later_meshes(folder: Path, step: int) -> None:
    if not folder.is_dir():
        return
    for path in folder.iterdir():
        match = _MESH_FILE.match(path.name)
        if match and int(match.group(1)) > step:
            path.unlink()


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
    from elastoflow.scenes import (
        CheckpointSpec,
        Fields3DSpec,
        FieldsSpec,
        Meshes3DSpec,
        MeshesSpec,
        Scene3D,
        Video3DSpec,
        VideoSpec,
    )

    three_d = isinstance(scene, Scene3D)
    outputs = scene.outputs.model_copy(deep=True)
    if video is False:
        outputs.video = None
    elif video or view is not None:
        outputs.video = outputs.video or (Video3DSpec() if three_d else VideoSpec())
    if outputs.video is not None and view is not None:
        outputs.video.view = view
    if fields is not None:
        fields_spec = Fields3DSpec if three_d else FieldsSpec
        outputs.fields = fields_spec(formats=list(fields)) if fields else None  # type: ignore[arg-type]
    if meshes is False:
        outputs.meshes = None
    elif meshes:
        outputs.meshes = outputs.meshes or (Meshes3DSpec() if three_d else MeshesSpec())
    if probes is False:
        outputs.probes = []
    if checkpoint_every is not None:
        outputs.checkpoint = CheckpointSpec(every=checkpoint_every) if checkpoint_every > 0 else None
    if every is not None:
        for spec in (outputs.video, outputs.fields, outputs.meshes):
            if spec is not None:
                spec.every = every
    return scene.model_copy(update={"outputs": outputs})
