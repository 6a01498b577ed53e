r"""Backgrounds: a perspective view of a lat-long environment, tone-mapped to 8-bit sRGB.

Used to composite portraits over a background that matches their lighting: the view of the environment
that the portrait's camera would see behind the subject.

Convention:
    The camera is the one of docs/conventions.rst ("Frames"): a pinhole at the origin looking along -Z, +X
    to the right of the image, +Y up. ``yaw_deg``, ``pitch_deg`` and ``roll_deg`` turn it by
    ``R = R_y(yaw) R_x(pitch) R_z(roll)`` (right-handed rotations about the frame's axes, applied to the
    camera's rays: a ray ``r`` of the unrotated camera looks along ``R r``). So positive yaw turns the
    camera to its left (yaw +90 deg looks along -X), positive pitch looks up (+90 deg looks along +Y), and
    positive roll turns the camera counter-clockwise about its axis (the image content turns clockwise).
    This is the rotation convention of :func:`kornia_ilum.geometry.rotate_lighting` (``R (0, 0, -1) =
    (-1, 0, 0)`` for +90 deg about +Y). ``fov_deg`` is the horizontal field of view, between the left and
    right image edges (not pixel centres); pixels are square.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch
import torch.nn.functional as F
from torch import nn

from kornia_ilum.color import LUMINANCE, encode_srgb8
from kornia_ilum.core.check import check_positive_int, check_tensor
from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.geometry import angles_to_latlong_pixel, direction_to_latlong
from kornia_ilum.geometry.resample import resample_bilinear

__all__ = [
    "LUMINANCE",
    "RenderBackground",
    "axis_rotation",
    "camera_rays",
    "camera_rotation",
    "latlong_grid",
    "lookup_latlong",
    "render_background",
    "sample_latlong",
]

#: Luminance ``Y`` of linear sRGB (Rec. 709 primaries, D65): the middle row of Kornia's RGB -> XYZ matrix.

_HALF = (torch.float16, torch.bfloat16)


def axis_rotation(axis: int, degrees: float) -> torch.Tensor:
    r"""Right-handed rotation ``(3, 3)`` float64 by ``degrees`` about the axis ``axis`` (0 = X, 1 = Y, 2 = Z).

    The building block of :func:`camera_rotation` and of
    :func:`~kornia_ilum_lab.synth.environments.lighting_rotation`. ``degrees`` is not checked here
    (:func:`camera_rotation` checks its angles).

    Args:
        axis: the axis of rotation, 0 (X), 1 (Y) or 2 (Z).
        degrees: the angle in degrees, counter-clockwise when looking down the axis towards the origin.

    Returns:
        the rotation matrix ``(3, 3)``, float64, on the CPU.

    Raises:
        ValueCheckError: ``axis`` is not 0, 1 or 2.

    Examples:
        >>> forward = torch.tensor([0.0, 0.0, -1.0], dtype=torch.float64)
        >>> (axis_rotation(1, 90.0) @ forward).round(decimals=6) + 0.0  # +90 deg about +Y: ahead -> left
        tensor([-1.,  0.,  0.], dtype=torch.float64)
    """
    if isinstance(axis, bool) or not isinstance(axis, int) or axis not in (0, 1, 2):
        raise ValueCheckError(f"axis must be 0, 1 or 2, got {axis!r}")
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    r = torch.eye(3, dtype=torch.float64)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    return r


def camera_rotation(yaw_deg: float = 0.0, pitch_deg: float = 0.0, roll_deg: float = 0.0) -> torch.Tensor:
    r"""The camera rotation ``R = R_y(yaw) R_x(pitch) R_z(roll)`` of :func:`render_background`, float64.

    Args:
        yaw_deg: camera yaw in degrees (about +Y; positive turns left).
        pitch_deg: camera pitch in degrees (about +X; positive looks up).
        roll_deg: camera roll in degrees (about the optical axis; positive turns the camera counter-clockwise).

    Returns:
        the rotation matrix ``(3, 3)``, float64, on the CPU: a ray ``r`` of the unrotated camera looks along
        ``R r``.

    Raises:
        TypeCheckError: an angle is not a number.
        ValueCheckError: an angle is not finite.

    Convention:
        Frame of docs/conventions.rst ("Frames"); the rotation convention is in the module docstring.

    Examples:
        >>> forward = torch.tensor([0.0, 0.0, -1.0], dtype=torch.float64)
        >>> (camera_rotation(yaw_deg=90.0) @ forward).round(decimals=6) + 0.0
        tensor([-1.,  0.,  0.], dtype=torch.float64)
    """
    for name, value in (("yaw_deg", yaw_deg), ("pitch_deg", pitch_deg), ("roll_deg", roll_deg)):
        _check_finite_number(value, name)
    return axis_rotation(1, yaw_deg) @ axis_rotation(0, pitch_deg) @ axis_rotation(2, roll_deg)


def _check_finite_number(value: object, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise TypeCheckError(f"{name} must be a number, got {type(value).__name__}")
    if not math.isfinite(value):
        raise ValueCheckError(f"{name} must be finite, got {value}")
    return float(value)


def sample_latlong(latlong: torch.Tensor, directions: torch.Tensor) -> torch.Tensor:
    r"""Bilinear lookup of a lat-long map in given directions (azimuth wraps, rows continue over the poles).

    Args:
        latlong: lat-long map, ``(C, H, 2H)``, or a batch of maps ``(B, C, H, 2H)``.
        directions: directions ``(..., 3)`` (normalised inside), any float dtype; with a batch of maps,
            ``(B, ..., 3)`` (one set per map) or ``(1, ..., 3)`` (one set for all maps).

    Returns:
        the values ``(C, ...)`` (``(B, C, ...)`` for a batch) in the dtype and on the device of ``latlong``.

    Shape:
        - latlong: :math:`(C, H, 2H)` or :math:`(B, C, H, 2H)`
        - directions: :math:`(*, 3)`, or :math:`(B, *, 3)` / :math:`(1, *, 3)` with a batch
        - Output: :math:`(C, *)` or :math:`(B, C, *)`

    Convention:
        Lat-long grid of docs/conventions.rst; interpolation as in
        :func:`kornia_ilum.geometry.latlong_to_mirror_ball` ``(mode="bilinear")``. Point sampling: it does not
        conserve energy (use it for pictures, not for lighting that is integrated).

    Examples:
        >>> env = torch.zeros(1, 2, 4)
        >>> env[0, :, 1:3] = 1.0  # the two centre columns: forward
        >>> sample_latlong(env, torch.tensor([[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]])).round(decimals=4)
        tensor([[1., 0.]])
        >>> both = sample_latlong(torch.stack([env, 2 * env]), torch.tensor([[[0.0, 0.0, -1.0]]] * 2))
        >>> both.flatten().round(decimals=4)
        tensor([1., 2.])
    """
    batched = isinstance(latlong, torch.Tensor) and latlong.dim() == 4
    check_tensor(latlong, "latlong", ["B", "C", "H", "2H"] if batched else ["C", "H", "2H"])
    check_tensor(directions, "directions", ["*", "3"])
    if batched and (directions.dim() < 2 or directions.shape[0] not in (1, latlong.shape[0])):
        raise ShapeError(
            f"directions must have shape ({latlong.shape[0]}, ..., 3) or (1, ..., 3), got {tuple(directions.shape)}"
        )
    maps = latlong if batched else latlong[None]
    dirs = directions if batched else directions[None]
    b, c, h = maps.shape[:3]
    if maps.shape[-1] != 2 * h:
        raise ShapeError(f"latlong must have shape ({'B, ' if batched else ''}C, H, 2H), got {tuple(latlong.shape)}")
    shape = dirs.shape[1:-1]
    grid = latlong_grid(dirs.reshape(dirs.shape[0], 1, -1, 3), h).to(device=latlong.device, dtype=latlong.dtype)
    out = lookup_latlong(maps, grid).reshape(b, c, *shape)
    return out if batched else out[0]


def latlong_grid(directions: torch.Tensor, rows: int) -> torch.Tensor:
    r"""The :func:`lookup_latlong` grid of directions in a lat-long map of ``rows`` rows (float64).

    Compute it once for directions that many lookups share (a camera's rays): the trigonometry costs more than
    the lookup.

    Args:
        directions: ``(..., 3)`` directions (normalised inside).
        rows: the map's height ``H``.

    Returns:
        ``(..., 2)`` normalised ``grid_sample`` coordinates (``align_corners=True``) into the map padded by one
        pixel on every side.

    Shape:
        - directions: :math:`(*, 3)`
        - Output: :math:`(*, 2)`

    Convention:
        Lat-long grid of docs/conventions.rst ("Lat-long").

    Examples:
        >>> grid = latlong_grid(torch.tensor([[0.0, 0.0, -1.0]]), 4)  # forward: the centre of the map
        >>> grid.dtype, tuple(grid.shape), [round(v, 4) for v in grid[0].tolist()]
        (torch.float64, (1, 2), [0.0, 0.0])
    """
    check_tensor(directions, "directions", ["*", "3"])
    check_positive_int(rows, "rows")
    phi, el = direction_to_latlong(directions.to(torch.float64))
    px = angles_to_latlong_pixel(phi, el, rows) + 1.0  # the source is padded by one pixel on every side
    return torch.stack([2.0 * px[..., 0] / (2 * rows + 1) - 1.0, 2.0 * px[..., 1] / (rows + 1) - 1.0], -1)


def lookup_latlong(latlong: torch.Tensor, grid: torch.Tensor) -> torch.Tensor:
    r"""Bilinear lookup of lat-long maps ``(B, C, H, 2H)`` at a :func:`latlong_grid` ``(B | 1, h, w, 2)``.

    Returns ``(B, C, h, w)``; no value checks (:func:`sample_latlong` is the checked entry point).

    Args:
        latlong: lat-long maps ``(B, C, H, 2H)``.
        grid: the :func:`latlong_grid` of the directions, ``(B, h, w, 2)`` or ``(1, h, w, 2)`` (one grid for
            all maps); cast to the dtype of ``latlong``.

    Returns:
        the values ``(B, C, h, w)`` in the dtype and on the device of ``latlong``.

    Shape:
        - latlong: :math:`(B, C, H, 2H)`
        - grid: :math:`(B, h, w, 2)` or :math:`(1, h, w, 2)`
        - Output: :math:`(B, C, h, w)`

    Convention:
        Lat-long grid of docs/conventions.rst ("Lat-long"); point sampling, as :func:`sample_latlong`.

    Examples:
        >>> env = torch.zeros(1, 1, 2, 4)
        >>> env[..., 1:3] = 1.0  # the two centre columns: forward
        >>> grid = latlong_grid(torch.tensor([[[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]]]), 2)  # (1, 1, 2, 2)
        >>> lookup_latlong(env, grid).flatten().round(decimals=4)
        tensor([1., 0.])
    """
    return resample_bilinear(latlong, ("latlong", latlong.shape[-2]), grid.to(latlong.dtype), None)


def _check_size(size: object) -> tuple[int, int]:
    if not isinstance(size, Sequence) or len(size) != 2:
        raise TypeCheckError(f"size must be a pair (height, width) of positive ints, got {size!r}")
    check_positive_int(size[0], "size[0] (height)")
    check_positive_int(size[1], "size[1] (width)")
    return int(size[0]), int(size[1])


def _check_view(size: object, fov_deg: object, exposure: object) -> tuple[int, int]:
    hw = _check_size(size)
    fov = _check_finite_number(fov_deg, "fov_deg")
    if not 0.0 < fov < 180.0:
        raise ValueCheckError(f"fov_deg must be in (0, 180) degrees, got {fov_deg}")
    if exposure is not None and not _check_finite_number(exposure, "exposure") > 0.0:
        raise ValueCheckError(f"exposure must be None (auto) or a positive gain, got {exposure}")
    return hw


def camera_rays(
    size: tuple[int, int], fov_deg: float, rotation: torch.Tensor, supersample: int = 1
) -> torch.Tensor:
    r"""Unit ray directions of the pixels of a rotated pinhole camera (module docstring), float64.

    Args:
        size: ``(height, width)`` in pixels.
        fov_deg: horizontal field of view in degrees (between the left and right image edges).
        rotation: the camera rotation ``(3, 3)`` (:func:`camera_rotation`).
        supersample: rays per pixel and axis, at the centres of an ``n x n`` grid of sub-pixels.

    Returns:
        ``(n h, n w, 3)`` unit directions; the focal length is ``(w / 2) / tan(fov / 2)`` pixels.

    Shape:
        - rotation: :math:`(3, 3)`
        - Output: :math:`(n h, n w, 3)`

    Convention:
        Camera of docs/conventions.rst ("Frames"), rotated as in the module docstring: row 0 is the top of the
        image, and the unrotated centre ray looks along -Z.

    Examples:
        >>> rays = camera_rays((1, 3), 90.0, torch.eye(3, dtype=torch.float64))
        >>> rays[0, 1]  # the centre pixel looks along -Z
        tensor([ 0.,  0., -1.], dtype=torch.float64)
    """
    hw = _check_size(size)
    check_positive_int(supersample, "supersample")
    h, w = hw
    n = supersample
    focal = (w / 2.0) / math.tan(math.radians(fov_deg) / 2.0)  # in pixels
    offs = (torch.arange(n, dtype=torch.float64) + 0.5) / n
    cols = (torch.arange(w, dtype=torch.float64)[:, None] + offs).flatten()
    rows = (torch.arange(h, dtype=torch.float64)[:, None] + offs).flatten()
    y, x = torch.meshgrid(h / 2.0 - rows, cols - w / 2.0, indexing="ij")
    rays = torch.stack([x, y, torch.full_like(x, -focal)], -1)
    rays = rays / rays.norm(dim=-1, keepdim=True)
    return rays @ rotation.T


def render_background(
    latlong: torch.Tensor,
    *,
    size: tuple[int, int] = (256, 256),
    fov_deg: float = 60.0,
    yaw_deg: float = 0.0,
    pitch_deg: float = 0.0,
    roll_deg: float = 0.0,
    exposure: float | None = None,
) -> torch.Tensor:
    r"""Perspective view of a lat-long environment, tone-mapped and encoded to 8-bit sRGB.

    Each pixel averages 2 x 2 rays (supersampling against aliasing), each a bilinear lookup of the map
    (:func:`sample_latlong`). The linear image is multiplied by the exposure, clipped to ``[0, 1]``,
    encoded with the sRGB curve and quantised to 8 bits (:func:`kornia_ilum.color.encode_srgb8`).

    Args:
        latlong: linear HDR lat-long environment, non-negative.
        size: ``(height, width)`` of the image in pixels.
        fov_deg: horizontal field of view in degrees, in ``(0, 180)``.
        yaw_deg: camera yaw (about +Y; positive turns left).
        pitch_deg: camera pitch (about +X; positive looks up).
        roll_deg: camera roll (about the optical axis; positive turns the camera counter-clockwise).
        exposure: linear gain applied before clipping. ``None``: auto-exposure, the gain that maps the
            median luminance of the view (linear, Rec. 709 ``Y``) to 0.18 (middle grey), falling back to the
            mean when the median is 0, and to 1 for a black view. Pass the portrait's exposure to keep the
            background in the units of the lighting.

    Returns:
        ``(3, h, w)`` ``torch.uint8`` sRGB image on the device of ``latlong``.

    Raises:
        ShapeError: ``latlong`` is not ``(3, H, 2H)``.
        ValueCheckError: negative lighting, ``fov_deg`` outside ``(0, 180)``, non-positive ``exposure``.
        NonFiniteError: NaN or Inf in ``latlong``.
        TypeCheckError: ``size`` is not a pair of ints, an angle is not a number.

    Shape:
        - latlong: :math:`(3, H, 2H)`
        - Output: :math:`(3, h, w)`

    Convention:
        Camera (looks along -Z, +X right, +Y up) and lat-long grid of docs/conventions.rst; the rotation
        convention is in the module docstring: with ``yaw_deg=90`` the centre pixel sees -X.

    Examples:
        >>> sky = torch.ones(3, 16, 32)
        >>> img = render_background(sky, size=(4, 6), exposure=0.5)
        >>> img.dtype, tuple(img.shape), img[0, 0, 0].item()  # sRGB(0.5) = 0.735 -> 188
        (torch.uint8, (3, 4, 6), 188)
    """
    check_tensor(latlong, "latlong", ["3", "H", "2H"], nonnegative=True)
    if latlong.shape[-1] != 2 * latlong.shape[-2]:
        raise ShapeError(f"latlong must have shape (3, H, 2H), got {tuple(latlong.shape)}")
    h, w = _check_view(size, fov_deg, exposure)
    rotation = camera_rotation(yaw_deg, pitch_deg, roll_deg)
    work = latlong.float() if latlong.dtype in _HALF else latlong
    rays = camera_rays((h, w), float(fov_deg), rotation, supersample=2)
    linear = F.avg_pool2d(sample_latlong(work, rays)[None], 2)[0]  # (3, h, w)
    if exposure is None:
        weights = torch.tensor(LUMINANCE, dtype=linear.dtype, device=linear.device)
        lum = torch.einsum("chw,c->hw", linear, weights)
        ref = lum.median()
        ref = ref if ref > 0 else lum.mean()
        gain = 0.18 / ref if ref > 0 else torch.ones((), dtype=linear.dtype, device=linear.device)
    else:
        gain = float(exposure)
    return encode_srgb8(linear.float().mul_(gain), inplace=True)


class RenderBackground(nn.Module):
    r"""Module twin of :func:`render_background`: holds the camera and the exposure.

    Args:
        size: ``(height, width)`` in pixels.
        fov_deg: horizontal field of view in degrees.
        yaw_deg: camera yaw in degrees.
        pitch_deg: camera pitch in degrees.
        roll_deg: camera roll in degrees.
        exposure: linear gain, or ``None`` for auto-exposure.

    Examples:
        >>> RenderBackground(size=(8, 8))(torch.ones(3, 16, 32)).shape
        torch.Size([3, 8, 8])
    """

    def __init__(
        self,
        size: tuple[int, int] = (256, 256),
        *,
        fov_deg: float = 60.0,
        yaw_deg: float = 0.0,
        pitch_deg: float = 0.0,
        roll_deg: float = 0.0,
        exposure: float | None = None,
    ) -> None:
        super().__init__()
        self.size = _check_view(size, fov_deg, exposure)
        camera_rotation(yaw_deg, pitch_deg, roll_deg)  # checks the angles
        self.fov_deg, self.exposure = float(fov_deg), exposure
        self.yaw_deg, self.pitch_deg, self.roll_deg = float(yaw_deg), float(pitch_deg), float(roll_deg)

    def forward(self, latlong: torch.Tensor) -> torch.Tensor:
        return render_background(
            latlong,
            size=self.size,
            fov_deg=self.fov_deg,
            yaw_deg=self.yaw_deg,
            pitch_deg=self.pitch_deg,
            roll_deg=self.roll_deg,
            exposure=self.exposure,
        )

    def extra_repr(self) -> str:
        return (
            f"size={self.size}, fov_deg={self.fov_deg}, yaw_deg={self.yaw_deg}, pitch_deg={self.pitch_deg}, "
            f"roll_deg={self.roll_deg}, exposure={self.exposure}"
        )
