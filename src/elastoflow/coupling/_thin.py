"""Bodies thinner than a cell: the pressure connections they cut (docs/method_notes.md item 4).

The projection has one pressure per cell and weighs each face by the open part of the segment
of length h through it. A body thinner than a cell that lies between two face lines cuts no
face segment, so both of its sides share one pressure and the fluid flows through it. The
map knows where such a body crosses the lines through the cell centres, which are the
segments between pressure samples:

* **Thin chord.** On a line through cell centres (an x-map row ``J = 2j+1`` or a y-map column
  ``I = 2i+1``) a chord is a maximal interval of non-zero winding; it is thin when it is
  shorter than 1.9 cells (`THIN_CHORD_CELLS`). Its midpoint ``m`` stands for the body's
  mid-line on that line.
* **Rule 1 (the mid-line crosses a connection).** The connection between the two cell centres
  on either side of ``m`` (``c_{k-1} < m <= c_k``, through face ``k``, the face line nearest
  ``m``) is cut: the face gets open fraction 0 and carries the whole face's flux at the body
  velocity at ``m`` (the mean of the chord's two crossings, exact for affine motion). A
  centre inside the chord stays connected to the side away from ``m`` only.
* **Rule 3 (the mid-line runs along a line).** Where thin chords on two neighbouring centre
  lines cut faces one apart (``k`` and ``k + 1``), the mid-line passes between the two
  centres of the cell column they share (``min(k)``), on the line across, where no crossing
  shows it: that connection is cut as well, at the mean velocity of the two chords'
  midpoints. Only pairs whose midpoints lie within h of each other count (a body closer to
  the other axis is cut by Rule 1 on that axis).
* **Tips are not thin.** A short chord is also where a centre line grazes the top of a round
  body or passes near the corner of a thick one. There the body's outline crosses the face
  segments, the open fractions already say how much of the connection is left, and the fluid
  on both sides of the tip is one region anyway. A thin chord is a tip, and is left alone,
  when the body widens on one side of its centre line and ends or narrows to less than half
  on the other: on one of the two face lines beside it (``J = 2j`` and ``2j+2``) a longer
  chord lies within h of it, on the other none or one less than half as long. The end of a
  plate (as long on one side, nothing on the other), the root of a fin on a thick body (as
  long on one side, longer on the other), a neck (longer on both sides) and a slowly
  tapering blade are cut.

The cut set contains every connection that the mid-line of a thin part crosses, so the two
sides of a thin body share no path in the pressure graph; the operator stays symmetric with
non-negative weights (only weights are set to 0). Bodies two cells thick or more (every chord
on a centre line at least 1.9 h long, tips aside) get no cut and are treated exactly as
before. The same cuts enter the strongly coupled scheme's ``W`` (`interface_flux`), so that
the projection and the body forces stay transposes of each other.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from elastoflow.coupling._map import BoundaryMap
from elastoflow.grid import Grid2D

# A chord shorter than this many cells is thin. One cell is not enough: a body between one and
# two cells thick along a line and tilted against it leaves one cell centre inside it with
# partly open faces on both of its sides (the cut-cell fractions), and the fluid passes
# through that cell (20 % of the swept flux for a plate 1 h thick at 15 degrees, 4 % for
# 1.2 h at 30 degrees, with one cell as the limit). Just under two cells, so that a body
# exactly two cells thick (a common flag) is not cut or left alone by round-off.
THIN_CHORD_CELLS = 1.9
# Chords on a face line longer than the centre line's by less than this (in cells) are as long:
# the two sides of a plate give equal chords up to round-off.
CAP_ROUND_OFF = 0.01


@dataclass(frozen=True, eq=False)
class ThinCuts:
    """Faces whose pressure connection a body thinner than a cell cuts (module docstring).

    Index space ``F``: one entry per cut face, each face once.

    Attributes:
        axis: 0 for a u face (x-face), 1 for a v face, int8, shape (F,).
        i: The face's first index (u face ``(i, j)`` of shape (nx+1, ny), v face ``(i, j)``
            of shape (nx, ny+1)), int64, shape (F,).
        j: The face's second index, int64, shape (F,).
        source: 0 when ``entries`` index the x-map's entry arrays, 1 the y-map's, int8,
            shape (F,).
        entries: The map entries (crossings) whose velocities give the body velocity on the
            face, int64, shape (F, 4); -1 where unused.
        weights: Weight of each entry, summing to 1 per face, shape (F, 4).
    """

    axis: np.ndarray
    i: np.ndarray
    j: np.ndarray
    source: np.ndarray
    entries: np.ndarray
    weights: np.ndarray

    @property
    def count(self) -> int:
        """Number of cut faces F."""
        return int(self.axis.shape[0])

    def velocities(self, bmap: BoundaryMap) -> np.ndarray:
        """Body velocity component normal to each face [m/s] (x for u faces, y for v faces),
        shape (F,)."""
        out = np.zeros(self.count)
        for source, velocity in ((0, bmap.x_velocity), (1, bmap.y_velocity)):
            for k in range(4):
                rows = np.flatnonzero((self.source == source) & (self.entries[:, k] >= 0))
                if rows.size:
                    component = self.axis[rows].astype(np.int64)
                    out[rows] += self.weights[rows, k] * velocity[self.entries[rows, k],
                                                                  component]
        return out


@njit(cache=True)
def _longest_near(offsets: np.ndarray, coordinate: np.ndarray, sign: np.ndarray, line: int,
                  low: float, high: float) -> float:
    """Length of the longest chord of ``line`` that overlaps [low, high]: ``inf`` for one that
    never closes (an open chain leaving the line), -1 when none does."""
    longest = -1.0
    winding = 0
    start = 0.0
    for c in range(offsets[line], offsets[line + 1]):
        before = winding
        winding += sign[c]
        if before == 0 and winding != 0:
            start = coordinate[c]
        elif before != 0 and winding == 0 and coordinate[c] >= low and start <= high:
            longest = max(longest, coordinate[c] - start)
    if winding != 0 and start <= high:
        longest = math.inf
    return longest


@njit(cache=True)
def _is_cap(below: float, above: float, length: float, h: float) -> bool:
    """A chord of ``length`` whose neighbouring face lines hold chords of ``below`` and
    ``above`` (`_longest_near`) is the tip of a body that widens on one side: longer there,
    absent or less than half as long on the other."""
    widens_below = below > length + CAP_ROUND_OFF * h
    widens_above = above > length + CAP_ROUND_OFF * h
    return (widens_below and above < 0.5 * length) or (widens_above and below < 0.5 * length)


@njit(cache=True)
def _family_cuts(offsets: np.ndarray, coordinate: np.ndarray, sign: np.ndarray,
                 line_count: int, point_count: int, origin_along: float, h: float,
                 out_line: np.ndarray, out_face: np.ndarray, out_rule: np.ndarray,
                 out_entries: np.ndarray, out_weights: np.ndarray) -> int:
    """Rules 1 and 3 along one family of centre lines (``line_count`` of them, centres
    ``origin_along + (k + 1/2) h``, ``k < point_count``). Writes, per cut, the line index
    across (``out_line``), the face index along (``out_face``), the rule (1: a face along the
    lines, 3: a face across them) and its entries; returns the number of cuts."""
    total = offsets[offsets.shape[0] - 1]
    chord_line = np.empty(total, np.int64)
    chord_face = np.empty(total, np.int64)
    chord_start = np.empty(total, np.int64)
    chord_end = np.empty(total, np.int64)
    chord_middle = np.empty(total)
    chord_count = 0
    cut = 0
    thin = THIN_CHORD_CELLS * h
    for l in range(line_count):
        line = 2 * l + 1
        winding = 0
        start = -1
        for c in range(offsets[line], offsets[line + 1]):
            before = winding
            winding += sign[c]
            if before == 0 and winding != 0:
                start = c
                continue
            if before == 0 or winding != 0:
                continue
            a = coordinate[start]
            b = coordinate[c]
            if b - a >= thin:
                continue
            below = _longest_near(offsets, coordinate, sign, line - 1, a - h, b + h)
            above = _longest_near(offsets, coordinate, sign, line + 1, a - h, b + h)
            if _is_cap(below, above, b - a, h):
                continue
            middle = 0.5 * (a + b)
            face = math.ceil((middle - origin_along) / h - 0.5)
            chord_line[chord_count] = l
            chord_face[chord_count] = face
            chord_start[chord_count] = start
            chord_end[chord_count] = c
            chord_middle[chord_count] = middle
            chord_count += 1
            if 1 <= face <= point_count - 1:
                out_line[cut] = l
                out_face[cut] = face
                out_rule[cut] = 1
                out_entries[cut, 0] = start
                out_entries[cut, 1] = c
                out_weights[cut, 0] = 0.5
                out_weights[cut, 1] = 0.5
                cut += 1
    # Rule 3: chords are in line order, so those of line l + 1 follow those of line l.
    first_of_next = 0
    for p in range(chord_count):
        l = chord_line[p]
        while first_of_next < chord_count and chord_line[first_of_next] <= l:
            first_of_next += 1
        for q in range(first_of_next, chord_count):
            if chord_line[q] != l + 1:
                break
            if abs(chord_face[p] - chord_face[q]) != 1:
                continue
            if abs(chord_middle[p] - chord_middle[q]) > h:
                continue
            shared = min(chord_face[p], chord_face[q])
            if shared < 0 or shared > point_count - 1:
                continue
            out_line[cut] = l + 1
            out_face[cut] = shared
            out_rule[cut] = 3
            out_entries[cut, 0] = chord_start[p]
            out_entries[cut, 1] = chord_end[p]
            out_entries[cut, 2] = chord_start[q]
            out_entries[cut, 3] = chord_end[q]
            for k in range(4):
                out_weights[cut, k] = 0.25
            cut += 1
    return cut


def thin_cuts(grid: Grid2D, bmap: BoundaryMap) -> ThinCuts:
    """The connections cut by bodies thinner than a cell (module docstring).

    Cost: the crossings of the lines through cell centres, plus those of the neighbouring
    face lines for each thin chord. A map without such chords gives no cut.

    Args:
        grid: The MAC grid.
        bmap: The boundary map of that grid.

    Returns:
        The cut faces, each once; where rules meet on one face, Rule 1 of the x-map rows
        first, then Rule 1 of the y-map columns, then Rule 3.
    """
    if bmap.grid != grid:
        raise ValueError(f"boundary map grid {bmap.grid!r}: must be the grid {grid!r}")
    nx, ny, h = grid.nx, grid.ny, grid.h
    ox, oy = grid.origin
    parts = []
    # x-map rows J = 2j+1: Rule 1 cuts u faces (face, j), Rule 3 v faces (face, line).
    # y-map columns I = 2i+1: Rule 1 cuts v faces (i, face), Rule 3 u faces (line, face).
    for family, (offsets, coordinate, sign, lines, points, origin) in enumerate((
        (bmap.x_offsets, bmap.x_coordinate, bmap.x_sign, ny, nx, ox),
        (bmap.y_offsets, bmap.y_coordinate, bmap.y_sign, nx, ny, oy),
    )):
        size = int(coordinate.shape[0])
        line = np.empty(size, np.int64)
        face = np.empty(size, np.int64)
        rule = np.empty(size, np.int64)
        entries = np.full((size, 4), -1, np.int64)
        weights = np.zeros((size, 4))
        count = _family_cuts(offsets, coordinate, sign, lines, points, origin, h, line, face,
                             rule, entries, weights)
        line, face, rule = line[:count], face[:count], rule[:count]
        along_faces = rule == 1
        if family == 0:
            axis = np.where(along_faces, 0, 1)
            i, j = face, line
        else:
            axis = np.where(along_faces, 1, 0)
            i, j = line, face
        parts.append((axis, i, j, np.full(count, family), entries[:count], weights[:count],
                      np.where(along_faces, 0, 1)))
    axis = np.concatenate([p[0] for p in parts]).astype(np.int8)
    i = np.concatenate([p[1] for p in parts]).astype(np.int64)
    j = np.concatenate([p[2] for p in parts]).astype(np.int64)
    source = np.concatenate([p[3] for p in parts]).astype(np.int8)
    entries = np.concatenate([p[4] for p in parts])
    weights = np.concatenate([p[5] for p in parts])
    late = np.concatenate([p[6] for p in parts])
    if axis.shape[0] > 1:
        u_faces = (nx + 1) * ny
        flat = np.where(axis == 0, i * ny + j, u_faces + i * (ny + 1) + j)
        # Rule 1 before Rule 3, x-map before y-map; the first of each face is kept.
        order = np.lexsort((np.arange(flat.shape[0]), late, flat))
        flat = flat[order]
        keep = np.ones(flat.shape[0], dtype=bool)
        keep[1:] = flat[1:] != flat[:-1]
        chosen = order[keep]
        axis, i, j, source = axis[chosen], i[chosen], j[chosen], source[chosen]
        entries, weights = entries[chosen], weights[chosen]
    return ThinCuts(axis, i, j, source, np.ascontiguousarray(entries),
                    np.ascontiguousarray(weights))
