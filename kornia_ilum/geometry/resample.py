r"""Resampling lighting between the lat-long and mirror-ball grids of docs/conventions.rst.

Two methods, picked by pixel count (``mode="auto"``: area when the target has no more valid pixels
than the source, i.e. fewer pixels per steradian on average; bilinear otherwise) or by name:

``"area"``: energy-conserving area averaging
    ``L_t = sum_s a[s, t] L_s / Omega_t``, where ``a[s, t]`` is the solid angle that source pixel ``s``
    shares with target pixel ``t`` and ``Omega_t`` the target's exact solid angle
    (:func:`~kornia_ilum.geometry.mirror_ball_solid_angles`,
    :func:`~kornia_ilum.geometry.latlong_solid_angles`). The overlaps are estimated by supersampling:
    every source pixel is cut into ``k x k`` sub-cells of its solid angle (their solid angles sum to the
    pixel's exactly) and each sub-cell is scattered into the target pixel that owns its centre direction:
    for a mirror-ball target :func:`~kornia_ilum.geometry.mirror_ball_pixel_index` (the partition whose
    areas are the mirror-ball solid angles), for a lat-long target the pixel that contains it (azimuth
    wraps). Target pixels that are not much larger than the sub-cells (equal sizes, or the tiny
    pixels next to a lat-long pole) receive a noisy share this way, so the target grid is supersampled
    too, each target sub-cell taking its share from the source pixel that owns it; the two estimates
    are mixed, each trusted in proportion to the other grid's sub-cell size. Finally 30 rounds of
    Sinkhorn scaling (Sinkhorn and Knopp, "Concerning nonnegative matrices and doubly stochastic
    matrices", Pacific J. Math. 1967) make the overlaps sum to ``Omega_t`` over each target pixel (a
    constant map stays constant) and, last, exactly to ``Omega_s`` over each source pixel. Hence
    ``sum(L * Omega)`` per channel is conserved to float precision, and a small bright source (the
    0.5-degree sun of docs/conventions.rst) keeps its full energy in the target pixel that contains it:
    scaling never creates an overlap, and a source pixel inside one target pixel overlaps no other. Point
    sampling at pixel centres would miss it or multiply it.

``"bilinear"``: interpolation, for upsampling
    The source is sampled at each target pixel centre's direction with
    :func:`torch.nn.functional.grid_sample`.
    A lat-long source wraps in azimuth and continues across the poles; a mirror-ball source is first
    extended outward (each invalid pixel takes the value of its nearest valid pixel) so that the rim
    does not darken.

Supersampling factor:
    ``k = clamp(ceil(16 e_grid / e_other), 4, 16)`` sub-cells per axis for each grid, with
    ``e = sqrt(4 pi / N)`` the mean angular size of a pixel of a grid with ``N`` valid pixels, and at
    most ``2^23`` sub-cells per grid. So sub-cells are at most 1/16 of the other grid's pixels, and never
    fewer than 4 x 4 per pixel: that floor resolves the 0.5-degree sun of a 512 x 1024 lat-long map
    (0.35-degree pixels) with 0.09-degree sub-cells, about 6 across its diameter, so that a sun that
    straddles a target-pixel boundary is split by area, not all-or-nothing. Larger maps keep the same
    0.09-degree sub-cells under the budget (k = 2 for 1024 x 2048, k = 1 for 2048 x 4096). Energy
    conservation does not depend on ``k``; uniformity does. Measured, a constant map stays constant to
    0.27 % in the worst pixel for lat-long 64 x 128 -> 32 x 32 (0.25 % for 512 x 1024, mean 0.02 %),
    0.1 % / 0.7 % / 0.5 % for mirror ball 32 -> 16 / 8 / 4, 0.1 % for mirror ball 32 -> lat-long 8 x 16.

Implementation:
    The table is built once per (grids, dtype, device), in float64 on the CPU (for a 512 x 1024 map:
    8.4 M sub-cells, 0.6 M entries after merging), stored as a ``torch.sparse_csr`` matrix ``M``
    (``T x N``) with int32 indices (MKL's own; int64 ones are converted on every call) and its
    transpose for the backward pass, and cached. Applying it is one sparse matrix-vector product per map
    and channel (differentiable, batched over ``B`` and ``C``). That is faster, forward and backward, than
    the gather + :func:`torch.index_add` scatter of the same table, whose scatter serialises on write
    conflicts, and than a single CSR x dense product, which needs an ``(N, B C)`` transposed copy of the
    input and rebuilds the transpose for the backward pass (the measured times are in the docs' geometry
    page, ``benchmarks/bench_ops.py``, section resample).
    CSR products have no half-precision kernels: float16 / bfloat16 inputs are resampled in float32 and
    cast back. Tables are built and applied outside ``torch.compile`` graphs
    (:func:`torch.compiler.disable`); the input checks cost more than the product itself on large maps.

Convention:
    Frame, grids and directions of docs/conventions.rst ("Frames", "Mirror ball", "Lat-long"); a direction
    means light arriving *from* it. Lighting is linear HDR radiance, never negative. Output mirror balls hold
    0 at invalid pixels.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterator
from functools import lru_cache
from typing import Literal

import torch
import torch.nn.functional as F
from torch import nn

from kornia_ilum.core.check import check_choice, check_positive_int, check_tensor, checks_active
from kornia_ilum.core.compiler import compiler_disable
from kornia_ilum.core.errors import ShapeError
from kornia_ilum.geometry.latlong import (
    angles_to_latlong_pixel,
    direction_to_latlong,
    latlong_directions,
    latlong_solid_angles,
)
from kornia_ilum.geometry.mirror_ball import (
    direction_to_mirror_ball,
    mirror_ball_pixel_index,
    mirror_ball_solid_angles,
    mirror_ball_to_direction,
    mirror_ball_uv,
    mirror_ball_valid,
    pixel_to_uv,
    uv_to_pixel,
)

__all__ = [
    "latlong_to_mirror_ball",
    "mirror_ball_to_latlong",
    "resize_mirror_ball",
    "LatLongToMirrorBall",
    "MirrorBallToLatLong",
    "ResizeMirrorBall",
    "check_layout",
    "check_lighting",
    "grid_overlaps",
    "grid_solid_angles",
    "resample_bilinear",
]

Layout = Literal["mirror_ball", "latlong"]
Mode = Literal["auto", "area", "bilinear"]
_MODES = ("auto", "area", "bilinear")
_LAYOUTS = ("mirror_ball", "latlong")
_K_MIN = 4  # sub-cells per axis at least (module docstring: the 0.5-degree sun)
_BUDGET = 1 << 23  # at most this many sub-cells per grid (lat-long 512 x 1024 at k = 4)
#: (k_rel = k_max, scaling rounds) for the cached resampling tables
_CACHED = (16, 30)
_CHUNK = 1 << 20  # sub-cells per chunk while building tables (bounds the float64 temporaries)


# ----------------------------------------------------------------------------------------------
# grids


def _shape(layout: str, size: int) -> tuple[int, int]:
    return (size, size) if layout == "mirror_ball" else (size, 2 * size)


@lru_cache(maxsize=64)
def _num_valid(layout: str, size: int) -> int:
    return int(mirror_ball_valid(size).sum()) if layout == "mirror_ball" else 2 * size * size


@lru_cache(maxsize=64)
def grid_solid_angles(layout: str, size: int) -> torch.Tensor:
    r"""Exact solid angle of every pixel of a grid (0 at invalid mirror-ball pixels), flattened.

    The weights that :func:`grid_overlaps` sums to; cached per grid and shared: read-only.

    Args:
        layout: ``"mirror_ball"`` (an ``S x S`` ball) or ``"latlong"`` (an ``S x 2S`` map).
        size: the grid's side ``S`` (the map's height for lat-long).

    Returns:
        float64 CPU ``(N,)`` solid angles in sr, row-major
        (:func:`~kornia_ilum.geometry.mirror_ball_solid_angles`,
        :func:`~kornia_ilum.geometry.latlong_solid_angles`).

    Shape:
        - Output: :math:`(S^2,)` for a mirror ball, :math:`(2 S^2,)` for lat-long

    Convention:
        docs/conventions.rst, "Mirror ball" and "Lat-long": the grids and their solid angles (rim slivers
        included, so the valid mirror-ball pixels sum to ``4 pi``).

    Examples:
        >>> round(grid_solid_angles("latlong", 8).sum().item(), 6)  # 4 pi
        12.566371
    """
    if layout == "mirror_ball":
        return mirror_ball_solid_angles(size, dtype=torch.float64).flatten()
    return latlong_solid_angles(size, dtype=torch.float64).flatten()


def _supersampling(grid: tuple[str, int], other: tuple[str, int], k_rel: int) -> int:
    """Sub-cells per axis for the pixels of ``grid`` when its overlaps with ``other`` are estimated.

    ``clamp(ceil(k_rel e_grid / e_other), 4, k_rel)`` with ``e = sqrt(4 pi / N)`` the mean angular pixel
    size of a grid of ``N`` valid pixels, and at most ``_BUDGET`` sub-cells in all (module docstring).
    """
    n = _num_valid(*grid)
    k = max(_K_MIN, min(k_rel, math.ceil(k_rel * math.sqrt(_num_valid(*other) / n) - 1e-9)))
    return max(1, min(k, math.isqrt(_BUDGET // n)))


def _owner(layout: str, size: int, d: torch.Tensor) -> torch.Tensor:
    """Flat index of the pixel of a grid that owns each direction ``(..., 3)`` (float64)."""
    if layout == "mirror_ball":
        return mirror_ball_pixel_index(direction_to_mirror_ball(d), size)
    phi, el = direction_to_latlong(d)
    px = angles_to_latlong_pixel(phi, el, size)
    col = torch.floor(px[..., 0] + 0.5).long().remainder(2 * size)
    row = torch.floor(px[..., 1] + 0.5).long().clamp(0, size - 1)
    return row * (2 * size) + col


def _mirror_ball_subcells(size: int, k: int, rows: range) -> torch.Tensor:
    """``(u, v)`` of the sub-cell centres in the disk, sub-rows ``rows`` of an ``(S k) x (S k)`` grid."""
    c = (torch.arange(size * k, dtype=torch.float64) + 0.5) / k - 0.5  # pixel coordinates of sub-centres
    # rows shift by 1/64 of a sub-cell so that no centre lies on a diagonal, where the nearest-valid-centre
    # partition of rim slivers has ties that a 1e-16 round-off could break either way
    r = (torch.arange(rows.start, rows.stop, dtype=torch.float64) + 0.5 + 1 / 64) / k - 0.5
    rr, cc = torch.meshgrid(r, c, indexing="ij")
    uv = pixel_to_uv(torch.stack([cc, rr], -1).reshape(-1, 2), size)
    return uv[uv.square().sum(-1) <= 1.0]


def _subcells(
    layout: str, size: int, k: int
) -> Iterator[tuple[torch.Tensor, torch.Tensor, torch.Tensor, int]]:
    """Yield chunks ``(directions (M, 3), pixel index (M,), solid angle (M,), group)`` of all sub-cells.

    The sub-cells of a pixel have solid angles that sum to the pixel's exact solid angle. ``group > 0``
    means the chunk lists the pixels in increasing order, ``group`` consecutive sub-cells each.
    """
    h, w = _shape(layout, size)
    if layout == "latlong":
        # a k x k split of each pixel in (phi, el): sub-rows have exact band solid angles
        edges = math.pi / 2 - math.pi * torch.arange(h * k + 1, dtype=torch.float64) / (h * k)
        band = (torch.sin(edges[:-1]) - torch.sin(edges[1:])) * (2 * math.pi / (w * k))
        el = (0.5 * (edges[:-1] + edges[1:])).reshape(h, 1, k, 1)
        phi = (2 * math.pi * (torch.arange(w * k, dtype=torch.float64) + 0.5) / (w * k) - math.pi).reshape(
            1, w, 1, k
        )
        band = band.reshape(h, 1, k, 1)
        step = max(1, _CHUNK // (w * k * k))
        for i0 in range(0, h, step):
            rows = slice(i0, min(h, i0 + step))
            ce, se = torch.cos(el[rows]), torch.sin(el[rows])
            shape = (ce.shape[0], w, k, k)
            d = torch.stack(
                [(torch.sin(phi) * ce).expand(shape), se.expand(shape), (-torch.cos(phi) * ce).expand(shape)],
                -1,
            )
            idx = torch.arange(rows.start * w, rows.stop * w).reshape(-1, w, 1, 1).expand(shape)
            yield d.reshape(-1, 3), idx.flatten(), band[rows].expand(shape).flatten(), k * k
        return
    # mirror ball: an (S k) x (S k) grid of uv sub-cells, the ones whose centre is in the disk, each owned
    # through the partition of mirror_ball_pixel_index; equal areas, renormalised to the exact solid angles
    step = max(1, _CHUNK // (size * k))
    blocks = [range(r0, min(size * k, r0 + step)) for r0 in range(0, size * k, step)]
    owners = [mirror_ball_pixel_index(_mirror_ball_subcells(size, k, b), size) for b in blocks]
    count = torch.bincount(torch.cat(owners), minlength=size * size).to(torch.float64)
    per_cell = grid_solid_angles(layout, size) / count.clamp(min=1.0)
    for b, idx in zip(blocks, owners, strict=True):
        yield mirror_ball_to_direction(_mirror_ball_subcells(size, k, b))[0], idx, per_cell[idx], 0


# ----------------------------------------------------------------------------------------------
# overlap tables (also used by kornia_ilum.geometry.transform and kornia_ilum.render.pyramid)


def _merge(s: torch.Tensor, t: torch.Tensor, *, w: torch.Tensor, n_tgt: int, group: int = 0):
    """Sum the weights of repeated ``(s, t)`` pairs; the result is sorted by ``s * n_tgt + t``."""
    key = s * n_tgt + t
    if group > 0:  # pixels in order with `group` sub-cells each: sorting inside each pixel sorts all
        key, order = key.reshape(-1, group).sort(dim=1)
        key, w = key.flatten(), w.reshape(-1, group).gather(1, order).flatten()
        uniq, inv = torch.unique_consecutive(key, return_inverse=True)
    else:
        uniq, inv = torch.unique(key, return_inverse=True)
    return uniq // n_tgt, uniq % n_tgt, torch.zeros(uniq.numel(), dtype=w.dtype).index_add_(0, inv, w)


def grid_overlaps(
    src: tuple[str, int],
    tgt: tuple[str, int],
    *,
    rotation: torch.Tensor | None = None,
    merge: bool = True,
    quality: tuple[int, int] = _CACHED,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    r"""Estimated solid angles ``a`` shared by source pixel ``s`` (rotated by ``R``) and target pixel ``t``.

    The table behind ``mode="area"`` resampling, lighting rotation
    (:func:`~kornia_ilum.geometry.rotate_lighting`) and the mirror-ball pyramid
    (:func:`~kornia_ilum.render.mirror_ball_downsample_matrix`). Both grids are supersampled (module
    docstring): source sub-cells are pushed to the target pixel that owns ``R d``, target sub-cells pull
    from the source pixel that owns ``R^T d``, the two estimates are mixed, trusting each in proportion to
    the other grid's sub-cell size, and rounds of scaling (Sinkhorn) make the target sums ``Omega_t`` and
    (last) the source sums exactly ``Omega_s`` (:func:`grid_solid_angles`). Built on every call, in
    float64 on the CPU; the arguments are not checked.

    Args:
        src, tgt: grids ``(layout, size)``, ``layout`` ``"mirror_ball"`` or ``"latlong"``.
        rotation: ``(3, 3)`` float64 CPU rotation, or ``None`` for the identity.
        merge: merge repeated ``(s, t)`` pairs (needed for cached tables; costs a sort).
        quality: ``(k_rel, rounds)``: the supersampling's ``k_rel`` (the most sub-cells per axis, module
            docstring) and the number of scaling rounds.

    Returns:
        float64 CPU ``(s, t, a)``, one entry per overlap (per sub-cell pair without ``merge``), with
        ``sum_t a[s, t] = Omega_s``.

    Shape:
        - rotation: :math:`(3, 3)`
        - Output: :math:`(K,)` int64, :math:`(K,)` int64 (flat row-major pixel indices) and :math:`(K,)`
          float64

    Convention:
        docs/conventions.rst, "Mirror ball", "Lat-long" and "Rotation": source content seen along ``d`` lands
        along ``R d`` in the target.

    Examples:
        >>> s, t, a = grid_overlaps(("mirror_ball", 8), ("mirror_ball", 4))
        >>> per_source = torch.zeros(64, dtype=a.dtype).index_add_(0, s, a)
        >>> torch.allclose(per_source, grid_solid_angles("mirror_ball", 8))
        True
    """
    om_s, om_t = grid_solid_angles(*src), grid_solid_angles(*tgt)
    k_rel, rounds = quality
    k_s, k_t = _supersampling(src, tgt, k_rel), _supersampling(tgt, src, k_rel)
    q_s, q_t = om_s / k_s**2, om_t / k_t**2  # sub-cell sizes: the error of each estimate
    parts = []
    for d, s, w, group in _subcells(*src, k_s):
        t = _owner(*tgt, d if rotation is None else d @ rotation.T)
        w = w * (q_t[t] / (q_s[s] + q_t[t]))
        parts.append(_merge(s, t, w=w, n_tgt=om_t.numel(), group=group) if merge else (s, t, w))
    for d, t, w, _ in _subcells(*tgt, k_t):
        s = _owner(*src, d if rotation is None else d @ rotation)
        w = w * (q_s[s] / (q_s[s] + q_t[t]))
        parts.append((s, t, w))
    s, t, a = (torch.cat(p) for p in zip(*parts, strict=True))
    if merge:
        s, t, a = _merge(s, t, w=a, n_tgt=om_t.numel())
    for _ in range(rounds):
        a = a * (om_t / torch.zeros_like(om_t).index_add_(0, t, a).clamp(min=1e-300))[t]
        a = a * (om_s / torch.zeros_like(om_s).index_add_(0, s, a).clamp(min=1e-300))[s]
    return s, t, a


class _SparseLinear(torch.autograd.Function):
    """``y = M x`` row by row, with the transpose cached for the backward pass (and double backward)."""

    @staticmethod
    def forward(x: torch.Tensor, mat: torch.Tensor, mat_t: torch.Tensor) -> torch.Tensor:  # x: (R, N)
        return torch.stack([mat @ row for row in x])

    @staticmethod
    def setup_context(ctx, inputs, output) -> None:
        ctx.mats = inputs[1:]

    @staticmethod
    def backward(ctx, grad: torch.Tensor):
        mat, mat_t = ctx.mats
        return _SparseLinear.apply(grad, mat_t, mat), None, None


def _csr(rows: torch.Tensor, cols: torch.Tensor, vals: torch.Tensor, shape: tuple[int, int]) -> torch.Tensor:
    """CSR matrix from COO triplets; int32 indices (MKL's native type: int64 ones are converted per call)."""
    order = torch.argsort(rows * shape[1] + cols)
    crow = torch.zeros(shape[0] + 1, dtype=torch.int64)
    crow[1:] = torch.bincount(rows, minlength=shape[0]).cumsum(0)
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Sparse CSR tensor support is in beta")
        return torch.sparse_csr_tensor(
            crow.int(), cols[order].int(), vals[order], shape, check_invariants=False
        )


@lru_cache(maxsize=16)
def _area_operator_f64(src: tuple[str, int], tgt: tuple[str, int]) -> tuple[torch.Tensor, torch.Tensor]:
    """``M`` (``T x N``, ``M[t, s] = a[s, t] / Omega_t``) and its transpose, float64 CSR on the CPU."""
    s, t, a = grid_overlaps(src, tgt)
    om_t = grid_solid_angles(*tgt)
    vals = a / om_t[t]
    n_src, n_tgt = grid_solid_angles(*src).numel(), om_t.numel()
    return _csr(t, s, vals, (n_tgt, n_src)), _csr(s, t, vals, (n_src, n_tgt))


@lru_cache(maxsize=16)
def _area_dense(src: tuple[str, int], tgt: tuple[str, int]) -> torch.Tensor:
    """``M`` of :func:`_area_operator_f64` as a dense float64 matrix: for :func:`torch.export` (ONNX)."""
    from torch.fx.experimental.proxy_tensor import disable_proxy_modes_tracing  # lazy: export only

    # a constant of the graph, built for real: neither traced nor faked
    with disable_proxy_modes_tracing(), torch._subclasses.fake_tensor.unset_fake_temporarily():
        with torch.inference_mode():  # the cached operator is an inference tensor if built under inference_mode
            dense = _area_operator_f64(src, tgt)[0].to_dense()
        return dense.clone()  # a normal tensor again: the export may not hold an inference tensor


@compiler_disable
def _apply_sparse(x: torch.Tensor, mat: torch.Tensor, mat_t: torch.Tensor) -> torch.Tensor:
    """``(B, C, N) -> (B, C, T)`` through the CSR operator (kept out of ``torch.compile`` graphs)."""
    if x.is_meta:  # a shape-only pass: sparse kernels have no meta implementation
        return x.new_empty(*x.shape[:2], mat.shape[0])
    return _SparseLinear.apply(x.reshape(-1, x.shape[-1]), mat, mat_t).reshape(*x.shape[:2], -1)


# ----------------------------------------------------------------------------------------------
# bilinear


@lru_cache(maxsize=32)
def _nearest_valid_f64(size: int) -> torch.Tensor:
    """For every pixel of an ``S x S`` mirror ball, the flat index of the nearest valid pixel."""
    valid = mirror_ball_valid(size).flatten()
    rr, cc = torch.meshgrid(torch.arange(size), torch.arange(size), indexing="ij")
    pos = torch.stack([rr.flatten(), cc.flatten()], -1).to(torch.float64)
    vidx = valid.nonzero().squeeze(1)
    dist = torch.cdist(pos, pos[vidx])
    return vidx[dist.argmin(dim=1)]


@lru_cache(maxsize=16)
def _bilinear_grid_f64(src: tuple[str, int], tgt: tuple[str, int]) -> torch.Tensor:
    """``grid_sample`` grid ``(1, H_t, W_t, 2)`` (align_corners=True) into the *padded* source."""
    (sl, ss), (tl, ts) = src, tgt
    if tl == "mirror_ball":
        uv = mirror_ball_uv(ts, dtype=torch.float64)
        d = mirror_ball_to_direction(uv)[0]
    else:
        uv, d = None, latlong_directions(ts, dtype=torch.float64)
    if sl == "mirror_ball":
        px = uv_to_pixel(uv if uv is not None else direction_to_mirror_ball(d), ss)
        h, w = ss, ss
    else:
        # lat-long sources are padded by one pixel on every side (azimuth wrap, across the poles)
        phi, el = direction_to_latlong(d)
        px = angles_to_latlong_pixel(phi, el, ss) + 1.0
        h, w = ss + 2, 2 * ss + 2
    gx = 2.0 * px[..., 0] / max(w - 1, 1) - 1.0
    gy = 2.0 * px[..., 1] / max(h - 1, 1) - 1.0
    return torch.stack([gx, gy], -1).unsqueeze(0)


def resample_bilinear(
    x: torch.Tensor, src: tuple[str, int], grid: torch.Tensor, nearest: torch.Tensor | None = None
) -> torch.Tensor:
    r"""Bilinear lookup of lighting at ``grid_sample`` coordinates into its padded grid (no checks).

    The sampling step of ``mode="bilinear"``, for callers that compute their own grid of directions once and
    look up many maps (a camera's rays). A lat-long source is padded by one pixel on every side: it wraps
    in azimuth, and the row beyond a pole is the same row half a turn on. A mirror-ball source is first
    extended outward: each pixel takes the value of pixel ``nearest`` (its nearest valid pixel), so that the
    rim does not darken.

    Args:
        x: lighting ``(B, C, H, W)`` on grid ``src``.
        src: the source grid ``(layout, size)``.
        grid: ``(1, H_t, W_t, 2)`` (or ``(B, ...)``) normalised coordinates, ``align_corners=True``, into
            the padded source: ``(H + 2) x (W + 2)`` for lat-long, ``H x W`` for a mirror ball.
        nearest: for a mirror-ball source, ``(H W,)`` flat index of each pixel's nearest valid pixel;
            ``None`` for lat-long.

    Returns:
        ``(B, C, H_t, W_t)`` samples in the dtype of ``x``.

    Shape:
        - x: :math:`(B, C, H, W)`
        - grid: :math:`(1, H_t, W_t, 2)` or :math:`(B, H_t, W_t, 2)`
        - nearest: :math:`(H W,)`
        - Output: :math:`(B, C, H_t, W_t)`

    Convention:
        docs/conventions.rst, "Lat-long" and "Mirror ball": the source grids; the lat-long padding follows
        its wrap in azimuth and across the poles.

    Examples:
        >>> grid = torch.zeros(1, 1, 1, 2)  # the centre of the padded 4 x 8 map
        >>> resample_bilinear(torch.ones(1, 3, 2, 4), ("latlong", 2), grid).flatten()
        tensor([1., 1., 1.])
    """
    if src[0] == "mirror_ball":
        xp = x.flatten(2).index_select(2, nearest).reshape(x.shape)
    else:
        w = x.shape[-1]
        top = x[..., :1, :].roll(w // 2, dims=-1)  # the row beyond a pole is the same row, half a turn on
        bottom = x[..., -1:, :].roll(w // 2, dims=-1)
        xp = torch.cat([top, x, bottom], dim=-2)
        xp = torch.cat([xp[..., -1:], xp, xp[..., :1]], dim=-1)
    grid = grid.expand(x.shape[0], -1, -1, -1)
    return F.grid_sample(xp, grid, mode="bilinear", padding_mode="border", align_corners=True)


# ----------------------------------------------------------------------------------------------
# dispatch


def check_layout(layout: str) -> None:
    """Require ``layout`` to be ``"mirror_ball"`` or ``"latlong"``.

    Args:
        layout: the value to check.

    Returns:
        ``None``; it raises on any other value.

    Raises:
        ValueCheckError: any other value; the message lists both.

    Examples:
        >>> check_layout("latlong")
    """
    check_choice(layout, "layout", _LAYOUTS)


def _check_mode(mode: str) -> None:
    check_choice(mode, "mode", _MODES)


def check_lighting(x: torch.Tensor, name: str, layout: str) -> None:
    """Check lighting on a grid: ``(B, C, S, S)`` or ``(B, C, H, 2H)``, floating, finite, non-negative.

    Args:
        x: the value to check.
        name: the argument's name, used in the messages.
        layout: ``"mirror_ball"`` or ``"latlong"`` (checked by the caller, :func:`check_layout`).

    Returns:
        ``None``; it raises on a bad argument (nothing is checked when :func:`checks_active` is false).

    Raises:
        ShapeError: a wrong shape for ``layout``.
        TypeCheckError: no floating-point tensor.
        NonFiniteError: NaN or Inf.
        ValueCheckError: a negative value.

    Shape:
        - x: :math:`(B, C, S, S)` for a mirror ball, :math:`(B, C, H, 2H)` for lat-long

    Convention:
        docs/conventions.rst, "Images": lighting is linear HDR, never negative.

    Examples:
        >>> check_lighting(torch.ones(1, 3, 4, 8), "env", "latlong")
    """
    expected = ["B", "C", "S", "S"] if layout == "mirror_ball" else ["B", "C", "H", "2H"]
    check_tensor(x, name, expected, nonnegative=True)
    if not checks_active():
        return
    h, w = x.shape[-2:]
    if (layout == "mirror_ball" and h != w) or (layout == "latlong" and w != 2 * h):
        raise ShapeError(f"{name} must have shape ({', '.join(expected)}), got {tuple(x.shape)}")


_CONSTANTS: dict[tuple, tuple] = {}


@compiler_disable
def _constants(
    src: tuple[str, int], tgt: tuple[str, int], *, mode: str, dtype: torch.dtype, device: torch.device
):
    """``(mode, tensors, target mask)`` for a resampling, cached per (grids, mode, dtype, device).

    ``mode`` comes back resolved (``"auto"`` picks by valid-pixel count); ``tensors`` is the CSR pair
    for ``"area"`` and ``(grid, nearest valid pixel)`` for ``"bilinear"``.
    """
    key = (src, tgt, mode, dtype, device)
    if key not in _CONSTANTS:
        if mode == "auto":
            mode = "area" if _num_valid(*tgt) <= _num_valid(*src) else "bilinear"
        # copies made outside inference mode: constants first built under torch.inference_mode() would be
        # inference tensors, which a later call with autograd cannot save for backward
        with torch.inference_mode(False):
            if src == tgt:
                tensors: tuple = ()
            elif mode == "area":
                tensors = tuple(m.to(device=device, dtype=dtype, copy=True) for m in _area_operator_f64(src, tgt))
            else:
                nearest = _nearest_valid_f64(src[1]).to(device, copy=True) if src[0] == "mirror_ball" else None
                tensors = (_bilinear_grid_f64(src, tgt).to(device=device, dtype=dtype, copy=True), nearest)
            mask = (mirror_ball_valid(tgt[1], device=device).to(dtype, copy=True) if tgt[0] == "mirror_ball"
                    else None)
        if len(_CONSTANTS) >= 64:
            _CONSTANTS.pop(next(iter(_CONSTANTS)))
        _CONSTANTS[key] = (mode, tensors, mask)
    return _CONSTANTS[key]


def _resample(x: torch.Tensor, src: tuple[str, int], tgt: tuple[str, int], mode: str) -> torch.Tensor:
    """Resample checked lighting ``x`` from grid ``src`` to grid ``tgt`` (half dtypes run in float32)."""
    work = x.float() if x.dtype in (torch.float16, torch.bfloat16) else x
    mode, tensors, mask = _constants(src, tgt, mode=mode, dtype=work.dtype, device=work.device)
    if src == tgt:
        out = work
    elif mode == "area" and torch.compiler.is_exporting():  # CSR has no export path: the same table, dense
        out = (work.flatten(2) @ _area_dense(src, tgt).to(work).T).reshape(*x.shape[:2], *_shape(*tgt))
    elif mode == "area":
        out = _apply_sparse(work.flatten(2), *tensors).reshape(*x.shape[:2], *_shape(*tgt))
    else:
        out = resample_bilinear(work, src, *tensors)
    if mask is not None:
        out = out * mask
    return out.to(x.dtype)


def latlong_to_mirror_ball(env: torch.Tensor, size: int = 32, mode: Mode = "auto") -> torch.Tensor:
    r"""Resample a lat-long environment map to an ``S x S`` mirror ball.

    Args:
        env: linear HDR lat-long map, non-negative.
        size: the mirror ball's side ``S``.
        mode: ``"area"`` (energy-conserving area averaging), ``"bilinear"``, or ``"auto"``: area when the
            mirror ball has no more valid pixels than the map (downsampling), bilinear otherwise.

    Returns:
        the mirror ball, 0 at invalid pixels, in the dtype and on the device of ``env``.

    Raises:
        ShapeError: ``env`` is not ``(B, C, H, 2H)``.
        ValueCheckError: negative lighting, or an unknown ``mode``.
        NonFiniteError: ``env`` holds NaN or Inf.

    Shape:
        - Input: :math:`(B, C, H, 2H)`
        - Output: :math:`(B, C, S, S)`

    Convention:
        docs/conventions.rst: ``d = (sin(phi) cos(el), sin(el), -cos(phi) cos(el))`` for the map, the Lambert
        equal-area ball for the output (centre +Z, rim -Z). In ``"area"`` mode
        ``sum(L * Omega)`` per channel is conserved to float precision (module docstring). Half
        precision is computed in float32 and cast back.

    Examples:
        >>> env = torch.ones(1, 3, 64, 128)
        >>> ball = latlong_to_mirror_ball(env, 32)
        >>> ball.shape
        torch.Size([1, 3, 32, 32])
        >>> omega = mirror_ball_solid_angles(32)
        >>> round((ball[0, 0] * omega).sum().item(), 4)  # 4 pi, conserved
        12.5664
    """
    check_lighting(env, "env", "latlong")
    check_positive_int(size, "size")
    _check_mode(mode)
    return _resample(env, ("latlong", env.shape[-2]), ("mirror_ball", size), mode)


def mirror_ball_to_latlong(mirror_ball: torch.Tensor, height: int, mode: Mode = "auto") -> torch.Tensor:
    r"""Resample an ``S x S`` mirror ball to an ``H x 2H`` lat-long map.

    Args:
        mirror_ball: linear HDR mirror ball, non-negative (invalid pixels are ignored).
        height: the map's height ``H``; its width is ``2H``.
        mode: ``"area"``, ``"bilinear"`` or ``"auto"`` (area when the map has no more pixels than the
            ball has valid ones, bilinear otherwise). See :func:`latlong_to_mirror_ball`.

    Returns:
        the lat-long map in the dtype and on the device of ``mirror_ball``.

    Shape:
        - Input: :math:`(B, C, S, S)`
        - Output: :math:`(B, C, H, 2H)`

    Convention:
        Grids of docs/conventions.rst. Bilinear mode extends the valid pixels outward (nearest valid pixel)
        before interpolating, so the rim (-Z) does not darken.

    Examples:
        >>> ball = latlong_to_mirror_ball(torch.ones(1, 3, 64, 128), 32)
        >>> env = mirror_ball_to_latlong(ball, 64)
        >>> env.shape, round(env.min().item(), 2), round(env.max().item(), 2)
        (torch.Size([1, 3, 64, 128]), 1.0, 1.0)
    """
    check_lighting(mirror_ball, "mirror_ball", "mirror_ball")
    check_positive_int(height, "height")
    _check_mode(mode)
    return _resample(mirror_ball, ("mirror_ball", mirror_ball.shape[-1]), ("latlong", height), mode)


def resize_mirror_ball(mirror_ball: torch.Tensor, size: int, mode: Mode = "auto") -> torch.Tensor:
    r"""Resample an ``S x S`` mirror ball to ``S' x S'``.

    Used for the multi-scale losses (32 -> 16, 8, 4). Downsampling conserves ``sum(L * Omega)``.

    Args:
        mirror_ball: linear HDR mirror ball, non-negative.
        size: the new side ``S'``.
        mode: ``"area"``, ``"bilinear"`` or ``"auto"`` (area when ``S' <= S``).

    Returns:
        the resized mirror ball, 0 at invalid pixels.

    Shape:
        - Input: :math:`(B, C, S, S)`
        - Output: :math:`(B, C, S', S')`

    Convention:
        Mirror-ball grid of docs/conventions.rst; see :func:`latlong_to_mirror_ball` for the modes.

    Examples:
        >>> ball = torch.zeros(1, 1, 32, 32)
        >>> ball[0, 0, 10, 12] = 64.0  # 1 W/sr over 1/64 sr
        >>> small = resize_mirror_ball(ball, 8)
        >>> round((small * mirror_ball_solid_angles(8)).sum().item(), 5)
        1.0
    """
    check_lighting(mirror_ball, "mirror_ball", "mirror_ball")
    check_positive_int(size, "size")
    _check_mode(mode)
    return _resample(mirror_ball, ("mirror_ball", mirror_ball.shape[-1]), ("mirror_ball", size), mode)


class LatLongToMirrorBall(nn.Module):
    r"""Module twin of :func:`latlong_to_mirror_ball`.

    Args:
        size: the mirror ball's side ``S``.
        mode: ``"auto"``, ``"area"`` or ``"bilinear"``.

    Shape:
        - Input: :math:`(B, C, H, 2H)`
        - Output: :math:`(B, C, S, S)`

    Examples:
        >>> LatLongToMirrorBall(16)(torch.rand(2, 3, 32, 64)).shape
        torch.Size([2, 3, 16, 16])
    """

    def __init__(self, size: int = 32, mode: Mode = "auto") -> None:
        super().__init__()
        check_positive_int(size, "size")
        _check_mode(mode)
        self.size, self.mode = size, mode

    def forward(self, env: torch.Tensor) -> torch.Tensor:
        return latlong_to_mirror_ball(env, self.size, self.mode)

    def extra_repr(self) -> str:
        return f"size={self.size}, mode={self.mode!r}"


class MirrorBallToLatLong(nn.Module):
    r"""Module twin of :func:`mirror_ball_to_latlong`.

    Args:
        height: the map's height ``H``.
        mode: ``"auto"``, ``"area"`` or ``"bilinear"``.

    Shape:
        - Input: :math:`(B, C, S, S)`
        - Output: :math:`(B, C, H, 2H)`

    Examples:
        >>> MirrorBallToLatLong(16)(torch.rand(2, 3, 32, 32)).shape
        torch.Size([2, 3, 16, 32])
    """

    def __init__(self, height: int, mode: Mode = "auto") -> None:
        super().__init__()
        check_positive_int(height, "height")
        _check_mode(mode)
        self.height, self.mode = height, mode

    def forward(self, mirror_ball: torch.Tensor) -> torch.Tensor:
        return mirror_ball_to_latlong(mirror_ball, self.height, self.mode)

    def extra_repr(self) -> str:
        return f"height={self.height}, mode={self.mode!r}"


class ResizeMirrorBall(nn.Module):
    r"""Module twin of :func:`resize_mirror_ball`.

    Args:
        size: the new side ``S'``.
        mode: ``"auto"``, ``"area"`` or ``"bilinear"``.

    Shape:
        - Input: :math:`(B, C, S, S)`
        - Output: :math:`(B, C, S', S')`

    Examples:
        >>> ResizeMirrorBall(8)(torch.rand(2, 3, 32, 32)).shape
        torch.Size([2, 3, 8, 8])
    """

    def __init__(self, size: int, mode: Mode = "auto") -> None:
        super().__init__()
        check_positive_int(size, "size")
        _check_mode(mode)
        self.size, self.mode = size, mode

    def forward(self, mirror_ball: torch.Tensor) -> torch.Tensor:
        return resize_mirror_ball(mirror_ball, self.size, self.mode)

    def extra_repr(self) -> str:
        return f"size={self.size}, mode={self.mode!r}"
