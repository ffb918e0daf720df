"""Per-node kernels of the bodies' contact with the domain's walls (`elastoflow.solid._contact`).

The walls are the sides of an axis-aligned box in d = 2 or 3 dimensions (the nodal arrays'
second axis): side 2a is x_a = lower[a], side 2a + 1 is x_a = upper[a] (left, right, bottom,
top[, back, front]); ``sides[k]`` says whether side k is a wall (inflow and outflow sides are
not). Each node is treated alone, so the result does not depend on the order or the number
of threads.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def select_held(positions: np.ndarray, velocities: np.ndarray, forces: np.ndarray,
                inverse_mass: np.ndarray, fixed_mask: np.ndarray, lower: np.ndarray,
                upper: np.ndarray, sides: np.ndarray, tolerance: float, dt: float,
                held: np.ndarray, impulse: np.ndarray) -> int:
    """Mark the node components that rest on a wall and press on it.

    Component ``a`` of node i is held when the node lies within ``tolerance`` [m] of (or
    beyond) a wall normal to axis ``a``, does not move away from it (velocity towards the
    inside <= 0) and its force (n, d) [N/m; N in 3D] pushes it into the wall (the wall's reaction is
    then compressive). ``impulse[i, a]`` receives the reaction's velocity change over ``dt``
    [m/s], ``|f_a| dt / m_i``, the normal impulse that Coulomb friction is bounded by; 0 on
    free components. Fixed nodes are never held (they are held already). Returns the number
    of held components.
    """
    count = 0
    dimension = positions.shape[1]
    for i in range(positions.shape[0]):
        for a in range(dimension):
            held[i, a] = False
            impulse[i, a] = 0.0
        if fixed_mask[i]:
            continue
        for a in range(dimension):
            x = positions[i, a]
            if (sides[2 * a] and x <= lower[a] + tolerance and velocities[i, a] <= 0.0
                    and forces[i, a] <= 0.0):
                held[i, a] = True
                impulse[i, a] = -forces[i, a] * dt * inverse_mass[i]
                count += 1
            elif (sides[2 * a + 1] and x >= upper[a] - tolerance and velocities[i, a] >= 0.0
                  and forces[i, a] >= 0.0):
                held[i, a] = True
                impulse[i, a] = forces[i, a] * dt * inverse_mass[i]
                count += 1
    return count


@njit(cache=True)
def project_onto_walls(positions: np.ndarray, velocities: np.ndarray, fixed_mask: np.ndarray,
                       impulse: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                       sides: np.ndarray, friction: float, position_weight: float) -> int:
    """Put every node back inside the walls, inelastically, with Coulomb friction.

    A node beyond a wall is moved onto it along the wall's normal and loses its velocity
    into the wall (kept when it moves away). Its tangential velocity then loses at most
    ``friction`` times the normal velocity change, that removed here plus ``impulse[i, a]``
    [m/s] (the reaction of a component held through the step), never reversing (in 3D the
    tangential velocity, a vector in the wall's plane, keeps its direction and loses at most
    that much of its length: isotropic Coulomb friction); the position follows the tangential change by ``position_weight`` [s] (the schemes pass 0:
    the velocity alone, which can only remove energy; dt/2 would keep an implicit step's
    end position consistent with its velocity). Fixed nodes are left alone.
    Returns the number of node components moved onto a wall.
    """
    moved = 0
    dimension = positions.shape[1]
    for i in range(positions.shape[0]):
        if fixed_mask[i]:
            continue
        for a in range(dimension):
            change = impulse[i, a]
            x = positions[i, a]
            if sides[2 * a] and x < lower[a]:
                positions[i, a] = lower[a]
                moved += 1
                if velocities[i, a] < 0.0:
                    change -= velocities[i, a]
                    velocities[i, a] = 0.0
            elif sides[2 * a + 1] and x > upper[a]:
                positions[i, a] = upper[a]
                moved += 1
                if velocities[i, a] > 0.0:
                    change += velocities[i, a]
                    velocities[i, a] = 0.0
            if change > 0.0 and friction > 0.0:
                if dimension == 2:
                    _rub_component(positions, velocities, i, 1 - a, friction * change,
                                   position_weight)
                else:
                    _rub_plane(positions, velocities, i, a, friction * change,
                               position_weight)
    return moved


@njit(cache=True, inline="always")
def _rub_component(positions: np.ndarray, velocities: np.ndarray, i: int, t: int,
                   largest: float, position_weight: float) -> None:
    """Friction on a 2D wall: the tangential component ``t`` of node i loses at most
    ``largest`` [m/s] of its speed, never changing sign."""
    tangential = velocities[i, t]
    reduction = min(abs(tangential), largest)
    if tangential < 0.0:
        reduction = -reduction
    velocities[i, t] = tangential - reduction
    positions[i, t] -= position_weight * reduction


@njit(cache=True, inline="always")
def _rub_plane(positions: np.ndarray, velocities: np.ndarray, i: int, normal: int,
               largest: float, position_weight: float) -> None:
    """Friction on a 3D wall normal to axis ``normal``: node i's velocity in the wall's plane
    loses at most ``largest`` [m/s] of its length, keeping its direction."""
    speed_squared = 0.0
    for b in range(3):
        if b != normal:
            speed_squared += velocities[i, b] * velocities[i, b]
    if speed_squared == 0.0:
        return
    speed = np.sqrt(speed_squared)
    share = min(speed, largest) / speed
    for b in range(3):
        if b != normal:
            reduction = share * velocities[i, b]
            velocities[i, b] -= reduction
            positions[i, b] -= position_weight * reduction


@njit(cache=True)
def near_walls(positions: np.ndarray, lower: np.ndarray, upper: np.ndarray,
               sides: np.ndarray, margin: float) -> bool:
    """Whether any node lies within ``margin`` [m] of (or beyond) a wall."""
    for i in range(positions.shape[0]):
        for a in range(positions.shape[1]):
            x = positions[i, a]
            if sides[2 * a] and x <= lower[a] + margin:
                return True
            if sides[2 * a + 1] and x >= upper[a] - margin:
                return True
    return False
