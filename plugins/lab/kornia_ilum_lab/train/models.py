r"""The training-only networks: ``ours`` with its multi-scale side branches, and the MSG-GAN discriminator.

LeGendre et al. 2020, Sec. 3.3-3.4: the generator is trained with sphere-render losses at 4, 8, 16 and 32 px
(MSG-GAN, Karnewar and Wang 2020), so the decoder's 4, 8 and 16 px feature maps each get a side branch that
turns them into 3-channel log lighting; the discriminator sees the clipped mirror balls of every scale.
Neither the side branches nor the discriminator is part of the shipped estimator.

Our choices where the paper is silent (also in the model card):

- side branches: one 1 x 1 convolution each (MSG-GAN's "toRGB"), natural-log radiance like the main head;
- log radiance is clamped to ``[-LOG_RANGE, LOG_RANGE]`` before ``exp`` in training, so an early wild step
  cannot overflow float32 (``e^16`` is 8.9e6, far above any sun in image units at these exposures);
- discriminator: the 32 px image enters first; after each max-pooling the image of the next scale down is
  concatenated to the features (MSG-GAN's simple combine), and the 4 px image joins the last features
  before the fully-connected layers ``FC 1024 -> ELU -> FC 1`` (one logit).
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

from kornia_ilum.estimators.ours import DECODER_DEPTHS, LIGHTING_SIZE, OursEstimator
from kornia_ilum.geometry import mirror_ball_valid

__all__ = ["LOG_RANGE", "SCALES", "MSGDiscriminator", "MultiScaleLighting", "MultiScaleOurs"]

#: The lighting sizes of the multi-scale losses, coarse to fine.
SCALES: tuple[int, ...] = (4, 8, 16, 32)
#: Training clamps natural-log radiance to +-LOG_RANGE before the exponential.
LOG_RANGE = 16.0

_DISC_DEPTHS = (64, 128, 256)
_DISC_FC = 1024


class MultiScaleLighting(dict):
    """``{size: (B, 3, size, size)}`` lighting of a multi-scale generator, plus the spread head's ``log b``.

    A ``dict`` (so the losses, the discriminator and the recipes take it as they take any multi-scale
    prediction) with two attributes, ``(B,)`` float32 or ``None``: :attr:`log_spread`, from the estimator's
    spread head (:class:`~kornia_ilum.estimators.OursEstimator`, ``spread_head``), and :attr:`log_albedo`, from
    the training-only albedo head (:class:`MultiScaleOurs`, ``albedo_head``).

    Examples:
        >>> out = MultiScaleLighting({32: torch.ones(1, 3, 32, 32)}, log_spread=None)
        >>> list(out), out.log_spread is None, out.log_albedo is None
        ([32], True, True)
    """

    def __init__(self, lighting: dict[int, Tensor], log_spread: Tensor | None,
                 log_albedo: Tensor | None = None) -> None:
        super().__init__(lighting)
        self.log_spread, self.log_albedo = log_spread, log_albedo


class MultiScaleOurs(nn.Module):
    r"""``ours`` plus the training-only side branches: face crops -> linear lighting at 4, 8, 16 and 32 px.

    Args:
        estimator: the network to train (a new :class:`~kornia_ilum.estimators.OursEstimator` by default);
            :attr:`estimator` is what gets exported.
        albedo_head: add a training-only linear layer from the bottleneck to the log of the subject's skin
            albedo (:func:`~kornia_ilum_lab.train.losses.albedo_loss`): it asks the encoder to tell skin tones
            apart; not exported.

    Returns:
        (``forward``) a :class:`MultiScaleLighting`: ``{size: (B, 3, size, size)}`` float32 linear radiance,
        0 off the ball, for :data:`SCALES`, and the spread head's ``log_spread`` (``None`` without it).

    Examples:
        >>> model = MultiScaleOurs()
        >>> out = model(torch.rand(1, 3, 256, 256))
        >>> [tuple(out[s].shape[-2:]) for s in SCALES]
        [(4, 4), (8, 8), (16, 16), (32, 32)]
    """

    def __init__(self, estimator: OursEstimator | None = None, albedo_head: bool = False) -> None:
        super().__init__()
        self.estimator = OursEstimator() if estimator is None else estimator
        self.sides = nn.ModuleList(nn.Conv2d(d, 3, 1) for d in DECODER_DEPTHS)
        self.albedo = nn.Linear(self.estimator.latent_dim, 1) if albedo_head else None
        for s in SCALES:
            self.register_buffer(f"valid_{s}", mirror_ball_valid(s), persistent=False)

    def forward(self, crops: Tensor) -> MultiScaleLighting:
        log_32, features, log_scale, log_spread, latent = self.estimator.decode(crops)  # log_scale: the exposure
        logs = [side(f) + log_scale for side, f in zip(self.sides, features, strict=True)] + [log_32]
        out = {}
        for s, y in zip(SCALES, logs, strict=True):
            radiance = torch.exp(y.float().clamp(-LOG_RANGE, LOG_RANGE))
            out[s] = torch.where(getattr(self, f"valid_{s}"), radiance, 0.0)
        log_albedo = None if self.albedo is None else self.albedo(latent)[:, 0].float()
        return MultiScaleLighting(out, log_spread, log_albedo)


class MSGDiscriminator(nn.Module):
    r"""The multi-scale discriminator of LeGendre et al. 2020: clipped mirror balls at 32, 16, 8, 4 px -> a logit.

    Three 3 x 3 convolutions of depth 64, 128, 256, each followed by ELU and 2 x 2 max-pooling, then a
    fully-connected layer of 1024 (ELU) and one output; the coarser images join the features after each
    pooling (module docstring).

    Args:
        images: ``{size: (B, 3, size, size)}`` for sizes 32, 16, 8 and 4: the clipped, gamma-encoded mirror
            spheres (what :func:`~kornia_ilum.render.sphere_pyramid` gives for ``"mirror"``).

    Returns:
        ``(B,)`` logits (real is positive).

    Examples:
        >>> d = MSGDiscriminator()
        >>> d({s: torch.rand(2, 3, s, s) for s in (4, 8, 16, 32)}).shape
        torch.Size([2])
    """

    def __init__(self) -> None:
        super().__init__()
        blocks, depth_in = [], 3
        for k, depth in enumerate(_DISC_DEPTHS):
            blocks.append(nn.Sequential(nn.Conv2d(depth_in + (3 if k else 0), depth, 3, padding=1), nn.ELU(),
                                        nn.MaxPool2d(2)))
            depth_in = depth
        self.blocks = nn.ModuleList(blocks)
        side = LIGHTING_SIZE >> len(_DISC_DEPTHS)  # 4
        self.fc = nn.Sequential(nn.Flatten(1), nn.Linear((depth_in + 3) * side * side, _DISC_FC), nn.ELU(),
                                nn.Linear(_DISC_FC, 1))

    def forward(self, images: dict[int, Tensor]) -> Tensor:
        x = images[LIGHTING_SIZE]
        size = LIGHTING_SIZE
        for k, block in enumerate(self.blocks):
            if k:
                x = torch.cat([x, images[size].to(x.dtype)], 1)
            x = block(x)
            size //= 2
        x = torch.cat([x, images[size].to(x.dtype)], 1)
        return self.fc(x)[:, 0]
