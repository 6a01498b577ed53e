r"""Rigid transforms of lighting: rotation and the horizontal flip that matches a flipped photo.

Convention:
    Frame of docs/conventions.rst ("Frames": +X right, +Y up, +Z toward the camera); a direction ``d`` means
    light arriving *from* ``d``. Lighting is an ``S x S`` mirror ball (``layout="mirror_ball"``) or an
    ``H x 2H`` lat-long map (``layout="latlong"``), linear HDR, never negative.
"""

from __future__ import annotations

import torch
from torch import nn

from kornia_ilum.core.check import check_same_device, check_tensor, checks_active
from kornia_ilum.core.compiler import compiler_disable
from kornia_ilum.core.errors import ShapeError, ValueCheckError
from kornia_ilum.geometry.resample import (
    Layout,
    check_layout,
    check_lighting,
    grid_overlaps,
    grid_solid_angles,
)

__all__ = ["rotate_lighting", "flip_lighting_horizontal", "RotateLighting", "FlipLightingHorizontal"]

_PER_CALL = (8, 10)  # (k_rel = k_max, scaling rounds) of the per-call rotation tables (grid_overlaps)


def _check_rotation(rotation: torch.Tensor, batch: int | None = None) -> None:
    """``(3, 3)`` or ``(B, 3, 3)``, finite, orthonormal with determinant +1."""
    check_tensor(rotation, "rotation", ["*", "3", "3"])
    if not checks_active():
        return
    if rotation.dim() not in (2, 3) or (
        batch is not None and rotation.dim() == 3 and rotation.shape[0] != batch
    ):
        want = "(3, 3) or (B, 3, 3)" if batch is None else f"(3, 3) or ({batch}, 3, 3)"
        raise ShapeError(f"rotation must have shape {want}, got {tuple(rotation.shape)}")
    if torch.compiler.is_compiling() or rotation.is_meta:
        return
    r = rotation.detach().to(torch.float64)
    tol = max(1e-5, 10.0 * torch.finfo(rotation.dtype).eps)
    err = (r @ r.transpose(-1, -2) - torch.eye(3, dtype=torch.float64, device=r.device)).abs().amax().item()
    if err > tol:
        raise ValueCheckError(
            f"rotation must be orthonormal (R R^T = I within {tol:g}), got max error {err:.3g}"
        )
    det = torch.linalg.det(r).min().item()
    if det < 0:
        raise ValueCheckError(
            f"rotation must be a proper rotation with det +1, got det {det:.3g} (a reflection; for the "
            "mirror image of a photo use flip_lighting_horizontal)"
        )


def _splat(
    x: torch.Tensor, *, s: torch.Tensor, t: torch.Tensor, weight: torch.Tensor, n_tgt: int
) -> torch.Tensor:
    """``out[b, :, t] = sum_m weight[b, m] x[b, :, s[b, m]]`` over entries ``m`` with ``t[b, m] = t``.

    Args:
        x: ``(B, C, N)``.
        s, t, weight: ``(B, M)`` per-map tables, or ``(1, M)`` shared ones (``weight`` in the dtype of ``x``).
        n_tgt: number of target pixels ``T``.

    Returns:
        ``(B, C, T)``; differentiable in ``x`` (a gather and :func:`torch.index_add`).
    """
    b, c, n = x.shape
    s, t, weight = (z.expand(b, -1) for z in (s, t, weight))
    offs = torch.arange(b, device=x.device).unsqueeze(1)
    rows = x.transpose(1, 2).reshape(b * n, c).index_select(0, (s + n * offs).flatten())
    out = torch.zeros(b * n_tgt, c, dtype=x.dtype, device=x.device)
    out = out.index_add(0, (t + n_tgt * offs).flatten(), rows * weight.reshape(-1, 1))
    return out.reshape(b, n_tgt, c).transpose(1, 2)


@compiler_disable
def _rotation_tables(
    grid: tuple[str, int], rotation: torch.Tensor, dtype: torch.dtype, device: torch.device
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Per-rotation ``(s, t, weight)`` tables ``(B_R, M)`` for :func:`_splat`."""
    rot = rotation.detach().to(device="cpu", dtype=torch.float64).reshape(-1, 3, 3)
    om = grid_solid_angles(*grid)
    tables = [grid_overlaps(grid, grid, rotation=r, merge=False, quality=_PER_CALL) for r in rot]
    s, t, a = (torch.stack(p) for p in zip(*tables, strict=True))
    return s.to(device), t.to(device), (a / om[t]).to(device=device, dtype=dtype)


def rotate_lighting(
    lighting: torch.Tensor, rotation: torch.Tensor, layout: Layout = "mirror_ball"
) -> torch.Tensor:
    r"""Rotate lighting: light that arrived from direction ``d`` arrives from ``R d`` afterwards.

    That is ``L'(d) = L(R^T d)``. The resampling is the energy-conserving area method of
    :mod:`kornia_ilum.geometry.resample` on the same grid, with the source sub-cells rotated by ``R``
    (and the target sub-cells by ``R^T``): ``sum(L * Omega)`` per channel is conserved to float
    precision, and a sun stays a sun (its energy moves to the pixels around ``R d``, it is neither
    missed nor multiplied as it would be by point sampling). Resampling on the same grid blurs slightly
    (each pixel spreads over up to four). Measured on a 32 x 32 mirror ball over a 15-degree grid of yaws and
    pitches: a constant map stays constant to 0.09 % on average over its pixels (0.3 % for the worst
    rotation), but single pixels on the rim, which are long and thin, are off by up to 7 % (4.5 % at yaw 37,
    pitch 21 degrees); rotating by ``R`` and back returns a smooth map to 1.2 % on average (4 % in the worst
    pixel away from -Z, where the long rim pixels average over some 30 degrees).
    ``tests/geometry/test_transform.py`` holds these bounds.

    The tables are built per call on the CPU in float64 (about 0.1 M entries per 32 x 32 ball, 17 M for
    a 512 x 1024 map, so rotate mirror balls, not large maps, inside a training loop). The result is
    differentiable in ``lighting``, not in ``rotation``.

    Args:
        lighting: linear HDR lighting, non-negative.
        rotation: a proper rotation ``(3, 3)`` shared by the batch or ``(B, 3, 3)`` one per map.
        layout: ``"mirror_ball"`` or ``"latlong"``.

    Returns:
        the rotated lighting, same shape, dtype and device (mirror balls hold 0 at invalid pixels).

    Raises:
        ShapeError: wrong shapes.
        ValueCheckError: negative lighting, unknown layout, or ``rotation`` not orthonormal with det +1.
        NonFiniteError: NaN or Inf in an argument.

    Shape:
        - lighting: :math:`(B, C, S, S)` or :math:`(B, C, H, 2H)`
        - rotation: :math:`(3, 3)` or :math:`(B, 3, 3)`
        - Output: as ``lighting``

    Convention:
        Frame of docs/conventions.rst. ``R`` acts on the directions light arrives from: with ``R`` the
        rotation by +90 degrees about +Y (``R (0, 0, -1) = (-1, 0, 0)``), light from straight ahead (-Z)
        arrives from the left (-X) afterwards. Half precision is computed in float32 and cast back.

    Examples:
        >>> ball = torch.zeros(1, 1, 8, 8)
        >>> ball[0, 0, 3, 6] = 1.0
        >>> turn = torch.tensor([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # 90 deg about +Y
        >>> out = rotate_lighting(ball, turn)
        >>> from kornia_ilum.geometry import mirror_ball_solid_angles
        >>> omega = mirror_ball_solid_angles(8)
        >>> abs((out * omega).sum().item() - (ball * omega).sum().item()) < 1e-6  # energy conserved
        True
    """
    check_layout(layout)
    check_lighting(lighting, "lighting", layout)
    _check_rotation(rotation, lighting.shape[0])
    check_same_device(("lighting", lighting), ("rotation", rotation))
    if lighting.is_meta:  # a shape-only pass: the tables need the rotation's values, the shape does not
        return torch.empty_like(lighting)
    work = lighting.float() if lighting.dtype in (torch.float16, torch.bfloat16) else lighting
    grid = (layout, lighting.shape[-2])
    s, t, w = _rotation_tables(grid, rotation, work.dtype, work.device)
    out = _splat(work.flatten(2), s=s, t=t, weight=w, n_tgt=lighting.shape[-2] * lighting.shape[-1])
    return out.reshape(lighting.shape).to(lighting.dtype)


def flip_lighting_horizontal(lighting: torch.Tensor, layout: Layout = "mirror_ball") -> torch.Tensor:
    r"""The lighting of a horizontally flipped photo: ``L'(x, y, z) = L(-x, y, z)``.

    Flipping a portrait left-right mirrors the scene in the camera frame (``x -> -x``). Both layouts are
    symmetric under ``x -> -x`` (mirror ball: ``u -> -u``; lat-long: ``phi -> -phi``), so this is exactly
    a column flip, with no resampling. It is a reflection (det -1), so no rotation can do it.

    Args:
        lighting: linear HDR lighting, non-negative.
        layout: ``"mirror_ball"`` or ``"latlong"``.

    Returns:
        the flipped lighting, same shape, dtype and device.

    Raises:
        ShapeError: wrong shape for ``layout``.
        ValueCheckError: negative lighting or an unknown layout.
        NonFiniteError: NaN or Inf in ``lighting``.

    Shape:
        - lighting: :math:`(B, C, S, S)` or :math:`(B, C, H, 2H)`
        - Output: as ``lighting``

    Convention:
        Frame and grids of docs/conventions.rst.

    Examples:
        >>> env = torch.zeros(1, 1, 2, 4)
        >>> env[0, 0, 0, 0] = 1.0  # upper left: light from the left (-X)
        >>> flip_lighting_horizontal(env, "latlong")[0, 0]
        tensor([[0., 0., 0., 1.],
                [0., 0., 0., 0.]])
    """
    check_layout(layout)
    check_lighting(lighting, "lighting", layout)
    return lighting.flip(-1)


class RotateLighting(nn.Module):
    r"""Module twin of :func:`rotate_lighting`; the rotation is a (non-persistent) buffer.

    Args:
        rotation: a proper rotation ``(3, 3)`` or ``(B, 3, 3)``.
        layout: ``"mirror_ball"`` or ``"latlong"``.

    Shape:
        - Input: :math:`(B, C, S, S)` or :math:`(B, C, H, 2H)`
        - Output: the shape of the input

    Examples:
        >>> RotateLighting(torch.eye(3))(torch.rand(2, 3, 8, 8)).shape
        torch.Size([2, 3, 8, 8])
    """

    rotation: torch.Tensor

    def __init__(self, rotation: torch.Tensor, layout: Layout = "mirror_ball") -> None:
        super().__init__()
        check_layout(layout)
        _check_rotation(rotation)
        self.layout = layout
        self.register_buffer("rotation", rotation, persistent=False)

    def forward(self, lighting: torch.Tensor) -> torch.Tensor:
        return rotate_lighting(lighting, self.rotation, self.layout)

    def extra_repr(self) -> str:
        return f"layout={self.layout!r}"


class FlipLightingHorizontal(nn.Module):
    r"""Module twin of :func:`flip_lighting_horizontal`.

    Args:
        layout: ``"mirror_ball"`` or ``"latlong"``.

    Shape:
        - Input: :math:`(B, C, S, S)` or :math:`(B, C, H, 2H)`
        - Output: the shape of the input

    Examples:
        >>> FlipLightingHorizontal("latlong")(torch.rand(1, 3, 4, 8)).shape
        torch.Size([1, 3, 4, 8])
    """

    def __init__(self, layout: Layout = "mirror_ball") -> None:
        super().__init__()
        check_layout(layout)
        self.layout = layout

    def forward(self, lighting: torch.Tensor) -> torch.Tensor:
        return flip_lighting_horizontal(lighting, self.layout)

    def extra_repr(self) -> str:
        return f"layout={self.layout!r}"
