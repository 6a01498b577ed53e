r"""The energy-keeping mirror-ball pyramid of docs/conventions.rst ("Reference spheres", "Multi-scale").

The multi-scale losses render the ``S x S`` reference spheres from lighting of size ``S``, and the lighting
at size ``S / 2`` keeps the energy of the lighting at size ``S``: ``sum(L * omega)`` per channel, with the
exact mirror-ball solid angles (:func:`~kornia_ilum.geometry.mirror_ball_solid_angles`). A coarse sphere
therefore sees all of the lighting: a small bright source lands in the coarse pixel that contains it,
whereas sampling the fine lighting at the coarse pixel centres (what a ``(16, 32)`` mirror field does)
would miss it or multiply it.

Convention:
    One halving ``S -> S / 2`` is the linear map ``L_c = sum_f a[f, c] L_f / omega_c``, where ``a[f, c]`` is
    the solid angle that fine pixel ``f`` shares with coarse pixel ``c`` under the partition of the sphere
    that defines the solid angles (:func:`~kornia_ilum.geometry.mirror_ball_pixel_index`: a pixel owns its
    square's part of the disk, and the rim slivers in invalid squares belong to the nearest valid pixel).
    So:

    - inside the rim, a coarse pixel is exactly the mean of its ``2 x 2`` fine pixels;
    - the energy of fine pixels (and slivers) under an invalid coarse pixel goes to the nearest valid
      coarse pixel;
    - ``sum_c a[f, c] = omega_f`` exactly, so ``sum(L * omega)`` is kept to float precision at every level,
      whatever the lighting.

    The overlaps ``a`` are the supersampled ones of
    :func:`~kornia_ilum.geometry.resize_mirror_ball` (``mode="area"``), with the Sinkhorn scaling run to
    convergence (1000 rounds instead of 30) so that a constant map also stays constant: to 0.03 % in the
    worst rim pixel for 32 -> 16, 1e-9 for 16 -> 8 and 8 -> 4 (whereas giving each fine pixel wholly to
    one coarse pixel, its parent or the nearest valid one, moves constants by up to 7 % at the rim).
    Smaller sizes are chained halvings, ``D_{32 -> 4} = D_{8 -> 4} D_{16 -> 8} D_{32 -> 16}``.

Implementation:
    The matrices are built once per size in float64 on the CPU, cached, and applied as one dense product
    ``(B C, S^2) @ (S^2, sum s^2)`` for all the coarse levels together: differentiable, and one matrix
    product for the whole batch instead of one resampling per level.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache

import torch
from torch import nn

from kornia_ilum.core.check import check_positive_int, check_tensor
from kornia_ilum.core.compiler import compiler_disable
from kornia_ilum.core.errors import ShapeError, ValueCheckError
from kornia_ilum.geometry.mirror_ball import mirror_ball_solid_angles
from kornia_ilum.geometry.resample import grid_overlaps

__all__ = ["PYRAMID_SIZES", "MirrorBallPyramid", "mirror_ball_downsample_matrix", "mirror_ball_pyramid"]

#: Sides of the mirror-ball pyramid (and of the reference spheres).
PYRAMID_SIZES: tuple[int, ...] = (4, 8, 16, 32, 64)
_ROUNDS = 1000  # Sinkhorn rounds for the halving tables (module docstring)
_K_REL = 16  # supersampling of the overlaps, as for the cached resampling tables


@lru_cache(maxsize=len(PYRAMID_SIZES))
def _halving_f64(size: int) -> torch.Tensor:
    """Dense ``((S/2)^2, S^2)`` float64 map of one halving ``S -> S/2`` (module docstring)."""
    s, t, a = grid_overlaps(("mirror_ball", size), ("mirror_ball", size // 2), quality=(_K_REL, _ROUNDS))
    omega = mirror_ball_solid_angles(size // 2, dtype=torch.float64).flatten()
    mat = torch.zeros((size // 2) ** 2, size * size, dtype=torch.float64)
    mat.index_put_((t, s), a / omega[t], accumulate=True)
    return mat


@lru_cache(maxsize=4 * len(PYRAMID_SIZES))
def _downsample_f64(size: int, target: int) -> torch.Tensor:
    """Dense ``(target^2, size^2)`` float64 map ``size -> target`` (chained halvings; never hand it out)."""
    if target == size:
        return torch.eye(size * size, dtype=torch.float64)
    return _halving_f64(2 * target) @ _downsample_f64(size, 2 * target)


def _check_target(size: int, target: int, name: str) -> None:
    check_positive_int(target, name, allowed=PYRAMID_SIZES)
    if target > size:
        raise ValueCheckError(
            f"{name} must not exceed the lighting's side {size} (the pyramid only goes down)"
        )


def mirror_ball_downsample_matrix(
    size: int,
    target: int,
    *,
    device: torch.device | str | None = None,
    dtype: torch.dtype = torch.float32,
) -> torch.Tensor:
    r"""The energy-keeping map ``D`` from ``S x S`` to ``S' x S'`` mirror-ball lighting: ``L' = D L``.

    Args:
        size: side ``S`` of the fine lighting, one of :data:`PYRAMID_SIZES`.
        target: side ``S' <= S`` of the coarse lighting, one of :data:`PYRAMID_SIZES`.
        device: device of the result.
        dtype: floating dtype of the result.

    Returns:
        ``(S'^2, S^2)`` matrix over row-major pixels; rows of invalid coarse pixels and columns of invalid
        fine pixels are zero. ``omega' @ D = omega`` (energy), ``D 1 = 1`` on the valid pixels to 0.03 %.

    Raises:
        TypeCheckError: ``size`` or ``target`` is not an int.
        ValueCheckError: ``size`` or ``target`` outside :data:`PYRAMID_SIZES`, or ``target > size``.

    Shape:
        - Output: :math:`(S'^2, S^2)`

    Convention:
        docs/conventions.rst, "Reference spheres" (multi-scale): each coarse pixel holds the energy of the
        fine pixels it covers over its own solid angle, and the energy under an invalid coarse pixel goes to
        the nearest valid one.

    Examples:
        >>> d = mirror_ball_downsample_matrix(32, 16, dtype=torch.float64)
        >>> from kornia_ilum.geometry import mirror_ball_solid_angles
        >>> energy = mirror_ball_solid_angles(16, dtype=torch.float64).flatten() @ d
        >>> torch.allclose(energy, mirror_ball_solid_angles(32, dtype=torch.float64).flatten())
        True
    """
    check_positive_int(size, "size", allowed=PYRAMID_SIZES)
    _check_target(size, target, "target")
    return _downsample_f64(size, target).to(device=device, dtype=dtype, copy=True)


@compiler_disable
@lru_cache(maxsize=32)
def _stacked(size: int, targets: tuple[int, ...], device: torch.device, dtype: torch.dtype) -> torch.Tensor:
    """``(S^2, sum t^2)``: the transposed maps of all ``targets`` side by side, for one product."""
    stacked = torch.cat([_downsample_f64(size, t) for t in targets]).T.contiguous()
    return stacked.to(device=device, dtype=dtype)


def _side(lighting: torch.Tensor) -> int:
    check_tensor(lighting, "lighting", ["B", "C", "S", "S"])
    s = lighting.shape[-1]
    if lighting.shape[-2] != s or s not in PYRAMID_SIZES:
        raise ShapeError(
            f"lighting must be a mirror ball (B, C, S, S) with S in {PYRAMID_SIZES}, "
            f"got {tuple(lighting.shape)}"
        )
    return s


def _check_sizes(sizes: Sequence[int], size: int) -> tuple[int, ...]:
    sizes = (sizes,) if isinstance(sizes, int) else tuple(sizes)
    if not sizes:
        raise ValueCheckError("sizes must name at least one size")
    for s in sizes:
        _check_target(size, s, "sizes")
    return sizes


def mirror_ball_pyramid(
    lighting: torch.Tensor, sizes: Sequence[int] = (4, 8, 16, 32)
) -> dict[int, torch.Tensor]:
    r"""Energy-keeping mirror-ball lighting at several sizes, as the multi-scale losses see it.

    Level ``s`` is ``D_{S -> s} L`` (:func:`mirror_ball_downsample_matrix`, module docstring): inside the
    rim the ``2 x 2`` block means, repeated; rim slivers and fine pixels under invalid coarse pixels go to
    the nearest valid coarse pixel; ``sum(L * omega)`` is the same at every level.

    Args:
        lighting: linear mirror-ball lighting ``(B, C, S, S)``, ``S`` in :data:`PYRAMID_SIZES`.
        sizes: the sides wanted, each in :data:`PYRAMID_SIZES` and at most ``S``.

    Returns:
        ``{s: (B, C, s, s)}`` in the dtype and device of ``lighting``; invalid pixels hold 0. Level ``S``
        is ``lighting`` itself (not a copy).

    Shape:
        - Input: :math:`(B, C, S, S)`
        - Output: ``{s:`` :math:`(B, C, s, s)` ``}``

    Convention:
        docs/conventions.rst, "Reference spheres", "Multi-scale"; its mirror-ball grid.

    Examples:
        >>> ball = torch.zeros(1, 3, 32, 32)
        >>> ball[0, :, 10, 12] = 64.0  # 1 W/sr over 1/64 sr
        >>> levels = mirror_ball_pyramid(ball, (4, 16))
        >>> from kornia_ilum.geometry import mirror_ball_solid_angles
        >>> [round((levels[s][0, 0] * mirror_ball_solid_angles(s)).sum().item(), 5) for s in (4, 16)]
        [1.0, 1.0]
    """
    s_l = _side(lighting)
    sizes = _check_sizes(sizes, s_l)
    coarse = tuple(sorted({s for s in sizes if s < s_l}))
    out: dict[int, torch.Tensor] = {}
    if coarse:
        b, c = lighting.shape[:2]
        flat = lighting.reshape(b * c, s_l * s_l) @ _stacked(s_l, coarse, lighting.device, lighting.dtype)
        start = 0
        for s in coarse:
            out[s] = flat[:, start : start + s * s].reshape(b, c, s, s)
            start += s * s
    return {s: (lighting if s == s_l else out[s]) for s in sizes}


class MirrorBallPyramid(nn.Module):
    r"""Module twin of :func:`mirror_ball_pyramid`.

    Args:
        sizes: the sides wanted.

    Shape:
        - Input: :math:`(B, C, S, S)`
        - Output: ``{s:`` :math:`(B, C, s, s)` ``}``

    Examples:
        >>> levels = MirrorBallPyramid((4, 8))(torch.ones(2, 3, 32, 32))
        >>> tuple(levels[4].shape), round(levels[8][0, 0, 4, 4].item(), 4)
        ((2, 3, 4, 4), 1.0)
    """

    def __init__(self, sizes: Sequence[int] = (4, 8, 16, 32)) -> None:
        super().__init__()
        self.sizes = _check_sizes(sizes, max(PYRAMID_SIZES))

    def forward(self, lighting: torch.Tensor) -> dict[int, torch.Tensor]:
        return mirror_ball_pyramid(lighting, self.sizes)

    def extra_repr(self) -> str:
        return f"sizes={self.sizes}"
