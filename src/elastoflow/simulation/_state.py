"""Model and state of a coupled simulation.

`CoupledModel` is everything static: the grid, the fluid solver (properties and boundary
conditions), the bodies' models and the obstacles. `CoupledState` is everything that changes:
the fluid's fields, each body's positions and velocities, time, step index and the forces of
the last step. A coupling scheme (`elastoflow.simulation.CouplingScheme`) steps one state into
another; the `Simulation` keeps two and swaps them, so a failed step leaves the last good
state untouched.

A state checkpoints by its fields: `CoupledState.to_arrays` walks the dataclass fields and
names each array by its path (``fluid.velocity_x``, ``bodies.0.positions``), and
`CoupledState.load_arrays` reads them back by the same walk.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

import numpy as np

from elastoflow.coupling import (
    BoundaryCutCell,
    BoundaryMap,
    BoundaryMap3D,
    BoundaryTreatment,
    Obstacle,
    Obstacle3D,
)
from elastoflow.fluid import (
    FluidSolver,
    FluidSolver3D,
    FluidState,
    FluidState3D,
    InteriorBoundary,
    InteriorBoundary3D,
    WallFreeSlip,
    WallMoving,
    WallMoving3D,
    WallNoSlip,
)
from elastoflow.grid import Grid2D, Grid3D
from elastoflow.solid import BodyModel, BodyState, ElasticBody3D, WallBox, WallContact

NOT_SAVED = {"checkpoint": False}
"""Field metadata of derived data a checkpoint leaves out (rebuilt by the next step)."""
OPTIONAL = {"checkpoint": "optional"}
"""Field metadata of data only some runs have (None otherwise): saved when present."""


@dataclass(eq=False)
class StepBoundary:
    """The boundary geometry a step used: the map and the grid's classification, built from
    the bodies and obstacles at the start of that step. Derived data: `Simulation.
    traction_forces` evaluates the force on the boundary with it."""

    boundary_map: BoundaryMap
    interior: InteriorBoundary


@dataclass(eq=False)
class StepBoundary3D:
    """`StepBoundary` in 3D: the surface map and the grid's classification of a step."""

    boundary_map: BoundaryMap3D
    interior: InteriorBoundary3D


FluidT = TypeVar("FluidT", FluidState, FluidState3D)
BoundaryT = TypeVar("BoundaryT", StepBoundary, StepBoundary3D)


@dataclass(eq=False)
class CoupledState(Generic[FluidT, BoundaryT]):
    """Everything a coupled run changes, in 2D (``CoupledState[FluidState, StepBoundary]``)
    or 3D (``CoupledState[FluidState3D, StepBoundary3D]``).

    Attributes:
        fluid: Velocity, pressure and dye fields.
        bodies: Positions and velocities of each body, in the model's order.
        time: Simulated time [s].
        step_index: Steps taken (0 before the first).
        body_forces: The fluid force each body received in the last step [N/m], (n, 2)
            (3D: [N], (n, 3)).
        previous_velocities: Each body's velocities at the start of the last step (the
            explicit scheme's added-mass estimate differentiates them).
        level_set: A free-surface run's level set [m] (nx, ny), liquid where negative
            (`elastoflow.fluid.FreeSurfaceState`); None without a free surface.
        liquid_area: The liquid area [m^2] its volume correction keeps; None without.
        boundary: The boundary geometry of the last step (None before the first step and
            after a restore); not saved.
    """

    fluid: FluidT
    bodies: list[BodyState]
    time: float = 0.0
    step_index: int = 0
    body_forces: list[np.ndarray] = field(default_factory=list)
    previous_velocities: list[np.ndarray] = field(default_factory=list)
    level_set: np.ndarray | None = field(default=None, metadata=OPTIONAL)
    liquid_area: float | None = field(default=None, metadata=OPTIONAL)
    boundary: BoundaryT | None = field(default=None, metadata=NOT_SAVED)

    def copy(self) -> CoupledState[FluidT, BoundaryT]:
        """An independent copy (the boundary geometry is shared, it is never changed)."""
        return CoupledState(
            fluid=self.fluid.copy(),
            bodies=[body.copy() for body in self.bodies],
            time=self.time,
            step_index=self.step_index,
            body_forces=[force.copy() for force in self.body_forces],
            previous_velocities=[v.copy() for v in self.previous_velocities],
            level_set=None if self.level_set is None else self.level_set.copy(),
            liquid_area=self.liquid_area,
            boundary=self.boundary,
        )

    def assign(self, other: CoupledState[FluidT, BoundaryT], fluid: bool = True) -> None:
        """Copy ``other``'s saved values into this state's arrays; the derived boundary
        geometry stays (a scheme replaces it, and reuses its arrays). ``fluid`` False
        leaves the fluid state to the caller."""
        if fluid:
            self.fluid.assign(other.fluid)
        for body, source_body in zip(self.bodies, other.bodies):
            body.assign(source_body)
        for target, source in zip(self.body_forces, other.body_forces):
            target[...] = source
        for target, source in zip(self.previous_velocities, other.previous_velocities):
            target[...] = source
        if other.level_set is None:
            self.level_set = None
        elif self.level_set is None or self.level_set.shape != other.level_set.shape:
            self.level_set = other.level_set.copy()
        else:
            self.level_set[...] = other.level_set
        self.liquid_area = other.liquid_area
        self.time = other.time
        self.step_index = other.step_index

    def to_arrays(self) -> dict[str, np.ndarray]:
        """Every saved field as an array, keyed by its path (bit-exact resume)."""
        return {path: np.array(value) for path, value, _ in _leaves(self)}

    def load_arrays(self, data: dict[str, np.ndarray]) -> None:
        """Put the values of `to_arrays` back; accepts checkpoints of earlier versions.

        Raises:
            ValueError: ``data`` holds other fields than this state's (another scene: a
                different number of bodies) or an array of another shape.
        """
        data = _upgrade_legacy_keys(data)
        _match_optional(self, "", data)
        leaves = list(_leaves(self))
        expected = {path for path, _, _ in leaves}
        if set(data) != expected:
            missing = sorted(expected - set(data))
            extra = sorted(set(data) - expected)
            raise ValueError(
                f"checkpoint fields do not match this scene ({len(self.bodies)} bodies): "
                f"missing {missing}, unexpected {extra}"
            )
        for path, value, store in leaves:
            source = np.asarray(data[path])
            if source.shape != np.shape(value):
                raise ValueError(
                    f"checkpoint {path} shape {source.shape}: must be {np.shape(value)}"
                )
            store(source)
        self.boundary = None


def _match_optional(value: Any, path: str, data: dict[str, np.ndarray]) -> None:
    """Give each optional field (metadata ``checkpoint="optional"``) under ``value`` the
    checkpoint's value, or None where the checkpoint has none (an older one, or a run that
    did not keep it)."""
    for item in dataclasses.fields(value):
        name = f"{path}{item.name}"
        child = getattr(value, item.name)
        if item.metadata.get("checkpoint") == "optional":
            if name not in data:
                setattr(value, item.name, None)
            elif np.ndim(data[name]) == 0:
                setattr(value, item.name, float(data[name]))
            else:
                setattr(value, item.name, np.array(data[name], dtype=np.float64))
        elif dataclasses.is_dataclass(child):
            _match_optional(child, f"{name}.", data)
        elif isinstance(child, list):
            for index, entry in enumerate(child):
                if dataclasses.is_dataclass(entry):
                    _match_optional(entry, f"{name}.{index}.", data)


Leaf = tuple[str, Any, Callable[[np.ndarray], None]]


def _leaves(value: Any, path: str = "") -> Iterator[Leaf]:
    """(path, value, store) of every saved array or number under ``value``: dataclass fields
    by name, list items by index; ``store`` writes a loaded value back."""
    for item in dataclasses.fields(value):
        if not item.metadata.get("checkpoint", True):
            continue
        name = f"{path}{item.name}"
        child = getattr(value, item.name)
        if child is None and item.metadata.get("checkpoint") == "optional":
            continue
        if dataclasses.is_dataclass(child):
            yield from _leaves(child, f"{name}.")
        elif isinstance(child, list):
            for index, entry in enumerate(child):
                if dataclasses.is_dataclass(entry):
                    yield from _leaves(entry, f"{name}.{index}.")
                else:
                    yield f"{name}.{index}", entry, _array_store(entry)
        elif isinstance(child, np.ndarray):
            yield name, child, _array_store(child)
        else:
            yield name, child, _scalar_store(value, item.name, type(child))


def _array_store(target: np.ndarray) -> Callable[[np.ndarray], None]:
    def store(source: np.ndarray) -> None:
        target[...] = source

    return store


def _scalar_store(owner: Any, name: str, kind: type) -> Callable[[np.ndarray], None]:
    def store(source: np.ndarray) -> None:
        setattr(owner, name, kind(source))

    return store


_LEGACY_BODY_FIELDS = {
    "positions": "bodies.{i}.positions",
    "velocities": "bodies.{i}.velocities",
    "previous_velocities": "previous_velocities.{i}",
    "forces": "body_forces.{i}",
}


def _upgrade_legacy_keys(data: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Checkpoints written before the state had fields used hand-made keys
    (``fluid_velocity_x``, ``body0_positions``): rename them."""
    if "fluid_velocity_x" not in data:
        return data
    renamed: dict[str, np.ndarray] = {}
    for key, value in data.items():
        if key.startswith("fluid_"):
            renamed[f"fluid.{key[len('fluid_'):]}"] = value
        elif key.startswith("body") and "_" in key:
            index, _, rest = key[len("body"):].partition("_")
            pattern = _LEGACY_BODY_FIELDS.get(rest)
            renamed[pattern.format(i=index) if pattern and index.isdigit() else key] = value
        else:
            renamed[key] = value
    return renamed


@dataclass(frozen=True, eq=False)
class CoupledModel:
    """Everything static in a coupled run.

    Attributes:
        grid: The MAC grid.
        fluid: The fluid solver: properties, boundary conditions, jets and the phases that
            advance a `FluidState`.
        bodies: The elastic bodies' models (triangle bodies and rods).
        obstacles: Static or prescribed-motion obstacles.
        boundary: How the fluid sees bodies and obstacles: `BoundaryCutCell` (open fractions
            and cut distances from the map, the default) or `BoundaryStaircase` (cells by
            their centres, faces open or closed; the baseline of docs/validation/
            boundary_study.md). Both schemes build each step's interior through it.
        contact: The bodies' contact with the domain's walls (`elastoflow.solid.WallContact`:
            nothing passes through a wall side; inflow and outflow sides have none), or None
            for none. Every 2D scheme applies it after (implicit rules: also inside) the
            bodies' advance.
    """

    grid: Grid2D
    fluid: FluidSolver
    bodies: tuple[BodyModel, ...] = ()
    obstacles: tuple[Obstacle, ...] = ()
    boundary: BoundaryTreatment = BoundaryCutCell()
    contact: WallContact | None = WallContact()

    def wall_box(self) -> WallBox:
        """The walls the bodies touch: the grid's box, the fluid's wall sides (`WallNoSlip`,
        `WallFreeSlip`, `WallMoving`; not `Inflow`, `Outflow`)."""
        grid = self.grid
        return _wall_box(grid.origin, (grid.lx, grid.ly), self.fluid.boundaries.sides())

    @property
    def has_boundaries(self) -> bool:
        return bool(self.bodies or self.obstacles)

    def state(self, fluid: FluidState | None = None
              ) -> CoupledState[FluidState, StepBoundary]:
        """A new initial state: ``fluid`` (default at rest) and each body's initial state."""
        if fluid is None:
            fluid = FluidState.zeros(self.grid)
        else:
            fluid.check(self.grid)
        return _initial_state(fluid, [body.state() for body in self.bodies])

    def object_offsets(self) -> np.ndarray:
        """Start of each body's nodes, then each obstacle's vertices, in the concatenated
        boundary points (`boundary_points`); one more entry for the end."""
        return _object_offsets(self.bodies, self.obstacles)

    def boundary_points(self, state: CoupledState
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """All boundary points, their velocities, the edges and each edge's object index, at
        ``state``: bodies first, then obstacles at ``state.time``.

        Bodies contribute all their nodes (interior nodes are simply not on any edge), so a
        nodal force array over these points slices by `object_offsets` into per-body forces.
        """
        points, velocities, edges, edge_body = [], [], [], []
        offsets = self.object_offsets()
        for index, (body, body_state) in enumerate(zip(self.bodies, state.bodies)):
            points.append(body_state.positions)
            velocities.append(body_state.velocities)
            edges.append(body.mesh.boundary_edges + offsets[index])
            edge_body.append(np.full(len(body.mesh.boundary_edges), index, dtype=np.int64))
        for index, obstacle in enumerate(self.obstacles, start=len(self.bodies)):
            points.append(obstacle.points_at(state.time))
            velocities.append(obstacle.velocities_at(state.time))
            edges.append(obstacle.edges + offsets[index])
            edge_body.append(np.full(len(obstacle.edges), index, dtype=np.int64))
        return (
            np.ascontiguousarray(np.concatenate(points), dtype=np.float64),
            np.ascontiguousarray(np.concatenate(velocities), dtype=np.float64),
            np.ascontiguousarray(np.concatenate(edges), dtype=np.int64),
            np.concatenate(edge_body),
        )


@dataclass(frozen=True, eq=False)
class CoupledModel3D:
    """`CoupledModel` in 3D: everything static in a coupled 3D run.

    Attributes:
        grid: The 3D MAC grid.
        fluid: The 3D fluid solver.
        bodies: The elastic bodies' models (tetrahedral meshes).
        obstacles: Static or prescribed-motion obstacles (closed surfaces).
        contact: The bodies' contact with the domain's walls, as `CoupledModel.contact`
            (both 3D schemes apply it).
    """

    grid: Grid3D
    fluid: FluidSolver3D
    bodies: tuple[ElasticBody3D, ...] = ()
    obstacles: tuple[Obstacle3D, ...] = ()
    contact: WallContact | None = WallContact()

    def wall_box(self) -> WallBox:
        """The walls the bodies touch: the grid's box, the fluid's wall sides (`WallNoSlip`,
        `WallFreeSlip`, `WallMoving3D`; not `Inflow`, `Outflow`)."""
        grid = self.grid
        return _wall_box(grid.origin, (grid.lx, grid.ly, grid.lz),
                         self.fluid.boundaries.sides())

    @property
    def has_boundaries(self) -> bool:
        return bool(self.bodies or self.obstacles)

    def state(self, fluid: FluidState3D | None = None
              ) -> CoupledState[FluidState3D, StepBoundary3D]:
        """A new initial state: ``fluid`` (default at rest) and each body's initial state."""
        if fluid is None:
            fluid = FluidState3D.zeros(self.grid)
        else:
            fluid.check(self.grid)
        return _initial_state(fluid, [body.state() for body in self.bodies])

    def object_offsets(self) -> np.ndarray:
        """Start of each body's nodes, then each obstacle's vertices, in the concatenated
        boundary points (`boundary_points`); one more entry for the end."""
        return _object_offsets(self.bodies, self.obstacles)

    def boundary_points(self, state: CoupledState[FluidState3D, StepBoundary3D]
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """All surface points, their velocities, the outward surface triangles and each
        triangle's object index, at ``state``: bodies first (all their nodes, so nodal forces
        slice by `object_offsets`), then obstacles at ``state.time``."""
        points, velocities, triangles, owner = [], [], [], []
        offsets = self.object_offsets()
        for index, (body, body_state) in enumerate(zip(self.bodies, state.bodies)):
            points.append(body_state.positions)
            velocities.append(body_state.velocities)
            triangles.append(body.boundary_triangles + offsets[index])
            owner.append(np.full(len(body.boundary_triangles), index, dtype=np.int64))
        for index, obstacle in enumerate(self.obstacles, start=len(self.bodies)):
            points.append(obstacle.points_at(state.time))
            velocities.append(obstacle.velocities_at(state.time))
            triangles.append(obstacle.triangles + offsets[index])
            owner.append(np.full(len(obstacle.triangles), index, dtype=np.int64))
        return (
            np.ascontiguousarray(np.concatenate(points), dtype=np.float64),
            np.ascontiguousarray(np.concatenate(velocities), dtype=np.float64),
            np.ascontiguousarray(np.concatenate(triangles), dtype=np.int64),
            np.concatenate(owner),
        )


def _wall_box(origin: Sequence[float], lengths: Sequence[float], sides: Sequence[object]
              ) -> WallBox:
    """The box from ``origin`` with side ``lengths`` [m] whose wall ``sides`` (two per axis,
    the fluid's side conditions) bodies touch."""
    lower = tuple(float(c) for c in origin)
    upper = tuple(lo + float(length) for lo, length in zip(lower, lengths, strict=True))
    walls = tuple(isinstance(side, WallNoSlip | WallFreeSlip | WallMoving | WallMoving3D)
                  for side in sides)
    return WallBox(lower, upper, walls)


def _initial_state(fluid: FluidT, bodies: list[BodyState]) -> CoupledState[FluidT, Any]:
    """A state at t = 0 with these fluid fields and body states, no force yet."""
    return CoupledState(
        fluid=fluid,
        bodies=bodies,
        body_forces=[np.zeros_like(b.positions) for b in bodies],
        previous_velocities=[b.velocities.copy() for b in bodies],
    )


def _object_offsets(bodies: tuple[Any, ...], obstacles: tuple[Any, ...]) -> np.ndarray:
    """Where each body's nodes, then each obstacle's vertices, start in the concatenated
    boundary points; one more entry for the end."""
    counts = [body.point_count for body in bodies]
    counts += [obstacle.point_count for obstacle in obstacles]
    return np.cumsum([0, *counts]).astype(np.int64)

