r"""The three-sphere evaluation protocol of StyleLight and DiffusionLight: RMSE, si-RMSE, angular error.

StyleLight (Wang et al. 2022, "StyleLight: HDR panorama generation for lighting estimation and editing")
and DiffusionLight (Phongthawee et al. 2024, "DiffusionLight: Light probes for free by painting a chrome
ball") score a lighting estimate by rendering a diffuse, a matte-silver and a mirror sphere with the
predicted and the ground-truth lighting and comparing the renders. This module follows their evaluation
code, ``evaluation/fast_rmse.py`` and ``evaluation/tonemap.py`` of github.com/Wanggcong/StyleLight, used
unchanged in definitions by ``stylelight/fast_rmse.py`` and ``stylelight/tonemap.py`` of
github.com/DiffusionLight/DiffusionLight-evaluation:

1. Tone mapping (``tonemap=True``, their ``TonemapHDR(gamma=2.4, percentile=50, max_mapping=0.5)`` with
   ``clip=False``): each lighting, prediction and ground truth independently, becomes
   ``alpha * L^(1/2.4)`` with ``alpha = 0.5 / (median + 1e-10)``, the median taken over the non-zero
   values of ``L^(1/2.4)`` (all pixels and channels, linear interpolation as ``np.percentile``).
2. The three spheres are rendered from the (tone-mapped) lightings.
3. Over the ``n`` pixels on the sphere (their mask: the render's alpha > 0), with ``P`` the prediction's
   and ``G`` the ground truth's RGB render:

   - ``rmse = sqrt(sum_{p, c} (P - G)^2 / n)``. The sum runs over pixels *and* channels but is divided by
     the number of pixels only, so this is ``sqrt(3)`` times the per-value RMSE; kept as published.
   - ``si_rmse = sqrt(min_a sum_{p, c} (a P - G)^2 / n)``, one least-squares scale
     ``a = <P, G> / <P, P>`` for all pixels and channels (their closed form ``(4ac - b^2) / (4a)``,
     evaluated here as the residual at ``a`` for accuracy; ``a = 0`` if ``P = 0``).
   - ``angular_error``: the mean over the ``n`` pixels of the angle in degrees between the RGB vectors
     ``P_p`` and ``G_p``, with the cosine clipped to ``[0, 1]`` (angles above 90 degrees count as 90) and
     0 for a pixel where either vector is zero (their ``nan_to_num``). Computed as
     ``atan2(|P x G|, P . G)``, which is exact near 0 where ``arccos`` of a rounded cosine is not.

Differences from the published numbers, by design: the spheres are the reference spheres of
docs/conventions.rst rendered by reflectance fields (:mod:`kornia_ilum.render`) from 32 x 32 mirror-ball
lighting, not Blender Cycles renders of 128 x 256 lat-long maps, and the tone-mapping median is over equal
solid angles (mirror-ball pixels) rather than lat-long pixels. The metric definitions are theirs, so the
numbers rank methods the same way but are not interchangeable with the published tables.
"""

from __future__ import annotations

import math

import torch
from torch import nn

from kornia_ilum.core.check import check_positive_int, check_tensor
from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.geometry.mirror_ball import mirror_ball_to_lights, mirror_ball_valid
from kornia_ilum.metrics.lighting import check_lighting_pair
from kornia_ilum.render.relight import relight
from kornia_ilum.render.spheres import BRDFS, SPHERE_SIZES, shared_sphere_field, sphere_reflectance_field

__all__ = ["METRICS", "ThreeSphereMetrics", "TonemapStylelight", "three_sphere_metrics", "tonemap_stylelight"]

#: Names of the metrics, as in StyleLight's ``fast_rmse.py``.
METRICS: tuple[str, ...] = ("rmse", "si_rmse", "angular_error")
_HALF = (torch.float16, torch.bfloat16)


def tonemap_stylelight(lighting: torch.Tensor, gamma: float = 2.4, median_to: float = 0.5) -> torch.Tensor:
    r"""StyleLight's evaluation tone map: ``alpha * L^(1/gamma)``, mapping the median non-zero value to 0.5.

    ``alpha = median_to / (median + 1e-10)`` per batch item, the median over the non-zero values of
    ``L^(1/gamma)`` in all pixels and channels (``np.percentile(x[x > 0], 50)``, linear interpolation). No
    clipping. A black lighting stays black.

    Args:
        lighting: linear, non-negative lighting ``(B, C, H, W)``.
        gamma: the encoding gamma (2.4 in the protocol).
        median_to: the value the median is mapped to (0.5 in the protocol).

    Returns:
        the tone-mapped lighting, same shape and dtype (computed in float32 for half inputs).

    Raises:
        ShapeError: ``lighting`` is not ``(B, C, H, W)``.
        NonFiniteError: NaN or Inf in ``lighting``.
        ValueCheckError: negative lighting.

    Shape:
        - lighting: :math:`(B, C, H, W)`
        - Output: :math:`(B, C, H, W)`

    Convention:
        docs/conventions.rst, "Images": the input is linear HDR; the output is display-encoded and unbounded
        above (no clipping), with the absolute scale of each lighting removed.

    Examples:
        >>> tonemap_stylelight(torch.tensor([[[[0.0, 1.0, 16.0]]]]))
        tensor([[[[0.0000, 0.2395, 0.7605]]]])
    """
    check_tensor(lighting, "lighting", ["B", "C", "H", "W"], nonnegative=True)
    work = lighting.float() if lighting.dtype in _HALF else lighting
    encoded = work.pow(1.0 / gamma)
    flat = encoded.flatten(1)
    median = torch.nanquantile(torch.where(flat > 0, flat, torch.full_like(flat, math.nan)), 0.5, dim=1)
    median = torch.nan_to_num(median, nan=0.0)  # all zero: np.percentile of zeros is 0 and the map stays 0
    alpha = median_to / (median + 1e-10)
    return (encoded * alpha[:, None, None, None]).to(lighting.dtype)


def _sphere_metrics(pred: torch.Tensor, target: torch.Tensor) -> dict[str, torch.Tensor]:
    """RMSE, si-RMSE and angular error, ``(B,)`` each, of renders ``(B, 3, n)`` of the ``n`` sphere pixels."""
    n = pred.shape[-1]
    rmse = (pred - target).square().sum((1, 2)).div(n).sqrt()
    pp = pred.square().sum((1, 2))
    scale = torch.where(
        pp > 0, (pred * target).sum((1, 2)) / torch.where(pp > 0, pp, torch.ones_like(pp)), 0.0
    )
    si_rmse = (scale[:, None, None] * pred - target).square().sum((1, 2)).div(n).sqrt()
    cross = torch.linalg.cross(pred, target, dim=1).square().sum(1)
    dot = (pred * target).sum(1)
    nonzero = (pred.square().sum(1) > 0) & (target.square().sum(1) > 0)
    # |P x G| is exactly 0 for parallel vectors; the clamp keeps the (unused) gradient of sqrt finite there
    sine = torch.where(
        cross > 0, cross.clamp(min=torch.finfo(cross.dtype).tiny).sqrt(), torch.zeros_like(cross)
    )
    angle = torch.atan2(sine, dot).clamp(max=math.pi / 2)
    angle = torch.where(nonzero, angle, torch.zeros_like(angle))
    return {"rmse": rmse, "si_rmse": si_rmse, "angular_error": torch.rad2deg(angle.mean(1))}


def _three_sphere(
    fields: dict[str, torch.Tensor], pred: torch.Tensor, target: torch.Tensor, tonemap: bool
) -> dict[tuple[str, str], torch.Tensor]:
    work = torch.float32 if pred.dtype in _HALF else pred.dtype
    pred, target = pred.to(work), target.to(work)
    if tonemap:
        pred, target = tonemap_stylelight(pred), tonemap_stylelight(target)
    lights_pred, lights_target = mirror_ball_to_lights(pred), mirror_ball_to_lights(target)
    out = {}
    for brdf, field in fields.items():
        size = (1, field.shape[0])
        render_pred = relight(field.to(work), lights_pred, size).flatten(2)
        render_target = relight(field.to(work), lights_target, size).flatten(2)
        for name, value in _sphere_metrics(render_pred, render_target).items():
            out[(brdf, name)] = value
    return out


def _check_tonemap(tonemap: bool) -> None:
    if not isinstance(tonemap, bool):
        raise ValueCheckError(f"tonemap must be a bool, got {tonemap!r}")


def three_sphere_metrics(
    pred: torch.Tensor, target: torch.Tensor, *, size: int = 64, tonemap: bool = True
) -> dict[tuple[str, str], torch.Tensor]:
    r"""RMSE, scale-invariant RMSE and angular error of diffuse, matte-silver and mirror sphere renders.

    The protocol of StyleLight (Wang et al. 2022) and DiffusionLight (Phongthawee et al. 2024); the exact
    definitions, their source files and the differences from the published setup are in the module
    docstring (:mod:`kornia_ilum.metrics.protocol`).

    Args:
        pred: predicted linear mirror-ball lighting ``(B, 3, S_L, S_L)``, non-negative.
        target: ground-truth lighting of the same shape, non-negative.
        size: side of the sphere renders, one of :data:`~kornia_ilum.render.SPHERE_SIZES`.
        tonemap: apply the protocol's per-lighting tone map (:func:`tonemap_stylelight`) first, as
            published. ``False`` compares linear renders in the lighting's own units.

    Returns:
        ``{(brdf, metric): (B,)}`` for ``brdf`` in :data:`~kornia_ilum.render.BRDFS` and ``metric`` in
        :data:`METRICS` (``"rmse"``, ``"si_rmse"``, ``"angular_error"`` in degrees). Lower is better; all are
        0 for identical lightings, and ``si_rmse`` does not change when ``pred`` is scaled (nor does anything
        with ``tonemap=True``, whose tone map removes the scale of each lighting).

    Shape:
        - pred, target: :math:`(B, 3, S_L, S_L)`
        - Output: ``{(brdf, metric):`` :math:`(B,)` ``}``

    Convention:
        docs/conventions.rst, "Reference spheres" and the mirror-ball grid. Half-precision inputs are
        evaluated in float32 and the metrics returned in float32.

    Examples:
        >>> gt = torch.rand(2, 3, 32, 32)
        >>> scores = three_sphere_metrics(gt, gt, size=16)
        >>> sorted(scores)[:3]
        [('diffuse', 'angular_error'), ('diffuse', 'rmse'), ('diffuse', 'si_rmse')]
        >>> scores[("mirror", "rmse")]
        tensor([0., 0.])
    """
    s_l = check_lighting_pair(pred, target)
    check_tensor(pred, "pred", ["B", "3", "S", "S"], nonnegative=True)
    check_tensor(target, "target", ["B", "3", "S", "S"], nonnegative=True)
    check_positive_int(size, "size", allowed=SPHERE_SIZES)
    _check_tonemap(tonemap)
    work = torch.float32 if pred.dtype in _HALF else pred.dtype
    fields = {
        b: shared_sphere_field(
            b, size, lighting_size=s_l, device=pred.device, dtype=work, on_sphere=True, multiscale=True
        )
        for b in BRDFS
    }
    return _three_sphere(fields, pred, target, tonemap)


class ThreeSphereMetrics(nn.Module):
    r"""Module twin of :func:`three_sphere_metrics`; the three fields are non-persistent buffers.

    Args:
        size: side of the sphere renders.
        tonemap: apply the protocol's tone map first.
        lighting_size: side ``S_L`` of the lighting the module accepts.

    Shape:
        - pred, target: :math:`(B, 3, S_L, S_L)` with ``S_L = lighting_size``
        - Output: ``{(brdf, metric):`` :math:`(B,)` ``}``

    Examples:
        >>> metrics = ThreeSphereMetrics(size=8)
        >>> gt = torch.rand(1, 3, 32, 32)
        >>> metrics(gt, gt)[("diffuse", "si_rmse")]
        tensor([0.])
    """

    def __init__(self, size: int = 64, tonemap: bool = True, lighting_size: int = 32) -> None:
        super().__init__()
        check_positive_int(size, "size", allowed=SPHERE_SIZES)
        _check_tonemap(tonemap)
        self.size, self.tonemap, self.lighting_size = size, tonemap, lighting_size
        for b in BRDFS:
            field = sphere_reflectance_field(b, size, lighting_size=lighting_size, multiscale=True)
            field = field[mirror_ball_valid(size).flatten()]
            self.register_buffer(f"field_{b}", field, persistent=False)

    def forward(self, pred: torch.Tensor, target: torch.Tensor) -> dict[tuple[str, str], torch.Tensor]:
        check_lighting_pair(pred, target, self.lighting_size)
        check_tensor(pred, "pred", ["B", "3", "S", "S"], nonnegative=True)
        check_tensor(target, "target", ["B", "3", "S", "S"], nonnegative=True)
        return _three_sphere({b: getattr(self, f"field_{b}") for b in BRDFS}, pred, target, self.tonemap)

    def extra_repr(self) -> str:
        return f"size={self.size}, tonemap={self.tonemap}, lighting_size={self.lighting_size}"


class TonemapStylelight(nn.Module):
    r"""Module twin of :func:`tonemap_stylelight`.

    Args:
        gamma: the encoding gamma (2.4 in the protocol).
        median_to: the value the median is mapped to (0.5 in the protocol).

    Shape:
        - Input: :math:`(B, C, H, W)`
        - Output: :math:`(B, C, H, W)`

    Examples:
        >>> TonemapStylelight()(torch.tensor([[[[0.0, 1.0, 16.0]]]]))
        tensor([[[[0.0000, 0.2395, 0.7605]]]])
    """

    def __init__(self, gamma: float = 2.4, median_to: float = 0.5) -> None:
        super().__init__()
        self.gamma, self.median_to = gamma, median_to

    def forward(self, lighting: torch.Tensor) -> torch.Tensor:
        return tonemap_stylelight(lighting, self.gamma, self.median_to)

    def extra_repr(self) -> str:
        return f"gamma={self.gamma}, median_to={self.median_to}"
