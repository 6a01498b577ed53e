r"""One-light-at-a-time (OLAT) reflectance fields of synthetic subjects, rendered with Mitsuba 3.

A reflectance field ``R`` holds, for every image pixel ``p`` and every light ``n`` of the ``S x S`` mirror-ball
lighting basis (SPEC.md), the pixel's linear response to unit radiance arriving from the solid angle of
mirror-ball pixel ``n``. Any lighting ``L`` (a mirror ball in radiance) then relights the subject exactly as the
renderer would have: ``I[c, p] = sum_n R[c, p, n] L[n, c]`` (:func:`kornia_ilum.render.relight`). This is the
virtual light stage of LeGendre et al. 2020 ("Learning Illumination from Diverse Portraits"), who relit
photographed subjects the same way (Debevec et al. 2000, "Acquiring the reflectance field of a human face").

How one OLAT image is rendered (:func:`render_olat`):

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
- **Frame and units.** The lighting frame is the *camera* frame of SPEC.md (+X right, +Y up, +Z toward the
  camera). The camera stays at the origin looking along -Z, and the subject is turned and moved in front of
  it (:class:`Camera`), so light directions never rotate with the view. The envmap holds radiance 1 in the
  light's solid angle, so ``R`` is in SPEC units: a white Lambertian patch facing a light of radiance ``L``
  over solid angle ``Omega`` reads ``L Omega cos / pi``.
- **Background and matte.** Directly visible emitters are hidden, so background pixels are 0 and the field is
  premultiplied by the pixel coverage (box pixel filter). The matte ``alpha`` is that coverage: the alpha
  channel of the first OLAT render (every render uses the same seed, hence the same sub-pixel positions, so
  ``alpha`` and the field agree exactly along the silhouette). Composite with ``I + (1 - alpha) B``.
- **Noise.** Mitsuba's stratified ``multijitter`` sampler (4 times less noise than independent samples at
  16 spp on the test sphere), with the same seed for every light: the Monte-Carlo noise is correlated across
  lights, so a relit image looks like one render rather than a sum of independent noisy images. On a white
  Lambertian sphere under a uniform environment (32 x 32 pixels, ``S = 8``, 16 spp) the sum of the OLATs
  is within 1.1 % rms of the albedo per pixel, 0.1 % on average.

Materials (:func:`material_bsdf`): ``diffuse`` is Lambertian; ``skin``, ``glossy`` and ``hair`` are Mitsuba's
``principled`` BSDF (Disney, Burley 2012) with a GGX specular lobe of ``alpha = roughness`` and the material's
``specular``; all of these are two-sided. ``cornea`` is a smooth clear coat: a one-sided Fresnel mirror
(IOR from ``specular``: ``F0 = 0.08 specular``, ``eta = (1 + sqrt(F0)) / (1 - sqrt(F0))``, 1.376 for the real
cornea's ``F0 = 0.025``) over a straight-through transmission of about ``1 - F(theta)``. The transmission is a
*null* interface, so the ``volpath`` integrator traces shadow rays through it and the iris behind it is lit by
next-event estimation (with a dielectric, shadow rays would stop at the cornea and the iris would be lit only
by rare BSDF-sampled paths); the mirror lobe is sampled with probability 0.3 (not ``F0``), so catch-lights are
not starved of samples. The mirror reflects on the outer side only, so the back of a closed lens adds no second
glint; a closed lens attenuates the iris by ``(1 - F0)^2`` each way (two interfaces). The cornea's albedo is
ignored (a clear cornea). Given vertex ``normals`` of a part are used for shading; otherwise Mitsuba computes
smooth vertex normals.

Cost (``benchmarks/bench_olat.py``, one thread of the project's shared 2-core CPU, a ``make_subject`` head of
about 140 000 triangles): 0.45 s per light at 256 x 256 and 16 spp with ``llvm_ad_rgb`` on a quiet core, 0.55 to
0.75 s under load, i.e. about 6 to 10 minutes per subject and view (812 lights); ``scalar_rgb`` is about 1.7
times slower. Each render costs about 25 ms plus a time proportional to ``size^2 * spp``; the ``volpath``
integrator that the cornea needs costs about 1.5 times ``path``. Threads scale with free cores.
"""

from __future__ import annotations

import functools
import math
import os
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from dataclasses import field as dataclass_field
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from kornia_ilum.core.check import check_choice, check_positive_int, check_tensor
from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.geometry import direction_to_mirror_ball, mirror_ball_pixel_index, mirror_ball_valid
from kornia_ilum.synth.lightstage.scene import PIVOT_RAISE, Camera, _pivot, camera_transform, project_points

if TYPE_CHECKING:  # the subjects module is only needed for the annotation
    from kornia_ilum.synth.lightstage.subjects import Material, Subject

__all__ = [
    "MATERIAL_KINDS",
    "MITSUBA_VARIANTS",
    "VARIANT_ENV",
    "ReflectanceField",
    "material_bsdf",
    "olat_envmap_basis",
    "render_lighting",
    "ONEPASS_EDGE_SPP",
    "ONEPASS_SHADE_SPP",
    "ONEPASS_SPP",
    "diffuse_twin_bsdf",
    "render_olat",
    "render_olat_reference",
    "select_mitsuba_variant",
]

#: Mitsuba variants tried in order by :func:`select_mitsuba_variant` when none is named.
MITSUBA_VARIANTS: tuple[str, ...] = ("llvm_ad_rgb", "scalar_rgb")

#: Environment variable that names the variant to use when ``variant=None`` (skips the probe).
VARIANT_ENV = "KORNIA_ILUM_MITSUBA_VARIANT"

MATERIAL_KINDS: tuple[str, ...] = ("skin", "diffuse", "glossy", "cornea", "hair")

_CORNEA_MIRROR_PROBABILITY = 0.3  # how often a camera path picks the cornea's mirror lobe
_SUPERSAMPLES = 8  # per texel axis, for the fraction of each envmap texel owned by each light

# Envmap-local -> camera frame: local +Y (the lat-long's top pole) -> -Z, local -Z (its centre) -> -Y.
_ENV_TO_WORLD = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


# ----------------------------------------------------------------------------------------------
# result


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


# ----------------------------------------------------------------------------------------------
# Mitsuba set-up


def _import_mitsuba() -> Any:
    try:
        import mitsuba as mi
    except ImportError as exc:  # pragma: no cover - depends on the optional extra
        raise ImportError(
            "render_olat needs Mitsuba 3: pip install 'kornia_ilum[lightstage]' (or pip install 'mitsuba>=3.5')"
        ) from exc
    return mi


_PROBE = """
import mitsuba as mi, numpy as np
mi.set_variant({variant!r})
scene = mi.load_dict({{'type': 'scene', 'integrator': {{'type': 'path', 'max_depth': 3}},
    'sensor': {{'type': 'perspective', 'film': {{'type': 'hdrfilm', 'width': 4, 'height': 4}}}},
    'env': {{'type': 'envmap', 'bitmap': mi.Bitmap(np.ones((4, 8, 3), np.float32))}},
    'ball': {{'type': 'sphere', 'center': [0, 0, -3]}}}})
img = np.asarray(mi.render(scene, spp=2))
assert np.isfinite(img).all() and img.max() > 0
"""


@functools.cache
def _variant_works(variant: str) -> bool:
    """Whether a tiny render succeeds in ``variant``, tried in a child process.

    A child, because a JIT variant can abort the whole process (not raise) when its LLVM is unusable: Debian
    12's LLVM 15 cannot compile Dr.Jit 1.x's kernels (``LLVM ERROR: Cannot select: fminimum``).
    """
    mi = _import_mitsuba()
    if variant not in mi.variants():
        return False
    if variant.startswith("scalar"):
        return True
    try:
        done = subprocess.run(
            [sys.executable, "-c", _PROBE.format(variant=variant)], capture_output=True, timeout=300, check=False
        )
    except (OSError, subprocess.TimeoutExpired):
        return False
    return done.returncode == 0


def select_mitsuba_variant(variant: str | None = None) -> str:
    r"""Activate a Mitsuba variant and return its name.

    Args:
        variant: a variant to use as is (``"llvm_ad_rgb"``, ``"scalar_rgb"``, ``"cuda_ad_rgb"``, ...). ``None``
            takes the environment variable ``KORNIA_ILUM_MITSUBA_VARIANT`` if set, else the first of
            :data:`MITSUBA_VARIANTS` that renders a tiny test scene in a child process (checked once per
            process). ``llvm_ad_rgb`` needs an LLVM that Dr.Jit can use (LLVM >= 16; on Debian 12
            ``apt-get install libllvm19``); otherwise ``scalar_rgb`` is used, which gives the same images.

    Returns:
        the active variant (Mitsuba's variant is process-global).

    Raises:
        ValueCheckError: the variant is not one that this Mitsuba build offers, or none works.

    Examples:
        >>> select_mitsuba_variant("scalar_rgb")
        'scalar_rgb'
    """
    mi = _import_mitsuba()
    if variant is None:
        variant = os.environ.get(VARIANT_ENV) or None
    if variant is None:
        variant = next((v for v in MITSUBA_VARIANTS if _variant_works(v)), None)
        if variant is None:
            raise ValueCheckError(f"no Mitsuba variant of {MITSUBA_VARIANTS} works here; have {mi.variants()}")
    check_choice(variant, "variant", mi.variants())
    if mi.variant() != variant:
        mi.set_variant(variant)
    return variant


def _rgb(value: tuple[float, float, float], name: str) -> dict[str, Any]:
    rgb = [float(c) for c in value]
    if len(rgb) != 3 or not all(0.0 <= c <= 1.0 for c in rgb):
        raise ValueCheckError(f"{name} must be 3 linear RGB values in [0, 1], got {value}")
    return {"type": "rgb", "value": rgb}


def _fresnel_ior(f0: float) -> float:
    """The IOR whose normal-incidence Fresnel reflectance is ``f0``."""
    return (1.0 + math.sqrt(f0)) / (1.0 - math.sqrt(f0))


def material_bsdf(material: Material) -> dict[str, Any]:
    r"""The Mitsuba BSDF (a ``mitsuba.load_dict`` dict) of a subject :class:`Material`.

    ``roughness`` is the GGX ``alpha``; Mitsuba's ``principled`` takes ``sqrt(alpha)``. See the module
    docstring for the models.

    Examples:
        >>> from types import SimpleNamespace
        >>> material_bsdf(SimpleNamespace(kind="diffuse", albedo=(0.5, 0.5, 0.5)))["bsdf"]["type"]
        'diffuse'
    """
    kind = getattr(material, "kind", None)
    check_choice(kind, "material.kind", MATERIAL_KINDS)
    alpha = float(getattr(material, "roughness", 0.5))
    specular = float(getattr(material, "specular", 0.5))
    if not 0.0 <= alpha <= 1.0:
        raise ValueCheckError(f"material.roughness must be in [0, 1], got {alpha}")
    if not 0.0 <= specular <= 1.0:
        raise ValueCheckError(f"material.specular must be in [0, 1], got {specular}")
    if kind == "cornea":
        f0 = 0.08 * max(specular, 1e-3)
        w = _CORNEA_MIRROR_PROBABILITY
        r_slab = f0 / (2.0 - f0)  # a thin slab reflects 2R / (1 + R): match F0 at normal incidence
        return {
            "type": "blendbsdf",
            "weight": w,  # probability of the mirror lobe; each lobe's weight is divided by its probability
            "transmission": {
                # straight through with 1 - F(theta) (a null interface for shadow rays); its own reflection is
                # zeroed, the mirror lobe below carries it
                "type": "thindielectric",
                "int_ior": _fresnel_ior(r_slab),
                "ext_ior": 1.0,
                "specular_reflectance": {"type": "uniform", "value": 0.0},
                "specular_transmittance": {"type": "uniform", "value": 1.0 / (1.0 - w)},
            },
            "mirror": {
                # k = 0: the Fresnel reflectance F(theta) of a dielectric of IOR eta. One-sided: it reflects only
                # on the outer side, so the back of a closed lens (seen from inside it) adds no second glint
                "type": "conductor",
                "eta": _fresnel_ior(f0),
                "k": 0.0,
                "specular_reflectance": {"type": "uniform", "value": 1.0 / w},
            },
        }
    albedo = _rgb(getattr(material, "albedo", None), "material.albedo")
    tex = getattr(material, "albedo_texture", None)
    if tex is not None:
        albedo = _bitmap(np.clip(np.asarray(tex, dtype=np.float32), 0.0, 1.0))
    rough_tex = getattr(material, "roughness_texture", None)
    if rough_tex is not None:
        roughness: Any = _bitmap(np.sqrt(np.clip(alpha * np.asarray(rough_tex, dtype=np.float32), 1e-4, 1.0)))
    else:
        roughness = math.sqrt(max(alpha, 1e-4))
    if kind == "diffuse":
        inner: dict[str, Any] = {"type": "diffuse", "reflectance": albedo}
    else:  # skin, glossy, hair: a diffuse base under a GGX dielectric specular lobe
        inner = {
            "type": "principled",
            "base_color": albedo,
            "roughness": roughness,
            "specular": specular,
            "metallic": 0.0,
        }
    return {"type": "twosided", "bsdf": inner}


def _bitmap(data: np.ndarray) -> dict[str, Any]:
    """A linear (raw) bitmap texture, nearest texel; row 0 of ``data`` is the top of the image."""
    mi = _import_mitsuba()
    arr = np.ascontiguousarray(data if data.ndim == 3 else data[..., None], dtype=np.float32)
    return {"type": "bitmap", "bitmap": mi.Bitmap(arr), "raw": True, "filter_type": "nearest"}


def diffuse_twin_bsdf(material: Material) -> dict[str, Any]:
    r"""The diffuse part of :func:`material_bsdf`: the same BSDF with ``specular = 0``.

    Mitsuba's ``principled`` is linear in ``specular`` (its GGX lobe's Fresnel scales with it and the diffuse
    base does not), so ``material_bsdf - diffuse_twin_bsdf`` is the specular part.

    Examples:
        >>> from types import SimpleNamespace
        >>> diffuse_twin_bsdf(SimpleNamespace(kind="skin", albedo=(0.5, 0.5, 0.5)))["bsdf"]["specular"]
        0.0
    """
    bsdf = material_bsdf(material)
    if bsdf["type"] == "twosided" and bsdf["bsdf"]["type"] == "principled":
        bsdf = {"type": "twosided", "bsdf": {**bsdf["bsdf"], "specular": 0.0}}
    return bsdf


def _mitsuba_mesh(mi: Any, name: str, vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray | None,
                  bsdf: dict[str, Any], uvs: np.ndarray | None = None) -> Any:
    """A Mitsuba mesh; ``uvs`` (OBJ convention, ``v`` up) are stored as ``(u, 1 - v)``: image row 0 at ``v = 1``."""
    props = mi.Properties()
    props["bsdf"] = mi.load_dict(bsdf)
    mesh = mi.Mesh(name, vertex_count=len(vertices), face_count=len(faces), has_vertex_normals=True,
                   has_vertex_texcoords=uvs is not None, props=props)
    params = mi.traverse(mesh)
    params["vertex_positions"] = type(params["vertex_positions"])(vertices.astype(np.float32).ravel())
    params["faces"] = type(params["faces"])(faces.astype(np.uint32).ravel())
    if normals is not None:
        params["vertex_normals"] = type(params["vertex_normals"])(normals.astype(np.float32).ravel())
    if uvs is not None:
        uv = np.asarray(uvs, dtype=np.float32).copy()
        uv[:, 1] = 1.0 - uv[:, 1]
        params["vertex_texcoords"] = type(params["vertex_texcoords"])(uv.ravel())
    params.update()  # without given normals, Mitsuba computes smooth (area-weighted) vertex normals
    return mesh


def _check_subject(subject: Any) -> None:
    parts = getattr(subject, "parts", None)
    if not isinstance(parts, (list, tuple)) or not parts:
        raise ValueCheckError("subject.parts must be a non-empty list of MeshPart")
    for i, part in enumerate(parts):
        v, f = np.asarray(part.vertices), np.asarray(part.faces)
        name = f"subject.parts[{i}] ({getattr(part, 'name', '?')})"
        if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
            raise ShapeError(f"{name}.vertices must have shape (V, 3) with V > 0, got {v.shape}")
        if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
            raise ShapeError(f"{name}.faces must have shape (F, 3) with F > 0, got {f.shape}")
        if not np.issubdtype(f.dtype, np.integer):
            raise TypeCheckError(f"{name}.faces must be integers, got {f.dtype}")
        if not np.isfinite(v).all():
            raise ValueCheckError(f"{name}.vertices must be finite")
        if f.min() < 0 or f.max() >= len(v):
            raise ValueCheckError(f"{name}.faces must index its {len(v)} vertices, got range [{f.min()}, {f.max()}]")
        normals = getattr(part, "normals", None)
        if normals is not None and (np.shape(normals) != v.shape or not np.isfinite(normals).all()):
            raise ShapeError(f"{name}.normals must be None or finite with the shape of its vertices {v.shape}")
    lm = np.asarray(getattr(subject, "face_landmarks", np.zeros((0, 3))))
    if lm.ndim != 2 or lm.shape[1] != 3 or len(lm) == 0 or not np.isfinite(lm).all():
        raise ShapeError(f"subject.face_landmarks must be finite with shape (K, 3), K > 0, got {lm.shape}")


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
    import scipy.sparse as sp

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


def _build_scene(mi: Any, subject: Any, camera: Camera, transform: np.ndarray, spp: int, max_depth: int,
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
            bsdf = {"type": "mask", "opacity": _bitmap((np.asarray(opacity) >= 0.5).astype(np.float32)), "bsdf": bsdf}
            has_null = True
        name = f"part{i:03d}_{getattr(part, 'name', 'mesh')}"
        objects[name] = _mitsuba_mesh(mi, name, v, np.asarray(part.faces), normals, bsdf, uvs=uvs)
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


def _session(subject: Any, camera: Camera, lighting_size: int, spp: int, variant: str | None, max_depth: int,
             seed: int, envmap_height: int | None, threads: int | None) -> _Session:
    """Validate everything, then select the variant and build the scene."""
    if not isinstance(camera, Camera):
        raise TypeCheckError(f"camera must be a Camera, got {type(camera).__name__}")
    check_positive_int(lighting_size, "lighting_size")
    check_positive_int(spp, "spp")
    check_positive_int(max_depth, "max_depth")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueCheckError(f"seed must be a non-negative int, got {seed!r}")
    height = 4 * lighting_size if envmap_height is None else envmap_height
    check_positive_int(height, "envmap_height")
    if threads is not None:
        check_positive_int(threads, "threads")
    _check_subject(subject)
    for part in subject.parts:
        material_bsdf(part.material)  # validates every material before any rendering
    basis, valid = olat_envmap_basis(lighting_size, height)
    variant = select_mitsuba_variant(variant)
    mi = _import_mitsuba()
    if threads is not None:
        import drjit as dr

        dr.set_thread_count(threads)
    transform = camera_transform(camera, _pivot(subject))
    scene, integrator = _build_scene(mi, subject, camera, transform, spp, max_depth, height)
    spp = int(scene.sensors()[0].sampler().sample_count())  # multijitter rounds up to a product, e.g. 32 -> 35
    return _Session(mi, scene, mi.traverse(scene), variant, integrator, transform, basis, valid, height, spp, seed)


def _meta(session: _Session, subject: Any, max_depth: int, lighting_size: int, seconds: float) -> dict[str, Any]:
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
        "pivot": _pivot(subject).tolist(),
        "subject_to_camera": session.transform.tolist(),
    }
    for key in ("split", "skin_tone"):
        if hasattr(subject, key):
            meta[key] = getattr(subject, key)
    return meta


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
        envmap_height, lights: the reference's (:func:`render_olat_reference`).
        threads: if given, sets Dr.Jit's thread count (process-global) before rendering.
        callback: progress, in lights: called with 1 after each light (reference), or after each chunk of the
            one-pass renderer with that chunk's share of the valid lights (floats that sum to the valid light
            count), so one progress bar of ``total`` = valid lights serves both.
        method: ``"onepass"`` (:mod:`~kornia_ilum.synth.lightstage.onepass`, needs a vectorised variant),
            ``"reference"`` (:func:`render_olat_reference`), or ``"auto"``: one-pass when the variant is
            vectorised and no reference-only option (``lights``, ``envmap_height``, ``max_depth`` other than 2)
            is given, else the reference.
        subsurface: one-pass only: apply ``subsurface.subsurface_scatter`` to the diffuse part when that module
            exists.
        denoise: one-pass only: apply ``denoise.denoise_field`` when that module exists (off by default: it
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
    if subsurface and _has_module("subsurface") and bool((res.gbuffer.subsurface > 0).any()):
        from kornia_ilum.synth.lightstage import subsurface as sss_mod

        diffuse = _on_dense(sss_mod.subsurface_scatter, diffuse, res, size)
        steps.append("subsurface")
    field = diffuse + specular
    del diffuse, specular
    if denoise and _has_module("denoise"):
        from kornia_ilum.synth.lightstage import denoise as dn_mod

        field = _on_dense(dn_mod.denoise_field, field, res, size)
        steps.append("denoise")
    rows = torch.zeros(3, len(res.rows), lighting_size**2, dtype=torch.bfloat16)
    rows.index_copy_(2, res.cols, field.to(torch.bfloat16))
    del field
    out = torch.zeros(3, size * size, lighting_size**2, dtype=torch.bfloat16)
    out.index_copy_(1, res.rows, rows)
    del rows
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


def _has_module(name: str) -> bool:
    import importlib.util

    return importlib.util.find_spec(f"kornia_ilum.synth.lightstage.{name}") is not None


def _on_dense(fn: Callable[..., torch.Tensor], compact: torch.Tensor, res: Any, size: int) -> torch.Tensor:
    """Apply a field operator that takes a dense ``(3, P, N_v)`` field and a GBuffer; back to the rows."""
    dense = torch.zeros(3, size * size, compact.shape[-1])
    dense[:, res.rows] = compact
    return fn(dense, res.gbuffer)[:, res.rows]


def render_olat_reference(
    subject: Subject,
    camera: Camera,
    *,
    lighting_size: int = 32,
    spp: int = 16,
    variant: str | None = None,
    max_depth: int = 4,
    seed: int = 0,
    envmap_height: int | None = None,
    threads: int | None = None,
    lights: np.ndarray | list[int] | None = None,
    callback: Callable[[int], Any] | None = None,
) -> ReflectanceField:
    r"""The per-light reference renderer: one Mitsuba render per light (module docstring for the method).

    Args:
        subject: a :class:`~kornia_ilum.synth.lightstage.subjects.Subject` (anything with ``parts`` of
            ``MeshPart`` with ``vertices``, ``faces`` and ``material``, ``face_landmarks`` and ``seed``).
        camera: the camera; its ``size`` is the image side.
        lighting_size: the mirror-ball side ``S`` of the lighting basis (``N = S^2`` lights).
        spp: samples per pixel of each OLAT render; the stratified sampler rounds it up to a product of two
            near-equal integers (16 and 25 stay, 32 becomes 35); ``meta["spp"]`` holds the count used.
        variant: the Mitsuba variant, or ``None`` for the first that works (:func:`select_mitsuba_variant`).
        max_depth: Mitsuba's path depth: 2 is direct light only, 4 adds two bounces of interreflection.
        seed: the sampler seed, the same for every light (module docstring, Noise).
        envmap_height: lat-long rows of the light bitmaps; default ``4 S`` (1.4 degree texels at ``S = 32``).
        threads: if given, sets Dr.Jit's thread count (process-global) before rendering.
        lights: render only these light indices (the other columns stay 0); default all valid lights.
            For benchmarks and tests.
        callback: called with 1 after each light (a progress bar's ``update``).

    Returns:
        the :class:`ReflectanceField`; ``meta`` records the variant, integrator, settings, the rendered light
        count, the wall time (``render_seconds``, of which ``setup_seconds`` before the first light), and the
        subject's ``split`` and ``skin_tone`` when it has them.

    Shape:
        - field: :math:`(3, P, N)` bfloat16, :math:`P = size^2`, :math:`N = S^2`
        - alpha: :math:`(1, size, size)` float32

    Convention:
        Light directions in the camera frame of SPEC.md; radiance units (module docstring).

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
        >>> rf = render_olat_reference(subject, Camera(30.0, 1.0, 0.0, 0.0, size=8), lighting_size=4, spp=4,
        ...                  variant="scalar_rgb")
        >>> rf.field.shape, rf.field.dtype, rf.meta["lights_rendered"]
        (torch.Size([3, 64, 16]), torch.bfloat16, 12)
    """
    start = time.perf_counter()
    session = _session(subject, camera, lighting_size, spp, variant, max_depth, seed, envmap_height, threads)
    setup = time.perf_counter() - start
    if lights is None:
        todo = session.valid
    else:
        todo = np.asarray(lights, dtype=np.int64).ravel()
        if len(todo) == 0 or not np.isin(todo, session.valid).all():
            raise ValueCheckError(f"lights must be valid light indices of the {lighting_size}^2 mirror ball")
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
    meta = _meta(session, subject, max_depth, lighting_size, time.perf_counter() - start)
    meta["lights_rendered"] = len(todo)
    meta["landmarks"] = [[round(float(x), 3) for x in xy] for xy in box.tolist()]  # LANDMARK_NAMES order
    meta["setup_seconds"] = round(setup, 3)
    return ReflectanceField(out, alpha, face_box, camera, int(subject.seed), meta)


def render_lighting(
    subject: Subject,
    camera: Camera,
    lighting: torch.Tensor,
    *,
    spp: int = 16,
    variant: str | None = None,
    max_depth: int = 4,
    seed: int = 0,
    envmap_height: int | None = None,
    threads: int | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    r"""Render a subject directly under a mirror-ball lighting: the reference that relighting must match.

    The envmap is the OLAT basis weighted by the lighting, ``sum_n L[n] basis_n``, so by the linearity of light
    transport the image equals ``relight(render_olat(...).field, L)`` up to Monte-Carlo noise (same scene,
    camera and settings as :func:`render_olat`).

    Args:
        subject: as for :func:`render_olat`.
        camera: the camera.
        lighting: ``(3, S, S)`` mirror-ball radiance (SPEC.md), non-negative; invalid pixels are ignored.
        spp, variant, max_depth, seed, envmap_height, threads: as for :func:`render_olat`.

    Returns:
        ``(image, alpha)``: ``(3, size, size)`` float32 linear RGB (premultiplied, background 0) and the
        ``(1, size, size)`` matte.

    Examples:
        >>> from types import SimpleNamespace
        >>> from kornia_ilum.synth.lightstage.olat import _icosphere
        >>> v, f = _icosphere(2)
        >>> ball = SimpleNamespace(name="ball", vertices=0.1 * v, faces=f,
        ...                        material=SimpleNamespace(kind="diffuse", albedo=(0.8, 0.8, 0.8)))
        >>> subject = SimpleNamespace(seed=0, parts=[ball], face_landmarks=0.1 * v)
        >>> image, alpha = render_lighting(subject, Camera(20.0, 1.0, 0.0, 0.0, size=8), torch.ones(3, 4, 4),
        ...                                spp=64, variant="scalar_rgb")
        >>> round(image[:, 3:5, 3:5].mean().item(), 1)  # a white environment: the albedo, up to noise
        0.8
    """
    check_tensor(lighting, "lighting", ["3", "S", "S"], nonnegative=True)
    if lighting.shape[-1] != lighting.shape[-2]:
        raise ShapeError(f"lighting must have shape (3, S, S), got {tuple(lighting.shape)}")
    lighting_size = int(lighting.shape[-1])
    session = _session(subject, camera, lighting_size, spp, variant, max_depth, seed, envmap_height, threads)
    lights = lighting.detach().to("cpu", torch.float64).flatten(1).T.numpy()  # (N, 3)
    img = session.render(np.asarray(session.basis @ lights))
    image = torch.from_numpy(np.ascontiguousarray(img[..., :3].transpose(2, 0, 1)))
    return image, torch.from_numpy(img[..., 3].copy())[None]


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
