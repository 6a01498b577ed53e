r"""The one-pass OLAT renderer: every light of the mirror-ball basis traced in one vectorised pass.

:func:`render_olat_onepass` computes the same reflectance field as the per-light reference of
:mod:`~kornia_ilum_lab.synth.lightstage.reference` (direct light, the same Mitsuba BSDFs), but instead of one
``mitsuba.render`` per light (812 renders at ``S = 32``, each with its fixed overhead) it traces, with
Dr.Jit's vectorised ``llvm_ad_rgb`` variant:

1. **Camera rays** (pinhole at the origin looking along -Z, horizontal ``fov_deg``), ``C = spp`` per pixel on a
   jittered ``k_u x k_v`` grid (``k_u k_v = C``, as square as ``C``'s divisors allow: 32 is 8 x 4). A ray
   continues through texels of alpha-tested parts (``opacity_texture < 0.5``, nearest texel) and through the
   cornea, at most :data:`MAX_LAYERS` surfaces. At a cornea hit seen from outside the Fresnel mirror's glint is
   recorded (weight ``F(theta)`` into the light that owns the reflected direction, if that direction is not
   shadowed) and the ray goes on with the thin-slab transmission ``1 - 2 r / (1 + r)`` (the reference's
   ``thindielectric``, :func:`~kornia_ilum_lab.synth.lightstage.materials.material_bsdf`). Camera rays are cheap: all
   ``C`` samples give the coverage, the albedo, the glints and the
   :class:`~kornia_ilum_lab.synth.lightstage.gbuffer.GBuffer`.
2. **Which hits trace the lights** (the expensive part). Without demodulation, all of them (the plain mean over
   the ``C`` samples). With it (the default when ``shade_spp < spp``), the terminal hits of a pixel are grouped
   by part (skin, hair cards, brows, eyes...), and a group of ``H_g`` of the pixel's ``H_p`` hits traces
   ``T_g = max(1, round(T H_g / H_p))`` of them, evenly spaced in the Z order of their strata (so spread over
   the pixel); ``T = shade_spp`` (4) in plain pixels and ``edge_spp`` (16) in *mixed* ones: partly covered
   (silhouettes), more than one part (hair over skin, brows, eyelids), or shading normals spread by more than
   :data:`EDGE_NORMAL_SPREAD` (creases, ears). About 10 % of a portrait's pixels are mixed and the light stage
   costs 5.3 traced samples per pixel instead of 4.
3. **Every light at every traced hit**: one direction is drawn uniformly (in mirror-ball ``(u, v)``, which is
   equal-area: ``dOmega = 4 du dv``) inside the region that light ``n`` owns, stratified over the ``T_g``
   traced hits of the group. The region is tabulated once per ``S`` as ``8 x 8`` sub-cells per pixel, each
   owned through :func:`~kornia_ilum.geometry.mirror_ball_pixel_index` of its centre (so the rim slivers
   belong to their nearest valid pixel, docs/conventions.rst "Mirror ball"); samples with ``r > 1`` count 0. A
   shadow ray (opaque parts; the cornea is transparent to it; alpha-tested parts are tested texel by texel,
   :data:`MAX_LAYERS` times) and the part's Mitsuba BSDF (``bsdf.eval``, which includes the cosine) give the
   sample ``f cos V * 4 A_n`` with ``A_n`` the ``(u, v)`` area of the light's region. The diffuse part is the
   same BSDF with ``specular = 0`` (Mitsuba's ``principled`` is linear in ``specular``; a ``diffuse`` part is
   all diffuse), the specular part the rest.
4. **Demodulation** (a ratio estimator per pixel and group): the traced hits measure the group's
   *irradiance factor* ``sum_i f_diffuse,i / sum_i albedo_i`` (albedo-free), the ``C`` samples its
   throughput-weighted albedo ``A_g`` and coverage ``alpha_g``: diffuse ``= A_g sum_i f_d,i / sum_i a_i``,
   specular ``= alpha_g mean_i f_s,i``. So texture, coverage and alpha-tested cards are anti-aliased with ``C``
   samples even under a single dominant light (the sun), while the lights are paid for ``T`` samples. This is
   linear in the lighting and exact for a group whose irradiance factor is constant over the pixel; it is
   approximate (a ratio estimator: the traced hits' albedo-weighted irradiance stands for the whole group's)
   where albedo and irradiance vary together inside one part and one pixel, e.g. a texel-sized shadow on a
   textured patch. The diffuse part of subsurface hits goes to ``diffuse`` (what subsurface scattering
   spreads), everything else to ``specular``; the cornea's glints are a mean over the ``C`` samples.

Measured (``benchmarks/bench_olat.py --reference onepass``: MakeHuman seed 1 view 0, 192 px, one thread of
the loaded 2-core machine; PSNR of relit 8-bit sRGB portraits against the mean of two one-pass fields at 32
samples that all trace every light, which agree with each other to 41.3 dB (sun) / 40.1 dB (overcast) and
with a 256-spp ``render_lighting`` Mitsuba render to 38.9 / 38.2 dB, that render's own noise):
``C:T:edge`` = 4:4 (the old default) 30.8 / 30.7 dB; 16:4:4 33.5 / 34.5; 16:4:16 35.4 / 36.6; 32:4:8
36.6 / 37.3; 32:4:16 (the default) 37.5 / 38.7 dB (seed 2 view 1: 4:4 30.1 / 31.1, 32:4:16 39.0 / 40.9). The
light stage dominates the cost, the camera rays are a small part of it (times in docs/lightstage.rst,
"Measured"). The remaining error sits on silhouettes (partly covered pixels: 4 % of the pixels, about 30 dB
there) and hair.

Cost. All ``C x P`` camera rays are traced as one batch (one kernel per layer). The light stage is chunked
over traced hits (``chunk_lanes`` light-hit pairs; same IR every chunk): a first kernel draws the directions and
tests the geometric horizon, the lanes above it (about half) are compacted (``dr.compress``) and only they pay
for the shadow rays; shadow rays that passed a transparent texel of an alpha-tested card go on alone
(compacted again), and only the visible lanes pay for the BSDF evaluations, scatter-added into the
``(pixel, light)`` accumulators. Every numpy array handed to Dr.Jit is copied to 64-byte aligned memory
first: Dr.Jit maps numpy memory and bakes the load alignment into the kernel, so randomly aligned inputs made
kernels differ between calls and recompile at every render. The first render of a process compiles the
kernels (less when Dr.Jit's disk cache has them).

The stages of :func:`render_olat_onepass`: the scenes and the light table, the camera rays (step 1,
``_trace_camera``), the trace plan (steps 2 and 4, ``_trace_plan``), the lights (step 3, ``_trace_lights``:
per chunk ``_draw_directions``, then ``_accumulate_visible``), then the glints and the G-buffer.
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from kornia_ilum.core.errors import TypeCheckError, ValueCheckError
from kornia_ilum.geometry import direction_to_mirror_ball, mirror_ball_pixel_index, mirror_ball_valid
from kornia_ilum_lab.synth.lightstage.gbuffer import GBuffer
from kornia_ilum_lab.synth.lightstage.materials import (
    diffuse_twin_bsdf,
    fresnel_ior,
    import_mitsuba,
    material_bsdf,
    mitsuba_mesh,
)
from kornia_ilum_lab.synth.lightstage.scene import Camera
from kornia_ilum_lab.synth.lightstage.settings import OnePass, is_vectorised

__all__ = ["EDGE_NORMAL_SPREAD", "MAX_LAYERS", "OnePassResult", "light_cells", "render_olat_onepass"]

#: Surfaces a camera or shadow ray may pass (cornea layers, transparent texels) before it stops.
MAX_LAYERS = 6

#: A pixel whose camera samples' shading normals have ``1 - |mean normal|`` above this is mixed (about 8 degrees
#: of spread): it traces ``edge_spp`` samples.
EDGE_NORMAL_SPREAD = 0.01

_CELLS = 8  # sub-cells per mirror-ball pixel axis for the light regions


@dataclass
class OnePassResult:
    """What :func:`render_olat_onepass` returns.

    Attributes:
        diffuse: ``(3, P', N_v)`` float32 diffuse part of the field at the ``rows`` pixels and ``cols`` lights,
            from hits on subsurface parts only (what subsurface scattering spreads).
        specular: ``(3, P', N_v)`` float32 the rest: specular lobes of subsurface parts, the whole response of
            the other parts, and the cornea's glints. ``diffuse + specular`` is the field.
        rows: int64 ``(P',)`` flat pixel indices (the pixels with any coverage or glint).
        cols: int64 ``(N_v,)`` the valid light indices.
        gbuffer: the :class:`GBuffer`.
        timings: seconds per stage.
        spp: camera samples per pixel ``C``.
        shade_spp: camera samples per pixel that traced the lights ``T``.
        demodulate: whether the shading was re-modulated by the ``C`` samples' coverage and albedo.
        traced: traced hits per covered pixel (the light stage's cost, in samples per pixel).

    Examples:
        >>> g = GBuffer(torch.zeros(3, 2, 2), torch.zeros(3, 2, 2), torch.zeros(1, 2, 2), torch.ones(1, 2, 2),
        ...             torch.zeros(1, 2, 2), focal_px=3.0)
        >>> part = torch.zeros(3, 4, 12)  # 4 pixels, the 12 valid lights of a 4 x 4 basis
        >>> result = OnePassResult(part, part.clone(), torch.arange(4), torch.arange(12), g, {}, spp=4)
        >>> (result.diffuse + result.specular).shape, result.shade_spp, result.demodulate
        (torch.Size([3, 4, 12]), 0, False)
    """

    diffuse: torch.Tensor
    specular: torch.Tensor
    rows: torch.Tensor
    cols: torch.Tensor
    gbuffer: GBuffer
    timings: dict[str, float]
    spp: int
    shade_spp: int = 0
    demodulate: bool = False
    traced: float = 0.0


def _morton(n: int) -> np.ndarray:
    """Row-major cell indices of an ``n x n`` grid (``n`` a power of 2) in Z order: blocks stay compact."""
    idx = np.arange(n * n)
    r = np.zeros_like(idx)
    c = np.zeros_like(idx)
    for b in range(int(math.log2(n))):
        c |= ((idx >> (2 * b)) & 1) << b
        r |= ((idx >> (2 * b + 1)) & 1) << b
    return r * n + c


@functools.lru_cache(maxsize=8)
def light_cells(lighting_size: int, cells: int = _CELLS) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    r"""The region of each valid light as sub-cells of the mirror ball.

    Args:
        lighting_size: the mirror-ball side ``S``.
        cells: sub-cells per pixel axis.

    Returns:
        ``(valid, start, count, corner)``: the valid light indices ``(N_v,)``; for each valid light the first
        row in ``corner`` and the number of its cells; ``corner`` ``(K, 2)`` float64 ``(u, v)`` of each cell's
        lower-left corner (cell side ``2 / (S cells)``). A light's own pixel comes first, in Z order, then its
        rim slivers. Only cells that reach inside the unit disk are listed.

    Examples:
        >>> valid, start, count, corner = light_cells(4, 2)
        >>> len(valid), int(count.min())
        (12, 4)
    """
    s, f = lighting_size, cells
    side = 2.0 / (s * f)
    g = s * f
    lo = -1.0 + side * np.arange(g)  # cell lower edges along u (columns) and v (rows from the bottom)
    cu, cv = np.meshgrid(lo, lo[::-1], indexing="xy")  # row 0 = top (largest v)
    nearest = np.maximum(0.0, np.maximum(cu, -(cu + side)) ) ** 2 + np.maximum(0.0, np.maximum(cv, -(cv + side))) ** 2
    reach = nearest < 1.0  # some of the cell is inside the disk
    centre = torch.from_numpy(np.stack([cu + side / 2, cv + side / 2], axis=-1))
    owner = mirror_ball_pixel_index(centre.reshape(-1, 2), s).numpy().reshape(g, g)
    own_pixel = (np.arange(g)[:, None] // f) * s + (np.arange(g)[None, :] // f)
    sub_order = _morton(f)
    local = ((np.arange(g)[:, None] % f) * f + np.arange(g)[None, :] % f)
    rank = np.argsort(sub_order)[local]  # Z-order rank of each cell within its pixel
    valid = np.flatnonzero(mirror_ball_valid(s).flatten().numpy())
    # sort key: owner, then own-pixel cells before slivers, then Z rank
    sel = reach.ravel()
    o = owner.ravel()[sel]
    key = np.lexsort(((own_pixel.ravel()[sel] != o) * (f * f) + rank.ravel()[sel], o))
    corner = np.stack([cu.ravel()[sel], cv.ravel()[sel]], axis=-1)[key]
    o = o[key]
    count = np.bincount(o, minlength=s * s)[valid]
    start = np.concatenate([[0], np.cumsum(np.bincount(o, minlength=s * s))])[valid]
    return valid, start.astype(np.int64), count.astype(np.int64), corner


def _aligned(x: np.ndarray, dtype: Any) -> np.ndarray:
    """A 64-byte aligned C-contiguous copy of ``x``.

    Dr.Jit maps numpy memory without copying and compiles the load's alignment into the kernel, so arrays of a
    random alignment give kernels that differ between calls and are compiled again (about a second each).
    """
    x = np.asarray(x, dtype=dtype)
    buf = np.empty(x.nbytes + 64, np.uint8)
    off = (-buf.ctypes.data) % 64
    out = buf[off:off + x.nbytes].view(x.dtype).reshape(x.shape)
    out[...] = x
    return out


def _jit(cls: Any, *arrays: np.ndarray, dtype: Any = np.float32) -> Any:
    """``cls(*arrays)`` from aligned copies (:func:`_aligned`)."""
    return cls(*[_aligned(a, dtype) for a in arrays])


# ----------------------------------------------------------------------------------------------
# scene


@dataclass
class _Part:
    index: int
    kind: str
    alpha_tested: bool
    subsurface: bool


def _opacity_texture(mi: Any, dr: Any, tex: np.ndarray) -> Any:
    t = (np.asarray(tex, dtype=np.float32) >= 0.5).astype(np.float32)[..., None]
    return mi.Texture2f(mi.TensorXf(t), filter_mode=dr.FilterMode.Nearest, wrap_mode=dr.WrapMode.Repeat)


class _Scenes:
    """The camera scene (all parts, their BSDFs), the opaque shadow scene and the alpha-tested one."""

    def __init__(self, mi: Any, dr: Any, subject: Any, transform: np.ndarray) -> None:
        self.mi, self.dr = mi, dr
        cam_objs: dict[str, Any] = {}
        shadow_objs: dict[str, Any] = {}
        alpha_objs: dict[str, Any] = {}
        self.parts: list[_Part] = []
        full, twin = [], []
        opacity: dict[int, Any] = {}
        dummy = {"type": "diffuse"}
        cam_ids, alpha_ids = [], []
        for i, part in enumerate(subject.parts):
            mat = part.material
            kind = mat.kind
            v = np.asarray(part.vertices, dtype=np.float64) @ transform[:3, :3].T + transform[:3, 3]
            f = np.asarray(part.faces)
            normals = getattr(part, "normals", None)
            if normals is not None:
                normals = np.asarray(normals, dtype=np.float64) @ transform[:3, :3].T
            uvs = getattr(part, "uvs", None)
            otex = getattr(mat, "opacity_texture", None)
            alpha_tested = otex is not None and uvs is not None
            name = f"part{i:03d}"
            bsdf = material_bsdf(mat) if kind != "cornea" else dummy
            mesh = mitsuba_mesh(mi, name, vertices=v, faces=f, normals=normals, bsdf=bsdf, uvs=uvs)
            cam_objs[name] = mesh
            cam_ids.append(mesh)
            if alpha_tested:
                amesh = mitsuba_mesh(mi, name, vertices=v, faces=f, normals=None, bsdf=dummy, uvs=uvs)
                alpha_objs[name] = amesh
                alpha_ids.append((i, amesh))
                opacity[i] = _opacity_texture(mi, dr, otex)
            elif kind != "cornea":
                shadow_objs[name] = mitsuba_mesh(mi, name, vertices=v, faces=f, normals=None, bsdf=dummy)
            full.append(mesh.bsdf())
            twin.append(mi.load_dict(diffuse_twin_bsdf(mat)) if kind != "cornea" else mesh.bsdf())
            self.parts.append(_Part(i, kind, alpha_tested, bool(getattr(mat, "subsurface", False))))
        self.cam = mi.load_dict({"type": "scene", **cam_objs})
        self.shadow = mi.load_dict({"type": "scene", **shadow_objs}) if shadow_objs else None
        self.alpha = mi.load_dict({"type": "scene", **alpha_objs}) if alpha_objs else None
        self.opacity = opacity

        def lut(meshes: list[tuple[int, Any]]) -> Any:
            ids = [int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(m))[0]) for _, m in meshes]
            table = np.full(max(ids, default=0) + 1, -1, dtype=np.int32)
            for (i, _), sid in zip(meshes, ids):
                table[sid] = i
            return _jit(mi.Int32, table, dtype=np.int32)

        self.cam_lut = lut(list(enumerate(cam_ids)))
        self.alpha_lut = lut(alpha_ids)
        self._keep = (full, twin)  # the pointer arrays below do not own their BSDFs
        self.full = mi.BSDFPtr(full)
        self.twin = mi.BSDFPtr(twin)
        kinds = [p.kind for p in self.parts]
        self.is_cornea = _jit(mi.Bool, [k == "cornea" for k in kinds], dtype=bool)
        self.is_alpha = _jit(mi.Bool, [p.alpha_tested for p in self.parts], dtype=bool)
        self.is_sss = _jit(mi.Float, [float(p.subsurface) for p in self.parts])
        self.is_lambert = _jit(mi.Float, [float(k == "diffuse") for k in kinds])
        self.needs_twin = _jit(mi.Float, [float(k not in ("diffuse", "cornea")) for k in kinds])
        self.cornea_params = {}
        for i, part in enumerate(subject.parts):
            if part.material.kind == "cornea":
                f0 = 0.08 * max(float(getattr(part.material, "specular", 0.5)), 1e-3)
                self.cornea_params[i] = (fresnel_ior(f0), fresnel_ior(f0 / (2.0 - f0)))
        eta_m = np.ones(len(self.parts), np.float32)
        eta_s = np.ones(len(self.parts), np.float32)
        for i, (m, s) in self.cornea_params.items():
            eta_m[i], eta_s[i] = m, s
        self.eta_mirror, self.eta_slab = _jit(mi.Float, eta_m), _jit(mi.Float, eta_s)

    def part_of(self, si: Any, lut: Any) -> Any:
        dr, mi = self.dr, self.mi
        sid = dr.reinterpret_array(mi.UInt32, si.shape)
        return dr.select(si.is_valid(), dr.gather(mi.Int32, lut, sid, si.is_valid()), -1)

    def opaque_texel(self, si: Any, part: Any, active: Any) -> Any:
        """Whether the alpha-tested hit is on an opaque texel (True for parts that are not alpha-tested)."""
        dr, mi = self.dr, self.mi
        opaque = mi.Bool(True)
        for i, tex in self.opacity.items():
            hit = active & (part == i)
            value = tex.eval(si.uv, active=hit)[0]
            opaque = dr.select(hit, value >= 0.5, opaque)
        return opaque

    def _alpha_step(self, ray: Any, vis: Any, todo: Any) -> tuple[Any, Any, Any]:
        """One alpha-tested layer of shadow rays: blocked by an opaque texel, or on through a transparent one."""
        dr, mi = self.dr, self.mi
        hit = self.alpha.ray_intersect(ray, ray_flags=mi.RayFlags.Minimal | mi.RayFlags.UV, coherent=False,
                                       active=todo)
        todo = todo & hit.is_valid()
        part = self.part_of(hit, self.alpha_lut)
        blocked = todo & self.opaque_texel(hit, part, todo)
        vis = vis & ~blocked
        todo = todo & ~blocked
        ray = dr.select(todo, hit.spawn_ray(ray.d), ray)
        return ray, vis, todo

    def visible(self, si: Any, wo: Any, active: Any, compact: bool = False) -> Any:
        """Whether the direction ``wo`` from the hit ``si`` escapes (shadow rays; the cornea is transparent).

        With ``compact``, the rays still going after the first alpha-tested layer (those that passed a
        transparent texel: few) are evaluated, compressed and continued alone, instead of carrying every lane
        through :data:`MAX_LAYERS` masked intersections (this ends the caller's kernel there).
        """
        dr, mi = self.dr, self.mi
        ray = si.spawn_ray(wo)
        vis = mi.Bool(active)
        if self.shadow is not None:
            vis &= ~self.shadow.ray_test(ray, active)
        if self.alpha is not None:
            todo = mi.Bool(vis)
            ray, vis, todo = self._alpha_step(ray, vis, todo)
            if compact:
                dr.eval(ray, vis, todo)
                idx = dr.compress(todo)
                if dr.width(idx):
                    r = dr.gather(mi.Ray3f, ray, idx)
                    v = dr.full(mi.Bool, True, dr.width(idx))
                    t = dr.full(mi.Bool, True, dr.width(idx))
                    for _ in range(MAX_LAYERS - 1):
                        r, v, t = self._alpha_step(r, v, t)
                    dr.scatter(vis, v & ~t, idx)  # still inside a stack of transparent texels: blocked
                return vis
            for _ in range(MAX_LAYERS - 1):
                ray, vis, todo = self._alpha_step(ray, vis, todo)
            vis &= ~todo  # still inside a stack of transparent texels: counted as blocked
        return vis


# ----------------------------------------------------------------------------------------------
# rendering


def _camera_dirs(camera: Camera, spp: int, rng: np.random.Generator) -> np.ndarray:
    """Unit ray directions ``(spp, P, 3)`` float32 and the sub-pixel positions used."""
    size = camera.size
    kv = max(d for d in range(1, math.isqrt(spp) + 1) if spp % d == 0)  # a kv x ku grid, ku * kv = spp
    ku = spp // kv
    s = np.arange(spp)
    su, sv = (s % ku)[:, None], (s // ku)[:, None]
    ju = (su + rng.random((spp, size * size))) / ku
    jv = (sv + rng.random((spp, size * size))) / kv
    i, j = np.divmod(np.arange(size * size), size)
    tanh = math.tan(math.radians(camera.fov_deg) / 2)
    x = ((j + ju) / size * 2 - 1) * tanh
    y = (1 - (i + jv) / size * 2) * tanh
    d = np.stack([x, y, -np.ones_like(x)], axis=-1)
    return (d / np.linalg.norm(d, axis=-1, keepdims=True)).astype(np.float32)


@functools.lru_cache(maxsize=16)
def _strata_rank(spp: int) -> np.ndarray:
    """Rank of each camera stratum ``s`` (``su = s % ku``, ``sv = s // ku``, :func:`_camera_dirs`) in Z order.

    Evenly spaced picks in this order are spread over the pixel (the traced hits of :func:`render_olat_onepass`).
    """
    kv = max(d for d in range(1, math.isqrt(spp) + 1) if spp % d == 0)
    ku = spp // kv
    s = np.arange(spp)
    su, sv = s % ku, s // ku
    code = np.zeros(spp, np.int64)
    for b in range(max(ku, kv).bit_length()):
        code |= ((su >> b) & 1) << (2 * b) | ((sv >> b) & 1) << (2 * b + 1)
    rank = np.empty(spp, np.int64)
    rank[np.argsort(code, kind="stable")] = np.arange(spp)
    return rank


def _dir_to_light(dirs: np.ndarray, lighting_size: int) -> np.ndarray:
    uv = direction_to_mirror_ball(torch.from_numpy(dirs.astype(np.float64)))
    return mirror_ball_pixel_index(uv, lighting_size).numpy()


def render_olat_onepass(
    subject: Any,
    camera: Camera,
    *,
    transform: np.ndarray,
    settings: OnePass,
    callback: Any = None,
) -> OnePassResult:
    r"""Trace every light of the basis at once (module docstring). Mitsuba's ``llvm_ad_rgb`` must be active.

    Args:
        subject: the subject (validated by the caller).
        camera: the camera.
        transform: subject-to-camera transform (:func:`~kornia_ilum_lab.synth.lightstage.scene.camera_transform`).
        settings: the :class:`~kornia_ilum_lab.synth.lightstage.settings.OnePass` settings: the mirror-ball side
            ``S``, the camera samples ``C = spp`` (coverage, albedo, G-buffer, glints), ``T = shade_spp`` that
            trace every light in plain pixels (module docstring, step 2), ``edge_spp`` in mixed pixels (partly
            covered, more than one part, or normals spread by more than :data:`EDGE_NORMAL_SPREAD`),
            ``demodulate`` (module docstring, step 4), the seed (camera jitter and light samples) and
            ``chunk_lanes`` (light-hit pairs per kernel). Its post-processing settings are the caller's.
        callback: called with a fraction of the work done (floats summing to 1), for progress bars.

    Returns:
        the :class:`OnePassResult`.

    Raises:
        TypeCheckError: ``settings`` is not :class:`~kornia_ilum_lab.synth.lightstage.settings.OnePass`.
        ValueCheckError: the active Mitsuba variant is not vectorised.

    Convention:
        Camera frame of docs/conventions.rst ("Frames"); lights in the row-major order of the ``S x S``
        mirror-ball grid ("Mirror ball"), each a unit radiance over its pixel's solid angle.

    Examples:
        >>> from kornia_ilum_lab.synth.lightstage.settings import Reference
        >>> render_olat_onepass(None, Camera(30.0, 1.0, 0.0, 0.0, size=8), transform=np.eye(4),
        ...                     settings=Reference())
        Traceback (most recent call last):
        ...
        kornia.core.exceptions.TypeCheckError: settings must be OnePass settings, got Reference
        >>> result = render_olat_onepass(subject, camera, transform=transform,
        ...                              settings=OnePass(lighting_size=8))  # doctest: +SKIP
    """
    import drjit as dr  # lazy: Dr.Jit comes with Mitsuba, an optional extra

    mi = import_mitsuba()
    if not isinstance(settings, OnePass):
        raise TypeCheckError(f"settings must be OnePass settings, got {type(settings).__name__}")
    if not mi.variant() or not is_vectorised(mi.variant()):
        raise ValueCheckError(f"the one-pass renderer needs a vectorised Mitsuba variant, got {mi.variant()}")
    spp = settings.spp
    t0 = time.perf_counter()
    timings: dict[str, float] = {}
    sc = _Scenes(mi, dr, subject, transform)
    table = _light_table(mi, settings.lighting_size)
    timings["scene"] = time.perf_counter() - t0

    rng = np.random.default_rng(settings.seed)
    dirs = _camera_dirs(camera, spp, rng)
    t1 = time.perf_counter()
    cam = _trace_camera(mi, dr, sc=sc, dirs=dirs, p_count=camera.size * camera.size)
    plan = _trace_plan(cam.layers, cam.row_of, n_rows=cam.n_rows, p_count=cam.p_count, spp=spp,
                       shade_spp=settings.shade_spp, edge_spp=settings.edge_spp,
                       demodulate=settings.demodulate, n_parts=len(sc.parts), rng=rng)
    timings["camera"] = time.perf_counter() - t1
    traced = len(plan[0]) / max(cam.n_rows, 1)

    t2 = time.perf_counter()
    diffuse, specular = _trace_lights(mi, dr, sc=sc, table=table, plan=plan, n_rows=cam.n_rows,
                                      settings=settings, callback=callback)
    timings["lights"] = time.perf_counter() - t2

    rows_all, diffuse, specular = _add_glints(cam, table.valid, diffuse=diffuse, specular=specular,
                                              lighting_size=settings.lighting_size, spp=spp)
    gbuf = _gbuffer(cam, camera, spp)
    timings["total"] = time.perf_counter() - t0
    return OnePassResult(diffuse, specular, torch.from_numpy(rows_all), torch.from_numpy(table.valid), gbuf,
                         {k: round(v, 3) for k, v in timings.items()}, spp, settings.shade_spp,
                         settings.demodulate, round(traced, 3))


@dataclass
class _LightTable:
    """The light regions of :func:`light_cells` as Dr.Jit arrays (:func:`_light_table`)."""

    valid: np.ndarray  # (N_v,) valid light indices
    cell: float  # sub-cell side in (u, v)
    start: Any  # UInt32 (N_v,): each light's first sub-cell
    count: Any  # UInt32 (N_v,): its number of sub-cells
    weight: Any  # Float (N_v,): 4 x the (u, v) area of its region
    c_u: Any  # Float (K,): each sub-cell's lower-left corner
    c_v: Any

    @property
    def nv(self) -> int:
        return len(self.valid)


def _light_table(mi: Any, lighting_size: int) -> _LightTable:
    valid, start, count, corner = light_cells(lighting_size)
    cell = 2.0 / (lighting_size * _CELLS)
    l_start, l_count = _jit(mi.UInt32, start, dtype=np.uint32), _jit(mi.UInt32, count, dtype=np.uint32)
    l_weight = _jit(mi.Float, 4.0 * count * cell * cell)  # 4 x (u, v) area of the region
    c_u, c_v = _jit(mi.Float, corner[:, 0]), _jit(mi.Float, corner[:, 1])
    return _LightTable(valid, cell, l_start, l_count, l_weight, c_u, c_v)


@dataclass
class _CameraPass:
    """What the camera rays found (:func:`_trace_camera`): G-buffer sums, glints and terminal hits."""

    p_count: int  # pixels P
    glints: list  # (pixel, reflected dir, weight) per layer with glints
    albedo: np.ndarray  # (3, P) float64 sums over the samples
    normal: np.ndarray  # (3, P)
    depth: np.ndarray  # (P,)
    alpha: np.ndarray  # (P,) samples that hit
    sss: np.ndarray  # (P,)
    layers: list  # per layer: stopping lanes, ray origins, directions, throughput, albedo, sss, part, normal
    rows_all: np.ndarray  # the covered pixels
    row_of: np.ndarray  # (P,) row of each covered pixel, -1 elsewhere

    @property
    def n_rows(self) -> int:
        return len(self.rows_all)


def _trace_camera(mi: Any, dr: Any, *, sc: _Scenes, dirs: np.ndarray, p_count: int) -> _CameraPass:
    """Step 1: all camera samples of all pixels in one batch (lane = sample * P + pixel), through transparent
    texels and the cornea, at most :data:`MAX_LAYERS` surfaces."""
    glints = []  # (pixel, reflected dir, weight)
    g_albedo = np.zeros((3, p_count), np.float64)
    g_normal = np.zeros((3, p_count), np.float64)
    g_depth = np.zeros(p_count, np.float64)
    g_alpha = np.zeros(p_count, np.float64)
    g_sss = np.zeros(p_count, np.float64)
    n_cam = dirs.shape[0] * p_count
    d = dirs.reshape(n_cam, 3)
    ray = mi.Ray3f(dr.zeros(mi.Point3f, n_cam), _jit(mi.Vector3f, d[:, 0], d[:, 1], d[:, 2]))
    active = dr.full(mi.Bool, True, n_cam)
    through = dr.full(mi.Float, 1.0, n_cam)
    layers = []  # per layer: lanes that stop there, ray origins, directions, throughput, albedo, subsurface
    for _ in range(MAX_LAYERS):
        si = sc.cam.ray_intersect(ray, active)
        active &= si.is_valid()
        part = sc.part_of(si, sc.cam_lut)
        pc = dr.maximum(part, 0)
        cornea = active & dr.gather(mi.Bool, sc.is_cornea, pc, active)
        alpha_part = active & dr.gather(mi.Bool, sc.is_alpha, pc, active)
        pass_texel = alpha_part & ~sc.opaque_texel(si, part, alpha_part)
        stop = active & ~cornea & ~pass_texel
        n_sh = si.sh_frame.n
        gw = mi.Float(0.0)
        refl = mi.Vector3f(0.0)
        if sc.cornea_params:
            # one-sided Fresnel mirror of the cornea (the conductor with k = 0 of the reference)
            outside = cornea & (dr.dot(si.n, -ray.d) > 0)
            cos_sh = dr.abs(dr.dot(n_sh, -ray.d))
            f_m = mi.fresnel(cos_sh, dr.gather(mi.Float, sc.eta_mirror, pc, cornea))[0]
            r_s = mi.fresnel(cos_sh, dr.gather(mi.Float, sc.eta_slab, pc, cornea))[0]
            refl = ray.d - 2.0 * dr.dot(ray.d, n_sh) * n_sh
            vis = sc.visible(si, refl, outside)
            gw = dr.select(outside & vis, through * f_m, 0.0)
        # terminal hits: G-buffer
        bsdf = dr.gather(mi.BSDFPtr, sc.full, pc, stop)
        albedo = bsdf.eval_diffuse_reflectance(si, stop)
        nrm = dr.select(dr.dot(n_sh, ray.d) > 0, -n_sh, n_sh)
        sss = dr.gather(mi.Float, sc.is_sss, pc, stop)
        depth = -si.p.z
        dr.eval(gw, refl, stop, albedo, nrm, sss, depth, ray, through)
        stop_np = np.asarray(stop)
        sel = np.flatnonzero(stop_np)
        if sc.cornea_params:
            gw_np = np.asarray(gw)
            gsel = np.flatnonzero(gw_np > 0)
            if len(gsel):
                glints.append((gsel % p_count, np.asarray(refl)[:, gsel].T, gw_np[gsel]))
        if len(sel):
            pix = sel % p_count
            alb = np.asarray(albedo)[:, sel]
            g_albedo += np.stack([np.bincount(pix, c, p_count) for c in alb])
            g_normal += np.stack([np.bincount(pix, c, p_count) for c in np.asarray(nrm)[:, sel]])
            g_depth += np.bincount(pix, np.asarray(depth)[sel], p_count)
            g_alpha += np.bincount(pix, None, p_count)
            s_np = np.asarray(sss)[sel]
            g_sss += np.bincount(pix, s_np, p_count)
            layers.append((sel, np.asarray(ray.o)[:, sel].T, np.asarray(ray.d)[:, sel].T, np.asarray(through)[sel],
                           alb.T, s_np > 0, np.asarray(part)[sel], np.asarray(nrm)[:, sel].T))
        if sc.cornea_params:
            through = dr.select(cornea, through * (1.0 - 2.0 * r_s / (1.0 + r_s)), through)
        active &= ~stop
        ray = dr.select(active, si.spawn_ray(ray.d), ray)
        if not bool(dr.any(active)):
            break
    rows_all = np.flatnonzero(g_alpha > 0)
    row_of = np.full(p_count, -1, np.int64)
    row_of[rows_all] = np.arange(len(rows_all))
    return _CameraPass(p_count, glints, g_albedo, g_normal, g_depth, g_alpha, g_sss, layers, rows_all, row_of)


@dataclass
class _Chunk:
    """One chunk of traced hits of the light stage, as Dr.Jit arrays (:func:`_trace_lights`)."""

    start: int  # index of its first traced hit
    n_h: int  # its traced hits
    si: Any  # their surface interactions
    strat: Any  # Float: stratum of each hit among its group's traced hits
    n_strat: Any  # Float: strata of its group
    row: Any  # UInt32: its pixel row
    w_diffuse: Any  # Color3f
    w_specular: Any  # Float
    sss: Any  # Bool: on a subsurface part


def _trace_lights(mi: Any, dr: Any, *, sc: _Scenes, table: _LightTable, plan: tuple, n_rows: int,
                  settings: OnePass, callback: Any) -> tuple[torch.Tensor, torch.Tensor]:
    """Step 3: every light at every traced hit, in chunks of ``chunk_lanes`` light-hit pairs; returns the
    ``(3, n_rows, N_v)`` diffuse (subsurface hits) and specular (the rest) parts."""
    nv = table.nv
    ctx = mi.BSDFContext()
    # accumulated by Dr.Jit's scatter-add: (row, light) -> row * N_v + light
    acc_d = dr.zeros(mi.Color3f, max(n_rows * nv, 1))  # the diffuse part of subsurface hits
    acc_s = dr.zeros(mi.Color3f, max(n_rows * nv, 1))  # the rest
    tr_row, tr_rank, tr_cnt, tr_o, tr_d, tr_wd, tr_ws, tr_sss = plan
    total = len(tr_row)
    hc = max(1, settings.chunk_lanes // nv)
    twin_at = sc.needs_twin if settings.demodulate else sc.is_sss
    for a in range(0, total, hc):
        b = min(total, a + hc)
        n_h = b - a
        ray = mi.Ray3f(_jit(mi.Point3f, *tr_o[a:b].T), _jit(mi.Vector3f, *tr_d[a:b].T))
        si = sc.cam.ray_intersect(ray)
        strat = _jit(mi.Float, tr_rank[a:b])
        n_strat = _jit(mi.Float, tr_cnt[a:b])
        chunk = _Chunk(a, n_h, si, strat, n_strat, _jit(mi.UInt32, tr_row[a:b], dtype=np.uint32),
                       _jit(mi.Color3f, *tr_wd[a:b].T), _jit(mi.Float, tr_ws[a:b]),
                       _jit(mi.Bool, tr_sss[a:b], dtype=bool))
        dr.eval(si, strat, n_strat)
        wo, up = _draw_directions(mi, dr, chunk=chunk, table=table, seed=settings.seed)
        # kernel 2, on the lanes above the horizon only (about half): shadow rays and BSDF evaluations
        idx = dr.compress(up)
        if dr.width(idx):
            _accumulate_visible(mi, dr, sc=sc, chunk=chunk, table=table, idx=idx, wo=wo, ctx=ctx,
                                twin_at=twin_at, demodulate=settings.demodulate, acc_d=acc_d,
                                acc_s=acc_s)
        if callback is not None:
            callback(n_h / max(total, 1))
    diffuse = torch.from_numpy(np.array(acc_d, dtype=np.float32)[:, :n_rows * nv]).reshape(3, n_rows, nv)
    specular = torch.from_numpy(np.array(acc_s, dtype=np.float32)[:, :n_rows * nv]).reshape(3, n_rows, nv)
    return diffuse, specular


def _draw_directions(mi: Any, dr: Any, *, chunk: _Chunk, table: _LightTable, seed: int) -> tuple[Any, Any]:
    """Kernel 1: one stratified direction per (hit, light) lane, and whether it is above the horizon."""
    nv = table.nv
    lane = dr.arange(mi.UInt32, chunk.n_h * nv)
    h = lane // nv
    light = lane - h * nv
    sih = dr.gather(mi.SurfaceInteraction3f, chunk.si, h)
    key = dr.opaque(mi.UInt32, (seed * 7919 + chunk.start * 31) & 0x7FFFFFFF)
    rng_d = mi.PCG32(dr.width(lane), lane + key * 2654435761)
    cnt = dr.gather(mi.UInt32, table.count, light)
    s_frac = ((dr.gather(mi.Float, chunk.strat, h) + rng_d.next_float32())
              / dr.gather(mi.Float, chunk.n_strat, h))
    k = dr.minimum(mi.UInt32(s_frac * mi.Float(cnt)), cnt - 1)
    cidx = dr.gather(mi.UInt32, table.start, light) + k
    u = dr.gather(mi.Float, table.c_u, cidx) + table.cell * rng_d.next_float32()
    v = dr.gather(mi.Float, table.c_v, cidx) + table.cell * rng_d.next_float32()
    r2 = u * u + v * v
    sq = 2.0 * dr.safe_sqrt(1.0 - r2)
    wo = mi.Vector3f(u * sq, v * sq, 1.0 - 2.0 * r2)
    ng = sih.n
    up = (r2 <= 1.0) & (dr.dot(ng, wo) * dr.dot(ng, sih.to_world(sih.wi)) > 0)
    dr.eval(wo, up)
    return wo, up


def _accumulate_visible(mi: Any, dr: Any, *, sc: _Scenes, chunk: _Chunk, table: _LightTable, idx: Any,
                        wo: Any, ctx: Any, twin_at: Any, demodulate: bool, acc_d: Any, acc_s: Any) -> None:
    """Kernels 2 and 3 on the lanes ``idx`` above the horizon: shadow rays, then the BSDFs of the visible
    lanes only, scatter-added into the accumulators ``acc_d`` (diffuse of subsurface hits) and ``acc_s``
    (the rest)."""
    nv = table.nv
    h = idx // nv
    light = idx - h * nv
    wo = dr.gather(mi.Vector3f, wo, idx)
    sih = dr.gather(mi.SurfaceInteraction3f, chunk.si, h)
    vis = sc.visible(sih, wo, mi.Bool(True), compact=True)
    # kernel 3: the BSDFs of the visible lanes only, added into the accumulators
    j = dr.compress(vis)
    if not dr.width(j):
        return
    idx = dr.gather(mi.UInt32, idx, j)
    wo = dr.gather(mi.Vector3f, wo, j)
    h = idx // nv
    light = idx - h * nv
    sih = dr.gather(mi.SurfaceInteraction3f, chunk.si, h)
    part = dr.maximum(sc.part_of(sih, sc.cam_lut), 0)
    wo_l = sih.to_local(wo)
    weight = dr.gather(mi.Float, table.weight, light)
    bs_full = dr.gather(mi.BSDFPtr, sc.full, part)
    f_full = bs_full.eval(ctx, sih, wo_l) * weight
    # the diffuse part: the twin (specular = 0) of principled parts where it is needed (subsurface
    # hits; with demodulation every principled hit), the whole response of diffuse parts
    twin = dr.gather(mi.Float, twin_at, part) > 0
    bs_twin = dr.gather(mi.BSDFPtr, sc.twin, part, twin)
    f_diff = dr.select(twin, bs_twin.eval(ctx, sih, wo_l, twin) * weight, 0.0)
    if demodulate:
        f_diff = dr.select(dr.gather(mi.Float, sc.is_lambert, part) > 0, f_full, f_diff)
    wd = dr.gather(mi.Color3f, chunk.w_diffuse, h) * f_diff
    ws = dr.gather(mi.Float, chunk.w_specular, h) * (f_full - f_diff)
    target = dr.gather(mi.UInt32, chunk.row, h) * nv + light
    sss = dr.gather(mi.Bool, chunk.sss, h)
    dr.scatter_reduce(dr.ReduceOp.Add, acc_d, wd, target, sss)
    dr.scatter_reduce(dr.ReduceOp.Add, acc_s, dr.select(sss, ws, ws + wd), target)
    dr.eval(acc_d, acc_s)


def _add_glints(cam: _CameraPass, valid: np.ndarray, *, diffuse: torch.Tensor, specular: torch.Tensor,
                lighting_size: int, spp: int) -> tuple[np.ndarray, torch.Tensor, torch.Tensor]:
    """The cornea's glints, a mean over the ``C`` samples, added to ``specular``; a glint over nothing opaque
    behind it adds its pixel as a new row. Returns the rows and both parts."""
    rows_all, row_of = cam.rows_all, cam.row_of
    nv = len(valid)
    for gsel, refl, w in cam.glints:
        li = _dir_to_light(refl, lighting_size)
        col = np.searchsorted(valid, li)
        r = row_of[gsel]
        keep = r >= 0  # a glint over nothing opaque behind it still lights its pixel
        if not keep.all():
            extra = np.setdiff1d(gsel[~keep], rows_all)
            rows_all = np.concatenate([rows_all, extra])
            row_of[extra] = np.arange(len(rows_all) - len(extra), len(rows_all))
            pad = torch.zeros(3, len(extra), nv)
            diffuse, specular = torch.cat([diffuse, pad], 1), torch.cat([specular, pad], 1)
            r = row_of[gsel]
        np_spec = specular.numpy()
        np.add.at(np_spec, (slice(None), r, col), (w / spp)[None].astype(np.float32))
    return rows_all, diffuse, specular


def _gbuffer(cam: _CameraPass, camera: Camera, spp: int) -> GBuffer:
    """The :class:`GBuffer`: means over the covering samples, coverage and subsurface over all ``C``."""
    size = camera.size
    cover = np.maximum(cam.alpha, 1.0)
    return GBuffer(
        albedo=torch.from_numpy((cam.albedo / cover).reshape(3, size, size)).float(),
        normal=torch.from_numpy((cam.normal / cover).reshape(3, size, size)).float(),
        depth=torch.from_numpy((cam.depth / cover).reshape(1, size, size)).float(),
        alpha=torch.from_numpy((cam.alpha / spp).reshape(1, size, size)).float(),
        subsurface=torch.from_numpy((cam.sss / spp).reshape(1, size, size)).float(),
        focal_px=0.5 * size / math.tan(math.radians(camera.fov_deg) / 2),
    )


def _trace_plan(layers: list, row_of: np.ndarray, *, n_rows: int, p_count: int, spp: int, shade_spp: int,
                edge_spp: int, demodulate: bool, n_parts: int, rng: np.random.Generator) -> tuple:
    r"""Which terminal hits trace the lights, their light strata and their weights.

    The hits are grouped per pixel and part ``g`` (``H_g`` of the ``C`` camera samples). Without demodulation
    every hit is traced with weight ``throughput / C``. With it, a group traces ``T_g = max(1, round(T H_g /
    H_p))`` of its hits (``H_p`` the pixel's), evenly spaced in the Z order of their strata (a random offset per
    group); the ``t``-th of them takes the ``t``-th of ``T_g`` light strata. Weights: the diffuse part
    ``A_g / a_g`` per channel, with ``A_g`` the mean over the ``C`` samples of ``throughput x albedo`` in ``g``
    and ``a_g`` the sum of the traced hits' albedos (a ratio estimator: the traced hits measure the group's
    irradiance factor, the ``C`` samples its coverage and albedo); the specular part ``alpha_g / T_g`` with
    ``alpha_g`` the mean throughput-weighted coverage of ``g``.

    Returns:
        ``(row, stratum, strata, origin, direction, w_diffuse (K, 3), w_specular (K,), subsurface)`` per traced
        hit.
    """
    if not layers:
        z = np.zeros(0, np.int64)
        return z, z, z, np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3), np.float32), np.zeros(0, np.float32), \
            np.zeros(0, bool)
    lanes = np.concatenate([x[0] for x in layers])
    o_all, d_all = np.concatenate([x[1] for x in layers]), np.concatenate([x[2] for x in layers])
    t_all = np.concatenate([x[3] for x in layers]).astype(np.float64)
    a_all = np.concatenate([x[4] for x in layers]).astype(np.float64)
    s_all = np.concatenate([x[5] for x in layers])
    part = np.concatenate([x[6] for x in layers]).astype(np.int64)
    n_all = np.concatenate([x[7] for x in layers]).astype(np.float64)
    row = row_of[lanes % p_count]
    rank = _strata_rank(spp)[lanes // p_count]
    gid = row * n_parts + part
    order = np.lexsort((rank, gid))
    gid, row = gid[order], row[order]
    o_all, d_all, t_all, a_all, s_all = o_all[order], d_all[order], t_all[order], a_all[order], s_all[order]
    groups, first, h_g = np.unique(gid, return_index=True, return_counts=True)
    g_of = np.repeat(np.arange(len(groups)), h_g)
    g_row = row[first]
    if demodulate:
        h_p = np.bincount(g_row, h_g, n_rows)
        # mixed pixels (partly covered, more than one part, or a spread of normals: silhouettes, hair, creases)
        # trace edge_spp of their hits, the others shade_spp
        n_sum = np.stack([np.bincount(row, n_all[order][:, c], n_rows) for c in range(3)], 1)
        spread = 1.0 - np.linalg.norm(n_sum, axis=1) / np.maximum(h_p, 1)
        mixed = (h_p < spp) | (np.bincount(g_row, None, n_rows) > 1) | (spread > EDGE_NORMAL_SPREAD)
        t_p = np.where(mixed, edge_spp, shade_spp)[g_row]
        t_g = np.minimum(h_g, np.maximum(1, np.rint(t_p * h_g / h_p[g_row]))).astype(np.int64)
    else:
        t_g = h_g
    t_grp = np.repeat(np.arange(len(groups)), t_g)
    t_rank = np.arange(len(t_grp)) - np.repeat(np.cumsum(t_g) - t_g, t_g)
    off = rng.random(len(groups))[t_grp] if demodulate else np.zeros(len(t_grp))
    pick = first[t_grp] + np.floor((t_rank + off) * h_g[t_grp] / t_g[t_grp]).astype(np.int64)
    if demodulate:
        cam_a = np.stack([np.bincount(g_of, a_all[:, c] * t_all, len(groups)) for c in range(3)], 1) / spp
        cov = np.bincount(g_of, t_all, len(groups)) / spp
        tr_a = np.stack([np.bincount(t_grp, a_all[pick, c], len(groups)) for c in range(3)], 1)
        w_s = cov / t_g
        w_d = np.where(tr_a > 1e-6, cam_a / np.maximum(tr_a, 1e-6), w_s[:, None])[t_grp]
        w_s = w_s[t_grp]
    else:
        w_s = t_all[pick] / spp
        w_d = np.repeat(w_s[:, None], 3, 1)
    return (g_row[t_grp], t_rank, t_g[t_grp], o_all[pick], d_all[pick], w_d.astype(np.float32),
            w_s.astype(np.float32), s_all[pick])
