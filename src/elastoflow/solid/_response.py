"""The body's linear response over one fluid step, for the strongly coupled pressure solve.

A strongly coupled step needs to know how the body's velocity answers a force held over the
fluid step ``dt``. The explicit substeps do not give a usable linear answer (a stiff mode with
period shorter than ``dt`` answers a constant force with ``sin(omega dt) / omega``, of either
sign), so the coupling uses the backward-Euler response of the linearised body instead:

    (M + dt D + dt^2 K + dt alpha M) dv = dt f

with ``M`` the lumped masses, ``K`` the St. Venant–Kirchhoff tangent stiffness at the current
positions, ``D`` the Voigt damping's tangent (the same form with the damping constants) and
``alpha`` the mass-proportional drag. The matrix is symmetric positive definite on the free
degrees of freedom: the material parts are positive semi-definite for any deformation, and the
stress (geometric) part uses the stress with its compressive eigenvalues clamped at zero, which
keeps it semi-definite where a compressed element would make the exact tangent indefinite. Rigid
motions cost nothing in ``K`` and ``D``, so a rigid translation answers ``dv = dt f / m`` exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse.linalg as sparse_linalg
from numba import njit
from scipy import linalg, sparse
from scipy.sparse.csgraph import reverse_cuthill_mckee
from threadpoolctl import ThreadpoolController

from elastoflow.linalg import banded_solve_in_place, banded_sweep_layouts



@njit(cache=True)
def _clamped_stress(e00: float, e01: float, e11: float, lame_lambda: float,
                    lame_mu: float) -> tuple[float, float, float]:
    """St. Venant–Kirchhoff second Piola–Kirchhoff stress with negative eigenvalues set to 0."""
    trace = e00 + e11
    s00 = lame_lambda * trace + 2.0 * lame_mu * e00
    s11 = lame_lambda * trace + 2.0 * lame_mu * e11
    s01 = 2.0 * lame_mu * e01
    mean = 0.5 * (s00 + s11)
    radius = np.sqrt(0.25 * (s00 - s11) ** 2 + s01 * s01)
    high = mean + radius
    low = mean - radius
    if low >= 0.0:
        return s00, s01, s11
    if high <= 0.0:
        return 0.0, 0.0, 0.0
    # Keep only the positive eigenpair: S+ = high * n n^T, n the eigenvector of ``high``.
    if radius == 0.0:
        return 0.0, 0.0, 0.0
    if abs(s01) > 0.0:
        nx, ny = s01, high - s00
    elif s00 >= s11:
        nx, ny = 1.0, 0.0
    else:
        nx, ny = 0.0, 1.0
    norm = nx * nx + ny * ny
    return high * nx * nx / norm, high * nx * ny / norm, high * ny * ny / norm


@njit(cache=True)
def response_triplets(
    positions: np.ndarray, triangles: np.ndarray, dm_inverse: np.ndarray,
    rest_area: np.ndarray, material_lambda: float, material_mu: float, stress_lambda: float,
    stress_mu: float, stress_scale: float, rows: np.ndarray, cols: np.ndarray,
    values: np.ndarray,
) -> None:
    """Element matrices of ``dt D + dt^2 K`` as COO triplets (36 per element).

    ``material_lambda``/``material_mu`` are the combined constants of the material parts
    (``dt lambda' + dt^2 lambda``), ``stress_lambda``/``stress_mu`` the elastic constants
    whose clamped stress gives the geometric part, scaled by ``stress_scale`` (``dt^2``).
    Degree of freedom ``2 node + component``.
    """
    column = np.empty(6)
    for e in range(triangles.shape[0]):
        i0, i1, i2 = triangles[e, 0], triangles[e, 1], triangles[e, 2]
        b00, b01 = dm_inverse[e, 0, 0], dm_inverse[e, 0, 1]
        b10, b11 = dm_inverse[e, 1, 0], dm_inverse[e, 1, 1]
        d00 = positions[i1, 0] - positions[i0, 0]
        d10 = positions[i1, 1] - positions[i0, 1]
        d01 = positions[i2, 0] - positions[i0, 0]
        d11 = positions[i2, 1] - positions[i0, 1]
        f00 = d00 * b00 + d01 * b10
        f01 = d00 * b01 + d01 * b11
        f10 = d10 * b00 + d11 * b10
        f11 = d10 * b01 + d11 * b11
        e00 = 0.5 * (f00 * f00 + f10 * f10 - 1.0)
        e11 = 0.5 * (f01 * f01 + f11 * f11 - 1.0)
        e01 = 0.5 * (f00 * f01 + f10 * f11)
        s00, s01, s11 = _clamped_stress(e00, e01, e11, stress_lambda, stress_mu)
        area = rest_area[e]
        nodes = (i0, i1, i2)
        base = 36 * e
        for a in range(3):
            for d in range(2):
                # dDs for a unit move of node a along d: column c of dDs is e_d times
                # (1 if a == c + 1, -1 if a == 0).
                c0 = 1.0 if a == 1 else (-1.0 if a == 0 else 0.0)
                c1 = 1.0 if a == 2 else (-1.0 if a == 0 else 0.0)
                # dF = dDs Dm^-1: only row d is non-zero.
                r0 = c0 * b00 + c1 * b10
                r1 = c0 * b01 + c1 * b11
                g00 = r0 if d == 0 else 0.0
                g01 = r1 if d == 0 else 0.0
                g10 = r0 if d == 1 else 0.0
                g11 = r1 if d == 1 else 0.0
                # dE = sym(F^T dF)
                de00 = f00 * g00 + f10 * g10
                de11 = f01 * g01 + f11 * g11
                de01 = 0.5 * (f00 * g01 + f10 * g11 + g00 * f01 + g10 * f11)
                trace = de00 + de11
                ds00 = material_lambda * trace + 2.0 * material_mu * de00
                ds11 = material_lambda * trace + 2.0 * material_mu * de11
                ds01 = 2.0 * material_mu * de01
                # dP = F dS + dt^2 dF S+
                p00 = f00 * ds00 + f01 * ds01 + stress_scale * (g00 * s00 + g01 * s01)
                p01 = f00 * ds01 + f01 * ds11 + stress_scale * (g00 * s01 + g01 * s11)
                p10 = f10 * ds00 + f11 * ds01 + stress_scale * (g10 * s00 + g11 * s01)
                p11 = f10 * ds01 + f11 * ds11 + stress_scale * (g10 * s01 + g11 * s11)
                # Column of K: A0 dP Dm^-T on nodes 1, 2; node 0 balances them.
                h00 = area * (p00 * b00 + p01 * b01)
                h01 = area * (p00 * b10 + p01 * b11)
                h10 = area * (p10 * b00 + p11 * b01)
                h11 = area * (p10 * b10 + p11 * b11)
                column[2] = h00
                column[3] = h10
                column[4] = h01
                column[5] = h11
                column[0] = -h00 - h01
                column[1] = -h10 - h11
                col = 2 * nodes[a] + d
                local_col = 2 * a + d
                for b in range(3):
                    for k in range(2):
                        index = base + (2 * b + k) * 6 + local_col
                        rows[index] = 2 * nodes[b] + k
                        cols[index] = col
                        values[index] = column[2 * b + k]


@njit(cache=True)
def _banded_inverse_columns(columns_of_u: np.ndarray, rows_of_u: np.ndarray,
                            starts: np.ndarray, targets: np.ndarray, scale: float,
                            out: np.ndarray) -> None:
    """``out[targets[r], targets[c]] = scale (U^T U)^-1 [starts[r], starts[c]]`` for
    increasing ``starts``, symmetric to the last bit; U
    upper triangular with half-band b given twice, contiguous along both sweeps:
    ``columns_of_u[i, t] = U[i - b + t, i]`` and ``rows_of_u[i, t] = U[i, i + t]``.

    All right-hand sides are swept together, a row at a time, so that the innermost loop
    runs along contiguous memory (it vectorises; one column at a time it is a chain of
    dependent sums, 4x slower); in the forward sweep a unit column is zero above its own
    row, so only the columns that have started take part."""
    band = columns_of_u.shape[1] - 1
    n = columns_of_u.shape[0]
    m = starts.shape[0]
    work = np.zeros((n, m))
    for c in range(m):
        work[starts[c], c] = 1.0
    active = 0
    for i in range(n):
        while active < m and starts[active] <= i:
            active += 1
        row = work[i]
        for k in range(max(0, i - band), i):
            factor = columns_of_u[i, band + k - i]
            if factor != 0.0:
                previous = work[k]
                for c in range(active):
                    row[c] -= factor * previous[c]
        diagonal = 1.0 / columns_of_u[i, band]
        for c in range(active):
            row[c] *= diagonal
    for i in range(n - 1, -1, -1):
        row = work[i]
        for t in range(1, min(band, n - 1 - i) + 1):
            factor = rows_of_u[i, t]
            if factor != 0.0:
                later = work[i + t]
                for c in range(m):
                    row[c] -= factor * later[c]
        diagonal = 1.0 / rows_of_u[i, 0]
        for c in range(m):
            row[c] *= diagonal
    for r in range(m):
        for c in range(r + 1):
            value = 0.5 * scale * (work[starts[r], c] + work[starts[c], r])
            out[targets[r], targets[c]] = value
            out[targets[c], targets[r]] = value


# One BLAS thread for the small dense factorizations below: OpenBLAS's threads, on 2 cores
# shared with the Numba pool, took 200 ms for a 288 x 288 Cholesky and inverse that one
# thread does in 4 ms. The controller is built once (scanning the loaded libraries costs
# 1.5 ms); each limit then costs microseconds and is undone on leaving.
_BLAS = ThreadpoolController()

# Free degrees of freedom up to which a body's matrix is always factored dense: below this
# the banded layout's bookkeeping does not pay off. Above it a narrow band wins (bar_in_jet's
# bar, 288 free dofs, half-band 19: response and compliance on its 200 boundary dofs in
# 3.2 ms banded against 6.6 ms dense).
_DENSE_BELOW = 64
# Free degrees of freedom up to which the matrix is factored dense (LAPACK Cholesky): for a
# few hundred, SuperLU's solve with one right-hand side per boundary degree of freedom is
# the slow part (51 ms for 288 against ~2 ms dense on bar_in_jet's bar).
_DENSE_LIMIT = 600
# Above it, a banded Cholesky in reverse Cuthill-McKee order while the band's work
# (n b^2, b the half-bandwidth) stays below this: slender bodies (flags, bars, rods) have
# narrow bands. For Turek-Hron's flag at 1270 free degrees of freedom the compliance on the
# degrees of freedom the interface touches took 66-79 ms a step against 730 ms by SuperLU
# (profile of FSI3 at 20 cells per diameter).
_BANDED_WORK_LIMIT = 2.0e8


@dataclass
class StepResponse:
    """The factored one-step response of one body: ``dv = dt A^-1 f`` on its free nodes.

    Attributes:
        free: Degrees of freedom (``2 node + component``) that are not held, int64.
        dt: The fluid step [s] it was built for.
    """

    free: np.ndarray
    dt: float
    _factor: sparse_linalg.SuperLU | None
    _inverse: np.ndarray | None = None
    # Banded Cholesky factor (upper form) of the matrix in the order ``_order``.
    _banded: np.ndarray | None = None
    _order: np.ndarray | None = None
    _sweep_layout: tuple[np.ndarray, np.ndarray] | None = None

    def _solve(self, values: np.ndarray) -> np.ndarray:
        if self._inverse is not None:
            return self._inverse @ values
        if self._banded is not None:
            assert self._order is not None
            result = np.empty_like(values)
            if values.ndim == 1:
                # One right-hand side (each Newton iteration and the coupled answer): the
                # compiled sweeps, without LAPACK's call and the thread limit around it
                # (~0.1 ms each, five or more a step).
                columns, rows = self._sweeps()
                work = np.ascontiguousarray(values[self._order], dtype=np.float64)
                banded_solve_in_place(columns, rows, work)
                result[self._order] = work
                return result
            with _BLAS.limit(limits=1, user_api="blas"):
                result[self._order] = linalg.cho_solve_banded(
                    (self._banded, False), values[self._order], check_finite=False)
            return result
        assert self._factor is not None
        return self._factor.solve(values)

    def _sweeps(self) -> tuple[np.ndarray, np.ndarray]:
        """The banded factor U laid out along its columns and along its rows (see
        ``banded_inverse_columns``), built once."""
        if self._sweep_layout is None:
            assert self._banded is not None
            self._sweep_layout = banded_sweep_layouts(self._banded)
        return self._sweep_layout

    @property
    def _factored(self) -> bool:
        return (self._factor is not None or self._inverse is not None
                or self._banded is not None)

    def solve(self, values: np.ndarray) -> np.ndarray:
        """``A^-1 values`` for nodal values (n, 2); 0 on held nodes."""
        flat = np.ascontiguousarray(values, dtype=np.float64).reshape(-1)
        result = np.zeros(flat.shape[0])
        if self._factored and self.free.size:
            result[self.free] = self._solve(flat[self.free])
        return result.reshape(-1, 2)

    def compliance(self, dofs: np.ndarray) -> np.ndarray:
        """``dt A^-1`` restricted to ``dofs`` (``2 node + component``), dense, symmetric:
        entry (a, b) is the velocity change of dof a per unit force on dof b."""
        dofs = np.asarray(dofs, dtype=np.int64)
        result = np.zeros((dofs.shape[0], dofs.shape[0]))
        if not self._factored or not dofs.size:
            return result
        position = np.full(max(int(dofs.max()), int(self.free.max())) + 1, -1, np.int64)
        position[self.free] = np.arange(self.free.shape[0])
        local = position[dofs]
        movable = np.flatnonzero(local >= 0)
        if movable.size:
            if self._inverse is not None:
                block = self.dt * self._inverse[np.ix_(local[movable], local[movable])]
                result[np.ix_(movable, movable)] = 0.5 * (block + block.T)
            elif self._banded is not None:
                assert self._order is not None
                # Positions in the factor's (reverse Cuthill-McKee) order.
                where = np.empty(self._order.shape[0], np.int64)
                where[self._order] = np.arange(self._order.shape[0])
                ordered = where[local[movable]]
                sort = np.argsort(ordered, kind="stable")
                _banded_inverse_columns(*self._sweeps(), np.ascontiguousarray(ordered[sort]),
                                        np.ascontiguousarray(movable[sort]), self.dt, result)
            else:
                unit = np.zeros((self.free.shape[0], movable.shape[0]))
                unit[local[movable], np.arange(movable.shape[0])] = 1.0
                block = self.dt * self._solve(unit)[local[movable]]
                result[np.ix_(movable, movable)] = 0.5 * (block + block.T)
        return result

    def compliance_factor(self, dofs: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """The compliance ``dt A^-1`` through its banded factor instead of as a matrix:
        ``(columns, rows, positions)`` with ``(U^T U)^-1 = dt A^-1`` in the factor's order,
        ``U`` laid out for the two sweeps of `elastoflow.linalg.BandedInverse`, and each of
        ``dofs``'s position in it (-1 on a held degree of freedom); None when the response is
        not held as a banded factor (`compliance` then forms the matrix)."""
        if self._banded is None or not self.free.size:
            return None
        assert self._order is not None
        columns, rows = self._sweeps()
        # U / sqrt(dt) makes (U^T U)^-1 the compliance itself.
        root = np.sqrt(self.dt)
        dofs = np.asarray(dofs, dtype=np.int64)
        position = np.full(max(int(dofs.max(initial=0)), int(self.free.max())) + 1, -1,
                           np.int64)
        where = np.empty(self._order.shape[0], np.int64)
        where[self._order] = np.arange(self._order.shape[0])
        position[self.free] = where
        return columns / root, rows / root, position[dofs]

    def velocity_change(self, forces: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """``dv`` [m/s], shape (n, 2), answering nodal ``forces`` [N/m] held over ``dt``."""
        flat = np.ascontiguousarray(forces, dtype=np.float64).reshape(-1)
        result = np.zeros(flat.shape[0]) if out is None else out.reshape(-1)
        if out is not None:
            result[:] = 0.0
        if self._factored and self.free.size:
            result[self.free] = self.dt * self._solve(flat[self.free])
        return result.reshape(-1, 2)


@dataclass(frozen=True)
class BandedLayout:
    """Where each element-matrix entry of a body's step matrix goes in LAPACK's upper banded
    storage of the free degrees of freedom in reverse Cuthill-McKee order. It depends only
    on the mesh and the held nodes, so a body builds it once (`banded_layout`) and every
    step assembles straight into the band, with no sparse-matrix work.

    Attributes:
        free: Free degrees of freedom (``2 node + component``), int64.
        order: ``order[k]`` is the local free index at banded position k (the RCM order).
        band: Half-bandwidth b.
        target: Per triplet of `response_triplets`, the flat index into the (b + 1, n_free)
            storage, or -1 for an entry on a held degree of freedom, int64.
        weight: Per triplet, 1 on the diagonal and 1/2 off it: each off-diagonal pair (r, c),
            (c, r) lands on one stored entry, which so holds the symmetric part.
        diagonal: Flat storage index of each local free index's diagonal, int64.
        nodal: Per node, the flat storage indices of its 2x2 block's entries (x, x), (y, y)
            and (x, y), -1 where a degree of freedom is held, int64, shape (n, 3): where
            nodal damping blocks go.
    """

    free: np.ndarray
    order: np.ndarray
    band: int
    target: np.ndarray
    weight: np.ndarray
    diagonal: np.ndarray
    nodal: np.ndarray


def banded_layout(triangles: np.ndarray, fixed_mask: np.ndarray,
                  points: np.ndarray) -> BandedLayout | None:
    """The `BandedLayout` of a mesh with held nodes ``fixed_mask``; None when the matrix is
    small enough for a dense factor (``_DENSE_BELOW`` free degrees of freedom or fewer) or
    its band too wide to pay off (``_BANDED_WORK_LIMIT``)."""
    n = points.shape[0]
    m = triangles.shape[0]
    free = np.flatnonzero(~np.repeat(fixed_mask, 2)).astype(np.int64)
    if free.size <= _DENSE_BELOW:
        return None
    rows = np.empty(36 * m, dtype=np.int64)
    cols = np.empty(36 * m, dtype=np.int64)
    values = np.empty(36 * m)
    # Only the pattern is wanted here; the values of the rest shape are discarded.
    response_triplets(np.ascontiguousarray(points, dtype=np.float64), triangles,
                      np.zeros((m, 2, 2)), np.zeros(m), 0.0, 0.0, 0.0, 0.0, 0.0, rows, cols,
                      values)
    local = np.full(2 * n, -1, np.int64)
    local[free] = np.arange(free.size)
    keep = (local[rows] >= 0) & (local[cols] >= 0)
    pattern = sparse.csr_matrix(
        (np.ones(int(keep.sum())), (local[rows[keep]], local[cols[keep]])),
        shape=(free.size, free.size),
    )
    order = reverse_cuthill_mckee(pattern, symmetric_mode=True).astype(np.int64)
    where = np.empty(free.size, np.int64)
    where[order] = np.arange(free.size)
    r = where[local[rows[keep]]]
    c = where[local[cols[keep]]]
    band = int(np.abs(r - c).max()) if r.size else 0
    if free.size * band * band > _BANDED_WORK_LIMIT:
        return None
    high, low = np.maximum(r, c), np.minimum(r, c)
    target = np.full(rows.shape[0], -1, np.int64)
    target[keep] = (band + low - high) * free.size + high
    weight = np.where(rows == cols, 1.0, 0.5)
    diagonal = band * free.size + where
    # A node's own block: its x-y entry is in every element matrix, so within the band.
    position = np.full(2 * n, -1, np.int64)
    position[free] = where
    x, y = position[0::2], position[1::2]
    nodal = np.full((n, 3), -1, np.int64)
    nodal[:, 0] = np.where(x >= 0, band * free.size + x, -1)
    nodal[:, 1] = np.where(y >= 0, band * free.size + y, -1)
    both = (x >= 0) & (y >= 0)
    high, low = np.maximum(x, y), np.minimum(x, y)
    nodal[both, 2] = ((band + low - high) * free.size + high)[both]
    return BandedLayout(free, order, band, target, weight, diagonal.astype(np.int64), nodal)


@njit(cache=True)
def _assemble_band(values: np.ndarray, target: np.ndarray, weight: np.ndarray,
                   diagonal: np.ndarray, lumped: np.ndarray, storage: np.ndarray) -> None:
    """``storage`` (flat) = the band of the symmetric part of the triplets plus ``lumped`` on
    the diagonal (``lumped`` per local free index)."""
    storage[:] = 0.0
    for k in range(values.shape[0]):
        if target[k] >= 0:
            storage[target[k]] += weight[k] * values[k]
    for i in range(diagonal.shape[0]):
        storage[diagonal[i]] += lumped[i]


def step_response(
    positions: np.ndarray, triangles: np.ndarray, dm_inverse: np.ndarray,
    rest_area: np.ndarray, mass: np.ndarray, fixed_mask: np.ndarray, lame_lambda: float,
    lame_mu: float, damping_lambda: float, damping_mu: float, velocity_damping: float,
    dt: float, stiffness_step: float | None = None, scale: float | None = None,
    layout: BandedLayout | None = None, nodal_damping: np.ndarray | None = None,
) -> StepResponse:
    """Assemble and factor ``M + dt D + s^2 K + dt alpha M`` on the free degrees of freedom
    (``s = stiffness_step``, default ``dt``), plus ``dt`` times the symmetric positive
    semi-definite ``nodal_damping`` blocks (n, 2, 2) when given; its answer is ``scale A^-1
    f`` (default ``dt``). With the body's ``layout`` (`banded_layout`) it assembles straight
    into the banded Cholesky's storage."""
    s = dt if stiffness_step is None else float(stiffness_step)
    n = positions.shape[0]
    m = triangles.shape[0]
    rows = np.empty(36 * m, dtype=np.int64)
    cols = np.empty(36 * m, dtype=np.int64)
    values = np.empty(36 * m)
    response_triplets(
        positions, triangles, dm_inverse, rest_area, dt * damping_lambda + s * s * lame_lambda,
        dt * damping_mu + s * s * lame_mu, lame_lambda, lame_mu, s * s, rows, cols, values,
    )
    answer = dt if scale is None else float(scale)
    if layout is not None:
        lumped = np.repeat(mass * (1.0 + dt * velocity_damping), 2)[layout.free]
        storage = np.empty((layout.band + 1, layout.free.size))
        _assemble_band(values, layout.target, layout.weight, layout.diagonal, lumped,
                       storage.reshape(-1))
        if nodal_damping is not None:
            flat = storage.reshape(-1)
            blocks = dt * np.asarray(nodal_damping, dtype=np.float64).reshape(n, 4)
            for column, entry in ((0, 0), (1, 3), (2, 1)):
                held = layout.nodal[:, column] < 0
                np.add.at(flat, np.where(held, 0, layout.nodal[:, column]),
                          np.where(held, 0.0, blocks[:, entry]))
        try:
            with _BLAS.limit(limits=1, user_api="blas"):
                factor = linalg.cholesky_banded(storage, lower=False, check_finite=False)
            return StepResponse(layout.free, answer, None, None, factor, layout.order)
        except linalg.LinAlgError:
            pass  # not positive definite to round-off: the general path below decides
    size = 2 * n
    matrix = sparse.coo_matrix((values, (rows, cols)), shape=(size, size)).tocsr()
    # Round-off makes the assembled tangent minutely unsymmetric; the factor wants it exact.
    matrix = 0.5 * (matrix + matrix.T)
    lumped = np.repeat(mass * (1.0 + dt * velocity_damping), 2)
    matrix = matrix + sparse.diags(lumped)
    if nodal_damping is not None:
        matrix = matrix + dt * sparse.block_diag(
            list(np.asarray(nodal_damping, dtype=np.float64)), format="csr")
    free = np.flatnonzero(~np.repeat(fixed_mask, 2)).astype(np.int64)
    if free.size == 0:
        return StepResponse(free, answer, None)
    reduced = matrix[free][:, free].tocsc()
    if free.size <= _DENSE_LIMIT:
        with _BLAS.limit(limits=1, user_api="blas"):
            try:
                factor = linalg.cho_factor(reduced.toarray(), check_finite=False)
            except linalg.LinAlgError:
                factor = None  # not positive definite to round-off: the LU below solves it
            if factor is not None:
                inverse = linalg.cho_solve(factor, np.eye(free.size), check_finite=False)
                return StepResponse(free, answer, None, 0.5 * (inverse + inverse.T))
    banded = _banded_cholesky(reduced)
    if banded is not None:
        return StepResponse(free, answer, None, None, banded[0], banded[1])
    lu = sparse_linalg.splu(reduced, permc_spec="MMD_AT_PLUS_A", options={"SymmetricMode": True})
    return StepResponse(free, answer, lu)


def _banded_cholesky(matrix: sparse.csc_matrix, work_limit: float | None = None
                     ) -> tuple[np.ndarray, np.ndarray] | None:
    """Cholesky factor of ``matrix`` in LAPACK's upper banded storage after a reverse
    Cuthill-McKee reordering, and the order; None when the band is too wide to pay off
    (``n b^2`` over ``work_limit``, default `_BANDED_WORK_LIMIT`) or the matrix is not
    positive definite to round-off."""
    if work_limit is None:
        work_limit = _BANDED_WORK_LIMIT
    order = reverse_cuthill_mckee(matrix.tocsr(), symmetric_mode=True).astype(np.int64)
    permuted = matrix[order][:, order].tocoo()
    band = int(np.abs(permuted.row - permuted.col).max()) if permuted.nnz else 0
    if matrix.shape[0] * band * band > work_limit:
        return None
    upper = permuted.row <= permuted.col
    storage = np.zeros((band + 1, matrix.shape[0]))
    rows, cols = permuted.row[upper], permuted.col[upper]
    np.add.at(storage, (band + rows - cols, cols), permuted.data[upper])
    try:
        # One BLAS thread (see _BLAS): Turek-Hron's flag at 1260 degrees of freedom and
        # half-band 25 factors in 3.4 ms on one thread and 673 ms on OpenBLAS's threads when
        # the other core is busy.
        with _BLAS.limit(limits=1, user_api="blas"):
            factor = linalg.cholesky_banded(storage, lower=False, check_finite=False)
    except linalg.LinAlgError:
        return None
    return factor, order
