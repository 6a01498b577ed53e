r"""Phone-camera effects: the augmentations that turn a clean render into the kind of 8-bit photo a phone writes.

The estimators meet portraits taken by phones, not renders encoded with the plain sRGB curve. Each effect here is
a pure function with a per-image strength (a tensor ``(B,)``; strength 0 is the identity, so a batch mixes affected
and unaffected images in one vectorised call) and a ``Random*`` module that draws the strengths with a probability
and a range from a :class:`torch.Generator` (Kornia style). :class:`CameraEffects` chains them in the order of a
camera pipeline, and is what :class:`~kornia_ilum_lab.synth.lightstage.PortraitDataset` applies:

1. :func:`lens_blur` (linear): a small Gaussian of ``sigma`` pixels, the optics' softness (0 to 1 px).
2. :func:`vignette` (linear): the lens' fall-off towards the corners, ``1 - strength * r^2`` (``r = 1`` at the
   corners).
3. :func:`sensor_noise` (linear, before any tone mapping, as on a sensor): Poisson-Gaussian noise of variance
   ``shot * x + read^2``. One ISO-like level sets both: ``shot`` is drawn log-uniformly and ``read`` follows it
   as measured on phone sensors by Brooks et al. 2019 ("Unprocessing images for learned raw denoising", Sec. 3.4:
   ``log read^2 = 2.18 log shot + 1.2``, without their jitter). The default range, ``shot`` in
   ``[1e-5, 1e-3]``, gives a noise of 0.04 to 1.3 % of mid-grey's value plus a read noise of at most 0.001
   (about 3 codes in black): a phone's output after its own denoising, not raw.
4. :func:`highlight_rolloff` (linear, the sensor's values after the gain): a shoulder that compresses the values
   above a knee ``1 - s`` towards white instead of clipping them at 1, as phones' HDR pipelines do (several
   exposures merged, highlights tone-mapped down). Without it an exposure metered on a dark face clips what is
   brighter than the skin: the whites of the eyes, the teeth, the background, which are the references a face
   carries for the strength of the light (docs/training.rst, "The references a face carries"). Drawn for half
   the photos, ``s`` in ``[0.25, 0.6]``: white (1) maps to 0.70-0.88, four times white to 0.91-0.98.
5. :func:`tone_curve` (on the sRGB-encoded values): a gamma ``y = x^gamma`` then a monotone S-curve
   ``y - c sin(2 pi y) / (2 pi)`` (``c > 0`` adds contrast, ``c < 0`` flattens; ``|c| < 1``); both end points stay
   fixed. Phones tone-map with curves of their own, not the bare sRGB curve. :func:`encode_tone8` is the fused
   path: linear to 8-bit codes through one table per image (of the sRGB curve and the tone curve), as fast as
   :func:`~kornia_ilum.color.encode_srgb8`; it folds the roll-off into the same table.
6. :func:`jpeg_compress` (8-bit): an OpenCV JPEG round trip at a quality of 40 to 95 (4:2:0 chroma subsampling,
   OpenCV's default), one image at a time (noise-like content costs more than photos).

:meth:`CameraEffects.apply` runs the chain fused on CPU, one image at a time in a scratch image that stays in
the cache (exposure and vignette as one multiplication, the noise in the units of the code table, each effect
only on the images that draw it; :meth:`CameraEffects.apply_reference` is the unfused chain, equal up to float
rounding). Fused, every effect off costs no more than :func:`~kornia_ilum.color.encode_srgb8` alone, and the
defaults a fraction of the unfused chain, JPEG being the largest part (``benchmarks/bench_portraits.py``;
timings in docs/environments.rst, "Measured").

White-balance errors are left out on purpose: the ground-truth lighting of a portrait is in the units of its
image (docs/conventions.rst, "Units of lighting"), so a colour cast would have to be applied to the truth as
well, which is what the environments' white-balance augmentation
(:class:`~kornia_ilum_lab.synth.environments.Augment`) already does; a cast applied to the image alone would teach
the estimator to ignore the lighting's colour.

Convention:
    Images are ``(B, C, H, W)``; linear effects take non-negative linear values (HDR allowed), the tone curve
    and JPEG take encoded values in ``[0, 1]`` (or ``uint8`` codes for JPEG). Randomness only comes from the
    generator passed in (or from a given noise tensor), so results are reproducible.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from collections.abc import Sequence
from typing import Any

import torch
import torch.nn.functional as F
from torch import nn

from kornia_ilum.color import SRGB8_TABLE_SIZE, encode_srgb8, linear_to_srgb, srgb8_table
from kornia_ilum.core.check import check_tensor
from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError

__all__ = [
    "CameraEffects",
    "RandomHighlightRolloff",
    "RandomJpeg",
    "RandomLensBlur",
    "RandomSensorNoise",
    "RandomToneCurve",
    "RandomVignette",
    "encode_tone8",
    "highlight_rolloff",
    "jpeg_compress",
    "lens_blur",
    "read_noise_for_shot",
    "sensor_noise",
    "tone_curve",
    "LINEAR_RESPONSE_GAMMA",
    "vignette",
]

#: The :func:`tone_curve` gamma (contrast 0) that undoes the sRGB curve: a camera with a **linear response**
#: (machine-vision and scientific cameras, raw dumps; codes proportional to the light), within 7 % of linear
#: above 5 % of white and darker below (the sRGB curve's linear toe).
LINEAR_RESPONSE_GAMMA = 2.2


def _per_image(value: torch.Tensor | float, b: int, name: str) -> torch.Tensor:
    """A ``(B,)`` float tensor from a scalar or a ``(B,)`` tensor."""
    t = torch.as_tensor(value, dtype=torch.float64)
    if t.dim() == 0:
        t = t.expand(b)
    if t.shape != (b,):
        raise ShapeError(f"{name} must be a number or have shape ({b},), got {tuple(t.shape)}")
    if not bool(torch.isfinite(t).all()):
        raise ValueCheckError(f"{name} must be finite")
    return t


def _check_images(image: torch.Tensor, name: str = "image") -> None:
    check_tensor(image, name, ["B", "C", "H", "W"])
    if not image.is_floating_point():
        raise TypeCheckError(f"{name} must be a float tensor, got {image.dtype}")


def _check_generator(generator: object) -> None:
    if generator is not None and not isinstance(generator, torch.Generator):
        raise TypeCheckError(f"generator must be a torch.Generator or None, got {type(generator).__name__}")


# ----------------------------------------------------------------------------------------------
# functionals


def lens_blur(image: torch.Tensor, sigma: torch.Tensor | float) -> torch.Tensor:
    r"""Blur each image with its own small Gaussian: the optics' softness.

    Args:
        image: ``(B, C, H, W)`` float images (linear).
        sigma: the standard deviation in pixels, a number or ``(B,)``; 0 leaves an image unchanged.

    Returns:
        ``(B, C, H, W)``; separable, reflected at the borders, truncated at ``ceil(2 max(sigma))`` pixels and
        normalised (a kernel per image). CPU float32 images go through OpenCV's separable filter, plane by
        plane (faster than grouped convolutions on one core); others through one grouped convolution per
        axis (the same values up to float rounding).

    Shape:
        - image: :math:`(B, C, H, W)`
        - sigma: a number or :math:`(B,)`
        - Output: :math:`(B, C, H, W)`

    Convention:
        Images of docs/conventions.rst ("Images"): ``(B, C, H, W)`` float, linear values (HDR allowed).

    Examples:
        >>> x = torch.zeros(2, 1, 9, 9); x[:, :, 4, 4] = 1.0
        >>> y = lens_blur(x, torch.tensor([0.0, 1.0]))
        >>> torch.equal(y[0], x[0]), round(y[1].sum().item(), 4), y[1, 0, 4, 4].item() < 1.0
        (True, 1.0, True)
    """
    _check_images(image)
    b, c, h, w = image.shape
    s = _per_image(sigma, b, "sigma")
    if (s < 0).any():
        raise ValueCheckError("sigma must be non-negative")
    r = _blur_radius(float(s.max()) if b else 0.0, h, w)
    if r < 1:
        return image.clone()
    kern = _blur_kernels(s, r)
    if image.dtype == torch.float32 and image.device.type == "cpu":
        return _lens_blur_cv2(image, kern, s.tolist())
    kern = kern.to(image.dtype).repeat_interleave(c, 0)  # (B C, 2r + 1)
    flat = image.reshape(1, b * c, h, w)
    flat = F.conv2d(F.pad(flat, (r, r, 0, 0), mode="reflect"), kern[:, None, None, :], groups=b * c)
    flat = F.conv2d(F.pad(flat, (0, 0, r, r), mode="reflect"), kern[:, None, :, None], groups=b * c)
    return flat.reshape(b, c, h, w)


def _blur_radius(smax: float, h: int, w: int) -> int:
    """The kernel's half width for the largest sigma of a batch (0: no blur)."""
    if smax == 0.0:
        return 0
    return min(max(1, math.ceil(2.0 * smax)), (min(h, w) - 1))


def _blur_kernels(s: torch.Tensor, r: int) -> torch.Tensor:
    """Normalised Gaussian taps ``(B, 2r + 1)`` float64 of the sigmas ``s`` (sigma 0: the identity)."""
    x = torch.arange(-r, r + 1, dtype=torch.float64)
    kern = torch.exp(-(x[None] ** 2) / (2.0 * s.clamp(min=1e-6)[:, None] ** 2))
    kern = torch.where(s[:, None] > 0, kern, (x[None] == 0).double())
    return kern / kern.sum(-1, keepdim=True)


def _lens_blur_cv2(image: torch.Tensor, kern: torch.Tensor, sigmas: list[float]) -> torch.Tensor:
    """:func:`lens_blur` of CPU float32 images: OpenCV's separable filter on each plane (reflected borders:
    ``BORDER_REFLECT_101`` is torch's ``"reflect"``), faster than grouped convolutions on one core."""
    import cv2  # lazy: OpenCV loads on first use, not with the module

    src = image.contiguous()
    out = torch.empty_like(src)
    taps = kern.float().numpy()
    for k, sigma in enumerate(sigmas):
        if sigma <= 0:
            out[k].copy_(src[k])
            continue
        for c in range(src.shape[1]):
            cv2.sepFilter2D(src[k, c].numpy(), -1, taps[k], taps[k], dst=out[k, c].numpy(),
                            borderType=cv2.BORDER_REFLECT_101)
    return out


@functools.lru_cache(maxsize=8)
def _radius2(h: int, w: int) -> torch.Tensor:
    """Squared distance of the pixel centres from the image centre, 1 at the corners, ``(H, W)`` float32."""
    yy = ((torch.arange(h, dtype=torch.float64) + 0.5) / h - 0.5) ** 2
    xx = ((torch.arange(w, dtype=torch.float64) + 0.5) / w - 0.5) ** 2
    return ((yy[:, None] + xx[None]) / 0.5).float()


def vignette(image: torch.Tensor, strength: torch.Tensor | float) -> torch.Tensor:
    r"""Darken towards the corners: multiply by ``1 - strength * r^2``, ``r`` the distance to the centre (1 at a corner).

    Args:
        image: ``(B, C, H, W)`` float images (linear).
        strength: in ``[0, 1]``, a number or ``(B,)``; 0 leaves an image unchanged.

    Returns:
        the darkened images ``(B, C, H, W)``, in the dtype and on the device of ``image``.

    Raises:
        ValueCheckError: ``strength`` outside ``[0, 1]`` or not finite.

    Shape:
        - image: :math:`(B, C, H, W)`
        - strength: a number or :math:`(B,)`
        - Output: :math:`(B, C, H, W)`

    Convention:
        Images of docs/conventions.rst ("Images"): ``(B, C, H, W)`` float, linear values (HDR allowed).

    Examples:
        >>> y = vignette(torch.ones(1, 1, 4, 4), 0.5)
        >>> round(y[0, 0, 0, 0].item(), 4), round(y[0, 0, 1, 1].item(), 4)  # a corner pixel, an inner pixel
        (0.7188, 0.9688)
    """
    _check_images(image)
    b, _, h, w = image.shape
    v = _per_image(strength, b, "strength")
    if ((v < 0) | (v > 1)).any():
        raise ValueCheckError("strength must be in [0, 1]")
    gain = 1.0 - v.to(image.dtype)[:, None, None, None] * _radius2(h, w).to(image)
    return image * gain


def read_noise_for_shot(shot: torch.Tensor | float) -> torch.Tensor:
    r"""The read-noise standard deviation that goes with a shot-noise gain on phone sensors (Brooks et al. 2019).

    ``log(read^2) = 2.18 log(shot) + 1.2``; ``shot = 0`` gives 0.

    Args:
        shot: the shot-noise gain (the variance per unit of linear signal), a number or a tensor of any shape,
            non-negative.

    Returns:
        the read-noise standard deviation, float64, in the shape of ``shot`` (a 0-d tensor for a number).

    Examples:
        >>> round(read_noise_for_shot(1e-3).item(), 5)
        0.00098
    """
    s = torch.as_tensor(shot, dtype=torch.float64)
    return torch.where(s > 0, torch.exp(0.5 * (2.18 * torch.log(s.clamp(min=1e-30)) + 1.2)), torch.zeros_like(s))


def sensor_noise(
    linear: torch.Tensor,
    shot: torch.Tensor | float,
    *,
    read: torch.Tensor | float | None = None,
    generator: torch.Generator | None = None,
    noise: torch.Tensor | None = None,
) -> torch.Tensor:
    r"""Signal-dependent sensor noise: ``x + sqrt(shot * max(x, 0) + read^2) n``, ``n`` standard normal.

    The Gaussian approximation of Poisson (shot) noise plus Gaussian read noise, in linear units of the exposed
    image (1 is the clipping level), before tone mapping, as on a sensor.

    Args:
        linear: ``(B, C, H, W)`` linear images.
        shot: the shot-noise gain (variance per unit of signal), a number or ``(B,)``.
        read: the read-noise standard deviation, a number or ``(B,)``; ``None``: :func:`read_noise_for_shot`.
        generator: the source of ``n`` when ``noise`` is not given.
        noise: standard normal samples of the shape of ``linear`` to use as ``n`` (a caller with a cheaper source).

    Returns:
        ``(B, C, H, W)``; ``shot = read = 0`` returns the input's values.

    Shape:
        - linear: :math:`(B, C, H, W)`
        - shot, read: numbers or :math:`(B,)`
        - Output: :math:`(B, C, H, W)`

    Convention:
        Images of docs/conventions.rst ("Images"): ``(B, C, H, W)`` float, linear values in the units of the
        exposed image, before any tone mapping.

    Examples:
        >>> x = torch.full((2, 3, 64, 64), 0.25)
        >>> y = sensor_noise(x, torch.tensor([0.0, 1e-2]), read=torch.tensor([0.0, 0.0]),
        ...                  generator=torch.Generator().manual_seed(0))
        >>> torch.equal(y[0], x[0]), abs((y[1] - x[1]).std().item() - 0.05) < 0.003  # sqrt(0.01 * 0.25)
        (True, True)
    """
    _check_images(linear, "linear")
    _check_generator(generator)
    b = linear.shape[0]
    a = _per_image(shot, b, "shot")
    r = read_noise_for_shot(a) if read is None else _per_image(read, b, "read")
    if (a < 0).any() or (r < 0).any():
        raise ValueCheckError("shot and read must be non-negative")
    if noise is None:
        noise = torch.randn(linear.shape, generator=generator, dtype=linear.dtype, device=linear.device)
    elif noise.shape != linear.shape:
        raise ShapeError(f"noise must have the shape of linear {tuple(linear.shape)}, got {tuple(noise.shape)}")
    a4 = a.to(linear.dtype)[:, None, None, None]
    r4 = (r**2).to(linear.dtype)[:, None, None, None]
    std = torch.addcmul(r4, linear.clamp(min=0.0), a4).sqrt_()
    return std.mul_(noise).add_(linear)


def highlight_rolloff(linear: torch.Tensor, strength: torch.Tensor | float) -> torch.Tensor:
    r"""A highlight shoulder: the values above the knee ``k = 1 - s`` compressed towards white (1) instead of clipped.

    ``y = x`` for ``x <= k``, ``y = k + (x - k) / (1 + (x - k) / s)`` above: continuous with slope 1 at the knee,
    increasing, and below 1 for every finite ``x``, so an 8-bit encoding that clips at 1 keeps highlights apart
    that it would otherwise clip to one white. ``s = 0`` is the identity (the encoding's own clip at 1).

    Args:
        linear: ``(B, C, H, W)`` float images (linear, exposed; HDR allowed, non-negative).
        strength: ``s`` in ``[0, 1)``, a number or ``(B,)``; 0 leaves an image unchanged.

    Returns:
        ``(B, C, H, W)``, in the dtype and on the device of ``linear``.

    Raises:
        ValueCheckError: ``strength`` outside ``[0, 1)`` or not finite.

    Shape:
        - linear: :math:`(B, C, H, W)`
        - strength: a number or :math:`(B,)`
        - Output: :math:`(B, C, H, W)`

    Convention:
        Images of docs/conventions.rst ("Images"): ``(B, C, H, W)`` float, linear values (HDR allowed).

    Examples:
        >>> x = torch.tensor([0.18, 0.5, 1.0, 3.0, 1e4]).reshape(1, 1, 1, 5)
        >>> [round(v, 3) for v in highlight_rolloff(x, 0.5).flatten().tolist()]  # mid-grey stays, white does not
        [0.18, 0.5, 0.75, 0.917, 1.0]
    """
    _check_images(linear, "linear")
    s = _rolloff_strength(strength, linear.shape[0], "strength")
    return _rolloff(linear, s.to(linear.dtype).reshape(-1, 1, 1, 1))


def _rolloff_strength(value: torch.Tensor | float, b: int, name: str) -> torch.Tensor:
    """``(b,)`` roll-off strengths, checked to lie in ``[0, 1)``."""
    s = _per_image(value, b, name)
    if ((s < 0) | (s >= 1) | ~torch.isfinite(s)).any():
        raise ValueCheckError(f"{name} must be in [0, 1)")
    return s


def _rolloff(x: torch.Tensor, s: torch.Tensor) -> torch.Tensor:
    """:func:`highlight_rolloff` on checked inputs (``s`` broadcasts against ``x``; ``s = 0`` rows unchanged)."""
    over = (x - (1.0 - s)).clamp(min=0.0)
    shoulder = over / (1.0 + over / s.clamp(min=1e-12))
    return torch.where(s > 0, x - over + shoulder, x)


def tone_curve(image: torch.Tensor, contrast: torch.Tensor | float, gamma: torch.Tensor | float = 1.0
               ) -> torch.Tensor:
    r"""A camera's tone curve on top of sRGB: ``y = x^gamma``, then the S-curve ``y - c sin(2 pi y) / (2 pi)``.

    Args:
        image: ``(B, C, H, W)`` encoded values in ``[0, 1]`` (values outside are clipped first).
        contrast: ``c`` in ``(-1, 1)``, a number or ``(B,)`` (positive: more contrast; 0: no S-curve).
        gamma: a positive number or ``(B,)`` (below 1 brightens the mid-tones; 1: none).

    Returns:
        ``(B, C, H, W)`` in ``[0, 1]``; monotone, 0 and 1 stay fixed, ``contrast=0, gamma=1`` is the identity.

    Shape:
        - image: :math:`(B, C, H, W)`
        - contrast, gamma: numbers or :math:`(B,)`
        - Output: :math:`(B, C, H, W)`

    Convention:
        Images of docs/conventions.rst ("Images"): ``(B, C, H, W)`` float, sRGB-encoded values in
        :math:`[0, 1]` (LDR), not linear ones.

    Examples:
        >>> x = torch.tensor([0.0, 0.25, 0.5, 1.0]).reshape(1, 1, 1, 4)
        >>> tone_curve(x, 0.0).flatten().tolist()
        [0.0, 0.25, 0.5, 1.0]
        >>> [round(v, 4) for v in tone_curve(x, 0.5).flatten().tolist()]  # darker shadows, same mid-grey
        [0.0, 0.1704, 0.5, 1.0]
    """
    _check_images(image)
    b = image.shape[0]
    c = _per_image(contrast, b, "contrast")
    g = _per_image(gamma, b, "gamma")
    if (c.abs() >= 1).any():
        raise ValueCheckError("contrast must be in (-1, 1) (the curve must stay monotone)")
    if (g <= 0).any():
        raise ValueCheckError("gamma must be positive")
    return _tone(image.clamp(0.0, 1.0), c, g)


def _tone(x: torch.Tensor, c: torch.Tensor, g: torch.Tensor) -> torch.Tensor:
    shape = (-1,) + (1,) * (x.dim() - 1)
    c, g = c.to(x.dtype).reshape(shape), g.to(x.dtype).reshape(shape)
    y = torch.where(g == 1, x, x.pow(g))
    return (y - c * torch.sin((2 * math.pi) * y) / (2 * math.pi)).clamp_(0.0, 1.0)


#: Cells of the per-image tables of :func:`encode_tone8`, evenly spaced in ``sqrt(x)`` (as in
#: :func:`~kornia_ilum.color.encode_srgb8`): fine enough that a value is at most a code off.
_TONE_CELLS = 4096

@functools.lru_cache(maxsize=1)
def _srgb_cells() -> torch.Tensor:
    x = ((torch.arange(_TONE_CELLS, dtype=torch.float64) + 0.5) / _TONE_CELLS) ** 2
    return linear_to_srgb(x.reshape(1, 1, 1, -1).expand(1, 3, 1, -1))[0, 0, 0]


def encode_tone8(linear: torch.Tensor, contrast: torch.Tensor | float, gamma: torch.Tensor | float = 1.0,
                 rolloff: torch.Tensor | float = 0.0) -> torch.Tensor:
    r"""Linear to 8-bit codes through :func:`highlight_rolloff`, the sRGB curve and :func:`tone_curve`, fused into
    one table per image.

    Rolls the highlights off, clips to ``[0, 1]``, encodes with sRGB, applies the tone curve and rounds to codes:
    the result of ``round(255 * tone_curve(linear_to_srgb(clip(highlight_rolloff(x)))))`` read from a table of
    4096 cells evenly spaced in ``sqrt(x)`` (at most one code off, near code boundaries); the roll-off runs on
    the values scaled to the table's units, before the lookup. Images without a curve go through
    :func:`~kornia_ilum.color.encode_srgb8`'s table and, without a roll-off either, are exactly its codes.

    Args:
        linear: ``(B, C, H, W)`` linear images (float).
        contrast, gamma: as in :func:`tone_curve`.
        rolloff: the strength of :func:`highlight_rolloff`, a number or ``(B,)`` (0: none).

    Returns:
        ``(B, C, H, W)`` ``torch.uint8``.

    Shape:
        - linear: :math:`(B, C, H, W)`
        - contrast, gamma, rolloff: numbers or :math:`(B,)`
        - Output: :math:`(B, C, H, W)`, ``torch.uint8``

    Convention:
        Images of docs/conventions.rst ("Images"): ``(B, C, H, W)`` float linear values in, 8-bit sRGB codes
        (with the tone curve) out.

    Examples:
        >>> x = torch.tensor([0.0, 0.2140, 1.0, 7.0]).reshape(1, 1, 1, 4)
        >>> encode_tone8(x, 0.0).flatten().tolist(), encode_tone8(x, 0.5).flatten().tolist()
        ([0, 127, 255, 255], [0, 127, 255, 255])
        >>> encode_tone8(x, 0.0, rolloff=0.5).flatten().tolist()  # white and 7 times white apart
        [0, 127, 225, 251]
    """
    _check_images(linear, "linear")
    b = linear.shape[0]
    c = _per_image(contrast, b, "contrast")
    g = _per_image(gamma, b, "gamma")
    s = _rolloff_strength(rolloff, b, "rolloff")
    if (c.abs() >= 1).any() or (g <= 0).any():
        raise ValueCheckError("contrast must be in (-1, 1) and gamma positive")
    if linear.device.type != "cpu":
        return _encode_tone8_reference(linear, c, g, s)
    out = torch.empty(linear.shape, dtype=torch.uint8)
    tables, cells = _code_tables(c, g)
    scratch = torch.empty(linear.shape[1:], dtype=torch.float32)
    index = torch.empty(linear.shape[1:], dtype=torch.int32)
    strength = s.tolist()
    for k in range(b):
        u = float(cells[k]) ** 2
        torch.mul(linear[k], u, out=scratch)
        if strength[k] > 0:
            _rolloff_scaled_(scratch, strength[k], u)
        _encode_one(scratch, tables[k], cells=cells[k], index=index, out=out[k])
    return out


def _encode_tone8_reference(linear: torch.Tensor, c: torch.Tensor, g: torch.Tensor, s: torch.Tensor | None = None
                            ) -> torch.Tensor:
    """:func:`encode_tone8` as first written (any device): the roll-off on the linear values, then
    ``encode_srgb8`` or a 4096-cell table per image."""
    if s is not None and bool((s > 0).any()):
        linear = _rolloff(linear, s.to(device=linear.device, dtype=linear.dtype).reshape(-1, 1, 1, 1))
    b = linear.shape[0]
    out = torch.empty(linear.shape, dtype=torch.uint8, device=linear.device)
    toned = ((c != 0) | (g != 1)).tolist()
    if not any(toned):
        return encode_srgb8(linear)
    tables = (_tone(_srgb_cells()[None].expand(b, -1), c, g) * 255.0).round_().to(torch.uint8).to(linear.device)
    n = float(_TONE_CELLS)
    for k in range(b):
        if not toned[k]:
            out[k] = encode_srgb8(linear[k])
            continue
        x = linear[k].to(torch.float32, copy=True).mul_(n * n).clamp_(0.0, (n - 0.5) ** 2).sqrt_()
        out[k] = tables[k].index_select(0, x.to(torch.int32).flatten()).view(x.shape)
    return out


def _code_tables(c: torch.Tensor, g: torch.Tensor) -> tuple[list[torch.Tensor], list[int]]:
    """Per image: the table of codes and its cell count (cells evenly spaced in ``sqrt(x)``).

    An image whose tone curve is the identity reads :func:`~kornia_ilum.color.encode_srgb8`'s own table (65536
    cells: exactly its codes); the others a table of :data:`_TONE_CELLS` cells of the sRGB curve then their
    tone curve (computed for those images only).
    """
    srgb = srgb8_table(torch.device("cpu"))
    toned = torch.nonzero((c != 0) | (g != 1)).flatten()
    tables, cells = [srgb] * len(c), [SRGB8_TABLE_SIZE] * len(c)
    if len(toned):
        cell = _srgb_cells()[None].expand(len(toned), -1)
        toned_tables = (_tone(cell, c[toned], g[toned]) * 255.0).round_().to(torch.uint8)
        for k, table in zip(toned.tolist(), toned_tables, strict=True):
            tables[k], cells[k] = table, _TONE_CELLS
    return tables, cells


def _rolloff_scaled_(x: torch.Tensor, s: float, u: float) -> torch.Tensor:
    """:func:`highlight_rolloff` of strength ``s > 0`` in place on values in units of ``1 / u`` (``x u``)."""
    over = (x - (1.0 - s) * u).clamp_(min=0.0)
    return x.sub_(over).add_(over.div_(over.mul(1.0 / (s * u)).add_(1.0)))


def _sqrt_(x: torch.Tensor) -> torch.Tensor:
    """In-place square root of a contiguous CPU float32 tensor (OpenCV's: faster than torch's here, and
    correctly rounded as IEEE ``sqrt`` is, so the same values)."""
    import cv2  # lazy: OpenCV loads on first use, not with the module

    flat = x.numpy().reshape(-1, x.shape[-1])
    cv2.sqrt(flat, dst=flat)
    return x


def _encode_one(scaled: torch.Tensor, table: torch.Tensor, *, cells: int, index: torch.Tensor,
                out: torch.Tensor) -> torch.Tensor:
    """Codes of one image from its linear values times ``cells^2`` (overwritten): clip, ``sqrt``, read the table.

    The steps of :func:`~kornia_ilum.color.encode_srgb8` (which does ``x * 65536^2``, clip, ``sqrt``, truncate,
    read), on a scratch image that stays in the cache; ``index`` is an int32 scratch of the image's shape.
    """
    _sqrt_(scaled.clamp_(0.0, (cells - 0.5) ** 2))
    index.copy_(scaled)
    return torch.index_select(table, 0, index.view(-1), out=out.view(-1))


def jpeg_compress(image: torch.Tensor, quality: torch.Tensor | int | float) -> torch.Tensor:
    r"""A JPEG round trip (OpenCV, 4:2:0), one image at a time, at a quality per image.

    Args:
        image: ``(B, 3, H, W)`` RGB, ``uint8`` codes or floats in ``[0, 1]`` (rounded to codes first).
        quality: the JPEG quality in ``[1, 100]``, a number or ``(B,)`` (rounded); 0 or less leaves an image
            unchanged (no compression).

    Returns:
        the decoded images, of the dtype of ``image`` (floats: codes / 255).

    Shape:
        - image: :math:`(B, 3, H, W)`
        - quality: a number or :math:`(B,)`
        - Output: :math:`(B, 3, H, W)`

    Convention:
        Images of docs/conventions.rst ("Images"): RGB, sRGB-encoded (8-bit codes or floats in :math:`[0, 1]`).

    Examples:
        >>> x = (torch.rand(1, 3, 16, 16, generator=torch.Generator().manual_seed(0)) * 255).to(torch.uint8)
        >>> torch.equal(jpeg_compress(x, 0), x), torch.equal(jpeg_compress(x, 40), x)
        (True, False)
    """
    check_tensor(image, "image", ["B", "3", "H", "W"], floating=False)
    b = image.shape[0]
    q = _per_image(quality, b, "quality").round().long().tolist()
    if any(v > 100 for v in q):
        raise ValueCheckError(f"quality must be at most 100, got {max(q)}")
    as_float = image.is_floating_point()
    if image.dtype != torch.uint8 and not as_float:
        raise TypeCheckError(f"image must be uint8 or float, got {image.dtype}")
    codes = (image.clamp(0.0, 1.0) * 255.0).round().to(torch.uint8) if as_float else image
    out = codes.cpu().clone().contiguous()
    for k in range(b):
        if q[k] > 0:
            _jpeg_one(out[k], q[k])
    out = out.to(image.device)
    return out.to(image.dtype) / 255.0 if as_float else out


def _jpeg_one(planes: torch.Tensor, quality: int) -> None:
    """JPEG round trip of one contiguous CPU ``(3, H, W)`` uint8 RGB image, in place (OpenCV, 4:2:0).

    The planes go to OpenCV's interleaved BGR and back with ``cv2.merge`` / ``cv2.split`` (vectorised, unlike
    numpy's and torch's strided copies of ``flip(0).permute(1, 2, 0)`` and back).
    """
    import cv2  # lazy: OpenCV loads on first use, not with the module

    p = planes.numpy()
    ok, buf = cv2.imencode(".jpg", cv2.merge([p[2], p[1], p[0]]), [int(cv2.IMWRITE_JPEG_QUALITY), int(quality)])
    if not ok:  # pragma: no cover - OpenCV failure
        raise ValueCheckError("cv2.imencode failed")
    dec = cv2.imdecode(buf, cv2.IMREAD_COLOR)
    cv2.split(dec, [p[2], p[1], p[0]])


# ----------------------------------------------------------------------------------------------
# random draws and modules


def _check_pair(value: Any, name: str, *, lo: float, hi: float, open_hi: bool = False) -> tuple[float, float]:
    if not (isinstance(value, (tuple, list)) and len(value) == 2):
        raise TypeCheckError(f"{name} must be a pair (low, high), got {value!r}")
    a, b = (float(v) for v in value)
    ok = math.isfinite(a) and math.isfinite(b) and lo <= a <= b and (b < hi if open_hi else b <= hi)
    if not ok:
        raise ValueCheckError(f"{name} must satisfy {lo:g} <= low <= high {'<' if open_hi else '<='} {hi:g}, "
                              f"got {value!r}")
    return a, b


def _check_p(p: Any, name: str) -> float:
    if isinstance(p, bool) or not isinstance(p, (int, float)) or not 0.0 <= p <= 1.0:
        raise ValueCheckError(f"{name} must be a probability in [0, 1], got {p!r}")
    return float(p)


def _draw(n: int, p: float, *, lo: float, hi: float, generator: torch.Generator | None, log: bool = False,
          off: float = 0.0) -> torch.Tensor:
    """``n`` values: with probability ``p`` uniform (log-uniform) in ``[lo, hi]``, else ``off``; float64.

    Always draws ``2 n`` uniforms, so the draws that follow do not depend on ``p`` or the range.
    """
    u = torch.rand(2, n, generator=generator, dtype=torch.float64)
    if log:
        value = torch.exp(math.log(lo) + (math.log(hi) - math.log(lo)) * u[1])
    else:
        value = lo + (hi - lo) * u[1]
    return torch.where(u[0] < p, value, torch.full_like(value, off))


class _RandomEffect(nn.Module):
    """A random effect: ``forward(image, generator)`` draws per-image parameters (:meth:`draw`) and applies them."""

    def draw(self, n: int, generator: torch.Generator | None = None) -> torch.Tensor:  # pragma: no cover
        raise NotImplementedError

    def extra_repr(self) -> str:
        return ", ".join(f"{k}={v}" for k, v in vars(self).items() if not k.startswith("_") and k != "training")


class RandomLensBlur(_RandomEffect):
    r"""Random :func:`lens_blur`: with probability ``p``, ``sigma`` uniform in ``sigma``, else none.

    Examples:
        >>> blur = RandomLensBlur(p=1.0)
        >>> blur(torch.rand(2, 3, 8, 8), torch.Generator().manual_seed(0)).shape
        torch.Size([2, 3, 8, 8])
    """

    def __init__(self, p: float = 0.2, sigma: tuple[float, float] = (0.0, 1.0)) -> None:
        super().__init__()
        self.p, self.sigma = _check_p(p, "p"), _check_pair(sigma, "sigma", lo=0.0, hi=8.0)

    def draw(self, n: int, generator: torch.Generator | None = None) -> torch.Tensor:
        return _draw(n, self.p, lo=self.sigma[0], hi=self.sigma[1], generator=generator)

    def forward(self, image: torch.Tensor, generator: torch.Generator | None = None) -> torch.Tensor:
        _check_generator(generator)
        return lens_blur(image, self.draw(image.shape[0], generator))


class RandomVignette(_RandomEffect):
    r"""Random :func:`vignette`: with probability ``p``, ``strength`` uniform in ``strength``, else none.

    Examples:
        >>> RandomVignette(p=1.0)(torch.ones(1, 3, 8, 8), torch.Generator().manual_seed(0)).max().item() <= 1.0
        True
    """

    def __init__(self, p: float = 0.3, strength: tuple[float, float] = (0.0, 0.3)) -> None:
        super().__init__()
        self.p, self.strength = _check_p(p, "p"), _check_pair(strength, "strength", lo=0.0, hi=1.0)

    def draw(self, n: int, generator: torch.Generator | None = None) -> torch.Tensor:
        return _draw(n, self.p, lo=self.strength[0], hi=self.strength[1], generator=generator)

    def forward(self, image: torch.Tensor, generator: torch.Generator | None = None) -> torch.Tensor:
        _check_generator(generator)
        return vignette(image, self.draw(image.shape[0], generator))


class RandomSensorNoise(_RandomEffect):
    r"""Random :func:`sensor_noise`: with probability ``p``, an ISO-like level ``shot`` log-uniform in ``shot``
    (read noise from :func:`read_noise_for_shot`), else none.

    Examples:
        >>> x = torch.full((1, 3, 8, 8), 0.5)
        >>> g = lambda: torch.Generator().manual_seed(0)
        >>> noisy = RandomSensorNoise(p=1.0)
        >>> torch.equal(noisy(x, g()), noisy(x, g())), torch.equal(noisy(x, g()), x)
        (True, False)
    """

    def __init__(self, p: float = 0.9, shot: tuple[float, float] = (1e-5, 1e-3)) -> None:
        super().__init__()
        self.p, self.shot = _check_p(p, "p"), _check_pair(shot, "shot", lo=1e-12, hi=1.0)

    def draw(self, n: int, generator: torch.Generator | None = None) -> torch.Tensor:
        return _draw(n, self.p, lo=self.shot[0], hi=self.shot[1], generator=generator, log=True)

    def forward(self, linear: torch.Tensor, generator: torch.Generator | None = None) -> torch.Tensor:
        _check_generator(generator)
        return sensor_noise(linear, self.draw(linear.shape[0], generator), generator=generator)


class RandomHighlightRolloff(_RandomEffect):
    r"""Random :func:`highlight_rolloff`: with probability ``p``, ``strength`` uniform in ``strength``, else none.

    Examples:
        >>> x = torch.full((4, 3, 8, 8), 3.0)
        >>> y = RandomHighlightRolloff(p=1.0)(x, torch.Generator().manual_seed(0))
        >>> bool((y < 1).all()), bool((y > 0.9).all())
        (True, True)
    """

    def __init__(self, p: float = 0.5, strength: tuple[float, float] = (0.25, 0.6)) -> None:
        super().__init__()
        self.p, self.strength = _check_p(p, "p"), _check_pair(strength, "strength", lo=0.0, hi=1.0,
                                                              open_hi=True)

    def draw(self, n: int, generator: torch.Generator | None = None) -> torch.Tensor:
        return _draw(n, self.p, lo=self.strength[0], hi=self.strength[1], generator=generator)

    def forward(self, linear: torch.Tensor, generator: torch.Generator | None = None) -> torch.Tensor:
        _check_generator(generator)
        return highlight_rolloff(linear, self.draw(linear.shape[0], generator))


class RandomToneCurve(_RandomEffect):
    r"""Random :func:`tone_curve`: with probability ``p``, ``contrast`` uniform and ``gamma`` log-uniform in their
    ranges, else the identity. :meth:`draw` returns ``(B, 2)``: contrast, gamma.

    Examples:
        >>> x = torch.rand(4, 3, 8, 8)
        >>> torch.equal(RandomToneCurve(p=0.0)(x, torch.Generator().manual_seed(0)), x)
        True
    """

    def __init__(self, p: float = 0.7, contrast: tuple[float, float] = (-0.2, 0.6),
                 gamma: tuple[float, float] = (0.8, 1.25)) -> None:
        super().__init__()
        self.p = _check_p(p, "p")
        c = _check_pair(contrast, "contrast", lo=-1.0, hi=1.0, open_hi=True)
        if c[0] <= -1.0:
            raise ValueCheckError(f"contrast must be in (-1, 1), got {contrast!r}")
        self.contrast, self.gamma = c, _check_pair(gamma, "gamma", lo=1e-3, hi=1e3)

    def draw(self, n: int, generator: torch.Generator | None = None) -> torch.Tensor:
        u = torch.rand(3, n, generator=generator, dtype=torch.float64)
        on = u[0] < self.p
        c = self.contrast[0] + (self.contrast[1] - self.contrast[0]) * u[1]
        lg = math.log(self.gamma[0]) + (math.log(self.gamma[1]) - math.log(self.gamma[0])) * u[2]
        return torch.stack([torch.where(on, c, 0.0), torch.where(on, torch.exp(lg), 1.0)], -1)

    def forward(self, image: torch.Tensor, generator: torch.Generator | None = None) -> torch.Tensor:
        _check_generator(generator)
        params = self.draw(image.shape[0], generator)
        if not ((params[:, 0] != 0) | (params[:, 1] != 1)).any():
            return image.clone()
        return tone_curve(image, params[:, 0], params[:, 1])


class RandomJpeg(_RandomEffect):
    r"""Random :func:`jpeg_compress`: with probability ``p``, a quality uniform in ``quality`` (rounded), else none.

    Examples:
        >>> x = torch.rand(2, 3, 16, 16)
        >>> torch.equal(RandomJpeg(p=0.0)(x, torch.Generator().manual_seed(0)), x)
        True
    """

    def __init__(self, p: float = 0.5, quality: tuple[float, float] = (40.0, 95.0)) -> None:
        super().__init__()
        self.p, self.quality = _check_p(p, "p"), _check_pair(quality, "quality", lo=1.0, hi=100.0)

    def draw(self, n: int, generator: torch.Generator | None = None) -> torch.Tensor:
        return _draw(n, self.p, lo=self.quality[0], hi=self.quality[1], generator=generator).round()

    def forward(self, image: torch.Tensor, generator: torch.Generator | None = None) -> torch.Tensor:
        _check_generator(generator)
        quality = self.draw(image.shape[0], generator)
        if not (quality > 0).any():
            return image.clone()
        return jpeg_compress(image, quality)


@dataclass(frozen=True)
class CameraEffects:
    r"""The phone-camera pipeline (module docstring): probabilities and ranges of each effect.

    :meth:`draw` draws every effect's parameters for a batch, always in the same order and always all of them
    (so switching an effect off leaves the others' draws unchanged; the roll-off, added last, is drawn last);
    :meth:`apply` runs the pipeline from exposed linear images to 8-bit codes: lens blur, vignette, sensor noise
    (linear), highlight roll-off, sRGB and tone curve (one table per image, :func:`encode_tone8`), JPEG. :meth:`off` has every probability 0: plain sRGB encoding, no noise.

    Args:
        blur_p, blur_sigma: :class:`RandomLensBlur`.
        vignette_p, vignette_strength: :class:`RandomVignette`.
        noise_p, noise_shot: :class:`RandomSensorNoise`.
        tone_p, tone_contrast, tone_gamma: :class:`RandomToneCurve`.
        jpeg_p, jpeg_quality: :class:`RandomJpeg`.
        rolloff_p, rolloff_strength: :class:`RandomHighlightRolloff`.

    Examples:
        >>> fx = CameraEffects()
        >>> params = fx.draw(2, torch.Generator().manual_seed(0))
        >>> sorted(params)
        ['blur', 'jpeg', 'noise', 'rolloff', 'tone', 'vignette']
        >>> fx.apply(torch.full((2, 3, 16, 16), 0.18), params, generator=torch.Generator().manual_seed(1)).dtype
        torch.uint8
    """

    blur_p: float = 0.2
    blur_sigma: tuple[float, float] = (0.0, 1.0)
    vignette_p: float = 0.3
    vignette_strength: tuple[float, float] = (0.0, 0.3)
    noise_p: float = 0.9
    noise_shot: tuple[float, float] = (1e-5, 1e-3)
    tone_p: float = 0.7
    tone_contrast: tuple[float, float] = (-0.2, 0.6)
    tone_gamma: tuple[float, float] = (0.8, 1.25)
    jpeg_p: float = 0.5
    jpeg_quality: tuple[float, float] = (40.0, 95.0)
    rolloff_p: float = 0.5
    rolloff_strength: tuple[float, float] = (0.25, 0.6)

    def __post_init__(self) -> None:
        self.modules()  # checks every field

    @classmethod
    def off(cls) -> CameraEffects:
        """No effect: the plain sRGB encoding of the exposed image, without noise."""
        return cls(blur_p=0.0, vignette_p=0.0, noise_p=0.0, tone_p=0.0, jpeg_p=0.0, rolloff_p=0.0)

    def modules(self) -> dict[str, _RandomEffect]:
        """The effects as modules, in the pipeline's order but for the roll-off (drawn last, applied before the
        tone curve)."""
        return {
            "blur": RandomLensBlur(self.blur_p, self.blur_sigma),
            "vignette": RandomVignette(self.vignette_p, self.vignette_strength),
            "noise": RandomSensorNoise(self.noise_p, self.noise_shot),
            "tone": RandomToneCurve(self.tone_p, self.tone_contrast, self.tone_gamma),
            "jpeg": RandomJpeg(self.jpeg_p, self.jpeg_quality),
            "rolloff": RandomHighlightRolloff(self.rolloff_p, self.rolloff_strength),
        }

    def draw(self, n: int, generator: torch.Generator | None = None) -> dict[str, torch.Tensor]:
        """Per-image parameters of every effect: ``blur``, ``vignette``, ``noise`` (shot), ``jpeg`` (quality;
        0: none), ``rolloff`` (strength) ``(n,)`` and ``tone`` ``(n, 2)`` (contrast, gamma); the identity where an effect is not drawn."""
        _check_generator(generator)
        return {name: module.draw(n, generator) for name, module in self.modules().items()}

    def apply(self, linear: torch.Tensor, params: dict[str, torch.Tensor], *, generator: torch.Generator | None = None,
              noise: torch.Tensor | Sequence[torch.Tensor] | None = None, inplace: bool = False,
              gain: torch.Tensor | None = None) -> torch.Tensor:
        """Exposed linear images ``(B, 3, H, W)`` to ``uint8`` codes with the parameters of :meth:`draw`.

        Args:
            linear: ``(B, 3, H, W)`` float linear images (exposed, or exposed by ``gain``); never modified.
            params: the parameters of :meth:`draw`.
            generator: the sensor noise's source when ``noise`` is not given (one ``randn`` of ``linear``'s shape,
                drawn when any image has noise).
            noise: standard normal samples: a tensor of ``linear``'s shape or a sequence of ``B`` tensors
                ``(3, H, W)`` (views, e.g. windows of a larger noise texture, are read without a copy).
            inplace: accepted for compatibility; the fused path never writes to ``linear``.
            gain: ``(B,)`` exposures: the exposed image is ``linear * gain`` (fused with the vignette).

        Convention:
            On CPU float32 the effects run fused, one image at a time on a scratch image that stays in the cache:
            the lens blur on the images that draw it (OpenCV's separable filter), then one multiplication by
            ``gain * (1 - v r^2)`` times the table's scale ``u`` (``cells^2``), the sensor noise in those units
            (``x u + sqrt(shot u) sqrt(x u + read^2 u / shot) n`` is ``u`` times the noisy ``x``), the highlight
            roll-off in those units, the table lookup of :func:`encode_tone8` and the JPEG round trip of the images that draw it. The result equals the
            unfused chain (:meth:`apply_reference`) up to float rounding: codes at most one off, for a few
            values near code boundaries (then JPEG may spread that difference a little). Other devices or
            dtypes run :meth:`apply_reference`.
        """
        _check_images(linear, "linear")
        if linear.device.type != "cpu" or linear.dtype != torch.float32:
            return self.apply_reference(linear, params, generator=generator, noise=noise, gain=gain)
        b, c, h, w = linear.shape
        shot = _per_image(params["noise"], b, "noise")
        noisy = (shot > 0).tolist()
        if any(noisy):
            noise = self._noise_list(linear, noise, generator)
        read2 = (read_noise_for_shot(shot) ** 2).tolist()
        shot_l = shot.tolist()
        scale = [1.0] * b if gain is None else _per_image(gain, b, "gain").tolist()
        vig = _per_image(params["vignette"], b, "vignette").tolist()
        quality = _per_image(params["jpeg"], b, "jpeg").round().long().tolist()
        tables, cells = _code_tables(params["tone"][:, 0].double(), params["tone"][:, 1].double())
        strength = _rolloff_strength(params["rolloff"], b, "rolloff").tolist()
        blur = _per_image(params["blur"], b, "blur")
        sources = list(linear)
        sel = torch.nonzero(blur > 0).flatten()
        if len(sel):
            for k, image in zip(sel.tolist(), lens_blur(linear[sel], blur[sel]), strict=True):
                sources[k] = image
        out = torch.empty(linear.shape, dtype=torch.uint8)
        x = torch.empty(c, h, w)
        std = torch.empty(c, h, w) if any(noisy) else None
        index = torch.empty(c, h, w, dtype=torch.int32)
        weight = torch.empty(h, w)
        r2 = _radius2(h, w)
        for k in range(b):
            u = float(cells[k]) ** 2  # exposed linear -> the table's units
            s = u * scale[k]
            if vig[k] > 0:
                torch.mul(r2, -vig[k] * s, out=weight).add_(s)
                torch.mul(sources[k], weight, out=x)
            else:
                torch.mul(sources[k], s, out=x)
            if noisy[k]:  # sqrt(A x+ + R) = sqrt(A) sqrt(x+ + R / A), A = shot u, R = read^2 u^2
                torch.clamp(x, min=0.0, out=std).add_(read2[k] * u / shot_l[k])
                x.addcmul_(_sqrt_(std), noise[k], value=math.sqrt(shot_l[k] * u))
            if strength[k] > 0:
                _rolloff_scaled_(x, strength[k], u)
            _encode_one(x, tables[k], cells=cells[k], index=index, out=out[k])
            if quality[k] > 0:
                _jpeg_one(out[k], quality[k])
        return out

    @staticmethod
    def _noise_list(linear: torch.Tensor, noise: torch.Tensor | Sequence[torch.Tensor] | None,
                    generator: torch.Generator | None) -> Sequence[torch.Tensor]:
        _check_generator(generator)
        if noise is None:
            return torch.randn(linear.shape, generator=generator, dtype=linear.dtype)
        if isinstance(noise, torch.Tensor):
            if noise.shape != linear.shape:
                raise ShapeError(f"noise must have the shape of linear {tuple(linear.shape)}, "
                                 f"got {tuple(noise.shape)}")
            return noise
        noise = list(noise)
        if len(noise) != len(linear) or any(not isinstance(n, torch.Tensor) or n.shape != linear.shape[1:]
                                            for n in noise):
            raise ShapeError(f"noise must be {len(linear)} tensors of shape {tuple(linear.shape[1:])}")
        return noise

    def apply_reference(self, linear: torch.Tensor, params: dict[str, torch.Tensor], *,
                        generator: torch.Generator | None = None,
                        noise: torch.Tensor | Sequence[torch.Tensor] | None = None,
                        gain: torch.Tensor | None = None) -> torch.Tensor:
        """:meth:`apply` unfused, effect after effect with the functionals (the reference; any device)."""
        _check_images(linear, "linear")
        x = linear.clone()
        if gain is not None:
            x.mul_(_per_image(gain, len(x), "gain").to(x)[:, None, None, None])
        for name, effect in (("blur", lens_blur), ("vignette", vignette)):
            value = params[name]
            if (value > 0).any():
                idx = torch.nonzero(value > 0).flatten()
                x[idx] = effect(x[idx], value[idx])
        if (params["noise"] > 0).any():
            if noise is not None and not isinstance(noise, torch.Tensor):
                noise = torch.stack(list(noise))
            x = sensor_noise(x, params["noise"], generator=generator, noise=noise)
        codes = _encode_tone8_reference(x, params["tone"][:, 0].double(), params["tone"][:, 1].double(),
                                        _rolloff_strength(params["rolloff"], len(x), "rolloff"))
        quality = params["jpeg"]
        if (quality > 0).any():
            codes = jpeg_compress(codes, quality)
        return codes
