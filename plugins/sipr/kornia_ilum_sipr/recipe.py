r"""Training of ``sipr``: relight one portrait to another lighting, and estimate its own lighting.

:class:`SIPRRecipe` is the plugin's entry point ``sipr`` of the group ``kornia_ilum.recipes``, so
``kornia-ilum train --estimator sipr`` (:func:`kornia_ilum_lab.train.train`) trains it with the loop, the
optimiser (Adam at 1.5e-4), the batch (32) and the steps of ``ours``, on the same light-stage cache and
environments. What differs is what SIPR needs (Sun et al. 2019; LeGendre et al. 2020, Sec. 4):

Data (:meth:`SIPRRecipe.dataset`). LeGendre et al. trained their SIPR on "random crops from portraits
composited over black backgrounds (not real-world imagery)", in pairs of one subject under two lightings:
``PortraitConfig(background="black", pairs=True)``, and crops around the face with a wider jitter than
``ours``'s (:data:`CROP_POSITION`, :data:`CROP_EXTENT`: the face's centre moves by up to 15 % of the crop's
side and the side changes by up to a factor ``e^0.3``), at the estimator's input size
(:data:`~kornia_ilum_sipr.estimator.INPUT_SIZE`, 128: the budget's cut). The light stage's ``crop="random"`` is not used: it
makes crops that miss the face on purpose (negatives), from which no lighting can be read. The camera
effects, flips and exposure are those of ``ours``; each image of a pair has its own auto-exposure, and each
lighting is in the units of its image.

Step (:meth:`SIPRRecipe.step`). The encoder sees the first image; its lighting head estimates that image's
lighting, and the decoder relights it to the second image's lighting. The loss is

- :data:`RELIT_WEIGHT` times the L1 distance of the relit crop to the second image (sRGB in ``[0, 1]``),
  over the subject's pixels only: ``sum(alpha |relit - target|) / (3 sum(alpha))``, ``alpha`` the subject's
  matte in the crop (the background is black in both, so outside the subject there is nothing to learn);
- :data:`LIGHTING_WEIGHT` times the log-L2 loss on the lighting, as LeGendre et al. describe Sun et al.'s
  ("the log-L2 loss on HDR lighting"): ``mean((z - log(1 + L))^2)`` over the 16 x 32 lat-long texels and
  channels, ``z`` the head's ``log(1 + L)`` and ``L`` the ground truth brought from its 32 x 32 mirror ball
  to the 16 x 32 lat-long grid by area averaging (energy kept). ``nelf`` uses L1 on ``log(1 + L)``; we
  follow the paper's L2.

Both weights are 1: neither paper gives them. No discriminator. The loop's ``rec`` and ``rec_<brdf>``
columns are, for ``sipr``, the rendering loss of the lighting estimate (computed without gradient, to
compare the curves with ``ours``'s); the losses that train it are the ``relit`` and ``lighting`` columns.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import torch
from torch import Tensor, nn

from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum_lab.synth.lightstage.portraits import PortraitDataset
from kornia_ilum_lab.train.config import RuntimeSettings, TrainConfig
from kornia_ilum_lab.train.losses import training_losses
from kornia_ilum_lab.train.recipes import Recipe, batch_images
from kornia_ilum_sipr.estimator import INPUT_SIZE, SIPREstimator
from kornia_ilum_sipr.network import LIGHTING_SHAPE, RelightingDecoder, log_latlong_target, log_latlong_to_mirror_ball

__all__ = ["CROP_EXTENT", "CROP_POSITION", "LIGHTING_WEIGHT", "RELIT_WEIGHT", "SIPRRecipe", "SIPRTrainer", "masked_l1"]

#: Weight of the masked L1 relighting loss.
RELIT_WEIGHT = 1.0
#: Weight of the log-L2 lighting loss.
LIGHTING_WEIGHT = 1.0
#: The face crops' centre jitter (fraction of the side) and log-scale jitter for SIPR's "random crops".
CROP_POSITION = 0.15
CROP_EXTENT = 0.3


def masked_l1(pred: Tensor, target: Tensor, alpha: Tensor) -> Tensor:
    r"""``sum(alpha |pred - target|) / (C sum(alpha))``: the mean absolute error over the subject's pixels.

    Args:
        pred, target: :math:`(B, C, H, W)`.
        alpha: :math:`(B, 1, H, W)` in ``[0, 1]``.

    Examples:
        >>> alpha = torch.zeros(1, 1, 2, 2); alpha[..., 0, 0] = 1
        >>> float(masked_l1(torch.ones(1, 3, 2, 2), torch.zeros(1, 3, 2, 2), alpha))
        1.0
    """
    weight = alpha.expand_as(pred)
    return (weight * (pred - target).abs()).sum() / weight.sum().clamp(min=1e-6)


class SIPRTrainer(nn.Module):
    r"""``sipr`` for training: the estimator plus the relighting decoder.

    Args:
        estimator: the network to train (a new :class:`~kornia_ilum_sipr.SIPREstimator` by default);
            :attr:`estimator` is what gets exported.

    Returns:
        (``forward(crops, target_log_lighting)``) ``(relit, log_lighting)``: the relit crops
        :math:`(B, 3, H, W)` in ``[0, 1]`` and the estimated ``log(1 + L)`` :math:`(B, 3, 16, 32)`.

    Examples:
        >>> model = SIPRTrainer()
        >>> relit, z = model(torch.rand(2, 3, 64, 64), torch.rand(2, 3, 16, 32))
        >>> tuple(relit.shape), tuple(z.shape)
        ((2, 3, 64, 64), (2, 3, 16, 32))
    """

    def __init__(self, estimator: SIPREstimator | None = None) -> None:
        super().__init__()
        self.estimator = SIPREstimator() if estimator is None else estimator
        self.decoder = RelightingDecoder(LIGHTING_SHAPE)

    def forward(self, crops: Tensor, target_log_lighting: Tensor) -> tuple[Tensor, Tensor]:
        features = self.estimator.encoder(crops)
        return self.decoder(features, target_log_lighting), self.estimator.log_latlong(crops, features)


class SIPRRecipe(Recipe):
    """``sipr``: :class:`SIPRTrainer` on paired black-background portraits; exports its estimator. Its one model
    option is ``spread_head`` (``--model spread_head=True``, for ``--fit-spread``)."""

    name = "sipr"
    log_fields = ("relit", "lighting")

    def build(self, spread_head: bool = False) -> tuple[nn.Module, nn.Module | None]:
        return SIPRTrainer(SIPREstimator(spread_head=spread_head)), None

    def dataset(self, dataset: PortraitDataset) -> PortraitDataset:
        """The portraits as SIPR was trained on them (module docstring)."""
        config = dataclasses.replace(dataset.config, background="black", pairs=True, crop="face",
                                     crop_position=CROP_POSITION, crop_extent=CROP_EXTENT, size=INPUT_SIZE)
        return type(dataset)(dataset.fields, config, seed=dataset.seed)

    def calibration_dataset(self, dataset: PortraitDataset) -> PortraitDataset:
        """The portraits as the estimator meets photos (``ours``'s: environment backgrounds, one image each, the
        detector's face crops) at its input size: what ``--fit-spread`` fits the spread on."""
        return type(dataset)(dataset.fields, dataclasses.replace(dataset.config, size=INPUT_SIZE), seed=dataset.seed)

    def estimator(self, model: nn.Module) -> nn.Module:
        return model.estimator

    def step(self, *, model: nn.Module, disc: nn.Module | None, opt_g: torch.optim.Optimizer,
             opt_d: torch.optim.Optimizer | None, batch: dict[str, Any], device: torch.device,
             config: TrainConfig, runtime: RuntimeSettings) -> dict[str, Tensor]:
        """One Adam step on the relighting and lighting losses (module docstring)."""
        if config.lambda_crop > 0 or config.lambda_energy > 0 or config.lambda_nll > 0 or config.lambda_albedo > 0:
            raise ValueCheckError("the sipr recipe has no crop-consistency or energy term: train it with "
                                  "lambda_crop=0, lambda_energy=0, lambda_nll=0 and lambda_albedo=0")
        crops = batch_images(batch, "image", device, runtime.memory_format)
        target_image, alpha = batch_images(batch, "pair_image", device), batch_images(batch, "alpha", device)
        source = batch["mirror_ball"].to(device, non_blocking=True).float()
        with torch.no_grad():
            source_z = log_latlong_target(source)
            target_z = log_latlong_target(batch["pair_mirror_ball"].to(device, non_blocking=True))
        with torch.autocast(device.type, dtype=torch.bfloat16, enabled=runtime.bf16):
            relit, z = model(crops, target_z)
        relit_loss = masked_l1(relit.float(), target_image, alpha)
        lighting_loss = (z.float() - source_z).square().mean()
        loss = RELIT_WEIGHT * relit_loss + LIGHTING_WEIGHT * lighting_loss
        opt_g.zero_grad(set_to_none=True)
        loss.backward()
        opt_g.step()
        with torch.no_grad():  # the rendering loss of the estimate, for the log only
            estimate = log_latlong_to_mirror_ball(z.detach(), source.shape[-1])
            rec, parts = training_losses({source.shape[-1]: estimate}, source,
                                         brdf_weights=config.brdf_weights)
        zero = loss.new_zeros(())
        return {"loss": loss.detach(), "rec": rec, "adv": zero, "disc": zero, "extra": zero, **parts,
                "relit": relit_loss.detach(), "lighting": lighting_loss.detach()}
