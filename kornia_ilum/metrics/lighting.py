r"""Lighting errors of LeGendre et al. 2020: sphere-render loss ``L_rec``, relative radiance.

Convention:
    docs/conventions.rst, "The paper's error measure L_rec" and "Relative radiance".
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache

import torch
from torch import nn

from kornia_ilum.core.check import check_choice, check_positive_int, check_tensor, checks_active
from kornia_ilum.core.dtypes import HALF, saturating_cast
from kornia_ilum.core.errors import ShapeError, ValueCheckError
from kornia_ilum.geometry.mirror_ball import (
    mirror_ball_solid_angles,
    mirror_ball_to_lights,
    mirror_ball_valid,
)
from kornia_ilum.render.spheres import (
    SPHERE_SIZES,
    SpherePlan,
    check_brdf,
    check_sphere_lighting,
    check_sphere_sizes,
    gamma_knee,
    render_plan,
    sphere_plan,
)

__all__ = [
    "LightingEnergy",
    "MultiscaleReconstructionLoss",
    "ReconstructionLoss",
    "RelativeRadiance",
    "TotalRadiance",
    "check_lighting_pair",
    "lighting_energy",
    "multiscale_reconstruction_loss",
    "reconstruction_loss",
    "relative_radiance",
    "total_radiance",
]

_REDUCTIONS = ("mean", "sum", "none")
_HALF = (torch.float16, torch.bfloat16)


def check_lighting_pair(pred: torch.Tensor, target: torch.Tensor, lighting_size: int | None = None) -> int:
    r"""Check a predicted and a ground-truth mirror-ball lighting batch of one shape; return their side.

    Each is checked by :func:`~kornia_ilum.render.check_sphere_lighting` (``(B, 3, S_L, S_L)``, finite,
    ``S_L`` in :data:`~kornia_ilum.render.SPHERE_SIZES`), then their shapes are compared, then ``S_L`` with
    ``lighting_size``.

    Args:
        pred: predicted lighting.
        target: ground-truth lighting.
        lighting_size: the side ``S_L`` required (a module's), or ``None`` for any.

    Returns:
        the side ``S_L``.

    Raises:
        ShapeError: a wrong shape, different shapes, or a side other than ``lighting_size``.
        TypeCheckError: no floating-point tensor.
        NonFiniteError: NaN or Inf in either.

    Shape:
        - pred, target: :math:`(B, 3, S_L, S_L)`

    Convention:
        docs/conventions.rst, "Mirror ball": both are mirror-ball lighting.

    Examples:
        >>> check_lighting_pair(torch.ones(2, 3, 16, 16), torch.zeros(2, 3, 16, 16))
        16
    """
    s = check_sphere_lighting(pred, "pred")
    check_sphere_lighting(target, "target")
    if pred.shape != target.shape:
        raise ShapeError(
            f"pred and target must have the same shape, got {tuple(pred.shape)} and {tuple(target.shape)}"
        )
    if lighting_size is not None and s != lighting_size:
        raise ShapeError(
            f"pred must have shape (B, 3, {lighting_size}, {lighting_size}), got {tuple(pred.shape)}"
        )
    return s


def _check_reduction(reduction: str) -> None:
    check_choice(reduction, "reduction", _REDUCTIONS)


def _reduce(x: torch.Tensor, reduction: str) -> torch.Tensor:
    return x.mean() if reduction == "mean" else x.sum() if reduction == "sum" else x


def _l_rec(
    plan: SpherePlan, counts: tuple[int, ...], *, pred: torch.Tensor, target: torch.Tensor, knee: float
) -> torch.Tensor:
    """Per-item ``L_rec`` averaged over the scales, ``(B,)``, from a render plan of one sphere at all scales.

    The target's renders are made without autograd unless it requires a gradient.
    """
    encoded_pred = render_plan(plan, mirror_ball_to_lights(pred), knee=knee)
    with torch.set_grad_enabled(torch.is_grad_enabled() and target.requires_grad):
        encoded_target = render_plan(plan, mirror_ball_to_lights(target), knee=knee)
    diff = (encoded_pred - encoded_target).abs().sum(1)  # (B, sum P)
    if len(counts) == 1:
        return diff.mean(1) / 3.0
    weights = torch.cat([diff.new_full((n,), 1.0 / (3 * n * len(counts))) for n in counts])
    return diff @ weights


@lru_cache(maxsize=16)
def _counts(sizes: tuple[int, ...]) -> tuple[int, ...]:
    return tuple(int(mirror_ball_valid(s).sum()) for s in sizes)


def reconstruction_loss(
    pred: torch.Tensor,
    target: torch.Tensor,
    *,
    brdf: str,
    size: int = 32,
    reduction: str = "mean",
    gamma: str = "exact",
) -> torch.Tensor:
    r"""The sphere-render loss ``L_rec`` of LeGendre et al. 2020 for one reference sphere.

    Both lightings render the sphere ``brdf`` at ``size`` (:func:`~kornia_ilum.render.render_spheres`:
    from the lighting brought down to ``size`` by the energy-keeping pyramid, so a coarse sphere sees all
    of the lighting); the loss is the mean over the pixels on the sphere and the channels of
    ``| softclip(I_pred)^(1/2.2) - softclip(I_gt)^(1/2.2) |`` (:func:`~kornia_ilum.render.encode_sphere`:
    :func:`~kornia_ilum.filters.soft_clip`, which counts negative values as 0, then the power).

    Use ``gamma="exact"`` (the default) to evaluate: it is the metric of docs/conventions.rst. Train with
    ``gamma="safe"``, whose gradient stays bounded on black pixels; targets precomputed for it with
    :func:`~kornia_ilum.render.sphere_pyramid` must use the same mode.

    Args:
        pred: predicted linear mirror-ball lighting ``(B, 3, S_L, S_L)`` (``S_L = 32`` in the paper).
        target: ground-truth lighting of the same shape.
        brdf: the sphere, ``"diffuse"``, ``"matte_silver"`` or ``"mirror"``.
        size: side of the sphere render in pixels, one of :data:`~kornia_ilum.render.SPHERE_SIZES`.
        reduction: ``"mean"`` over the batch (a scalar), ``"sum"``, or ``"none"`` (one loss per item).
        gamma: the power ``x^(1/2.2)``: ``"exact"`` (default; the metric of docs/conventions.rst, gradient
            unbounded near 0) or ``"safe"`` (for training: the chord below 1e-6, finite slope at 0, at most
            5.3e-4 below the exact power), see :func:`~kornia_ilum.render.encode_sphere`.

    Returns:
        the loss: a scalar, or ``(B,)`` for ``reduction="none"``.

    Shape:
        - pred, target: :math:`(B, 3, S_L, S_L)`
        - Output: :math:`()` or :math:`(B,)`

    Convention:
        docs/conventions.rst, "The paper's error measure L_rec" and "Reference spheres" (multi-scale): the
        spheres shaded with lighting in the units of the input image, so the soft clip at 1 is the camera's
        white point.

    Examples:
        >>> gt = torch.ones(2, 3, 32, 32)
        >>> reconstruction_loss(gt, gt, brdf="diffuse").item()
        0.0
        >>> round(reconstruction_loss(0.5 * gt, gt, brdf="mirror", size=16).item(), 3)
        0.247
        >>> round(reconstruction_loss(-0.1 * gt, gt, brdf="diffuse").item(), 3)  # negative light counts as 0
        0.903
    """
    s_l = check_lighting_pair(pred, target)
    check_brdf(brdf)
    check_positive_int(size, "size", allowed=SPHERE_SIZES)
    _check_reduction(reduction)
    knee = gamma_knee(gamma)
    plan = sphere_plan((brdf,), (size,), lighting_size=s_l, device=pred.device, dtype=pred.dtype)
    return _reduce(_l_rec(plan, _counts((size,)), pred=pred, target=target, knee=knee), reduction)


def multiscale_reconstruction_loss(
    pred: torch.Tensor,
    target: torch.Tensor,
    *,
    brdf: str,
    sizes: Sequence[int] = (4, 8, 16, 32),
    reduction: str = "mean",
    gamma: str = "exact",
) -> torch.Tensor:
    r"""``L_rec`` averaged over several sphere resolutions.

    ``(1 / K) sum_k reconstruction_loss(pred, target, brdf, sizes[k])``: the sphere of size ``s`` is
    rendered from the lighting brought down to ``s`` by the energy-keeping pyramid (docs/conventions.rst,
    "Multi-scale"; :func:`~kornia_ilum.render.mirror_ball_pyramid`), shaded at each pixel centre; the coarse
    renders weigh the low-frequency content (overall level and colour) as much as the 32 x 32 render weighs
    detail. Each scale is a mean over its own sphere pixels, so every scale counts equally whatever its pixel
    count. All the scales are one matrix product per lighting. For a generator with one output per scale
    (MSG-GAN style), call :func:`reconstruction_loss` on each.

    Args:
        pred: predicted linear mirror-ball lighting ``(B, 3, S_L, S_L)``.
        target: ground-truth lighting of the same shape.
        brdf: the sphere, ``"diffuse"``, ``"matte_silver"`` or ``"mirror"``.
        sizes: sphere resolutions, each in :data:`~kornia_ilum.render.SPHERE_SIZES`.
        reduction: ``"mean"``, ``"sum"`` (over the batch) or ``"none"``.
        gamma: ``"exact"`` (default, the metric) or ``"safe"`` (training), see :func:`reconstruction_loss`.

    Returns:
        a scalar, or ``(B,)`` for ``reduction="none"``.

    Shape:
        - pred, target: :math:`(B, 3, S_L, S_L)`
        - Output: :math:`()` or :math:`(B,)`

    Convention:
        docs/conventions.rst, "The paper's error measure ``L_rec``" and "Reference spheres" (multi-scale: the
        lighting at each size keeps the energy of the lighting at ``S_L``).

    Examples:
        >>> gt = torch.ones(1, 3, 32, 32)
        >>> multiscale_reconstruction_loss(gt, gt, brdf="matte_silver").item()
        0.0
        >>> pred = gt.clone()
        >>> pred[0, :, 16, 16] = 50.0  # one bright pixel: every scale sees it
        >>> bool(multiscale_reconstruction_loss(pred, gt, brdf="mirror", sizes=(4,), gamma="safe") > 0)
        True
    """
    s_l = check_lighting_pair(pred, target)
    check_brdf(brdf)
    sizes = check_sphere_sizes(sizes)
    _check_reduction(reduction)
    knee = gamma_knee(gamma)
    plan = sphere_plan((brdf,), sizes, lighting_size=s_l, device=pred.device, dtype=pred.dtype)
    return _reduce(_l_rec(plan, _counts(sizes), pred=pred, target=target, knee=knee), reduction)


def total_radiance(mirror_ball: torch.Tensor, dtype: torch.dtype | None = None) -> torch.Tensor:
    r"""Each channel's radiance summed over the sphere, weighted by each pixel's exact solid angle
    (:func:`~kornia_ilum.geometry.mirror_ball_solid_angles`, 0 outside the ball): ``(B, 3)``, computed in
    ``dtype`` (default: the input's; half precision is summed in float32 and saturates at the dtype's largest
    finite value on the way back, :mod:`kornia_ilum.core.dtypes`). A uniform lighting of radiance 1 gives
    :math:`4\pi`. Raises :class:`~kornia_ilum.core.errors.NonFiniteError` on NaN or Inf.

    Args:
        mirror_ball: linear mirror-ball lighting (or any ``(C, S, S)`` images on the mirror-ball grid).
        dtype: the dtype to sum in, or ``None`` for the input's (half precision: float32, cast back).

    Returns:
        the per-channel totals in ``dtype`` (the input's dtype when ``dtype`` is ``None``).

    Raises:
        NonFiniteError: NaN or Inf in ``mirror_ball``.
        ShapeError: fewer than 3 dimensions.

    Shape:
        - mirror_ball: :math:`(*, C, S, S)`
        - Output: :math:`(*, C)`

    Convention:
        docs/conventions.rst, "Mirror ball" (the exact solid angles, rim slivers included) and "Relative
        radiance" (the sums it compares).

    Examples:
        >>> import math
        >>> t = total_radiance(torch.ones(1, 3, 32, 32), torch.float64)
        >>> bool(torch.allclose(t, torch.full((1, 3), 4 * math.pi, dtype=torch.float64)))
        True
    """
    check_tensor(mirror_ball, "mirror_ball", ["*", "C", "S", "S"])
    if dtype is None and mirror_ball.dtype in HALF:  # summed in float32, saturating on the way back
        return saturating_cast(total_radiance(mirror_ball, torch.float32), mirror_ball.dtype)
    work = mirror_ball.dtype if dtype is None else dtype
    omega = mirror_ball_solid_angles(mirror_ball.shape[-1], device=mirror_ball.device, dtype=work)
    return (mirror_ball.to(work) * omega).sum((-2, -1))


def lighting_energy(mirror_ball: torch.Tensor) -> torch.Tensor:
    r"""The lighting's energy: the integral over the sphere of the mean over R, G, B (the scalar of
    :func:`total_radiance`: its mean over the channels).

    :math:`E = \sum_p \Omega_p \tfrac{1}{3}(L_r + L_g + L_b)_p` over the valid pixels, with the exact solid
    angles of :func:`~kornia_ilum.geometry.mirror_ball_solid_angles` (they sum to :math:`4\pi`): a uniform
    lighting of radiance 1 has :math:`E = 4\pi`.

    Args:
        mirror_ball: linear lighting (docs/conventions.rst, "Mirror ball").

    Returns:
        ``(B,)`` energies, in the lighting's units times steradians.

    Shape:
        - mirror_ball: :math:`(B, 3, S, S)`
        - Output: :math:`(B,)`

    Convention:
        docs/conventions.rst, "Mirror ball" (the solid angles, summing to 4 pi) and "Units of lighting".

    Examples:
        >>> import math
        >>> from kornia_ilum.geometry import mirror_ball_valid
        >>> E = lighting_energy(torch.ones(2, 3, 32, 32) * mirror_ball_valid(32))
        >>> bool(torch.allclose(E, torch.full((2,), 4 * math.pi)))
        True
    """
    check_tensor(mirror_ball, "mirror_ball", ["B", "3", "S", "S"])
    s = mirror_ball.shape[-1]
    omega = mirror_ball_solid_angles(s, device=mirror_ball.device, dtype=mirror_ball.dtype)
    return (mirror_ball.mean(1) * omega).sum((-2, -1))  # omega is 0 on the invalid pixels


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

    Raises:
        ValueCheckError: ``target`` has a negative value or a channel with zero total radiance.

    Shape:
        - pred, target: :math:`(B, 3, S, S)`
        - Output: :math:`(B, 3)`

    Convention:
        docs/conventions.rst, "Relative radiance"; its mirror-ball grid (equal-area, exact rim solid angles).

    Examples:
        >>> gt = torch.ones(1, 3, 32, 32)
        >>> relative_radiance(2.0 * gt, gt)
        tensor([[-1., -1., -1.]])
    """
    check_lighting_pair(pred, target)
    check_tensor(target, "target", ["B", "3", "S", "S"], nonnegative=True)
    work = torch.float32 if pred.dtype in _HALF else pred.dtype
    total_gt, total_pred = total_radiance(target, work), total_radiance(pred, work)
    if checks_active() and not torch.compiler.is_compiling() and not total_gt.is_meta and bool((total_gt <= 0).any()):
        raise ValueCheckError(
            "target must have a positive total radiance in every channel (it is the denominator)"
        )
    return ((total_gt - total_pred) / total_gt).to(pred.dtype)


class _PlanBuffers(nn.Module):
    """Holds a render plan of one sphere at several scales as non-persistent buffers."""

    def _register_plan(self, brdf: str, sizes: tuple[int, ...], lighting_size: int) -> None:
        plan = sphere_plan(
            (brdf,), sizes, lighting_size=lighting_size, device=torch.device("cpu"), dtype=torch.float32
        )
        self.register_buffer("field", plan.field.clone(), persistent=False)
        self.register_buffer("index", plan.index.clone(), persistent=False)
        self.register_buffer("order", None if plan.order is None else plan.order.clone(), persistent=False)
        self.counts = _counts(sizes)
        self._plan_sizes = tuple(sizes)

    def _plan(self, dtype: torch.dtype) -> SpherePlan:
        if dtype == torch.float64:  # the float64 field, not the float32 buffer rounded up (class docstrings)
            return sphere_plan(
                (self.brdf,),
                self._plan_sizes,
                lighting_size=self.lighting_size,
                device=self.field.device,
                dtype=dtype,
            )
        return SpherePlan(self.field.to(dtype), self.index, self.order)


class ReconstructionLoss(_PlanBuffers):
    r"""Module twin of :func:`reconstruction_loss`; the sphere's field is a non-persistent float32 buffer (float64
    inputs use the functional's float64 field instead, so they are not rounded through float32).

    Args:
        brdf: the sphere, ``"diffuse"``, ``"matte_silver"`` or ``"mirror"``.
        size: side of the sphere render.
        reduction: ``"mean"``, ``"sum"`` or ``"none"``.
        lighting_size: side ``S_L`` of the lighting the module accepts.
        gamma: ``"exact"`` (default, the metric) or ``"safe"`` (training), see :func:`reconstruction_loss`.

    Shape:
        - pred, target: :math:`(B, 3, S_L, S_L)` with ``S_L = lighting_size``
        - Output: :math:`()` or :math:`(B,)` for ``reduction="none"``

    Examples:
        >>> loss = ReconstructionLoss("mirror", gamma="safe")
        >>> loss(torch.zeros(1, 3, 32, 32), torch.zeros(1, 3, 32, 32)).item()
        0.0
    """

    def __init__(
        self,
        brdf: str,
        *,
        size: int = 32,
        reduction: str = "mean",
        lighting_size: int = 32,
        gamma: str = "exact",
    ) -> None:
        super().__init__()
        _check_reduction(reduction)
        check_brdf(brdf)
        check_positive_int(size, "size", allowed=SPHERE_SIZES)
        check_positive_int(lighting_size, "lighting_size", allowed=SPHERE_SIZES)
        self.knee = gamma_knee(gamma)
        self.brdf, self.size, self.reduction, self.lighting_size, self.gamma = (
            brdf,
            size,
            reduction,
            lighting_size,
            gamma,
        )
        self._register_plan(brdf, (size,), lighting_size)

    def forward(self, pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        check_lighting_pair(pred, target, self.lighting_size)
        return _reduce(
            _l_rec(self._plan(pred.dtype), self.counts, pred=pred, target=target, knee=self.knee),
            self.reduction,
        )

    def extra_repr(self) -> str:
        return f"brdf={self.brdf!r}, size={self.size}, reduction={self.reduction!r}, gamma={self.gamma!r}"


class MultiscaleReconstructionLoss(_PlanBuffers):
    r"""Module twin of :func:`multiscale_reconstruction_loss`; the fields of all sizes are one buffer.

    Args:
        brdf: the sphere, ``"diffuse"``, ``"matte_silver"`` or ``"mirror"``.
        sizes: sphere resolutions.
        reduction: ``"mean"``, ``"sum"`` or ``"none"``.
        lighting_size: side ``S_L`` of the lighting the module accepts.
        gamma: ``"exact"`` (default, the metric) or ``"safe"`` (training), see :func:`reconstruction_loss`.

    Shape:
        - pred, target: :math:`(B, 3, S_L, S_L)` with ``S_L = lighting_size``
        - Output: :math:`()` or :math:`(B,)` for ``reduction="none"``

    Examples:
        >>> loss = MultiscaleReconstructionLoss("diffuse", sizes=(4, 8))
        >>> loss(torch.ones(1, 3, 32, 32), torch.ones(1, 3, 32, 32)).item()
        0.0
    """

    def __init__(
        self,
        brdf: str,
        *,
        sizes: Sequence[int] = (4, 8, 16, 32),
        reduction: str = "mean",
        lighting_size: int = 32,
        gamma: str = "exact",
    ) -> None:
        super().__init__()
        _check_reduction(reduction)
        check_brdf(brdf)
        check_positive_int(lighting_size, "lighting_size", allowed=SPHERE_SIZES)
        self.knee = gamma_knee(gamma)
        self.brdf, self.sizes, self.reduction, self.lighting_size, self.gamma = (
            brdf,
            check_sphere_sizes(sizes),
            reduction,
            lighting_size,
            gamma,
        )
        self._register_plan(brdf, self.sizes, lighting_size)

    def forward(self, pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        check_lighting_pair(pred, target, self.lighting_size)
        return _reduce(
            _l_rec(self._plan(pred.dtype), self.counts, pred=pred, target=target, knee=self.knee),
            self.reduction,
        )

    def extra_repr(self) -> str:
        return f"brdf={self.brdf!r}, sizes={self.sizes}, reduction={self.reduction!r}, gamma={self.gamma!r}"


class RelativeRadiance(nn.Module):
    r"""Module twin of :func:`relative_radiance`.

    Shape:
        - pred, target: :math:`(B, 3, S, S)`
        - Output: :math:`(B, 3)`

    Examples:
        >>> RelativeRadiance()(torch.ones(1, 3, 8, 8), torch.ones(1, 3, 8, 8))
        tensor([[0., 0., 0.]])
    """

    def forward(self, pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        return relative_radiance(pred, target)


class LightingEnergy(nn.Module):
    r"""Module twin of :func:`lighting_energy`.

    Shape:
        - Input: :math:`(B, 3, S, S)`
        - Output: :math:`(B,)`

    Examples:
        >>> LightingEnergy()(torch.ones(2, 3, 32, 32)).shape
        torch.Size([2])
    """

    def forward(self, mirror_ball: torch.Tensor) -> torch.Tensor:
        return lighting_energy(mirror_ball)


class TotalRadiance(nn.Module):
    r"""Module twin of :func:`total_radiance`.

    Args:
        dtype: the dtype to sum in, or ``None`` for the input's (half precision: float32, cast back).

    Shape:
        - Input: :math:`(*, C, S, S)`
        - Output: :math:`(*, C)`

    Examples:
        >>> TotalRadiance(torch.float64)(torch.ones(1, 3, 32, 32)).shape
        torch.Size([1, 3])
    """

    def __init__(self, dtype: torch.dtype | None = None) -> None:
        super().__init__()
        self.dtype = dtype

    def forward(self, mirror_ball: torch.Tensor) -> torch.Tensor:
        return total_radiance(mirror_ball, self.dtype)

    def extra_repr(self) -> str:
        return f"dtype={self.dtype}"
