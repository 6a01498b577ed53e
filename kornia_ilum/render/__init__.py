"""Image-based relighting (``I = R . L``), the three reference spheres of SPEC.md and their pyramid."""

from kornia_ilum.render.pyramid import (
    PYRAMID_SIZES,
    MirrorBallPyramid,
    mirror_ball_downsample_matrix,
    mirror_ball_pyramid,
)
from kornia_ilum.render.relight import Relight, relight
from kornia_ilum.render.spheres import (
    BRDFS,
    DIFFUSE_ALBEDO,
    GAMMA_MODES,
    MIRROR_REFLECTIVITY,
    SAFE_GAMMA_KNEE,
    SILVER_ALPHA,
    SILVER_F0,
    SPHERE_SIZES,
    RenderSpheres,
    encode_sphere,
    render_spheres,
    sphere_pyramid,
    sphere_reflectance_field,
)

__all__ = [
    "BRDFS",
    "DIFFUSE_ALBEDO",
    "GAMMA_MODES",
    "MIRROR_REFLECTIVITY",
    "PYRAMID_SIZES",
    "SAFE_GAMMA_KNEE",
    "SILVER_ALPHA",
    "SILVER_F0",
    "SPHERE_SIZES",
    "MirrorBallPyramid",
    "Relight",
    "RenderSpheres",
    "encode_sphere",
    "mirror_ball_downsample_matrix",
    "mirror_ball_pyramid",
    "relight",
    "render_spheres",
    "sphere_pyramid",
    "sphere_reflectance_field",
]
