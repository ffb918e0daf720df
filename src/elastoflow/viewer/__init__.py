"""Interactive window (pygame-ce): watch a scene run, push the fluid, drag the bodies."""

from elastoflow.viewer._viewer import VIEW_CYCLE, Viewer, run_viewer

__all__ = ["VIEW_CYCLE", "Viewer", "run_viewer"]
