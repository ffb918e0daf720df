"""From a `Scene3D` to the 3D physics objects and a ready 3D `Simulation`."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from elastoflow.scenes import _checks
from elastoflow.scenes._checks3d import SIDES_3D, shape_bounds
from elastoflow.scenes._errors import SceneError
from elastoflow.scenes._schema3d import (
    AXES,
    Body3DSpec,
    BoxObstacleSpec,
    BoxShape3DSpec,
    CylinderObstacleSpec,
    CylinderShape3DSpec,
    MeshFile3DSpec,
    Obstacle3DSpec,
    RigidMotion3DSpec,
    Scene3D,
    SphereObstacleSpec,
    SphereShape3DSpec,
)

if TYPE_CHECKING:
    from elastoflow.coupling import Obstacle3D, RigidMotion3D
    from elastoflow.fluid import FluidSolver3D, Side3D
    from elastoflow.grid import Grid3D
    from elastoflow.simulation import Simulation
    from elastoflow.solid import ElasticBody3D, TetrahedralMesh

# Memory of a 3D run per cell (fields, the solvers' work arrays and multigrid levels, the
# interior's face arrays; measured peak about 1.1 kB per cell at 64^3 and 96^3, see
# docs/benchmarks.md) and per tetrahedron (the body's arrays and the map's share).
BYTES_PER_CELL_3D = 1200.0
BYTES_PER_TETRAHEDRON = 400.0
BYTES_RUNTIME_3D = 400e6

# A cyclic permutation of the coordinates takes the z axis of the built-in cylinder mesh to
# each axis and keeps every element's orientation.
_AXIS_ORDER = {"x": (2, 0, 1), "y": (1, 2, 0), "z": (0, 1, 2)}


def build_grid_3d(scene: Scene3D) -> Grid3D:
    from elastoflow.grid import Grid3D

    nx, ny, nz = scene.domain.cells
    return Grid3D(nx, ny, nz, scene.domain.cell_size, origin=scene.domain.origin)


def _side(spec: object) -> Side3D:
    from elastoflow import fluid
    from elastoflow.scenes._schema import FreeSlipSpec, InflowSpec, NoSlipSpec
    from elastoflow.scenes._schema3d import MovingWall3DSpec

    if isinstance(spec, NoSlipSpec):
        return fluid.WallNoSlip()
    if isinstance(spec, FreeSlipSpec):
        return fluid.WallFreeSlip()
    if isinstance(spec, MovingWall3DSpec):
        return fluid.WallMoving3D(velocity=spec.velocity)
    if isinstance(spec, InflowSpec):
        return fluid.Inflow(speed=spec.speed, profile=spec.profile, ramp_time=spec.ramp_time)
    return fluid.Outflow()


def build_fluid_solver_3d(scene: Scene3D, grid: Grid3D) -> FluidSolver3D:
    """The `FluidSolver3D` of the scene's fluid, sides and jets."""
    from elastoflow import fluid, linalg

    sides = {name: _side(getattr(scene.boundaries, name)) for name in SIDES_3D}
    jets = tuple(fluid.Jet3D(region=j.region, velocity=j.velocity, dye=j.dye)
                 for j in scene.jets)
    spec = scene.fluid
    return fluid.FluidSolver3D(
        grid, density=spec.density, viscosity=spec.viscosity,
        boundaries=fluid.DomainBoundaries3D(**sides), gravity=spec.gravity, jets=jets,
        buoyancy=spec.buoyancy or None,
        pressure_solver=linalg.PoissonSolverMGPCG3D(rtol=spec.pressure_rtol),
        viscosity_solver=linalg.PoissonSolverMGPCG3D(rtol=spec.viscosity_rtol),
        advection=spec.advection, incremental_pressure=spec.incremental_pressure,
    )


def _motion(spec: RigidMotion3DSpec | None) -> RigidMotion3D | None:
    from elastoflow.coupling import RigidMotion3D

    if spec is None:
        return None
    return RigidMotion3D(velocity=spec.velocity, angular_velocity=spec.angular_velocity)


def build_obstacle_3d(spec: Obstacle3DSpec, h: float) -> Obstacle3D:
    """One obstacle's closed surface; triangles of half a cell unless the scene says."""
    from elastoflow import coupling

    size = spec.element_size or 0.5 * h
    motion = _motion(spec.motion)
    if isinstance(spec, SphereObstacleSpec):
        return coupling.obstacle_sphere(spec.center, spec.radius, size, motion=motion)
    if isinstance(spec, BoxObstacleSpec):
        x0, y0, z0, x1, y1, z1 = spec.box
        return coupling.obstacle_box((x0, y0, z0), (x1, y1, z1), size, motion=motion)
    assert isinstance(spec, CylinderObstacleSpec)
    return coupling.obstacle_cylinder(spec.center, spec.radius, spec.length, size,
                                      axis=AXES.index(spec.axis), motion=motion)


def build_mesh_3d(spec: Body3DSpec, h: float, base_dir: str | None = None) -> TetrahedralMesh:
    """A body's rest mesh; elements of a fluid cell's side unless the scene says."""
    from elastoflow import solid

    shape = spec.shape
    if isinstance(shape, BoxShape3DSpec):
        x0, y0, z0, x1, y1, z1 = shape.box
        size = (x1 - x0, y1 - y0, z1 - z0)
        if shape.divisions is not None:
            return solid.mesh_box(size, counts=shape.divisions, origin=(x0, y0, z0))
        return solid.mesh_box(size, shape.element_size or h, origin=(x0, y0, z0))
    if isinstance(shape, SphereShape3DSpec):
        return solid.mesh_sphere(shape.radius, shape.element_size or h, center=shape.center)
    if isinstance(shape, CylinderShape3DSpec):
        mesh = solid.mesh_cylinder(shape.radius, shape.length, shape.element_size or h)
        points = mesh.points[:, _AXIS_ORDER[shape.axis]] + np.asarray(shape.center)
        return solid.TetrahedralMesh(points, mesh.tetrahedra)
    assert isinstance(shape, MeshFile3DSpec)
    path = Path(shape.path)
    if not path.is_absolute() and base_dir is not None:
        path = Path(base_dir) / path
    mesh = solid.read_tetrahedral_mesh(path)
    return solid.TetrahedralMesh(mesh.points * shape.scale + np.asarray(shape.offset),
                                 mesh.tetrahedra)


def build_bodies_3d(scene: Scene3D) -> list[ElasticBody3D]:
    """The scene's elastic bodies, one line per problem on failure."""
    from elastoflow import solid

    h = scene.domain.cell_size
    bodies, problems = [], []
    for index, spec in enumerate(scene.bodies):
        try:
            mesh = build_mesh_3d(spec, h, scene.base_dir)
        except (OSError, ValueError) as error:
            problems.append(f"bodies.{index}.shape: {error}")
            continue
        fixed: list[int] = []
        if spec.fixed is not None:
            if spec.fixed.box is not None:
                in_box = solid.nodes_in_box_3d(mesh, spec.fixed.box)
                if in_box.size == 0:
                    problems.append(f"bodies.{index}.fixed.box = {list(spec.fixed.box)}: holds "
                                    "no node of the body; it must contain at least one")
                fixed.extend(int(n) for n in in_box)
            for node in spec.fixed.nodes:
                if node >= mesh.point_count:
                    problems.append(f"bodies.{index}.fixed.nodes: {node} is not a node (the "
                                    f"mesh has {mesh.point_count})")
            fixed.extend(n for n in spec.fixed.nodes if n < mesh.point_count)
        material = solid.MaterialStVK(
            spec.material.density, spec.material.young_modulus, spec.material.poisson_ratio,
            damping_lambda=spec.material.damping_lambda, damping_mu=spec.material.damping_mu)
        bodies.append(solid.ElasticBody3D(mesh, material, fixed_nodes=sorted(set(fixed)),
                                          gravity=scene.fluid.gravity))
    if problems:
        raise SceneError(problems, scene.source)
    return bodies


def memory_parts_3d(scene: Scene3D) -> list[tuple[str, float]]:
    """Memory of each part of a 3D run [bytes], by the key that sizes it: the grid, then
    each body's mesh (about six tetrahedra per element-size cube of its bounding box)."""
    cells = math.prod(scene.domain.cells)
    h = scene.domain.cell_size
    nx, ny, nz = scene.domain.cells
    key = (f"domain.nx = {scene.domain.nx}" if scene.domain.nx is not None
           else f"domain.h = {h:g}")
    parts = [(f"{key} ({nx} x {ny} x {nz} cells)", cells * BYTES_PER_CELL_3D)]
    for index, body in enumerate(scene.bodies):
        bounds = shape_bounds(body.shape)
        if bounds is None:
            continue
        divisions = getattr(body.shape, "divisions", None)
        if divisions is not None:
            elements = 6.0 * math.prod(divisions)
            name = f"bodies.{index}.shape.divisions = {list(divisions)}"
        else:
            size = getattr(body.shape, "element_size", None) or h
            volume = math.prod(bounds[k + 3] - bounds[k] for k in range(3))
            elements = 6.0 * volume / size ** 3
            name = f"bodies.{index}.shape.element_size = {size:g}"
        parts.append((f"{name} (~{elements:.3g} tetrahedra)", elements * BYTES_PER_TETRAHEDRON))
    return parts


def memory_estimate_3d(scene: Scene3D) -> float:
    """Memory a run of the 3D ``scene`` needs [bytes] (grid and bodies)."""
    return BYTES_RUNTIME_3D + sum(share for _, share in memory_parts_3d(scene))


def _check_built(scene: Scene3D, grid: Grid3D, bodies: list[ElasticBody3D]) -> list[str]:
    problems = []
    low = np.asarray(grid.origin, dtype=np.float64)
    high = low + grid.h * np.array(grid.shape_cells)
    for index, body in enumerate(bodies):
        points = body.mesh.points
        if (points < low - 1e-12).any() or (points > high + 1e-12).any():
            problems.append(f"bodies.{index}.shape: the mesh reaches "
                            f"{np.round(points.min(axis=0), 6).tolist()} to "
                            f"{np.round(points.max(axis=0), 6).tolist()}, outside the domain")
    return problems


def _check_motions(scene: Scene3D, grid: Grid3D, obstacles: list[Obstacle3D],
                   duration: float) -> list[str]:
    """Moving obstacles must stay inside the domain for the whole run (sampled at 65
    times)."""
    problems = []
    low = np.asarray(grid.origin, dtype=np.float64)
    high = low + grid.h * np.array(grid.shape_cells)
    for index, obstacle in enumerate(obstacles):
        if obstacle.motion is None:
            continue
        for time in np.linspace(0.0, duration, 65):
            points = obstacle.points_at(float(time))
            if (points < low - 1e-12).any() or (points > high + 1e-12).any():
                problems.append(f"obstacles.{index}.motion: the obstacle leaves the domain at "
                                f"t = {time:.4g} s, before the run ends at {duration:.4g} s")
                break
    return problems


def build_simulation_3d(scene: Scene3D, *, steps: int | None = None,
                        warnings: list[str] | None = None) -> Simulation:
    """The ready-to-step 3D `Simulation` of ``scene``.

    Raises:
        SceneError: One line per problem.
    """
    from elastoflow.scenes._build import _monolithic, step_count, time_step
    from elastoflow.simulation import Simulation
    from elastoflow.solid import WallContact

    available = _checks.available_memory()
    need = memory_estimate_3d(scene)
    if available is not None and need > available:
        # Named by the part that takes most of it.
        key, _ = max(memory_parts_3d(scene), key=lambda part: part[1])
        raise SceneError([f"{key}: the run would need about {need / 2**30:.3g} GB of memory, "
                          f"more than the {available / 2**30:.3g} GB available; use fewer "
                          "cells or elements"], scene.source)
    dt = time_step(scene)
    grid = build_grid_3d(scene)
    bodies = build_bodies_3d(scene)
    try:
        obstacles = [build_obstacle_3d(spec, grid.h) for spec in scene.obstacles]
    except ValueError as error:
        raise SceneError([f"obstacles: {error}"], scene.source) from None
    total = step_count(scene) if steps is None else steps
    problems = _check_built(scene, grid, bodies) + _check_motions(scene, grid, obstacles,
                                                                 total * dt)
    if problems:
        raise SceneError(problems, scene.source)
    found = []
    for index, body in enumerate(bodies):
        extent = body.mesh.points.max(axis=0) - body.mesh.points.min(axis=0)
        if extent.min() < 2.0 * grid.h:
            found.append(f"bodies.{index}: {extent.min():.3g} m thin, under two cells of "
                         f"{grid.h:g} m; the fluid sees it only coarsely")
    if warnings is not None:
        warnings.extend(found)
    else:
        import warnings as _warnings

        from elastoflow.scenes._build import SceneWarning

        for line in found:
            _warnings.warn(line, SceneWarning, stacklevel=2)
    try:
        fluid_solver = build_fluid_solver_3d(scene, grid)
    except (ValueError, ArithmeticError) as error:
        raise SceneError([f"fluid: {error}"], scene.source) from None
    # Under gravity the run starts from the hydrostatic pressure: from zero pressure the first
    # step's traction would miss part of the buoyancy (13 % on a neutrally buoyant sphere at
    # rest, which then dropped and bounced) and the walls would stir the fluid.
    state = fluid_solver.rest_state()
    for field, value in zip(state.velocity(), scene.fluid.initial_velocity, strict=True):
        field[...] = value
    try:
        return Simulation(grid, fluid_solver, state=state, bodies=bodies, obstacles=obstacles,
                          dt=dt, substeps=scene.time.substeps,
                          force_relaxation=scene.coupling.force_relaxation,
                          coupling=(_monolithic(scene.coupling)
                                    if scene.coupling.scheme == "monolithic" else "explicit"),
                          cfl_limit=scene.time.cfl_limit,
                          contact=(WallContact(friction=scene.coupling.wall_friction)
                                   if scene.coupling.wall_contact else None))
    except (ValueError, ArithmeticError) as error:
        raise SceneError([f"time or coupling: {error}"], scene.source) from None
