r"""The per-light reference renderer: one Mitsuba render per light of the OLAT basis.

:func:`render_olat_reference` is the renderer that the fast one-pass renderer
(:mod:`~kornia_ilum_lab.synth.lightstage.onepass`) is tested against: it uses Mitsuba's own path tracers, so it
also renders interreflection (``max_depth`` above 2), and it is independent of the one-pass sampling code.
:func:`render_lighting` renders a subject directly under one lighting, the reference that relighting must match.

How one OLAT image is rendered:

- **Renderer.** Mitsuba 3 (an optional extra: ``pip install kornia_ilum[lightstage]``), variant
  ``llvm_ad_rgb`` (vectorised, JIT-compiled) or ``scalar_rgb`` (fallback); see :func:`select_mitsuba_variant`.
  A path tracer (``path``, or ``volpath`` when the subject has a cornea, see below) with ``max_depth = 4``:
  cast shadows, specular reflection and two bounces of interreflection.
- **Each light is exactly one mirror-ball pixel.** The emitter is an ``envmap`` whose lat-long bitmap holds,
  at each texel, the fraction of that texel's (bilinear) footprint owned by light ``n`` under
  :func:`~kornia_ilum.geometry.mirror_ball_pixel_index` (the energy-conserving partition of the sphere;
  footprints supersampled 8 x 8 per texel). Mitsuba interpolates the bitmap bilinearly, so this construction
  is exact in two ways: the bitmaps of all lights sum to 1 at every texel (the sum of the OLAT images *is*
  the render under a uniform white environment), and the solid angle that light ``n`` emits from is
  :func:`~kornia_ilum.geometry.mirror_ball_solid_angles` ``[n]`` to 0.35 % (supersampling error, measured at
  ``S = 32``; each light's boundary is blurred by about one texel, 1.4 degrees at the default ``4 S`` rows).
  The bitmap is rotated so that -Z (the rim of the mirror ball, where all rim pixels meet) sits at a pole of
  the lat-long map, whose fine azimuthal resolution separates the thin rim wedges. Only the valid lights
  (812 at ``S = 32``) are rendered; the bitmap changes through :func:`mitsuba.traverse` between renders, the
  scene is built once.
- **Frame and units.** The lighting frame is the *camera* frame of docs/conventions.rst ("Frames": +X right,
  +Y up, +Z toward the camera). The camera stays at the origin looking along -Z, and the subject is turned and
  moved in front of it (:class:`Camera`), so light directions never rotate with the view. The envmap holds
  radiance 1 in the light's solid angle, so ``R`` is in the units of docs/conventions.rst: a white Lambertian
  patch facing a light of radiance ``L`` over solid angle ``Omega`` reads ``L Omega cos / pi``.
- **Background and matte.** Directly visible emitters are hidden, so background pixels are 0 and the field is
  premultiplied by the pixel coverage (box pixel filter). The matte ``alpha`` is that coverage: the alpha
  channel of the first OLAT render (every render uses the same seed, hence the same sub-pixel positions, so
  ``alpha`` and the field agree exactly along the silhouette). Composite with ``I + (1 - alpha) B``.
- **Noise.** Mitsuba's stratified ``multijitter`` sampler (4 times less noise than independent samples at
  16 spp on the test sphere), with the same seed for every light: the Monte-Carlo noise is correlated across
  lights, so a relit image looks like one render rather than a sum of independent noisy images. On a white
  Lambertian sphere under a uniform environment (32 x 32 pixels, ``S = 8``, 16 spp) the sum of the OLATs
  is within 1.1 % rms of the albedo per pixel, 0.1 % on average.

Cost of the reference: one Mitsuba render per valid light (812 at ``S = 32``), each a fixed overhead plus a
time proportional to ``size^2 * spp``; ``scalar_rgb`` is slower than ``llvm_ad_rgb``, and the ``volpath``
integrator that the cornea needs is slower than ``path``. Threads scale with free cores. The measured times
(``benchmarks/bench_olat.py``) are in docs/lightstage.rst, "Measured".
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from kornia_ilum.core.check import check_positive_int, check_tensor
from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.geometry import direction_to_mirror_ball, mirror_ball_pixel_index, mirror_ball_valid
from kornia_ilum_lab.synth.lightstage.field import ReflectanceField
from kornia_ilum_lab.synth.lightstage.materials import (
    bitmap_texture,
    check_subject,
    import_mitsuba,
    material_bsdf,
    mitsuba_mesh,
    select_mitsuba_variant,
)
from kornia_ilum_lab.synth.lightstage.scene import Camera, camera_transform, project_points, subject_pivot
from kornia_ilum_lab.synth.lightstage.settings import REFERENCE_MAX_DEPTH, REFERENCE_SPP, Reference

if TYPE_CHECKING:  # the subjects module is only needed for the annotation
    from kornia_ilum_lab.synth.lightstage.subjects import Subject

__all__ = ["olat_envmap_basis", "render_lighting", "render_olat_reference"]

_SUPERSAMPLES = 8  # per texel axis, for the fraction of each envmap texel owned by each light

# Envmap-local -> camera frame: local +Y (the lat-long's top pole) -> -Z, local -Z (its centre) -> -Y.
_ENV_TO_WORLD = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


# ----------------------------------------------------------------------------------------------
# the OLAT lighting basis as envmap bitmaps


@functools.lru_cache(maxsize=8)
def olat_envmap_basis(lighting_size: int, height: int) -> tuple[Any, np.ndarray]:
    r"""The envmap bitmaps of all lights: which fraction of each lat-long texel each light owns.

    Args:
        lighting_size: the mirror-ball side ``S``.
        height: lat-long rows ``H`` (``W = 2 H`` columns).

    Returns:
        ``(basis, valid_lights)``: a SciPy CSC matrix ``(H * W, S * S)`` whose column ``n`` is light ``n``'s
        bitmap (row-major texels, rows sum to 1), and the int64 indices of the valid lights.

    Convention:
        Mitsuba's ``envmap`` (3.5 to 3.9) interpolates bilinearly between texel values placed at
        ``theta = pi i / (H - 1)`` (row ``i``, from the top pole) and ``phi = 2 pi (k + 0.5) / W`` (column
        ``k``), with the local direction ``(sin phi sin theta, cos theta, -cos phi sin theta)``; the emitter's
        ``to_world`` maps local ``+Y`` to the camera frame's -Z. Texel ``v`` of light ``n`` holds
        ``int hat_v 1_n dOmega / int hat_v dOmega`` (``hat_v`` the bilinear tent of texel ``v``, ``1_n`` the
        indicator of the sphere region owned by light ``n``), integrated with ``8 x 8`` samples per texel cell.

    Examples:
        >>> basis, valid = olat_envmap_basis(4, 16)
        >>> basis.shape, len(valid)
        ((512, 16), 12)
    """
    import scipy.sparse as sp  # lazy: only the reference renderer builds sparse bases

    check_positive_int(lighting_size, "lighting_size")
    check_positive_int(height, "height")
    if height < 3:
        raise ValueCheckError(f"height must be at least 3, got {height}")
    h, w, f = height, 2 * height, _SUPERSAMPLES
    dth = math.pi / (h - 1)
    a = (np.arange(f) + 0.5) / f
    i, k, s = np.meshgrid(np.arange(h - 1), np.arange(w), np.arange(f * f), indexing="ij")
    fa, fb = a[s // f], a[s % f]  # offsets within the cell along theta and phi
    theta = (i + fa) * dth
    phi = 2.0 * math.pi * (k + 0.5 + fb) / w
    local = np.stack([np.sin(phi) * np.sin(theta), np.cos(theta), -np.cos(phi) * np.sin(theta)], axis=-1)
    dirs = torch.from_numpy((local @ _ENV_TO_WORLD.T).reshape(-1, 3))
    owner = mirror_ball_pixel_index(direction_to_mirror_ball(dirs), lighting_size).numpy()
    weight = (np.sin(theta) * dth * (2.0 * math.pi / w) / (f * f)).ravel()
    fa, fb, i, k = fa.ravel(), fb.ravel(), i.ravel(), k.ravel()
    rows, vals = [], []
    for di, dk, tent in ((0, 0, (1 - fa) * (1 - fb)), (0, 1, (1 - fa) * fb), (1, 0, fa * (1 - fb)), (1, 1, fa * fb)):
        rows.append((i + di) * w + (k + dk) % w)
        vals.append(weight * tent)
    acc = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.tile(owner, 4))), shape=(h * w, lighting_size**2)
    )
    acc.sum_duplicates()
    basis = (sp.diags(1.0 / np.asarray(acc.sum(axis=1)).ravel()) @ acc).tocsc()
    valid = np.flatnonzero(mirror_ball_valid(lighting_size).flatten().numpy())
    return basis, valid


def _envmap_data(texels: np.ndarray, height: int, width: int, data_width: int) -> np.ndarray:
    """Texel values ``(H * W, C)`` as Mitsuba's envmap ``data`` tensor ``(H, W', 3)``, with its periodic padding."""
    img = texels.reshape(height, width, -1).astype(np.float32)
    if data_width == width + 2:  # Mitsuba >= 3.6: columns [W - 1, 0 .. W - 1, 0]
        img = np.concatenate([img[:, -1:], img, img[:, :1]], axis=1)
    elif data_width == width + 1:  # Mitsuba 3.5: columns [0 .. W - 1, 0]
        img = np.concatenate([img, img[:, :1]], axis=1)
    elif data_width != width:
        raise ValueCheckError(f"unexpected Mitsuba envmap data width {data_width} for a {width}-wide bitmap")
    return np.ascontiguousarray(np.broadcast_to(img, img.shape[:2] + (3,)))


# ----------------------------------------------------------------------------------------------
# rendering


def _build_scene(mi: Any, subject: Any, *, camera: Camera, transform: np.ndarray, spp: int, max_depth: int,
                 height: int) -> tuple[Any, str]:
    objects: dict[str, Any] = {}
    has_null = False
    for i, part in enumerate(subject.parts):
        v = np.asarray(part.vertices, dtype=np.float64) @ transform[:3, :3].T + transform[:3, 3]
        normals = getattr(part, "normals", None)
        if normals is not None:
            normals = np.asarray(normals, dtype=np.float64) @ transform[:3, :3].T
        has_null |= part.material.kind == "cornea"
        uvs = getattr(part, "uvs", None)
        bsdf = material_bsdf(part.material)
        opacity = getattr(part.material, "opacity_texture", None)
        if opacity is not None and uvs is not None:  # alpha-tested: binary texels, nearest (as the one-pass)
            mask = bitmap_texture((np.asarray(opacity) >= 0.5).astype(np.float32))
            bsdf = {"type": "mask", "opacity": mask, "bsdf": bsdf}
            has_null = True
        name = f"part{i:03d}_{getattr(part, 'name', 'mesh')}"
        objects[name] = mitsuba_mesh(mi, name, vertices=v, faces=np.asarray(part.faces), normals=normals,
                                     bsdf=bsdf, uvs=uvs)
    integrator = "volpath" if has_null else "path"
    to_world = np.eye(4)
    to_world[:3, :3] = _ENV_TO_WORLD
    scene = mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": integrator, "max_depth": max_depth, "hide_emitters": True},
            "sensor": {
                "type": "perspective",
                "fov": float(camera.fov_deg),
                "fov_axis": "x",
                "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 0], target=[0, 0, -1], up=[0, 1, 0]),
                "film": {
                    "type": "hdrfilm",
                    "width": camera.size,
                    "height": camera.size,
                    "pixel_format": "rgba",
                    "rfilter": {"type": "box"},
                },
                "sampler": {"type": "multijitter", "sample_count": spp},
            },
            "env": {
                "type": "envmap",
                "bitmap": mi.Bitmap(np.ones((height, 2 * height, 3), np.float32)),
                "to_world": mi.ScalarTransform4f(to_world.tolist()),
            },
            **objects,
        }
    )
    return scene, integrator


@dataclass
class _Session:
    """A built scene ready for renders under different envmap bitmaps."""

    mi: Any
    scene: Any
    params: Any
    variant: str
    integrator: str
    transform: np.ndarray
    basis: Any
    valid: np.ndarray
    height: int
    spp: int
    seed: int

    def set_texels(self, texels: np.ndarray) -> None:
        """Set the envmap to texel radiances ``(H * W, C)`` (row-major texels of :func:`olat_envmap_basis`)."""
        data = self.params["env.data"]
        self.params["env.data"] = type(data)(_envmap_data(texels, self.height, 2 * self.height, data.shape[1]))
        self.params.update()

    def render(self, texels: np.ndarray) -> np.ndarray:
        """Render under texel radiances ``(H * W, C)``; returns ``(size, size, 4)`` float32, RGB finite >= 0."""
        self.set_texels(texels)
        img = np.array(self.mi.render(self.scene, seed=self.seed), dtype=np.float32)
        rgb = img[..., :3]
        rgb[~np.isfinite(rgb)] = 0.0
        np.maximum(rgb, 0.0, out=rgb)
        img[..., 3] = np.clip(img[..., 3], 0.0, 1.0)
        return img


def _session(subject: Any, camera: Camera, *, settings: Reference, variant: str | None, threads: int | None
             ) -> _Session:
    """Validate the rest (the settings are), then select the variant and build the scene."""
    if not isinstance(camera, Camera):
        raise TypeCheckError(f"camera must be a Camera, got {type(camera).__name__}")
    if threads is not None:
        check_positive_int(threads, "threads")
    check_subject(subject)
    for part in subject.parts:
        material_bsdf(part.material)  # validates every material before any rendering
    height = settings.envmap_height
    basis, valid = olat_envmap_basis(settings.lighting_size, height)
    variant = select_mitsuba_variant(variant)
    mi = import_mitsuba()
    if threads is not None:
        import drjit as dr  # lazy: Dr.Jit comes with Mitsuba, an optional extra

        dr.set_thread_count(threads)
    transform = camera_transform(camera, subject_pivot(subject))
    scene, integrator = _build_scene(mi, subject, camera=camera, transform=transform, spp=settings.spp,
                                     max_depth=settings.max_depth, height=height)
    spp = int(scene.sensors()[0].sampler().sample_count())  # multijitter rounds up to a product, e.g. 32 -> 35
    return _Session(mi, scene, mi.traverse(scene), variant, integrator, transform, basis, valid, height, spp,
                    settings.seed)


def _meta(session: _Session, subject: Any, *, max_depth: int, lighting_size: int, seconds: float
          ) -> dict[str, Any]:
    meta: dict[str, Any] = {
        "renderer": f"mitsuba {session.mi.__version__}",
        "variant": session.variant,
        "integrator": session.integrator,
        "max_depth": max_depth,
        "spp": session.spp,
        "seed": session.seed,
        "lighting_size": lighting_size,
        "envmap_size": [session.height, 2 * session.height],
        "render_seconds": round(seconds, 3),
        "pivot": subject_pivot(subject).tolist(),
        "subject_to_camera": session.transform.tolist(),
    }
    for key in ("split", "skin_tone"):
        if hasattr(subject, key):
            meta[key] = getattr(subject, key)
    return meta


def render_olat_reference(
    subject: Subject,
    camera: Camera,
    *,
    settings: Reference | None = None,
    variant: str | None = None,
    threads: int | None = None,
    callback: Callable[[int], Any] | None = None,
) -> ReflectanceField:
    r"""The per-light reference renderer: one Mitsuba render per light (module docstring for the method).

    Args:
        subject: a :class:`~kornia_ilum_lab.synth.lightstage.subjects.Subject` (anything with ``parts`` of
            ``MeshPart`` with ``vertices``, ``faces`` and ``material``, ``face_landmarks`` and ``seed``).
        camera: the camera; its ``size`` is the image side.
        settings: the :class:`~kornia_ilum_lab.synth.lightstage.settings.Reference` settings (lighting size,
            samples, path depth, seed, envmap height, lights); ``None``: ``Reference()``. The seed is the same
            for every light (module docstring, Noise).
        variant: the Mitsuba variant, or ``None`` for the first that works (:func:`select_mitsuba_variant`).
        threads: if given, sets Dr.Jit's thread count (process-global) before rendering.
        callback: called with 1 after each light (a progress bar's ``update``).

    Returns:
        the :class:`ReflectanceField`; ``meta`` records the variant, integrator, settings, the rendered light
        count, the wall time (``render_seconds``, of which ``setup_seconds`` before the first light), and the
        subject's ``split`` and ``skin_tone`` when it has them.

    Raises:
        ImportError: Mitsuba is not installed.
        ShapeError, TypeCheckError, ValueCheckError: a malformed subject, camera or setting.

    Shape:
        - field: :math:`(3, P, N)` bfloat16, :math:`P = size^2`, :math:`N = S^2`
        - alpha: :math:`(1, size, size)` float32

    Convention:
        Light directions in the camera frame of docs/conventions.rst ("Frames"); radiance units (module
        docstring).

    Examples:
        >>> from types import SimpleNamespace
        >>> from kornia_ilum_lab.synth.lightstage.subjects.base import icosphere  # a unit sphere mesh
        >>> v, f = icosphere(2)
        >>> ball = SimpleNamespace(name="ball", vertices=0.1 * v, faces=f,
        ...                        material=SimpleNamespace(kind="diffuse", albedo=(0.8, 0.8, 0.8)))
        >>> subject = SimpleNamespace(seed=0, parts=[ball], face_landmarks=0.1 * v)
        >>> rf = render_olat_reference(subject, Camera(30.0, 1.0, 0.0, 0.0, size=8),
        ...                            settings=Reference(lighting_size=4, spp=4), variant="scalar_rgb")
        >>> rf.field.shape, rf.field.dtype, rf.meta["lights_rendered"]
        (torch.Size([3, 64, 16]), torch.bfloat16, 12)
    """
    start = time.perf_counter()
    settings = Reference() if settings is None else settings
    if not isinstance(settings, Reference):
        raise TypeCheckError(f"settings must be Reference settings, got {type(settings).__name__}")
    lighting_size = settings.lighting_size
    session = _session(subject, camera, settings=settings, variant=variant, threads=threads)
    setup = time.perf_counter() - start
    todo = session.valid if settings.lights is None else np.asarray(settings.lights, dtype=np.int64)
    size = camera.size
    out = torch.zeros(3, size * size, lighting_size**2, dtype=torch.bfloat16)
    alpha = torch.zeros(1, size, size)
    for j, light in enumerate(todo):
        img = session.render(session.basis[:, light].toarray())
        out[:, :, light] = torch.from_numpy(img[..., :3].reshape(-1, 3)).T.to(torch.bfloat16)
        if j == 0:  # every render shares the seed, hence the sub-pixel positions: one matte fits all
            alpha = torch.from_numpy(img[..., 3].copy())[None]
        if callback is not None:
            callback(1)
    box = project_points(subject.face_landmarks, camera, session.transform)
    face_box = torch.cat([box.min(dim=0).values, box.max(dim=0).values])
    meta = _meta(session, subject, max_depth=settings.max_depth, lighting_size=lighting_size,
                 seconds=time.perf_counter() - start)
    meta["lights_rendered"] = len(todo)
    meta["landmarks"] = [[round(float(x), 3) for x in xy] for xy in box.tolist()]  # LANDMARK_NAMES order
    meta["setup_seconds"] = round(setup, 3)
    return ReflectanceField(out, alpha, face_box, camera, int(subject.seed), meta)


def render_lighting(
    subject: Subject,
    camera: Camera,
    *,
    lighting: torch.Tensor,
    spp: int = REFERENCE_SPP,
    variant: str | None = None,
    max_depth: int = REFERENCE_MAX_DEPTH,
    seed: int = 0,
    envmap_height: int | None = None,
    threads: int | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    r"""Render a subject directly under a mirror-ball lighting: the reference that relighting must match.

    The envmap is the OLAT basis weighted by the lighting, ``sum_n L[n] basis_n``, so by the linearity of light
    transport the image equals ``relight(render_olat_reference(...).field, L)`` up to Monte-Carlo noise (same
    scene, camera and settings).

    Args:
        subject: as for :func:`render_olat_reference`.
        camera: the camera.
        lighting: ``(3, S, S)`` mirror-ball radiance (docs/conventions.rst, "Mirror ball"), non-negative;
            invalid pixels are ignored.
        spp, max_depth, seed, envmap_height: as for :class:`~kornia_ilum_lab.synth.lightstage.settings.Reference`.
        variant, threads: as for :func:`render_olat_reference`.

    Returns:
        ``(image, alpha)``: ``(3, size, size)`` float32 linear RGB (premultiplied, background 0) and the
        ``(1, size, size)`` matte.

    Shape:
        - lighting: :math:`(3, S, S)`
        - Output: :math:`(3, size, size)` and :math:`(1, size, size)`

    Convention:
        Mirror-ball lighting in the camera frame of docs/conventions.rst ("Mirror ball", "Frames"); the image
        in the units of the lighting ("Units of lighting").

    Examples:
        >>> from types import SimpleNamespace
        >>> from kornia_ilum_lab.synth.lightstage.subjects.base import icosphere
        >>> v, f = icosphere(2)
        >>> ball = SimpleNamespace(name="ball", vertices=0.1 * v, faces=f,
        ...                        material=SimpleNamespace(kind="diffuse", albedo=(0.8, 0.8, 0.8)))
        >>> subject = SimpleNamespace(seed=0, parts=[ball], face_landmarks=0.1 * v)
        >>> image, alpha = render_lighting(subject, Camera(20.0, 1.0, 0.0, 0.0, size=8),
        ...                                lighting=torch.ones(3, 4, 4), spp=64, variant="scalar_rgb")
        >>> round(image[:, 3:5, 3:5].mean().item(), 1)  # a white environment: the albedo, up to noise
        0.8
    """
    check_tensor(lighting, "lighting", ["3", "S", "S"], nonnegative=True)
    if lighting.shape[-1] != lighting.shape[-2]:
        raise ShapeError(f"lighting must have shape (3, S, S), got {tuple(lighting.shape)}")
    settings = Reference(lighting_size=int(lighting.shape[-1]), spp=spp, max_depth=max_depth, seed=seed,
                         envmap_height=envmap_height)
    session = _session(subject, camera, settings=settings, variant=variant, threads=threads)
    lights = lighting.detach().to("cpu", torch.float64).flatten(1).T.numpy()  # (N, 3)
    img = session.render(np.asarray(session.basis @ lights))
    image = torch.from_numpy(np.ascontiguousarray(img[..., :3].transpose(2, 0, 1)))
    return image, torch.from_numpy(img[..., 3].copy())[None]
