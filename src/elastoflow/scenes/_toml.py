"""Scenes to and from TOML: ``tomllib`` reads, a small writer covers the scene's data types."""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from elastoflow.scenes._errors import SceneError, check_scene, format_validation_error
from elastoflow.scenes._schema import Scene
from elastoflow.scenes._schema3d import Scene3D


def is_3d(data: dict[str, Any]) -> bool:
    """Whether a scene's data describes a 3D scene: its ``[domain]`` has ``lz``."""
    domain = data.get("domain")
    return isinstance(domain, dict) and "lz" in domain


def parse_scene(
    data: dict[str, Any], *, base_dir: str | Path | None = None, source: str | None = None
) -> Scene | Scene3D:
    """Validate a scene given as nested dicts (the shape of the TOML file): a `Scene3D` when
    its domain has ``lz``, else a `Scene`.

    Raises:
        SceneError: With one line per problem (key path, value, what is allowed).
    """
    if is_3d(data):
        from elastoflow.scenes._checks3d import check_scene_3d

        try:
            scene_3d = Scene3D.model_validate(data)
        except ValidationError as error:
            raise SceneError(format_validation_error(error, Scene3D), source) from None
        problems = check_scene_3d(scene_3d)
        if problems:
            raise SceneError(problems, source)
        if base_dir is not None:
            scene_3d.base_dir = str(base_dir)
        scene_3d.source = source
        return scene_3d
    try:
        scene = Scene.model_validate(data)
    except ValidationError as error:
        raise SceneError(format_validation_error(error), source) from None
    problems = check_scene(scene)
    if problems:
        raise SceneError(problems, source)
    if base_dir is not None:
        scene.base_dir = str(base_dir)
    scene.source = source
    return scene


def load_scene(path: str | Path) -> Scene | Scene3D:
    """Read and validate a scene TOML file; relative mesh paths are taken from its folder.

    Raises:
        SceneError: The file is missing, is not TOML, or describes an invalid scene.
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as error:
        raise SceneError([f"cannot read scene file: {error.strerror or error}"], str(path)) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as error:
        line = raw[:error.start].count(b"\n") + 1
        raise SceneError([(f"not a text file in UTF-8 (byte 0x{raw[error.start]:02x} at line "
                          f"{line}, offset {error.start}); a scene file is UTF-8 TOML")],
                         str(path)) from None
    if "\x00" in text:
        line = text[:text.index("\x00")].count("\n") + 1
        raise SceneError([(f"not a text file (a NUL byte at line {line}); a scene file is UTF-8 "
                          "TOML")], str(path)) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise SceneError([f"not valid TOML: {error}"], str(path)) from None
    return parse_scene(data, base_dir=path.resolve().parent, source=str(path))


def scene_to_toml(scene: Scene | Scene3D) -> str:
    """The scene as TOML text that ``load_scene`` reads back to an equal scene."""
    data = scene.model_dump(mode="json", exclude_none=True)
    data["boundaries"] = {
        side: (spec["type"] if set(spec) == {"type"} else spec)
        for side, spec in data["boundaries"].items()
    }
    lines: list[str] = []
    _emit_table(data, [], lines, array_element=False)
    return "\n".join(lines).strip() + "\n"


def _is_table_array(value: Any) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value)


def _emit_table(table: dict[str, Any], path: list[str], lines: list[str], array_element: bool) -> None:
    if path:
        dotted = ".".join(_key(k) for k in path)
        lines.append("")
        lines.append(f"[[{dotted}]]" if array_element else f"[{dotted}]")
    for key, value in table.items():
        if not isinstance(value, dict) and not _is_table_array(value):
            lines.append(f"{_key(key)} = {_value(value)}")
    for key, value in table.items():
        if isinstance(value, dict):
            _emit_table(value, [*path, key], lines, array_element=False)
    for key, value in table.items():
        if _is_table_array(value):
            for item in value:
                _emit_table(item, [*path, key], lines, array_element=True)


def _key(key: str) -> str:
    return key if key.replace("_", "").replace("-", "").isalnum() else json.dumps(key)


def _value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{_key(k)} = {_value(v)}" for k, v in value.items()) + " }"
    raise TypeError(f"cannot write {type(value).__name__} to TOML")
