"""The six sides of a 3D box domain.

The side conditions themselves are the 2D ones (`WallNoSlip`, `WallFreeSlip`, `Inflow`,
`Outflow`): what they mean does not depend on the dimension. Only the set of sides does, so
3D has its own `DomainBoundaries3D`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from elastoflow.fluid._boundaries import Inflow, Outflow, WallFreeSlip, WallNoSlip

SIDE_NAMES = ("left", "right", "bottom", "top", "back", "front")


@dataclass(frozen=True)
class WallMoving3D:
    """A wall sliding along itself (a lid), zero normal velocity (3D `WallMoving`).

    Attributes:
        velocity: Wall velocity ``(vx, vy, vz)`` [m/s]; its component normal to the side it
            is put on must be 0.
    """

    velocity: tuple[float, float, float]

    def __post_init__(self) -> None:
        if len(self.velocity) != 3 or not all(math.isfinite(float(c)) for c in self.velocity):
            raise ValueError(
                f"WallMoving3D.velocity = {self.velocity!r}: must be three finite numbers")


Side3D = WallNoSlip | WallFreeSlip | WallMoving3D | Inflow | Outflow
_SIDE_TYPES = (WallNoSlip, WallFreeSlip, WallMoving3D, Inflow, Outflow)


@dataclass(frozen=True)
class DomainBoundaries3D:
    """The condition on each side of the box domain.

    Attributes:
        left: Side x = x0.
        right: Side x = x0 + Lx.
        bottom: Side y = y0.
        top: Side y = y0 + Ly.
        back: Side z = z0.
        front: Side z = z0 + Lz.
    """

    left: Side3D
    right: Side3D
    bottom: Side3D
    top: Side3D
    back: Side3D
    front: Side3D

    def __post_init__(self) -> None:
        for name in SIDE_NAMES:
            side = getattr(self, name)
            if not isinstance(side, _SIDE_TYPES):
                raise ValueError(
                    f"DomainBoundaries3D.{name} = {side!r}: must be WallNoSlip, WallFreeSlip, "
                    "WallMoving3D, Inflow or Outflow"
                )
            axis = SIDE_NAMES.index(name) // 2
            if isinstance(side, WallMoving3D) and side.velocity[axis] != 0.0:
                raise ValueError(
                    f"DomainBoundaries3D.{name} = {side!r}: a moving wall slides along itself; "
                    f"its velocity's {'xyz'[axis]} component must be 0"
                )

    @classmethod
    def closed_box(cls) -> DomainBoundaries3D:
        """No-slip walls on all six sides."""
        wall = WallNoSlip()
        return cls(left=wall, right=wall, bottom=wall, top=wall, back=wall, front=wall)

    @classmethod
    def channel(cls, inflow: Inflow, walls: Side3D = WallNoSlip()) -> DomainBoundaries3D:
        """Flow along x: ``inflow`` on the left, outflow on the right, ``walls`` elsewhere."""
        return cls(left=inflow, right=Outflow(), bottom=walls, top=walls, back=walls,
                   front=walls)

    def sides(self) -> tuple[Side3D, ...]:
        """The six sides in the order left, right, bottom, top, back, front (the kernels'
        side numbers)."""
        return tuple(getattr(self, name) for name in SIDE_NAMES)


def inflow_profile_3d(inflow: Inflow, s: NDArray[np.floating],
                      t: NDArray[np.floating]) -> NDArray[np.float64]:
    """Speed [m/s] at full ramp on a side, at fractions ``s``, ``t`` in [0, 1] of its two
    tangential extents (arrays broadcast together): ``speed`` everywhere ("uniform"), or
    ``16 speed s (1 - s) t (1 - t)``, zero along the side's edges and ``speed`` at its
    centre ("parabolic")."""
    s, t = np.broadcast_arrays(np.asarray(s, dtype=np.float64), np.asarray(t, dtype=np.float64))
    if inflow.profile == "uniform":
        return np.full(s.shape, float(inflow.speed))
    return np.asarray(16.0 * float(inflow.speed) * s * (1.0 - s) * t * (1.0 - t),
                      dtype=np.float64)


@dataclass(frozen=True)
class Jet3D:
    """A box whose velocity faces are set to a prescribed velocity every step (3D `Jet`).

    Attributes:
        region: Box ``(x0, y0, z0, x1, y1, z1)`` [m] in domain coordinates, x0 < x1, y0 < y1,
            z0 < z1; the u, v and w points inside it (boundary included) get the velocity.
        velocity: Prescribed velocity ``(ux, uy, uz)`` [m/s].
        dye: Dye concentration set in the cells whose centres lie in the box.
    """

    region: tuple[float, float, float, float, float, float]
    velocity: tuple[float, float, float]
    dye: float = 1.0

    def __post_init__(self) -> None:
        if len(self.region) != 6 or not all(math.isfinite(float(c)) for c in self.region):
            raise ValueError(f"Jet3D.region = {self.region!r}: must be six finite numbers")
        low, high = self.region[:3], self.region[3:]
        if not all(a < b for a, b in zip(low, high, strict=True)):
            raise ValueError(
                f"Jet3D.region = {self.region!r}: must satisfy x0 < x1, y0 < y1 and z0 < z1")
        if len(self.velocity) != 3 or not all(math.isfinite(float(c)) for c in self.velocity):
            raise ValueError(f"Jet3D.velocity = {self.velocity!r}: must be three finite numbers")
        if not math.isfinite(float(self.dye)):
            raise ValueError(f"Jet3D.dye = {self.dye!r}: must be a finite number")
