"""The signed-distance toolkit of the mannequins (kornia_ilum_lab.synth.lightstage.sdf)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from kornia_ilum_lab.synth.lightstage.sdf import (
    bounded,
    capsule,
    edit_in_box,
    ellipsoid,
    mesh_sdf,
    smax,
    smin,
    sphere,
)
from tests.lab.synth.lightstage.meshes import edge_counts, signed_volume

class TestSdf:
    def test_mesh_sphere(self):
        v, f, n = mesh_sdf(
            lambda x, y, z: sphere(x, y, z, c=(0.01, 0.0, 0.0), r=0.1),
            lo=(-0.12,) * 3,
            hi=(0.13,) * 3,
            step=0.004,
        )
        np.testing.assert_allclose(np.linalg.norm(v - [0.01, 0, 0], axis=1), 0.1, atol=5e-4)
        assert (edge_counts(f) == 2).all()
        assert signed_volume(v, f) == pytest.approx(4 / 3 * np.pi * 0.1**3, rel=0.01)
        assert ((n * (v - [0.01, 0, 0])).sum(1) > 0).all()  # outward normals

    def test_mesh_closed_at_box(self):
        # A slab cut by the box: the outer layer is outside, so the mesh is still closed.
        v, f, _ = mesh_sdf(lambda x, y, z: np.abs(y) - 0.02, lo=(-0.05,) * 3, hi=(0.05,) * 3, step=0.005)
        assert (edge_counts(f) == 2).all() and signed_volume(v, f) > 0

    def test_mesh_empty(self):
        v, f, n = mesh_sdf(
            lambda x, y, z: sphere(x, y, z, c=(1.0, 0.0, 0.0), r=0.1),
            lo=(-0.1,) * 3,
            hi=(0.1,) * 3,
            step=0.01,
        )
        assert v.shape == (0, 3) and f.shape == (0, 3) and n.shape == (0, 3)

    def test_narrow_band_matches_full(self):
        def fn(x, y, z):
            d = smin(
                ellipsoid(x, y, z, c=(0, 0, 0), r=(0.05, 0.03, 0.04)),
                capsule(x, y, z, a=(0, 0, 0), b=(0.05, 0.05, 0), ra=0.01),
                0.01,
            )
            return smax(d, -sphere(x, y, z, c=(0.0, 0.0, 0.04), r=0.02), 0.005)

        v1, f1, _ = mesh_sdf(fn, lo=(-0.07,) * 3, hi=(0.08,) * 3, step=0.0025)
        v2, f2, _ = mesh_sdf(
            fn, lo=(-0.07,) * 3, hi=(0.08,) * 3, step=0.0025, coarse=1
        )  # every node evaluated
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
            return sphere(a, b, c, c=(0.1, 0, 0), r=0.04)

        exact = fn(x, y, z)
        d = bounded(fn, x, y, z, lo=(0.06, -0.04, -0.04), hi=(0.14, 0.04, 0.04), margin=0.02)
        assert (d <= exact + 1e-6).all() and (np.sign(d) == np.sign(exact)).all()
        near = (np.abs(x - 0.1) < 0.06) & (np.abs(y) < 0.06) & (np.abs(z) < 0.06)
        np.testing.assert_array_equal(d[near], exact[near])

    def test_edit_in_box(self):
        x = np.linspace(-1, 1, 5, dtype=np.float32)
        o = np.zeros_like(x)
        out = edit_in_box(x, x, o, o, lo=(-0.6, -1, -1), hi=(0.6, 1, 1), fn=lambda d, *_: d + 10)
        np.testing.assert_allclose(out, [-1.0, -0.5 + 10, 10.0, 0.5 + 10, 1.0])
