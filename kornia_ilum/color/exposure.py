r"""Exposure: a camera's centre-weighted metering, and the normalisation that makes an estimator scale with it.

A lighting estimate is in the units of the photograph (docs/conventions.rst, "Units of lighting"): darken a
photo by ``k`` in linear light and its lighting must darken by ``k``. A network that sees the photo as it is
has to learn that from data, and pulls dark photos towards the brightness it was trained on.
:func:`normalize_exposure` does it by design: it scales the crop's linear values so that their centre-weighted
mean luminance (:func:`metered_luminance`, the face fills the centre of a face crop) is ``key``, and returns
the factor to multiply an estimate made on the normalised crop by. Both are exact for ``k x`` wherever the
darkened photo has no new clipping: the metered value is linear in the image, so ``k x`` normalises to the
same crop (bit for bit in exact arithmetic) and its factor is ``k`` times that of ``x``.

The weights are a Gaussian of standard deviation ``sigma`` (a fraction of the image side) around the centre;
the luminance is Rec. 709 ``Y`` of linear RGB (:data:`LUMINANCE`).
"""

from __future__ import annotations

import functools

import torch
from torch import nn

from kornia_ilum.color.transfer import linear_to_srgb, srgb_to_linear
from kornia_ilum.core.check import check_tensor
from kornia_ilum.core.dtypes import HALF, saturating_cast
from kornia_ilum.core.errors import ValueCheckError

__all__ = [
    "EXPOSURE_KEY",
    "LUMINANCE",
    "METERING_SIGMA",
    "MeteredLuminance",
    "NormalizeExposure",
    "centre_weights",
    "metered_luminance",
    "normalize_exposure",
]

#: Rec. 709 / sRGB luminance weights of linear R, G, B.
LUMINANCE: tuple[float, float, float] = (0.212671, 0.715160, 0.072169)
#: The metered mean that :func:`normalize_exposure` maps a crop to (middle grey).
EXPOSURE_KEY = 0.18
#: Standard deviation of the metering's centre weights, as a fraction of the image side.
METERING_SIGMA = 0.25
_DARKEST = 1e-6  # metered luminance below this counts as this (a black crop): the factor stays finite


def centre_weights(
    height: int, width: int, *, sigma: float = METERING_SIGMA, device: torch.device | None = None,
    dtype: torch.dtype = torch.float64,
) -> torch.Tensor:
    r"""Centre-weighted metering weights ``(height, width)``, summing to 1: a Gaussian of ``sigma`` x the side.

    Pixel ``(i, j)`` sits at ``((j + 0.5) / width - 0.5, (i + 0.5) / height - 0.5)``.

    Args:
        height: number of rows.
        width: number of columns.
        sigma: the Gaussian's standard deviation, a fraction of the side, > 0.
        device: device of the result.
        dtype: dtype of the result (computed in float64).

    Returns:
        the weights, non-negative, summing to 1.

    Raises:
        ValueCheckError: ``sigma`` not positive.

    Shape:
        - Output: :math:`(H, W)`

    Examples:
        >>> w = centre_weights(4, 4)
        >>> round(w.sum().item(), 6), bool(w[1, 1] > w[0, 0])
        (1.0, True)
    """
    if not sigma > 0:
        raise ValueCheckError(f"sigma must be positive, got {sigma}")
    yy = (torch.arange(height, dtype=torch.float64) + 0.5) / height - 0.5
    xx = (torch.arange(width, dtype=torch.float64) + 0.5) / width - 0.5
    weight = torch.exp(-(yy[:, None] ** 2 + xx[None] ** 2) / (2 * sigma**2))
    return (weight / weight.sum()).to(device=device, dtype=dtype)


def metered_luminance(linear: torch.Tensor, sigma: float = METERING_SIGMA) -> torch.Tensor:
    r"""The centre-weighted mean luminance of linear images: ``sum_p w_p Y_p`` (:func:`centre_weights`).

    Linear in the image: ``metered_luminance(k x) = k metered_luminance(x)``.

    Args:
        linear: :math:`(B, 3, H, W)` linear RGB.
        sigma: the weights' standard deviation, a fraction of the side.

    Returns:
        :math:`(B,)` in the dtype of ``linear``.

    Shape:
        - linear: :math:`(B, 3, H, W)`
        - Output: :math:`(B,)`

    Convention:
        docs/conventions.rst, "Images": ``linear`` is linear RGB (decode sRGB first, :func:`srgb_to_linear`).

    Examples:
        >>> metered_luminance(torch.full((1, 3, 8, 8), 0.5)).tolist()
        [0.5]
    """
    check_tensor(linear, "linear", ["B", "3", "H", "W"])
    h, w = linear.shape[-2:]
    tracing = torch.compiler.is_compiling() or torch.compiler.is_exporting()  # no traced tensor in the cache
    build = _metering_map.__wrapped__ if tracing else _metering_map
    weight = build(int(h), int(w), float(sigma)).to(device=linear.device, dtype=linear.dtype)
    # a product and a sum, not einsum: ONNX Runtime runs an exported Einsum (or MatMul) of this shape several
    # times slower (docs/bench.rst)
    return (linear * weight).sum(dim=(1, 2, 3))


@functools.lru_cache(maxsize=8)
def _metering_map(height: int, width: int, sigma: float) -> torch.Tensor:
    """``LUMINANCE[c] * centre_weights(height, width, sigma)``, ``(3, H, W)`` float64: built once per size (its
    float64 ``exp`` cost a third of :func:`normalize_exposure`'s time when it was built per call)."""
    with torch.inference_mode(False):  # a normal tensor even when first built under inference_mode: autograd
        lum = torch.tensor(LUMINANCE, dtype=torch.float64)  # may save it for backward later
        return lum[:, None, None] * centre_weights(height, width, sigma=sigma)


def normalize_exposure(
    srgb: torch.Tensor, key: float = EXPOSURE_KEY, sigma: float = METERING_SIGMA
) -> tuple[torch.Tensor, torch.Tensor]:
    r"""Re-expose sRGB crops so that their metered luminance is ``key``; return them and the factor back.

    ``linear = srgb_to_linear(srgb)``, ``m = metered_luminance(linear)``, ``g = key / m``; the normalised crop is
    ``linear_to_srgb(min(g linear, 1))`` (a camera's white clips), and ``scale = m / key``: lighting estimated
    from the normalised crop times ``scale`` is in the units of ``srgb``. See the module docstring for why this
    makes an estimator scale exactly with the photo's exposure. A black crop (``m`` below 1e-6) counts as
    ``m = 1e-6``.

    Args:
        srgb: :math:`(B, 3, H, W)` sRGB in ``[0, 1]``.
        key: the target metered luminance.
        sigma: the metering weights' standard deviation, a fraction of the side.

    Returns:
        ``(normalised, scale)``: :math:`(B, 3, H, W)` sRGB in ``[0, 1]`` and :math:`(B,)`, both in the dtype of
        ``srgb`` (half precision computed in float32, saturating on the way back).

    Raises:
        ValueCheckError: ``key`` not positive.

    Shape:
        - srgb: :math:`(B, 3, H, W)`
        - Output: :math:`(B, 3, H, W)` and :math:`(B,)`

    Convention:
        docs/conventions.rst, "Units of lighting": an estimate made on the normalised crop, times ``scale``,
        is in the units of the photograph.

    Examples:
        >>> x = torch.rand(2, 3, 16, 16)
        >>> a, s = normalize_exposure(x)
        >>> dark = linear_to_srgb(0.5 * srgb_to_linear(x))  # half the light, nothing clips anew
        >>> b, t = normalize_exposure(dark)
        >>> torch.allclose(a, b, atol=1e-5), torch.allclose(t, 0.5 * s)
        (True, True)
    """
    if not key > 0:
        raise ValueCheckError(f"key must be positive, got {key}")
    if srgb.dtype in HALF:  # a dark crop's gain and its gradient overflow float16: computed in float32
        normalised, scale = normalize_exposure(saturating_cast(srgb, torch.float32), key, sigma)
        return saturating_cast(normalised, srgb.dtype), saturating_cast(scale, srgb.dtype)
    linear = srgb_to_linear(srgb)
    metered = metered_luminance(linear, sigma).clamp(min=_DARKEST)
    gain = (key / metered)[:, None, None, None]
    return linear_to_srgb((linear * gain).clamp(0.0, 1.0)), metered / key


class MeteredLuminance(nn.Module):
    r"""Module twin of :func:`metered_luminance`.

    Args:
        sigma: the weights' standard deviation, a fraction of the side.

    Shape:
        - Input: :math:`(B, 3, H, W)` linear RGB
        - Output: :math:`(B,)`

    Examples:
        >>> MeteredLuminance()(torch.full((1, 3, 8, 8), 0.5)).tolist()
        [0.5]
    """

    def __init__(self, sigma: float = METERING_SIGMA) -> None:
        super().__init__()
        self.sigma = sigma

    def forward(self, linear: torch.Tensor) -> torch.Tensor:
        return metered_luminance(linear, self.sigma)


class NormalizeExposure(nn.Module):
    r"""Module twin of :func:`normalize_exposure`: ``forward(srgb) -> (normalised, scale)``.

    Args:
        key: the target metered luminance.
        sigma: the metering weights' standard deviation, a fraction of the side.

    Shape:
        - Input: :math:`(B, 3, H, W)`
        - Output: :math:`(B, 3, H, W)` and :math:`(B,)`

    Examples:
        >>> normalised, scale = NormalizeExposure()(torch.full((1, 3, 8, 8), 0.5))
        >>> round(scale.item(), 3)  # srgb_to_linear(0.5) = 0.214, over the key 0.18
        1.189
    """

    def __init__(self, key: float = EXPOSURE_KEY, sigma: float = METERING_SIGMA) -> None:
        super().__init__()
        self.key, self.sigma = key, sigma

    def forward(self, srgb: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return normalize_exposure(srgb, self.key, self.sigma)
