"""kornia_ilum plugin ``sh``: order-2 spherical-harmonics lighting from the encoder of ``ours``.

Registered with kornia_ilum through the entry point ``sh = "kornia_ilum_sh:SHEstimator"`` (group
``kornia_ilum.estimators``); use it as ``kornia_ilum.estimators.create_estimator("sh")``
(the shipped weights, see ``weights/MODEL_CARD.md``) and train it with ``kornia-ilum train --estimator sh`` (:class:`SHRecipe`).
"""

from kornia_ilum_sh.estimator import (
    INIT_RADIANCE,
    LIGHTING_SIZE,
    NUM_COEFFICIENTS,
    PAPER,
    SHEstimator,
)
from kornia_ilum_sh.recipe import NEGATIVE_PENALTY, SCALES, MultiScaleSH, SHRecipe, negative_penalty

__version__ = "0.1.0.dev0"

__all__ = [
    "INIT_RADIANCE",
    "LIGHTING_SIZE",
    "NEGATIVE_PENALTY",
    "NUM_COEFFICIENTS",
    "PAPER",
    "SCALES",
    "MultiScaleSH",
    "SHEstimator",
    "SHRecipe",
    "__version__",
    "negative_penalty",
]
