r"""Training of ``sh``: the rendering loss of ``ours`` on the unclamped SH reconstruction, no discriminator.

:class:`SHRecipe` is the plugin's entry point ``sh`` of the group ``kornia_ilum.recipes``, so
``kornia-ilum train --estimator sh`` (:func:`kornia_ilum_lab.train.train`) trains it: the same data, optimiser
and multi-scale loss ``sum_s lambda_s sum_k lambda_k L_rec(k, s)`` as ``ours``
(:func:`~kornia_ilum_lab.train.losses.training_losses`), without the adversarial term (an order-2 function cannot
look like a real mirror ball, so there is nothing for a discriminator to teach).

:class:`MultiScaleSH` gives the loop ``{size: lighting}`` for sizes 4, 8, 16, 32: the *unclamped*
reconstruction of the predicted coefficients at 32 px, brought to each size by the energy-keeping pyramid
(:func:`~kornia_ilum.render.mirror_ball_pyramid`, docs/conventions.rst, "Multi-scale"). The loss thus sees
the negative lobes; ``softclip`` counts negative sphere pixels as 0 with gradient 0 (docs/conventions.rst,
"The paper's error measure L_rec").

Stalling, and the penalty. Where a sphere pixel's render is negative the loss has no gradient. The mirror
sphere shows the lighting itself, so a negative lobe gets no gradient from it, only from the diffuse and
matte silver spheres, which average over a hemisphere. If the constant term itself goes negative for a
sample, all three spheres of it are negative and that sample gives no gradient at all; if that happened to
every sample the training would stop for good. Two things prevent it:

- the head's bias starts at a positive uniform lighting (:data:`~kornia_ilum_sh.estimator.INIT_RADIANCE`);
- a penalty ``NEGATIVE_PENALTY * mean(relu(-L))`` on the 32 px reconstruction (mean over the batch,
  channels and valid pixels, radiance in image units), added to the generator's loss through the recipe's
  :meth:`SHRecipe.extra_losses` and logged as the ``extra`` column of the run's ``log.csv``. At 0.05 its
  gradient on a negative pixel is about 2 % of the rendering loss's (median over the pixels of random
  lighting at half the truth, batch 2: 1.0e-5 against 5.8e-4): a tie-breaker where the loss is flat, not
  a pull away from the (genuinely negative) order-2 fit of a bright light. Adam normalises gradient
  scales, so where it is the only gradient (every sphere negative) it still moves the weights.
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum.render import mirror_ball_pyramid
from kornia_ilum.sh import sh_reconstruct
from kornia_ilum_lab.train.models import MultiScaleLighting
from kornia_ilum_lab.train.recipes import Recipe
from kornia_ilum_sh.estimator import SHEstimator

__all__ = ["NEGATIVE_PENALTY", "SCALES", "MultiScaleSH", "SHRecipe", "negative_penalty"]

#: The lighting sizes of the multi-scale losses, coarse to fine (as ``ours``).
SCALES: tuple[int, ...] = (4, 8, 16, 32)
#: Weight of the penalty on negative radiance of the 32 px reconstruction (module docstring).
NEGATIVE_PENALTY = 0.05


def negative_penalty(lighting: Tensor, valid: Tensor) -> Tensor:
    r"""``mean(relu(-L))`` over the batch, channels and valid pixels: how negative the lighting is.

    Args:
        lighting: linear mirror-ball lighting :math:`(B, 3, S, S)`.
        valid: the ball's pixels :math:`(S, S)`, bool.

    Returns:
        a scalar tensor, 0 for non-negative lighting.

    Examples:
        >>> valid = mirror_ball_valid(4)
        >>> float(negative_penalty(-torch.ones(1, 3, 4, 4) * valid, valid))
        1.0
    """
    return torch.relu(-lighting)[..., valid].mean()


class MultiScaleSH(nn.Module):
    r"""``sh`` for training: face crops -> unclamped SH lighting at 4, 8, 16 and 32 px.

    Args:
        estimator: the network to train (a new :class:`~kornia_ilum_sh.SHEstimator` by default);
            :attr:`estimator` is what gets exported.

    Returns:
        (``forward``) a :class:`~kornia_ilum_lab.train.models.MultiScaleLighting`: ``{size: (B, 3, size, size)}`` float32
        linear radiance, 0 off the ball, possibly negative (the order-2 function as it is), for :data:`SCALES`,
        and the spread head's ``log_spread`` (``None`` without it).

    Examples:
        >>> model = MultiScaleSH()
        >>> out = model(torch.rand(1, 3, 256, 256))
        >>> [tuple(out[s].shape[-2:]) for s in SCALES]
        [(4, 4), (8, 8), (16, 16), (32, 32)]
    """

    def __init__(self, estimator: SHEstimator | None = None) -> None:
        super().__init__()
        self.estimator = SHEstimator() if estimator is None else estimator

    def forward(self, crops: Tensor) -> MultiScaleLighting:
        sh, log_spread = self.estimator.decode(crops)
        with torch.autocast(sh.device.type, enabled=False):
            lighting = sh_reconstruct(sh.float(), SCALES[-1], "mirror_ball")
            return MultiScaleLighting(mirror_ball_pyramid(lighting, SCALES), log_spread)


class SHRecipe(Recipe):
    """``sh``: :class:`MultiScaleSH`, no discriminator; exports :attr:`MultiScaleSH.estimator`. Its one model
    option is ``spread_head`` (``--model spread_head=True``, for ``--lambda-nll``)."""

    name = "sh"

    def build(self, spread_head: bool = False) -> tuple[nn.Module, nn.Module | None]:
        return MultiScaleSH(SHEstimator(spread_head=spread_head)), None

    def estimator(self, model: nn.Module) -> nn.Module:
        return model.estimator

    def extra_losses(self, pred: dict[int, Tensor]) -> dict[str, Tensor]:
        """``{"negative": NEGATIVE_PENALTY * negative_penalty(pred[32])}`` (module docstring)."""
        lighting = pred[SCALES[-1]]
        valid = mirror_ball_valid(lighting.shape[-1], device=lighting.device)
        return {"negative": NEGATIVE_PENALTY * negative_penalty(lighting, valid)}
