"""Sphere geometry: mirror-ball and lat-long grids, solid angles, resampling and rotation; lat-long maps in the
conventions of Mitsuba, Blender, three.js and Unity (:func:`latlong_for_tool`).

The frame and the grids are those of docs/conventions.rst ("Frames", "Mirror ball", "Lat-long").
"""

from kornia_ilum.geometry.latlong import (
    angles_to_latlong_pixel,
    direction_to_latlong,
    latlong_angles,
    latlong_directions,
    latlong_solid_angles,
    latlong_to_direction,
)
from kornia_ilum.geometry.mirror_ball import (
    direction_to_mirror_ball,
    lights_to_mirror_ball,
    mirror_ball_directions,
    mirror_ball_pixel_index,
    mirror_ball_solid_angles,
    mirror_ball_to_direction,
    mirror_ball_to_lights,
    mirror_ball_uv,
    mirror_ball_valid,
    pixel_to_uv,
    uv_to_pixel,
)
from kornia_ilum.geometry.resample import (
    LatLongToMirrorBall,
    MirrorBallToLatLong,
    ResizeMirrorBall,
    check_layout,
    check_lighting,
    grid_overlaps,
    grid_solid_angles,
    latlong_to_mirror_ball,
    mirror_ball_to_latlong,
    resample_bilinear,
    resize_mirror_ball,
)
from kornia_ilum.geometry.tools import TOOLS, latlong_for_tool, orientation_map
from kornia_ilum.geometry.transform import (
    FlipLightingHorizontal,
    RotateLighting,
    flip_lighting_horizontal,
    rotate_lighting,
)

__all__ = [
    "TOOLS",
    "angles_to_latlong_pixel",
    "latlong_for_tool",
    "direction_to_latlong",
    "direction_to_mirror_ball",
    "latlong_angles",
    "latlong_directions",
    "latlong_solid_angles",
    "latlong_to_direction",
    "lights_to_mirror_ball",
    "mirror_ball_directions",
    "mirror_ball_pixel_index",
    "mirror_ball_solid_angles",
    "mirror_ball_to_direction",
    "mirror_ball_to_lights",
    "mirror_ball_uv",
    "mirror_ball_valid",
    "orientation_map",
    "pixel_to_uv",
    "uv_to_pixel",
    "latlong_to_mirror_ball",
    "mirror_ball_to_latlong",
    "resize_mirror_ball",
    "LatLongToMirrorBall",
    "MirrorBallToLatLong",
    "ResizeMirrorBall",
    "check_layout",
    "check_lighting",
    "grid_overlaps",
    "grid_solid_angles",
    "resample_bilinear",
    "rotate_lighting",
    "flip_lighting_horizontal",
    "RotateLighting",
    "FlipLightingHorizontal",
]
