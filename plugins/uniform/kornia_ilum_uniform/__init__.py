"""kornia_ilum plugin ``uniform``: constant lighting from the mean face colour and an assumed skin albedo.

Registered with kornia_ilum through the entry point ``uniform = "kornia_ilum_uniform:UniformEstimator"``
(group ``kornia_ilum.estimators``); use it as ``kornia_ilum.estimators.create_estimator("uniform")``.
"""

from kornia_ilum_uniform.estimator import (
    CLIP_THRESHOLD,
    DARK_THRESHOLD,
    LIGHTING_SIZE,
    SKIN_ALBEDO,
    UniformEstimator,
    face_ellipse,
    uniform_lighting,
)

__version__ = "0.1.0.dev0"

__all__ = [
    "__version__",
    "SKIN_ALBEDO",
    "CLIP_THRESHOLD",
    "DARK_THRESHOLD",
    "LIGHTING_SIZE",
    "face_ellipse",
    "uniform_lighting",
    "UniformEstimator",
]
