r"""One-light-at-a-time (OLAT) reflectance fields of synthetic subjects, rendered with Mitsuba 3.

A reflectance field (:class:`~kornia_ilum_lab.synth.lightstage.field.ReflectanceField`) holds, for every image
pixel and every light of the ``S x S`` mirror-ball lighting basis (docs/conventions.rst, "Mirror ball"), the
pixel's linear response to unit radiance from that light's solid angle, so any lighting relights the subject
exactly as the renderer would have (:func:`kornia_ilum.render.relight`). This is the virtual light stage of
LeGendre et al. 2020 ("Learning Illumination from Diverse Portraits"), who relit photographed subjects the
same way (Debevec et al. 2000, "Acquiring the reflectance field of a human face").

:func:`render_olat` dispatches on its settings (:mod:`~kornia_ilum_lab.synth.lightstage.settings`); both renderers
make the same field (direct light, the Mitsuba BSDFs of
:func:`~kornia_ilum_lab.synth.lightstage.materials.material_bsdf`):

- :class:`~kornia_ilum_lab.synth.lightstage.settings.OnePass` (the default where the Mitsuba variant is
  vectorised): all lights in one vectorised Dr.Jit pass, :mod:`~kornia_ilum_lab.synth.lightstage.onepass`, then
  the subsurface step of :mod:`~kornia_ilum_lab.synth.lightstage.subsurface` on the skin's diffuse part (and
  optionally the denoiser of :mod:`~kornia_ilum_lab.synth.lightstage.denoise`), both linear in the lighting;
- :class:`~kornia_ilum_lab.synth.lightstage.settings.Reference`:
  :func:`~kornia_ilum_lab.synth.lightstage.reference.render_olat_reference`, one Mitsuba render per light, the
  reference of the tests and of ``benchmarks/bench_olat.py``; far slower (one render per light).

Their costs are in docs/lightstage.rst. The lighting frame is the *camera* frame of docs/conventions.rst
("Frames"); the field is premultiplied by the pixel coverage ``alpha`` (background 0): composite with
``I + (1 - alpha) B``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import torch

from kornia_ilum.core.check import check_positive_int
from kornia_ilum.core.errors import TypeCheckError, ValueCheckError
from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum_lab.synth.lightstage.denoise import denoise_field
from kornia_ilum_lab.synth.lightstage.field import ReflectanceField
from kornia_ilum_lab.synth.lightstage.materials import (
    check_subject,
    import_mitsuba,
    material_bsdf,
    select_mitsuba_variant,
)
from kornia_ilum_lab.synth.lightstage.onepass import OnePassResult, render_olat_onepass
from kornia_ilum_lab.synth.lightstage.reference import render_olat_reference
from kornia_ilum_lab.synth.lightstage.scene import Camera, camera_transform, project_points, subject_pivot
from kornia_ilum_lab.synth.lightstage.settings import Auto, OnePass, Reference, is_vectorised
from kornia_ilum_lab.synth.lightstage.subsurface import subsurface_scatter

if TYPE_CHECKING:  # the subjects module is only needed for the annotation
    from kornia_ilum_lab.synth.lightstage.subjects import Subject

__all__ = ["render_olat"]


def render_olat(
    subject: Subject,
    camera: Camera,
    *,
    settings: OnePass | Reference | Auto | None = None,
    variant: str | None = None,
    threads: int | None = None,
    callback: Callable[[float], Any] | None = None,
) -> ReflectanceField:
    r"""Render the OLAT reflectance field of a subject seen by a camera.

    Args:
        subject: a :class:`~kornia_ilum_lab.synth.lightstage.subjects.Subject` (anything with ``parts`` of
            ``MeshPart`` with ``vertices``, ``faces`` and ``material``, ``face_landmarks`` and ``seed``).
        camera: the camera; its ``size`` is the image side.
        settings: the renderer and its settings (:mod:`~kornia_ilum_lab.synth.lightstage.settings`):
            :class:`~kornia_ilum_lab.synth.lightstage.settings.OnePass` (needs a vectorised variant, e.g.
            ``llvm_ad_rgb``), :class:`~kornia_ilum_lab.synth.lightstage.settings.Reference`
            (:func:`~kornia_ilum_lab.synth.lightstage.reference.render_olat_reference`), or
            :class:`~kornia_ilum_lab.synth.lightstage.settings.Auto`: one-pass when the variant is vectorised,
            else the reference. ``None``: ``Auto()``.
        variant: the Mitsuba variant, or ``None`` for the first that works (:func:`select_mitsuba_variant`).
        threads: if given, sets Dr.Jit's thread count (process-global) before rendering.
        callback: progress, in lights: called with 1 after each light (reference), or after each chunk of the
            one-pass renderer with that chunk's share of the valid lights (floats that sum to the valid light
            count), so one progress bar of ``total`` = valid lights serves both.

    Returns:
        the :class:`~kornia_ilum_lab.synth.lightstage.field.ReflectanceField`; ``meta`` records the method,
        settings and timings. The one-pass renderer also sets ``gbuffer``
        (:class:`~kornia_ilum_lab.synth.lightstage.gbuffer.GBuffer`).

    Raises:
        ImportError: Mitsuba is not installed.
        ShapeError, TypeCheckError, ValueCheckError: a malformed subject, camera or setting.

    Examples:
        >>> from types import SimpleNamespace
        >>> from kornia_ilum_lab.synth.lightstage.subjects.base import icosphere  # a unit sphere mesh
        >>> v, f = icosphere(2)
        >>> ball = SimpleNamespace(name="ball", vertices=0.1 * v, faces=f,
        ...                        material=SimpleNamespace(kind="diffuse", albedo=(0.8, 0.8, 0.8)))
        >>> subject = SimpleNamespace(seed=0, parts=[ball], face_landmarks=0.1 * v)
        >>> rf = render_olat(subject, Camera(30.0, 1.0, 0.0, 0.0, size=8),
        ...                  settings=Auto(lighting_size=4, spp=4))
        >>> rf.field.shape, rf.field.dtype
        (torch.Size([3, 64, 16]), torch.bfloat16)
    """
    settings = Auto() if settings is None else settings
    if not isinstance(settings, (OnePass, Reference, Auto)):
        raise TypeCheckError(f"settings must be OnePass, Reference or Auto, got {type(settings).__name__}")
    if isinstance(settings, Auto):
        settings = settings.resolve(select_mitsuba_variant(variant))
    if isinstance(settings, Reference):
        return render_olat_reference(subject, camera, settings=settings, variant=variant, threads=threads,
                                     callback=callback)
    return _render_onepass(subject, camera, settings=settings, variant=variant, threads=threads,
                           callback=callback)


def _render_onepass(subject: Subject, camera: Camera, *, settings: OnePass, variant: str | None,
                    threads: int | None, callback: Callable[[float], Any] | None) -> ReflectanceField:
    """The one-pass renderer, then its post-processing (subsurface, denoiser) and the field's ``meta``."""
    start = time.perf_counter()
    if not isinstance(camera, Camera):
        raise TypeCheckError(f"camera must be a Camera, got {type(camera).__name__}")
    check_subject(subject)
    for part in subject.parts:
        material_bsdf(part.material)
    variant = select_mitsuba_variant(variant)
    if not is_vectorised(variant):
        raise ValueCheckError(f"OnePass settings need a vectorised Mitsuba variant (llvm_ad_rgb), got "
                              f"{variant}")
    mi = import_mitsuba()
    if threads is not None:
        import drjit as dr  # lazy: Dr.Jit comes with Mitsuba, an optional extra

        check_positive_int(threads, "threads")
        dr.set_thread_count(threads)
    pivot = subject_pivot(subject)
    transform = camera_transform(camera, pivot)
    n_lights = int(mirror_ball_valid(settings.lighting_size).sum())
    res = render_olat_onepass(subject, camera, transform=transform, settings=settings,
                              callback=None if callback is None else (lambda frac: callback(frac * n_lights)))
    t_post = time.perf_counter()
    out, steps = _post_process(res, settings, camera.size)
    box = project_points(subject.face_landmarks, camera, transform)
    face_box = torch.cat([box.min(dim=0).values, box.max(dim=0).values])
    meta: dict[str, Any] = {
        "renderer": f"mitsuba {mi.__version__}",
        "method": "onepass",
        "variant": variant,
        "max_depth": 2,
        "spp": settings.spp,
        "shade_spp": settings.shade_spp,
        "edge_spp": settings.edge_spp,
        "demodulate": settings.demodulate,
        "traced_per_pixel": res.traced,
        "seed": settings.seed,
        "lighting_size": settings.lighting_size,
        "post": steps,
        "timings": {**res.timings, "post": round(time.perf_counter() - t_post, 3)},
        "render_seconds": round(time.perf_counter() - start, 3),
        "pivot": pivot.tolist(),
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


def _post_process(res: OnePassResult, settings: OnePass, size: int) -> tuple[torch.Tensor, list[str]]:
    """Subsurface scattering of the diffuse part, the sum with the specular part, the denoiser: the dense
    bfloat16 field ``(3, size^2, S^2)`` and the names of the steps applied."""
    diffuse, specular, steps = res.diffuse, res.specular, []
    if settings.subsurface and bool((res.gbuffer.subsurface > 0).any()):
        diffuse = _on_dense(subsurface_scatter, diffuse, res, size)
        steps.append("subsurface")
    field = diffuse + specular
    del diffuse, specular
    if settings.denoise:
        field = _on_dense(denoise_field, field, res, size)
        steps.append("denoise")
    out = torch.zeros(3, size * size, settings.lighting_size**2, dtype=torch.bfloat16)
    out[:, res.rows[:, None], res.cols] = field.to(torch.bfloat16)
    return out, steps


def _on_dense(fn: Callable[..., torch.Tensor], compact: torch.Tensor, res: OnePassResult, size: int
              ) -> torch.Tensor:
    """Apply a field operator that takes a dense ``(3, P, N_v)`` field and a GBuffer; back to the rows."""
    dense = torch.zeros(3, size * size, compact.shape[-1])
    dense[:, res.rows] = compact
    return fn(dense, res.gbuffer)[:, res.rows]
