r"""Screen-space subsurface scattering of a light-stage reflectance field, linear in the lighting.

The one-pass renderer (:mod:`~kornia_ilum_lab.synth.lightstage.olat`) shades skin as a Lambertian surface:
light enters and leaves at the same point. Real skin carries light sideways under the surface, red farthest
(millimetres), blue least, which softens shadow edges and gives them a red fringe. This module approximates
that with a diffusion of the *irradiance* over the skin pixels of each OLAT image, in screen space, as in
Jimenez et al. 2009 ("Screen-space perceptual rendering of human skin", ACM TAP 6(4)) and Jimenez et al.
2015 ("Separable subsurface scattering", CGF 34(6)), with the skin diffusion profile of d'Eon & Luebke 2007
("Advanced techniques for realistic real-time skin rendering", GPU Gems 3, ch. 14).

The weights depend only on the :class:`~kornia_ilum_lab.synth.lightstage.gbuffer.GBuffer`, so the filter is one
sparse linear operator over pixels: ``subsurface_scatter(R) @ L == subsurface_scatter(R @ L)`` for any
lighting ``L``.

**Profile.** Each channel's kernel is the sum of six Gaussians that d'Eon & Luebke fit to a three-layer skin
model, with the red channel's weights (as Jimenez et al. 2015 do for all channels): variances
``(0.0064, 0.0484, 0.187, 0.567, 1.99, 7.41) mm^2``, weights ``(0.233, 0.100, 0.118, 0.113, 0.358, 0.078)``
(they sum to 1). Its RMS radius is 1.66 mm. Channel ``c`` scales every distance by
``radii_mm[c] / 1.66``, so ``radii_mm`` is each channel's RMS scattering radius. The default
``(1.66, 0.62, 0.50)`` mm is d'Eon & Luebke's red profile with Jimenez et al.'s per-channel falloff
``(1, 0.37, 0.3)``. (Jensen et al. 2001's dipole for their "skin1" measurement decays with the diffuse mean
free paths ``1 / sigma_tr = (3.67, 1.37, 0.68)`` mm, a softer look: pass those for it.)

**Geometry.** Pixels are back-projected with ``focal_px`` and ``depth`` (pinhole, docs/conventions.rst frame)
and the profile is evaluated at the 3D distance between the two surface points, so a radius in millimetres
spans ``focal_px * r / depth`` pixels, and light does not cross depth steps: across a 5 cm step the weight is
``exp(-50^2 / (2 * 7.41 * s^2))``, zero in float64. The window is truncated at 3 standard deviations of the
widest Gaussian (and at ``max_radius_px``).

**Texturing.** ``texturing="post"`` (default; Jimenez et al.'s post-scatter texturing): the diffuse value is
divided by the albedo (clamped to ``eps``) to give an irradiance, that is scattered, and the result is
multiplied by the receiving pixel's albedo, so the albedo texture stays sharp. ``"pre_post"`` (d'Eon &
Luebke): divide and multiply by ``sqrt(albedo)``, which blurs half of the texture.

**Energy.** Scatter-normalised: every source pixel hands out its skin share with weights that sum to 1 over
its receivers (each Gaussian is normalised on its own, so a Gaussian narrower than a pixel keeps its weight
in the source pixel). Hence, for every channel and light, exactly (up to rounding)
``sum_p out[p] / m[p] == sum_p diffuse[p] / m[p]`` with ``m = max(albedo, eps)`` (``sqrt`` of it for
``"pre_post"``): the total demodulated diffuse energy over the image (pixel sums, i.e. flux towards the camera
up to the albedo) is conserved; with a constant albedo, the plain pixel sum is. Near the skin's borders the
receivers are fewer, so border pixels get a little brighter while the light that would have left stays in.

**Coverage.** The field is premultiplied by ``alpha`` (as :class:`~kornia_ilum_lab.synth.lightstage.field.
ReflectanceField`), ``gbuffer.subsurface`` is the skin fraction of all of a pixel's samples, and the albedo is
the mean over the pixel's hits. Pixel ``p``'s skin share is ``f[p] = subsurface[p] / alpha[p]``: that part of
its value scatters, the rest stays; receivers are weighted by their skin area ``subsurface[p]``. Pixels
without skin are unchanged.

Measured: a single lit pixel on a flat patch at 0.5 mm per pixel spreads with RMS radii
``(1.64, 0.61, 0.49)`` mm (asked ``(1.66, 0.62, 0.50)``) and keeps ``(35, 56, 62) %`` of its light; the
conserved sum above holds to 2e-16 (relative) on a 192 x 192 synthetic head. Build and apply times are in
``benchmarks/bench_filters.py`` (far below the direct per-light reference's there).

Limits: a screen-space approximation (no light through thin parts such as ears, no scattering from surfaces
the camera does not see, chord instead of geodesic distance); one scattering profile for the whole face; the
per-pixel kernel is sampled at pixel centres (a Gaussian narrower than a pixel stays in its pixel).
"""

from __future__ import annotations

import math

import torch
from torch import nn

from kornia_ilum.core.check import check_choice
from kornia_ilum.core.errors import TypeCheckError, ValueCheckError
from kornia_ilum_lab.synth.lightstage._pixel_operator import (
    PixelOperator,
    check_field,
    check_gbuffer,
    csr,
    neighbours,
    window_offsets,
)
from kornia_ilum_lab.synth.lightstage.gbuffer import GBuffer

__all__ = [
    "SKIN_PROFILE",
    "SKIN_RADII_MM",
    "SubsurfaceScatter",
    "subsurface_operator",
    "subsurface_scatter",
]

#: d'Eon & Luebke 2007's sum-of-Gaussians skin profile (red channel): ``(variance in mm^2, weight)`` pairs.
SKIN_PROFILE: tuple[tuple[float, float], ...] = (
    (0.0064, 0.233),
    (0.0484, 0.100),
    (0.187, 0.118),
    (0.567, 0.113),
    (1.99, 0.358),
    (7.41, 0.078),
)

_PROFILE_RMS_MM = math.sqrt(sum(2.0 * v * w for v, w in SKIN_PROFILE) / sum(w for _, w in SKIN_PROFILE))

#: Default per-channel RMS scattering radii in mm: the profile's own 1.66 mm times Jimenez et al. 2015's
#: falloff ``(1, 0.37, 0.3)``.
SKIN_RADII_MM: tuple[float, float, float] = (
    round(_PROFILE_RMS_MM, 2),
    round(_PROFILE_RMS_MM * 0.37, 2),
    round(_PROFILE_RMS_MM * 0.30, 2),
)

_TEXTURING = ("post", "pre_post")
_BUILD_ENTRIES = 1 << 21  # (source, neighbour) pairs per block while building: ~50 MB of float64 each


def _check_params(
    radii_mm: object, texturing: object, eps: object, max_radius_px: object
) -> tuple[float, ...]:
    if not isinstance(radii_mm, (tuple, list)) or len(radii_mm) != 3:
        raise TypeCheckError(f"radii_mm must be a tuple of 3 floats (R, G, B), got {radii_mm!r}")
    radii = tuple(float(r) for r in radii_mm)
    if not all(math.isfinite(r) and r >= 0 for r in radii):
        raise ValueCheckError(f"radii_mm must be finite and non-negative, got {radii_mm!r}")
    check_choice(texturing, "texturing", _TEXTURING)
    if isinstance(eps, bool) or not isinstance(eps, (int, float)) or not eps > 0:
        raise ValueCheckError(f"eps must be a positive float, got {eps!r}")
    if isinstance(max_radius_px, bool) or not isinstance(max_radius_px, int) or max_radius_px < 0:
        raise ValueCheckError(f"max_radius_px must be a non-negative int, got {max_radius_px!r}")
    return radii


def _points(gbuffer: GBuffer, pixels: torch.Tensor) -> torch.Tensor:
    """``(S, 3)`` float64 camera-frame points in mm of flat pixel indices (pinhole back-projection)."""
    size = gbuffer.size
    z = gbuffer.depth.reshape(-1)[pixels].double()
    u = (pixels % size).double() + 0.5 - size / 2
    v = size / 2 - ((pixels // size).double() + 0.5)
    f = float(gbuffer.focal_px)
    return torch.stack([u * z / f, v * z / f, -z], dim=1) * 1000.0


def subsurface_operator(
    gbuffer: GBuffer,
    *,
    radii_mm: tuple[float, float, float] = SKIN_RADII_MM,
    texturing: str = "post",
    eps: float = 1e-3,
    max_radius_px: int = 16,
) -> PixelOperator:
    r"""Build the subsurface operator of :func:`subsurface_scatter` once, to apply to many fields.

    Args:
        gbuffer: the render's buffers (see :func:`subsurface_scatter`).
        radii_mm: per-channel RMS scattering radius in mm.
        texturing: ``"post"`` or ``"pre_post"``.
        eps: albedo clamp before demodulation.
        max_radius_px: cap on the kernel's window radius in pixels.

    Returns:
        A :class:`~kornia_ilum_lab.synth.lightstage._pixel_operator.PixelOperator` over the skin pixels, its
        matrices in float64.

    Examples:
        >>> g = GBuffer(torch.full((3, 4, 4), 0.5), torch.zeros(3, 4, 4), torch.ones(1, 4, 4),
        ...             torch.ones(1, 4, 4), torch.ones(1, 4, 4), focal_px=800.0)
        >>> op = subsurface_operator(g)
        >>> op.pixels.numel(), op.apply(torch.ones(3, 16, 5)).shape  # every pixel is skin here
        (16, torch.Size([3, 16, 5]))
    """
    radii = _check_params(radii_mm, texturing, eps, max_radius_px)
    size = check_gbuffer(gbuffer)
    dev = gbuffer.alpha.device
    alpha = gbuffer.alpha.reshape(-1).double()
    skin = gbuffer.subsurface.reshape(-1).double().clamp(0.0, 1.0)
    skin = torch.minimum(skin, alpha.clamp_min(0.0))
    pixels = torch.nonzero((skin > 0) & (gbuffer.depth.reshape(-1) > 0)).reshape(-1)
    n = pixels.numel()
    if n == 0:
        return PixelOperator(pixels, [[], [], []], size)
    s = skin[pixels]  # receiver weight: the skin area of the pixel
    share = (s / alpha[pixels]).clamp(0.0, 1.0)  # the part of the pixel's value that scatters
    pts = _points(gbuffer, pixels)
    z_min = float(gbuffer.depth.reshape(-1)[pixels].min()) * 1000.0
    f = float(gbuffer.focal_px)
    albedo = gbuffer.albedo.reshape(3, -1)[:, pixels].double().clamp_min(eps)
    m_all = albedo.sqrt() if texturing == "pre_post" else albedo
    sigma_max = math.sqrt(max(v for v, _ in SKIN_PROFILE))
    arange = torch.arange(n, device=dev)
    mats: list[list[torch.Tensor]] = []
    for c in range(3):
        scale = radii[c] / _PROFILE_RMS_MM
        cut_mm = 3.0 * sigma_max * scale
        radius = min(max_radius_px, int(math.ceil(cut_mm * f / z_min)))
        m = m_all[c]
        if radius == 0 or scale == 0:
            mats.append([csr(arange, arange, torch.ones(n, dtype=torch.float64, device=dev), n)])
            continue
        offsets = window_offsets(radius)
        rows, cols, vals = [arange], [arange], [1.0 - share]  # the part that does not scatter stays
        block = max(1, _BUILD_ENTRIES // offsets.shape[0])
        for a0 in range(0, n, block):  # sources in blocks: bounded memory while building
            srcs = arange[a0 : a0 + block]
            idx, valid = neighbours(size, pixels[srcs], offsets, pixels)  # (b, K): receivers of each source
            d2 = ((pts[idx] - pts[srcs, None, :]) ** 2).sum(-1)
            valid &= d2 <= cut_mm**2
            local, k = torch.nonzero(valid, as_tuple=True)  # the (source, receiver) pairs within reach
            dst = idx[local, k]
            d2 = d2[local, k]
            recv = s[dst]
            w = torch.zeros_like(d2)
            for var, weight in SKIN_PROFILE:
                g = torch.exp(-d2 / (2.0 * var * scale**2)) * recv
                z = torch.zeros(srcs.numel(), dtype=g.dtype, device=dev).index_add_(0, local, g)
                w += weight * g / z[local]  # the source pixel itself is a receiver: z > 0
            w = w / sum(wt for _, wt in SKIN_PROFILE)
            keep = w > 0
            src, dst, w = srcs[local[keep]], dst[keep], w[keep]
            rows.append(dst)
            cols.append(src)
            vals.append(w * m[dst] * share[src] / m[src])
        rows, cols, vals = torch.cat(rows), torch.cat(cols), torch.cat(vals)
        mats.append([csr(rows, cols, vals, n)])
    return PixelOperator(pixels, mats, size)


def subsurface_scatter(
    diffuse: torch.Tensor,
    gbuffer: GBuffer,
    *,
    radii_mm: tuple[float, float, float] = SKIN_RADII_MM,
    texturing: str = "post",
    eps: float = 1e-3,
    max_radius_px: int = 16,
    chunk: int = 128,
) -> torch.Tensor:
    r"""Diffuse the irradiance of every OLAT image under the skin, in screen space (see the module notes).

    Args:
        diffuse: ``(3, P, N)`` float32 or float64 diffuse reflectance field, ``P = size * size`` pixels in
            row-major order, premultiplied by ``alpha``.
        gbuffer: the render's :class:`~kornia_ilum_lab.synth.lightstage.gbuffer.GBuffer`: ``albedo``,
            ``depth`` (metres), ``alpha``, ``subsurface`` and ``focal_px`` are used.
        radii_mm: per-channel ``(R, G, B)`` RMS scattering radius in mm (red widest for skin); 0 turns a
            channel's scattering off.
        texturing: ``"post"`` (demodulate by the albedo, remodulate after) or ``"pre_post"`` (by its square
            root).
        eps: the albedo is clamped to at least ``eps`` before demodulation.
        max_radius_px: cap on the kernel's window radius in pixels (bounds time and memory).
        chunk: lights per batched sparse product (memory: two ``(S, chunk)`` blocks, S the skin pixels).

    Returns:
        The scattered diffuse field, same shape and dtype; pixels without skin are unchanged.

    Shape:
        - diffuse: :math:`(3, P, N)`, output :math:`(3, P, N)`, with :math:`P = H W` from ``gbuffer.size``.

    Convention:
        Camera frame of docs/conventions.rst; ``depth`` in metres along -Z; radii in millimetres.

    Examples:
        >>> g = GBuffer(torch.full((3, 8, 8), 0.5), torch.zeros(3, 8, 8), torch.ones(1, 8, 8),
        ...             torch.ones(1, 8, 8), torch.ones(1, 8, 8), focal_px=800.0)
        >>> d = torch.zeros(3, 64, 2)
        >>> d[:, 27, 0] = 1.0  # one lit pixel under light 0
        >>> out = subsurface_scatter(d, g)
        >>> out.shape
        torch.Size([3, 64, 2])
        >>> bool(torch.allclose(out.sum(1), d.sum(1)))  # constant albedo: the pixel sum is kept
        True
        >>> bool(out[0, 27, 0] < out[2, 27, 0])  # red leaves its pixel more than blue
        True
    """
    check_field(diffuse, gbuffer, "diffuse")
    op = subsurface_operator(
        gbuffer, radii_mm=radii_mm, texturing=texturing, eps=eps, max_radius_px=max_radius_px
    )
    return op.apply(diffuse, chunk)


class SubsurfaceScatter(nn.Module):
    r"""Module form of :func:`subsurface_scatter`: holds the hyperparameters only.

    Args:
        radii_mm: per-channel RMS scattering radius in mm.
        texturing: ``"post"`` or ``"pre_post"``.
        eps: albedo clamp before demodulation.
        max_radius_px: cap on the window radius in pixels.
        chunk: lights per batched sparse product.

    Examples:
        >>> g = GBuffer(torch.full((3, 4, 4), 0.5), torch.zeros(3, 4, 4), torch.ones(1, 4, 4),
        ...             torch.ones(1, 4, 4), torch.ones(1, 4, 4), focal_px=800.0)
        >>> SubsurfaceScatter()(torch.ones(3, 16, 5), g).shape
        torch.Size([3, 16, 5])
    """

    def __init__(
        self,
        *,
        radii_mm: tuple[float, float, float] = SKIN_RADII_MM,
        texturing: str = "post",
        eps: float = 1e-3,
        max_radius_px: int = 16,
        chunk: int = 128,
    ) -> None:
        super().__init__()
        self.radii_mm = _check_params(radii_mm, texturing, eps, max_radius_px)
        self.texturing = texturing
        self.eps = eps
        self.max_radius_px = max_radius_px
        self.chunk = chunk

    def forward(self, diffuse: torch.Tensor, gbuffer: GBuffer) -> torch.Tensor:
        return subsurface_scatter(
            diffuse,
            gbuffer,
            radii_mm=self.radii_mm,
            texturing=self.texturing,
            eps=self.eps,
            max_radius_px=self.max_radius_px,
            chunk=self.chunk,
        )

    def extra_repr(self) -> str:
        return f"radii_mm={self.radii_mm}, texturing={self.texturing!r}, eps={self.eps}"


def _subsurface_reference(
    diffuse: torch.Tensor,
    gbuffer: GBuffer,
    *,
    radii_mm: tuple[float, float, float] = SKIN_RADII_MM,
    texturing: str = "post",
    eps: float = 1e-3,
    max_radius_px: int = 16,
) -> torch.Tensor:
    """The same filter written directly: one light and one channel at a time, weights recomputed each time.

    For the tests and ``benchmarks/bench_filters.py`` only (slow): shifted whole images, no sparse operator.
    """
    radii = _check_params(radii_mm, texturing, eps, max_radius_px)
    size = check_field(diffuse, gbuffer, "diffuse")
    h = w_ = size
    f = float(gbuffer.focal_px)
    dt = torch.float64
    alpha = gbuffer.alpha[0].to(dt)
    skin = torch.minimum(gbuffer.subsurface[0].to(dt).clamp(0, 1), alpha.clamp_min(0))
    z = gbuffer.depth[0].to(dt)
    skin = torch.where(z > 0, skin, torch.zeros((), dtype=dt))
    share = torch.where(skin > 0, skin / alpha.clamp_min(1e-300), torch.zeros((), dtype=dt)).clamp(0, 1)
    jj, ii = torch.meshgrid(torch.arange(w_, dtype=dt), torch.arange(h, dtype=dt), indexing="xy")
    pts = torch.stack([(jj + 0.5 - w_ / 2) * z / f, (h / 2 - ii - 0.5) * z / f, -z]) * 1000.0  # (3, H, W)
    out = diffuse.clone()
    z_min = float(z[skin > 0].min()) * 1000.0 if bool((skin > 0).any()) else 1.0
    sigma_max = math.sqrt(max(v for v, _ in SKIN_PROFILE))
    total = sum(wt for _, wt in SKIN_PROFILE)
    for c in range(3):
        scale = radii[c] / _PROFILE_RMS_MM
        cut = 3.0 * sigma_max * scale
        r = min(max_radius_px, int(math.ceil(cut * f / z_min)))
        if r == 0 or scale == 0:
            continue
        m = gbuffer.albedo[c].to(dt).clamp_min(eps)
        m = m.sqrt() if texturing == "pre_post" else m
        pad = torch.nn.functional.pad
        skin_p = pad(skin, (r, r, r, r))
        pts_p = pad(pts, (r, r, r, r))
        offs = [(dy, dx) for dy in range(-r, r + 1) for dx in range(-r, r + 1)]
        for n in range(diffuse.shape[2]):
            e = diffuse[c, :, n].to(dt).reshape(h, w_) / m * share
            acc = torch.zeros(h + 2 * r, w_ + 2 * r, dtype=dt)
            for var, weight in SKIN_PROFILE:
                gs, norm = [], torch.zeros(h, w_, dtype=dt)
                for dy, dx in offs:
                    sl = (slice(r + dy, r + dy + h), slice(r + dx, r + dx + w_))
                    d2 = ((pts_p[(slice(None), *sl)] - pts) ** 2).sum(0)
                    g = torch.exp(-d2 / (2 * var * scale**2)) * skin_p[sl] * (d2 <= cut**2) * (skin > 0)
                    gs.append(g)
                    norm += g
                for (dy, dx), g in zip(offs, gs):
                    sl = (slice(r + dy, r + dy + h), slice(r + dx, r + dx + w_))
                    acc[sl] += weight / total * torch.where(norm > 0, g / norm, torch.zeros((), dtype=dt)) * e
            res = acc[r : r + h, r : r + w_] * m + diffuse[c, :, n].to(dt).reshape(h, w_) * (1 - share)
            res = torch.where(skin > 0, res, diffuse[c, :, n].to(dt).reshape(h, w_))
            out[c, :, n] = res.reshape(-1).to(out.dtype)
    return out
