r"""Mitsuba set-up shared by the light stage's renderers: the variant, the materials, the meshes.

Both renderers of :mod:`~kornia_ilum_lab.synth.lightstage.olat` (the one-pass one and the per-light reference) and
the previews shade a :class:`~kornia_ilum_lab.synth.lightstage.subjects.Material` with the Mitsuba BSDF of
:func:`material_bsdf`, so they differ only in how they sample, never in what they render.

Variants: Mitsuba 3 is an optional extra (``pip install kornia_ilum[lightstage]``); :func:`select_mitsuba_variant`
takes ``llvm_ad_rgb`` (vectorised, JIT-compiled; needed by the one-pass renderer) when it works on this machine,
else ``scalar_rgb``. ``constraints.txt`` pins Mitsuba 3.9.0 with Dr.Jit 1.4.0: Dr.Jit 1.5 emits LLVM
intrinsics that the system LLVM 15 of Debian 12 cannot compile, and the probe would then fall back to the
much slower scalar variant (docs/lightstage.rst, "Measured").

Materials (:func:`material_bsdf`): ``diffuse`` is Lambertian; ``skin``, ``glossy`` and ``hair`` are Mitsuba's
``principled`` BSDF (Disney, Burley 2012) with a GGX specular lobe of ``alpha = roughness`` and the material's
``specular``; ``metal`` is ``principled`` with ``metallic = 1`` (no diffuse part: a GGX lobe tinted by the
albedo, taken as ``F0``, Schlick's Fresnel towards white at grazing angles); all of these are two-sided. ``cornea`` is a smooth clear coat: a one-sided Fresnel mirror
(IOR from ``specular``: ``F0 = 0.08 specular``, ``eta = (1 + sqrt(F0)) / (1 - sqrt(F0))``, 1.376 for the real
cornea's ``F0 = 0.025``) over a straight-through transmission of about ``1 - F(theta)``. The transmission is a
*null* interface, so the ``volpath`` integrator traces shadow rays through it and the iris behind it is lit by
next-event estimation (with a dielectric, shadow rays would stop at the cornea and the iris would be lit only
by rare BSDF-sampled paths); the mirror lobe is sampled with probability 0.3 (not ``F0``), so catch-lights are
not starved of samples. The mirror reflects on the outer side only, so the back of a closed lens adds no second
glint; a closed lens attenuates the iris by ``(1 - F0)^2`` each way (two interfaces). The cornea's albedo is
ignored (a clear cornea). Given vertex ``normals`` of a part are used for shading; otherwise Mitsuba computes
smooth vertex normals.
Textures: ``albedo_texture`` and ``roughness_texture`` become Mitsuba ``bitmap`` textures looked up through the
part's ``uvs`` (stored as ``(u, 1 - v)``: Mitsuba's ``v`` runs down the image); ``opacity_texture`` parts are
wrapped in a ``mask`` BSDF by the reference renderer (texels thresholded at 0.5, nearest filtering), and the
one-pass renderer tests the same texels itself.
"""

from __future__ import annotations

import functools
import math
import os
import subprocess
import sys
from typing import TYPE_CHECKING, Any

import numpy as np

from kornia_ilum.core.check import check_choice
from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError

if TYPE_CHECKING:  # the subjects module is only needed for the annotation
    from kornia_ilum_lab.synth.lightstage.subjects import Material

__all__ = [
    "MATERIAL_KINDS",
    "MITSUBA_VARIANTS",
    "VARIANT_ENV",
    "bitmap_texture",
    "check_subject",
    "diffuse_twin_bsdf",
    "fresnel_ior",
    "import_mitsuba",
    "material_bsdf",
    "mitsuba_mesh",
    "select_mitsuba_variant",
]

#: Mitsuba variants tried in order by :func:`select_mitsuba_variant` when none is named.
MITSUBA_VARIANTS: tuple[str, ...] = ("llvm_ad_rgb", "scalar_rgb")

#: Environment variable that names the variant to use when ``variant=None`` (skips the probe).
VARIANT_ENV = "KORNIA_ILUM_MITSUBA_VARIANT"

MATERIAL_KINDS: tuple[str, ...] = ("skin", "diffuse", "glossy", "metal", "cornea", "hair")

_CORNEA_MIRROR_PROBABILITY = 0.3  # how often a camera path picks the cornea's mirror lobe



def import_mitsuba() -> Any:
    """The ``mitsuba`` module, or an :class:`ImportError` that names the optional extra to install.

    Returns:
        the ``mitsuba`` module (no variant is set here: :func:`select_mitsuba_variant` does it).

    Raises:
        ImportError: Mitsuba 3 is not installed.

    Examples:
        >>> import_mitsuba().__name__
        'mitsuba'
    """
    try:
        import mitsuba as mi  # lazy: keeps import kornia_ilum_lab.synth.lightstage free of Mitsuba
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
    mi = import_mitsuba()
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
            process). ``llvm_ad_rgb`` needs an LLVM that Dr.Jit can use (the system LLVM 15 of Debian 12
            works with the pinned Dr.Jit 1.4.0, not with 1.5); otherwise ``scalar_rgb`` is used, which gives
            the same images but only the slow per-light renderer.

    Returns:
        the active variant (Mitsuba's variant is process-global).

    Raises:
        ValueCheckError: the variant is not one that this Mitsuba build offers, or none works.

    Examples:
        >>> select_mitsuba_variant("scalar_rgb")
        'scalar_rgb'
    """
    mi = import_mitsuba()
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


def fresnel_ior(f0: float) -> float:
    """The IOR whose normal-incidence Fresnel reflectance is ``f0``.

    Inverts ``f0 = ((eta - 1) / (eta + 1))^2``: ``eta = (1 + sqrt(f0)) / (1 - sqrt(f0))``.

    Args:
        f0: the reflectance at normal incidence, in ``[0, 1)``.

    Returns:
        the relative index of refraction ``eta >= 1``.

    Examples:
        >>> round(fresnel_ior(0.04), 3)
        1.5
    """
    return (1.0 + math.sqrt(f0)) / (1.0 - math.sqrt(f0))


def material_bsdf(material: Material) -> dict[str, Any]:
    r"""The Mitsuba BSDF (a ``mitsuba.load_dict`` dict) of a subject :class:`Material`.

    ``roughness`` is the GGX ``alpha``; Mitsuba's ``principled`` takes ``sqrt(alpha)``. See the module
    docstring for the models.

    Args:
        material: a :class:`~kornia_ilum_lab.synth.lightstage.subjects.Material` (or anything with its attributes:
            ``kind``, ``albedo``, and optionally ``roughness``, ``specular`` and the textures).

    Returns:
        the BSDF as a dict for ``mitsuba.load_dict``: a ``twosided`` BSDF, or a ``blendbsdf`` for the cornea.
        With textures, it holds Mitsuba bitmaps (a variant must be set: :func:`select_mitsuba_variant`).

    Raises:
        ValueCheckError: an unknown ``kind``, or an albedo, roughness or specular outside ``[0, 1]``.

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
                "int_ior": fresnel_ior(r_slab),
                "ext_ior": 1.0,
                "specular_reflectance": {"type": "uniform", "value": 0.0},
                "specular_transmittance": {"type": "uniform", "value": 1.0 / (1.0 - w)},
            },
            "mirror": {
                # k = 0: the Fresnel reflectance F(theta) of a dielectric of IOR eta. One-sided: it reflects only
                # on the outer side, so the back of a closed lens (seen from inside it) adds no second glint
                "type": "conductor",
                "eta": fresnel_ior(f0),
                "k": 0.0,
                "specular_reflectance": {"type": "uniform", "value": 1.0 / w},
            },
        }
    albedo = _rgb(getattr(material, "albedo", None), "material.albedo")
    tex = getattr(material, "albedo_texture", None)
    if tex is not None:
        albedo = bitmap_texture(np.clip(np.asarray(tex, dtype=np.float32), 0.0, 1.0))
    rough_tex = getattr(material, "roughness_texture", None)
    if rough_tex is not None:
        rough = np.sqrt(np.clip(alpha * np.asarray(rough_tex, dtype=np.float32), 1e-4, 1.0))
        roughness: Any = bitmap_texture(rough)
    else:
        roughness = math.sqrt(max(alpha, 1e-4))
    if kind == "diffuse":
        inner: dict[str, Any] = {"type": "diffuse", "reflectance": albedo}
    else:  # skin, glossy, hair: a diffuse base under a GGX dielectric specular lobe; metal: the tinted lobe alone
        inner = {
            "type": "principled",
            "base_color": albedo,
            "roughness": roughness,
            "specular": specular,
            "metallic": 1.0 if kind == "metal" else 0.0,
        }
    return {"type": "twosided", "bsdf": inner}


def bitmap_texture(data: np.ndarray) -> dict[str, Any]:
    """A linear (raw) Mitsuba bitmap texture dict, nearest texel; row 0 of ``data`` is the top of the image.

    Args:
        data: ``(H, W)`` or ``(H, W, C)`` texel values.

    Returns:
        the texture as a dict for ``mitsuba.load_dict`` (``raw``: the values are used as they are, linear).

    Examples:
        >>> import numpy as np
        >>> _ = select_mitsuba_variant("scalar_rgb")  # Mitsuba's bitmaps need a variant
        >>> tex = bitmap_texture(np.zeros((2, 4, 3)))
        >>> tex["type"], tex["bitmap"].size(), tex["bitmap"].channel_count()
        ('bitmap', [4, 2], 3)
    """
    mi = import_mitsuba()
    arr = np.ascontiguousarray(data if data.ndim == 3 else data[..., None], dtype=np.float32)
    return {"type": "bitmap", "bitmap": mi.Bitmap(arr), "raw": True, "filter_type": "nearest"}


def diffuse_twin_bsdf(material: Material) -> dict[str, Any]:
    r"""The diffuse part of :func:`material_bsdf`: the same BSDF with ``specular = 0``.

    Mitsuba's ``principled`` is linear in ``specular`` (its GGX lobe's Fresnel scales with it and the diffuse
    base does not), so ``material_bsdf - diffuse_twin_bsdf`` is the specular part. A ``metal`` has no diffuse
    part: its twin is a black Lambertian, and all of its light is specular.

    Args:
        material: a subject :class:`Material`, as for :func:`material_bsdf`.

    Returns:
        the BSDF dict of :func:`material_bsdf` with the principled lobe's ``specular`` set to 0 (a black
        ``diffuse`` for a ``metal``; other BSDFs unchanged).

    Examples:
        >>> from types import SimpleNamespace
        >>> diffuse_twin_bsdf(SimpleNamespace(kind="skin", albedo=(0.5, 0.5, 0.5)))["bsdf"]["specular"]
        0.0
    """
    bsdf = material_bsdf(material)
    if getattr(material, "kind", None) == "metal":
        return {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0] * 3}}}
    if bsdf["type"] == "twosided" and bsdf["bsdf"]["type"] == "principled":
        bsdf = {"type": "twosided", "bsdf": {**bsdf["bsdf"], "specular": 0.0}}
    return bsdf


def mitsuba_mesh(mi: Any, name: str, *, vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray | None,
                  bsdf: dict[str, Any], uvs: np.ndarray | None = None) -> Any:
    """A Mitsuba mesh with the BSDF dict ``bsdf``, for the renderers and the previews.

    ``uvs`` (OBJ convention, ``v`` up) are stored as ``(u, 1 - v)``: image row 0 at ``v = 1``. Without
    ``normals``, Mitsuba computes smooth (area-weighted) vertex normals.

    Args:
        mi: the ``mitsuba`` module, with a variant set (:func:`select_mitsuba_variant`).
        name: the mesh's name.
        vertices: ``(V, 3)`` vertex positions in metres.
        faces: ``(F, 3)`` vertex indices of the triangles.
        normals: ``(V, 3)`` shading normals, or ``None``.
        bsdf: the BSDF dict (:func:`material_bsdf`).
        uvs: ``(V, 2)`` texture coordinates, or ``None``.

    Returns:
        the ``mitsuba.Mesh``.

    Convention:
        Metres, in the subject's frame (docs/conventions.rst, "Frames"); nothing is transformed here.

    Examples:
        >>> import numpy as np
        >>> mi = import_mitsuba()
        >>> _ = select_mitsuba_variant("scalar_rgb")
        >>> tri = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
        >>> mesh = mitsuba_mesh(mi, "tri", vertices=tri, faces=np.array([[0, 1, 2]]), normals=None,
        ...                    bsdf={"type": "diffuse"})
        >>> mesh.vertex_count(), mesh.face_count(), round(mesh.surface_area(), 3)
        (3, 1, 0.5)
    """
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


def check_subject(subject: Any) -> None:
    """Check a subject's ``parts`` (meshes) and ``face_landmarks`` before any rendering.

    Args:
        subject: a subject (:class:`~kornia_ilum_lab.synth.lightstage.Subject`, or anything with ``parts`` that
            have ``vertices``, ``faces`` and optionally ``normals``, and ``face_landmarks`` ``(K, 3)``).

    Returns:
        ``None``; it raises on a malformed subject.

    Raises:
        ShapeError, TypeCheckError, ValueCheckError: a malformed part (vertices, faces, normals) or landmarks.

    Examples:
        >>> from types import SimpleNamespace
        >>> tri = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
        >>> part = SimpleNamespace(name="tri", vertices=tri, faces=np.array([[0, 1, 2]]))
        >>> check_subject(SimpleNamespace(parts=[part], face_landmarks=tri))  # a valid subject: no error
        >>> check_subject(SimpleNamespace(parts=[part], face_landmarks=np.zeros((0, 3))))
        Traceback (most recent call last):
        ...
        kornia.core.exceptions.ShapeError: subject.face_landmarks must be finite with shape (K, 3), K > 0, got (0, 3)
    """
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
