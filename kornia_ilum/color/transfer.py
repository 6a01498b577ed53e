r"""Colour transfer functions: sRGB (IEC 61966-2-1), gamma 2.2, and 8-bit quantisation.

The sRGB pair is Kornia's (:func:`kornia.color.linear_rgb_to_rgb` and
:func:`kornia.color.rgb_to_linear_rgb`, which use the exact IEC 61966-2-1 piecewise curve). The
wrappers here only add kornia_ilum's argument checks (named arguments, NaN/Inf) so that every
public entry point fails the same way. While :func:`torch.onnx.export` traces them they compute the same curve
with a blend by the mask in place of ``where``: ONNX Runtime's ``Where`` costs far more than a ``Mul``
(docs/bench.rst has the measurement; the exported estimators convert every crop twice).
"""

from __future__ import annotations

import functools

import torch
from kornia.color import linear_rgb_to_rgb, rgb_to_linear_rgb
from torch import nn

from kornia_ilum.core.check import check_positive_int, check_tensor
from kornia_ilum.core.dtypes import HALF, saturating_cast
from kornia_ilum.core.errors import ValueCheckError

__all__ = [
    "linear_to_srgb",
    "srgb_to_linear",
    "gamma_encode",
    "gamma_decode",
    "quantize",
    "encode_srgb8",
    "gamma_encode_unchecked",
    "srgb8_table",
    "SRGB8_TABLE_SIZE",
    "LinearToSrgb",
    "SrgbToLinear",
    "GammaDecode",
    "GammaEncode",
    "Quantize",
]

#: Below this linear value :func:`gamma_encode` is the chord through the origin, so its slope is finite.
GAMMA_KNEE = 1e-5


def linear_to_srgb(image: torch.Tensor) -> torch.Tensor:
    r"""Encode linear RGB with the exact sRGB transfer function (IEC 61966-2-1).

    ``12.92 x`` for ``x <= 0.0031308``, else ``1.055 x^(1/2.4) - 0.055``. Values above 1 are encoded
    by the same curve (no clipping); clip first for display.

    Args:
        image: linear RGB of shape :math:`(*, 3, H, W)`.

    Returns:
        sRGB-encoded image of the same shape and dtype (half precision computed in float32, saturating).

    Shape:
        - image: :math:`(*, 3, H, W)`
        - Output: :math:`(*, 3, H, W)`

    Convention:
        docs/conventions.rst, "Images": HDR data is linear; LDR images are sRGB-encoded in ``[0, 1]``.

    Examples:
        >>> linear_to_srgb(torch.full((3, 1, 1), 0.5)).flatten()
        tensor([0.7354, 0.7354, 0.7354])
    """
    check_tensor(image, "image", ["*", "3", "H", "W"])
    if torch.compiler.is_exporting():
        t = 0.0031308
        return _blend(image > t, 1.055 * torch.pow(image.clamp(min=t), 1 / 2.4) - 0.055, 12.92 * image)
    if image.dtype in HALF:  # computed in float32, saturating on the way back (kornia_ilum.core.dtypes)
        return saturating_cast(linear_rgb_to_rgb(saturating_cast(image, torch.float32)), image.dtype)
    return linear_rgb_to_rgb(image)


def srgb_to_linear(image: torch.Tensor) -> torch.Tensor:
    r"""Decode sRGB to linear RGB (IEC 61966-2-1), the inverse of :func:`linear_to_srgb`.

    Args:
        image: sRGB image of shape :math:`(*, 3, H, W)`, normally in ``[0, 1]``.

    Returns:
        linear RGB of the same shape and dtype (half precision computed in float32; a value beyond the dtype's
        range saturates at its largest finite value).

    Shape:
        - image: :math:`(*, 3, H, W)`
        - Output: :math:`(*, 3, H, W)`

    Convention:
        docs/conventions.rst, "Images": LDR inputs are sRGB-encoded in ``[0, 1]``; lighting and renders are
        linear.

    Examples:
        >>> srgb_to_linear(torch.full((3, 1, 1), 0.5)).flatten()
        tensor([0.2140, 0.2140, 0.2140])
    """
    check_tensor(image, "image", ["*", "3", "H", "W"])
    if torch.compiler.is_exporting():
        return _blend(image > 0.04045, torch.pow((image + 0.055).clamp(min=0.0) / 1.055, 2.4), image / 12.92)
    if image.dtype in HALF:  # computed in float32, saturating on the way back (kornia_ilum.core.dtypes)
        return saturating_cast(rgb_to_linear_rgb(saturating_cast(image, torch.float32)), image.dtype)
    return rgb_to_linear_rgb(image)


def _blend(mask: torch.Tensor, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """``where(mask, a, b)`` as ``b + mask (a - b)``: the form the ONNX export takes (module docstring); equal up
    to one rounding of ``a - b`` for finite values."""
    return b + mask.to(a.dtype) * (a - b)


def gamma_encode(x: torch.Tensor, gamma: float = 2.2, *, knee: float = GAMMA_KNEE) -> torch.Tensor:
    r"""``x^(1/gamma)``, by default with a finite gradient at 0.

    Exact for ``x >= knee`` (default :data:`GAMMA_KNEE`, 1e-5); below it the curve is the chord
    ``x * knee^(1/gamma - 1)`` through the origin, continuous at the knee, with slope
    ``knee^(1/gamma - 1)`` (about 530 for 2.2 and the default knee) instead of infinity. Negative values
    map to their chord value (negative), never NaN. The chord lies below the curve by at most
    ``0.28 knee^(1/gamma)`` for ``gamma = 2.2`` (1.5e-3 at the default knee, 5.3e-4 at 1e-6).

    ``knee=0`` is the exact power: ``x^(1/gamma)`` for ``x > 0`` and 0 for ``x <= 0``. Its gradient is
    finite everywhere (0 at and below 0; the power is evaluated at ``max(x, tiny)`` so that no ``inf``
    reaches the backward pass) but unbounded near 0: use it to evaluate, a positive knee to train.

    Args:
        x: linear values of any shape.
        gamma: the display gamma, > 0.
        knee: where the chord meets the curve, ``>= 0``; 0 for the exact power.

    Returns:
        encoded values of the same shape and dtype.

    Raises:
        ValueCheckError: ``gamma`` not positive, or ``knee`` outside ``[0, 1)``.
        NonFiniteError: NaN or Inf in ``x``.

    Shape:
        - x: :math:`(*)`
        - Output: :math:`(*)`

    Convention:
        docs/conventions.rst, "The paper's error measure ``L_rec``": the metric uses the exact power
        (``knee=0``); a training loss may use the gradient-safe chord below a positive knee.

    Examples:
        >>> gamma_encode(torch.tensor([0.0, 0.25, 1.0]))
        tensor([0.0000, 0.5325, 1.0000])
        >>> bool(gamma_encode(torch.tensor([1e-6]), knee=0.0) > gamma_encode(torch.tensor([1e-6])))
        True
    """
    check_tensor(x, "x", None, nonempty=False)
    if not gamma > 0:
        raise ValueCheckError(f"gamma must be positive, got {gamma}")
    if isinstance(knee, bool) or not isinstance(knee, (int, float)) or not 0.0 <= knee < 1.0:
        raise ValueCheckError(f"knee must be a number in [0, 1), got {knee!r}")
    return gamma_encode_unchecked(x, float(gamma), float(knee))


def gamma_encode_unchecked(x: torch.Tensor, gamma: float = 2.2, knee: float = GAMMA_KNEE) -> torch.Tensor:
    r""":func:`gamma_encode` without the argument checks, for callers that checked their inputs.

    The same values as :func:`gamma_encode`; nothing is validated (no NaN/Inf scan of ``x``), so a loss or a
    renderer that checked its inputs once does not pay for a second pass over the data.

    Args:
        x: linear values of any shape.
        gamma: the display gamma, > 0.
        knee: where the chord meets the curve, in ``[0, 1)``; 0 for the exact power.

    Returns:
        encoded values of the same shape and dtype.

    Shape:
        - x: :math:`(*)`
        - Output: :math:`(*)`

    Examples:
        >>> gamma_encode_unchecked(torch.tensor([0.0, 0.25, 1.0]), 2.2, 0.0)
        tensor([0.0000, 0.5325, 1.0000])
    """
    inv = 1.0 / gamma
    if knee == 0.0:
        tiny = torch.finfo(x.dtype).tiny if x.is_floating_point() else 1e-30
        return torch.where(x > 0, x.clamp(min=tiny).pow(inv), torch.zeros_like(x))
    curve = x.clamp(min=knee).pow(inv)
    chord = x * (knee ** (inv - 1.0))
    return torch.where(x >= knee, curve, chord)


def gamma_decode(x: torch.Tensor, gamma: float = 2.2) -> torch.Tensor:
    r"""``x^gamma`` for ``x >= 0``; the inverse of :func:`gamma_encode` on ``[knee^(1/gamma), inf)``.

    Below ``GAMMA_KNEE^(1/gamma)`` (the encoded default knee) it is the chord through the origin, the inverse
    of :func:`gamma_encode`'s chord at the default :data:`GAMMA_KNEE`.

    Args:
        x: gamma-encoded values of any shape.
        gamma: the display gamma, > 0.

    Returns:
        linear values of the same shape and dtype.

    Raises:
        ValueCheckError: ``gamma`` not positive.
        NonFiniteError: NaN or Inf in ``x``.

    Shape:
        - x: :math:`(*)`
        - Output: :math:`(*)`

    Examples:
        >>> gamma_decode(torch.tensor([0.5]))
        tensor([0.2176])
        >>> x = torch.tensor([0.001, 0.25, 1.0])
        >>> torch.allclose(gamma_decode(gamma_encode(x)), x)
        True
    """
    check_tensor(x, "x", None, nonempty=False)
    if not gamma > 0:
        raise ValueCheckError(f"gamma must be positive, got {gamma}")
    knee_out = GAMMA_KNEE ** (1.0 / gamma)
    curve = x.clamp(min=knee_out).pow(gamma)
    chord = x / (GAMMA_KNEE ** (1.0 / gamma - 1.0))
    return torch.where(x >= knee_out, curve, chord)


class _RoundSTE(torch.autograd.Function):
    @staticmethod
    def forward(ctx, x: torch.Tensor) -> torch.Tensor:  # noqa: D102
        return torch.round(x)

    @staticmethod
    def backward(ctx, grad: torch.Tensor) -> torch.Tensor:  # noqa: D102
        return grad


def quantize(x: torch.Tensor, bits: int = 8, straight_through: bool = False) -> torch.Tensor:
    r"""Clip to ``[0, 1]`` and round to ``2^bits - 1`` levels, as a camera writes an 8-bit file.

    Args:
        x: encoded (for example sRGB) values of any shape.
        bits: bit depth, 1 to 16.
        straight_through: pass the gradient of the rounding through unchanged (the clip still zeroes
            the gradient outside ``[0, 1]``); otherwise the rounding has zero gradient.

    Returns:
        quantised values in ``[0, 1]``, same dtype (use float32 or wider for 16 bits).

    Shape:
        - x: :math:`(*)`
        - Output: :math:`(*)`

    Examples:
        >>> quantize(torch.tensor([-0.2, 0.5, 0.999, 3.0]))
        tensor([0.0000, 0.5020, 1.0000, 1.0000])
    """
    check_tensor(x, "x", None, nonempty=False)
    check_positive_int(bits, "bits", allowed=range(1, 17))
    levels = float(2**bits - 1)
    y = x.clamp(0.0, 1.0) * levels
    y = _RoundSTE.apply(y) if straight_through else torch.round(y)
    return y / levels


#: Cells of :func:`srgb8_table`, evenly spaced in ``sqrt(x)`` over linear ``x`` in ``[0, 1]``.
SRGB8_TABLE_SIZE = 1 << 16


def encode_srgb8(linear: torch.Tensor, *, inplace: bool = False) -> torch.Tensor:
    r"""Clip linear values to ``[0, 1]``, encode them with the sRGB curve and quantise to 8-bit codes.

    What a camera writes to an 8-bit file: the codes of :func:`linear_to_srgb` then :func:`quantize`
    (``bits=8``), as ``uint8``.

    Args:
        linear: linear values of any shape, float.
        inplace: use ``linear`` (float32, contiguous) as scratch space and overwrite it: no allocation of
            the input's size.

    Returns:
        ``torch.uint8`` codes of the shape of ``linear`` (divide by 255 for ``[0, 1]``).

    Raises:
        NonFiniteError: ``linear`` holds NaN or Inf.

    Shape:
        - linear: :math:`(*)`
        - Output: :math:`(*)`, ``torch.uint8``

    Convention:
        The codes are read from a table of 65536 cells evenly spaced in ``sqrt(x)`` (:func:`srgb8_table`):
        one lookup per value instead of the sRGB curve's power and the rounding, so it is faster than
        :func:`linear_to_srgb` and :func:`quantize` (``benchmarks/bench_ops.py``, section images; the numbers
        are in the docs' colour page). A value within a cell that straddles a code
        boundary may land on the neighbouring code: 0.1 % of the values of random images, never more than
        one code off.

    Examples:
        >>> encode_srgb8(torch.tensor([0.0, 0.2140, 1.0, 7.0, -1.0]))
        tensor([  0, 127, 255, 255,   0], dtype=torch.uint8)
    """
    check_tensor(linear, "linear", None, nonempty=False)
    if inplace and (linear.dtype != torch.float32 or not linear.is_contiguous()):
        raise ValueCheckError(f"inplace needs a contiguous float32 tensor, got {linear.dtype}")
    x = linear if inplace else linear.to(torch.float32, copy=True)
    n = SRGB8_TABLE_SIZE
    x = x.mul_(float(n) ** 2).clamp_(0.0, (n - 0.5) ** 2)  # float32 rounds 2^32 - 1 up to 2^32
    codes = srgb8_table(x.device)
    return codes.index_select(0, x.sqrt_().to(torch.int32).flatten()).view(x.shape)


@functools.cache
def srgb8_table(device: torch.device) -> torch.Tensor:
    r"""The table of :func:`encode_srgb8`: the 8-bit sRGB code of every cell of ``sqrt(x)``.

    Cell ``i`` holds the code of ``x = ((i + 0.5) / SRGB8_TABLE_SIZE)^2``; a linear value ``x`` in ``[0, 1]``
    reads cell ``floor(sqrt(x) * SRGB8_TABLE_SIZE)`` (truncation). Built once per device and cached: the
    result is shared, do not modify it.

    Args:
        device: device of the table.

    Returns:
        ``torch.uint8`` codes of shape ``(SRGB8_TABLE_SIZE,)``.

    Examples:
        >>> table = srgb8_table(torch.device("cpu"))
        >>> table.shape, table[0].item(), table[-1].item()
        (torch.Size([65536]), 0, 255)
    """
    x = ((torch.arange(SRGB8_TABLE_SIZE, dtype=torch.float64) + 0.5) / SRGB8_TABLE_SIZE) ** 2
    encoded = quantize(linear_to_srgb(x.reshape(1, 1, 1, -1).expand(1, 3, 1, -1)), 8)[0, 0, 0]
    return torch.round(encoded * 255.0).to(device=device, dtype=torch.uint8).contiguous()


class LinearToSrgb(nn.Module):
    """Module twin of :func:`linear_to_srgb`.

    Shape:
        - Input: :math:`(*, 3, H, W)`
        - Output: :math:`(*, 3, H, W)`

    Examples:
        >>> x = torch.rand(2, 3, 4, 4)
        >>> torch.allclose(LinearToSrgb()(x), linear_to_srgb(x))
        True
    """

    def forward(self, image: torch.Tensor) -> torch.Tensor:
        return linear_to_srgb(image)


class SrgbToLinear(nn.Module):
    """Module twin of :func:`srgb_to_linear`.

    Shape:
        - Input: :math:`(*, 3, H, W)`
        - Output: :math:`(*, 3, H, W)`

    Examples:
        >>> x = torch.rand(2, 3, 4, 4)
        >>> torch.allclose(SrgbToLinear()(LinearToSrgb()(x)), x, atol=1e-6)
        True
    """

    def forward(self, image: torch.Tensor) -> torch.Tensor:
        return srgb_to_linear(image)


class GammaEncode(nn.Module):
    """Module twin of :func:`gamma_encode`.

    Args:
        gamma: the display gamma, > 0.
        knee: where the chord meets the curve, in ``[0, 1)``; 0 for the exact power.

    Shape:
        - Input: :math:`(*)`
        - Output: :math:`(*)`

    Examples:
        >>> [round(v, 4) for v in GammaEncode()(torch.tensor([0.0, 0.25, 1.0])).tolist()]
        [0.0, 0.5325, 1.0]
    """

    def __init__(self, gamma: float = 2.2, knee: float = GAMMA_KNEE) -> None:
        super().__init__()
        self.gamma = gamma
        self.knee = knee

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return gamma_encode(x, self.gamma, knee=self.knee)


class GammaDecode(nn.Module):
    """Module twin of :func:`gamma_decode`.

    Args:
        gamma: the display gamma, > 0.

    Shape:
        - Input: :math:`(*)`
        - Output: :math:`(*)`

    Examples:
        >>> x = torch.tensor([0.001, 0.25, 1.0])
        >>> torch.allclose(GammaDecode()(GammaEncode()(x)), x)
        True
    """

    def __init__(self, gamma: float = 2.2) -> None:
        super().__init__()
        self.gamma = gamma

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return gamma_decode(x, self.gamma)


class Quantize(nn.Module):
    """Module twin of :func:`quantize`.

    Args:
        bits: bit depth, 1 to 16.
        straight_through: pass the gradient of the rounding through unchanged.

    Shape:
        - Input: :math:`(*)`
        - Output: :math:`(*)`

    Examples:
        >>> Quantize(bits=1)(torch.tensor([-0.5, 0.2, 0.7, 2.0])).tolist()
        [0.0, 0.0, 1.0, 1.0]
    """

    def __init__(self, bits: int = 8, straight_through: bool = False) -> None:
        super().__init__()
        self.bits = bits
        self.straight_through = straight_through

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return quantize(x, self.bits, self.straight_through)
