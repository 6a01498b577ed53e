r"""Procedural outdoor environments: the Preetham daylight model, a sun disk, ground and horizon.

Sky model:
    A. J. Preetham, P. Shirley and B. Smits, "A Practical Analytic Model for Daylight", SIGGRAPH 1999
    (appendix A.2). Luminance ``Y`` and chromaticities ``x``, ``y`` each follow the Perez et al. (1993)
    all-weather distribution

    .. math::

        F(\theta, \gamma) = (1 + A e^{B / \cos\theta}) (1 + C e^{D \gamma} + E \cos^2\gamma),
        \qquad Y(\theta, \gamma) = Y_z \frac{F(\theta, \gamma)}{F(0, \theta_s)},

    with ``theta`` the zenith angle of the view, ``gamma`` its angle to the sun, ``theta_s`` the sun's zenith
    angle, coefficients ``A..E`` linear in the turbidity ``T`` (the paper's matrices, transcribed in
    ``_PEREZ``), the zenith luminance ``Y_z = (4.0453 T - 4.9710) tan(chi) - 0.2155 T + 2.4192`` kcd/m^2
    with ``chi = (4/9 - T/120)(pi - 2 theta_s)`` and the zenith chromaticities cubic in ``theta_s`` and
    quadratic in ``T`` (``_ZENITH_XY``). Chosen over Hosek-Wilkie (2012), whose RGB model needs about
    3,600 fitted coefficients from its reference implementation, because Preetham's 59 published constants
    fit in this file and are checked against the paper's formulas in the tests.

    ``xyY`` becomes CIE XYZ, then linear Rec. 709 / sRGB (D65) with Kornia's matrix
    (:func:`kornia.color.xyz_to_rgb`). Preetham colours near a low sun fall outside the sRGB gamut; they
    are desaturated toward their own luminance until no channel is negative (luminance and hue kept).

Units:
    Absolute photometric units: **1.0 = 1 kcd/m^2** (the luminance ``Y`` of linear sRGB), so irradiances
    ``sum(L cos Omega)`` come out in klux. A clear noon sky gives about 100 klux on the ground and a white
    Lambertian surface reads about 30; the median night pixel is 4 to 6 decades darker than by day. The
    relative levels of the conditions are physical; exposure is left to the consumer (the environment
    sampler normalises it, and the "units of the input image" of docs/conventions.rst fix it per photo).

Sun:
    A uniform disk of angular diameter 0.53 degrees. Its irradiance at normal incidence is the luminous
    solar constant 133.8 klux (Darula, Kittler and Gueymard, Solar Energy 2005) attenuated per wavelength
    by Rayleigh scattering, ``tau_R = 0.008735 lambda^-4.08`` (Leckner 1978, lambda in um), and aerosols,
    ``tau_a = beta lambda^-1.3`` with Preetham's ``beta = 0.04608 T - 0.04586``, over the Kasten-Young
    (1989) relative air mass; the extraterrestrial spectrum is a 5778 K blackbody and colours are
    integrated with the CIE 1931 matching functions (the analytic fit of Wyman, Sloan and Shirley, JCGT
    2013). Ozone and water-vapour absorption are neglected. This gives about 106 klux at 60 degrees of
    elevation and ``T = 2`` (disk radiance 1.5e6 kcd/m^2, 1e5 to 2e5 times the mean sky), 23 to 68 klux
    in haze (``T`` = 6 to 9, 30 to 60 degrees), and a dim red sun at dusk. The disk is far smaller than a
    128 x 256 pixel (1.4 degrees): its energy ``L_sun Omega_sun`` is added to the pixels that contain it,
    split by area (:func:`splat_disk`), so ``sum(L Omega)`` holds it exactly and the energy-conserving
    resampling to the mirror ball (:func:`~kornia_ilum.geometry.latlong_to_mirror_ball`) keeps it in one
    ball pixel.

Low sun:
    Preetham's fit is not meant for a sun at the horizon: at ``theta_s = 90`` degrees it gives 5 to 16 klux
    of diffuse light (``T`` = 5 to 2) where measurements give under 1 klux. For clear, hazy and dusk skies
    with the sun (or moon) below 10 degrees of elevation, the sky is evaluated with the sun clamped to the
    horizon and scaled by ``(e + 1) / 11`` (``e`` in degrees, ``0 <= e < 10``), which brings the diffuse
    illuminance at sunset to 0.5 to 1.2 klux (the IES clear-sky value is about 0.8 klux), and below the
    horizon by a further ``10^(0.35 e)``: a decade per 3 degrees, 4 to 9 lux at the end of civil twilight
    (-6 degrees). Above 10 degrees Preetham's own levels stand; its diffuse illuminance there is up to twice
    the IES clear-sky value.

Conditions (each a parameter set drawn by :meth:`SkySource.sample_params`):
    ``clear``: ``T`` in [1.9, 3.2], sun 10 to 75 degrees high. ``hazy``: ``T`` in [4.5, 9]. ``overcast``:
    the CIE overcast sky (Moon and Spencer 1942) ``L = L_z (1 + 2 cos theta) / 3``, no sun, horizontal
    illuminance ``0.3 + 21 sin(e)`` klux (Krochmann) times 0.4 to 1.4, colour on the CIE daylight locus at
    6000 to 8000 K. ``dusk``: sun between -5 and +5 degrees, ``T`` in [2.2, 4.5]: red sun, warm horizon
    toward it, blue zenith. ``night``: the sky lit by the moon (Preetham's sky scaled by the moon's share
    of the solar constant, as in Jensen et al., "A Physically-Based Night Sky Model", SIGGRAPH 2001;
    0.01 to 0.3 lux), warm urban sky glow (0.2 to 20 mcd/m^2, brighter toward the horizon) and 2 to 8
    street lamps (200 to 2000 cd toward the camera, 8 to 80 m away, 4 to 10 m high; sodium 2000 K or LED
    3000 to 4500 K) that light pools on the ground.

Ground and horizon:
    Below the horizon a Lambertian ground of albedo ``rho`` (grass, asphalt, soil, concrete, sand or snow)
    has radiance ``rho E / pi``, ``E`` the horizontal irradiance of sun and sky (the sky's integrated
    numerically). Over a band of 0.5 to 2 degrees below the horizon it fades into the horizon radiance
    (distant terrain and aerial perspective). Optional occluders (buildings: flat tops; trees: domes),
    up to 20 degrees high, replace the sky near the horizon; they are Lambertian facades facing the camera,
    lit by the sun (when in front of them), half the sky and half the ground's reflection. Occluders that
    would hide the sun or the moon are dropped when sampling.

Convention:
    Camera frame of docs/conventions.rst (+X right, +Y up, +Z toward the camera; a direction is where light
    comes *from*) and lat-long grid; maps are float32 on the CPU. The sun's azimuth is uniform over the full
    circle.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import torch
from kornia.color import xyz_to_rgb
from torch import nn

from kornia_ilum.core.check import check_positive_int, check_tensor
from kornia_ilum.core.errors import TypeCheckError, ValueCheckError
from kornia_ilum.geometry import (
    angles_to_latlong_pixel,
    direction_to_latlong,
    latlong_solid_angles,
    latlong_to_direction,
    latlong_to_mirror_ball,
)
from kornia_ilum_lab.synth.environments.base import Environment
from kornia_ilum_lab.synth.environments.procedural import Draw, latlong_pixels

__all__ = [
    "CONDITIONS",
    "CctToRgb",
    "OutdoorScene",
    "SkyRadiance",
    "SkySource",
    "cct_to_rgb",
    "outdoor_scene",
    "preetham_zenith",
    "render_outdoor",
    "sky_radiance",
    "splat_disk",
    "sun_irradiance",
]

#: The outdoor conditions, in the order :class:`SkySource` lists them by default.
CONDITIONS = ("clear", "hazy", "overcast", "dusk", "night")

#: Preetham et al. 1999, appendix A.2: ``(slope, intercept)`` in ``T`` of the Perez coefficients A..E,
#: rows ``Y``, ``x``, ``y``.
_PEREZ = (
    ((0.1787, -1.4630), (-0.3554, 0.4275), (-0.0227, 5.3251), (0.1206, -2.5771), (-0.0670, 0.3703)),
    ((-0.0193, -0.2592), (-0.0665, 0.0008), (-0.0004, 0.2125), (-0.0641, -0.8989), (-0.0033, 0.0452)),
    ((-0.0167, -0.2608), (-0.0950, 0.0092), (-0.0079, 0.2102), (-0.0441, -1.6537), (-0.0109, 0.0529)),
)
#: Preetham et al. 1999, appendix A.2: zenith chromaticity
#: ``[T^2, T, 1] M [theta_s^3, theta_s^2, theta_s, 1]``, rows ``x``, ``y``.
_ZENITH_XY = (
    ((0.00166, -0.00375, 0.00209, 0.0), (-0.02903, 0.06377, -0.03202, 0.00394),
     (0.11693, -0.21196, 0.06052, 0.25886)),
    ((0.00275, -0.00610, 0.00317, 0.0), (-0.04214, 0.08970, -0.04153, 0.00516),
     (0.15346, -0.26756, 0.06670, 0.26688)),
)  # fmt: skip
#: Luminance weights of linear sRGB (the Y row of the sRGB -> XYZ matrix, IEC 61966-2-1).
_LUMA = (0.2126729, 0.7151522, 0.0721750)
_TURBIDITY_RANGE = (1.7, 10.0)  # Preetham's fit covers T = 2..10; 1.7 is a common lower extension
_SOLAR_KLUX = 133.8  # luminous solar constant (Darula, Kittler and Gueymard 2005)
_SUN_DIAMETER_DEG = 0.53
_SUN_RADIUS = math.radians(_SUN_DIAMETER_DEG / 2)
_MOON_RADIUS = math.radians(0.52 / 2)
_CAMERA_HEIGHT_M = 1.6  # eye height above the ground: places the night lamps' light pools


# ----------------------------------------------------------------------------------------------
# colour


def _gauss(lam: torch.Tensor, mu: float, s1: float, s2: float) -> torch.Tensor:
    return torch.exp(-0.5 * ((lam - mu) / torch.where(lam < mu, s1, s2)) ** 2)


def _make_cmf() -> tuple[torch.Tensor, torch.Tensor]:
    """Wavelengths 360..830 nm (5 nm) and the CIE 1931 2-degree matching functions ``(N, 3)``.

    The multi-lobe piecewise-Gaussian fit of Wyman, Sloan and Shirley, "Simple Analytic Approximations to
    the CIE XYZ Color Matching Functions", JCGT 2(2), 2013 (their equation 2), float64.
    """
    lam = torch.arange(360.0, 831.0, 5.0, dtype=torch.float64)
    x = 1.056 * _gauss(lam, 599.8, 37.9, 31.0) + 0.362 * _gauss(lam, 442.0, 16.0, 26.7)
    x = x - 0.065 * _gauss(lam, 501.1, 20.4, 26.2)
    y = 0.821 * _gauss(lam, 568.8, 46.9, 40.5) + 0.286 * _gauss(lam, 530.9, 16.3, 31.1)
    z = 1.217 * _gauss(lam, 437.0, 11.8, 36.0) + 0.681 * _gauss(lam, 459.0, 26.0, 13.8)
    return lam, torch.stack([x, y, z], -1)


_CMF = _make_cmf()


def _planck(lam_nm: torch.Tensor, kelvin: torch.Tensor) -> torch.Tensor:
    """Planck's spectral radiance up to a constant factor, ``(..., N)`` for temperatures ``(..., 1)``."""
    lam = lam_nm * 1e-9
    return lam.pow(-5) / torch.expm1(1.4388e-2 / (lam * kelvin))


def _xyz_to_rgb(xyz: torch.Tensor) -> torch.Tensor:
    """CIE XYZ ``(..., 3)`` to linear sRGB ``(..., 3)`` with Kornia's D65 matrix."""
    shape = xyz.shape
    rgb = xyz_to_rgb(xyz.reshape(-1, 3).T.reshape(3, -1, 1))
    return rgb.reshape(3, -1).T.reshape(shape)


def _xyY_to_rgb(x: torch.Tensor, y: torch.Tensor, lum: torch.Tensor) -> torch.Tensor:
    """Chromaticity and luminance to linear sRGB ``(..., 3)``, desaturated into the gamut (module doc)."""
    xyz = torch.stack([x / y * lum, lum, (1 - x - y) / y * lum], -1)
    rgb = _xyz_to_rgb(xyz)
    luma = (rgb * rgb.new_tensor(_LUMA)).sum(-1, keepdim=True)
    low = rgb.amin(-1, keepdim=True)
    scale = torch.where(
        low < 0, luma / (luma - low).clamp(min=torch.finfo(rgb.dtype).tiny), torch.ones_like(low)
    )
    return (luma + scale * (rgb - luma)).clamp(min=0.0)


def cct_to_rgb(kelvin: torch.Tensor, locus: str = "planckian") -> torch.Tensor:
    r"""Linear sRGB colour of unit luminance of a correlated colour temperature.

    ``"planckian"``: a blackbody, integrated from Planck's law with the CIE 1931 matching functions (the
    analytic fit of Wyman, Sloan and Shirley, JCGT 2013; chromaticity within 0.002 of the tabulated
    locus). ``"daylight"``: the CIE daylight locus (CIE 15:2004, valid 4000 to 25000 K), so 6504 K is D65,
    the sRGB white ``(1, 1, 1)``. Lamps are Planckian; skies are daylight.

    Args:
        kelvin: colour temperatures in K, 1000 to 40000 (``"planckian"``) or 4000 to 25000 (``"daylight"``).
        locus: ``"planckian"`` or ``"daylight"``.

    Returns:
        linear sRGB with luminance ``0.2127 R + 0.7152 G + 0.0722 B = 1``; out-of-gamut colours (below
        about 1900 K) are desaturated until no channel is negative.

    Shape:
        - Input: :math:`(*)`
        - Output: :math:`(*, 3)`

    Convention:
        Linear Rec. 709 / sRGB primaries, D65 white (docs/conventions.rst, "Images": HDR data is linear).

    Examples:
        >>> cct_to_rgb(torch.tensor(6504.0), "daylight").round(decimals=2)  # D65: the sRGB white
        tensor([1., 1., 1.])
        >>> rgb = cct_to_rgb(torch.tensor([2700.0, 6500.0]))
        >>> bool(rgb[0, 0] > rgb[0, 2]), bool(rgb[1, 0] < 1.1 * rgb[1, 2])  # warm, near white
        (True, True)
    """
    check_tensor(kelvin, "kelvin", None, nonempty=False)
    lo, hi = {"planckian": (1000.0, 40000.0), "daylight": (4000.0, 25000.0)}.get(locus, (None, None))
    if lo is None:
        raise ValueCheckError(f"locus must be 'planckian' or 'daylight', got {locus!r}")
    if kelvin.numel() and not torch.compiler.is_compiling():
        k_lo, k_hi = float(kelvin.detach().min()), float(kelvin.detach().max())
        if k_lo < lo or k_hi > hi:
            raise ValueCheckError(
                f"kelvin must lie in [{lo:g}, {hi:g}] for the {locus} locus, got [{k_lo:g}, {k_hi:g}]"
            )
    work = torch.float32 if kelvin.dtype in (torch.float16, torch.bfloat16) else kelvin.dtype
    t = kelvin.to(work)
    if locus == "daylight":
        x = torch.where(
            t <= 7000.0,
            -4.6070e9 / t**3 + 2.9678e6 / t**2 + 0.09911e3 / t + 0.244063,
            -2.0064e9 / t**3 + 1.9018e6 / t**2 + 0.24748e3 / t + 0.237040,
        )
        y = -3.0 * x**2 + 2.870 * x - 0.275
    else:
        lam, cmf = _CMF
        xyz = _planck(lam.to(device=t.device, dtype=work), t[..., None]) @ cmf.to(device=t.device, dtype=work)
        x, y = xyz[..., 0] / xyz.sum(-1), xyz[..., 1] / xyz.sum(-1)
    return _xyY_to_rgb(x, y, torch.ones_like(x)).to(kelvin.dtype)


class CctToRgb(nn.Module):
    r"""Module twin of :func:`cct_to_rgb`.

    Args:
        locus: ``"planckian"`` or ``"daylight"``.

    Examples:
        >>> CctToRgb("daylight")(torch.tensor([5000.0, 6504.0])).shape
        torch.Size([2, 3])
    """

    def __init__(self, locus: str = "planckian") -> None:
        super().__init__()
        if locus not in ("planckian", "daylight"):
            raise ValueCheckError(f"locus must be 'planckian' or 'daylight', got {locus!r}")
        self.locus = locus

    def forward(self, kelvin: torch.Tensor) -> torch.Tensor:
        return cct_to_rgb(kelvin, self.locus)

    def extra_repr(self) -> str:
        return f"locus={self.locus!r}"


# ----------------------------------------------------------------------------------------------
# Preetham sky


def preetham_zenith(
    turbidity: torch.Tensor, theta_s: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    r"""Preetham's zenith luminance (kcd/m^2) and chromaticity ``x``, ``y`` (appendix A.2 of the paper).

    Args:
        turbidity: ``T`` (broadcastable with ``theta_s``).
        theta_s: the sun's zenith angle in radians, ``[0, pi/2]``.

    Returns:
        ``(Y_z, x_z, y_z)``, each of the broadcast shape.

    Convention:
        Luminance in kcd/m^2, chromaticity in CIE 1931 ``(x, y)``; ``theta_s`` is measured from +Y, the zenith
        of the frame of docs/conventions.rst.

    Examples:
        >>> t, theta_s = torch.tensor(2.0, dtype=torch.float64), torch.tensor(math.pi / 6)
        >>> y_z, x_z, y_zc = preetham_zenith(t, theta_s)
        >>> round(float(y_z), 3)
        5.887
    """
    dtype = torch.promote_types(turbidity.dtype, theta_s.dtype)
    t, theta_s = turbidity.to(dtype), theta_s.to(dtype)
    chi = (4.0 / 9.0 - t / 120.0) * (math.pi - 2.0 * theta_s)
    y_z = (4.0453 * t - 4.9710) * torch.tan(chi) - 0.2155 * t + 2.4192
    t_vec = torch.stack(torch.broadcast_tensors(t * t, t, torch.ones_like(t)), -1)
    th = torch.stack([theta_s**3, theta_s**2, theta_s, torch.ones_like(theta_s)], -1)
    chroma = []
    for m in _ZENITH_XY:
        mat = th.new_tensor(m)
        chroma.append(((t_vec @ mat) * th).sum(-1))
    return y_z, chroma[0], chroma[1]


def _perez(cos_theta: torch.Tensor, gamma: torch.Tensor, coef: torch.Tensor) -> torch.Tensor:
    a, b, c, d, e = coef.unbind(-1)
    return (1 + a * torch.exp(b / cos_theta)) * (1 + c * torch.exp(d * gamma) + e * torch.cos(gamma) ** 2)


def _angle(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Angle between unit vectors, stable near 0 and pi: ``2 atan2(|a - b|, |a + b|)``."""
    return 2 * torch.atan2((a - b).norm(dim=-1), (a + b).norm(dim=-1))


def sky_radiance(
    directions: torch.Tensor, sun_direction: torch.Tensor, turbidity: float | torch.Tensor
) -> torch.Tensor:
    r"""Sky radiance of the Preetham et al. (1999) model in linear sRGB, kcd/m^2.

    ``Y = Y_z F(theta, gamma) / F(0, theta_s)`` and likewise ``x``, ``y`` (module docstring), then
    ``xyY -> XYZ -> linear sRGB`` (:func:`kornia.color.xyz_to_rgb`), desaturated into the gamut at constant
    luminance. The sun disk itself is not included (:func:`sun_irradiance`, :func:`splat_disk`).

    Args:
        directions: view directions (normalised here).
        sun_direction: direction of the sun, broadcastable with ``directions``; a sun below the horizon is
            treated as on it (see the module docstring for twilight).
        turbidity: Preetham's ``T`` in [1.7, 10] (2 very clear, 3 clear, 6 hazy, 10 thin fog); a float or a
            tensor broadcastable with ``directions[..., 0]``.

    Returns:
        linear sRGB radiance, ``>= 0``. Directions below the horizon get the value at the horizon
        (``cos theta`` is clamped to 1e-3), at the same angle from the sun.

    Shape:
        - directions: :math:`(*, 3)`, sun_direction: :math:`(*, 3)` broadcastable
        - Output: :math:`(*, 3)`

    Convention:
        Frame of docs/conventions.rst: +Y is the zenith. Units: 1 = 1 kcd/m^2 (module docstring).
        Half-precision inputs are computed in float32 and cast back.

    Examples:
        >>> sun = torch.tensor([0.0, 0.5, -math.sqrt(0.75)])  # 30 degrees high, ahead
        >>> zenith = sky_radiance(torch.tensor([0.0, 1.0, 0.0]), sun, 2.0)
        >>> round(float((zenith * torch.tensor([0.2126729, 0.7151522, 0.0721750])).sum()), 3)  # Y_z
        3.487
    """
    check_tensor(directions, "directions", ["*", "3"])
    check_tensor(sun_direction, "sun_direction", ["*", "3"])
    if isinstance(turbidity, torch.Tensor):
        check_tensor(turbidity, "turbidity")
        t_lo, t_hi = _TURBIDITY_RANGE
        if not torch.compiler.is_compiling():
            t_lo, t_hi = float(turbidity.detach().min()), float(turbidity.detach().max())
    else:
        t_lo = t_hi = float(turbidity)
    if t_lo < _TURBIDITY_RANGE[0] or t_hi > _TURBIDITY_RANGE[1]:
        raise ValueCheckError(
            f"turbidity must lie in [{_TURBIDITY_RANGE[0]:g}, {_TURBIDITY_RANGE[1]:g}] (Preetham's fit), "
            f"got [{t_lo:g}, {t_hi:g}]"
        )
    out_dtype = directions.dtype
    work = torch.float32 if out_dtype in (torch.float16, torch.bfloat16) else out_dtype
    d = directions.to(work)
    d = d / d.norm(dim=-1, keepdim=True).clamp(min=1e-12)
    s = sun_direction.to(device=d.device, dtype=work)
    s = s / s.norm(dim=-1, keepdim=True).clamp(min=1e-12)
    # a sun below the horizon is put on it (theta_s <= pi / 2)
    horiz = s[..., [0, 2]].norm(dim=-1, keepdim=True)
    s = torch.cat([s[..., :1], s[..., 1:2].clamp(min=0.0), s[..., 2:]], -1)
    s = s / s.norm(dim=-1, keepdim=True).clamp(min=1e-12)
    theta_s = torch.atan2(horiz[..., 0], s[..., 1])
    t = torch.as_tensor(turbidity, device=d.device, dtype=work)
    table = torch.tensor(_PEREZ, device=d.device, dtype=work)  # (3, 5, 2)
    coef = t[..., None, None] * table[..., 0] + table[..., 1]  # (*, 3, 5)
    cos_theta = d[..., 1].clamp(min=1e-3)
    gamma = _angle(d, s)
    zen = torch.stack(torch.broadcast_tensors(*preetham_zenith(t, theta_s)), -1)  # (*, 3): Y_z, x_z, y_z
    ratio = _perez(cos_theta[..., None], gamma[..., None], coef) / _perez(
        torch.ones_like(theta_s)[..., None], theta_s[..., None], coef
    )
    lum, x, y = (zen * ratio).unbind(-1)
    return _xyY_to_rgb(x, y, lum).to(out_dtype)


class SkyRadiance(nn.Module):
    r"""Module twin of :func:`sky_radiance`: holds the turbidity.

    Args:
        turbidity: Preetham's ``T`` in [1.7, 10].

    Examples:
        >>> sky = SkyRadiance(3.0)
        >>> sky(torch.randn(4, 3), torch.tensor([0.0, 0.5, -0.8])).shape
        torch.Size([4, 3])
    """

    def __init__(self, turbidity: float = 3.0) -> None:
        super().__init__()
        if not _TURBIDITY_RANGE[0] <= float(turbidity) <= _TURBIDITY_RANGE[1]:
            raise ValueCheckError(f"turbidity must lie in [1.7, 10] (Preetham's fit), got {turbidity:g}")
        self.turbidity = float(turbidity)

    def forward(self, directions: torch.Tensor, sun_direction: torch.Tensor) -> torch.Tensor:
        return sky_radiance(directions, sun_direction, self.turbidity)

    def extra_repr(self) -> str:
        return f"turbidity={self.turbidity:g}"


# ----------------------------------------------------------------------------------------------
# sun


def _air_mass(elevation_deg: float) -> float:
    """Kasten and Young (1989) relative optical air mass; ``inf`` below -6 degrees."""
    zenith = 90.0 - elevation_deg
    if zenith >= 96.0:
        return math.inf
    return 1.0 / (math.cos(math.radians(zenith)) + 0.50572 * (96.07995 - zenith) ** -1.6364)


@lru_cache(maxsize=1024)
def _transmitted_xyz(elevation_deg: float, turbidity: float) -> tuple[float, float, float]:
    """XYZ of the attenuated 5778 K solar spectrum, normalised to extraterrestrial ``Y = 1``."""
    lam, cmf = _CMF
    sun = _planck(lam, torch.tensor(5778.0, dtype=torch.float64))
    m = _air_mass(elevation_deg)
    if not math.isfinite(m):
        return (0.0, 0.0, 0.0)
    um = lam / 1000.0
    beta = 0.04608 * turbidity - 0.04586
    tau = 0.008735 * um**-4.08 + beta * um**-1.3
    xyz = (sun * torch.exp(-m * tau)) @ cmf / (sun @ cmf[:, 1])
    return tuple(float(v) for v in xyz)


def sun_irradiance(
    elevation_deg: float, turbidity: float, extraterrestrial_klux: float = _SOLAR_KLUX
) -> torch.Tensor:
    r"""Direct solar irradiance at normal incidence in linear sRGB, klux (module docstring "Sun").

    Args:
        elevation_deg: the sun's elevation above the horizon in degrees (0 below -0.27: set).
        turbidity: Preetham's ``T`` (sets the aerosol optical depth).
        extraterrestrial_klux: the source's illuminance above the atmosphere (133.8 for the sun; the moon
            uses its own, 1e-6 times less).

    Returns:
        ``(3,)`` float64 linear sRGB irradiance whose luminance is the illuminance in klux.

    Examples:
        >>> e = sun_irradiance(60.0, 2.0)
        >>> round(float((e * torch.tensor([0.2126729, 0.7151522, 0.0721750], dtype=torch.float64)).sum()))
        106
    """
    if elevation_deg < -math.degrees(_SUN_RADIUS):
        return torch.zeros(3, dtype=torch.float64)
    xyz = torch.tensor(_transmitted_xyz(round(elevation_deg, 6), round(turbidity, 6)), dtype=torch.float64)
    return _xyz_to_rgb(xyz * extraterrestrial_klux).clamp(min=0.0)


# ----------------------------------------------------------------------------------------------
# grids and splatting


@lru_cache(maxsize=16)
def _disk_pattern(k: int) -> torch.Tensor:
    """Centres ``(M, 2)`` of the cells of a ``k x k`` grid over ``[-1, 1]^2`` that lie in the unit disk."""
    c = (torch.arange(k, dtype=torch.float64) + 0.5) / k * 2 - 1
    v, u = torch.meshgrid(c, c, indexing="ij")
    uv = torch.stack([u.flatten(), v.flatten()], -1)
    return uv[uv.square().sum(-1) <= 1.0]


def _tangent_basis(d: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    ref = d.new_tensor([0.0, 1.0, 0.0]) if abs(float(d[1])) < 0.9 else d.new_tensor([1.0, 0.0, 0.0])
    e1 = torch.linalg.cross(ref, d)
    e1 = e1 / e1.norm()
    return e1, torch.linalg.cross(d, e1)


def splat_disk(
    latlong: torch.Tensor, direction: Sequence[float] | torch.Tensor, radius: float, irradiance: torch.Tensor
) -> torch.Tensor:
    r"""Add a uniform disk light source to a lat-long map, conserving its energy exactly.

    The disk (angular radius ``radius``) is cut into equal sub-cells, at least 8 x 8 and fine enough that a
    pixel holds several across (``k >= 8 radius / pixel``, at most 64); each carries ``irradiance / M`` into
    the pixel that owns its centre, divided by that pixel's exact solid angle. Hence
    ``sum(L Omega)`` grows by ``irradiance`` (to float rounding) and a disk that straddles pixels is split
    by area.

    Args:
        latlong: ``(3, H, 2H)`` map, updated in place and returned.
        direction: the disk's centre direction (normalised here).
        radius: angular radius in radians.
        irradiance: ``(3,)`` irradiance at normal incidence, ``L_disk * Omega_disk`` (klux in this module).

    Returns:
        ``latlong``.

    Shape:
        - latlong: :math:`(3, H, 2H)`
        - irradiance: :math:`(3,)`
        - Output: :math:`(3, H, 2H)` (``latlong`` itself)

    Convention:
        Lat-long grid and frame of docs/conventions.rst; ``direction`` is where the light arrives from.

    Examples:
        >>> env = torch.zeros(3, 8, 16)
        >>> _ = splat_disk(env, [0.0, 0.3, -1.0], math.radians(0.265), torch.tensor([1.0, 2.0, 3.0]))
        >>> (env * latlong_solid_angles(8)).sum((-2, -1)).round(decimals=4)
        tensor([1., 2., 3.])
    """
    h = latlong.shape[-2]
    d = torch.as_tensor(direction, dtype=torch.float64).flatten()
    d = d / d.norm()
    k = int(min(64, max(8, math.ceil(8 * radius / (math.pi / h)))))
    uv = _disk_pattern(k)
    e1, e2 = _tangent_basis(d)
    pts = d + math.tan(radius) * (uv[:, :1] * e1 + uv[:, 1:] * e2)
    phi, el = direction_to_latlong(pts)
    px = angles_to_latlong_pixel(phi, el, h)
    col = torch.floor(px[:, 0] + 0.5).long().remainder(2 * h)
    row = torch.floor(px[:, 1] + 0.5).long().clamp(0, h - 1)
    counts = torch.zeros(h * 2 * h, dtype=torch.float64).index_add_(
        0, row * (2 * h) + col, torch.full((uv.shape[0],), 1.0 / uv.shape[0], dtype=torch.float64)
    )
    om = latlong_solid_angles(h, dtype=torch.float64).reshape(-1)
    hit = counts.nonzero().squeeze(1)
    add = counts[hit, None] / om[hit, None] * torch.as_tensor(irradiance, dtype=torch.float64)[None]
    flat = latlong.view(3, -1)
    flat[:, hit] += add.T.to(latlong.dtype)
    return latlong


# ----------------------------------------------------------------------------------------------
# scenes


def _twilight(elevation_deg: float) -> float:
    """Scale of the Preetham sky for a low or set source (module docstring "Low sun")."""
    if elevation_deg >= 10.0:
        return 1.0
    if elevation_deg >= 0.0:
        return (elevation_deg + 1.0) / 11.0
    return 10.0 ** (0.35 * elevation_deg) / 11.0


def _dir(azimuth_deg: float, elevation_deg: float) -> torch.Tensor:
    return latlong_to_direction(
        torch.tensor(math.radians(azimuth_deg), dtype=torch.float64),
        torch.tensor(math.radians(elevation_deg), dtype=torch.float64),
    )


@lru_cache(maxsize=1)
def _hemisphere_grid() -> tuple[torch.Tensor, torch.Tensor]:
    """A 32 x 64 lat-long grid (float32 directions and solid angles) for irradiance integrals."""
    return latlong_pixels(32)


@dataclass
class OutdoorScene:
    """A prepared outdoor scene (from :func:`outdoor_scene`): radiance of every direction but the disks.

    Attributes:
        sky: ``directions (N, 3) -> (N, 3)`` radiance of the sky alone (no sun, ground or occluders).
        ground_albedo: ``(3,)`` Lambertian albedo of the ground.
        disks: light sources smaller than pixels, ``(direction (3,), angular radius, irradiance (3,))``:
            the sun or the moon, and street lamps.
        sun_direction: ``(3,)`` direction of the sun (or moon) whose light is direct.
        sun_normal_irradiance: ``(3,)`` its irradiance at normal incidence (0 when hidden), klux.
        lamps: street lamps, ``(position (3,) relative to the eye, intensity (3,) kcd)``, lighting the ground.
        occluders: horizon silhouettes (dicts of :meth:`SkySource.sample_params`).
        horizon_blur_deg: width of the ground-to-horizon fade.

    Examples:
        >>> scene = OutdoorScene(sky=lambda d: torch.ones(d.shape[0], 3), ground_albedo=torch.zeros(3))
        >>> round(scene.sky_irradiance[0].item(), 1)  # a uniform sky of radiance 1: pi on a horizontal plane
        3.1
        >>> scene.radiance(torch.tensor([[0.0, 1.0, 0.0], [0.0, -1.0, 0.0]]))[:, 0].tolist()  # sky, black ground
        [1.0, 0.0]
    """

    sky: Callable[[torch.Tensor], torch.Tensor]
    ground_albedo: torch.Tensor
    disks: list[tuple[torch.Tensor, float, torch.Tensor]] = field(default_factory=list)
    sun_direction: torch.Tensor = field(default_factory=lambda: torch.tensor([0.0, 1.0, 0.0]))
    sun_normal_irradiance: torch.Tensor = field(default_factory=lambda: torch.zeros(3))
    lamps: list[tuple[torch.Tensor, torch.Tensor]] = field(default_factory=list)
    occluders: list[dict[str, Any]] = field(default_factory=list)
    horizon_blur_deg: float = 1.0

    def __post_init__(self) -> None:
        d, om = _hemisphere_grid()
        sky = self.sky(d)
        up = d[:, 1].clamp(min=0.0)
        #: horizontal irradiance of the sky (klux, linear sRGB)
        self.sky_irradiance = (sky * (om * up)[:, None]).sum(0)
        sun_h = self.sun_normal_irradiance.float() * max(float(self.sun_direction[1]), 0.0)
        #: horizontal irradiance of sun and sky on the ground
        self.ground_irradiance = self.sky_irradiance + sun_h

    def irradiance(self, normal: torch.Tensor, include_sun: bool = True) -> torch.Tensor:
        """Irradiance ``(3,)`` on a plane facing ``normal`` from sky, ground and (optionally) the sun, klux.

        Street lamps and the moon's disk count only through the ground they light.
        """
        d, om = _hemisphere_grid()
        n = normal.float() / normal.float().norm()
        out = (self.radiance(d) * (om * (d @ n).clamp(min=0.0))[:, None]).sum(0)
        if include_sun:
            out = out + self.sun_normal_irradiance.float() * max(float(self.sun_direction.float() @ n), 0.0)
        return out

    def radiance(self, directions: torch.Tensor) -> torch.Tensor:
        """Radiance ``(N, 3)`` of sky, occluders and ground along unit ``directions (N, 3)`` (no disks)."""
        d = directions
        sky = self.sky(d)
        el = torch.rad2deg(torch.asin(d[:, 1].clamp(-1.0, 1.0)))
        phi = torch.rad2deg(torch.atan2(d[:, 0], -d[:, 2]))
        above = sky
        if self.occluders:
            e_ground_up = self.ground_irradiance * self.ground_albedo / 2  # ground's light on a facade
            el0 = el.clamp(min=0.0)
            for occ in self.occluders:
                dphi = torch.remainder(phi - occ["azimuth_deg"] + 180.0, 360.0) - 180.0
                half = occ["width_deg"] / 2
                rel = (dphi / half).clamp(-1.0, 1.0)
                top = occ["height_deg"] * (
                    torch.sqrt(1 - rel**2) if occ["kind"] == "tree" else torch.ones_like(rel)
                )
                mask = (dphi.abs() < half) & (el0 < top)
                if not bool(mask.any()):
                    continue
                n = -_dir(occ["azimuth_deg"], 0.0).float()  # facing the camera
                sun = self.sun_normal_irradiance.float() * max(float(self.sun_direction.float() @ n), 0.0)
                sun = sun * (0.5 if occ["kind"] == "tree" else 1.0)  # foliage shades itself
                e = sun + self.sky_irradiance / 2 + e_ground_up
                lum = torch.tensor(occ["albedo"]) * e / math.pi
                above = torch.where(mask[:, None], lum, above)
        ground = self.ground_albedo * self.ground_irradiance / math.pi
        ground = ground.expand(d.shape[0], 3)
        if self.lamps:
            down = (-d[:, 1]).clamp(min=1e-4)
            p = d * (_CAMERA_HEIGHT_M / down)[:, None]  # ground points, relative to the eye
            pool = torch.zeros_like(ground)
            for pos, intensity in self.lamps:
                r = pos.float()[None] - p
                dist2 = r.square().sum(-1).clamp(min=0.25)
                cos_g = r[:, 1] / dist2.sqrt()
                pool = pool + (cos_g / dist2)[:, None] * intensity.float()[None]
            ground = ground + self.ground_albedo * pool / math.pi
        w = self.horizon_blur_deg
        t = ((el + w) / w).clamp(0.0, 1.0)
        t = t * t * (3 - 2 * t)  # smoothstep: ground at -w, horizon at 0
        return torch.where((el >= 0)[:, None], above, ground + t[:, None] * (above - ground))


def outdoor_scene(params: dict[str, Any]) -> OutdoorScene:
    """Build the :class:`OutdoorScene` that a parameter set of :meth:`SkySource.sample_params` describes.

    Args:
        params: a parameter set of :meth:`SkySource.sample_params` (any condition).

    Returns:
        the scene: the radiance of sky, ground and occluders, and the disks (sun or moon, street lamps) to
        splat, in klux and kcd/m^2.

    Convention:
        Camera frame of docs/conventions.rst ("Frames"), linear sRGB; directions are where light arrives from.

    Examples:
        >>> params = SkySource(("clear",)).sample_params(torch.Generator().manual_seed(0))
        >>> scene = outdoor_scene(params)
        >>> scene.radiance(torch.tensor([[0.0, 1.0, 0.0]])).shape, bool(scene.sun_direction[1] > 0)
        (torch.Size([1, 3]), True)
    """
    cond = params["condition"]
    albedo = torch.tensor(params["ground"]["albedo"], dtype=torch.float32)
    common = {"occluders": params["occluders"], "horizon_blur_deg": params["horizon_blur_deg"]}
    if cond == "overcast":
        lz = 9.0 * params["illuminance_klux"] / (7.0 * math.pi)  # E_h = 7 pi L_z / 9
        color = cct_to_rgb(torch.tensor(params["cct_k"], dtype=torch.float32), "daylight")

        def overcast(d: torch.Tensor) -> torch.Tensor:
            return (lz * (1 + 2 * d[:, 1:2].clamp(min=0.0)) / 3) * color

        return OutdoorScene(sky=overcast, ground_albedo=albedo, **common)
    turb = params["turbidity"]
    if cond == "night":
        moon = params["moon"]
        glow_color = cct_to_rgb(torch.tensor(params["skyglow_cct_k"], dtype=torch.float32))
        glow = params["skyglow_kcd_m2"]
        disks, lamps = [], []
        moon_dir, moon_e = torch.tensor([0.0, 1.0, 0.0]), torch.zeros(3)
        if moon is not None:
            moon_dir = _dir(moon["azimuth_deg"], moon["elevation_deg"]).float()
            extra = moon["illuminance_lux"] * 1e-3  # klux above the atmosphere (the stated value)
            moon_e = sun_irradiance(moon["elevation_deg"], turb, extra).float()
            disks.append((moon_dir, _MOON_RADIUS, moon_e))
            moon_scale = extra / _SOLAR_KLUX * _twilight(moon["elevation_deg"])
        for lamp in params["lamps"]:
            rel = _dir(lamp["azimuth_deg"], 0.0) * lamp["distance_m"]
            rel[1] = lamp["height_m"] - _CAMERA_HEIGHT_M
            color = cct_to_rgb(torch.tensor(lamp["cct_k"], dtype=torch.float64))
            intensity = color * lamp["intensity_kcd"]
            dist = float(rel.norm())
            disks.append((rel / dist, math.asin(min(0.5, lamp["radius_m"] / dist)), intensity / dist**2))
            lamps.append((rel, intensity))

        def night(d: torch.Tensor) -> torch.Tensor:
            el = d[:, 1:2].clamp(min=0.0)
            out = glow * (0.25 + 0.75 * torch.exp(-torch.asin(el) / math.radians(8.0))) * glow_color
            if moon is not None:
                out = out + moon_scale * sky_radiance(d, moon_dir, turb)
            return out

        return OutdoorScene(
            sky=night,
            ground_albedo=albedo,
            disks=disks,
            sun_direction=moon_dir,
            sun_normal_irradiance=moon_e,
            lamps=lamps,
            **common,
        )
    el_s = params["sun_elevation_deg"]
    sun_dir = _dir(params["sun_azimuth_deg"], el_s).float()
    scale = _twilight(el_s)
    sun_e = sun_irradiance(el_s, turb).float()

    def sky(d: torch.Tensor) -> torch.Tensor:
        return scale * sky_radiance(d, sun_dir, turb)

    disks = [(sun_dir, _SUN_RADIUS, sun_e)] if float(sun_e.sum()) > 0 else []
    return OutdoorScene(
        sky=sky,
        ground_albedo=albedo,
        disks=disks,
        sun_direction=sun_dir,
        sun_normal_irradiance=sun_e,
        **common,
    )


def render_outdoor(params: dict[str, Any], height: int = 128) -> torch.Tensor:
    r"""Render the lat-long map ``(3, H, 2H)`` (float32, kcd/m^2) of an outdoor parameter set.

    Args:
        params: a parameter set of :meth:`SkySource.sample_params` (the ``params`` of an outdoor
            :class:`~kornia_ilum_lab.synth.environments.Environment`).
        height: the map's height ``H``.

    Returns:
        the lat-long map of docs/conventions.rst: radiance at the pixel centres, plus the disks (sun or moon,
        street lamps) splatted energy-conservingly (:func:`splat_disk`).

    Examples:
        >>> params = SkySource(("overcast",)).sample_params(torch.Generator().manual_seed(0))
        >>> render_outdoor(params, 16).shape
        torch.Size([3, 16, 32])
    """
    check_positive_int(height, "height")
    scene = outdoor_scene(params)
    d, _ = latlong_pixels(height)
    env = scene.radiance(d).T.reshape(3, height, 2 * height).contiguous()
    for direction, radius, irradiance in scene.disks:
        splat_disk(env, direction, radius, irradiance)
    return env


# ----------------------------------------------------------------------------------------------
# sampling

#: ground types: linear RGB albedo at scale 1, and the range of the random scale
_GROUNDS = {
    "grass": ((0.075, 0.12, 0.04), (0.7, 1.5)),
    "asphalt": ((0.085, 0.085, 0.085), (0.6, 1.4)),
    "soil": ((0.17, 0.125, 0.085), (0.7, 1.3)),
    "concrete": ((0.30, 0.29, 0.27), (0.7, 1.2)),
    "sand": ((0.45, 0.38, 0.28), (0.7, 1.1)),
    "snow": ((0.86, 0.89, 0.93), (0.75, 1.0)),
}
_GROUND_WEIGHTS = {"grass": 3.0, "asphalt": 3.0, "soil": 1.5, "concrete": 2.0, "sand": 1.0, "snow": 0.7}


def _sample_ground(draw: Draw) -> dict[str, Any]:
    kind = draw.choice(list(_GROUNDS), list(_GROUND_WEIGHTS.values()))
    base, (lo, hi) = _GROUNDS[kind]
    scale = draw.uniform(lo, hi)
    tint = [draw.uniform(0.92, 1.08) for _ in range(3)]
    return {"type": kind, "albedo": [min(0.95, b * scale * t) for b, t in zip(base, tint, strict=True)]}


def _sample_occluders(draw: Draw) -> list[dict[str, Any]]:
    if draw.bernoulli(0.35):
        return []
    out = []
    for _ in range(draw.integer(1, 6)):
        kind = draw.choice(["building", "tree"])
        if kind == "building":
            albedo = [draw.uniform(0.1, 0.35)] * 3
            albedo = [a * draw.uniform(0.9, 1.1) for a in albedo]
            width, height = draw.uniform(4.0, 40.0), draw.uniform(2.0, 20.0)
        else:
            albedo = [draw.uniform(0.03, 0.06), draw.uniform(0.06, 0.11), draw.uniform(0.02, 0.05)]
            width, height = draw.uniform(5.0, 30.0), draw.uniform(2.0, 12.0)
        out.append(
            {
                "kind": kind,
                "azimuth_deg": draw.uniform(-180.0, 180.0),
                "width_deg": width,
                "height_deg": height,
                "albedo": albedo,
            }
        )
    return out


def _hides(occ: dict[str, Any], azimuth_deg: float, elevation_deg: float) -> bool:
    """Whether a horizon occluder covers (within a degree) the direction of the sun or moon."""
    dphi = abs((azimuth_deg - occ["azimuth_deg"] + 180.0) % 360.0 - 180.0)
    return dphi < occ["width_deg"] / 2 + 1.0 and elevation_deg < occ["height_deg"] + 1.0


class SkySource:
    r"""Procedural outdoor environments: Preetham sky, sun, ground, horizon; five conditions.

    The model, its units and its sources are in the module docstring
    (:mod:`kornia_ilum_lab.synth.environments.sky`).

    Args:
        conditions: the conditions to draw from, a subset of ``("clear", "hazy", "overcast", "dusk",
            "night")``.
        height: lat-long height ``H`` of the rendered maps (width ``2H``).
        weights: relative probability of each condition (default: equal).

    Convention:
        ``sample(generator)`` depends only on the generator's state: same state, identical tensors. Maps are
        in the camera frame of docs/conventions.rst, float32 on the CPU, 1 = 1 kcd/m^2.

    Examples:
        >>> source = SkySource(height=32)
        >>> env = source.sample(torch.Generator().manual_seed(0))
        >>> env.label, env.latlong.shape, env.mirror_ball.shape
        ('outdoor', torch.Size([3, 32, 64]), torch.Size([3, 32, 32]))
        >>> env.source in {f"sky:{c}" for c in CONDITIONS}
        True
    """

    label = "outdoor"

    def __init__(
        self,
        conditions: Sequence[str] = CONDITIONS,
        height: int = 128,
        weights: Sequence[float] | None = None,
    ) -> None:
        if isinstance(conditions, str):
            conditions = (conditions,)
        conditions = tuple(conditions)
        if not conditions:
            raise ValueCheckError(f"conditions must name at least one of {CONDITIONS}")
        unknown = [c for c in conditions if c not in CONDITIONS]
        if unknown:
            raise ValueCheckError(f"unknown conditions {unknown}; valid ones are {CONDITIONS}")
        check_positive_int(height, "height")
        if weights is not None:
            weights = tuple(float(w) for w in weights)
            if len(weights) != len(conditions):
                raise ValueCheckError(
                    f"weights must have one entry per condition ({len(conditions)}), got {len(weights)}"
                )
            if any(not math.isfinite(w) or w < 0 for w in weights) or sum(weights) <= 0:
                raise ValueCheckError(f"weights must be finite, non-negative and not all zero, got {weights}")
        self.conditions, self.height, self.weights = conditions, height, weights

    def __repr__(self) -> str:
        return f"SkySource(conditions={self.conditions}, height={self.height}, weights={self.weights})"

    def sample_params(self, generator: torch.Generator, condition: str | None = None) -> dict[str, Any]:
        """Draw a JSON-serialisable parameter set (condition, sun, turbidity, ground, occluders, ...).

        Args:
            generator: the only source of randomness.
            condition: force a condition (default: drawn with ``weights``).
        """
        if not isinstance(generator, torch.Generator):
            raise TypeCheckError(f"generator must be a torch.Generator, got {type(generator).__name__}")
        draw = Draw(generator)
        cond = condition if condition is not None else draw.choice(self.conditions, self.weights)
        if cond not in CONDITIONS:
            raise ValueCheckError(f"unknown condition {cond!r}; valid ones are {CONDITIONS}")
        p: dict[str, Any] = {"condition": cond, "sun_azimuth_deg": draw.uniform(-180.0, 180.0)}
        if cond == "clear":
            p.update(sun_elevation_deg=draw.uniform(10.0, 75.0), turbidity=draw.uniform(1.9, 3.2))
        elif cond == "hazy":
            p.update(sun_elevation_deg=draw.uniform(10.0, 75.0), turbidity=draw.uniform(4.5, 9.0))
        elif cond == "dusk":
            p.update(sun_elevation_deg=draw.uniform(-5.0, 5.0), turbidity=draw.uniform(2.2, 4.5))
        elif cond == "overcast":
            el = draw.uniform(8.0, 70.0)
            p.update(
                sun_elevation_deg=el,
                turbidity=None,
                cct_k=draw.uniform(6000.0, 8000.0),
                illuminance_klux=(0.3 + 21.0 * math.sin(math.radians(el))) * draw.uniform(0.4, 1.4),
            )
        else:  # night
            moon = None
            if draw.bernoulli(0.6):
                moon = {
                    "azimuth_deg": draw.uniform(-180.0, 180.0),
                    "elevation_deg": draw.uniform(10.0, 70.0),
                    "illuminance_lux": draw.log_uniform(0.01, 0.3),
                }
            lamps = []
            for _ in range(draw.integer(2, 8)):
                sodium = draw.bernoulli(0.5)
                lamps.append(
                    {
                        "azimuth_deg": draw.uniform(-180.0, 180.0),
                        "distance_m": draw.log_uniform(8.0, 80.0),
                        "height_m": draw.uniform(4.0, 10.0),
                        "radius_m": draw.uniform(0.1, 0.3),
                        "intensity_kcd": draw.log_uniform(0.2, 2.0),
                        "cct_k": draw.uniform(1950.0, 2200.0) if sodium else draw.uniform(3000.0, 4500.0),
                    }
                )
            p.update(
                sun_elevation_deg=-20.0,
                turbidity=draw.uniform(2.0, 4.0),
                moon=moon,
                lamps=lamps,
                skyglow_kcd_m2=draw.log_uniform(2e-7, 2e-5),
                skyglow_cct_k=draw.uniform(2200.0, 4000.0),
            )
        p["ground"] = _sample_ground(draw)
        occluders = _sample_occluders(draw)
        lights = [(p["sun_azimuth_deg"], p["sun_elevation_deg"])] if cond in ("clear", "hazy", "dusk") else []
        if p.get("moon"):
            lights.append((p["moon"]["azimuth_deg"], p["moon"]["elevation_deg"]))
        for light in lights:  # no occluder hides the sun or the moon
            occluders = [o for o in occluders if not _hides(o, *light)]
        p["occluders"] = occluders
        p["horizon_blur_deg"] = draw.uniform(0.5, 2.0)
        return p

    def sample(self, generator: torch.Generator) -> Environment:
        """Draw one outdoor environment; it depends only on ``generator``'s state."""
        params = self.sample_params(generator)
        latlong = render_outdoor(params, self.height)
        ball = latlong_to_mirror_ball(latlong[None], 32)[0]
        return Environment(
            latlong=latlong,
            mirror_ball=ball,
            label="outdoor",
            source=f"sky:{params['condition']}",
            params=params,
        )
