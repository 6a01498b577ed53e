r"""The main light and the ambient of a lighting, as users ask for them: ARCore's Environmental HDR shape.

:func:`dominant_light` splits a mirror-ball lighting ``L`` in two, with nothing lost:

- **the main light**: the brightest pixel of the ball and its neighbours within ``max_angle`` whose luminance
  is at least ``threshold`` times the brightest's, above the radiance ``b`` of the sky around them (the
  per-channel median of the pixels between ``max_angle`` and twice that from the brightest). It is given as
  a direction (luminance-weighted over its pixels), a solid angle, and an irradiance
  ``E = sum_p max(L_p - b, 0) Omega_p``: what a surface facing it receives, in the units of the lighting
  times steradians. ``color`` is ``E`` at unit luminance and ``intensity`` its luminance (Rec. 709);
- **the ambient**: everything else, ``L - max(L - b, 0)`` on the light's pixels, as order-2 SH
  (:func:`~kornia_ilum.sh.sh_project`; :func:`~kornia_ilum.sh.sh_to_arcore` gives ARCore's 27 floats).

So ``E`` plus the ambient's irradiance from every direction add up to the lighting's. A lighting with no
light at all (black) gives a zero direction and zero irradiance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import torch
from torch import nn

from kornia_ilum.color import LUMINANCE
from kornia_ilum.core.check import check_tensor
from kornia_ilum.core.dtypes import work_dtype
from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.geometry import mirror_ball_directions, mirror_ball_solid_angles
from kornia_ilum.sh.harmonics import sh_project
from kornia_ilum.sh.layouts import sh_to_arcore

__all__ = ["DOMINANT_MAX_ANGLE", "DOMINANT_THRESHOLD", "DominantLight", "SplitDominantLight", "dominant_light"]

#: The default ``threshold`` of :func:`dominant_light`: the light's pixels reach this fraction of the peak.
DOMINANT_THRESHOLD = 0.02
#: The default ``max_angle`` of :func:`dominant_light` in degrees: the light's largest angular radius.
DOMINANT_MAX_ANGLE = 20.0


@dataclass(frozen=True)
class DominantLight:
    """The main light and the ambient of a batch of lightings (:func:`dominant_light`).

    Attributes:
        direction: ``(B, 3)`` unit vector the light arrives *from*, in the camera frame (+X right, +Y up, +Z
            toward the camera; docs/conventions.rst); zero for a black lighting.
        solid_angle: ``(B,)`` the light's solid angle in steradians (its pixels').
        irradiance: ``(B, 3)`` linear RGB irradiance of the light on a surface facing it, above the sky behind
            it: the units of the lighting times steradians.
        ambient_sh: ``(B, 9, 3)`` order-2 radiance SH of the rest (docs/conventions.rst, "Spherical
            harmonics").

    Examples:
        >>> light = dominant_light(torch.zeros(2, 3, 32, 32))  # black: no light at all
        >>> light.direction.shape, light.ambient_sh.shape, light.intensity.tolist()
        (torch.Size([2, 3]), torch.Size([2, 9, 3]), [0.0, 0.0])
        >>> light.color[0].tolist()  # (1, 1, 1) where there is no light
        [1.0, 1.0, 1.0]
    """

    direction: torch.Tensor
    solid_angle: torch.Tensor
    irradiance: torch.Tensor
    ambient_sh: torch.Tensor

    @property
    def intensity(self) -> torch.Tensor:
        """``(B,)`` the luminance (Rec. 709) of :attr:`irradiance`."""
        return self.irradiance @ self.irradiance.new_tensor(LUMINANCE)

    @property
    def color(self) -> torch.Tensor:
        """``(B, 3)`` :attr:`irradiance` at unit luminance (``(1, 1, 1)`` where there is none)."""
        y = self.intensity[:, None]
        return torch.where(y > 0, self.irradiance / y.clamp(min=torch.finfo(y.dtype).tiny), 1.0)

    def to_dict(self, index: int = 0) -> dict[str, Any]:
        """Item ``index`` as plain numbers (for JSON), with what each field means.

        Raises:
            ValueCheckError: ``index`` outside the batch.

        Examples:
            >>> ball = torch.zeros(1, 3, 32, 32)
            >>> ball[:, :, 8, 16] = 1000.0  # one white pixel of 1000, up and toward the camera
            >>> light = dominant_light(ball).to_dict()
            >>> [round(v, 2) for v in light["direction"]], round(light["intensity"], 1)  # 1000 x 16 / 32^2 sr
            ([0.06, 0.83, 0.56], 15.6)
        """
        if not isinstance(index, int) or not -len(self.solid_angle) <= index < len(self.solid_angle):
            raise ValueCheckError(f"index must be in [0, {len(self.solid_angle)}), got {index!r}")

        def numbers(t: torch.Tensor) -> Any:
            return t[index].detach().double().cpu().tolist()

        return {
            "direction": numbers(self.direction),
            "solid_angle_sr": numbers(self.solid_angle),
            "irradiance_rgb": numbers(self.irradiance),
            "color_rgb": numbers(self.color),
            "intensity": numbers(self.intensity),
            "ambient_sh": numbers(self.ambient_sh),
            "ambient_sh_arcore": numbers(sh_to_arcore(self.ambient_sh)),
            "convention": (
                "direction: the light arrives from it, camera frame +X right, +Y up, +Z toward the camera; "
                "irradiance: on a surface facing the light, linear RGB in the units of the lighting times sr "
                "(the photo's units for an estimate); intensity: its Rec. 709 luminance, color: irradiance / "
                "intensity; ambient_sh: 9 x RGB real radiance SH of the rest, order (0,0), (1,-1), (1,0), "
                "(1,1), (2,-2), (2,-1), (2,0), (2,1), (2,2) (kornia_ilum docs/conventions.rst); "
                "ambient_sh_arcore: the same as ARCore's 27 floats"
            ),
        }


def _masked_median(values: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """``(B, C)``: the per-channel median of ``values`` ``(B, C, P)`` over ``mask`` ``(B, P)``; 0 where empty."""
    filled = torch.where(mask[:, None], values, torch.nan)
    return torch.nan_to_num(filled.nanmedian(dim=-1).values, nan=0.0)


def _check_split(threshold: float, max_angle: float) -> None:
    """Raise :class:`ValueCheckError` unless ``threshold`` is in ``(0, 1]`` and ``max_angle`` in ``(0, 90]``."""
    if isinstance(threshold, bool) or not isinstance(threshold, (int, float)) or not 0.0 < threshold <= 1.0:
        raise ValueCheckError(f"threshold must be a number in (0, 1], got {threshold!r}")
    if isinstance(max_angle, bool) or not isinstance(max_angle, (int, float)) or not 0.0 < max_angle <= 90.0:
        raise ValueCheckError(f"max_angle must be a number of degrees in (0, 90], got {max_angle!r}")


def dominant_light(mirror_ball: torch.Tensor, *, threshold: float = DOMINANT_THRESHOLD,
                   max_angle: float = DOMINANT_MAX_ANGLE) -> DominantLight:
    r"""The main light (direction, solid angle, colour, intensity) and the order-2 SH of the rest.

    The module docstring gives the split. It is the shape of ARCore's Environmental HDR (main light direction
    and intensity, ambient SH), from any lighting.

    Args:
        mirror_ball: linear HDR lighting in radiance, non-negative, 0 outside the ball.
        threshold: the light's pixels reach at least this fraction of its brightest pixel's luminance, in
            ``(0, 1]``.
        max_angle: the light's largest angular radius in degrees, in ``(0, 90]``.

    Returns:
        a :class:`DominantLight`, in the dtype of ``mirror_ball`` (half precision is computed in float32).

    Raises:
        ValueCheckError: ``threshold`` or ``max_angle`` out of range, or negative lighting.
        NonFiniteError: NaN or Inf in ``mirror_ball``.
        ShapeError: not ``(B, 3, S, S)``.

    Shape:
        - mirror_ball: :math:`(B, 3, S, S)`
        - Output: direction :math:`(B, 3)`, solid_angle :math:`(B,)`, irradiance :math:`(B, 3)`, ambient_sh
          :math:`(B, 9, 3)`

    Convention:
        docs/conventions.rst: the camera frame, the mirror ball's pixel directions and solid angles, the SH.

    Examples:
        >>> from kornia_ilum.geometry import mirror_ball_valid
        >>> sky = 0.5 * torch.ones(1, 3, 32, 32) * mirror_ball_valid(32)
        >>> sky[0, :, 16, 28] += torch.tensor([800.0, 600.0, 400.0])  # a warm sun to the right
        >>> light = dominant_light(sky)
        >>> [round(v, 2) for v in light.direction[0].tolist()], round(light.solid_angle.item(), 4)
        ([0.97, -0.04, -0.22], 0.0156)
        >>> [round(v, 2) for v in light.color[0].tolist()]
        [1.27, 0.96, 0.64]
        >>> round(light.ambient_sh[0, 0, 0].item() / (0.5 * 2 * math.pi ** 0.5), 3)  # the sky: 0.5 everywhere
        1.0
    """
    check_tensor(mirror_ball, "mirror_ball", ["B", "3", "S", "S"], nonnegative=True)
    _check_split(threshold, max_angle)
    dtype = work_dtype(mirror_ball.dtype)
    light = mirror_ball.to(dtype)
    b, _, s, _ = light.shape
    dirs, valid = mirror_ball_directions(s, device=light.device, dtype=dtype)
    dirs, valid = dirs.reshape(-1, 3), valid.reshape(-1)
    omega = mirror_ball_solid_angles(s, device=light.device, dtype=dtype).reshape(-1)
    flat = light.reshape(b, 3, -1)
    luma = light.new_tensor(LUMINANCE)
    y = torch.einsum("bcp,c->bp", flat, luma)
    peak = torch.where(valid, y, -1.0).argmax(dim=1)  # (B,)
    peak_y = y.gather(1, peak[:, None])  # (B, 1)
    closeness = dirs[peak] @ dirs.T  # (B, P): cosine to the brightest pixel
    near = valid & (closeness >= math.cos(math.radians(max_angle)))
    region = near & (y >= threshold * peak_y) & (peak_y > 0)
    ring = valid & ~near & (closeness >= math.cos(math.radians(min(2.0 * max_angle, 180.0))))
    behind = _masked_median(flat, ring)  # (B, 3): the sky behind the light
    excess = (flat - behind[:, :, None]).clamp(min=0) * region[:, None]  # (B, 3, P)
    weights = excess * omega  # (B, 3, P)
    irradiance = weights.sum(-1)
    toward = torch.einsum("bcp,c,pk->bk", weights, luma, dirs)
    norm = toward.norm(dim=1, keepdim=True)
    direction = torch.where(norm > 0, toward / norm.clamp(min=torch.finfo(dtype).tiny), 0.0)
    ambient = (flat - excess).reshape(b, 3, s, s)
    result = DominantLight(direction, (region * omega).sum(-1), irradiance, sh_project(ambient))
    if dtype == mirror_ball.dtype:
        return result
    return DominantLight(*(t.to(mirror_ball.dtype) for t in (result.direction, result.solid_angle,
                                                             result.irradiance, result.ambient_sh)))


class SplitDominantLight(nn.Module):
    r"""Module twin of :func:`dominant_light` (named for what it does: :class:`DominantLight` is its result).

    Args:
        threshold: the light's pixels reach at least this fraction of its brightest pixel's luminance, in
            ``(0, 1]``.
        max_angle: the light's largest angular radius in degrees, in ``(0, 90]``.

    Raises:
        ValueCheckError: ``threshold`` or ``max_angle`` out of range.

    Shape:
        - Input: :math:`(B, 3, S, S)`
        - Output: a :class:`DominantLight`: direction :math:`(B, 3)`, solid_angle :math:`(B,)`, irradiance
          :math:`(B, 3)`, ambient_sh :math:`(B, 9, 3)`

    Examples:
        >>> SplitDominantLight(max_angle=10.0)(torch.zeros(2, 3, 32, 32)).ambient_sh.shape
        torch.Size([2, 9, 3])
    """

    def __init__(self, threshold: float = DOMINANT_THRESHOLD, max_angle: float = DOMINANT_MAX_ANGLE) -> None:
        super().__init__()
        _check_split(threshold, max_angle)
        self.threshold, self.max_angle = threshold, max_angle

    def forward(self, mirror_ball: torch.Tensor) -> DominantLight:
        return dominant_light(mirror_ball, threshold=self.threshold, max_angle=self.max_angle)

    def extra_repr(self) -> str:
        return f"threshold={self.threshold}, max_angle={self.max_angle}"
