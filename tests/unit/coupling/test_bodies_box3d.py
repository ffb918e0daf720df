"""Work limited to the bodies' box (`bodies_box_3d`, `InteriorBoundary3D.box`) gives exactly
what the whole grid gives: refilled cut distances, the viscosity operator rewritten around the
bodies only."""

from __future__ import annotations

import numpy as np
from coupling_surfaces import icosphere

from elastoflow.coupling import build_boundary_map_3d
from elastoflow.coupling._interior3d import interior_boundary_3d
from elastoflow.coupling._map3d import bodies_box_3d
from elastoflow.fluid._boundaries import Inflow
from elastoflow.fluid._boundaries3d import DomainBoundaries3D
from elastoflow.fluid._interior3d import InteriorBoundary3D
from elastoflow.fluid._solver3d import FluidSolver3D
from elastoflow.grid import Grid3D

GRID = Grid3D(nx=20, ny=16, nz=16, h=0.1)
_FIELDS = ("solid_cells", "solid_faces_x", "solid_faces_y", "solid_faces_z",
           "velocity_faces_x", "velocity_faces_y", "velocity_faces_z", "open_fraction_x",
           "open_fraction_y", "open_fraction_z", "cut_theta_x", "cut_theta_y", "cut_theta_z",
           "cut_velocity_x", "cut_velocity_y", "cut_velocity_z")


def _interior(centre: tuple[float, float, float], radius: float,
              out: InteriorBoundary3D | None = None) -> InteriorBoundary3D:
    unit, triangles = icosphere(2)
    points = np.asarray(centre) + radius * unit
    velocities = np.cross(np.array([0.3, -1.0, 2.0]), points - np.asarray(centre))
    bmap = build_boundary_map_3d(GRID, points, velocities, triangles)
    return interior_boundary_3d(bmap, out=out)


def test_box_holds_every_body_point() -> None:
    """Outside the box every point is fluid, open (to rounding) and uncut."""
    interior = _interior((0.83, 0.61, 0.58), 0.31)
    assert interior.box is not None
    i0, j0, k0, i1, j1, k1 = interior.box
    for name in _FIELDS:
        array = getattr(interior, name)
        outside = np.ones(array.shape[-3:], dtype=np.bool_)
        outside[i0:i1, j0:j1, k0:k1] = False
        values = array[..., outside]
        if name.startswith("solid") or name.startswith("velocity") or name.startswith(
                "cut_velocity"):
            assert not values.any(), name
        elif name.startswith("open"):
            # The section areas' sums leave rounding (2e-16 seen) far from the body.
            assert (np.abs(values - 1.0) <= 1e-12).all(), name
        else:
            assert np.isinf(values).all(), name


def test_refilled_interior_equals_a_fresh_one() -> None:
    """Reusing an earlier interior's arrays (reset inside its box only) gives the fresh
    arrays bitwise, for a body that moved by more than its size and one that shrank."""
    first = _interior((0.55, 0.61, 0.58), 0.33)
    for centre, radius in (((1.31, 0.83, 0.9), 0.25), ((0.52, 0.6, 0.6), 0.2)):
        fresh = _interior(centre, radius)
        reused = _interior(centre, radius, out=first)
        for name in _FIELDS:
            np.testing.assert_array_equal(getattr(reused, name), getattr(fresh, name), name)
        assert reused.box == fresh.box
        first = reused


def test_empty_map_has_an_empty_box() -> None:
    bmap = build_boundary_map_3d(GRID, np.zeros((0, 3)), np.zeros((0, 3)),
                                 np.zeros((0, 3), dtype=np.int64))
    assert bodies_box_3d(bmap) == (0, 0, 0, 0, 0, 0)


def test_viscosity_operator_rewritten_around_the_bodies_equals_a_fresh_one() -> None:
    """The second call with bodies rewrites only the old and new boxes: operator and
    right-hand side equal those of a solver that never saw the first body."""
    boundaries = DomainBoundaries3D.channel(Inflow(1.0, profile="parabolic"))
    rng = np.random.default_rng(3)
    first = _interior((0.55, 0.61, 0.58), 0.33)
    second = _interior((1.31, 0.83, 0.9), 0.25)
    kept = FluidSolver3D(GRID, density=1.0, viscosity=0.01, boundaries=boundaries)
    fresh = FluidSolver3D(GRID, density=1.0, viscosity=0.01, boundaries=boundaries)
    for axis, shape in enumerate((GRID.shape_faces_x, GRID.shape_faces_y,
                                  GRID.shape_faces_z)):
        field = rng.standard_normal(shape)
        kept.viscosity_system(field, axis, 0.05, first)
        operator, rhs = kept.viscosity_system(field, axis, 0.05, second)
        rhs = rhs.copy()
        expected, expected_rhs = fresh.viscosity_system(field, axis, 0.05, second)
        np.testing.assert_array_equal(rhs, expected_rhs)
        for name in ("diagonal", "weights_x", "weights_y", "weights_z"):
            np.testing.assert_array_equal(getattr(operator, name), getattr(expected, name))
