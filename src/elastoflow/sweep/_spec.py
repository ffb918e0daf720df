"""The sweep file: a base scene, the parameters to vary (by key path), and what to keep.

A sweep is TOML::

    name = "strouhal"
    scene = "cylinder_wake.toml"     # built-in name, or a file (relative to the sweep file)

    [set]                            # the same on every point
    "time.duration" = 12.0

    [grid]                           # every combination (or [[points]], or [sample])
    "fluid.viscosity" = [1.0e-3, 5.0e-4]
    "boundaries.left.speed" = [0.5, 1.0]

    [run]
    checkpoint_every = 200           # a point restarted on another worker resumes from here
    results_after = 6.0              # periodic statistics from this time on [s]

    [snapshots]                      # optional: fields of every point in one Zarr store
    times = [10.0, 12.0]
    fields = ["velocity_x", "velocity_y", "vorticity"]

Key paths address the scene as its TOML file is written (``scene_to_toml``): tables by name,
arrays of tables by index (``bodies.0.material.young_modulus``, ``obstacles.0.radius``).
"""

from __future__ import annotations

import itertools
import math
import tomllib
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    NonNegativeFloat,
    PositiveInt,
    Strict,
    ValidationError,
    model_validator,
)

SNAPSHOT_FIELDS: tuple[str, ...] = ("velocity_x", "velocity_y", "pressure", "dye", "vorticity",
                                    "solid")
"""Fields a sweep can keep at chosen times, all at cell centres, shape (nx, ny)."""

MAX_POINTS = 1_000_000
"""Most points of one sweep (a grid's product included)."""


class SweepError(ValueError):
    """A sweep file or one of its points is invalid; ``problems`` holds one line per problem
    (for a bad point, one line naming the point, its parameters and every problem)."""

    def __init__(self, problems: list[str], source: str | None = None) -> None:
        self.problems = list(problems)
        self.source = source
        prefix = f"{source}: " if source else ""
        super().__init__("\n".join(prefix + p for p in self.problems))


class _Spec(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)


class RangeSpec(_Spec):
    """A sampled parameter: uniform in ``[low, high]``, or uniform in its logarithm."""

    low: float
    high: float
    scale: Literal["linear", "log"] = "linear"
    integer: bool = False
    """Round the samples to integers (a grid size, a count)."""

    @model_validator(mode="after")
    def _ordered(self) -> RangeSpec:
        if not self.high > self.low:
            raise ValueError(f"high = {self.high!r} must exceed low = {self.low!r}")
        if self.scale == "log" and self.low <= 0.0:
            raise ValueError(f"low = {self.low!r}: a log scale needs low > 0")
        return self


class SampleSpec(_Spec):
    """``count`` points drawn at random or by Latin hypercube (one point in every one of
    ``count`` equal slices of each range), reproducible from ``seed``."""

    method: Literal["latin_hypercube", "random"] = "latin_hypercube"
    count: Annotated[int, Field(ge=1, le=MAX_POINTS)]
    seed: Annotated[int, Field(ge=0)] = 0
    ranges: Annotated[dict[str, RangeSpec], Field(min_length=1)]

    @model_validator(mode="before")
    @classmethod
    def _pairs_to_ranges(cls, data: Any) -> Any:
        # ``"key" = [low, high]`` is short for ``{ low = ..., high = ... }``.
        if isinstance(data, dict) and isinstance(data.get("ranges"), dict):
            ranges = {key: ({"low": value[0], "high": value[1]}
                            if isinstance(value, list) and len(value) == 2 else value)
                      for key, value in data["ranges"].items()}
            return {**data, "ranges": ranges}
        return data


class RunSpec(_Spec):
    """How each point runs: its length, its outputs, and what its results are taken from."""

    steps: PositiveInt | None = None
    """Run every point this many steps (default: each point's scene says)."""
    checkpoint_every: PositiveInt | None = None
    """Checkpoint every N steps, so that a point whose worker died resumes there (default: a
    tenth of the run, the scene's own interval if shorter)."""
    results_after: NonNegativeFloat = 0.0
    """Periodic statistics of the probes use only samples from this time on [s] (drop the
    start-up transient)."""
    video: bool = False
    """Write each point's video (off by default: a sweep is about numbers)."""
    fields: Annotated[list[Literal["npz", "vtk", "xdmf"]], Strict(False)] | None = None
    """Field formats of each point's own outputs (default: as the scene says)."""
    meshes: bool | None = None
    probe_plot: bool = True
    """Draw each point's ``probes.png`` (0.3-0.5 s a point: off for many short points)."""


SnapshotField = Literal["velocity_x", "velocity_y", "pressure", "dye", "vorticity", "solid"]


def _default_snapshot_fields() -> list[SnapshotField]:
    return ["velocity_x", "velocity_y", "pressure"]


class SnapshotSpec(_Spec):
    """Fields of every point at the given times, gathered in ``fields.zarr`` (xarray Dataset
    with dimensions point, time, x, y)."""

    times: Annotated[list[NonNegativeFloat], Field(min_length=1), Strict(False)]
    """Simulated times [s]; each is taken at the first step at or after it."""
    fields: Annotated[list[SnapshotField], Field(min_length=1), Strict(False)] = Field(
        default_factory=_default_snapshot_fields)

    @model_validator(mode="after")
    def _increasing(self) -> SnapshotSpec:
        if any(b <= a for a, b in itertools.pairwise(self.times)):
            raise ValueError(f"times = {self.times}: must increase")
        return self


class SweepSpec(_Spec):
    """A sweep: a base scene, fixed changes, and points as a grid, a list, or samples."""

    name: str = "sweep"
    description: str = ""
    scene: str
    """Built-in scene name, or a scene file (relative paths from the sweep file's folder)."""
    set: dict[str, Any] = Field(default_factory=dict)
    grid: dict[str, Annotated[list[Any], Field(min_length=1), Strict(False)]] | None = None
    points: Annotated[list[dict[str, Any]], Field(min_length=1), Strict(False)] | None = None
    sample: SampleSpec | None = None
    run: RunSpec = Field(default_factory=RunSpec)
    snapshots: SnapshotSpec | None = None
    base_dir: str | None = Field(default=None, exclude=True)
    """Folder the scene file is taken from (the sweep file's folder)."""
    source: str | None = Field(default=None, exclude=True)

    @model_validator(mode="after")
    def _one_design(self) -> SweepSpec:
        given = [name for name in ("grid", "points", "sample") if getattr(self, name) is not None]
        if len(given) != 1:
            raise ValueError("give exactly one of [grid] (every combination), [[points]] (a "
                             "list) or [sample] (random / Latin hypercube)"
                             + (f"; found {', '.join(given)}" if given else ""))
        if self.grid is not None:
            count = math.prod(len(values) for values in self.grid.values())
            if count > MAX_POINTS:
                raise ValueError(f"[grid] makes {count} points: at most {MAX_POINTS}")
        return self

    def parameter_points(self) -> list[dict[str, Any]]:
        """The varied parameters of every point, in order: key path -> value."""
        if self.grid is not None:
            keys = list(self.grid)
            return [dict(zip(keys, values, strict=True))
                    for values in itertools.product(*self.grid.values())]
        if self.points is not None:
            return [dict(point) for point in self.points]
        assert self.sample is not None
        return _sample_points(self.sample)


def _sample_points(sample: SampleSpec) -> list[dict[str, Any]]:
    """Random or Latin-hypercube points in the unit cube, mapped onto the ranges."""
    rng = np.random.default_rng(sample.seed)
    n, d = sample.count, len(sample.ranges)
    if sample.method == "random":
        unit = rng.random((n, d))
    else:
        # One sample in each of n slices per dimension, slices matched at random.
        strata = np.stack([rng.permutation(n) for _ in range(d)], axis=1)
        unit = (strata + rng.random((n, d))) / n
    points: list[dict[str, Any]] = [{} for _ in range(n)]
    for column, (key, spec) in enumerate(sample.ranges.items()):
        u = unit[:, column]
        if spec.scale == "log":
            values = np.exp(np.log(spec.low) + u * (np.log(spec.high) - np.log(spec.low)))
        else:
            values = spec.low + u * (spec.high - spec.low)
        for point, value in zip(points, values, strict=True):
            point[key] = int(round(value)) if spec.integer else float(value)
    return points


def _format_errors(error: ValidationError) -> list[str]:
    lines = []
    for item in error.errors():
        where = ".".join(str(k) for k in item["loc"] if k not in ("function-after",))
        value = item.get("input")
        shown = "" if isinstance(value, dict) else f" = {value!r}"
        message = item["msg"].removeprefix("Value error, ")
        lines.append(f"{where or '(sweep)'}{shown}: {message}")
    return lines


def parse_sweep(data: dict[str, Any], *, base_dir: str | Path | None = None,
                source: str | None = None) -> SweepSpec:
    """Validate a sweep given as nested dicts (the shape of its TOML file).

    Raises:
        SweepError: One line per problem with the file's key path.
    """
    try:
        spec = SweepSpec.model_validate(data)
    except ValidationError as error:
        raise SweepError(_format_errors(error), source) from None
    spec.base_dir = None if base_dir is None else str(base_dir)
    spec.source = source
    return spec


def load_sweep(path: str | Path) -> SweepSpec:
    """Read and validate a sweep TOML file (its points are checked by `plan_sweep`).

    Raises:
        SweepError: The file is missing, is not TOML, or is not a valid sweep.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as error:
        raise SweepError([f"not a text file in UTF-8 (byte 0x{error.object[error.start]:02x} "
                          f"at offset {error.start}); a sweep file is UTF-8 TOML"],
                         str(path)) from None
    except OSError as error:
        raise SweepError([f"cannot read sweep file: {error.strerror or error}"],
                         str(path)) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise SweepError([f"not valid TOML: {error}"], str(path)) from None
    return parse_sweep(data, base_dir=path.resolve().parent, source=str(path))
