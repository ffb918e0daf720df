"""``elastoflow sweep SWEEP.toml``: the command (registered in `elastoflow.cli`).

Exit codes as for ``run``: 0 every point done, 2 bad input (one line per problem or bad point),
1 points failed or were lost (the summary says which and why), 130 stopped by Ctrl-C.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated, Any, NoReturn

import typer

_EXIT_BAD_INPUT = 2
_EXIT_FAILED = 1
_EXIT_STOPPED = 130


def _fail(lines: list[str], code: int = _EXIT_BAD_INPUT) -> NoReturn:
    for line in lines:
        typer.echo(f"error: {line}", err=True)
    raise typer.Exit(code)


class _ProgressLine:
    """One line for the sweep: rewritten in place on a terminal, else printed on change."""

    def __init__(self, quiet: bool) -> None:
        self.quiet = quiet
        self.tty = sys.stderr.isatty()
        self.last = ""

    def __call__(self, progress: Any) -> None:
        if self.quiet:
            return
        line = progress.line()
        counts = line.split(" elapsed")[0]
        if self.tty:
            sys.stderr.write("\r\x1b[2K" + line)
            sys.stderr.flush()
        elif counts != self.last.split(" elapsed")[0]:
            typer.echo(line, err=True)
        self.last = line

    def end(self) -> None:
        if self.tty and self.last and not self.quiet:
            sys.stderr.write("\n")


def _resume_command(sweep_file: Path, out: Path | None, scheduler: str | None,
                    workers: int | None, dashboard: bool, quiet: bool) -> str:
    """The command that runs the same sweep again on the same kind of cluster (no
    ``--retry-failed``: a rerun after Ctrl-C only resumes)."""
    import shlex

    words = ["elastoflow", "sweep", str(sweep_file)]
    if out is not None:
        words += ["--out", str(out)]
    if scheduler is not None:
        words += ["--scheduler", scheduler]
    if workers is not None:
        words += ["--workers", str(workers)]
    if not dashboard:
        words.append("--no-dashboard")
    if quiet:
        words.append("--quiet")
    return " ".join(shlex.quote(word) for word in words)


def sweep_command(
    sweep_file: Annotated[Path, typer.Argument(help="Sweep TOML file (docs/sweeps.md).")],
    out: Annotated[Path | None, typer.Option(help="Sweep folder (default out/<sweep name>).")]
    = None,
    scheduler: Annotated[str | None, typer.Option(help="Address (tcp://host:8786) or "
                                                  "scheduler file of a running Dask cluster; "
                                                  "default: a local cluster.")] = None,
    workers: Annotated[int | None, typer.Option(help="Local cluster: worker processes "
                                                "(default one per core).", min=1)] = None,
    retry_failed: Annotated[bool, typer.Option(help="Run again the points that failed "
                                               "before.")] = False,
    check: Annotated[bool, typer.Option(help="Only check every point and list them.")] = False,
    dashboard: Annotated[bool, typer.Option("--dashboard/--no-dashboard", help="Local cluster: "
                                            "serve Dask's dashboard.")] = True,
    quiet: Annotated[bool, typer.Option(help="No progress line.")] = False,
) -> None:
    """Run a parameter sweep on Dask: every point of SWEEP_FILE, one output folder each, a
    summary table (summary.parquet) and optionally the fields of all points (fields.zarr).

    Every point is checked before anything runs. Points already finished in the folder are
    skipped, so running the same sweep again goes on where it stopped. Ctrl-C stops; run the
    same command again to resume.
    """
    from elastoflow.io import folder_name
    from elastoflow.sweep import (
        SweepError,
        load_sweep,
        open_client,
        plan_sweep,
        prepare_folder,
        run_sweep,
    )

    try:
        spec = load_sweep(sweep_file)
        plan = plan_sweep(spec)
    except SweepError as error:
        _fail(str(error).splitlines())
    for line in plan.warnings:
        typer.echo(f"warning: {line}", err=True)
    # A name from a sweep file never leads out of out/ ("../../x" becomes out/x).
    folder = out if out is not None else Path("out") / folder_name(spec.name)
    option = "--out" if out is not None else "output folder"
    if check:
        for point in plan.points:
            typer.echo(f"  {point.describe()}: {point.steps} steps")
        typer.echo(f"ok: {spec.name}: {len(plan.points)} points")
        return
    try:
        prepare_folder(plan, folder, sweep_file.read_text(encoding="utf-8"))
    except SweepError as error:
        _fail(str(error).splitlines())
    except OSError as error:
        _fail([f"{option} = {str(folder)!r}: cannot write there ({error.strerror or error})"])
    typer.echo(f"sweep {spec.name}: {len(plan.points)} points -> {folder}")
    progress_line = _ProgressLine(quiet)
    resume = _resume_command(sweep_file, out, scheduler, workers, dashboard, quiet)
    unwritable: OSError | None = None
    try:
        with open_client(scheduler, workers=workers, dashboard=dashboard) as client:
            workers_now = len(client.nthreads())
            link = client.dashboard_link if scheduler is not None or dashboard else "off"
            typer.echo(f"dask: {client.scheduler.address}, {workers_now} workers, "
                       f"dashboard {link}")
            try:
                outcome = run_sweep(plan, folder, client, retry_failed=retry_failed,
                                    on_progress=progress_line)
            except OSError as error:
                # A full or read-only disk under the summary or the Zarr store.
                unwritable = error
    except KeyboardInterrupt:
        # Ctrl-C while the cluster starts or closes: the points' folders are as they were.
        progress_line.end()
        typer.echo(f"stopped; resume with:\n  {resume}")
        raise typer.Exit(_EXIT_STOPPED) from None
    except (OSError, TimeoutError) as error:
        progress_line.end()
        _fail([f"--scheduler = {scheduler!r}: cannot reach it ({error})"] if scheduler else
              [f"cannot start the local Dask cluster: {error}"], _EXIT_FAILED)
    progress_line.end()
    if unwritable is not None:
        where = f" ({unwritable.filename})" if unwritable.filename else ""
        _fail([f"cannot write the sweep's results in {folder}: "
               f"{unwritable.strerror or unwritable}{where}; the finished points are kept: "
               f"once the disk is writable, resume with: {resume}"], _EXIT_FAILED)
    for line in outcome.warnings:
        typer.echo(f"warning: {line}", err=True)
    typer.echo(f"wrote {outcome.summary}")
    if outcome.zarr is not None:
        typer.echo(f"wrote {outcome.zarr}")
    progress = outcome.progress
    typer.echo(f"{progress.skipped + progress.done} of {progress.total} points done, "
               f"{progress.failed} failed, {progress.lost} lost")
    if outcome.stopped:
        typer.echo(f"stopped; resume with:\n  {resume}")
        raise typer.Exit(_EXIT_STOPPED)
    if outcome.failed_points:
        shown = outcome.failed_points[:10]
        more = len(outcome.failed_points) - len(shown)
        _fail([*shown, *([f"... and {more} more (see the summary)"] if more else [])],
              _EXIT_FAILED)

