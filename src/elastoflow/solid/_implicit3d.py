"""The step matrix of a tetrahedral body (`ElasticBody3D`) and its factor: what the implicit
rules (`elastoflow.solid.NewmarkFem`, `MidpointFem`, `EnergyMomentumFem`, and
`static_equilibrium`: one class each for 2D and 3D bodies, in `elastoflow.solid._integrators`)
read of a 3D body through its ``response_at``; the 3D counterpart of
`elastoflow.solid._response`:

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
  arrays of shape (n, 3) and degrees of freedom ``3 node + component``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse.linalg as sparse_linalg
from scipy import linalg, sparse

from elastoflow.solid import _kernels3d
from elastoflow.solid._body3d import ElasticBody3D
from elastoflow.solid._response import _BLAS, StepResponse, _banded_cholesky

# Free degrees of freedom up to which the matrix is inverted dense (2D: `_DENSE_LIMIT`, 600,
# chosen for the compliance on many boundary dofs). A 3D body's Newton step pays the whole
# inverse: the k = 2 cantilever (540 free dofs) took 63 ms a step dense against 9.2 ms with
# the banded factor (its compliance on 81 dofs: 1.7 ms dense, 18 ms banded); at 108 free
# dofs both take 6-7 ms.
_DENSE_LIMIT_3D = 192
# Above it, the banded factor while its work n b^2 stays below this (2D: 2e8, for slender
# bodies). A body's compliance on the surface dofs the pressure touches is then applied by
# the factor's sweeps inside the coupled solve; SuperLU's answer has to be formed, one
# solve per touched dof: the settling sphere at 6 cells per diameter (2337 dofs, half-band
# 431 in RCM order, n b^2 = 4.3e8) spent 18 s a step there, while its banded factor takes
# 0.2 s (SuperLU 0.1 s). The elastic block with 20480 tetrahedra (14.6k free dofs, n b^2 =
# 3e9) had not finished its first coupled step in 9 CPU minutes through SuperLU (the
# compliance on ~6000 touched dofs); banded it steps in 2.5-3.8 s (1.2 s of it the body),
# so the band is used up to 2e10 (a factor of 150 MB at most for such bodies).
_BANDED_WORK_LIMIT_3D = 2.0e10


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


def nodal_block_matrix(blocks: np.ndarray, free: np.ndarray) -> sparse.csr_matrix:
    """The block-diagonal matrix of nodal 3x3 ``blocks`` (n, 3, 3) on the ``free`` degrees
    of freedom (``3 node + component``), sparse CSR (f, f) in their order."""
    n = blocks.shape[0]
    position = np.full(3 * n, -1, np.int64)
    position[free] = np.arange(free.shape[0])
    node = np.repeat(np.arange(n), 9)
    rows = position[3 * node + np.tile(np.repeat(np.arange(3), 3), n)]
    cols = position[3 * node + np.tile(np.tile(np.arange(3), 3), n)]
    keep = (rows >= 0) & (cols >= 0)
    return sparse.csr_matrix((blocks.reshape(-1)[keep], (rows[keep], cols[keep])),
                             shape=(free.shape[0], free.shape[0]))


def step_response_3d(body: ElasticBody3D, positions: np.ndarray, dt: float,
                     stiffness_step: float | None = None, scale: float | None = None,
                     layout: StepMatrixLayout3D | None = None,
                     nodal_damping: np.ndarray | None = None) -> StepResponse3D:
    """Assemble (`step_matrix_3d`, plus ``dt`` times the symmetric positive semi-definite
    ``nodal_damping`` blocks (n, 3, 3) when given) and factor ``A``; its answer is ``scale
    A^-1 f`` (default ``dt``). Up to ``_DENSE_LIMIT_3D`` free degrees of freedom the inverse is formed (dense
    Cholesky); above, a banded Cholesky in reverse Cuthill-McKee order when the band is
    narrow enough (`_response._banded_cholesky`: slender bodies), SuperLU otherwise."""
    if layout is None:
        layout = StepMatrixLayout3D.build(body)
    answer = dt if scale is None else float(scale)
    free = layout.free
    if free.size == 0:
        return StepResponse3D(free, answer, None)
    matrix = step_matrix_3d(body, positions, dt, stiffness_step, layout)
    if nodal_damping is not None:
        # Symmetric blocks inside the pattern's nodal blocks: the sum keeps A symmetric.
        matrix = (matrix + dt * nodal_block_matrix(nodal_damping, free)).tocsr()
        matrix.sort_indices()
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
    banded = _banded_cholesky(columns, _BANDED_WORK_LIMIT_3D)
    if banded is not None:
        return StepResponse3D(free, answer, None, None, banded[0], banded[1])
    lu = sparse_linalg.splu(columns, permc_spec="MMD_AT_PLUS_A",
                            options={"SymmetricMode": True})
    return StepResponse3D(free, answer, lu)
