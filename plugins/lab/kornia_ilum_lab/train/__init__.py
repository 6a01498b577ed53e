r"""Training of the lighting estimators on the virtual light stage (``kornia-ilum train``).

- :class:`TrainConfig`, :class:`RuntimeSettings` (:mod:`kornia_ilum_lab.train.config`): a run's settings, and
  what :func:`resolve_runtime` decides of them for the device;
- :func:`train` (:mod:`kornia_ilum_lab.train.loop`): the loop, resumable, DDP-ready; it calls the estimator's
  recipe;
- :class:`Recipe`, :func:`get_recipe`, :func:`list_recipes`, :func:`train_step`
  (:mod:`kornia_ilum_lab.train.recipes`): what is trained for each estimator, found through the entry-point group
  ``kornia_ilum.recipes``, and the default optimisation step;
- :func:`training_losses`, :data:`BRDF_WEIGHTS` (:mod:`kornia_ilum_lab.train.losses`): the losses;
- :class:`MultiScaleOurs`, :class:`MSGDiscriminator` (:mod:`kornia_ilum_lab.train.models`): the training-only
  networks of ``ours``;
- :func:`export_weights`, :func:`read_log`, :func:`save_snapshot`, :func:`average_snapshots`;
- :func:`~kornia_ilum_lab.train.calibration.calibrate_energy` (:mod:`kornia_ilum_lab.train.calibration`): the energy
  gain of ``--calibrate-energy`` at export.

``import kornia_ilum`` never imports this package; importing it loads the light stage's data code
(:mod:`kornia_ilum_lab.synth`). The data and the networks are built by :func:`train`.
"""

from kornia_ilum_lab.train.config import RuntimeSettings, TrainConfig, resolve_runtime
from kornia_ilum_lab.train.loop import average_snapshots, export_weights, read_log, save_snapshot, train
from kornia_ilum_lab.train.losses import BRDF_WEIGHTS, training_losses
from kornia_ilum_lab.train.models import SCALES, MSGDiscriminator, MultiScaleOurs
from kornia_ilum_lab.train.recipes import Recipe, get_recipe, list_recipes, train_step

__all__ = [
    "BRDF_WEIGHTS",
    "MSGDiscriminator",
    "MultiScaleOurs",
    "Recipe",
    "RuntimeSettings",
    "SCALES",
    "TrainConfig",
    "average_snapshots",
    "export_weights",
    "get_recipe",
    "list_recipes",
    "read_log",
    "resolve_runtime",
    "save_snapshot",
    "train",
    "train_step",
    "training_losses",
]
