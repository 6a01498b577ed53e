"""kornia_ilum plugin ``sipr``: a reimplementation of Sun et al. 2019, "Single Image Portrait Relighting".

Registered with kornia_ilum through the entry point ``sipr = "kornia_ilum_sipr:SIPREstimator"`` (group
``kornia_ilum.estimators``); use it as ``kornia_ilum.estimators.create_estimator("sipr")``. Its training
recipe, :class:`SIPRRecipe`, is the entry point ``sipr = "kornia_ilum_sipr.recipe:SIPRRecipe"`` of the group
``kornia_ilum.recipes``: train it with ``kornia-ilum train --estimator sipr``.

The training names (:mod:`kornia_ilum_sipr.recipe`: :class:`SIPRRecipe`, :class:`SIPRTrainer`, ...) are
importable from here too, but load on first use, so that creating the estimator for inference never imports
the training code (:mod:`kornia_ilum_lab.train`).
"""

from typing import Any

from kornia_ilum_sipr.estimator import INPUT_SIZE, LIGHTING_SIZE, PAPER, SIPREstimator
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

__version__ = "0.1.0.dev0"

#: The names of :mod:`kornia_ilum_sipr.recipe` that this package gives on first use.
_RECIPE_NAMES = ("CROP_EXTENT", "CROP_POSITION", "LIGHTING_WEIGHT", "RELIT_WEIGHT", "SIPRRecipe", "SIPRTrainer",
                 "masked_l1")

__all__ = [
    "CROP_EXTENT",
    "CROP_POSITION",
    "ENCODER_DEPTHS",
    "INPUT_SIZE",
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


def __getattr__(name: str) -> Any:
    if name in _RECIPE_NAMES:
        from kornia_ilum_sipr import recipe  # lazy: the estimator alone must not import kornia_ilum_lab.train

        return getattr(recipe, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
