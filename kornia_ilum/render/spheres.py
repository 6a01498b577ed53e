r"""The three reference spheres of docs/conventions.rst (diffuse, matte silver, mirror) as reflectance fields.

A sphere render is a reflectance field applied to mirror-ball lighting (:func:`~kornia_ilum.render.relight`):
``I[p, c] = sum_n R[p, n] L[n, c]``. This module builds the fields ``R`` once, in float64, and caches them.

Convention:
    Orthographic view along -Z (docs/conventions.rst, "Reference spheres"). The sphere image uses the
    mirror-ball pixel grid: the pixel centre ``(u, v)`` of an ``S x S`` image sees the surface normal
    ``n = (u, v, sqrt(1 - r^2))`` with view direction ``v = +Z``; pixels with ``r > 1`` are off the sphere
    and their rows of ``R`` are zero. Lighting is an ``S_L x S_L`` mirror-ball image in radiance
    (:mod:`kornia_ilum.geometry.mirror_ball`), so ``R`` is unitless (BRDF times cosine times solid angle):
    a uniform white environment ``L = 1`` renders the diffuse sphere at exactly its albedo 0.8, the mirror
    at 0.827, and the matte-silver sphere at its directional albedo (0.68 to 0.73, see
    :func:`sphere_reflectance_field`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import lru_cache
from typing import NamedTuple

import torch
from torch import nn

from kornia_ilum.color.transfer import gamma_encode_unchecked
from kornia_ilum.core.check import check_choice, check_positive_int, check_tensor
from kornia_ilum.core.compiler import compiler_disable
from kornia_ilum.core.errors import ShapeError, ValueCheckError
from kornia_ilum.filters.soft_clip import soft_clip_unchecked
from kornia_ilum.geometry.mirror_ball import (
    mirror_ball_pixel_index,
    mirror_ball_solid_angles,
    mirror_ball_to_direction,
    mirror_ball_to_lights,
    mirror_ball_uv,
    mirror_ball_valid,
)
from kornia_ilum.render.pyramid import mirror_ball_downsample_matrix
from kornia_ilum.render.relight import relight, relight_product

__all__ = [
    "BRDFS",
    "DIFFUSE_ALBEDO",
    "GAMMA_MODES",
    "MIRROR_REFLECTIVITY",
    "PREVIEW_RTOL",
    "PREVIEW_SUPERSAMPLES",
    "SAFE_GAMMA_KNEE",
    "SILVER_ALPHA",
    "SILVER_F0",
    "SPHERE_SIZES",
    "EncodeSphere",
    "RenderSpheres",
    "SpherePlan",
    "SpherePyramid",
    "check_brdf",
    "check_sphere_lighting",
    "check_sphere_sizes",
    "encode_sphere",
    "gamma_knee",
    "render_plan",
    "render_spheres",
    "shared_sphere_field",
    "sphere_plan",
    "sphere_pyramid",
    "sphere_reflectance_field",
]

#: Names of the reference spheres, in the order of docs/conventions.rst.
BRDFS: tuple[str, ...] = ("diffuse", "matte_silver", "mirror")
#: Sphere and lighting resolutions for which fields can be built.
SPHERE_SIZES: tuple[int, ...] = (4, 8, 16, 32, 64)
#: Lambertian albedo of the diffuse sphere.
DIFFUSE_ALBEDO = 0.8
#: Reflectivity of the mirror sphere (LeGendre et al. 2020's measured value).
MIRROR_REFLECTIVITY = 0.827
#: Schlick ``F0`` of the matte-silver sphere.
SILVER_F0 = 0.827
#: GGX ``alpha`` of the matte-silver sphere (the alpha of the distribution itself, not a "roughness").
SILVER_ALPHA = 0.3
#: The two forms of the power ``x^(1/2.2)`` of ``L_rec``: ``"exact"`` (the metric) and ``"safe"`` (training).
GAMMA_MODES: tuple[str, ...] = ("exact", "safe")
#: Knee of the ``"safe"`` power (:func:`~kornia_ilum.color.gamma_encode`): slope 1874 at 0, and at most
#: 5.3e-4 below the exact power.
SAFE_GAMMA_KNEE = 1e-6

_SUPERSAMPLES = 8  # sub-samples per lighting pixel and axis (64 per pixel)
#: The quadrature's sub-samples per lighting pixel and axis for pictures (:meth:`LightingEstimate.preview`), not
#: metrics: 16 times fewer sub-samples, so :func:`render_spheres` builds its fields faster (docs/bench.rst).
PREVIEW_SUPERSAMPLES = 2
#: How far (relative to the brightest value of each sphere) a render with :data:`PREVIEW_SUPERSAMPLES` may be
#: from the default's (tested).
PREVIEW_RTOL = 0.02
_CHUNK = 8  # sphere pixels per chunk: float64 temporaries of _CHUNK * 51k samples stay in cache


def check_brdf(brdf: str, name: str = "brdf") -> None:
    """Require ``brdf`` to name a reference sphere, one of :data:`BRDFS`.

    Args:
        brdf: the value to check.
        name: the argument's name, used in the message.

    Returns:
        ``None``; it raises on any other value.

    Raises:
        ValueCheckError: ``brdf`` is not in :data:`BRDFS`; the message lists them.

    Examples:
        >>> check_brdf("mirror")
        >>> try:
        ...     check_brdf("chrome")
        ... except ValueError as error:
        ...     print(error)
        brdf must be one of ('diffuse', 'matte_silver', 'mirror'), got 'chrome'
    """
    check_choice(brdf, name, BRDFS)


def _grid_lookup(uv: torch.Tensor, n: int) -> torch.Tensor:
    """Flat ``row * n + col`` index of points ``(u, v)`` on the pixel centres of an ``n x n`` grid."""
    col = torch.round(((uv[:, 0] + 1.0) * n - 1.0) * 0.5).long()
    row = torch.round(((1.0 - uv[:, 1]) * n - 1.0) * 0.5).long()
    return row * n + col


def _d4(uv: torch.Tensor) -> list[torch.Tensor]:
    """The 8 images of ``(..., 2)`` points (or of the ``x, y`` of ``(..., 3)`` directions) under the square's
    symmetries: sign flips of ``x`` and ``y``, optionally followed by their swap (exact in floating point)."""
    out = []
    for su in (1.0, -1.0):
        for sv in (1.0, -1.0):
            flipped = uv.clone()
            flipped[..., 0] *= su
            flipped[..., 1] *= sv
            out.append(flipped)
            swapped = flipped.clone()
            swapped[..., [0, 1]] = flipped[..., [1, 0]]
            out.append(swapped)
    return out


@lru_cache(maxsize=2 * len(SPHERE_SIZES))
def _lighting_samples(lighting_size: int, supersamples: int = _SUPERSAMPLES
                      ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Sub-samples of the lighting sphere, for the quadrature of every lighting pixel's solid angle.

    Returns directions ``(M, 3)``, owner pixels ``(M,)``, weights ``(M,)`` in sr, and ``(8, M)`` sample
    permutations ``sigma[g, m]`` = index of the image of sample ``m`` under the ``g``-th symmetry of
    :func:`_d4`. A regular ``(S_L k) x (S_L k)`` grid over the mirror-ball disk is equal-area
    (``dOmega = 4 du dv``), so the samples of one lighting pixel get equal weights, scaled so that they sum
    exactly to the pixel's solid angle (:func:`~kornia_ilum.geometry.mirror_ball_solid_angles`).
    """
    n = lighting_size * supersamples
    c = (2 * torch.arange(n, dtype=torch.float64) + 1) / n - 1
    v, u = torch.meshgrid(-c, c, indexing="ij")
    uv = torch.stack([u, v], -1).reshape(-1, 2)
    uv = uv[uv.square().sum(-1) <= 1.0]
    dirs, _ = mirror_ball_to_direction(uv)
    owner = mirror_ball_pixel_index(uv, lighting_size)
    count = torch.bincount(owner, minlength=lighting_size**2).to(torch.float64)
    omega = mirror_ball_solid_angles(lighting_size, dtype=torch.float64).flatten()
    weight = omega[owner] / count[owner]
    lookup = torch.full((n * n,), -1, dtype=torch.long)
    lookup[_grid_lookup(uv, n)] = torch.arange(uv.shape[0])
    sigma = torch.stack([lookup[_grid_lookup(g, n)] for g in _d4(uv)])
    return dirs, owner, weight, sigma


def _diffuse(normals: torch.Tensor, dirs: torch.Tensor) -> torch.Tensor:
    """Lambert: ``(albedo / pi) max(n . l, 0)``, ``(P, M)``."""
    return (DIFFUSE_ALBEDO / math.pi) * (normals @ dirs.T).clamp(min=0.0)


def _matte_silver(normals: torch.Tensor, dirs: torch.Tensor) -> torch.Tensor:
    """GGX conductor ``f (n . l)+ = D F G1(l) G1(v) / (4 n.v)`` for view ``+Z``, ``(P, M)``."""
    a2 = SILVER_ALPHA**2
    nl = normals @ dirs.T  # (P, M)
    nv = normals[:, 2:3]  # (P, 1), > 0 at every pixel centre on the sphere
    half = dirs + dirs.new_tensor([0.0, 0.0, 1.0])
    half = half / half.norm(dim=-1, keepdim=True).clamp(min=1e-12)  # l = -Z is masked by nl < 0 below
    nh = normals @ half.T
    vh = half[:, 2][None, :]
    d = a2 / (math.pi * (nh.square() * (a2 - 1.0) + 1.0).square())

    def g1(x: torch.Tensor) -> torch.Tensor:
        return 2.0 * x / (x + torch.sqrt(a2 + (1.0 - a2) * x.square()))

    fresnel = SILVER_F0 + (1.0 - SILVER_F0) * (1.0 - vh).pow(5)
    nl_pos = nl.clamp(min=0.0)
    value = d * fresnel * g1(nl_pos) * g1(nv) / (4.0 * nv)
    return torch.where(nl > 0, value, torch.zeros_like(value))


@lru_cache(maxsize=2 * len(BRDFS) * len(SPHERE_SIZES))
def _field_f64(brdf: str, size: int, lighting_size: int, supersamples: int = _SUPERSAMPLES) -> torch.Tensor:
    """The ``(size^2, lighting_size^2)`` field in float64 on the CPU (cached; never hand it out).

    The BRDFs, the view direction +Z and both pixel grids are invariant under the 8 symmetries of the
    square (:func:`_d4`), so the integrand is evaluated only for the sphere pixels with ``u >= v > 0``: the
    row of pixel ``g(p)`` is ``sum_m f(p, l_m) w[sigma_g(m)]`` accumulated into lighting pixel
    ``owner[sigma_g(m)]``, which is the direct quadrature of ``g(p)`` term by term.
    """
    uv = mirror_ball_uv(size, dtype=torch.float64).reshape(-1, 2)
    valid = mirror_ball_valid(size).flatten()
    field = torch.zeros(size * size, lighting_size * lighting_size, dtype=torch.float64)
    rows = valid.nonzero().squeeze(1)
    if brdf == "mirror":
        # the reflection of the view ray +Z about n(u, v) is exactly the mirror-ball direction of (u, v)
        field[rows, mirror_ball_pixel_index(uv[rows], lighting_size)] = MIRROR_REFLECTIVITY
        return field
    reps = rows[(uv[rows, 0] >= uv[rows, 1]) & (uv[rows, 1] > 0)]
    targets = [_grid_lookup(g, size) for g in _d4(uv[reps])]  # 8 x (R,) pixel of g(rep)
    r2 = uv[reps].square().sum(-1, keepdim=True)
    normals = torch.cat([uv[reps], torch.sqrt((1.0 - r2).clamp(min=0.0))], dim=-1)
    dirs, owner, weight, sigma = _lighting_samples(lighting_size, supersamples)
    shade = _diffuse if brdf == "diffuse" else _matte_silver
    chunk = _CHUNK * max(1, _SUPERSAMPLES // supersamples) ** 2  # temporaries of the same size at any supersamples
    for start in range(0, reps.numel(), chunk):
        stop = min(start + chunk, reps.numel())
        values = shade(normals[start:stop], dirs)
        for g in range(8):
            part = torch.zeros(stop - start, field.shape[1], dtype=torch.float64)
            part.index_add_(1, owner[sigma[g]], values * weight[sigma[g]])
            field[targets[g][start:stop]] = part
    return field


def sphere_reflectance_field(
    brdf: str,
    size: int,
    *,
    lighting_size: int = 32,
    multiscale: bool = False,
    device: torch.device | str | None = None,
    dtype: torch.dtype = torch.float32,
) -> torch.Tensor:
    r"""Reflectance field of a reference sphere: ``I = R . L`` renders it from mirror-ball lighting.

    ``R[p, n]`` is the integral, over the solid angle of lighting pixel ``n``, of the BRDF times the cosine
    at sphere pixel ``p``:

    - ``"diffuse"``: Lambert, albedo 0.8: ``(0.8 / pi) * int_n max(n . w, 0) dw``.
    - ``"matte_silver"``: GGX microfacet conductor (Walter et al. 2007, "Microfacet models for refraction
      through rough surfaces") with ``alpha = 0.3``,
      ``D = alpha^2 / (pi ((n.h)^2 (alpha^2 - 1) + 1)^2)``, separable Smith shadowing ``G1(l) G1(v)`` with
      ``G1(x) = 2 (n.x) / ((n.x) + sqrt(alpha^2 + (1 - alpha^2) (n.x)^2))``, Schlick Fresnel with
      ``F0 = 0.827`` at ``(v.h)``, no diffuse term: ``int_n D F G / (4 (n.l)(n.v)) (n.l)+ dw``. Its
      directional albedo (the render under ``L = 1``) is 0.726 at the centre, dips to 0.674 at
      ``n.v = 0.36`` and rises again towards the silhouette as Fresnel grows (0.737 at the outermost
      pixels of a 64 x 64 sphere, ``n.v = 0.04``): the "0.68 to 0.73" of docs/conventions.rst to within 1%.
    - ``"mirror"``: reflectivity 0.827 in the single lighting pixel that owns the reflected view direction
      (:func:`~kornia_ilum.geometry.mirror_ball_pixel_index`); at the pixel centre that direction is
      exactly the mirror-ball direction of the pixel, so at ``size == lighting_size`` the mirror field is
      ``0.827`` times the identity on the valid pixels.

    The integrals are quadratures over ``8 x 8`` equal-area sub-samples per lighting pixel, each assigned to
    the lighting pixel that owns it and weighted so that every pixel's weights sum exactly to its solid
    angle (:func:`~kornia_ilum.geometry.mirror_ball_solid_angles`). Fields are computed once per
    ``(brdf, size, lighting_size)`` in float64 (fast enough that there is no disk cache: the time is in the
    docs' render page), cached in memory, and returned as a fresh copy. Against 16 x 16 sub-samples,
    renders differ by at most 0.25% (matte silver) and 0.01% (diffuse).

    With ``multiscale=True`` and ``size < lighting_size`` the field is the one that
    :func:`render_spheres` and the losses use (docs/conventions.rst, "Multi-scale"): the lighting is first
    brought down to ``size`` by the energy-keeping pyramid
    (:func:`~kornia_ilum.render.mirror_ball_downsample_matrix` ``D``), and the sphere is rendered from it,
    ``R_multiscale = R(size, size) D``. So a coarse sphere sees all of the lighting (the coarse mirror shows
    ``0.827`` times the pyramid level, a bright pixel included), where the plain ``R(size, lighting_size)``
    samples the mirror direction at each pixel centre and misses most lighting pixels. For
    ``size >= lighting_size`` both are the same field.

    Args:
        brdf: one of :data:`BRDFS`: ``"diffuse"``, ``"matte_silver"``, ``"mirror"``.
        size: sphere image side ``S`` in pixels, one of :data:`SPHERE_SIZES`.
        lighting_size: mirror-ball lighting side ``S_L``, one of :data:`SPHERE_SIZES`.
        multiscale: render from the lighting brought down to ``size`` (see above).
        device: device of the result.
        dtype: floating dtype of the result.

    Returns:
        the field ``R``, shared across colour channels, of shape ``(S^2, S_L^2)``; rows of pixels off the
        sphere are zero.

    Raises:
        ValueCheckError: unknown ``brdf`` or a size outside :data:`SPHERE_SIZES`.
        TypeCheckError: a size is not an int.

    Shape:
        - Output: :math:`(S^2, S_L^2)`, row-major sphere pixels by row-major lighting pixels.

    Convention:
        docs/conventions.rst, "Reference spheres": orthographic view along -Z, sphere pixel ``(u, v)`` has
        normal ``(u, v, sqrt(1 - r^2))`` and is shaded at its centre with view direction ``+Z``; lighting in
        radiance, so a white uniform environment renders the diffuse sphere at 0.8 everywhere.

    Examples:
        >>> R = sphere_reflectance_field("diffuse", 8)
        >>> R.shape
        torch.Size([64, 1024])
        >>> round(R.sum(1).max().item(), 4)  # uniform white lighting -> albedo 0.8
        0.8
    """
    check_brdf(brdf)
    check_positive_int(size, "size", allowed=SPHERE_SIZES)
    check_positive_int(lighting_size, "lighting_size", allowed=SPHERE_SIZES)
    build = _multiscale_f64 if multiscale else _field_f64
    return build(brdf, size, lighting_size).to(device=device, dtype=dtype, copy=True)


@lru_cache(maxsize=2 * len(BRDFS) * len(SPHERE_SIZES))
def _multiscale_f64(brdf: str, size: int, lighting_size: int, supersamples: int = _SUPERSAMPLES) -> torch.Tensor:
    """The field of :func:`render_spheres`: the sphere of size ``s`` lit by the lighting brought down to it.

    For ``size < lighting_size``: ``R_s D`` with ``D = D(lighting_size -> size)`` (the pyramid) and ``R_s``
    the field of the ``size`` sphere over the ``size x size`` lighting pixels. For the mirror
    ``R_s = 0.827 I`` exactly. For the other two, ``R_s`` integrates the BRDF over each coarse pixel's
    region with the fine quadrature, ``R_s = R(size, lighting_size) U``, where
    ``U[f, c] = D[c, f] omega_c / omega_f`` is the share of fine pixel ``f`` in coarse pixel ``c`` (the same
    overlaps as ``D``, rows summing to 1): 64 times the samples of ``R(size, size)``, whose 8 x 8 samples per
    4 x 4 pixel are 1 % off. Otherwise ``R(size, lighting_size)``.
    """
    if size >= lighting_size:
        return _field_f64(brdf, size, lighting_size, supersamples)
    down = mirror_ball_downsample_matrix(lighting_size, size, dtype=torch.float64)
    if brdf == "mirror":
        return MIRROR_REFLECTIVITY * down
    omega_f = mirror_ball_solid_angles(lighting_size, dtype=torch.float64).flatten()
    omega_c = mirror_ball_solid_angles(size, dtype=torch.float64).flatten()
    up = down.T * omega_c[None, :] / torch.where(omega_f > 0, omega_f, 1.0)[:, None]
    return (_field_f64(brdf, size, lighting_size, supersamples) @ up) @ down


@compiler_disable  # called eagerly from compiled code: Dynamo would otherwise trace the build itself
@lru_cache(maxsize=64)
def shared_sphere_field(
    brdf: str,
    size: int,
    *,
    lighting_size: int,
    device: torch.device,
    dtype: torch.dtype,
    on_sphere: bool = False,
    multiscale: bool = False,
    supersamples: int = _SUPERSAMPLES,
) -> torch.Tensor:
    r"""The field of :func:`sphere_reflectance_field`, cached on ``device`` in ``dtype`` and shared (no copy).

    For losses and metrics that render many batches with one field: the field is built once per
    arguments (up to 64 of them cached) and every call returns the same tensor. It is read-only: modify
    it and every later render changes. The arguments are not checked (:func:`check_brdf`,
    :data:`SPHERE_SIZES`); use :func:`sphere_reflectance_field` for a checked, private copy.

    Args:
        brdf: one of :data:`BRDFS`.
        size: sphere image side ``S``, one of :data:`SPHERE_SIZES`.
        lighting_size: mirror-ball lighting side ``S_L``, one of :data:`SPHERE_SIZES`.
        device: device of the field.
        dtype: floating dtype of the field.
        on_sphere: keep only the rows of the pixels on the sphere, in row-major order.
        multiscale: the field of :func:`render_spheres` (see :func:`sphere_reflectance_field`).
        supersamples: the quadrature's sub-samples per lighting pixel and axis (:func:`render_spheres`).

    Returns:
        the field ``(S^2, S_L^2)``, or ``(P_valid, S_L^2)`` with ``on_sphere``.

    Shape:
        - Output: :math:`(S^2, S_L^2)`, or :math:`(P_\mathrm{valid}, S_L^2)` with ``on_sphere``

    Convention:
        docs/conventions.rst, "Reference spheres" and "Mirror ball": row-major sphere pixels by row-major
        lighting pixels, as :func:`sphere_reflectance_field`.

    Examples:
        >>> settings = {"lighting_size": 32, "device": torch.device("cpu"), "dtype": torch.float32}
        >>> field = shared_sphere_field("mirror", 8, **settings, on_sphere=True)
        >>> field.shape, field is shared_sphere_field("mirror", 8, **settings, on_sphere=True)
        (torch.Size([52, 1024]), True)
    """
    field = (_multiscale_f64 if multiscale else _field_f64)(brdf, size, lighting_size, supersamples)
    if on_sphere:
        field = field[mirror_ball_valid(size).flatten()]
    return field.to(device=device, dtype=dtype)


class SpherePlan(NamedTuple):
    r"""How to render the on-sphere pixels of several spheres ``(brdf, size)`` at once.

    Built by :func:`sphere_plan`, applied by :func:`render_plan`. The rows of the multi-scale fields
    (:func:`sphere_reflectance_field` with ``multiscale=True``) are one matrix product, except the mirror at
    the lighting's own size, whose renders are copies of lighting pixels.

    Examples:
        >>> cpu = torch.device("cpu")
        >>> plan = sphere_plan(("mirror",), (8, 32), lighting_size=32, device=cpu, dtype=torch.float32)
        >>> plan.field.shape, plan.index.shape, plan.order is None  # the 8 px mirror: one product
        (torch.Size([52, 1024]), torch.Size([812]), True)
    """

    #: ``(P_mm, N)``: the rows rendered by one matrix product.
    field: torch.Tensor
    #: ``(P_copy,)``: the lighting pixels shown as they are, times :data:`MIRROR_REFLECTIVITY`.
    index: torch.Tensor
    #: ``(P,)``: the permutation that makes ``cat([product, copies])`` brdf-major and in the order of the
    #: sizes; ``None`` when that is already the order.
    order: torch.Tensor | None


@compiler_disable
@lru_cache(maxsize=64)
def sphere_plan(
    brdfs: tuple[str, ...],
    sizes: tuple[int, ...],
    *,
    lighting_size: int,
    device: torch.device,
    dtype: torch.dtype,
) -> SpherePlan:
    r"""The on-sphere rows of the multi-scale fields of every ``(brdf, size)``, brdf-major, as one product.

    The mirror at ``size == lighting_size`` is ``0.827`` times the lighting on the valid pixels: those rows
    are copies (a gather), not rows of a dense product, which saves most of the mirror's cost. Plans are
    cached (up to 64) and shared: read-only. The arguments are not checked (:func:`check_brdf`,
    :func:`check_sphere_sizes`, :data:`SPHERE_SIZES`).

    Args:
        brdfs: names from :data:`BRDFS`, a tuple.
        sizes: sphere sides from :data:`SPHERE_SIZES`, a tuple.
        lighting_size: side ``S_L`` of the mirror-ball lighting, from :data:`SPHERE_SIZES`.
        device: device of the plan.
        dtype: floating dtype of the plan's field.

    Returns:
        the :class:`SpherePlan`; :func:`render_plan` renders ``P`` values per channel, the pixels on each
        sphere in row-major order, brdf-major and in the order of ``sizes``.

    Examples:
        >>> plan = sphere_plan(("diffuse", "mirror"), (4, 32), lighting_size=32, device=torch.device("cpu"),
        ...                    dtype=torch.float32)
        >>> plan.field.shape, plan.index.shape  # the 32 x 32 mirror is a copy of the lighting
        (torch.Size([836, 1024]), torch.Size([812]))
    """
    rows, copies, kinds = [], [], []
    for b in brdfs:
        for s in sizes:
            valid = mirror_ball_valid(s).flatten()
            if b == "mirror" and s == lighting_size:
                copies.append(valid.nonzero().squeeze(1))
                kinds.append(torch.ones(copies[-1].numel(), dtype=torch.bool))
            else:
                rows.append(_multiscale_f64(b, s, lighting_size)[valid])
                kinds.append(torch.zeros(rows[-1].shape[0], dtype=torch.bool))
    n = lighting_size * lighting_size
    field = torch.cat(rows) if rows else torch.zeros(0, n, dtype=torch.float64)
    index = torch.cat(copies) if copies else torch.zeros(0, dtype=torch.long)
    is_copy = torch.cat(kinds)
    position = torch.empty(is_copy.numel(), dtype=torch.long)  # where each output row sits in cat([mm, copy])
    position[~is_copy] = torch.arange(field.shape[0])
    position[is_copy] = field.shape[0] + torch.arange(index.numel())
    order = None if bool((position == torch.arange(position.numel())).all()) else position.to(device)
    return SpherePlan(field.to(device=device, dtype=dtype), index.to(device), order)


def render_plan(plan: SpherePlan, lights: torch.Tensor, *, knee: float | None = None) -> torch.Tensor:
    r"""Render the spheres of a :class:`SpherePlan` from a light list, optionally encoded for ``L_rec``.

    For callers that checked the lighting (:func:`check_sphere_lighting`): nothing is validated. With
    ``knee`` the renders are mapped through :func:`encode_sphere` (``softclip(I)^(1/2.2)``) with that knee of
    the power (:func:`gamma_knee`), as the losses compare them.

    Args:
        plan: from :func:`sphere_plan`.
        lights: ``(B, N, 3)`` light list of the mirror-ball lighting
            (:func:`~kornia_ilum.geometry.mirror_ball_to_lights`).
        knee: ``None`` for the linear renders, else the knee of :func:`gamma_knee`.

    Returns:
        ``(B, 3, P)``: the pixels on each sphere in row-major order, brdf-major, in the order of the plan's
        sizes; in the dtype of the plan's field.

    Shape:
        - lights: :math:`(B, N, 3)`, :math:`N = S_L^2`
        - Output: :math:`(B, 3, P)`

    Examples:
        >>> plan = sphere_plan(("diffuse",), (4,), lighting_size=32, device=torch.device("cpu"),
        ...                    dtype=torch.float32)
        >>> out = render_plan(plan, torch.ones(1, 1024, 3))
        >>> out.shape, round(out[0, 0, 0].item(), 4)  # uniform white lighting: the albedo
        (torch.Size([1, 3, 12]), 0.8)
    """
    parts = []
    if plan.field.shape[0]:
        parts.append(relight_product(plan.field, lights.to(plan.field.dtype)))
    if plan.index.numel():
        parts.append(MIRROR_REFLECTIVITY * lights.index_select(1, plan.index).transpose(1, 2))
    out = parts[0] if len(parts) == 1 else torch.cat(parts, -1)
    out = out if plan.order is None else out.index_select(-1, plan.order)
    return out if knee is None else _encode(out, knee)


def check_sphere_lighting(lighting: torch.Tensor, name: str = "lighting", size: int | None = None) -> int:
    r"""Check a mirror-ball lighting batch that the reference spheres can be rendered from; return its side.

    Args:
        lighting: the value to check: ``(B, 3, S_L, S_L)``, floating, finite, ``S_L`` in
            :data:`SPHERE_SIZES`.
        name: the argument's name, used in the messages.
        size: the side ``S_L`` required, or ``None`` for any of :data:`SPHERE_SIZES`.

    Returns:
        the side ``S_L``.

    Raises:
        ShapeError: wrong shape, a side outside :data:`SPHERE_SIZES`, or not ``size``.
        TypeCheckError: no floating-point tensor.
        NonFiniteError: ``lighting`` holds NaN or Inf.

    Shape:
        - lighting: :math:`(B, 3, S_L, S_L)`

    Convention:
        docs/conventions.rst, "Mirror ball": the lighting is a mirror-ball image.

    Examples:
        >>> check_sphere_lighting(torch.ones(2, 3, 32, 32))
        32
    """
    check_tensor(lighting, name, ["B", "3", "S", "S"])
    s = lighting.shape[-1]
    if lighting.shape[-2] != s:
        raise ShapeError(f"{name} must have shape (B, 3, S, S), got {tuple(lighting.shape)}")
    if s not in SPHERE_SIZES:
        raise ShapeError(
            f"{name} must be a mirror ball of side in {SPHERE_SIZES}, got {tuple(lighting.shape)}"
        )
    if size is not None and s != size:
        raise ShapeError(f"{name} must have shape (B, 3, {size}, {size}), got {tuple(lighting.shape)}")
    return s


def _check_brdfs(brdfs: Sequence[str]) -> tuple[str, ...]:
    names = (brdfs,) if isinstance(brdfs, str) else tuple(brdfs)
    if not names:
        raise ValueCheckError(f"brdfs must name at least one of {BRDFS}, got {brdfs!r}")
    for b in names:
        check_brdf(b, "brdfs")
    return names


def check_sphere_sizes(sizes: Sequence[int]) -> tuple[int, ...]:
    """Check sphere sides, each one of :data:`SPHERE_SIZES`, and return them as a tuple.

    Args:
        sizes: the sides, or one side as an int.

    Returns:
        the sides as a tuple, in the order given.

    Raises:
        ValueCheckError: no side, or a side outside :data:`SPHERE_SIZES`.
        TypeCheckError: a side is not an int.

    Examples:
        >>> check_sphere_sizes([4, 16])
        (4, 16)
    """
    sizes = tuple(sizes) if not isinstance(sizes, int) else (sizes,)
    if not sizes:
        raise ValueCheckError("sizes must name at least one sphere size")
    for s in sizes:
        check_positive_int(s, "sizes", allowed=SPHERE_SIZES)
    return sizes


def gamma_knee(gamma: str) -> float:
    """The knee of the power ``x^(1/2.2)`` for a gamma mode of :data:`GAMMA_MODES`.

    ``0.0`` for ``"exact"`` (the exact power), :data:`SAFE_GAMMA_KNEE` for ``"safe"``: the ``knee`` of
    :func:`~kornia_ilum.color.gamma_encode` and of :func:`render_plan`.

    Args:
        gamma: ``"exact"`` or ``"safe"``.

    Returns:
        the knee, ``>= 0``.

    Raises:
        ValueCheckError: ``gamma`` is not one of :data:`GAMMA_MODES`.

    Examples:
        >>> gamma_knee("exact"), gamma_knee("safe")
        (0.0, 1e-06)
    """
    check_choice(gamma, "gamma", GAMMA_MODES)
    return 0.0 if gamma == "exact" else SAFE_GAMMA_KNEE


def encode_sphere(render: torch.Tensor, gamma: str = "exact") -> torch.Tensor:
    r"""A sphere render as ``L_rec`` compares it: ``softclip(I)^(1/2.2)``.

    :func:`~kornia_ilum.filters.soft_clip` (negative values count as 0) then the power ``1/2.2``:

    - ``gamma="exact"``: the exact ``x^(1/2.2)`` (docs/conventions.rst: the metric). Its gradient is finite
      but unbounded near 0 (0 at exactly 0).
    - ``gamma="safe"``: :func:`~kornia_ilum.color.gamma_encode` with knee :data:`SAFE_GAMMA_KNEE` (1e-6): the
      chord through 0 below the knee, slope 1874 there, at most 5.3e-4 below the exact power. For training.

    Args:
        render: linear sphere renders of any shape.
        gamma: ``"exact"`` or ``"safe"``.

    Returns:
        encoded values in ``[0, 1]``, same shape and dtype.

    Raises:
        ValueCheckError: ``gamma`` is not one of :data:`GAMMA_MODES`.
        NonFiniteError: NaN or Inf in ``render``.

    Shape:
        - render: :math:`(*)`
        - Output: :math:`(*)`

    Convention:
        docs/conventions.rst, "The paper's error measure ``L_rec``": ``softclip`` then the exact power
        ``x^(1/2.2)`` for the metric; a training loss may use the gradient-safe variant.

    Examples:
        >>> encode_sphere(torch.tensor([-0.5, 0.0, 0.25, 100.0]))
        tensor([0.0000, 0.0000, 0.5325, 1.0000])
    """
    check_tensor(render, "render", None, nonempty=False)
    return _encode(render, gamma_knee(gamma))


def _encode(render: torch.Tensor, knee: float) -> torch.Tensor:
    """:func:`encode_sphere` without the checks."""
    return gamma_encode_unchecked(soft_clip_unchecked(render), 2.2, knee)


def render_spheres(
    lighting: torch.Tensor, size: int = 32, brdfs: Sequence[str] = BRDFS, *, supersamples: int = _SUPERSAMPLES
) -> dict[str, torch.Tensor]:
    r"""Render the reference spheres from mirror-ball lighting.

    A sphere of size ``S`` is rendered from the lighting of size ``S`` (docs/conventions.rst, "Multi-scale"):
    lighting larger than ``size`` is first brought down by the energy-keeping pyramid
    (:func:`~kornia_ilum.render.mirror_ball_pyramid`), so a coarse sphere sees all of the lighting, a single
    bright pixel included. Spheres larger than the lighting are rendered from it directly (the field
    integrates each lighting pixel over its solid angle). This is ``sphere_reflectance_field(brdf, size,
    lighting_size=S_L, multiscale=True)`` applied to the lighting.

    Args:
        lighting: linear mirror-ball lighting in radiance, ``(B, 3, S_L, S_L)``, ``S_L`` in
            :data:`SPHERE_SIZES` (32 in the paper).
        size: side of the sphere renders, one of :data:`SPHERE_SIZES`.
        brdfs: the spheres to render, names from :data:`BRDFS`.
        supersamples: sub-samples per lighting pixel and axis of the fields' quadrature: 8 (the default) for
            the metrics and losses; :data:`PREVIEW_SUPERSAMPLES` (2, 16 times fewer) for pictures: its fields
            build faster (they are most of a process's first preview; docs/bench.rst has the times), and its
            renders are within :data:`PREVIEW_RTOL` of the default's (``tests/render/test_spheres.py``).

    Returns:
        ``{name: render}`` with linear renders ``(B, 3, size, size)`` in the dtype and device of
        ``lighting``; pixels off the sphere are 0.

    Shape:
        - Input: :math:`(B, 3, S_L, S_L)`
        - Output: ``{name:`` :math:`(B, 3, S, S)` ``}``

    Convention:
        docs/conventions.rst, "Reference spheres" (see :func:`sphere_reflectance_field`); the renders are
        linear HDR in the units of the lighting. Reference spheres as in LeGendre et al. 2020, "Learning
        Illumination from Diverse Portraits".

    Examples:
        >>> out = render_spheres(torch.ones(2, 3, 32, 32), size=16)
        >>> sorted(out), tuple(out["mirror"].shape)
        (['diffuse', 'matte_silver', 'mirror'], (2, 3, 16, 16))
        >>> round(out["diffuse"][0, 0, 8, 8].item(), 4)
        0.8
    """
    s_l = check_sphere_lighting(lighting)
    check_positive_int(size, "size", allowed=SPHERE_SIZES)
    names = _check_brdfs(brdfs)
    check_positive_int(supersamples, "supersamples")
    lights = mirror_ball_to_lights(lighting)
    return {
        b: relight(
            shared_sphere_field(b, size, lighting_size=s_l, device=lighting.device, dtype=lighting.dtype,
                                multiscale=True,
                                supersamples=supersamples), lights, size
        )
        for b in names
    }


def _scatter_on_sphere(
    values: torch.Tensor, brdfs: tuple[str, ...], sizes: tuple[int, ...]
) -> dict[str, torch.Tensor]:
    """Split the brdf-major rows ``(B, 3, sum P_valid)`` into images ``{f"{brdf}_{size}": (B, 3, s, s)}``.

    Pixels off the sphere are 0.
    """
    b = values.shape[0]
    out, start = {}, 0
    for name in brdfs:
        for s in sizes:
            mask = mirror_ball_valid(s, device=values.device).flatten()
            n = int(mask.sum())
            image = values.new_zeros(b, 3, s * s)
            image[:, :, mask] = values[:, :, start : start + n]
            out[f"{name}_{s}"] = image.reshape(b, 3, s, s)
            start += n
    return out


def sphere_pyramid(
    lighting: torch.Tensor,
    *,
    sizes: Sequence[int] = (4, 8, 16, 32),
    brdfs: Sequence[str] = BRDFS,
    encode: bool = True,
    gamma: str = "exact",
) -> dict[str, torch.Tensor]:
    r"""The reference spheres at several sizes, as the multi-scale loss compares them.

    Each sphere of size ``s`` is rendered from the lighting brought down to ``s``
    (:func:`render_spheres`), and with ``encode`` mapped through :func:`encode_sphere`:
    ``softclip(I)^(1/2.2)``. These are exactly the values that
    :func:`~kornia_ilum.metrics.reconstruction_loss` (with the same ``gamma``) takes the mean absolute
    difference of over the on-sphere pixels, so they can be stored as training targets: the loss of a
    prediction ``p`` is ``mean(|sphere_pyramid(p)[k] - target[k]|)`` over ``mirror_ball_valid(s)``. All the
    renders are one matrix product.

    Args:
        lighting: linear mirror-ball lighting ``(B, 3, S_L, S_L)``, ``S_L`` in :data:`SPHERE_SIZES`.
        sizes: sphere sides, each in :data:`SPHERE_SIZES`.
        brdfs: the spheres, names from :data:`BRDFS`.
        encode: apply :func:`encode_sphere`; otherwise return the linear renders.
        gamma: ``"exact"`` (the metric) or ``"safe"`` (training targets: use the same mode as the
            training loss), see :func:`encode_sphere`.

    Returns:
        ``{f"{brdf}_{size}": (B, 3, size, size)}`` in the dtype and device of ``lighting``, 0 off the
        sphere.

    Shape:
        - Input: :math:`(B, 3, S_L, S_L)`
        - Output: ``{key:`` :math:`(B, 3, s, s)` ``}``

    Convention:
        docs/conventions.rst, "Reference spheres" ("Multi-scale") and "The paper's error measure L_rec".

    Examples:
        >>> out = sphere_pyramid(torch.ones(1, 3, 32, 32), sizes=(4, 16), gamma="safe")
        >>> sorted(out)
        ['diffuse_16', 'diffuse_4', 'matte_silver_16', 'matte_silver_4', 'mirror_16', 'mirror_4']
        >>> round(out["diffuse_4"][0, 0, 1, 1].item(), 3)  # softclip(0.8)^(1/2.2)
        0.903
    """
    s_l = check_sphere_lighting(lighting)
    sizes = check_sphere_sizes(sizes)
    names = _check_brdfs(brdfs)
    knee = gamma_knee(gamma)
    plan = sphere_plan(names, sizes, lighting_size=s_l, device=lighting.device, dtype=lighting.dtype)
    values = render_plan(plan, mirror_ball_to_lights(lighting), knee=knee if encode else None)
    return _scatter_on_sphere(values, names, sizes)


class RenderSpheres(nn.Module):
    r"""Module twin of :func:`render_spheres`; the fields are non-persistent float32 buffers.

    Float32 and half-precision lighting is rendered through the buffers (cast to the lighting's dtype);
    float64 lighting through the float64 fields of :func:`render_spheres`, so that it is not rounded through
    float32 (the two agree to float32 precision, about 1e-8 relative).

    Args:
        size: side of the sphere renders, one of :data:`SPHERE_SIZES`.
        brdfs: the spheres to render, names from :data:`BRDFS`.
        lighting_size: side ``S_L`` of the mirror-ball lighting the module accepts.

    Shape:
        - Input: :math:`(B, 3, S_L, S_L)` with ``S_L = lighting_size``
        - Output: ``{name:`` :math:`(B, 3, S, S)` ``}``

    Examples:
        >>> render = RenderSpheres(8, brdfs=("mirror",))
        >>> round(render(torch.ones(1, 3, 32, 32))["mirror"][0, 0, 4, 4].item(), 4)
        0.827
    """

    def __init__(self, size: int = 32, brdfs: Sequence[str] = BRDFS, lighting_size: int = 32) -> None:
        super().__init__()
        check_positive_int(size, "size", allowed=SPHERE_SIZES)
        check_positive_int(lighting_size, "lighting_size", allowed=SPHERE_SIZES)
        self.size = size
        self.lighting_size = lighting_size
        self.brdfs = _check_brdfs(brdfs)
        for b in self.brdfs:
            field = sphere_reflectance_field(b, size, lighting_size=lighting_size, multiscale=True)
            self.register_buffer(f"field_{b}", field, persistent=False)

    def forward(self, lighting: torch.Tensor) -> dict[str, torch.Tensor]:
        check_sphere_lighting(lighting, size=self.lighting_size)
        if lighting.dtype == torch.float64:  # the float64 fields, not the float32 buffers
            return render_spheres(lighting, self.size, self.brdfs)
        lights = mirror_ball_to_lights(lighting)
        return {
            b: relight(getattr(self, f"field_{b}").to(lighting.dtype), lights, self.size) for b in self.brdfs
        }

    def extra_repr(self) -> str:
        return f"size={self.size}, brdfs={self.brdfs}, lighting_size={self.lighting_size}"


class EncodeSphere(nn.Module):
    r"""Module twin of :func:`encode_sphere`.

    Args:
        gamma: ``"exact"`` (the metric) or ``"safe"`` (training), one of :data:`GAMMA_MODES`.

    Shape:
        - Input: :math:`(*)`
        - Output: :math:`(*)`

    Examples:
        >>> EncodeSphere("safe")(torch.tensor([0.0, 100.0])).tolist()
        [0.0, 1.0]
    """

    def __init__(self, gamma: str = "exact") -> None:
        super().__init__()
        gamma_knee(gamma)  # checked when built
        self.gamma = gamma

    def forward(self, render: torch.Tensor) -> torch.Tensor:
        return encode_sphere(render, self.gamma)

    def extra_repr(self) -> str:
        return f"gamma={self.gamma!r}"


class SpherePyramid(nn.Module):
    r"""Module twin of :func:`sphere_pyramid`.

    Args:
        sizes: sphere sides, each in :data:`SPHERE_SIZES`.
        brdfs: the spheres, names from :data:`BRDFS`.
        encode: apply :func:`encode_sphere`; otherwise return the linear renders.
        gamma: ``"exact"`` or ``"safe"``, see :func:`encode_sphere`.

    Shape:
        - Input: :math:`(B, 3, S_L, S_L)`
        - Output: ``{f"{brdf}_{size}":`` :math:`(B, 3, s, s)` ``}``

    Examples:
        >>> sorted(SpherePyramid(sizes=(4,), brdfs=("mirror",))(torch.ones(1, 3, 32, 32)))
        ['mirror_4']
    """

    def __init__(self, sizes: Sequence[int] = (4, 8, 16, 32), brdfs: Sequence[str] = BRDFS, encode: bool = True,
                 gamma: str = "exact") -> None:
        super().__init__()
        self.sizes, self.brdfs = check_sphere_sizes(sizes), _check_brdfs(brdfs)
        gamma_knee(gamma)  # checked when built
        self.encode, self.gamma = encode, gamma

    def forward(self, lighting: torch.Tensor) -> dict[str, torch.Tensor]:
        return sphere_pyramid(lighting, sizes=self.sizes, brdfs=self.brdfs, encode=self.encode,
                              gamma=self.gamma)

    def extra_repr(self) -> str:
        return f"sizes={self.sizes}, brdfs={self.brdfs}, encode={self.encode}, gamma={self.gamma!r}"
