"""The force on what a box of whole cells holds, from the fluid's momentum balance.

``F = -d/dt int_V rho u dV - oint_S (rho u (u.n) - sigma n) dS + int_V rho g dV``,
``sigma = -p I + mu (grad u + grad u^T)``, over a box whose sides run along cell faces away
from every body: every value on the sides is read from the regular grid, no cut cell enters
it. Taken with the time derivative the fluid's step takes, this is the scheme's own force on
the obstacles inside, whatever the box (DFG 2D-2 at 20 cells per diameter with BDF2: c_L max
1.0334 / 1.0326 / 1.0277 / 1.0319 on boxes reaching 0.75 / 1 / 1.5 / 1.9 diameters from the
cylinder's centre); the traction integral on the outline reads the lift 7 % lower there
(docs/validation/unsteady.md). Finite-element studies use the same idea where the surface
integral is in doubt: a volume integral of the momentum equation against a function equal to
1 on the body, instead of the stress on its surface.

The box's momentum counts every face in it whose both sides are inside the box (faces on the
box's sides count half), the faces inside static obstacles included: they hold the
obstacle's velocity, zero, and add nothing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from elastoflow.grid import Grid2D


@dataclass(frozen=True)
class BoxCells:
    """A box of whole cells: columns ``i0..i1 - 1`` and rows ``j0..j1 - 1`` (its sides on the
    x faces ``i0``, ``i1`` and the y faces ``j0``, ``j1``)."""

    i0: int
    i1: int
    j0: int
    j1: int

    @classmethod
    def around(cls, grid: Grid2D, lower: tuple[float, float], upper: tuple[float, float]
               ) -> BoxCells:
        """The box whose sides are the face lines nearest ``lower`` and ``upper`` [m],
        clipped to one cell inside the domain (the side fluxes read one face beyond)."""
        h = grid.h
        ox, oy = (float(c) for c in grid.origin)
        return cls(max(1, int(round((lower[0] - ox) / h))),
                   min(grid.nx - 1, int(round((upper[0] - ox) / h))),
                   max(1, int(round((lower[1] - oy) / h))),
                   min(grid.ny - 1, int(round((upper[1] - oy) / h))))

    def bounds(self, grid: Grid2D) -> tuple[float, float, float, float]:
        """``(x0, y0, x1, y1)`` [m]."""
        h = grid.h
        ox, oy = (float(c) for c in grid.origin)
        return (ox + self.i0 * h, oy + self.j0 * h, ox + self.i1 * h, oy + self.j1 * h)


class MomentumBalance:
    """The force [N/m] on what ``box`` holds, after each step (see the module).

    Call `force` after every step, in order: it keeps the box's momentum of the last two
    steps for the time derivative. With ``bdf2`` (the fluid solver's
    ``viscosity_scheme="bdf2"``, which advances the whole step by BDF2) the derivative is
    ``(3 P^{n+1} - 4 P^n + P^{n-1}) / (2 dt)`` where the last two steps had one length (the
    solver's own condition), else ``(P^{n+1} - P^n) / dt``, as backward Euler and
    Crank-Nicolson steps take it. Taking the two-level difference after BDF2 steps leaves an
    error of ``dt / 2`` times the second derivative of the box's momentum, which grows with
    the box: DFG 2D-2's c_L max read 1.0304 / 1.0316 / 1.0515 / 1.0733 on the boxes above.

    Args:
        grid: The MAC grid.
        box: The control volume's cells.
        density: rho [kg/m^3]; viscosity: nu [m^2/s].
        bdf2: Whether the fluid's steps are BDF2.
        gravity: The fluid's acceleration of gravity [m/s^2], counted on the fluid faces
            (`force`'s ``solid_faces``).
    """

    def __init__(self, grid: Grid2D, box: BoxCells, density: float, viscosity: float, *,
                 bdf2: bool = False, gravity: tuple[float, float] = (0.0, 0.0)) -> None:
        if not (1 <= box.i0 < box.i1 <= grid.nx - 1 and 1 <= box.j0 < box.j1 <= grid.ny - 1):
            raise ValueError(f"box cells {box}: must hold a cell and keep one cell from the "
                             f"edges of the {grid.nx} x {grid.ny} grid")
        self.grid = grid
        self.box = box
        self.density = float(density)
        self.viscosity = float(viscosity)
        self.bdf2 = bdf2
        b = box
        weights_x = np.zeros(grid.shape_faces_x)
        weights_x[b.i0:b.i1 + 1, b.j0:b.j1] = 1.0
        weights_x[[b.i0, b.i1], b.j0:b.j1] = 0.5
        weights_y = np.zeros(grid.shape_faces_y)
        weights_y[b.i0:b.i1, b.j0:b.j1 + 1] = 1.0
        weights_y[b.i0:b.i1, [b.j0, b.j1]] = 0.5
        self._weights = (weights_x, weights_y)
        self.gravity = (float(gravity[0]), float(gravity[1]))
        self._levels: list[tuple[float, float]] = []
        self._steps: list[float] = []

    def momentum(self, u: np.ndarray, v: np.ndarray) -> tuple[float, float]:
        """``int_V rho u dV`` (x, y) [kg m/s per m]."""
        area = self.density * self.grid.h * self.grid.h
        return (area * float(np.sum(self._weights[0] * u)),
                area * float(np.sum(self._weights[1] * v)))

    def fluxes(self, u: np.ndarray, v: np.ndarray, p: np.ndarray) -> tuple[float, float]:
        """``oint_S (rho u (u.n) - sigma n) dS`` (x, y) [N/m]."""
        b, h = self.box, self.grid.h
        i0, i1, j0, j1 = b.i0, b.i1, b.j0, b.j1
        rho, mu = self.density, self.density * self.viscosity
        fx = fy = 0.0
        rows = slice(j0, j1)
        for i, sign in ((i1, 1.0), (i0, -1.0)):
            un = u[i, rows]
            # v at the face centres (i h, (j + 1/2) h): four neighbours.
            vc = 0.25 * (v[i - 1, j0:j1] + v[i, j0:j1] + v[i - 1, j0 + 1:j1 + 1]
                         + v[i, j0 + 1:j1 + 1])
            pc = 0.5 * (p[i - 1, rows] + p[i, rows])
            dudx = (u[i + 1, rows] - u[i - 1, rows]) / (2.0 * h)
            dudy = (u[i, j0 + 1:j1 + 1] - u[i, j0 - 1:j1 - 1]) / (2.0 * h)
            dvdx = 0.5 * ((v[i, j0:j1] - v[i - 1, j0:j1])
                          + (v[i, j0 + 1:j1 + 1] - v[i - 1, j0 + 1:j1 + 1])) / h
            fx += sign * h * float(np.sum(rho * un * un + pc - 2.0 * mu * dudx))
            fy += sign * h * float(np.sum(rho * un * vc - mu * (dudy + dvdx)))
        columns = slice(i0, i1)
        for j, sign in ((j1, 1.0), (j0, -1.0)):
            vn = v[columns, j]
            uc = 0.25 * (u[i0:i1, j - 1] + u[i0:i1, j] + u[i0 + 1:i1 + 1, j - 1]
                         + u[i0 + 1:i1 + 1, j])
            pc = 0.5 * (p[columns, j - 1] + p[columns, j])
            dvdy = (v[columns, j + 1] - v[columns, j - 1]) / (2.0 * h)
            dvdx = (v[i0 + 1:i1 + 1, j] - v[i0 - 1:i1 - 1, j]) / (2.0 * h)
            dudy = 0.5 * ((u[i0:i1, j] - u[i0:i1, j - 1])
                          + (u[i0 + 1:i1 + 1, j] - u[i0 + 1:i1 + 1, j - 1])) / h
            fx += sign * h * float(np.sum(rho * uc * vn - mu * (dudy + dvdx)))
            fy += sign * h * float(np.sum(rho * vn * vn + pc - 2.0 * mu * dvdy))
        return fx, fy

    def start(self, momenta: list[tuple[float, float]], dt: float | None = None) -> None:
        """Begin from known momenta of the last steps, oldest first (a resumed run: the
        state's previous and current velocity), the steps between them ``dt`` long."""
        self._levels = list(momenta)[-2:]
        self._steps = [float(dt)] if dt is not None and len(self._levels) == 2 else []

    def weight(self, solid_faces: tuple[np.ndarray, np.ndarray] | None) -> tuple[float, float]:
        """Gravity on the box's fluid [N/m]: on its faces less ``(x, y)`` solid ones."""
        if self.gravity == (0.0, 0.0):
            return 0.0, 0.0
        mass = self.density * self.grid.h * self.grid.h
        weights = self._weights
        if solid_faces is not None:
            weights = (np.where(solid_faces[0], 0.0, weights[0]),
                       np.where(solid_faces[1], 0.0, weights[1]))
        return (mass * self.gravity[0] * float(weights[0].sum()),
                mass * self.gravity[1] * float(weights[1].sum()))

    def force(self, u: np.ndarray, v: np.ndarray, p: np.ndarray, dt: float,
              solid_faces: tuple[np.ndarray, np.ndarray] | None = None
              ) -> tuple[float, float]:
        """The force [N/m] on what the box holds after a step of ``dt`` to these fields; NaN
        when no momentum before the step is known (the first call only records it).
        ``solid_faces``: the faces inside obstacles, where gravity does not act on fluid."""
        momentum = self.momentum(u, v)
        levels, steps = self._levels, self._steps
        self._levels = (levels + [momentum])[-2:]
        self._steps = (steps + [float(dt)])[-1:] if levels else []
        if not levels:
            return math.nan, math.nan
        previous = levels[-1]
        if self.bdf2 and len(levels) == 2 and steps and steps[-1] == dt:
            before = levels[0]
            rate = [(3.0 * momentum[k] - 4.0 * previous[k] + before[k]) / (2.0 * dt)
                    for k in range(2)]
        else:
            rate = [(momentum[k] - previous[k]) / dt for k in range(2)]
        flux = self.fluxes(u, v, p)
        weight = self.weight(solid_faces)
        return -rate[0] - flux[0] + weight[0], -rate[1] - flux[1] + weight[1]
