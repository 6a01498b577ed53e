"""Lighting errors: the sphere-render loss ``L_rec``, relative radiance, the lighting's energy, and the
three-sphere protocol."""

from kornia_ilum.metrics.lighting import (
    LightingEnergy,
    MultiscaleReconstructionLoss,
    ReconstructionLoss,
    RelativeRadiance,
    TotalRadiance,
    check_lighting_pair,
    lighting_energy,
    multiscale_reconstruction_loss,
    reconstruction_loss,
    relative_radiance,
    total_radiance,
)
from kornia_ilum.metrics.protocol import (
    METRICS,
    ThreeSphereMetrics,
    TonemapStylelight,
    three_sphere_metrics,
    tonemap_stylelight,
)

__all__ = [
    "METRICS",
    "LightingEnergy",
    "MultiscaleReconstructionLoss",
    "ReconstructionLoss",
    "RelativeRadiance",
    "ThreeSphereMetrics",
    "TonemapStylelight",
    "TotalRadiance",
    "check_lighting_pair",
    "lighting_energy",
    "multiscale_reconstruction_loss",
    "reconstruction_loss",
    "relative_radiance",
    "three_sphere_metrics",
    "tonemap_stylelight",
    "total_radiance",
]
