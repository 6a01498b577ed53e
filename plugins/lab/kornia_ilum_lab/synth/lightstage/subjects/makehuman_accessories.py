r"""Glasses, beards and beanies for the MakeHuman subjects, fitted to each morphed head.

The MakeHuman assets have no accessories, so these are built here, with the styles and frequencies of the
signed-distance mannequins' (:mod:`~kornia_ilum_lab.synth.lightstage.subjects.mannequin`), as meshes fitted to the
subject's own geometry (metres, the frame of docs/conventions.rst, the eyes' centres at ``y = 0``):

- **Glasses** (:func:`glasses_parts`): two rims (tubes along superellipses, from oval to rectangular, wrapped on
  an arch of radius 16 cm; full rims, browline half-rims or rimless), a bridge and two temples that run back
  over the ears. The frame's plane sits
  ``vertex_mm`` in front of the corneas, moved forward until it clears the skin, brows and lashes under the
  rims and the bridge by 3 mm; each temple point is pushed out until it clears the side of the head. The lenses
  are thin clear sheets of the ``"cornea"`` kind (a thin dielectric slab of index 1.5: transmission plus
  Fresnel glints, transparent to shadow rays).
- **Beards** (:func:`beard_weight`, :func:`beard_parts`): a soft region on the base mesh per style (stubble,
  moustache, goatee, full beard), drawn into the skin's UV atlas. Every style darkens the skin under it
  towards the beard's colour (the shadow of stubble); the moustache, goatee and beard add fur shells: copies of
  the skin's region pushed out along its normals by fractions of the beard's thickness, alpha-tested with a
  strand mask whose density falls from the root to the tips.
- **Beanies** (:func:`beanie_part`): a knit sheet over the skull and the hair, its radius in each direction
  the largest of the head's and the hair's (a smoothed upper envelope, plus 4 mm), down to a plane tilted from
  the mid-forehead to the occiput, with a folded cuff. Hair faces inside it are dropped
  (:func:`inside_beanie`).
"""

from __future__ import annotations

import numpy as np

from kornia_ilum_lab.synth.lightstage.subjects.base import (
    FRAME_ALBEDO,
    GLASSES_FRAMES,
    Material,
    MeshPart,
    fabric_colour,
    frame_material,
    merge_meshes,
    pick,
)
from kornia_ilum_lab.synth.lightstage.subjects.makehuman_assets import opaque_faces, raster_uv_mask, vertex_normals

__all__ = [
    "ARCH_RADIUS",
    "accessory_params",
    "beanie_part",
    "beard_parts",
    "beard_weight",
    "glasses_parts",
    "inside_beanie",
    "tube",
    "uv_weight_map",
]

#: The radius (metres) of the arch that frames wrap on, as the mannequins' glasses.
ARCH_RADIUS = 0.16
_BEARD_STYLES = {"stubble": 1.0, "moustache": 0.5, "goatee": 0.6, "beard": 1.0}
_SHELLS = 3


def accessory_params(rng: np.random.Generator, *, male: float, years: float) -> dict:
    """The accessories of one subject (JSON-serialisable), with the mannequins' frequencies.

    Args:
        rng: the subject's generator (drawn from after its other choices, so those do not change).
        male: the masculinity in ``[0, 1]`` (MakeHuman's gender).
        years: the age.

    Returns:
        ``glasses`` (bool) with its frame colour, style (full rim, browline half rim or rimless), rim, lens
        and fit; ``facial_hair`` (``"none"``, ``"stubble"``, ``"moustache"``, ``"goatee"`` or ``"beard"``) with
        ``beard_thickness_mm``, ``beard_density`` and ``stubble_shadow``; ``hat`` (``"none"`` or ``"beanie"``)
        with its colour and the height of its front edge over the brows.

    Examples:
        >>> p = accessory_params(np.random.default_rng(0), male=0.0, years=30.0)
        >>> p["facial_hair"], p["glasses_style"] in ("full", "half", "rimless"), p["hat"] in ("none", "beanie")
        ('none', True, True)
    """
    u = lambda lo, hi: round(float(rng.uniform(lo, hi)), 5)  # noqa: E731
    frame = pick(rng, GLASSES_FRAMES)
    p = {
        "glasses": bool(rng.random() < 0.2 + (0.15 if years > 50 else 0.0)),
        "glasses_frame": frame,
        "glasses_albedo": list(FRAME_ALBEDO.get(frame) or fabric_colour(rng, 1.0)[1]),
        "glasses_rim_mm": u(0.8, 1.1) if frame == "metal" else u(1.2, 2.0),
        "glasses_style": pick(rng, {"full": 3.0, "half": 1.0, "rimless": 1.0}),
        "lens_half_width_mm": u(21.0, 27.0),
        "lens_half_height_mm": u(13.0, 20.0),
        "lens_squareness": u(2.3, 5.0),
        "vertex_mm": u(24.0, 29.0),
    }
    p["facial_hair"] = pick(rng, _BEARD_STYLES) if rng.random() < 0.6 * male**2 else "none"
    p["beard_thickness_mm"] = u(3.0, 10.0)
    p["beard_density"] = u(0.35, 0.8)
    p["stubble_shadow"] = u(0.3, 0.6)
    p["hat"] = "beanie" if rng.random() < 0.1 else "none"
    p["hat_colour"], albedo = fabric_colour(rng, 0.6)
    p["hat_albedo"] = list(albedo)
    p["hat_front_mm"] = u(15.0, 35.0)
    return p


# --------------------------------------------------------------------------------------------------------
# Meshes
# --------------------------------------------------------------------------------------------------------


def tube(path: np.ndarray, radius: float, *, closed: bool, up: tuple[float, float, float], sides: int = 8):
    """A tube of circular section along a polyline (a frame's rim, bridge or temple).

    Args:
        path: ``(N, 3)`` points.
        radius: the section's radius.
        closed: join the last point to the first (a rim); otherwise the two ends are capped.
        up: a direction never parallel to the path: each section's frame is ``(tangent x up, ...)``, so a
            closed planar path (``up`` its plane's normal) has no twist at its seam.
        sides: vertices per section.

    Returns:
        ``(vertices, faces, normals)``: float64 ``(V, 3)``, int ``(F, 3)`` counter-clockwise seen from outside,
        unit outward normals.

    Examples:
        >>> t = np.linspace(0, 2 * np.pi, 24, endpoint=False)
        >>> v, f, n = tube(np.stack([np.cos(t), np.sin(t), 0 * t], 1), 0.1, closed=True, up=(0, 0, 1))
        >>> v.shape, f.shape, bool(np.allclose(np.linalg.norm(n, axis=1), 1.0))
        ((192, 3), (384, 3), True)
    """
    path = np.asarray(path, dtype=np.float64)
    n = len(path)
    nxt = np.roll(path, -1, 0) if closed else np.concatenate([path[1:], 2 * path[-1:] - path[-2:-1]])
    prv = np.roll(path, 1, 0) if closed else np.concatenate([2 * path[:1] - path[1:2], path[:-1]])
    t = nxt - prv
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    a = np.cross(t, np.asarray(up, dtype=np.float64))
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b = np.cross(t, a)
    ang = 2 * np.pi * np.arange(sides) / sides
    nrm = np.cos(ang)[None, :, None] * a[:, None] + np.sin(ang)[None, :, None] * b[:, None]
    v = (path[:, None] + radius * nrm).reshape(-1, 3)
    nrm = nrm.reshape(-1, 3)
    rings = n if closed else n - 1
    i, j = np.meshgrid(np.arange(rings), np.arange(sides), indexing="ij")
    i, j = i.ravel(), j.ravel()
    p00, p01 = i * sides + j, i * sides + (j + 1) % sides
    p10, p11 = ((i + 1) % n) * sides + j, ((i + 1) % n) * sides + (j + 1) % sides
    f = np.concatenate([np.stack([p00, p10, p11], 1), np.stack([p00, p11, p01], 1)])
    if not closed:
        ends = []
        for k, sgn in ((0, -1.0), (n - 1, 1.0)):
            c = len(v) + len(ends)
            ends.append((path[k], sgn * t[k]))
            ring = k * sides + np.arange(sides)
            f = np.concatenate([f, np.stack([ring, np.roll(ring, -1), np.full(sides, c)], 1)])
        v = np.concatenate([v, [e[0] for e in ends]])
        nrm = np.concatenate([nrm, [e[1] for e in ends]])
    return v, _orient(v, f, nrm), nrm


def _orient(v: np.ndarray, f: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Flip each face whose winding disagrees with its vertices' normals."""
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    flip = (fn * n[f].sum(1)).sum(1) < 0
    f = f.copy()
    f[flip] = f[flip][:, ::-1]
    return f


def _disc_faces(m: int, rings: int) -> np.ndarray:
    """Faces of a disc whose vertices are a centre then ``rings`` rings of ``m`` (a lens, a hat's crown down to
    its edge): a fan to the centre and strips between consecutive rings, wound as given (orient them after)."""
    k = np.arange(m)
    nxt = (k + 1) % m
    faces = [np.stack([np.zeros(m, int), 1 + k, 1 + nxt], 1)]
    for q in range(rings - 1):
        o0, o1 = 1 + q * m, 1 + (q + 1) * m
        faces += [np.stack([o0 + k, o1 + k, o1 + nxt], 1), np.stack([o0 + k, o1 + nxt, o0 + nxt], 1)]
    return np.concatenate(faces)


def _superellipse(a: float, b: float, n: float, count: int) -> np.ndarray:
    """``(count, 2)`` points of ``|x/a|^n + |y/b|^n = 1``, counter-clockwise."""
    t = 2 * np.pi * np.arange(count) / count
    c, s = np.cos(t), np.sin(t)
    return np.stack([a * np.sign(c) * np.abs(c) ** (2 / n), b * np.sign(s) * np.abs(s) ** (2 / n)], 1)


def _arch(x: np.ndarray, z0: float) -> np.ndarray:
    return z0 - x * x / (2.0 * ARCH_RADIUS)


def glasses_parts(p: dict, eye_centres: list[np.ndarray], ears: list[np.ndarray], head: np.ndarray) -> list[MeshPart]:
    """The frame (``"glasses"``, :func:`~kornia_ilum_lab.synth.lightstage.subjects.base.frame_material`) and the
    lenses (``"lenses"``, ``"cornea"`` kind) fitted to a head.

    Args:
        p: :func:`accessory_params`.
        eye_centres: the right (``x < 0``) and left eyeball centres.
        ears: the right and left ear landmarks.
        head: ``(N, 3)`` points the frame must clear: skin, brows and lashes.

    Returns:
        The two parts, or ``[]`` when ``p["glasses"]`` is false.

    Examples:
        >>> from kornia_ilum_lab.synth.lightstage.subjects.base import icosphere
        >>> p = dict(accessory_params(np.random.default_rng(0), male=0.0, years=30.0), glasses=True)
        >>> head = 0.1 * icosphere(2)[0]  # a ball for a head
        >>> eyes = [np.array([-0.032, 0.0, 0.07]), np.array([0.032, 0.0, 0.07])]
        >>> ears = [np.array([-0.075, -0.01, -0.01]), np.array([0.075, -0.01, -0.01])]
        >>> p["glasses_frame"], [(part.name, part.material.kind) for part in glasses_parts(p, eyes, ears, head)]
        ('metal', [('glasses', 'metal'), ('lenses', 'cornea')])
    """
    if not p["glasses"]:
        return []
    r = 1e-3 * p["glasses_rim_mm"]
    a, b, sq = 1e-3 * p["lens_half_width_mm"], 1e-3 * p["lens_half_height_mm"], p["lens_squareness"]
    ex = 0.5 * (abs(eye_centres[0][0]) + abs(eye_centres[1][0]))
    a = min(a, ex - 0.007 - r)  # keep a bridge of at least 14 mm
    cx, cy = ex + 0.001, -0.002
    yb = cy + 0.35 * b  # the bridge's height
    xb = a * (1.0 - 0.35**sq) ** (1.0 / sq)  # the rims' inner edge at that height
    # The frame's plane: vertex_mm in front of the eyes, forward until the rims and bridge clear the face.
    warped = head[:, 2] + head[:, 0] ** 2 / (2.0 * ARCH_RADIUS)
    under = ((np.abs(np.abs(head[:, 0]) - cx) < a + 0.004) & (np.abs(head[:, 1] - cy) < b + 0.004)) | (
        (np.abs(head[:, 0]) < cx - xb + 0.002) & (np.abs(head[:, 1] - yb) < 0.006)
    )
    z0 = float(max(eye_centres[0][2], eye_centres[1][2])) + 1e-3 * p["vertex_mm"]
    if under.any():
        z0 = max(z0, float(warped[under].max()) + r + 0.003)
    ring = _superellipse(a, b, sq, 72)
    frame, lenses = [], []  # (vertices, faces[, normals]) pieces
    for sgn, ear in ((-1.0, ears[0]), (1.0, ears[1])):
        x = sgn * cx + ring[:, 0]
        rim = np.stack([x, cy + ring[:, 1], _arch(x, z0)], 1)
        if p["glasses_style"] == "full":
            frame.append(tube(rim, r, closed=True, up=(0.0, 0.0, 1.0)))
        elif p["glasses_style"] == "half":  # a browline frame: the rim's upper part only, the lens hangs below
            upper = ring[:, 1] > -0.1 * b
            first = (int(np.nonzero(~upper)[0].max()) + 1) % len(ring)  # the ring is counter-clockwise from +x
            arc = np.roll(rim, -first, 0)[np.roll(upper, -first)]
            frame.append(tube(arc, r, closed=False, up=(0.0, 0.0, 1.0)))
        # The lens: concentric copies of the rim (inset by the rim's radius) fanned to its centre.
        s = np.linspace(0.25, 1.0, 4)[:, None, None]
        inner = np.stack([sgn * cx + s * ring[None, :, 0] * (1 - r / a), cy + s * ring[None, :, 1] * (1 - r / b)], -1)
        pts = np.concatenate([[[sgn * cx, cy]], inner.reshape(-1, 2)])
        lenses.append((np.stack([pts[:, 0], pts[:, 1], _arch(pts[:, 0], z0)], 1), _disc_faces(len(ring), len(s))))
        # The temple: from the rim's outer edge back over the ear, then down behind it, clear of the head.
        hinge = np.array([sgn * (cx + xb), yb, _arch(sgn * (cx + xb), z0)])
        # (over the ear's root, medial to the ear, then down behind it; the ear itself does not push it out)
        root = (0.9 * ear[0], ear[1] + 0.022, ear[2] + 0.004)
        knots = np.array([hinge, hinge + (sgn * 0.004, 0.0, -0.008), root, (0.88 * ear[0], ear[1], ear[2] - 0.02)])
        path = np.concatenate([np.linspace(knots[i], knots[i + 1], 12, endpoint=False) for i in range(3)] + [knots[3:]])
        side = head[(np.sign(head[:, 0]) == sgn) & (np.linalg.norm(head - ear, axis=1) > 0.03)]
        for i in range(2, len(path)):
            near = (np.abs(side[:, 1] - path[i, 1]) < 0.008) & (np.abs(side[:, 2] - path[i, 2]) < 0.008)
            if near.any():
                path[i, 0] = sgn * max(abs(path[i, 0]), float(np.abs(side[near, 0]).max()) + r + 0.0015)
        frame.append(tube(path, r, closed=False, up=(0.0, 1.0, 0.0)))
    bx = np.linspace(-(cx - xb) - 0.5 * r, cx - xb + 0.5 * r, 12)
    bridge = np.stack([bx, yb + 0.003 * (1.0 - (bx / bx[-1]) ** 2), _arch(bx, z0) + 0.0005], 1)
    frame.append(tube(bridge, r, closed=False, up=(0.0, 0.0, 1.0)))
    fv, ff, fnrm = merge_meshes(frame)
    lv, lf, _ = merge_meshes(lenses)
    ln = np.tile(np.float32([0.0, 0.0, 1.0]), (len(lv), 1))
    return [
        MeshPart("glasses", fv, ff, frame_material(p["glasses_frame"], p["glasses_albedo"], 0.12), fnrm),
        MeshPart("lenses", lv, _orient(lv, lf, ln).astype(np.int32), Material("cornea", (1.0, 1.0, 1.0), 0.0, 0.5), ln),
    ]


# --------------------------------------------------------------------------------------------------------
# Beards
# --------------------------------------------------------------------------------------------------------


def beard_weight(style: str, v: np.ndarray, lm: dict[str, np.ndarray]) -> np.ndarray:
    """Per vertex, how much of ``style``'s beard grows there (``[0, 1]``, with a soft 8 mm edge).

    Args:
        style: ``"stubble"`` and ``"beard"`` (the full region), ``"moustache"`` or ``"goatee"``.
        v: ``(N, 3)`` points in any frame where ``lm`` holds (metres, +Y up, the face along +Z).
        lm: the landmarks by name (:data:`~kornia_ilum_lab.synth.lightstage.subjects.LANDMARK_NAMES`).

    Returns:
        ``(N,)`` float64.

    Examples:
        >>> lm = {"mouth_right": (-0.025, -0.06, 0.09), "mouth_left": (0.025, -0.06, 0.09), "chin": (0.0, -0.11, 0.08),
        ...       "upper_lip": (0.0, -0.05, 0.1), "lower_lip": (0.0, -0.07, 0.1), "subnasale": (0.0, -0.04, 0.1),
        ...       "ear_right": (-0.075, -0.01, -0.01), "ear_left": (0.075, -0.01, -0.01),
        ...       "brow_right_top": (-0.03, 0.03, 0.09), "brow_left_top": (0.03, 0.03, 0.09)}
        >>> lm = {k: np.array(v) for k, v in lm.items()}  # a face's landmarks, metres, the eyes at y = 0
        >>> pts = np.array([[0.0, -0.045, 0.1], [0.0, 0.05, 0.1], [0.0, -0.09, 0.09]])  # upper lip, brow, chin
        >>> beard_weight("moustache", pts, lm).tolist(), beard_weight("goatee", pts, lm).tolist()
        ([1.0, 0.0, 0.0], [1.0, 0.0, 1.0])
    """
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    ax = np.abs(x)
    mouth_x = 0.5 * (abs(lm["mouth_right"][0]) + abs(lm["mouth_left"][0]))
    mouth_y = 0.5 * (lm["mouth_right"][1] + lm["mouth_left"][1])
    ear_x = 0.5 * (abs(lm["ear_right"][0]) + abs(lm["ear_left"][0]))
    ear_y, ear_z = 0.5 * (lm["ear_right"][1] + lm["ear_left"][1]), 0.5 * (lm["ear_right"][2] + lm["ear_left"][2])
    chin_y, lip_y, nose_y = lm["chin"][1], lm["upper_lip"][1], lm["subnasale"][1]
    low_y = lm["lower_lip"][1]
    ramp, fine = 0.008, 0.003
    # The lips and the mouth stay bare: an ellipse around them.
    lips = ((x / (1.1 * mouth_x)) ** 2 + ((y - 0.5 * (lip_y + low_y)) / (0.5 * (lip_y - low_y) + 0.002)) ** 2) - 1.0
    bare = np.clip(lips / 0.25, 0.0, 1.0)
    front = np.clip((z - (ear_z + 0.012)) / ramp, 0.0, 1.0)
    moustache = np.minimum(np.clip((1.2 * mouth_x - ax) / fine, 0, 1), np.clip((nose_y - 0.001 - y) / fine, 0, 1))
    moustache = np.minimum(moustache, np.clip((y - (mouth_y - 0.008)) / fine, 0, 1))
    if style == "moustache":
        return moustache * bare * front
    chin = np.minimum(np.clip((0.95 * mouth_x - ax) / ramp, 0, 1), np.clip((low_y - y) / ramp, 0, 1))
    chin = np.minimum(chin, np.clip((y - (chin_y - 0.012)) / ramp, 0, 1))
    if style == "goatee":
        return np.maximum(moustache, chin) * bare * front
    # Full beard: under a cheek line from the sideburn (in front of the ear, at its top) down to the mouth's
    # corner, over the jaw and under the chin down to the neck.
    t = np.clip((ax - mouth_x) / max(ear_x - mouth_x, 1e-3), 0.0, 1.0)
    cheek_line = (mouth_y + 0.01) + t * (ear_y + 0.025 - mouth_y - 0.01)
    neck_line = (chin_y - 0.035) + np.clip((lm["chin"][2] - z) / 0.09, 0.0, 1.0) * 0.02
    full = np.minimum(np.clip((cheek_line - y) / ramp, 0, 1), np.clip((y - neck_line) / ramp, 0, 1))
    full = np.minimum(full, np.clip((ear_x + 0.002 - ax) / ramp, 0, 1))
    full = np.maximum(full, moustache)
    return full * bare * front


def uv_weight_map(uv: np.ndarray, faces: np.ndarray, weight: np.ndarray, size: int) -> np.ndarray:
    """``(size, size)`` float32: a per-vertex ``weight`` drawn into the UV atlas (rows: ``v`` down).

    Each face is filled with its vertices' mean weight (in 16 levels), then blurred by a texel and a half,
    so that the weight has no steps at the faces' edges.

    Args:
        uv: ``(V, 2)`` texture coordinates of the vertices (``v`` up).
        faces: ``(F, 3)`` vertex indices of the triangles.
        weight: ``(V,)`` per-vertex weights in ``[0, 1]``.
        size: the map's side in texels.

    Returns:
        the map ``(size, size)``, float32 in ``[0, 1]``, row 0 at ``v = 1``.

    Examples:
        >>> uv = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])  # the lower-left half of the atlas
        >>> m = uv_weight_map(uv, np.array([[0, 1, 2]]), np.ones(3), 16)
        >>> m.shape, round(float(m[12, 2]), 2), round(float(m[0, 15]), 2)  # inside, and the far corner
        ((16, 16), 1.0, 0.0)
    """
    import cv2  # lazy: OpenCV is slow to import, and few steps need it

    img = np.zeros((size, size), np.float32)
    level = np.round(weight[faces].mean(1) * 16).astype(int)
    for q in range(1, 17):  # later levels drawn over earlier ones, as overlapping fills
        sel = level == q
        if sel.any():
            img[raster_uv_mask(uv[faces[sel]], size)] = q / 16.0
    return np.clip(cv2.GaussianBlur(img, (0, 0), 1.5), 0.0, 1.0)


def _strand_mask(size: int, direction: np.ndarray, length: int, rng: np.random.Generator) -> np.ndarray:
    """``(size, size)`` float32 in ``[0, 1]``: noise smeared along ``direction`` (``(col, row)`` in the texture)
    over ``length`` texels (strands), equalised so that ``mask < d`` covers a fraction ``d``."""
    import cv2  # lazy: OpenCV is slow to import, and few steps need it

    noise = rng.random((size, size)).astype(np.float32)
    k = length
    kernel = np.zeros((k, k), np.float32)
    d = direction / max(float(np.linalg.norm(direction)), 1e-12)
    for t in np.linspace(-(k // 2), k // 2, 4 * k):
        c, r = np.round(k // 2 + t * d).astype(int)
        if 0 <= c < k and 0 <= r < k:
            kernel[r, c] = 1.0
    noise = cv2.filter2D(noise, -1, kernel / kernel.sum(), borderType=cv2.BORDER_REFLECT)
    order = np.argsort(noise.ravel())
    ranks = np.empty_like(order)
    ranks[order] = np.arange(order.size)  # the inverse permutation: one sort, not two
    return (ranks / (ranks.size - 1)).reshape(size, size).astype(np.float32)


def beard_parts(
    p: dict, skin: MeshPart, *, weight: np.ndarray, island: np.ndarray, colour: np.ndarray,
    rng: np.random.Generator, size: int = 1024,
) -> list[MeshPart]:  # fmt: skip
    """The fur shells of a beard style over ``skin``: three for a moustache, goatee or beard, one short sparse
    layer for stubble, none without facial hair.

    Args:
        p: :func:`accessory_params`.
        skin: the subject's skin part (vertices, faces, normals and UVs).
        weight: ``(V,)`` the style's :func:`beard_weight` at the skin's vertices.
        island: ``(H, W)`` 0/1 mask of the UV island the beard may cover (upsampled to ``size``).
        colour: the beard's linear RGB.
        rng: for the strand mask.
        size: the opacity maps' side (1024: texels of about 0.6 mm on the face).

    Returns:
        Parts ``"beard0"``..., alpha-tested ``"hair"`` material, outermost last.

    Examples:
        >>> from kornia_ilum_lab.synth.lightstage.subjects.base import icosphere
        >>> v, f = icosphere(1)
        >>> uv = (0.5 + 0.5 * v[:, :2]).astype(np.float32)  # any atlas will do here
        >>> skin = MeshPart("skin", 0.1 * v, f, Material("skin", (0.5, 0.4, 0.3)), v, uv)
        >>> p = dict(accessory_params(np.random.default_rng(0), male=1.0, years=30.0), facial_hair="beard")
        >>> parts = beard_parts(p, skin, weight=np.ones(len(v)), island=np.ones((4, 4), np.float32),
        ...                     colour=np.array([0.02, 0.015, 0.01]), rng=np.random.default_rng(0), size=64)
        >>> [part.name for part in parts], parts[0].material.kind, parts[0].material.opacity_texture.shape
        (['beard0', 'beard1', 'beard2'], 'hair', (64, 64))
    """
    if p["facial_hair"] == "none":
        return []
    import cv2  # lazy: OpenCV is slow to import, and few steps need it

    keep = weight[skin.faces].max(1) > 0.02
    used, f = np.unique(skin.faces[keep], return_inverse=True)
    f = f.reshape(-1, 3)
    v0, n0, uv0, w0 = skin.vertices[used].astype(np.float64), skin.normals[used], skin.uvs[used], weight[used]
    wuv = uv_weight_map(uv0, f, w0, size) * cv2.resize(island, (size, size), interpolation=cv2.INTER_NEAREST)
    # Strands hang down: the texture direction of -Y over the region (a least-squares fit of uv to position).
    fit, *_ = np.linalg.lstsq(np.c_[v0, np.ones(len(v0))], uv0, rcond=None)
    style = p["facial_hair"]
    # strands of about 5 mm (9 texels of 0.6 mm), 2 mm for stubble
    strands = _strand_mask(size, np.array([-fit[1, 0], fit[1, 1]]), 3 if style == "stubble" else 9, rng)
    thick = 1e-3 * p["beard_thickness_mm"] * {"stubble": 0.1, "moustache": 0.45}.get(style, 1.0)
    shells = 1 if style == "stubble" else _SHELLS  # stubble: one sparse layer of short hairs
    out = []
    for k in range(shells):
        frac = (k + 1) / shells
        # Off the skin even at the region's edge (at least 0.15 mm): a shell on the skin would stop the skin's
        # own shadow rays.
        vk = v0 + n0 * (max(thick * frac, 0.0005) * (0.3 + 0.7 * np.sqrt(w0)))[:, None]
        density = p["beard_density"] * (0.35 if style == "stubble" else 1.0 - 0.55 * k / _SHELLS)
        opacity = (strands < density * wuv).astype(np.float32)
        fk = f[opaque_faces(uv0[f], opacity)]
        out.append(MeshPart(f"beard{k}", vk.astype(np.float32), fk.astype(np.int32),
                            Material("hair", tuple(float(c) for c in colour), 0.35, 0.5, opacity_texture=opacity),
                            n0.astype(np.float32), uv0.astype(np.float32)))  # fmt: skip
    return out


# --------------------------------------------------------------------------------------------------------
# Hats
# --------------------------------------------------------------------------------------------------------


def _beanie_frame(p: dict, lm: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray, float]:
    """The beanie's centre, its edge plane's normal (pointing up, into the hat) and offset."""
    ears = 0.5 * (lm["ear_right"] + lm["ear_left"])
    centre = np.array([0.0, ears[1] + 0.03, ears[2] - 0.01])
    front = np.array([0.0, 0.5 * (lm["brow_right_top"][1] + lm["brow_left_top"][1]) + 1e-3 * p["hat_front_mm"], 0.12])
    back = np.array([0.0, ears[1] - 0.02, ears[2] - 0.12])
    along = front - back
    normal = np.array([0.0, along[2], -along[1]])
    normal /= np.linalg.norm(normal)
    return centre, normal, float(normal @ front)


_BINS = (48, 96)  # the envelope's table: polar angle from +Y, azimuth


def _bins(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The envelope table's cell of each direction ``d`` (``(..., 3)``, not necessarily unit)."""
    d = d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-12)
    th, ph = np.arccos(np.clip(d[..., 1], -1, 1)), np.arctan2(d[..., 0], d[..., 2])
    i = np.clip((th / np.pi * _BINS[0]).astype(int), 0, _BINS[0] - 1)
    j = np.clip(((ph + np.pi) / (2 * np.pi) * _BINS[1]).astype(int), 0, _BINS[1] - 1)
    return i, j


def inside_beanie(points: np.ndarray, envelope: np.ndarray, p: dict, lm: dict[str, np.ndarray]) -> np.ndarray:
    """Which ``points`` lie under the beanie of envelope ``envelope`` (above its edge plane, inside it).

    Args:
        points: ``(N, 3)`` points (metres, the landmarks' frame).
        envelope: the hat's radius table of :func:`beanie_part`.
        p: :func:`accessory_params`.
        lm: the landmarks by name.

    Returns:
        ``(N,)`` bool.

    Examples:
        >>> from kornia_ilum_lab.synth.lightstage.subjects.base import icosphere
        >>> lm = {"mouth_right": (-0.025, -0.06, 0.09), "mouth_left": (0.025, -0.06, 0.09), "chin": (0.0, -0.11, 0.08),
        ...       "upper_lip": (0.0, -0.05, 0.1), "lower_lip": (0.0, -0.07, 0.1), "subnasale": (0.0, -0.04, 0.1),
        ...       "ear_right": (-0.075, -0.01, -0.01), "ear_left": (0.075, -0.01, -0.01),
        ...       "brow_right_top": (-0.03, 0.03, 0.09), "brow_left_top": (0.03, 0.03, 0.09)}
        >>> lm = {k: np.array(v) for k, v in lm.items()}  # a face's landmarks, metres, the eyes at y = 0
        >>> p = {"hat": "beanie", "hat_front_mm": 25.0, "hat_albedo": [0.5, 0.1, 0.1]}
        >>> _, envelope = beanie_part(p, lm, 0.1 * icosphere(2)[0], np.zeros((0, 3)))
        >>> inside_beanie(np.array([[0.0, 0.08, 0.0], [0.0, -0.08, 0.0], [0.0, 0.3, 0.0]]), envelope, p, lm).tolist()
        [True, False, False]
    """
    centre, normal, off = _beanie_frame(p, lm)
    d = points - centre
    return (points @ normal > off) & (np.linalg.norm(d, axis=1) < envelope[_bins(d)])


def beanie_part(
    p: dict, lm: dict[str, np.ndarray], head: np.ndarray, hair: np.ndarray
) -> tuple[MeshPart, np.ndarray] | None:
    """The beanie (``"hat"``, diffuse knit) over the head and hair points, or None without one.

    Args:
        p: :func:`accessory_params`.
        lm: the landmarks by name.
        head: ``(N, 3)`` skin points (the ears excluded by the caller if they should poke out).
        hair: ``(M, 3)`` hair points the hat covers.

    Returns:
        ``(part, envelope)``: the envelope is the ``(48, 96)`` table of the hat's radius around its centre
        (polar angle x azimuth) that :func:`inside_beanie` reads.

    Examples:
        >>> from kornia_ilum_lab.synth.lightstage.subjects.base import icosphere
        >>> lm = {"mouth_right": (-0.025, -0.06, 0.09), "mouth_left": (0.025, -0.06, 0.09), "chin": (0.0, -0.11, 0.08),
        ...       "upper_lip": (0.0, -0.05, 0.1), "lower_lip": (0.0, -0.07, 0.1), "subnasale": (0.0, -0.04, 0.1),
        ...       "ear_right": (-0.075, -0.01, -0.01), "ear_left": (0.075, -0.01, -0.01),
        ...       "brow_right_top": (-0.03, 0.03, 0.09), "brow_left_top": (0.03, 0.03, 0.09)}
        >>> lm = {k: np.array(v) for k, v in lm.items()}  # a face's landmarks, metres, the eyes at y = 0
        >>> p = {"hat": "beanie", "hat_front_mm": 25.0, "hat_albedo": [0.5, 0.1, 0.1]}
        >>> part, envelope = beanie_part(p, lm, 0.1 * icosphere(2)[0], np.zeros((0, 3)))  # a ball for a head
        >>> part.name, part.material.kind, envelope.shape
        ('hat', 'diffuse', (48, 96))
        >>> beanie_part(dict(p, hat="none"), lm, None, None) is None
        True
    """
    if p["hat"] != "beanie":
        return None
    import cv2  # lazy: OpenCV is slow to import, and few steps need it

    centre, normal, off = _beanie_frame(p, lm)
    pts = np.concatenate([head, hair])
    pts = pts[pts @ normal > off - 0.02]
    d = pts - centre
    table = np.zeros(_BINS, np.float32)
    np.maximum.at(table, _bins(d), np.linalg.norm(d, axis=1).astype(np.float32))
    # Fill the empty bins from their neighbours, then a smooth upper envelope (dilate, blur), plus the knit.
    for _ in range(6):
        grown = cv2.dilate(table, np.ones((3, 3), np.uint8), borderType=cv2.BORDER_REPLICATE)
        table = np.where(table > 0, table, grown)
    table = cv2.GaussianBlur(cv2.dilate(table, np.ones((5, 5), np.uint8)), (0, 0), 1.5, borderType=cv2.BORDER_REPLICATE)
    table += 0.004
    # The sheet: meridians from the crown down to where they cross the edge plane.
    n_az, n_t = 96, 40
    phi = -np.pi + 2 * np.pi * (np.arange(n_az) + 0.5) / n_az
    theta = np.linspace(0.0, np.pi * 0.85, 400)
    dirs = np.stack([np.sin(theta)[:, None] * np.sin(phi), np.cos(theta)[:, None] + 0 * phi,
                     np.sin(theta)[:, None] * np.cos(phi)], -1)  # fmt: skip
    r_fine = table[_bins(dirs)]
    above = (centre + dirs * r_fine[..., None]) @ normal > off
    edge = np.argmin(above, axis=0)  # first sample below the plane, per meridian
    edge = np.where(above.all(0), len(theta) - 1, edge)
    t = np.linspace(0.0, 1.0, n_t)[1:]
    th_grid = t[:, None] * theta[edge][None, :]
    d_grid = np.stack([np.sin(th_grid) * np.sin(phi), np.cos(th_grid), np.sin(th_grid) * np.cos(phi)], -1)
    r_grid = table[_bins(d_grid)]
    arc = (1.0 - t)[:, None] * theta[edge][None, :] * r_grid
    cuff = np.clip((0.035 - arc) / 0.004, 0.0, 1.0) * 0.003  # the folded band
    verts = centre + d_grid * (r_grid + cuff)[..., None]
    v = np.concatenate([(centre + np.array([0.0, table[0].mean(), 0.0]))[None], verts.reshape(-1, 3)])
    f = _orient(v, _disc_faces(n_az, n_t - 1), v - centre)
    nrm = vertex_normals(v, f)
    k = np.arange(n_az)
    uvs = np.concatenate([[[0.5, 1.0]], np.stack([np.broadcast_to((k + 0.5) / n_az, (n_t - 1, n_az)),
                                                  np.broadcast_to(1.0 - t[:, None], (n_t - 1, n_az))], -1).reshape(-1, 2)])  # fmt: skip
    # Knit ribs along the meridians (48 around the head).
    ribs = 0.85 + 0.15 * np.cos(2 * np.pi * 48 * np.arange(256) / 256)
    tex = np.broadcast_to(ribs[None, :, None] * np.asarray(p["hat_albedo"], np.float32), (256, 256, 3))
    part = MeshPart("hat", v.astype(np.float32), f.astype(np.int32),
                    Material("diffuse", tuple(float(c) for c in p["hat_albedo"]), albedo_texture=tex.astype(np.float32)),
                    nrm.astype(np.float32), uvs.astype(np.float32))  # fmt: skip
    return part, table
