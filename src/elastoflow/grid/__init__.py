"""Uniform staggered (MAC) grid geometry and the half grid used by the boundary map.

Picture of one cell ``(i, j)`` of side ``h`` (x to the right, y up)::

        (i,j+1) v-face
     +------^------+          p[i, j]   at ((i+1/2) h, (j+1/2) h)   shape (nx, ny)
     |             |          u[i, j]   at (i h, (j+1/2) h)         shape (nx+1, ny)
     >      p      >          v[i, j]   at ((i+1/2) h, j h)         shape (nx, ny+1)
   u-face (i,j)    u-face (i+1,j)
     |             |          half grid: (I h/2, J h/2), I = 0..2nx, J = 0..2ny
     +------^------+            cell centres (odd, odd), u-faces (even, odd),
        (i,j) v-face            v-faces (odd, even), corners (even, even)

Arrays are indexed ``[i, j]`` with ``i`` along x. Positions are relative to ``origin``.
Dimension-specific geometry lives here; `Grid3D` is the 3D grid beside this one (its module
docstring has its picture: u (nx+1, ny, nz), v (nx, ny+1, nz), w (nx, ny, nz+1), p (nx, ny, nz)).
"""

from elastoflow.grid._grid import Grid2D
from elastoflow.grid._grid3d import Grid3D

__all__ = ["Grid2D", "Grid3D"]
