"""The model of a 3D elastic body: tetrahedral mesh, material, constraints, lumped masses.

The 3D twin of `ElasticBody`: the same attributes and methods that `ExplicitFem` and the
energy checks read, on a `TetrahedralMesh` with positions and velocities of shape (n, 3) in a
`BodyState`. Units are full 3D ones (forces [N], energies [J], masses [kg]), where the 2D body
counts per metre of depth. It also has what the implicit steps read of a body (`forces_at`
with the energy-momentum strain, `viscous_forces_at`, `response_at`, `determinants_at`): the
step matrix ``M + dt D + s^2 K`` assembled from the tetrahedra's tangent stiffness and damping
matrices (`stiffness_matrix`, `damping_matrix`; kernels in `elastoflow.solid._kernels3d`,
factoring in `elastoflow.solid._implicit3d`), so the 3D implicit integrators of
`elastoflow.solid._implicit3d` advance it as the 2D ones do `ElasticBody`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from scipy import sparse

from elastoflow.solid import _kernels3d
from elastoflow.solid._body import DEFAULT_SAFETY, stable_substep
from elastoflow.solid._material import MaterialStVK
from elastoflow.solid._response import StepResponse
from elastoflow.solid._state import BodyState
from elastoflow.solid._tet_mesh import TetrahedralMesh

if TYPE_CHECKING:
    from elastoflow.solid._implicit3d import StepMatrixLayout3D


class ElasticBody3D:
    """A viscoelastic 3D body's model: tetrahedral mesh, St. Venant-Kirchhoff material with
    Voigt damping, fixed nodes, gravity and lumped masses.

    Static: nothing here changes during a run. The changing part is a `BodyState` (positions
    and velocities (n, 3); `state()` gives the initial one), advanced by `ExplicitFem` or
    by the implicit `NewmarkFem`, `MidpointFem` and `EnergyMomentumFem`.

    The material's Lamé constants are the 3D ones: ``MaterialStVK(plane="strain")`` (its
    default) gives exactly ``lambda = E nu / ((1 + nu)(1 - 2 nu))`` and the 3D P-wave speed;
    a plane-stress material is refused.

    Attributes:
        mesh: Rest mesh.
        material: Material constants.
        mass: Lumped node mass [kg] (``rho V0 / 4`` from each element), shape (n,).
        inverse_mass: ``1 / mass`` [1/kg], shape (n,).
        fixed_mask: Nodes held in place, bool, shape (n,).
        fixed_nodes: Their indices, int64, shape (k,).
        gravity: Gravitational acceleration [m/s^2], shape (3,).
        velocity_damping: Mass-proportional drag rate alpha [1/s] (force ``-alpha m v``).
        dm_inverse: Inverse rest edge matrix ``Dm^-1`` of each element [1/m], shape (m, 3, 3).
        rest_volume: Rest volume of each element [m^3], shape (m,).
        parallel: Whether `ExplicitFem` uses the threaded substep kernel.
    """

    def __init__(
        self,
        mesh: TetrahedralMesh,
        material: MaterialStVK,
        *,
        fixed_nodes: Sequence[int] | np.ndarray = (),
        gravity: tuple[float, float, float] | np.ndarray = (0.0, 0.0, 0.0),
        positions: np.ndarray | None = None,
        velocities: np.ndarray | None = None,
        velocity_damping: float = 0.0,
        parallel: bool | None = None,
    ) -> None:
        """A body whose initial state is its rest shape at rest, unless ``positions`` or
        ``velocities`` are given.

        Args:
            mesh: Rest mesh.
            material: Material constants (3D Lamé constants: ``plane="strain"``).
            fixed_nodes: Node indices whose positions stay put (zero velocity).
            gravity: Acceleration of gravity on the body [m/s^2], three numbers.
            positions: Initial world positions [m], shape (n, 3); default the rest points.
            velocities: Initial velocities [m/s], shape (n, 3); default zero. Zeroed on fixed
                nodes.
            velocity_damping: Drag rate alpha [1/s] applied as ``-alpha m v`` (implicitly, so
                it never limits the substep); for dynamic relaxation to a static state.
            parallel: Use the threaded kernel; default: when the mesh has at least
                ``PARALLEL_ELEMENT_THRESHOLD_3D`` elements. Both agree to round-off.
        """
        if material.plane != "strain":
            raise ValueError(f"material plane = {material.plane!r}: a 3D body needs the 3D "
                             "Lamé constants, plane='strain' (plane stress is a 2D model)")
        self.mesh = mesh
        self.material = material
        n = mesh.point_count
        fixed = np.asarray(fixed_nodes, dtype=np.int64).ravel()
        if fixed.size and (fixed.min() < 0 or fixed.max() >= n):
            bad = fixed[(fixed < 0) | (fixed >= n)][0]
            raise ValueError(f"fixed_nodes contains {bad}: node indices must lie in [0, {n})")
        gravity_array = np.asarray(gravity, dtype=np.float64)
        if gravity_array.shape != (3,) or not np.all(np.isfinite(gravity_array)):
            raise ValueError(f"gravity = {gravity!r}: must be three finite numbers [m/s^2]")
        if not (np.isfinite(velocity_damping) and velocity_damping >= 0.0):
            raise ValueError(f"velocity_damping = {velocity_damping!r}: must be finite and >= 0")
        self.fixed_mask = np.zeros(n, dtype=np.bool_)
        self.fixed_mask[fixed] = True
        self.fixed_nodes = np.flatnonzero(self.fixed_mask)
        self.gravity = gravity_array
        self.velocity_damping = float(velocity_damping)

        initial = BodyState(
            _state_array("positions", positions, mesh.points),
            _state_array("velocities", velocities, np.zeros((n, 3))),
        )
        initial.velocities[self.fixed_mask] = 0.0
        self._initial = initial

        points = mesh.points
        tetrahedra = mesh.tetrahedra
        edges = np.stack([points[tetrahedra[:, k]] - points[tetrahedra[:, 0]] for k in (1, 2, 3)],
                         axis=2)
        self.dm_inverse = np.ascontiguousarray(np.linalg.inv(edges))
        self.rest_volume = np.ascontiguousarray(mesh.tetrahedron_volumes)
        self.mass = np.bincount(tetrahedra.ravel(),
                                weights=np.repeat(material.density * self.rest_volume / 4.0, 4),
                                minlength=n)
        self.inverse_mass = 1.0 / self.mass
        if parallel is None:
            parallel = mesh.tetrahedron_count >= _kernels3d.PARALLEL_ELEMENT_THRESHOLD_3D
        self.parallel = bool(parallel)
        corner_of = np.argsort(tetrahedra.ravel(), kind="stable")
        # Elements and corners around each node, for the threaded kernel's gather.
        self.node_elements = (corner_of // 4).astype(np.int64)
        self.node_corners = (corner_of % 4).astype(np.int64)
        self.node_offsets = np.concatenate(
            [[0], np.cumsum(np.bincount(tetrahedra.ravel(), minlength=n))]
        ).astype(np.int64)
        self._stable_substep = stable_substep(mesh, material)
        # Where the step matrix's element entries go, built at the first response_at.
        self._matrix_layout: StepMatrixLayout3D | None = None

    @property
    def point_count(self) -> int:
        """Number of nodes."""
        return self.mesh.point_count

    @property
    def boundary_triangles(self) -> np.ndarray:
        """Outward boundary triangles of the mesh, shape (k, 3)."""
        return self.mesh.boundary_triangles

    def state(self) -> BodyState:
        """A new copy of the body's initial state."""
        return self._initial.copy()

    def check_state(self, state: BodyState) -> None:
        """Raise ValueError unless ``state`` has this body's shape and finite values."""
        expected = (self.mesh.point_count, 3)
        for name in ("positions", "velocities"):
            value = getattr(state, name)
            if value.shape != expected:
                raise ValueError(f"{name} shape {value.shape}: must be {expected}")
            if not np.all(np.isfinite(value)):
                raise ValueError(f"{name}: values must be finite")

    def stable_substep(self, safety: float = DEFAULT_SAFETY) -> float:
        """Stable substep estimate [s] (see :func:`stable_substep`: the smallest tetrahedron
        altitude over the P-wave speed, times ``safety``, with the damping correction)."""
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
        and ``velocities`` (n, 3) under ``external_forces`` (n, 3) [N] (gravity included);
        the kernel's status convention (`elastoflow.solid._kernels3d`). `ExplicitFem` calls
        this."""
        m = self.material
        _kernels3d.advance_3d(
            (positions, velocities),
            (self.mesh.tetrahedra, self.dm_inverse, self.rest_volume, inverse_mass,
             self.fixed_mask),
            (float(m.lame_lambda), float(m.lame_mu), float(m.damping_lambda),
             float(m.damping_mu), float(self.velocity_damping)),
            external_forces, float(dt), int(substeps),
            (self.node_offsets, self.node_elements, self.node_corners), self.parallel,
            (status, determinant),
        )

    def forces_at(self, positions: np.ndarray, velocities: np.ndarray,
                  rate_strain: float = 0.0) -> np.ndarray:
        """Internal (elastic, Voigt and drag) nodal forces [N] at a given state, (n, 3).

        ``rate_strain`` w > 0 computes the elastic stress from ``E(F) + w Fdot^T Fdot``: at a
        step's midpoint with ``w = dt^2 / 8`` that is the mean strain of the step's ends
        (`EnergyMomentumFem`)."""
        forces = np.empty((self.mesh.point_count, 3))
        determinants = np.empty(self.mesh.tetrahedron_count)
        m = self.material
        _kernels3d.internal_forces_3d(
            np.ascontiguousarray(positions, dtype=np.float64),
            np.ascontiguousarray(velocities, dtype=np.float64), self.mesh.tetrahedra,
            self.dm_inverse, self.rest_volume, m.lame_lambda, m.lame_mu, m.damping_lambda,
            m.damping_mu, float(rate_strain), forces, determinants,
        )
        if self.velocity_damping:
            forces -= self.velocity_damping * self.mass[:, None] * velocities
        return forces

    def viscous_forces_at(self, positions: np.ndarray, velocities: np.ndarray,
                          time_scale: float) -> np.ndarray:
        """Nodal forces [N], (n, 3), of a Voigt damping with constants ``time_scale`` times
        the material's Lame constants (objective: no force for rigid motion)."""
        forces = np.zeros((self.mesh.point_count, 3))
        if time_scale == 0.0:
            return forces
        determinants = np.empty(self.mesh.tetrahedron_count)
        m = self.material
        _kernels3d.internal_forces_3d(
            np.ascontiguousarray(positions, dtype=np.float64),
            np.ascontiguousarray(velocities, dtype=np.float64), self.mesh.tetrahedra,
            self.dm_inverse, self.rest_volume, 0.0, 0.0, time_scale * m.lame_lambda,
            time_scale * m.lame_mu, 0.0, forces, determinants,
        )
        return forces

    def _matrix(self, positions: np.ndarray, material_lambda: float, material_mu: float,
                stress_scale: float, clamp: bool) -> sparse.csr_matrix:
        m = self.material
        count = _kernels3d.MATRIX_TRIPLETS_3D * self.mesh.tetrahedron_count
        rows = np.empty(count, dtype=np.int64)
        cols = np.empty(count, dtype=np.int64)
        values = np.empty(count)
        _kernels3d.step_matrix_triplets_3d(
            np.ascontiguousarray(positions, dtype=np.float64), self.mesh.tetrahedra,
            self.dm_inverse, self.rest_volume, material_lambda, material_mu, m.lame_lambda,
            m.lame_mu, stress_scale, clamp, rows, cols, values,
        )
        size = 3 * self.mesh.point_count
        return sparse.csr_matrix((values, (rows, cols)), shape=(size, size))

    def stiffness_matrix(self, positions: np.ndarray, *,
                         clamp_compression: bool = False) -> sparse.csr_matrix:
        """Tangent stiffness ``K = -d f_elastic / dx`` [N/m] at ``positions`` (n, 3): sparse
        (3n, 3n), symmetric, degree of freedom ``3 node + component``, held nodes included.

        Exact (material plus stress part) by default; ``clamp_compression`` sets the
        stress's negative eigenvalues to 0 in the stress part, which keeps K positive
        semi-definite where compressed elements make the exact one indefinite (the step
        matrix of `response_at` uses that form)."""
        m = self.material
        return self._matrix(positions, m.lame_lambda, m.lame_mu, 1.0, clamp_compression)

    def damping_matrix(self, positions: np.ndarray) -> sparse.csr_matrix:
        """Voigt damping matrix ``D = -d f / dv`` [N s/m] at ``positions`` (n, 3): sparse
        (3n, 3n), symmetric positive semi-definite (the forces are linear in the
        velocities); without the drag ``velocity_damping`` (``alpha M``)."""
        m = self.material
        return self._matrix(positions, m.damping_lambda, m.damping_mu, 0.0, False)

    def response_at(self, positions: np.ndarray, dt: float,
                    stiffness_step: float | None = None,
                    scale: float | None = None,
                    nodal_damping: np.ndarray | None = None) -> StepResponse:
        """The linearised answer ``(M + dt D + s^2 K + dt alpha M) dv = scale f`` at
        ``positions`` (``s = stiffness_step``, default ``dt``; ``scale`` default ``dt``;
        held nodes get 0; K with the compressive stress clamped), with ``dt`` times the
        ``nodal_damping`` blocks (n, 3, 3) added to ``D`` when given:
        `elastoflow.solid._implicit3d.step_response_3d`."""
        from elastoflow.solid._implicit3d import StepMatrixLayout3D, step_response_3d

        if self._matrix_layout is None:
            self._matrix_layout = StepMatrixLayout3D.build(self)
        return step_response_3d(self, positions, float(dt), stiffness_step, scale,
                                self._matrix_layout, nodal_damping)

    def step_response(self, state: BodyState, dt: float) -> StepResponse:
        """The body's linearised backward-Euler answer to a force held over ``dt`` [s]:
        ``step_response(state, dt).velocity_change(f)`` solves ``(M + dt D + dt^2 K + dt
        alpha M) dv = dt f`` at the state's positions (held nodes get 0)."""
        return self.response_at(state.positions, dt)

    def internal_forces(self, state: BodyState) -> np.ndarray:
        """Elastic plus Voigt damping nodal forces [N] in ``state``, shape (n, 3) (without
        the drag ``velocity_damping``)."""
        forces = np.empty((self.mesh.point_count, 3))
        determinants = np.empty(self.mesh.tetrahedron_count)
        m = self.material
        _kernels3d.internal_forces_3d(
            state.positions, state.velocities, self.mesh.tetrahedra, self.dm_inverse,
            self.rest_volume, m.lame_lambda, m.lame_mu, m.damping_lambda, m.damping_mu, 0.0,
            forces, determinants,
        )
        return forces

    def determinants_at(self, positions: np.ndarray) -> np.ndarray:
        """det F of each element at ``positions`` (n, 3), shape (m,)."""
        out = np.empty(self.mesh.tetrahedron_count)
        _kernels3d.element_determinants_3d(np.ascontiguousarray(positions, dtype=np.float64),
                                           self.mesh.tetrahedra, self.dm_inverse, out)
        return out

    def deformation_determinants(self, state: BodyState) -> np.ndarray:
        """det F of each element in ``state``, shape (m,)."""
        return self.determinants_at(state.positions)

    def deformation_gradients(self, state: BodyState) -> np.ndarray:
        """F of each element in ``state``, shape (m, 3, 3)."""
        p = state.positions
        t = self.mesh.tetrahedra
        ds = np.stack([p[t[:, k]] - p[t[:, 0]] for k in (1, 2, 3)], axis=2)
        return ds @ self.dm_inverse

    def second_piola_kirchhoff_stress(self, state: BodyState) -> np.ndarray:
        """Elastic second Piola-Kirchhoff stress ``S(E)`` [Pa] per element, (m, 3, 3)
        (without the Voigt term)."""
        f = self.deformation_gradients(state)
        e = 0.5 * (np.swapaxes(f, 1, 2) @ f - np.eye(3))
        m = self.material
        trace = np.trace(e, axis1=1, axis2=2)
        return m.lame_lambda * trace[:, None, None] * np.eye(3) + 2.0 * m.lame_mu * e

    def elastic_energy(self, state: BodyState) -> float:
        """Strain energy [J] of the state's positions."""
        m = self.material
        return float(_kernels3d.elastic_energy_3d(
            np.ascontiguousarray(state.positions, dtype=np.float64), self.mesh.tetrahedra,
            self.dm_inverse, self.rest_volume, m.lame_lambda, m.lame_mu,
        ))

    def kinetic_energy(self, state: BodyState) -> float:
        """Kinetic energy ``sum m |v|^2 / 2`` [J] with the lumped masses."""
        return float(0.5 * np.sum(self.mass * np.sum(state.velocities**2, axis=1)))

    def gravity_potential_energy(self, state: BodyState) -> float:
        """Potential energy ``-sum m g . x`` [J] in the gravity field (zero at the origin)."""
        return float(-np.sum(self.mass * (state.positions @ self.gravity)))

    def total_energy(self, state: BodyState) -> float:
        """Elastic plus kinetic plus gravity potential energy [J]."""
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
