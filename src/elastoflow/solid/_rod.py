"""Elastic rods and strings: a body of zero thickness for the fluid, a polyline for the solid.

A rod in 2D (per unit depth: a plate or membrane seen edge on) is a polyline of nodes with
lumped masses, stretching energy on its segments and bending energy at its interior nodes
(a discrete elastic rod, Bergou et al. 2008, reduced to the plane: no twist):

* stretching, segment i from node i to i+1, rest length L_i: Green strain
  ``eps_i = (|e_i|^2 - L_i^2) / (2 L_i^2)``, energy ``EA L_i eps_i^2 / 2``;
* bending at node j between segments a = e_(j-1) and b = e_j: ``q_j = a x b`` (the z
  component of the cross product, ``|a| |b| sin(theta_j)``), energy
  ``EI (q_j - q_j^rest)^2 / (2 l_j (L_(j-1) L_j)^2)`` with ``l_j`` the node's share of the
  rest length: for small turns ``EI theta^2 / (2 l)``, the Euler-Bernoulli energy
  ``EI kappa^2 l / 2`` with curvature ``theta / l``.

Both measures are quadratic in the positions (eps through ``|e|^2``, q bilinear in a and b),
so Simo & Tarnow's energy-momentum rule is exact for them as for St. Venant-Kirchhoff: at a
step's midpoint the mean of the ends' strain is the midpoint's plus ``w`` times the rate's
(``w = dt^2 / 8``, `forces_at`'s ``rate_strain``): ``|e|^2`` gains ``2 w |edot|^2`` and q
gains ``2 w adot x bdot``. Both are invariant under rigid motion (objective), so the
implicit midpoint and energy-momentum steps keep both momenta.

A clamped end holds its node and its tangent: a fixed ghost node one rest segment behind the
end, whose bending term has half a segment as its length share (the clamped node's own), so
that a clamped rod's curvature at the clamp is that of the beam, not of a beam half a segment
longer. Clamped and pinned nodes are held (`fixed_mask`), as an `ElasticBody`'s fixed nodes.

For the fluid the rod is the loop along its line and back (as `coupling.obstacle_polyline`):
it covers no grid point and no face, and the thin-body cuts (`coupling._thin`) make the
pressure see it. `RodBody` has the attributes and methods the implicit integrators
(`NewmarkFem`, `MidpointFem`, `EnergyMomentumFem`, `static_equilibrium`) and the monolithic
coupling read of a body; its ``mesh`` is a `PolylineMesh`, a mesh without triangles.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy import linalg

from elastoflow.solid._body import ElasticBody
from elastoflow.solid._response import _BLAS, StepResponse
from elastoflow.solid._state import BodyState

RodEnd = Literal["start", "end"]


@dataclass(frozen=True)
class MaterialRod:
    """A rod's material and cross-section, per unit depth (a plate of ``thickness`` in 2D).

    Attributes:
        density: Mass density [kg/m^3].
        young_modulus: Young's modulus E [Pa] (a plate in plane strain: E / (1 - nu^2)).
        thickness: Thickness t [m] of the cross-section; the fluid sees the rod as a line.
        bending_stiffness: Flexural rigidity EI per unit depth [N m]; None: ``E t^3 / 12``;
            0: a string (tension only).
        damping_time: Kelvin-Voigt relaxation time tau [s]: the viscous forces are the
            elastic ones of the strain rate times tau (stretching and bending), >= 0.
    """

    density: float
    young_modulus: float
    thickness: float
    bending_stiffness: float | None = None
    damping_time: float = 0.0

    def __post_init__(self) -> None:
        for name in ("density", "young_modulus", "thickness"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0.0):
                raise ValueError(f"rod {name} = {value!r}: must be finite and > 0")
        if self.bending_stiffness is not None and not (
                np.isfinite(self.bending_stiffness) and self.bending_stiffness >= 0.0):
            raise ValueError(
                f"rod bending_stiffness = {self.bending_stiffness!r}: must be finite and >= 0")
        if not (np.isfinite(self.damping_time) and self.damping_time >= 0.0):
            raise ValueError(f"rod damping_time = {self.damping_time!r}: must be finite, >= 0")

    @property
    def line_density(self) -> float:
        """Mass per length and depth ``rho t`` [kg/m^2]."""
        return self.density * self.thickness

    @property
    def stretch_stiffness(self) -> float:
        """Axial stiffness EA per unit depth ``E t`` [N/m]."""
        return self.young_modulus * self.thickness

    @property
    def flexural_rigidity(self) -> float:
        """EI per unit depth [N m]: ``bending_stiffness`` or ``E t^3 / 12``."""
        if self.bending_stiffness is not None:
            return float(self.bending_stiffness)
        return self.young_modulus * self.thickness**3 / 12.0

    @property
    def dilatational_wave_speed(self) -> float:
        """Speed of axial waves ``sqrt(E / rho)`` [m/s] (`static_equilibrium`'s time scale)."""
        return math.sqrt(self.young_modulus / self.density)


class PolylineMesh:
    """A rod's rest line, read by the coupling as a mesh without triangles.

    Attributes:
        points: Rest node positions [m], shape (n, 2), n >= 2, read-only.
        triangles: None of them, shape (0, 3) (the interface operator then takes the body
            velocity of the nearest point of the line).
        boundary_edges: The loop along the line and back, (2n - 2, 2): its k segments
            forwards, then backwards, so it encloses no area.
    """

    def __init__(self, points: np.ndarray) -> None:
        points = np.array(points, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 2 or points.shape[0] < 2:
            raise ValueError(f"rod points shape {points.shape}: must be (n, 2), n >= 2")
        if not np.all(np.isfinite(points)):
            raise ValueError("rod points: values must be finite")
        repeated = np.flatnonzero(np.all(points[1:] == points[:-1], axis=1))
        if repeated.size:
            raise ValueError(f"rod points {int(repeated[0])} and {int(repeated[0]) + 1}: "
                             "equal; consecutive points must differ")
        points.setflags(write=False)
        self.points = points
        self.triangles = np.zeros((0, 3), dtype=np.int64)
        first = np.arange(points.shape[0] - 1, dtype=np.int64)
        forward = np.stack([first, first + 1], axis=1)
        self.boundary_edges = np.concatenate([forward, forward[::-1, ::-1]])
        self.segments = forward

    @property
    def point_count(self) -> int:
        """Number of nodes n."""
        return int(self.points.shape[0])

    @property
    def triangle_count(self) -> int:
        """0: a rod has no area."""
        return 0


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


class RodBody:
    """An elastic rod's model: rest line, material, held nodes and lumped masses.

    Static, as `ElasticBody`: the changing part is a `BodyState`, advanced by the implicit
    integrators or `static_equilibrium` (the explicit substeps, `ExplicitFem`, are for
    triangle bodies only). Energies and forces: module docstring.

    Attributes:
        mesh: The rest line (`PolylineMesh`).
        material: `MaterialRod`.
        mass: Lumped node mass [kg/m] (half of each adjacent segment's), shape (n,).
        inverse_mass: ``1 / mass``, shape (n,).
        fixed_mask: Held nodes (clamped and pinned), bool, shape (n,).
        fixed_nodes: Their indices.
        gravity: [m/s^2], shape (2,).
        velocity_damping: Drag rate alpha [1/s] (force ``-alpha m v``).
        rest_lengths: L_i [m], shape (n - 1,).
        hinges: Bending terms (i, j, k): node j between nodes i and k, indices into the
            positions followed by the ghost nodes of clamped ends, shape (h, 3).
        ghosts: The clamped ends' fixed ghost positions [m], shape (g, 2).
    """

    def __init__(
        self,
        points: np.ndarray | Sequence[tuple[float, float]],
        material: MaterialRod,
        *,
        clamped: Sequence[RodEnd] = (),
        pinned_nodes: Sequence[int] | np.ndarray = (),
        gravity: tuple[float, float] | np.ndarray = (0.0, 0.0),
        positions: np.ndarray | None = None,
        velocities: np.ndarray | None = None,
        velocity_damping: float = 0.0,
    ) -> None:
        """A rod whose initial state is its rest line at rest, unless ``positions`` or
        ``velocities`` are given.

        Args:
            points: Rest node positions [m], shape (n, 2), n >= 3 when it bends.
            material: Material and cross-section.
            clamped: Ends held in place and in direction: ``"start"`` (node 0), ``"end"``
                (node n - 1). The clamp keeps the end segment's rest direction.
            pinned_nodes: Nodes held in place, free to turn.
            gravity: Acceleration of gravity on the rod [m/s^2].
            positions: Initial positions [m], shape (n, 2); default the rest points.
            velocities: Initial velocities [m/s], shape (n, 2); default zero (zeroed on held
                nodes).
            velocity_damping: Drag rate alpha [1/s], force ``-alpha m v`` (dynamic
                relaxation).
        """
        self.mesh = PolylineMesh(np.asarray(points, dtype=np.float64))
        self.material = material
        rest = self.mesh.points
        n = rest.shape[0]
        for end in clamped:
            if end not in ("start", "end"):
                raise ValueError(f"clamped end {end!r}: must be 'start' or 'end'")
        pinned = np.asarray(pinned_nodes, dtype=np.int64).ravel()
        if pinned.size and (pinned.min() < 0 or pinned.max() >= n):
            raise ValueError(f"pinned_nodes: node indices must lie in [0, {n})")
        gravity_array = np.asarray(gravity, dtype=np.float64)
        if gravity_array.shape != (2,) or not np.all(np.isfinite(gravity_array)):
            raise ValueError(f"gravity = {gravity!r}: must be two finite numbers [m/s^2]")
        if not (np.isfinite(velocity_damping) and velocity_damping >= 0.0):
            raise ValueError(f"velocity_damping = {velocity_damping!r}: must be finite and >= 0")
        self.gravity = gravity_array
        self.velocity_damping = float(velocity_damping)

        initial = BodyState(_state_array("positions", positions, rest),
                            _state_array("velocities", velocities, np.zeros((n, 2))))
        segments = rest[1:] - rest[:-1]
        self.rest_lengths = np.linalg.norm(segments, axis=1)
        share = np.zeros(n)
        share[:-1] += 0.5 * self.rest_lengths
        share[1:] += 0.5 * self.rest_lengths
        self.mass = material.line_density * share
        self.inverse_mass = 1.0 / self.mass

        self.fixed_mask = np.zeros(n, dtype=np.bool_)
        self.fixed_mask[pinned] = True
        hinges = [np.stack([np.arange(n - 2), np.arange(1, n - 1), np.arange(2, n)], axis=1)]
        lengths = [0.5 * (self.rest_lengths[:-1] + self.rest_lengths[1:])]
        ghosts: list[np.ndarray] = []
        rest_ghosts: list[np.ndarray] = []
        for end in dict.fromkeys(clamped):
            # The ghost continues the end segment's rest direction behind the clamped node.
            node, inner, segment = (0, 1, 0) if end == "start" else (n - 1, n - 2, n - 2)
            self.fixed_mask[node] = True
            ghost = n + len(ghosts)
            ghosts.append(initial.positions[node] - (rest[inner] - rest[node]))
            rest_ghosts.append(rest[node] - (rest[inner] - rest[node]))
            hinges.append(np.array([[ghost, node, inner] if end == "start"
                                    else [inner, node, ghost]]))
            lengths.append(np.array([0.5 * self.rest_lengths[segment]]))
        self.ghosts = np.array(ghosts, dtype=np.float64).reshape(-1, 2)
        self.hinges = np.concatenate(hinges).astype(np.int64)
        hinge_length = np.concatenate(lengths)
        rest_extended = np.concatenate([rest, np.reshape(rest_ghosts, (-1, 2))])
        a = rest_extended[self.hinges[:, 1]] - rest_extended[self.hinges[:, 0]]
        b = rest_extended[self.hinges[:, 2]] - rest_extended[self.hinges[:, 1]]
        la, lb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
        self.rest_cross = _cross(a, b)
        self.hinge_coefficients = material.flexural_rigidity / (hinge_length * (la * lb) ** 2)
        self.fixed_nodes = np.flatnonzero(self.fixed_mask)
        initial.velocities[self.fixed_mask] = 0.0
        self._initial = initial
        self._layout = _rod_band_layout(n, self.hinges, self.fixed_mask)

    @property
    def point_count(self) -> int:
        """Number of nodes."""
        return self.mesh.point_count

    @property
    def boundary_edges(self) -> np.ndarray:
        """The loop along the line and back, shape (2n - 2, 2)."""
        return self.mesh.boundary_edges

    def state(self) -> BodyState:
        """A new copy of the rod's initial state."""
        return self._initial.copy()

    def check_state(self, state: BodyState) -> None:
        """Raise ValueError unless ``state`` has this rod's shape and finite values."""
        expected = (self.point_count, 2)
        for name in ("positions", "velocities"):
            value = getattr(state, name)
            if value.shape != expected or not np.all(np.isfinite(value)):
                raise ValueError(f"{name}: must be finite, shape {expected}")

    def stable_substep(self, safety: float = 0.5) -> float:
        """Explicit stability estimate [s] (reported only; rods advance implicitly): the
        axial wave's ``L / c`` and the bending wave's ``L^2 / (2 sqrt(EI / (rho t)))``."""
        m = self.material
        length = float(self.rest_lengths.min())
        axial = length / m.dilatational_wave_speed
        bending_speed = math.sqrt(m.flexural_rigidity / m.line_density)
        bending = length * length / (2.0 * bending_speed) if bending_speed > 0 else np.inf
        return safety * min(axial, bending)

    def _extended(self, positions: np.ndarray) -> np.ndarray:
        return np.concatenate([positions, self.ghosts]) if self.ghosts.size else positions

    def _forces(self, positions: np.ndarray, velocities: np.ndarray, rate_strain: float,
                elastic: float, viscous: float) -> np.ndarray:
        """Nodal forces of ``elastic`` times the elastic energy's gradient (strains with
        ``rate_strain`` w) plus a Voigt damping of relaxation time ``viscous``."""
        ea = self.material.stretch_stiffness
        lengths = self.rest_lengths
        e = positions[1:] - positions[:-1]
        rate = velocities[1:] - velocities[:-1]
        strain = ((np.sum(e * e, axis=1) + 2.0 * rate_strain * np.sum(rate * rate, axis=1))
                  / lengths**2 - 1.0) * 0.5
        strain_rate = np.sum(e * rate, axis=1) / lengths**2
        tension = (ea / lengths * (elastic * strain + viscous * strain_rate))[:, None] * e
        forces = np.zeros_like(positions)
        forces[1:] -= tension
        forces[:-1] += tension
        if self.hinges.shape[0] and self.material.flexural_rigidity > 0.0:
            x = self._extended(positions)
            v = np.concatenate([velocities, np.zeros_like(self.ghosts)])
            i, j, k = self.hinges[:, 0], self.hinges[:, 1], self.hinges[:, 2]
            a, b = x[j] - x[i], x[k] - x[j]
            a_rate, b_rate = v[j] - v[i], v[k] - v[j]
            q = _cross(a, b) + 2.0 * rate_strain * _cross(a_rate, b_rate)
            q_rate = _cross(a_rate, b) + _cross(a, b_rate)
            moment = self.hinge_coefficients * (elastic * (q - self.rest_cross)
                                                + viscous * q_rate)
            d_a = np.stack([b[:, 1], -b[:, 0]], axis=1) * moment[:, None]
            d_b = np.stack([-a[:, 1], a[:, 0]], axis=1) * moment[:, None]
            extended = np.zeros_like(x)
            np.add.at(extended, i, d_a)
            np.add.at(extended, j, d_b - d_a)
            np.add.at(extended, k, -d_b)
            forces += extended[: positions.shape[0]]
        return forces

    def forces_at(self, positions: np.ndarray, velocities: np.ndarray,
                  rate_strain: float = 0.0) -> np.ndarray:
        """Internal (elastic, Voigt and drag) nodal forces [N/m] at a given state.

        ``rate_strain`` w > 0 takes the strains as their value plus w times the rates'
        (``|e|^2 + 2 w |edot|^2``, ``q + 2 w adot x bdot``): at a step's midpoint with ``w =
        dt^2 / 8`` the mean of the ends' (`EnergyMomentumFem`)."""
        forces = self._forces(positions, velocities, float(rate_strain), 1.0,
                              self.material.damping_time)
        if self.velocity_damping:
            forces -= self.velocity_damping * self.mass[:, None] * velocities
        return forces

    def viscous_forces_at(self, positions: np.ndarray, velocities: np.ndarray,
                          time_scale: float) -> np.ndarray:
        """Nodal forces [N/m] of a Voigt damping of relaxation time ``time_scale`` [s]
        (objective: no force for rigid motion)."""
        if time_scale == 0.0:
            return np.zeros_like(positions)
        return self._forces(positions, velocities, 0.0, 0.0, float(time_scale))

    def internal_forces(self, state: BodyState) -> np.ndarray:
        """Elastic plus Voigt nodal forces [N/m] in ``state`` (without the drag)."""
        return self._forces(state.positions, state.velocities, 0.0, 1.0,
                            self.material.damping_time)

    def response_at(self, positions: np.ndarray, dt: float,
                    stiffness_step: float | None = None,
                    scale: float | None = None,
                    nodal_damping: np.ndarray | None = None) -> StepResponse:
        """The linearised answer ``(M + dt D + s^2 K + dt alpha M) dv = scale f`` at
        ``positions`` (as `ElasticBody.response_at`, ``nodal_damping`` blocks (n, 2, 2) added
        to ``D`` when given), factored as a band (natural order, half-band 5). K keeps what
        is positive semi-definite for any shape: the material parts of stretching and
        bending and the geometric part of tension (compression and the bending's own
        curvature term left out), so the matrix stays SPD."""
        s = dt if stiffness_step is None else float(stiffness_step)
        answer = dt if scale is None else float(scale)
        m = self.material
        material_weight = s * s + dt * m.damping_time
        x = self._extended(np.asarray(positions, dtype=np.float64))
        n = self.point_count
        lengths = self.rest_lengths
        e = x[1:n] - x[: n - 1]
        strain = 0.5 * (np.sum(e * e, axis=1) / lengths**2 - 1.0)
        ea = m.stretch_stiffness
        # Per segment, the 2x2 block K_ee; nodes (i, i+1) get [[K, -K], [-K, K]].
        outer = e[:, :, None] * e[:, None, :]
        block = (material_weight * ea / lengths**3)[:, None, None] * outer
        # Compression softens the transverse stiffness by far more than a slender rod's
        # bending stiffens it (EA eps / L against EI / L^3): left out, Newton crawled (40
        # iterations a step for a spinning rod). It is kept down to what leaves half of
        # the lumped mass, so the matrix stays SPD for any step.
        geometric = s * s * ea / lengths * strain
        floor = -0.125 * np.minimum(self.mass[:-1], self.mass[1:])
        block += np.maximum(geometric, floor)[:, None, None] * np.eye(2)
        signs = np.array([[1.0, -1.0], [-1.0, 1.0]])
        stretch = (signs[None, :, None, :, None] * block[:, None, :, None, :]).reshape(-1, 4, 4)
        values = [stretch.reshape(-1)]
        if self.hinges.shape[0] and m.flexural_rigidity > 0.0:
            i, j, k = self.hinges[:, 0], self.hinges[:, 1], self.hinges[:, 2]
            a, b = x[j] - x[i], x[k] - x[j]
            d_a = np.stack([b[:, 1], -b[:, 0]], axis=1)
            d_b = np.stack([-a[:, 1], a[:, 0]], axis=1)
            gradient = np.concatenate([-d_a, d_a - d_b, d_b], axis=1)
            bend = (material_weight * self.hinge_coefficients)[:, None, None] * (
                gradient[:, :, None] * gradient[:, None, :])
            values.append(bend.reshape(-1))
        layout = self._layout
        flat_storage = np.zeros((layout.band + 1) * layout.free.size)
        flat = np.concatenate(values)
        keep = layout.target >= 0
        np.add.at(flat_storage, layout.target[keep], flat[keep])
        storage = flat_storage.reshape(layout.band + 1, layout.free.size)
        lumped = np.repeat(self.mass * (1.0 + dt * self.velocity_damping), 2)[layout.free]
        storage[layout.band] += lumped
        if nodal_damping is not None:
            _add_nodal_blocks(storage, layout, dt * np.asarray(nodal_damping[:n]))
        if layout.free.size == 0:
            return StepResponse(layout.free, answer, None)
        with _BLAS.limit(limits=1, user_api="blas"):
            factor = linalg.cholesky_banded(storage, lower=False, check_finite=False)
        return StepResponse(layout.free, answer, None, None, factor,
                            np.arange(layout.free.size, dtype=np.int64))

    def step_response(self, state: BodyState, dt: float) -> StepResponse:
        """The linearised backward-Euler answer to a force held over ``dt`` [s]."""
        return self.response_at(state.positions, dt)

    def determinants_at(self, positions: np.ndarray) -> np.ndarray:
        """Stretch ``|e_i| / L_i`` of each segment, shape (n - 1,): the rod's det F (a
        segment collapsed to a point has 0)."""
        e = positions[1:] - positions[:-1]
        return np.asarray(np.linalg.norm(e, axis=1) / self.rest_lengths)

    def deformation_determinants(self, state: BodyState) -> np.ndarray:
        """Stretch of each segment in ``state``, shape (n - 1,)."""
        return self.determinants_at(state.positions)

    def elastic_energy(self, state: BodyState) -> float:
        """Stretching plus bending energy [J/m] of the state's positions."""
        x = self._extended(state.positions)
        n = self.point_count
        e = x[1:n] - x[: n - 1]
        lengths = self.rest_lengths
        strain = 0.5 * (np.sum(e * e, axis=1) / lengths**2 - 1.0)
        energy = 0.5 * self.material.stretch_stiffness * float(np.sum(lengths * strain**2))
        if self.hinges.shape[0]:
            i, j, k = self.hinges[:, 0], self.hinges[:, 1], self.hinges[:, 2]
            q = _cross(x[j] - x[i], x[k] - x[j])
            energy += 0.5 * float(np.sum(self.hinge_coefficients * (q - self.rest_cross) ** 2))
        return energy

    def kinetic_energy(self, state: BodyState) -> float:
        """Kinetic energy ``sum m |v|^2 / 2`` [J/m] with the lumped masses."""
        return float(0.5 * np.sum(self.mass * np.sum(state.velocities**2, axis=1)))

    def gravity_potential_energy(self, state: BodyState) -> float:
        """Potential energy ``-sum m g . x`` [J/m] in the gravity field (zero at the origin)."""
        return float(-np.sum(self.mass * (state.positions @ self.gravity)))

    def total_energy(self, state: BodyState) -> float:
        """Elastic plus kinetic plus gravity potential energy [J/m]."""
        return (self.elastic_energy(state) + self.kinetic_energy(state)
                + self.gravity_potential_energy(state))


@dataclass(frozen=True)
class _RodBandLayout:
    """Where each entry of `RodBody.response_at`'s element matrices lands in the upper
    banded storage (flat index into ``(band + 1, free.size)``, -1: a held degree of freedom
    or below the diagonal); built once per rod."""

    free: np.ndarray
    band: int
    target: np.ndarray


def _rod_band_layout(n: int, hinges: np.ndarray, fixed_mask: np.ndarray) -> _RodBandLayout:
    free = np.flatnonzero(~np.repeat(fixed_mask, 2)).astype(np.int64)
    local = np.full(2 * max(n, int(hinges.max()) + 1 if hinges.size else 0), -1, np.int64)
    local[free] = np.arange(free.size)
    blocks = [np.stack([np.arange(n - 1), np.arange(1, n)], axis=1), hinges]
    rows, cols = [], []
    for nodes in blocks:
        dofs = (2 * nodes[:, :, None] + np.arange(2)).reshape(nodes.shape[0], -1)
        size = dofs.shape[1]
        rows.append(np.repeat(dofs, size, axis=1).reshape(-1))
        cols.append(np.tile(dofs, (1, size)).reshape(-1))
    r = local[np.concatenate(rows)]
    c = local[np.concatenate(cols)]
    valid = (r >= 0) & (c >= 0)
    band = int(np.abs(r[valid] - c[valid]).max()) if valid.any() else 0
    target = np.full(r.shape[0], -1, np.int64)
    # Upper storage: entry (r, c) with r <= c at [band + r - c, c]; each symmetric element
    # matrix gives its upper triangle once.
    upper = valid & (r <= c)
    target[upper] = (band + r[upper] - c[upper]) * free.size + c[upper]
    return _RodBandLayout(free, band, target)


def _add_nodal_blocks(storage: np.ndarray, layout: _RodBandLayout, blocks: np.ndarray) -> None:
    """Add symmetric 2x2 blocks (n, 2, 2), one per node, to the upper banded ``storage`` of
    the free degrees of freedom (a held component keeps none of its block)."""
    n = blocks.shape[0]
    local = np.full(2 * n, -1, np.int64)
    inside = layout.free < 2 * n
    local[layout.free[inside]] = np.flatnonzero(inside)
    x, y = local[0::2], local[1::2]
    band = layout.band
    for dof, value in ((x, blocks[:, 0, 0]), (y, blocks[:, 1, 1])):
        free = dof >= 0
        storage[band, dof[free]] += value[free]
    both = (x >= 0) & (y >= 0)
    # (x, y) of one node are neighbours in the natural order: one above the diagonal.
    storage[band - 1, y[both]] += blocks[both, 0, 1]


def _state_array(name: str, value: np.ndarray | None, default: np.ndarray) -> np.ndarray:
    if value is None:
        return np.array(default, dtype=np.float64, order="C")
    array = np.array(value, dtype=np.float64, order="C")
    if array.shape != default.shape or not np.all(np.isfinite(array)):
        raise ValueError(f"{name}: must be finite, shape {default.shape}")
    return array


BodyModel = ElasticBody | RodBody
"""A body model the implicit integrators and the monolithic coupling advance: a triangle
body (`ElasticBody`) or a rod (`RodBody`)."""
