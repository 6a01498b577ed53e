"""Image-based relighting (``I = R . L``), the three reference spheres and their pyramid.

The spheres and the pyramid are those of docs/conventions.rst ("Reference spheres", "Multi-scale").
"""

from kornia_ilum.render.pyramid import (
    PYRAMID_SIZES,
    MirrorBallPyramid,
    mirror_ball_downsample_matrix,
    mirror_ball_pyramid,
)
from kornia_ilum.render.relight import Relight, relight, relight_product
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
    SpherePlan,
    check_brdf,
    check_sphere_lighting,
    check_sphere_sizes,
    encode_sphere,
    gamma_knee,
    render_plan,
    render_spheres,
    shared_sphere_field,
    sphere_plan,
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
    "SpherePlan",
    "check_brdf",
    "check_sphere_lighting",
    "check_sphere_sizes",
    "encode_sphere",
    "gamma_knee",
    "mirror_ball_downsample_matrix",
    "mirror_ball_pyramid",
    "relight",
    "relight_product",
    "render_plan",
    "render_spheres",
    "shared_sphere_field",
    "sphere_plan",
    "sphere_pyramid",
    "sphere_reflectance_field",
]
