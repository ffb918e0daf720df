"""Compile the Numba kernels into the on-disk cache ahead of the first run.

Numba compiles each kernel the first time it is called and keeps the machine code in its
cache (``__pycache__`` beside the sources, or ``NUMBA_CACHE_DIR``). A fresh install therefore
spends about a minute of its first step compiling on two cores. `warm_up` runs every built-in
scene for two steps on a grid just large enough to reach the threaded variants of the kernels
and draws a frame of every view, then steps the parts no scene uses yet (the free surface's
semi-Lagrangian step, the 3D fluid with and without a sphere in it, tetrahedral bodies and
the 3D map, the dual-cell boundary), so that a later run finds everything compiled; ``make``
runs it once after installing (``elastoflow warmup``). Nothing is written but the cache.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

# Larger than the kernels' parallel threshold (96^2 points) so that both the serial variants
# (coarse multigrid levels) and the threaded ones are compiled; small enough to step quickly.
_GRID = 128
_VIEWS = ("speed", "vorticity", "pressure", "dye")


def warm_up(
    scenes: list[str] | None = None,
    report: Callable[[str, float], Any] | None = None,
) -> float:
    """Step each scene twice on a 128-cell-wide grid and render every view.

    Args:
        scenes: Built-in scene names (default: all of them).
        report: Called with ``(scene name, seconds)`` after each scene.

    Returns:
        Seconds spent in total.
    """
    import numpy as np

    from elastoflow._api import frame
    from elastoflow.render._kernels import rgb_to_yuv420
    from elastoflow.scenes import Scene3D, build_simulation, get_scene, list_scenes

    # The 3D scenes' kernels are those of the 3D parts below, compiled on small grids.
    names = ([name for name in list_scenes() if not isinstance(get_scene(name), Scene3D)]
             if scenes is None else scenes)
    start = time.perf_counter()
    for name in names:
        began = time.perf_counter()
        scene = get_scene(name)
        scene = scene.model_copy(update={"domain": scene.domain.model_copy(
            update={"nx": _GRID, "ny": None})})
        # Coarser than the scenes themselves: thin-body warnings would only be noise here.
        simulation = build_simulation(scene, warnings=[])
        for _ in range(2):
            simulation.step()
        for view in _VIEWS:
            image = frame(simulation, view)
        height, width = image.shape[0] // 2 * 2, image.shape[1] // 2 * 2
        planes = np.empty(height * width * 3 // 2, dtype=np.uint8)
        rgb_to_yuv420(np.ascontiguousarray(image[:height, :width]), planes)
        if report is not None:
            report(name, time.perf_counter() - began)
    if scenes is None:
        for name, warm in (("free surface", _free_surface), ("3D fluid", _fluid_3d),
                           ("3D bodies", _bodies_3d), ("3D obstacle", _obstacle_3d),
                           ("3D strong coupling", _monolithic_3d),
                           ("dual-cell boundary", _dual_cell),
                           ("flux-form advection", _flux_advection)):
            began = time.perf_counter()
            warm()
            if report is not None:
                report(name, time.perf_counter() - began)
    return time.perf_counter() - start


def _free_surface() -> None:
    """Two dam-break steps of the Python API with each advection scheme (the scenes
    dam_break and sloshing take MacCormack)."""
    from elastoflow.fluid import (
        DomainBoundaries,
        FluidSolver,
        FreeSurfaceSolver,
        level_set_box,
    )
    from elastoflow.grid import Grid2D

    grid = Grid2D(_GRID, _GRID // 2, 0.4 / _GRID)
    for advection in ("semi_lagrangian", "maccormack"):
        fluid = FluidSolver(grid, density=1000.0, viscosity=1e-6,
                            boundaries=DomainBoundaries.closed_box(), gravity=(0.0, -9.81),
                            advection=advection)
        solver = FreeSurfaceSolver(fluid)
        state = solver.state(level_set_box(grid, (0.0, 0.0, 0.1, 0.15)))
        for _ in range(2):
            solver.step(state, solver.stable_dt(state, cfl=0.8, dt_max=0.01))


def _fluid_3d() -> None:
    """Two steps of the 3D fluid with each advection scheme, on a grid above the kernels'
    thread threshold."""
    from elastoflow.fluid import DomainBoundaries3D, FluidSolver3D, FluidState3D, Inflow
    from elastoflow.grid import Grid3D

    grid = Grid3D(nx=40, ny=24, nz=24, h=1.0 / 24)
    for advection in ("semi_lagrangian", "maccormack"):
        solver = FluidSolver3D(grid, density=1.0, viscosity=1e-3,
                               boundaries=DomainBoundaries3D.channel(Inflow(1.0)),
                               gravity=(0.0, -1.0, 0.0), advection=advection)
        state = FluidState3D.zeros(grid)
        for index in range(2):
            solver.step(state, 0.01, 0.01 * index)


def _bodies_3d() -> None:
    """A tetrahedral body's explicit step, and the 3D boundary map of its surface."""
    import numpy as np

    from elastoflow.coupling import (
        build_boundary_map_3d,
        cut_distances_3d,
        face_open_fractions_3d,
        solid_cells_3d,
    )
    from elastoflow.grid import Grid3D
    from elastoflow.solid import ElasticBody3D, ExplicitFem, MaterialStVK, mesh_sphere

    mesh = mesh_sphere(0.3, 0.1)
    body = ElasticBody3D(mesh, MaterialStVK(1000.0, 1e5, 0.3), gravity=(0.0, -9.81, 0.0))
    state_in, state_out = body.state(), body.state()
    ExplicitFem().advance(body, state_in, state_out, 1e-3)
    points = mesh.points + 0.5
    surface = mesh.boundary_triangles
    bmap = build_boundary_map_3d(Grid3D(nx=16, ny=16, nz=16, h=1.0 / 16), points,
                                 np.zeros_like(points), surface)
    solid_cells_3d(bmap)
    # Twice: the second refills the first's arrays in the box (as the coupled steps do).
    face_open_fractions_3d(bmap, out=face_open_fractions_3d(bmap), out_box=(0, 0, 0, 4, 4, 4))
    cut_distances_3d(bmap)


def _obstacle_3d() -> None:
    """Two steps of the 3D fluid around a sphere with each advection scheme (the interior's
    kernels, 276 s to compile from scratch), and the traction on it."""
    import numpy as np

    from elastoflow.coupling import build_boundary_map_3d, force_traction_3d, interior_boundary_3d
    from elastoflow.fluid import DomainBoundaries3D, FluidSolver3D, FluidState3D, Inflow
    from elastoflow.grid import Grid3D
    from elastoflow.solid import mesh_sphere

    grid = Grid3D(nx=40, ny=24, nz=24, h=1.0 / 24)
    mesh = mesh_sphere(0.25, 0.1)
    points = mesh.points + np.array([0.6, 0.5, 0.5])
    bmap = build_boundary_map_3d(grid, points, np.zeros_like(points), mesh.boundary_triangles)
    interior = interior_boundary_3d(bmap)
    for advection in ("semi_lagrangian", "maccormack"):
        solver = FluidSolver3D(grid, density=1.0, viscosity=1e-2,
                               boundaries=DomainBoundaries3D.channel(Inflow(1.0)),
                               advection=advection)
        state = FluidState3D.zeros(grid)
        for index in range(2):
            solver.step(state, 0.01, 0.01 * index, interior)
    force_traction_3d(grid, bmap, state.velocity_x, state.velocity_y, state.velocity_z,
                      state.pressure, 1.0, 1e-2, interior)


def _monolithic_3d() -> None:
    """Two monolithic steps of a light cube in a closed box (the 3D interface flux, the
    coupled solve), and the 3D video's picture of the result."""
    from elastoflow.fluid import DomainBoundaries3D, FluidSolver3D
    from elastoflow.grid import Grid3D
    from elastoflow.render import render_scene_3d
    from elastoflow.simulation import Simulation
    from elastoflow.solid import ElasticBody3D, MaterialStVK, mesh_box

    grid = Grid3D(nx=12, ny=12, nz=12, h=1.0 / 12)
    solver = FluidSolver3D(grid, density=1000.0, viscosity=1e-3,
                           boundaries=DomainBoundaries3D.closed_box(), gravity=(0.0, -9.81, 0.0))
    mesh = mesh_box((0.3, 0.3, 0.3), counts=(3, 3, 3), origin=(0.35, 0.35, 0.35))
    body = ElasticBody3D(mesh, MaterialStVK(500.0, 1e6, 0.3), gravity=(0.0, -9.81, 0.0))
    simulation = Simulation(grid, solver, state=solver.rest_state(), bodies=[body], dt=0.005,
                            coupling="monolithic")
    simulation.run(2)
    render_scene_3d(grid, simulation.state.fluid,
                    surfaces=[(simulation.state.bodies[0].positions, mesh.boundary_triangles)],
                    time=simulation.time)


def _dual_cell() -> None:
    """The dual-cell boundary's interior and interface flux on a moving disc."""
    import numpy as np

    from elastoflow.coupling import (
        build_boundary_map,
        interface_flux,
        interior_boundary_dual_cell,
        obstacle_circle,
    )
    from elastoflow.grid import Grid2D

    grid = Grid2D(32, 32, 1.0 / 32)
    disc = obstacle_circle((0.5, 0.5), 0.2, segments=24)
    points = disc.points_at(0.0)
    bmap = build_boundary_map(grid, points, np.full_like(points, 0.1), disc.edges)
    interface_flux(grid, bmap, interior_boundary_dual_cell(grid, bmap))


def _flux_advection() -> None:
    """The flux form's kernels (``advection="upwind3"``, no built-in scene uses it), serial
    and threaded, without bodies and around an obstacle."""
    import numpy as np

    from elastoflow.coupling import build_boundary_map, interior_boundary_from_map, obstacle_circle
    from elastoflow.fluid import DomainBoundaries, FluidSolver, FluidState
    from elastoflow.grid import Grid2D

    for cells in (32, 160):
        grid = Grid2D(cells, cells // 2, 1.0 / cells)
        solver = FluidSolver(grid, density=1.0, viscosity=1e-3,
                             boundaries=DomainBoundaries.closed_box(), advection="upwind3")
        state = FluidState.zeros(grid)
        disc = obstacle_circle((0.5, 0.25), 0.1, segments=24)
        points = disc.points_at(0.0)
        bmap = build_boundary_map(grid, points, np.zeros_like(points), disc.edges)
        for interior in (None, interior_boundary_from_map(grid, bmap)):
            solver.advect(state, 0.5 / cells, interior)


_KERNEL_MODULES = ("fluid", "linalg", "solid", "coupling", "render")


def kernels_need_compiling() -> bool:
    """Whether a run would first compile kernels: some kernel module has no usable entry in
    Numba's disk cache (none written yet, or written for an older source). A guess from the
    cache's index files, for a message; False when it cannot tell."""
    import importlib

    try:
        from numba.core.registry import CPUDispatcher

        for name in _KERNEL_MODULES:
            module = importlib.import_module(f"elastoflow.{name}._kernels")
            found: list[Any] = [getattr(getattr(value, "_cache", None), "_cache_file", None)
                                for value in vars(module).values()
                                if isinstance(value, CPUDispatcher)]
            caches = [cache for cache in found if cache is not None]
            if caches and not any(cache._load_index() for cache in caches):
                return True
    except Exception:  # noqa: BLE001 - Numba's cache internals differ between versions
        return False
    return False
