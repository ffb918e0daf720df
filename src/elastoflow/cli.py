"""The ``elastoflow`` command: run, list, validate, dump, view, render, bench, warmup.

Exit codes: 0 success, 2 bad input (one line per problem, no traceback), 1 the run failed
(the message says at which step, body and element).
"""

from __future__ import annotations

import _thread
import functools
import signal
import sys
import time as _time
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, NoReturn, Self

import typer

from elastoflow.sweep._cli import sweep_command

EXIT_BAD_INPUT = 2
EXIT_RUN_FAILED = 1

app = typer.Typer(
    name="elastoflow",
    help=(
        "Fluid and elastic bodies coupled through a boundary map (Imamura, Harada & Kawaguchi).\n\n"
        "Examples:\n\n"
        "  elastoflow list                                  # built-in scenes\n\n"
        "  elastoflow run bar_in_jet --steps 200            # video + probes in out/bar_in_jet\n\n"
        "  elastoflow run my_scene.toml --fields npz,vtk    # also ParaView files\n\n"
        "  elastoflow run bar_in_jet --resume               # continue after Ctrl-C\n\n"
        "  elastoflow dump windmill -o windmill.toml        # a built-in scene as a starting file\n\n"
        "  elastoflow validate windmill.toml                # check a scene file\n\n"
        "  elastoflow validate turek-hron FSI3              # a published benchmark\n\n"
        "  elastoflow validate dfg-2d-2 --resolution 20     # vortex shedding at Re 100\n\n"
        "  elastoflow validate dfg-2d-1 --viscosity-scheme bdf2  # steady flow at Re 20\n\n"
        "  elastoflow validate boundary-study --out docs/validation  # map vs staircase\n\n"
        "  elastoflow view jet_in_box                       # interactive window\n\n"
        "  elastoflow render out/bar_in_jet --view vorticity  # new video from saved fields\n\n"
        "  elastoflow warmup                                # compile the kernels once, ahead"
    ),
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def _fail(lines: list[str] | str, code: int = EXIT_BAD_INPUT) -> NoReturn:
    for line in [lines] if isinstance(lines, str) else lines:
        typer.echo(f"error: {line}", err=True)
    raise typer.Exit(code)


def _scene(name_or_path: str) -> Any:
    from elastoflow.scenes import SceneError, resolve_scene

    try:
        return resolve_scene(name_or_path)
    except SceneError as error:
        _fail(str(error).splitlines())


def _build(scene: Any, steps: int | None = None) -> Any:
    """The scene's `Simulation`, built and checked as for a run (memory, meshes, constraints,
    geometry); problems exit 2, warnings are printed."""
    from elastoflow.scenes import SceneError, build_simulation

    warnings: list[str] = []
    try:
        simulation = build_simulation(scene, steps=steps, warnings=warnings)
    except SceneError as error:
        _fail(str(error).splitlines())
    prefix = f"{scene.source}: " if scene.source else ""
    for line in warnings:
        typer.echo(f"warning: {prefix}{line}", err=True)
    return simulation


def _output_folder(out: Path, option: str) -> None:
    """Exit 2 unless ``out`` is (or can be made) a folder this process can write in."""
    import tempfile

    if out.exists() and not out.is_dir():
        _fail(f"{option} = {str(out)!r}: is a file; must be a folder (created if missing)")
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out):
            pass
    except OSError as error:
        _fail(f"{option} = {str(out)!r}: cannot write there ({error.strerror or error}); choose "
              "a writable folder")


def _parse_formats(text: str | None, three_d: bool = False) -> list[str] | None:
    from elastoflow.io import FIELD_FORMATS

    if text is None:
        return None
    formats = [f.strip() for f in text.split(",") if f.strip()]
    if formats in (["none"], ["off"]):
        return []
    allowed = ("vti",) if three_d else FIELD_FORMATS
    bad = [f for f in formats if f not in allowed]
    if bad:
        kind = "a 3D scene's formats are" if three_d else "formats must be among"
        _fail(f"--fields = {text!r}: {kind} {', '.join(allowed)} (comma separated) or 'none'")
    return formats


class _StopRequest:
    """First Ctrl-C: finish the current step, then stop cleanly. Second: stop at once.

    Leaving the ``with`` block (the stepping) does not give Ctrl-C back: the outputs are
    then closed and the resume command printed, which a Ctrl-C must not cut short (a second
    Ctrl-C 2 ms after the first, landing there, used to exit 130 without the command).
    `release` gives it back.
    """

    def __init__(self) -> None:
        self.requested = False
        self.finishing = False
        self._previous: Any = None
        self._previous_hook: Any = None
        self._in_hook = False

    def __enter__(self) -> Self:
        self._previous = signal.signal(signal.SIGINT, self._handle)
        self._previous_hook = sys.unraisablehook
        sys.unraisablehook = self._unraisable
        return self

    def __exit__(self, *exc: object) -> None:
        self.finishing = True

    def release(self) -> None:
        """Ctrl-C as before the stepping (safe to call when never entered, or twice)."""
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)
            self._previous = None
        if self._previous_hook is not None:
            sys.unraisablehook = self._previous_hook
            self._previous_hook = None

    def _unraisable(self, unraisable: Any) -> None:
        # The second Ctrl-C's KeyboardInterrupt can land where Python cannot raise it: in a
        # weakref callback or a __del__ run by the garbage collector (seen in CI: the
        # interpreter printed "Exception ignored in ... WeakValueDictionary ... remove" with
        # a traceback, and the run went on to the end of the step). Deliver it again, so
        # that it is raised at the next point that can raise it, and print nothing.
        if (unraisable.exc_type is KeyboardInterrupt and self.requested
                and not self.finishing):
            # Delivered while this hook runs (starting the timer thread can wait long enough
            # under load), the handler delivers it once more instead of raising here.
            self._in_hook = True
            try:
                _deliver_again()
            finally:
                self._in_hook = False
            return
        (self._previous_hook or sys.__unraisablehook__)(unraisable)

    def _handle(self, signum: int, frame: Any) -> None:
        # Never raised inside Numba's compiler or cache loader: the exception lands in an
        # llvmlite ctypes callback, which ignores it and then crashes the process (SIGSEGV,
        # seen on a double Ctrl-C during the first step). There the second Ctrl-C stops after
        # the step, as the first one does.
        if self.requested and not self.finishing and not _inside_compiler(frame):
            if self._in_hook:
                _deliver_again()
                return
            raise KeyboardInterrupt
        self.requested = True


def _deliver_again() -> None:
    """SIGINT to the main thread again, a millisecond from now.

    From another thread: a signal raised from the main thread is handled at once, inside
    the unraisable hook that wants it handled after it returns.
    """
    import threading

    timer = threading.Timer(0.001, _thread.interrupt_main, args=(signal.SIGINT,))
    timer.daemon = True
    timer.start()


def _inside_compiler(frame: Any) -> bool:
    """Whether a Python frame of Numba or llvmlite is on the stack of ``frame``."""
    import os

    marks = (f"{os.sep}numba{os.sep}", f"{os.sep}llvmlite{os.sep}")
    while frame is not None:
        if any(mark in frame.f_code.co_filename for mark in marks):
            return True
        frame = frame.f_back
    return False


def _option_words(options: dict[str, Any]) -> list[str]:
    """The command-line words that give ``options`` (the keys of `run`'s output options)."""
    words: list[str] = []
    for flag in ("video", "meshes", "probes"):
        if options.get(flag) is not None:
            words.append(f"--{flag}" if options[flag] else f"--no-{flag}")
    if options.get("view") is not None:
        words += ["--view", str(options["view"])]
    if options.get("fields") is not None:
        words += ["--fields", ",".join(options["fields"]) or "none"]
    if options.get("every") is not None:
        words += ["--every", str(options["every"])]
    if options.get("checkpoint_every") is not None:
        words += ["--checkpoint-every", str(options["checkpoint_every"])]
    return words


def _scene_differences(current: Any, stored: Any) -> list[str]:
    """Key paths (``fluid.viscosity: 0.001 -> 1.0``) where two scenes differ, outputs and
    name aside."""
    exclude = {"outputs", "name", "description"}

    def flat(value: Any, prefix: str, into: dict[str, Any]) -> dict[str, Any]:
        if isinstance(value, dict):
            for key, item in value.items():
                flat(item, f"{prefix}.{key}" if prefix else str(key), into)
        elif isinstance(value, list) and any(isinstance(v, dict | list) for v in value):
            for index, item in enumerate(value):
                flat(item, f"{prefix}.{index}", into)
            into[f"{prefix}.#"] = len(value)
        else:
            into[prefix] = value
        return into

    a = flat(current.model_dump(mode="json", exclude=exclude), "", {})
    b = flat(stored.model_dump(mode="json", exclude=exclude), "", {})
    return [f"{key}: {b.get(key, '(none)')} -> {a.get(key, '(none)')}"
            for key in sorted(set(a) | set(b)) if a.get(key) != b.get(key)]


def _stored_scene(text: str) -> Any:
    import tomllib

    from elastoflow.scenes import SceneError, parse_scene

    try:
        return parse_scene(tomllib.loads(text))
    except (SceneError, tomllib.TOMLDecodeError):
        return None


@app.command()
def run(
    scene: Annotated[str, typer.Argument(help="Built-in scene name or scene TOML file.")],
    steps: Annotated[int | None, typer.Option(help="Run until this step (default: the scene's "
                                              "duration).", min=1)] = None,
    out: Annotated[Path | None, typer.Option(help="Output folder (default out/<scene name>).")] = None,
    video: Annotated[bool | None, typer.Option("--video/--no-video", help="Write (or not) a "
                                               "video; default as the scene says.")] = None,
    view: Annotated[str | None, typer.Option(help="Video view: speed, vorticity, pressure, "
                                             "dye.")] = None,
    fields: Annotated[str | None, typer.Option(help="Field formats to save, comma separated: "
                                               "npz,vtk,xdmf (3D: vti); 'none' for none.")
                      ] = None,
    meshes: Annotated[bool | None, typer.Option("--meshes/--no-meshes", help="Extruded body "
                                                "meshes (3D: surfaces; OBJ) per frame.")
                      ] = None,
    probes: Annotated[bool | None, typer.Option("--probes/--no-probes", help="Probe time "
                                                "series (CSV + PNG).")] = None,
    every: Annotated[int | None, typer.Option(help="Save video frames, fields and meshes every "
                                              "N steps.", min=1)] = None,
    checkpoint_every: Annotated[int | None, typer.Option(help="Checkpoint every N steps (0: "
                                                         "only at the end).", min=0)] = None,
    resume: Annotated[bool, typer.Option(help="Continue from the newest checkpoint in the "
                                         "output folder, with the options of the run that "
                                         "wrote it (options given now override them).")] = False,
    force_resume: Annotated[bool, typer.Option(help="Resume even though the scene differs "
                                               "from the one the checkpoint was saved "
                                               "with.")] = False,
    overwrite: Annotated[bool, typer.Option(help="Start a new run in an output folder that "
                                            "holds checkpoints of an earlier one (they are "
                                            "deleted).")] = False,
    quiet: Annotated[bool, typer.Option(help="No progress bar.")] = False,
) -> None:
    """Run a scene, writing video, fields, meshes, probes and checkpoints.

    Ctrl-C stops after the current step, keeps everything written so far (the video is
    finished, a checkpoint saved) and prints how to resume. A run killed at any point leaves
    complete files; --resume removes its temporaries and continues every output.
    """
    import json
    import shlex

    from elastoflow.io import (
        CheckpointError,
        OutputFolderBusy,
        OutputSession,
        apply_output_overrides,
        checkpoints_by_step,
        find_resume_checkpoint,
        folder_name,
        load_checkpoint,
        lock_output_folder,
        read_checkpoint,
        remove_temporaries,
        run_record,
    )
    from elastoflow.render import VIEWS
    from elastoflow.scenes import SceneError, scene_to_toml, step_count

    chosen = _scene(scene)
    if view is not None and view not in VIEWS:
        _fail(f"--view = {view!r}: must be one of {', '.join(VIEWS)}")
    three_d = getattr(chosen, "dimension", 2) == 3
    given: dict[str, Any] = {"video": video, "view": view,
                             "fields": _parse_formats(fields, three_d), "meshes": meshes,
             "probes": probes, "every": every, "checkpoint_every": checkpoint_every}
    given = {key: value for key, value in given.items() if value is not None}
    # A name from a scene file never leads out of out/ ("../../x" becomes "_x").
    out_dir = out if out is not None else Path("out") / folder_name(chosen.name)
    checkpoints = out_dir / "checkpoints"

    options = dict(given)
    checkpoint: Path | None = None
    saved: dict[str, Any] = {}
    if resume:
        checkpoint = find_resume_checkpoint(out_dir)
        if checkpoint is None:
            _fail(f"--resume: no checkpoint in {checkpoints}")
        try:
            saved = read_checkpoint(checkpoint)
        except CheckpointError as error:
            older = [p for _, p in checkpoints_by_step(checkpoints)][:-1]
            advice = (f"; move it away to resume from {older[-1].name}" if older else
                      "; run again without --resume to start over")
            _fail(f"--resume: {error}{advice}")
        record = run_record(saved)
        stored = _stored_scene(record["scene"]) if "scene" in record else None
        if stored is not None:
            changed = _scene_differences(chosen, stored)
            if changed and not force_resume:
                shown = "; ".join(changed[:3]) + (f"; and {len(changed) - 3} more"
                                                  if len(changed) > 3 else "")
                _fail(f"--resume: the scene differs from the one {checkpoint} was saved with "
                      f"({shown}); pass --force-resume to continue from it anyway, or run "
                      "again without --resume")
            # The resumed run writes what the first one wrote, unless told otherwise now.
            chosen = chosen.model_copy(update={"outputs": stored.outputs})
        saved_options = record.get("options", {})
        options = {**{k: v for k, v in saved_options.items() if k != "steps"}, **given}
    chosen = apply_output_overrides(chosen, **given)
    try:
        # The scene's own length is checked even when --steps replaces it.
        scene_steps = step_count(chosen)
        total = steps if steps is not None else scene_steps
    except SceneError as error:
        _fail(str(error).splitlines())
    simulation = _build(chosen, total)
    folder_option = "--out" if out is not None else "output folder"
    _output_folder(out_dir, folder_option)
    try:
        lock = lock_output_folder(out_dir)
        removed = remove_temporaries(out_dir)
    except OutputFolderBusy:
        _fail(f"{folder_option} = {str(out_dir)!r}: another elastoflow run is writing there; "
              "wait for it to end or choose another folder")
    except OSError as error:
        _fail(f"{folder_option} = {str(out_dir)!r}: cannot write there "
              f"({error.strerror or error}); choose a writable folder")
    stop = _StopRequest()
    try:
        if removed:
            typer.echo(f"removed {len(removed)} temporary files left by an interrupted run",
                       err=True)

        if checkpoint is not None:
            try:
                load_checkpoint(checkpoint, simulation, saved)
            except CheckpointError as error:
                _fail(f"--resume: {error}; run again without --resume to start over")
            typer.echo(f"resuming from {checkpoint} (step {simulation.step_index}, "
                       f"t = {simulation.time:.4g} s)")
        else:
            earlier = checkpoints_by_step(checkpoints)
            if earlier and not overwrite:
                _fail(f"{folder_option} = {str(out_dir)!r} holds checkpoints of an earlier run (the "
                      f"newest at step {earlier[-1][0]}); continue it with --resume, choose "
                      "another --out, or pass --overwrite to delete them and start over")
            for _, path in earlier:
                path.unlink()
        if simulation.step_index >= total:
            typer.echo(f"nothing to do: already at step {simulation.step_index} of {total}")
            return

        resume_words = ["elastoflow", "run", scene, "--out", str(out_dir), "--resume", "--steps",
                        str(total), *_option_words(options)]
        resume_command = " ".join(shlex.quote(word) for word in resume_words)
        run_info = {"scene": scene_to_toml(chosen),
                    "options": json.dumps({**options, "steps": total})}
        if "video_range" in (saved_record := run_record(saved)):
            run_info["video_range"] = saved_record["video_range"]
        compiling = _compile_notice(quiet)
        try:
            with compiling:
                session = OutputSession(chosen, simulation, out_dir, resumed=checkpoint is not None,
                                        run=run_info)
        except OSError as error:
            _fail(f"--out = {str(out_dir)!r}: cannot write the outputs there "
                  f"({error.strerror or error}: {error.filename or ''})")
        failure: BaseException | None = None
        unfinished: OSError | None = None
        stopped = False
        mid_step = False
        written: list[Path] = []
        try:
            with stop:
                _step_loop(simulation, session, total, stop, quiet, compiling)
                stopped = stop.requested
        except KeyboardInterrupt:
            stopped = mid_step = True
        except Exception as error:  # noqa: BLE001 - reported with its step, then exit 1
            failure = error
        finally:
            # A failed or hard-interrupted step may leave a half-updated state: go back to the
            # last step whose outputs were all written, and save that.
            recovered = (failure is not None or mid_step) and session.recover()
            try:
                written = session.close(final_checkpoint=failure is None or recovered,
                                        failed=failure is not None or mid_step,
                                        stopped=stopped)
            except OSError as error:
                # A full or read-only file system: say so instead of a traceback.
                unfinished = error

        if session.video_note:
            typer.echo(f"note: {session.video_note}", err=True)
        for path in written:
            typer.echo(f"wrote {path}")
        problems = []
        if failure is not None:
            where = f"step {simulation.step_index + 1} (t = {simulation.time:.6g} s)"
            message = str(failure)
            if not message.startswith("step"):
                message = f"{where}: {type(failure).__name__}: {message}"
            problems.append(f"run failed at {message}")
        if unfinished is not None:
            problems.append(f"cannot finish the outputs in {out_dir} after step "
                            f"{simulation.step_index}: {unfinished.strerror or unfinished}"
                            + (f" ({unfinished.filename})" if unfinished.filename else ""))
        if problems:
            for line in problems:
                typer.echo(f"error: {line}", err=True)
            last = session.last_checkpoint or find_resume_checkpoint(out_dir)
            if last is not None:
                hint = "" if isinstance(failure, OSError | None) else (
                    " (after changing the scene, add --force-resume)")
                typer.echo(f"note: the last good state is saved in {last}; resume with{hint}:\n"
                           f"  {resume_command}", err=True)
            raise typer.Exit(EXIT_RUN_FAILED)
        if stopped:
            typer.echo(f"stopped at step {simulation.step_index} of {total}; resume with:\n"
                       f"  {resume_command}")
            raise typer.Exit(130)
    finally:
        stop.release()
        # Also on exit 2 below: a run in process (tests) must not keep the folder locked.
        lock.close()


class _CompileNotice:
    """Says, before the wait, that the kernels are being compiled (no disk cache yet), and
    shows a spinner while the first frame and the first step run."""

    def __init__(self, active: bool, quiet: bool) -> None:
        self.active = active
        self._status: Any = None
        if active and not quiet:
            from rich.console import Console

            console = Console(stderr=True)
            message = ("compiling kernels (first run, about a minute; `elastoflow warmup` does "
                       "it ahead)...")
            if console.is_terminal:
                self._status = console.status(message, spinner="dots")
            else:
                typer.echo(message, err=True)

    def __enter__(self) -> Self:
        if self._status is not None:
            self._status.start()
        return self

    def __exit__(self, *exc: object) -> None:
        pass

    def done(self) -> None:
        """The compiling is over (the first step has run): stop the spinner."""
        if self._status is not None:
            self._status.stop()
            self._status = None
        self.active = False


def _compile_notice(quiet: bool) -> _CompileNotice:
    from elastoflow._warmup import kernels_need_compiling

    return _CompileNotice(kernels_need_compiling(), quiet)


def _step_loop(simulation: Any, session: Any, total: int, stop: _StopRequest, quiet: bool,
               compiling: _CompileNotice | None = None) -> None:
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    if compiling is not None and compiling.active:
        try:
            # The first step compiles what the first frame did not, under the spinner.
            report = simulation.step()
            session.after_step(simulation, report)
        finally:
            compiling.done()
    start = simulation.step_index
    progress = Progress(
        TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
        TextColumn("{task.fields[rate]:.2f} steps/s"), TimeElapsedColumn(), TextColumn("ETA"),
        TimeRemainingColumn(), disable=quiet,
    )
    began = _time.perf_counter()
    with progress:
        task = progress.add_task("steps", total=total, completed=start, rate=0.0)
        while simulation.step_index < total and not stop.requested:
            report = simulation.step()
            session.after_step(simulation, report)
            done = simulation.step_index - start
            progress.update(task, completed=simulation.step_index,
                            rate=done / max(_time.perf_counter() - began, 1e-9))


@app.command("list")
def list_command() -> None:
    """List the built-in scenes."""
    from rich.console import Console
    from rich.table import Table

    from elastoflow.scenes import list_scenes

    table = Table("scene", "description")
    for name, summary in list_scenes().items():
        table.add_row(name, summary)
    Console().print(table)


@app.command()
def validate(
    scene: Annotated[str, typer.Argument(help="Scene TOML file (or built-in name), or a "
                                         "benchmark: turek-hron, perpendicular-flap, "
                                         "dfg-2d-2, dfg-2d-1, boundary-study, "
                                         "force-smoothness.")],
    case: Annotated[str | None, typer.Argument(help="The benchmark's case: CFD1-3, CSM1-3, "
                                               "FSI1-3 (turek-hron); the study's part, "
                                               "default all (boundary-study: poisson, "
                                               "leakage, spurious, force_jump, dfg, "
                                               "speed, stability; force-smoothness: disc, "
                                               "flap10, flap20, fsi2, refinement).")
                    ] = None,
    resolution: Annotated[int, typer.Option(help="Benchmark: about this many cells per "
                                            "cylinder diameter (turek-hron) or metre "
                                            "(perpendicular-flap), 5-200; cells per diameter, "
                                            "4-160 (dfg-2d-2, dfg-2d-1).")] = 20,
    duration: Annotated[float | None, typer.Option(help="Benchmark: simulated time [s] "
                                                   "(default: the case's).")] = None,
    dt: Annotated[float | None, typer.Option(help="Benchmark: time step [s] (default: CFL "
                                             "0.5 on the inflow peak).")] = None,
    scheme: Annotated[str, typer.Option(help="Benchmark: coupling scheme, monolithic or "
                                        "explicit.")] = "monolithic",
    boundary: Annotated[str, typer.Option(help="Benchmark: how the fluid sees the bodies, "
                                          "cut_cell, dual_cell or staircase.")] = "cut_cell",
    out: Annotated[Path, typer.Option("--out", help="Benchmark: folder for the CSV and PNG.")]
    = Path("out/validation"),
    json_file: Annotated[bool, typer.Option("--json", help="Benchmark: also write the "
                                            "quantities as JSON.")] = False,
    advection: Annotated[str, typer.Option(
        help="dfg-2d-1, dfg-2d-2: the fluid's advection scheme, maccormack, "
             "semi_lagrangian or upwind3 (flux form).")] = "maccormack",
    advecting_velocity: Annotated[str, typer.Option(
        help="dfg-2d-1, dfg-2d-2: the back-trace's velocity, current or extrapolated (to "
             "mid-step, second order in time).")] = "current",
    viscosity_scheme: Annotated[str, typer.Option(
        help="dfg-2d-1, dfg-2d-2: the viscosity's time discretization, backward_euler, "
             "crank_nicolson, or bdf2 (the whole step by BDF2 along trajectories).")
    ] = "backward_euler",
    incremental_pressure: Annotated[bool, typer.Option(
        "--incremental-pressure",
        help="dfg-2d-1, dfg-2d-2, turek-hron (CFD and FSI cases), perpendicular-flap: "
             "solve for the pressure increment.")] = False,
) -> None:
    """Check a scene, or run a published benchmark.

    A scene: builds everything a run builds (memory estimate, meshes, obstacles, constraints,
    geometry checks) short of stepping; prints one line per problem (exit 2) or a summary
    (exit 0); warnings go to stderr.

    A benchmark (``elastoflow validate turek-hron FSI3 --resolution 20``, ``elastoflow
    validate perpendicular-flap``): runs the case in its exact geometry, prints its quantities in the benchmark's format (periodic: mean ± amplitude
    [frequency] over the last period), writes the time series (CSV) and plots (PNG) to --out.

    The boundary study (``elastoflow validate boundary-study --out docs/validation``): the
    boundary map against the staircase boundary (issue 13); prints each part's table and
    rewrites its block of ``boundary_study.md`` and its files in ``boundary_study/``.
    """
    from elastoflow.scenes import SceneError, memory_estimate, step_count, time_step
    from elastoflow.validation import BENCHMARKS

    if scene == "dfg-2d-2":
        _dfg_benchmark(case, resolution, duration, dt, advection, out, json_file,
                       advecting_velocity, viscosity_scheme, incremental_pressure)
        return
    if scene == "dfg-2d-1":
        _dfg_steady_benchmark(case, resolution, duration, dt, advection, out, json_file,
                              advecting_velocity, viscosity_scheme, incremental_pressure)
        return
    if incremental_pressure and scene not in ("dfg-2d-1", "dfg-2d-2", *BENCHMARKS):
        _fail(f"--incremental-pressure: {scene} takes no such option (it is for the "
              "benchmarks dfg-2d-1, dfg-2d-2, turek-hron and perpendicular-flap; a scene "
              "file sets fluid.incremental_pressure)")
    if scene == "boundary-study":
        _boundary_study(case, out)
        return
    if scene == "force-smoothness":
        _force_smoothness(case, out)
        return
    if scene in BENCHMARKS:
        _benchmark(scene, case, resolution, duration, dt, scheme, out, json_file, boundary,
                   incremental_pressure)
        return
    if case is not None:
        _fail(f"{case!r}: a scene takes no case (benchmarks: {', '.join(BENCHMARKS)})")
    chosen = _scene(scene)
    try:
        dt, steps = time_step(chosen), step_count(chosen)
    except SceneError as error:
        _fail(str(error).splitlines())
    simulation = _build(chosen, steps)
    cells = "x".join(str(count) for count in chosen.domain.cells)
    if simulation.dimension == 3:
        elements = sum(body.mesh.tetrahedron_count for body in simulation.bodies)
        segments = 0
    else:
        elements = sum(body.mesh.triangle_count for body in simulation.bodies)
        # Rods have segments, not triangles: count them apart so a rod scene is not "0
        # elements".
        segments = sum(body.point_count - 1 for body in simulation.bodies
                       if body.mesh.triangle_count == 0)
    parts = f"{elements} elements" + (f", {segments} rod segments" if segments else "")
    memory = memory_estimate(chosen)[0] / 2**20
    typer.echo(f"ok: {chosen.name}: {cells} cells, {len(chosen.bodies)} bodies "
               f"({parts}), {len(chosen.obstacles)} obstacles, dt = {dt:.4g} s, "
               f"{steps} steps, about {memory:.0f} MB of memory")


def _benchmark(name: str, case: str | None, resolution: int, duration: float | None,
               dt: float | None, scheme: str, out: Path, json_file: bool,
               boundary: str = "cut_cell", incremental_pressure: bool = False) -> None:
    """Run one case of a published benchmark with a progress bar; print and write its results."""
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    from elastoflow.simulation import SimulationBlowUp
    from elastoflow.solid import SolidInversionError
    from elastoflow.validation import (
        CASES,
        check_resolution,
        default_setup,
        flap_setup,
        get_case,
        run_case,
        run_flap,
    )
    from elastoflow.validation import describe, format_quantities, write_report

    try:
        if name == "perpendicular-flap":
            if case is not None:
                _fail(f"{case!r}: the perpendicular flap has one case (leave it out)")
            setup = flap_setup(resolution, duration=duration, dt=dt, scheme=scheme,
                               boundary=boundary, incremental_pressure=incremental_pressure)
            title = "flap"

            def run(progress: Any) -> Any:
                return run_flap(resolution, duration=setup.duration, dt=setup.dt,
                                scheme=scheme, progress=progress, boundary=boundary,
                                incremental_pressure=incremental_pressure)
        else:
            if case is None:
                _fail(f"{name}: name the case ({', '.join(CASES)})")
            chosen = get_case(case)
            check_resolution(resolution)
            setup = default_setup(chosen, resolution, duration=duration, dt=dt, scheme=scheme,
                                  boundary=boundary, incremental_pressure=incremental_pressure)
            title = chosen.name

            def run(progress: Any) -> Any:
                return run_case(chosen.name, resolution, duration=setup.duration, dt=setup.dt,
                                scheme=scheme, progress=progress, boundary=boundary,
                                incremental_pressure=incremental_pressure)
    except ValueError as error:
        _fail(str(error))
    _output_folder(out, "--out")
    columns = (TextColumn(f"{title} N={resolution}"), BarColumn(),
               TextColumn("{task.completed}/{task.total}"), TimeRemainingColumn())
    with Progress(*columns, transient=True, disable=not sys.stderr.isatty()) as progress:
        task = progress.add_task("run", total=setup.steps)
        try:
            result = run(lambda done, total: progress.update(task, completed=done, total=total))
        except (SimulationBlowUp, SolidInversionError) as error:
            _fail(f"{title} failed: {error}", EXIT_RUN_FAILED)
    _report_benchmark(describe(result), format_quantities(result),
                      lambda: write_report(result, out, json_file=json_file), out,
                      result.failure is not None)


def _dfg_benchmark(case: str | None, resolution: int, duration: float | None,
                   dt: float | None, advection: str, out: Path, json_file: bool,
                   advecting_velocity: str = "current",
                   viscosity_scheme: str = "backward_euler",
                   incremental_pressure: bool = False) -> None:
    """DFG 2D-2: run it, print its quantities against the published bounds, write the report.
    Exit 1 when the run blew up or was not periodic yet."""
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    from elastoflow.validation import dfg_setup, run_dfg, write_dfg_report
    from elastoflow.validation._dfg import describe, format_quantities

    if case is not None:
        _fail(f"{case!r}: DFG 2D-2 has one case (leave it out)")
    try:
        setup = dfg_setup(resolution, duration=duration, dt=dt, advection=advection,
                          incremental_pressure=incremental_pressure,
                          advecting_velocity=advecting_velocity,
                          viscosity_scheme=viscosity_scheme)
    except ValueError as error:
        _fail(str(error))
    _output_folder(out, "--out")
    columns = (TextColumn(f"DFG 2D-2 N={resolution}"), BarColumn(),
               TextColumn("{task.completed}/{task.total}"), TimeRemainingColumn())
    with Progress(*columns, transient=True, disable=not sys.stderr.isatty()) as progress:
        task = progress.add_task("run", total=setup.steps)
        result = run_dfg(resolution, duration=setup.duration, dt=setup.dt, advection=advection,
                         incremental_pressure=incremental_pressure,
                         advecting_velocity=advecting_velocity,
                         viscosity_scheme=viscosity_scheme,
                         progress=lambda done, total: progress.update(task, completed=done))
    _report_benchmark(describe(result), format_quantities(result),
                      lambda: write_dfg_report(result, out, json_file=json_file), out,
                      result.failure is not None)


def _dfg_steady_benchmark(case: str | None, resolution: int, duration: float | None,
                          dt: float | None, advection: str, out: Path, json_file: bool,
                          advecting_velocity: str, viscosity_scheme: str,
                          incremental_pressure: bool) -> None:
    """DFG 2D-1 through the unsteady step: run it, print its steady quantities against the
    reference and the bounds, write the report. Exit 1 when the run blew up."""
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    from elastoflow.validation import run_dfg_steady
    from elastoflow.validation._dfg import STEADY_PEAK_SPEED, dfg_setup
    from elastoflow.validation._dfg_steady import (
        STEADY_WINDOW,
        describe_steady,
        format_steady,
        write_dfg_steady_report,
    )

    if case is not None:
        _fail(f"{case!r}: DFG 2D-1 has one case (leave it out)")
    duration = 5.0 if duration is None else duration
    if not duration >= 2.0 * STEADY_WINDOW:
        _fail(f"--duration = {duration!r}: must be >= {2.0 * STEADY_WINDOW:g} s for DFG 2D-1 "
              f"(its quantities are the means over the last {STEADY_WINDOW:g} s)")
    try:
        setup = dfg_setup(resolution, duration=duration, dt=dt, advection=advection,
                          incremental_pressure=incremental_pressure,
                          advecting_velocity=advecting_velocity,
                          viscosity_scheme=viscosity_scheme, kick=0.0,
                          peak_speed=STEADY_PEAK_SPEED)
    except ValueError as error:
        _fail(str(error))
    _output_folder(out, "--out")
    columns = (TextColumn(f"DFG 2D-1 N={resolution}"), BarColumn(),
               TextColumn("{task.completed}/{task.total}"), TimeRemainingColumn())
    with Progress(*columns, transient=True, disable=not sys.stderr.isatty()) as progress:
        task = progress.add_task("run", total=setup.steps)
        result = run_dfg_steady(
            resolution, duration=setup.duration, dt=setup.dt, advection=advection,
            incremental_pressure=incremental_pressure, advecting_velocity=advecting_velocity,
            viscosity_scheme=viscosity_scheme,
            progress=lambda done, total: progress.update(task, completed=done))
    _report_benchmark(describe_steady(result), format_steady(result),
                      lambda: write_dfg_steady_report(result, out, json_file=json_file), out,
                      result.failure is not None)


def _force_smoothness(case: str | None, out: Path) -> None:
    """Issue 12's force smoothness: every case (or the one named) with the cut-cell and the
    dual-cell boundary; print the table and write the report."""
    from elastoflow.validation._force_smoothness import (
        CASES,
        disc_refinement,
        force_smoothness_table,
        refinement_table,
        run_force_smoothness,
        write_force_smoothness_report,
        write_refinement_report,
    )

    if case is not None and case not in (*CASES, "refinement"):
        _fail(f"{case!r}: the force-smoothness cases are {', '.join(CASES)}, refinement")
    _output_folder(out, "--out")
    if case == "refinement":
        runs = disc_refinement()
        for line in refinement_table(runs):
            typer.echo(line)
        typer.echo(f"wrote {write_refinement_report(runs, out)}")
        return
    study = run_force_smoothness(CASES if case is None else (case,))
    for line in force_smoothness_table(study):
        typer.echo(line)
    for path in write_force_smoothness_report(study, out):
        typer.echo(f"wrote {path}")


def _boundary_study(part: str | None, out: Path) -> None:
    """Run the boundary study's parts (all, or the one named), print and write each."""
    from elastoflow.validation import (
        STUDY_PARTS,
        run_leakage_study,
        run_poisson_study,
        write_leakage_report,
        write_poisson_report,
    )
    from elastoflow.validation._boundary_study import (
        dfg_table,
        force_jump_lines,
        poisson_table,
        run_dfg_study,
        run_force_jump_study,
        run_spurious_study,
        spurious_table,
        write_dfg_study_report,
        write_force_jump_report,
        write_spurious_report,
    )
    from elastoflow.validation._boundary_speed import (
        run_speed_study,
        run_stability_study,
        speed_lines,
        stability_lines,
        write_speed_report,
        write_stability_report,
    )
    from elastoflow.validation._leakage_study import leakage_table

    if part is not None and part not in STUDY_PARTS:
        _fail(f"{part!r}: the boundary study's parts are {', '.join(STUDY_PARTS)}")
    _output_folder(out, "--out")
    def poisson_lines(study: Any) -> list[str]:
        orders = ", ".join(f"{name} {study.order(name):.2f}" for name in study.treatments)
        return [*poisson_table(study), f"observed order: {orders}"]

    # Each part: what it measures, how to run it, its printed lines, its writer.
    parts: dict[str, tuple[str, Callable[[], Any], Callable[[Any], list[str]],
                           Callable[[Any, Path], list[Path]]]] = {
        "poisson": ("accuracy: -lap u = f on a disk, du/dn = 0", run_poisson_study,
                    poisson_lines, write_poisson_report),
        "leakage": ("leakage: flux through a moving plate / (V H), worst offset",
                    run_leakage_study, leakage_table, write_leakage_report),
        "spurious": ("spurious velocities: a fixed body in water at rest", run_spurious_study,
                     spurious_table, write_spurious_report),
        "force_jump": ("force smoothness: a disc moving slowly across the grid",
                       run_force_jump_study, force_jump_lines, write_force_jump_report),
        "dfg": ("DFG 2D-1: c_D and c_L against resolution", run_dfg_study, dfg_table,
                write_dfg_study_report),
        "speed": ("speed: map, interiors and brute force against edges and grid; whole steps",
                  run_speed_study, speed_lines, write_speed_report),
        "stability": ("stability: the bar in a jet's largest dt and lowest density ratio",
                      run_stability_study, stability_lines, write_stability_report),
    }
    for name in STUDY_PARTS:
        if part not in (None, name):
            continue
        title, run, lines, write = parts[name]
        result = run()
        _report_benchmark(f"boundary study, {title} ({result.seconds:.1f} s)", lines(result),
                          functools.partial(write, result, out), out, False)


def _report_benchmark(title: str, quantities: list[str], write: Callable[[], list[Path]],
                      out: Path, failed: bool) -> None:
    """Print a benchmark run's summary and quantities, write its files (one line if the
    folder refuses them); exit 1 when the run did not finish as a valid result."""
    typer.echo(title)
    for line in quantities:
        typer.echo(f"  {line}")
    try:
        paths = write()
    except OSError as error:
        _fail(f"--out = {str(out)!r}: cannot write ({error.strerror or error})")
    typer.echo("wrote " + ", ".join(str(path) for path in paths))
    if failed:
        raise typer.Exit(EXIT_RUN_FAILED)


@app.command()
def dump(
    scene: Annotated[str, typer.Argument(help="Built-in scene name.")],
    output: Annotated[Path | None, typer.Option("--output", "-o", help="File to write "
                                                "(default: print).")] = None,
) -> None:
    """Write a built-in scene as TOML, a starting point for your own."""
    from elastoflow.io import write_text_atomic
    from elastoflow.scenes import scene_to_toml

    text = scene_to_toml(_scene(scene))
    if output is None:
        typer.echo(text, nl=False)
    else:
        if output.is_dir():
            _fail(f"--output = {str(output)!r}: is a folder; must name a file")
        try:
            write_text_atomic(output, text)
        except OSError as error:
            _fail(f"--output = {str(output)!r}: cannot write it ({error.strerror or error})")
        typer.echo(f"wrote {output}")


@app.command()
def view(
    scene: Annotated[str, typer.Argument(help="Built-in scene name or scene TOML file.")],
    scale: Annotated[int | None, typer.Option(help="Pixels per cell.", min=1)] = None,
) -> None:
    """Interactive window: left-drag pushes the fluid, right-drag grabs a body node.

    Keys: space pause, s single step, r reset, v cycle view, p screenshot, q/esc quit.
    A 3D scene shows a slice and a 3D view: x/y/z turn the slice, Up/Down or the wheel move
    it a cell, PageUp/PageDown an eighth of the domain, h help; left-drag on the slice
    pushes the fluid, on the 3D view turns it (no grabbing of body nodes in 3D).
    """
    from elastoflow.scenes import SceneError

    chosen = _scene(scene)
    try:
        from elastoflow.viewer import run_viewer
    except ImportError as error:
        _fail(f"the viewer needs pygame-ce (pip install 'elastoflow[viewer]'): {error}")
    try:
        run_viewer(chosen, scale=scale)
    except SceneError as error:
        _fail(str(error).splitlines())


@app.command()
def render(
    out_dir: Annotated[Path, typer.Argument(help="Output folder of a run with npz fields.")],
    view: Annotated[str, typer.Option(help="speed, vorticity, pressure or dye.")] = "speed",
    fps: Annotated[int, typer.Option(min=1)] = 30,
    output: Annotated[Path | None, typer.Option("--output", "-o", help="Video file (default "
                                                "OUT_DIR/render_<view>.mp4).")] = None,
) -> None:
    """Render a video again from the saved field snapshots (fields/step_*.npz)."""
    from elastoflow.render import VIEWS
    from elastoflow.render._replay import render_saved_frames

    if view not in VIEWS:
        _fail(f"--view = {view!r}: must be one of {', '.join(VIEWS)}")
    folder = out_dir / "fields"
    if not any(folder.glob("step_*.npz")):
        _fail(f"{folder}: no step_*.npz snapshots (run with --fields npz)")
    target = output if output is not None else out_dir / f"render_{view}.mp4"
    if target.is_dir():
        _fail(f"--output = {str(target)!r}: is a folder; must name a video file")
    try:
        written, count = render_saved_frames(folder, target, view=view, fps=fps)
    except ValueError as error:
        _fail(str(error))
    except OSError as error:
        _fail(f"cannot write {target} ({error.strerror or error})")
    typer.echo(f"wrote {written} ({count} frames)")


@app.command()
def bench(
    scene: Annotated[str | None, typer.Argument(help="Time this scene's steps instead of the "
                                                "benchmark suite.")] = None,
    steps: Annotated[int, typer.Option(min=1, help="Steps to time (scene timing).")] = 20,
) -> None:
    """Run the benchmark suite (python -m benchmarks), or time the steps of one scene."""
    import importlib.util
    import subprocess

    if scene is None and importlib.util.find_spec("benchmarks") is not None:
        raise typer.Exit(subprocess.call([sys.executable, "-m", "benchmarks"]))
    chosen = _scene(scene or "bar_in_jet")
    simulation = _build(chosen, steps + 1)
    simulation.step()  # compile the kernels outside the timing
    began = _time.perf_counter()
    phases: dict[str, float] = {}
    for _ in range(steps):
        report = simulation.step()
        for phase, seconds in report.seconds_by_phase.items():
            phases[phase] = phases.get(phase, 0.0) + seconds
    elapsed = _time.perf_counter() - began
    nx, ny = chosen.domain.cells
    typer.echo(f"{chosen.name}: {nx}x{ny}, {steps} steps in {elapsed:.3f} s = "
               f"{steps / elapsed:.2f} steps/s")
    for phase, seconds in sorted(phases.items(), key=lambda item: -item[1]):
        typer.echo(f"  {phase:<16} {1000 * seconds / steps:8.2f} ms/step")


@app.command()
def warmup(
    scenes: Annotated[list[str] | None, typer.Argument(help="Built-in scenes (default: all).")]
    = None,
) -> None:
    """Compile the kernels into Numba's disk cache now (~1 min once), so runs start at once."""
    from elastoflow._warmup import warm_up
    from elastoflow.scenes import SceneError, list_scenes

    known = list_scenes()
    unknown = [name for name in scenes or [] if name not in known]
    if unknown:
        _fail([f"scene = {name!r}: unknown scene name (built-in scenes: {', '.join(known)})"
               for name in unknown])
    try:
        total = warm_up(scenes or None,
                        report=lambda name, seconds: typer.echo(f"  {name:<14} {seconds:6.1f} s"))
    except SceneError as error:
        _fail(str(error).splitlines())
    typer.echo(f"kernels compiled and cached in {total:.1f} s")


app.command("sweep")(sweep_command)


def main() -> None:
    """Entry point of the ``elastoflow`` command."""
    app()


if __name__ == "__main__":
    main()
