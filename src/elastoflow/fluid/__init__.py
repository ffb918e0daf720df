"""Incompressible fluid on the MAC grid: state, domain boundaries, jets, solver phases."""

from elastoflow.fluid._interior import InteriorBoundary

__all__ = ["InteriorBoundary"]
