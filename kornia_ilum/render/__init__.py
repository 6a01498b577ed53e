"""Image-based relighting (``I = R . L``) and the three reference spheres of SPEC.md."""

from kornia_ilum.render.relight import Relight, relight
from kornia_ilum.render.spheres import (
    BRDFS,
    DIFFUSE_ALBEDO,
    MIRROR_REFLECTIVITY,
    SILVER_ALPHA,
    SILVER_F0,
    SPHERE_SIZES,
    RenderSpheres,
    render_spheres,
    sphere_reflectance_field,
)

__all__ = [
    "BRDFS",
    "DIFFUSE_ALBEDO",
    "MIRROR_REFLECTIVITY",
    "SILVER_ALPHA",
    "SILVER_F0",
    "SPHERE_SIZES",
    "Relight",
    "RenderSpheres",
    "relight",
    "render_spheres",
    "sphere_reflectance_field",
]
