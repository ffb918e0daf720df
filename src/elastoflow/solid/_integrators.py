"""What advances an elastic body's state: the FEM time integrators and the static solve.

Each reads a `BodyState`, writes the result into another (or the same) one, and leaves both
untouched when it fails. The body (`ElasticBody`, `ElasticBody3D`, or for the implicit steps
also a rod, `RodBody`) is the static model they read; one class per rule serves every body,
which brings what differs by dimension: its forces, its step matrix and factor
(``response_at``: `elastoflow.solid._response` in 2D, `elastoflow.solid._implicit3d` in 3D)
and the shape (n, 2) or (n, 3) of its arrays.

* `ExplicitFem`: symplectic Euler substeps under a force held over the step (METHOD §4, the
  paper's scheme; the explicit coupling uses it).
* `MidpointFem`, `NewmarkFem`: one implicit step by Newton's method (the monolithic coupling
  uses them, because their answer to a held force is exactly the response the coupled
  pressure solve sees: docs/method_notes.md, "Strong coupling"); the midpoint rule keeps the
  angular momentum, Newmark's damps the unresolved modes.
* `static_equilibrium`: the rest state under given loads (Turek–Hron CSM1/2, the 3D
  cantilever's static deflection).
"""

from __future__ import annotations

import weakref
from collections.abc import Callable
from typing import Literal

import numpy as np

from elastoflow.solid._body import (
    DEFAULT_SAFETY,
    ElasticBody,
    SolidInversionError,
    SolidStepReport,
)
from elastoflow.solid._body3d import ElasticBody3D
from elastoflow.solid._contact import HeldResponse, WallBox, hold_response, project_onto_box
from elastoflow.solid._response import StepResponse
from elastoflow.solid._rod import BodyModel
from elastoflow.solid._state import BodyState

Substeps = int | Literal["auto"]

# What the implicit rules advance: 2D bodies (`ElasticBody`, `RodBody`) and 3D ones.
ImplicitBody = BodyModel | ElasticBody3D


class ExplicitFem:
    """Symplectic Euler substeps: ``v += dt_s (f_internal + f_external + m g) / (m +
    m_added)``; fixed nodes get ``v = 0``; ``x += dt_s v``. Gravity pulls on the body's own
    mass ``m`` only. Advances 2D (`ElasticBody`) and 3D (`ElasticBody3D`) bodies: the body
    runs its own substep kernel (``explicit_substeps``), the rest is shared.

    Args:
        substeps: Substeps per step, or ``"auto"`` for the fewest with ``dt / n`` below the
            body's stable substep (``safety`` times its estimate).
        safety: Fraction of the estimated critical substep that ``"auto"`` uses.
    """

    def __init__(self, substeps: Substeps = "auto", safety: float = DEFAULT_SAFETY) -> None:
        if isinstance(substeps, str):
            if substeps != "auto":
                raise ValueError(f"n_sub = {substeps!r}: must be a positive integer or 'auto'")
        elif int(substeps) != substeps or substeps < 1:
            raise ValueError(f"n_sub = {substeps!r}: must be a positive integer or 'auto'")
        self.substeps: Substeps = substeps if isinstance(substeps, str) else int(substeps)
        self.safety = float(safety)

    def substeps_for(self, body: ElasticBody | ElasticBody3D, dt: float) -> int:
        """The substep count this integrator takes for ``body`` over ``dt``."""
        if isinstance(self.substeps, str):
            return body.substeps_for(dt, self.safety)
        return self.substeps

    def advance(
        self,
        body: ElasticBody | ElasticBody3D,
        state_in: BodyState,
        state_out: BodyState,
        dt: float,
        external_forces: np.ndarray | None = None,
        *,
        step: int | None = None,
        added_mass: np.ndarray | None = None,
        walls: WallBox | None = None,
        friction: float = 0.0,
    ) -> SolidStepReport:
        """Advance ``state_in`` by ``dt`` [s] into ``state_out`` (may be ``state_in``).

        Args:
            body: The body's model.
            state_in: State at the start of the step.
            state_out: Receives the state at the end.
            dt: Outer (fluid) step [s].
            external_forces: Nodal forces [N/m], shape (n, 2) (3D: [N], (n, 3)), held
                constant over the substeps (the fluid's force); default none.
            step: Outer step index, only used to name the step in errors.
            added_mass: Extra nodal inertia ``m_added`` [kg/m], shape (n,), >= 0, for this call
                only (an added-mass estimate of the surrounding fluid, whose matching force
                the caller puts in ``external_forces``); gravity still acts on ``m`` alone.
            walls: Contact with these walls (2D bodies): after every substep the nodes
                beyond a wall are put back onto it, inelastically, with Coulomb
                ``friction`` (`elastoflow.solid.project_onto_box`). Substeps are then run
                one kernel call each, while the body can reach a wall within the step.
            friction: Coulomb coefficient of that contact.

        Raises:
            SolidInversionError: An element inverted or a value became non-finite; both
                states keep their values.
        """
        if not (np.isfinite(dt) and dt > 0.0):
            raise ValueError(f"dt = {dt!r}: must be finite and > 0 [s]")
        substeps = self.substeps_for(body, dt)
        n = body.point_count
        dimension = body.gravity.shape[0]
        if external_forces is None:
            forces = np.zeros((n, dimension))
        else:
            forces = np.ascontiguousarray(external_forces, dtype=np.float64)
            if forces.shape != (n, dimension):
                raise ValueError(f"external_forces shape {forces.shape}: must be ({n}, "
                                 f"{dimension})")
            if not np.all(np.isfinite(forces)):
                node = int(np.flatnonzero(~np.isfinite(forces).all(axis=1))[0])
                raise ValueError(f"external_forces at node {node} is not finite"
                                 + ("" if step is None else f" (step {step})"))
        # Gravity enters as a nodal force so that it pulls on m alone when m_added > 0.
        forces = forces + body.mass[:, None] * body.gravity
        inverse_mass = body.inverse_mass
        if added_mass is not None:
            extra = np.asarray(added_mass, dtype=np.float64)
            if extra.shape != (n,) or not np.all(np.isfinite(extra)) or np.any(extra < 0.0):
                raise ValueError(f"added_mass: must be finite, >= 0, shape ({n},), got shape "
                                 f"{extra.shape}")
            inverse_mass = 1.0 / (body.mass + extra)
        positions = state_in.positions.copy()
        velocities = state_in.velocities.copy()
        status = np.zeros(3, dtype=np.int64)
        determinant = np.zeros(1)
        sub_dt = dt / substeps
        reach = 0.0
        if walls is not None:
            # How far a node can go in the step under its own speed and the held forces.
            acceleration = float(np.abs(forces * inverse_mass[:, None]).max(initial=0.0))
            reach = dt * float(np.abs(velocities).max(initial=0.0)) + dt * dt * acceleration
        # Internal (elastic) forces are not in ``reach``: a margin of 1 % of the box more.
        if walls is None or not walls.near(positions, 2.0 * reach + 1e-2 * walls.size):
            body.explicit_substeps(positions, velocities, inverse_mass, forces, sub_dt,
                                   substeps, status, determinant)
        else:
            for substep in range(substeps):
                body.explicit_substeps(positions, velocities, inverse_mass, forces, sub_dt, 1,
                                       status, determinant)
                if status[0]:
                    status[1] += substep
                    break
                project_onto_box(walls, positions, velocities, body.fixed_mask, friction, 0.0)
        where = "" if step is None else f"step {step}, "
        stable = body.stable_substep()
        if status[0]:
            raise SolidInversionError(
                f"elastic body failed at {where}substep {int(status[1])} of {substeps} "
                f"(dt_s = {sub_dt:.3g} s, stable estimate {stable:.3g} s): "
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
        state_out.positions[...] = positions
        state_out.velocities[...] = velocities
        return SolidStepReport(
            substeps=substeps, substep_dt=sub_dt, stable_substep=stable,
            min_determinant=float(body.determinants_at(positions).min()),
        )


class NewmarkFem:
    """One implicit step by Newmark's rule with ``beta = gamma / 2``.

    ``x1 = x0 + dt v0 + dt^2 ((1/2 - beta) a0 + beta a1)``, ``v1 = v0 + dt ((1 - gamma) a0 +
    gamma a1)``, with ``M a = f_internal(x, v) + f_external + M g``, solved by modified Newton
    iterations on the matrix of `response`. With ``gamma = 1/2`` (average acceleration) it is
    second order and conserves the energy of every linear mode; larger ``gamma`` damps the
    modes the step does not resolve. Unconditionally stable for the linearised body; its answer
    to a force held over the step is exactly `response`, which keeps the strongly coupled step
    stable (docs/method_notes.md, "Strong coupling").

    For 2D (`ElasticBody`, `RodBody`) and 3D (`ElasticBody3D`) bodies alike: the body brings
    its forces and its step matrix (``response_at``), the rule and its Newton iteration
    (`_implicit_step`) are shared.

    Args:
        gamma: Newmark's gamma in [0.5, 1].
        tolerance: Stop when the Newton update is below ``tolerance`` times the body's size.
        max_iterations: Newton iterations at most.
        reuse_strain: 0 (default): `response` builds and factors the step matrix at the
            state's positions every call. > 0: a 3D body's last response is reused while no
            element's deformation gradient has moved by more than this since it was built
            (`_FactorCache`; the factorization is most of a large 3D body's step; 2D bodies
            build every call).
    """

    def __init__(self, gamma: float = 0.5, tolerance: float = 1e-10,
                 max_iterations: int = 12, *, reuse_strain: float = 0.0) -> None:
        if not 0.5 <= gamma <= 1.0:
            raise ValueError(f"gamma = {gamma!r}: must lie in [0.5, 1]")
        self.gamma = float(gamma)
        self.tolerance = float(tolerance)
        self.max_iterations = int(max_iterations)
        self.factors = _FactorCache(reuse_strain)

    def response(self, body: ImplicitBody, state: BodyState, dt: float,
                 nodal_damping: np.ndarray | None = None) -> StepResponse:
        """The answer of `advance` to a force held over the step, at the state's positions:
        mean velocity ``dt/2 A^-1 f`` with ``A = M + gamma dt (D + C + alpha M) + beta dt^2 K``
        (end velocity twice that; ``C`` the ``nodal_damping`` blocks)."""
        gamma = self.gamma
        return self.factors.response(
            body, state, dt, lambda positions: body.response_at(
                positions, gamma * dt, np.sqrt(0.5 * gamma) * dt, 0.5 * dt,
                nodal_damping=nodal_damping), nodal_damping)

    def advance(
        self, body: ImplicitBody, state_in: BodyState, state_out: BodyState, dt: float,
        external_forces: np.ndarray, response: StepResponse | HeldResponse, *,
        step: int | None = None,
        nodal_damping: np.ndarray | None = None, hold: np.ndarray | None = None,
    ) -> SolidStepReport:
        """Advance ``state_in`` by ``dt`` [s] into ``state_out`` (may be ``state_in``).

        Args:
            body: The body's model.
            state_in: State at the start of the step.
            state_out: Receives the state at the end.
            dt: Step [s].
            external_forces: Nodal forces held over the step, [N/m] shape (n, 2) (3D: [N],
                (n, 3)).
            response: ``response(body, state_in, dt)``.
            step: Outer step index, only used to name the step in errors.
            nodal_damping: Nodal blocks ``C`` (n, d, d), symmetric positive
                semi-definite: the force ``-C (v - v0)`` taken implicitly, the
                linearisation of a force held over the step in the body's velocity (the
                fluid's viscous traction: `MonolithicCoupling`, `MonolithicCoupling3D`). It
                vanishes when the velocity does not change.
            hold: (n, d) bool: node components held at their start position over the step
                (a wall contact's hold, `elastoflow.solid.WallHold`); ``response`` must then
                be the held one (`elastoflow.solid.hold_response`).

        Raises:
            SolidInversionError: An element inverted or a value became non-finite; both
                states keep their values.
        """
        forces = _checked_forces(body, external_forces)
        gamma = self.gamma
        mass = body.mass[:, None]
        held = body.fixed_mask
        x0 = state_in.positions
        v0 = state_in.velocities
        f_external = forces + mass * body.gravity
        a0 = (body.forces_at(x0, v0) + f_external) / mass
        a0[held] = 0.0
        if hold is not None:
            a0[hold] = 0.0
        beta = 0.5 * gamma
        drift = x0 + dt * v0 + (0.5 - beta) * dt * dt * a0

        def residual_at(x: np.ndarray) -> np.ndarray:
            # With beta = gamma / 2 the end velocity is 2 (x1 - x0) / dt - v0 for any gamma.
            v = 2.0 * (x - x0) / dt - v0
            forces = body.forces_at(x, v) + f_external
            if nodal_damping is not None:
                forces -= np.einsum("nab,nb->na", nodal_damping, v - v0)
            return beta * dt * dt * forces - mass * (x - drift)

        def tangent_at(x: np.ndarray) -> StepResponse:
            return body.response_at(x, gamma * dt, np.sqrt(beta) * dt, 0.5 * dt,
                                    nodal_damping=nodal_damping)

        return _implicit_step(body, state_in, state_out, dt, residual_at, response, tangent_at,
                              self.tolerance, self.max_iterations, step, hold)


class MidpointFem:
    """One step of the implicit midpoint rule.

    ``v1 = v0 + dt M^-1 (f_internal(x_m, v_m) + f_external + M g)`` and ``x1 = x0 + dt (v0 +
    v1) / 2``, with the internal forces at the midpoint ``x_m = (x0 + x1) / 2``, ``v_m = (x1 -
    x0) / dt``. Second order, unconditionally stable for the linearised body, and it keeps the
    linear and the angular momentum of a free body exactly (the internal forces of a
    frame-indifferent material have no net force and no torque at ``x_m``, and the rule makes
    the momenta change by exactly those) and the energy of linear vibrations. Newmark's rule
    with forces at the ends (`NewmarkFem`) keeps the angular momentum only to ``O(dt^2)`` of
    the vibration's forces: coupled to a fluid, whose pressure keeps exciting a body's stiff
    modes, that error spun discs up exponentially (docs/method_notes.md item 8).

    Its answer to a force held over the step is `response`: mean velocity ``dt/2 A^-1 f``
    with ``A = M + dt/2 (D + alpha M) + dt^2/4 K`` (end velocity twice that), the matrix of
    Newmark's average-acceleration rule, so the strongly coupled solve is the same SPD system.

    For 2D and 3D bodies alike, as `NewmarkFem`.

    Args:
        tolerance: Stop when the Newton update is below ``tolerance`` times the body's size.
        max_iterations: Newton iterations at most.
        reuse_strain: Reuse of a 3D body's factor, as `NewmarkFem`.
    """

    gamma = 0.5
    # Weight of Fdot^T Fdot in the strain of the elastic stress, in units of dt^2 (0: the
    # midpoint's own strain).
    _rate_strain = 0.0

    def __init__(self, tolerance: float = 1e-10, max_iterations: int = 12, *,
                 reuse_strain: float = 0.0) -> None:
        self.tolerance = float(tolerance)
        self.max_iterations = int(max_iterations)
        self.factors = _FactorCache(reuse_strain)

    def response(self, body: ImplicitBody, state: BodyState, dt: float,
                 nodal_damping: np.ndarray | None = None) -> StepResponse:
        """The answer of `advance` to a force held over the step, at the state's positions:
        mean velocity ``dt/2 A^-1 f`` (end velocity twice that); ``nodal_damping`` as in
        `NewmarkFem.response`."""
        return self.factors.response(
            body, state, dt,
            lambda positions: self._response_at(body, positions, dt, nodal_damping),
            nodal_damping)

    def _response_at(self, body: ImplicitBody, positions: np.ndarray, dt: float,
                     nodal_damping: np.ndarray | None = None) -> StepResponse:
        """`response`'s matrix at ``positions``, built and factored (no reuse)."""
        return body.response_at(positions, 0.5 * dt, 0.5 * dt, 0.5 * dt,
                                nodal_damping=nodal_damping)

    def _extra_forces(self, body: ImplicitBody, middle: np.ndarray, rate: np.ndarray,
                      dt: float) -> np.ndarray:
        return np.zeros_like(middle)

    def advance(
        self, body: ImplicitBody, state_in: BodyState, state_out: BodyState, dt: float,
        external_forces: np.ndarray, response: StepResponse | HeldResponse, *,
        step: int | None = None,
        nodal_damping: np.ndarray | None = None, hold: np.ndarray | None = None,
    ) -> SolidStepReport:
        """Advance ``state_in`` by ``dt`` [s] into ``state_out`` (may be ``state_in``); as
        `NewmarkFem.advance` (``nodal_damping``'s force at the midpoint velocity; ``hold``
        the components held over the step)."""
        forces = _checked_forces(body, external_forces)
        mass = body.mass[:, None]
        x0 = state_in.positions
        v0 = state_in.velocities
        f_external = forces + mass * body.gravity

        rate_strain = self._rate_strain * dt * dt

        def residual_at(x: np.ndarray) -> np.ndarray:
            middle = 0.5 * (x0 + x)
            internal = body.forces_at(middle, (x - x0) / dt, rate_strain)
            internal += self._extra_forces(body, middle, (x - x0) / dt, dt)
            if nodal_damping is not None:
                internal -= np.einsum("nab,nb->na", nodal_damping, (x - x0) / dt - v0)
            return 0.5 * dt * dt * (internal + f_external) - mass * (x - x0 - dt * v0)

        def tangent_at(x: np.ndarray) -> StepResponse:
            return self._response_at(body, 0.5 * (x0 + x), dt, nodal_damping)

        return _implicit_step(body, state_in, state_out, dt, residual_at, response, tangent_at,
                              self.tolerance, self.max_iterations, step, hold)


class EnergyMomentumFem(MidpointFem):
    """The implicit midpoint rule with Simo & Tarnow's (1992) energy-momentum stress.

    As `MidpointFem`, with the elastic stress at the midpoint taken from the mean of the
    step's end strains, ``S((E(F0) + E(F1)) / 2)``, instead of the midpoint's strain. For
    St. Venant–Kirchhoff (energy quadratic in E) the step's elastic work is then exactly the
    change of the strain energy, so a free body keeps its energy to the Newton tolerance also
    in large rotations, where the plain midpoint rule can gain energy without bound (its
    stress at the midpoint is not the mean of the ends); momentum and angular momentum are
    kept as by the midpoint rule. The Voigt damping, evaluated at the midpoint with
    ``Fdot = (F1 - F0) / dt``, has the strain rate ``(E(F1) - E(F0)) / dt`` exactly and so
    only removes energy.

    Args:
        damping: Numerical damping c: a Voigt damping with the material's Lame constants
            times ``c dt``, added to the material's own. Objective (no force for rigid
            motion, so both momenta stay exact) and first order in dt, it damps a linear
            mode as Newmark's rule with ``gamma = 1/2 + c`` does (the same spectral radius):
            modes the step does not resolve (``omega dt`` from about 1 to 30: per step 0.96
            at 1, 0.82 at 10 for c = 0.1), resolved ones at a damping ratio ``c omega dt /
            2``. Neither rule damps ``omega dt -> infinity``. Its answer to a held force is
            `response`, with the damping's share in the matrix.
        tolerance: Stop when the Newton update is below ``tolerance`` times the body's size.
        max_iterations: Newton iterations at most.
        reuse_strain: Reuse of a 3D body's factor, as `NewmarkFem`.
    """

    _rate_strain = 0.125

    def __init__(self, damping: float = 0.0, tolerance: float = 1e-10,
                 max_iterations: int = 12, *, reuse_strain: float = 0.0) -> None:
        super().__init__(tolerance, max_iterations, reuse_strain=reuse_strain)
        if not (0.0 <= damping < np.inf):
            raise ValueError(f"damping = {damping!r}: must be a finite number >= 0")
        self.damping = float(damping)

    def _response_at(self, body: ImplicitBody, positions: np.ndarray, dt: float,
                     nodal_damping: np.ndarray | None = None) -> StepResponse:
        # The numerical Voigt damping c dt (lambda, mu) adds c dt^2 / 2 to the stiffness's
        # dt^2 / 4 in the step's matrix.
        stiffness = dt * np.sqrt(0.25 + 0.5 * self.damping)
        return body.response_at(positions, 0.5 * dt, stiffness, 0.5 * dt,
                                nodal_damping=nodal_damping)

    def _extra_forces(self, body: ImplicitBody, middle: np.ndarray, rate: np.ndarray,
                      dt: float) -> np.ndarray:
        return body.viscous_forces_at(middle, rate, self.damping * dt)


def _checked_forces(body: ImplicitBody, external_forces: np.ndarray) -> np.ndarray:
    n = body.point_count
    dimension = body.gravity.shape[0]
    forces = np.ascontiguousarray(external_forces, dtype=np.float64)
    if forces.shape != (n, dimension) or not np.all(np.isfinite(forces)):
        raise ValueError(f"external_forces: must be finite, shape ({n}, {dimension})")
    return forces


class _FactorCache:
    """The last response a rule built for each 3D body, handed out again while no element's
    deformation gradient has changed by more than ``reuse_strain`` since (and the step is the
    same): the step matrix of slightly earlier positions. Newton still solves the step's
    equations to its tolerance (with a fresh tangent when the old one contracts slowly);
    what changes is the coupled pressure solve's answer of the body, linearised at those
    earlier positions instead of the step's start (still symmetric positive definite, and
    the same matrix in the predictor and the pressure solve). 2D bodies build every call."""

    def __init__(self, reuse_strain: float) -> None:
        if not (np.isfinite(reuse_strain) and reuse_strain >= 0.0):
            raise ValueError(f"reuse_strain = {reuse_strain!r}: must be finite and >= 0")
        self.reuse_strain = float(reuse_strain)
        self.built = 0
        self._held: weakref.WeakKeyDictionary[ElasticBody3D, tuple[float, np.ndarray,
                                                                   StepResponse]] = (
            weakref.WeakKeyDictionary())

    def response(self, body: ImplicitBody, state: BodyState, dt: float,
                 build: Callable[[np.ndarray], StepResponse],
                 nodal_damping: np.ndarray | None = None) -> StepResponse:
        """``build(state.positions)``, or the response held for ``body`` (see the class;
        never with ``nodal_damping``, which changes with the body's surface)."""
        if (self.reuse_strain > 0.0 and isinstance(body, ElasticBody3D)
                and nodal_damping is None):
            held = self._held.get(body)
            if (held is not None and held[0] == dt
                    and _largest_strain_change(body, held[1], state.positions)
                    <= self.reuse_strain):
                return held[2]
            self.built += 1
            response = build(state.positions)
            self._held[body] = (dt, state.positions.copy(), response)
            return response
        self.built += 1
        return build(state.positions)


def _largest_strain_change(body: ElasticBody3D, reference: np.ndarray,
                           positions: np.ndarray) -> float:
    """``max |F(positions) - F(reference)|`` over the elements and entries."""
    change = positions - reference
    t = body.mesh.tetrahedra
    edges = np.stack([change[t[:, k]] - change[t[:, 0]] for k in (1, 2, 3)], axis=2)
    return float(np.abs(edges @ body.dm_inverse).max())


# Newton on a 3D body keeps a factor while each update shrinks the residual at least this
# much; slower contraction gets a fresh tangent at the new iterate. A block spinning 0.09 rad
# a step and vibrating (strains ~1 %), 10 x the explicit substep, 12 iterations at most, 60
# steps: the start's tangent, rotated against the midpoint, contracts by ~0.2 an iteration;
# angular momentum kept to 1e-5 (no such refresh), 6e-6 (0.5), 4e-8 (0.25), 4e-11 (0.1) by
# the midpoint rule, 5e-5 / 8e-6 / 4e-9 / 2e-11 by energy-momentum (at 20 x: without the
# refresh an element inverts at step 27, 0.25 keeps 3e-8). A refactor costs ~30-50 Newton
# iterations of a 5000-tetrahedron body.
_REFRESH_CONTRACTION_3D = 0.25


def _refresh_contraction(body: ImplicitBody) -> float:
    """The contraction above which `_implicit_step` refactors at the iterate. 2D bodies: 1,
    never (an accepted update always contracts by less), so only a residual that fails to
    shrink gets a fresh tangent: the 2D steps stay bit for bit those measured and validated
    before 3D bodies shared this iteration. No threshold below 1 would leave them so:
    tests/unit/solid, tests/unit/simulation and test_coupling_schemes.py take 15735 accepted
    updates, 1730 of them contracting by more than 0.25 (up to 0.998), Turek-Hron FSI3 at
    resolution 5 over 1 s 87 of 851 (up to 0.93)."""
    return _REFRESH_CONTRACTION_3D if isinstance(body, ElasticBody3D) else 1.0


def _implicit_step(
    body: ImplicitBody, state_in: BodyState, state_out: BodyState, dt: float,
    residual: Callable[[np.ndarray], np.ndarray], response: StepResponse | HeldResponse,
    tangent_at: Callable[[np.ndarray], StepResponse | HeldResponse], tolerance: float, max_iterations: int,
    step: int | None, hold: np.ndarray | None = None,
) -> SolidStepReport:
    """Newton on an implicit rule's residual in the end positions (end velocity ``2 (x1 - x0)
    / dt - v0``): the matrix of ``response`` (tangent at the start of the step) while it
    contracts, a fresh tangent at the iterate and a halving line search when it does not
    (fast rotations leave the start's tangent behind); also a fresh tangent after an update
    that leaves more than `_refresh_contraction` of the residual (3D bodies), unless it was
    the last iteration allowed. ``hold`` (n, d) bool: components kept at their start
    position (a wall contact's), taken like fixed nodes; ``response`` must be held on them
    too (`elastoflow.solid.hold_response`), and the fresh tangents are."""
    refresh_above = _refresh_contraction(body)
    held = body.fixed_mask
    x0 = state_in.positions
    v0 = state_in.velocities
    if hold is not None and not hold.any():
        hold = None
    if hold is not None:
        fresh_tangent = tangent_at

        def tangent_at(x: np.ndarray) -> StepResponse | HeldResponse:
            response = fresh_tangent(x)
            assert isinstance(response, StepResponse)
            return hold_response(response, hold)

    def residual_at(x: np.ndarray) -> tuple[np.ndarray, float]:
        r = residual(x)
        r[held] = 0.0
        if hold is not None:
            r[hold] = 0.0
        norm = float(np.linalg.norm(r))
        return r, norm if np.isfinite(norm) else np.inf

    # The first Newton update solves the linearised step exactly; an explicit guess (the
    # acceleration extrapolated) would start stiff bodies far off.
    x1 = x0 + dt * v0
    x1[held] = x0[held]
    if hold is not None:
        x1[hold] = x0[hold]
    size = float(np.ptp(body.mesh.points, axis=0).max())
    factor = response
    fresh = False
    current, norm = residual_at(x1)
    iterations = 0
    for iterations in range(1, max_iterations + 1):
        update = factor.solve(current)
        step_length = 1.0
        for _ in range(8):
            trial = x1 + step_length * update
            trial_residual, trial_norm = residual_at(trial)
            if trial_norm < norm:
                break
            if not fresh:
                # Retry the full step with the tangent at the current iterate.
                factor = tangent_at(x1)
                fresh = True
                update = factor.solve(current)
                continue
            step_length *= 0.5
        else:
            break
        contraction = trial_norm / norm
        x1 = trial
        current, norm = trial_residual, trial_norm
        fresh = False
        if step_length * float(np.abs(update).max()) <= tolerance * size:
            break
        if contraction > refresh_above and iterations < max_iterations:
            factor = tangent_at(x1)
            fresh = True
    v1 = 2.0 * (x1 - x0) / dt - v0
    v1[held] = 0.0
    if hold is not None:
        v1[hold] = 0.0
    determinants = body.determinants_at(x1)
    where = "" if step is None else f"step {step}, "
    if not (np.all(np.isfinite(x1)) and np.all(np.isfinite(v1)) and determinants.min() > 0.0):
        element = int(np.argmin(np.nan_to_num(determinants, nan=-np.inf)))
        raise SolidInversionError(
            f"elastic body failed at {where}implicit step (dt = {dt:.3g} s): element "
            f"{element} has det F = {determinants[element]:.3g} (inverted or non-finite); "
            "use a smaller dt",
            step=step, substep=0, element=element,
            determinant=float(determinants[element]), positions=x1,
        )
    state_out.positions[...] = x1
    state_out.velocities[...] = v1
    return SolidStepReport(
        substeps=iterations, substep_dt=dt, stable_substep=body.stable_substep(),
        min_determinant=float(determinants.min()),
    )


def static_equilibrium(body: ImplicitBody, state: BodyState,
                       external_forces: np.ndarray | None = None, *,
                       tolerance: float = 1e-10, max_iterations: int = 100) -> int:
    """Move ``state`` to rest under the body's elastic forces, gravity and ``external_forces``.

    Newton's method on ``f_internal(x) + f_external + M g = 0`` with the tangent of the
    implicit step (`NewmarkFem.response`'s matrix with a step so long that the stiffness
    dominates the mass, which only keeps it regular; compressive stress is left out of it,
    so convergence is linear, about halving the error per iteration), updates halved
    while they would invert an element, and the load applied in increments when a full
    one does not converge. Velocities are set to zero.

    Args:
        body: The body's model.
        state: Start of the iteration; receives the equilibrium.
        external_forces: Nodal forces [N/m], shape (n, 2) (3D: [N], (n, 3)); default none.
        tolerance: Stop when the update is below ``tolerance`` times the body's size.
        max_iterations: Newton iterations at most per load increment.

    Returns:
        Newton iterations taken in all.

    Raises:
        SolidInversionError: No equilibrium found without inverting an element; ``state``
            keeps its values.
    """
    n = body.point_count
    dimension = body.gravity.shape[0]
    forces = (np.zeros((n, dimension)) if external_forces is None
              else _checked_forces(body, external_forces))
    held = body.fixed_mask
    still = np.zeros((n, dimension))
    size = float(np.ptp(body.mesh.points, axis=0).max())
    load = forces + body.mass[:, None] * body.gravity
    # A "step" of s seconds: s^2 K outweighs M by (s omega)^2 in every mode; 1e4 wave
    # crossings exceed the slowest (bending) period of slender bodies by far.
    pseudo_step = 1e4 * size / body.material.dilatational_wave_speed

    def residual_at(x: np.ndarray, fraction: float) -> tuple[np.ndarray, float]:
        r = body.forces_at(x, still) + fraction * load
        r[held] = 0.0
        norm = float(np.linalg.norm(r))
        return r, norm if np.isfinite(norm) else np.inf

    x = state.positions.copy()
    total = 0
    fraction, increment = 0.0, 1.0
    while fraction < 1.0:
        target = min(1.0, fraction + increment)
        trial_x = x.copy()
        residual, norm = residual_at(trial_x, target)
        # Round-off floor of the residual: the forces' own size times machine precision.
        floor = 1e3 * np.finfo(float).eps * (float(np.linalg.norm(load)) + 1e-300)
        converged = False
        for _ in range(max_iterations):
            total += 1
            response = body.response_at(trial_x, 0.0, pseudo_step, 1.0)
            update = response.solve(pseudo_step**2 * residual)
            # The residual is a poor merit function for the first, large updates (it
            # jumps before it falls): only an inverted element shortens the step.
            length = 1.0
            for _ in range(30):
                candidate = trial_x + length * update
                if body.determinants_at(candidate).min() > 0.0:
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
        determinants = body.determinants_at(trial_x)
        if converged and determinants.min() > 0.0:
            x, fraction = trial_x, target
            increment = min(2.0 * increment, 1.0)
            continue
        increment *= 0.25
        if increment < 1e-4:
            element = int(np.argmin(determinants))
            raise SolidInversionError(
                f"elastic body: no static equilibrium found at {100 * target:.3g} % of "
                f"the load (element {element}, det F = {determinants[element]:.3g})",
                step=None, substep=0, element=element,
                determinant=float(determinants[element]), positions=trial_x,
            )
    state.positions[...] = x
    state.velocities[...] = 0.0
    return total
