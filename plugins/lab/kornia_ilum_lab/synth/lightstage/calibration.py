r"""The uniform-white check: does a light-stage face reflect what its skin is documented to reflect?

Relit by a uniform white environment of radiance 1 (:func:`uniform_response`), an unoccluded surface of
total reflectance ``rho`` reads ``rho``: no subsurface scattering, denoising or relighting step may create or
lose energy. The cache keeps each view's G-buffer albedo and skin coverage
(:class:`~kornia_ilum_lab.synth.lightstage.ReflectanceField` ``albedo``, ``skin``), so :func:`check_skin` compares,
pixel by pixel over the face's skin (fully covered skin pixels inside :func:`face_mask`, lips included):

- **energy**: the median of ``reading / (albedo + SKIN_SPECULAR_ALBEDO)`` per channel is at most ``1 + rtol``
  (nothing creates light) and at least ``1 - occlusion`` (:data:`~kornia_ilum_lab.synth.lightstage.subjects.skin.
  SKIN_SPECULAR_ALBEDO`: the light stage's skin specular under uniform light, seen head-on). The lower bound is
  wider: a face hides part of a uniform environment from itself (nose, brows, a fringe, glasses), so a real
  face reads less than its albedo too, while no step may add light;
- **skin**: the skin's documented total reflectance (the median albedo plus ``SKIN_SPECULAR_ALBEDO``: what a
  spectrophotometer held to an unoccluded patch would read) lies inside the measured range of facial skin of the
  subject's Monk tone (:func:`~kornia_ilum_lab.synth.lightstage.subjects.skin.measured_skin_range`). The reading
  itself is held to that total by the energy test; judging the reading against the range instead would count
  the face's own occlusion as a wrong skin colour.

:func:`check_cache` runs it over the subjects of a light-stage cache; ``kornia-ilum synth check-skin`` prints
the table and fails when a subject fails.

:func:`check_parts` holds a subject's other parts (eyes, brows, lashes, hair, facial hair, teeth, glasses,
hats) to what they may reflect, from its materials alone (no render): each part's mean diffuse albedo over its
opaque texels inside :data:`PART_ALBEDO_RANGES`. Hair of every kind is held to the span of natural hair, from
black (measured ``L*`` 18 with its shine, Y 0.025, so its diffuse part lies below that: J. Cosmetic Science
51(5), "Measurement of hair luster") to white; the teeth, over their enamel texels (not the gums, not the
map's blank area), to the span of in-vivo incisors (Joiner et al. 2008: L* 70-85, b* 15-25: 0.2 to 0.85 per
linear channel and a luminance of 0.41 to 0.66, :data:`PART_LUMINANCE_RANGES`); the rest, for which no measured albedo was found, to what any natural surface may reflect
(below fresh snow's 0.9), so nothing in the light stage reflects more light than it receives. A metal glasses
frame has no diffuse albedo: its ``albedo`` is its specular colour ``F0`` and is held to the same span. The
lips are skin (the same albedo map) and are inside the skin check's mask.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any

import torch

from kornia_ilum.color import LUMINANCE
from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum_lab.synth.lightstage.cache import read_manifest
from kornia_ilum_lab.synth.lightstage.field import ReflectanceField
from kornia_ilum_lab.synth.lightstage.portraits import load_fields
from kornia_ilum_lab.synth.lightstage.portraits.compose import add_relit
from kornia_ilum_lab.synth.lightstage.subjects import LANDMARK_NAMES
from kornia_ilum_lab.synth.lightstage.subjects.makehuman import enamel_mask
from kornia_ilum_lab.synth.lightstage.subjects.skin import SKIN_SPECULAR_ALBEDO, measured_skin_range

__all__ = [
    "PART_ALBEDO_RANGES",
    "PART_LUMINANCE_RANGES",
    "PartCheck",
    "SkinCheck",
    "check_cache",
    "check_parts",
    "check_skin",
    "face_mask",
    "uniform_response",
]

_FACE_OUTLINE = ("brow_right_top", "brow_left_top", "eye_right_outer", "eye_left_outer", "jaw_right", "jaw_left",
                 "chin", "cheek_right", "cheek_left")


def uniform_response(field: ReflectanceField, radiance: float = 1.0) -> torch.Tensor:
    r"""The subject relit by a uniform white environment of ``radiance``: ``(3, size, size)`` linear.

    Args:
        field: a reflectance field, dense or compact.
        radiance: the environment's radiance, the same in every direction and channel; finite, non-negative.

    Returns:
        the relit image ``(3, size, size)`` float32, linear, premultiplied by the field's alpha (0 outside
        the subject).

    Raises:
        ValueCheckError: ``radiance`` is negative or not finite.

    Convention:
        Units of docs/conventions.rst ("Units of lighting"): an unoccluded white Lambertian surface reads
        ``radiance``.

    Examples:
        >>> from kornia_ilum_lab.synth.lightstage.scene import Camera
        >>> rf = ReflectanceField(torch.full((3, 4, 16), 0.25, dtype=torch.bfloat16), torch.ones(1, 2, 2),
        ...                       torch.tensor([0.0, 0.0, 2.0, 2.0]), Camera(30.0, 1.0, 0.0, 0.0, size=2), 7)
        >>> uniform_response(rf).shape
        torch.Size([3, 2, 2])
    """
    if not (math.isfinite(radiance) and radiance >= 0):
        raise ValueCheckError(f"radiance must be finite and non-negative, got {radiance}")
    s = field.lighting_size
    lighting = radiance * mirror_ball_valid(s).float().expand(1, 3, s, s)
    frame = torch.zeros(1, 3, field.size, field.size)
    return add_relit(frame, field, lighting=lighting)[0]


def face_mask(landmarks: torch.Tensor, size: int) -> torch.Tensor:
    r"""``(size, size)`` bool: the pixels inside the convex hull of the face's outline landmarks (brows, outer eye
    corners, cheeks, jaw, chin), given in pixels ``(x, y)`` in the order of
    :data:`~kornia_ilum_lab.synth.lightstage.subjects.LANDMARK_NAMES`.

    Args:
        landmarks: ``(L, 2)`` (or ``(L, 3)``, the third column ignored) pixel coordinates ``(x, y)`` of the
            face landmarks, ``L = len(LANDMARK_NAMES)``; continuous coordinates, pixel ``(i, j)`` has its
            centre at ``(j + 0.5, i + 0.5)``.
        size: the image side in pixels.

    Returns:
        the mask ``(size, size)``, bool: True for the pixels whose centre is inside the hull.

    Shape:
        - landmarks: :math:`(L, 2)` or :math:`(L, 3)`
        - Output: :math:`(size, size)`

    Convention:
        Image pixels, row 0 at the top, ``x`` to the right (the box convention of :mod:`kornia_ilum.detection`).

    Examples:
        >>> from kornia_ilum_lab.synth.lightstage.subjects import LANDMARK_NAMES
        >>> lm = torch.full((len(LANDMARK_NAMES), 2), 8.0)
        >>> corners = {"brow_right_top": (2, 2), "brow_left_top": (6, 2), "chin": (4, 7), "jaw_right": (2, 6)}
        >>> for name, xy in corners.items():
        ...     lm[LANDMARK_NAMES.index(name)] = torch.tensor(xy, dtype=torch.float32)
        >>> lm[LANDMARK_NAMES.index("jaw_left")] = torch.tensor([6.0, 6.0])
        >>> int(face_mask(lm, 10).sum()) > 0, bool(face_mask(lm, 10)[0, 0])
        (True, False)
    """
    from scipy.spatial import ConvexHull  # lazy: SciPy only for the check

    pts = torch.stack([landmarks[LANDMARK_NAMES.index(n), :2].double() for n in _FACE_OUTLINE])
    hull = pts[torch.as_tensor(ConvexHull(pts.numpy()).vertices)]  # counter-clockwise in (x, y)
    yy, xx = torch.meshgrid(torch.arange(size, dtype=torch.float64) + 0.5,
                            torch.arange(size, dtype=torch.float64) + 0.5, indexing="ij")
    edge = hull.roll(-1, 0) - hull
    cross = edge[:, 0, None, None] * (yy[None] - hull[:, 1, None, None]) - edge[:, 1, None, None] * (
        xx[None] - hull[:, 0, None, None])
    return (cross >= 0).all(0)


@dataclass
class SkinCheck:
    r"""The uniform-white check of one subject-view (:func:`check_skin`).

    Attributes:
        subject_seed, view_index, skin_tone: which subject and view; its Monk tone.
        pixels: the face's skin pixels checked (fully covered, all skin, inside :func:`face_mask`).
        albedo: their median diffuse albedo (the G-buffer's), linear RGB.
        measured: their median reading under uniform radiance 1.
        total: the documented total reflectance, ``albedo + SKIN_SPECULAR_ALBEDO``.
        energy: the median of ``reading / (albedo + SKIN_SPECULAR_ALBEDO)`` per pixel, per channel.
        low, high: the measured range of facial skin of the tone.
        rtol, occlusion: the energy test's bounds, ``1 - occlusion <= energy <= 1 + rtol``.

    Examples:
        >>> grey = (0.5, 0.5, 0.5)
        >>> check = SkinCheck(1, 0, 3, pixels=100, albedo=(0.476,) * 3, measured=grey, total=grey,
        ...                   energy=(1.0, 1.0, 1.0), low=(0.34, 0.21, 0.14), high=(0.53, 0.31, 0.25), rtol=0.1,
        ...                   occlusion=0.15)
        >>> check.energy_ok, check.skin_ok, check.ok  # energy conserved, but grey is not tone 3's skin
        (True, False, False)
    """

    subject_seed: int
    view_index: int
    skin_tone: int
    pixels: int
    albedo: tuple[float, float, float]
    measured: tuple[float, float, float]
    total: tuple[float, float, float]
    energy: tuple[float, float, float]
    low: tuple[float, float, float]
    high: tuple[float, float, float]
    rtol: float
    occlusion: float

    @property
    def energy_ok(self) -> bool:
        """The skin neither creates nor loses energy: ``1 - occlusion <= energy <= 1 + rtol``."""
        return all(1.0 - self.occlusion <= e <= 1.0 + self.rtol for e in self.energy)

    @property
    def skin_ok(self) -> bool:
        """The skin reflects like measured skin of its tone: ``total`` inside ``[low, high]``."""
        return all(lo <= t <= hi for lo, t, hi in zip(self.low, self.total, self.high, strict=True))

    @property
    def ok(self) -> bool:
        """Both tests pass."""
        return self.energy_ok and self.skin_ok


def _rgb(values: torch.Tensor) -> tuple[float, float, float]:
    return (float(values[0]), float(values[1]), float(values[2]))


def check_skin(field: ReflectanceField, skin_tone: int, rtol: float = 0.1, occlusion: float = 0.15) -> SkinCheck:
    r"""The uniform-white check of one subject-view (module docstring).

    Args:
        field: a subject-view of the one-pass renderer (its ``gbuffer``) or of a cache (its ``albedo`` and
            ``skin``), with ``meta["landmarks"]``.
        skin_tone: its Monk tone (1 to 10).
        rtol: how much more than its albedo the skin may read (its specular grows at grazing views: dark skin
            in blue reads up to 8 % more seen from the side; noise; interreflection).
        occlusion: how much less (the face's own occlusion of the environment).

    Returns:
        the check's readings and verdicts (:attr:`SkinCheck.ok`).

    Raises:
        ValueCheckError: the field has no ``albedo`` / ``skin`` (a cache of an older light stage) or no
            landmarks, or its face shows no skin pixel.

    Examples:
        >>> from kornia_ilum.geometry import mirror_ball_valid
        >>> from kornia_ilum_lab.synth.lightstage.scene import Camera
        >>> lights = mirror_ball_valid(4).flatten()  # the 12 valid lights of a 4 x 4 basis
        >>> field = (lights * 0.5 / lights.sum()).to(torch.bfloat16).expand(3, 16, 16).clone()  # reads 0.5
        >>> lm = torch.full((len(LANDMARK_NAMES), 2), 2.0)
        >>> corners = {"brow_right_top": (0, 0), "brow_left_top": (4, 0), "jaw_left": (4, 4), "jaw_right": (0, 4)}
        >>> for name, xy in corners.items():  # a face outline around the whole 4 x 4 image
        ...     lm[LANDMARK_NAMES.index(name)] = torch.tensor(xy, dtype=torch.float32)
        >>> rf = ReflectanceField(field, torch.ones(1, 4, 4), torch.tensor([0.0, 0.0, 4.0, 4.0]),
        ...                       Camera(30.0, 1.0, 0.0, 0.0, size=4), 7, {"landmarks": lm.tolist()},
        ...                       albedo=torch.full((3, 4, 4), 0.5 - SKIN_SPECULAR_ALBEDO), skin=torch.ones(1, 4, 4))
        >>> check = check_skin(rf, skin_tone=3)
        >>> check.pixels, check.energy_ok, check.skin_ok  # a grey face: energy conserved, but no skin colour
        (16, True, False)
    """
    gbuffer = field.gbuffer  # a fresh render has its G-buffer; a cached view, the two buffers the cache keeps
    albedo_map = field.albedo if gbuffer is None else gbuffer.albedo
    skin_map = field.skin if gbuffer is None else gbuffer.subsurface
    if albedo_map is None or skin_map is None or "landmarks" not in field.meta:
        raise ValueCheckError(
            f"subject {field.subject_seed}: the uniform-white check needs the field's albedo, skin and landmarks "
            "(rebuild the cache with this version's one-pass renderer)"
        )
    mask = face_mask(torch.tensor(field.meta["landmarks"]), field.size)
    mask &= (field.alpha[0] >= 0.999) & (skin_map[0] >= 0.999)
    if not bool(mask.any()):
        raise ValueCheckError(f"subject {field.subject_seed}: its face shows no skin pixel")
    reading = uniform_response(field)[:, mask].double()
    albedo = albedo_map[:, mask].double()
    ratio = reading / (albedo + SKIN_SPECULAR_ALBEDO)
    low, high = measured_skin_range(int(skin_tone))
    median_albedo = albedo.median(1).values
    return SkinCheck(
        subject_seed=field.subject_seed, view_index=int(field.meta.get("view_index", -1)), skin_tone=int(skin_tone),
        pixels=int(mask.sum()), albedo=_rgb(median_albedo), measured=_rgb(reading.median(1).values),
        total=_rgb(median_albedo + SKIN_SPECULAR_ALBEDO), energy=_rgb(ratio.median(1).values), low=low, high=high,
        rtol=rtol, occlusion=occlusion,
    )


def check_cache(cache: str | os.PathLike[str], split: str | None = "eval", rtol: float = 0.1,
                occlusion: float = 0.15) -> list[SkinCheck]:
    r"""The uniform-white check of every subject-view of a light-stage cache (of ``split``; ``None``: all).

    Each subject's tone comes from the cache manifest (``skin_tone``); subjects without one (mannequins) are
    skipped.

    Args:
        cache: a light-stage cache folder (:func:`~kornia_ilum_lab.synth.lightstage.build_cache`).
        split: ``"train"``, ``"eval"`` or ``None`` (every subject).
        rtol: as in :func:`check_skin`.
        occlusion: as in :func:`check_skin`.

    Returns:
        one :class:`SkinCheck` per subject-view with a skin tone, in the cache's order.

    Raises:
        ValueCheckError: the cache has no field of ``split``, or fields of an older light stage (no albedo and
            skin buffers).

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as d:  # an empty folder: no field to check
        ...     check_cache(d)  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        kornia.core.exceptions.ValueCheckError: no reflectance field in '...' for split 'eval'
        >>> results = check_cache("lightstage/")  # a cache built by kornia-ilum synth subjects  # doctest: +SKIP
    """
    tones = {(e["subject_seed"], e["view_index"]): e.get("skin_tone") for e in read_manifest(cache)["entries"]}
    out = []
    for field in load_fields(cache, split=split):
        tone = tones.get((field.subject_seed, int(field.meta.get("view_index", -1))))
        if tone is not None:
            out.append(check_skin(field, int(tone), rtol, occlusion))
    return out


#: The range ``(low, high)`` of a part's mean linear albedo (every channel), by part name (``"beard"``: every
#: ``beard*`` shell); a part not named here (cornea, lenses: clear; the mannequins' pupil, mouth and shirt) is not
#: checked. Module docstring.
PART_ALBEDO_RANGES: dict[str, tuple[float, float]] = {
    "hair": (0.005, 0.6), "brows": (0.005, 0.6), "lashes": (0.005, 0.6), "beard": (0.005, 0.6),
    "eyes": (0.02, 0.9), "sclera": (0.02, 0.9), "iris": (0.005, 0.9), "lips": (0.005, 0.9),
    "teeth": (0.2, 0.85), "tongue": (0.02, 0.9), "glasses": (0.005, 0.9), "hat": (0.0, 0.9),
}  # fmt: skip

#: The range ``(low, high)`` of a part's mean luminance (Rec. 709 ``Y`` of its mean albedo), for the parts that
#: have a measured one: the teeth, L* 70-85 (Joiner et al. 2008).
PART_LUMINANCE_RANGES: dict[str, tuple[float, float]] = {"teeth": (0.41, 0.66)}


@dataclass
class PartCheck:
    """The albedo check of one part of a subject (:func:`check_parts`): its mean albedo and allowed range.

    Attributes:
        name: the part's name.
        albedo: its mean diffuse albedo over its opaque texels, linear RGB.
        low, high: the allowed range (:data:`PART_ALBEDO_RANGES`), for every channel.
        luminance: the allowed range of its luminance (:data:`PART_LUMINANCE_RANGES`), or ``None``.

    Examples:
        >>> PartCheck("hair", (0.02, 0.015, 0.01), *PART_ALBEDO_RANGES["hair"]).ok
        True
        >>> PartCheck("teeth", (0.95, 0.95, 0.9), *PART_ALBEDO_RANGES["teeth"]).ok  # brighter than snow
        False
    """

    name: str
    albedo: tuple[float, float, float]
    low: float
    high: float
    luminance: tuple[float, float] | None = None

    @property
    def ok(self) -> bool:
        """Every channel inside ``[low, high]``, and the luminance inside its range where there is one."""
        y = sum(w * a for w, a in zip(LUMINANCE, self.albedo))
        return all(self.low <= a <= self.high for a in self.albedo) and (
            self.luminance is None or self.luminance[0] <= y <= self.luminance[1])


def _mean_albedo(material: Any, name: str = "") -> tuple[float, float, float]:
    """A material's mean albedo over its opaque texels (``alpha >= 0.5``; for ``"teeth"`` its enamel texels,
    :func:`~kornia_ilum_lab.synth.lightstage.subjects.makehuman.enamel_mask`, not the gums or the map's blank
    area), or its constant albedo."""
    texture = material.albedo_texture
    if texture is None:
        return tuple(float(c) for c in material.albedo)  # type: ignore[return-value]
    rgb = torch.as_tensor(texture, dtype=torch.float64).reshape(-1, 3)
    if material.opacity_texture is not None:
        rgb = rgb[torch.as_tensor(material.opacity_texture).reshape(-1) >= 0.5]
    elif name == "teeth":
        rgb = rgb[torch.from_numpy(enamel_mask(texture)).reshape(-1)]
    return _rgb(rgb.mean(0))


def check_parts(subject: Any) -> list[PartCheck]:
    r"""The albedo check of each part of ``subject`` named in :data:`PART_ALBEDO_RANGES` (module docstring).

    Args:
        subject: a subject (:class:`~kornia_ilum_lab.synth.lightstage.Subject`, or anything with ``parts`` that
            have a ``name`` and a ``material``).

    Returns:
        one :class:`PartCheck` per checked part, in the order of ``subject.parts``.

    Examples:
        >>> from kornia_ilum_lab.synth.lightstage.subjects import MannequinSource
        >>> all(c.ok for c in check_parts(MannequinSource().sample(0)))
        True
    """
    out = []
    for part in subject.parts:
        key = "beard" if part.name.startswith("beard") else part.name
        if key in PART_ALBEDO_RANGES:
            low, high = PART_ALBEDO_RANGES[key]
            out.append(PartCheck(part.name, _mean_albedo(part.material, key), low, high,
                                 PART_LUMINANCE_RANGES.get(key)))
    return out
