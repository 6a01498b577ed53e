"""kornia_ilum plugin ``sipr``: a reimplementation of Sun et al. 2019, "Single Image Portrait Relighting".

Registered with kornia_ilum through the entry point ``sipr = "kornia_ilum_sipr:SIPREstimator"`` (group
``kornia_ilum.estimators``); use it as ``kornia_ilum.estimators.create_estimator("sipr")`` and train it with
``kornia-ilum train --estimator sipr`` (:class:`SIPRRecipe`).
"""

from kornia_ilum_sipr.estimator import LIGHTING_SIZE, PAPER, SIPREstimator
from kornia_ilum_sipr.network import (
    ENCODER_DEPTHS,
    LIGHTING_SHAPE,
    ConvNormAct,
    Encoder,
    LightingHead,
    RelightingDecoder,
    log_latlong_target,
    log_latlong_to_mirror_ball,
)
from kornia_ilum_sipr.recipe import (
    CROP_EXTENT,
    CROP_POSITION,
    LIGHTING_WEIGHT,
    RELIT_WEIGHT,
    SIPRRecipe,
    SIPRTrainer,
    masked_l1,
)

__version__ = "0.1.0.dev0"

__all__ = [
    "CROP_EXTENT",
    "CROP_POSITION",
    "ENCODER_DEPTHS",
    "LIGHTING_SHAPE",
    "LIGHTING_SIZE",
    "LIGHTING_WEIGHT",
    "PAPER",
    "RELIT_WEIGHT",
    "ConvNormAct",
    "Encoder",
    "LightingHead",
    "RelightingDecoder",
    "SIPREstimator",
    "SIPRRecipe",
    "SIPRTrainer",
    "__version__",
    "log_latlong_target",
    "log_latlong_to_mirror_ball",
    "masked_l1",
]
