"""Spherical harmonics (order 2) of lighting, and converters to other SH layouts (DECA, ARCore, WebXR)."""

from kornia_ilum.sh.harmonics import (
    LAYOUTS,
    SH_CONSTANTS,
    SH_IRRADIANCE_FACTORS,
    SHIrradiance,
    SHIrradianceAt,
    SHProject,
    SHReconstruct,
    sh_basis,
    sh_irradiance,
    sh_irradiance_at,
    sh_project,
    sh_reconstruct,
)
from kornia_ilum.sh.layouts import (
    sh_from_arcore,
    sh_from_deca,
    sh_from_webxr,
    sh_to_arcore,
    sh_to_deca,
    sh_to_webxr,
)

__all__ = [
    "LAYOUTS",
    "SH_CONSTANTS",
    "SH_IRRADIANCE_FACTORS",
    "SHIrradiance",
    "SHIrradianceAt",
    "SHProject",
    "SHReconstruct",
    "sh_basis",
    "sh_irradiance",
    "sh_irradiance_at",
    "sh_project",
    "sh_reconstruct",
    "sh_from_arcore",
    "sh_from_deca",
    "sh_from_webxr",
    "sh_to_arcore",
    "sh_to_deca",
    "sh_to_webxr",
]
