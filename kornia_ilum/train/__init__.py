r"""Training of the lighting estimators on the virtual light stage (``kornia-ilum train``).

- :class:`TrainConfig`, :func:`train`: the loop (:mod:`kornia_ilum.train.loop`), resumable, DDP-ready.
- :class:`MultiScaleOurs`, :class:`MSGDiscriminator`: the training-only networks of ``ours``.
- :func:`training_losses`, :func:`export_weights`.

Importing this package is cheap; the data and the networks are built by :func:`train`.
"""

from kornia_ilum.train.loop import BRDF_WEIGHTS, TrainConfig, export_weights, read_log, train, training_losses
from kornia_ilum.train.models import SCALES, MSGDiscriminator, MultiScaleOurs
from kornia_ilum.train.recipes import get_recipe, list_recipes

__all__ = [
    "BRDF_WEIGHTS",
    "SCALES",
    "MSGDiscriminator",
    "MultiScaleOurs",
    "TrainConfig",
    "export_weights",
    "get_recipe",
    "list_recipes",
    "read_log",
    "train",
    "training_losses",
]
