"""What a coupled step reports, and the error that stops a diverged run."""

from __future__ import annotations

from dataclasses import dataclass, field


class SimulationBlowUp(RuntimeError):
    """The coupled run left its valid range; the message says what happened where."""


@dataclass
class StepReport:
    """What one coupled step did.

    Attributes:
        step: Index of the step just taken (1 for the first).
        time: Simulated time after the step [s].
        pressure_iterations: Iterations of the pressure solve.
        pressure_residual: Final relative residual of the pressure solve.
        substeps: FEM substeps taken by each body (empty without bodies).
        cfl: max |u| dt / h after the step.
        crossing_count: Entries in the boundary map (0 without bodies or obstacles).
        seconds_by_phase: Wall time of each phase [s]: map, fluid phases, force, solid.
    """

    step: int
    time: float
    pressure_iterations: int
    pressure_residual: float
    substeps: list[int] = field(default_factory=list)
    cfl: float = 0.0
    crossing_count: int = 0
    seconds_by_phase: dict[str, float] = field(default_factory=dict)
