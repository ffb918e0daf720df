"""The free surface with bodies: exact identities of its operator and level-set kernels on tiny
grids (elastoflow.fluid._free_surface_bodies)."""

from __future__ import annotations

import numpy as np

from elastoflow.fluid import _free_surface_bodies_kernels as kernels
from elastoflow.fluid import _level_set_kernels as level_set_kernels


def _level_set(nx: int = 9, ny: int = 7, height: float = 3.3) -> np.ndarray:
    j = np.arange(ny)[None, :] + 0.5
    return np.ascontiguousarray(np.broadcast_to(j - height, (nx, ny)), dtype=np.float64)


def _operator(phi, open_x, open_y, build):
    nx, ny = phi.shape
    arrays = (np.zeros((nx, ny)), np.zeros((nx - 1, ny)), np.zeros((nx, ny - 1)))
    build(phi, open_x, open_y, 1e-3, *arrays) if open_x is not None else build(phi, 1e-3, *arrays)
    return arrays


def test_open_faces_give_the_free_surface_operator() -> None:
    """With every face open the operator is the liquid's own ghost-fluid operator."""
    phi = _level_set()
    phi[4, 2] = 0.2  # a bubble
    nx, ny = phi.shape
    ones_x, ones_y = np.ones((nx + 1, ny)), np.ones((nx, ny + 1))
    cut = _operator(phi, ones_x, ones_y, kernels.build_cut_free_surface_operator)
    plain = _operator(phi, None, None, level_set_kernels.build_free_surface_operator)
    for a, b in zip(cut, plain):
        np.testing.assert_array_equal(a, b)


def test_open_fractions_weight_the_couplings_and_the_surface_terms() -> None:
    """A face's weight is its open fraction, towards air A / theta; closed faces carry none."""
    phi = _level_set(height=3.3)  # liquid rows 0-2, the surface 0.8 cells above row 2
    nx, ny = phi.shape
    open_x, open_y = np.ones((nx + 1, ny)), np.ones((nx, ny + 1))
    open_x[3, 1] = 0.4
    open_y[5, 3] = 0.5   # between liquid row 2 and air row 3
    open_y[6, 2] = 0.0   # closed (below the fluid's floor)
    diagonal, weights_x, weights_y = _operator(phi, open_x, open_y,
                                               kernels.build_cut_free_surface_operator)
    assert weights_x[2, 1] == 0.4
    assert weights_y[6, 1] == 0.0
    theta = phi[5, 2] / (phi[5, 2] - phi[5, 3])
    assert np.isclose(diagonal[5, 2], 0.5 / theta)
    assert np.isclose(diagonal[4, 2], 1.0 / theta)
    assert np.all(diagonal[:, 3:] == 0.0) and np.all(weights_y[:, 2:] == 0.0)


def test_level_set_carried_across_a_body_takes_each_side_s_value() -> None:
    """A body 4 cells thick between water (phi = -2 next to it) and air (phi = +1): each
    half holds the value just outside its own face, so a cell the body uncovers on the dry
    side stays air; a constant level set stays constant; a cell no outside cell reaches is
    reported."""
    nx, ny = 10, 6
    phi = np.ones((nx, ny))
    phi[:3] = -2.0
    body = np.zeros((nx, ny), dtype=np.bool_)
    body[3:7] = True
    phi[body] = 99.0
    known = np.zeros((nx, ny), dtype=np.int8)
    fresh = np.zeros((nx, ny), dtype=np.int8)
    assert kernels.extend_level_set(phi, body, known, fresh) == 0
    assert np.all(phi[3:5] == -2.0) and np.all(phi[5:7] == 1.0)
    flat = np.full((nx, ny), 0.25)
    flat[body] = 7.0
    kernels.extend_level_set(flat, body, known, fresh)
    assert np.all(flat == 0.25)
    assert kernels.extend_level_set(np.zeros((3, 3)), np.ones((3, 3), dtype=np.bool_),
                                    np.zeros((3, 3), dtype=np.int8),
                                    np.zeros((3, 3), dtype=np.int8)) == 9


def test_weighted_area_with_unit_weights_is_the_liquid_area() -> None:
    phi = _level_set(height=3.3)
    area, ramp = kernels.weighted_liquid_area(phi, np.ones(phi.shape), 0.1)
    reference, cells = level_set_kernels.liquid_area(phi, 0.1)
    assert area == reference and ramp == cells


def test_fluid_fractions_are_the_faces_mean() -> None:
    nx, ny = 3, 2
    open_x, open_y = np.ones((nx + 1, ny)), np.ones((nx, ny + 1))
    open_x[1, 0] = 0.0
    open_y[1, 0] = 0.2
    out = np.zeros((nx, ny))
    kernels.fluid_fractions(open_x, open_y, out)
    assert out[0, 0] == 0.75 and out[1, 0] == 0.25 * (0.0 + 1.0 + 0.2 + 1.0)
    assert out[2, 1] == 1.0
