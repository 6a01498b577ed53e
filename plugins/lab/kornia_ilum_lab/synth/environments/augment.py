r"""Augmentation of lighting environments: rotation, horizontal flip, exposure and white balance.

A handful of real maps become many lighting conditions: any yaw, a pitch within +-30 degrees (the
camera looking up or down), the mirror image (:func:`kornia_ilum.geometry.flip_lighting_horizontal`), an
exposure of ``2^stops``, and a white-balance shift to another colour temperature with a green-magenta tint.
The last one makes strongly hued lighting appear, the failure case of LeGendre et al. 2020 ("Learning
Illumination from Diverse Portraits", Sec. 7: unnatural colour balance).

Rotation:
    :func:`kornia_ilum.geometry.rotate_lighting` (``layout="latlong"``) is exact but builds its tables per
    call (the area method with its source sub-cells rotated by ``R``), too slow for a sampler
    (docs/environments.rst, "Measured"). So the lat-long map is rotated by :func:`rotate_latlong`, which
    splits it in two:

    - the *smooth part*, the map with every pixel's luminance capped at a threshold ``tau``, is resampled
      by bilinear lookup (:func:`~kornia_ilum_lab.synth.background.sample_latlong` at ``R^T d``), then scaled
      per channel so that its ``sum(L * Omega)`` is unchanged;
    - the *peaks*, what the cap removed (suns, lamps, windows: at most 1 % of the sphere, see below), are
      splatted forward: each pixel is cut into 2 x 2 sub-cells carrying a quarter of its energy
      ``L Omega``, each moved to ``R d`` and shared bilinearly among the four pixels around it there.

    ``tau = max(16 x median, 99th percentile)`` of the luminance, both weighted by solid angle. So
    ``sum(L * Omega)`` per channel is conserved to float precision, a constant map stays exactly constant,
    nothing becomes negative, and a sun's energy lands within a pixel of ``R d``: it is neither missed nor
    multiplied as point sampling would (the energy centroid of a one-pixel sun lands within 0.01 degrees of
    ``R d``). It needs no tables, only one lookup per pixel and one splat per peak sub-cell, so it costs a
    small fraction of :func:`~kornia_ilum.geometry.rotate_lighting` (docs/environments.rst, "Measured"); the
    32 x 32 mirror balls of the two differ by 0.2 to 5 % (relative L1, three shared maps rotated by yaw 37,
    pitch 21 degrees; the differences sit around the sun, which both spread over neighbouring pixels in
    their own way).

    The mirror ball is then recomputed from the augmented lat-long map
    (:func:`~kornia_ilum.geometry.latlong_to_mirror_ball`, ``mode="area"``, energy-conserving), so the two
    stay consistent: a light that came from direction ``d`` comes from ``M d`` in both, with
    ``M = F R``, ``R = R_x(pitch) R_y(yaw)`` and ``F = diag(-1, 1, 1)`` when flipped (identity otherwise).
    ``M`` is recorded in ``params["augment"]["direction_map"]``.

White balance:
    :func:`white_balance_gains`: per-channel gains ``w(T) / w(6500 K)``, with ``w(T)`` the linear sRGB
    colour of the Planckian (blackbody) white at ``T``
    (:func:`kornia_ilum_lab.synth.environments.sky.cct_to_rgb`), times a green-magenta tint ``2^(-tint)`` on green
    (positive is magenta), normalised to keep the luminance (Rec. 709 ``Y``): exposure is set by the
    exposure shift alone. A von Kries-style scaling in linear sRGB: the lighting looks as if its
    illuminant had temperature ``T`` instead of 6500 K. ``T`` is drawn uniformly in mired (``1e6 / T``,
    the perceptually even scale of colour temperature) within ``kelvin``. The default, 4000 to 40000 K
    (25 to 250 mired), is set so that warm and cool shifts balance on the real maps: their median colour
    temperature (McCamy, :mod:`kornia_ilum_lab.synth.stats`) is 5850 K as captured and 5900 K after the
    shift (10th / 90th percentiles 3970 / 12900 K; measured over 4000 draws on the 10 shared maps). A range
    centred on 6500 K in mired would turn the set warmer by about 20 mired, because the colour temperature
    of a shifted colour is not the mired sum. The gains are ``(1.35, 0.94, 0.52)`` at 4000 K and
    ``(0.68, 1.00, 1.98)`` at 40000 K (blue / red 0.38 and 2.9), and the tint of +-0.25 stops adds
    green or magenta casts: strongly hued light.

Convention:
    Frame and lat-long grid of docs/conventions.rst; ``R`` acts on directions light arrives from, as in
    :func:`~kornia_ilum.geometry.rotate_lighting` (yaw +90 deg moves a light from straight ahead, -Z, to the
    left, -X; pitch +90 deg moves it up, +Y).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import torch
from torch import nn

from kornia_ilum.core.check import check_tensor
from kornia_ilum.core.compiler import compiler_disable
from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.geometry import (
    angles_to_latlong_pixel,
    direction_to_latlong,
    flip_lighting_horizontal,
    latlong_directions,
    latlong_solid_angles,
    latlong_to_direction,
    latlong_to_mirror_ball,
)
from kornia_ilum_lab.synth.background import LUMINANCE, axis_rotation, sample_latlong
from kornia_ilum_lab.synth.environments.base import Environment
from kornia_ilum_lab.synth.environments.sky import cct_to_rgb

__all__ = [
    "REFERENCE_KELVIN",
    "Augment",
    "RotateLatLong",
    "lighting_rotation",
    "rotate_latlong",
    "weighted_quantile",
    "white_balance_gains",
]

#: The colour temperature that white-balance gains are relative to (close to D65, 6504 K).
REFERENCE_KELVIN = 6500.0

_KELVIN_RANGE = (1000.0, 40000.0)  # the range of cct_to_rgb's Planckian locus


def white_balance_gains(kelvin: float, tint: float = 0.0) -> torch.Tensor:
    r"""Per-channel gains ``(3,)`` (float64) that move the white point from 6500 K to ``kelvin``.

    ``g = w(kelvin) / w(6500 K)``, ``w`` the Planckian white
    (:func:`~kornia_ilum_lab.synth.environments.sky.cct_to_rgb`), green multiplied by ``2^(-tint)`` (``tint`` in
    stops, positive = magenta), then divided by its luminance so that ``Y(g) = 1``.

    Args:
        kelvin: the new colour temperature in K, within ``[1000, 40000]`` (the range of
            :func:`~kornia_ilum_lab.synth.environments.sky.cct_to_rgb`).
        tint: green-magenta shift in stops (positive = magenta), finite.

    Returns:
        the gains ``(3,)``, float64, RGB, with a luminance (Rec. 709 ``Y``) of 1.

    Raises:
        ValueCheckError: ``kelvin`` outside its range, ``tint`` not a finite number.

    Convention:
        Linear sRGB, as the lighting of docs/conventions.rst ("Images"): multiply a linear map by the gains.

    Examples:
        >>> white_balance_gains(6500.0).round(decimals=6)  # the reference white: no change
        tensor([1., 1., 1.], dtype=torch.float64)
        >>> g = white_balance_gains(3000.0, tint=0.2)
        >>> bool(g[0] > g[1] > g[2])
        True
    """
    if isinstance(tint, bool) or not isinstance(tint, (int, float)) or not math.isfinite(tint):
        raise ValueCheckError(f"tint must be a finite number of stops, got {tint!r}")
    lo, hi = _KELVIN_RANGE
    if isinstance(kelvin, bool) or not isinstance(kelvin, (int, float)) or not lo <= kelvin <= hi:
        raise ValueCheckError(f"kelvin must be a number in [{lo:g}, {hi:g}] K, got {kelvin!r}")
    white = cct_to_rgb(torch.tensor([float(kelvin), REFERENCE_KELVIN], dtype=torch.float64))
    gains = white[0] / white[1]
    gains[1] = gains[1] * 2.0 ** (-float(tint))
    return gains / (gains @ torch.tensor(LUMINANCE, dtype=torch.float64))


def lighting_rotation(yaw_deg: float = 0.0, pitch_deg: float = 0.0) -> torch.Tensor:
    r"""``R = R_x(pitch) R_y(yaw)`` ``(3, 3)`` float64: yaw about +Y first, then pitch about +X.

    Args:
        yaw_deg: rotation about +Y in degrees (positive moves a light from ahead to the left).
        pitch_deg: rotation about +X in degrees (positive moves a light from ahead upwards).

    Returns:
        the rotation ``(3, 3)``, float64, on the CPU: a light seen along ``d`` appears along ``R d``.

    Convention:
        docs/conventions.rst, "Rotation" (right-handed, degrees).

    Examples:
        >>> forward = torch.tensor([0.0, 0.0, -1.0], dtype=torch.float64)
        >>> lighting_rotation(yaw_deg=90.0).round(decimals=6) @ forward  # light from ahead now from the left
        tensor([-1.,  0.,  0.], dtype=torch.float64)
    """
    return axis_rotation(0, pitch_deg) @ axis_rotation(1, yaw_deg)


def weighted_quantile(
    values: torch.Tensor, weights: torch.Tensor, q: float | Sequence[float]
) -> torch.Tensor:
    r"""The ``q``-quantile(s) of ``values`` under non-negative ``weights``.

    The smallest value whose cumulative weight reaches ``q`` times the total (``values`` and ``weights``
    flat, same length; one sort for several ``q``).

    Args:
        values: the values ``(N,)``.
        weights: their non-negative weights ``(N,)``, not all 0.
        q: a quantile in ``[0, 1]`` or a sequence of them.

    Returns:
        a scalar tensor for a float ``q``, else one value per ``q``.

    Shape:
        - values, weights: :math:`(N,)`
        - Output: :math:`()` for a float ``q``, else :math:`(len(q),)`

    Examples:
        >>> weighted_quantile(torch.tensor([3.0, 1.0, 2.0]), torch.tensor([1.0, 1.0, 2.0]), 0.5)
        tensor(2.)
        >>> weighted_quantile(torch.tensor([3.0, 1.0, 2.0]), torch.ones(3), [0.0, 1.0])
        tensor([1., 3.])
    """
    order = torch.argsort(values)
    cum = torch.cumsum(weights[order], 0)
    qs = torch.as_tensor(q, dtype=cum.dtype, device=cum.device)
    k = torch.searchsorted(cum, qs.reshape(-1) * cum[-1]).clamp(max=values.numel() - 1)
    return values[order][k].reshape(qs.shape)


@compiler_disable
def rotate_latlong(latlong: torch.Tensor, rotation: torch.Tensor) -> torch.Tensor:
    r"""Rotate a lat-long map fast, conserving energy: ``L'(d) = L(R^T d)`` (module docstring, "Rotation").

    Args:
        latlong: linear HDR lat-long map, non-negative.
        rotation: a rotation ``(3, 3)`` (any float dtype; used in float64).

    Returns:
        the rotated map, same shape, dtype and device.

    Shape:
        - latlong: :math:`(C, H, 2H)` (luminance uses the first three channels as RGB when ``C = 3``,
          their mean otherwise)
        - Output: :math:`(C, H, 2H)`

    Convention:
        Frame and lat-long grid of docs/conventions.rst; ``R`` as in
        :func:`kornia_ilum.geometry.rotate_lighting`.
        ``sum(L * Omega)`` per channel is conserved to float precision; half precision runs in float32.
        Its control flow depends on the data (which pixels are peaks), so it runs outside
        :func:`torch.compile` graphs (:func:`torch.compiler.disable`). Differentiable in ``latlong``.

    Examples:
        >>> from kornia_ilum.geometry import latlong_solid_angles
        >>> env = torch.rand(3, 16, 32)
        >>> env[:, 8, 16] = 1e4  # a sun
        >>> out = rotate_latlong(env, lighting_rotation(40.0, 20.0))
        >>> omega = latlong_solid_angles(16)
        >>> torch.allclose((out * omega).sum((1, 2)), (env * omega).sum((1, 2)))
        True
    """
    check_tensor(latlong, "latlong", ["C", "H", "2H"], nonnegative=True)
    check_tensor(rotation, "rotation", ["3", "3"])
    c, h, w = latlong.shape
    if w != 2 * h:
        raise ShapeError(f"latlong must have shape (C, H, 2H), got {tuple(latlong.shape)}")
    rot = rotation.detach().to(device="cpu", dtype=torch.float64)
    if torch.equal(rot, torch.eye(3, dtype=torch.float64)):
        return latlong.clone()
    work = latlong.float() if latlong.dtype in (torch.float16, torch.bfloat16) else latlong
    omega = latlong_solid_angles(h, device=work.device, dtype=work.dtype)
    if c == 3:
        lum = torch.einsum("chw,c->hw", work, torch.tensor(LUMINANCE, dtype=work.dtype, device=work.device))
    else:
        lum = work.mean(0)
    flat_lum, flat_om = lum.flatten(), omega.flatten()
    median, q99 = weighted_quantile(flat_lum, flat_om, [0.5, 0.99])
    tau = torch.maximum(16.0 * median, q99)
    scale = torch.where(lum > tau, tau / lum.clamp(min=torch.finfo(work.dtype).tiny), torch.ones_like(lum))
    smooth = work * scale
    peaks = work - smooth

    # smooth part: pull (bilinear lookup at R^T d), then restore its energy per channel
    dirs = latlong_directions(h, dtype=torch.float64) @ rot  # rows: (R^T d)^T = d^T R
    pulled = sample_latlong(smooth, dirs.to(work.device))
    e_src, e_dst = (smooth * omega).sum((1, 2)), (pulled * omega).sum((1, 2))
    ratio = torch.where(e_dst > 0, e_src / e_dst.clamp(min=torch.finfo(work.dtype).tiny), 1.0)
    pulled = pulled * ratio[:, None, None]

    # peaks: push 2 x 2 sub-cells of each peak pixel to R d, bilinearly
    ii, jj = (lum > tau).nonzero(as_tuple=True)
    if ii.numel() == 0:
        return pulled.to(latlong.dtype)
    sub = torch.tensor([0.25, 0.75], dtype=torch.float64)
    oi, oj = torch.meshgrid(sub, sub, indexing="ij")
    rows = (ii.cpu().double()[:, None] + oi.flatten()).flatten()  # (4 P,)
    cols = (jj.cpu().double()[:, None] + oj.flatten()).flatten()
    phi = 2.0 * math.pi * cols / w - math.pi
    el = math.pi / 2.0 - math.pi * rows / h
    px = angles_to_latlong_pixel(*direction_to_latlong(latlong_to_direction(phi, el) @ rot.T), h)
    c0, r0 = px[:, 0].floor(), px[:, 1].floor()
    fc, fr = px[:, 0] - c0, px[:, 1] - r0
    energy = (peaks[:, ii, jj] * omega[ii, jj] / 4.0).repeat_interleave(4, dim=1)  # (C, 4 P)
    out = torch.zeros(c, h * w, dtype=work.dtype, device=work.device)
    for dr, wr in ((0, 1.0 - fr), (1, fr)):
        for dc, wc in ((0, 1.0 - fc), (1, fc)):
            tr = (r0 + dr).clamp(0, h - 1).long()
            tc = (c0 + dc).long() % w
            weight = (wr * wc).to(device=work.device, dtype=work.dtype)
            out.index_add_(1, (tr * w + tc).to(work.device), energy * weight)
    out = out.reshape(c, h, w) / omega
    return (pulled + out).to(latlong.dtype)


class RotateLatLong(nn.Module):
    r"""Module twin of :func:`rotate_latlong`; the rotation is a (non-persistent) buffer.

    Args:
        rotation: a rotation ``(3, 3)``.

    Examples:
        >>> RotateLatLong(lighting_rotation(30.0, 10.0))(torch.rand(3, 8, 16)).shape
        torch.Size([3, 8, 16])
    """

    rotation: torch.Tensor

    def __init__(self, rotation: torch.Tensor) -> None:
        super().__init__()
        check_tensor(rotation, "rotation", ["3", "3"])
        self.register_buffer("rotation", rotation, persistent=False)

    def forward(self, latlong: torch.Tensor) -> torch.Tensor:
        return rotate_latlong(latlong, self.rotation)


def _check_range(value: Any, name: str, lo: float, hi: float) -> tuple[float, float]:
    if not (isinstance(value, (tuple, list)) and len(value) == 2):
        raise TypeCheckError(f"{name} must be a pair (low, high), got {value!r}")
    a, b = (float(v) for v in value)
    if not (math.isfinite(a) and math.isfinite(b) and lo <= a <= b <= hi):
        raise ValueCheckError(f"{name} must satisfy {lo:g} <= low <= high <= {hi:g}, got {value!r}")
    return a, b


@dataclass(frozen=True)
class Augment:
    r"""Random augmentation of an :class:`~kornia_ilum_lab.synth.environments.Environment` (module docstring).

    Calling it with a generator draws six uniform numbers, always in the same order (so switching one
    augmentation off leaves the others' draws unchanged), and applies :meth:`apply`:

    - yaw uniform in ``[0, 360)`` degrees (0 when ``yaw=False``);
    - pitch uniform in ``[-pitch_deg, pitch_deg]``;
    - flip with probability 1/2 (never when ``flip=False``);
    - exposure shift uniform in ``exposure_stops`` (0 when ``None``);
    - colour temperature uniform in mired within ``kelvin`` and tint uniform in ``tint`` (6500 K and 0 when
      ``white_balance=False``).

    An environment whose lights are placed relative to the camera (``params["camera_anchored"]`` true: the
    on-camera flash, studio lights and window of
    :class:`~kornia_ilum_lab.synth.environments.PortraitLightSource`) is not turned: its yaw and pitch are drawn
    (the other draws stay the same) but set to 0; flip, exposure and white balance apply as to any other.

    Args:
        yaw: random yaw about +Y (the full turn).
        pitch_deg: largest pitch about +X in degrees (0 disables it), at most 90.
        flip: random horizontal flip.
        exposure_stops: range of the exposure shift in stops, or ``None``.
        white_balance: random white-balance shift.
        kelvin: range of colour temperatures in K, within ``[1000, 40000]``.
        tint: range of the green-magenta tint in stops (positive = magenta).

    Examples:
        >>> from kornia_ilum_lab.synth.environments import Environment
        >>> env = Environment(torch.ones(3, 8, 16), torch.ones(3, 32, 32), "outdoor", "test")
        >>> out = Augment()(env, torch.Generator().manual_seed(0))
        >>> sorted(out.params["augment"])[:4]
        ['direction_map', 'exposure_stops', 'flip', 'gains']
    """

    yaw: bool = True
    pitch_deg: float = 30.0
    flip: bool = True
    exposure_stops: tuple[float, float] | None = (-2.0, 2.0)
    white_balance: bool = True
    kelvin: tuple[float, float] = (4000.0, 40000.0)
    tint: tuple[float, float] = (-0.25, 0.25)

    def __post_init__(self) -> None:
        pitch = float(self.pitch_deg)
        if not 0.0 <= pitch <= 90.0:
            raise ValueCheckError(f"pitch_deg must be in [0, 90], got {self.pitch_deg}")
        if self.exposure_stops is not None:
            _check_range(self.exposure_stops, "exposure_stops", -64.0, 64.0)
        _check_range(self.kelvin, "kelvin", *_KELVIN_RANGE)
        _check_range(self.tint, "tint", -4.0, 4.0)

    def draw(self, generator: torch.Generator) -> dict[str, Any]:
        """The random parameters of one augmentation (keyword arguments of :meth:`apply`)."""
        if not isinstance(generator, torch.Generator):
            raise TypeCheckError(f"generator must be a torch.Generator, got {type(generator).__name__}")
        u = torch.rand(6, generator=generator, dtype=torch.float64).tolist()
        lo, hi = self.exposure_stops if self.exposure_stops is not None else (0.0, 0.0)
        m_lo, m_hi = 1e6 / self.kelvin[1], 1e6 / self.kelvin[0]
        return {
            "yaw_deg": 360.0 * u[0] if self.yaw else 0.0,
            "pitch_deg": float(self.pitch_deg) * (2.0 * u[1] - 1.0),
            "flip": bool(self.flip and u[2] < 0.5),
            "exposure_stops": lo + (hi - lo) * u[3],
            "kelvin": 1e6 / (m_lo + (m_hi - m_lo) * u[4]) if self.white_balance else REFERENCE_KELVIN,
            "tint": self.tint[0] + (self.tint[1] - self.tint[0]) * u[5] if self.white_balance else 0.0,
        }

    def __call__(self, env: Environment, generator: torch.Generator) -> Environment:
        kwargs = self.draw(generator)
        if isinstance(env, Environment) and env.params.get("camera_anchored"):
            kwargs["yaw_deg"] = kwargs["pitch_deg"] = 0.0  # lights placed relative to the camera stay there
        return self.apply(env, **kwargs)

    @staticmethod
    def apply(
        env: Environment,
        *,
        yaw_deg: float = 0.0,
        pitch_deg: float = 0.0,
        flip: bool = False,
        exposure_stops: float = 0.0,
        kelvin: float = REFERENCE_KELVIN,
        tint: float = 0.0,
    ) -> Environment:
        """Apply given parameters: rotate by ``R_x(pitch) R_y(yaw)``, flip, scale by ``2^stops`` and gains.

        Returns a new :class:`Environment` (the input is not modified) whose mirror ball is recomputed from
        the augmented lat-long map, with ``params["augment"]`` holding the parameters, the ``gains`` and
        the ``direction_map`` ``M`` (a light from ``d`` now comes from ``M d``).
        """
        if not isinstance(env, Environment):
            raise TypeCheckError(f"env must be an Environment, got {type(env).__name__}")
        rot = lighting_rotation(yaw_deg, pitch_deg)
        latlong = rotate_latlong(env.latlong, rot)
        if flip:
            latlong = flip_lighting_horizontal(latlong[None], "latlong")[0]
        gains = white_balance_gains(kelvin, tint) * 2.0 ** float(exposure_stops)
        latlong = latlong * gains.to(device=latlong.device, dtype=latlong.dtype)[:, None, None]
        ball = latlong_to_mirror_ball(latlong[None], env.mirror_ball.shape[-1], mode="area")[0]
        flip_m = torch.diag(torch.tensor([-1.0 if flip else 1.0, 1.0, 1.0], dtype=torch.float64))
        record = {
            "yaw_deg": float(yaw_deg),
            "pitch_deg": float(pitch_deg),
            "flip": bool(flip),
            "exposure_stops": float(exposure_stops),
            "kelvin": float(kelvin),
            "tint": float(tint),
            "gains": gains.tolist(),
            "direction_map": (flip_m @ rot).tolist(),
        }
        params = {**env.params, "augment": record}
        return dataclasses.replace(env, latlong=latlong, mirror_ball=ball, params=params)
