"""Interactive window (pygame-ce): watch a scene run, push the fluid, drag the bodies; a 3D
scene through a slice (`Viewer3D`)."""

from elastoflow.viewer._viewer import VIEW_CYCLE, Viewer, run_viewer
from elastoflow.viewer._viewer3d import HELP_3D, Viewer3D

__all__ = ["HELP_3D", "VIEW_CYCLE", "Viewer", "Viewer3D", "run_viewer"]
