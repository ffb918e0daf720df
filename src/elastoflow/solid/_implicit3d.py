"""Implicit steps of tetrahedral bodies (`ElasticBody3D`): the step matrix, its factor, the
integrators.

The building block of a strongly coupled 3D scheme, the 3D counterpart of
`elastoflow.solid._integrators` and `elastoflow.solid._response`:

* the step matrix ``A = M + c D + s^2 K + c alpha M`` of a body at given positions (``K`` the
  St. Venant-Kirchhoff tangent stiffness with the compressive stress clamped, ``D`` the Voigt
  damping matrix, ``M`` the lumped masses): its element entries (compiled,
  `elastoflow.solid._kernels3d.step_matrix_scatter_3d`; the COO twin
  `step_matrix_triplets_3d` gives `ElasticBody3D.stiffness_matrix`) summed straight into a
  CSR pattern of the free degrees of freedom that the body builds once
  (`StepMatrixLayout3D`), and factored (`step_response_3d`): dense Cholesky for small
  bodies, banded Cholesky in reverse Cuthill-McKee order for slender ones, SuperLU
  otherwise;
* `StepResponse3D`, the factored answer ``scale A^-1 f`` to a force held over the step: the
  contract of the 2D `StepResponse` (``solve``, ``velocity_change``, ``compliance``,
  ``compliance_factor``), what the monolithic pressure solve reads of a body, with nodal
  arrays of shape (n, 3) and degrees of freedom ``3 node + component``;
* `NewmarkFem3D`, `MidpointFem3D`, `EnergyMomentumFem3D`: the 2D rules (`NewmarkFem`,
  `MidpointFem`, `EnergyMomentumFem`) with the same arguments, ``response`` and
  ``advance``, for both dimensions. They subclass the 2D classes, so they are accepted
  wherever those are (e.g. `elastoflow.simulation.MonolithicCoupling(integrator=...)`), and
  hand 2D bodies to them unchanged; a 3D body runs the same residual through `_newton_step`.
  Why not the 2D classes themselves: their ``advance`` checks the forces against shape
  (n, 2) (``_integrators._checked_forces``), and their Newton (`_integrators._implicit_step`:
  the start's tangent until the residual grows) converged too slowly in 3D rotations;
  `_newton_step` also refactors when the residual contracts slowly. With the check taking
  the body's dimension and that Newton shared, these three would reduce to the 2D classes;
* `static_equilibrium_3d`: the rest state under loads (static deflection).
"""

from __future__ import annotations

import weakref
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse.linalg as sparse_linalg
from scipy import linalg, sparse

from elastoflow.solid import _kernels3d
from elastoflow.solid._body import SolidInversionError, SolidStepReport
from elastoflow.solid._body3d import ElasticBody3D
from elastoflow.solid._integrators import EnergyMomentumFem, MidpointFem, NewmarkFem
from elastoflow.solid._response import _BLAS, StepResponse, _banded_cholesky
from elastoflow.solid._rod import BodyModel
from elastoflow.solid._state import BodyState

# Free degrees of freedom up to which the matrix is inverted dense (2D: `_DENSE_LIMIT`, 600,
# chosen for the compliance on many boundary dofs). A 3D body's Newton step pays the whole
# inverse: the k = 2 cantilever (540 free dofs) took 63 ms a step dense against 9.2 ms with
# the banded factor (its compliance on 81 dofs: 1.7 ms dense, 18 ms banded); at 108 free
# dofs both take 6-7 ms.
_DENSE_LIMIT_3D = 192


@dataclass
class StepResponse3D(StepResponse):
    """The factored one-step response of a 3D body: ``dv = scale A^-1 f`` on its free nodes.

    `StepResponse` with nodal arrays of shape (n, 3).

    Attributes:
        free: Degrees of freedom (``3 node + component``) that are not held, int64.
        dt: The ``scale`` it was built for [s] (the answer's factor).
    """

    def solve(self, values: np.ndarray) -> np.ndarray:
        """``A^-1 values`` for nodal values (n, 3); 0 on held nodes."""
        flat = np.ascontiguousarray(values, dtype=np.float64).reshape(-1)
        result = np.zeros(flat.shape[0])
        if self._factored and self.free.size:
            result[self.free] = self._solve(flat[self.free])
        return result.reshape(-1, 3)

    def velocity_change(self, forces: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """``dv`` [m/s], shape (n, 3), answering nodal ``forces`` [N] held over the step."""
        flat = np.ascontiguousarray(forces, dtype=np.float64).reshape(-1)
        result = np.zeros(flat.shape[0]) if out is None else out.reshape(-1)
        if out is not None:
            result[:] = 0.0
        if self._factored and self.free.size:
            result[self.free] = self.dt * self._solve(flat[self.free])
        return result.reshape(-1, 3)


@dataclass(frozen=True)
class StepMatrixLayout3D:
    """Where each triplet of `step_matrix_triplets_3d` goes in the step matrix restricted to
    the free degrees of freedom, stored as CSR (sorted columns). It depends only on the mesh
    and the held nodes, so a body builds it once and every step sums its element entries
    into the data array (`step_matrix_scatter_3d`), with no sorting.

    Attributes:
        free: Free degrees of freedom (``3 node + component``), int64, shape (f,).
        indptr: CSR row pointers of the free block, int64, shape (f + 1,).
        indices: CSR column indices, int64, shape (nnz,).
        target: Per triplet, its index into the CSR data, or -1 on a held degree of
            freedom, int64, shape (144 m,).
        diagonal: CSR data index of each free degree of freedom's diagonal, int64, (f,).
    """

    free: np.ndarray
    indptr: np.ndarray
    indices: np.ndarray
    target: np.ndarray
    diagonal: np.ndarray

    @staticmethod
    def build(body: ElasticBody3D) -> StepMatrixLayout3D:
        """The layout of ``body``'s mesh and held nodes."""
        n = body.point_count
        count = _kernels3d.MATRIX_TRIPLETS_3D * body.mesh.tetrahedron_count
        rows = np.empty(count, dtype=np.int64)
        cols = np.empty(count, dtype=np.int64)
        values = np.empty(count)
        # Only the pattern is wanted; the values at the rest shape are discarded.
        _kernels3d.step_matrix_triplets_3d(
            np.ascontiguousarray(body.mesh.points, dtype=np.float64), body.mesh.tetrahedra,
            body.dm_inverse, body.rest_volume, 0.0, 0.0, 0.0, 0.0, 0.0, False, rows, cols,
            values,
        )
        free = np.flatnonzero(~np.repeat(body.fixed_mask, 3)).astype(np.int64)
        local = np.full(3 * n, -1, np.int64)
        local[free] = np.arange(free.size)
        r, c = local[rows], local[cols]
        keep = (r >= 0) & (c >= 0)
        keys, inverse = np.unique(r[keep] * free.size + c[keep], return_inverse=True)
        target = np.full(count, -1, np.int64)
        target[keep] = inverse
        key_rows = keys // max(free.size, 1)
        indptr = np.concatenate([[0], np.cumsum(np.bincount(key_rows, minlength=free.size))])
        indices = keys % max(free.size, 1)
        diagonal = np.searchsorted(keys, np.arange(free.size) * (free.size + 1))
        return StepMatrixLayout3D(free, indptr.astype(np.int64), indices.astype(np.int64),
                                  target, diagonal.astype(np.int64))


def step_matrix_3d(body: ElasticBody3D, positions: np.ndarray, dt: float,
                   stiffness_step: float | None = None,
                   layout: StepMatrixLayout3D | None = None) -> sparse.csr_matrix:
    """``A = M + dt D + s^2 K + dt alpha M`` on the free degrees of freedom (``s =
    stiffness_step``, default ``dt``), sparse CSR (f, f) in the order of ``layout.free``;
    ``K`` with the compressive stress clamped (positive semi-definite), so ``A`` is
    symmetric positive definite. (Newton with the exact, indefinite tangent instead
    converged worse: a spinning, vibrating block at 20 x the explicit substep inverted at
    step 3 under the energy-momentum rule, where the clamped one keeps the angular
    momentum to 3e-8.)"""
    if layout is None:
        layout = StepMatrixLayout3D.build(body)
    s = dt if stiffness_step is None else float(stiffness_step)
    m = body.material
    data = np.empty(layout.indices.shape[0])
    _kernels3d.step_matrix_scatter_3d(
        np.ascontiguousarray(positions, dtype=np.float64), body.mesh.tetrahedra,
        body.dm_inverse, body.rest_volume, dt * m.damping_lambda + s * s * m.lame_lambda,
        dt * m.damping_mu + s * s * m.lame_mu, m.lame_lambda, m.lame_mu, s * s, True,
        layout.target, data,
    )
    lumped = np.repeat(body.mass * (1.0 + dt * body.velocity_damping), 3)[layout.free]
    data[layout.diagonal] += lumped
    size = layout.free.shape[0]
    return sparse.csr_matrix((data, layout.indices, layout.indptr), shape=(size, size))


def step_response_3d(body: ElasticBody3D, positions: np.ndarray, dt: float,
                     stiffness_step: float | None = None, scale: float | None = None,
                     layout: StepMatrixLayout3D | None = None) -> StepResponse3D:
    """Assemble (`step_matrix_3d`) and factor ``A``; its answer is ``scale A^-1 f`` (default
    ``dt``). Up to ``_DENSE_LIMIT_3D`` free degrees of freedom the inverse is formed (dense
    Cholesky); above, a banded Cholesky in reverse Cuthill-McKee order when the band is
    narrow enough (`_response._banded_cholesky`: slender bodies), SuperLU otherwise."""
    if layout is None:
        layout = StepMatrixLayout3D.build(body)
    answer = dt if scale is None else float(scale)
    free = layout.free
    if free.size == 0:
        return StepResponse3D(free, answer, None)
    matrix = step_matrix_3d(body, positions, dt, stiffness_step, layout)
    if free.size <= _DENSE_LIMIT_3D:
        with _BLAS.limit(limits=1, user_api="blas"):
            try:
                factor = linalg.cho_factor(matrix.toarray(), check_finite=False)
            except linalg.LinAlgError:
                factor = None  # not positive definite to round-off: the LU below solves it
            if factor is not None:
                inverse = linalg.cho_solve(factor, np.eye(free.size), check_finite=False)
                return StepResponse3D(free, answer, None, 0.5 * (inverse + inverse.T))
    # Symmetric to the last bit (the kernel mirrors its blocks): the CSR arrays read as CSC
    # are the same matrix.
    columns = sparse.csc_matrix((matrix.data, matrix.indices, matrix.indptr),
                                shape=matrix.shape)
    banded = _banded_cholesky(columns)
    if banded is not None:
        return StepResponse3D(free, answer, None, None, banded[0], banded[1])
    lu = sparse_linalg.splu(columns, permc_spec="MMD_AT_PLUS_A",
                            options={"SymmetricMode": True})
    return StepResponse3D(free, answer, lu)


def _checked_forces_3d(body: ElasticBody3D, external_forces: np.ndarray) -> np.ndarray:
    n = body.point_count
    forces = np.ascontiguousarray(external_forces, dtype=np.float64)
    if forces.shape != (n, 3) or not np.all(np.isfinite(forces)):
        raise ValueError(f"external_forces: must be finite, shape ({n}, 3)")
    return forces


# Newton keeps a factor while each update shrinks the residual at least this much; slower
# contraction gets a fresh tangent at the new iterate (2D: only when the residual grows).
# A block spinning 0.09 rad a step and vibrating (strains ~1 %), 10 x the explicit
# substep, 12 iterations at most, 60 steps: the start's tangent, rotated against the
# midpoint, contracts by ~0.2 an iteration; angular momentum kept to 1e-5 (2D rule), 6e-6
# (0.5), 4e-8 (0.25), 4e-11 (0.1) by the midpoint rule, 5e-5 / 8e-6 / 4e-9 / 2e-11 by
# energy-momentum (at 20 x: the 2D rule inverts an element at step 27, 0.25 keeps 3e-8).
# A refactor costs ~30-50 Newton iterations of a 5000-tetrahedron body.
_CONTRACTION = 0.25


def _newton_step(
    body: ElasticBody3D, state_in: BodyState, state_out: BodyState, dt: float,
    residual: Callable[[np.ndarray], np.ndarray], response: StepResponse,
    tangent_at: Callable[[np.ndarray], StepResponse], tolerance: float, max_iterations: int,
    step: int | None,
) -> SolidStepReport:
    """Newton on an implicit rule's residual in the end positions (end velocity ``2 (x1 -
    x0) / dt - v0``), as `_integrators._implicit_step`: first with the matrix of
    ``response`` (the tangent at the start, the linearised step's exact answer), a fresh
    tangent at the iterate whenever an update contracts the residual by less than
    ``_CONTRACTION`` or fails to reduce it, and a halving line search when even a fresh one
    does not."""
    held = body.fixed_mask
    x0 = state_in.positions
    v0 = state_in.velocities

    def residual_at(x: np.ndarray) -> tuple[np.ndarray, float]:
        r = residual(x)
        r[held] = 0.0
        norm = float(np.linalg.norm(r))
        return r, norm if np.isfinite(norm) else np.inf

    x1 = x0 + dt * v0
    x1[held] = x0[held]
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
                factor = tangent_at(x1)
                fresh = True
                update = factor.solve(current)
                continue
            step_length *= 0.5
        else:
            break
        contraction = trial_norm / norm if norm > 0.0 else 0.0
        x1 = trial
        current, norm = trial_residual, trial_norm
        if step_length * float(np.abs(update).max()) <= tolerance * size:
            break
        fresh = False
        if contraction > _CONTRACTION and iterations < max_iterations:
            factor = tangent_at(x1)
            fresh = True
    v1 = 2.0 * (x1 - x0) / dt - v0
    v1[held] = 0.0
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


class _FactorCache:
    """The last response a rule built for each 3D body, handed out again while no element's
    deformation gradient has changed by more than ``reuse_strain`` since (and the step is the
    same): the step matrix of slightly earlier positions. Newton still solves the step's
    equations to its tolerance (with a fresh tangent when the old one contracts slowly);
    what changes is the coupled pressure solve's answer of the body, linearised at those
    earlier positions instead of the step's start (still symmetric positive definite, and
    the same matrix in the predictor and the pressure solve)."""

    def __init__(self, reuse_strain: float) -> None:
        if not (np.isfinite(reuse_strain) and reuse_strain >= 0.0):
            raise ValueError(f"reuse_strain = {reuse_strain!r}: must be finite and >= 0")
        self.reuse_strain = float(reuse_strain)
        self.built = 0
        self._held: weakref.WeakKeyDictionary[ElasticBody3D, tuple[float, np.ndarray,
                                                                   StepResponse]] = (
            weakref.WeakKeyDictionary())

    def response(self, body: BodyModel | ElasticBody3D, state: BodyState, dt: float,
                 build: Callable[[BodyState], StepResponse]) -> StepResponse:
        if self.reuse_strain > 0.0 and isinstance(body, ElasticBody3D):
            held = self._held.get(body)
            if (held is not None and held[0] == dt
                    and _largest_strain_change(body, held[1], state.positions)
                    <= self.reuse_strain):
                return held[2]
        self.built += 1
        response = build(state)
        if self.reuse_strain > 0.0 and isinstance(body, ElasticBody3D):
            self._held[body] = (dt, state.positions.copy(), response)
        return response


def _largest_strain_change(body: ElasticBody3D, reference: np.ndarray,
                           positions: np.ndarray) -> float:
    """``max |F(positions) - F(reference)|`` over the elements and entries."""
    change = positions - reference
    t = body.mesh.tetrahedra
    edges = np.stack([change[t[:, k]] - change[t[:, 0]] for k in (1, 2, 3)], axis=2)
    return float(np.abs(edges @ body.dm_inverse).max())


class NewmarkFem3D(NewmarkFem):
    """`NewmarkFem` (Newmark's rule with ``beta = gamma / 2``, Newton on the step matrix) for
    2D and 3D bodies: a 2D body goes to `NewmarkFem.advance`, an `ElasticBody3D` takes the
    same rule here (module docstring: why a subclass). ``response`` is the 2D one (it reads
    the body's ``response_at``): mean velocity ``dt/2 A^-1 f`` with ``A = M + gamma dt (D +
    alpha M) + beta dt^2 K``.

    Args:
        gamma: Newmark's gamma in [0.5, 1]; 1/2 keeps the energy of linear vibrations.
        tolerance: Stop when the Newton update is below ``tolerance`` times the body's size.
        max_iterations: Newton iterations at most.
        reuse_strain: 0 (default): ``response`` builds and factors the step matrix at the
            state's positions every call, as in 2D. > 0: a 3D body's last response is
            reused while no element's deformation gradient has moved by more than this
            since it was built (`_FactorCache`; the factorization is most of a large body's
            step).
    """

    def __init__(self, gamma: float = 0.5, tolerance: float = 1e-10,
                 max_iterations: int = 12, *, reuse_strain: float = 0.0) -> None:
        super().__init__(gamma, tolerance, max_iterations)
        self.factors = _FactorCache(reuse_strain)

    def response(self, body: BodyModel | ElasticBody3D, state: BodyState,
                 dt: float) -> StepResponse:
        """As `NewmarkFem.response` (``reuse_strain``: the class docstring)."""
        build = super().response
        # BodyModel names the 2D bodies; the 2D rule reads only what ElasticBody3D also has.
        return self.factors.response(body, state, dt,
                                     lambda s: build(body, s, dt))  # type: ignore[arg-type]

    def advance(
        self, body: BodyModel | ElasticBody3D, state_in: BodyState, state_out: BodyState,
        dt: float, external_forces: np.ndarray, response: StepResponse, *,
        step: int | None = None,
    ) -> SolidStepReport:
        """Advance ``state_in`` by ``dt`` [s] into ``state_out`` (may be ``state_in``); as
        `NewmarkFem.advance`, with forces [N] of shape (n, 3) for a 3D body."""
        if not isinstance(body, ElasticBody3D):
            return super().advance(body, state_in, state_out, dt, external_forces, response,
                                   step=step)
        forces = _checked_forces_3d(body, external_forces)
        gamma = self.gamma
        mass = body.mass[:, None]
        x0 = state_in.positions
        v0 = state_in.velocities
        f_external = forces + mass * body.gravity
        a0 = (body.forces_at(x0, v0) + f_external) / mass
        a0[body.fixed_mask] = 0.0
        beta = 0.5 * gamma
        drift = x0 + dt * v0 + (0.5 - beta) * dt * dt * a0

        def residual_at(x: np.ndarray) -> np.ndarray:
            # With beta = gamma / 2 the end velocity is 2 (x1 - x0) / dt - v0 for any gamma.
            v = 2.0 * (x - x0) / dt - v0
            return beta * dt * dt * (body.forces_at(x, v) + f_external) - mass * (x - drift)

        def tangent_at(x: np.ndarray) -> StepResponse:
            return body.response_at(x, gamma * dt, np.sqrt(beta) * dt, 0.5 * dt)

        return _newton_step(body, state_in, state_out, dt, residual_at, response, tangent_at,
                            self.tolerance, self.max_iterations, step)


def _midpoint_advance(
    rule: MidpointFem, body: ElasticBody3D, state_in: BodyState, state_out: BodyState,
    dt: float, external_forces: np.ndarray, response: StepResponse, step: int | None,
) -> SolidStepReport:
    """`MidpointFem.advance` (and its energy-momentum variant) for a 3D body."""
    forces = _checked_forces_3d(body, external_forces)
    mass = body.mass[:, None]
    x0 = state_in.positions
    v0 = state_in.velocities
    f_external = forces + mass * body.gravity
    rate_strain = rule._rate_strain * dt * dt

    def residual_at(x: np.ndarray) -> np.ndarray:
        middle = 0.5 * (x0 + x)
        internal = body.forces_at(middle, (x - x0) / dt, rate_strain)
        internal += rule._extra_forces(body, middle, (x - x0) / dt, dt)  # type: ignore[arg-type]
        return 0.5 * dt * dt * (internal + f_external) - mass * (x - x0 - dt * v0)

    stiffness = dt * np.sqrt(0.25 + 0.5 * getattr(rule, "damping", 0.0))

    def tangent_at(x: np.ndarray) -> StepResponse:
        return body.response_at(0.5 * (x0 + x), 0.5 * dt, stiffness, 0.5 * dt)

    return _newton_step(body, state_in, state_out, dt, residual_at, response, tangent_at,
                        rule.tolerance, rule.max_iterations, step)


class MidpointFem3D(MidpointFem):
    """`MidpointFem` (the implicit midpoint rule: both momenta of a free body kept exactly)
    for 2D and 3D bodies: a 2D body goes to `MidpointFem.advance`, an `ElasticBody3D` takes
    the same rule here (module docstring: why a subclass).

    Args:
        tolerance: Stop when the Newton update is below ``tolerance`` times the body's size.
        max_iterations: Newton iterations at most.
        reuse_strain: Reuse of a 3D body's factor, as `NewmarkFem3D`.
    """

    def __init__(self, tolerance: float = 1e-10, max_iterations: int = 12, *,
                 reuse_strain: float = 0.0) -> None:
        super().__init__(tolerance, max_iterations)
        self.factors = _FactorCache(reuse_strain)

    def response(self, body: BodyModel | ElasticBody3D, state: BodyState,
                 dt: float) -> StepResponse:
        """As `MidpointFem.response` (``reuse_strain``: `NewmarkFem3D`)."""
        build = super().response
        # BodyModel names the 2D bodies; the 2D rule reads only what ElasticBody3D also has.
        return self.factors.response(body, state, dt,
                                     lambda s: build(body, s, dt))  # type: ignore[arg-type]

    def advance(
        self, body: BodyModel | ElasticBody3D, state_in: BodyState, state_out: BodyState,
        dt: float, external_forces: np.ndarray, response: StepResponse, *,
        step: int | None = None,
    ) -> SolidStepReport:
        """As `MidpointFem.advance`, with forces [N] of shape (n, 3) for a 3D body."""
        if not isinstance(body, ElasticBody3D):
            return super().advance(body, state_in, state_out, dt, external_forces, response,
                                   step=step)
        return _midpoint_advance(self, body, state_in, state_out, dt, external_forces,
                                 response, step)


class EnergyMomentumFem3D(EnergyMomentumFem):
    """`EnergyMomentumFem` (the midpoint rule with Simo & Tarnow's stress from the mean of
    the step's end strains: for St. Venant-Kirchhoff a free body keeps its energy to the
    Newton tolerance, and both momenta exactly) for 2D and 3D bodies: a 2D body goes to
    `EnergyMomentumFem.advance`, an `ElasticBody3D` takes the same rule here (module
    docstring: why a subclass).

    Args:
        damping: Numerical damping c (objective Voigt damping ``c dt`` times the Lame
            constants), as `EnergyMomentumFem`.
        tolerance: Stop when the Newton update is below ``tolerance`` times the body's size.
        max_iterations: Newton iterations at most.
        reuse_strain: Reuse of a 3D body's factor, as `NewmarkFem3D`.
    """

    def __init__(self, damping: float = 0.0, tolerance: float = 1e-10,
                 max_iterations: int = 12, *, reuse_strain: float = 0.0) -> None:
        super().__init__(damping, tolerance, max_iterations)
        self.factors = _FactorCache(reuse_strain)

    def response(self, body: BodyModel | ElasticBody3D, state: BodyState,
                 dt: float) -> StepResponse:
        """As `EnergyMomentumFem.response` (``reuse_strain``: `NewmarkFem3D`)."""
        build = super().response
        # BodyModel names the 2D bodies; the 2D rule reads only what ElasticBody3D also has.
        return self.factors.response(body, state, dt,
                                     lambda s: build(body, s, dt))  # type: ignore[arg-type]

    def advance(
        self, body: BodyModel | ElasticBody3D, state_in: BodyState, state_out: BodyState,
        dt: float, external_forces: np.ndarray, response: StepResponse, *,
        step: int | None = None,
    ) -> SolidStepReport:
        """As `EnergyMomentumFem.advance`, with forces [N] of shape (n, 3) for a 3D body."""
        if not isinstance(body, ElasticBody3D):
            return super().advance(body, state_in, state_out, dt, external_forces, response,
                                   step=step)
        return _midpoint_advance(self, body, state_in, state_out, dt, external_forces,
                                 response, step)


def static_equilibrium_3d(body: ElasticBody3D, state: BodyState,
                          external_forces: np.ndarray | None = None, *,
                          tolerance: float = 1e-10, max_iterations: int = 100) -> int:
    """Move ``state`` to rest under the body's elastic forces, gravity and
    ``external_forces`` (n, 3) [N]: Newton's method on ``f_internal(x) + f_external + M g =
    0`` with the tangent of `static_equilibrium` (2D): the step matrix of a pseudo-step so
    long that the stiffness dominates the masses, compressive stress clamped; updates halved
    while they would invert an element. No load increments: for loads that bend the body
    well beyond small strains, step towards them (or use an implicit integrator with
    damping). Velocities are set to zero.

    Returns:
        Newton iterations taken.

    Raises:
        SolidInversionError: No converged equilibrium without inverting an element;
            ``state`` keeps its values.
    """
    n = body.point_count
    forces = (np.zeros((n, 3)) if external_forces is None
              else _checked_forces_3d(body, external_forces))
    held = body.fixed_mask
    still = np.zeros((n, 3))
    size = float(np.ptp(body.mesh.points, axis=0).max())
    load = forces + body.mass[:, None] * body.gravity
    pseudo_step = 1e4 * size / body.material.dilatational_wave_speed
    floor = 1e3 * np.finfo(float).eps * (float(np.linalg.norm(load)) + 1e-300)
    x = state.positions.copy()
    for iteration in range(1, max_iterations + 1):
        residual = body.forces_at(x, still) + load
        residual[held] = 0.0
        if float(np.linalg.norm(residual)) <= floor:
            break
        update = body.response_at(x, 0.0, pseudo_step, 1.0).solve(pseudo_step**2 * residual)
        length = 1.0
        for _ in range(30):
            if body.determinants_at(x + length * update).min() > 0.0:
                break
            length *= 0.5
        else:
            break
        x = x + length * update
        if length * float(np.abs(update).max()) <= tolerance * size:
            break
    else:
        iteration = max_iterations
    residual = body.forces_at(x, still) + load
    residual[held] = 0.0
    determinants = body.determinants_at(x)
    converged = (float(np.linalg.norm(residual)) <= max(floor, 1e-6 * float(
        np.linalg.norm(load)))) and determinants.min() > 0.0
    if not converged:
        element = int(np.argmin(determinants))
        raise SolidInversionError(
            f"elastic body: no static equilibrium found in {max_iterations} iterations "
            f"(element {element}, det F = {determinants[element]:.3g})",
            step=None, substep=0, element=element, determinant=float(determinants[element]),
            positions=x,
        )
    state.positions[...] = x
    state.velocities[...] = 0.0
    return iteration
