"""Every leaf key of built-in scenes set to values of every wrong kind: parsing and building end
in a SceneError or a valid simulation, never in another exception (5565 such scenes over all
the built-ins found tracebacks from four causes once: huge substeps, denormal moduli and
element sizes, an element size whose square overflows)."""

from __future__ import annotations

import copy
import math
import tomllib
import warnings
from collections.abc import Iterator
from typing import Any

import pytest

from elastoflow.scenes import (
    SceneError,
    build_simulation,
    get_scene,
    parse_scene,
    scene_to_toml,
    step_count,
    time_step,
)
from elastoflow.scenes import _checks as checks

VALUES: list[Any] = [True, "x", -1, 0, 10**30, 1e308, 1e-320, math.inf, math.nan, [], [0.5],
                     [0.1, 0.1, 0.2, 0.2], {}]


def _leaves(data: Any, prefix: tuple[Any, ...] = ()) -> Iterator[tuple[Any, ...]]:
    if isinstance(data, dict):
        for key, value in data.items():
            yield from _leaves(value, (*prefix, key))
    elif isinstance(data, list) and data and all(isinstance(item, dict) for item in data):
        for index, value in enumerate(data):
            yield from _leaves(value, (*prefix, index))
    else:
        yield prefix


@pytest.mark.parametrize("name", ["bar_in_jet", "dfg_cylinder"])
def test_any_value_at_any_key_is_a_scene_error_or_a_scene(name: str,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(checks, "available_memory", lambda: 16 * 2**30)
    base = tomllib.loads(scene_to_toml(get_scene(name)))
    refused = 0
    for path in _leaves(base):
        for value in VALUES:
            data = copy.deepcopy(base)
            node = data
            for key in path[:-1]:
                node = node[key]
            node[path[-1]] = value
            try:
                scene = parse_scene(data)
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    step_count(scene)
                    time_step(scene)
                    build_simulation(scene, warnings=[])
            except SceneError as error:
                refused += 1
                # Named at the key or at the key it conflicts with (a body box that no longer
                # holds the fixed box), always in the same table.
                assert str(path[0]) in error.problems[0], (path, error.problems)
    assert refused > 0.8 * len(VALUES) * len(list(_leaves(base)))
