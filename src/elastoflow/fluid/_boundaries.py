from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def _check_finite(owner: str, name: str, value: float) -> None:
    if not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError(f"{owner}.{name} = {value!r}: must be a finite number")


@dataclass(frozen=True)
class WallNoSlip:
    """A solid wall at rest: zero normal and zero tangential velocity at the side."""


@dataclass(frozen=True)
class WallFreeSlip:
    """A frictionless wall: zero normal velocity, zero normal gradient of the tangential one."""


@dataclass(frozen=True)
class WallMoving:
    """A wall sliding along itself (a cavity lid), zero normal velocity.

    Attributes:
        velocity: Tangential wall velocity [m/s]: the x-velocity on the bottom and top sides,
            the y-velocity on the left and right sides.
    """

    velocity: float

    def __post_init__(self) -> None:
        _check_finite("WallMoving", "velocity", self.velocity)


@dataclass(frozen=True)
class Inflow:
    """Prescribed inflow through a side, normal to it and into the domain.

    Attributes:
        speed: Mean speed into the domain [m/s] ("uniform") or the peak speed ("parabolic").
        profile: "uniform" or "parabolic" (zero at both ends of the side).
        ramp_time: Start-up time [s]: the speed grows as (1 - cos(pi t / T)) / 2 up to T;
            0 means the full speed from the start.
        dye: Dye concentration carried in by the inflow.
    """

    speed: float
    profile: str = "uniform"
    ramp_time: float = 0.0
    dye: float = 0.0

    def __post_init__(self) -> None:
        _check_finite("Inflow", "speed", self.speed)
        if self.profile not in ("uniform", "parabolic"):
            raise ValueError(
                f"Inflow.profile = {self.profile!r}: must be 'uniform' or 'parabolic'"
            )
        _check_finite("Inflow", "ramp_time", self.ramp_time)
        if self.ramp_time < 0.0:
            raise ValueError(f"Inflow.ramp_time = {self.ramp_time!r}: must be >= 0")
        _check_finite("Inflow", "dye", self.dye)

    def ramp(self, time: float) -> float:
        """Fraction in [0, 1] of the full speed at ``time`` [s]."""
        if self.ramp_time <= 0.0 or time >= self.ramp_time:
            return 1.0
        if time <= 0.0:
            return 0.0
        return 0.5 * (1.0 - math.cos(math.pi * time / self.ramp_time))

    def profile_values(self, coordinate: np.ndarray, length: float) -> np.ndarray:
        """Speed profile [m/s] at full ramp at positions ``coordinate`` in [0, length] [m]."""
        if self.profile == "uniform":
            return np.full(coordinate.shape, float(self.speed))
        s = coordinate / length
        return 4.0 * float(self.speed) * s * (1.0 - s)


@dataclass(frozen=True)
class Outflow:
    """An open side: pressure 0 at the side, zero normal gradient of the velocity."""


Side = WallNoSlip | WallFreeSlip | WallMoving | Inflow | Outflow
_SIDE_TYPES = (WallNoSlip, WallFreeSlip, WallMoving, Inflow, Outflow)


@dataclass(frozen=True)
class DomainBoundaries:
    """The condition on each side of the rectangular domain.

    Attributes:
        left: Side x = x0.
        right: Side x = x0 + Lx.
        bottom: Side y = y0.
        top: Side y = y0 + Ly.
    """

    left: Side
    right: Side
    bottom: Side
    top: Side

    def __post_init__(self) -> None:
        for name in ("left", "right", "bottom", "top"):
            side = getattr(self, name)
            if not isinstance(side, _SIDE_TYPES):
                raise ValueError(
                    f"DomainBoundaries.{name} = {side!r}: must be WallNoSlip, WallFreeSlip, "
                    "WallMoving, Inflow or Outflow"
                )

    @classmethod
    def closed_box(cls) -> DomainBoundaries:
        """No-slip walls on all four sides."""
        wall = WallNoSlip()
        return cls(left=wall, right=wall, bottom=wall, top=wall)

    def sides(self) -> tuple[Side, Side, Side, Side]:
        """The four sides in the order left, right, bottom, top."""
        return (self.left, self.right, self.bottom, self.top)


@dataclass(frozen=True)
class Jet:
    """A region whose velocity faces are set to a prescribed velocity every step.

    Attributes:
        region: Rectangle ``(x0, y0, x1, y1)`` [m] in domain coordinates, x0 < x1, y0 < y1.
        velocity: Prescribed velocity ``(ux, uy)`` [m/s].
        dye: Dye concentration set in the cells whose centres lie in the region.
    """

    region: tuple[float, float, float, float]
    velocity: tuple[float, float]
    dye: float = 1.0

    def __post_init__(self) -> None:
        if len(self.region) != 4 or not all(math.isfinite(float(c)) for c in self.region):
            raise ValueError(f"Jet.region = {self.region!r}: must be four finite numbers")
        x0, y0, x1, y1 = (float(c) for c in self.region)
        if not (x0 < x1 and y0 < y1):
            raise ValueError(f"Jet.region = {self.region!r}: must satisfy x0 < x1 and y0 < y1")
        if len(self.velocity) != 2 or not all(math.isfinite(float(c)) for c in self.velocity):
            raise ValueError(f"Jet.velocity = {self.velocity!r}: must be two finite numbers")
        _check_finite("Jet", "dye", self.dye)
