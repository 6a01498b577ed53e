r"""Soft clip: a monotone, differentiable clamp to ``[0, 1]``.

Convention:
    docs/conventions.rst, "The paper's error measure L_rec": the ``softclip`` of the sphere-render loss.
"""

from __future__ import annotations

import math

import torch
from torch import nn

from kornia_ilum.core.check import check_tensor, checks_active
from kornia_ilum.core.errors import NonFiniteError, ValueCheckError

__all__ = ["soft_clip", "soft_clip_unchecked", "SoftClip"]


def soft_clip(x: torch.Tensor, sharpness: float = 20.0) -> torch.Tensor:
    r"""Monotone clamp to ``[0, 1]``: 0 for ``x <= 0``, a smooth ``min(x, 1)`` above, saturating at 1.

    .. math::

        f(x) = \frac{x^+ - \operatorname{softplus}(\beta (x^+ - 1))/\beta + c}{1 + c},
        \qquad c = \operatorname{softplus}(-\beta)/\beta, \qquad x^+ = \max(x, 0)

    This is the softplus-smoothed minimum, evaluated above the knee in the equivalent form
    ``1 - softplus(-beta (x - 1)) / beta`` so that no term grows with ``x`` (no cancellation for large
    inputs, no overflow in float16), shifted so that
    ``f(0) = 0`` and scaled so that ``f(+inf) = 1``. For ``x > 0`` it is infinitely differentiable and
    strictly increasing (``f'(x) = (1 - sigmoid(beta (x - 1))) / (1 + c) > 0``), equals ``x`` up to
    ``e^{-beta (1 - x)} / beta`` below the knee, and ``f(1) = 1 - ln 2 / beta``.

    Negative values map to 0 (docs/conventions.rst: negative sphere values, for example renders of SH lighting
    with negative lobes, count as 0), with gradient 0. So ``f`` is monotone (non-decreasing), continuous, and
    differentiable everywhere except for the kink at 0, where the gradient used is the right-hand one,
    ``f'(0+) = (1 - sigmoid(-beta)) / (1 + c)`` (1 to within ``2e-9`` for ``beta = 20``); every gradient is
    finite. Without the clamp the formula would pass negatives through almost unchanged, and a power law
    after it (``x^(1/2.2)``) would then blow them up or return NaN.

    Half-precision inputs are computed in float32 and cast back. ``+inf`` (for example ``1e6`` cast to
    float16) maps to 1 with gradient 0.

    Args:
        x: tensor of any shape, typically linear HDR sphere renders.
        sharpness: :math:`\beta > 0`, the knee's sharpness. Larger is closer to a hard clip.

    Returns:
        tensor of the shape and dtype of ``x``, in ``[0, 1]``.

    Raises:
        NonFiniteError: ``x`` holds NaN.
        ValueCheckError: ``sharpness`` is not positive.

    Shape:
        - Input: :math:`(*)`
        - Output: :math:`(*)`

    Convention:
        docs/conventions.rst, "The paper's error measure ``L_rec``": the smooth, monotone, differentiable
        clamp ``softclip`` applied to the sphere renders; negative values count as 0.

    Examples:
        >>> soft_clip(torch.tensor([-3.0, 0.0, 0.5, 1.0, 1e6]))
        tensor([0.0000, 0.0000, 0.5000, 0.9653, 1.0000])
    """
    check_tensor(x, "x", None, finite=False, nonempty=False)
    if not (isinstance(sharpness, (int, float)) and sharpness > 0 and math.isfinite(sharpness)):
        raise ValueCheckError(f"sharpness must be a finite positive number, got {sharpness!r}")
    if checks_active() and not torch.compiler.is_compiling() and not x.is_meta and bool(torch.isnan(x).any()):
        raise NonFiniteError("x must not hold NaN")
    return soft_clip_unchecked(x, float(sharpness))


def soft_clip_unchecked(x: torch.Tensor, beta: float = 20.0) -> torch.Tensor:
    r""":func:`soft_clip` without the argument checks, for callers that checked their inputs.

    The same values and gradients as :func:`soft_clip` with ``sharpness=beta``; nothing is validated (no
    NaN scan of ``x``), so a loss that checked its inputs once does not pay for a second pass over the data.

    Args:
        x: tensor of any shape.
        beta: the knee's sharpness, > 0.

    Returns:
        tensor of the shape and dtype of ``x``, in ``[0, 1]``.

    Shape:
        - Input: :math:`(*)`
        - Output: :math:`(*)`

    Examples:
        >>> soft_clip_unchecked(torch.tensor([-3.0, 0.0, 0.5, 1.0, 1e6]))
        tensor([0.0000, 0.0000, 0.5000, 0.9653, 1.0000])
    """
    work = x.float() if x.dtype in (torch.float16, torch.bfloat16) else x
    # negatives count as 0 (docs/conventions.rst); clamp's gradient at exactly 0 is 1
    work = work.clamp(min=0.0)
    softplus = nn.functional.softplus
    c = softplus(torch.tensor(-beta, dtype=work.dtype, device=work.device)) / beta  # cancels f(0) exactly
    t = work - 1.0
    # Two exact forms of min(x, 1) - softplus(-beta |t|) / beta, each evaluated only where it is stable:
    # below the knee x - softplus(beta t) / beta, above it 1 - softplus(-beta t) / beta. Clamping inside
    # each branch keeps the unselected one finite, so the gradient through torch.where stays finite too.
    below = work - softplus(beta * t.clamp(max=0.0)) / beta
    above = 1.0 - softplus(-beta * t.clamp(min=0.0)) / beta
    y = (torch.where(t <= 0, below, above) + c) / (1.0 + c)
    return y.to(x.dtype)


class SoftClip(nn.Module):
    r"""Module twin of :func:`soft_clip`.

    Args:
        sharpness: :math:`\beta`, see :func:`soft_clip`.

    Shape:
        - Input: :math:`(*)`
        - Output: :math:`(*)`

    Examples:
        >>> SoftClip(sharpness=5.0)(torch.tensor([0.5, 1.0, 2.0]))
        tensor([0.4849, 0.8616, 0.9987])
    """

    def __init__(self, sharpness: float = 20.0) -> None:
        super().__init__()
        self.sharpness = sharpness

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return soft_clip(x, self.sharpness)

    def extra_repr(self) -> str:
        return f"sharpness={self.sharpness}"
