r"""One-light-at-a-time (OLAT) reflectance fields of synthetic subjects, rendered with Mitsuba 3.

A reflectance field ``R`` holds, for every image pixel ``p`` and every light ``n`` of the ``S x S`` mirror-ball
lighting basis (SPEC.md), the pixel's linear response to unit radiance arriving from the solid angle of
mirror-ball pixel ``n``. Any lighting ``L`` (a mirror ball in radiance) then relights the subject exactly as the
renderer would have: ``I[c, p] = sum_n R[c, p, n] L[n, c]`` (:func:`kornia_ilum.render.relight`). This is the
virtual light stage of LeGendre et al. 2020 ("Learning Illumination from Diverse Portraits"), who relit
photographed subjects the same way (Debevec et al. 2000, "Acquiring the reflectance field of a human face").

Two renderers make the same field (direct light, the Mitsuba BSDFs of
:func:`~kornia_ilum.synth.lightstage.materials.material_bsdf`):

- :func:`render_olat` (the default, ``method="onepass"``): all lights in one vectorised Dr.Jit pass,
  :mod:`~kornia_ilum.synth.lightstage.onepass`, then the subsurface step of
  :mod:`~kornia_ilum.synth.lightstage.subsurface` on the skin's diffuse part (and optionally the denoiser of
  :mod:`~kornia_ilum.synth.lightstage.denoise`), both linear in the lighting; about 13 s per subject-view at
  192 x 192 on one core.
- :func:`~kornia_ilum.synth.lightstage.reference.render_olat_reference`: one Mitsuba render per light, the
  reference of the tests and of ``benchmarks/bench_olat.py``; minutes per subject-view.

The lighting frame is the *camera* frame of SPEC.md; the field is premultiplied by the pixel coverage
``alpha`` (background 0): composite with ``I + (1 - alpha) B``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from dataclasses import field as dataclass_field
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from kornia_ilum.core.check import check_choice, check_positive_int
from kornia_ilum.core.errors import TypeCheckError, ValueCheckError
from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum.synth.lightstage.materials import (
    _check_subject,
    _import_mitsuba,
    material_bsdf,
    select_mitsuba_variant,
)
from kornia_ilum.synth.lightstage.denoise import denoise_field
from kornia_ilum.synth.lightstage.scene import Camera, _pivot, camera_transform, project_points
from kornia_ilum.synth.lightstage.subsurface import subsurface_scatter

if TYPE_CHECKING:  # the subjects module is only needed for the annotation
    from kornia_ilum.synth.lightstage.subjects import Subject

__all__ = ["ONEPASS_EDGE_SPP", "ONEPASS_SHADE_SPP", "ONEPASS_SPP", "ReflectanceField", "render_olat"]

@dataclass
class ReflectanceField:
    r"""An OLAT reflectance field of one subject seen by one camera.

    Attributes:
        field: ``(3, P, N)`` bfloat16, channel-major, ``P = size * size`` pixels in row-major order and
            ``N = lighting_size ** 2`` lights in the row-major order of the mirror-ball grid. The columns of
            invalid mirror-ball pixels are zero. Linear, premultiplied by ``alpha``, in SPEC units: relight with
            ``kornia_ilum.render.relight(field, lights)`` where ``lights`` is ``(B, N, 3)`` radiance.
        alpha: ``(1, size, size)`` float32 matte in ``[0, 1]`` (pixel coverage).
        face_box: ``(4,)`` float32 ``(x0, y0, x1, y1)`` box of the projected face landmarks, in continuous
            pixel coordinates (:func:`project_points`).
        camera: the camera.
        subject_seed: the subject's seed.
        meta: JSON-ready facts: renderer settings, timings, the subject's split and skin tone when known.
        pixel_index: ``None`` for the dense layout above. In the *compact* layout of the cache
            (:func:`kornia_ilum.synth.lightstage.cache.read_field` with ``dense=False``), int64 ``(P',)`` flat
            indices of the stored pixels (the others are 0: background), and ``field`` is ``(3, P', N')``.
        light_index: ``None``, or in the compact layout int64 ``(N',)`` indices of the stored lights (the valid
            ones).
        gbuffer: the renderer's :class:`~kornia_ilum.synth.lightstage.gbuffer.GBuffer` (one-pass renders), or
            ``None`` (not cached).

    Examples:
        >>> rf = ReflectanceField(torch.zeros(3, 4, 16, dtype=torch.bfloat16), torch.ones(1, 2, 2),
        ...                       torch.tensor([0.0, 0.0, 2.0, 2.0]), Camera(30.0, 1.0, 0.0, 0.0, size=2), 7)
        >>> rf.size, rf.lighting_size, rf.is_compact
        (2, 4, False)
    """

    field: torch.Tensor
    alpha: torch.Tensor
    face_box: torch.Tensor
    camera: Camera
    subject_seed: int
    meta: dict[str, Any] = dataclass_field(default_factory=dict)
    pixel_index: torch.Tensor | None = None
    light_index: torch.Tensor | None = None
    gbuffer: Any = dataclass_field(default=None, repr=False, compare=False)

    @property
    def size(self) -> int:
        """The image side in pixels."""
        return int(self.alpha.shape[-1])

    @property
    def lighting_size(self) -> int:
        """The mirror-ball side ``S`` of the lighting basis: ``meta["lighting_size"]``, else ``sqrt(N)`` (dense)."""
        if "lighting_size" in self.meta:
            return int(self.meta["lighting_size"])
        if self.is_compact:  # N' valid lights do not give S
            raise ValueCheckError("a compact ReflectanceField needs meta['lighting_size']")
        return math.isqrt(self.field.shape[-1])

    @property
    def is_compact(self) -> bool:
        """Whether ``field`` holds only the ``pixel_index`` rows and ``light_index`` columns."""
        return self.pixel_index is not None or self.light_index is not None

    def to_dense(self) -> ReflectanceField:
        """This field in the dense ``(3, size^2, S^2)`` layout (itself if it already is)."""
        if not self.is_compact:
            return self
        p, n = self.size**2, self.lighting_size**2
        rows = torch.arange(p) if self.pixel_index is None else self.pixel_index
        cols = torch.arange(n) if self.light_index is None else self.light_index
        dense = torch.zeros(3, p, n, dtype=self.field.dtype)
        dense[:, rows[:, None], cols] = self.field
        return ReflectanceField(dense, self.alpha, self.face_box, self.camera, self.subject_seed, dict(self.meta))

    def to_compact(self) -> ReflectanceField:
        """Only the pixels with coverage or any response, and only the valid lights (lossless)."""
        if self.is_compact:
            return self
        cols = torch.from_numpy(np.flatnonzero(mirror_ball_valid(self.lighting_size).flatten().numpy()))
        keep = (self.alpha.flatten() > 0) | (self.field != 0).any(dim=2).any(dim=0)
        rows = torch.nonzero(keep).flatten()
        compact = self.field[:, rows[:, None], cols]
        return ReflectanceField(compact, self.alpha, self.face_box, self.camera, self.subject_seed, dict(self.meta),
                                rows, cols)


def render_olat(
    subject: Subject,
    camera: Camera,
    *,
    lighting_size: int = 32,
    spp: int | None = None,
    variant: str | None = None,
    max_depth: int | None = None,
    seed: int = 0,
    envmap_height: int | None = None,
    threads: int | None = None,
    lights: np.ndarray | list[int] | None = None,
    callback: Callable[[int], Any] | None = None,
    method: str = "auto",
    subsurface: bool = True,
    denoise: bool = False,
    chunk_lanes: int | None = None,
    shade_spp: int | None = None,
    demodulate: bool | None = None,
    edge_spp: int | None = None,
) -> ReflectanceField:
    r"""Render the OLAT reflectance field of a subject seen by a camera.

    Args:
        subject: a :class:`~kornia_ilum.synth.lightstage.subjects.Subject` (anything with ``parts`` of
            ``MeshPart`` with ``vertices``, ``faces`` and ``material``, ``face_landmarks`` and ``seed``).
        camera: the camera; its ``size`` is the image side.
        lighting_size: the mirror-ball side ``S`` of the lighting basis (``N = S^2`` lights).
        spp: camera samples per pixel; default :data:`ONEPASS_SPP` for the one-pass renderer, 16 for the
            reference.
        variant: the Mitsuba variant, or ``None`` for the first that works (:func:`select_mitsuba_variant`).
        max_depth: the reference's path depth (default 4); the one-pass renderer is direct light only
            (``max_depth = 2``; anything else raises).
        seed: the random seed.
        envmap_height, lights: the reference's (:func:`~.reference.render_olat_reference`).
        threads: if given, sets Dr.Jit's thread count (process-global) before rendering.
        callback: progress, in lights: called with 1 after each light (reference), or after each chunk of the
            one-pass renderer with that chunk's share of the valid lights (floats that sum to the valid light
            count), so one progress bar of ``total`` = valid lights serves both.
        method: ``"onepass"`` (:mod:`~kornia_ilum.synth.lightstage.onepass`, needs a vectorised variant),
            ``"reference"`` (:func:`~.reference.render_olat_reference`), or ``"auto"``: one-pass when the variant is
            vectorised and no reference-only option (``lights``, ``envmap_height``, ``max_depth`` other than 2)
            is given, else the reference.
        subsurface: one-pass only: apply :func:`~.subsurface.subsurface_scatter` to the skin's diffuse part.
        denoise: one-pass only: apply :func:`~.denoise.denoise_field` (off by default: it
            lowers the PSNR of relit portraits at :data:`ONEPASS_SPP`, see there).
        chunk_lanes: one-pass only: light-hit pairs per kernel.
        shade_spp: one-pass only: camera samples per pixel that trace the lights (the expensive part); default
            ``min(spp, ONEPASS_SHADE_SPP)``.
        demodulate: one-pass only: scale the traced samples' shading by the coverage and albedo of all ``spp``
            camera samples (:mod:`~kornia_ilum.synth.lightstage.onepass`); default ``shade_spp < spp``.
        edge_spp: one-pass, demodulated only: the samples that trace the lights in mixed pixels (silhouettes,
            hair, creases); default ``min(spp, max(shade_spp, ONEPASS_EDGE_SPP))``.

    Returns:
        the :class:`ReflectanceField`; ``meta`` records the method, settings and timings. The one-pass
        renderer also sets ``gbuffer`` (:class:`~kornia_ilum.synth.lightstage.gbuffer.GBuffer`).

    Raises:
        ImportError: Mitsuba is not installed.
        ShapeError, TypeCheckError, ValueCheckError: a malformed subject, camera or setting.

    Examples:
        >>> from types import SimpleNamespace
        >>> from kornia_ilum.synth.lightstage.olat import _icosphere  # a unit sphere mesh, for examples
        >>> v, f = _icosphere(2)
        >>> ball = SimpleNamespace(name="ball", vertices=0.1 * v, faces=f,
        ...                        material=SimpleNamespace(kind="diffuse", albedo=(0.8, 0.8, 0.8)))
        >>> subject = SimpleNamespace(seed=0, parts=[ball], face_landmarks=0.1 * v)
        >>> rf = render_olat(subject, Camera(30.0, 1.0, 0.0, 0.0, size=8), lighting_size=4, spp=4)
        >>> rf.field.shape, rf.field.dtype
        (torch.Size([3, 64, 16]), torch.bfloat16)
    """
    check_choice(method, "method", ("auto", "onepass", "reference"))
    reference_only = lights is not None or envmap_height is not None or max_depth not in (None, 2)
    if method == "reference" or (method == "auto" and (reference_only or not _vectorised(variant))):
        from kornia_ilum.synth.lightstage.reference import render_olat_reference  # it imports this module

        return render_olat_reference(
            subject, camera, lighting_size=lighting_size, spp=16 if spp is None else spp, variant=variant,
            max_depth=4 if max_depth is None else max_depth, seed=seed, envmap_height=envmap_height,
            threads=threads, lights=lights, callback=callback,
        )
    from kornia_ilum.synth.lightstage.onepass import _DEFAULT_LANES, render_olat_onepass

    start = time.perf_counter()
    if not isinstance(camera, Camera):
        raise TypeCheckError(f"camera must be a Camera, got {type(camera).__name__}")
    check_positive_int(lighting_size, "lighting_size")
    spp = ONEPASS_SPP if spp is None else spp
    check_positive_int(spp, "spp")
    shade_spp = min(spp, ONEPASS_SHADE_SPP) if shade_spp is None else shade_spp
    check_positive_int(shade_spp, "shade_spp")
    if shade_spp > spp:
        raise ValueCheckError(f"shade_spp must be at most spp = {spp}, got {shade_spp}")
    if demodulate is None:
        demodulate = shade_spp < spp
    edge_spp = min(spp, max(shade_spp, ONEPASS_EDGE_SPP)) if edge_spp is None else edge_spp
    check_positive_int(edge_spp, "edge_spp")
    if edge_spp > spp:
        raise ValueCheckError(f"edge_spp must be at most spp = {spp}, got {edge_spp}")
    if not demodulate and shade_spp != spp:
        raise ValueCheckError("demodulate=False needs shade_spp == spp (every camera sample traces the lights)")
    if max_depth not in (None, 2):
        raise ValueCheckError(f"the one-pass renderer traces direct light only (max_depth 2), got {max_depth}")
    if lights is not None:
        raise ValueCheckError("lights is a reference-renderer option (method='reference')")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueCheckError(f"seed must be a non-negative int, got {seed!r}")
    _check_subject(subject)
    for part in subject.parts:
        material_bsdf(part.material)
    variant = select_mitsuba_variant(variant)
    if not variant.startswith(("llvm", "cuda")):
        raise ValueCheckError(f"method='onepass' needs a vectorised Mitsuba variant (llvm_ad_rgb), got {variant}")
    mi = _import_mitsuba()
    if threads is not None:
        import drjit as dr

        check_positive_int(threads, "threads")
        dr.set_thread_count(threads)
    transform = camera_transform(camera, _pivot(subject))
    n_lights = int(mirror_ball_valid(lighting_size).sum())
    res = render_olat_onepass(subject, camera, transform, lighting_size=lighting_size, spp=spp,
                              shade_spp=shade_spp, edge_spp=edge_spp if demodulate else shade_spp,
                              demodulate=demodulate, seed=seed,
                              chunk_lanes=chunk_lanes or _DEFAULT_LANES,
                              callback=None if callback is None else (lambda frac: callback(frac * n_lights)))
    t_post = time.perf_counter()
    diffuse, specular, steps = res.diffuse, res.specular, []
    size = camera.size
    if subsurface and bool((res.gbuffer.subsurface > 0).any()):
        diffuse = _on_dense(subsurface_scatter, diffuse, res, size)
        steps.append("subsurface")
    field = diffuse + specular
    del diffuse, specular
    if denoise:
        field = _on_dense(denoise_field, field, res, size)
        steps.append("denoise")
    out = torch.zeros(3, size * size, lighting_size**2, dtype=torch.bfloat16)
    out[:, res.rows[:, None], res.cols] = field.to(torch.bfloat16)
    del field
    box = project_points(subject.face_landmarks, camera, transform)
    face_box = torch.cat([box.min(dim=0).values, box.max(dim=0).values])
    meta: dict[str, Any] = {
        "renderer": f"mitsuba {mi.__version__}",
        "method": "onepass",
        "variant": variant,
        "max_depth": 2,
        "spp": spp,
        "shade_spp": shade_spp,
        "edge_spp": edge_spp if demodulate else shade_spp,
        "demodulate": demodulate,
        "traced_per_pixel": res.traced,
        "seed": seed,
        "lighting_size": lighting_size,
        "post": steps,
        "timings": {**res.timings, "post": round(time.perf_counter() - t_post, 3)},
        "render_seconds": round(time.perf_counter() - start, 3),
        "pivot": _pivot(subject).tolist(),
        "subject_to_camera": transform.tolist(),
        "lights_rendered": int(len(res.cols)),
        "landmarks": [[round(float(x), 3) for x in xy] for xy in box.tolist()],
    }
    for key in ("split", "skin_tone"):
        if hasattr(subject, key):
            meta[key] = getattr(subject, key)
    rf = ReflectanceField(out, res.gbuffer.alpha.clone(), face_box, camera, int(subject.seed), meta)
    rf.gbuffer = res.gbuffer
    return rf


#: Default camera samples per pixel of the one-pass renderer (``spp``: coverage, albedo, G-buffer, glints).
#:
#: With :data:`ONEPASS_SHADE_SPP` = 4 of them tracing the lights in plain pixels and :data:`ONEPASS_EDGE_SPP` =
#: 16 in mixed ones (silhouettes, hair, several parts, creases), demodulated by albedo and coverage
#: (:mod:`~kornia_ilum.synth.lightstage.onepass`). Chosen with ``benchmarks/bench_olat.py --reference onepass``
#: (MakeHuman seed 1, view 0, 192 px, one thread on the loaded 2-core machine): PSNR of relit 8-bit sRGB
#: portraits (exposure: reference's median subject luminance -> 0.18, black background, covered pixels only,
#: no subsurface) under pedestrian_overpass (sun) / phalzer_forest_01 (overcast), against the mean of two
#: one-pass fields at 32 samples that all trace every light (they agree to 41.3 / 40.1 dB; a 256-spp
#: ``render_lighting`` render agrees with their mean to 38.9 / 38.2 dB, its own noise). ``spp:shade:edge``:
#: 4:4:4 (the previous default, every sample traced) 30.8 / 30.7 dB; 16:4:4 33.5 / 34.5; 16:4:16 35.4 / 36.6;
#: 32:3:16 34.9 / 38.4; 32:4:8 36.6 / 37.3; 32:4:12 37.2 / 38.3; 32:4:16 37.5 / 38.7; 64:4:16 36.7 / 39.1
#: (and a slower camera stage); on seed 2 view 1, 4:4:4 30.1 / 31.1 and 32:4:16 39.0 / 40.9. 32:4:16 costs about 13 s per subject-view including the subject build and the subsurface pass
#: (light stage 8.2 s for 5.3 traced samples per pixel, camera rays 1.1 s). The denoiser lowers this PSNR (it
#: smooths texture and edge detail that the reference has), so :func:`render_olat` does not denoise by default.
ONEPASS_SPP = 32

#: Default camera samples per pixel that trace the lights in plain pixels (:func:`render_olat`'s ``shade_spp``).
ONEPASS_SHADE_SPP = 4

#: Default samples per pixel that trace the lights in mixed pixels (:func:`render_olat`'s ``edge_spp``).
ONEPASS_EDGE_SPP = 16


def _vectorised(variant: str | None) -> bool:
    return select_mitsuba_variant(variant).startswith(("llvm", "cuda"))


def _on_dense(fn: Callable[..., torch.Tensor], compact: torch.Tensor, res: Any, size: int) -> torch.Tensor:
    """Apply a field operator that takes a dense ``(3, P, N_v)`` field and a GBuffer; back to the rows."""
    dense = torch.zeros(3, size * size, compact.shape[-1])
    dense[:, res.rows] = compact
    return fn(dense, res.gbuffer)[:, res.rows]


def _icosphere(subdivisions: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """A unit icosphere ``(vertices (V, 3) float32, faces (F, 3) int32)``, outward-wound; for examples and tests."""
    t = (1.0 + math.sqrt(5.0)) / 2.0
    verts = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
             (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
             (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11),
             (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    v = [np.array(p, dtype=np.float64) / np.linalg.norm(p) for p in verts]
    midpoints: dict[tuple[int, int], int] = {}

    def mid(a: int, b: int) -> int:
        key = (min(a, b), max(a, b))
        if key not in midpoints:
            m = v[a] + v[b]
            v.append(m / np.linalg.norm(m))
            midpoints[key] = len(v) - 1
        return midpoints[key]

    for _ in range(subdivisions):
        new = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            new += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new
    return np.asarray(v, dtype=np.float32), np.asarray(faces, dtype=np.int32)
