r"""Colour looks: what users do to a photo's colours after the camera, and what that does to its lighting.

A portrait reaches an estimator black and white, desaturated, white-balanced warmer or cooler, or graded
through a "look". None of these moves a light: where the light comes from is written in the shading, not in
the colour. This module is that family of changes, used twice:

- by the **colour check** of the evaluation (:mod:`kornia_ilum_lab.evaluation.colour`), which applies each of
  :data:`LOOKS` to a portrait and measures how far the estimated main light turns and how its strength
  changes;
- by **training** (``PortraitConfig.colour_looks``), which draws a random look for a share of the portraits
  (:func:`draw_looks`) and changes their lighting target as the look changes the photo's units
  (:func:`apply_looks`), so that the network cannot read the light's direction from the photo's colours.

The looks act on sRGB-encoded images ``(B, 3, H, W)`` in ``[0, 1]``, as an editor does:

- :func:`greyscale`: the luma of the encoded values, Rec. 601 weights, replicated into R, G and B (what
  OpenCV's, Pillow's and Kornia's ``rgb_to_grayscale`` write; :func:`kornia.color.rgb_to_grayscale`);
- :func:`desaturate`: each pixel moved towards that luma by ``amount`` (1: greyscale);
- :func:`white_balance`: per-channel gains in *linear* light, normalised to keep the luminance
  (``LUMINANCE . gains = 1``), as a white-balance slider does on a raw or linear image;
- :func:`grade`: the ASC CDL (American Society of Cinematographers Color Decision List) per channel on the
  encoded values, ``clip(x * slope + offset) ^ power``, a colourist's primary grade; then an optional
  saturation (the CDL's own ``sat``), towards the Rec. 709 luma of the result.

**The lighting target of a look** (docs/conventions.rst, "Units of lighting": the lighting is in the units of
the photograph): a white balance multiplies every channel of a linear image by its gain, so the lighting is
multiplied by the same gains, exactly; a greyscale photo has one channel, whose linear value is close to the
luminance of the colour photo's, so its lighting is the **luminance of the lighting, grey**; a desaturated
photo's lighting is the lighting moved towards its luminance by the same amount (exact for a grey subject); a
grade is a non-linear curve with no lighting of its own, so the target stays the lighting of the ungraded
photo (its direction is what counts; its colour is as near as a curve allows).

Examples:
    >>> image = torch.rand(2, 3, 8, 8)
    >>> grey = greyscale(image)
    >>> bool((grey[:, 0] == grey[:, 1]).all() and (grey[:, 1] == grey[:, 2]).all())
    True
    >>> sorted(LOOKS)
    ['cool', 'desaturated', 'faded', 'greyscale', 'sepia', 'teal_orange', 'warm']
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import kornia
import torch

from kornia_ilum.color import LUMINANCE, linear_to_srgb, srgb_to_linear
from kornia_ilum.core.check import check_tensor
from kornia_ilum.core.errors import ShapeError, ValueCheckError

__all__ = [
    "LOOKS",
    "LOOK_KINDS",
    "Look",
    "apply_look",
    "apply_looks",
    "desaturate",
    "draw_looks",
    "grade",
    "greyscale",
    "look_lighting",
    "white_balance",
]


def _images(image: torch.Tensor) -> None:
    check_tensor(image, "image", ["B", "3", "H", "W"], floating=True)


def _per_image(value: torch.Tensor | float, b: int, name: str, shape: tuple[int, ...] = ()) -> torch.Tensor:
    v = torch.as_tensor(value, dtype=torch.float32)
    if v.dim() == len(shape):
        v = v.expand(b, *shape)
    if tuple(v.shape) != (b, *shape):
        raise ShapeError(f"{name} must be a number, {tuple(shape) or 'a scalar'} or one per image "
                         f"{(b, *shape)}, got {tuple(v.shape)}")
    return v


def greyscale(image: torch.Tensor) -> torch.Tensor:
    r"""The photo in black and white: the Rec. 601 luma of the encoded values in all three channels.

    Args:
        image: sRGB-encoded images in ``[0, 1]``.

    Returns:
        the grey images, the same shape.

    Shape:
        - image: :math:`(B, 3, H, W)`
        - Output: :math:`(B, 3, H, W)`

    Examples:
        >>> [round(v, 3) for v in greyscale(torch.tensor([1.0, 0.0, 0.0]).view(1, 3, 1, 1)).flatten().tolist()]
        [0.299, 0.299, 0.299]
    """
    _images(image)
    return kornia.color.rgb_to_grayscale(image).expand_as(image).contiguous()


def desaturate(image: torch.Tensor, amount: torch.Tensor | float) -> torch.Tensor:
    r"""Each pixel moved towards its luma (:func:`greyscale`) by ``amount`` (0: unchanged, 1: grey).

    Args:
        image: sRGB-encoded images in ``[0, 1]``.
        amount: a number or one per image ``(B,)``, in ``[0, 1]``.

    Returns:
        the desaturated images, the same shape.

    Shape:
        - image: :math:`(B, 3, H, W)`
        - Output: :math:`(B, 3, H, W)`

    Examples:
        >>> x = torch.tensor([0.8, 0.2, 0.2]).view(1, 3, 1, 1)
        >>> y = desaturate(x, 0.5).flatten()
        >>> bool(y[0] < 0.8 and y[1] > 0.2)
        True
    """
    _images(image)
    a = _per_image(amount, image.shape[0], "amount").to(image)
    return torch.lerp(image, greyscale(image), a.view(-1, 1, 1, 1))


def white_balance(image: torch.Tensor, gains: torch.Tensor) -> torch.Tensor:
    r"""Per-channel gains in linear light, normalised to keep the luminance, then clipped at white.

    Args:
        image: sRGB-encoded images in ``[0, 1]``.
        gains: ``(3,)`` or ``(B, 3)`` positive gains of R, G, B (scaled so that ``LUMINANCE . gains = 1``).

    Returns:
        the white-balanced images, the same shape.

    Shape:
        - image: :math:`(B, 3, H, W)`
        - Output: :math:`(B, 3, H, W)`

    Examples:
        >>> x = torch.full((1, 3, 2, 2), 0.5)
        >>> y = white_balance(x, torch.tensor([1.2, 1.0, 0.7]))
        >>> bool(y[0, 0, 0, 0] > 0.5 > y[0, 2, 0, 0])
        True
    """
    _images(image)
    g = _normalised_gains(_per_image(gains, image.shape[0], "gains", (3,))).to(image)
    return linear_to_srgb((srgb_to_linear(image) * g[:, :, None, None]).clamp(0.0, 1.0))


def _normalised_gains(gains: torch.Tensor) -> torch.Tensor:
    if not bool((gains > 0).all()):
        raise ValueCheckError("white-balance gains must be positive")
    weights = torch.tensor(LUMINANCE, dtype=gains.dtype)
    return gains / (gains * weights).sum(-1, keepdim=True)


def grade(image: torch.Tensor, slope: torch.Tensor, offset: torch.Tensor, power: torch.Tensor,
          saturation: torch.Tensor | float = 1.0) -> torch.Tensor:
    r"""The ASC CDL on the encoded values: ``clip(x * slope + offset, 0, 1) ^ power`` per channel, then the
    saturation towards the Rec. 709 luma of the result.

    Args:
        image: sRGB-encoded images in ``[0, 1]``.
        slope, offset, power: ``(3,)`` or ``(B, 3)``; ``power`` positive.
        saturation: a number or ``(B,)``; 1 keeps the colours, 0 makes them grey.

    Returns:
        the graded images in ``[0, 1]``, the same shape.

    Shape:
        - image: :math:`(B, 3, H, W)`
        - Output: :math:`(B, 3, H, W)`

    Examples:
        >>> x = torch.rand(1, 3, 4, 4)
        >>> one, zero = torch.ones(3), torch.zeros(3)
        >>> torch.allclose(grade(x, one, zero, one), x)
        True
    """
    _images(image)
    b = image.shape[0]
    s, o, p = (_per_image(v, b, name, (3,)).to(image)[:, :, None, None]
               for v, name in ((slope, "slope"), (offset, "offset"), (power, "power")))
    if not bool((p > 0).all()):
        raise ValueCheckError("the grade's power must be positive")
    y = (image * s + o).clamp(0.0, 1.0) ** p
    sat = _per_image(saturation, b, "saturation").to(image).view(-1, 1, 1, 1)
    luma = (y * torch.tensor(LUMINANCE, dtype=y.dtype, device=y.device).view(1, 3, 1, 1)).sum(1, keepdim=True)
    return (luma + sat * (y - luma)).clamp(0.0, 1.0)


# ----------------------------------------------------------------------------------------------
# a look: one of the kinds with its parameters


#: The kinds of look, by code (the ``kind`` of :class:`Look`): 0 none, then these.
LOOK_KINDS: tuple[str, ...] = ("none", "greyscale", "desaturate", "white_balance", "grade")


@dataclass(frozen=True)
class Look:
    r"""One colour look per image, as tensors (a batch of looks; kind 0 leaves an image as it is).

    Args:
        kind: ``(B,)`` int64 codes of :data:`LOOK_KINDS`.
        amount: ``(B,)`` the desaturation's amount (greyscale: 1).
        gains: ``(B, 3)`` the white balance's gains (others: 1).
        slope, offset, power: ``(B, 3)`` the grade's CDL (others: 1, 0, 1).
        saturation: ``(B,)`` the grade's saturation (others: 1).
        grey_first: ``(B,)`` bool, the grade applied to the greyscale photo (a toned black and white: sepia).
    """

    kind: torch.Tensor
    amount: torch.Tensor
    gains: torch.Tensor
    slope: torch.Tensor
    offset: torch.Tensor
    power: torch.Tensor
    saturation: torch.Tensor
    grey_first: torch.Tensor

    @classmethod
    def identity(cls, n: int) -> Look:
        """``n`` looks that change nothing."""
        ones3 = torch.ones(n, 3)
        return cls(kind=torch.zeros(n, dtype=torch.int64), amount=torch.zeros(n), gains=ones3.clone(),
                   slope=ones3.clone(), offset=torch.zeros(n, 3), power=ones3.clone(), saturation=torch.ones(n),
                   grey_first=torch.zeros(n, dtype=torch.bool))

    @classmethod
    def named(cls, name: str, n: int = 1) -> Look:
        """The look of :data:`LOOKS` called ``name``, for ``n`` images."""
        if name not in LOOKS:
            raise ValueCheckError(f"unknown look {name!r}; the looks are {', '.join(sorted(LOOKS))}")
        spec = LOOKS[name]
        base = cls.identity(n)
        fields = {"kind": torch.full((n,), LOOK_KINDS.index(str(spec["kind"])), dtype=torch.int64)}
        for key, value in spec.items():
            if key == "kind":
                continue
            current = getattr(base, key)
            fields[key] = torch.as_tensor(value, dtype=current.dtype).expand_as(current).clone()
        return cls(**{**base.__dict__, **fields})


#: The looks of the colour check, by name: what users do to photos' colours.
LOOKS: dict[str, Mapping[str, object]] = {
    "greyscale": {"kind": "greyscale", "amount": 1.0},
    "desaturated": {"kind": "desaturate", "amount": 0.6},
    # white balance of a photo taken under about 3200 K and balanced for daylight (and the reverse)
    "warm": {"kind": "white_balance", "gains": (1.35, 1.0, 0.62)},
    "cool": {"kind": "white_balance", "gains": (0.74, 1.0, 1.45)},
    # the grades of common presets: the teal-and-orange of films, a faded film look, a sepia-toned black and white
    "teal_orange": {"kind": "grade", "slope": (1.12, 1.0, 0.86), "offset": (-0.02, 0.01, 0.05),
                    "power": (0.95, 1.0, 1.12), "saturation": 1.2},
    "faded": {"kind": "grade", "slope": (0.82, 0.82, 0.78), "offset": (0.12, 0.10, 0.10),
              "power": (1.0, 1.0, 1.0), "saturation": 0.7},
    "sepia": {"kind": "grade", "slope": (1.08, 0.96, 0.78), "offset": (0.02, 0.0, -0.02),
              "power": (1.0, 1.0, 1.05), "grey_first": True},
}


def apply_look(image: torch.Tensor, look: Look) -> torch.Tensor:
    r"""Each image through its look (:class:`Look`; kind 0: unchanged).

    Args:
        image: sRGB-encoded images in ``[0, 1]``.
        look: ``B`` looks.

    Returns:
        the images, the same shape.

    Shape:
        - image: :math:`(B, 3, H, W)`
        - Output: :math:`(B, 3, H, W)`

    Examples:
        >>> x = torch.rand(2, 3, 4, 4)
        >>> y = apply_look(x, Look.named("greyscale", 2))
        >>> torch.allclose(y, greyscale(x))
        True
    """
    _images(image)
    if look.kind.shape != (image.shape[0],):
        raise ShapeError(f"look has {tuple(look.kind.shape)} kinds for {image.shape[0]} images")
    out = image.clone()
    kind = look.kind
    grey = kind == LOOK_KINDS.index("greyscale")
    if grey.any():
        out[grey] = greyscale(image[grey])
    des = kind == LOOK_KINDS.index("desaturate")
    if des.any():
        out[des] = desaturate(image[des], look.amount[des])
    wb = kind == LOOK_KINDS.index("white_balance")
    if wb.any():
        out[wb] = white_balance(image[wb], look.gains[wb])
    gr = kind == LOOK_KINDS.index("grade")
    if gr.any():
        source = torch.where(look.grey_first[gr].view(-1, 1, 1, 1), greyscale(image[gr]), image[gr])
        out[gr] = grade(source, look.slope[gr], look.offset[gr], look.power[gr], look.saturation[gr])
    return out


def look_lighting(lighting: torch.Tensor, look: Look) -> torch.Tensor:
    r"""The lighting of each photo after its look, in the look's units (module docstring): greyscale and toned
    black and white give the luminance in grey, desaturation moves towards it by the amount, white balance
    multiplies by the normalised gains, a colour grade keeps the lighting.

    Args:
        lighting: linear lighting (any image shape: a mirror ball, spheres).
        look: ``B`` looks.

    Returns:
        the lighting, the same shape.

    Shape:
        - lighting: :math:`(B, 3, H, W)`
        - Output: :math:`(B, 3, H, W)`

    Examples:
        >>> ball = torch.zeros(1, 3, 4, 4); ball[:, 0] = 1.0  # a red light
        >>> grey = look_lighting(ball, Look.named("greyscale"))
        >>> [round(v, 4) for v in grey[0, :, 0, 0].tolist()]
        [0.2127, 0.2127, 0.2127]
    """
    check_tensor(lighting, "lighting", ["B", "3", "H", "W"], floating=True)
    weights = torch.tensor(LUMINANCE, dtype=lighting.dtype, device=lighting.device).view(1, 3, 1, 1)
    luminance = (lighting * weights).sum(1, keepdim=True).expand_as(lighting)
    kind = look.kind.to(lighting.device)
    grey = (kind == LOOK_KINDS.index("greyscale")) | ((kind == LOOK_KINDS.index("grade"))
                                                      & look.grey_first.to(lighting.device))
    amount = torch.where(kind == LOOK_KINDS.index("desaturate"), look.amount.to(lighting.device), 0.0)
    amount = torch.where(grey, 1.0, amount)
    gains = torch.where((kind == LOOK_KINDS.index("white_balance"))[:, None],
                        _normalised_gains(look.gains.double()).float().to(lighting.device),
                        torch.ones_like(look.gains, device=lighting.device))
    out = torch.lerp(lighting, luminance, amount.to(lighting.dtype).view(-1, 1, 1, 1))
    return out * gains.to(lighting.dtype)[:, :, None, None]


def apply_looks(image: torch.Tensor, lighting: torch.Tensor, look: Look) -> tuple[torch.Tensor, torch.Tensor]:
    r"""A photo and its lighting through the look: :func:`apply_look` and :func:`look_lighting` together.

    Args:
        image: sRGB-encoded images in ``[0, 1]``, or ``uint8`` codes (returned as ``uint8``, rounded).
        lighting: their linear lighting.
        look: ``B`` looks.

    Returns:
        ``(image, lighting)``.

    Shape:
        - image: :math:`(B, 3, H, W)`; lighting: :math:`(B, 3, S, S)`

    Examples:
        >>> codes = torch.randint(0, 256, (2, 3, 8, 8), dtype=torch.uint8)
        >>> image, ball = apply_looks(codes, torch.rand(2, 3, 4, 4), Look.named("sepia", 2))
        >>> image.dtype, tuple(ball.shape)
        (torch.uint8, (2, 3, 4, 4))
    """
    codes = image.dtype == torch.uint8
    x = image.float() / 255.0 if codes else image
    y = apply_look(x, look)
    if codes:
        y = (y * 255.0).round_().clamp_(0, 255).to(torch.uint8)
    return y, look_lighting(lighting, look)


def draw_looks(n: int, p: float, generator: torch.Generator) -> Look:
    r"""Random looks for ``n`` photos: with probability ``p`` one of greyscale, a desaturation, a toned black
    and white or a colour grade (equally likely), else none.

    The draws, per photo: the desaturation's amount uniform in ``[0.3, 1]``; a grade's slope and power
    ``exp(N(0, 0.1))`` per channel, offset ``N(0, 0.03)``, saturation ``exp(N(0, 0.25))``; a toned black and
    white is a grade of the greyscale photo with saturation 1. White balance is not drawn: the environments'
    own augmentation already changes the light's colour, in the photo and its target alike
    (:class:`~kornia_ilum_lab.synth.environments.Augment`).

    Args:
        n: the photos.
        p: the share with a look, in ``[0, 1]``.
        generator: the random source.

    Returns:
        the looks.

    Examples:
        >>> looks = draw_looks(1000, 0.4, torch.Generator().manual_seed(0))
        >>> 0.35 < float((looks.kind > 0).float().mean()) < 0.45
        True
    """
    if not 0.0 <= p <= 1.0:
        raise ValueCheckError(f"p must be in [0, 1], got {p!r}")
    on = torch.rand(n, generator=generator) < p
    which = torch.randint(4, (n,), generator=generator)  # greyscale, desaturate, toned b&w, grade
    amount = 0.3 + 0.7 * torch.rand(n, generator=generator)
    slope = torch.exp(0.1 * torch.randn(n, 3, generator=generator))
    offset = 0.03 * torch.randn(n, 3, generator=generator)
    power = torch.exp(0.1 * torch.randn(n, 3, generator=generator))
    saturation = torch.exp(0.25 * torch.randn(n, generator=generator))
    codes = torch.tensor([LOOK_KINDS.index(k) for k in ("greyscale", "desaturate", "grade", "grade")])
    kind = torch.where(on, codes[which], 0)
    grey_first = on & (which == 2)
    saturation = torch.where(grey_first, 1.0, saturation)
    amount = torch.where(which == 0, 1.0, amount)
    return Look(kind=kind, amount=amount, gains=torch.ones(n, 3), slope=slope, offset=offset, power=power,
                saturation=saturation, grey_first=grey_first)

