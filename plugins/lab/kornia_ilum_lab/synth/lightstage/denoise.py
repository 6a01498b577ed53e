r"""A cross-bilateral denoiser of light-stage reflectance fields, linear in the lighting.

The one-pass Monte-Carlo renderer (:mod:`~kornia_ilum_lab.synth.lightstage.olat`) leaves per-pixel noise in
every OLAT image. This filter averages each pixel with its neighbours, weighted by how alike their geometry
buffers are: a joint (cross) bilateral filter (Eisemann & Durand 2004, Petschnigg et al. 2004) guided by the
albedo, the normal and the relative depth, as edge-avoiding a-trous filters guide theirs (Dammertz et al.
2010, "Edge-avoiding A-Trous wavelet transform for fast global illumination filtering"; Schied et al. 2017,
SVGF). Since the weights come only from the :class:`~kornia_ilum_lab.synth.lightstage.gbuffer.GBuffer`, never
from the radiance, the filter is one sparse linear operator over pixels:
``denoise_field(R) @ L == denoise_field(R @ L)`` for every lighting ``L``.

**Weights.** For an output pixel ``p`` and a neighbour ``q`` in a ``(2 radius + 1)^2`` window (taps ``2^i``
pixels apart in a-trous iteration ``i``):
``w = alpha_q * exp(-|o|^2 / (2 sigma_spatial^2)) * exp(-|a_p - a_q|^2 / (2 sigma_albedo^2))
* exp(-|n_p - n_q|^2 / (2 sigma_normal^2)) * exp(-((z_p - z_q) / z_p)^2 / (2 sigma_depth^2))``, with ``o``
the tap offset in taps, ``a`` the albedo, ``n`` the renormalised normal and ``z`` the depth; only covered
pixels (``alpha > 0``) take part, and the weights of each output pixel are normalised to sum to 1 (gather
normalisation), so a constant stays constant.

**Demodulation.** The field is premultiplied by ``alpha`` (as :class:`~kornia_ilum_lab.synth.lightstage.field.
ReflectanceField`) and the albedo is the mean over the pixel's hits: each value is divided by
``m = max(albedo * alpha, eps)`` before filtering and multiplied by the output pixel's ``m`` after, so the
filter averages irradiance and the albedo texture (and the matte's edge) stay sharp. The specular part of a
field is not modulated by the albedo; ``demodulate=False`` divides by ``max(alpha, eps)`` only. Being
linear, ``denoise(d + s) == denoise(d) + denoise(s)`` for one operator, so a caller can filter the diffuse
and specular fields with ``demodulate=True`` and ``False`` and add them.

Measured with the defaults (radius 2, sigmas 1.5 taps, 0.1, 0.2, 0.02): the variance of white noise on a
flat region drops 20x (100x with 2 a-trous iterations, 400x with 3); across a 45-degree crease a pixel takes
under 0.3 % of its value from the other side, across a 5 cm step at 0.5 m and an albedo edge 0.5 | 0.1 under
0.01 %; a textured albedo under a constant irradiance is returned exactly. Times are in
``benchmarks/bench_filters.py`` (about a second for 192 x 192 x 812 on one thread).

Limits: it trades noise for blur within each region of alike buffers (radiance detail finer than the
window, such as a sharp shadow edge on a flat cheek, is blurred: the buffers do not know about shadows);
the weights do not adapt to the noise level (no variance estimate, which would make it depend on the
radiance and break linearity); background pixels (``alpha == 0``) are returned unchanged.
"""

from __future__ import annotations

import math

import torch
from torch import nn

from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum_lab.synth.lightstage._pixel_operator import (
    PixelOperator,
    check_field,
    check_gbuffer,
    csr,
    neighbours,
    window_offsets,
)
from kornia_ilum_lab.synth.lightstage.gbuffer import GBuffer

__all__ = ["DenoiseField", "denoise_field", "denoise_operator"]

_BUILD_ENTRIES = 1 << 21


def _check_params(
    radius: object, iterations: object, sigmas: dict[str, object], eps: object
) -> None:
    for name, value in (("radius", radius), ("iterations", iterations)):
        if isinstance(value, bool) or not isinstance(value, int) or value < (0 if name == "radius" else 1):
            raise ValueCheckError(f"{name} must be an int >= {0 if name == 'radius' else 1}, got {value!r}")
    for name, value in sigmas.items():
        ok = not isinstance(value, bool) and isinstance(value, (int, float))
        if not (ok and value > 0 and math.isfinite(value)):
            raise ValueCheckError(f"{name} must be a positive finite float, got {value!r}")
    if isinstance(eps, bool) or not isinstance(eps, (int, float)) or not eps > 0:
        raise ValueCheckError(f"eps must be a positive float, got {eps!r}")


def denoise_operator(
    gbuffer: GBuffer,
    *,
    radius: int = 2,
    sigma_spatial: float = 1.5,
    sigma_albedo: float = 0.1,
    sigma_normal: float = 0.2,
    sigma_depth: float = 0.02,
    iterations: int = 1,
    demodulate: bool = True,
    eps: float = 1e-3,
) -> PixelOperator:
    r"""Build the operator of :func:`denoise_field` once, to apply to many fields (same arguments).

    Args:
        gbuffer: the render's :class:`~kornia_ilum_lab.synth.lightstage.gbuffer.GBuffer`.
        radius: window radius in taps (0: an operator that changes nothing).
        sigma_spatial: spatial standard deviation, in taps.
        sigma_albedo: albedo difference at one standard deviation.
        sigma_normal: normal difference at one standard deviation.
        sigma_depth: relative depth difference at one standard deviation.
        iterations: a-trous iterations.
        demodulate: divide by the albedo before filtering and multiply after.
        eps: the lower clamp of the demodulation factor.

    Returns:
        A :class:`~kornia_ilum_lab.synth.lightstage._pixel_operator.PixelOperator` over the covered pixels
        (``alpha > 0``), one matrix per iteration and channel, in float64; ``op.apply(field)`` is
        :func:`denoise_field`.

    Examples:
        >>> g = GBuffer(torch.full((3, 4, 4), 0.5), torch.zeros(3, 4, 4), torch.ones(1, 4, 4),
        ...             torch.ones(1, 4, 4), torch.zeros(1, 4, 4), focal_px=800.0)
        >>> op = denoise_operator(g, radius=1)
        >>> field = torch.rand(3, 16, 5, generator=torch.Generator().manual_seed(0))
        >>> torch.equal(op.apply(field), denoise_field(field, g, radius=1))
        True
    """
    _check_params(
        radius,
        iterations,
        {"sigma_spatial": sigma_spatial, "sigma_albedo": sigma_albedo, "sigma_normal": sigma_normal,
         "sigma_depth": sigma_depth},
        eps,
    )
    size = check_gbuffer(gbuffer)
    dev = gbuffer.alpha.device
    alpha = gbuffer.alpha.reshape(-1).double()
    pixels = torch.nonzero(alpha > 0).reshape(-1)
    n = pixels.numel()
    if n == 0 or radius == 0:
        return PixelOperator(pixels[:0], [[], [], []], size)
    al = alpha[pixels]
    albedo = gbuffer.albedo.reshape(3, -1)[:, pixels].double().T  # (S, 3)
    normal = gbuffer.normal.reshape(3, -1)[:, pixels].double().T
    normal = normal / normal.norm(dim=1, keepdim=True).clamp_min(1e-12)
    depth = gbuffer.depth.reshape(-1)[pixels].double()
    mod = (albedo.T * al if demodulate else al.expand(3, n)).clamp_min(eps)  # (3, S)
    arange = torch.arange(n, device=dev)
    steps: list[tuple[torch.Tensor, torch.Tensor, torch.Tensor]] = []
    for it in range(iterations):
        offsets = window_offsets(radius, 2**it)
        spatial = torch.exp(-(window_offsets(radius).double() ** 2).sum(1) / (2.0 * sigma_spatial**2)).to(dev)
        rows, cols, vals = [], [], []
        block = max(1, _BUILD_ENTRIES // offsets.shape[0])
        for a0 in range(0, n, block):
            outs = arange[a0 : a0 + block]
            idx, valid = neighbours(size, pixels[outs], offsets, pixels)  # (b, K) sources of each output
            lw = (
                -((albedo[idx] - albedo[outs, None]) ** 2).sum(-1) / (2.0 * sigma_albedo**2)
                - ((normal[idx] - normal[outs, None]) ** 2).sum(-1) / (2.0 * sigma_normal**2)
                - ((depth[idx] - depth[outs, None]) / depth[outs, None].clamp_min(1e-6)) ** 2
                / (2.0 * sigma_depth**2)
            )
            zero = torch.zeros((), dtype=lw.dtype, device=dev)
            w = torch.where(valid, torch.exp(lw) * spatial * al[idx], zero)
            w = w / w.sum(1, keepdim=True)  # the centre tap is valid with weight alpha_p > 0
            keep = w > 0
            rows.append(outs[:, None].expand_as(idx)[keep])
            cols.append(idx[keep])
            vals.append(w[keep])
        steps.append((torch.cat(rows), torch.cat(cols), torch.cat(vals)))
    mats = [
        [csr(r, c, v * mod[ch][r] / mod[ch][c], n) for r, c, v in steps] for ch in range(3)
    ]
    return PixelOperator(pixels, mats, size)


def denoise_field(
    field: torch.Tensor,
    gbuffer: GBuffer,
    *,
    radius: int = 2,
    sigma_spatial: float = 1.5,
    sigma_albedo: float = 0.1,
    sigma_normal: float = 0.2,
    sigma_depth: float = 0.02,
    iterations: int = 1,
    demodulate: bool = True,
    eps: float = 1e-3,
    chunk: int = 128,
) -> torch.Tensor:
    r"""Cross-bilateral filter of every OLAT image of a field, guided by the G-buffer (see the module notes).

    Args:
        field: ``(3, P, N)`` float32 or float64 reflectance field, ``P = size * size`` pixels in row-major
            order, premultiplied by ``alpha``.
        gbuffer: the render's :class:`~kornia_ilum_lab.synth.lightstage.gbuffer.GBuffer` (``albedo``,
            ``normal``, ``depth``, ``alpha``).
        radius: window radius in taps (``(2 radius + 1)^2`` taps; 0 returns the field unchanged).
        sigma_spatial: spatial standard deviation, in taps.
        sigma_albedo: albedo difference (RGB, Euclidean) at one standard deviation.
        sigma_normal: normal difference (Euclidean, unit normals: 0.2 is about 11.5 degrees).
        sigma_depth: depth difference relative to the output pixel's depth.
        iterations: a-trous iterations; iteration ``i`` spaces its taps ``2^i`` pixels apart.
        demodulate: divide by the albedo before filtering and multiply after (always by ``alpha``).
        eps: the demodulation factor is clamped to at least ``eps``.
        chunk: lights per batched sparse product.

    Returns:
        The filtered field, same shape and dtype; background pixels (``alpha == 0``) unchanged.

    Shape:
        - field: :math:`(3, P, N)`, output :math:`(3, P, N)`, with :math:`P = H W` from ``gbuffer.size``.

    Convention:
        Camera frame of docs/conventions.rst for the G-buffer's normals (+Z toward the camera); ``depth`` in
        metres. The filter is linear in the field (its weights come from the G-buffer only).

    Examples:
        >>> normal = torch.zeros(3, 8, 8)
        >>> normal[2] = 1.0
        >>> g = GBuffer(torch.full((3, 8, 8), 0.5), normal, torch.ones(1, 8, 8), torch.ones(1, 8, 8),
        ...             torch.zeros(1, 8, 8), focal_px=800.0)
        >>> noisy = 0.5 + 0.1 * torch.randn(3, 64, 4, generator=torch.Generator().manual_seed(0))
        >>> out = denoise_field(noisy, g)
        >>> bool(out.std() < noisy.std() / 2)
        True
    """
    check_field(field, gbuffer, "field")
    op = denoise_operator(
        gbuffer,
        radius=radius,
        sigma_spatial=sigma_spatial,
        sigma_albedo=sigma_albedo,
        sigma_normal=sigma_normal,
        sigma_depth=sigma_depth,
        iterations=iterations,
        demodulate=demodulate,
        eps=eps,
    )
    return op.apply(field, chunk)


class DenoiseField(nn.Module):
    r"""Module form of :func:`denoise_field`: holds the hyperparameters only (same meaning).

    Examples:
        >>> g = GBuffer(torch.full((3, 4, 4), 0.5), torch.zeros(3, 4, 4), torch.ones(1, 4, 4),
        ...             torch.ones(1, 4, 4), torch.zeros(1, 4, 4), focal_px=800.0)
        >>> DenoiseField(radius=1)(torch.ones(3, 16, 5), g).shape
        torch.Size([3, 16, 5])
    """

    def __init__(
        self,
        *,
        radius: int = 2,
        sigma_spatial: float = 1.5,
        sigma_albedo: float = 0.1,
        sigma_normal: float = 0.2,
        sigma_depth: float = 0.02,
        iterations: int = 1,
        demodulate: bool = True,
        eps: float = 1e-3,
        chunk: int = 128,
    ) -> None:
        super().__init__()
        _check_params(
            radius,
            iterations,
            {"sigma_spatial": sigma_spatial, "sigma_albedo": sigma_albedo, "sigma_normal": sigma_normal,
             "sigma_depth": sigma_depth},
            eps,
        )
        self.radius = radius
        self.sigma_spatial = sigma_spatial
        self.sigma_albedo = sigma_albedo
        self.sigma_normal = sigma_normal
        self.sigma_depth = sigma_depth
        self.iterations = iterations
        self.demodulate = demodulate
        self.eps = eps
        self.chunk = chunk

    def forward(self, field: torch.Tensor, gbuffer: GBuffer) -> torch.Tensor:
        return denoise_field(
            field,
            gbuffer,
            radius=self.radius,
            sigma_spatial=self.sigma_spatial,
            sigma_albedo=self.sigma_albedo,
            sigma_normal=self.sigma_normal,
            sigma_depth=self.sigma_depth,
            iterations=self.iterations,
            demodulate=self.demodulate,
            eps=self.eps,
            chunk=self.chunk,
        )

    def extra_repr(self) -> str:
        return (
            f"radius={self.radius}, sigma_spatial={self.sigma_spatial}, sigma_albedo={self.sigma_albedo}, "
            f"sigma_normal={self.sigma_normal}, sigma_depth={self.sigma_depth}, iterations={self.iterations}"
        )


def _denoise_reference(
    field: torch.Tensor,
    gbuffer: GBuffer,
    *,
    radius: int = 2,
    sigma_spatial: float = 1.5,
    sigma_albedo: float = 0.1,
    sigma_normal: float = 0.2,
    sigma_depth: float = 0.02,
    iterations: int = 1,
    demodulate: bool = True,
    eps: float = 1e-3,
) -> torch.Tensor:
    """The same filter written directly: one light at a time, weights recomputed each time.

    For the tests and ``benchmarks/bench_filters.py`` only (slow): shifted whole images, no sparse operator.
    """
    size = check_field(field, gbuffer, "field")
    dt = torch.float64
    h = w_ = size
    alpha = gbuffer.alpha[0].to(dt)
    albedo = gbuffer.albedo.to(dt)
    normal = gbuffer.normal.to(dt)
    normal = normal / normal.norm(dim=0, keepdim=True).clamp_min(1e-12)
    depth = gbuffer.depth[0].to(dt)
    mod = ((albedo if demodulate else torch.ones_like(albedo)) * alpha).clamp_min(eps)
    covered = alpha > 0
    out = field.clone()
    if radius == 0:
        return out
    pad = torch.nn.functional.pad
    for n in range(field.shape[2]):
        x = field[:, :, n].to(dt).reshape(3, h, w_) / mod
        for it in range(iterations):
            step = 2**it
            r = radius * step
            xp, ap, np_ = pad(x, (r,) * 4), pad(albedo, (r,) * 4), pad(normal, (r,) * 4)
            zp, alp = pad(depth, (r,) * 4), pad(alpha, (r,) * 4)
            acc = torch.zeros(3, h, w_, dtype=dt)
            norm = torch.zeros(h, w_, dtype=dt)
            for ty in range(-radius, radius + 1):
                for tx in range(-radius, radius + 1):
                    sl = (slice(r + ty * step, r + ty * step + h), slice(r + tx * step, r + tx * step + w_))
                    wgt = (
                        math.exp(-(ty * ty + tx * tx) / (2 * sigma_spatial**2))
                        * alp[sl]
                        * torch.exp(-((ap[(slice(None), *sl)] - albedo) ** 2).sum(0) / (2 * sigma_albedo**2))
                        * torch.exp(-((np_[(slice(None), *sl)] - normal) ** 2).sum(0) / (2 * sigma_normal**2))
                        * torch.exp(-((zp[sl] - depth) / depth.clamp_min(1e-6)) ** 2 / (2 * sigma_depth**2))
                    )
                    acc += wgt * xp[(slice(None), *sl)]
                    norm += wgt
            x = torch.where(covered, acc / norm.clamp_min(1e-300), x)
        res = torch.where(covered, x * mod, field[:, :, n].to(dt).reshape(3, h, w_))
        out[:, :, n] = res.reshape(3, -1).to(out.dtype)
    return out
