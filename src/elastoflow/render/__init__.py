"""Frames and videos: the fluid field in colour with bodies and obstacles drawn on top.

Rendering reads the simulation's arrays and never changes them. A 3D state is drawn through a
plane (`render_slice_3d`), with the bodies' cross-sections, or in perspective with the
bodies' surfaces and the slice (`render_scene_3d`, what a 3D run's video shows). Fields are coloured through a
lookup table and bodies rasterised by small Numba kernels, so a frame costs milliseconds.
"""

from elastoflow.render._colormap import apply_colormap, colormap_lut
from elastoflow.render._fields import speed_at_cells, velocity_at_cells, vorticity_at_cells
from elastoflow.render._frame import (
    BODY_EDGE_COLOR,
    BODY_FILL_COLOR,
    OBSTACLE_FILL_COLOR,
    VIEWS,
    default_value_range,
    liquid_values,
    render_frame,
    triangle_edges,
    view_values,
)
from elastoflow.render._scene3d import (
    Camera3D,
    render_scene_3d,
    scene_camera,
    scene_orientation,
)
from elastoflow.render._slice3d import (
    AXES,
    VIEWS_3D,
    fill_segments,
    layer_values,
    render_slice_3d,
    slice_values,
    surface_section,
    surface_silhouette,
    tetrahedra_section,
)
from elastoflow.render._video import SegmentedVideo, VideoWriter, join_videos

__all__ = [
    "AXES",
    "BODY_EDGE_COLOR",
    "Camera3D",
    "BODY_FILL_COLOR",
    "OBSTACLE_FILL_COLOR",
    "VIEWS",
    "VIEWS_3D",
    "SegmentedVideo",
    "VideoWriter",
    "apply_colormap",
    "colormap_lut",
    "default_value_range",
    "fill_segments",
    "join_videos",
    "layer_values",
    "liquid_values",
    "render_frame",
    "render_scene_3d",
    "render_slice_3d",
    "scene_camera",
    "scene_orientation",
    "slice_values",
    "speed_at_cells",
    "surface_section",
    "surface_silhouette",
    "tetrahedra_section",
    "triangle_edges",
    "velocity_at_cells",
    "view_values",
    "vorticity_at_cells",
]
