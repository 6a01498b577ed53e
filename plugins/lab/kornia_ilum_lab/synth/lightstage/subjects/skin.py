r"""Skin that reflects like skin: the light stage's skin albedo per Monk tone, from measured facial skin colour.

The Monk Skin Tone (MST) scale (Monk 2019) names 10 tones by display swatches; a swatch is how skin *looks* in
a picture, not what it *reflects*: decoded to CIELAB the swatches span ``L*`` 94 to 15, while measured facial
skin spans about ``L*`` 70 to 27 (docs/lightstage.rst, "Skin"). So each tone gets a measured colour instead:

- ``L*`` evenly spaced over the measured facial span, from 70 for MST 1 (the top of the "very light" class of
  the individual typology angle, ITA > 55 deg: Chardon et al. 1991; Del Bino et al. 2006) to 29 for MST 10
  (the darkest facial clusters measured: Wee et al. 2013, ``L*`` 26.7 at 45/0 on the nose and upper lip); the
  MST tones are designed to be perceptually evenly spaced, and ``L*`` is perceptual lightness;
- ``a*`` 9 to 12 (facial ``a*`` varies little across groups: Xiao et al. 2017) and ``b*`` rising from 12 to
  19 for tan and brown skin and falling again for the darkest (Xiao et al. 2017; Del Bino and Bernerd 2013),
  so that the ITA passes through the six classes in order.

:data:`MEASURED_SKIN_LAB` holds them; :func:`lab_to_linear_rgb` converts to linear sRGB (D65, CIE 1931 2 deg,
Kornia's conversion). A spectrophotometer reads skin's total reflectance: the light scattered back from under
the surface *and* the few per cent reflected at it. The renderer's skin (Mitsuba ``principled``, GGX
``alpha`` 0.3 to 0.5, ``F0`` 0.025 to 0.035, i.e. the index 1.38 to 1.46 of the stratum corneum: Weyrich et al.
2006 fit ``eta = 1.38``) adds its specular lobe on top of its base colour: under a uniform white environment of
radiance 1, seen head-on, a flat patch reads ``base + 0.024`` (:data:`SKIN_SPECULAR_ALBEDO`, measured on the
renderer). So the base colour (the diffuse albedo that the subsurface step spreads, never scales) is the
measured total minus that: :data:`SKIN_ALBEDO`. :func:`measured_skin_range` gives, per tone, the box of linear
RGB totals of ``L*`` +-4, ``a*`` +-3, ``b*`` +-3 around it: what the uniform-white check of
:mod:`~kornia_ilum_lab.synth.lightstage.calibration` holds a rendered face to.
"""

from __future__ import annotations

import itertools

import torch
from kornia.color import lab_to_rgb

from kornia_ilum.color import srgb_to_linear
from kornia_ilum.core.errors import ValueCheckError

__all__ = [
    "MEASURED_SKIN_LAB",
    "SKIN_ALBEDO",
    "SKIN_LAB_TOLERANCE",
    "SKIN_SPECULAR_ALBEDO",
    "SKIN_TOTAL_REFLECTANCE",
    "lab_to_linear_rgb",
    "measured_skin_range",
]

_L_LIGHTEST, _L_DARKEST = 70.0, 29.0
_A_STAR = (9.0, 10.0, 11.0, 11.5, 12.0, 12.0, 12.0, 11.0, 10.0, 9.0)
_B_STAR = (12.0, 13.5, 15.0, 17.0, 18.5, 19.0, 18.0, 16.0, 13.5, 11.0)

#: Measured facial skin colour ``(L*, a*, b*)`` (D65) of each MST tone, index 0 is tone 1 (module docstring).
MEASURED_SKIN_LAB: tuple[tuple[float, float, float], ...] = tuple(
    (round(_L_LIGHTEST - (_L_LIGHTEST - _L_DARKEST) * i / 9, 2), a, b)
    for i, (a, b) in enumerate(zip(_A_STAR, _B_STAR, strict=True))
)
#: The spread of measured faces around a tone's colour: ``(L*, a*, b*)`` half-widths of its box.
SKIN_LAB_TOLERANCE: tuple[float, float, float] = (4.0, 3.0, 3.0)
#: What the renderer's skin specular adds to its base colour under uniform white light, seen head-on.
SKIN_SPECULAR_ALBEDO = 0.024
_MIN_ALBEDO = 0.005


def lab_to_linear_rgb(lab: tuple[float, float, float]) -> tuple[float, float, float]:
    """Linear sRGB (D65) of a CIELAB colour, unclipped (Kornia's ``lab_to_rgb``, then the sRGB decoding).

    Args:
        lab: ``(L*, a*, b*)``, D65 white, CIE 1931 2 deg observer.

    Returns:
        ``(r, g, b)`` linear sRGB, not clipped to ``[0, 1]`` (negative or above 1 out of the gamut).

    Examples:
        >>> [round(c, 3) for c in lab_to_linear_rgb((100.0, 0.0, 0.0))]
        [1.0, 1.0, 1.0]
    """
    srgb = lab_to_rgb(torch.tensor(lab, dtype=torch.float64).view(3, 1, 1), clip=False)
    lin = srgb_to_linear(srgb).flatten().tolist()
    return (lin[0], lin[1], lin[2])


#: Total reflectance (linear RGB) of each MST tone's measured colour: what a spectrophotometer reads.
SKIN_TOTAL_REFLECTANCE: tuple[tuple[float, float, float], ...] = tuple(
    tuple(round(c, 4) for c in lab_to_linear_rgb(lab)) for lab in MEASURED_SKIN_LAB  # type: ignore[misc]
)
#: The diffuse (base) albedo of each MST tone, index 0 is tone 1: the total less :data:`SKIN_SPECULAR_ALBEDO`.
SKIN_ALBEDO: tuple[tuple[float, float, float], ...] = tuple(
    tuple(round(max(c - SKIN_SPECULAR_ALBEDO, _MIN_ALBEDO), 4) for c in total)  # type: ignore[misc]
    for total in SKIN_TOTAL_REFLECTANCE
)


def measured_skin_range(tone: int) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    r"""The box ``(low, high)`` of linear RGB total reflectance of measured faces of MST ``tone`` (1 to 10).

    The colours ``(L*, a*, b*)`` within :data:`SKIN_LAB_TOLERANCE` of the tone's :data:`MEASURED_SKIN_LAB`,
    converted to linear RGB: the per-channel minimum and maximum over the box's corners (the conversion is
    monotonic along each axis per channel, so the corners bound it).

    Args:
        tone: the Monk Skin Tone, an int from 1 (lightest) to 10 (darkest).

    Returns:
        ``(low, high)``, each ``(r, g, b)`` linear sRGB; ``low`` is clipped at 0.

    Raises:
        ValueCheckError: ``tone`` is not an int from 1 to 10 (a :class:`ValueError`).

    Examples:
        >>> low, high = measured_skin_range(1)
        >>> all(lo < t < hi for lo, t, hi in zip(low, SKIN_TOTAL_REFLECTANCE[0], high))
        True
    """
    if not (isinstance(tone, int) and 1 <= tone <= len(MEASURED_SKIN_LAB)):
        raise ValueCheckError(f"tone must be an MST tone 1..{len(MEASURED_SKIN_LAB)}, got {tone!r}")
    centre = MEASURED_SKIN_LAB[tone - 1]
    corners = [
        lab_to_linear_rgb(tuple(c + s * t for c, s, t in zip(centre, signs, SKIN_LAB_TOLERANCE, strict=True)))
        for signs in itertools.product((-1.0, 1.0), repeat=3)
    ]
    low = tuple(max(0.0, min(c[i] for c in corners)) for i in range(3))
    high = tuple(max(c[i] for c in corners) for i in range(3))
    return low, high  # type: ignore[return-value]
