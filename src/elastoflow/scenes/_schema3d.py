"""The 3D scene description: a scene whose ``[domain]`` has ``lz`` is a `Scene3D`.

The same file format and rules as the 2D scene (`elastoflow.scenes._schema`: unknown keys
refused, values strict and finite), with points ``[x, y, z]``, boxes ``[x0, y0, z0, x1, y1,
z1]``, two more sides (``back`` at z = z0, ``front`` at z = z0 + lz), tetrahedral bodies
(``box``, ``cylinder``, ``sphere`` or a mesh file) and closed-surface obstacles (``sphere``,
``box``, ``cylinder``). What 3D does not have yet (rods, a free surface, the dual-cell
boundary, the explicit scheme's other force models) has no key here, so asking for it is an
unknown-key error.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import (
    AfterValidator,
    Field,
    NonNegativeFloat,
    PositiveFloat,
    PositiveInt,
    Strict,
    model_validator,
)

from elastoflow.scenes._schema import (
    CheckpointSpec,
    FreeSlipSpec,
    InflowSpec,
    NoSlipSpec,
    OutflowSpec,
    TimeSpec,
    View,
    _Spec,
    sides_as_tables,
)

Point3 = Annotated[tuple[float, float, float], Strict(False)]
"""A point ``[x, y, z]`` [m] or a vector."""
Box3 = Annotated[tuple[float, float, float, float, float, float], Strict(False)]
"""Axis-aligned box ``[x0, y0, z0, x1, y1, z1]`` [m]."""
Axis = Literal["x", "y", "z"]
AXES: tuple[str, str, str] = ("x", "y", "z")

MAX_CELLS_3D = 512 ** 3
"""Most cells of a 3D grid a scene may ask for (the memory check then bounds it further)."""


def check_box3(box: Box3) -> Box3:
    if not (box[3] > box[0] and box[4] > box[1] and box[5] > box[2]):
        raise ValueError("must be [x0, y0, z0, x1, y1, z1] with x1 > x0, y1 > y0 and z1 > z0")
    return box


CheckedBox3 = Annotated[Box3, AfterValidator(check_box3)]


class Domain3DSpec(_Spec):
    """Box domain ``[x0, x0 + lx] x [y0, y0 + ly] x [z0, z0 + lz]`` cut into cubic cells.

    Give exactly one of ``nx`` (cells across ``lx``) or ``h`` (cell side [m]); ``ly`` and
    ``lz`` must then be whole numbers of cells. y is up (gravity usually points along -y).
    """

    lx: PositiveFloat
    ly: PositiveFloat
    lz: PositiveFloat
    nx: Annotated[int, Field(ge=2)] | None = None
    h: PositiveFloat | None = None
    origin: Point3 = (0.0, 0.0, 0.0)
    """Low corner ``[x0, y0, z0]`` [m]: every position in the scene is in these coordinates."""

    @model_validator(mode="after")
    def _one_resolution(self) -> Domain3DSpec:
        if (self.nx is None) == (self.h is None):
            raise ValueError("give exactly one of nx (cells along x) or h (cell side)")
        h = self.cell_size
        if not h > 0.0:
            raise ValueError(f"cell side lx / nx = {h!r}: must be a positive length")
        for label, length in (("lx", self.lx), ("ly", self.ly), ("lz", self.lz)):
            cells = length / h
            if not math.isfinite(cells) or abs(cells - round(cells)) > 1e-6 or round(cells) < 2:
                key, value = ("h", self.h) if self.h is not None else ("nx", self.nx)
                raise ValueError(
                    f"domain.{key} = {value!r} gives cells of side {h:g}: {label} must be a "
                    f"whole number (>= 2) of them, got {cells:g} cells")
        count = math.prod(self.cells)
        if count > MAX_CELLS_3D:
            key, value = ("h", self.h) if self.h is not None else ("nx", self.nx)
            raise ValueError(f"domain.{key} = {value!r} gives {self.cells[0]} x "
                             f"{self.cells[1]} x {self.cells[2]} = {count:.3g} cells: at most "
                             f"{MAX_CELLS_3D} (512^3)")
        return self

    @property
    def cell_size(self) -> float:
        """Cell side h [m]."""
        return self.h if self.h is not None else self.lx / float(self.nx)  # type: ignore[arg-type]

    @property
    def cells(self) -> tuple[int, int, int]:
        """``(nx, ny, nz)``."""
        h = self.cell_size
        return round(self.lx / h), round(self.ly / h), round(self.lz / h)

    @property
    def bounds(self) -> Box3:
        """``(x0, y0, z0, x0 + lx, y0 + ly, z0 + lz)`` [m]."""
        x0, y0, z0 = self.origin
        return (x0, y0, z0, x0 + self.lx, y0 + self.ly, z0 + self.lz)


class Fluid3DSpec(_Spec):
    """Fluid properties and numerical choices of a 3D scene."""

    density: PositiveFloat = 1.0
    viscosity: NonNegativeFloat = 1e-3
    """Kinematic viscosity [m^2/s]."""
    gravity: Point3 = (0.0, 0.0, 0.0)
    """Gravity [m/s^2], also applied to the elastic bodies."""
    pressure_rtol: Annotated[float, Field(gt=0.0, lt=1.0)] = 1e-6
    """Relative residual the pressure solve (7-point, multigrid-preconditioned CG) reaches."""
    viscosity_rtol: Annotated[float, Field(gt=0.0, lt=1.0)] = 1e-6
    """Relative residual of each implicit viscosity solve."""
    advection: Literal["semi_lagrangian", "maccormack"] = "maccormack"
    """MacCormack's limited correction (second order where smooth; the default, as in 2D) or
    the plain semi-Lagrangian step (cheaper, diffusive)."""
    incremental_pressure: bool = True
    """Solve for the pressure increment (`FluidSolver3D`'s default: keeps water at rest under
    gravity at rest next to no-slip walls)."""
    buoyancy: float = 0.0
    """Upward (+y) acceleration per unit dye [m/s^2] (0: passive dye)."""
    initial_velocity: Point3 = (0.0, 0.0, 0.0)
    """Uniform velocity at t = 0 [m/s]."""


class MovingWall3DSpec(_Spec):
    type: Literal["moving"] = "moving"
    velocity: Point3
    """Wall velocity [m/s], along the wall (its normal component must be 0)."""


Side3DSpec = Annotated[
    NoSlipSpec | FreeSlipSpec | MovingWall3DSpec | InflowSpec | OutflowSpec,
    Field(discriminator="type"),
]


class Boundaries3DSpec(_Spec):
    """One condition per side; a bare string such as ``"outflow"`` is accepted for short."""

    left: Side3DSpec = Field(default_factory=NoSlipSpec)
    right: Side3DSpec = Field(default_factory=NoSlipSpec)
    bottom: Side3DSpec = Field(default_factory=NoSlipSpec)
    top: Side3DSpec = Field(default_factory=NoSlipSpec)
    back: Side3DSpec = Field(default_factory=NoSlipSpec)
    front: Side3DSpec = Field(default_factory=NoSlipSpec)

    @model_validator(mode="before")
    @classmethod
    def _strings_to_tables(cls, data: object) -> object:
        return sides_as_tables(data)


class Jet3DSpec(_Spec):
    """Faces inside ``region`` are given ``velocity``; cells inside get ``dye``."""

    region: CheckedBox3
    velocity: Point3
    dye: NonNegativeFloat = 1.0


class RigidMotion3DSpec(_Spec):
    """Constant translation and rotation (a rotation vector [rad/s], right-handed) about the
    obstacle's centre."""

    velocity: Point3 = (0.0, 0.0, 0.0)
    angular_velocity: Point3 = (0.0, 0.0, 0.0)


class SphereObstacleSpec(_Spec):
    shape: Literal["sphere"] = "sphere"
    name: str | None = None
    center: Point3
    radius: PositiveFloat
    element_size: PositiveFloat | None = None
    """Side of its surface triangles [m] (default half a cell)."""
    motion: RigidMotion3DSpec | None = None


class BoxObstacleSpec(_Spec):
    shape: Literal["box"] = "box"
    name: str | None = None
    box: CheckedBox3
    element_size: PositiveFloat | None = None
    motion: RigidMotion3DSpec | None = None


class CylinderObstacleSpec(_Spec):
    shape: Literal["cylinder"] = "cylinder"
    name: str | None = None
    center: Point3
    radius: PositiveFloat
    length: PositiveFloat
    axis: Axis = "z"
    element_size: PositiveFloat | None = None
    motion: RigidMotion3DSpec | None = None


Obstacle3DSpec = Annotated[
    SphereObstacleSpec | BoxObstacleSpec | CylinderObstacleSpec,
    Field(discriminator="shape"),
]


class BoxShape3DSpec(_Spec):
    """A box of tetrahedra (each cube cell cut into five or six)."""

    type: Literal["box"] = "box"
    box: CheckedBox3
    divisions: Annotated[tuple[PositiveInt, PositiveInt, PositiveInt], Strict(False)] | None = None
    """Cells along x, y, z (default from ``element_size``)."""
    element_size: PositiveFloat | None = None
    """Target cell side [m] (default: a cell of the fluid grid)."""

    @model_validator(mode="after")
    def _one_size(self) -> BoxShape3DSpec:
        if self.divisions is not None and self.element_size is not None:
            raise ValueError("give divisions or element_size, not both")
        return self


class CylinderShape3DSpec(_Spec):
    type: Literal["cylinder"] = "cylinder"
    center: Point3
    radius: PositiveFloat
    length: PositiveFloat
    axis: Axis = "z"
    element_size: PositiveFloat | None = None


class SphereShape3DSpec(_Spec):
    type: Literal["sphere"] = "sphere"
    center: Point3
    radius: PositiveFloat
    element_size: PositiveFloat | None = None


class MeshFile3DSpec(_Spec):
    """A tetrahedral mesh file meshio reads (.vtu, .msh, ...); relative paths from the scene
    file's folder."""

    type: Literal["mesh"] = "mesh"
    path: str
    scale: PositiveFloat = 1.0
    offset: Point3 = (0.0, 0.0, 0.0)


Shape3DSpec = Annotated[
    BoxShape3DSpec | CylinderShape3DSpec | SphereShape3DSpec | MeshFile3DSpec,
    Field(discriminator="type"),
]


class Material3DSpec(_Spec):
    """St. Venant-Kirchhoff material with Voigt damping, 3D Lamé constants."""

    density: PositiveFloat
    young_modulus: PositiveFloat
    poisson_ratio: Annotated[float, Field(gt=-1.0, lt=0.5)]
    damping_lambda: NonNegativeFloat = 0.0
    """Damping constant lambda' [Pa s]."""
    damping_mu: NonNegativeFloat = 0.0
    """Damping constant mu' [Pa s]."""


class Fixed3DSpec(_Spec):
    """Nodes held at their rest position: those inside ``box`` and those listed in
    ``nodes``; each selection given must pick at least one node."""

    box: CheckedBox3 | None = None
    nodes: Annotated[list[Annotated[int, Field(ge=0)]], Strict(False)] = Field(
        default_factory=list)


class Body3DSpec(_Spec):
    """An elastic body of tetrahedra: its shape, material and constraints."""

    name: str | None = None
    shape: Shape3DSpec
    material: Material3DSpec
    fixed: Fixed3DSpec | None = None


class Coupling3DSpec(_Spec):
    """How fluid and bodies advance together in 3D.

    ``scheme = "explicit"`` (default): the paper's partitioned step
    (`elastoflow.simulation.ExplicitCoupling3D`), stable only for bodies heavier than the
    fluid they displace; ``force_relaxation`` is its key. ``scheme = "monolithic"``: one
    pressure solve sees the bodies' inertia, stable for any density ratio
    (`elastoflow.simulation.MonolithicCoupling3D`), with the bodies' implicit step chosen by
    ``integrator`` as in 2D.
    """

    scheme: Literal["explicit", "monolithic"] = "explicit"
    force_relaxation: Annotated[float, Field(gt=0.0, le=1.0)] = 1.0
    """Explicit scheme: under-relaxation of the force on the bodies (1: none)."""
    integrator: Literal["energy_momentum", "newmark", "midpoint"] = "energy_momentum"
    """Monolithic scheme: the bodies' implicit step (as the 2D key)."""
    numerical_damping: Annotated[float, Field(ge=0.0, le=1.0)] = 0.1
    """Monolithic scheme, "energy_momentum": objective numerical damping in units of dt."""
    newmark_gamma: Annotated[float, Field(ge=0.5, le=1.0)] = 0.55
    """Monolithic scheme, "newmark": Newmark's gamma."""
    wall_contact: bool = True
    """Bodies touching the domain's wall sides stop there, as the 2D key: nothing passes
    through a wall (inflow and outflow sides have no contact). false: bodies pass through
    the walls."""
    wall_friction: Annotated[float, Field(ge=0.0, allow_inf_nan=False)] = 0.3
    """Coulomb friction coefficient between bodies and walls (0: frictionless)."""

    @model_validator(mode="after")
    def _scheme_keys(self) -> Coupling3DSpec:
        if self.scheme == "monolithic" and self.force_relaxation != 1.0:
            raise ValueError("force_relaxation stabilises the explicit scheme only; with "
                             "scheme = \"monolithic\" leave it out")
        if not self.wall_contact and "wall_friction" in self.model_fields_set:
            raise ValueError("wall_friction needs wall_contact = true (friction acts only "
                             "where a body touches a wall)")
        return self


class Video3DSpec(_Spec):
    """A video of a 3D run: by default the bodies' and obstacles' surfaces in perspective
    with a slice through the fluid coloured by ``view`` (`elastoflow.render.render_scene_3d`);
    ``style = "slice"`` draws the slice alone, flat, with the bodies' and obstacles'
    sections (`elastoflow.render.render_slice_3d`)."""

    view: View = "speed"
    style: Literal["3d", "slice"] = "3d"
    """"3d": the scene in perspective; "slice": the slice seen face on."""
    azimuth: float | None = None
    """``style = "3d"``: the camera's turn about y from +z towards +x [degrees] (default: in
    front of the slice, `elastoflow.render.scene_orientation`)."""
    elevation: Annotated[float, Field(ge=-85.0, le=85.0)] | None = None
    """``style = "3d"``: the camera's height above the x-z plane [degrees] (default as
    ``azimuth``)."""
    fps: Annotated[int, Field(gt=0, le=1000)] = 30
    every: PositiveInt = 1
    axis: Axis = "z"
    """The slice's normal."""
    at: float | None = None
    """The slice's coordinate along ``axis`` [m] (default: the domain's middle)."""


def _default_formats_3d() -> list[Literal["vti"]]:
    return ["vti"]


class Fields3DSpec(_Spec):
    """Fields as VTK image data (``fields/fluid_<step>.vti`` and a ``fluid.pvd`` series) and
    the bodies as tetrahedral meshes (``bodies_<step>.vtu``) for ParaView."""

    formats: Annotated[list[Literal["vti"]], Field(min_length=1), Strict(False)] = Field(
        default_factory=_default_formats_3d)
    every: PositiveInt = 10


class Meshes3DSpec(_Spec):
    """The bodies' surfaces per frame (OBJ or PLY) for Blender."""

    format: Literal["obj", "ply"] = "obj"
    every: PositiveInt = 1


class Probe3DSpec(_Spec):
    """One probe, sampled every ``outputs.probes_every`` steps into ``probes.csv``; as the 2D
    probe (`elastoflow.scenes.ProbeSpec`) with three components and 3D points."""

    kind: Literal["node_displacement", "body_force", "force", "pressure", "velocity",
                  "pressure_difference", "pressure_iterations"]
    body: Annotated[int, Field(ge=0)] | None = None
    node: Annotated[int, Field(ge=0)] | None = None
    point: Point3 | None = None
    bodies: Annotated[list[Annotated[int, Field(ge=0)]], Strict(False)] = Field(
        default_factory=list)
    obstacles: Annotated[list[Annotated[int, Field(ge=0)]], Strict(False)] = Field(
        default_factory=list)
    points: Annotated[list[Point3], Strict(False)] | None = None

    @model_validator(mode="after")
    def _needs(self) -> Probe3DSpec:
        if self.kind in ("node_displacement", "body_force") and self.body is None:
            raise ValueError(f"probe kind {self.kind!r} needs body (an index)")
        if self.kind == "node_displacement" and (self.node is None) == (self.point is None):
            raise ValueError("probe kind 'node_displacement' needs exactly one of node or point")
        if self.kind == "force" and not (self.bodies or self.obstacles):
            raise ValueError("probe kind 'force' needs bodies or obstacles (index lists)")
        if self.kind in ("pressure", "velocity") and self.point is None:
            raise ValueError(f"probe kind {self.kind!r} needs point ([x, y, z])")
        if self.kind == "pressure_difference" and (self.points is None or len(self.points) != 2):
            raise ValueError("probe kind 'pressure_difference' needs points (two [x, y, z])")
        return self


class Outputs3DSpec(_Spec):
    """Each output is off when left out."""

    video: Video3DSpec | None = None
    fields: Fields3DSpec | None = None
    meshes: Meshes3DSpec | None = None
    probes: Annotated[list[Probe3DSpec], Strict(False)] = Field(default_factory=list)
    probes_every: PositiveInt = 1
    checkpoint: CheckpointSpec | None = None


class Scene3D(_Spec):
    """A complete 3D simulation set-up (``[domain]`` with ``lz``)."""

    name: str = "scene"
    description: str = ""
    domain: Domain3DSpec
    fluid: Fluid3DSpec = Field(default_factory=Fluid3DSpec)
    boundaries: Boundaries3DSpec = Field(default_factory=Boundaries3DSpec)
    jets: Annotated[list[Jet3DSpec], Strict(False)] = Field(default_factory=list)
    obstacles: Annotated[list[Obstacle3DSpec], Strict(False)] = Field(default_factory=list)
    bodies: Annotated[list[Body3DSpec], Strict(False)] = Field(default_factory=list)
    time: TimeSpec
    coupling: Coupling3DSpec = Field(default_factory=Coupling3DSpec)
    outputs: Outputs3DSpec = Field(default_factory=Outputs3DSpec)
    base_dir: str | None = Field(default=None, exclude=True)
    """Folder that relative mesh paths are taken from (the scene file's folder); not saved."""
    source: str | None = Field(default=None, exclude=True)
    """Where the scene came from, for messages; not saved."""

    @property
    def dimension(self) -> int:
        return 3
