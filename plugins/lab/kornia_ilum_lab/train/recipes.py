r"""Training recipes: what :func:`~kornia_ilum_lab.train.train` builds, feeds, steps and exports per estimator.

A recipe names the trainable model (and its discriminator, if adversarial), how the light-stage dataset is
configured for it, how one optimisation step runs (:meth:`Recipe.step`; by default :func:`train_step`), and
how the trained model becomes a registered :class:`~kornia_ilum.estimators.LightingEstimator`. The loop
(:mod:`kornia_ilum_lab.train.loop`: data order, checkpoints, logs, DDP) is the same for every recipe; it calls
the recipe, and the recipe never calls back into the loop. The losses live in :mod:`kornia_ilum_lab.train.losses`.

Recipes are found by the estimator's registry name through their own entry-point group,
:data:`RECIPE_ENTRY_POINT_GROUP` (``kornia_ilum.recipes``), apart from the estimators' group, so that creating
an estimator for inference never imports the training code. The built-in ``ours`` registers from kornia_ilum's
own ``pyproject.toml``; a plugin declares, in its ``pyproject.toml``::

    [project.entry-points."kornia_ilum.recipes"]
    sh = "kornia_ilum_sh.recipe:SHRecipe"

and ``kornia-ilum train --estimator sh`` trains it. A recipe entry point that fails to load, or is not a
:class:`Recipe` subclass, gives a :class:`RuntimeWarning` and is skipped; for one name declared twice, the
first found on ``sys.path`` wins.
"""

from __future__ import annotations

import importlib.metadata
import warnings
from collections.abc import Iterator
from typing import Any

import torch
import torch.nn.functional as F
from torch import nn

from kornia_ilum.color import LUMINANCE
from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.estimators import OursEstimator
from kornia_ilum.render import mirror_ball_pyramid
from kornia_ilum.sh import sh_project
from kornia_ilum_lab.synth.colour_looks import Look, apply_looks
from kornia_ilum_lab.synth.lightstage.portraits import PortraitDataset, crop_images
from kornia_ilum_lab.train.config import RuntimeSettings, TrainConfig
from kornia_ilum_lab.train.data import batch_loader, collate
from kornia_ilum_lab.train.losses import (
    albedo_loss,
    discriminator_images,
    energy_loss,
    energy_nll,
    log_l2_loss,
    to_true_energy,
    training_losses,
)
from kornia_ilum_lab.train.models import MSGDiscriminator, MultiScaleOurs

__all__ = [
    "PROBE_SIZE",
    "PROBE_STREAM",
    "RECIPE_ENTRY_POINT_GROUP",
    "OursRecipe",
    "Recipe",
    "batch_images",
    "colour_consistency",
    "colour_pairs",
    "crop_consistency",
    "crop_pairs",
    "get_recipe",
    "list_recipes",
    "train_step",
]

#: The entry-point group that the built-in recipes and plugins declare their training recipes in.
RECIPE_ENTRY_POINT_GROUP = "kornia_ilum.recipes"
#: The data stream of the probe batch that checks float16 weights (never a training stream: those are
#: ``rank * workers + k``).
PROBE_STREAM = 1023
PROBE_SIZE = 32


def batch_images(batch: dict[str, Any], key: str, device: torch.device,
                 memory: torch.memory_format = torch.contiguous_format) -> torch.Tensor:
    """``batch[key]`` (uint8 codes) as float32 in ``[0, 1]`` on ``device``, in memory format ``memory``.

    Args:
        batch: a collated batch (:func:`~kornia_ilum_lab.train.data.collate`).
        key: the images to take (``"image"``, ``"pair_image"``).
        device: where the result goes (copied without blocking).
        memory: the result's memory format (:attr:`~kornia_ilum_lab.train.RuntimeSettings.memory_format`).

    Returns:
        the images divided by 255, float32.

    Shape:
        - batch[key]: :math:`(B, 3, S, S)` uint8
        - Output: :math:`(B, 3, S, S)` float32

    Convention:
        sRGB codes in, sRGB values in ``[0, 1]`` out (docs/conventions.rst, "Images").

    Examples:
        >>> batch = {"image": torch.full((2, 3, 4, 4), 255, dtype=torch.uint8)}
        >>> crops = batch_images(batch, "image", torch.device("cpu"), torch.channels_last)
        >>> crops.dtype, float(crops.max()), crops.is_contiguous(memory_format=torch.channels_last)
        (torch.float32, 1.0, True)
    """
    return batch[key].to(device, non_blocking=True).float().div_(255.0).contiguous(memory_format=memory)


class Recipe:
    """The default recipe: a multi-scale lighting generator plus an optional discriminator.

    A subclass sets :attr:`name` and implements :meth:`build` and :meth:`estimator`; the other methods have
    defaults (the data as it is, :func:`~kornia_ilum_lab.train.data.batch_loader`, :func:`train_step`, no extra
    loss, a probe batch of the training distribution, no output scaling). It is found through
    :data:`RECIPE_ENTRY_POINT_GROUP` (:func:`get_recipe`).

    Examples:
        >>> recipe = Recipe()
        >>> recipe.extra_losses({32: torch.ones(1, 3, 32, 32)}), recipe.log_fields
        ({}, ())
        >>> recipe.build()
        Traceback (most recent call last):
        ...
        NotImplementedError
    """

    name = ""
    #: Columns of ``log.csv`` beyond the common ones, taken from :meth:`step`'s result by name.
    log_fields: tuple[str, ...] = ()

    def build(self, **options: Any) -> tuple[nn.Module, nn.Module | None]:
        """The model to train (``forward(crops) -> {size: lighting}``) and the discriminator or ``None``.

        ``options`` are the estimator's constructor arguments (:attr:`TrainConfig.model`); a recipe whose
        estimator takes none raises :class:`~kornia_ilum.core.errors.ValueCheckError` for any.
        """
        raise NotImplementedError

    def dataset(self, dataset: PortraitDataset) -> PortraitDataset:
        """The light-stage dataset as this recipe needs it (default: as it is)."""
        return dataset

    def calibration_dataset(self, dataset: PortraitDataset) -> PortraitDataset:
        """The portraits of the calibrations at export (``--calibrate-energy``, ``--fit-spread``): the training
        portraits as the estimator meets photos at inference (default: :meth:`dataset`'s)."""
        return self.dataset(dataset)

    def batches(self, dataset: PortraitDataset, batch: int, *, start: int, rank: int, world: int,
                workers: int) -> Iterator[dict[str, Any]]:
        """The batches of steps ``start, start + 1, ...`` of one rank
        (:func:`~kornia_ilum_lab.train.data.batch_loader`)."""
        return batch_loader(dataset, batch, start=start, rank=rank, world=world, workers=workers)

    def estimator(self, model: nn.Module) -> nn.Module:
        """The registered estimator inside the trained model (what is exported)."""
        raise NotImplementedError

    def step(self, *, model: nn.Module, disc: nn.Module | None, opt_g: torch.optim.Optimizer,
             opt_d: torch.optim.Optimizer | None, batch: dict[str, Any], device: torch.device,
             config: TrainConfig, runtime: RuntimeSettings) -> dict[str, torch.Tensor]:
        """One optimisation step on a collated ``batch`` (:func:`~kornia_ilum_lab.train.data.collate`).

        Returns the detached losses: ``loss``, ``rec``, ``adv``, ``disc``, ``extra``, ``rec_<brdf>`` and the
        recipe's :attr:`log_fields`. The default is :func:`train_step` on the crops and their ground-truth
        lighting.
        """
        crops = batch_images(batch, "image", device, runtime.memory_format)
        target = batch["mirror_ball"].to(device, non_blocking=True).float()
        tones = batch.get("skin_tone")
        pairs = twins = 0
        if config.lambda_crop > 0:
            crops, target, pairs = crop_pairs(crops, target, batch["second_crop"], config.crop_pairs)
            crops = crops.contiguous(memory_format=runtime.memory_format)
            if tones is not None:  # a pair's second crop shows its first crop's face
                tones = torch.cat([tones[: len(tones) - pairs], tones[:pairs]])
        if config.lambda_colour > 0:
            crops, target, twins = colour_pairs(crops, target, config.colour_pairs, start=pairs)
            crops = crops.contiguous(memory_format=runtime.memory_format)
            if tones is not None:  # a greyscale twin shows its first's face
                b = len(tones)
                tones = torch.cat([tones[: b - pairs - twins], tones[pairs:pairs + twins], tones[b - pairs:]])
        return train_step(model=model, disc=disc, opt_g=opt_g, opt_d=opt_d, crops=crops, target=target,
                          config=config, runtime=runtime, recipe=self, pairs=pairs, twins=twins, skin_tone=tones)

    def extra_losses(self, pred: dict[int, torch.Tensor]) -> dict[str, torch.Tensor]:
        """Terms added to the generator's loss, by name, from its multi-scale prediction (default: none).

        Their sum is logged as ``extra``; ``ours`` has none.
        """
        return {}

    def probe(self, dataset: PortraitDataset) -> dict[str, Any]:
        """A fixed batch of the training distribution that checks the float16 export."""
        samples = dataset.samples(PROBE_STREAM)
        return collate([next(samples) for _ in range(PROBE_SIZE)])

    def export(self, estimator: nn.Module, path: Any, probe: dict[str, Any]) -> dict[str, Any] | None:
        """Write the trained weights to ``path`` in the recipe's own way and describe them, or ``None`` (the
        default): the loop's :func:`~kornia_ilum_lab.train.export_weights` (float16 where ``L_rec`` allows)."""
        return None

    def scale_output(self, estimator: nn.Module, gain: torch.Tensor) -> None:
        """Multiply the lighting that ``estimator`` outputs by ``gain`` (``(3,)``, R, G, B), in place and exactly
        (the calibration reports its effect without measuring it again): the energy calibration of
        :func:`~kornia_ilum_lab.train.calibration.calibrate_energy`.

        Raises:
            ValueCheckError: the recipe cannot scale its estimator's output (the default).
        """
        raise ValueCheckError(f"the recipe of {self.name!r} cannot scale its estimator's output, so its energy "
                              "cannot be calibrated")


class OursRecipe(Recipe):
    """``ours``: :class:`~kornia_ilum_lab.train.models.MultiScaleOurs` with the MSG-GAN discriminator.

    Its ``build`` options are :class:`~kornia_ilum.estimators.OursEstimator`'s, and ``albedo_head``
    (:class:`~kornia_ilum_lab.train.models.MultiScaleOurs`'s, training only); the exported estimator is the
    generator's ``estimator``, and its energy calibration adds ``log(gain)`` to the head's bias (exact).

    Examples:
        >>> recipe = OursRecipe()
        >>> model, disc = recipe.build(normalize_exposure=False)
        >>> type(model).__name__, type(disc).__name__, recipe.estimator(model) is model.estimator
        ('MultiScaleOurs', 'MSGDiscriminator', True)
    """

    name = "ours"

    def build(self, **options: Any) -> tuple[nn.Module, nn.Module | None]:
        albedo_head = bool(options.pop("albedo_head", False))  # the training model's, not the estimator's
        try:
            estimator = OursEstimator(**options)
        except TypeError as exc:
            raise ValueCheckError(f"model options {sorted(options)} are not OursEstimator's: {exc}") from exc
        return MultiScaleOurs(estimator, albedo_head=albedo_head), MSGDiscriminator()

    def estimator(self, model: nn.Module) -> nn.Module:
        return model.estimator

    def scale_output(self, estimator: nn.Module, gain: torch.Tensor) -> None:
        # ours outputs log radiance from its head: a gain is a constant on the head's bias, exactly
        with torch.no_grad():
            estimator.head.bias.add_(torch.log(gain).to(estimator.head.bias))


def crop_pairs(crops: torch.Tensor, target: torch.Tensor, boxes: torch.Tensor, pairs: int
               ) -> tuple[torch.Tensor, torch.Tensor, int]:
    r"""The batch with its last ``P`` samples replaced by second crops of its first ``P`` (crop consistency).

    Sample ``B - P + i`` becomes the crop ``boxes[i]`` of sample ``i`` (in its pixels,
    :func:`~kornia_ilum_lab.synth.lightstage.portraits.inner_crop_boxes`), resampled to the crops' side
    (:func:`~kornia_ilum_lab.synth.lightstage.portraits.crop_images`, bilinear), with sample ``i``'s lighting: the same
    face and light seen through another detector's box. ``P`` is ``pairs``, at most half the batch.

    Args:
        crops: ``(B, 3, S, S)`` sRGB crops in ``[0, 1]``.
        target: ``(B, 3, 32, 32)`` their lighting.
        boxes: ``(B, 4)`` a second box inside each crop (``batch["second_crop"]``).
        pairs: the number of pairs ``P`` asked for.

    Returns:
        ``(crops, target, P)``: new contiguous tensors (the inputs are left alone).

    Examples:
        >>> crops, target = torch.rand(4, 3, 16, 16), torch.rand(4, 3, 32, 32)
        >>> boxes = torch.tensor([[0.0, 0.0, 16.0, 16.0]]).repeat(4, 1)  # the whole crop: the same image
        >>> c, t, p = crop_pairs(crops, target, boxes, 8)
        >>> p, torch.allclose(c[2:], crops[:2], atol=1e-6), torch.equal(t[2:], target[:2])
        (2, True, True)
    """
    p = min(int(pairs), len(crops) // 2)
    second = crop_images(crops[:p].float(), boxes[:p].to(crops.device, torch.float64), crops.shape[-1])
    crops = torch.cat([crops[: len(crops) - p], second.clamp_(0.0, 1.0).to(crops.dtype)])
    return crops, torch.cat([target[: len(target) - p], target[:p]]), p


def crop_consistency(pred: dict[int, torch.Tensor], pairs: int, brdf_weights: dict[str, float]) -> torch.Tensor:
    r"""How far the two crops of each pair are apart in lighting: ``sum_k lambda_k L_rec(k)`` at the finest
    scale, between the predictions of samples ``i`` and ``B - P + i`` (both get gradients).

    The term is blind to a scale that the two predictions share: both are multiplied by ``m.detach() / m``,
    with ``m`` the geometric mean of the pair's two mean radiances. That leaves its value as it is but takes
    away the gradient that would darken both: ``L_rec`` compares gamma-encoded spheres, so two predictions
    scaled by ``c`` lie about ``c^(1/2.2)`` times as far apart. (Measured, that pull was not what made the
    fine-tuned estimates dark: docs/training.rst, "Why the energy drifts low".)

    Args:
        pred: ``{size: (B, 3, size, size)}`` the generator's linear lighting per scale; only the finest is read.
        pairs: the number of pairs ``P`` at the ends of the batch (:func:`crop_pairs`).
        brdf_weights: ``lambda_k`` per sphere.

    Returns:
        the term, a scalar (:func:`~kornia_ilum_lab.train.losses.training_losses` with the first crops of the pairs
        as the truth of the second).

    Shape:
        - pred[size]: :math:`(B, 3, size, size)`, :math:`B \ge 2P`
        - Output: :math:`()`

    Examples:
        >>> light = torch.ones(4, 3, 32, 32)
        >>> float(crop_consistency({32: light}, 2, {"diffuse": 1.0}))
        0.0
    """
    size = max(pred)
    x = pred[size]
    first, second = x[:pairs], x[len(x) - pairs :]
    mean = (first.float().clamp_min(0).mean((1, 2, 3)) * second.float().clamp_min(0).mean((1, 2, 3))).clamp_min(
        1e-12).sqrt()
    shared = (mean.detach() / mean).view(-1, 1, 1, 1)
    first, second = first * shared, second * shared  # the pairs' first crops stand as the truth of the second
    return training_losses({size: second}, first, brdf_weights=brdf_weights, truth={size: first})[0]


def colour_pairs(crops: torch.Tensor, target: torch.Tensor, pairs: int, *, start: int = 0
                 ) -> tuple[torch.Tensor, torch.Tensor, int]:
    r"""The batch with ``P`` samples before its last ``start`` replaced by greyscale twins of the ``P`` samples
    after its first ``start`` (colour consistency), with the greyscale lighting target.

    Sample ``B - start - P + i`` becomes the greyscale photo of sample ``start + i``
    (:func:`~kornia_ilum_lab.synth.colour_looks.greyscale`), and its target that sample's lighting in grey
    (:func:`~kornia_ilum_lab.synth.colour_looks.look_lighting`). ``start`` is the crop pairs' count
    (:func:`crop_pairs`), whose first and second crops the twins leave alone.

    Args:
        crops: ``(B, 3, S, S)`` sRGB crops in ``[0, 1]``.
        target: ``(B, 3, 32, 32)`` their lighting.
        pairs: the number of twins ``P`` asked for.
        start: the samples left alone at each end of the batch.

    Returns:
        ``(crops, target, P)``: new contiguous tensors (the inputs are left alone); ``P`` at most
        ``(B - 2 start) / 2``.

    Examples:
        >>> crops, target = torch.rand(8, 3, 16, 16), torch.rand(8, 3, 32, 32)
        >>> c, t, p = colour_pairs(crops, target, 2, start=1)
        >>> p, torch.equal(c[:5], crops[:5]), torch.equal(c[5, 0], c[5, 2]), torch.equal(c[7], crops[7])
        (2, True, True, True)
    """
    b = len(crops)
    p = min(int(pairs), (b - 2 * start) // 2)
    first = slice(start, start + p)
    grey, grey_target = apply_looks(crops[first].float(), target[first], Look.named("greyscale", p))
    keep = b - start - p
    crops = torch.cat([crops[:keep], grey.to(crops.dtype), crops[b - start:]])
    return crops, torch.cat([target[:keep], grey_target.to(target.dtype), target[b - start:]]), p


def colour_consistency(pred: dict[int, torch.Tensor], twins: int, *, start: int = 0,
                       teacher: bool = False) -> torch.Tensor:
    r"""How far apart the main lights of each portrait and its greyscale twin are: the mean of ``1 - cos`` of the
    angle between the luminance dipoles ``sum_p Omega_p Y_p omega_p`` (the l = 1 band of
    :func:`~kornia_ilum.sh.sh_project`) of the two predictions at the finest scale
    (samples ``start + i`` and ``B - start - P + i``, :func:`colour_pairs`; both get gradients, or with
    ``teacher`` only the twin: the colour photo's estimate, which sees more, is the twin's target and is not
    pulled toward it).

    Args:
        pred: ``{size: (B, 3, size, size)}`` the generator's linear lighting per scale.
        twins: the pairs ``P``.
        start: as :func:`colour_pairs`.
        teacher: detach the colour photos' dipoles.

    Returns:
        the term, a scalar in ``[0, 2]``.

    Shape:
        - pred[size]: :math:`(B, 3, size, size)`
        - Output: :math:`()`

    Examples:
        >>> light = torch.rand(6, 3, 32, 32)
        >>> same = light[[0, 1, 2, 3, 0, 1]]  # the last two are the first two again
        >>> float(colour_consistency({32: light}, 2)) > 0, abs(float(colour_consistency({32: same}, 2))) < 1e-6
        (True, True)
    """
    x = pred[max(pred)].float()
    b = len(x)
    # the l = 1 SH band is the dipole, up to a constant and the order (y, z, x); the projection is linear, so
    # the luminance's band is the channels' bands weighted by the luminance's coefficients
    dipole = sh_project(x)[:, 1:4] @ torch.tensor(LUMINANCE, dtype=x.dtype, device=x.device)
    first, second = dipole[start:start + twins], dipole[b - start - twins:b - start]
    if teacher:
        first = first.detach()
    return (1.0 - F.cosine_similarity(first, second, dim=-1, eps=1e-8)).mean()


def train_step(*, model: nn.Module, disc: nn.Module | None, opt_g: torch.optim.Optimizer,
               opt_d: torch.optim.Optimizer | None, crops: torch.Tensor, target: torch.Tensor,
               config: TrainConfig, runtime: RuntimeSettings, recipe: Recipe | None = None, pairs: int = 0,
               twins: int = 0, skin_tone: torch.Tensor | None = None) -> dict[str, torch.Tensor]:
    r"""One discriminator step, then one generator step; returns the detached losses (the default
    :meth:`Recipe.step`).

    LeGendre et al. 2020, Sec. 3.4:

    1. the generator predicts lighting at 4, 8, 16 and 32 px
       (:class:`~kornia_ilum_lab.train.models.MultiScaleOurs`); the ground truth is brought to the same sizes by
       the energy-keeping pyramid of docs/conventions.rst, "Multi-scale";
    2. the discriminator (:class:`~kornia_ilum_lab.train.models.MSGDiscriminator`) takes one Adam step on the
       clipped mirror balls of the truth (real) and of the prediction (fake, detached): the logistic loss
       ``softplus(-D(real)) + softplus(D(fake))``;
    3. the generator takes one Adam step on
       ``sum_s lambda_s sum_k lambda_k L_rec(k, s) + lambda_adv softplus(-D(fake)) + extra``, with the
       training form of ``L_rec`` (:func:`~kornia_ilum_lab.train.losses.training_losses`) and ``extra`` the sum of
       the recipe's :meth:`Recipe.extra_losses`. The paper's ablations change the first term: without
       ``config.multi_scale`` it is taken at 32 px only, and ``config.loss == "log_l2"`` puts
       :func:`~kornia_ilum_lab.train.losses.log_l2_loss` in place of ``L_rec``. With ``pairs`` (:func:`crop_pairs`), plus
       ``lambda_crop`` times :func:`crop_consistency`; with ``twins`` (:func:`colour_pairs`), plus
       ``lambda_colour`` times :func:`colour_consistency`; with ``lambda_energy``, plus that times
       :func:`~kornia_ilum_lab.train.losses.energy_loss` at 32 px. With ``lambda_nll``, every scale's prediction is
       first brought to the truth's energy (:func:`~kornia_ilum_lab.train.losses.to_true_energy`: ``L_rec``, the
       discriminator and the crop term see the lighting's shape only), and ``lambda_nll`` times
       :func:`~kornia_ilum_lab.train.losses.energy_nll` at 32 px (the model's ``log_spread``) learns the scale.

    Args:
        model: the multi-scale generator (possibly DDP-wrapped): ``crops -> {size: lighting}``.
        disc: the discriminator (possibly DDP-wrapped) or ``None`` (no adversarial term).
        opt_g, opt_d: their optimisers (``opt_d`` is ``None`` with ``disc``).
        crops: ``(B, 3, 256, 256)`` sRGB in ``[0, 1]``, in the networks' memory format.
        target: ``(B, 3, 32, 32)`` linear ground-truth lighting.
        config: the loss weights (``brdf_weights``, ``lambda_scale``, ``lambda_adv``, ...) and the ablations'
            ``multi_scale`` and ``loss``.
        runtime: ``bf16`` and the memory format.
        recipe: its :meth:`Recipe.extra_losses` join the generator's loss (none for ``None``).
        pairs: the crop pairs at the ends of the batch (:func:`crop_pairs`; 0: none).
        twins: the greyscale twins inside them (:func:`colour_pairs`; 0: none).
        skin_tone: ``(B,)`` the subjects' Monk tones, for ``lambda_albedo``.

    Returns:
        the detached ``loss``, ``rec``, ``adv``, ``disc``, ``extra``, ``crop`` (:func:`crop_consistency`, 0
        without pairs), ``colour`` (:func:`colour_consistency`, 0 without twins), ``energy`` (:func:`~kornia_ilum_lab.train.losses.energy_loss`, 0 without
        ``lambda_energy``), ``nll`` and ``spread`` (:func:`~kornia_ilum_lab.train.losses.energy_nll` and the batch's
        mean ``b``, 0 without ``lambda_nll``), ``albedo`` (:func:`~kornia_ilum_lab.train.losses.albedo_loss`, 0
        without ``lambda_albedo``) and ``rec_<brdf>`` (at 32 px).

    Raises:
        ValueCheckError: ``lambda_nll`` for a model without a spread head, ``lambda_albedo`` for one without an
            albedo head or without ``skin_tone``.

    Examples:
        One step of a toy generator, a constant lighting, without a discriminator (not run here: the first
        optimiser of a process imports ``torch._dynamo``, which is slow):

        >>> class Constant(nn.Module):
        ...     def __init__(self):
        ...         super().__init__()
        ...         self.light = nn.Parameter(torch.ones(3, 1, 1))
        ...     def forward(self, crops):
        ...         return {32: self.light.expand(len(crops), 3, 32, 32)}
        >>> model = Constant()
        >>> config = TrainConfig(out="runs/toy", cache=("lightstage/",), lambda_adv=0.0,
        ...                      brdf_weights={"mirror": 1.0})
        >>> opt_g = torch.optim.SGD(model.parameters(), lr=0.1)  # doctest: +SKIP
        >>> losses = train_step(model=model, disc=None, opt_g=opt_g, opt_d=None, crops=torch.rand(2, 3, 8, 8),
        ...                     target=torch.ones(2, 3, 32, 32), config=config,
        ...                     runtime=RuntimeSettings(bf16=False, channels_last=False, workers=0))  # doctest: +SKIP
        >>> sorted(losses)  # doctest: +SKIP
        ['adv', 'albedo', 'colour', 'crop', 'disc', 'energy', 'extra', 'loss', 'nll', 'rec', 'rec_mirror', 'spread']
        >>> round(losses["loss"].item(), 6)  # doctest: +SKIP
        0.0
    """
    memory = runtime.memory_format
    autocast = torch.autocast(crops.device.type, dtype=torch.bfloat16, enabled=runtime.bf16)
    with autocast:
        pred = model(crops)
    truth = mirror_ball_pyramid(target, tuple(pred))  # the losses' targets, the discriminator's real images
    finest = max(pred)
    nll = spread = albedo = target.new_zeros(())
    if config.lambda_albedo > 0:
        log_albedo = getattr(pred, "log_albedo", None)
        if log_albedo is None or skin_tone is None:
            raise ValueCheckError("lambda_albedo needs a model with an albedo head (--model albedo_head=True) "
                                  "and the batch's skin tones")
        albedo = albedo_loss(log_albedo, skin_tone)
    if config.lambda_nll > 0:
        log_spread = getattr(pred, "log_spread", None)
        if log_spread is None:
            raise ValueCheckError("lambda_nll needs a model with a spread head (--model spread_head=True)")
        nll = energy_nll(pred[finest], truth[finest], log_spread)
        spread = log_spread.detach().exp().mean()
        pred = to_true_energy(pred, truth)  # the rest sees the shape: the scale is the likelihood's alone
    scored = pred if config.multi_scale else {finest: pred[finest]}
    if config.loss == "log_l2":
        rec = log_l2_loss(scored, truth, config.lambda_scale)
        with torch.no_grad():  # L_rec at 32 px for the log only
            parts = training_losses({finest: pred[finest]}, target, brdf_weights=config.brdf_weights,
                                    truth=truth)[1]
    else:
        rec, parts = training_losses(scored, target, brdf_weights=config.brdf_weights,
                                     lambda_scale=config.lambda_scale, truth=truth)
    adv = disc_loss = rec.new_zeros(())
    if disc is not None:
        plain = getattr(disc, "module", disc)  # the generator's step syncs no gradient of the discriminator
        real, fake = discriminator_images(truth), discriminator_images(pred)
        both = {s: torch.cat([real[s], fake[s].detach()]).contiguous(memory_format=memory) for s in real}
        with autocast:
            logits = disc(both).float()
        n = len(target)
        disc_loss = F.softplus(-logits[:n]).mean() + F.softplus(logits[n:]).mean()
        opt_d.zero_grad(set_to_none=True)
        disc_loss.backward()
        opt_d.step()
        with autocast:
            fake_logits = plain({s: v.contiguous(memory_format=memory) for s, v in fake.items()}).float()
            adv = F.softplus(-fake_logits).mean()
    extra = sum((recipe.extra_losses(pred) if recipe is not None else {}).values(), rec.new_zeros(()))
    crop = crop_consistency(pred, pairs, config.brdf_weights) if pairs else rec.new_zeros(())
    colour = (colour_consistency(pred, twins, start=pairs, teacher=config.colour_teacher) if twins
              else rec.new_zeros(()))
    energy = energy_loss(pred[finest], truth[finest]) if config.lambda_energy > 0 else rec.new_zeros(())
    loss = (rec + config.lambda_adv * adv + extra + config.lambda_crop * crop + config.lambda_colour * colour
            + config.lambda_energy * energy
            + config.lambda_nll * nll + config.lambda_albedo * albedo)
    opt_g.zero_grad(set_to_none=True)
    loss.backward()
    opt_g.step()
    return {"loss": loss.detach(), "rec": rec.detach(), "adv": adv.detach(), "disc": disc_loss.detach(),
            "extra": extra.detach(), "crop": crop.detach(), "colour": colour.detach(), "energy": energy.detach(),
            "nll": nll.detach(),
            "spread": spread, "albedo": albedo.detach(), **parts}


def _recipe_classes() -> dict[str, type[Recipe]]:
    """Load every entry point of :data:`RECIPE_ENTRY_POINT_GROUP`; warn about and skip the broken ones."""
    found: dict[str, type[Recipe]] = {}
    for ep in importlib.metadata.entry_points(group=RECIPE_ENTRY_POINT_GROUP):
        if ep.name in found:  # the first on sys.path wins, as for estimators
            continue
        try:
            cls = ep.load()
            if not (isinstance(cls, type) and issubclass(cls, Recipe)):
                raise TypeError(f"{cls!r} is not a subclass of kornia_ilum_lab.train.recipes.Recipe")
        except Exception as e:  # a broken plugin must never break the other recipes
            warnings.warn(
                f"kornia_ilum: skipping training recipe entry point '{ep.name} = {ep.value}' "
                f"(group {RECIPE_ENTRY_POINT_GROUP}): {type(e).__name__}: {e}",
                RuntimeWarning,
                stacklevel=3,
            )
            continue
        found[ep.name] = cls
    return found


def list_recipes() -> list[str]:
    """The estimators that ``kornia-ilum train`` can train: the names of the recipe entry points, sorted.

    Returns:
        the names (broken entry points are left out with a :class:`RuntimeWarning`).

    Examples:
        >>> "ours" in list_recipes()
        True
    """
    return sorted(_recipe_classes())


def get_recipe(name: str) -> Recipe:
    """The recipe of estimator ``name``, from :data:`RECIPE_ENTRY_POINT_GROUP`.

    Args:
        name: the estimator's registry name (:func:`list_recipes`).

    Returns:
        a new instance of its recipe class.

    Raises:
        ValueCheckError: no recipe for ``name``.

    Examples:
        >>> type(get_recipe("ours")).__name__
        'OursRecipe'
    """
    recipes = _recipe_classes()
    if name not in recipes:
        trainable = ", ".join(sorted(recipes))
        raise ValueCheckError(f"no training recipe for estimator {name!r}; trainable: {trainable}")
    return recipes[name]()
