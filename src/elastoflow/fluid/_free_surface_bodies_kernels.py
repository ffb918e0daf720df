"""Numba kernels of the free surface with bodies in it: the pressure operator with both the
bodies' open face fractions and the surface's ghost-fluid terms, the gradient that goes with
it, and the level set carried across the bodies.

Index conventions are those of `elastoflow.grid` and `elastoflow.fluid._level_set_kernels`:
``phi`` in the cells (nx, ny), liquid where ``phi < 0``; u on x-faces (nx+1, ny), v on y-faces
(nx, ny+1); open fractions on the faces, as in `elastoflow.fluid.InteriorBoundary`.
"""

from __future__ import annotations

from numba import njit

from elastoflow.fluid._kernels import _open
from elastoflow.fluid._level_set_kernels import _face_gradient, interface_fraction


@njit(cache=True)
def build_cut_free_surface_operator(phi, open_x, open_y, theta_min, diagonal, weights_x,
                                    weights_y):
    """Pressure operator of a liquid with a free surface around bodies: ``A p = -h^2
    div(A grad p)`` on the liquid cells.

    A face between two liquid cells has its open fraction ``A`` as weight (Batty et al. 2007);
    a liquid cell next to an air cell gets ``A / theta`` on its diagonal (p = 0 at the
    surface, a fraction theta of the spacing away, Gibou et al. 2002) through a face whose
    open part is ``A``; closed faces (``A`` below the fluid's floor) carry nothing; air cells
    are inactive; domain sides are walls. Symmetric, diagonally dominant; with ``A = 1``
    everywhere it is `build_free_surface_operator`'s operator.
    """
    nx, ny = phi.shape
    for i in range(nx):
        for j in range(ny):
            diagonal[i, j] = 0.0
            if i + 1 < nx:
                weights_x[i, j] = 0.0
            if j + 1 < ny:
                weights_y[i, j] = 0.0
    for i in range(nx):
        for j in range(ny):
            here = phi[i, j]
            if here >= 0.0:
                continue
            d = 0.0
            if i + 1 < nx:
                a = _open(open_x[i + 1, j])
                if a > 0.0:
                    if phi[i + 1, j] < 0.0:
                        weights_x[i, j] = a
                    else:
                        d += a / interface_fraction(here, phi[i + 1, j], theta_min)
            if i > 0 and phi[i - 1, j] >= 0.0:
                a = _open(open_x[i, j])
                if a > 0.0:
                    d += a / interface_fraction(here, phi[i - 1, j], theta_min)
            if j + 1 < ny:
                a = _open(open_y[i, j + 1])
                if a > 0.0:
                    if phi[i, j + 1] < 0.0:
                        weights_y[i, j] = a
                    else:
                        d += a / interface_fraction(here, phi[i, j + 1], theta_min)
            if j > 0 and phi[i, j - 1] >= 0.0:
                a = _open(open_y[i, j])
                if a > 0.0:
                    d += a / interface_fraction(here, phi[i, j - 1], theta_min)
            diagonal[i, j] = d


@njit(cache=True)
def subtract_cut_free_surface_gradient(u, v, p, phi, open_x, open_y, closed_u, closed_v, k,
                                       theta_min, valid_u, valid_v):
    """``u -= (dt / rho) grad p`` on the open faces with liquid on a side (ghost pressure 0 at
    the surface), ``u = closed_u`` on closed faces; ``k = dt / (rho h)``.

    Marks ``valid_u`` / ``valid_v`` (int32) 1 on the faces solved, the closed faces with liquid
    on a side (they hold the bodies' velocity) and the wall faces of liquid cells; 0 on the
    faces that the extrapolation into the air fills: closed faces in the air too, so that the
    air beside a body moves with the liquid below it, not with the body (with the body's
    velocity there, the surface was dragged up a heaving box's sides until water spilled onto
    its top). Wall faces keep their values.
    """
    nx, ny = phi.shape
    for i in range(nx + 1):
        for j in range(ny):
            if i == 0 or i == nx:
                cell = 0 if i == 0 else nx - 1
                valid_u[i, j] = 1 if phi[cell, j] < 0.0 else 0
                continue
            if _open(open_x[i, j]) == 0.0:
                u[i, j] = closed_u[i, j]
                valid_u[i, j] = 1 if (phi[i - 1, j] < 0.0 or phi[i, j] < 0.0) else 0
                continue
            gradient, solved = _face_gradient(p[i - 1, j], p[i, j], phi[i - 1, j], phi[i, j],
                                              0.0, 0.0, theta_min)
            if solved:
                u[i, j] -= k * gradient
                valid_u[i, j] = 1
            else:
                valid_u[i, j] = 0
    for i in range(nx):
        for j in range(ny + 1):
            if j == 0 or j == ny:
                cell = 0 if j == 0 else ny - 1
                valid_v[i, j] = 1 if phi[i, cell] < 0.0 else 0
                continue
            if _open(open_y[i, j]) == 0.0:
                v[i, j] = closed_v[i, j]
                valid_v[i, j] = 1 if (phi[i, j - 1] < 0.0 or phi[i, j] < 0.0) else 0
                continue
            gradient, solved = _face_gradient(p[i, j - 1], p[i, j], phi[i, j - 1], phi[i, j],
                                              0.0, 0.0, theta_min)
            if solved:
                v[i, j] -= k * gradient
                valid_v[i, j] = 1
            else:
                valid_v[i, j] = 0


@njit(cache=True)
def extend_level_set(phi, unknown, known, fresh):
    """Replace ``phi`` on the ``unknown`` cells (bool, (nx, ny)) layer by layer from the known
    ones: each cell of the next layer takes the mean of its known neighbours' values (a
    constant extension along the layers, so each part of a body holds the value just
    outside its nearest face). ``known`` / ``fresh``: int8 scratch (nx, ny). Returns the
    cells left unknown (none reached: no known cell in their component)."""
    nx, ny = phi.shape
    remaining = 0
    for i in range(nx):
        for j in range(ny):
            known[i, j] = 0 if unknown[i, j] else 1
            remaining += 1 - known[i, j]
    while remaining > 0:
        added = 0
        for i in range(nx):
            for j in range(ny):
                fresh[i, j] = 0
                if known[i, j]:
                    continue
                total = 0.0
                count = 0
                for di, dj in ((-1, 0), (1, 0), (0, -1), (0, 1)):
                    ia, ja = i + di, j + dj
                    if 0 <= ia < nx and 0 <= ja < ny and known[ia, ja]:
                        total += phi[ia, ja]
                        count += 1
                if count > 0:
                    phi[i, j] = total / count
                    fresh[i, j] = 1
                    added += 1
        if added == 0:
            break
        for i in range(nx):
            for j in range(ny):
                if fresh[i, j]:
                    known[i, j] = 1
        remaining -= added
    return remaining


@njit(cache=True)
def fluid_fractions(open_x, open_y, out):
    """Each cell's fluid fraction [-], the mean of its four faces' open fractions, into
    ``out`` (nx, ny): 1 away from bodies, 0 inside one."""
    nx, ny = out.shape
    for i in range(nx):
        for j in range(ny):
            out[i, j] = 0.25 * (min(open_x[i, j], 1.0) + min(open_x[i + 1, j], 1.0)
                                + min(open_y[i, j], 1.0) + min(open_y[i, j + 1], 1.0))


@njit(cache=True)
def weighted_liquid_area(phi, weights, h):
    """``sum weights * clamp(1/2 - phi / h, 0, 1) h^2`` [m^2] (the water outside bodies when
    ``weights`` are the fluid fractions) and the weight of the cells on the ramp."""
    nx, ny = phi.shape
    total = 0.0
    ramp = 0.0
    for i in range(nx):
        for j in range(ny):
            fraction = 0.5 - phi[i, j] / h
            if fraction >= 1.0:
                total += weights[i, j]
            elif fraction > 0.0:
                total += weights[i, j] * fraction
                ramp += weights[i, j]
    return total * h * h, ramp
