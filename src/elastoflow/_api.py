"""The notebook API: a scene by name or file to a ready simulation, and a frame as an array."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np


def load(scene: Any) -> Any:
    """A ready `Simulation` from a built-in scene name, a TOML path, or a `Scene` object.

    Example::

        import elastoflow
        sim = elastoflow.load("bar_in_jet")
        for _ in range(100):
            sim.step()
        speed_x = sim.state.fluid.velocity_x    # (nx+1, ny) [m/s]
        nodes = sim.state.bodies[0].positions   # (n, 2) [m]
        rgb = elastoflow.frame(sim, view="vorticity")    # (H, W, 3) uint8

    Raises:
        elastoflow.scenes.SceneError: unknown scene name or an invalid file (one line per
            problem, naming the key, the value and what is allowed).
    """
    from elastoflow.scenes import Scene, Scene3D, build_simulation, resolve_scene

    chosen = scene if isinstance(scene, Scene | Scene3D) else resolve_scene(str(Path(scene)) if isinstance(
        scene, Path) else scene)
    return build_simulation(chosen)


def frame(simulation: Any, view: str = "speed", *, style: str = "slice",
          **options: Any) -> np.ndarray:
    """The simulation's current frame as an RGB array (H, W, 3) uint8, as the videos show it.

    Args:
        simulation: A `Simulation`.
        view: "speed", "vorticity", "pressure" or "dye".
        style: A 3D simulation's look: "slice" draws it through a plane by
            `elastoflow.render.render_slice_3d` (``axis`` "x", "y" or "z", default "z";
            ``position`` [m], default the middle), its bodies' and obstacles' sections
            filled; "3d" in perspective by `elastoflow.render.render_scene_3d` (the same
            ``axis`` and ``position``; ``size``, ``azimuth``, ``elevation``), the bodies'
            and obstacles' surfaces shaded, as a 3D run's video shows it. Ignored in 2D.
        **options: Passed to `elastoflow.render.render_frame` (value_range, scale, colorbar);
            a free surface's level set is passed unless given.
    """
    from elastoflow.render import render_frame, render_scene_3d, render_slice_3d

    if getattr(simulation, "dimension", 2) == 3:
        if style == "3d":
            obstacles = [(obstacle.points_at(simulation.time), obstacle.triangles)
                         for obstacle in simulation.obstacles]
            return render_scene_3d(simulation.grid, simulation.state.fluid, view=view,
                                   surfaces=simulation.body_geometry(), obstacles=obstacles,
                                   time=simulation.time, **options)
        if style != "slice":
            raise ValueError(f"style = {style!r}: must be 'slice' or '3d'")
        solids = [(state.positions, body.mesh.tetrahedra)
                  for body, state in zip(simulation.bodies, simulation.state.bodies)]
        solids += [solid for obstacle in simulation.obstacles
                   if (solid := obstacle.solid_at(simulation.time)) is not None]
        return render_slice_3d(simulation.grid, simulation.state.fluid, view=view,
                               bodies=solids, time=simulation.time, **options)
    options.setdefault("level_set", getattr(simulation, "level_set", None))
    return render_frame(
        simulation.grid, simulation.state.fluid, simulation.body_geometry(),
        simulation.obstacles, view, simulation.time, **options,
    )
