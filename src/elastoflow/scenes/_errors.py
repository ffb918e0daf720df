"""Scene validation: pydantic errors and cross-field checks as one line per problem."""

from __future__ import annotations

import contextvars
import math
import re
import types
import typing
from collections.abc import Sequence
from typing import Any

from pydantic import BaseModel, ValidationError

from elastoflow.scenes._schema import Scene


class SceneError(ValueError):
    """A scene is invalid. ``problems`` holds one line per problem, each naming the key path,
    the value and what is allowed."""

    def __init__(self, problems: Sequence[str], source: str | None = None) -> None:
        self.problems = list(problems)
        self.source = source
        prefix = f"{source}: " if source else ""
        super().__init__("\n".join(prefix + p for p in self.problems))


def _unwrap(annotation: Any) -> list[Any]:
    """The candidate types inside Optional / Union / Annotated / list / tuple annotations."""
    origin = typing.get_origin(annotation)
    if origin is typing.Annotated:
        return _unwrap(typing.get_args(annotation)[0])
    if origin in (typing.Union, types.UnionType):
        return [t for a in typing.get_args(annotation) for t in _unwrap(a)]
    if origin in (list, tuple):
        return [t for a in typing.get_args(annotation) if a is not Ellipsis for t in _unwrap(a)]
    return [annotation]


# The scene model an error is read against (Scene, or Scene3D while a 3D scene's errors are
# formatted).
_ROOT: contextvars.ContextVar[type[BaseModel]] = contextvars.ContextVar("root", default=Scene)


def _types_at(loc: tuple[Any, ...]) -> list[Any]:
    """The candidate types at ``loc`` (a pydantic error location), following union tags."""
    current: list[Any] = [_ROOT.get()]
    for key in loc:
        if isinstance(key, int):
            continue
        models = [t for t in current if isinstance(t, type) and issubclass(t, BaseModel)]
        tagged = [m for m in models if _tag(m) == key]
        if tagged:
            current = tagged
            continue
        current = [
            t
            for m in models
            if key in m.model_fields
            for t in _unwrap(m.model_fields[key].annotation)
        ]
    return current


def _model_at(loc: tuple[Any, ...]) -> type[BaseModel] | None:
    """The model class whose field set applies at ``loc``, if there is exactly one."""
    models = [t for t in _types_at(loc) if isinstance(t, type) and issubclass(t, BaseModel)]
    return models[0] if len(models) == 1 else None


def _tag(model: type[BaseModel]) -> str | None:
    label = getattr(model, "union_tag", None)
    if isinstance(label, str):
        return label
    for name in ("type", "shape"):
        field = model.model_fields.get(name)
        if field is not None and isinstance(field.default, str):
            return field.default
    return None


def _is_key(loc: tuple[Any, ...], position: int) -> bool:
    """Whether ``loc[position]`` is a key of the file, not a label pydantic adds: the tag of a
    discriminated union (``circle``) or the member of a plain union (``constrained-int``,
    ``literal['auto']``)."""
    key = loc[position]
    if not isinstance(key, str):
        return True
    models = [t for t in _types_at(loc[:position])
              if isinstance(t, type) and issubclass(t, BaseModel)]
    if not any(_tag(m) == key for m in models):
        return bool(models)
    # A field named as its own model's tag (a 3D box shape's ``box``) follows the tag, when
    # the union is already resolved to that one model.
    return len(models) == 1 and key in models[0].model_fields


def _path(loc: tuple[Any, ...]) -> str:
    """Dotted key path as the user wrote it (pydantic's labels for union members left out)."""
    kept = [str(key) for position, key in enumerate(loc) if _is_key(loc, position)]
    return ".".join(kept) or "(scene)"


def _member(loc: tuple[Any, ...]) -> str | None:
    """The label of the plain-union member an error belongs to, if any."""
    labels = [key for position, key in enumerate(loc) if not _is_key(loc, position)
              and isinstance(key, str) and not any(
                  _tag(t) == key for t in _types_at(loc[:position])
                  if isinstance(t, type) and issubclass(t, BaseModel))]
    return labels[-1] if labels else None


def _show(value: Any) -> str:
    """The value as it is spelled in TOML (shortened)."""
    text = _toml_spelling(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _toml_spelling(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "nan" if math.isnan(value) else repr(value)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml_spelling(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {_toml_spelling(v)}" for k, v in value.items()) + " }"
    return repr(value)


# What pydantic's type errors mean in the words of a TOML file.
_TYPE_WORDS = {
    "int_type": "an integer",
    "int_from_float": "an integer",
    "float_type": "a number",
    "string_type": "a string",
    "bool_type": "true or false",
    "model_type": "a table",
    "model_attributes_type": "a table",
    "dict_type": "a table",
    "list_type": "an array",
    "tuple_type": "an array",
    "finite_number": "a finite number",
}


def _allowed(item: Any, member: str | None) -> str:
    """What is allowed, as the tail of ``must be ...``."""
    kind = item["type"]
    if kind in _TYPE_WORDS:
        return _TYPE_WORDS[kind]
    message = item["msg"].removeprefix("Value error, ")
    if kind == "too_short":
        return message.split(" after validation")[0].replace("List should", "must").replace(
            "Tuple should", "must")
    phrase = message.removeprefix("Input should be ")
    if phrase == message:
        return message
    if member is not None and member.startswith("constrained-int"):
        phrase = f"an integer {phrase}"
    return phrase


def format_validation_error(error: ValidationError,
                            root: type[BaseModel] = Scene) -> list[str]:
    """One line per problem: ``key.path = value: what is allowed``.

    One key makes one line: the alternatives of a union (``substeps``: an integer or "auto"),
    the missing items of a too short array, and the items of an array that all fail the same
    way are each folded into one. ``root``: the scene model validated (`Scene` or
    `Scene3D`).
    """
    token = _ROOT.set(root)
    try:
        return _format(error)
    finally:
        _ROOT.reset(token)


def _format(error: ValidationError) -> list[str]:
    # Each problem as (path, value text, what is allowed); a value text of None: no value.
    problems: list[tuple[str, str | None, str]] = []
    union: dict[str, tuple[Any, list[str]]] = {}
    short: dict[str, int] = {}
    for item in error.errors(include_url=False):
        loc = tuple(item["loc"])
        path = _path(loc)
        kind = item["type"]
        member = _member(loc)
        if member is not None:
            if path not in union:
                union[path] = (item.get("input"), [])
                problems.append((path, "", ""))  # filled below
            union[path][1].append(_allowed(item, member))
        elif kind == "extra_forbidden":
            parent = _model_at(loc[:-1])
            allowed = ", ".join(parent.model_fields) if parent else "see the documentation"
            problems.append((path, None, f"unknown key (allowed keys: {allowed})"))
        elif kind == "missing" and loc and isinstance(loc[-1], int):
            parent_path = _path(loc[:-1])
            if parent_path not in short:
                problems.append((parent_path, _show(item.get("input")), ""))  # filled below
            short[parent_path] = max(short.get(parent_path, 0), loc[-1] + 1)
        elif kind == "missing":
            problems.append((path, None, "missing (required)"))
        elif kind == "too_long":
            problems.append((path, _show(item.get("input")), "too many items"))
        elif kind == "union_tag_invalid":
            ctx = item.get("ctx", {})
            discriminator = ctx.get("discriminator", "type").strip(chr(39))
            expected = ctx.get("expected_tags")
            if re.fullmatch(r"bodies\.\d+\.shape", path):
                # A rod is a body model of its own (RodBodySpec), chosen by this same key.
                expected = f"{expected}, 'rod'"
            problems.append((f"{path}.{discriminator}", _show(ctx.get("tag")),
                             f"unknown kind (allowed: {expected})"))
        elif kind == "union_tag_not_found":
            ctx = item.get("ctx", {})
            problems.append((path, None, f"missing key {ctx.get('discriminator', 'type')}"))
        else:
            allowed = _allowed(item, None)
            if kind in _TYPE_WORDS or item["msg"].startswith("Input should be "):
                allowed = f"must be {allowed}"
            problems.append((path, _show(item.get("input")), allowed))
    for index, (path, value, allowed) in enumerate(problems):
        if path in union and value == "":
            raw, alternatives = union[path]
            unique = list(dict.fromkeys(alternatives))
            problems[index] = (path, _show(raw), f"must be {' or '.join(unique)}")
        elif path in short and not allowed:
            problems[index] = (path, value, f"too few items (needs {short[path]})")
    return [_line(*problem) for problem in _fold_items(problems)]


def _line(path: str, value: str | None, allowed: str) -> str:
    return f"{path}: {allowed}" if value is None else f"{path} = {value}: {allowed}"


def _fold_items(problems: list[tuple[str, str | None, str]]) -> list[tuple[str, str | None, str]]:
    """Items of one array that fail the same way (``jets.0 = 0: must be a table``,
    ``jets.1 = 0: must be a table``) as one problem of the array."""
    groups: dict[tuple[str, str], list[int]] = {}
    for index, (path, value, allowed) in enumerate(problems):
        parent, _, last = path.rpartition(".")
        if last.isdigit() and value is not None:
            groups.setdefault((parent, allowed), []).append(index)
    folded: list[tuple[str, str | None, str]] = []
    done: set[int] = set()
    for index, problem in enumerate(problems):
        if index in done:
            continue
        path, value, allowed = problem
        parent, _, last = path.rpartition(".")
        members = groups.get((parent, allowed), []) if last.isdigit() else []
        if len(members) < 2:
            folded.append(problem)
            continue
        done.update(members)
        items = ", ".join(problems[m][0].rpartition(".")[2] for m in members)
        values = ", ".join(str(problems[m][1]) for m in members)
        folded.append((parent, None, f"items {items} = {values}: {allowed}"))
    return folded


MAX_CELLS_FROM_ZERO = 1e6
"""Farthest the domain's origin may lie from 0, in cells: positions there still resolve a
millionth of a cell, and the geometry checks' relative tolerances stay far below a cell."""


def _inside(bounds: tuple[float, float, float, float],
            domain: tuple[float, float, float, float]) -> bool:
    x0, y0, x1, y1 = domain
    tolerance = 1e-9 * max(x1 - x0, y1 - y0, abs(x0), abs(y0), abs(x1), abs(y1))
    return (
        bounds[0] >= x0 - tolerance
        and bounds[1] >= y0 - tolerance
        and bounds[2] <= x1 + tolerance
        and bounds[3] <= y1 + tolerance
    )


def domain_text(scene: Scene) -> str:
    """``[x0, x1] x [y0, y1]``, the domain as messages show it."""
    x0, y0, x1, y1 = scene.domain.bounds
    return f"[{x0:g}, {x1:g}] x [{y0:g}, {y1:g}]"


def check_scene(scene: Scene) -> list[str]:
    """Cross-field problems pydantic cannot see: geometry outside the domain, bad references,
    polygons that are not simple, a closed domain whose inflows do not balance, numerical
    choices that contradict each other."""
    from elastoflow.scenes._checks import (
        check_flow,
        check_liquid,
        check_numerics,
        check_outlines,
        check_rods,
    )

    problems: list[str] = (check_flow(scene) + check_outlines(scene) + check_numerics(scene)
                           + check_rods(scene) + check_liquid(scene))
    domain = scene.domain.bounds
    if not all(math.isfinite(c) for c in domain):
        return problems + [(f"domain.origin = {_show(list(scene.domain.origin))}: with lx = "
                            f"{scene.domain.lx:g} and ly = {scene.domain.ly:g} the far corner "
                            "is not a finite position; must be a finite point nearer 0")]
    far = max(abs(c) for c in scene.domain.origin)
    if far > MAX_CELLS_FROM_ZERO * scene.domain.cell_size:
        problems.append(
            f"domain.origin = {_show(list(scene.domain.origin))}: puts the domain {far:.3g} m "
            f"from 0, more than {MAX_CELLS_FROM_ZERO:.0e} cells of side "
            f"{scene.domain.cell_size:.4g} m, where positions no longer resolve a cell "
            "finely enough; must be nearer 0 (the origin only shifts coordinates)")
    allowed = f"must lie inside the domain {domain_text(scene)}"
    for index, obstacle in enumerate(scene.obstacles):
        bounds = obstacle.bounds()
        if obstacle.motion is None and not _inside(bounds, domain):
            problems.append(f"obstacles.{index} = {obstacle.shape} with bounds {_fmt(bounds)}: {allowed}")
    problems += _obstacle_references(scene)
    for index, body in enumerate(scene.bodies):
        body_bounds = body.shape.bounds()
        if body_bounds is not None and not _inside(body_bounds, domain):
            problems.append(
                f"bodies.{index}.shape = {body.shape.type} with bounds {_fmt(body_bounds)}: "
                f"{allowed}"
            )
        if body.pivot is not None and not _inside((*body.pivot, *body.pivot), domain):
            problems.append(f"bodies.{index}.pivot = {list(body.pivot)}: {allowed}")
    for index, jet in enumerate(scene.jets):
        if not _inside(jet.region, domain):
            problems.append(f"jets.{index}.region = {list(jet.region)}: {allowed}")
    for index, probe in enumerate(scene.outputs.probes):
        where = f"outputs.probes.{index}"
        if probe.body is not None and probe.body >= len(scene.bodies):
            problems.append(
                f"{where}.body = {probe.body}: must be a body index in "
                f"0..{len(scene.bodies) - 1}" if scene.bodies else
                f"{where}.body = {probe.body}: the scene has no bodies"
            )
        for key, count, what in (("bodies", len(scene.bodies), "body"),
                                 ("obstacles", len(scene.obstacles), "obstacle")):
            chosen = getattr(probe, key)
            bad = [i for i in chosen if i >= count]
            if bad:
                problems.append(
                    f"{where}.{key} = {chosen}: must be {what} indices in 0..{count - 1}"
                    if count else f"{where}.{key} = {chosen}: the scene has no {key}")
        places: list[tuple[str, tuple[float, float] | None]] = (
            [("point", probe.point)] if probe.kind in ("pressure", "velocity") else [])
        for k, point in enumerate(probe.points or []):
            places.append((f"points.{k}", point))
        for key, place in places:
            if place is not None and not _inside((*place, *place), domain):
                problems.append(f"{where}.{key} = {list(place)}: {allowed}")
        if probe.kind == "momentum_balance" and probe.region is not None:
            problems += _balance_problems(scene, where, probe)
    return problems


def _balance_problems(scene: Scene, where: str, probe: Any) -> list[str]:
    """A momentum balance's box: a cell inside the domain, its obstacles still and two cells
    clear of its sides (the side fluxes read a cell on each side), nothing else in reach."""
    region = tuple(probe.region)
    h = scene.domain.cell_size
    x0, y0, x1, y1 = scene.domain.bounds
    key = f"{where}.region = {_fmt(region)}"
    if scene.liquid is not None:
        return [f"{key}: the momentum balance needs one fluid filling the box; a scene with "
                "[liquid] (a free surface) cannot use it"]
    problems = []
    if not _inside(region, (x0 + h, y0 + h, x1 - h, y1 - h)):
        problems.append(f"{key}: must lie inside the domain {domain_text(scene)} and keep one "
                        f"cell ({h:.4g} m) from its edges")
    inner = (region[0] + 2 * h, region[1] + 2 * h, region[2] - 2 * h, region[3] - 2 * h)
    outer = (region[0] - 2 * h, region[1] - 2 * h, region[2] + 2 * h, region[3] + 2 * h)
    for index, obstacle in enumerate(scene.obstacles):
        bounds = obstacle.bounds()
        if index in probe.obstacles:
            if obstacle.motion is not None:
                problems.append(f"{where}.obstacles: obstacles.{index} moves (it has a "
                                "motion); the momentum balance reads the force on still "
                                "obstacles")
            elif not _inside(bounds, inner):
                problems.append(f"{key}: must hold obstacles.{index} (bounds {_fmt(bounds)}) "
                                f"two cells ({2 * h:.4g} m) clear of its sides")
        elif obstacle.motion is not None or _overlaps(bounds, outer):
            problems.append(f"{key}: obstacles.{index} is not in the probe's obstacles, and "
                            + ("moves" if obstacle.motion is not None else
                               f"reaches within two cells of the box (bounds {_fmt(bounds)})")
                            + "; the box must hold only the probe's obstacles")
    if scene.bodies:
        problems.append(f"{key}: the scene has bodies, which could enter the box; the momentum "
                        "balance reads the force on still obstacles in a scene without bodies")
    return problems


def _overlaps(a: tuple[float, ...], b: tuple[float, ...]) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def obstacle_index(scene: Scene, reference: int | str) -> int | None:
    """The index of the obstacle a scene refers to by index or by name (None: no such)."""
    if isinstance(reference, int):
        return reference if reference < len(scene.obstacles) else None
    names = [obstacle.name for obstacle in scene.obstacles]
    return names.index(reference) if reference in names else None


def _obstacle_references(scene: Scene) -> list[str]:
    """Obstacle names unique; ``bodies.N.fixed.obstacle`` naming an obstacle that exists and
    does not move; ``tolerance`` only with ``obstacle``."""
    problems = []
    seen: dict[str, int] = {}
    for index, obstacle in enumerate(scene.obstacles):
        if obstacle.name is None:
            continue
        if obstacle.name in seen:
            problems.append(f"obstacles.{index}.name = {_show(obstacle.name)}: already the "
                            f"name of obstacles.{seen[obstacle.name]}; names must be unique")
        else:
            seen[obstacle.name] = index
    names = [o.name for o in scene.obstacles if o.name is not None]
    for index, body in enumerate(scene.bodies):
        fixed = body.fixed
        if fixed is None:
            continue
        key = f"bodies.{index}.fixed"
        if fixed.obstacle is None:
            if fixed.tolerance is not None:
                problems.append(f"{key}.tolerance = {fixed.tolerance!r}: applies to the nodes "
                                "on an obstacle; give obstacle (an index or a name) too, or "
                                "leave tolerance out")
            continue
        found = obstacle_index(scene, fixed.obstacle)
        if found is None:
            if not scene.obstacles:
                allowed = "the scene has no obstacles"
            elif isinstance(fixed.obstacle, int):
                allowed = f"must be an obstacle index in 0..{len(scene.obstacles) - 1}"
            else:
                allowed = ("must name an obstacle (names: " + ", ".join(map(repr, names)) + ")"
                           if names else "no obstacle has a name; give one (obstacles.N.name) "
                           "or use its index")
            problems.append(f"{key}.obstacle = {_show(fixed.obstacle)}: {allowed}")
        elif scene.obstacles[found].motion is not None:
            problems.append(f"{key}.obstacle = {_show(fixed.obstacle)}: obstacles.{found} "
                            "moves (it has a motion); nodes can be held only on an obstacle "
                            "that stays still")
    return problems


def _fmt(bounds: tuple[float, ...]) -> str:
    return "[" + ", ".join(f"{b:g}" for b in bounds) + "]"
