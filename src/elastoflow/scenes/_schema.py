"""The scene description: pydantic models, one per TOML table.

Every model forbids unknown keys, so a typo is an error rather than a silently ignored setting.
Values are taken as written, never converted: a number must be a TOML number (``nx = "256"``
and ``lx = true`` are refused; an integer is accepted where a float is expected), and every
float must be finite (``inf`` and ``nan`` are refused). Lengths in metres, times in seconds,
densities in kg/m^3, moduli in Pa.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, ClassVar, Literal

from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Discriminator,
    Field,
    NonNegativeFloat,
    PositiveFloat,
    PositiveInt,
    Strict,
    Tag,
    field_validator,
    model_validator,
)

# Models are strict (no str -> number, bool -> number coercion), but TOML arrays arrive as
# lists: tuples and lists accept either, their items stay strict.
Point = Annotated[tuple[float, float], Strict(False)]
Box = Annotated[tuple[float, float, float, float], Strict(False)]
"""Axis-aligned box ``(x0, y0, x1, y1)`` [m]."""

MAX_SUBSTEPS = 1_000_000
"""Most solid substeps per fluid step a scene may ask for ("auto" computes the count)."""

MAX_SEGMENTS = 100_000
"""Most outline vertices of a circle obstacle. More only add cost (the overlap checks compare
outline edges pairwise) and no accuracy: the fluid sees the outline through the grid cells."""


MAX_POLYGON_POINTS = 2_000
"""Most vertices of a polygon written in a scene (body or obstacle outline); finer outlines
come as mesh files. The simplicity check compares every pair of edges (0.7 s at 2000)."""


class _Spec(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)


def _check_box(box: Box) -> Box:
    if not (box[2] > box[0] and box[3] > box[1]):
        raise ValueError("must be [x0, y0, x1, y1] with x1 > x0 and y1 > y0")
    return box


# --------------------------------------------------------------------------------------------
# domain and fluid


class DomainSpec(_Spec):
    """Rectangular domain ``[x0, x0 + lx] x [y0, y0 + ly]`` cut into square cells.

    Give exactly one of ``nx`` (cells across ``lx``) or ``h`` (cell side [m]); ``ly`` must then
    be a whole number of cells.
    """

    lx: PositiveFloat
    ly: PositiveFloat
    nx: Annotated[int, Field(ge=2)] | None = None
    h: PositiveFloat | None = None
    origin: Point = (0.0, 0.0)
    """Lower-left corner ``[x0, y0]`` [m]. Every position in the scene (bodies, obstacles,
    jets, probes, pivots) is in the same coordinates, and so are the saved fields."""

    @model_validator(mode="after")
    def _one_resolution(self) -> DomainSpec:
        if (self.nx is None) == (self.h is None):
            raise ValueError("give exactly one of nx (cells along x) or h (cell side)")
        if not self.cell_size > 0.0:
            raise ValueError(f"cell side lx / nx = {self.cell_size!r}: must be a positive length")
        cells_x = self.lx / self.cell_size
        cells_y = self.ly / self.cell_size
        for label, cells in (("lx", cells_x), ("ly", cells_y)):
            if not math.isfinite(cells):
                raise ValueError(f"{label} / h = {cells}: must be a finite number of cells")
            if abs(cells - round(cells)) > 1e-6 or round(cells) < 2:
                key, value = ("h", self.h) if self.h is not None else ("nx", self.nx)
                raise ValueError(
                    f"domain.{key} = {value!r} gives cells of side {self.cell_size:g}: {label} "
                    f"must be a whole number (>= 2) of them, got {cells:g} cells"
                )
        return self

    @property
    def cell_size(self) -> float:
        """Cell side h [m]."""
        return self.h if self.h is not None else self.lx / float(self.nx)  # type: ignore[arg-type]

    @property
    def cells(self) -> tuple[int, int]:
        """``(nx, ny)``."""
        h = self.cell_size
        return round(self.lx / h), round(self.ly / h)

    @property
    def bounds(self) -> Box:
        """``(x0, y0, x0 + lx, y0 + ly)`` [m]."""
        x0, y0 = self.origin
        return (x0, y0, x0 + self.lx, y0 + self.ly)


class InitialVelocitySpec(_Spec):
    """The fluid's velocity at t = 0, one component per key, sampled at the face centres of
    the MAC grid (``x`` on the x-faces, ``y`` on the y-faces).

    Each component is a number [m/s] or a string: an expression in the coordinates ``x`` and
    ``y`` [m] (in the domain's coordinates, origin included) with ``pi``, ``e``, arithmetic,
    comparisons, ``a if c else b`` and the functions of
    `elastoflow.scenes._expression.FUNCTIONS` (sin, cos, exp, sqrt, where, ...). The first
    step's projection makes the field divergence-free and imposes the walls and bodies.
    """

    x: float | str = 0.0
    """u [m/s]: a number or an expression."""
    y: float | str = 0.0
    """v [m/s]: a number or an expression."""

    @field_validator("x", "y")
    @classmethod
    def _expression(cls, value: float | str) -> float | str:
        if isinstance(value, str):
            from elastoflow.scenes._expression import Expression

            Expression(value)
        return value


class FluidSpec(_Spec):
    """Fluid properties and numerical choices."""

    density: PositiveFloat = 1.0
    viscosity: NonNegativeFloat = 1e-3
    """Kinematic viscosity [m^2/s]."""
    gravity: Point = (0.0, 0.0)
    """Gravity [m/s^2], also applied to the elastic bodies."""
    pressure_solver: Literal["mgpcg", "jacobi"] = "mgpcg"
    """Solver of the pressure equation: multigrid-preconditioned conjugate gradient, or the
    paper's Jacobi iteration."""
    pressure_rtol: Annotated[float, Field(gt=0.0, lt=1.0)] = 1e-6
    """Relative residual the pressure solve must reach; 1 or more would skip the solve."""
    viscosity_solver: Literal["mgpcg", "jacobi"] = "mgpcg"
    """Solver of the implicit viscosity equations (one per velocity component)."""
    viscosity_rtol: Annotated[float, Field(gt=0.0, lt=1.0)] = 1e-6
    """Relative residual each viscosity solve must reach; 1 or more would skip the solve."""
    advection: Literal["semi_lagrangian", "maccormack", "upwind3"] | None = None
    """Transport of velocity and dye: "upwind3", the velocity in flux form, third-order
    upwind-biased fluxes and three Runge-Kutta stages, sub-stepped above an advective CFL
    sum of 1.2 (conserves momentum; the dye by the semi-Lagrangian step; the default, the
    scheme that puts DFG 2D-2 inside the published bounds: docs/validation/unsteady.md);
    "maccormack", the limited correction of the semi-Lagrangian step (second order where the
    flow is smooth, any CFL number in one pass; the default with [liquid], where the flux
    form has no air-side treatment); or "semi_lagrangian", the paper's plain step (first
    order, diffusive; the cheapest, docs/benchmarks.md). Left out: "upwind3", or
    "maccormack" with [liquid]."""
    incremental_pressure: bool = False
    """Solve for the pressure increment (removes the plain splitting's O(dt) error at walls
    in steady flow; docs/method_notes.md item 6)."""
    advecting_velocity: Literal["current", "extrapolated"] = "current"
    """Velocity the advection's back-trace follows: the step's starting velocity (the
    paper's, first order in time) or the one extrapolated to mid-step from the last two
    steps (second order; docs/validation/unsteady.md, time discretization)."""
    viscosity_scheme: Literal["backward_euler", "crank_nicolson", "bdf2"] = "backward_euler"
    """Time discretization of the implicit viscosity: backward Euler (the paper's, first
    order), Crank-Nicolson (second order), or the whole step by BDF2 along trajectories
    (second order for the pressure too; the only one that put DFG 2D-2's Strouhal number
    inside its bounds at 20 cells per diameter, docs/validation/unsteady.md)."""
    pressure_guess: Literal["previous", "extrapolated"] = "extrapolated"
    """Where each pressure solve starts: the pressure extrapolated linearly from the last two
    steps (the default: the same answer to ``pressure_rtol`` in fewer iterations where the
    pressure changes smoothly, e.g. 9 -> 4 on Turek-Hron FSI3) or the last pressure (the
    paper's)."""
    initial_velocity: InitialVelocitySpec | None = None
    """Velocity at t = 0 [m/s] (at rest when left out): ``[ux, uy]``, or a table
    ``{ x = ..., y = ... }`` whose components are numbers or expressions in x and y."""

    @field_validator("initial_velocity", mode="before")
    @classmethod
    def _pair_to_table(cls, value: Any) -> Any:
        if isinstance(value, list | tuple):
            if len(value) != 2:
                raise ValueError("must be [ux, uy] (two numbers) or a table "
                                 "{ x = ..., y = ... }")
            return {"x": value[0], "y": value[1]}
        return value


class LiquidSpec(_Spec):
    """A liquid with a free surface (issue 15): the fluid fills the regions given here and
    the rest of the domain is air, a void at pressure 0 (`elastoflow.fluid.FreeSurfaceSolver`;
    docs/method_notes.md item 12). The liquid is the union of ``boxes`` and of the layer
    below ``height``. Every side must be a wall; elastic bodies and obstacles need
    ``coupling.scheme = "monolithic"`` (`elastoflow.simulation.FreeSurfaceMonolithicCoupling`);
    rods and jets are not supported with a free surface yet.
    """

    boxes: Annotated[list[Annotated[Box, AfterValidator(_check_box)]], Strict(False)] = Field(
        default_factory=list)
    """Rectangles of water at t = 0, each ``[x0, y0, x1, y1]`` [m]."""
    height: float | str | None = None
    """Water below ``y = height`` at t = 0 [m]: a number, or an expression in ``x`` (as for
    ``fluid.initial_velocity``), e.g. ``"0.05 + 0.005 * cos(pi * x / 0.1)"``."""
    viscosity: Literal["stress_free", "whole_grid"] = "stress_free"
    """How viscosity meets the surface: "stress_free" (implicit, the full viscous stress on
    the liquid, zero viscous stress at the surface; `elastoflow.fluid.ViscosityStressFree`,
    docs/method_notes.md item 12) or "whole_grid"
    (the fluid's own viscosity over the whole grid, the air holding the extrapolated
    velocity; `elastoflow.fluid.ViscosityWholeGrid`)."""
    maccormack_fallback: Literal["walls_and_air", "walls", "none"] = "walls_and_air"
    """With ``fluid.advection = "maccormack"``: where the velocity's MacCormack correction
    gives way to the semi-Lagrangian value (`FreeSurfaceSolver`); "none" gains energy
    (docs/validation/free_surface.md)."""
    theta_min: Annotated[float, Field(gt=0.0, le=1.0)] = 1e-3
    """Floor of the surface's distance from a liquid cell centre, in cells (ghost fluid)."""
    volume_correction: bool = True
    """Shift the level set every step so that the liquid's area stays the initial one."""
    redistance_interval: PositiveInt = 1
    """Steps between two redistancings of the level set."""
    extrapolation_layers: Annotated[int, Field(ge=1, le=64)] = 5
    """Layers of faces the velocity is extended into the air (must exceed the CFL number)."""

    @field_validator("height")
    @classmethod
    def _expression(cls, value: float | str | None) -> float | str | None:
        if isinstance(value, str):
            from elastoflow.scenes._expression import Expression

            Expression(value)
        return value

    @model_validator(mode="after")
    def _some_liquid(self) -> LiquidSpec:
        if not self.boxes and self.height is None:
            raise ValueError("give boxes (rectangles of water) or height (water below it), "
                             "or both")
        return self


# --------------------------------------------------------------------------------------------
# domain sides


class NoSlipSpec(_Spec):
    type: Literal["no_slip"] = "no_slip"


class FreeSlipSpec(_Spec):
    type: Literal["free_slip"] = "free_slip"


class MovingWallSpec(_Spec):
    type: Literal["moving"] = "moving"
    velocity: float
    """Tangential wall velocity [m/s]."""


class InflowSpec(_Spec):
    type: Literal["inflow"] = "inflow"
    speed: float
    """Mean speed for a uniform profile, peak speed for a parabolic one [m/s], into the domain."""
    profile: Literal["uniform", "parabolic"] = "uniform"
    ramp_time: NonNegativeFloat = 0.0


class OutflowSpec(_Spec):
    type: Literal["outflow"] = "outflow"


SideSpec = Annotated[
    NoSlipSpec | FreeSlipSpec | MovingWallSpec | InflowSpec | OutflowSpec,
    Field(discriminator="type"),
]


class BoundariesSpec(_Spec):
    """One condition per side; a bare string such as ``"outflow"`` is accepted for short."""

    left: SideSpec = Field(default_factory=NoSlipSpec)
    right: SideSpec = Field(default_factory=NoSlipSpec)
    bottom: SideSpec = Field(default_factory=NoSlipSpec)
    top: SideSpec = Field(default_factory=NoSlipSpec)

    @model_validator(mode="before")
    @classmethod
    def _strings_to_tables(cls, data: Any) -> Any:
        return sides_as_tables(data)


def sides_as_tables(data: Any) -> Any:
    """A ``[boundaries]`` table with each bare string (``"outflow"``) made ``{type = ...}``."""
    if isinstance(data, dict):
        return {k: ({"type": v} if isinstance(v, str) else v) for k, v in data.items()}
    return data


class JetSpec(_Spec):
    """Faces inside ``region`` are given ``velocity``; cells inside get ``dye``."""

    region: Box
    velocity: Point
    dye: NonNegativeFloat = 1.0

    _region = field_validator("region")(_check_box)


# --------------------------------------------------------------------------------------------
# obstacles


class RigidMotionSpec(_Spec):
    """Prescribed rigid motion: translation at ``velocity`` and rotation at ``angular_velocity``
    about ``center`` (which moves with the body; the polygon's centroid when left out)."""

    velocity: Point = (0.0, 0.0)
    angular_velocity: float = 0.0
    """[rad/s], counter-clockwise positive."""
    center: Point | None = None


class CircleObstacleSpec(_Spec):
    shape: Literal["circle"] = "circle"
    name: str | None = None
    """A name for references (``bodies.N.fixed.obstacle``); unique among the obstacles."""
    center: Point
    radius: PositiveFloat
    segments: Annotated[int, Field(ge=8, le=MAX_SEGMENTS)] = 64
    motion: RigidMotionSpec | None = None

    def bounds(self) -> Box:
        (cx, cy), r = self.center, self.radius
        return (cx - r, cy - r, cx + r, cy + r)


class RectangleObstacleSpec(_Spec):
    shape: Literal["rectangle"] = "rectangle"
    name: str | None = None
    """A name for references (``bodies.N.fixed.obstacle``); unique among the obstacles."""
    box: Box
    motion: RigidMotionSpec | None = None

    _box = field_validator("box")(_check_box)

    def bounds(self) -> Box:
        return self.box


class PolygonObstacleSpec(_Spec):
    shape: Literal["polygon"] = "polygon"
    name: str | None = None
    """A name for references (``bodies.N.fixed.obstacle``); unique among the obstacles."""
    points: Annotated[list[Point], Field(min_length=3, max_length=MAX_POLYGON_POINTS),
                      Strict(False)]
    """Closed polygon [m], either orientation, each vertex once."""
    motion: RigidMotionSpec | None = None

    def bounds(self) -> Box:
        xs = [p[0] for p in self.points]
        ys = [p[1] for p in self.points]
        return (min(xs), min(ys), max(xs), max(ys))


ObstacleSpec = Annotated[
    CircleObstacleSpec | RectangleObstacleSpec | PolygonObstacleSpec,
    Field(discriminator="shape"),
]


# --------------------------------------------------------------------------------------------
# elastic bodies


class RectangleShapeSpec(_Spec):
    """Structured triangulation of a box cut into ``divisions`` cells (along x, along y)."""

    type: Literal["rectangle"] = "rectangle"
    box: Box
    divisions: Annotated[tuple[PositiveInt, PositiveInt], Strict(False)]
    pattern: Literal["alternating", "crossed"] = "alternating"
    """How each cell is cut: ``"alternating"``, two triangles whose diagonals alternate like
    a chequerboard (``2 * divisions[0] * divisions[1]`` triangles); ``"crossed"``, four
    triangles around a node at the cell centre (twice as many; locks less in bending, the
    Turek-Hron flag's mesh)."""

    @property
    def triangles_per_cell(self) -> int:
        return 2 if self.pattern == "alternating" else 4

    _box = field_validator("box")(_check_box)

    def bounds(self) -> Box | None:
        return self.box


class WindmillShapeSpec(_Spec):
    """A hub with ``blades`` rectangular blades, meshed with Triangle."""

    type: Literal["windmill"] = "windmill"
    center: Point
    radius: PositiveFloat
    """Blade tip radius [m]."""
    hub_radius: PositiveFloat
    blade_width: PositiveFloat
    blades: Annotated[int, Field(ge=1)] = 4
    angle: float = 0.0
    """Direction of the first blade [rad]."""
    element_size: PositiveFloat | None = None
    """Target edge length [m]; None: half the blade width."""

    @model_validator(mode="after")
    def _sizes(self) -> WindmillShapeSpec:
        if self.hub_radius >= self.radius:
            raise ValueError(f"hub_radius {self.hub_radius:g}: must be below radius {self.radius:g}")
        return self

    def bounds(self) -> Box | None:
        (cx, cy), r = self.center, self.radius
        return (cx - r, cy - r, cx + r, cy + r)


class PolygonShapeSpec(_Spec):
    """A polygon (counter-clockwise) meshed with Triangle."""

    type: Literal["polygon"] = "polygon"
    points: Annotated[list[Point], Field(min_length=3, max_length=MAX_POLYGON_POINTS),
                      Strict(False)]
    element_size: PositiveFloat | None = None
    """Target edge length [m]; None lets the mesher pick."""

    def bounds(self) -> Box | None:
        xs = [p[0] for p in self.points]
        ys = [p[1] for p in self.points]
        return (min(xs), min(ys), max(xs), max(ys))


class MeshFileShapeSpec(_Spec):
    """A triangle mesh read from a file (any format meshio reads, e.g. Gmsh .msh)."""

    type: Literal["mesh"] = "mesh"
    path: str
    """Relative paths are taken from the scene file's folder."""
    scale: PositiveFloat = 1.0
    offset: Point = (0.0, 0.0)

    def bounds(self) -> Box | None:
        return None


ShapeSpec = Annotated[
    RectangleShapeSpec | WindmillShapeSpec | PolygonShapeSpec | MeshFileShapeSpec,
    Field(discriminator="type"),
]


class MaterialSpec(_Spec):
    """St. Venant-Kirchhoff material with Voigt damping (METHOD section 4)."""

    density: PositiveFloat
    young_modulus: PositiveFloat
    poisson_ratio: Annotated[float, Field(gt=-1.0, lt=0.5)]
    damping_lambda: NonNegativeFloat = 0.0
    """Damping constant lambda' [Pa s]."""
    damping_mu: NonNegativeFloat = 0.0
    """Damping constant mu' [Pa s]."""
    plane: Literal["strain", "stress"] = "strain"


class FixedSpec(_Spec):
    """Nodes held at their rest position: those inside ``box``, those listed in ``nodes``, and
    those on the outline of ``obstacle`` (a body clamped to an obstacle along the curve where
    they meet); each selection given must pick at least one node."""

    box: Box | None = None
    nodes: Annotated[list[Annotated[int, Field(ge=0)]], Strict(False)] = Field(
        default_factory=list)
    obstacle: Annotated[int, Field(ge=0)] | str | None = None
    """An obstacle, by index or by name: the nodes within ``tolerance`` of its outline (inside
    or outside it) are held. The obstacle must not move."""
    tolerance: PositiveFloat | None = None
    """Largest distance [m] from the obstacle's outline of a held node (default: a quarter of
    a cell, less than the fluid can see). A circle's outline is the exact circle."""

    @field_validator("box")
    @classmethod
    def _box(cls, box: Box | None) -> Box | None:
        return None if box is None else _check_box(box)


class BodySpec(_Spec):
    """An elastic body: its shape, material and constraints."""

    union_tag: ClassVar[str] = "elastic"
    """Its label among the body kinds (`RodBodySpec`), for error messages."""

    name: str | None = None
    shape: ShapeSpec
    material: MaterialSpec
    fixed: FixedSpec | None = None
    pivot: Point | None = None
    """The node nearest this point [m] is pinned; the body rotates freely about it."""


MAX_ROD_SEGMENTS = 10_000
"""Most segments of one rod. Its implicit step factors a band of width 12 per node; more
segments than the grid has cells along the rod add cost and no accuracy the fluid can see."""


class RodShapeSpec(_Spec):
    """A rod's rest line: a polyline through ``points``, open (its ends are the rod's ends).

    The fluid sees it with zero thickness (`elastoflow.solid.RodBody`): it blocks the flow at
    any position on the grid, however thin its ``material.thickness``.
    """

    type: Literal["rod"] = "rod"
    points: Annotated[list[Point], Field(min_length=2, max_length=MAX_POLYGON_POINTS),
                      Strict(False)]
    """Vertices [m] from the rod's start to its end, each once."""
    segments: Annotated[int, Field(ge=1, le=MAX_ROD_SEGMENTS)] | None = None
    """Segments of the rod: nodes at equal arc length along the polyline (its corners are
    kept only where a node falls on them); None: the ``points`` are the nodes."""

    def bounds(self) -> Box | None:
        xs = [p[0] for p in self.points]
        ys = [p[1] for p in self.points]
        return (min(xs), min(ys), max(xs), max(ys))

    def nodes(self) -> list[tuple[float, float]]:
        """The rod's rest nodes [m], ``segments + 1`` of them (or the points)."""
        if self.segments is None:
            return list(self.points)
        xs = [p[0] for p in self.points]
        ys = [p[1] for p in self.points]
        lengths = [math.hypot(xs[k + 1] - xs[k], ys[k + 1] - ys[k]) for k in range(len(xs) - 1)]
        arc = [0.0]
        for length in lengths:
            arc.append(arc[-1] + length)
        nodes = []
        piece = 0
        for index in range(self.segments + 1):
            s = arc[-1] * index / self.segments
            while piece < len(lengths) - 1 and arc[piece + 1] < s:
                piece += 1
            t = 0.0 if lengths[piece] == 0.0 else min(1.0, (s - arc[piece]) / lengths[piece])
            nodes.append((xs[piece] + t * (xs[piece + 1] - xs[piece]),
                          ys[piece] + t * (ys[piece + 1] - ys[piece])))
        nodes[-1] = (xs[-1], ys[-1])
        return nodes


class RodMaterialSpec(_Spec):
    """A rod's material and cross-section, per unit depth: the rod is a plate of
    ``thickness`` seen edge on (`elastoflow.solid.MaterialRod`).

    Mass per length ``density * thickness`` [kg/m^2]; stretching stiffness ``EA = E t``
    [N/m]; bending stiffness ``EI = E t^3 / 12`` [N m] unless ``bending_stiffness`` is given.
    """

    density: PositiveFloat
    """Density of the rod's material [kg/m^3]."""
    young_modulus: PositiveFloat
    """Young's modulus E [Pa] (a plate in plane strain: E / (1 - nu^2))."""
    thickness: PositiveFloat
    """Thickness t [m]: sets the mass and stiffnesses only (the fluid sees a line)."""
    bending_stiffness: NonNegativeFloat | None = None
    """Flexural rigidity EI per unit depth [N m] instead of ``E t^3 / 12``; 0: a string."""
    damping_time: NonNegativeFloat = 0.0
    """Kelvin-Voigt relaxation time [s]: viscous forces are the elastic ones of the strain
    rate times this (stretching and bending)."""


RodEnd = Literal["start", "end"]


class RodBodySpec(_Spec):
    """An elastic rod (``shape.type = "rod"``): a polyline with stretching and bending
    stiffness, its ends free or clamped. Advanced by the monolithic scheme only."""

    union_tag: ClassVar[str] = "rod"
    """Its label among the body kinds (`BodySpec`), for error messages."""
    fixed: ClassVar[None] = None
    """A rod is held by ``clamped``; None here, so that code reading any body's ``fixed`` or
    ``pivot`` passes rods by."""
    pivot: ClassVar[None] = None

    name: str | None = None
    shape: RodShapeSpec
    material: RodMaterialSpec
    clamped: Annotated[list[RodEnd], Field(max_length=2), Strict(False)] = Field(
        default_factory=list)
    """Ends held in place and in direction (their rest tangent): ``"start"`` (the first
    point), ``"end"`` (the last); free when left out."""

    @field_validator("clamped")
    @classmethod
    def _each_once(cls, value: list[RodEnd]) -> list[RodEnd]:
        if len(set(value)) != len(value):
            raise ValueError("lists an end twice; give each of \"start\", \"end\" once")
        return value


def _body_kind(value: Any) -> str:
    """Which body model reads a ``[[bodies]]`` table: a rod shape makes it a rod."""
    if isinstance(value, RodBodySpec):
        return "rod"
    if isinstance(value, dict):
        shape = value.get("shape")
        if isinstance(shape, RodShapeSpec) or (isinstance(shape, dict)
                                               and shape.get("type") == "rod"):
            return "rod"
    return "elastic"


AnyBodySpec = Annotated[
    Annotated[BodySpec, Tag("elastic")] | Annotated[RodBodySpec, Tag("rod")],
    Discriminator(_body_kind),
]
"""A ``[[bodies]]`` table: a triangle body, or a rod when its shape's type is "rod"."""


# --------------------------------------------------------------------------------------------
# time and coupling


class TimeSpec(_Spec):
    """Fluid step (``dt`` [s], or ``cfl`` with the scene's characteristic speed), run length
    (``duration`` [s] or ``steps``) and solid substeps per fluid step."""

    dt: PositiveFloat | None = None
    cfl: PositiveFloat | None = None
    duration: PositiveFloat | None = None
    steps: PositiveInt | None = None
    substeps: Annotated[int, Field(gt=0, le=MAX_SUBSTEPS)] | Literal["auto"] = "auto"
    cfl_limit: PositiveFloat = 20.0
    """The run stops as diverged when the Courant number ``max |u| dt / h`` exceeds this (the
    semi-Lagrangian step is stable beyond 1; a jump this large means a blow-up)."""

    @model_validator(mode="after")
    def _exactly_one(self) -> TimeSpec:
        if (self.dt is None) == (self.cfl is None):
            raise ValueError("give exactly one of dt (seconds) or cfl (Courant number)")
        if (self.duration is None) == (self.steps is None):
            raise ValueError("give exactly one of duration (seconds) or steps (count)")
        return self


class CouplingSpec(_Spec):
    """How fluid and bodies advance together.

    ``scheme = "monolithic"`` (default): one pressure solve sees the bodies' inertia, stable
    for any density ratio with no relaxation (`elastoflow.simulation.MonolithicCoupling`).
    ``scheme = "explicit"``: the paper's partitioned step, whose force model, relaxation and
    added-mass estimate are the other keys; they are refused with the monolithic scheme,
    which needs none of them.
    """

    scheme: Literal["monolithic", "explicit"] = "monolithic"
    force_model: Literal["traction", "momentum_exchange"] = "traction"
    alpha: Annotated[float, Field(gt=0.0, le=1.0)] = 0.5
    """Volume fraction in eq. 8 of the momentum-exchange model."""
    force_relaxation: Annotated[float, Field(gt=0.0, le=1.0)] = 1.0
    """Under-relaxation of the force on the bodies (1: none); stabilises light bodies."""
    added_mass: Annotated[float, Field(ge=0.0)] = 0.0
    """Coefficient of the added-mass stabilisation (0: off)."""
    integrator: Literal["energy_momentum", "newmark", "midpoint"] = "energy_momentum"
    """Monolithic scheme: the bodies' implicit step. "energy_momentum" (default) keeps
    momentum, angular momentum and, up to its numerical damping, energy; "newmark" (with
    newmark_gamma) keeps the angular momentum only to O(dt^2), which spins up discs in water;
    "midpoint" keeps the momenta but not the energy in large rotations."""
    numerical_damping: Annotated[float, Field(ge=0.0, le=1.0)] = 0.1
    """Monolithic scheme, "energy_momentum": objective numerical damping c in units of dt (a
    linear mode is damped as by Newmark's gamma = 1/2 + c; 0: none)."""
    newmark_gamma: Annotated[float, Field(ge=0.5, le=1.0)] = 0.55
    """Monolithic scheme, "newmark": Newmark's gamma (0.5: no numerical damping; more damps
    the modes the step does not resolve)."""
    boundary: Literal["cut_cell", "dual_cell", "staircase"] = "cut_cell"
    """How the fluid sees bodies and obstacles: "cut_cell" (open fractions of faces and cut
    distances from the boundary map), "dual_cell" (the same, each face weighted by the fluid
    share of its dual cell: weights and forces continuous as bodies move, docs/method_notes.md
    item 9) or "staircase" (cells flagged by their centres, faces fully open or closed; the
    baseline of docs/validation/boundary_study.md)."""
    wall_contact: bool = True
    """Bodies touching the domain's wall sides stop there: nothing passes through a wall
    (inflow and outflow sides have no contact). Resting nodes are held inside the bodies'
    implicit step, nodes ending a step beyond a wall are put back onto it, inelastically
    (`elastoflow.solid.WallContact`). false: bodies pass through the walls."""
    wall_friction: Annotated[float, Field(ge=0.0, allow_inf_nan=False)] = 0.3
    """Coulomb friction coefficient between bodies and walls (0: frictionless)."""

    @model_validator(mode="after")
    def _explicit_keys(self) -> CouplingSpec:
        if self.scheme == "monolithic":
            if self.force_model != "traction":
                raise ValueError(
                    f"force_model = {self.force_model!r} needs scheme = \"explicit\"; the "
                    "monolithic scheme takes the force from its own pressure solve"
                )
            if self.force_relaxation != 1.0 or self.added_mass != 0.0:
                raise ValueError(
                    "force_relaxation and added_mass stabilise the explicit scheme only; with "
                    "scheme = \"monolithic\" (the default) leave them out, or set "
                    "scheme = \"explicit\""
                )
        if not self.wall_contact and "wall_friction" in self.model_fields_set:
            raise ValueError("wall_friction needs wall_contact = true (friction acts only "
                             "where a body touches a wall)")
        return self


# --------------------------------------------------------------------------------------------
# outputs

View = Literal["speed", "vorticity", "pressure", "dye"]


class VideoSpec(_Spec):
    view: View = "speed"
    fps: Annotated[int, Field(gt=0, le=1000)] = 30
    every: PositiveInt = 1
    """Render a frame every this many fluid steps."""


FieldFormat = Literal["npz", "vtk", "xdmf"]


def _default_field_formats() -> list[FieldFormat]:
    return ["npz"]


class FieldsSpec(_Spec):
    formats: Annotated[list[FieldFormat], Field(min_length=1), Strict(False)] = Field(
        default_factory=_default_field_formats
    )
    every: PositiveInt = 10


class MeshesSpec(_Spec):
    """Bodies extruded to 3D prisms (pseudo-3D, paper Fig. 7)."""

    format: Literal["obj", "ply"] = "obj"
    thickness: PositiveFloat = 0.05
    every: PositiveInt = 1


class ProbeSpec(_Spec):
    """One probe, sampled after every ``outputs.probes_every`` steps into ``probes.csv``.

    Kinds: ``node_displacement`` (body, node or point), ``body_force`` (the force the coupling
    applied to a body), ``force`` and ``torque`` (the fluid's traction integrated over the
    listed ``bodies`` and ``obstacles`` together: drag and lift; torque about ``about``),
    ``pressure`` and ``velocity`` at ``point``, ``pressure_difference`` between ``points``,
    ``kinetic_energy`` (a body's, else the fluid's: with ``[liquid]`` the faces with liquid on a
    side), ``pressure_iterations``, ``momentum_balance`` (the force on the still ``obstacles``
    inside ``region`` from the fluid's momentum balance over that box: the scheme's own
    force, which the traction integral reads with a first-order error, largest in the lift;
    `elastoflow.fluid.MomentumBalance`).
    """

    kind: Literal["node_displacement", "body_force", "force", "torque", "pressure", "velocity",
                  "pressure_difference", "kinetic_energy", "pressure_iterations",
                  "momentum_balance"]
    body: Annotated[int, Field(ge=0)] | None = None
    """Body index (node_displacement, body_force; kinetic_energy of a body, else the fluid's)."""
    node: Annotated[int, Field(ge=0)] | None = None
    point: Point | None = None
    """node_displacement: the node nearest this rest position, instead of ``node``; pressure,
    velocity: where [m]."""
    bodies: Annotated[list[Annotated[int, Field(ge=0)]], Strict(False)] = Field(
        default_factory=list)
    """force, torque: body indices whose traction counts."""
    obstacles: Annotated[list[Annotated[int, Field(ge=0)]], Strict(False)] = Field(
        default_factory=list)
    """force, torque: obstacle indices whose traction counts."""
    about: Point | None = None
    """torque: the axis [m] (counter-clockwise positive)."""
    points: Annotated[list[Point], Strict(False)] | None = None
    """pressure_difference: two points [m]; the column is p(first) - p(second)."""
    region: Box | None = None
    """momentum_balance: the control volume ``[x0, y0, x1, y1]`` [m], its sides taken to the
    nearest face lines; it must hold the listed obstacles, two cells clear of its sides, and
    nothing else."""

    _region = field_validator("region")(lambda box: box if box is None else _check_box(box))

    @model_validator(mode="after")
    def _needs(self) -> ProbeSpec:
        if self.kind in ("node_displacement", "body_force") and self.body is None:
            raise ValueError(f"probe kind {self.kind!r} needs body (an index)")
        if self.kind == "node_displacement" and (self.node is None) == (self.point is None):
            raise ValueError("probe kind 'node_displacement' needs exactly one of node or point")
        if self.kind in ("force", "torque") and not (self.bodies or self.obstacles):
            raise ValueError(f"probe kind {self.kind!r} needs bodies or obstacles (index lists)")
        if self.kind == "torque" and self.about is None:
            raise ValueError("probe kind 'torque' needs about (the axis, [x, y])")
        if self.kind in ("pressure", "velocity") and self.point is None:
            raise ValueError(f"probe kind {self.kind!r} needs point ([x, y])")
        if self.kind == "pressure_difference" and (self.points is None or len(self.points) != 2):
            raise ValueError("probe kind 'pressure_difference' needs points (two [x, y])")
        if self.kind == "momentum_balance":
            if not self.obstacles or self.bodies:
                raise ValueError("probe kind 'momentum_balance' needs obstacles (an index "
                                 "list) and no bodies: it reads the force on still obstacles")
            if self.region is None:
                raise ValueError("probe kind 'momentum_balance' needs region ([x0, y0, x1, "
                                 "y1], the box around the obstacles)")
        return self


class CheckpointSpec(_Spec):
    every: PositiveInt = 100


class OutputsSpec(_Spec):
    """Each output is off when left out."""

    video: VideoSpec | None = None
    fields: FieldsSpec | None = None
    meshes: MeshesSpec | None = None
    probes: Annotated[list[ProbeSpec], Strict(False)] = Field(default_factory=list)
    probes_every: PositiveInt = 1
    checkpoint: CheckpointSpec | None = None


# --------------------------------------------------------------------------------------------
# the scene


class Scene(_Spec):
    """A complete simulation set-up: typed data, loadable from TOML (``load_scene``)."""

    name: str = "scene"
    description: str = ""
    domain: DomainSpec
    fluid: FluidSpec = Field(default_factory=FluidSpec)
    liquid: LiquidSpec | None = None
    """A liquid with a free surface in air (left out: the fluid fills the domain)."""
    boundaries: BoundariesSpec = Field(default_factory=BoundariesSpec)
    jets: Annotated[list[JetSpec], Strict(False)] = Field(default_factory=list)
    obstacles: Annotated[list[ObstacleSpec], Strict(False)] = Field(default_factory=list)
    bodies: Annotated[list[AnyBodySpec], Strict(False)] = Field(default_factory=list)
    time: TimeSpec
    coupling: CouplingSpec = Field(default_factory=CouplingSpec)
    outputs: OutputsSpec = Field(default_factory=OutputsSpec)
    base_dir: str | None = Field(default=None, exclude=True)
    """Folder that relative mesh paths are taken from (the scene file's folder); not saved."""
    source: str | None = Field(default=None, exclude=True)
    """Where the scene came from (its file, or "built-in scene 'NAME'"), for messages; not
    saved."""

    @model_validator(mode="after")
    def _default_advection(self) -> Scene:
        # The flux form is the default where it is available (issue 11: the default must
        # reproduce DFG 2D-2); a free surface takes MacCormack, which has an air side.
        if self.fluid.advection is None:
            # A copy: a FluidSpec given to several scenes must not take the first one's fill.
            chosen = "maccormack" if self.liquid is not None else "upwind3"
            self.fluid = self.fluid.model_copy(update={"advection": chosen})
        return self
