"""The level set of a free surface: constructors, transport, redistancing, volume correction.

The level set ``phi`` [m] lives in the cells, shape (nx, ny): liquid where ``phi < 0``, air
where ``phi >= 0``, ``|phi|`` about the distance to the surface. `LevelSetTransport` is the
scheme that carries it with the flow each step (MacCormack or semi-Lagrangian), keeps it a
signed distance (`RedistanceFastSweeping`) and keeps the liquid area (global volume
correction). The state itself is an array of `FreeSurfaceState` (elastoflow.fluid).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from elastoflow.fluid import _level_set_kernels as kernels
from elastoflow.grid import Grid2D

FloatArray = NDArray[np.float64]

_LEVEL_SET_ADVECTION = ("semi_lagrangian", "maccormack")


def level_set_from_function(
    grid: Grid2D, distance: Callable[[FloatArray, FloatArray], FloatArray]
) -> FloatArray:
    """The level set of ``distance(x, y)`` [m] at the cell centres, shape (nx, ny).

    Args:
        grid: The grid.
        distance: Signed distance (negative in the liquid) at positions x, y [m], arrays of
            the cells' shape.
    """
    x, y = grid.cell_centers()
    return np.ascontiguousarray(distance(x, y), dtype=np.float64)


def level_set_below(grid: Grid2D, height: Callable[[FloatArray], FloatArray] | float) -> FloatArray:
    """Liquid below the surface ``y = height(x)`` [m] (a number: a flat surface).

    The level set is ``y - height(x)``, a signed distance for a flat surface and close to one
    for a gentle wave (redistance it for a steep one).
    """
    x, y = grid.cell_centers()
    surface = height(x) if callable(height) else np.full_like(x, float(height))
    return np.ascontiguousarray(y - surface, dtype=np.float64)


def level_set_box(grid: Grid2D, region: tuple[float, float, float, float]) -> FloatArray:
    """Liquid filling the rectangle ``(x0, y0, x1, y1)`` [m]: its exact signed distance.

    A box that reaches a domain side extends beyond it (the side is then a wall, not a surface).
    """
    x0, y0, x1, y1 = (float(c) for c in region)
    if not (x0 < x1 and y0 < y1):
        raise ValueError(f"level_set_box region = {region!r}: must satisfy x0 < x1 and y0 < y1")
    h = grid.h
    ox, oy = grid.origin
    # Sides of the box on the domain's sides move outwards: walls, not surfaces.
    if x0 <= ox:
        x0 = ox - 10.0 * grid.lx
    if y0 <= oy:
        y0 = oy - 10.0 * grid.ly
    if x1 >= ox + grid.nx * h:
        x1 = ox + 11.0 * grid.lx
    if y1 >= oy + grid.ny * h:
        y1 = oy + 11.0 * grid.ly
    x, y = grid.cell_centers()
    dx = np.maximum(x0 - x, x - x1)
    dy = np.maximum(y0 - y, y - y1)
    outside = np.hypot(np.maximum(dx, 0.0), np.maximum(dy, 0.0))
    inside = np.minimum(np.maximum(dx, dy), 0.0)
    return np.ascontiguousarray(outside + inside, dtype=np.float64)


def liquid_area(level_set: FloatArray, h: float) -> float:
    """Liquid area [m^2] (per metre of depth: volume [m^3/m]) of a level set on cells of side
    ``h`` [m]: each cell counts ``clamp(1/2 - phi / h, 0, 1) h^2``."""
    area, _ = kernels.liquid_area(level_set, float(h))
    return float(area)


def correct_volume(level_set: FloatArray, h: float, target: float, iterations: int = 8) -> float:
    """Shift ``level_set`` in place by a constant so that its `liquid_area` is ``target``.

    The area is piecewise linear in the shift, with slope ``-h * (cells on the ramp)``: Newton
    steps reach the target to round-off in a few iterations unless the ramp cells change.

    Returns:
        The total shift [m] added to the level set.
    """
    total = 0.0
    for _ in range(iterations):
        area, ramp = kernels.liquid_area(level_set, float(h))
        excess = float(area) - target
        if ramp == 0 or abs(excess) <= 1e-14 * max(target, h * h):
            break
        shift = excess / (h * ramp)
        level_set += shift
        total += shift
    return total


@dataclass(frozen=True)
class RedistanceFastSweeping:
    """Redistancing by first-order fast sweeping (Zhao 2005) in a Numba kernel.

    The cells next to the interface keep their zero crossing (``phi / |grad phi|``; where
    |grad phi| < 1, at most the distance to their nearest crossing along a grid direction);
    the rest get the upwind distance from them.

    Attributes:
        bound_by_crossings: Bound the cells next to the interface by their crossing distance
            (default); False: ``phi / |grad phi|`` alone (the former scheme, which thickened
            sheets one or two cells thick; kept for comparison).
        rounds: Rounds of four sweeps. One is exact for a straight surface; far from a folded
            one it leaves distances too large, which nothing reads (only the sign and the
            values next to the surface are used): the dam break at a / 16 gave the same
            front and liquid area to 4 digits with 1 and 2 rounds (T = 3.3, 7, 9), and one
            round halves the cost (2.5 against 4.1 ms at 256x128).
    """

    rounds: int = 1
    bound_by_crossings: bool = True
    _padded: dict[tuple[int, int], tuple[FloatArray, NDArray[np.bool_]]] = field(
        default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not isinstance(self.rounds, int) or self.rounds < 1:
            raise ValueError(f"RedistanceFastSweeping.rounds = {self.rounds!r}: must be an int >= 1")

    def redistance(self, level_set: FloatArray, h: float, out: FloatArray,
                   scratch: NDArray[np.bool_] | None = None) -> None:
        """Write the signed distance [m] to the zero level of ``level_set`` into ``out``
        (shape (nx, ny), not ``level_set``).

        The sweeps work on padded copies kept per grid shape (so one instance must not
        redistance from several threads at once). ``scratch`` (optional; bool, shape
        (nx, ny)) receives the cells next to the surface, those that kept their crossing."""
        shape = (int(level_set.shape[0]), int(level_set.shape[1]))
        padded = self._padded.get(shape)
        if padded is None:
            size = (shape[0] + 2) * (shape[1] + 2)
            padded = (np.empty(size), np.empty(size, dtype=np.bool_))
            self._padded[shape] = padded
        kernels.redistance_fast_sweeping(level_set, float(h), self.rounds, out, *padded,
                                         bool(self.bound_by_crossings))
        if scratch is not None:
            scratch[...] = padded[1].reshape(shape[0] + 2, shape[1] + 2)[1:-1, 1:-1]


@dataclass(frozen=True)
class LevelSetTransport:
    """How the level set moves each step.

    Attributes:
        advection: "maccormack" (default; second order in smooth regions, clamped to the
            local range, Selle et al. 2008) or "semi_lagrangian" (first order, diffusive).
        redistancing: How it is kept a signed distance (None: never).
        redistance_interval: Redistance every this many steps.
        volume_correction: Shift the level set after each step so that the liquid area stays
            the initial one (`correct_volume`): a global correction, which puts the area that
            advection and redistancing lose back uniformly along the whole surface.
    """

    advection: str = "maccormack"
    redistancing: RedistanceFastSweeping | None = field(default_factory=RedistanceFastSweeping)
    redistance_interval: int = 1
    volume_correction: bool = True

    def __post_init__(self) -> None:
        if self.advection not in _LEVEL_SET_ADVECTION:
            raise ValueError(
                f"LevelSetTransport.advection = {self.advection!r}: must be one of "
                f"{_LEVEL_SET_ADVECTION}"
            )
        if not isinstance(self.redistance_interval, int) or self.redistance_interval < 1:
            raise ValueError(
                f"LevelSetTransport.redistance_interval = {self.redistance_interval!r}: "
                "must be an int >= 1"
            )


class LevelSetWorkspace:
    """Scratch arrays of `LevelSetTransport` on one grid (allocated once)."""

    def __init__(self, grid: Grid2D) -> None:
        shape = grid.shape_cells
        self.forward = np.zeros(shape)
        self.backward = np.zeros(shape)
        # MacCormack's clamp range, from its first pass (`advect_cells_forward_range`).
        self.low = np.zeros(shape)
        self.high = np.zeros(shape)
        # Per row of u and of v, the hull of the columns with a value other than 0 (low u,
        # high u, low v, high v; `nonzero_spans`): cells in still air are not traced.
        nx = shape[0]
        self.nonzero_spans = (np.zeros(nx + 1, dtype=np.int64), np.zeros(nx + 1, dtype=np.int64),
                              np.zeros(nx, dtype=np.int64), np.zeros(nx, dtype=np.int64))
        self.fixed = np.zeros(shape, dtype=np.bool_)


def still_air_spans(velocity_x: FloatArray, velocity_y: FloatArray,
                    workspace: LevelSetWorkspace) -> tuple[NDArray[np.int64], ...]:
    """`nonzero_spans` of u and v into the workspace's arrays, for the MacCormack kernels."""
    spans = workspace.nonzero_spans
    kernels.nonzero_spans(velocity_x, spans[0], spans[1])
    kernels.nonzero_spans(velocity_y, spans[2], spans[3])
    return spans


def transport_level_set(
    transport: LevelSetTransport, grid: Grid2D, level_set: FloatArray, velocity_x: FloatArray,
    velocity_y: FloatArray, dt: float, step_index: int, target_area: float | None,
    workspace: LevelSetWorkspace,
) -> None:
    """Advance ``level_set`` [m] in place over ``dt`` [s] by the face velocity (u, v) [m/s]:
    advect, redistance (on steps that are multiples of the interval), correct the volume.

    The velocity must be defined around the surface on both sides (extrapolated into the air).
    """
    step = dt / grid.h
    forward, backward = workspace.forward, workspace.backward
    if transport.advection == "maccormack":
        # Two passes, each tracing back once (the clamp's range is found in the first).
        spans = still_air_spans(velocity_x, velocity_y, workspace)
        kernels.advect_cells_forward_range(level_set, velocity_x, velocity_y, step, forward,
                                           workspace.low, workspace.high, *spans)
        kernels.maccormack_backward_correct(level_set, forward, workspace.low, workspace.high,
                                            velocity_x, velocity_y, step, backward, *spans)
        result = backward
    else:
        kernels.advect_cells_semi_lagrangian(level_set, velocity_x, velocity_y, step, forward)
        result = forward
    redistancing = transport.redistancing
    if redistancing is not None and step_index % transport.redistance_interval == 0:
        other = forward if result is backward else backward
        redistancing.redistance(result, grid.h, other)
        result = other
    level_set[...] = result
    if transport.volume_correction and target_area is not None:
        correct_volume(level_set, grid.h, target_area)
