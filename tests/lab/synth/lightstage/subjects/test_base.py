"""What every subject source shares (kornia_ilum_lab.synth.lightstage.subjects.base): skin tones, the split,
seeds, meshes."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from kornia_ilum.core.errors import TypeCheckError
from kornia_ilum_lab.synth.lightstage import SKIN_ALBEDO, subject_split
from kornia_ilum_lab.synth.lightstage.subjects import MONK_SKIN_TONES_SRGB
from kornia_ilum_lab.synth.lightstage.subjects.base import icosphere, seed_digest

class TestSkinTones:
    def test_table(self):
        """One albedo per MST swatch (the calibration itself is tested in test_skin.py)."""
        assert len(MONK_SKIN_TONES_SRGB) == len(SKIN_ALBEDO) == 10
        lum = [0.2126 * r + 0.7152 * g + 0.0722 * b for r, g, b in SKIN_ALBEDO]
        assert all(a > b for a, b in itertools.pairwise(lum))  # every tone darker than the one before


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

class TestSeedDigest:
    def test_salts_are_independent(self) -> None:
        assert seed_digest(3, "a") == seed_digest(3, "a") != seed_digest(3, "b")
        assert seed_digest(np.int64(3), "a") == seed_digest(3, "a")
        with pytest.raises(TypeCheckError, match="seed must be an int"):
            seed_digest(True, "a")


class TestIcosphere:
    @pytest.mark.parametrize("subdivisions", [0, 1, 3])
    def test_closed_unit_sphere(self, subdivisions: int) -> None:
        v, f = icosphere(subdivisions)
        assert v.dtype == np.float32 and f.dtype == np.int32 and len(f) == 20 * 4**subdivisions
        np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1.0, atol=1e-6)
        a, b, c = (v[f[:, i]].astype(np.float64) for i in range(3))
        assert (np.einsum("ij,ij->i", np.cross(b - a, c - a), a + b + c) > 0).all()  # outward-wound
