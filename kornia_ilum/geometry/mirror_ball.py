r"""The mirror-ball (Lambert azimuthal equal-area) lighting grid of docs/conventions.rst ("Mirror ball").

Convention:
    Frame: +X right, +Y up, +Z toward the camera; a direction ``d`` means light arriving *from* ``d``.
    An ``S x S`` grid has pixel centres ``u = (2j + 1)/S - 1`` and ``v = 1 - (2i + 1)/S`` for row ``i``
    and column ``j``; with ``r^2 = u^2 + v^2`` the direction is
    ``d = (2u sqrt(1 - r^2), 2v sqrt(1 - r^2), 1 - 2 r^2)``. The centre is +Z, the rim is -Z. A pixel is
    valid iff its centre has ``r <= 1``; invalid pixels hold 0.

    The map is equal-area: ``dOmega = 4 du dv``, so a pixel fully inside the disk spans exactly
    ``16 / S^2`` sr. The disk is partitioned among the valid pixels: a point in a valid pixel's square
    belongs to that pixel; a point in an *invalid* pixel's square (the thin sliver of disk beyond the
    valid pixels) belongs to the nearest *rim pixel*, a valid pixel whose square crosses the unit circle.
    Fully inside pixels therefore never receive slivers. The disk area in each square is integrated
    analytically, and only the split of each sliver between rim pixels is supersampled (ties split
    equally, so the result keeps the grid's symmetries). The solid angles sum to ``4 pi`` to float
    precision at every size, and :func:`mirror_ball_pixel_index` assigns every direction to the pixel
    whose solid angle covers it, which is what energy-conserving resampling needs.
"""

from __future__ import annotations

import math
from functools import lru_cache

import torch

from kornia_ilum.core.check import check_positive_int, check_tensor
from kornia_ilum.core.compiler import compiler_disable
from kornia_ilum.core.errors import ShapeError

__all__ = [
    "mirror_ball_uv",
    "mirror_ball_valid",
    "mirror_ball_directions",
    "mirror_ball_solid_angles",
    "mirror_ball_to_direction",
    "direction_to_mirror_ball",
    "uv_to_pixel",
    "pixel_to_uv",
    "mirror_ball_pixel_index",
    "mirror_ball_to_lights",
    "lights_to_mirror_ball",
]

_RIM_SUPERSAMPLES = 32  # per axis, only for splitting invalid rim slivers between valid neighbours


def mirror_ball_uv(
    size: int, *, device: torch.device | str | None = None, dtype: torch.dtype = torch.float32
) -> torch.Tensor:
    r"""Pixel-centre coordinates ``(u, v)`` of an ``S x S`` mirror ball.

    Args:
        size: the side ``S`` in pixels.
        device: device of the result.
        dtype: floating dtype of the result.

    Returns:
        ``(S, S, 2)`` tensor; ``[..., 0]`` is ``u`` (right), ``[..., 1]`` is ``v`` (up).

    Raises:
        TypeCheckError: ``size`` is not an int.
        ValueCheckError: ``size`` is not positive.

    Shape:
        - Output: :math:`(S, S, 2)`

    Convention:
        docs/conventions.rst, "Mirror ball": ``u = (2j + 1)/S - 1``, ``v = 1 - (2i + 1)/S`` for row ``i`` and
        column ``j``; valid iff ``r <= 1``.

    Examples:
        >>> mirror_ball_uv(2)[0, 0]
        tensor([-0.5000,  0.5000])
    """
    check_positive_int(size, "size")
    c = (2 * torch.arange(size, device=device, dtype=torch.float64) + 1) / size - 1
    v, u = torch.meshgrid(-c, c, indexing="ij")
    return torch.stack([u, v], dim=-1).to(dtype)


def mirror_ball_valid(size: int, *, device: torch.device | str | None = None) -> torch.Tensor:
    r"""Boolean ``(S, S)`` mask of the pixels whose centre lies on the ball (``r <= 1``).

    Args:
        size: the side ``S`` in pixels.
        device: device of the result.

    Returns:
        ``torch.bool`` mask, ``True`` on the ball.

    Raises:
        TypeCheckError: ``size`` is not an int.
        ValueCheckError: ``size`` is not positive.

    Shape:
        - Output: :math:`(S, S)`

    Convention:
        docs/conventions.rst, "Mirror ball": ``u = (2j + 1)/S - 1``, ``v = 1 - (2i + 1)/S`` for row ``i`` and
        column ``j``; valid iff ``r <= 1``.

    Examples:
        >>> mirror_ball_valid(4).sum().item()
        12
    """
    uv = mirror_ball_uv(size, device=device, dtype=torch.float64)
    return (uv.square().sum(-1) <= 1.0 + 1e-12)


def mirror_ball_to_direction(uv: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    r"""Map mirror-ball coordinates to unit directions.

    Args:
        uv: ``(..., 2)`` continuous coordinates ``(u, v)`` in ``[-1, 1]``.

    Returns:
        ``(d, valid)``: ``(..., 3)`` unit directions and the ``(...)`` boolean mask ``r <= 1``. Points
        outside the ball are clamped radially onto the rim (direction -Z) so that ``d`` stays finite.

    Raises:
        ShapeError: ``uv``'s last dimension is not 2.
        NonFiniteError: NaN or Inf in ``uv``.

    Shape:
        - uv: :math:`(*, 2)`
        - Output: :math:`(*, 3)` and :math:`(*)`

    Convention:
        ``d = (2u sqrt(1 - r^2), 2v sqrt(1 - r^2), 1 - 2 r^2)`` (docs/conventions.rst, "Mirror ball").

    Examples:
        >>> d, valid = mirror_ball_to_direction(torch.tensor([[0.0, 0.0], [1.0, 0.0]]))
        >>> d
        tensor([[ 0.,  0.,  1.],
                [ 0.,  0., -1.]])
    """
    check_tensor(uv, "uv", ["*", "2"])
    r2 = uv.square().sum(-1, keepdim=True)
    valid = r2.squeeze(-1) <= 1.0 + 1e-6
    r2c = r2.clamp(max=1.0)
    scale = 2.0 * torch.sqrt((1.0 - r2c).clamp(min=0.0))
    # outside the disk: project onto the rim, where d = -Z regardless of the azimuth
    uv_in = torch.where(r2 > 1.0, uv / r2.sqrt().clamp(min=1e-12), uv)
    d = torch.cat([uv_in * scale, 1.0 - 2.0 * r2c], dim=-1)
    return d, valid


def direction_to_mirror_ball(d: torch.Tensor) -> torch.Tensor:
    r"""Map directions to continuous mirror-ball coordinates ``(u, v)``; the inverse of
    :func:`mirror_ball_to_direction`.

    Args:
        d: ``(..., 3)`` directions; they are normalised first.

    Returns:
        ``(..., 2)`` coordinates with ``r = sqrt((1 - z) / 2) <= 1``. Directions near -Z map to the rim
        along the azimuth of ``(x, y)``; exactly -Z maps to the rim point ``(0, -1)``.

    Raises:
        ShapeError: ``d``'s last dimension is not 3.
        NonFiniteError: NaN or Inf in ``d``.

    Shape:
        - d: :math:`(*, 3)`
        - Output: :math:`(*, 2)`

    Convention:
        docs/conventions.rst, "Mirror ball" and "Frames": +Z (toward the camera) maps to the centre, -Z to the
        rim.

    Examples:
        >>> direction_to_mirror_ball(torch.tensor([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]))
        tensor([[0.0000, 0.0000],
                [0.7071, 0.0000]])
    """
    check_tensor(d, "d", ["*", "3"])
    d = d / d.norm(dim=-1, keepdim=True).clamp(min=torch.finfo(d.dtype).tiny)
    xy, z = d[..., :2], d[..., 2:]
    # (u, v) = (x, y) / sqrt(2 (1 + z)): stable away from z = -1; near -Z use r * (x, y) / |(x, y)|.
    front = xy / torch.sqrt((2.0 * (1.0 + z)).clamp(min=1e-12))
    rho = xy.norm(dim=-1, keepdim=True)
    r = torch.sqrt(((1.0 - z) * 0.5).clamp(min=0.0, max=1.0))
    fallback = torch.zeros_like(xy)
    fallback[..., 1] = -1.0
    back = torch.where(rho > 1e-12, r * xy / rho.clamp(min=1e-12), r * fallback)
    return torch.where(z > -0.5, front, back)


def uv_to_pixel(uv: torch.Tensor, size: int) -> torch.Tensor:
    r"""Continuous ``(u, v)`` to continuous pixel coordinates ``(col, row)``; centres are integers.

    ``col = ((u + 1) S - 1) / 2``, ``row = ((1 - v) S - 1) / 2``. Nothing is checked or clamped.

    Args:
        uv: coordinates ``(u, v)``, ``u`` right and ``v`` up.
        size: the side ``S`` in pixels.

    Returns:
        ``(col, row)`` stacked on the last dimension, in the dtype of ``uv``.

    Shape:
        - uv: :math:`(*, 2)`
        - Output: :math:`(*, 2)`

    Convention:
        docs/conventions.rst, "Mirror ball": ``u = (2j + 1)/S - 1``, ``v = 1 - (2i + 1)/S`` for row ``i`` and
        column ``j``; valid iff ``r <= 1``.

    Examples:
        >>> uv_to_pixel(torch.tensor([-0.75, 0.75]), 4)
        tensor([0., 0.])
    """
    col = ((uv[..., 0] + 1.0) * size - 1.0) * 0.5
    row = ((1.0 - uv[..., 1]) * size - 1.0) * 0.5
    return torch.stack([col, row], dim=-1)


def pixel_to_uv(px: torch.Tensor, size: int) -> torch.Tensor:
    r"""Continuous pixel coordinates ``(col, row)`` to ``(u, v)``; the inverse of :func:`uv_to_pixel`.

    Args:
        px: pixel coordinates ``(col, row)``; pixel centres are integers.
        size: the side ``S`` in pixels.

    Returns:
        ``(u, v)`` stacked on the last dimension, in the dtype of ``px``. Nothing is checked or clamped.

    Shape:
        - px: :math:`(*, 2)`
        - Output: :math:`(*, 2)`

    Convention:
        docs/conventions.rst, "Mirror ball": ``u = (2j + 1)/S - 1``, ``v = 1 - (2i + 1)/S`` for row ``i`` and
        column ``j``; valid iff ``r <= 1``.

    Examples:
        >>> pixel_to_uv(torch.tensor([0.0, 0.0]), 4).tolist()  # the top-left pixel's centre
        [-0.75, 0.75]
        >>> px = torch.tensor([[1.5, 2.25]])
        >>> torch.allclose(uv_to_pixel(pixel_to_uv(px, 8), 8), px)
        True
    """
    u = (2.0 * px[..., 0] + 1.0) / size - 1.0
    v = 1.0 - (2.0 * px[..., 1] + 1.0) / size
    return torch.stack([u, v], dim=-1)


def mirror_ball_directions(
    size: int, *, device: torch.device | str | None = None, dtype: torch.dtype = torch.float32
) -> tuple[torch.Tensor, torch.Tensor]:
    r"""Directions of the pixel centres of an ``S x S`` mirror ball.

    Args:
        size: the side ``S`` in pixels.
        device: device of the result.
        dtype: dtype of the directions (computed in float64).

    Returns:
        ``(d, valid)``: ``(S, S, 3)`` unit directions (invalid pixels hold the clamped rim direction -Z)
        and the ``(S, S)`` valid mask.

    Raises:
        TypeCheckError: ``size`` is not an int.
        ValueCheckError: ``size`` is not positive.

    Shape:
        - Output: :math:`(S, S, 3)` and :math:`(S, S)`

    Convention:
        docs/conventions.rst, "Mirror ball" and "Frames": the centre is +Z (behind the camera), the rim -Z;
        a direction is where the light arrives from.

    Examples:
        >>> d, valid = mirror_ball_directions(32)
        >>> d.shape, int(valid.sum())
        (torch.Size([32, 32, 3]), 812)
    """
    d, valid = mirror_ball_to_direction(mirror_ball_uv(size, device=device, dtype=torch.float64))
    return d.to(dtype), mirror_ball_valid(size, device=device)


# ----------------------------------------------------------------------------------------------
# exact solid angles


def _quadrant_area(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Area of ``[0, a] x [0, b]`` inside the unit disk, for ``a, b >= 0`` (float64)."""

    def g(s: torch.Tensor) -> torch.Tensor:  # integral of sqrt(1 - t^2) from 0 to s
        return 0.5 * (s * torch.sqrt((1 - s * s).clamp(min=0)) + torch.asin(s.clamp(-1, 1)))

    a1 = a.clamp(max=1.0)
    bc = b.clamp(max=1.0)
    s_star = torch.sqrt((1 - bc * bc).clamp(min=0))
    inside = a1 <= s_star
    partial = bc * s_star + g(a1) - g(s_star)
    return torch.where(inside, a1 * bc, partial)


def _signed_area(x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
    return torch.sign(x) * torch.sign(y) * _quadrant_area(x.abs(), y.abs())


def _disk_area_in_pixels(size: int) -> torch.Tensor:
    """Exact area (in uv units) of each pixel square intersected with the unit disk, ``(S, S)``."""
    edges = torch.linspace(-1.0, 1.0, size + 1, dtype=torch.float64)
    x0, x1 = edges[:-1][None, :], edges[1:][None, :]
    y1, y0 = edges.flip(0)[:-1][:, None], edges.flip(0)[1:][:, None]  # rows go top (v=1) to bottom
    return _signed_area(x1, y1) - _signed_area(x0, y1) - _signed_area(x1, y0) + _signed_area(x0, y0)


def _rim_pixels(size: int, device: torch.device | str | None = None) -> torch.Tensor:
    """``(S, S)`` mask of the valid pixels whose square crosses the unit circle (the owners of slivers)."""
    edges = torch.linspace(-1.0, 1.0, size + 1, dtype=torch.float64, device=device)
    far = torch.maximum(edges[:-1].abs(), edges[1:].abs())
    fully_inside = far[None, :].square() + far.flip(0)[:, None].square() <= 1.0
    return mirror_ball_valid(size, device=device) & ~fully_inside


def _sliver_candidates(px: torch.Tensor, size: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Rim-pixel candidates in the 5x5 window of each point and their squared distances (inf if not rim).

    The window always holds the owner: a sliver point lies within one pixel diagonal of the circle, and
    the rim pixels along the circle are at most two pixels away from it.
    """
    row = px[..., 1].round().clamp(0, size - 1).long()
    col = px[..., 0].round().clamp(0, size - 1).long()
    offs = torch.arange(-2, 3, device=px.device)
    dr, dc = torch.meshgrid(offs, offs, indexing="ij")
    rr = (row[..., None] + dr.flatten()).clamp(0, size - 1)
    cc = (col[..., None] + dc.flatten()).clamp(0, size - 1)
    dist = (cc - px[..., :1]).square() + (rr - px[..., 1:]).square()
    dist = torch.where(_rim_pixels(size, device=px.device)[rr, cc], dist, torch.full_like(dist, math.inf))
    return rr * size + cc, dist


def mirror_ball_pixel_index(uv: torch.Tensor, size: int) -> torch.Tensor:
    r"""Flat index ``row * S + col`` of the valid pixel that owns each point ``(u, v)`` of the disk.

    A point in a valid pixel's square maps to that pixel; a point in an invalid rim square (or just
    outside the disk) maps to the nearest rim pixel (a valid pixel whose square crosses the circle).
    This is the partition whose areas are :func:`mirror_ball_solid_angles`, so scattering energy through
    it conserves energy exactly. On the measure-zero lines where two rim pixels are equally near, the
    first in row-major order wins.

    Args:
        uv: ``(..., 2)`` coordinates.
        size: the side ``S``.

    Returns:
        ``(...)`` int64 indices into the flattened ``S x S`` grid, always of a valid pixel.

    Raises:
        ShapeError: ``uv``'s last dimension is not 2.
        NonFiniteError: NaN or Inf in ``uv``.

    Shape:
        - uv: :math:`(*, 2)`
        - Output: :math:`(*)`

    Convention:
        docs/conventions.rst, "Mirror ball": the rim slivers belong to the nearest valid pixel.

    Examples:
        >>> uv = torch.tensor([[0.1, 0.1], [0.95, 0.9]])  # the 2nd is in an invalid corner
        >>> mirror_ball_pixel_index(uv, 4)
        tensor([6, 7])
    """
    check_tensor(uv, "uv", ["*", "2"], finite=True)
    px = uv_to_pixel(uv.to(torch.float64), size)
    col = px[..., 0].round().clamp(0, size - 1).long()
    row = px[..., 1].round().clamp(0, size - 1).long()
    idx = row * size + col
    own_ok = mirror_ball_valid(size, device=uv.device).flatten()[idx]
    if bool(own_ok.all()):
        return idx
    bad = ~own_ok
    cand, dist = _sliver_candidates(px[bad], size)
    idx = idx.clone()
    idx[bad] = cand.gather(-1, dist.argmin(dim=-1, keepdim=True)).squeeze(-1)
    return idx


@lru_cache(maxsize=32)
def _solid_angles_f64(size: int) -> torch.Tensor:
    area = _disk_area_in_pixels(size)  # (S, S)
    valid = mirror_ball_valid(size)
    omega = torch.where(valid, area, torch.zeros_like(area)).flatten()
    slivers = (~valid & (area > 0)).nonzero()  # (K, 2) rows, cols
    if len(slivers):
        n = _RIM_SUPERSAMPLES
        sub = (torch.arange(n, dtype=torch.float64) + 0.5) / n - 0.5  # offsets in pixel units
        dr, dc = torch.meshgrid(sub, sub, indexing="ij")
        px = torch.stack(
            [slivers[:, 1, None] + dc.flatten(), slivers[:, 0, None] + dr.flatten()], dim=-1
        )  # (K, n*n, 2)
        inside = pixel_to_uv(px, size).square().sum(-1) <= 1.0
        cand, dist = _sliver_candidates(px, size)  # (K, n*n, 25)
        # each sample's share goes to its nearest rim pixel; exact ties split equally (keeps symmetry)
        ties = (dist <= dist.min(dim=-1, keepdim=True).values + 1e-9) & inside[..., None]
        weight = ties.to(torch.float64) / ties.sum(-1, keepdim=True).clamp(min=1)
        # samples inside the disk, per sliver (0 for a corner that only touches)
        per_sliver = weight.sum((1, 2))
        sliver_area = area[slivers[:, 0], slivers[:, 1]]
        scale = torch.where(per_sliver > 0, sliver_area / per_sliver.clamp(min=1.0), 0.0)
        weight = weight * scale[:, None, None]
        omega.index_add_(0, cand.flatten(), weight.flatten())
    return (4.0 * omega).reshape(size, size)


@compiler_disable
def mirror_ball_solid_angles(
    size: int, *, device: torch.device | str | None = None, dtype: torch.dtype = torch.float32
) -> torch.Tensor:
    r"""Solid angle in steradians of every pixel of an ``S x S`` mirror ball, exact at the rim.

    Args:
        size: the side ``S`` in pixels.
        device: device of the result.
        dtype: dtype of the result (computed in float64, cached per size).

    Returns:
        ``(S, S)`` tensor; invalid pixels hold 0, interior pixels ``16 / S^2``, and the sum is ``4 pi``.

    Raises:
        TypeCheckError: ``size`` is not an int.
        ValueCheckError: ``size`` is not positive.

    Shape:
        - Output: :math:`(S, S)`

    Convention:
        docs/conventions.rst, "Mirror ball": equal-area, every fully valid pixel spans ``16 / S^2`` sr, and
        the rim slivers belong to the nearest valid pixel so that the valid pixels sum to ``4 pi``.

    Examples:
        >>> omega = mirror_ball_solid_angles(32, dtype=torch.float64)
        >>> abs(omega.sum().item() - 4 * math.pi) < 1e-10
        True
        >>> omega[16, 16].item() == 1 / 64
        True
    """
    check_positive_int(size, "size")
    return _solid_angles_f64(size).to(device=device, dtype=dtype)


# ----------------------------------------------------------------------------------------------
# layout helpers between images and the light list used by relighting


def mirror_ball_to_lights(x: torch.Tensor) -> torch.Tensor:
    r"""Reshape a mirror-ball image ``(B, C, S, S)`` to the light list ``(B, S*S, C)`` (row-major pixels).

    Light ``n`` is pixel ``(n // S, n % S)``, of direction ``mirror_ball_directions(S)[0].reshape(-1, 3)[n]``.

    Args:
        x: mirror-ball images (any values, NaN included: only the layout changes).

    Returns:
        a view of ``x`` where possible, with the lights on dimension 1.

    Raises:
        ShapeError: ``x`` is not ``(B, C, S, S)``.

    Shape:
        - x: :math:`(B, C, S, S)`
        - Output: :math:`(B, S^2, C)`

    Convention:
        docs/conventions.rst, "Mirror ball": the pixel grid; the lights are its pixels, invalid ones
        included.

    Examples:
        >>> mirror_ball_to_lights(torch.zeros(2, 3, 32, 32)).shape
        torch.Size([2, 1024, 3])
    """
    check_tensor(x, "x", ["B", "C", "S", "S"], finite=False)
    return x.flatten(2).transpose(1, 2)


def lights_to_mirror_ball(lights: torch.Tensor) -> torch.Tensor:
    r"""Reshape a light list ``(B, N, C)`` with ``N = S*S`` back to a mirror-ball image ``(B, C, S, S)``.

    The inverse of :func:`mirror_ball_to_lights`.

    Args:
        lights: light lists in row-major pixel order (any values: only the layout changes).

    Returns:
        mirror-ball images of side ``S = sqrt(N)``.

    Raises:
        ShapeError: ``lights`` is not ``(B, N, C)``, or ``N`` is not a square.

    Shape:
        - lights: :math:`(B, S^2, C)`
        - Output: :math:`(B, C, S, S)`

    Convention:
        docs/conventions.rst, "Mirror ball": the pixel grid.

    Examples:
        >>> x = torch.rand(2, 3, 8, 8)
        >>> lights = mirror_ball_to_lights(x)
        >>> lights.shape, torch.equal(lights_to_mirror_ball(lights), x)
        (torch.Size([2, 64, 3]), True)
    """
    check_tensor(lights, "lights", ["B", "N", "C"], finite=False)
    s = math.isqrt(lights.shape[1])
    if s * s != lights.shape[1]:
        raise ShapeError(f"lights must have N = S*S lights, got N = {lights.shape[1]}")
    return lights.transpose(1, 2).reshape(lights.shape[0], lights.shape[2], s, s)
