"""Tests of the procedural sources' shared helpers: the scalar draws, the cached lat-long pixel grid and the
energy-exact splatting of emitters."""

from __future__ import annotations

import math

import pytest
import torch

from kornia_ilum.geometry import latlong_directions, latlong_solid_angles
from kornia_ilum.core.errors import ShapeError, ValueCheckError
from kornia_ilum_lab.synth.environments.procedural import (
    Draw,
    latlong_pixels,
    rectangle_cells,
    splat_directions,
    splat_rectangle,
)

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


def centred_rectangle_solid_angle(a: float, b: float, d: float) -> float:
    """Solid angle of a ``2a x 2b`` rectangle at distance ``d``, centred on its axis (closed form)."""
    return 4 * math.asin(a * b / math.sqrt((a * a + d * d) * (b * b + d * d)))


def energy(env: torch.Tensor) -> torch.Tensor:
    return (env.double() * latlong_solid_angles(env.shape[-2], dtype=F64)).sum((-2, -1))


class TestSplatting:
    def test_splat_directions_conserves_energy_and_wraps(self):
        env = torch.zeros(2, 8, 16)
        d = torch.tensor([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [0.3, -0.2, -1.0], [0.0, 0.0, 1.0]])
        e = torch.tensor([[1.0, 0.5], [2.0, 0.0], [0.25, 1.0], [1.0, 0.5]])
        out = splat_directions(env, d, e)
        assert out is env
        torch.testing.assert_close(energy(env), e.double().sum(0), rtol=1e-6, atol=0.0)
        assert int((env[0] > 0).sum()) == 3  # the two +Z cells share a pixel on the seam
        assert bool(env[:, :, [0, -1]].sum() > 0)  # +Z is at the left or right edge
        before = env.clone()
        splat_directions(env, torch.zeros(0, 3), torch.zeros(0, 2))
        assert torch.equal(env, before)

    def test_rectangle_cells_are_exact(self):
        for nu, nv in ((1, 1), (3, 7), (40, 40)):
            _, om = rectangle_cells(
                [-0.5, -0.3, -2.0], edge_u=[1.0, 0.0, 0.0], edge_v=[0.0, 0.6, 0.0], nu=nu, nv=nv
            )
            assert om.dtype == F64 and om.shape == (nu * nv,)
            assert float(om.sum()) == pytest.approx(centred_rectangle_solid_angle(0.5, 0.3, 2.0), rel=1e-12)
        # off the axis: the cells of any subdivision add up to the same, and to the whole's two triangles
        rect = {"corner": [0.4, -1.0, -1.5], "edge_u": [0.8, 0.0, 0.9], "edge_v": [0.0, 1.2, 0.0]}
        whole = float(rectangle_cells(**rect, nu=1, nv=1)[1].sum())
        assert float(rectangle_cells(**rect, nu=17, nv=5)[1].sum()) == pytest.approx(whole, rel=1e-12)
        with pytest.raises(ValueCheckError, match="at least 1"):
            rectangle_cells(**rect, nu=0, nv=2)

    @pytest.mark.parametrize("height", [8, 32, 128])
    def test_splat_rectangle_keeps_its_energy(self, height):
        env = torch.zeros(3, height, 2 * height)
        radiance = torch.tensor([1.0, 2.0, 0.5])
        # a 10 x 5 cm card 1.5 m away on the camera's axis (+Z: on the map's seam), smaller than a pixel
        splat_rectangle(
            env,
            corner=[-0.05, -0.025, 1.5],
            edge_u=[0.1, 0.0, 0.0],
            edge_v=[0.0, 0.05, 0.0],
            radiance=radiance,
        )
        om = centred_rectangle_solid_angle(0.05, 0.025, 1.5)
        torch.testing.assert_close(energy(env), radiance.double() * om, rtol=1e-6, atol=0.0)
        env = torch.zeros(3, height, 2 * height)  # off the axis, large
        rect = {"corner": [0.3, 0.2, -1.5], "edge_u": [1.0, 0.0, 0.4], "edge_v": [0.0, 0.8, 0.0]}
        splat_rectangle(env, **rect, radiance=radiance)
        exact = float(rectangle_cells(**rect, nu=1, nv=1)[1].sum())
        torch.testing.assert_close(energy(env), radiance.double() * exact, rtol=1e-6, atol=0.0)

    def test_splat_rectangle_with_a_radiance_function(self):
        env = torch.zeros(3, 32, 64)
        corner, eu, ev = [-1.0, -1.0, -1.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]

        def sky(d: torch.Tensor) -> torch.Tensor:  # brighter upward
            return (1.0 + d[:, 1:2]).expand(-1, 3)

        splat_rectangle(env, corner=corner, edge_u=eu, edge_v=ev, radiance=sky, cells=(64, 64))
        dirs, om = rectangle_cells(corner, edge_u=eu, edge_v=ev, nu=64, nv=64)
        dirs = dirs / dirs.norm(dim=-1, keepdim=True)
        expected = float(((1.0 + dirs[:, 1]) * om).sum())
        assert float(energy(env)[0]) == pytest.approx(expected, rel=1e-6)
        upper = env[0, :16].sum() > env[0, 16:].sum()
        assert bool(upper)

    def test_shapes(self):
        with pytest.raises(ShapeError):
            splat_directions(torch.zeros(3, 8, 16), torch.zeros(2, 3), torch.zeros(3, 3))
        with pytest.raises(ShapeError):
            splat_directions(torch.zeros(3, 8, 12), torch.zeros(2, 3), torch.zeros(2, 3))
