"""Validation against published benchmarks: one function (and one CLI command) per benchmark,
which builds the benchmark in its exact geometry, runs it and evaluates its quantities the way
the benchmark defines them.

``run_case("FSI3", resolution=20)`` runs Turek & Hron's FSI3; `write_report` writes its time
series (CSV), plots (PNG) and quantities (JSON); ``elastoflow validate turek-hron FSI3`` does
both. ``run_dfg(20)`` runs DFG 2D-2 (vortex shedding at Re = 100) and `write_dfg_report`
writes its report; ``elastoflow validate dfg-2d-2`` does both; `dfg_quantities` evaluates the
benchmark's quantities from any time series (a scene's probes). ``run_dfg_steady(20)`` runs
DFG 2D-1 (steady, Re = 20) through the same unsteady step, to show what the time scheme does
to a steady state; ``elastoflow validate dfg-2d-1`` prints it. ``run_couette(CouetteSetup(64))``
steps circular Couette flow between two cut-cell cylinders from its exact solution and
measures how far the scheme's steady state lies from it.

The boundary study (issue 13: the boundary map against the staircase boundary) is not a
published benchmark but is run the same way: ``run_poisson_study()`` solves the pressure
equation on a disk with both treatments, `write_poisson_report` writes its part of
``docs/validation/boundary_study.md``; ``run_leakage_study()`` measures the flux through a moving
plate from 2 h thick to 0 (`plate_leakage`), `write_leakage_report` writes its part;
``run_spurious_study()`` (velocities around a fixed body in water at rest),
``run_force_jump_study()`` (the force on a disc moving slowly across the grid) and
``run_dfg_study()`` (DFG 2D-1 drag and lift against resolution) likewise, each with its
writer; ``run_speed_study()`` (the map, the interiors and the brute-force classification
against the body's edges and the grid, and the built-in scenes' whole step) and
``run_stability_study()`` (the bar in a jet's largest stable dt and lowest stable density
ratio) with theirs; ``elastoflow validate boundary-study [PART]`` runs every part
(`STUDY_PARTS`) or one.
"""

from elastoflow.validation._boundary_study import (
    STUDY_PARTS,
    DfgStudy,
    ForceJumpStudy,
    PoissonDisk,
    PoissonSolve,
    PoissonStudy,
    SpuriousStudy,
    observed_order,
    run_dfg_study,
    run_force_jump_study,
    run_poisson_study,
    run_spurious_study,
    solve_poisson_disk,
    write_dfg_study_report,
    write_force_jump_report,
    write_poisson_report,
    write_spurious_report,
)
from elastoflow.validation._boundary_speed import (
    SpeedStudy,
    StabilityStudy,
    run_speed_study,
    run_stability_study,
    write_speed_report,
    write_stability_report,
)
from elastoflow.validation._leakage_study import (
    LeakageStudy,
    plate_leakage,
    run_leakage_study,
    write_leakage_report,
)
from elastoflow.validation._couette import CouetteResult, CouetteSetup, run_couette
from elastoflow.validation._dfg import (
    DfgResult,
    DfgSetup,
    dfg_quantities,
    dfg_setup,
    run_dfg,
    write_dfg_report,
)
from elastoflow.validation._dfg_steady import DfgSteadyResult, run_dfg_steady
from elastoflow.validation._perpendicular_flap import FLAP_CASE, cells_high, flap_setup, run_flap
from elastoflow.validation._report import (
    describe,
    format_quantities,
    quantities_json,
    write_report,
)
from elastoflow.validation._turek_hron import (
    CASES,
    REFERENCE,
    Case,
    Result,
    Setup,
    case_simulation,
    cells_across,
    check_resolution,
    default_setup,
    flag_mesh,
    get_case,
    rigid_flag_polygon,
    run_case,
    run_setup,
)

# Benchmarks that `elastoflow validate NAME [CASE]` runs.
BENCHMARKS = ("turek-hron", "perpendicular-flap", "dfg-2d-2")

__all__ = [
    "BENCHMARKS",
    "CASES",
    "FLAP_CASE",
    "LeakageStudy",
    "REFERENCE",
    "STUDY_PARTS",
    "Case",
    "CouetteResult",
    "CouetteSetup",
    "DfgResult",
    "DfgSetup",
    "DfgSteadyResult",
    "DfgStudy",
    "ForceJumpStudy",
    "PoissonDisk",
    "PoissonSolve",
    "PoissonStudy",
    "Result",
    "Setup",
    "SpeedStudy",
    "SpuriousStudy",
    "StabilityStudy",
    "case_simulation",
    "cells_across",
    "cells_high",
    "check_resolution",
    "default_setup",
    "describe",
    "dfg_quantities",
    "dfg_setup",
    "flag_mesh",
    "flap_setup",
    "format_quantities",
    "get_case",
    "observed_order",
    "plate_leakage",
    "quantities_json",
    "rigid_flag_polygon",
    "run_case",
    "run_setup",
    "run_couette",
    "run_dfg",
    "run_dfg_steady",
    "run_dfg_study",
    "run_flap",
    "run_force_jump_study",
    "run_leakage_study",
    "run_poisson_study",
    "run_speed_study",
    "run_spurious_study",
    "run_stability_study",
    "solve_poisson_disk",
    "write_dfg_report",
    "write_dfg_study_report",
    "write_force_jump_report",
    "write_leakage_report",
    "write_poisson_report",
    "write_speed_report",
    "write_spurious_report",
    "write_stability_report",
    "write_report",
]
