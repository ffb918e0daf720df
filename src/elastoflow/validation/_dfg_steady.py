"""DFG 2D-1 (Schäfer & Turek 1996): steady flow past the DFG 2D-2 cylinder at Re = 20.

The same channel, cylinder, fluid and run as `elastoflow.validation.run_dfg` (the fluid
solver's own phases, the cylinder a static obstacle in the boundary map), with the inflow's
peak at 0.3 m/s (mean U = 0.2 m/s) and no start-up kick. The flow starts as the inflow's
Poiseuille profile and settles to its steady state within about 3 s; the quantities are the
means over the last 0.5 s of the run: ``c_D`` and ``c_L`` by the traction integral, ``c_D``
by the control-volume balance (a box of whole cells that no cut cell enters), the traction's
pressure part, and ``Δp = p(0.15, 0.2) - p(0.25, 0.2)``, against the fine reference values
of ../shared/reference/dfg_cylinder.json and the published bounds.

What it is for: a steady flow through the unsteady path shows what the time discretization
does to a steady state. Backward Euler along trajectories (the paper's step) has a steady
state that depends on dt; the BDF2 step's converges in dt at about second order
(docs/validation/unsteady.md, "DFG 2D-1 through the unsteady step").
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from elastoflow.validation._dfg import (
    STEADY_PEAK_SPEED,
    DfgSetup,
    Progress,
    dfg_setup,
    setup_record,
    step_series,
)

# ../shared/reference/dfg_cylinder.json, "2D-1": the fine reference (FEAT3) and the bounds
# the 1996 paper required of the participating codes' best results.
STEADY_REFERENCE: dict[str, float] = {
    "drag": 5.57953523384,
    "lift": 0.010618948146,
    "delta_p": 0.11752016697,
}
STEADY_BOUNDS: dict[str, tuple[float, float]] = {
    "drag": (5.57, 5.59),
    "lift": (0.0104, 0.0110),
    "delta_p": (0.1172, 0.1176),
}
STEADY_LABELS = {"drag": "c_D", "lift": "c_L", "delta_p": "Δp [Pa]",
                 "drag_cv": "c_D (control volume)", "lift_cv": "c_L (control volume)",
                 "drag_pressure": "c_D pressure part"}
# Quantities read by the control-volume balance, and the traction quantity each stands for.
_BALANCE_OF = {"drag_cv": "drag", "lift_cv": "lift"}
# The window the steady quantities are averaged over, at the end of the run [s].
STEADY_WINDOW = 0.5


@dataclass
class DfgSteadyResult:
    """A DFG 2D-1 run: time series and its steady quantities.

    Attributes:
        setup: What it was run with (``setup.peak_speed`` is 0.3 m/s).
        time: Sample times [s], one per step.
        series: As `DfgResult.series`, coefficients on U = 0.2 m/s.
        quantities: Means over the last `STEADY_WINDOW` seconds: "drag", "lift", "delta_p"
            [Pa], "drag_cv" and "lift_cv" (control-volume balance), "drag_pressure" (the
            traction's pressure part); and "drift" and "lift_drift", the largest minus the smallest
            traction c_D and c_L in that window (how steady the run ended; the lift, 0.2 %
            of the drag, settles last). Empty when ``failure`` is set.
        seconds: Wall time of the stepping [s].
        failure: None, or why the quantities could not be computed.
    """

    setup: DfgSetup
    time: np.ndarray
    series: dict[str, np.ndarray]
    quantities: dict[str, float] = field(default_factory=dict)
    seconds: float = 0.0
    failure: str | None = None

    def error(self, key: str) -> float:
        """Relative error of a quantity against the fine reference value."""
        reference = STEADY_REFERENCE[_BALANCE_OF.get(key, key)]
        return self.quantities[key] / reference - 1.0


def run_dfg_steady(resolution: int = 20, *, duration: float = 5.0, dt: float | None = None,
                   advection: str = "maccormack", cfl: float = 0.5,
                   incremental_pressure: bool = False, advecting_velocity: str = "current",
                   viscosity_scheme: str = "backward_euler", offset: float = 0.0,
                   progress: Progress | None = None) -> DfgSteadyResult:
    """Run DFG 2D-1 for ``duration`` seconds and evaluate its steady quantities.

    Args:
        resolution: Cells per cylinder diameter (4..160).
        duration: Simulated time [s]; at least twice `STEADY_WINDOW`.
        dt: Time step [s] (default: ``cfl`` on the inflow peak, 0.3 m/s).
        advection, cfl, incremental_pressure, advecting_velocity, viscosity_scheme, offset:
            As `run_dfg`.
        progress: Called with (steps done, steps in all) as the run goes.

    Raises:
        ValueError: one line naming the bad argument.
    """
    if not (isinstance(duration, (int, float)) and duration >= 2.0 * STEADY_WINDOW):
        raise ValueError(f"duration = {duration!r}: must be a number >= "
                         f"{2.0 * STEADY_WINDOW:g} [s] (the steady window is the last "
                         f"{STEADY_WINDOW:g} s)")
    setup = dfg_setup(resolution, duration=duration, dt=dt, advection=advection, cfl=cfl,
                      incremental_pressure=incremental_pressure, kick=0.0,
                      advecting_velocity=advecting_velocity, viscosity_scheme=viscosity_scheme,
                      offset=offset, peak_speed=STEADY_PEAK_SPEED)
    times, series, seconds = step_series(setup, progress)
    return evaluate_steady(setup, times, series, seconds)


def evaluate_steady(setup: DfgSetup, time: np.ndarray, series: dict[str, np.ndarray],
                    seconds: float) -> DfgSteadyResult:
    """The steady quantities: means over the last `STEADY_WINDOW` seconds of the series."""
    result = DfgSteadyResult(setup, time, series, seconds=seconds)
    window = time >= time[-1] - STEADY_WINDOW
    if not all(np.isfinite(values[window]).all() for values in series.values()):
        result.failure = "non-finite forces: the run blew up"
        return result
    for key in ("drag", "lift", "delta_p", "drag_cv", "lift_cv", "drag_pressure"):
        result.quantities[key] = float(np.mean(series[key][window]))
    result.quantities["drift"] = float(np.ptp(series["drag"][window]))
    result.quantities["lift_drift"] = float(np.ptp(series["lift"][window]))
    return result


def describe_steady(result: DfgSteadyResult) -> str:
    """One line: benchmark, resolution, grid, time scheme, steps and wall time."""
    s = result.setup
    nx, ny = s.cells
    form = ", incremental pressure" if s.incremental_pressure else ""
    form += ", extrapolated trace" if s.advecting_velocity == "extrapolated" else ""
    form += {"crank_nicolson": ", Crank-Nicolson viscosity",
             "bdf2": ", BDF2"}.get(s.viscosity_scheme, "")
    form += f", cylinder {s.offset:g} cell downstream" if s.offset else ""
    return (f"{s.name}, resolution {s.resolution}: {nx}x{ny} cells (h = {s.h:.5g} m), "
            f"{s.advection} advection{form}, dt = {s.dt:.4g} s ({s.steps} steps), "
            f"{result.seconds:.1f} s wall")


def format_steady(result: DfgSteadyResult) -> list[str]:
    """Each quantity beside the reference and the published bounds, one per line."""
    if result.failure is not None:
        return [f"not evaluated: {result.failure}"]
    lines = []
    for key in ("drag", "drag_cv", "drag_pressure", "lift", "lift_cv", "delta_p"):
        value = result.quantities[key]
        standing_for = _BALANCE_OF.get(key, key)
        if standing_for in STEADY_BOUNDS:
            low, high = STEADY_BOUNDS[standing_for]
            verdict = "inside" if low <= value <= high else "outside"
            lines.append(f"{STEADY_LABELS[key]:<22} {value:.5g}   reference "
                         f"{STEADY_REFERENCE[standing_for]:.5g} "
                         f"({100.0 * result.error(key):+.2f} %), bounds {low:g}-{high:g}: "
                         f"{verdict}")
        else:
            lines.append(f"{STEADY_LABELS[key]:<22} {value:.5g}")
    lines.append(f"{'drift of c_D, c_L':<22} {result.quantities['drift']:.2g}, "
                 f"{result.quantities['lift_drift']:.2g} over the last {STEADY_WINDOW:g} s")
    return lines


def steady_json(result: DfgSteadyResult) -> dict[str, Any]:
    """The run and its quantities as JSON-ready data."""
    return {
        **setup_record(result.setup),
        "duration": result.setup.duration,
        "steps": result.setup.steps,
        "wall_seconds": result.seconds,
        "quantities": dict(result.quantities),
        "reference": STEADY_REFERENCE,
        "bounds": {key: list(value) for key, value in STEADY_BOUNDS.items()},
        "failure": result.failure,
    }


def steady_stem(result: DfgSteadyResult) -> str:
    """``dfg2d1_<advection>[_extrapolated][_<viscosity scheme>]_n<N>``."""
    s = result.setup
    time_scheme = ("_extrapolated" if s.advecting_velocity == "extrapolated" else "") + (
        "" if s.viscosity_scheme == "backward_euler" else f"_{s.viscosity_scheme}")
    return f"dfg2d1_{s.advection}{time_scheme}_n{s.resolution}"


def write_dfg_steady_report(result: DfgSteadyResult, folder: str | Path, *,
                            json_file: bool = True) -> list[Path]:
    """Write ``<stem>.csv`` (time series), ``.png`` (c_D, c_L, Δp against time with the
    reference) and, with ``json_file``, ``.json`` into ``folder`` (`steady_stem`); each file
    appears whole or not at all."""
    from elastoflow.validation._report import write_series_report

    return write_series_report(folder, steady_stem(result), result.time, result.series,
                               list(result.series), lambda path: _plot(result, path),
                               steady_json(result) if json_file else None)


def _plot(result: DfgSteadyResult, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from elastoflow.io import atomic_path

    figure, axes = plt.subplots(1, 3, figsize=(13, 3.4))
    panels = ((("drag", "traction"), ("drag_cv", "control volume")),
              (("lift", "traction"), ("lift_cv", "control volume")),
              (("delta_p", "surface"),))
    for axis, lines, key in zip(axes, panels, ("drag", "lift", "delta_p")):
        for name, label in lines:
            axis.plot(result.time, result.series[name], lw=0.9, label=label)
        low, high = STEADY_BOUNDS[key]
        axis.axhspan(low, high, color="tab:green", alpha=0.25, label="published bounds")
        axis.axhline(STEADY_REFERENCE[key], color="k", lw=0.6, ls="--", label="reference")
        # The start-up's impulsive first steps are left off the scale.
        tail = np.concatenate([result.series[name][len(result.time) // 5:]
                               for name, _ in lines])
        tail = tail[np.isfinite(tail)]
        if len(tail):
            span = max(float(np.ptp(tail)), 0.02 * abs(STEADY_REFERENCE[key]))
            axis.set_ylim(min(tail.min(), low) - 0.3 * span, max(tail.max(), high) + 0.3 * span)
        axis.set_xlabel("t [s]")
        axis.set_ylabel(STEADY_LABELS[key])
        axis.grid(alpha=0.3)
        axis.legend(loc="lower right", fontsize=7)
    figure.suptitle(describe_steady(result), fontsize=8)
    figure.tight_layout()
    with atomic_path(path) as temporary:
        figure.savefig(temporary, dpi=100, format="png")
    plt.close(figure)
