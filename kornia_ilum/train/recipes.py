r"""Training recipes: what :func:`~kornia_ilum.train.train` builds, feeds and exports for each estimator.

A recipe names the trainable model (and its discriminator, if adversarial), how the light-stage dataset is
configured for it, and how the trained model becomes a registered :class:`~kornia_ilum.estimators.LightingEstimator`.
The loop itself (losses, checkpoints, logs, DDP) is the same for every recipe.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from torch import nn

from kornia_ilum.core.errors import ValueCheckError

__all__ = ["PROBE_SIZE", "PROBE_STREAM", "OursRecipe", "Recipe", "get_recipe", "list_recipes"]

#: The data stream of the probe batch that checks float16 weights (never a training stream: those are
#: ``rank * workers + k``).
PROBE_STREAM = 1023
PROBE_SIZE = 32


class Recipe:
    """The default recipe: a multi-scale lighting generator plus an optional discriminator."""

    name = ""

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


def list_recipes() -> list[str]:
    """The estimators that ``kornia-ilum train`` can train."""
    return sorted(_RECIPES)


def get_recipe(name: str) -> Recipe:
    """The recipe of estimator ``name``.

    Raises:
        ValueCheckError: no recipe for ``name``.
    """
    if name not in _RECIPES:
        raise ValueCheckError(f"no training recipe for estimator {name!r}; trainable: {', '.join(list_recipes())}")
    return _RECIPES[name]()
