r"""Lighting errors of LeGendre et al. 2020: sphere-render loss ``L_rec``, relative radiance (SPEC.md)."""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn

from kornia_ilum.color.transfer import gamma_encode
from kornia_ilum.core.check import check_choice, check_positive_int, check_tensor, checks_active
from kornia_ilum.core.errors import ShapeError, ValueCheckError
from kornia_ilum.filters.soft_clip import soft_clip
from kornia_ilum.geometry.mirror_ball import (
    mirror_ball_solid_angles,
    mirror_ball_to_lights,
    mirror_ball_valid,
)
from kornia_ilum.render.relight import relight
from kornia_ilum.render.spheres import (
    SPHERE_SIZES,
    _check_brdf,
    _lighting_size,
    _shared_field,
    sphere_reflectance_field,
)

__all__ = [
    "MultiscaleReconstructionLoss",
    "ReconstructionLoss",
    "RelativeRadiance",
    "multiscale_reconstruction_loss",
    "reconstruction_loss",
    "relative_radiance",
]

_REDUCTIONS = ("mean", "sum", "none")
_HALF = (torch.float16, torch.bfloat16)


def _check_pair(pred: torch.Tensor, target: torch.Tensor) -> int:
    """Check two mirror-ball lighting batches of one shape; return their side ``S_L``."""
    s = _lighting_size(pred, "pred")
    _lighting_size(target, "target")
    if pred.shape != target.shape:
        raise ShapeError(
            f"pred and target must have the same shape, got {tuple(pred.shape)} and {tuple(target.shape)}"
        )
    return s


def _check_reduction(reduction: str) -> None:
    check_choice(reduction, "reduction", _REDUCTIONS)


def _reduce(x: torch.Tensor, reduction: str) -> torch.Tensor:
    return x.mean() if reduction == "mean" else x.sum() if reduction == "sum" else x


def _l_rec(field: torch.Tensor, pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Per-item ``L_rec``, ``(B,)``, given the on-sphere rows ``(P_valid, N)`` of one sphere's field."""
    size = (1, field.shape[0])
    render_pred = relight(field, mirror_ball_to_lights(pred), size)
    render_target = relight(field, mirror_ball_to_lights(target), size)
    diff = gamma_encode(soft_clip(render_pred), 2.2) - gamma_encode(soft_clip(render_target), 2.2)
    return diff.abs().flatten(1).mean(1)


def reconstruction_loss(
    pred: torch.Tensor, target: torch.Tensor, brdf: str, size: int = 32, reduction: str = "mean"
) -> torch.Tensor:
    r"""The sphere-render loss ``L_rec`` of LeGendre et al. 2020 for one reference sphere.

    Both lightings render the sphere ``brdf`` (:func:`~kornia_ilum.render.render_spheres`); the loss is the
    mean over the pixels on the sphere and the channels of
    ``| softclip(I_pred)^(1/2.2) - softclip(I_gt)^(1/2.2) |``, with
    :func:`~kornia_ilum.filters.soft_clip` and :func:`~kornia_ilum.color.gamma_encode` (``x^(1/2.2)`` with a
    finite slope at 0, so the gradient stays finite on black pixels).

    Args:
        pred: predicted linear mirror-ball lighting ``(B, 3, S_L, S_L)`` (``S_L = 32`` in the paper).
        target: ground-truth lighting of the same shape.
        brdf: the sphere, ``"diffuse"``, ``"matte_silver"`` or ``"mirror"``.
        size: side of the sphere render in pixels, one of :data:`~kornia_ilum.render.SPHERE_SIZES`.
        reduction: ``"mean"`` over the batch (a scalar), ``"sum"``, or ``"none"`` (one loss per item).

    Returns:
        the loss: a scalar, or ``(B,)`` for ``reduction="none"``.

    Shape:
        - pred, target: :math:`(B, 3, S_L, S_L)`
        - Output: :math:`()` or :math:`(B,)`

    Convention:
        SPEC.md, "The paper's error measure L_rec": the spheres of SPEC.md, "Reference spheres", shaded
        with lighting in the units of the input image, so the soft clip at 1 is the camera's white point.

    Examples:
        >>> gt = torch.ones(2, 3, 32, 32)
        >>> reconstruction_loss(gt, gt, "diffuse").item()
        0.0
        >>> round(reconstruction_loss(0.5 * gt, gt, "mirror", size=16).item(), 4)
        0.2471
    """
    s_l = _check_pair(pred, target)
    _check_brdf(brdf)
    check_positive_int(size, "size", allowed=SPHERE_SIZES)
    _check_reduction(reduction)
    field = _shared_field(brdf, size, s_l, pred.device, pred.dtype, on_sphere=True)
    return _reduce(_l_rec(field, pred, target), reduction)


def multiscale_reconstruction_loss(
    pred: torch.Tensor,
    target: torch.Tensor,
    brdf: str,
    sizes: Sequence[int] = (4, 8, 16, 32),
    reduction: str = "mean",
) -> torch.Tensor:
    r"""``L_rec`` averaged over several sphere resolutions.

    ``(1 / K) sum_k reconstruction_loss(pred, target, brdf, sizes[k])``: the spheres are rendered from the
    same lighting at every size in ``sizes``, shaded at each pixel centre; the coarse renders weigh the
    low-frequency content (overall level and colour) as much as the 32 x 32 render weighs detail. Each
    scale is a mean over its own sphere pixels, so every scale counts equally whatever its pixel count.
    For a generator with one output per scale (MSG-GAN style), call :func:`reconstruction_loss` on each.

    Args:
        pred: predicted linear mirror-ball lighting ``(B, 3, S_L, S_L)``.
        target: ground-truth lighting of the same shape.
        brdf: the sphere, ``"diffuse"``, ``"matte_silver"`` or ``"mirror"``.
        sizes: sphere resolutions, each in :data:`~kornia_ilum.render.SPHERE_SIZES`.
        reduction: ``"mean"``, ``"sum"`` (over the batch) or ``"none"``.

    Returns:
        a scalar, or ``(B,)`` for ``reduction="none"``.

    Examples:
        >>> gt = torch.ones(1, 3, 32, 32)
        >>> multiscale_reconstruction_loss(gt, gt, "matte_silver").item()
        0.0
    """
    s_l = _check_pair(pred, target)
    _check_brdf(brdf)
    sizes = _check_sizes(sizes)
    _check_reduction(reduction)
    per_scale = [
        _l_rec(_shared_field(brdf, s, s_l, pred.device, pred.dtype, True), pred, target) for s in sizes
    ]
    return _reduce(torch.stack(per_scale).mean(0), reduction)


def _check_sizes(sizes: Sequence[int]) -> tuple[int, ...]:
    sizes = tuple(sizes) if not isinstance(sizes, int) else (sizes,)
    if not sizes:
        raise ValueCheckError("sizes must name at least one sphere size")
    for s in sizes:
        check_positive_int(s, "sizes", allowed=SPHERE_SIZES)
    return sizes


def relative_radiance(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    r"""Relative radiance error per channel: ``(sum(L_gt) - sum(L_pred)) / sum(L_gt)``.

    Sums are over the mirror ball, weighted by each pixel's exact solid angle
    (:func:`~kornia_ilum.geometry.mirror_ball_solid_angles`), so they are the total radiant intensity of
    each lighting. Negative means the estimate added light; 0 is the right total; 1 is a black estimate.

    Args:
        pred: predicted linear mirror-ball lighting ``(B, 3, S, S)``.
        target: ground-truth lighting of the same shape; non-negative, with a positive total in every
            channel.

    Returns:
        ``(B, 3)`` relative errors. Half-precision inputs are summed in float32 (a float16 sum of an HDR
        sun overflows) and the result is cast back.

    Shape:
        - pred, target: :math:`(B, 3, S, S)`
        - Output: :math:`(B, 3)`

    Convention:
        SPEC.md, "Relative radiance"; the mirror-ball grid of SPEC.md (equal-area, exact rim solid angles).

    Raises:
        ValueCheckError: ``target`` has a negative value or a channel with zero total radiance.

    Examples:
        >>> gt = torch.ones(1, 3, 32, 32)
        >>> relative_radiance(2.0 * gt, gt)
        tensor([[-1., -1., -1.]])
    """
    s = _check_pair(pred, target)
    check_tensor(target, "target", ["B", "3", "S", "S"], nonnegative=True)
    work = torch.float32 if pred.dtype in _HALF else pred.dtype
    omega = mirror_ball_solid_angles(s, device=pred.device, dtype=work)
    total_gt = (target.to(work) * omega).sum((-2, -1))
    total_pred = (pred.to(work) * omega).sum((-2, -1))
    if checks_active() and not torch.compiler.is_compiling() and bool((total_gt <= 0).any()):
        raise ValueCheckError(
            "target must have a positive total radiance in every channel (it is the denominator)"
        )
    return ((total_gt - total_pred) / total_gt).to(pred.dtype)


class ReconstructionLoss(nn.Module):
    r"""Module twin of :func:`reconstruction_loss`; the sphere's field is a non-persistent buffer.

    Args:
        brdf: the sphere, ``"diffuse"``, ``"matte_silver"`` or ``"mirror"``.
        size: side of the sphere render.
        reduction: ``"mean"``, ``"sum"`` or ``"none"``.
        lighting_size: side ``S_L`` of the lighting the module accepts.

    Examples:
        >>> loss = ReconstructionLoss("mirror")
        >>> loss(torch.zeros(1, 3, 32, 32), torch.zeros(1, 3, 32, 32)).item()
        0.0
    """

    def __init__(self, brdf: str, size: int = 32, reduction: str = "mean", lighting_size: int = 32) -> None:
        super().__init__()
        _check_reduction(reduction)
        self.brdf, self.size, self.reduction, self.lighting_size = brdf, size, reduction, lighting_size
        check_positive_int(size, "size", allowed=SPHERE_SIZES)
        field = sphere_reflectance_field(brdf, size, lighting_size)[mirror_ball_valid(size).flatten()]
        self.register_buffer("field", field, persistent=False)

    def forward(self, pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        _check_lighting_size(_check_pair(pred, target), self.lighting_size, pred)
        return _reduce(_l_rec(self.field.to(pred.dtype), pred, target), self.reduction)

    def extra_repr(self) -> str:
        return f"brdf={self.brdf!r}, size={self.size}, reduction={self.reduction!r}"


class MultiscaleReconstructionLoss(nn.Module):
    r"""Module twin of :func:`multiscale_reconstruction_loss`; one field buffer per size.

    Examples:
        >>> loss = MultiscaleReconstructionLoss("diffuse", sizes=(4, 8))
        >>> loss(torch.ones(1, 3, 32, 32), torch.ones(1, 3, 32, 32)).item()
        0.0
    """

    def __init__(
        self,
        brdf: str,
        sizes: Sequence[int] = (4, 8, 16, 32),
        reduction: str = "mean",
        lighting_size: int = 32,
    ) -> None:
        super().__init__()
        _check_reduction(reduction)
        self.brdf, self.sizes, self.reduction, self.lighting_size = (
            brdf,
            _check_sizes(sizes),
            reduction,
            lighting_size,
        )
        for s in self.sizes:
            field = sphere_reflectance_field(brdf, s, lighting_size)[mirror_ball_valid(s).flatten()]
            self.register_buffer(f"field_{s}", field, persistent=False)

    def forward(self, pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        _check_lighting_size(_check_pair(pred, target), self.lighting_size, pred)
        per_scale = [_l_rec(getattr(self, f"field_{s}").to(pred.dtype), pred, target) for s in self.sizes]
        return _reduce(torch.stack(per_scale).mean(0), self.reduction)

    def extra_repr(self) -> str:
        return f"brdf={self.brdf!r}, sizes={self.sizes}, reduction={self.reduction!r}"


class RelativeRadiance(nn.Module):
    r"""Module twin of :func:`relative_radiance`.

    Examples:
        >>> RelativeRadiance()(torch.ones(1, 3, 8, 8), torch.ones(1, 3, 8, 8))
        tensor([[0., 0., 0.]])
    """

    def forward(self, pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        return relative_radiance(pred, target)


def _check_lighting_size(s_l: int, expected: int, pred: torch.Tensor) -> None:
    if s_l != expected:
        raise ShapeError(f"pred must have shape (B, 3, {expected}, {expected}), got {tuple(pred.shape)}")
