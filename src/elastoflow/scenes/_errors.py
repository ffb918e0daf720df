"""Scene validation: pydantic errors and cross-field checks as one line per problem."""

from __future__ import annotations

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


def _types_at(loc: tuple[Any, ...]) -> list[Any]:
    """The candidate types at ``loc`` (a pydantic error location), following union tags."""
    current: list[Any] = [Scene]
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
    for name in ("type", "shape"):
        field = model.model_fields.get(name)
        if field is not None and isinstance(field.default, str):
            return field.default
    return None


def _path(loc: tuple[Any, ...]) -> str:
    """Dotted key path as the user wrote it: discriminated unions add their tag to pydantic's
    location, which is not a key in the file."""
    kept: list[str] = []
    for position, key in enumerate(loc):
        if isinstance(key, str):
            candidates = _types_at(loc[:position])
            if any(isinstance(t, type) and issubclass(t, BaseModel) and _tag(t) == key
                   for t in candidates):
                continue
        kept.append(str(key))
    return ".".join(kept) or "(scene)"


def _show(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def format_validation_error(error: ValidationError) -> list[str]:
    """One line per pydantic error: ``key.path = value: what is allowed``."""
    lines = []
    for item in error.errors(include_url=False):
        loc = tuple(item["loc"])
        path = _path(loc)
        kind = item["type"]
        if kind == "extra_forbidden":
            parent = _model_at(loc[:-1])
            allowed = ", ".join(parent.model_fields) if parent else "see the documentation"
            lines.append(f"{path}: unknown key (allowed keys: {allowed})")
        elif kind == "missing":
            lines.append(f"{path}: missing (required)")
        elif kind == "union_tag_invalid":
            ctx = item.get("ctx", {})
            lines.append(
                f"{path}.{ctx.get('discriminator', 'type').strip(chr(39))} = "
                f"{_show(ctx.get('tag'))}: unknown kind (allowed: {ctx.get('expected_tags')})"
            )
        elif kind == "union_tag_not_found":
            ctx = item.get("ctx", {})
            lines.append(f"{path}: missing key {ctx.get('discriminator', 'type')}")
        else:
            message = item["msg"]
            message = message.removeprefix("Value error, ").replace("Input should be", "must be")
            lines.append(f"{path} = {_show(item.get('input'))}: {message}")
    return lines


def _inside(bounds: tuple[float, float, float, float], lx: float, ly: float) -> bool:
    tolerance = 1e-9 * max(lx, ly)
    return (
        bounds[0] >= -tolerance
        and bounds[1] >= -tolerance
        and bounds[2] <= lx + tolerance
        and bounds[3] <= ly + tolerance
    )


def check_scene(scene: Scene) -> list[str]:
    """Cross-field problems pydantic cannot see: geometry outside the domain, bad references."""
    problems: list[str] = []
    lx, ly = scene.domain.lx, scene.domain.ly
    allowed = f"must lie inside the domain [0, {lx:g}] x [0, {ly:g}]"
    for index, obstacle in enumerate(scene.obstacles):
        bounds = obstacle.bounds()
        if obstacle.motion is None and not _inside(bounds, lx, ly):
            problems.append(f"obstacles.{index} = {obstacle.shape} with bounds {_fmt(bounds)}: {allowed}")
    for index, body in enumerate(scene.bodies):
        body_bounds = body.shape.bounds()
        if body_bounds is not None and not _inside(body_bounds, lx, ly):
            problems.append(
                f"bodies.{index}.shape = {body.shape.type} with bounds {_fmt(body_bounds)}: "
                f"{allowed}"
            )
        if body.pivot is not None and not _inside((*body.pivot, *body.pivot), lx, ly):
            problems.append(f"bodies.{index}.pivot = {list(body.pivot)}: {allowed}")
    for index, jet in enumerate(scene.jets):
        if not _inside(jet.region, lx, ly):
            problems.append(f"jets.{index}.region = {list(jet.region)}: {allowed}")
    for index, probe in enumerate(scene.outputs.probes):
        if probe.body is not None and probe.body >= len(scene.bodies):
            problems.append(
                f"outputs.probes.{index}.body = {probe.body}: must be a body index in "
                f"0..{len(scene.bodies) - 1}" if scene.bodies else
                f"outputs.probes.{index}.body = {probe.body}: the scene has no bodies"
            )
    return problems


def _fmt(bounds: tuple[float, ...]) -> str:
    return "[" + ", ".join(f"{b:g}" for b in bounds) + "]"
