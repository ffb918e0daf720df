"""Contact of bodies (2D and 3D) with the domain's walls: nothing passes through the box.

Two parts, both per node (`elastoflow.solid._contact_kernels`):

* **Held components** (a unilateral constraint inside the implicit step, as Baraff & Witkin
  1998 constrain cloth nodes in their implicit solve): at the start of a step, a node
  component resting on a wall whose force presses it into the wall is held at its position
  for the step. The implicit rules (`NewmarkFem`, `MidpointFem`, `EnergyMomentumFem`) take
  the hold in their Newton iteration, and their answer to the pressure (`HeldResponse`) is
  the constrained one, so the strongly coupled pressure solve sees a body that cannot move
  into the wall: a body at rest on the floor stays exactly at rest, its weight carried by
  the wall. A held component whose force turns away from the wall is released at the next
  step's start.
* **Projection** (Bridson, Fedkiw & Anderson 2002's inelastic collision impulse, per node,
  after the step): a node that ended the step beyond a wall is put back onto it and loses
  its velocity into the wall; its tangential velocity loses at most ``friction`` times the
  normal velocity change (Coulomb; in 3D the velocity in the wall's plane keeps its
  direction), also on held components (by their reaction's impulse).
  The box is convex, so a node inside at both ends of a step never crossed a wall.

The explicit substeps (`ExplicitFem`) take the projection after every substep instead.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg

from elastoflow.solid._contact_kernels import near_walls, project_onto_walls, select_held
from elastoflow.solid._response import StepResponse

# A node within this share of the box's size of a wall touches it (projected nodes sit on
# it exactly; this only forgives round-off).
_TOUCH_TOLERANCE = 1e-9


@dataclass(frozen=True)
class WallContact:
    """Contact of the bodies with the domain's walls (a swappable part of the coupled model).

    Attributes:
        friction: Coulomb friction coefficient mu >= 0 between a body and a wall: the
            tangential velocity change at a node is at most mu times its normal one (0:
            frictionless).
    """

    friction: float = 0.3

    def __post_init__(self) -> None:
        if not (np.isfinite(self.friction) and self.friction >= 0.0):
            raise ValueError(f"friction = {self.friction!r}: must be a finite number >= 0")


@dataclass(frozen=True)
class WallBox:
    """The walls a body may touch: sides of the box ``lower``..``upper`` [m], in 2D or 3D.

    Attributes:
        lower: (x0, y0[, z0]) [m].
        upper: (x1, y1[, z1]) [m].
        sides: Which sides are walls, two per axis: (left, right, bottom, top[, back,
            front]).
    """

    lower: tuple[float, ...]
    upper: tuple[float, ...]
    sides: tuple[bool, ...]

    def __post_init__(self) -> None:
        if len(self.lower) not in (2, 3) or len(self.upper) != len(self.lower):
            raise ValueError(f"lower = {self.lower!r}, upper = {self.upper!r}: must be two "
                             "or three coordinates each, as many in both")
        if len(self.sides) != 2 * len(self.lower):
            raise ValueError(f"sides = {self.sides!r}: must be {2 * len(self.lower)} "
                             "flags, two per axis")

    @property
    def dimension(self) -> int:
        """2 or 3."""
        return len(self.lower)

    @property
    def size(self) -> float:
        """The box's largest side [m]."""
        return max(hi - lo for lo, hi in zip(self.lower, self.upper, strict=True))

    @property
    def tolerance(self) -> float:
        """Distance [m] within which a node touches a wall."""
        return _TOUCH_TOLERANCE * self.size

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``lower``, ``upper``, ``sides`` as the kernels take them."""
        return (np.array(self.lower, dtype=np.float64), np.array(self.upper, dtype=np.float64),
                np.array(self.sides, dtype=np.bool_))

    def near(self, positions: np.ndarray, margin: float = 0.0) -> bool:
        """Whether a node of ``positions`` (n, d) lies within ``margin`` [m] of a wall."""
        lower, upper, sides = self.arrays()
        return bool(near_walls(np.ascontiguousarray(positions, dtype=np.float64), lower, upper,
                               sides, float(margin) + self.tolerance))


@dataclass
class WallHold:
    """The node components held on a wall over one step.

    Attributes:
        held: (n, d) bool, component a of node i held at its start position.
        impulse: (n, d) [m/s], the wall's reaction over the step per unit mass on held
            components (what friction is bounded by), 0 elsewhere.
        count: Number of held components.
    """

    held: np.ndarray
    impulse: np.ndarray
    count: int


def wall_hold(box: WallBox, positions: np.ndarray, velocities: np.ndarray,
              forces: np.ndarray, mass: np.ndarray, fixed_mask: np.ndarray,
              dt: float) -> WallHold:
    """The components of a body's nodes to hold on the walls this step (`select_held`).

    Args:
        box: The walls.
        positions, velocities: The body's state at the step's start, (n, d).
        forces: The nodes' total force estimate [N/m; N in 3D] (n, d): internal, gravity
            and the fluid's last force; its sign on a wall's normal decides press or release.
        mass: Lumped nodal masses [kg/m; kg in 3D] (n,).
        fixed_mask: The body's fixed nodes (n,).
        dt: The step [s].
    """
    if positions.shape[1] != box.dimension:
        raise ValueError(f"positions of shape {positions.shape}: the walls are "
                         f"{box.dimension}D")
    held = np.zeros(positions.shape, dtype=np.bool_)
    impulse = np.zeros(positions.shape)
    lower, upper, sides = box.arrays()
    count = select_held(np.ascontiguousarray(positions, dtype=np.float64),
                        np.ascontiguousarray(velocities, dtype=np.float64),
                        np.ascontiguousarray(forces, dtype=np.float64), 1.0 / mass,
                        fixed_mask, lower, upper, sides, box.tolerance, float(dt), held,
                        impulse)
    return WallHold(held, impulse, int(count))


def project_onto_box(box: WallBox, positions: np.ndarray, velocities: np.ndarray,
                     fixed_mask: np.ndarray, friction: float, position_weight: float,
                     impulse: np.ndarray | None = None) -> int:
    """Move the nodes beyond a wall onto it in place (`project_onto_walls`); returns how
    many components moved. ``impulse``: the held components' reaction (`WallHold`)."""
    if positions.shape[1] != box.dimension:
        raise ValueError(f"positions of shape {positions.shape}: the walls are "
                         f"{box.dimension}D")
    lower, upper, sides = box.arrays()
    if impulse is None:
        impulse = np.zeros_like(positions)
    return int(project_onto_walls(positions, velocities, fixed_mask,
                                  np.ascontiguousarray(impulse, dtype=np.float64), lower,
                                  upper, sides, float(friction), float(position_weight)))


class HeldResponse:
    """A body's step response with some degrees of freedom held: ``A_c^-1 = A^-1 - A^-1 P
    S^-1 P^T A^-1`` with ``S = P^T A^-1 P`` on the held degrees of freedom ``P`` (the
    answer of the matrix with those rows and columns removed, through the body's own factor
    and ``k`` extra solves for ``k`` held components). Held degrees of freedom answer 0.

    Serves the implicit rules' Newton iteration (`solve`) and the coupled pressure solve
    (`velocity_change`, `compliance`; no banded factor: the compliance is formed, a dense
    block on the touched degrees of freedom).

    Args:
        base: The unconstrained response (2D or 3D).
        held: (n, d) bool, the held components.
    """

    def __init__(self, base: StepResponse, held: np.ndarray) -> None:
        self.base = base
        self.dt = base.dt
        flat_held = np.flatnonzero(np.asarray(held, dtype=np.bool_).reshape(-1))
        self.held = np.intersect1d(flat_held, base.free).astype(np.int64)
        self.free = np.setdiff1d(base.free, self.held).astype(np.int64)
        self._size = held.size
        self._dimension = held.shape[1]
        k = self.held.shape[0]
        # G = A^-1 P (full degrees of freedom x k) by k solves with the base factor.
        columns = np.zeros((self._size, k))
        if k:
            position = np.full(self._size, -1, np.int64)
            position[base.free] = np.arange(base.free.shape[0])
            unit = np.zeros((base.free.shape[0], k))
            unit[position[self.held], np.arange(k)] = 1.0
            columns[base.free] = base._solve(unit).reshape(base.free.shape[0], k)
            block = columns[self.held]
            self._schur = linalg.cho_factor(0.5 * (block + block.T), check_finite=False)
        self._columns = columns

    def solve(self, values: np.ndarray) -> np.ndarray:
        """``A_c^-1 values`` for nodal values (n, d); 0 on held and fixed components."""
        result = self.base.solve(values).reshape(-1)
        if self.held.size:
            result -= self._columns @ linalg.cho_solve(self._schur, result[self.held],
                                                       check_finite=False)
            result[self.held] = 0.0
        return result.reshape(-1, self._dimension)

    def velocity_change(self, forces: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """``dv`` [m/s], shape (n, d), answering nodal ``forces`` held over ``dt``."""
        change = self.dt * self.solve(forces)
        if out is None:
            return change
        out[...] = change
        return out

    def compliance(self, dofs: np.ndarray) -> np.ndarray:
        """``dt A_c^-1`` on ``dofs`` (``d node + component``), dense, symmetric."""
        dofs = np.asarray(dofs, dtype=np.int64)
        if not self.held.size:
            return self.base.compliance(dofs)
        union = np.union1d(dofs, self.held)
        full = self.base.compliance(union)
        mine = np.searchsorted(union, dofs)
        held = np.searchsorted(union, self.held)
        coupling = full[np.ix_(mine, held)]
        schur = linalg.cho_factor(full[np.ix_(held, held)], check_finite=False)
        result = full[np.ix_(mine, mine)] - coupling @ linalg.cho_solve(
            schur, coupling.T, check_finite=False)
        result = 0.5 * (result + result.T)
        on_held = np.isin(dofs, self.held)
        result[on_held, :] = 0.0
        result[:, on_held] = 0.0
        return result

    def compliance_factor(self, dofs: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """None: the held compliance is formed by `compliance`."""
        return None


def hold_response(response: StepResponse, held: np.ndarray | None
                  ) -> StepResponse | HeldResponse:
    """``response`` with the components ``held`` (n, d) held, or itself when none are."""
    if held is None or not held.any():
        return response
    return HeldResponse(response, held)
