r"""Several faces, one light: fuse the per-face estimates of a photo into one lighting.

A light far from the people in a photo (the sun, a sky, a ceiling) is the same for every face in it, so
several faces are several noisy readings of one lighting. :func:`fuse_faces` combines them in log space, a
weighted geometric mean per pixel,

.. math::

    \log L(\omega) = \frac{\sum_i w_i \log \max(L_i(\omega), \epsilon_i)}{\sum_i w_i},

because the faces' errors are mostly errors of scale (a face's albedo, its exposure), which a mean of logs
treats symmetrically (a face read 2x too bright and one read 2x too dark give the truth). The floor
:math:`\epsilon_i` is ``1e-6`` of face ``i``'s mean radiance, so a pixel that one estimator leaves at 0 cannot
drag the mean to 0. The weights are the caller's confidence in each face: :func:`kornia_ilum.estimate_lighting`
with ``faces="fused"`` uses the detector's score times the face box's side in pixels (a larger face shows its
shading over more pixels). Where the estimator gives the spread of each face's log energy ``b_i``
(:attr:`~kornia_ilum.estimators.LightingEstimate.log_energy_spread`), each weight is also divided by
``b_i^2``: a face that cannot settle the light's strength (a skin of unknown albedo, a face half in shadow)
counts as the inverse of its variance. The fused spread is then ``sqrt(sum_i p_i^2 b_i^2)`` with ``p_i`` the
normalised weights: the faces' errors taken as independent (their albedos are), so several faces narrow it.

Light near one person (a lamp beside one face) is not shared, and the fused estimate then averages two
different lightings: it is for photos whose light is distant.
"""

from __future__ import annotations

import torch
from torch import Tensor

from kornia_ilum.core.check import check_tensor
from kornia_ilum.core.dtypes import work_dtype
from kornia_ilum.core.errors import ShapeError, ValueCheckError
from kornia_ilum.estimators.base import LightingEstimate

__all__ = ["FLOOR", "fuse_faces"]

#: The floor of each face's radiance in the log mean, relative to that face's mean radiance.
FLOOR = 1e-6


def fuse_faces(estimate: LightingEstimate, weights: Tensor, groups: Tensor) -> LightingEstimate:
    r"""One lighting per group of faces: the weighted geometric mean of the module docstring.

    Args:
        estimate: per-face estimates, ``B`` of them.
        weights: :math:`(B,)` non-negative confidences; each group needs a positive total.
        groups: :math:`(B,)` int64, the group (photo) of each face, ``0 .. G - 1``, each used.

    Returns:
        a :class:`~kornia_ilum.estimators.LightingEstimate` of ``G`` lightings: ``mirror_ball``,
        ``log_mirror_ball`` (``log(1 + L)``), ``valid``, ``log_energy_spread`` where the faces have it (module
        docstring); ``sh`` is ``None`` (project the fused lighting with
        :func:`~kornia_ilum.sh.sh_project` if needed); ``boxes`` (where the input has them) is the box of each
        group's most confident face, and ``image_index`` the group.

    Raises:
        ShapeError: ``weights`` or ``groups`` does not have one entry per face.
        ValueCheckError: a negative weight, a group without positive weight, or a group index left unused.

    Shape:
        - estimate.mirror_ball: :math:`(B, 3, S, S)`; weights, groups: :math:`(B,)`
        - Output: ``mirror_ball``, ``log_mirror_ball``: :math:`(G, 3, S, S)`; ``boxes``: :math:`(G, 4)`

    Convention:
        docs/conventions.rst, "Mirror ball" and "Units of lighting": the fused lighting is in the faces' units,
        0 outside the ball.

    Examples:
        >>> from kornia_ilum.geometry import mirror_ball_valid
        >>> valid = mirror_ball_valid(32)
        >>> light = torch.stack([2.0 * valid, 0.5 * valid])[:, None].expand(2, 3, 32, 32).float()
        >>> faces = LightingEstimate(mirror_ball=light, valid=valid)
        >>> one = fuse_faces(faces, torch.ones(2), torch.zeros(2, dtype=torch.int64))
        >>> round(one.mirror_ball[0, 0, 16, 16].item(), 6)  # 2x too bright and 2x too dark: the truth
        1.0
        >>> sure = LightingEstimate(mirror_ball=light, valid=valid, log_energy_spread=torch.tensor([0.1, 1.0]))
        >>> one = fuse_faces(sure, torch.ones(2), torch.zeros(2, dtype=torch.int64))
        >>> round(one.mirror_ball[0, 0, 16, 16].item(), 3), round(one.log_energy_spread.item(), 4)  # the sure face
        (1.973, 0.0995)
    """
    light = estimate.mirror_ball
    n = light.shape[0]
    check_tensor(weights, "weights", [str(n)], nonnegative=True)
    if not isinstance(groups, Tensor) or groups.shape != (n,) or groups.dtype != torch.int64:
        got = tuple(groups.shape) if isinstance(groups, Tensor) else type(groups).__name__
        raise ShapeError(f"groups must be an int64 tensor of shape ({n},), one group per face, got {got}")
    count = int(groups.max()) + 1 if n else 0
    if n == 0 or int(groups.min()) < 0 or torch.unique(groups).numel() != count:
        raise ValueCheckError(f"groups must use every index of 0 .. G - 1, got {groups.tolist()}")
    work = light.to(work_dtype(light.dtype))
    valid = estimate.valid.to(light.device)
    mean = (work * valid).sum((1, 2, 3)) / (3 * valid.sum()).clamp(min=1)
    floor = (FLOOR * mean).clamp(min=torch.finfo(work.dtype).tiny)[:, None, None, None]
    logs = torch.log(torch.maximum(work, floor))
    w = weights.to(work)
    spread = estimate.log_energy_spread
    if spread is not None:
        b = spread.to(work).clamp(min=torch.finfo(work.dtype).tiny)
        w = w / b**2  # inverse variance
    total = torch.zeros(count, dtype=work.dtype, device=light.device).index_add_(0, groups, w)
    if bool((total <= 0).any()):
        raise ValueCheckError("every group of faces needs a positive total weight")
    fused_spread = None
    if spread is not None:
        p = w / total[groups]
        fused_spread = torch.zeros(count, dtype=work.dtype, device=light.device).index_add_(0, groups, (p * b) ** 2)
        fused_spread = fused_spread.sqrt().to(spread.dtype)
    summed = torch.zeros(count, *light.shape[1:], dtype=work.dtype, device=light.device)
    summed.index_add_(0, groups, logs * w[:, None, None, None])
    fused = torch.where(valid, torch.exp(summed / total[:, None, None, None]), 0.0)
    boxes = None
    if estimate.boxes is not None:
        best = [int(torch.nonzero(groups == g)[torch.argmax(w[groups == g])]) for g in range(count)]
        boxes = estimate.boxes[best]
    return LightingEstimate(mirror_ball=fused.to(light.dtype), valid=estimate.valid,
                            log_mirror_ball=torch.log1p(fused).to(light.dtype), boxes=boxes,
                            image_index=torch.arange(count, device=light.device), log_energy_spread=fused_spread)
