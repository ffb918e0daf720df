"""From a sweep file to checked points: each point's scene, built once as for a run.

Nothing runs here. Every point is validated (its key paths, the scene's own checks, the
built geometry), and every bad point gives one line, so a sweep never fails half-way on a
typo in its last point.
"""

from __future__ import annotations

import copy
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from elastoflow.sweep._spec import SweepError, SweepSpec

# Keys of the scene of which exactly one is given: setting one drops the other, so that a
# sweep over ``time.dt`` works on a scene written with ``time.cfl``.
_EXCLUSIVE = {
    "time.dt": "time.cfl", "time.cfl": "time.dt",
    "time.steps": "time.duration", "time.duration": "time.steps",
    "domain.nx": "domain.h", "domain.h": "domain.nx",
}


@dataclass(frozen=True)
class SweepPoint:
    """One point of a sweep, checked and ready to run.

    Attributes:
        index: Position in the sweep (0-based); names the output folder ``point_{index:05d}``.
        parameters: The varied parameters, key path -> value (the ``[set]`` ones left out).
        scene: The point's `elastoflow.scenes.Scene`, outputs as the sweep asks.
        steps: Fluid steps of the run.
    """

    index: int
    parameters: dict[str, Any]
    scene: Any
    steps: int

    @property
    def folder_name(self) -> str:
        return f"point_{self.index:05d}"

    def describe(self) -> str:
        """``point 3 (fluid.viscosity = 0.001, ...)``, for messages."""
        shown = ", ".join(f"{key} = {_show(value)}" for key, value in self.parameters.items())
        return f"point {self.index} ({shown})" if shown else f"point {self.index}"


@dataclass(frozen=True)
class SweepPlan:
    """A checked sweep: the spec, its points and the warnings found while building them."""

    spec: SweepSpec
    points: list[SweepPoint]
    warnings: list[str] = field(default_factory=list)

    @property
    def parameter_names(self) -> list[str]:
        names: dict[str, None] = {}
        for point in self.points:
            names.update(dict.fromkeys(point.parameters))
        return list(names)


def _show(value: Any) -> str:
    return json.dumps(value) if isinstance(value, str | list | dict | bool) else repr(value)


def set_key_path(data: dict[str, Any], path: str, value: Any) -> None:
    """Set ``value`` at a dotted key path in nested dicts and lists (the scene's TOML shape).

    Tables are entered by name, arrays by index; the last key may be new (the scene's own
    validation then says whether it is allowed).

    Raises:
        KeyError: A key or index on the way does not exist (message: what exists there).
    """
    parts = path.split(".")
    if not path or any(part == "" for part in parts):
        raise KeyError(f"{path!r} is not a key path (names joined by dots)")
    node: Any = data
    for depth, part in enumerate(parts):
        last = depth == len(parts) - 1
        where = ".".join(parts[:depth]) or "the scene"
        if isinstance(node, list):
            if not node:
                raise KeyError(f"{where} is an empty array: {part!r} indexes nothing")
            if not part.isdigit() or int(part) >= len(node):
                raise KeyError(f"{where} is an array of {len(node)}: {part!r} must be an index "
                               f"0..{len(node) - 1}")
            if last:
                node[int(part)] = value
            else:
                node = node[int(part)]
        elif isinstance(node, dict):
            if last:
                node[part] = value
            elif part not in node:
                known = ", ".join(sorted(node)) or "none"
                raise KeyError(f"{where} has no {part!r} (keys there: {known})")
            else:
                node = node[part]
        else:
            raise KeyError(f"{where} is a value ({_show(node)}), not a table or an array")
    if path in _EXCLUSIVE:
        table, key = _EXCLUSIVE[path].split(".")
        if isinstance(data.get(table), dict):
            data[table].pop(key, None)


def _base_scene(spec: SweepSpec) -> Any:
    from elastoflow.scenes import SceneError, get_scene, list_scenes, load_scene

    name = spec.scene
    path = Path(name)
    if not path.is_absolute() and spec.base_dir is not None:
        path = Path(spec.base_dir) / path
    if name not in list_scenes() and not path.exists():
        raise SweepError([f"scene = {name!r}: neither a built-in scene ({', '.join(list_scenes())})"
                          f" nor a file ({path} does not exist)"], spec.source)
    try:
        if name in list_scenes() and not path.exists():
            return get_scene(name)
        return load_scene(path)
    except SceneError as error:
        raise SweepError([f"scene = {name!r}: {line}" for line in error.problems],
                         spec.source) from None


def _outputs(scene: Any, spec: SweepSpec, steps: int) -> Any:
    """The point's scene with its outputs as the sweep asks (checkpoints always on)."""
    from elastoflow.io import apply_output_overrides

    run = spec.run
    every = run.checkpoint_every
    if every is None:
        every = max(1, steps // 10)
        if scene.outputs.checkpoint is not None:
            every = min(every, scene.outputs.checkpoint.every)
    return apply_output_overrides(scene, video=run.video, fields=run.fields, meshes=run.meshes,
                                  checkpoint_every=every)


def plan_sweep(spec: SweepSpec, *, build: bool = True) -> SweepPlan:
    """Every point of ``spec`` as a checked scene.

    Args:
        spec: The sweep.
        build: Also build each point's simulation as a run would (memory, meshes, geometry):
            what `elastoflow validate` checks; False checks the scene data only.

    Raises:
        SweepError: The base scene or ``[set]`` is invalid (their problems), or points are
            (one line per bad point, naming its parameters and all its problems).
    """
    from elastoflow.scenes import SceneError, build_simulation, parse_scene, step_count

    base = _base_scene(spec)
    base_data = base.model_dump(mode="json", exclude_none=True)
    label = spec.source
    problems: list[str] = []
    for key, value in spec.set.items():
        try:
            set_key_path(base_data, key, value)
        except KeyError as error:
            problems.append(f"set.{key!s}: {error.args[0]}")
    if problems:
        raise SweepError(problems, label)

    points: list[SweepPoint] = []
    warnings: dict[str, None] = {}
    shapes: dict[tuple[Any, ...], int] = {}
    for index, parameters in enumerate(spec.parameter_points()):
        data = copy.deepcopy(base_data)
        errors: list[str] = []
        for key, value in parameters.items():
            try:
                set_key_path(data, key, value)
            except KeyError as error:
                errors.append(f"{key}: {error.args[0]}")
        scene = None
        steps = 0
        if not errors:
            try:
                scene = parse_scene(data, base_dir=base.base_dir, source=base.source)
                steps = spec.run.steps if spec.run.steps is not None else step_count(scene)
                scene = _outputs(scene, spec, steps)
                if build:
                    found: list[str] = []
                    build_simulation(scene, steps=steps, warnings=found)
                    warnings.update(dict.fromkeys(found))
            except SceneError as error:
                errors.extend(error.problems)
        point = SweepPoint(index, parameters, scene, steps)
        if errors:
            problems.append(f"{point.describe()}: {'; '.join(errors)}")
            continue
        assert scene is not None
        domain = scene.domain
        origin = tuple(float(v) for v in getattr(domain, "origin", (0.0, 0.0)))
        shapes.setdefault((*domain.cells, float(domain.cell_size), origin), index)
        points.append(point)
    if spec.snapshots is not None and len(shapes) > 1:
        # The store's x and y are one set of cell centres: cells, size and origin must agree.
        listed = ", ".join(f"{nx}x{ny} cells of {h:.6g} m from ({x0:.6g}, {y0:.6g}) (point "
                           f"{index})" for (nx, ny, h, (x0, y0)), index in shapes.items())
        problems.append(f"snapshots: every point must have the same grid to share one Zarr "
                        f"store; the points have {listed}")
    if problems:
        raise SweepError(problems, label)
    return SweepPlan(spec, points, list(warnings))
