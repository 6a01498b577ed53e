"""kornia_ilum plugin ``sh``: order-2 spherical-harmonics lighting from the encoder of ``ours``.

Registered with kornia_ilum through the entry point ``sh = "kornia_ilum_sh:SHEstimator"`` (group
``kornia_ilum.estimators``); use it as ``kornia_ilum.estimators.create_estimator("sh")`` (the shipped
weights, see ``weights/MODEL_CARD.md``). Its training recipe, :class:`SHRecipe`, is the entry point
``sh = "kornia_ilum_sh.recipe:SHRecipe"`` of the group ``kornia_ilum.recipes``: train it with
``kornia-ilum train --estimator sh``.

The training names (:mod:`kornia_ilum_sh.recipe`: :class:`SHRecipe`, :class:`MultiScaleSH`, ...) are
importable from here too, but load on first use, so that creating the estimator for inference never imports
the training code (:mod:`kornia_ilum_lab.train`).
"""

from typing import Any

from kornia_ilum_sh.estimator import (
    INIT_RADIANCE,
    LIGHTING_SIZE,
    NUM_COEFFICIENTS,
    PAPER,
    SHEstimator,
)

__version__ = "0.1.0.dev0"

#: The names of :mod:`kornia_ilum_sh.recipe` that this package gives on first use.
_RECIPE_NAMES = ("NEGATIVE_PENALTY", "SCALES", "MultiScaleSH", "SHRecipe", "negative_penalty")

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


def __getattr__(name: str) -> Any:
    if name in _RECIPE_NAMES:
        from kornia_ilum_sh import recipe  # lazy: the estimator alone must not import kornia_ilum_lab.train

        return getattr(recipe, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
