"""Unsteady accuracy (issue 11): DFG 2D-2, the advection schemes' order, the drag's
convergence, and what each advection scheme costs on the paper's scenes.

``python -m benchmarks unsteady [--parts=order,dfg,drag,pieces,speed,time,placement,couette,steady,balance]
[--resolutions=10,20,30] [--advection=maccormack,semi_lagrangian,upwind3] [--duration=10]
[--name=NAME]
[--quick]``

Parts:

* ``order``: RMS error of a Gaussian dye bump carried diagonally by a uniform velocity and of
  a transverse velocity ``v = g(x - U t)`` carried by ``u = U`` (exact solutions), 32²-256²
  at CFL 0.8; the observed order between successive grids.
* ``dfg``: DFG 2D-2 (`elastoflow.validation.run_dfg`) at each resolution with each scheme:
  Strouhal number, c_D max, c_L max, Δp against the published bounds; the mean drag by the
  traction integral and by a control-volume balance; wall time. A Richardson table of the
  drag from the three finest MacCormack runs (observed order and extrapolated value).
* ``drag``: what the drag depends on, MacCormack at N = 10 (``--drag-resolution``): the
  time step (CFL 0.25, 0.5, 1), the pressure-correction form (incremental pressure), the
  limiter (unclamped correction), the start-up kick. Each run also gives the drag by a
  control-volume balance, independent of the traction evaluation at cut cells.
* ``pieces``: the same, N = 10 over 8 s, with one near-wall piece at a time taken back to
  the plain grid: advection or viscosity without the cut distances, the projection with
  open fractions rounded to 0/1 (how much the drag depends on each).
* ``time``: the time discretization, MacCormack at N = 10 (``--time-resolution``) at CFL 1,
  0.5 and 0.25: the paper's first-order step beside the back-trace with the velocity
  extrapolated to mid-step, alone, with Crank-Nicolson viscosity, with incremental
  pressure, with both, and with the BDF2 step; then the first-order step and the variants
  named by ``--time-fine-variants`` (default: BDF2) at N = 20 (``--time-fine``, 0 skips
  it), CFL 0.5.
  Not in the default parts.
* ``placement``: DFG 2D-2 with the flux form and every second-order option (as
  ``balance``) at each resolution N of ``--placement-resolutions`` (default 10, 20): the
  benchmark's geometry on the grids of ``ceil(4.1 N) - 2 .. + 2`` cells across the height
  (``run_dfg(across=...)``: where the grid cuts the circle; at the middle one the centre
  lies on a grid node and the circle passes through nodes), their mean and spread; then
  the middle grid with the cylinder moved downstream by one and two cells
  (``run_dfg(offset=...)``: the same cuts, the cylinder's place in the channel changed).
  Not in the default parts.
* ``couette``: circular Couette flow between two cut-cell cylinders
  (`elastoflow.validation._couette`, exact at any Reynolds number; U = 1 m/s, nu = 0.01,
  3 s from the exact flow) on 32², 64², 128² with the first-order step, BDF2 with the
  extrapolated trace, the incremental pressure form and both; then 64² at CFL 0.25 and
  0.125: the errors of u_theta and of the pressure near the inner wall, and their orders.
  Not in the default parts.
* ``steady``: DFG 2D-1 (steady, Re = 20; `elastoflow.validation.run_dfg_steady`) through the
  same unsteady step, MacCormack, 5 s: the first-order step and BDF2 with the extrapolated
  trace at CFL 0.5 at each resolution of ``--steady-resolutions`` (default 10, 20, 30, 40,
  60), then both at CFL 0.25 and 0.125 at the second: c_D by the traction integral and by
  the control-volume balance against the fine reference, the traction's pressure part, c_L
  and Δp (what the time scheme does to a steady state). Not in the default parts.
* ``balance``: how the force is read, DFG 2D-2 with the flux form and every second-order
  option (BDF2, extrapolated trace, incremental pressure) at each resolution of
  ``--balance-resolutions`` (default 10, 20, 30) over ``--balance-duration`` (default 6 s):
  c_D max and c_L max over the last 0.7 s by the momentum balance
  (`elastoflow.fluid.MomentumBalance`) on boxes reaching 0.75, 1, 1.5 and 1.9 diameters
  from the centre, with the step's time derivative and with the two-level one, and by the
  traction integral with its first sample at 0.5-2.5 h. Not in the default parts.
* ``speed``: the paper's scenes (``bar_in_jet``, ``windmill``) stepped with each advection
  scheme: ms per step and the advection phase.

Writes ``benchmarks/results/NAME.json`` (default unsteady; one row per measurement, with the
part it belongs to), plots and per-run JSON into ``docs/validation/unsteady/``, time series
into ``out/validation/unsteady/``; prints the Markdown tables docs/validation/unsteady.md is
written from. ``--quick``: N = 8 and 12 for 2 s (a smoke test; nothing is copied to docs).
``--reevaluate``: no DFG runs; quantities, plots and JSON again from the time series in
``out/validation/unsteady`` (after a change to the evaluation or the plots).
"""

from __future__ import annotations

import math
import shutil
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import machine, markdown_table, write_results

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs" / "validation" / "unsteady"
SERIES = ROOT / "out" / "validation" / "unsteady"
SCHEMES = ("maccormack", "semi_lagrangian", "upwind3")


def _option(argv: list[str], name: str, default: str) -> str:
    for item in argv:
        if item.startswith(f"--{name}="):
            return item.split("=", 1)[1]
    return default


def _order_module() -> Any:
    import importlib.util

    path = ROOT / "tests" / "unit" / "fluid" / "test_advection_order.py"
    spec = importlib.util.spec_from_file_location("_advection_order", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def order_part(quick: bool) -> list[dict[str, Any]]:
    """Errors and observed orders of the schemes on the translating fields (with "upwind3"
    the dye goes by the semi-Lagrangian step: its velocity is the flux form's)."""
    order = _order_module()
    sizes = (32, 64, 128) if quick else (32, 64, 128, 256)
    rows = []
    errors: dict[str, np.ndarray] = {}
    for advection in SCHEMES:
        values = np.array([order.translation_errors(n, advection) for n in sizes])
        errors[advection] = values
        for k, n in enumerate(sizes):
            row: dict[str, Any] = {"part": "order", "advection": advection, "n": n,
                                   "dye RMS": float(values[k, 0]),
                                   "velocity RMS": float(values[k, 1])}
            if k > 0:
                row["dye order"] = float(np.log2(values[k - 1, 0] / values[k, 0]))
                row["velocity order"] = float(np.log2(values[k - 1, 1] / values[k, 1]))
            rows.append(row)
    print(markdown_table(rows, ["advection", "n", "dye RMS", "dye order", "velocity RMS",
                                "velocity order"]), flush=True)
    if not quick:
        _plot_order(sizes, errors)
    return rows


def _plot_order(sizes: tuple[int, ...], errors: dict[str, np.ndarray]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    h = 1.0 / np.array(sizes)
    figure, axis = plt.subplots(figsize=(5.5, 4))
    for advection, values in errors.items():
        axis.loglog(h, values[:, 0], "o-", label=f"{advection}: dye")
        axis.loglog(h, values[:, 1], "s--", label=f"{advection}: velocity")
    axis.loglog(h, 0.5 * errors["maccormack"][0, 0] * (h / h[0]) ** 2, "k:", label="h²")
    axis.loglog(h, 0.5 * errors["semi_lagrangian"][0, 0] * (h / h[0]), "k-.", label="h")
    if "upwind3" in errors:
        axis.loglog(h, 0.5 * errors["upwind3"][0, 1] * (h / h[0]) ** 3, "k--", label="h³")
    axis.set_xlabel("h [m] (dt = 0.8 h / U)")
    axis.set_ylabel("RMS error")
    axis.set_title("smooth translating fields", fontsize=9)
    axis.legend(fontsize=7)
    axis.grid(alpha=0.3, which="both")
    figure.tight_layout()
    DOCS.mkdir(parents=True, exist_ok=True)
    figure.savefig(DOCS / "advection_order.png", dpi=100)
    plt.close(figure)


def _dfg_row(result: Any, part: str, label: str = "") -> dict[str, Any]:
    s = result.setup
    row: dict[str, Any] = {
        "part": part, "advection": s.advection, "N": s.resolution, "h [m]": s.h,
        "dt [s]": s.dt, "cells": "x".join(map(str, s.cells)), "steps": s.steps,
        "t_end [s]": float(result.time[-1]), "wall [s]": round(result.seconds, 1),
        "incremental": s.incremental_pressure, "variant": label,
        "advecting velocity": s.advecting_velocity, "viscosity scheme": s.viscosity_scheme,
    }
    for key, value in result.quantities.items():
        row[key] = value
        row[f"{key} inside"] = result.within_bounds(key)
    for key in ("drag", "drag_cv"):
        stats = result.statistics.get(key)
        if stats is not None:
            row[f"{key} mean"] = stats.mean
            row[f"{key} growth"] = stats.growth
    if "drag" in result.statistics:
        part_mask = (result.time >= result.statistics["drag"].start)
        for key in ("drag_pressure", "drag_pressure_constant", "drag_pressure_linear"):
            if key in result.series:
                row[f"{key} mean"] = float(np.mean(result.series[key][part_mask]))
    if result.failure:
        row["note"] = result.failure
    return row


def _reevaluate(resolution: int, advection: str, label: str = "", **options: Any) -> Any:
    """A `DfgResult` rebuilt from the CSV and JSON of an earlier run (after a change to the
    evaluation or the plots)."""
    import json

    from elastoflow.validation import dfg_setup
    from elastoflow.validation._dfg import evaluate, report_stem

    folder = SERIES / label.replace(" ", "_") if label else SERIES
    stem = folder / report_stem(
        advection, resolution, options.get("advecting_velocity", "current"),
        options.get("viscosity_scheme", "backward_euler"))
    saved = json.loads(stem.with_suffix(".json").read_text())
    with stem.with_suffix(".csv").open() as file:
        keys = file.readline().strip().split(",")[1:]
    data = np.loadtxt(stem.with_suffix(".csv"), delimiter=",", skiprows=1)
    setup = dfg_setup(resolution, duration=saved["duration"], dt=saved["dt"],
                      advection=advection,
                      incremental_pressure=saved["incremental_pressure"],
                      limiter=saved.get("maccormack_limiter", True),
                      advecting_velocity=saved.get("advecting_velocity", "current"),
                      viscosity_scheme=saved.get("viscosity_scheme", "backward_euler"))
    series = {key: data[:, k + 1] for k, key in enumerate(keys)}
    return evaluate(setup, data[:, 0], series, saved["wall_seconds"])


REEVALUATE = False


def _run_dfg(resolution: int, advection: str, duration: float, copy: bool,
             label: str = "", **options: Any) -> Any:
    from elastoflow.validation import run_dfg, write_dfg_report
    from elastoflow.validation._dfg import describe, format_quantities

    began = time.perf_counter()
    if REEVALUATE:
        result = _reevaluate(resolution, advection, label, **options)
    else:
        result = run_dfg(resolution, duration=duration, advection=advection, **options)
    print(f"{describe(result)} ({time.perf_counter() - began:.0f} s) {label}", flush=True)
    for line in format_quantities(result):
        print(f"  {line}", flush=True)
    folder = SERIES / label.replace(" ", "_") if label else SERIES
    paths = write_dfg_report(result, folder)
    if copy:
        target = DOCS / label.replace(" ", "_") if label else DOCS
        target.mkdir(parents=True, exist_ok=True)
        for path in paths:
            if path.suffix in (".png", ".json"):
                shutil.copyfile(path, target / path.name)
    return result


QUANTITIES = ("strouhal", "drag_max", "lift_max", "delta_p")


def richardson(h: list[float], values: list[float]) -> dict[str, float]:
    """Observed order p and extrapolated value from three grids h1 > h2 > h3, assuming
    ``f(h) = f0 + C h^p``: p solves ``(f1 - f2) / (f2 - f3) = (h1^p - h2^p) / (h2^p - h3^p)``
    (bisection on 0.1..6), ``f0 = f3 - (f2 - f3) h3^p / (h2^p - h3^p)``. NaN when the
    differences change sign or p falls outside 0.1..6 (not in the asymptotic range)."""
    nan = {"order": float("nan"), "extrapolated": float("nan")}
    d12, d23 = values[0] - values[1], values[1] - values[2]
    if d12 == 0.0 or d23 == 0.0 or d12 * d23 < 0.0:
        return nan
    target = d12 / d23

    def ratio(p: float) -> float:
        return (h[0] ** p - h[1] ** p) / (h[1] ** p - h[2] ** p)

    low, high = 0.1, 6.0
    if not (ratio(low) - target) * (ratio(high) - target) < 0.0:
        return nan
    for _ in range(100):
        middle = 0.5 * (low + high)
        if (ratio(low) - target) * (ratio(middle) - target) <= 0.0:
            high = middle
        else:
            low = middle
    p = 0.5 * (low + high)
    return {"order": p,
            "extrapolated": values[2] - d23 * h[2] ** p / (h[1] ** p - h[2] ** p)}


def dfg_part(resolutions: list[int], schemes: list[str], duration: float, quick: bool,
             name: str) -> list[dict[str, Any]]:
    rows = []
    results: dict[tuple[str, int], Any] = {}
    # Coarse grids first, and the rows written after every run: the finest runs take tens
    # of minutes on two cores.
    for n in resolutions:
        for advection in schemes:
            try:
                result = _run_dfg(n, advection, duration, copy=not quick)
            except FileNotFoundError:
                # --reevaluate: this resolution was not run with this scheme.
                continue
            results[(advection, n)] = result
            rows.append(_dfg_row(result, "dfg"))
            write_results(name, rows)
    columns = ["advection", "N", "cells", "dt [s]", "wall [s]", *QUANTITIES, "drag mean",
               "drag_cv mean", "note"]
    print(markdown_table(rows, columns), flush=True)
    for advection in schemes:
        done = sorted(n for (a, n) in results if a == advection)[-3:]
        chosen = [results[(advection, n)] for n in done]
        if len(chosen) < 3 or any(r.failure for r in chosen):
            continue
        h = [r.setup.h for r in chosen]
        for key, pick in (("drag_max", lambda r: r.quantities["drag_max"]),
                          ("drag mean (traction)", lambda r: r.statistics["drag"].mean),
                          ("drag mean (control volume)",
                           lambda r: r.statistics["drag_cv"].mean),
                          ("strouhal", lambda r: r.quantities["strouhal"]),
                          ("lift_max", lambda r: r.quantities["lift_max"])):
            values = [float(pick(r)) for r in chosen]
            fit = richardson(h, values)
            # Two finest grids with an assumed order: brackets when the three-grid order is
            # outside the asymptotic range.
            for order in (1, 2):
                fit[f"two finest, p = {order}"] = values[2] - (values[1] - values[2]) * (
                    h[2] ** order / (h[1] ** order - h[2] ** order))
            row = {"part": "richardson", "advection": advection, "quantity": key,
                   "grids": ",".join(map(str, done)),
                   **{f"N{k + 1}": v for k, v in enumerate(values)}, **fit}
            rows.append(row)
    table = [r for r in rows if r["part"] == "richardson"]
    if table:
        print(markdown_table(table, ["advection", "quantity", "grids", "N1", "N2", "N3",
                                     "order", "extrapolated", "two finest, p = 1",
                                     "two finest, p = 2"]), flush=True)
    if not quick:
        _plot_convergence(_documented_runs())
    return rows


def _documented_runs() -> list[dict[str, Any]]:
    """N and the quantities of every first-order-step run whose JSON is in docs (this run's
    copied there, the others' from earlier runs of this part), for the convergence plot."""
    import json

    rows = []
    for advection in SCHEMES:
        for path in DOCS.glob(f"dfg2d2_{advection}_n*.json"):
            if not path.stem.removeprefix(f"dfg2d2_{advection}_n").isdigit():
                continue
            record = json.loads(path.read_text())
            row: dict[str, Any] = {"advection": advection, "N": record["resolution"]}
            row.update({key: value["value"] for key, value in record["quantities"].items()})
            rows.append(row)
    return sorted(rows, key=lambda row: (row["advection"], row["N"]))


def _plot_convergence(rows: list[dict[str, Any]]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from elastoflow.validation._dfg import BOUNDS, LABELS

    figure, axes = plt.subplots(1, 4, figsize=(15, 3.4))
    for axis, key in zip(axes, QUANTITIES):
        for advection, marker in zip(SCHEMES, "os^"):
            chosen = [r for r in rows if r["advection"] == advection and key in r]
            if chosen:
                axis.plot([r["N"] for r in chosen], [r[key] for r in chosen], marker + "-",
                          label=advection)
        low, high = BOUNDS[key]
        axis.axhspan(low, high, color="tab:green", alpha=0.25, label="published bounds")
        axis.set_xscale("log", base=2)
        resolutions = sorted({r["N"] for r in rows})
        axis.set_xticks(resolutions, [str(n) for n in resolutions])
        axis.minorticks_off()
        axis.set_xlabel("N (cells per diameter)")
        axis.set_title(LABELS[key], fontsize=9)
        axis.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    figure.suptitle("DFG 2D-2 against grid refinement (CFL 0.5 on the inflow peak)",
                    fontsize=9)
    figure.tight_layout()
    DOCS.mkdir(parents=True, exist_ok=True)
    figure.savefig(DOCS / "dfg2d2_convergence.png", dpi=100)
    plt.close(figure)


def drag_part(resolution: int, duration: float, quick: bool) -> list[dict[str, Any]]:
    """What the drag depends on, MacCormack at one resolution: the time step, the pressure
    splitting, the limiter, the start-up kick (beside the plain run)."""
    n = 8 if quick else resolution
    rows = []
    variants: list[tuple[str, dict[str, Any]]] = [
        ("plain", {}), ("cfl0.25", {"cfl": 0.25}), ("cfl1", {"cfl": 1.0}),
        ("incremental", {"incremental_pressure": True}), ("unlimited", {"limiter": False}),
        ("no kick", {"kick": 0.0}),
    ]
    for label, options in variants:
        result = _run_dfg(n, "maccormack", duration, copy=False, label=label, **options)
        rows.append(_dfg_row(result, "drag", label))
    print(markdown_table(rows, ["variant", "N", "dt [s]", "wall [s]", *QUANTITIES,
                                "drag mean", "drag_cv mean", "drag_pressure mean",
                                "drag_pressure_linear mean", "note"]),
          flush=True)
    return rows


TIME_VARIANTS: tuple[tuple[str, dict[str, Any]], ...] = (
    ("first order", {}),
    ("extrapolated", {"advecting_velocity": "extrapolated"}),
    ("extrapolated + CN", {"advecting_velocity": "extrapolated",
                           "viscosity_scheme": "crank_nicolson"}),
    ("extrapolated + incremental", {"advecting_velocity": "extrapolated",
                                    "incremental_pressure": True}),
    ("extrapolated + CN + incremental", {"advecting_velocity": "extrapolated",
                                         "viscosity_scheme": "crank_nicolson",
                                         "incremental_pressure": True}),
    ("extrapolated + BDF2", {"advecting_velocity": "extrapolated", "viscosity_scheme": "bdf2"}),
)


def time_part(resolution: int, fine: int, duration: float, quick: bool,
              fine_variants: tuple[str, ...] = ("extrapolated + BDF2",)) -> list[dict[str, Any]]:
    """How the quantities depend on dt with each time discretization (MacCormack)."""
    n = 8 if quick else resolution
    rows = []
    for cfl in (1.0, 0.5, 0.25):
        for label, options in TIME_VARIANTS:
            name = f"time {label} cfl{cfl:g}".replace(" + ", "_")
            result = _run_dfg(n, "maccormack", duration, copy=False, label=name, cfl=cfl,
                              **options)
            rows.append({**_dfg_row(result, "time", label), "cfl": cfl})
    if fine and not quick:
        for label, options in TIME_VARIANTS:
            if label != "first order" and label not in fine_variants:
                continue
            name = f"time {label} cfl0.5".replace(" + ", "_")
            result = _run_dfg(fine, "maccormack", duration, copy=False, label=name, **options)
            rows.append({**_dfg_row(result, "time", label), "cfl": 0.5})
    print(markdown_table(rows, ["variant", "N", "cfl", "wall [s]", *QUANTITIES,
                                "drag mean", "note"]), flush=True)
    return rows


def pieces_part(resolution: int, duration: float) -> list[dict[str, Any]]:
    """How much the drag depends on each near-wall piece: one fluid phase at a time gets
    the cylinder without its cut distances (advection, viscosity: the solid point's own
    value instead of the cut-distance ghost) or with its open fractions rounded to 0/1
    (projection: a staircase). The forces are always the traction on the real polygon."""
    import dataclasses

    from elastoflow.analysis import periodic_statistics
    from elastoflow.coupling import force_traction
    from elastoflow.validation import dfg_setup
    from elastoflow.validation._dfg import (
        DENSITY,
        DIAMETER,
        MEAN_SPEED,
        VISCOSITY,
        dfg_solver,
        initial_state,
    )

    rows = []
    for variant in ("advection without cut distances", "viscosity without cut distances",
                    "projection as a staircase"):
        setup = dfg_setup(resolution, duration=duration)
        grid, solver, bmap, interior = dfg_solver(setup)
        no_cut = dataclasses.replace(
            interior, cut_theta_x=np.full_like(interior.cut_theta_x, np.inf),
            cut_theta_y=np.full_like(interior.cut_theta_y, np.inf))
        stairs = dataclasses.replace(
            interior, open_fraction_x=(~interior.solid_faces_x).astype(np.float64),
            open_fraction_y=(~interior.solid_faces_y).astype(np.float64))
        advected = no_cut if variant.startswith("advection") else interior
        diffused = no_cut if variant.startswith("viscosity") else interior
        projected = stairs if variant.startswith("projection") else interior
        state = initial_state(grid, interior, setup.kick)
        scale = 2.0 / (DENSITY * MEAN_SPEED**2 * DIAMETER)
        times = np.arange(1, setup.steps + 1) * setup.dt
        forces = np.zeros((setup.steps, 2))
        began = time.perf_counter()
        for k in range(setup.steps):
            solver.advect(state, setup.dt, advected)
            solver.diffuse(state, setup.dt, diffused)
            solver.apply_forces(state, setup.dt, k * setup.dt)
            solver.project(state, setup.dt, projected)
            forces[k] = scale * force_traction(
                grid, bmap, state.velocity_x, state.velocity_y, state.pressure, DENSITY,
                VISCOSITY, interior).sum(axis=0)
        row: dict[str, Any] = {"part": "pieces", "variant": variant, "N": resolution,
                               "wall [s]": round(time.perf_counter() - began, 1)}
        try:
            lift = periodic_statistics(times, forces[:, 1])
            drag = periodic_statistics(times, forces[:, 0])
            row.update({"strouhal": DIAMETER * lift.frequency / MEAN_SPEED,
                        "drag_max": drag.maximum, "lift_max": lift.maximum,
                        "drag mean": drag.mean})
        except ValueError as error:
            row["note"] = str(error)
        print(row, flush=True)
        rows.append(row)
    print(markdown_table(rows, ["variant", "N", "wall [s]", "strouhal", "drag_max", "lift_max",
                                "drag mean", "note"]), flush=True)
    return rows


# The placement part's grids: ceil(4.1 N) + d cells across the height.
PLACEMENT_GRIDS = (-2, -1, 0, 1, 2)
# ... and the cylinder moved downstream on the benchmark's grid [cells].
SHIFTS = (1, 2)
COUETTE_SCHEMES: tuple[tuple[str, dict[str, Any]], ...] = (
    ("first order", {}),
    ("BDF2 + extrapolated trace", {"viscosity_scheme": "bdf2",
                                   "advecting_velocity": "extrapolated"}),
    ("incremental pressure", {"incremental_pressure": True}),
    ("BDF2 + extrapolated + incremental", {"viscosity_scheme": "bdf2",
                                           "advecting_velocity": "extrapolated",
                                           "incremental_pressure": True}),
)


def couette_part(sizes: list[int]) -> list[dict[str, Any]]:
    """Circular Couette flow: each time scheme on each grid at CFL 0.5, then the first-order
    step and BDF2 at smaller steps on the middle grid (whether the error is the time step's)."""
    from elastoflow.validation._couette import PRESSURE_BANDS, CouetteSetup, run_couette

    bands = [f"p err {low:g}-{high:g} h" for low, high in PRESSURE_BANDS]
    runs: list[tuple[str, int, float, dict[str, Any]]] = [
        (label, size, 0.5, options) for label, options in COUETTE_SCHEMES for size in sizes]
    middle = sizes[len(sizes) // 2]
    runs += [(label, middle, cfl, options) for label, options in COUETTE_SCHEMES[:2]
             for cfl in (0.25, 0.125)]
    rows: list[dict[str, Any]] = []
    for label, size, cfl, options in runs:
        result = run_couette(CouetteSetup(size, cfl=cfl, **options))
        row: dict[str, Any] = {
            "part": "couette", "scheme": label, "cells": size, "cfl": cfl,
            "u err core (rms)": result.speed_error_core, "u err max": result.speed_error_max,
            "p err core (rms)": result.pressure_error_core,
            **dict(zip(bands, result.pressure_error_bands)),
            "wall [s]": round(result.seconds, 1)}
        previous = [r for r in rows if r["scheme"] == label and r["cfl"] == cfl]
        if previous:
            ratio = size / previous[-1]["cells"]
            for key in ("u err core (rms)", "u err max"):
                row[f"order ({key.split(' (')[0]})"] = (
                    math.log(previous[-1][key] / row[key]) / math.log(ratio))
        print(row, flush=True)
        rows.append(row)
    print(markdown_table(rows, ["scheme", "cells", "cfl", "u err core (rms)",
                                "order (u err core)", "u err max", "order (u err max)",
                                "p err core (rms)", *bands, "wall [s]"]), flush=True)
    return rows


STEADY_SCHEMES: tuple[tuple[str, dict[str, str]], ...] = (
    ("first order", {}),
    ("BDF2 + extrapolated", {"viscosity_scheme": "bdf2", "advecting_velocity": "extrapolated"}),
)


def steady_part(resolutions: list[int], duration: float) -> list[dict[str, Any]]:
    """DFG 2D-1 with each time scheme: at CFL 0.5 over the resolutions, then at smaller
    steps on the second resolution (whether the steady state depends on dt)."""
    from elastoflow.validation import run_dfg_steady

    runs = [(label, n, 0.5, options) for label, options in STEADY_SCHEMES for n in resolutions]
    middle = resolutions[min(1, len(resolutions) - 1)]
    runs += [(label, middle, cfl, options) for label, options in STEADY_SCHEMES
             for cfl in (0.25, 0.125)]
    rows: list[dict[str, Any]] = []
    for label, resolution, cfl, options in runs:
        result = run_dfg_steady(resolution, duration=duration, cfl=cfl, **options)
        row: dict[str, Any] = {"part": "steady", "scheme": label, "N": resolution, "cfl": cfl,
                               "wall [s]": round(result.seconds, 1)}
        if result.failure is not None:
            row["note"] = result.failure
        else:
            q = result.quantities
            row.update({"c_D": q["drag"], "c_D err": result.error("drag"),
                        "c_D cv": q["drag_cv"], "c_D cv err": result.error("drag_cv"),
                        "c_D pressure": q["drag_pressure"], "c_L": q["lift"],
                        "c_L cv": q["lift_cv"], "c_L cv err": result.error("lift_cv"),
                        "Δp": q["delta_p"], "Δp err": result.error("delta_p"),
                        "drift": q["drift"], "c_L drift": q["lift_drift"]})
        print(row, flush=True)
        rows.append(row)
    print(markdown_table(rows, ["scheme", "N", "cfl", "c_D", "c_D err", "c_D cv", "c_D cv err",
                                "c_D pressure", "c_L", "c_L cv", "c_L cv err", "Δp", "Δp err",
                                "drift", "c_L drift", "wall [s]", "note"]), flush=True)
    return rows


def placement_part(resolutions: list[int], duration: float, quick: bool
                   ) -> list[dict[str, Any]]:
    """Where the grid lies about the geometry, and where the cylinder lies in the channel.

    Per resolution N, the flux form with every second-order option (as the ``balance``
    part): (a) the benchmark's geometry on the grids of ``ceil(4.1 N) + d`` cells across
    the height, d in `PLACEMENT_GRIDS` (h changes by a few percent, the circle's cuts
    change; each quantity's mean and spread over them); (b) the benchmark's grid with the
    cylinder moved downstream by whole cells, `SHIFTS` (the grid's placement about the
    cylinder unchanged: what moving the cylinder in the channel does by itself). The plot
    into docs unless ``quick``."""
    from elastoflow.validation import run_dfg
    from elastoflow.validation._dfg import cells_across

    options = {"advection": "upwind3", "viscosity_scheme": "bdf2",
               "advecting_velocity": "extrapolated", "incremental_pressure": True}
    rows: list[dict[str, Any]] = []
    keys = ("strouhal", "drag_max", "lift_max", "delta_p", "c_D max (balance)",
            "c_L max (balance)")

    def measure(resolution: int, across: int, offset: float, kind: str, d: int
                ) -> dict[str, Any]:
        result = run_dfg(resolution, duration=duration, across=across, offset=offset,
                         **options)
        h = 0.41 / across
        row: dict[str, Any] = {"part": "placement", "kind": kind, "N": resolution,
                               "d": d, "across": across, "offset [cells]": offset,
                               "centre [cells]": round(0.2 / h + offset, 3),
                               "wall [s]": round(result.seconds, 1)}
        row.update(result.quantities)
        if result.balance:
            row["c_D max (balance)"] = result.balance["drag_max"]
            row["c_L max (balance)"] = result.balance["lift_max"]
        if result.failure is not None:
            row["note"] = result.failure
        print(row, flush=True)
        return row

    for resolution in resolutions:
        base = cells_across(resolution)
        group = [measure(resolution, base + d, 0.0, "grid", d) for d in PLACEMENT_GRIDS]
        rows += group
        summary: dict[str, Any] = {"part": "placement", "kind": "grid", "N": resolution,
                                   "across": "mean"}
        spread: dict[str, Any] = {"part": "placement", "kind": "grid", "N": resolution,
                                  "across": "spread"}
        for key in keys:
            values = [row[key] for row in group if key in row]
            if len(values) == len(group):
                summary[key] = float(np.mean(values))
                spread[key] = float(np.max(values) - np.min(values))
        rows += [summary, spread]
        rows += [measure(resolution, base, float(shift), "shift", 0) for shift in SHIFTS]
    print(markdown_table(rows, ["N", "kind", "across", "offset [cells]", "centre [cells]",
                                *keys, "wall [s]", "note"]), flush=True)
    if not quick:
        plot_placement(rows)
    return rows


def plot_placement(rows: list[dict[str, Any]]) -> None:
    """``docs/validation/unsteady/dfg2d2_placement.png``: c_L max and c_D max by the
    balance against the cylinder's distance downstream of its benchmark position, one line
    per resolution: the shifted cylinder on the benchmark's grid, and the benchmark's
    geometry on the nearby grids (at distance 0; rows of `placement_part`)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from elastoflow.validation._dfg import BOUNDS, LABELS

    runs = [r for r in rows if r.get("part") == "placement" and isinstance(r["across"], int)]
    figure, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    for axis, key, bound in zip(axes, ("c_L max (balance)", "c_D max (balance)"),
                                ("lift_max", "drag_max")):
        for index, resolution in enumerate(sorted({r["N"] for r in runs})):
            colour = f"C{index}"
            # The cylinder on the benchmark's grid (d = 0), in its place and moved.
            shifted = [r for r in runs if r["N"] == resolution and key in r and r["d"] == 0]
            shifted.sort(key=lambda r: r["offset [cells]"])
            axis.plot([1e3 * r["offset [cells]"] * 0.41 / r["across"] for r in shifted],
                      [r[key] for r in shifted], "o-", color=colour,
                      label=f"N = {resolution}: cylinder moved")
            grids = [r[key] for r in runs if r["N"] == resolution and r["kind"] == "grid"
                     and key in r]
            axis.plot([0.0] * len(grids), grids, "x", color=colour, markersize=8,
                      label=f"N = {resolution}: {len(grids)} grids, benchmark's geometry")
        low, high = BOUNDS[bound]
        axis.axhspan(low, high, color="tab:green", alpha=0.25, label="published bounds")
        axis.set_xlabel("cylinder moved downstream [mm]")
        axis.set_title(f"{LABELS[bound]} (momentum balance)", fontsize=9)
        axis.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    figure.suptitle("DFG 2D-2, flux form (BDF2, extrapolated trace, incremental pressure): "
                    "the grid's placement and the cylinder's position", fontsize=9)
    figure.tight_layout()
    DOCS.mkdir(parents=True, exist_ok=True)
    figure.savefig(DOCS / "dfg2d2_placement.png", dpi=100)
    plt.close(figure)


def speed_part(steps: int, quick: bool) -> list[dict[str, Any]]:
    """ms per step of the paper's scenes with each advection scheme. The two simulations of
    a scene are stepped in alternating blocks of 10 steps, so that a change in the machine's
    load during the measurement falls on both alike."""
    from elastoflow.scenes import build_simulation, get_scene

    rows = []
    clock = time.perf_counter
    for name in ("bar_in_jet", "windmill"):
        simulations = {}
        for advection in SCHEMES:
            scene = get_scene(name)
            scene = scene.model_copy(update={"fluid": scene.fluid.model_copy(
                update={"advection": advection})})
            simulations[advection] = build_simulation(scene)
            for _ in range(5):
                simulations[advection].step()
        total = dict.fromkeys(SCHEMES, 0.0)
        advecting = dict.fromkeys(SCHEMES, 0.0)
        for _ in range(max(1, steps // 10)):
            for advection, simulation in simulations.items():
                began = clock()
                for _ in range(10):
                    report = simulation.step()
                    advecting[advection] += report.seconds_by_phase.get("advection", 0.0)
                total[advection] += clock() - began
        count = 10 * max(1, steps // 10)
        for advection in SCHEMES:
            rows.append({"part": "speed", "case": name, "advection": advection,
                         "steps": count, "ms per step": 1e3 * total[advection] / count,
                         "steps/s": count / total[advection],
                         "advection ms": 1e3 * advecting[advection] / count,
                         "cost vs semi_lagrangian": total[advection] / total["semi_lagrangian"]})
        print(f"{name}: " + ", ".join(f"{a} {1e3 * total[a] / count:.2f} ms/step"
                                      for a in SCHEMES), flush=True)
    print(markdown_table(rows, ["case", "advection", "ms per step", "steps/s", "advection ms",
                                "cost vs semi_lagrangian"]), flush=True)
    return rows


BALANCE_BOXES = (0.75, 1.0, 1.5, 1.9)
BALANCE_SAMPLES = (0.5, 1.0, 1.5, 2.0, 2.5)


def balance_part(resolutions: list[int], duration: float) -> list[dict[str, Any]]:
    """The force on DFG 2D-2's cylinder read by the momentum balance over boxes of each size
    (with BDF2's derivative, which the step takes, and the two-level one) and by the traction
    integral with its samples at each distance: one row per reading."""
    from elastoflow.coupling import force_traction
    from elastoflow.validation._dfg import (
        DENSITY,
        DIAMETER,
        VISCOSITY,
        ControlVolumeDrag,
        dfg_setup,
        dfg_solver,
        initial_state,
    )

    rows: list[dict[str, Any]] = []
    for resolution in resolutions:
        setup = dfg_setup(resolution, duration=duration, advection="upwind3",
                          incremental_pressure=True, viscosity_scheme="bdf2",
                          advecting_velocity="extrapolated")
        grid, solver, bmap, interior = dfg_solver(setup)
        state = initial_state(grid, interior, setup.kick, setup.center, setup.peak_speed)
        balances = {(half, bdf2): ControlVolumeDrag(grid, setup.center, half=half, bdf2=bdf2)
                    for half in BALANCE_BOXES for bdf2 in (True, False)}
        for balance in balances.values():
            balance.force(state.velocity_x, state.velocity_y, state.pressure, setup.dt)
        scale = 2.0 / (DENSITY * setup.mean_speed**2 * DIAMETER)
        window = int(round(0.7 / setup.dt))
        readings: dict[str, list[tuple[float, float]]] = {}
        began = time.perf_counter()
        for step in range(setup.steps):
            solver.step(state, setup.dt, step * setup.dt, interior)
            u, v, p = state.velocity_x, state.velocity_y, state.pressure
            for (half, bdf2), balance in balances.items():
                force = balance.force(u, v, p, setup.dt)
                key = f"balance {half:g} D, {'BDF2' if bdf2 else 'two-level'} derivative"
                readings.setdefault(key, []).append(force)
            if step < setup.steps - window:
                continue
            for distance in BALANCE_SAMPLES:
                force = force_traction(grid, bmap, u, v, p, DENSITY, VISCOSITY, interior,
                                       sample_distances=(distance, distance + 1.0,
                                                         distance + 2.0)).sum(axis=0)
                readings.setdefault(f"traction, first sample at {distance:g} h", []).append(
                    (float(force[0]), float(force[1])))
        seconds = time.perf_counter() - began
        for reading, values in readings.items():
            last = scale * np.asarray(values[-window:])
            rows.append({"part": "balance", "N": resolution, "reading": reading,
                         "c_D max": float(last[:, 0].max()),
                         "c_L max": float(last[:, 1].max()),
                         "c_L min": float(last[:, 1].min()), "wall [s]": round(seconds, 1)})
    print(markdown_table(rows, ["N", "reading", "c_D max", "c_L max", "c_L min", "wall [s]"]),
          flush=True)
    return rows


PARTS = ("order", "dfg", "drag", "pieces", "speed", "time", "placement", "couette", "steady",
         "balance")
OPTIONS = ("parts", "resolutions", "advection", "duration", "name", "drag-resolution",
           "pieces-duration", "time-resolution", "time-fine", "time-fine-variants",
           "couette-sizes", "placement-resolutions", "steady-resolutions", "steady-duration",
           "balance-resolutions", "balance-duration")
FLAGS = ("--quick", "--reevaluate")


def check_arguments(argv: list[str]) -> None:
    """Refuse, in one line, an argument this benchmark does not know (``--name=value`` and
    the flags only: ``--resolutions 20`` would otherwise run the defaults), an unknown part
    or advection scheme."""
    for item in argv:
        name, has_value, value = item.removeprefix("--").partition("=")
        if item in FLAGS:
            continue
        if not (item.startswith("--") and has_value and name in OPTIONS):
            _refuse(f"unsteady: argument {item!r}: must be one of {', '.join(FLAGS)} or "
                    f"--NAME=VALUE with NAME one of {', '.join(OPTIONS)}")
        allowed = {"parts": PARTS, "advection": SCHEMES}.get(name)
        unknown = [v for v in value.split(",") if allowed is not None and v not in allowed]
        if unknown:
            _refuse(f"unsteady: --{name}={value}: {unknown[0]!r} is not one of "
                    f"{', '.join(allowed or ())}")


def _refuse(message: str) -> None:
    """One line on stderr, exit status 2 (bad input), as the CLI does."""
    print(message, file=sys.stderr)
    raise SystemExit(2)


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    global REEVALUATE
    argv = list(argv or [])
    check_arguments(argv)
    quick = "--quick" in argv
    REEVALUATE = "--reevaluate" in argv
    parts = _option(argv, "parts", "order,dfg,drag,pieces,speed").split(",")
    resolutions = [int(v) for v in _option(argv, "resolutions",
                                           "8,12" if quick else "10,20,30").split(",")]
    schemes = _option(argv, "advection", ",".join(SCHEMES)).split(",")
    duration = float(_option(argv, "duration", "2" if quick else "10"))
    rows: list[dict[str, Any]] = []
    if "order" in parts:
        rows += order_part(quick)
    if "dfg" in parts:
        rows += dfg_part(resolutions, schemes, duration, quick, _option(argv, "name", "unsteady"))
    if "drag" in parts:
        rows += drag_part(int(_option(argv, "drag-resolution", "10")), duration, quick)
    if "pieces" in parts:
        rows += pieces_part(8 if quick else int(_option(argv, "drag-resolution", "10")),
                            float(_option(argv, "pieces-duration", "2" if quick else "8")))
    if "time" in parts:
        rows += time_part(int(_option(argv, "time-resolution", "10")),
                          int(_option(argv, "time-fine", "20")), duration, quick,
                          tuple(_option(argv, "time-fine-variants",
                                        "extrapolated + BDF2").split(",")))
    if "couette" in parts:
        rows += couette_part([int(v) for v in _option(argv, "couette-sizes",
                                                      "16,32" if quick else "32,64,128"
                                                      ).split(",")])
    if "placement" in parts:
        rows += placement_part(
            [int(v) for v in _option(argv, "placement-resolutions",
                                     "8" if quick else "10,20").split(",")],
            duration, quick)
    if "steady" in parts:
        rows += steady_part([int(v) for v in _option(argv, "steady-resolutions",
                                                     "8,12" if quick else "10,20,30,40,60"
                                                     ).split(",")],
                            float(_option(argv, "steady-duration", "2" if quick else "5")))
    if "balance" in parts:
        rows += balance_part([int(v) for v in _option(argv, "balance-resolutions",
                                                      "8" if quick else "10,20,30").split(",")],
                             float(_option(argv, "balance-duration", "1" if quick else "6")))
    if "speed" in parts:
        rows += speed_part(20 if quick else 100, quick)
    write_results(_option(argv, "name", "unsteady"), rows)
    print(machine())
    return rows


if __name__ == "__main__":
    main(sys.argv[1:])
