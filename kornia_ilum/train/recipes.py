r"""Training recipes: what :func:`~kornia_ilum.train.train` builds, feeds and exports for each estimator.

A recipe names the trainable model (and its discriminator, if adversarial), how the light-stage dataset is
configured for it, and how the trained model becomes a registered :class:`~kornia_ilum.estimators.LightingEstimator`.
The loop itself (losses, checkpoints, logs, DDP) is the same for every recipe.

Plugins bring their own: an estimator class with a ``training_recipe`` class attribute (a :class:`Recipe`
subclass) is trainable by its registry name, ``kornia-ilum train --estimator NAME``.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import torch
from torch import nn

from kornia_ilum.core.errors import ValueCheckError

__all__ = ["PROBE_SIZE", "PROBE_STREAM", "OursRecipe", "Recipe", "batch_images", "get_recipe", "list_recipes"]

#: The data stream of the probe batch that checks float16 weights (never a training stream: those are
#: ``rank * workers + k``).
PROBE_STREAM = 1023
PROBE_SIZE = 32


def batch_images(batch: dict[str, Any], key: str, device: torch.device,
                 memory: torch.memory_format = torch.contiguous_format) -> torch.Tensor:
    """``batch[key]`` (uint8 codes) as float32 in ``[0, 1]`` on ``device``, in the memory format ``memory``."""
    return batch[key].to(device, non_blocking=True).float().div_(255.0).contiguous(memory_format=memory)


class Recipe:
    """The default recipe: a multi-scale lighting generator plus an optional discriminator."""

    name = ""
    #: Columns of ``log.csv`` beyond the common ones, taken from :meth:`step`'s result by name.
    log_fields: tuple[str, ...] = ()

    def build(self) -> tuple[nn.Module, nn.Module | None]:
        """The model to train (``forward(crops) -> {size: lighting}``) and the discriminator or ``None``."""
        raise NotImplementedError

    def dataset(self, dataset: Any) -> Any:
        """The light-stage dataset as this recipe needs it (default: as it is)."""
        return dataset

    def batches(self, dataset: Any, batch: int, start: int, rank: int, world: int, workers: int) -> Iterator:
        from kornia_ilum.train.data import batch_loader

        return batch_loader(dataset, batch, start, rank, world, workers)

    def estimator(self, model: nn.Module) -> nn.Module:
        """The registered estimator inside the trained model (what is exported)."""
        raise NotImplementedError

    def step(self, model: nn.Module, disc: nn.Module | None, opt_g: Any, opt_d: Any, batch: dict[str, Any],
             device: torch.device, config: Any) -> dict[str, torch.Tensor]:
        """One optimisation step on a collated ``batch`` (:func:`~kornia_ilum.train.data.collate`).

        Returns the detached losses: ``loss``, ``rec``, ``adv``, ``disc``, ``extra``, ``rec_<brdf>`` and the
        recipe's :attr:`log_fields`. The default is :func:`~kornia_ilum.train.train_step` on the crops and
        their ground-truth lighting.
        """
        from kornia_ilum.train.loop import train_step

        memory = torch.channels_last if config.channels_last else torch.contiguous_format
        crops = batch_images(batch, "image", device, memory)
        target = batch["mirror_ball"].to(device, non_blocking=True).float()
        return train_step(model, disc, opt_g, opt_d, crops, target, config, self)

    def extra_losses(self, pred: dict[int, Any]) -> dict[str, Any]:
        """Terms added to the generator's loss, by name, from its multi-scale prediction (default: none).

        Their sum is logged as ``extra``; ``ours`` has none.
        """
        return {}

    def probe(self, dataset: Any) -> dict[str, Any]:
        """A fixed batch of the training distribution that checks the float16 export."""
        from kornia_ilum.train.data import collate

        samples = dataset.samples(PROBE_STREAM)
        return collate([next(samples) for _ in range(PROBE_SIZE)])


class OursRecipe(Recipe):
    """``ours``: :class:`~kornia_ilum.train.models.MultiScaleOurs` with the MSG-GAN discriminator."""

    name = "ours"

    def build(self) -> tuple[nn.Module, nn.Module | None]:
        from kornia_ilum.train.models import MSGDiscriminator, MultiScaleOurs

        return MultiScaleOurs(), MSGDiscriminator()

    def estimator(self, model: nn.Module) -> nn.Module:
        return model.estimator


_RECIPES: dict[str, type[Recipe]] = {"ours": OursRecipe}


def _plugin_recipe(name: str) -> type[Recipe] | None:
    from kornia_ilum.estimators import estimator_registry

    cls = estimator_registry().get(name)
    recipe = getattr(cls, "training_recipe", None)
    return recipe if isinstance(recipe, type) and issubclass(recipe, Recipe) else None


def list_recipes() -> list[str]:
    """The estimators that ``kornia-ilum train`` can train (built-in recipes and plugins' ``training_recipe``)."""
    from kornia_ilum.estimators import list_estimators

    return sorted(set(_RECIPES) | {n for n in list_estimators() if _plugin_recipe(n) is not None})


def get_recipe(name: str) -> Recipe:
    """The recipe of estimator ``name``.

    Raises:
        ValueCheckError: no recipe for ``name``.
    """
    recipe = _RECIPES.get(name) or _plugin_recipe(name)
    if recipe is None:
        raise ValueCheckError(f"no training recipe for estimator {name!r}; trainable: {', '.join(list_recipes())}")
    return recipe()
