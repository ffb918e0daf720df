from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from elastoflow.solid import _kernels
from elastoflow.solid._material import MaterialStVK
from elastoflow.solid._mesh import TriangleMesh
from elastoflow.solid._response import StepResponse, step_response

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

    The body keeps the state it had before the failing ``advance`` call; the bad state is in
    ``positions``.

    Attributes:
        step: Outer (fluid) step index passed to ``advance``, or None.
        substep: Number of substeps completed when the bad element was found (0: the state
            given to ``advance`` was already bad).
        element: Index of the first bad element (-1 when only velocities were non-finite).
        determinant: Its det F (nan when non-finite).
        positions: Node positions [m] of the bad state, shape (n, 2).
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
    """What one ``ElasticBody.advance`` call did.

    Attributes:
        substeps: Number of substeps taken.
        substep_dt: Substep size [s].
        stable_substep: The body's stability estimate ``safety h_min / c`` [s] (with the Voigt
            damping correction), for comparison with ``substep_dt``.
        min_determinant: Smallest det F over the elements after the last substep.
    """

    substeps: int
    substep_dt: float
    stable_substep: float
    min_determinant: float


def stable_substep(mesh: TriangleMesh, material: MaterialStVK,
                   safety: float = DEFAULT_SAFETY) -> float:
    """Largest substep [s] that explicit symplectic Euler takes safely on this mesh.

    ``safety * (h / c) * (sqrt(1 + zeta^2) - zeta)`` with ``h`` the smallest element altitude,
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
    """A viscoelastic body: explicit FEM on linear triangles (METHOD §4).

    Model (mesh, material, constraints) is fixed at construction; the state is the world
    ``positions`` and ``velocities``, changed in place by :meth:`advance`.

    Attributes:
        mesh: Rest mesh.
        material: Material constants.
        positions: World node positions [m], float64, shape (n, 2).
        velocities: World node velocities [m/s], float64, shape (n, 2).
        mass: Lumped node mass [kg/m] (``rho A0 / 3`` from each element), shape (n,).
        fixed_mask: Nodes held in place (fixed nodes and the pivot), bool, shape (n,).
        gravity: Gravitational acceleration [m/s^2], shape (2,).
        velocity_damping: Mass-proportional drag rate alpha [1/s] (force ``-alpha m v``).
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
        """Create a body at rest in its rest shape unless ``positions``/``velocities`` are given.

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

        self.positions = self._state_array("positions", positions, mesh.points)
        self.velocities = self._state_array("velocities", velocities, np.zeros((n, 2)))
        self.velocities[self.fixed_mask] = 0.0

        points = mesh.points
        triangles = mesh.triangles
        edges = np.stack(
            [points[triangles[:, 1]] - points[triangles[:, 0]],
             points[triangles[:, 2]] - points[triangles[:, 0]]], axis=2
        )
        self._dm_inverse = np.ascontiguousarray(np.linalg.inv(edges))
        self._rest_area = np.ascontiguousarray(mesh.triangle_areas)
        self.mass = np.zeros(n)
        np.add.at(self.mass, triangles.ravel(), np.repeat(material.density * self._rest_area / 3.0,
                                                          3))
        self._inverse_mass = 1.0 / self.mass
        if parallel is None:
            parallel = mesh.triangle_count >= _kernels.PARALLEL_ELEMENT_THRESHOLD
        self._parallel = bool(parallel)
        corner_of = np.argsort(triangles.ravel(), kind="stable")
        self._node_elements = (corner_of // 3).astype(np.int64)
        self._node_corners = (corner_of % 3).astype(np.int64)
        self._node_offsets = np.concatenate(
            [[0], np.cumsum(np.bincount(triangles.ravel(), minlength=n))]
        ).astype(np.int64)
        self._stable_substep = stable_substep(mesh, material)

    def _state_array(self, name: str, value: np.ndarray | None, default: np.ndarray) -> np.ndarray:
        if value is None:
            return np.array(default, dtype=np.float64, order="C")
        array = np.array(value, dtype=np.float64, order="C")
        if array.shape != default.shape:
            raise ValueError(f"{name} shape {array.shape}: must be {default.shape}")
        if not np.all(np.isfinite(array)):
            raise ValueError(f"{name}: values must be finite")
        return array

    @property
    def boundary_edges(self) -> np.ndarray:
        """Boundary edges of the mesh (body on the left), shape (k, 2)."""
        return self.mesh.boundary_edges

    def stable_substep(self, safety: float = DEFAULT_SAFETY) -> float:
        """Stable substep estimate [s] (see :func:`stable_substep`)."""
        if safety == DEFAULT_SAFETY:
            return self._stable_substep
        return stable_substep(self.mesh, self.material, safety)

    def substeps_for(self, dt: float, safety: float = DEFAULT_SAFETY) -> int:
        """Smallest substep count ``n`` with ``dt / n <= stable_substep(safety)``."""
        return max(1, math.ceil(dt / self.stable_substep(safety) * (1.0 - 1e-12)))

    def advance(
        self,
        dt: float,
        n_sub: int | Literal["auto"] = "auto",
        external_forces: np.ndarray | None = None,
        *,
        step: int | None = None,
        added_mass: np.ndarray | None = None,
    ) -> SolidStepReport:
        """Advance by ``dt`` [s] in ``n_sub`` symplectic Euler substeps.

        Each substep: ``v += dt_s (f_internal + f_external + m g) / (m + m_added)``; fixed
        nodes get ``v = 0``; ``x += dt_s v``. Gravity pulls on the body's own mass ``m`` only.

        Args:
            dt: Outer (fluid) step [s].
            n_sub: Substep count, or ``"auto"`` for the fewest with ``dt / n_sub`` below
                :meth:`stable_substep`.
            external_forces: Nodal forces [N/m], shape (n, 2), held constant over the
                substeps (the fluid's force); default none.
            step: Outer step index, only used to name the step in errors.
            added_mass: Extra nodal inertia ``m_added`` [kg/m], shape (n,), >= 0, for this call
                only (an added-mass estimate of the surrounding fluid, whose matching force
                the caller puts in ``external_forces``); gravity still acts on ``m`` alone.

        Returns:
            What was done.

        Raises:
            SolidInversionError: An element inverted or a value became non-finite; the body
                keeps its state from before this call.
        """
        if not (np.isfinite(dt) and dt > 0.0):
            raise ValueError(f"dt = {dt!r}: must be finite and > 0 [s]")
        if isinstance(n_sub, str):
            if n_sub != "auto":
                raise ValueError(f"n_sub = {n_sub!r}: must be a positive integer or 'auto'")
            substeps = self.substeps_for(dt)
        else:
            substeps = int(n_sub)
            if substeps != n_sub or substeps < 1:
                raise ValueError(f"n_sub = {n_sub!r}: must be a positive integer or 'auto'")
        n = self.mesh.point_count
        if external_forces is None:
            forces = np.zeros((n, 2))
        else:
            forces = np.ascontiguousarray(external_forces, dtype=np.float64)
            if forces.shape != (n, 2):
                raise ValueError(f"external_forces shape {forces.shape}: must be ({n}, 2)")
            if not np.all(np.isfinite(forces)):
                node = int(np.flatnonzero(~np.isfinite(forces).all(axis=1))[0])
                raise ValueError(f"external_forces at node {node} is not finite"
                                 + ("" if step is None else f" (step {step})"))
        # Gravity enters as a nodal force so that it pulls on m alone when m_added > 0.
        forces = forces + self.mass[:, None] * self.gravity
        inverse_mass = self._inverse_mass
        if added_mass is not None:
            extra = np.asarray(added_mass, dtype=np.float64)
            if extra.shape != (n,) or not np.all(np.isfinite(extra)) or np.any(extra < 0.0):
                raise ValueError(f"added_mass: must be finite, >= 0, shape ({n},), got shape "
                                 f"{extra.shape}")
            inverse_mass = 1.0 / (self.mass + extra)
        positions = self.positions.copy()
        velocities = self.velocities.copy()
        status = np.zeros(3, dtype=np.int64)
        determinant = np.zeros(1)
        sub_dt = dt / substeps
        material = self.material
        arguments = (
            positions, velocities, self.mesh.triangles, self._dm_inverse, self._rest_area,
            inverse_mass, self.fixed_mask, forces, material.lame_lambda, material.lame_mu,
            material.damping_lambda, material.damping_mu, self.velocity_damping, sub_dt,
            substeps, status, determinant,
        )
        if self._parallel:
            _kernels.advance_parallel(
                *arguments, self._node_offsets, self._node_elements, self._node_corners
            )
        else:
            _kernels.advance_serial(*arguments)
        where = "" if step is None else f"step {step}, "
        if status[0]:
            raise SolidInversionError(
                f"elastic body failed at {where}substep {int(status[1])} of {substeps} "
                f"(dt_s = {sub_dt:.3g} s, stable estimate {self._stable_substep:.3g} s): "
                f"element {int(status[2])} has det F = {determinant[0]:.3g} (inverted or "
                "non-finite); use more substeps or smaller forces",
                step=step, substep=int(status[1]), element=int(status[2]),
                determinant=float(determinant[0]), positions=positions,
            )
        if not np.all(np.isfinite(velocities)):
            raise SolidInversionError(
                f"elastic body failed at {where}substep {substeps} of {substeps}: velocities "
                "became non-finite; use more substeps or smaller forces",
                step=step, substep=substeps, element=-1, determinant=float("nan"),
                positions=positions,
            )
        self.positions[:] = positions
        self.velocities[:] = velocities
        return SolidStepReport(
            substeps=substeps, substep_dt=sub_dt, stable_substep=self._stable_substep,
            min_determinant=float(self.deformation_determinants().min()),
        )

    def step_response(self, dt: float) -> StepResponse:
        """The body's linearised backward-Euler answer to a force held over ``dt`` [s].

        ``step_response(dt).velocity_change(f)`` solves ``(M + dt D + dt^2 K + dt alpha M) dv
        = dt f`` at the current positions (held nodes get 0): what the strongly coupled
        pressure solve uses as the body's inertia (`elastoflow.solid._response`).
        """
        return self._response_at(self.positions, dt)

    def advance_newmark(
        self, dt: float, external_forces: np.ndarray, response: StepResponse, *,
        step: int | None = None, tolerance: float = 1e-10, max_iterations: int = 12,
        gamma: float = 0.5,
    ) -> SolidStepReport:
        """One implicit step of ``dt`` [s] by Newmark's average-acceleration rule.

        ``x1 = x0 + dt v0 + dt^2/4 (a0 + a1)``, ``v1 = v0 + dt/2 (a0 + a1)``, with
        ``M a = f_internal(x, v) + f_external + M g``, solved by modified Newton iterations on
        the matrix of ``response`` (`step_response` built for ``dt / 2``, i.e.
        ``M + dt/2 D + dt^2/4 K``). Unconditionally stable for the linearised body and second
        order; the strongly coupled scheme uses it because its answer to a force held over
        the step is exactly ``response`` (the same rule), which keeps the coupled step stable
        (docs/method_notes.md, "Strong coupling").

        Args:
            dt: Step [s].
            external_forces: Nodal forces [N/m] held over the step, shape (n, 2).
            response: ``step_response(dt / 2)`` at the current positions.
            step: Outer step index, only used to name the step in errors.
            tolerance: Stop when the Newton update is below ``tolerance`` times the body's
                size.
            max_iterations: Newton iterations at most.

        Raises:
            SolidInversionError: An element inverted or a value became non-finite; the body
                keeps its state from before this call.
        """
        n = self.mesh.point_count
        forces = np.ascontiguousarray(external_forces, dtype=np.float64)
        if forces.shape != (n, 2) or not np.all(np.isfinite(forces)):
            raise ValueError(f"external_forces: must be finite, shape ({n}, 2)")
        mass = self.mass[:, None]
        held = self.fixed_mask
        x0 = self.positions
        v0 = self.velocities
        f_external = forces + mass * self.gravity
        a0 = (self._forces_at(x0, v0) + f_external) / mass
        a0[held] = 0.0
        # The first Newton update solves the linearised step exactly; an explicit guess (a0
        # extrapolated) would start stiff bodies far off.
        x1 = x0 + dt * v0
        x1[held] = x0[held]
        size = float(np.ptp(self.mesh.points, axis=0).max())

        beta = 0.5 * gamma
        drift = x0 + dt * v0 + (0.5 - beta) * dt * dt * a0

        def residual_at(x: np.ndarray) -> tuple[np.ndarray, float]:
            # With beta = gamma / 2 the end velocity is 2 (x1 - x0) / dt - v0 for any gamma.
            v = 2.0 * (x - x0) / dt - v0
            r = beta * dt * dt * (self._forces_at(x, v) + f_external)
            r -= mass * (x - drift)
            r[held] = 0.0
            norm = float(np.linalg.norm(r))
            return r, norm if np.isfinite(norm) else np.inf

        # Newton on Newmark's residual: the matrix of ``response`` (tangent at the start of
        # the step) while it contracts, a fresh tangent at the iterate and a halving line
        # search when it does not (fast rotations leave the start's tangent behind).
        factor = response
        fresh = False
        residual, norm = residual_at(x1)
        iterations = 0
        for iterations in range(1, max_iterations + 1):
            update = factor.solve(residual)
            step_length = 1.0
            for _ in range(8):
                trial = x1 + step_length * update
                trial_residual, trial_norm = residual_at(trial)
                if trial_norm < norm:
                    break
                if not fresh:
                    # Retry the full step with the tangent at the current iterate.
                    factor = self._response_at(x1, gamma * dt, np.sqrt(beta) * dt, 0.5 * dt)
                    fresh = True
                    update = factor.solve(residual)
                    continue
                step_length *= 0.5
            else:
                break
            x1 = trial
            residual, norm = trial_residual, trial_norm
            fresh = False
            if step_length * float(np.abs(update).max()) <= tolerance * size:
                break
        v1 = 2.0 * (x1 - x0) / dt - v0
        v1[held] = 0.0
        determinants = np.empty(self.mesh.triangle_count)
        _kernels.element_determinants(x1, self.mesh.triangles, self._dm_inverse, determinants)
        where = "" if step is None else f"step {step}, "
        if not (np.all(np.isfinite(x1)) and np.all(np.isfinite(v1))
                and determinants.min() > 0.0):
            element = int(np.argmin(np.nan_to_num(determinants, nan=-np.inf)))
            raise SolidInversionError(
                f"elastic body failed at {where}implicit step (dt = {dt:.3g} s): element "
                f"{element} has det F = {determinants[element]:.3g} (inverted or non-finite); "
                "use a smaller dt",
                step=step, substep=0, element=element,
                determinant=float(determinants[element]), positions=x1,
            )
        self.positions[:] = x1
        self.velocities[:] = v1
        return SolidStepReport(
            substeps=iterations, substep_dt=dt, stable_substep=self._stable_substep,
            min_determinant=float(determinants.min()),
        )

    def _response_at(self, positions: np.ndarray, dt: float,
                     stiffness_step: float | None = None,
                     scale: float | None = None) -> StepResponse:
        m = self.material
        return step_response(
            np.ascontiguousarray(positions), self.mesh.triangles, self._dm_inverse,
            self._rest_area, self.mass, self.fixed_mask, m.lame_lambda, m.lame_mu,
            m.damping_lambda, m.damping_mu, self.velocity_damping, float(dt),
            stiffness_step, scale,
        )

    def newmark_response(self, dt: float, gamma: float = 0.5) -> StepResponse:
        """The answer of `advance_newmark` (``gamma``, ``beta = gamma / 2``) to a force held
        over the step, at the current positions: mean velocity ``dt/2 A^-1 f`` with
        ``A = M + gamma dt (D + alpha M) + beta dt^2 K`` (end velocity twice that)."""
        return self._response_at(self.positions, gamma * dt, np.sqrt(0.5 * gamma) * dt,
                                 0.5 * dt)

    def _forces_at(self, positions: np.ndarray, velocities: np.ndarray) -> np.ndarray:
        """Internal (elastic, Voigt and drag) nodal forces [N/m] at a given state."""
        forces = np.empty_like(positions)
        determinants = np.empty(self.mesh.triangle_count)
        m = self.material
        _kernels.internal_forces(
            np.ascontiguousarray(positions), np.ascontiguousarray(velocities),
            self.mesh.triangles, self._dm_inverse, self._rest_area, m.lame_lambda, m.lame_mu,
            m.damping_lambda, m.damping_mu, forces, determinants,
        )
        if self.velocity_damping:
            forces -= self.velocity_damping * self.mass[:, None] * velocities
        return forces

    def substep(self, dt_s: float, external_forces: np.ndarray | None = None) -> SolidStepReport:
        """One substep of size ``dt_s`` [s] (``advance(dt_s, 1, external_forces)``)."""
        return self.advance(dt_s, 1, external_forces)

    def static_equilibrium(self, external_forces: np.ndarray | None = None, *,
                           tolerance: float = 1e-10, max_iterations: int = 100) -> int:
        """Move the body to rest under its elastic forces, gravity and ``external_forces``.

        Newton's method on ``f_internal(x) + f_external + M g = 0`` with the tangent of the
        implicit step (`newmark_response`'s matrix with a step so long that the stiffness
        dominates the mass, which only keeps it regular; compressive stress is left out of it,
        so convergence is linear, about halving the error per iteration), updates halved
        while they would invert an element, and the load applied in increments when a full
        one does not converge.
        Velocities are set to zero.

        Args:
            external_forces: Nodal forces [N/m], shape (n, 2); default none.
            tolerance: Stop when the update is below ``tolerance`` times the body's size.
            max_iterations: Newton iterations at most per load increment.

        Returns:
            Newton iterations taken in all.

        Raises:
            SolidInversionError: No equilibrium found without inverting an element; the body
                keeps its state from before the call.
        """
        n = self.mesh.point_count
        forces = (np.zeros((n, 2)) if external_forces is None
                  else np.ascontiguousarray(external_forces, dtype=np.float64))
        if forces.shape != (n, 2) or not np.all(np.isfinite(forces)):
            raise ValueError(f"external_forces: must be finite, shape ({n}, 2)")
        held = self.fixed_mask
        still = np.zeros((n, 2))
        size = float(np.ptp(self.mesh.points, axis=0).max())
        load = forces + self.mass[:, None] * self.gravity
        # A "step" of s seconds: s^2 K outweighs M by (s omega)^2 in every mode; 1e4 wave
        # crossings exceed the slowest (bending) period of slender bodies by far.
        pseudo_step = 1e4 * size / self.material.dilatational_wave_speed

        def residual_at(x: np.ndarray, fraction: float) -> tuple[np.ndarray, float]:
            r = self._forces_at(x, still) + fraction * load
            r[held] = 0.0
            norm = float(np.linalg.norm(r))
            return r, norm if np.isfinite(norm) else np.inf

        start = self.positions.copy()
        x = start.copy()
        total = 0
        fraction, increment = 0.0, 1.0
        while fraction < 1.0:
            target = min(1.0, fraction + increment)
            trial_x = x.copy()
            residual, norm = residual_at(trial_x, target)
            # Round-off floor of the residual: the forces' own size times machine precision.
            floor = 1e3 * np.finfo(float).eps * (float(np.linalg.norm(load)) + 1e-300)
            converged = False
            determinants = np.empty(self.mesh.triangle_count)
            for _ in range(max_iterations):
                total += 1
                response = self._response_at(trial_x, 0.0, pseudo_step, 1.0)
                update = response.solve(pseudo_step**2 * residual)
                # The residual is a poor merit function for the first, large updates (it
                # jumps before it falls): only an inverted element shortens the step.
                length = 1.0
                for _ in range(30):
                    candidate = trial_x + length * update
                    _kernels.element_determinants(candidate, self.mesh.triangles,
                                                  self._dm_inverse, determinants)
                    if determinants.min() > 0.0:
                        break
                    length *= 0.5
                else:
                    break
                trial_x = candidate
                residual, norm = residual_at(trial_x, target)
                if not np.isfinite(norm):
                    break
                if length * float(np.abs(update).max()) <= tolerance * size or norm <= floor:
                    converged = True
                    break
            determinants = np.empty(self.mesh.triangle_count)
            _kernels.element_determinants(trial_x, self.mesh.triangles, self._dm_inverse,
                                          determinants)
            if converged and determinants.min() > 0.0:
                x, fraction = trial_x, target
                increment = min(2.0 * increment, 1.0)
                continue
            increment *= 0.25
            if increment < 1e-4:
                element = int(np.argmin(determinants))
                self.positions[:] = start
                raise SolidInversionError(
                    f"elastic body: no static equilibrium found at {100 * target:.3g} % of "
                    f"the load (element {element}, det F = {determinants[element]:.3g})",
                    step=None, substep=0, element=element,
                    determinant=float(determinants[element]), positions=trial_x,
                )
        self.positions[:] = x
        self.velocities[:] = 0.0
        return total

    def deformation_determinants(self) -> np.ndarray:
        """det F of each element in the current positions, shape (m,)."""
        out = np.empty(self.mesh.triangle_count)
        _kernels.element_determinants(self.positions, self.mesh.triangles, self._dm_inverse,
                                       out)
        return out

    def deformation_gradients(self) -> np.ndarray:
        """F of each element in the current positions, shape (m, 2, 2)."""
        p = self.positions
        t = self.mesh.triangles
        ds = np.stack([p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]], axis=2)
        return ds @ self._dm_inverse

    def first_piola_kirchhoff_stress(self) -> np.ndarray:
        """Elastic first Piola-Kirchhoff stress ``P = F S(E)`` [Pa] per element, (m, 2, 2).

        Without the Voigt term (use :meth:`internal_forces` for the full force).
        """
        f = self.deformation_gradients()
        e = 0.5 * (np.swapaxes(f, 1, 2) @ f - np.eye(2))
        m = self.material
        trace = e[:, 0, 0] + e[:, 1, 1]
        s = m.lame_lambda * trace[:, None, None] * np.eye(2) + 2.0 * m.lame_mu * e
        return f @ s

    def internal_forces(self) -> np.ndarray:
        """Elastic plus Voigt damping nodal forces [N/m] in the current state, shape (n, 2)."""
        forces = np.empty_like(self.positions)
        determinants = np.empty(self.mesh.triangle_count)
        m = self.material
        _kernels.internal_forces(
            self.positions, self.velocities, self.mesh.triangles, self._dm_inverse,
            self._rest_area, m.lame_lambda, m.lame_mu, m.damping_lambda, m.damping_mu, forces,
            determinants,
        )
        return forces

    def elastic_energy(self) -> float:
        """Strain energy [J/m] of the current positions."""
        m = self.material
        return float(_kernels.elastic_energy(
            self.positions, self.mesh.triangles, self._dm_inverse, self._rest_area,
            m.lame_lambda, m.lame_mu,
        ))

    def kinetic_energy(self) -> float:
        """Kinetic energy ``sum m |v|^2 / 2`` [J/m] with the lumped masses."""
        return float(0.5 * np.sum(self.mass * np.sum(self.velocities**2, axis=1)))

    def gravity_potential_energy(self) -> float:
        """Potential energy ``-sum m g . x`` [J/m] in the gravity field (zero at the origin)."""
        return float(-np.sum(self.mass * (self.positions @ self.gravity)))

    def total_energy(self) -> float:
        """Elastic plus kinetic plus gravity potential energy [J/m]."""
        return self.elastic_energy() + self.kinetic_energy() + self.gravity_potential_energy()
