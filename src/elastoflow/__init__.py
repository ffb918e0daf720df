"""elastoflow: fast two-way coupling of incompressible fluid and elastic bodies.

Implements Imamura, Harada & Kawaguchi, *Fast Coupling of Fluid and Deformable Bodies using
Boundary Mapping*: a MAC-grid stable-fluids solver, explicit FEM triangle meshes, and a boundary
map built from the bodies' boundary edges that classifies grid points, imposes cut-distance
boundary conditions and gives the fluid-to-solid force.
"""

__version__ = "0.1.0"
