r"""Photoreal light-stage subjects from the CC0 MakeHuman 1.1 assets (hm08 base mesh, targets and proxies).

:class:`MakeHumanSource` turns a seed into a :class:`~kornia_ilum_lab.synth.lightstage.subjects.Subject`:

1. Shape: the base mesh plus the macro targets (a Dirichlet ethnicity mix, gender, age 18 to 85 years, muscle,
   weight; the weights of :func:`macro_target_weights`), a random subset of the face-detail sliders of
   ``modeling_modifiers.json`` (values ``N(0, 0.3)`` clipped to ``[-0.8, 0.8]``, left/right pairs mirrored) and,
   for about half the subjects, a few expression units with small weights (smile, brow raise, a slightly open
   mouth, squint). Targets apply to the whole mesh, helpers included (the proxies bind to helper vertices).
2. Cut: the ``body`` group's head, neck and shoulders down to a horizontal plane 21 cm below the chin (the
   source's ``cut_below_chin``; lower for whole-photo framings); the triangles crossing the plane are clipped, so
   the border is a straight triangulated line on the plane.
3. UVs: vertices are split at UV seams (one UV per vertex); normals are the area-weighted smooth normals of the
   unsplit mesh, so seams do not show.
4. Skin: one of the 18 albedo maps (age and sex matched, of the tone family nearer the target), decoded to
   linear RGB and re-tinted by a per-channel scale so that its mean over the face's UV area is the subject's
   tone (:data:`SKIN_ALBEDO` of an MST tone drawn uniformly over 1..10, times ``exp(N(0, 0.08))`` brightness,
   the draw clipped to +-0.12, and ``exp(N(0, 0.03))`` per channel), clipped to 0.95. Kind ``"skin"`` with ``subsurface=True``, GGX roughness
   0.3 to 0.5, F0 0.025 to 0.035 and a ``roughness_texture`` that makes the T-zone (forehead and nose) oilier.
5. Proxies bound to the morphed mesh: high-poly eyes (the eyeball, diffuse, textured with one of 9 iris
   colours drawn by skin tone (:func:`iris_probabilities`; the ``brown`` map's irises re-tinted medium to
   dark brown, :func:`retint_iris`), and its outer shell as a closed ``"cornea"``, the tear film's and the
   cornea's gloss), one of 12 eyebrows, one of 4 eyelashes, teeth (the enamel re-tinted to measured incisors,
   :func:`retint_teeth`), tongue and one of
   six hair styles (or bald), hair re-tinted to a natural colour. Hair, brows and lashes carry binary
   ``opacity_texture`` maps (:func:`clean_alpha`); their faces that cover no opaque texel are dropped
   (:func:`~kornia_ilum_lab.synth.lightstage.subjects.makehuman_assets.opaque_faces`). For three subjects in four,
   hair that hangs in front of the face below the brows (the side-swept fringes of ``short03`` and ``bob02``)
   is trimmed there, as a cut fringe.
6. Accessories (:mod:`~kornia_ilum_lab.synth.lightstage.subjects.makehuman_accessories`), drawn after every other
   choice so that those stay as they were: glasses, for men a stubble, moustache, goatee or beard, and a beanie
   (short hair under it).
7. Clothes, for a source built with ``clothes=True``: one of MakeHuman's 12 CC0 outfits (of the subject's sex
   four times in five) bound like the proxies, cut at the same plane, with the skin under it hidden, and a matte
   cloth of a measured fabric's albedo (black cotton 0.015 to white 0.75, or a saturated dye;
   :func:`~kornia_ilum_lab.synth.lightstage.subjects.fabric_colour`), drawn from its own stream so that every
   other choice stays as it was. The outfits ship without textures: the cloth is uniform.
8. Frame: metres, the axes of docs/conventions.rst (+Y up, +Z toward the camera), the eyes' centres at
   ``y = 0``, ``z = 0.066``.

The assets are parsed once per source, lazily (targets on first use), and cached as sparse offsets.
"""

from __future__ import annotations

import dataclasses
import os
import re
import threading
from pathlib import Path

import numpy as np

from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum_lab.synth.lightstage.subjects.base import (
    LANDMARK_NAMES,
    SKIN_ALBEDO,
    TEETH_ALBEDO,
    Material,
    MeshPart,
    Subject,
    fabric_colour,
    seed_digest,
    subject_split,
)
from kornia_ilum_lab.synth.lightstage.subjects.makehuman_accessories import (
    accessory_params,
    beanie_part,
    beard_parts,
    beard_weight,
    glasses_parts,
    inside_beanie,
    uv_weight_map,
)
from kornia_ilum_lab.synth.lightstage.subjects.makehuman_assets import (
    ETHNICITIES,
    MakeHumanAssetsNotFoundError,
    ObjMesh,
    Proxy,
    bind_proxy,
    load_texture,
    macro_target_weights,
    opaque_faces,
    raster_uv_mask,
    read_mhclo,
    read_mhmat,
    read_modifier_pairs,
    read_obj,
    read_target,
    vertex_normals,
    years_to_age,
)

__all__ = [
    "LANDMARK_VERTICES",
    "SWEPT_FRINGE_STYLES",
    "MakeHumanAssetsNotFoundError",
    "MakeHumanSource",
    "clean_alpha",
    "clip_mesh_below",
    "enamel_mask",
    "find_makehuman_root",
    "iris_probabilities",
    "retint_hair",
    "retint_iris",
    "retint_skin",
    "retint_teeth",
]

#: hm08 base-mesh vertex of each :data:`LANDMARK_NAMES` point. Chosen by geometry on the unmorphed base mesh
#: (decimetres): the midline points (nose tip 297 = most forward; subnasale 5072 = the profile's deepest point
#: under it; upper/lower lip 466/495 = the lips' most forward points; chin 747 = the menton, lowest front point)
#: from the outer profile of the ``|x| < 0.012`` vertices; eye corners = the extreme-x skin vertices within
#: 1.25 eyeball radii of the ``helper-*-eye`` centre at its height; brow tops = the most forward vertex 2.8 cm
#: above the eye centre at its x; glabella = the midline 1.4 cm above the eyes; mouth corners = the vertices
#: moved most by the ``mouth-corner-puller`` (smile) unit; jaw = the extreme-x vertex at the gonion's height
#: (y 6.38-6.48, z 0.3-0.9); cheeks = the extreme-x vertex 1.5 cm below and 3 cm behind the eye centre; ears =
#: the vertex nearest the centroid of the outermost 2.2 cm of the ear. Mirror pairs were checked symmetric.
LANDMARK_VERTICES: dict[str, int] = {
    "brow_right_top": 229, "brow_left_top": 7002, "glabella": 227,
    "eye_right_outer": 4880, "eye_right_inner": 1207, "eye_left_inner": 7899, "eye_left_outer": 11498,
    "nose_tip": 297, "subnasale": 5072, "mouth_right": 369, "mouth_left": 7129, "upper_lip": 466,
    "lower_lip": 495, "chin": 747, "jaw_right": 1001, "jaw_left": 7695, "cheek_right": 5201,
    "cheek_left": 11812, "ear_right": 5662, "ear_left": 12259,
}  # fmt: skip

_DETAIL_GROUPS = ("head", "forehead", "eyebrows", "eyes", "nose", "mouth", "ears", "chin", "cheek", "neck")
_EYE_Z = 0.066  # the eyes' centres, like the mannequins'
_CUT_BELOW_CHIN = 0.21  # metres
#: The lowest cut (metres below the chin): the hands hang about 0.5 m below it, the hips 0.6 m.
_DEEPEST_CUT = 1.0
#: MakeHuman's CC0 outfits (``clothes/``), by the sex they were made for.
_OUTFITS = {
    "female": ("female_casualsuit01", "female_casualsuit02", "female_elegantsuit01", "female_sportsuit01"),
    "male": ("male_casualsuit01", "male_casualsuit02", "male_casualsuit03", "male_casualsuit04",
             "male_casualsuit05", "male_casualsuit06", "male_elegantsuit01", "male_worksuit01"),
}  # fmt: skip
#: The share of dyed (saturated) cloth among the outfits; the rest are the measured neutrals.
_DYED_CLOTH = 0.35
_HAIR_STYLES = ("short01", "short02", "short03", "short04", "bob02", "afro01")
#: The styles whose fringe sweeps over an eye unless trimmed (``params["fringe"] == "trimmed"``).
SWEPT_FRINGE_STYLES = ("short03", "bob02")
_IRIS = ("blue", "bluegreen", "brown", "brownlight", "deepblue", "green", "grey", "ice", "lightblue")
#: The iris maps' shares among light (blue, green, grey) eyes, and among brown ones (``brownlight`` is hazel).
_IRIS_P = (0.08, 0.06, 0.0, 0.0, 0.05, 0.08, 0.06, 0.05, 0.08)
_BROWN_IRIS_P = (0.0, 0.0, 0.7, 0.3, 0.0, 0.0, 0.0, 0.0, 0.0)
#: The share of light eyes by Monk skin tone 1-10: common with the lightest skin, rare from tone 5 on.
_LIGHT_EYES = (0.6, 0.5, 0.35, 0.2, 0.08, 0.03, 0.01, 0.01, 0.01, 0.01)
#: The linear colour of a brown iris, medium brown (tone 1) to dark brown (tone 10): the ``brown`` map's own
#: iris is a saturated red-brown (linear mean 0.058, 0.006, 0.002) that renders red.
_BROWN_IRIS = ((0.060, 0.027, 0.011), (0.022, 0.011, 0.005))
#: Natural hair colours, linear RGB (a dyed look is left out).
_HAIR_COLOURS: dict[str, tuple[float, float, float]] = {
    "black": (0.012, 0.010, 0.009), "dark_brown": (0.035, 0.022, 0.014), "brown": (0.080, 0.048, 0.026),
    "light_brown": (0.17, 0.11, 0.060), "blonde": (0.36, 0.26, 0.14), "red": (0.23, 0.075, 0.030),
    "grey": (0.26, 0.25, 0.24), "white": (0.55, 0.54, 0.52),
}  # fmt: skip
#: Expression units: (name, [(unit, scale)], max weight).
_EXPRESSIONS = (
    ("smile", [("mouth-corner-puller", 1.0)], 0.7),
    ("brow_raise", [("eyebrows-left-up", 1.0), ("eyebrows-right-up", 1.0)], 0.7),
    ("mouth_open", [("mouth-open", 1.0)], 0.35),
    ("squint", [("eye-left-slit", 1.0), ("eye-right-slit", 1.0)], 0.5),
    ("brow_down", [("eyebrows-left-down", 1.0), ("eyebrows-right-down", 1.0)], 0.4),
)


def find_makehuman_root(root: str | Path | None = None) -> Path:
    """The MakeHuman data root: ``root``, else ``$KORNIA_ILUM_MAKEHUMAN``, else ``$KORNIA_ILUM_SHARED_DATA/makehuman``.

    Args:
        root: the data root, or ``None`` to take it from the environment variables.

    Returns:
        the data root (a folder with ``3dobjs/base.obj``).

    Raises:
        MakeHumanAssetsNotFoundError: no folder with ``3dobjs/base.obj`` there.

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as d:
        ...     try:
        ...         find_makehuman_root(d)
        ...     except MakeHumanAssetsNotFoundError:  # also a FileNotFoundError
        ...         print("no assets")
        ...     (Path(d) / "3dobjs").mkdir()
        ...     (Path(d) / "3dobjs" / "base.obj").touch()
        ...     find_makehuman_root(d) == Path(d)
        no assets
        True
    """
    if root is None:
        if os.environ.get("KORNIA_ILUM_MAKEHUMAN"):
            root = os.environ["KORNIA_ILUM_MAKEHUMAN"]
        elif os.environ.get("KORNIA_ILUM_SHARED_DATA"):
            root = Path(os.environ["KORNIA_ILUM_SHARED_DATA"]) / "makehuman"
        else:
            raise MakeHumanAssetsNotFoundError(
                "no MakeHuman assets: pass root=, or set $KORNIA_ILUM_MAKEHUMAN to the MakeHuman data root "
                "(the folder with 3dobjs/base.obj) or $KORNIA_ILUM_SHARED_DATA to the folder holding makehuman/"
            )
    root = Path(root)
    if not (root / "3dobjs" / "base.obj").is_file():
        raise MakeHumanAssetsNotFoundError(
            f"no MakeHuman data root at {root} (3dobjs/base.obj is missing): set $KORNIA_ILUM_MAKEHUMAN to the "
            "MakeHuman data root or $KORNIA_ILUM_SHARED_DATA to the folder holding makehuman/"
        )
    return root


# --------------------------------------------------------------------------------------------------------
# Geometry helpers
# --------------------------------------------------------------------------------------------------------


def clip_mesh_below(
    vertices: np.ndarray, faces: np.ndarray, y_cut: float, attrs: list[np.ndarray]
) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """Keep the part of a triangle mesh with ``y >= y_cut``, clipping the triangles that cross the plane.

    The crossing edges get one new vertex each (shared by the triangles on both sides of the edge), exactly on
    the plane, with the attributes interpolated linearly; orientation is kept.

    Args:
        vertices: ``(V, 3)`` positions.
        faces: ``(F, 3)`` triangles.
        y_cut: the plane's height.
        attrs: per-vertex ``(V, ...)`` arrays interpolated onto the new vertices (uvs, normals).

    Returns:
        ``(vertices, faces, attrs)`` of the kept part, unused vertices dropped.

    Examples:
        >>> v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 2, 0]])
        >>> cv, cf, _ = clip_mesh_below(v, np.array([[0, 1, 2]]), 1.0, [])
        >>> cf.shape, bool(np.allclose(sorted(cv[:, 1]), [1.0, 1.0, 2.0]))
        ((1, 3), True)
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    above = v[:, 1] >= y_cut
    na = above[f].sum(1)
    keep = f[na == 3]
    cross = f[(na == 1) | (na == 2)]
    ca = above[cross]
    one_above = ca.sum(1) == 1
    # Rotate each crossing triangle so that its odd corner (the only one above, or the only one below) is first.
    odd = np.where(one_above, np.argmax(ca, 1), np.argmin(ca, 1))
    idx = (odd[:, None] + np.arange(3)[None]) % 3
    rot = np.take_along_axis(cross, idx, 1)
    a, b, c = rot[:, 0], rot[:, 1], rot[:, 2]
    edges = np.concatenate([np.stack([a, b], 1), np.stack([c, a], 1)])  # the bc edge is never crossed
    ek = np.sort(edges, 1)
    uk, inv = np.unique(ek, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    n = len(cross)
    e_ab, e_ca = inv[:n] + len(v), inv[n:] + len(v)
    i0, i1 = uk[:, 0], uk[:, 1]
    t = (y_cut - v[i0, 1]) / np.where(np.abs(v[i1, 1] - v[i0, 1]) > 1e-30, v[i1, 1] - v[i0, 1], 1.0)
    t = np.clip(t, 0.0, 1.0)
    new_v = v[i0] + t[:, None] * (v[i1] - v[i0])
    new_v[:, 1] = y_cut
    tris = [keep]
    oa = one_above
    tris.append(np.stack([a[oa], e_ab[oa], e_ca[oa]], 1))  # a above: the tip
    ob = ~one_above  # a below, b and c above: a quad b, c, e_ca, e_ab
    tris.append(np.stack([b[ob], c[ob], e_ca[ob]], 1))
    tris.append(np.stack([b[ob], e_ca[ob], e_ab[ob]], 1))
    out_f = np.concatenate(tris)
    all_v = np.concatenate([v, new_v])
    out_attrs = []
    for at in attrs:
        at = np.asarray(at, dtype=np.float64)
        tt = t.reshape((-1,) + (1,) * (at.ndim - 1))
        out_attrs.append(np.concatenate([at, at[i0] + tt * (at[i1] - at[i0])]))
    used, remap = np.unique(out_f, return_inverse=True)
    return all_v[used], remap.reshape(-1, 3), [at[used] for at in out_attrs]


def _over_the_eyes(points: np.ndarray, brow_y: float) -> np.ndarray:
    """Which ``points`` (metres) hang in front of the face below the brows' tops (at height ``brow_y``): a fringe
    there is trimmed.

    The region is the front of the face (``|x| < 7`` cm, in front of the eyes' centres less 1 cm) below 4 mm
    over the brows' tops, so a trimmed fringe ends just over the brows, as a cut fringe does.
    """
    return (points[:, 1] < brow_y + 0.004) & (np.abs(points[:, 0]) < 0.07) & (points[:, 2] > _EYE_Z - 0.01)


def _split_uv(tri_v: np.ndarray, tri_t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Split vertices at UV seams: ``(base_vertex, uv_index, faces)`` of the split vertices."""
    key = tri_v.astype(np.int64) * 10_000_000 + tri_t.astype(np.int64)
    uk, inv = np.unique(key.reshape(-1), return_inverse=True)
    return uk // 10_000_000, uk % 10_000_000, inv.reshape(-1, 3)


# --------------------------------------------------------------------------------------------------------
# Textures
# --------------------------------------------------------------------------------------------------------


def retint_skin(
    texture: np.ndarray, mask: np.ndarray, target: tuple[float, float, float], max_albedo: float = 0.95
) -> tuple[np.ndarray, tuple[float, float, float]]:
    """Scale a linear albedo map per channel so that its mean over ``mask`` is ``target``, keeping its detail.

    A few fixed-point steps compensate for the clipping to ``max_albedo``.

    Args:
        texture: ``(H, W, 3)`` linear albedo.
        mask: ``(H, W)`` bool region whose mean is matched (the face's UV area).
        target: the wanted mean, linear RGB.
        max_albedo: the clip.

    Returns:
        ``(texture, mean)``: the ``(H, W, 3)`` float32 re-tinted map and its mean over ``mask`` (RGB tuple).

    Examples:
        >>> tex = np.full((4, 4, 3), 0.5, np.float32)
        >>> out, mean = retint_skin(tex, np.ones((4, 4), bool), (0.2, 0.1, 0.05))
        >>> [round(c, 3) for c in mean]
        [0.2, 0.1, 0.05]
    """
    tex = np.asarray(texture, dtype=np.float32)
    tgt = np.asarray(target, dtype=np.float64)
    base = tex[mask].astype(np.float64).mean(0)
    scale = tgt / np.maximum(base, 1e-6)
    out = tex
    for _ in range(4):
        out = np.clip(tex * scale.astype(np.float32), 0.0, max_albedo)
        mean = out[mask].astype(np.float64).mean(0)
        scale = scale * tgt / np.maximum(mean, 1e-6)
    out = np.clip(tex * scale.astype(np.float32), 0.0, max_albedo).astype(np.float32)
    mean = out[mask].astype(np.float64).mean(0)
    return out, (float(mean[0]), float(mean[1]), float(mean[2]))


def enamel_mask(texture: np.ndarray) -> np.ndarray:
    """The texels of a teeth map that are enamel: neither gum (red over 1.6 times green) nor blank (linear mean
    under 0.05, the map's unused area).

    Args:
        texture: ``(H, W, 3)`` linear albedo.

    Returns:
        ``(H, W)`` bool.

    Examples:
        >>> tex = np.array([[[0.3, 0.28, 0.27], [0.2, 0.04, 0.05], [0.0, 0.0, 0.0]]], np.float32)
        >>> enamel_mask(tex).tolist()  # a tooth, the gum, blank
        [[True, False, False]]
    """
    t = np.asarray(texture, dtype=np.float32)
    return (t[..., 0] <= 1.6 * t[..., 1]) & (t.mean(-1) >= 0.05)


def retint_teeth(texture: np.ndarray, target: tuple[float, float, float] = TEETH_ALBEDO) -> np.ndarray:
    """A teeth map whose enamel texels (:func:`enamel_mask`) average ``target`` (:func:`retint_skin` on them;
    the gums and the rest unchanged).

    MakeHuman's map has neutral enamel of about 0.30 linear (L* 60); measured incisors are brighter and
    yellower (:data:`~kornia_ilum_lab.synth.lightstage.subjects.base.TEETH_ALBEDO`).

    Args:
        texture: ``(H, W, 3)`` linear albedo.
        target: the enamel's mean, linear RGB.

    Returns:
        ``(H, W, 3)`` float32.

    Examples:
        >>> tex = np.array([[[0.3, 0.28, 0.27], [0.2, 0.04, 0.05]]], np.float32)
        >>> [round(float(c), 2) for c in retint_teeth(tex)[0, 0]], retint_teeth(tex)[0, 1].tolist() == tex[0, 1].tolist()
        ([0.62, 0.5, 0.32], True)
    """
    tex = np.asarray(texture, dtype=np.float32)
    mask = enamel_mask(tex)
    if not mask.any():
        return tex
    tinted, _ = retint_skin(tex, mask, target)
    return np.where(mask[..., None], tinted, tex).astype(np.float32)


def iris_probabilities(tone: int) -> np.ndarray:
    """The probability of each iris map (:data:`_IRIS`) for a subject of Monk skin tone ``tone`` (1-10).

    A mix of the light-eyed and the brown-eyed distributions, the share of light eyes falling with the tone.

    Args:
        tone: the Monk Skin Tone, 1 (lightest) to 10 (darkest).

    Returns:
        ``(len(_IRIS),)`` float64 probabilities summing to 1, in the order of ``_IRIS``.

    Examples:
        >>> p = iris_probabilities(8)
        >>> round(float(p.sum()), 6), bool(p[_IRIS.index("brown")] > 0.6)
        (1.0, True)
    """
    light = _LIGHT_EYES[int(tone) - 1]
    p = light * np.array(_IRIS_P) / sum(_IRIS_P) + (1.0 - light) * np.array(_BROWN_IRIS_P) / sum(_BROWN_IRIS_P)
    return p / p.sum()


def retint_iris(texture: np.ndarray, colour: tuple[float, float, float]) -> np.ndarray:
    """Re-colour the irises of an eye map: ``colour`` times the iris texels' relative luminance (clipped 0.2-3).

    The iris texels are the saturated ones (chroma over 0.35 of the value, in display-encoded values above
    0.15): neither the pale sclera nor the black pupil.

    Args:
        texture: ``(H, W, 3)`` linear RGB.
        colour: the irises' wanted mean colour, linear RGB.

    Returns:
        ``(H, W, 3)`` float32, the rest of the map unchanged.

    Examples:
        >>> tex = np.array([[[0.6, 0.55, 0.5], [0.06, 0.006, 0.002], [0.0, 0.0, 0.0]]], np.float32)
        >>> [round(float(x), 3) for x in retint_iris(tex, (0.03, 0.015, 0.006))[0, :, 0]]
        [0.6, 0.03, 0.0]
    """
    tex = np.asarray(texture, np.float32)
    enc = np.clip(tex, 0.0, 1.0) ** (1 / 2.2)
    value = enc.max(-1)
    iris = (value > 0.15) & ((value - enc.min(-1)) > 0.35 * value)
    out = tex.copy()
    if iris.any():
        out[iris] = _luminance_detail(tex, iris)[iris, None] * np.asarray(colour, np.float32)
    return out


def _luminance_detail(texture: np.ndarray, where: np.ndarray) -> np.ndarray:
    """A map's detail: each texel's Rec. 709 luminance over the mean luminance of the ``where`` texels (of all
    texels when none), clipped to 0.2-3; a new colour times it re-colours the map."""
    lum = np.asarray(texture, np.float32) @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    ref = float(lum[where].mean()) if where.any() else float(lum.mean())
    return np.clip(lum / max(ref, 1e-5), 0.2, 3.0)


def retint_hair(texture: np.ndarray, opaque: np.ndarray, colour: tuple[float, float, float]) -> np.ndarray:
    """Re-colour a hair/brow map: ``colour`` times the map's relative luminance (its detail, clipped to 0.2-3).

    Args:
        texture: ``(H, W, 3)`` linear RGB.
        opaque: ``(H, W)`` bool where the strands are (the mean is taken there).
        colour: the wanted mean colour, linear RGB.

    Returns:
        ``(H, W, 3)`` float32 linear RGB in ``[0, 0.95]``. The transparent texels take the detail of their
        nearest strand texel (edge padding): the maps are black there, and a bilinear lookup at a strand's edge
        would blend that black in, drawing a dark line along every card's cut-out.

    Examples:
        >>> tex = np.zeros((1, 4, 3), np.float32); tex[0, :2] = 0.2  # two strand texels, then black
        >>> out = retint_hair(tex, np.array([[True, True, False, False]]), (0.1, 0.05, 0.02))
        >>> [round(float(x), 3) for x in out[0, :, 0]]  # the black texels are padded with the strand's colour
        [0.1, 0.1, 0.1, 0.1]
    """
    import cv2  # lazy: OpenCV is slow to import, and few steps need it

    detail = _luminance_detail(texture, opaque)
    if opaque.any():  # the clipping moves the mean (brow and lash maps: to 0.2, all but a few texels clipped)
        detail = detail / max(float(detail[opaque].mean()), 1e-6)
    if opaque.any() and not opaque.all():
        # nearest opaque texel of every texel: labels number the zero (opaque) pixels in raster order
        _, label = cv2.distanceTransformWithLabels((~opaque).astype(np.uint8), cv2.DIST_L2, 5,
                                                  labelType=cv2.DIST_LABEL_PIXEL)
        detail = detail[opaque][label - 1]
    return np.clip(detail[..., None] * np.asarray(colour, np.float32), 0.0, 0.95).astype(np.float32)


def clean_alpha(alpha: np.ndarray, lo: float = 0.2, hi: float = 0.6) -> np.ndarray:
    """A binary opacity from a soft alpha mask: the threshold that keeps the mask's mean coverage.

    Alpha-testing at 0.5 a soft mask (hair cards, brows and lashes are mostly grey) would thin it; here the
    threshold is the alpha level whose covered area equals ``mean(alpha)`` (clipped to ``[lo, hi]``), so the
    faint film (alpha below it) goes and the strands stay, with no grey left.

    Args:
        alpha: ``(H, W)`` alpha in ``[0, 1]``.
        lo: the lowest threshold.
        hi: the highest threshold.

    Returns:
        ``(H, W)`` float32 of 0 and 1.

    Examples:
        >>> a = np.array([[0.0, 0.05, 0.3, 1.0]])
        >>> clean_alpha(a).tolist()
        [[0.0, 0.0, 1.0, 1.0]]
    """
    a = np.asarray(alpha, dtype=np.float32)
    cover = float(a.mean())
    q = np.quantile(a, 1.0 - cover) if 0.0 < cover < 1.0 else 0.5
    thr = float(np.clip(q, lo, hi))
    return (a >= thr).astype(np.float32)


# --------------------------------------------------------------------------------------------------------
# The source
# --------------------------------------------------------------------------------------------------------


def _clothes_params(seed: int, male: bool) -> dict:
    """The outfit and its cloth of subject ``seed``, from their own stream (module docstring, step 7)."""
    rng = np.random.default_rng(seed_digest(seed, "clothes"))
    own, other = ("male", "female") if male else ("female", "male")
    outfits = _OUTFITS[own if rng.random() < 0.8 else other]
    fabric, albedo = fabric_colour(rng, saturated_p=_DYED_CLOTH)
    return {"outfit": str(outfits[int(rng.integers(len(outfits)))]), "fabric": fabric,
            "albedo": [round(float(x), 5) for x in albedo]}


class _Assets:
    """Everything parsed once: the base mesh, targets (lazily), proxies, textures and the UV masks."""

    def __init__(self, root: Path, cut_below_chin: float = _CUT_BELOW_CHIN) -> None:
        self.root = root
        self.lock = threading.RLock()
        self.base: ObjMesh = read_obj(root / "3dobjs" / "base.obj")
        self.nv = len(self.base.vertices)
        self.target_files = {p.stem: p for p in (root / "targets").rglob("*.target") if "expression" not in p.parts}
        self.expr_files = {
            (p.parent.name, p.stem): p for p in (root / "targets" / "expression" / "units").rglob("*.target")
        }
        self.targets: dict[object, tuple[np.ndarray, np.ndarray]] = {}
        pairs = read_modifier_pairs(root / "modifiers" / "modeling_modifiers.json", _DETAIL_GROUPS)
        self.sliders: list[tuple[str, str | None, str | None]] = []
        for _, t, lo, hi in pairs:
            names = [f"{t}-{lo}", f"{t}-{hi}"] if lo else [t]
            if all(n in self.target_files for n in names):
                self.sliders.append((t, lo, hi))
        body = self.base.groups.index("body")
        bt = self.base.tri_group == body
        tri_v, tri_t = self.base.tri_v[bt], self.base.tri_t[bt]
        self.body_tri = tri_v
        self.eye_groups = [self.base.group_vertices(g) for g in ("helper-r-eye", "helper-l-eye")]
        v0 = self.base.vertices
        # Keep only what can be above any cut (the chin rises at most a few cm with the targets).
        chin = v0[LANDMARK_VERTICES["chin"], 1]
        near = (v0[tri_v, 1] > chin - 10 * cut_below_chin - 1.2).any(1)
        sb, st, sf = _split_uv(tri_v[near], tri_t[near])
        self.split_base, self.split_uv, self.split_faces = sb, self.base.uvs[st], sf
        # Face region (for the skin re-tint): the front of the head between brows and chin, inside the jaw.
        lm = {k: v0[i] for k, i in LANDMARK_VERTICES.items()}
        n0 = vertex_normals(v0, tri_v)
        fx = (v0[:, 0] > lm["cheek_right"][0]) & (v0[:, 0] < lm["cheek_left"][0])
        fy = (v0[:, 1] > lm["chin"][1]) & (v0[:, 1] < lm["brow_left_top"][1] + 0.1)
        face_v = fx & fy & (n0[:, 2] > 0.35) & (v0[:, 2] > lm["cheek_left"][2])
        face_t = face_v[tri_v].all(1)
        self.tex_size = 512
        self.face_mask = raster_uv_mask(self.base.uvs[tri_t[face_t]], self.tex_size)
        # T-zone: forehead (brows to 4 cm above) and the nose ridge, for an oilier (smoother) skin there.
        fh = (np.abs(v0[:, 0]) < 0.35) & (v0[:, 1] > lm["brow_left_top"][1] - 0.05) & (
            v0[:, 1] < lm["brow_left_top"][1] + 0.45
        )
        nose = (np.abs(v0[:, 0]) < 0.14) & (v0[:, 1] > lm["subnasale"][1]) & (v0[:, 1] < lm["glabella"][1])
        tz = (fh | nose) & (n0[:, 2] > 0.3) & (v0[:, 2] > lm["cheek_left"][2])
        import cv2  # lazy: OpenCV is slow to import, and few steps need it

        tzm = raster_uv_mask(self.base.uvs[tri_t[tz[tri_v].all(1)]], self.tex_size).astype(np.float32)
        self.tzone = cv2.GaussianBlur(tzm, (0, 0), 6.0)
        # The head's UV island (the one that holds the nose tip): where a beard may grow. Inner surfaces of the
        # mouth and nostrils lie inside a beard's region in space but on other islands.
        body_mask = raster_uv_mask(self.base.uvs[tri_t], self.tex_size).astype(np.uint8)
        _, islands = cv2.connectedComponents(body_mask, connectivity=4)
        nose_uv = self.base.uvs[tri_t[(tri_v == LANDMARK_VERTICES["nose_tip"]).any(1)]].reshape(-1, 2).mean(0)
        row = int(np.clip((1.0 - nose_uv[1]) * self.tex_size, 0, self.tex_size - 1))
        col = int(np.clip(nose_uv[0] * self.tex_size, 0, self.tex_size - 1))
        self.head_island = (islands == islands[row, col]).astype(np.float32)
        self.proxies: dict[str, Proxy] = {}
        self.textures: dict[str, tuple[np.ndarray, np.ndarray | None]] = {}
        self.skins = sorted((root / "skins" / "textures").glob("*_diffuse*.png"))

    def target(self, key) -> tuple[np.ndarray, np.ndarray]:
        with self.lock:
            if key not in self.targets:
                path = self.expr_files[key] if isinstance(key, tuple) else self.target_files[key]
                self.targets[key] = read_target(path)
            return self.targets[key]

    def proxy(self, rel: str) -> Proxy:
        with self.lock:
            if rel not in self.proxies:
                self.proxies[rel] = read_mhclo(self.root / rel)
            return self.proxies[rel]

    def texture(self, path: Path) -> tuple[np.ndarray, np.ndarray | None]:
        key = str(path)
        with self.lock:
            if key not in self.textures:
                self.textures[key] = load_texture(path)
            return self.textures[key]

    def material_texture(self, proxy: Proxy, mhmat: str | None = None) -> Path:
        mat_path = proxy.folder / (mhmat or proxy.material)
        mat = read_mhmat(mat_path)
        return mat_path.parent / mat["diffuseTexture"]


def _orient_outward(v: np.ndarray, f: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Flip a part's winding when most of its area faces ``centre`` (the proxies' files mix conventions)."""
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    s = (fn * (v[f].mean(1) - centre)).sum()
    return f if s >= 0 else f[:, ::-1].copy()


def _close_cap(v: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Close each open boundary loop of a mesh with a fan to its centroid (a closed cornea lens)."""
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    k = np.sort(e, 1)
    u, inv, c = np.unique(k, axis=0, return_inverse=True, return_counts=True)
    border = e[c[inv.reshape(-1)] == 1]  # directed border edges, in the faces' orientation
    if not len(border):
        return v, f
    import scipy.sparse as sp  # lazy: SciPy is an optional dependency (the dev extra)
    import scipy.sparse.csgraph as cg  # lazy: as scipy.sparse

    n, lab = cg.connected_components(
        sp.coo_matrix((np.ones(len(border)), (border[:, 0], border[:, 1])), shape=(len(v), len(v))), directed=False
    )
    new_v, new_f = [v], [f]
    nxt = len(v)
    for comp in np.unique(lab[border[:, 0]]):
        be = border[lab[border[:, 0]] == comp]
        cen = v[np.unique(be)].mean(0)
        new_v.append(cen[None])
        new_f.append(np.stack([be[:, 1], be[:, 0], np.full(len(be), nxt)], 1))  # reversed: closes the hole
        nxt += 1
    return np.concatenate(new_v), np.concatenate(new_f)


class MakeHumanSource:
    """Photoreal subjects from the MakeHuman assets, a :class:`~kornia_ilum_lab.synth.lightstage.subjects.SubjectSource`.

    Build it with :meth:`from_assets`; the assets are parsed on the first :meth:`sample` and cached.

    Args:
        root: the MakeHuman data root (the folder with ``3dobjs/base.obj``).
        clothes: dress every subject in one of the CC0 outfits (module docstring, step 7).
        cut_below_chin: the bust's cut, metres below the chin (0.21; at most 1.0, for framings that show the
            body down to the hips).

    Its :attr:`name` (:attr:`Subject.source` and the caches' ``source`` setting) is ``"makehuman"`` with the
    defaults, and says what differs otherwise (``"makehuman+clothes"``, ``"makehuman+clothes+cut0.60"``), so that
    a cache never mixes subjects built two ways.

    Raises:
        MakeHumanAssetsNotFoundError: ``root`` has no ``3dobjs/base.obj``.
        ValueCheckError: ``cut_below_chin`` outside ``[0.1, 1.0]``.

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as d:  # a folder that looks like a data root: nothing is parsed yet
        ...     (Path(d) / "3dobjs").mkdir()
        ...     (Path(d) / "3dobjs" / "base.obj").touch()
        ...     source = MakeHumanSource(d)
        ...     source.name, source.root == Path(d)
        ('makehuman', True)
        >>> subject = MakeHumanSource.from_assets().sample(1)  # with the CC0 assets  # doctest: +SKIP
    """

    def __init__(self, root: str | Path, *, clothes: bool = False, cut_below_chin: float = _CUT_BELOW_CHIN) -> None:
        if not 0.1 <= cut_below_chin <= _DEEPEST_CUT:
            raise ValueCheckError(f"cut_below_chin must be in [0.1, {_DEEPEST_CUT}] m, got {cut_below_chin!r}")
        self.root = find_makehuman_root(root)
        self.clothes = bool(clothes)
        self.cut_below_chin = float(cut_below_chin)
        self.name = "makehuman" + ("+clothes" if self.clothes else "") + (
            f"+cut{self.cut_below_chin:.2f}" if self.cut_below_chin != _CUT_BELOW_CHIN else "")
        self._assets: _Assets | None = None
        self._lock = threading.Lock()

    @classmethod
    def from_assets(cls, root: str | Path | None = None) -> MakeHumanSource:
        """The source of the assets at ``root``, else ``$KORNIA_ILUM_MAKEHUMAN``, else
        ``$KORNIA_ILUM_SHARED_DATA/makehuman``.

        Raises:
            MakeHumanAssetsNotFoundError: none of them holds the assets (a ``FileNotFoundError``).
        """
        return cls(find_makehuman_root(root))

    @property
    def assets(self) -> _Assets:
        """The parsed assets (parsed on first use)."""
        with self._lock:
            if self._assets is None:
                self._assets = _Assets(self.root, self.cut_below_chin)
            return self._assets

    def __getstate__(self) -> dict:
        """Pickle only the root and the options: a worker process parses the assets itself (and a lock does not
        pickle)."""
        return {"root": self.root, "clothes": self.clothes, "cut_below_chin": self.cut_below_chin}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["root"], clothes=state.get("clothes", False),
                      cut_below_chin=state.get("cut_below_chin", _CUT_BELOW_CHIN))

    def __repr__(self) -> str:
        options = (", clothes=True" if self.clothes else "") + (
            f", cut_below_chin={self.cut_below_chin}" if self.cut_below_chin != _CUT_BELOW_CHIN else "")
        return f"MakeHumanSource({str(self.root)!r}{options})"

    # ----------------------------------------------------------------------------------------------------
    def params(self, seed: int) -> dict:
        """The random choices of ``seed`` (JSON-serialisable): shape, expression and appearance."""
        a = self.assets
        rng = np.random.default_rng(seed_digest(seed, "makehuman"))
        ethnic = rng.dirichlet((0.8, 0.8, 0.8))
        male = bool(rng.random() < 0.5)
        gender = float(np.clip(1.0 - abs(rng.normal(0, 0.12)), 0.5, 1.0)) if male else float(
            np.clip(abs(rng.normal(0, 0.12)), 0.0, 0.5)
        )
        years = float(rng.uniform(18.0, 85.0))
        muscle = float(np.clip(rng.normal(0.5, 0.15), 0.1, 0.9))
        weight = float(np.clip(rng.normal(0.5, 0.17), 0.1, 0.95))
        # Face-detail sliders: a random subset, the left/right twins mirrored (with a little asymmetry).
        n_sl = int(rng.integers(6, 20))
        chosen = rng.choice(len(a.sliders), size=min(n_sl, len(a.sliders)), replace=False)
        sliders: dict[str, float] = {}
        for i in sorted(chosen.tolist()):
            t, lo, hi = a.sliders[i]
            val = float(np.clip(rng.normal(0, 0.3), -0.8, 0.8)) if lo else float(min(abs(rng.normal(0, 0.3)), 0.8))
            sliders[t] = round(val, 4)
            twin = re.sub(r"^(l|r)-", lambda m: "r-" if m.group(1) == "l" else "l-", t)
            if twin != t and any(s[0] == twin for s in a.sliders):
                sliders[twin] = round(float(np.clip(val + rng.normal(0, 0.05), -0.85, 0.85)), 4)
        expression: dict[str, float] = {}
        if rng.random() < 0.55:
            k = int(rng.integers(1, 3))
            for j in rng.choice(len(_EXPRESSIONS), size=k, replace=False).tolist():
                nm, _, mx = _EXPRESSIONS[j]
                expression[nm] = round(float(rng.uniform(0.15, 1.0) * mx), 4)
        tone = int(rng.integers(1, 11))
        bright = float(np.exp(np.clip(rng.normal(0, 0.08), -0.12, 0.12)))  # within the tone's measured range
        chan = np.exp(rng.normal(0, 0.03, 3))
        target = np.clip(np.asarray(SKIN_ALBEDO[tone - 1]) * bright * chan, 0.005, 0.95)
        p_bald = 0.05 + (0.35 if male and years > 40 else 0.08 if male else 0.0)
        if rng.random() < p_bald:
            hair = "bald"
        else:
            # short03 and bob02 sweep a fringe over one eye: kept, but rarer (a quarter of women, 1 in 14 men)
            w = np.array([3.0, 3.0, 0.5, 3.0, 0.3, 1.0]) if male else np.array([1.5, 1.0, 1.0, 1.0, 1.0, 1.5])
            hair = str(_HAIR_STYLES[int(rng.choice(6, p=w / w.sum()))])
        dark_skin = tone >= 7
        hc = {"black": 3.0 if dark_skin else 1.0, "dark_brown": 2.5, "brown": 2.5, "light_brown": 1.2,
              "blonde": 0.2 if dark_skin else 1.2, "red": 0.1 if dark_skin else 0.4,
              "grey": 0.0, "white": 0.0}  # fmt: skip
        if years > 45:
            hc["grey"] = 0.06 * (years - 45)
            hc["white"] = 0.03 * max(0.0, years - 60)
        names = list(hc)
        pw = np.array([hc[n] for n in names])
        hair_colour = str(names[int(rng.choice(len(names), p=pw / pw.sum()))])
        params = {
            "ethnic": {e: round(float(x), 5) for e, x in zip(ETHNICITIES, ethnic)},
            "gender": round(gender, 4),
            "age_years": round(years, 2),
            "age": round(years_to_age(years), 5),
            "muscle": round(muscle, 4),
            "weight": round(weight, 4),
            "sliders": sliders,
            "expression": expression,
            "skin_tone": tone,
            "skin_target": [round(float(c), 5) for c in target],
            "skin_roughness": round(float(rng.uniform(0.3, 0.5)), 4),
            "skin_f0": round(float(rng.uniform(0.025, 0.035)), 5),
            "tzone_oil": round(float(rng.uniform(0.7, 0.9)), 4),
            "skin_texture_pick": round(float(rng.random()), 5),
            "iris": str(rng.choice(_IRIS, p=iris_probabilities(tone))),
            "eyebrows": f"eyebrow{int(rng.integers(1, 13)):03d}",
            "eyelashes": f"eyelashes{int(rng.integers(1, 5)):02d}",
            "hair": hair,
            "hair_colour": hair_colour,
            "hair_jitter": [round(float(x), 4) for x in np.exp(rng.normal(0, 0.08, 3))],
        }
        # Accessories, drawn last so that every choice above stays what it was without them.
        params.update(accessory_params(rng, male=gender, years=years))
        # short03 and bob02 sweep a fringe over an eye: trimmed at the brows for three subjects in four
        params["fringe"] = "swept" if rng.random() < 0.25 else "trimmed"
        if params["hat"] != "none" and hair in ("bob02", "afro01"):
            params["hair"] = "short01"  # what shows of such hair under a beanie
        if self.clothes:
            params["clothes"] = _clothes_params(seed, male=gender >= 0.5)
        return params

    def _skin_texture(self, p: dict) -> Path:
        """The albedo map of the tone family nearer the target, matched in age and sex where possible."""
        a = self.assets
        age = "young" if p["age_years"] < 35 else "middleage" if p["age_years"] < 60 else "old"
        sex = "male" if p["gender"] >= 0.5 else "female"
        best = None
        for fam in ("lightskinned", "darkskinned"):
            cands = [s for s in a.skins if f"_{fam}_" in s.name] or a.skins
            m = np.mean([a.texture(c)[0][a.face_mask].mean(0) for c in cands[:1]], axis=0)
            cost = float(np.abs(np.log(np.asarray(p["skin_target"]) / m)).sum())
            if best is None or cost < best[0]:
                best = (cost, fam)
        fam = best[1]
        pool = [s for s in a.skins if f"_{fam}_" in s.name]
        exact = [s for s in pool if s.name.startswith(f"{age}_") and f"_{sex}_" in s.name]
        pool = exact or [s for s in pool if f"_{sex}_" in s.name] or pool
        return pool[int(p["skin_texture_pick"] * len(pool)) % len(pool)]

    def _morph(self, p: dict) -> np.ndarray:
        a = self.assets
        v = a.base.vertices.copy()

        def add(key, w: float) -> None:
            if abs(w) > 1e-6:
                idx, d = a.target(key)
                v[idx] += w * d

        eth = (p["ethnic"]["african"], p["ethnic"]["asian"], p["ethnic"]["caucasian"])
        for name, w in macro_target_weights(
            eth, gender=p["gender"], age=p["age"], muscle=p["muscle"], weight=p["weight"]
        ).items():
            add(name, w)
        lookup = {s[0]: s for s in a.sliders}
        for t, val in p["sliders"].items():
            _, lo, hi = lookup[t]
            if lo is None:
                add(t, val)
            else:
                add(f"{t}-{hi}" if val > 0 else f"{t}-{lo}", abs(val))
        exprs = {e[0]: e[1] for e in _EXPRESSIONS}
        for nm, w in p["expression"].items():
            for unit, sc in exprs[nm]:
                for e in ETHNICITIES:
                    add((e, unit), w * sc * p["ethnic"][e])
        return v

    def sample(self, seed: int) -> Subject:
        """The subject of ``seed`` (deterministic).

        Args:
            seed: any int.

        Returns:
            The :class:`~kornia_ilum_lab.synth.lightstage.subjects.Subject` (``source="makehuman"``), metres,
            the frame of docs/conventions.rst, facing +Z, eye centres at ``y = 0``.
        """
        a = self.assets
        p = self.params(seed)
        v = self._morph(p)
        # Frame: decimetres -> metres, the eyes' centres to (0, 0, _EYE_Z).
        eye_c = 0.5 * (v[a.eye_groups[0]].mean(0) + v[a.eye_groups[1]].mean(0))
        shift = np.array([0.0, 0.0, _EYE_Z]) - 0.1 * eye_c

        def to_m(x: np.ndarray) -> np.ndarray:
            return (0.1 * x + shift).astype(np.float32)

        vm = 0.1 * v + shift
        # Skin: split at UV seams, smooth normals of the unsplit mesh, clip at the cut plane.
        normals = vertex_normals(v, a.body_tri)
        faces = a.split_faces
        deleted = np.zeros(a.nv, bool)
        y_cut = float(vm[LANDMARK_VERTICES["chin"], 1] - self.cut_below_chin)
        sv = vm[a.split_base]
        sn = normals[a.split_base]
        # Nudge the plane off any vertex exactly on it (no zero-length clipped edges).
        while np.any(sv[:, 1] == y_cut):
            y_cut = float(np.nextafter(y_cut, np.inf))
        parts: list[MeshPart] = []

        # Proxies.
        def proxy_mesh(rel: str, centre: np.ndarray):
            px = a.proxy(rel)
            deleted[px.delete_verts] = True
            pv = 0.1 * bind_proxy(px, v) + shift
            b, t, f = _split_uv(px.mesh.tri_v, px.mesh.tri_t)
            pv, uv = pv[b], px.mesh.uvs[t]
            f = _orient_outward(pv, f, centre)
            return px, pv, f, uv

        head_c = np.array([0.0, 0.01, 0.0])
        eyes_px = a.proxy("eyes/high-poly/high-poly.mhclo")
        eye_all = 0.1 * bind_proxy(eyes_px, v) + shift
        mesh = eyes_px.mesh
        eb, et, ef = _split_uv(mesh.tri_v, mesh.tri_t)
        # The eye file holds, per eye, the eyeball and its outer (cornea) shell; the shell's faces map to the
        # texture's transparent corner.
        tex_rgb, tex_a = a.texture(eyes_px.folder / "../materials" / f"{p['iris']}_eye.png")
        if p["iris"] == "brown":
            t = (p["skin_tone"] - 1) / 9
            tex_rgb = retint_iris(tex_rgb, tuple((1 - t) * m + t * d for m, d in zip(*_BROWN_IRIS)))
        shell_v = self._eye_shell(eyes_px, tex_a)
        shell = shell_v[eb][ef].all(1)
        ev, euv = eye_all[eb], mesh.uvs[et]
        eye_centres = [vm[g].mean(0) for g in a.eye_groups]
        ball_f = ef[~shell]
        cornea_v, cornea_f = [], []
        for side, cen in enumerate(eye_centres):
            # The cornea has no texture: close it on the unsplit (welded) vertices.
            fs = mesh.tri_v[shell_v[mesh.tri_v].all(1) & ((eye_all[mesh.tri_v][:, :, 0].mean(1) > 0) == (side == 1))]
            used, rm = np.unique(fs, return_inverse=True)
            cv_, cf_ = _close_cap(eye_all[used], rm.reshape(-1, 3))
            cf_ = _orient_outward(cv_, cf_, cen)
            cornea_f.append(cf_ + sum(len(x) for x in cornea_v))
            cornea_v.append(cv_)
        # The eyeballs: winding outward from each eye's centre.
        fl = ev[ball_f].mean(1)[:, 0] > 0
        bf = np.concatenate([_orient_outward(ev, ball_f[~fl], eye_centres[0]), _orient_outward(ev, ball_f[fl], eye_centres[1])])
        used, rm = np.unique(bf, return_inverse=True)
        bv, bfc, buv = ev[used], rm.reshape(-1, 3), euv[used]
        iris_mean = tuple(float(x) for x in tex_rgb.reshape(-1, 3).mean(0))
        # Diffuse: the eye's only gloss is the tear film's and cornea's, the closed shell over the whole eyeball
        parts.append(MeshPart("eyes", bv.astype(np.float32), bfc.astype(np.int32),
                              Material("diffuse", iris_mean, albedo_texture=tex_rgb),
                              vertex_normals(bv, bfc).astype(np.float32), buv.astype(np.float32)))  # fmt: skip
        cv_all, cf_all = np.concatenate(cornea_v), np.concatenate(cornea_f)
        parts.append(MeshPart("cornea", cv_all.astype(np.float32), cf_all.astype(np.int32),
                              Material("cornea", (1.0, 1.0, 1.0), 0.0, 0.313),
                              vertex_normals(cv_all, cf_all).astype(np.float32)))  # fmt: skip

        hair_rgb = np.asarray(_HAIR_COLOURS[p["hair_colour"]]) * np.asarray(p["hair_jitter"])
        brow_rgb = hair_rgb if p["hair_colour"] in ("grey", "white") else hair_rgb * min(0.85, 0.05 / hair_rgb.max())
        cards = [
            ("brows", f"eyebrows/{p['eyebrows']}/{p['eyebrows']}.mhclo", brow_rgb, 0.35),
            ("lashes", f"eyelashes/{p['eyelashes']}/{p['eyelashes']}.mhclo", (0.01, 0.008, 0.007), 0.35),
        ]
        if p["hair"] != "bald":
            cards.append(("hair", f"hair/{p['hair']}/{p['hair']}.mhclo", hair_rgb, 0.3))
        for name, rel, colour, rough in cards:
            px, pv, f, uv = proxy_mesh(rel, head_c)
            rgb, alpha = a.texture(a.material_texture(px))
            op = self._opacity(rel, alpha)
            keep = self._opaque_faces(rel, uv, f, op)
            if name == "hair" and p["fringe"] == "trimmed":
                brow_y = vm[[LANDMARK_VERTICES["brow_right_top"], LANDMARK_VERTICES["brow_left_top"]], 1].mean()
                keep &= ~_over_the_eyes(pv[f].mean(1), float(brow_y))
            used, f = np.unique(f[keep], return_inverse=True)
            pv, uv, f = pv[used], uv[used], f.reshape(-1, 3)
            albedo = retint_hair(rgb, op > 0.5, tuple(float(c) for c in colour))
            parts.append(MeshPart(name, pv.astype(np.float32), f.astype(np.int32),
                                  Material("hair", tuple(float(c) for c in colour), rough, 0.5, albedo_texture=albedo,
                                           opacity_texture=op),
                                  vertex_normals(pv, f).astype(np.float32), np.clip(uv, 0, 1).astype(np.float32)))  # fmt: skip
        mouth_c = vm[[LANDMARK_VERTICES["upper_lip"], LANDMARK_VERTICES["lower_lip"]]].mean(0) - (0, 0, 0.03)
        for name, rel, kind, rough in (("teeth", "teeth/teeth_base/teeth_base.mhclo", "glossy", 0.25),
                                       ("tongue", "tongue/tongue01/tongue01.mhclo", "skin", 0.4)):  # fmt: skip
            px, pv, f, uv = proxy_mesh(rel, mouth_c)
            rgb, _ = a.texture(a.material_texture(px))
            if name == "teeth":
                rgb = retint_teeth(rgb)
            parts.append(MeshPart(name, pv.astype(np.float32), f.astype(np.int32),
                                  Material(kind, tuple(float(c) for c in rgb.reshape(-1, 3).mean(0)), rough, 0.5,
                                           albedo_texture=rgb, subsurface=kind == "skin"),
                                  vertex_normals(pv, f).astype(np.float32), np.clip(uv, 0, 1).astype(np.float32)))  # fmt: skip

        if "clothes" in p:
            parts.append(self._clothes(p["clothes"], v, shift, y_cut, deleted))
        # Skin, after the proxies and clothes (their delete_verts hide base vertices).
        if deleted.any():
            faces = faces[~deleted[a.split_base[faces]].any(1)]
        cv_, cf_, (cuv, cn) = clip_mesh_below(sv, faces, y_cut, [a.split_uv, sn])
        cn /= np.maximum(np.linalg.norm(cn, axis=1, keepdims=True), 1e-12)
        skin_path = self._skin_texture(p)
        base_tex, _ = a.texture(skin_path)
        tex, face_albedo = retint_skin(base_tex, a.face_mask, tuple(p["skin_target"]))
        rough_tex = (1.0 - (1.0 - p["tzone_oil"]) * a.tzone).astype(np.float32)
        skin_mat = Material("skin", face_albedo, p["skin_roughness"], p["skin_f0"] / 0.08, albedo_texture=tex,
                            roughness_texture=rough_tex, subsurface=True)  # fmt: skip
        parts.insert(0, MeshPart("skin", cv_.astype(np.float32), cf_.astype(np.int32), skin_mat,
                                 cn.astype(np.float32), np.clip(cuv, 0, 1).astype(np.float32)))  # fmt: skip
        landmarks = to_m(v[[LANDMARK_VERTICES[n] for n in LANDMARK_NAMES]])
        parts = self._accessories(p, parts, lm=dict(zip(LANDMARK_NAMES, landmarks.astype(np.float64))),
                                  eye_centres=eye_centres, hair_rgb=hair_rgb, seed=seed)  # fmt: skip
        params = dict(p)
        params.update(skin_texture=skin_path.name, cut_y=round(y_cut, 5),
                      macro_targets={k: round(w, 5) for k, w in macro_target_weights(
                          tuple(p["ethnic"].values()), gender=p["gender"], age=p["age"], muscle=p["muscle"],
                          weight=p["weight"]).items()})  # fmt: skip
        return Subject(
            seed=seed,
            split=subject_split(seed),
            parts=parts,
            skin_tone=p["skin_tone"],
            face_landmarks=landmarks,
            params=params,
            source=self.name,
            face_albedo=face_albedo,
        )

    def _clothes(self, c: dict, v: np.ndarray, shift: np.ndarray, y_cut: float, deleted: np.ndarray) -> MeshPart:
        """The outfit of ``c`` (:func:`_clothes_params`) bound to the morphed mesh ``v`` (decimetres), cut at
        ``y_cut``; marks the skin it covers in ``deleted``."""
        px = self.assets.proxy(f"clothes/{c['outfit']}/{c['outfit']}.mhclo")
        deleted[px.delete_verts] = True
        cv = 0.1 * bind_proxy(px, v) + shift
        chest = np.array([0.0, y_cut, -0.03])  # inside the torso: the winding faces away from it
        cf = _orient_outward(cv, px.mesh.tri_v, chest)
        cv, cf, (cn,) = clip_mesh_below(cv, cf, y_cut, [vertex_normals(cv, cf)])
        cn /= np.maximum(np.linalg.norm(cn, axis=1, keepdims=True), 1e-12)
        return MeshPart("clothes", cv.astype(np.float32), cf.astype(np.int32),
                        Material("diffuse", tuple(c["albedo"])), cn.astype(np.float32))

    def _accessories(self, p: dict, parts: list[MeshPart], *, lm: dict[str, np.ndarray], eye_centres: list,
                     hair_rgb: np.ndarray, seed: int) -> list[MeshPart]:  # fmt: skip
        """``parts`` with the subject's beard, beanie and glasses (:mod:`.makehuman_accessories`) added."""
        by_name = {q.name: q for q in parts}
        skin = by_name["skin"]
        if p["facial_hair"] != "none":
            beard_rgb = hair_rgb if p["hair_colour"] in ("grey", "white") else hair_rgb * 0.8
            if p["age_years"] > 45 and p["hair_colour"] not in ("grey", "white"):  # greying earlier than the hair
                mix = min(1.0, 0.02 * (p["age_years"] - 45))
                beard_rgb = (1 - mix) * beard_rgb + mix * np.asarray(_HAIR_COLOURS["grey"])
            wv = beard_weight(p["facial_hair"], skin.vertices.astype(np.float64), lm)
            tex = skin.material.albedo_texture
            wuv = uv_weight_map(skin.uvs, skin.faces, wv, tex.shape[0]) * self.assets.head_island
            shade = (p["stubble_shadow"] * wuv)[..., None]
            tex = ((1.0 - shade) * tex + shade * np.minimum(tex, beard_rgb.astype(np.float32))).astype(np.float32)
            skin = dataclasses.replace(skin, material=dataclasses.replace(skin.material, albedo_texture=tex))
            parts = [skin if q.name == "skin" else q for q in parts]
            rng = np.random.default_rng(seed_digest(seed, "makehuman-beard"))
            parts += beard_parts(p, skin, weight=wv, island=self.assets.head_island, colour=beard_rgb,
                                 rng=rng)
        if p["hat"] != "none":
            ears = np.concatenate([lm["ear_right"][None], lm["ear_left"][None]])
            head = skin.vertices[np.linalg.norm(skin.vertices[:, None] - ears[None], axis=-1).min(1) > 0.035]
            hair = by_name.get("hair")
            made = beanie_part(p, lm, head, hair.vertices if hair is not None else np.zeros((0, 3)))
            if made is not None:
                hat, envelope = made
                if hair is not None:
                    hidden = inside_beanie(hair.vertices.astype(np.float64), envelope, p, lm)[hair.faces].all(1)
                    used, f = np.unique(hair.faces[~hidden], return_inverse=True)
                    hair = dataclasses.replace(hair, vertices=hair.vertices[used], faces=f.reshape(-1, 3).astype(np.int32),
                                               normals=hair.normals[used], uvs=hair.uvs[used])  # fmt: skip
                    parts = [hair if q.name == "hair" else q for q in parts]
                parts.append(hat)
        cards = [q.vertices for q in parts if q.name in ("brows", "lashes")]
        parts += glasses_parts(p, eye_centres, [lm["ear_right"], lm["ear_left"]],
                               np.concatenate([skin.vertices, *cards]).astype(np.float64))  # fmt: skip
        return parts

    def _eye_shell(self, px: Proxy, alpha: np.ndarray) -> np.ndarray:
        """Per proxy vertex: whether it is on an eye's outer shell (a connected piece mapped to clear texels)."""
        import scipy.sparse as sp  # lazy: SciPy is an optional dependency (the dev extra)
        import scipy.sparse.csgraph as cg  # lazy: as scipy.sparse

        m = px.mesh
        e = np.concatenate([m.tri_v[:, [0, 1]], m.tri_v[:, [1, 2]]])
        nv = len(m.vertices)
        _, lab = cg.connected_components(
            sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(nv, nv)), directed=False
        )
        uvf = m.uvs[m.tri_t].mean(1)
        h, w = alpha.shape
        at = alpha[np.clip(((1 - uvf[:, 1]) * h).astype(int), 0, h - 1), np.clip((uvf[:, 0] * w).astype(int), 0, w - 1)]
        comp = lab[m.tri_v[:, 0]]
        clear = np.bincount(comp, weights=at < 0.5, minlength=lab.max() + 1) / np.maximum(
            np.bincount(comp, minlength=lab.max() + 1), 1
        )
        return clear[lab] > 0.5

    def _opaque_faces(self, rel: str, uv: np.ndarray, f: np.ndarray, op: np.ndarray) -> np.ndarray:
        """:func:`opaque_faces` of a card proxy, once per asset (its UVs do not depend on the subject)."""
        a = self.assets
        key = "opaque_faces:" + rel
        with a.lock:
            if key not in a.textures:
                a.textures[key] = (opaque_faces(np.clip(uv, 0, 1)[f], op), None)
            return a.textures[key][0]

    def _opacity(self, rel: str, alpha: np.ndarray | None) -> np.ndarray:
        a = self.assets
        key = "opacity:" + rel
        with a.lock:
            if key not in a.textures:
                a.textures[key] = (clean_alpha(alpha if alpha is not None else np.ones((4, 4), np.float32)), None)
            return a.textures[key][0]
