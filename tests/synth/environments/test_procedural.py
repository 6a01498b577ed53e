"""Tests of the procedural sources' shared helpers: the scalar draws and the cached lat-long pixel grid."""

from __future__ import annotations

import math

import pytest
import torch

from kornia_ilum.geometry import latlong_directions, latlong_solid_angles
from kornia_ilum.synth.environments.procedural import Draw, latlong_pixels

F64 = torch.float64


class TestLatLongPixels:
    def test_matches_the_geometry_grid(self):
        d, om = latlong_pixels(8)
        assert d.dtype == om.dtype == torch.float32 and d.shape == (8 * 16, 3) and om.shape == (8 * 16,)
        assert torch.equal(d, latlong_directions(8, dtype=torch.float32).reshape(-1, 3))
        assert torch.equal(om, latlong_solid_angles(8, dtype=torch.float32).reshape(-1))
        assert math.isclose(float(om.double().sum()), 4 * math.pi, rel_tol=1e-6)

    def test_cached(self):
        assert latlong_pixels(8)[0] is latlong_pixels(8)[0]


def _draws(seed: int) -> list:
    draw = Draw(torch.Generator().manual_seed(seed))
    return [
        draw.uniform(-1.0, 2.0),
        draw.log_uniform(1e-3, 10.0),
        draw.integer(3, 5),
        draw.choice(["a", "b", "c"], [1.0, 0.0, 2.0]),
        draw.choice(["x", "y"]),
        draw.bernoulli(0.5),
    ]


class TestDraw:
    def test_depends_only_on_the_generator(self):
        assert _draws(7) == _draws(7)
        assert _draws(7) != _draws(8)

    def test_one_generator_draw_each(self):
        """uniform, log_uniform and bernoulli read one float64 each: the generator's stream, in order."""
        g = torch.Generator().manual_seed(3)
        draw = Draw(g)
        values = [draw.uniform(0.0, 1.0), draw.log_uniform(1.0, math.e), draw.bernoulli(2.0)]
        u = torch.rand(3, generator=torch.Generator().manual_seed(3), dtype=F64).tolist()
        assert values[0] == u[0]
        assert values[1] == pytest.approx(math.exp(u[1]), rel=1e-15)
        assert values[2] is True

    def test_ranges(self):
        draw = Draw(torch.Generator().manual_seed(0))
        for _ in range(200):
            assert 2.0 <= draw.uniform(2.0, 3.0) < 3.0
            assert 0.01 <= draw.log_uniform(0.01, 100.0) < 100.0
            assert draw.integer(-1, 1) in (-1, 0, 1)
            assert draw.choice("ab", [0.0, 1.0]) == "b"
            assert draw.bernoulli(0.0) is False

    def test_integer_bounds_inclusive(self):
        draw = Draw(torch.Generator().manual_seed(0))
        assert {draw.integer(0, 2) for _ in range(200)} == {0, 1, 2}
