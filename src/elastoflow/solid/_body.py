from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from elastoflow.solid import _kernels
from elastoflow.solid._material import MaterialStVK
from elastoflow.solid._mesh import TriangleMesh
from elastoflow.solid._response import (
    BandedLayout,
    StepResponse,
    banded_layout,
    step_response,
)
from elastoflow.solid._state import BodyState
from elastoflow.solid._tet_mesh import TetrahedralMesh

DEFAULT_SAFETY = 0.5
"""Fraction of the estimated critical substep that ``n_sub="auto"`` uses.

The estimate ``h_min / c`` (smallest element altitude over the P-wave speed) is exact for 1D
linear elements with lumped mass. On triangle meshes at rest the true critical substep
``2 / omega_max`` (eigenvalues of ``M^-1 K``) measured 0.98-1.36 times the estimate (structured
and Triangle meshes, nu = 0 to 0.45; tests/unit/solid/test_fem.py checks the ratio).
During a run elements compress (smaller altitude) and StVK stiffens under stretch, which raises
omega_max; 0.5 leaves a factor of 2 or more for that. Three times the ``"auto"`` substep
(1.5 h/c) exceeds the critical substep of every mesh measured.
"""


class SolidInversionError(ValueError):
    """An element inverted (det F <= 0) or the state became non-finite during a substep.

    The integrator leaves its input and output states as they were; the bad state is in
    ``positions``.

    Attributes:
        step: Outer (fluid) step index passed to the integrator, or None.
        substep: Number of substeps completed when the bad element was found (0: the state
            given was already bad).
        element: Index of the first bad element (-1 when only velocities were non-finite).
        determinant: Its det F (nan when non-finite).
        positions: Node positions [m] of the bad state, shape (n, 2) or (n, 3).
    """

    def __init__(self, message: str, *, step: int | None, substep: int, element: int,
                 determinant: float, positions: np.ndarray) -> None:
        super().__init__(message)
        self.step = step
        self.substep = substep
        self.element = element
        self.determinant = determinant
        self.positions = positions


@dataclass(frozen=True)
class SolidStepReport:
    """What one integrator step of a body did (`ExplicitFem`, `NewmarkFem`).

    Attributes:
        substeps: Number of substeps taken (Newton iterations for `NewmarkFem`).
        substep_dt: Substep size [s].
        stable_substep: The body's stability estimate ``safety h_min / c`` [s] (with the Voigt
            damping correction), for comparison with ``substep_dt``.
        min_determinant: Smallest det F over the elements after the last substep.
    """

    substeps: int
    substep_dt: float
    stable_substep: float
    min_determinant: float


def stable_substep(mesh: TriangleMesh | TetrahedralMesh, material: MaterialStVK,
                   safety: float = DEFAULT_SAFETY) -> float:
    """Largest substep [s] that explicit symplectic Euler takes safely on this mesh.

    ``safety * (h / c) * (sqrt(1 + zeta^2) - zeta)`` with ``h`` the smallest element altitude
    (triangle or tetrahedron),
    ``c`` the dilatational wave speed and ``zeta = c tau / h`` the damping ratio that Voigt
    damping (relaxation time ``tau``) gives the highest mode, ``omega_max ~ 2 c / h``. The last
    factor is the critical step of a damped oscillator under explicit time stepping relative to
    the undamped one; it goes to ``h / (2 c zeta)`` (a diffusive limit) for strong damping.
    """
    if not (0.0 < safety <= 1.0):
        raise ValueError(f"safety = {safety!r}: must lie in (0, 1]")
    h = mesh.min_element_height
    c = material.dilatational_wave_speed
    zeta = c * material.damping_time / h
    return safety * (h / c) * (math.sqrt(1.0 + zeta * zeta) - zeta)


class ElasticBody:
    """A viscoelastic body's model: mesh, material, constraints and lumped masses (METHOD §4).

    Static: nothing here changes during a run. The changing part is a `BodyState` (positions
    and velocities, `state()` gives the initial one), and what advances it is a FEM time
    integrator (`ExplicitFem`, `NewmarkFem`, `static_equilibrium`). The methods below evaluate
    the body's physics at a given state without changing it.

    Attributes:
        mesh: Rest mesh.
        material: Material constants.
        mass: Lumped node mass [kg/m] (``rho A0 / 3`` from each element), shape (n,).
        inverse_mass: ``1 / mass``, shape (n,).
        fixed_mask: Nodes held in place (fixed nodes and the pivot), bool, shape (n,).
        fixed_nodes: Their indices, shape (k,).
        pivot_node: The pinned node the body turns about, or None.
        gravity: Gravitational acceleration [m/s^2], shape (2,).
        velocity_damping: Mass-proportional drag rate alpha [1/s] (force ``-alpha m v``).
        dm_inverse: Inverse rest edge matrix of each element, shape (m, 2, 2).
        rest_area: Rest area of each element [m^2], shape (m,).
        parallel: Whether the integrators use the threaded element kernels.
    """

    def __init__(
        self,
        mesh: TriangleMesh,
        material: MaterialStVK,
        *,
        fixed_nodes: Sequence[int] | np.ndarray = (),
        pivot_node: int | None = None,
        gravity: tuple[float, float] | np.ndarray = (0.0, 0.0),
        positions: np.ndarray | None = None,
        velocities: np.ndarray | None = None,
        velocity_damping: float = 0.0,
        parallel: bool | None = None,
    ) -> None:
        """A body whose initial state is its rest shape at rest, unless ``positions`` or
        ``velocities`` are given.

        Args:
            mesh: Rest mesh.
            material: Material constants.
            fixed_nodes: Node indices whose positions stay put (zero velocity).
            pivot_node: Node pinned in place; the body turns freely about it (a single pinned
                node lets rigid rotation about it cost no elastic energy).
            gravity: Acceleration of gravity on the body [m/s^2].
            positions: Initial world positions [m], shape (n, 2); default the rest points.
            velocities: Initial velocities [m/s], shape (n, 2); default zero. Zeroed on fixed
                nodes and the pivot.
            velocity_damping: Drag rate alpha [1/s] applied as ``-alpha m v`` (implicitly, so
                it never limits the substep). Default 0: only the material's Voigt damping. A
                tool for reaching static states quickly (dynamic relaxation) or for a body in
                a resisting medium.
            parallel: Use the threaded kernel; default: when the mesh has at least
                ``PARALLEL_ELEMENT_THRESHOLD`` elements. Both give the same result to round-off.
        """
        self.mesh = mesh
        self.material = material
        n = mesh.point_count
        fixed = np.asarray(fixed_nodes, dtype=np.int64).ravel()
        if fixed.size and (fixed.min() < 0 or fixed.max() >= n):
            bad = fixed[(fixed < 0) | (fixed >= n)][0]
            raise ValueError(f"fixed_nodes contains {bad}: node indices must lie in [0, {n})")
        if pivot_node is not None and not (0 <= int(pivot_node) < n):
            raise ValueError(f"pivot_node = {pivot_node!r}: must lie in [0, {n})")
        gravity_array = np.asarray(gravity, dtype=np.float64)
        if gravity_array.shape != (2,) or not np.all(np.isfinite(gravity_array)):
            raise ValueError(f"gravity = {gravity!r}: must be two finite numbers [m/s^2]")
        if not (np.isfinite(velocity_damping) and velocity_damping >= 0.0):
            raise ValueError(f"velocity_damping = {velocity_damping!r}: must be finite and >= 0")
        self.fixed_mask = np.zeros(n, dtype=np.bool_)
        self.fixed_mask[fixed] = True
        self.pivot_node = None if pivot_node is None else int(pivot_node)
        if self.pivot_node is not None:
            self.fixed_mask[self.pivot_node] = True
        self.fixed_nodes = np.flatnonzero(self.fixed_mask)
        self.gravity = gravity_array
        self.velocity_damping = float(velocity_damping)

        initial = BodyState(
            _state_array("positions", positions, mesh.points),
            _state_array("velocities", velocities, np.zeros((n, 2))),
        )
        initial.velocities[self.fixed_mask] = 0.0
        self._initial = initial

        points = mesh.points
        triangles = mesh.triangles
        edges = np.stack(
            [points[triangles[:, 1]] - points[triangles[:, 0]],
             points[triangles[:, 2]] - points[triangles[:, 0]]], axis=2
        )
        self.dm_inverse = np.ascontiguousarray(np.linalg.inv(edges))
        self.rest_area = np.ascontiguousarray(mesh.triangle_areas)
        self.mass = np.zeros(n)
        np.add.at(self.mass, triangles.ravel(), np.repeat(material.density * self.rest_area / 3.0,
                                                          3))
        self.inverse_mass = 1.0 / self.mass
        if parallel is None:
            parallel = mesh.triangle_count >= _kernels.PARALLEL_ELEMENT_THRESHOLD
        self.parallel = bool(parallel)
        corner_of = np.argsort(triangles.ravel(), kind="stable")
        # Elements and corners around each node, for the threaded kernel's gather.
        self.node_elements = (corner_of // 3).astype(np.int64)
        self.node_corners = (corner_of % 3).astype(np.int64)
        self.node_offsets = np.concatenate(
            [[0], np.cumsum(np.bincount(triangles.ravel(), minlength=n))]
        ).astype(np.int64)
        self._stable_substep = stable_substep(mesh, material)
        # The implicit steps' banded layout (mesh and held nodes only), built on first use:
        # explicit runs never need it.
        self._banded_layout: BandedLayout | None = None
        self._banded_layout_built = False

    @property
    def point_count(self) -> int:
        """Number of nodes."""
        return self.mesh.point_count

    @property
    def boundary_edges(self) -> np.ndarray:
        """Boundary edges of the mesh (body on the left), shape (k, 2)."""
        return self.mesh.boundary_edges

    def state(self) -> BodyState:
        """A new copy of the body's initial state."""
        return self._initial.copy()

    def check_state(self, state: BodyState) -> None:
        """Raise ValueError unless ``state`` has this body's shape and finite values."""
        expected = (self.mesh.point_count, 2)
        for name in ("positions", "velocities"):
            value = getattr(state, name)
            if value.shape != expected:
                raise ValueError(f"{name} shape {value.shape}: must be {expected}")
            if not np.all(np.isfinite(value)):
                raise ValueError(f"{name}: values must be finite")

    def stable_substep(self, safety: float = DEFAULT_SAFETY) -> float:
        """Stable substep estimate [s] (see :func:`stable_substep`)."""
        if safety == DEFAULT_SAFETY:
            return self._stable_substep
        return stable_substep(self.mesh, self.material, safety)

    def substeps_for(self, dt: float, safety: float = DEFAULT_SAFETY) -> int:
        """Smallest substep count ``n`` with ``dt / n <= stable_substep(safety)``."""
        return max(1, math.ceil(dt / self.stable_substep(safety) * (1.0 - 1e-12)))

    def explicit_substeps(
        self, positions: np.ndarray, velocities: np.ndarray, inverse_mass: np.ndarray,
        external_forces: np.ndarray, dt: float, substeps: int, status: np.ndarray,
        determinant: np.ndarray,
    ) -> None:
        """Run ``substeps`` symplectic Euler substeps of ``dt`` [s] in place on ``positions``
        and ``velocities`` (n, 2) under ``external_forces`` (n, 2) [N/m] (gravity included);
        the kernel's status convention (`elastoflow.solid._kernels`). `ExplicitFem` calls
        this, so that it advances 2D and 3D bodies alike."""
        m = self.material
        _kernels.advance(
            (positions, velocities),
            (self.mesh.triangles, self.dm_inverse, self.rest_area, inverse_mass,
             self.fixed_mask),
            (float(m.lame_lambda), float(m.lame_mu), float(m.damping_lambda),
             float(m.damping_mu), float(self.velocity_damping)),
            external_forces, dt, substeps,
            (self.node_offsets, self.node_elements, self.node_corners), self.parallel,
            (status, determinant),
        )

    def response_at(self, positions: np.ndarray, dt: float,
                    stiffness_step: float | None = None,
                    scale: float | None = None,
                    nodal_damping: np.ndarray | None = None) -> StepResponse:
        """The linearised answer ``(M + dt D + s^2 K + dt alpha M) dv = scale f`` at
        ``positions`` (``s = stiffness_step``, default ``dt``; ``scale`` default ``dt``;
        held nodes get 0), ``nodal_damping`` blocks (n, 2, 2) added to ``D`` when given:
        `elastoflow.solid._response.step_response`."""
        m = self.material
        if not self._banded_layout_built:
            self._banded_layout = banded_layout(self.mesh.triangles, self.fixed_mask,
                                                self.mesh.points)
            self._banded_layout_built = True
        return step_response(
            np.ascontiguousarray(positions), self.mesh.triangles, self.dm_inverse,
            self.rest_area, self.mass, self.fixed_mask, m.lame_lambda, m.lame_mu,
            m.damping_lambda, m.damping_mu, self.velocity_damping, float(dt),
            stiffness_step, scale, self._banded_layout, nodal_damping,
        )

    def step_response(self, state: BodyState, dt: float) -> StepResponse:
        """The body's linearised backward-Euler answer to a force held over ``dt`` [s].

        ``step_response(state, dt).velocity_change(f)`` solves ``(M + dt D + dt^2 K +
        dt alpha M) dv = dt f`` at the state's positions (held nodes get 0).
        """
        return self.response_at(state.positions, dt)

    def forces_at(self, positions: np.ndarray, velocities: np.ndarray,
                  rate_strain: float = 0.0) -> np.ndarray:
        """Internal (elastic, Voigt and drag) nodal forces [N/m] at a given state.

        ``rate_strain`` w > 0 computes the elastic stress from ``E(F) + w Fdot^T Fdot``: at a
        step's midpoint with ``w = dt^2 / 8`` that is the mean strain of the step's ends
        (`EnergyMomentumFem`)."""
        forces = np.empty_like(positions)
        determinants = np.empty(self.mesh.triangle_count)
        m = self.material
        _kernels.internal_forces(
            np.ascontiguousarray(positions), np.ascontiguousarray(velocities),
            self.mesh.triangles, self.dm_inverse, self.rest_area, m.lame_lambda, m.lame_mu,
            m.damping_lambda, m.damping_mu, float(rate_strain), forces, determinants,
        )
        if self.velocity_damping:
            forces -= self.velocity_damping * self.mass[:, None] * velocities
        return forces

    def viscous_forces_at(self, positions: np.ndarray, velocities: np.ndarray,
                          time_scale: float) -> np.ndarray:
        """Nodal forces [N/m] of a Voigt damping with constants ``time_scale`` times the
        material's Lame constants (objective: no force for rigid motion)."""
        forces = np.empty_like(positions)
        if time_scale == 0.0:
            forces[:] = 0.0
            return forces
        determinants = np.empty(self.mesh.triangle_count)
        m = self.material
        _kernels.internal_forces(
            np.ascontiguousarray(positions), np.ascontiguousarray(velocities),
            self.mesh.triangles, self.dm_inverse, self.rest_area, 0.0, 0.0,
            time_scale * m.lame_lambda, time_scale * m.lame_mu, 0.0, forces, determinants,
        )
        return forces

    def determinants_at(self, positions: np.ndarray) -> np.ndarray:
        """det F of each element at ``positions``, shape (m,)."""
        out = np.empty(self.mesh.triangle_count)
        _kernels.element_determinants(np.ascontiguousarray(positions), self.mesh.triangles,
                                       self.dm_inverse, out)
        return out

    def deformation_determinants(self, state: BodyState) -> np.ndarray:
        """det F of each element in ``state``, shape (m,)."""
        return self.determinants_at(state.positions)

    def deformation_gradients(self, state: BodyState) -> np.ndarray:
        """F of each element in ``state``, shape (m, 2, 2)."""
        p = state.positions
        t = self.mesh.triangles
        ds = np.stack([p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]], axis=2)
        return ds @ self.dm_inverse

    def first_piola_kirchhoff_stress(self, state: BodyState) -> np.ndarray:
        """Elastic first Piola-Kirchhoff stress ``P = F S(E)`` [Pa] per element, (m, 2, 2).

        Without the Voigt term (use :meth:`internal_forces` for the full force).
        """
        f = self.deformation_gradients(state)
        e = 0.5 * (np.swapaxes(f, 1, 2) @ f - np.eye(2))
        m = self.material
        trace = e[:, 0, 0] + e[:, 1, 1]
        s = m.lame_lambda * trace[:, None, None] * np.eye(2) + 2.0 * m.lame_mu * e
        return f @ s

    def internal_forces(self, state: BodyState) -> np.ndarray:
        """Elastic plus Voigt damping nodal forces [N/m] in ``state``, shape (n, 2) (without
        the drag ``velocity_damping``)."""
        forces = np.empty_like(state.positions)
        determinants = np.empty(self.mesh.triangle_count)
        m = self.material
        _kernels.internal_forces(
            state.positions, state.velocities, self.mesh.triangles, self.dm_inverse,
            self.rest_area, m.lame_lambda, m.lame_mu, m.damping_lambda, m.damping_mu, 0.0,
            forces, determinants,
        )
        return forces

    def elastic_energy(self, state: BodyState) -> float:
        """Strain energy [J/m] of the state's positions."""
        m = self.material
        return float(_kernels.elastic_energy(
            state.positions, self.mesh.triangles, self.dm_inverse, self.rest_area,
            m.lame_lambda, m.lame_mu,
        ))

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


def _state_array(name: str, value: np.ndarray | None, default: np.ndarray) -> np.ndarray:
    if value is None:
        return np.array(default, dtype=np.float64, order="C")
    array = np.array(value, dtype=np.float64, order="C")
    if array.shape != default.shape:
        raise ValueError(f"{name} shape {array.shape}: must be {default.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name}: values must be finite")
    return array
