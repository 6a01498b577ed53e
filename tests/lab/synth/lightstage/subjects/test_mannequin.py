"""The signed-distance mannequins (kornia_ilum_lab.synth.lightstage.subjects.mannequin)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from kornia_ilum.core.errors import TypeCheckError
from kornia_ilum_lab.synth.lightstage import (
    LANDMARK_NAMES,
    SKIN_ALBEDO,
    Material,
    MeshPart,
    Subject,
    make_subject,
    subject_params,
    subject_split,
)
from tests.lab.synth.lightstage.meshes import edge_counts, signed_volume

KINDS = {"skin", "diffuse", "glossy", "cornea", "hair"}

SEEDS = (0, 5, 6, 8)

@pytest.fixture(scope="module")
def subjects() -> dict[int, Subject]:
    return {s: make_subject(s) for s in SEEDS}

def _weld(parts: list[MeshPart]) -> tuple[np.ndarray, np.ndarray]:
    """Concatenate parts and merge vertices at the same position (split parts share their seams)."""
    v = np.concatenate([p.vertices for p in parts])
    off = np.cumsum([0] + [len(p.vertices) for p in parts])[:-1]
    f = np.concatenate([p.faces + o for p, o in zip(parts, off)])
    u, inv = np.unique(np.round(v.astype(np.float64) * 1e6).astype(np.int64), axis=0, return_inverse=True)
    return u.astype(np.float64) * 1e-6, inv.reshape(-1)[f]

class TestMakeSubject:
    def test_smoke(self, subjects):
        s = subjects[0]
        assert isinstance(s, Subject) and s.seed == 0 and s.split in ("train", "eval")
        names = [p.name for p in s.parts]
        assert len(names) == len(set(names))
        for required in ("skin", "lips", "sclera", "iris", "pupil", "cornea", "brows", "shirt"):
            assert required in names
        assert s.part("cornea").material.kind == "cornea"
        json.dumps(s.params)  # the parameters are JSON-serialisable
        with pytest.raises(KeyError, match="no part 'tail'"):
            s.part("tail")

    def test_cardinality(self, subjects):
        for s in subjects.values():
            assert s.face_landmarks.shape == (len(LANDMARK_NAMES), 3) and s.face_landmarks.dtype == np.float32
            for p in s.parts:
                assert p.vertices.ndim == 2 and p.vertices.shape[1] == 3 and p.vertices.dtype == np.float32
                assert p.faces.ndim == 2 and p.faces.shape[1] == 3 and p.faces.dtype == np.int32
                assert len(p.faces) > 0
                assert p.faces.min() >= 0 and p.faces.max() < len(p.vertices)
                assert np.isfinite(p.vertices).all()
                if p.normals is not None:
                    assert p.normals.shape == p.vertices.shape
                    np.testing.assert_allclose(np.linalg.norm(p.normals, axis=1), 1.0, atol=1e-3)

    def test_exception(self):
        with pytest.raises(TypeCheckError, match="seed must be an int"):
            make_subject("3")  # type: ignore[arg-type]
        with pytest.raises(TypeCheckError, match="seed must be an int"):
            make_subject(True)  # type: ignore[arg-type]
        with pytest.raises(TypeCheckError, match="seed must be an int"):
            subject_split(1.5)  # type: ignore[arg-type]
        with pytest.raises(TypeCheckError, match="seed must be an int"):
            subject_params(None)  # type: ignore[arg-type]

    def test_deterministic(self, subjects):
        again = make_subject(5)
        ref = subjects[5]
        assert [p.name for p in again.parts] == [p.name for p in ref.parts]
        for a, b in zip(again.parts, ref.parts):
            assert np.array_equal(a.vertices, b.vertices) and np.array_equal(a.faces, b.faces)
            assert a.material == b.material
        assert np.array_equal(again.face_landmarks, ref.face_landmarks)
        assert again.params == ref.params == subject_params(5)

    def test_seeds_differ(self, subjects):
        a, b = subjects[0], subjects[5]
        assert a.params != b.params
        assert a.part("skin").vertices.shape != b.part("skin").vertices.shape or not np.array_equal(
            a.part("skin").vertices, b.part("skin").vertices
        )
        # The shape parameters differ for almost all seeds, not only the colours.
        widths = {round(subject_params(s)["head_width"], 6) for s in range(50)}
        assert len(widths) == 50

    def test_variety(self):
        params = [subject_params(s) for s in range(400)]
        for key, values in (
            ("hair_style", {"bald", "buzz", "short", "medium", "long", "afro", "bun"}),
            ("facial_hair", {"none", "stubble", "moustache", "goatee", "beard", "long_beard"}),
            ("hat", {"none", "beanie", "cap"}),
            ("shirt_style", {"crew", "vneck", "turtleneck", "collar"}),
            ("glasses", {True, False}),
            ("earrings", {True, False}),
        ):
            assert {p[key] for p in params} == values, key
        assert any(p["hair_colour"].startswith("dyed") for p in params)
        assert {p["mouth_open"] > 0 for p in params} == {True, False}

    def test_parts_are_closed_without_culling(self):
        s = make_subject(6, cull_hidden=False)  # hair, hat, beard, crew collar
        skin = [p for p in s.parts if p.name in ("skin", "lips", "mouth", "stubble")]
        groups = {"skin": skin, "eyeball": [s.part(n) for n in ("sclera", "iris", "pupil")]}
        groups.update({p.name: [p] for p in s.parts if p.name not in ("skin", "lips", "mouth", "stubble", "sclera",
                                                                         "iris", "pupil")})  # fmt: skip
        for name, parts in groups.items():
            v, f = _weld(parts)
            counts = edge_counts(f)
            # Marching cubes' meshes are closed up to a few vertices that land exactly on grid nodes.
            assert (counts == 1).mean() < 1e-3, name
            assert signed_volume(v, f) > 0.0, name  # outward normals

    def test_culling_keeps_the_visible_surface(self):
        full = make_subject(6, cull_hidden=False)
        culled = make_subject(6)
        n_full = sum(len(p.faces) for p in full.parts)
        n_culled = sum(len(p.faces) for p in culled.parts)
        assert n_culled < 0.8 * n_full
        # The face is untouched: the same lips, eyes and landmarks.
        for name in ("lips", "cornea", "iris"):
            assert np.array_equal(full.part(name).vertices, culled.part(name).vertices)
        assert np.array_equal(full.face_landmarks, culled.face_landmarks)

    def test_size_and_triangles(self, subjects):
        for s in subjects.values():
            skin = np.concatenate([p.vertices for p in s.parts if p.material.kind == "skin"])
            lo, hi = skin.min(0), skin.max(0)
            assert 0.13 < hi[0] - lo[0] < 0.25  # ear to ear (metres)
            top = max(p.vertices[:, 1].max() for p in s.parts)
            assert 0.1 < top < 0.22  # the top of the head, hair or hat
            assert sum(len(p.faces) for p in s.parts) < 220_000

    def test_landmarks(self, subjects):
        idx = {n: i for i, n in enumerate(LANDMARK_NAMES)}
        for s in subjects.values():
            lm = s.face_landmarks
            skin = np.concatenate([p.vertices for p in s.parts if p.material.kind == "skin"])
            assert (lm >= skin.min(0) - 1e-3).all() and (lm <= skin.max(0) + 1e-3).all()
            assert np.isfinite(lm).all()
            y = lm[:, 1]
            assert y[idx["brow_left_top"]] > y[idx["eye_left_outer"]] > y[idx["nose_tip"]] > y[idx["chin"]]
            assert y[idx["upper_lip"]] > y[idx["lower_lip"]]
            x = lm[:, 0]  # the subject faces +Z: their left is the image's right (+X)
            assert x[idx["ear_left"]] > x[idx["eye_left_outer"]] > x[idx["eye_left_inner"]] > 0.0
            assert x[idx["ear_right"]] < x[idx["eye_right_outer"]] < x[idx["eye_right_inner"]] < 0.0
            assert lm[idx["nose_tip"], 2] == lm[:, 2].max()
            # The box spans a face: 12 to 20 cm wide, 12 to 20 cm tall.
            w, h = x.max() - x.min(), y.max() - y.min()
            assert 0.12 < w < 0.2 and 0.12 < h < 0.2

    def test_materials(self, subjects):
        for s in subjects.values():
            for p in s.parts:
                m = p.material
                assert isinstance(m, Material) and m.kind in KINDS
                assert len(m.albedo) == 3 and all(0.0 <= c <= 1.0 for c in m.albedo)
                assert 0.0 <= m.roughness <= 1.0 and 0.0 <= m.specular <= 1.0
            skin = s.part("skin").material
            assert skin.kind == "skin" and 0.35 <= skin.roughness <= 0.5 and 0.3 <= skin.specular <= 0.4
            lips, skin_rgb = np.array(s.part("lips").material.albedo), np.array(skin.albedo)
            if not s.params["lipstick"]:
                assert lips[1] < skin_rgb[1]  # redder: less green than the skin

    def test_eyes(self, subjects):
        s = subjects[0]
        for name in ("sclera", "iris", "cornea"):
            v = s.part(name).vertices
            left, right = v[v[:, 0] > 0], v[v[:, 0] < 0]
            assert len(left) and len(right)  # both eyes
        cornea, iris = s.part("cornea").vertices, s.part("iris").vertices
        assert cornea[:, 2].max() > iris[:, 2].max()  # the cornea bulges in front of the iris

class TestSkinTones:
    def test_coverage(self):
        tones = [subject_params(s)["skin_tone"] for s in range(300)]
        counts = np.bincount(tones, minlength=11)[1:]
        assert (counts >= 15).all()  # every tone, roughly uniformly

    def test_albedo_follows_tone(self):
        for s in range(40):
            p = subject_params(s)
            base = np.array(SKIN_ALBEDO[p["skin_tone"] - 1])
            ratio = np.array(p["skin_albedo"]) / base
            assert ((ratio > 0.6) & (ratio < 1.6)).all()
