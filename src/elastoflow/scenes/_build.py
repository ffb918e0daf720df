"""From a `Scene` (typed data) to the physics objects and a ready `Simulation`."""

from __future__ import annotations

import contextlib
import io
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from elastoflow.scenes._errors import SceneError
from elastoflow.scenes._schema import (
    BodySpec,
    CircleObstacleSpec,
    CouplingSpec,
    InflowSpec,
    MeshFileShapeSpec,
    MovingWallSpec,
    PolygonObstacleSpec,
    PolygonShapeSpec,
    RectangleObstacleSpec,
    RectangleShapeSpec,
    RodBodySpec,
    Scene,
    WindmillShapeSpec,
)
from elastoflow.scenes._schema3d import Coupling3DSpec, Scene3D

if TYPE_CHECKING:
    from elastoflow.grid import Grid2D
    from elastoflow.simulation import MonolithicCoupling, Simulation
    from elastoflow.solid import WallContact


def characteristic_speed(scene: Scene | Scene3D) -> float:
    """Largest speed the scene imposes [m/s]: inflows, moving walls, jets, obstacle motion,
    the initial velocity.

    Raises:
        SceneError: An initial velocity expression to evaluate on a grid larger than the
            memory allows, or that is not finite (see `initial_velocity`).
    """
    if isinstance(scene, Scene3D):
        from elastoflow.scenes._checks3d import characteristic_speed_3d

        return characteristic_speed_3d(scene)
    speeds = [0.0]
    if scene.fluid.initial_velocity is not None:
        speeds.append(_initial_speed(scene))
    for side in (scene.boundaries.left, scene.boundaries.right, scene.boundaries.bottom,
                 scene.boundaries.top):
        if isinstance(side, InflowSpec):
            speeds.append(abs(side.speed))
        elif isinstance(side, MovingWallSpec):
            speeds.append(abs(side.velocity))
    speeds.extend(math.hypot(*jet.velocity) for jet in scene.jets)
    for obstacle in scene.obstacles:
        if obstacle.motion is not None:
            speeds.append(math.hypot(*obstacle.motion.velocity))
    if scene.liquid is not None:
        speeds.append(_free_fall_speed(scene))
    return max(speeds)


def _liquid_top(scene: Scene) -> float:
    """The highest point of the initial liquid [m] (``liquid.height`` sampled at the cell
    centres' x when it is an expression)."""
    from elastoflow.scenes._expression import Expression

    liquid = scene.liquid
    assert liquid is not None
    tops = [box[3] for box in liquid.boxes]
    if isinstance(liquid.height, str):
        nx, _ = scene.domain.cells
        x = scene.domain.origin[0] + (np.arange(nx) + 0.5) * scene.domain.cell_size
        values = Expression(liquid.height).evaluate({"x": x})
        finite = values[np.isfinite(values)]
        if finite.size:
            tops.append(float(finite.max()))
    elif liquid.height is not None:
        tops.append(float(liquid.height))
    return min(max(tops, default=scene.domain.bounds[1]), scene.domain.bounds[3])


def _free_fall_speed(scene: Scene) -> float:
    """``sqrt(2 |g| H)`` [m/s], H from the highest point of the liquid, or of a body dropped
    into it, to the domain's bottom: the speed of water falling that far (a dam break's surge
    runs at about this)."""
    g = math.hypot(*scene.fluid.gravity)
    top = _liquid_top(scene)
    for body in scene.bodies:
        bounds = body.shape.bounds()
        if bounds is not None:
            top = max(top, min(bounds[3], scene.domain.bounds[3]))
    return math.sqrt(2.0 * g * max(top - scene.domain.bounds[1], 0.0))


def time_step(scene: Scene | Scene3D) -> float:
    """The fluid step [s]: ``time.dt``, or ``cfl * h / characteristic_speed``."""
    if scene.time.dt is not None:
        return scene.time.dt
    speed = characteristic_speed(scene)
    if speed <= 0.0:
        raise SceneError([(
            f"time.cfl = {scene.time.cfl}: needs a characteristic speed (inflow, moving wall, "
            "jet, or liquid under gravity); this scene has none, give time.dt instead"
        )], scene.source)
    dt = float(scene.time.cfl) * scene.domain.cell_size / speed  # type: ignore[arg-type]
    if not (dt > 0.0 and math.isfinite(dt)):
        raise SceneError([(f"time.cfl = {scene.time.cfl}: gives dt = {dt!r} s with cell side "
                          f"{scene.domain.cell_size:g} m and speed {speed:g} m/s; the time step "
                          "must be a finite positive number, give time.dt instead")], scene.source)
    return dt


MAX_STEPS = 10**12
"""Most fluid steps of one run (a million years at a million steps per second)."""


def step_count(scene: Scene | Scene3D) -> int:
    """Number of fluid steps of the whole run: ``time.steps`` or ``ceil(duration / dt)``.

    Raises:
        SceneError: More than `MAX_STEPS` steps.
    """
    if scene.time.steps is not None:
        count = float(scene.time.steps)
        key = f"time.steps = {scene.time.steps}"
    else:
        count = float(scene.time.duration) / time_step(scene)  # type: ignore[arg-type]
        key = f"time.duration = {scene.time.duration:g}"
    if not count <= MAX_STEPS:
        raise SceneError([(f"{key}: makes {count:.3g} steps of dt = {time_step(scene):.3g} s, "
                          f"more than {MAX_STEPS:.0e}")], scene.source)
    if scene.time.steps is not None:
        return scene.time.steps
    return max(1, math.ceil(count - 1e-9))


def build_grid(scene: Scene) -> Grid2D:
    from elastoflow.grid import Grid2D

    nx, ny = scene.domain.cells
    return Grid2D(nx=nx, ny=ny, h=scene.domain.cell_size, origin=scene.domain.origin)


def initial_velocity(scene: Scene, grid: Grid2D) -> tuple[np.ndarray, np.ndarray]:
    """The scene's velocity at t = 0 on the faces of ``grid``: u (nx+1, ny) sampled at the
    x-face centres, v (nx, ny+1) at the y-face centres [m/s]; zeros without
    ``fluid.initial_velocity``.

    Raises:
        SceneError: A component whose expression gives a value that is not finite (named by
            its key path, with a point where it fails).
    """
    from elastoflow.scenes._expression import Expression

    spec = scene.fluid.initial_velocity
    fields = []
    for key, faces in (("x", grid.faces_x), ("y", grid.faces_y)):
        x, y = faces()
        value = 0.0 if spec is None else getattr(spec, key)
        if not isinstance(value, str):
            fields.append(np.full(x.shape, float(value)))
            continue
        field = Expression(value).evaluate({"x": x, "y": y})
        bad = ~np.isfinite(field)
        if bad.any():
            i, j = np.argwhere(bad)[0]
            raise SceneError([(f"fluid.initial_velocity.{key} = {value!r}: is {field[i, j]} "
                               f"at (x, y) = ({x[i, j]:.6g}, {y[i, j]:.6g}) ({int(bad.sum())} "
                               f"of {bad.size} faces); must be finite on every "
                               f"{key}-face of the domain")], scene.source)
        fields.append(field)
    return fields[0], fields[1]


def _initial_speed(scene: Scene) -> float:
    """Largest initial face speed [m/s] (the expressions evaluated on the scene's grid once
    its memory is known to fit)."""
    from elastoflow.scenes._checks import check_memory

    spec = scene.fluid.initial_velocity
    if spec is None:
        return 0.0
    if not isinstance(spec.x, str) and not isinstance(spec.y, str):
        return math.hypot(float(spec.x), float(spec.y))
    problems = check_memory(scene)
    if problems:
        raise SceneError(problems, scene.source)
    u, v = initial_velocity(scene, build_grid(scene))
    return max(float(np.abs(u).max()), float(np.abs(v).max()))


def _initial_state(scene: Scene, grid: Grid2D) -> Any:
    """The fluid state at t = 0 when the scene sets an initial velocity (else None: the
    simulation starts at rest)."""
    from elastoflow.fluid import FluidState

    if scene.fluid.initial_velocity is None:
        return None
    state = FluidState.zeros(grid)
    state.velocity_x[...], state.velocity_y[...] = initial_velocity(scene, grid)
    return state


def liquid_level_set(scene: Scene, grid: Grid2D) -> np.ndarray:
    """The level set [m] (nx, ny) of the scene's initial liquid (``[liquid]``), negative in the
    water: the union of its boxes and of the layer below its height, redistanced when a
    height is given (``y - height(x)`` is a distance only for a flat surface).

    Raises:
        SceneError: A height expression that is not finite, or water that covers no cell
            centre.
    """
    from elastoflow.fluid import RedistanceFastSweeping, level_set_box, level_set_below
    from elastoflow.scenes._expression import Expression

    liquid = scene.liquid
    assert liquid is not None
    parts = [level_set_box(grid, box) for box in liquid.boxes]
    if liquid.height is not None:
        height = liquid.height
        if isinstance(height, str):
            x, _ = grid.cell_centers()
            values = Expression(height).evaluate({"x": x[:, 0]})
            bad = ~np.isfinite(values)
            if bad.any():
                i = int(np.argwhere(bad)[0][0])
                raise SceneError([(f"liquid.height = {height!r}: is {values[i]} at x = "
                                   f"{x[i, 0]:.6g}; must be finite over the domain")],
                                 scene.source)
            below = level_set_below(grid, lambda _: values[:, None])
        else:
            below = level_set_below(grid, float(height))
        phi = below.copy()
        RedistanceFastSweeping().redistance(below, grid.h, phi,
                                            np.zeros(grid.shape_cells, dtype=np.bool_))
        parts.append(phi)
    level_set = np.minimum.reduce(parts) if len(parts) > 1 else parts[0]
    if not np.any(level_set < 0.0):
        raise SceneError([("liquid: no cell centre lies in the water (boxes and height as "
                           f"given, cells of side {grid.h:g} m); give the water at least one "
                           "cell")], scene.source)
    return np.ascontiguousarray(level_set)


def build_free_surface(scene: Scene, fluid_solver: Any) -> Any:
    """The `elastoflow.simulation.FreeSurfaceScheme` of the scene's ``[liquid]``; with bodies
    or obstacles, `elastoflow.simulation.FreeSurfaceMonolithicCoupling` with the scene's
    choice of the bodies' implicit step."""
    from elastoflow import fluid
    from elastoflow.simulation import FreeSurfaceMonolithicCoupling, FreeSurfaceScheme

    liquid = scene.liquid
    assert liquid is not None
    viscosity = (fluid.ViscosityWholeGrid() if liquid.viscosity == "whole_grid"
                 else fluid.ViscosityStressFree())
    solver = fluid.FreeSurfaceSolver(
        fluid_solver,
        projection=fluid.GhostFluidProjection(theta_min=liquid.theta_min),
        transport=fluid.LevelSetTransport(redistance_interval=liquid.redistance_interval,
                                          volume_correction=liquid.volume_correction),
        viscosity=viscosity,
        extrapolation_layers=liquid.extrapolation_layers,
        maccormack_fallback=liquid.maccormack_fallback,
    )
    if scene.bodies or scene.obstacles:
        return FreeSurfaceMonolithicCoupling(solver, integrator=_monolithic(scene.coupling).fem)
    return FreeSurfaceScheme(solver)


def _side(spec: Any) -> Any:
    from elastoflow import fluid

    factories = {
        "no_slip": lambda s: fluid.WallNoSlip(),
        "free_slip": lambda s: fluid.WallFreeSlip(),
        "moving": lambda s: fluid.WallMoving(velocity=s.velocity),
        "inflow": lambda s: fluid.Inflow(speed=s.speed, profile=s.profile, ramp_time=s.ramp_time),
        "outflow": lambda s: fluid.Outflow(),
    }
    return factories[spec.type](spec)


def build_fluid_solver(scene: Scene, grid: Grid2D) -> Any:
    """The `FluidSolver` of the scene's fluid, domain sides and jets."""
    from elastoflow import fluid, linalg

    solvers = {"mgpcg": linalg.PoissonSolverMGPCG, "jacobi": linalg.PoissonSolverJacobi}
    b = scene.boundaries
    boundaries = fluid.DomainBoundaries(
        left=_side(b.left), right=_side(b.right), bottom=_side(b.bottom), top=_side(b.top)
    )
    jets = tuple(fluid.Jet(region=j.region, velocity=j.velocity, dye=j.dye) for j in scene.jets)
    advection = scene.fluid.advection
    assert advection is not None  # `Scene` fills in the default
    return fluid.FluidSolver(
        grid,
        density=scene.fluid.density,
        viscosity=scene.fluid.viscosity,
        boundaries=boundaries,
        jets=jets,
        gravity=scene.fluid.gravity,
        pressure_solver=solvers[scene.fluid.pressure_solver](rtol=scene.fluid.pressure_rtol),
        viscosity_solver=solvers[scene.fluid.viscosity_solver](rtol=scene.fluid.viscosity_rtol),
        advection=advection,
        incremental_pressure=scene.fluid.incremental_pressure,
        advecting_velocity=scene.fluid.advecting_velocity,
        viscosity_scheme=scene.fluid.viscosity_scheme,
        pressure_guess=scene.fluid.pressure_guess,
    )


def _circle_polygon(center: tuple[float, float], radius: float, segments: int) -> np.ndarray:
    angles = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    return np.column_stack(
        (center[0] + radius * np.cos(angles), center[1] + radius * np.sin(angles))
    )


def obstacle_polygon(spec: Any) -> np.ndarray:
    """The obstacle's outline at rest, counter-clockwise, shape (k, 2) [m]."""
    if isinstance(spec, CircleObstacleSpec):
        return _circle_polygon(spec.center, spec.radius, spec.segments)
    if isinstance(spec, RectangleObstacleSpec):
        x0, y0, x1, y1 = spec.box
        return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=np.float64)
    if isinstance(spec, PolygonObstacleSpec):
        polygon = np.asarray(spec.points, dtype=np.float64)
        if len(polygon) > 3 and np.array_equal(polygon[0], polygon[-1]):
            polygon = polygon[:-1]
        x, y = polygon[:, 0], polygon[:, 1]
        if np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y) < 0.0:
            polygon = polygon[::-1].copy()
        return polygon
    raise TypeError(f"unknown obstacle spec {type(spec).__name__}")


def build_obstacles(scene: Scene) -> list[Any]:
    """The scene's obstacles (`elastoflow.coupling.Obstacle`), in order.

    Raises:
        SceneError: An outline the coupling layer refuses (named by its key path).
    """
    from elastoflow import coupling

    obstacles = []
    for index, spec in enumerate(scene.obstacles):
        motion = None
        try:
            if spec.motion is not None:
                motion = coupling.RigidMotion(
                    velocity=spec.motion.velocity,
                    angular_velocity=spec.motion.angular_velocity,
                    center=spec.motion.center,
                )
            obstacles.append(coupling.Obstacle(obstacle_polygon(spec), motion=motion))
        except ValueError as error:
            raise SceneError([f"obstacles.{index}: {error}"], scene.source) from None
    return obstacles


def build_mesh(body: BodySpec, base_dir: str | None = None) -> Any:
    """The body's rest mesh (`elastoflow.solid.TriangleMesh`)."""
    from elastoflow import solid

    shape = body.shape
    if isinstance(shape, RectangleShapeSpec):
        x0, y0, x1, y1 = shape.box
        return solid.mesh_rectangle(x1 - x0, y1 - y0, counts=shape.divisions, origin=(x0, y0),
                                    pattern=shape.pattern)
    if isinstance(shape, WindmillShapeSpec):
        return solid.mesh_windmill(
            shape.hub_radius, shape.blades, shape.radius - shape.hub_radius, shape.blade_width,
            center=shape.center, element_size=shape.element_size, angle=shape.angle,
        )
    if isinstance(shape, PolygonShapeSpec):
        return solid.mesh_from_polygon(np.asarray(shape.points, float), element_size=shape.element_size)
    if isinstance(shape, MeshFileShapeSpec):
        return _read_mesh_file(shape, base_dir)
    raise TypeError(f"unknown body shape {type(shape).__name__}")


def _read_mesh_file(shape: MeshFileShapeSpec, base_dir: str | None) -> Any:
    """The mesh of a ``type = "mesh"`` shape, scaled and moved; every failure of the file (not
    there, a folder, an unknown format, damaged, not a valid triangle mesh) as a SceneError
    naming ``shape.path``."""
    import meshio

    from elastoflow import solid

    path = Path(shape.path)
    if not path.is_absolute() and base_dir is not None:
        path = Path(base_dir) / path
    key = f"shape.path = {shape.path!r}"
    if not path.exists():
        raise SceneError([f"{key}: mesh file not found ({path})"])
    if not path.is_file():
        raise SceneError([f"{key}: {path} is not a file (a folder?); must name a mesh file"])
    known = meshio.extension_to_filetypes
    suffixes = "".join(path.suffixes[-2:]).lower()
    if path.suffix.lower() not in known and suffixes not in known:
        raise SceneError([(f"{key}: unknown mesh format {path.suffix or '(no extension)'!r}; "
                          "allowed: a file meshio reads, e.g. .msh, .vtu, .vtk, .obj, .ply, "
                          ".off, .stl, .xdmf")])
    chatter = io.StringIO()
    try:
        # Some meshio readers print their complaint and call sys.exit.
        with contextlib.redirect_stdout(chatter), contextlib.redirect_stderr(chatter):
            mesh = solid.read_mesh(path)
    except ValueError as error:
        raise SceneError([f"{key}: not a valid triangle mesh: {error}"]) from None
    except (Exception, SystemExit) as error:  # noqa: BLE001 - meshio fails with any type
        detail = " ".join(chatter.getvalue().split()) or str(error) or type(error).__name__
        raise SceneError([(f"{key}: cannot read the mesh file ({type(error).__name__}: "
                           f"{detail}); it may be damaged or not in the format its extension "
                           "says")]) from None
    points = mesh.points * shape.scale + np.asarray(shape.offset, float)
    try:
        return solid.TriangleMesh(points, mesh.triangles)
    except ValueError as error:
        raise SceneError([(f"shape.scale = {shape.scale:g}: the scaled mesh is not valid: "
                          f"{error}")]) from None


def build_rod(scene: Scene, index: int) -> Any:
    """Body ``index`` of the scene, a rod spec, as an `elastoflow.solid.RodBody` at rest.

    Raises:
        SceneError: A material or line the rod refuses (named by its key path).
    """
    from elastoflow import solid

    spec = scene.bodies[index]
    assert isinstance(spec, RodBodySpec)
    m = spec.material
    try:
        material = solid.MaterialRod(
            density=m.density, young_modulus=m.young_modulus, thickness=m.thickness,
            bending_stiffness=m.bending_stiffness, damping_time=m.damping_time,
        )
    except ValueError as error:
        raise SceneError([f"bodies.{index}.material: {error}"], scene.source) from None
    try:
        return solid.RodBody(spec.shape.nodes(), material, clamped=tuple(spec.clamped),
                             gravity=scene.fluid.gravity)
    except ValueError as error:
        raise SceneError([f"bodies.{index}.shape: {error}"], scene.source) from None


def build_bodies(scene: Scene) -> list[Any]:
    """The scene's bodies in order, at rest: `elastoflow.solid.ElasticBody` for triangle
    shapes, `elastoflow.solid.RodBody` for rods.

    Raises:
        SceneError: A shape that cannot be meshed or read, a constraint that selects no node or
            a node the mesh does not have (named by its key path).
    """
    from elastoflow import solid

    bodies = []
    for index, spec in enumerate(scene.bodies):
        if isinstance(spec, RodBodySpec):
            bodies.append(build_rod(scene, index))
            continue
        try:
            mesh = build_mesh(spec, scene.base_dir)
        except SceneError as error:
            raise SceneError([f"bodies.{index}.{p}" for p in error.problems],
                             scene.source) from None
        except (ValueError, ArithmeticError) as error:
            raise SceneError([(f"bodies.{index}.shape = {spec.shape.type}: cannot mesh it: "
                              f"{error}")], scene.source) from None
        m = spec.material
        try:
            material = solid.MaterialStVK(
                density=m.density, young_modulus=m.young_modulus, poisson_ratio=m.poisson_ratio,
                damping_lambda=m.damping_lambda, damping_mu=m.damping_mu, plane=m.plane,
            )
        except ValueError as error:
            raise SceneError([f"bodies.{index}.material: {error}"], scene.source) from None
        fixed: np.ndarray = np.zeros(0, dtype=np.int64)
        if spec.fixed is not None:
            if any(node >= mesh.point_count for node in spec.fixed.nodes):
                raise SceneError([(f"bodies.{index}.fixed.nodes = {spec.fixed.nodes}: the mesh "
                                   f"has nodes 0..{mesh.point_count - 1}")], scene.source)
            parts = [np.asarray(spec.fixed.nodes, dtype=np.int64)]
            if spec.fixed.box is not None:
                in_box = solid.nodes_in_box(mesh, spec.fixed.box)
                if in_box.size == 0:
                    raise SceneError([(f"bodies.{index}.fixed.box = {list(spec.fixed.box)}: "
                                       "contains no node of the body's mesh")], scene.source)
                parts.append(in_box)
            if spec.fixed.obstacle is not None:
                parts.append(_nodes_on_obstacle(scene, index, mesh))
            fixed = np.unique(np.concatenate(parts))
        pivot = None if spec.pivot is None else solid.nearest_node(mesh, spec.pivot)
        try:
            bodies.append(solid.ElasticBody(
                mesh, material, fixed_nodes=fixed, pivot_node=pivot, gravity=scene.fluid.gravity,
            ))
        except ValueError as error:
            raise SceneError([f"bodies.{index}: {error}"], scene.source) from None
        except ArithmeticError as error:
            # Denormal or extreme material values: the wave speed or substep is not a number.
            raise SceneError([(f"bodies.{index}.material: its values give no finite stable "
                               f"substep ({type(error).__name__}: {error}); use physical "
                               "values")], scene.source) from None
    return bodies


def obstacle_outline_distance(spec: Any, points: np.ndarray) -> np.ndarray:
    """Distance [m] of each point (p, 2) to the obstacle's outline at rest: to the exact
    circle for a circle, to the polygon's edges otherwise; shape (p,)."""
    from elastoflow.scenes import _geometry as geometry

    if isinstance(spec, CircleObstacleSpec):
        return np.abs(np.linalg.norm(points - np.asarray(spec.center), axis=1) - spec.radius)
    return geometry.distance_to_segments(points, *geometry.polygon_edges(obstacle_polygon(spec)))


def _nodes_on_obstacle(scene: Scene, index: int, mesh: Any) -> np.ndarray:
    """The nodes of body ``index``'s rest mesh that ``fixed.obstacle`` holds: those within
    ``fixed.tolerance`` (default a quarter cell) of the obstacle's outline.

    Raises:
        SceneError: No node lies that near.
    """
    from elastoflow.scenes._checks import OVERLAP_CELLS
    from elastoflow.scenes._errors import _show, obstacle_index

    fixed = scene.bodies[index].fixed
    assert fixed is not None and fixed.obstacle is not None
    found = obstacle_index(scene, fixed.obstacle)
    assert found is not None  # parse_scene checked the reference
    tolerance = (fixed.tolerance if fixed.tolerance is not None
                 else OVERLAP_CELLS * scene.domain.cell_size)
    distance = obstacle_outline_distance(scene.obstacles[found], mesh.points)
    chosen = np.flatnonzero(distance <= tolerance).astype(np.int64)
    if chosen.size == 0:
        given = ("" if fixed.tolerance is not None
                 else " (the default, a quarter cell; set bodies.N.fixed.tolerance)")
        raise SceneError([(f"bodies.{index}.fixed.obstacle = {_show(fixed.obstacle)}: no node "
                           f"of the body's mesh lies within {tolerance:.4g} m{given} of "
                           f"obstacles.{found}'s outline (the nearest is "
                           f"{float(distance.min()):.4g} m away); the body must touch the "
                           "obstacle where it is clamped")], scene.source)
    return chosen


def build_simulation(scene: Scene | Scene3D, *, steps: int | None = None,
                     warnings: list[str] | None = None) -> Simulation:
    """The ready-to-step `Simulation` of ``scene`` (fluid at rest, bodies at their rest shape).

    Everything a run needs is built and checked here, so that a scene that builds only fails
    later by its physics: first the memory the run needs against the memory available (before
    anything large is allocated), then the meshes, obstacles and constraints, then the
    geometry (`elastoflow.scenes._checks.check_built`: bodies and obstacles inside the domain
    and apart, bodies resolved by the grid, jets in the fluid, pivots and probes on their
    bodies, moving obstacles inside the domain for the whole run).

    Args:
        scene: The scene.
        steps: Fluid steps the run will take (default: the scene's); moving obstacles must stay
            inside the domain until then.
        warnings: A list that receives one line per warning (a body only a few cells across);
            None issues them as `SceneWarning`.

    Raises:
        SceneError: Everything found, one line per problem naming the key path, the value and
            what is allowed.
    """
    from elastoflow.scenes._checks import check_built, check_memory
    from elastoflow.simulation import Simulation

    if isinstance(scene, Scene3D):
        from elastoflow.scenes._build3d import build_simulation_3d

        return build_simulation_3d(scene, steps=steps, warnings=warnings)
    problems = check_memory(scene)
    if problems:
        raise SceneError(problems, scene.source)
    dt = time_step(scene)
    total = step_count(scene) if steps is None else steps
    grid = build_grid(scene)
    bodies = build_bodies(scene)
    obstacles = build_obstacles(scene)
    problems, found = check_built(scene, grid, [b.mesh for b in bodies], obstacles,
                                  steps=total, dt=dt)
    if problems:
        raise SceneError(problems, scene.source)
    if warnings is not None:
        warnings.extend(found)
    else:
        import warnings as _warnings

        for line in found:
            _warnings.warn(line, SceneWarning, stacklevel=2)
    try:
        fluid_solver = build_fluid_solver(scene, grid)
    except (ValueError, ArithmeticError) as error:
        raise SceneError([f"fluid: {error}"], scene.source) from None
    state = _initial_state(scene, grid)
    if scene.liquid is not None:
        level_set = liquid_level_set(scene, grid)
        try:
            return Simulation(grid, fluid_solver, state=state, cfl_limit=scene.time.cfl_limit,
                              bodies=bodies, obstacles=obstacles, dt=dt,
                              coupling=build_free_surface(scene, fluid_solver),
                              boundary=scene.coupling.boundary, level_set=level_set,
                              contact=_wall_contact(scene.coupling))
        except (ValueError, ArithmeticError) as error:
            raise SceneError([f"liquid: {error}"], scene.source) from None
    try:
        return Simulation(
            grid,
            fluid_solver,
            state=state,
            cfl_limit=scene.time.cfl_limit,
            bodies=bodies,
            obstacles=obstacles,
            dt=dt,
            substeps=scene.time.substeps,
            force_model=scene.coupling.force_model,
            alpha=scene.coupling.alpha,
            force_relaxation=scene.coupling.force_relaxation,
            added_mass=scene.coupling.added_mass,
            coupling=(_monolithic(scene.coupling)
                      if scene.coupling.scheme == "monolithic" else "explicit"),
            boundary=scene.coupling.boundary,
            contact=_wall_contact(scene.coupling),
        )
    except (ValueError, ArithmeticError) as error:
        raise SceneError([f"time or coupling: {error}"], scene.source) from None


def _wall_contact(spec: CouplingSpec) -> WallContact | None:
    """The bodies' contact with the walls from ``coupling.wall_contact`` / ``wall_friction``."""
    from elastoflow.solid import WallContact

    return WallContact(friction=spec.wall_friction) if spec.wall_contact else None


def _monolithic(spec: CouplingSpec | Coupling3DSpec) -> MonolithicCoupling:
    """The monolithic scheme with the scene's choice of the bodies' implicit step (a 3D
    `Simulation` hands its integrator to `MonolithicCoupling3D`)."""
    from elastoflow.simulation import MonolithicCoupling
    from elastoflow.solid import EnergyMomentumFem, MidpointFem

    if spec.integrator == "newmark":
        return MonolithicCoupling(gamma=spec.newmark_gamma)
    if spec.integrator == "midpoint":
        return MonolithicCoupling(integrator=MidpointFem())
    return MonolithicCoupling(integrator=EnergyMomentumFem(spec.numerical_damping))


class SceneWarning(UserWarning):
    """A scene that runs but may give poor results (a body only a few cells across)."""


def resolve_scene(name_or_path: str) -> Scene | Scene3D:
    """A built-in scene by name, or a scene file by path (anything ending in .toml or that
    exists on disk)."""
    from elastoflow.scenes._library import get_scene
    from elastoflow.scenes._toml import load_scene

    path = Path(name_or_path)
    looks_like_a_path = path.suffix != "" or len(path.parts) > 1
    if name_or_path.endswith(".toml") or path.exists() or looks_like_a_path:
        return load_scene(path)
    return get_scene(name_or_path)
