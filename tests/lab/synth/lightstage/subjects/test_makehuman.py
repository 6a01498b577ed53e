"""MakeHuman subjects (kornia_ilum_lab.synth.lightstage.subjects.makehuman): re-tinting, opacity, clipping and
sampled subjects."""

from __future__ import annotations

import json
import pickle

import numpy as np
import pytest
from kornia_ilum_lab.synth.lightstage.subjects import (
    LANDMARK_NAMES,
    SKIN_ALBEDO,
    MakeHumanAssetsNotFoundError,
    MakeHumanSource,
    subject_source,
    subject_split,
)
from kornia_ilum_lab.synth.lightstage.subjects.makehuman import (
    _IRIS,
    _OUTFITS,
    clean_alpha,
    clip_mesh_below,
    enamel_mask,
    iris_probabilities,
    retint_iris,
    retint_skin,
    retint_teeth,
)
from kornia_ilum_lab.synth.lightstage.subjects.makehuman_assets import load_texture

from kornia_ilum.core.errors import ValueCheckError


def test_retint_keeps_detail_and_hits_target(mh):
    a = mh.assets
    for tone in (1, 10):
        fam = "lightskinned" if tone == 1 else "darkskinned"
        tex, _ = load_texture(next(s for s in a.skins if f"_{fam}_" in s.name))
        target = SKIN_ALBEDO[tone - 1]
        out, mean = retint_skin(tex, a.face_mask, target)
        np.testing.assert_allclose(mean, target, rtol=0.02)
        assert out.dtype == np.float32 and out.shape == tex.shape and out.max() <= 0.95
        m = a.face_mask
        lo, lt = np.log(out[m] + 1e-4), np.log(tex[m] + 1e-4)
        for c in range(3):
            assert np.corrcoef(lo[:, c], lt[:, c])[0, 1] > 0.98


def test_iris_colours_follow_skin_tone_and_brown_irises_are_brown(mh):
    light = [i for i, n in enumerate(_IRIS) if n not in ("brown", "brownlight")]
    for tone in range(1, 11):
        p = iris_probabilities(tone)
        assert abs(p.sum() - 1.0) < 1e-9 and (p >= 0).all()
    assert iris_probabilities(1)[light].sum() > 0.5 > 0.05 > iris_probabilities(7)[light].sum()
    # The brown map's iris (saturated red-brown) takes the wanted colour; sclera and pupil stay as they were.
    tex, _ = load_texture(mh.root / "eyes" / "materials" / "brown_eye.png")
    want = (0.03, 0.015, 0.007)
    out = retint_iris(tex, want)
    changed = np.any(out != tex, -1)
    assert 0.03 < changed.mean() < 0.15  # the two irises, not the sclera
    np.testing.assert_allclose(out[changed].mean(0), want, rtol=0.15)
    enc = tex ** (1 / 2.2)
    sclera = enc.min(-1) > 0.6
    pupil = enc.max(-1) < 0.1
    assert sclera.any() and pupil.any() and not changed[sclera].any() and not changed[pupil].any()
    # Sampled subjects: mostly brown eyes on dark skin.
    dark = [q for q in map(mh.params, range(400)) if q["skin_tone"] >= 6]
    assert sum(q["iris"] in ("brown", "brownlight") for q in dark) >= 0.9 * len(dark)


def test_teeth_enamel_is_measured_incisors_and_gums_stay(mh):
    """MakeHuman's enamel (about 0.30 linear, neutral) is re-tinted to TEETH_ALBEDO (L* 77, b* 20); the gums and
    the blank texels keep their values; a sampled subject's teeth carry the re-tinted map and pass the part check."""
    from kornia_ilum_lab.synth.lightstage.calibration import check_parts
    from kornia_ilum_lab.synth.lightstage.subjects.base import TEETH_ALBEDO

    tex, _ = load_texture(mh.root / "teeth" / "materials" / "teeth.png")
    enamel = enamel_mask(tex)
    assert 0.15 < enamel.mean() < 0.4  # a quarter of the map; the gums and the blank area are not enamel
    before = tex[enamel].mean(0)
    assert before.max() < 0.4 and before.max() - before.min() < 0.05  # too dark and neutral: the audit's finding
    out = retint_teeth(tex)
    np.testing.assert_allclose(out[enamel].mean(0), TEETH_ALBEDO, rtol=0.02)
    assert np.array_equal(out[~enamel], tex[~enamel])
    subject = mh.sample(0)
    teeth = next(p for p in subject.parts if p.name == "teeth")
    np.testing.assert_allclose(teeth.material.albedo_texture[enamel].mean(0), TEETH_ALBEDO, rtol=0.02)
    assert next(c for c in check_parts(subject) if c.name == "teeth").ok
    assert not check_parts_on(tex)


def check_parts_on(texture):
    """Whether MakeHuman's own teeth map (before the re-tint) passes the teeth check: it does not (too dark)."""
    from types import SimpleNamespace

    from kornia_ilum_lab.synth.lightstage.calibration import check_parts

    part = SimpleNamespace(name="teeth", material=SimpleNamespace(albedo_texture=texture, opacity_texture=None))
    return check_parts(SimpleNamespace(parts=[part]))[0].ok


def test_opacity_textures_binary_without_film(mh):
    root = mh.root
    pngs = [root / "hair" / h / f for h in ("short01", "afro01", "bob02") for f in [f"{h}_diffuse.png"]]
    pngs[1] = root / "hair" / "afro01" / "afro_diffuse.png"
    pngs += [root / "eyebrows" / "eyebrow003" / "eyebrow003.png", root / "eyelashes" / "eyelashes02" / "eyelashes02.png"]
    for p in pngs:
        _, alpha = load_texture(p)
        op = clean_alpha(alpha)
        assert set(np.unique(op).tolist()) <= {0.0, 1.0}
        assert np.all(op[alpha >= 0.7] == 1.0)  # no holes in the strands
        assert np.all(op[alpha < 0.15] == 0.0)  # no film
        assert abs(op.mean() - alpha.mean()) < 0.25 * alpha.mean() + 0.01  # coverage kept


def test_clip_mesh_below_is_straight():
    v = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    f = np.array([[0, 1, 2], [0, 2, 3]])
    cv, cf, (uv,) = clip_mesh_below(v, f, 0.3, [v[:, :2]])
    assert cv[:, 1].min() == pytest.approx(0.3)
    area = 0.5 * np.abs(np.cross(cv[cf[:, 1]] - cv[cf[:, 0]], cv[cf[:, 2]] - cv[cf[:, 0]])[:, 2]).sum()
    assert area == pytest.approx(0.7)
    n = np.cross(cv[cf[:, 1]] - cv[cf[:, 0]], cv[cf[:, 2]] - cv[cf[:, 0]])[:, 2]
    assert np.all(n > 0)  # orientation kept
    np.testing.assert_allclose(uv, cv[:, :2])


def _border_vertices(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Border vertices of the mesh welded by position (UV seams split vertices but are not borders)."""
    _, first, weld = np.unique(np.round(vertices.astype(np.float64), 6), axis=0, return_index=True, return_inverse=True)
    faces = weld.reshape(-1)[faces]
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), 1)
    u, c = np.unique(e, axis=0, return_counts=True)
    return first[np.unique(u[c == 1])]


def test_sampled_subject(mh):
    s = mh.sample(11)
    s2 = mh.sample(11)
    assert s.source == "makehuman" and s.split == subject_split(11)
    names = {p.name for p in s.parts}
    need = {"skin", "eyes", "cornea", "brows", "lashes", "teeth"} | ({"hair"} if s.params["hair"] != "bald" else set())
    assert need <= names
    for p, q in zip(s.parts, s2.parts):
        np.testing.assert_array_equal(p.vertices, q.vertices)
        assert p.vertices.dtype == np.float32 and p.vertices.ndim == 2 and p.vertices.shape[1] == 3
        assert p.faces.dtype == np.int32 and p.faces.min() >= 0 and p.faces.max() < len(p.vertices)
        assert np.isfinite(p.vertices).all()
        if p.normals is not None:
            np.testing.assert_allclose(np.linalg.norm(p.normals, axis=1), 1.0, atol=1e-4)
        if p.uvs is not None:
            assert p.uvs.shape == (len(p.vertices), 2) and p.uvs.min() >= 0 and p.uvs.max() <= 1
        for t in (p.material.albedo_texture, p.material.opacity_texture, p.material.roughness_texture):
            assert t is None or (t.dtype == np.float32 and np.isfinite(t).all())
    json.dumps(s.params)
    assert 1 <= s.skin_tone <= 10 and len(s.face_albedo) == 3
    skin = s.part("skin")
    assert skin.material.kind == "skin" and skin.material.subsurface
    assert s.part("cornea").material.kind == "cornea"
    # Landmarks: inside the head's box, the subject's right at -X.
    lm = dict(zip(LANDMARK_NAMES, s.face_landmarks))
    assert s.face_landmarks.shape == (20, 3) and s.face_landmarks.dtype == np.float32
    lo, hi = skin.vertices.min(0), skin.vertices.max(0)
    assert np.all(s.face_landmarks >= lo - 1e-3) and np.all(s.face_landmarks <= hi + 1e-3)
    assert lm["eye_right_outer"][0] < lm["eye_right_inner"][0] < lm["eye_left_inner"][0] < lm["eye_left_outer"][0]
    assert lm["ear_right"][0] < lm["mouth_right"][0] < 0 < lm["mouth_left"][0] < lm["ear_left"][0]
    assert lm["chin"][1] < lm["lower_lip"][1] < lm["upper_lip"][1] < lm["nose_tip"][1] < lm["glabella"][1]
    assert abs(0.5 * (lm["eye_right_outer"][1] + lm["eye_left_outer"][1])) < 0.01
    # The cut: every border vertex of the skin lies on the cut plane (within 1 mm).
    b = _border_vertices(skin.vertices, skin.faces)
    assert len(b) > 20
    np.testing.assert_allclose(skin.vertices[b, 1], s.params["cut_y"], atol=1e-3)
    # Outward normals: the nose tip's normal points forward.
    i = np.argmin(np.linalg.norm(skin.vertices - lm["nose_tip"], axis=1))
    assert skin.normals[i, 2] > 0.5


def test_sample_is_cached_and_varied(mh):
    a = mh.assets
    before = len(a.targets)
    mh.sample(11)
    assert len(a.targets) == before  # no reparse for a seed already seen
    s = mh.sample(12)
    assert s.params != mh.sample(11).params


def test_missing_assets_error(tmp_path, monkeypatch):
    monkeypatch.delenv("KORNIA_ILUM_MAKEHUMAN", raising=False)
    monkeypatch.delenv("KORNIA_ILUM_SHARED_DATA", raising=False)
    with pytest.raises(MakeHumanAssetsNotFoundError, match="KORNIA_ILUM_MAKEHUMAN"):
        MakeHumanSource.from_assets()
    with pytest.raises(FileNotFoundError, match="base.obj"):
        MakeHumanSource.from_assets(tmp_path)
    monkeypatch.setenv("KORNIA_ILUM_MAKEHUMAN", str(tmp_path))
    with pytest.raises(MakeHumanAssetsNotFoundError):
        subject_source("makehuman")
    assert subject_source("mannequin").name == "mannequin"


def test_source_pickles_to_worker_processes(mh):
    """build_cache sends the source to spawned workers: it pickles as its root and samples the same subject."""
    copy = pickle.loads(pickle.dumps(mh))
    assert copy.root == mh.root and copy._assets is None
    a, b = copy.sample(5), mh.sample(5)
    assert a.params == b.params and np.array_equal(a.parts[0].vertices, b.parts[0].vertices)


class TestClothes:
    """``MakeHumanSource(clothes=True, cut_below_chin=...)``: the CC0 outfits, and a lower cut."""

    _dressed: dict = {}

    @pytest.fixture
    def dressed(self, mh):
        """One dressed source per root (its assets are parsed once)."""
        return self._dressed.setdefault(mh.root, MakeHumanSource(mh.root, clothes=True))

    def test_outfit_is_bound_cut_and_drawn_apart(self, mh, dressed):
        bare, s = mh.sample(11), dressed.sample(11)
        assert s.source == "makehuman+clothes" and bare.source == "makehuman"
        # its own stream: every other choice of the subject is what it was
        assert {k: v for k, v in s.params.items() if k != "clothes"} == bare.params
        c = s.params["clothes"]
        assert c["outfit"] in _OUTFITS["male"] + _OUTFITS["female"]
        assert all(0.0 < x < 0.95 for x in c["albedo"])
        cloth = s.part("clothes")
        assert cloth.material.kind == "diffuse" and cloth.material.albedo == tuple(c["albedo"])
        assert cloth.vertices[:, 1].min() >= s.params["cut_y"] - 1e-5
        assert cloth.vertices[:, 1].min() <= s.params["cut_y"] + 1e-5  # cut at the plane, not above it
        np.testing.assert_allclose(np.linalg.norm(cloth.normals, axis=1), 1.0, atol=1e-4)
        # the skin under the cloth is hidden; the face is not
        assert len(s.part("skin").faces) < len(bare.part("skin").faces)
        np.testing.assert_array_equal(s.face_landmarks, bare.face_landmarks)
        # outward: the cloth's normal at its most forward point faces the camera
        i = np.argmax(cloth.vertices[:, 2])
        assert cloth.normals[i, 2] > 0.3

    def test_outfits_follow_sex_mostly(self, dressed):
        picks = [(dressed.params(seed)["gender"] >= 0.5, dressed.params(seed)["clothes"]["outfit"])
                 for seed in range(40)]
        own = np.mean([outfit.startswith("male_" if male else "female_") for male, outfit in picks])
        assert 0.6 <= own <= 0.97

    def test_lower_cut_and_its_name(self, mh):
        low = MakeHumanSource(mh.root, clothes=True, cut_below_chin=0.6)
        assert low.name == "makehuman+clothes+cut0.60"
        s = low.sample(11)
        skin = s.part("skin")
        chin = dict(zip(LANDMARK_NAMES, s.face_landmarks))["chin"][1]
        assert abs(s.params["cut_y"] - (chin - 0.6)) < 1e-3
        assert skin.vertices[:, 1].min() >= s.params["cut_y"] - 1e-5
        assert s.part("clothes").vertices[:, 1].min() < chin - 0.55
        copy = pickle.loads(pickle.dumps(low))
        assert (copy.clothes, copy.cut_below_chin, copy.name) == (True, 0.6, low.name)
        assert "cut_below_chin=0.6" in repr(copy)

    @pytest.mark.parametrize("cut", [0.05, 1.5])
    def test_cut_out_of_range(self, mh, cut):
        with pytest.raises(ValueCheckError, match="cut_below_chin"):
            MakeHumanSource(mh.root, cut_below_chin=cut)

    def test_subject_source_options(self, mh):
        assert subject_source("makehuman", assets=str(mh.root), clothes=True).name == "makehuman+clothes"
        with pytest.raises(ValueCheckError, match="no options"):
            subject_source("mannequin", clothes=True)
