r"""What every subject source shares: materials, meshes, :class:`Subject`, skin tones, the split.

A *subject source* turns a seed into a :class:`Subject` (:class:`SubjectSource`): the MakeHuman heads of
:mod:`~kornia_ilum_lab.synth.lightstage.subjects.makehuman` (photoreal, need the CC0 assets) or the mannequins of
:mod:`~kornia_ilum_lab.synth.lightstage.subjects.mannequin` (signed-distance heads, need nothing). Renderers see only
:class:`MeshPart` and :class:`Material`.

Skin tones (Monk Skin Tone scale):
    The 10 tones of the Monk Skin Tone (MST) scale (Monk 2019; Google's published swatches
    :data:`MONK_SKIN_TONES_SRGB`). The swatches are display colours, not reflectances; each tone's albedo
    :data:`SKIN_ALBEDO` comes from measured facial skin colour instead (:mod:`.skin`, docs/lightstage.rst,
    "Skin").

Train / evaluation split:
    :func:`subject_split` is ``"eval"`` when the first 8 bytes of
    ``blake2b(f"kornia_ilum.lightstage.subject:{seed}")`` (little-endian) are 0 modulo 10, else ``"train"``:
    about 10% of seeds, fixed forever, disjoint by construction, the same for every source, and unrelated to
    the subject's appearance.

Convention:
    Metres, in the frame of docs/conventions.rst (+X right, +Y up, +Z toward the camera): the subject faces
    +Z, the eyes are near ``y = 0``. The subject's right eye is at ``-X`` (on the image's left).
"""

from __future__ import annotations

import colorsys
import math
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np
import torch

from kornia_ilum.color import srgb_to_linear
from kornia_ilum.core.errors import TypeCheckError
from kornia_ilum.core.seeding import hashed_seed
from kornia_ilum_lab.synth.lightstage.subjects.skin import SKIN_ALBEDO

__all__ = [
    "FABRIC_NEUTRALS",
    "FRAME_ALBEDO",
    "GLASSES_FRAMES",
    "LANDMARK_NAMES",
    "MONK_SKIN_TONES_SRGB",
    "SKIN_ALBEDO",
    "TEETH_ALBEDO",
    "Material",
    "MeshPart",
    "Subject",
    "SubjectSource",
    "fabric_colour",
    "frame_material",
    "icosphere",
    "merge_meshes",
    "pick",
    "seed_digest",
    "subject_split",
]

#: The Monk Skin Tone scale's published sRGB swatches, tones 1 (lightest) to 10 (darkest).
MONK_SKIN_TONES_SRGB: tuple[str, ...] = (
    "f6ede4", "f3e7db", "f7ead0", "eadaba", "d7bd96", "a07e56", "825c43", "604134", "3a312a", "292420",
)  # fmt: skip

#: Linear RGB of neutral fabrics (shirts, hats).
FABRIC_NEUTRALS = {
    "white": (0.75, 0.75, 0.73),
    "light_grey": (0.40, 0.40, 0.40),
    "charcoal": (0.05, 0.05, 0.055),
    "black": (0.015, 0.015, 0.017),
    "navy": (0.010, 0.018, 0.070),
    "beige": (0.48, 0.40, 0.28),
    "olive": (0.10, 0.10, 0.035),
    "denim": (0.07, 0.11, 0.20),
}


#: Glasses frames, by kind: the share of each (mannequins and MakeHuman heads alike).
GLASSES_FRAMES: dict[str, float] = {"black": 3.0, "tortoise": 2.0, "metal": 1.5, "colour": 1.5}
#: The linear albedo of each frame kind but ``"colour"`` (a random :func:`fabric_colour`); for ``"metal"`` the
#: colour of its specular reflectance at normal incidence, ``F0`` (metals have no diffuse albedo): titanium, the
#: commonest metal of spectacle frames, (0.542, 0.497, 0.449) in Real-Time Rendering 4th ed., Table 9.2.
FRAME_ALBEDO: dict[str, tuple[float, float, float]] = {
    "black": (0.015, 0.015, 0.015), "tortoise": (0.12, 0.05, 0.015), "metal": (0.542, 0.497, 0.449),
}  # fmt: skip

#: Linear RGB albedo of tooth enamel (the incisors' mean): CIELAB L* 77, a* 1, b* 20, the middle of the in-vivo
#: spectrophotometer measurements of Joiner et al. 2008 ("Tooth colour: a review of the literature", L* 70-85,
#: b* 15-25), converted with D65 sRGB primaries.
TEETH_ALBEDO: tuple[float, float, float] = (0.62, 0.50, 0.32)


def frame_material(frame: str, albedo: tuple[float, float, float], roughness: float) -> "Material":
    """The material of a glasses frame of kind ``frame`` (:data:`GLASSES_FRAMES`).

    A ``"metal"`` frame is a ``"metal"`` material (a tinted GGX lobe, no diffuse part) of ``F0`` = ``albedo``;
    the others are ``"glossy"`` plastics (a diffuse ``albedo`` under a 4 % lobe); both of GGX ``roughness``
    (a satin finish: the one-pass renderer samples each light's region, so a sharper lobe would only be
    noisier).

    Args:
        frame: the frame's kind.
        albedo: its :data:`FRAME_ALBEDO` (or a random colour for ``"colour"``), linear RGB.
        roughness: the GGX alpha of a plastic frame's lobe.

    Returns:
        the :class:`Material`.

    Examples:
        >>> frame_material("metal", FRAME_ALBEDO["metal"], 0.12).kind, frame_material("black", (0.015,) * 3, 0.12).kind
        ('metal', 'glossy')
    """
    rgb = tuple(float(c) for c in albedo)
    if frame == "metal":
        return Material("metal", rgb, roughness, 0.5)
    return Material("glossy", rgb, roughness, 0.5)


def icosphere(subdivisions: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """A unit icosphere ``(vertices (V, 3) float32, faces (F, 3) int32)``, outward-wound; for examples, tests.

    Args:
        subdivisions: how many times each triangle of the icosahedron is split in four.

    Returns:
        ``(vertices, faces)``: ``V = 10 * 4^n + 2`` unit vertices and ``F = 20 * 4^n`` triangles,
        counter-clockwise seen from outside.

    Examples:
        >>> v, f = icosphere(1)
        >>> v.shape, f.shape
        ((42, 3), (80, 3))
    """
    t = (1.0 + math.sqrt(5.0)) / 2.0
    verts = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
             (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
             (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5),
             (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
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


def merge_meshes(meshes: list[tuple[np.ndarray, ...]]) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Concatenate meshes ``(verts, faces[, normals])`` into one (float32 vertices and normals, int32 faces).

    Args:
        meshes: the meshes, each ``(vertices (V, 3), faces (F, 3))`` or ``(vertices, faces, normals (V, 3))``.

    Returns:
        ``(vertices, faces, normals)``, the faces re-indexed into the concatenated vertices; ``normals`` is
        ``None`` unless every mesh has them.

    Examples:
        >>> v, f = icosphere(0)
        >>> verts, faces, normals = merge_meshes([(v, f), (v + 3.0, f)])
        >>> verts.shape, faces.shape, int(faces.max()), normals
        ((24, 3), (40, 3), 23, None)
    """
    vs, fs, ns, off = [], [], [], 0
    for m in meshes:
        vs.append(m[0])
        fs.append(m[1] + off)
        off += len(m[0])
        ns.append(m[2] if len(m) > 2 else None)
    normals = None if any(n is None for n in ns) else np.concatenate(ns).astype(np.float32)
    return np.concatenate(vs).astype(np.float32), np.concatenate(fs).astype(np.int32), normals


def pick(rng: np.random.Generator, options: dict[str, float]) -> str:
    """One of ``options``' names, drawn with probabilities proportional to their weights.

    Args:
        rng: the random generator (one draw).
        options: non-negative weights by name, not all 0.

    Returns:
        the name drawn.

    Examples:
        >>> pick(np.random.default_rng(0), {"black": 3.0, "white": 0.0})
        'black'
    """
    names = list(options)
    w = np.array([options[n] for n in names], dtype=np.float64)
    return names[int(rng.choice(len(names), p=w / w.sum()))]


def fabric_colour(rng: np.random.Generator, saturated_p: float) -> tuple[str, tuple[float, float, float]]:
    """A random fabric colour: a saturated hue (name ``"hsv"``) or a named neutral.

    Args:
        rng: the random generator.
        saturated_p: the probability of a saturated hue, in ``[0, 1]``.

    Returns:
        ``(name, albedo)``: ``"hsv"`` and a random saturated colour, or a name of :data:`FABRIC_NEUTRALS` and its
        albedo; linear RGB in ``[0, 1]``.

    Examples:
        >>> name, rgb = fabric_colour(np.random.default_rng(0), saturated_p=0.0)
        >>> name in FABRIC_NEUTRALS, rgb == FABRIC_NEUTRALS[name]
        (True, True)
        >>> fabric_colour(np.random.default_rng(0), saturated_p=1.0)[0]
        'hsv'
    """
    if rng.random() < saturated_p:
        h, s, v = rng.random(), rng.uniform(0.55, 1.0), rng.uniform(0.35, 0.95)
        srgb = colorsys.hsv_to_rgb(h, s, v)
        lin = srgb_to_linear(torch.tensor(srgb, dtype=torch.float64).view(3, 1, 1)).flatten().tolist()
        return "hsv", (round(lin[0], 4), round(lin[1], 4), round(lin[2], 4))
    name = str(rng.choice(list(FABRIC_NEUTRALS)))
    return name, FABRIC_NEUTRALS[name]


#: The names of :attr:`Subject.face_landmarks`, in order ("left"/"right" are the subject's own).
LANDMARK_NAMES: tuple[str, ...] = (
    "brow_right_top", "brow_left_top", "glabella",
    "eye_right_outer", "eye_right_inner", "eye_left_inner", "eye_left_outer",
    "nose_tip", "subnasale", "mouth_right", "mouth_left", "upper_lip", "lower_lip", "chin",
    "jaw_right", "jaw_left", "cheek_right", "cheek_left", "ear_right", "ear_left",
)  # fmt: skip


@dataclass
class Material:
    """How a mesh part is shaded (see the module's *Materials*).

    Args:
        kind: ``"skin"``, ``"diffuse"``, ``"glossy"``, ``"metal"``, ``"cornea"`` or ``"hair"``.
        albedo: the diffuse albedo (the transmittance for ``"cornea"``, the specular colour ``F0`` for
            ``"metal"``), linear RGB in ``[0, 1]``.
        roughness: the GGX alpha of the specular lobe.
        specular: Mitsuba principled ``specular`` (``F0 = 0.08 specular``; 0.5 is an index of refraction of 1.5).
        albedo_texture: optional ``(H, W, 3)`` float32 linear albedo map, looked up through the part's
            ``uvs``; it replaces ``albedo`` where given (``albedo`` then holds its mean, for previews).
        opacity_texture: optional ``(H, W)`` float32 alpha in ``[0, 1]`` (hair cards, brows, lashes): light
            and camera rays pass where it is 0 (alpha-tested, ``alpha >= 0.5`` is opaque).
        roughness_texture: optional ``(H, W)`` float32 multiplier of ``roughness`` (oily and dry skin zones).
        subsurface: whether the renderer's subsurface approximation applies to this part's diffuse light.

    Examples:
        >>> skin = Material("skin", (0.45, 0.3, 0.22), roughness=0.35, subsurface=True)
        >>> skin.kind, skin.specular, skin.albedo_texture is None
        ('skin', 0.5, True)
    """

    kind: str
    albedo: tuple[float, float, float]
    roughness: float = 0.5
    specular: float = 0.5
    albedo_texture: np.ndarray | None = field(default=None, repr=False)
    opacity_texture: np.ndarray | None = field(default=None, repr=False)
    roughness_texture: np.ndarray | None = field(default=None, repr=False)
    subsurface: bool = False


@dataclass
class MeshPart:
    """One mesh with one material.

    Args:
        name: the part (``"skin"``, ``"lips"``, ``"sclera"``, ``"iris"``, ``"cornea"``, ``"hair"``, ...).
        vertices: ``(V, 3)`` float32 metres in the frame of docs/conventions.rst.
        faces: ``(F, 3)`` int32, counter-clockwise seen from outside (normals point out).
        material: its :class:`Material`.
        normals: optional ``(V, 3)`` float32 unit outward vertex normals (the SDF's gradient), for smooth
            shading; ``None`` lets the renderer compute them.
        uvs: optional ``(V, 2)`` float32 texture coordinates in ``[0, 1]`` (``v`` up, OBJ convention), needed
            by the material's textures.

    Examples:
        >>> v, f = icosphere(1)
        >>> ball = MeshPart("ball", 0.1 * v, f, Material("diffuse", (0.8, 0.8, 0.8)))  # 10 cm radius
        >>> ball.vertices.shape, ball.material.kind, ball.normals
        ((42, 3), 'diffuse', None)
    """

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    material: Material
    normals: np.ndarray | None = None
    uvs: np.ndarray | None = None


@dataclass
class Subject:
    """A synthetic subject: its meshes, skin tone, face landmarks and the parameters it was drawn with.

    Args:
        seed: the seed it was made from.
        split: ``"train"`` or ``"eval"`` (:func:`subject_split`).
        parts: its :class:`MeshPart`, each name once.
        skin_tone: the Monk Skin Tone index, 1 (lightest) to 10 (darkest).
        face_landmarks: ``(K, 3)`` float32 points on the face named by :data:`LANDMARK_NAMES`, from the top of
            the brows to the chin and from ear to ear: their projected bounding box is the face box.
        params: the sampled shape, expression and appearance parameters (JSON-serialisable).
        source: the generator's name (``"mannequin"``, ``"makehuman"``, ...).
        face_albedo: the mean linear albedo of the face's skin, RGB.

    Examples:
        >>> v, f = icosphere(1)
        >>> ball = MeshPart("ball", 0.1 * v, f, Material("diffuse", (0.8, 0.8, 0.8)))
        >>> subject = Subject(1, subject_split(1), [ball], skin_tone=5, face_landmarks=0.1 * v[:len(LANDMARK_NAMES)])
        >>> subject.split, subject.part("ball").name, subject.source
        ('eval', 'ball', 'mannequin')
    """

    seed: int
    split: str
    parts: list[MeshPart]
    skin_tone: int
    face_landmarks: np.ndarray
    params: dict = field(default_factory=dict)
    source: str = "mannequin"
    face_albedo: tuple[float, float, float] | None = None

    def part(self, name: str) -> MeshPart:
        """The part called ``name`` (``KeyError`` when the subject has none)."""
        for p in self.parts:
            if p.name == name:
                return p
        raise KeyError(f"subject {self.seed} has no part {name!r}; it has {[p.name for p in self.parts]}")


def seed_digest(seed: int, salt: str) -> int:
    """A seed for one purpose (``salt``) of subject ``seed``: a hash, so purposes draw independent numbers.

    Args:
        seed: the subject's seed.
        salt: the purpose (``"subject"``, ``"hair"``, ...).

    Returns:
        the first 8 bytes of ``blake2b(f"kornia_ilum.lightstage.{salt}:{seed}")``, an int in ``[0, 2^64)``.

    Raises:
        TypeCheckError: ``seed`` is not an int.

    Examples:
        >>> seed_digest(7, "hair") == seed_digest(7, "hair"), seed_digest(7, "hair") == seed_digest(7, "eyes")
        (True, False)
    """
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise TypeCheckError(f"seed must be an int, got {type(seed).__name__}")
    return hashed_seed(f"kornia_ilum.lightstage.{salt}:{int(seed)}")


def subject_split(seed: int) -> str:
    """``"eval"`` for about one seed in ten (fixed by a hash of the seed), else ``"train"``.

    Args:
        seed: the subject's seed (any int).

    Returns:
        ``"eval"`` when ``blake2b(f"kornia_ilum.lightstage.subject:{seed}")`` is 0 modulo 10, else ``"train"``.

    Raises:
        TypeCheckError: ``seed`` is not an int.

    Examples:
        >>> [subject_split(s) for s in range(6)]
        ['train', 'eval', 'train', 'eval', 'train', 'train']
        >>> sum(subject_split(s) == "eval" for s in range(10_000))
        1015
    """
    return "eval" if seed_digest(seed, "subject") % 10 == 0 else "train"


@runtime_checkable
class SubjectSource(Protocol):
    """Anything that makes subjects from seeds: ``name`` and ``sample(seed) -> Subject``.

    Attributes:
        name: the source's name, stored as :attr:`Subject.source` (``"mannequin"``, ``"makehuman"``, ...).

    Examples:
        >>> class Balls:  # one ball per seed
        ...     name = "balls"
        ...     def sample(self, seed):
        ...         v, f = icosphere(1)
        ...         ball = MeshPart("skin", 0.1 * v, f, Material("skin", SKIN_ALBEDO[4], subsurface=True))
        ...         return Subject(seed, subject_split(seed), [ball], 5, 0.1 * v[:20], source=self.name)
        >>> isinstance(Balls(), SubjectSource), Balls().sample(3).source
        (True, 'balls')
    """

    name: str

    def sample(self, seed: int) -> Subject:
        """The subject of ``seed`` (the same seed always gives the same subject)."""
        ...
