"""Synthetic subjects (kornia_ilum.synth.lightstage.subjects) and their SDF toolkit (sdf.py)."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from kornia_ilum.color import srgb_to_linear
from kornia_ilum.core.errors import TypeCheckError
from kornia_ilum.synth.lightstage import (
    LANDMARK_NAMES,
    SKIN_ALBEDO,
    Material,
    MeshPart,
    Subject,
    make_subject,
    subject_params,
    subject_split,
)
from kornia_ilum.synth.lightstage.sdf import (
    bounded,
    capsule,
    edit_in_box,
    ellipsoid,
    mesh_sdf,
    smax,
    smin,
    sphere,
)
from kornia_ilum.synth.lightstage.subjects import MONK_SKIN_TONES_SRGB, SKIN_ALBEDO_SCALE

KINDS = {"skin", "diffuse", "glossy", "cornea", "hair"}
#: Seeds that between them cover every hair style, facial hair, hat, glasses, earrings, open mouths and shirts.
SEEDS = (0, 5, 6, 8)


@pytest.fixture(scope="module")
def subjects() -> dict[int, Subject]:
    return {s: make_subject(s) for s in SEEDS}


def _edge_counts(faces: np.ndarray) -> np.ndarray:
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    return np.unique(e, axis=0, return_counts=True)[1]


def _signed_volume(v: np.ndarray, f: np.ndarray) -> float:
    a, b, c = (v[f[:, i]].astype(np.float64) for i in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


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
            counts = _edge_counts(f)
            # Marching cubes' meshes are closed up to a few vertices that land exactly on grid nodes.
            assert (counts == 1).mean() < 1e-3, name
            assert _signed_volume(v, f) > 0.0, name  # outward normals

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
    def test_table(self):
        assert len(MONK_SKIN_TONES_SRGB) == len(SKIN_ALBEDO) == 10
        for code, albedo in zip(MONK_SKIN_TONES_SRGB, SKIN_ALBEDO):
            srgb = torch.tensor([int(code[i : i + 2], 16) / 255 for i in (0, 2, 4)], dtype=torch.float64)
            lin = srgb_to_linear(srgb.view(3, 1, 1)).flatten().numpy()
            np.testing.assert_allclose(albedo, SKIN_ALBEDO_SCALE * lin, atol=1e-4)
        lum = [0.2126 * r + 0.7152 * g + 0.0722 * b for r, g, b in SKIN_ALBEDO]
        # Tones 1 to 3 are equally light (3 is yellower), then every tone is darker than the one before.
        assert min(lum[:3]) > 0.6 and all(a > b for a, b in itertools.pairwise(lum[2:])) and lum[9] < 0.02

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


class TestSubjectSplit:
    def test_stable(self):
        # Pinned: changing the rule would move subjects between training and evaluation.
        evals = [s for s in range(200) if subject_split(s) == "eval"]
        assert evals[:5] == _FIRST_EVAL_SEEDS
        assert all(subject_split(s) == subject_split(s) for s in range(50))

    def test_fraction_and_disjoint(self):
        split = {s: subject_split(s) for s in range(3000)}
        train = {s for s, v in split.items() if v == "train"}
        ev = {s for s, v in split.items() if v == "eval"}
        assert not train & ev and len(train) + len(ev) == 3000
        assert 0.08 < len(ev) / 3000 < 0.12

    def test_subject_carries_split(self):
        seed = _FIRST_EVAL_SEEDS[0]
        assert subject_split(seed) == "eval"
        assert subject_split(-seed - 1) in ("train", "eval")  # any int

    @given(st.integers(min_value=-(2**62), max_value=2**62))
    def test_values(self, seed):
        assert subject_split(seed) in ("train", "eval")


_FIRST_EVAL_SEEDS = [s for s in range(200) if subject_split(s) == "eval"][:5]


class TestSdf:
    def test_mesh_sphere(self):
        v, f, n = mesh_sdf(
            lambda x, y, z: sphere(x, y, z, (0.01, 0.0, 0.0), 0.1), (-0.12,) * 3, (0.13,) * 3, 0.004
        )
        np.testing.assert_allclose(np.linalg.norm(v - [0.01, 0, 0], axis=1), 0.1, atol=5e-4)
        assert (_edge_counts(f) == 2).all()
        assert _signed_volume(v, f) == pytest.approx(4 / 3 * np.pi * 0.1**3, rel=0.01)
        assert ((n * (v - [0.01, 0, 0])).sum(1) > 0).all()  # outward normals

    def test_mesh_closed_at_box(self):
        # A slab cut by the box: the outer layer is outside, so the mesh is still closed.
        v, f, _ = mesh_sdf(lambda x, y, z: np.abs(y) - 0.02, (-0.05,) * 3, (0.05,) * 3, 0.005)
        assert (_edge_counts(f) == 2).all() and _signed_volume(v, f) > 0

    def test_mesh_empty(self):
        v, f, n = mesh_sdf(
            lambda x, y, z: sphere(x, y, z, (1.0, 0.0, 0.0), 0.1), (-0.1,) * 3, (0.1,) * 3, 0.01
        )
        assert v.shape == (0, 3) and f.shape == (0, 3) and n.shape == (0, 3)

    def test_narrow_band_matches_full(self):
        def fn(x, y, z):
            d = smin(
                ellipsoid(x, y, z, (0, 0, 0), (0.05, 0.03, 0.04)),
                capsule(x, y, z, (0, 0, 0), (0.05, 0.05, 0), 0.01),
                0.01,
            )
            return smax(d, -sphere(x, y, z, (0.0, 0.0, 0.04), 0.02), 0.005)

        v1, f1, _ = mesh_sdf(fn, (-0.07,) * 3, (0.08,) * 3, 0.0025)
        v2, f2, _ = mesh_sdf(fn, (-0.07,) * 3, (0.08,) * 3, 0.0025, coarse=1)  # every node evaluated
        assert len(f1) == len(f2)
        np.testing.assert_allclose(np.sort(v1, axis=0), np.sort(v2, axis=0), atol=1e-6)

    @given(st.floats(-1, 1), st.floats(-1, 1), st.floats(0.001, 0.5))
    def test_smooth_min_max(self, a, b, k):
        a_, b_ = np.float32(a), np.float32(b)
        assert smin(a_, b_, k) <= min(a_, b_) + 1e-6 and smin(a_, b_, k) >= min(a_, b_) - k / 4 - 1e-6
        assert smax(a_, b_, k) >= max(a_, b_) - 1e-6

    def test_bounded_is_exact_near_and_lower_bound_far(self):
        rng = np.random.default_rng(0)
        x, y, z = (rng.uniform(-0.5, 0.5, 5000).astype(np.float32) for _ in range(3))

        def fn(a, b, c):
            return sphere(a, b, c, (0.1, 0, 0), 0.04)

        exact = fn(x, y, z)
        d = bounded(fn, x, y, z, (0.06, -0.04, -0.04), (0.14, 0.04, 0.04), 0.02)
        assert (d <= exact + 1e-6).all() and (np.sign(d) == np.sign(exact)).all()
        near = (np.abs(x - 0.1) < 0.06) & (np.abs(y) < 0.06) & (np.abs(z) < 0.06)
        np.testing.assert_array_equal(d[near], exact[near])

    def test_edit_in_box(self):
        x = np.linspace(-1, 1, 5, dtype=np.float32)
        o = np.zeros_like(x)
        out = edit_in_box(x, x, o, o, (-0.6, -1, -1), (0.6, 1, 1), lambda d, *_: d + 10)
        np.testing.assert_allclose(out, [-1.0, -0.5 + 10, 10.0, 0.5 + 10, 1.0])
