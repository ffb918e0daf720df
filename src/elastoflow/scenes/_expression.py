"""Arithmetic expressions of a scene file (an initial velocity ``"sin(pi*x) * cos(pi*y)"``),
parsed once and evaluated on whole coordinate arrays.

A small, closed evaluator over Python's parse tree, never ``eval``: an expression may use
numbers, the variables of `VARIABLES`, the constants of `CONSTANTS`, the functions of
`FUNCTIONS`, arithmetic (``+ - * / ** %``), comparisons, ``and``/``or``/``not`` and
``a if condition else b`` (all element-wise). Anything else (attributes, subscripts, strings,
lambdas, other names) is refused when the scene is read, with the part that is not allowed.
Numbers are float64 throughout, so ``9**9**9`` overflows to inf (refused as not finite)
instead of computing a huge integer.
"""

from __future__ import annotations

import ast
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

MAX_LENGTH = 1000
"""Longest expression accepted [characters] (Python's parser recurses on nesting)."""

VARIABLES = ("x", "y")
"""Coordinates [m] of the point where the expression is evaluated."""

CONSTANTS: dict[str, float] = {"pi": float(np.pi), "e": float(np.e)}

FUNCTIONS: dict[str, tuple[Callable[..., Any], int]] = {
    # name: (NumPy function, number of arguments)
    "sin": (np.sin, 1), "cos": (np.cos, 1), "tan": (np.tan, 1),
    "asin": (np.arcsin, 1), "acos": (np.arccos, 1), "atan": (np.arctan, 1),
    "atan2": (np.arctan2, 2), "sinh": (np.sinh, 1), "cosh": (np.cosh, 1),
    "tanh": (np.tanh, 1), "exp": (np.exp, 1), "log": (np.log, 1), "sqrt": (np.sqrt, 1),
    "abs": (np.abs, 1), "sign": (np.sign, 1), "floor": (np.floor, 1), "ceil": (np.ceil, 1),
    "min": (np.minimum, 2), "max": (np.maximum, 2), "hypot": (np.hypot, 2),
    "where": (np.where, 3),
}

_BINARY: dict[type, Callable[[Any, Any], Any]] = {
    ast.Add: np.add, ast.Sub: np.subtract, ast.Mult: np.multiply, ast.Div: np.true_divide,
    ast.Pow: np.power, ast.Mod: np.mod,
}
_COMPARE: dict[type, Callable[[Any, Any], Any]] = {
    ast.Lt: np.less, ast.LtE: np.less_equal, ast.Gt: np.greater, ast.GtE: np.greater_equal,
    ast.Eq: np.equal, ast.NotEq: np.not_equal,
}


def allowed_text() -> str:
    """What an expression may use, for messages."""
    return (f"an arithmetic expression in {', '.join(VARIABLES)} [m] with "
            f"{', '.join(CONSTANTS)}, + - * / ** %, comparisons, and/or/not, "
            f"'a if c else b' and the functions {', '.join(FUNCTIONS)}")


class Expression:
    """A checked expression; `evaluate` computes it on coordinate arrays.

    Raises:
        ValueError: (from the constructor) The text does not parse, or uses a name, function
            or construct that is not allowed; the message names the part.
    """

    def __init__(self, text: str) -> None:
        if len(text) > MAX_LENGTH:
            raise ValueError(f"longer than {MAX_LENGTH} characters")
        try:
            tree = ast.parse(text.strip(), mode="eval")
        except SyntaxError as error:
            where = f" at column {error.offset}" if error.offset else ""
            raise ValueError(f"does not parse{where} ({error.msg})") from None
        except (RecursionError, MemoryError, ValueError):
            raise ValueError("does not parse (nested too deeply)") from None
        self.text = text
        self._tree = tree.body
        try:
            _check(self._tree)
        except RecursionError:
            raise ValueError("nested too deeply") from None

    def evaluate(self, variables: Mapping[str, np.ndarray]) -> np.ndarray:
        """The expression's value where ``variables`` (each of `VARIABLES`, arrays of one
        shape) are given, as a float64 array of that shape (non-finite values are returned
        as they come; the caller decides)."""
        shape = np.broadcast_shapes(*(np.shape(v) for v in variables.values()))
        with np.errstate(all="ignore"):
            value = _evaluate(self._tree, variables)
            return np.broadcast_to(np.asarray(value, dtype=np.float64), shape).copy()


def _describe(node: ast.AST) -> str:
    try:
        return repr(ast.unparse(node))
    except Exception:  # noqa: BLE001 - only for the message
        return type(node).__name__


def _check(node: ast.AST) -> None:
    """Refuse every node the evaluator does not know, naming it."""
    if isinstance(node, ast.Constant):
        if isinstance(node.value, bool) or not isinstance(node.value, int | float):
            raise ValueError(f"{_describe(node)} is not a number")
        return
    if isinstance(node, ast.Name):
        if node.id not in VARIABLES and node.id not in CONSTANTS:
            if node.id in FUNCTIONS:
                raise ValueError(f"{node.id!r} is a function: call it, e.g. {node.id}(x)")
            raise ValueError(
                f"unknown name {node.id!r} (variables: {', '.join(VARIABLES)}; constants: "
                f"{', '.join(CONSTANTS)})")
        return
    if isinstance(node, ast.BinOp):
        if type(node.op) not in _BINARY:
            raise ValueError(f"operator in {_describe(node)} is not allowed (+ - * / ** %)")
        _check(node.left)
        _check(node.right)
        return
    if isinstance(node, ast.UnaryOp):
        if not isinstance(node.op, ast.UAdd | ast.USub | ast.Not):
            raise ValueError(f"operator in {_describe(node)} is not allowed")
        _check(node.operand)
        return
    if isinstance(node, ast.BoolOp):
        for value in node.values:
            _check(value)
        return
    if isinstance(node, ast.Compare):
        if any(type(op) not in _COMPARE for op in node.ops):
            raise ValueError(f"comparison in {_describe(node)} is not allowed "
                             "(< <= > >= == !=)")
        for item in (node.left, *node.comparators):
            _check(item)
        return
    if isinstance(node, ast.IfExp):
        for item in (node.test, node.body, node.orelse):
            _check(item)
        return
    if isinstance(node, ast.Call):
        name = node.func.id if isinstance(node.func, ast.Name) else None
        if name not in FUNCTIONS:
            raise ValueError(f"unknown function in {_describe(node)} (allowed: "
                             f"{', '.join(FUNCTIONS)})")
        if node.keywords or any(isinstance(a, ast.Starred) for a in node.args):
            raise ValueError(f"{_describe(node)}: give the arguments by position only")
        count = FUNCTIONS[name][1]
        if len(node.args) != count:
            raise ValueError(f"{_describe(node)}: {name} takes {count} argument"
                             f"{'s' if count > 1 else ''}, got {len(node.args)}")
        for argument in node.args:
            _check(argument)
        return
    raise ValueError(f"{_describe(node)} is not allowed ({type(node).__name__}); "
                     f"allowed: {allowed_text()}")


def _evaluate(node: ast.AST, variables: Mapping[str, np.ndarray]) -> Any:
    if isinstance(node, ast.Constant):
        assert isinstance(node.value, int | float)  # _check refused anything else
        return np.float64(node.value)
    if isinstance(node, ast.Name):
        if node.id in variables:
            return np.asarray(variables[node.id], dtype=np.float64)
        return np.float64(CONSTANTS[node.id])
    if isinstance(node, ast.BinOp):
        return _BINARY[type(node.op)](_evaluate(node.left, variables),
                                      _evaluate(node.right, variables))
    if isinstance(node, ast.UnaryOp):
        operand = _evaluate(node.operand, variables)
        if isinstance(node.op, ast.Not):
            return np.logical_not(operand)
        return np.negative(operand) if isinstance(node.op, ast.USub) else np.positive(operand)
    if isinstance(node, ast.BoolOp):
        combine = np.logical_and if isinstance(node.op, ast.And) else np.logical_or
        result = _evaluate(node.values[0], variables)
        for value in node.values[1:]:
            result = combine(result, _evaluate(value, variables))
        return result
    if isinstance(node, ast.Compare):
        left = _evaluate(node.left, variables)
        result = None
        for op, comparator in zip(node.ops, node.comparators, strict=True):
            right = _evaluate(comparator, variables)
            step = _COMPARE[type(op)](left, right)
            result = step if result is None else np.logical_and(result, step)
            left = right
        return result
    if isinstance(node, ast.IfExp):
        return np.where(_evaluate(node.test, variables), _evaluate(node.body, variables),
                        _evaluate(node.orelse, variables))
    if isinstance(node, ast.Call):
        function = FUNCTIONS[node.func.id][0]  # type: ignore[attr-defined]
        return function(*(_evaluate(argument, variables) for argument in node.args))
    raise AssertionError(f"unchecked node {type(node).__name__}")
