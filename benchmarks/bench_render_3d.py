"""Time per frame of a 3D run's video picture (`render_scene_3d`) at 64^3, and of the two
libraries it was chosen against.

The state is ``bar_in_jet_3d`` (64^3) after ``--steps`` steps; the picture is its video's
(the z = 0.5 m speed slice, 640x480 plus the colour bar), drawn ``--frames`` times into one
array as a run does, with the bar's surface (336 triangles) and again with a sphere's of
4800. ``--alternatives`` also draws the same slice and sphere with matplotlib's mplot3d
(one Figure reused: Poly3DCollection + plot_surface with face colours, perspective) and,
where it can open an offscreen window, PyVista/VTK (one Plotter reused, the slice's
scalars and the surface's points updated each frame, ``screenshot``). Reported: the median
ms per frame and the first frame's (Numba compilation or window start).

Usage: ``python -m benchmarks render_3d [--frames N] [--steps N] [--size N] [--alternatives]``
(``--size``: cells across the domain, default 64).
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._common import markdown_table, write_results


def _state(steps: int, size: int) -> Any:
    from elastoflow.scenes import build_simulation, get_scene

    scene = get_scene("bar_in_jet_3d")
    if size != 64:
        scene = scene.model_copy(update={"domain": scene.domain.model_copy(
            update={"nx": size})})
    # A coarse grid's thin-bar warning would only be noise here.
    simulation = build_simulation(scene, warnings=[])
    for _ in range(steps):
        simulation.step()
    return simulation


def _sphere(segments: int = 60, rings: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """A latitude-longitude sphere of radius 0.15 m at (0.5, 0.55, 0.55), outward triangles:
    ``2 segments rings`` of them (4800), built in milliseconds (a tetrahedral ball of this
    surface takes seconds)."""
    polar = np.pi * np.arange(1, rings + 1) / (rings + 1)
    around = 2.0 * np.pi * np.arange(segments) / segments
    ring_points = np.stack([np.outer(np.sin(polar), np.cos(around)),
                            np.repeat(np.cos(polar)[:, None], segments, axis=1),
                            np.outer(np.sin(polar), np.sin(around))], axis=-1).reshape(-1, 3)
    points = np.concatenate([[[0.0, 1.0, 0.0]], ring_points, [[0.0, -1.0, 0.0]]])
    south = points.shape[0] - 1
    k = np.arange(segments)
    following = (k + 1) % segments
    triangles = [np.stack([np.zeros(segments, dtype=np.int64), 1 + following, 1 + k], axis=1)]
    for ring in range(rings - 1):
        top, bottom = 1 + ring * segments, 1 + (ring + 1) * segments
        triangles.append(np.stack([top + k, top + following, bottom + k], axis=1))
        triangles.append(np.stack([top + following, bottom + following, bottom + k], axis=1))
    last = 1 + (rings - 1) * segments
    triangles.append(np.stack([last + k, last + following, np.full(segments, south)], axis=1))
    return 0.15 * points + np.array([0.5, 0.55, 0.55]), np.concatenate(triangles)


def _row(case: str, surface: tuple[np.ndarray, np.ndarray], shape: tuple[int, ...],
         times: list[float], grid: str = "64^3") -> dict[str, Any]:
    return {"case": case, "grid": grid, "triangles": int(surface[1].shape[0]),
            "pixels": f"{shape[1]}x{shape[0]}", "frames": len(times) - 1,
            "ms_per_frame": 1e3 * statistics.median(times[1:]),
            "first_frame_ms": 1e3 * times[0]}


def measure_ours(simulation: Any, surface: tuple[np.ndarray, np.ndarray], frames: int,
                 case: str) -> dict[str, Any]:
    from elastoflow.render import render_scene_3d

    image = None
    times = []
    for k in range(frames + 1):
        start = time.perf_counter()
        image = render_scene_3d(simulation.grid, simulation.state.fluid, axis="z",
                                position=0.5, surfaces=[surface], time=simulation.time + k,
                                out=image)
        times.append(time.perf_counter() - start)
    assert image is not None
    return _row(case, surface, image.shape, times, f"{simulation.grid.nx}^3")


def measure_matplotlib(values: np.ndarray, surface: tuple[np.ndarray, np.ndarray],
                       frames: int) -> dict[str, Any]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib import colormaps
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    points, triangles = surface
    figure = plt.figure(figsize=(7.68, 4.8), dpi=100)
    axes = figure.add_subplot(projection="3d")
    x, y = np.meshgrid(np.linspace(0, 1, values.shape[0] + 1),
                       np.linspace(0, 1, values.shape[1] + 1), indexing="ij")
    times = []
    image = np.zeros((1, 1, 3), dtype=np.uint8)
    for _ in range(frames + 1):
        start = time.perf_counter()
        axes.clear()
        axes.set_proj_type("persp")
        colors = colormaps["jet"](values / max(values.max(), 1e-12))
        axes.plot_surface(x, y, np.full_like(x, 0.5), facecolors=colors, shade=False,
                          rstride=1, cstride=1)
        corners = points[triangles]
        normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        normals /= np.linalg.norm(normals, axis=1)[:, None]
        light = 0.3 + 0.7 * np.abs(normals @ np.array([0.3, 0.6, 0.74]))
        axes.add_collection3d(Poly3DCollection(corners, edgecolor="none",
                                               facecolors=light[:, None] * [0.94, 0.9, 0.8]))
        axes.set_xlim(0, 1)
        axes.set_ylim(0, 1)
        axes.set_zlim(0, 1)
        figure.canvas.draw()
        image = np.asarray(figure.canvas.buffer_rgba())[..., :3].copy()  # type: ignore[attr-defined]
        times.append(time.perf_counter() - start)
    plt.close(figure)
    return _row("matplotlib mplot3d", surface, image.shape, times)


def measure_pyvista(values: np.ndarray, surface: tuple[np.ndarray, np.ndarray],
                    frames: int) -> dict[str, Any]:
    import pyvista

    points, triangles = surface
    faces = np.hstack([np.full((triangles.shape[0], 1), 3), triangles]).ravel()
    mesh = pyvista.PolyData(points.copy(), faces)
    plane = pyvista.ImageData(dimensions=(values.shape[0] + 1, values.shape[1] + 1, 1),
                              spacing=(1.0 / values.shape[0], 1.0 / values.shape[1], 1.0),
                              origin=(0.0, 0.0, 0.5))
    plane.cell_data["speed"] = values.ravel(order="F")
    times = []
    start = time.perf_counter()
    plotter = pyvista.Plotter(off_screen=True, window_size=(768, 480))
    plotter.add_mesh(plane, scalars="speed", cmap="jet")
    plotter.add_mesh(mesh, color=(0.94, 0.9, 0.8))
    plotter.add_mesh(pyvista.Box((0, 1, 0, 1, 0, 1)).extract_all_edges(), color="grey")
    image = np.zeros((1, 1, 3), dtype=np.uint8)
    for k in range(frames + 1):
        if k:
            start = time.perf_counter()
        plane.cell_data["speed"] = values.ravel(order="F") * (1.0 + 0.01 * k)
        mesh.points = points + 1e-4 * k
        image = plotter.screenshot(return_img=True)
        times.append(time.perf_counter() - start)
    window = plotter.render_window.GetClassName()
    plotter.close()
    return _row(f"PyVista offscreen ({window})", surface, image.shape, times)


def main(argv: list[str] | None = None) -> list[dict[str, Any]]:
    """Run the benchmark, print a Markdown table, write ``results/render_3d.json``."""
    args = list(sys.argv[1:] if argv is None else argv)
    frames = int(args[args.index("--frames") + 1]) if "--frames" in args else 20
    steps = int(args[args.index("--steps") + 1]) if "--steps" in args else 10
    size = int(args[args.index("--size") + 1]) if "--size" in args else 64
    simulation = _state(steps, size)
    bar = simulation.body_geometry()[0]
    sphere = _sphere()
    rows = [measure_ours(simulation, bar, frames, "render_scene_3d, bar_in_jet_3d's bar"),
            measure_ours(simulation, sphere, frames, "render_scene_3d, sphere")]
    if "--alternatives" in args:
        from elastoflow.render import layer_values

        values = layer_values(simulation.grid, simulation.state.fluid, 2, 32, "speed")
        rows.append(measure_matplotlib(values, sphere, min(frames, 5)))
        try:
            rows.append(measure_pyvista(values, sphere, frames))
        except Exception as error:  # noqa: BLE001 - no GL context is the finding itself
            rows.append({"case": f"PyVista offscreen: {type(error).__name__}: {error}"})
    print(markdown_table(rows, ["case", "grid", "triangles", "pixels", "frames",
                                "ms_per_frame", "first_frame_ms"]))
    path = write_results("render_3d", rows)
    print(f"\nwrote {path}")
    return rows


if __name__ == "__main__":
    main()
