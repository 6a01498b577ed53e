"""kornia_ilum: HDR lighting from one LDR portrait, with Kornia-style differentiable ops.

Implements "Learning Illumination from Diverse Portraits" (LeGendre et al., SIGGRAPH Asia 2020).
The conventions (frame, mirror-ball and lat-long mappings, units, reference spheres) are in
``docs/conventions.rst``.
"""

__version__ = "0.1.0.dev0"

from kornia_ilum import color, core, detection, estimators, filters, geometry, io, metrics, render, sh
from kornia_ilum.api import estimate_lighting
from kornia_ilum.estimators import create_estimator, list_estimators

__all__ = [
    "__version__",
    "estimate_lighting",
    "create_estimator",
    "list_estimators",
    "color",
    "core",
    "detection",
    "estimators",
    "filters",
    "geometry",
    "io",
    "metrics",
    "render",
    "sh",
]
