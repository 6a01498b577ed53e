r"""The ``uniform`` estimator: constant lighting = mean linear face colour / an assumed skin albedo.

The baseline every learned estimator must beat. Under a uniform environment of radiance ``L``, a Lambertian
surface of albedo ``a`` shows radiance ``a L`` from every direction (docs/conventions.rst, "Units of
lighting"), so the lighting is estimated, per channel, as ``L = m / a`` with ``m`` the mean linear colour of
the face pixels.

Face pixels: the crop is the square of side 1.25 x the face box centred on it (LeGendre et al. 2020), so
the box is the central 80 % of the crop; inside it, a central ellipse with semi-axes 0.35 (horizontal)
and 0.45 (vertical) of the box side (our choice: it keeps cheeks, forehead and chin and drops most hair
and background), without clipped pixels (any channel >= ``clip_threshold`` in sRGB: their linear value
is a lower bound) and very dark ones (every channel < ``dark_threshold``: hair, pupils, background). When
no pixel survives, the mean over the whole ellipse is used, so the result is never NaN.

Assumed albedo (:data:`SKIN_ALBEDO`, linear RGB): the mean of the two skin patches of the Macbeth
ColorChecker, "dark skin" and "light skin" (McCamy, Marcus and Davidson 1976, "A Color-Rendition Chart",
J. Applied Photographic Engineering 2(3); chosen to match medium dark and medium light human skin), from
their sRGB coordinates (115, 82, 68) and (194, 150, 130) (D. Pascale 2006, "RGB coordinates of the Macbeth
ColorChecker", BabelColor), decoded with the sRGB transfer function: (0.1714, 0.0844, 0.0578) and
(0.5395, 0.3050, 0.2232), luminance 0.10 and 0.35. Per-channel values keep the skin's colour out of the
lighting: white light on mid skin gives a white estimate. For skin like either patch the estimate is about
1.5x too bright (light skin) or 0.45x (dark skin): the albedo / light-strength ambiguity.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch
from torch import Tensor

from kornia_ilum.color import srgb_to_linear
from kornia_ilum.core.check import check_positive_int, check_tensor, checks_active
from kornia_ilum.core.errors import ShapeError, ValueCheckError
from kornia_ilum.estimators import EstimatorInfo, LightingEstimate, LightingEstimator
from kornia_ilum.geometry import mirror_ball_valid

__all__ = [
    "SKIN_ALBEDO",
    "CLIP_THRESHOLD",
    "DARK_THRESHOLD",
    "LIGHTING_SIZE",
    "face_ellipse",
    "uniform_lighting",
    "UniformEstimator",
]

#: Assumed diffuse skin albedo, linear RGB: mean of the ColorChecker "dark skin" and "light skin" patches.
SKIN_ALBEDO: tuple[float, float, float] = (0.3555, 0.1947, 0.1405)
#: sRGB value from which a channel counts as clipped.
CLIP_THRESHOLD = 0.98
#: sRGB value under which a pixel (all channels) counts as very dark.
DARK_THRESHOLD = 0.04
#: Side of the mirror ball of the estimate.
LIGHTING_SIZE = 32

_BOX_FRACTION = 1 / 1.25  # the face box's side as a fraction of the crop's
_SEMI_AXES = (0.35, 0.45)  # of the face box's side: horizontal, vertical


def face_ellipse(size: int, *, device: torch.device | str | None = None) -> Tensor:
    r"""Boolean mask of the central face ellipse of a ``size x size`` crop.

    The face box is the central ``1 / 1.25`` of the crop; the ellipse has semi-axes 0.35 (horizontal) and
    0.45 (vertical) of the box side, tested at pixel centres.

    Shape:
        - Output: :math:`(size, size)`, bool

    Examples:
        >>> mask = face_ellipse(256)
        >>> mask.shape, mask[128, 128].item(), mask[0, 0].item()
        (torch.Size([256, 256]), True, False)
    """
    check_positive_int(size, "size")
    c = (torch.arange(size, device=device, dtype=torch.float64) + 0.5) / size - 0.5
    y, x = torch.meshgrid(c, c, indexing="ij")
    rx, ry = (_BOX_FRACTION * a for a in _SEMI_AXES)
    return (x / rx).square() + (y / ry).square() <= 1.0


def _check_albedo(albedo: Tensor | Sequence[float] | float, like: Tensor) -> Tensor:
    """``albedo`` as a ``(3,)`` tensor like ``like``; the value check follows the global check switch."""
    a = torch.as_tensor(albedo, dtype=like.dtype, device=like.device).flatten()
    if a.numel() == 1:
        a = a.expand(3)
    if a.numel() != 3:
        raise ValueCheckError(f"albedo must be one or three positive finite values, got {albedo!r}")
    if (
        checks_active()
        and not torch.compiler.is_compiling()
        and not bool(((a > 0) & torch.isfinite(a)).all())
    ):
        raise ValueCheckError(f"albedo must be one or three positive finite values, got {albedo!r}")
    return a


def uniform_lighting(
    crops: Tensor,
    albedo: Tensor | Sequence[float] | float = SKIN_ALBEDO,
    clip_threshold: float = CLIP_THRESHOLD,
    dark_threshold: float = DARK_THRESHOLD,
) -> Tensor:
    r"""Uniform lighting radiance per crop: mean linear colour of the face pixels divided by ``albedo``.

    Args:
        crops: sRGB face crops in ``[0, 1]`` (square; the face box is the central 80 %).
        albedo: assumed skin albedo, linear RGB (three values, or one for grey).
        clip_threshold: pixels with any sRGB channel at or above it are left out.
        dark_threshold: pixels with every sRGB channel below it are left out.

    Returns:
        the radiance ``L`` per crop and channel, in the units of the crops' linear values, dtype of
        ``crops`` (float16/bfloat16 are computed in float32 and cast back).

    Raises:
        ShapeError: ``crops`` is not ``(B, 3, S, S)``.
        ValueCheckError: ``albedo`` is not one or three positive finite values.

    Shape:
        - Input: :math:`(B, 3, S, S)`
        - Output: :math:`(B, 3)`

    Convention:
        docs/conventions.rst, "Units of lighting": a Lambertian surface of albedo ``a`` under uniform radiance
        ``L`` shows ``a L``, so ``L = mean / a``. Each crop is independent of the others in the batch.

    Examples:
        >>> grey = torch.full((1, 3, 256, 256), 0.5)  # sRGB 0.5 = linear 0.2140
        >>> uniform_lighting(grey, albedo=0.5)
        tensor([[0.4281, 0.4281, 0.4281]])
    """
    check_tensor(crops, "crops", ["B", "3", "S", "S"])
    if crops.shape[-1] != crops.shape[-2]:
        raise ShapeError(f"crops must have shape (B, 3, S, S) (square), got {tuple(crops.shape)}")
    work = crops if crops.dtype in (torch.float32, torch.float64) else crops.float()
    a = _check_albedo(albedo, work)
    srgb = work.clamp(0.0, 1.0)
    linear = srgb_to_linear(srgb)
    ellipse = face_ellipse(crops.shape[-1], device=crops.device)
    peak = srgb.amax(dim=1)  # (B, S, S)
    keep = ellipse & (peak < clip_threshold) & (peak >= dark_threshold)
    # the ellipse where nothing is kept (as floats: ONNX Runtime has no Where on booleans)
    weights = torch.where(keep.any(dim=(-2, -1), keepdim=True), keep.to(work.dtype), ellipse.to(work.dtype))
    mean = (linear * weights[:, None]).sum(dim=(-2, -1)) / weights.sum(dim=(-2, -1))[:, None]
    return (mean / a).to(crops.dtype)


class UniformEstimator(LightingEstimator):
    r"""Constant lighting from the mean face colour and an assumed skin albedo (:func:`uniform_lighting`).

    No trained parameters: ``create_estimator("uniform")`` (``pretrained=True``) works without weights.

    Args:
        albedo: assumed skin albedo, linear RGB (default :data:`SKIN_ALBEDO`).
        clip_threshold: sRGB level from which a channel counts as clipped.
        dark_threshold: sRGB level under which a pixel counts as very dark.

    Returns:
        (from ``forward``) a :class:`~kornia_ilum.estimators.LightingEstimate` with ``mirror_ball`` (``L``
        on the ball, 0 outside), ``log_mirror_ball`` (``log(1 + L)``), ``sh`` (``L sqrt(4 pi)`` in
        coefficient (0, 0), zeros elsewhere) and ``valid``; dtype and device of the crops.

    Shape:
        - Input: :math:`(B, 3, 256, 256)`, sRGB in ``[0, 1]``
        - Output: ``mirror_ball``, ``log_mirror_ball``: :math:`(B, 3, 32, 32)`; ``sh``: :math:`(B, 9, 3)`

    Examples:
        >>> est = UniformEstimator(albedo=0.5)(torch.full((2, 3, 256, 256), 0.5))
        >>> tuple(est.mirror_ball.shape), round(est.mirror_ball[0, 0, 16, 16].item(), 4)
        ((2, 3, 32, 32), 0.4281)
    """

    info = EstimatorInfo(
        name="uniform",
        description="constant lighting: mean linear colour of the face pixels / assumed skin albedo",
        paper="none: a baseline (the floor every learned estimator must beat)",
        input_size=256,
        weights=(),
        install_hint="pip install ./plugins/uniform (package kornia_ilum_uniform)",
        needs_weights=False,
    )

    def __init__(
        self,
        albedo: Sequence[float] | float = SKIN_ALBEDO,
        clip_threshold: float = CLIP_THRESHOLD,
        dark_threshold: float = DARK_THRESHOLD,
    ) -> None:
        super().__init__()
        self.register_buffer("albedo", _check_albedo(albedo, torch.empty(0)), persistent=False)
        self.clip_threshold = float(clip_threshold)
        self.dark_threshold = float(dark_threshold)
        self.register_buffer("valid", mirror_ball_valid(LIGHTING_SIZE), persistent=False)

    def predict(self, crops: Tensor) -> LightingEstimate:
        radiance = uniform_lighting(crops, self.albedo, self.clip_threshold, self.dark_threshold)  # (B, 3)
        mirror_ball = radiance[:, :, None, None] * self.valid
        sh = torch.cat(
            [radiance[:, None] * math.sqrt(4 * math.pi), radiance.new_zeros(radiance.shape[0], 8, 3)], 1
        )
        return LightingEstimate(
            mirror_ball=mirror_ball,
            valid=self.valid,
            log_mirror_ball=torch.log1p(mirror_ball),
            sh=sh,
        )
