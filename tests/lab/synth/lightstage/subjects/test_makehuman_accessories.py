"""MakeHuman subjects' accessories and hair fixes: glasses, beards, beanies, trimmed fringes, clear hair cards."""

from __future__ import annotations

import json

import numpy as np
from scipy.spatial import cKDTree

from kornia_ilum_lab.synth.lightstage.subjects import LANDMARK_NAMES
from kornia_ilum_lab.synth.lightstage.subjects.makehuman import _over_the_eyes
from kornia_ilum_lab.synth.lightstage.subjects.makehuman_assets import opaque_faces
from kornia_ilum_lab.synth.lightstage.subjects.makehuman_accessories import (
    _BINS,
    _beanie_frame,
    _bins,
    beard_weight,
    inside_beanie,
    tube,
)


def _first(mh, want, limit: int = 400) -> int:
    return next(s for s in range(limit) if want(mh.params(s)))


def _landmarks(subject) -> dict:
    return dict(zip(LANDMARK_NAMES, subject.face_landmarks.astype(np.float64)))


def test_accessory_frequencies(mh):
    """Over 300 seeds: glasses for about a quarter, facial hair on men only, a beanie for about one in ten."""
    ps = [mh.params(s) for s in range(300)]
    glasses = np.mean([p["glasses"] for p in ps])
    hats = np.mean([p["hat"] == "beanie" for p in ps])
    assert 0.15 < glasses < 0.4 and 0.04 < hats < 0.18, (glasses, hats)
    men = [p for p in ps if p["gender"] >= 0.5]
    women = [p for p in ps if p["gender"] < 0.5]
    assert 0.3 < np.mean([p["facial_hair"] != "none" for p in men]) < 0.7
    assert np.mean([p["facial_hair"] != "none" for p in women]) < 0.05
    assert {p["facial_hair"] for p in men} == {"none", "stubble", "moustache", "goatee", "beard"}
    assert all(p["hair"] not in ("bob02", "afro01") for p in ps if p["hat"] == "beanie")  # short hair under a hat
    json.dumps(ps)


def test_tube_is_closed_and_outward():
    t = np.linspace(0, 2 * np.pi, 32, endpoint=False)
    v, f, n = tube(np.stack([np.cos(t), np.sin(t), 0 * t], 1), 0.1, closed=True, up=(0, 0, 1))
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    assert (np.einsum("fi,fi->f", fn, n[f].mean(1)) > 0).all()
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), 1)
    assert (np.unique(edges, axis=0, return_counts=True)[1] == 2).all()  # watertight
    np.testing.assert_allclose(np.linalg.norm(v - np.c_[np.cos(np.arctan2(v[:, 1], v[:, 0])),
                                                        np.sin(np.arctan2(v[:, 1], v[:, 0])), 0 * v[:, 0]], axis=1),
                               0.1, atol=1e-9)  # fmt: skip


def test_glasses_clear_the_face_and_reach_the_ears(mh):
    s = mh.sample(_first(mh, lambda p: p["glasses"]))
    frame, lenses, skin = s.part("glasses"), s.part("lenses"), s.part("skin")
    assert frame.material.kind == "glossy" and lenses.material.kind == "cornea"
    rim = 1e-3 * s.params["glasses_rim_mm"]
    lm = _landmarks(s)
    ears = np.stack([lm["ear_right"], lm["ear_left"]])
    # Every frame vertex is at least 1 mm off the skin, except where the temples rest on the ears' roots.
    away = np.linalg.norm(frame.vertices[:, None] - ears[None], axis=-1).min(1) > 0.03
    gap = cKDTree(skin.vertices).query(frame.vertices[away])[0]
    assert gap.min() > 0.001, gap.min()
    # The lenses are in front of the corneas and the brows; the temples reach back to the ears.
    front = np.concatenate([s.part("cornea").vertices, s.part("lashes").vertices])
    assert lenses.vertices[:, 2].min() > front[np.abs(front[:, 1]) < 0.012, 2].max()
    assert frame.vertices[:, 2].min() < ears[:, 2].max() + 0.005
    assert frame.vertices[:, 0].min() < lm["ear_right"][0] + 0.02 and frame.vertices[:, 0].max() > lm["ear_left"][0] - 0.02
    np.testing.assert_allclose(np.linalg.norm(frame.normals, axis=1), 1.0, atol=1e-5)


def test_beard_regions(mh):
    s = mh.sample(_first(mh, lambda p: p["facial_hair"] == "beard"))
    lm = _landmarks(s)
    pts = np.stack([lm["chin"], lm["upper_lip"], lm["lower_lip"], lm["glabella"], lm["nose_tip"],
                    0.5 * (lm["subnasale"] + lm["upper_lip"]) + (0, 0.002, 0)])  # fmt: skip
    full = beard_weight("beard", pts, lm)
    assert full[0] > 0.9 and full[5] > 0.5  # chin, moustache
    assert (full[1:5] == 0).all()  # the lips, the brow, the nose stay bare
    tache = beard_weight("moustache", pts, lm)
    assert tache[5] > 0.5 and tache[0] == 0
    goatee = beard_weight("goatee", pts, lm)
    assert goatee[0] > 0.9 and goatee[3] == 0


def test_beard_shells_lie_over_the_skin(mh):
    s = mh.sample(_first(mh, lambda p: p["facial_hair"] == "beard"))
    shells = [p for p in s.parts if p.name.startswith("beard")]
    assert len(shells) == 3
    skin = s.part("skin")
    tree = cKDTree(skin.vertices)
    thick = 1e-3 * s.params["beard_thickness_mm"]
    for k, sh in enumerate(shells):
        assert sh.material.kind == "hair" and set(np.unique(sh.material.opacity_texture)) <= {0.0, 1.0}
        d = tree.query(sh.vertices)[0]
        assert d.min() > 0.0001 and d.max() < thick * (k + 1) / 3 + 0.002
        # every face covers an opaque texel, and the outer shells are sparser
        assert opaque_faces(sh.uvs[sh.faces], sh.material.opacity_texture).all()
    cover = [sh.material.opacity_texture.mean() for sh in shells]
    assert cover[0] > cover[1] > cover[2] > 0


def test_beanie_covers_the_hair_it_holds(mh):
    s = mh.sample(_first(mh, lambda p: p["hat"] == "beanie" and p["hair"] != "bald"))
    hat, hair = s.part("hat"), s.part("hair")
    lm = _landmarks(s)
    assert hat.material.kind == "diffuse"
    # the crown is over the highest hair and skin; in front, the edge is over the eyebrows; it dips at the back
    assert hat.vertices[:, 1].max() > max(hair.vertices[:, 1].max(), s.part("skin").vertices[:, 1].max())
    front = hat.vertices[(hat.vertices[:, 2] > lm["glabella"][2] - 0.03) & (np.abs(hat.vertices[:, 0]) < 0.03)]
    assert len(front) and front[:, 1].min() > max(lm["brow_left_top"][1], lm["brow_right_top"][1])
    assert hat.vertices[:, 1].min() < lm["ear_left"][1] + 0.01
    # the hair under it is gone (what stays hangs below its edge), and none pokes out through it
    centre, normal, off = _beanie_frame(s.params, lm)
    radius = np.zeros(_BINS)
    np.maximum.at(radius, _bins(hat.vertices - centre), np.linalg.norm(hat.vertices - centre, axis=1))
    up = hair.vertices[hair.vertices @ normal > off + 0.01]
    style = s.params["hair"]
    whole = len(mh.assets.proxy(f"hair/{style}/{style}.mhclo").mesh.vertices)
    assert len(hair.vertices) < 0.6 * whole and len(up) < 0.05 * whole, (len(up), len(hair.vertices), whole)
    cell = _bins(up - centre)
    covered = radius[cell] > 0
    assert (np.linalg.norm(up - centre, axis=1)[covered] <= radius[cell][covered] + 0.003).all()
    # and the hair wholly inside it is gone
    assert not inside_beanie(hair.vertices.astype(np.float64), radius, s.params, lm)[hair.faces].all(1).any()


def test_trimmed_fringe_leaves_the_eyes_clear(mh):
    """A trimmed fringe ends over the brows; bob02's swept one still hangs over an eye."""

    def over(subject) -> int:
        hair, lm = subject.part("hair"), _landmarks(subject)
        brow_y = 0.5 * (lm["brow_right_top"][1] + lm["brow_left_top"][1])
        return int(_over_the_eyes(hair.vertices[hair.faces].mean(1), brow_y).sum())

    for style in ("bob02", "short03"):
        assert over(mh.sample(_first(mh, lambda p, st=style: p["hair"] == st and p["fringe"] == "trimmed"))) == 0
    assert over(mh.sample(_first(mh, lambda p: p["hair"] == "bob02" and p["fringe"] == "swept"))) > 5


def test_hair_cards_keep_only_faces_with_opaque_texels(mh):
    """short02 stacks clear cards over the forehead (they blocked rays as black blotches): all gone."""
    s = mh.sample(_first(mh, lambda p: p["hair"] == "short02"))
    for name in ("hair", "brows", "lashes"):
        part = s.part(name)
        assert opaque_faces(part.uvs[part.faces], part.material.opacity_texture).all(), name
    raw = mh.assets.proxy("hair/short02/short02.mhclo").mesh
    assert len(s.part("hair").faces) < 0.9 * len(raw.tri_v)
