"""How the fluid sees the bodies: a swappable part of the coupled model.

Both treatments start from the same boundary map; they differ in the `InteriorBoundary` they
hand to the fluid (and so in what the projection, advection and viscosity see):

* `BoundaryCutCell` (the default, METHOD.md §6): open fractions of faces and cut distances
  from the map's crossings;
* `BoundaryDualCell`: as the cut cell, with each face weighted by the fluid share of its dual
  cell (Batty et al. 2007) instead of its segment, so that the weights, and the coupled
  pressure's force, change continuously as bodies move (docs/method_notes.md item 9);
* `BoundaryStaircase`: cells flagged by their centres, faces fully open or closed, no cut
  distances: the usual baseline the paper's future work names.

The forces (traction, momentum exchange) read the map in both; the strongly coupled scheme's
interface operator follows the interior it is given (`interface_flux`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Protocol

from elastoflow.coupling._classify import interior_boundary_from_map
from elastoflow.coupling._dual import interior_boundary_dual_cell
from elastoflow.coupling._map import BoundaryMap
from elastoflow.coupling._staircase import interior_boundary_staircase
from elastoflow.fluid import InteriorBoundary
from elastoflow.grid import Grid2D

BoundaryName = Literal["cut_cell", "dual_cell", "staircase"]


class BoundaryTreatment(Protocol):
    """Builds the fluid's `InteriorBoundary` from a step's boundary map."""

    @property
    def name(self) -> str:
        """The scene key's value (``coupling.boundary``)."""
        ...

    def interior(self, grid: Grid2D, bmap: BoundaryMap, *,
                 out: InteriorBoundary | None = None) -> InteriorBoundary:
        """The interior boundary of ``bmap`` on ``grid``, reusing ``out``'s arrays (the
        result of an earlier call of the same treatment) when given."""
        ...


@dataclass(frozen=True)
class BoundaryCutCell:
    """Open fractions and cut distances from the map (`interior_boundary_from_map`)."""

    name: str = "cut_cell"

    def interior(self, grid: Grid2D, bmap: BoundaryMap, *,
                 out: InteriorBoundary | None = None) -> InteriorBoundary:
        return interior_boundary_from_map(grid, bmap, out=out)


@dataclass(frozen=True)
class BoundaryDualCell:
    """Dual-cell open fractions over the cut cell's flags and cuts
    (`interior_boundary_dual_cell`)."""

    name: str = "dual_cell"

    def interior(self, grid: Grid2D, bmap: BoundaryMap, *,
                 out: InteriorBoundary | None = None) -> InteriorBoundary:
        return interior_boundary_dual_cell(grid, bmap, out=out)


@dataclass(frozen=True)
class BoundaryStaircase:
    """Cells by their centres, faces open or closed (`interior_boundary_staircase`)."""

    name: str = "staircase"

    def interior(self, grid: Grid2D, bmap: BoundaryMap, *,
                 out: InteriorBoundary | None = None) -> InteriorBoundary:
        return interior_boundary_staircase(grid, bmap, out=out)


BOUNDARY_TREATMENTS: dict[str, type[BoundaryCutCell] | type[BoundaryDualCell]
                          | type[BoundaryStaircase]] = {
    "cut_cell": BoundaryCutCell,
    "dual_cell": BoundaryDualCell,
    "staircase": BoundaryStaircase,
}
"""The treatments by their scene name."""


def boundary_treatment(name: str) -> BoundaryCutCell | BoundaryDualCell | BoundaryStaircase:
    """The treatment of a scene name ("cut_cell", "dual_cell" or "staircase")."""
    if name not in BOUNDARY_TREATMENTS:
        raise ValueError(f"boundary = {name!r}: must be one of {tuple(BOUNDARY_TREATMENTS)}")
    return BOUNDARY_TREATMENTS[name]()
