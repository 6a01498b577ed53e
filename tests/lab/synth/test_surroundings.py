"""Tests of the near surfaces lit by the same environment (kornia_ilum_lab.synth.surroundings)."""

from __future__ import annotations

import math

import pytest
import torch
from kornia_ilum_lab.synth.surroundings import (
    Surroundings,
    draw_backdrops,
    plane_radiance,
    surroundings_view,
    with_surroundings,
)

from kornia_ilum.core.errors import ShapeError, ValueCheckError
from kornia_ilum.geometry import latlong_directions, latlong_solid_angles


def _sun(height: int, direction: tuple[float, float, float]) -> tuple[torch.Tensor, torch.Tensor]:
    """A map that is black but for the one pixel nearest ``direction``, of irradiance 1 at normal incidence,
    and that pixel's centre direction."""
    d = latlong_directions(height, dtype=torch.float64).reshape(-1, 3)
    i = int((d @ torch.tensor(direction, dtype=torch.float64)).argmax())
    out = torch.zeros(3, height * 2 * height, dtype=torch.float64)
    out[:, i] = 1.0 / latlong_solid_angles(height, dtype=torch.float64).flatten()[i]
    return out.view(3, height, 2 * height), d[i]


class TestPlaneRadiance:
    def test_uniform_sky_gives_the_albedo(self):
        """A uniform radiance 1 gives E = pi on any plane: rho / pi * pi = rho (pixel-centre cosines: 0.2 %)."""
        rho = (0.2, 0.5, 0.8)
        for normal in ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0)):
            got = plane_radiance(torch.ones(3, 32, 64), normal, rho)
            torch.testing.assert_close(got, torch.tensor(rho, dtype=torch.float64), rtol=2e-3, atol=0)

    def test_a_sun_behind_the_plane_lights_nothing(self):
        sun, _ = _sun(32, (0.0, 0.0, -1.0))  # behind the wall, which faces +Z
        assert float(plane_radiance(sun, (0.0, 0.0, 1.0), (1.0, 1.0, 1.0)).abs().max()) == 0.0

    def test_a_sun_in_front_follows_lambert(self):
        d = (0.0, math.sin(0.5), math.cos(0.5))
        sun, centre = _sun(64, d)
        got = plane_radiance(sun, (0.0, 0.0, 1.0), (0.6, 0.6, 0.6))
        want = 0.6 / math.pi * float(centre[2])  # irradiance 1 times the cosine to the wall's normal
        torch.testing.assert_close(got, torch.full((3,), want, dtype=torch.float64), rtol=1e-9, atol=0)


class TestWithSurroundings:
    def test_no_planes_is_a_copy(self):
        x = torch.rand(3, 16, 32)
        y = with_surroundings(x, Surroundings())
        assert torch.equal(x, y) and y.data_ptr() != x.data_ptr()

    def test_an_unbounded_wall_fills_the_back_hemisphere(self):
        x = torch.rand(3, 16, 32)
        y = with_surroundings(x, Surroundings(wall_distance=1.0))
        d = latlong_directions(16)
        back = d[..., 2] < 0
        assert bool((y[:, back] == y[:, back][:, :1]).all())  # one radiance
        assert torch.equal(y[:, ~back], x[:, ~back])  # the front is the map

    def test_a_low_wall_shows_the_sky_above_it(self):
        x = torch.ones(3, 32, 64)
        y = with_surroundings(x, Surroundings(wall_distance=1.0, wall_top=0.5, wall_albedo=(0.1, 0.1, 0.1)))
        d = latlong_directions(32)
        over = (d[..., 2] < 0) & (d[..., 1] / (-d[..., 2]).clamp(min=1e-9) > 0.5)
        assert bool((y[:, over] == 1.0).all()) and bool((y[:, (d[..., 2] < -0.9)] < 1.0).all())

    def test_floor_below_and_the_wall_ends_it(self):
        x = torch.ones(3, 32, 64)
        s = Surroundings(wall_distance=0.5, floor_drop=1.5, floor_albedo=(0.0, 0.0, 0.0))
        y = with_surroundings(x, s)
        d = latlong_directions(32)
        floor = (d[..., 1] < 0) & (d[..., 2] > 0)  # down and toward the camera: the floor, not the wall
        assert bool((y[:, floor] == 0.0).all())
        steep_back = (d[..., 2] < -0.5) & (d[..., 1] > -0.2)  # down-back but shallow: the wall, 0.5 m away
        assert bool((y[:, steep_back] > 0.0).all())

    def test_energy_the_subject_receives_from_the_wall(self):
        """Under a uniform sky of radiance 1, a white wall to the ceiling returns the same radiance."""
        y = with_surroundings(torch.ones(3, 32, 64), Surroundings(wall_distance=2.0, wall_albedo=(1.0, 1.0, 1.0)))
        torch.testing.assert_close(y, torch.ones(3, 32, 64), rtol=2e-3, atol=0)

    def test_errors(self):
        with pytest.raises(ShapeError):
            with_surroundings(torch.ones(16, 32), Surroundings(wall_distance=1.0))
        for bad in ({"wall_distance": 0.0}, {"floor_drop": -1.0}, {"wall_albedo": (0.5, 1.5, 0.5)},
                    {"wall_distance": math.inf}, {"floor_drop": 1.0, "wall_top": -2.0}):
            with pytest.raises(ValueCheckError):
                Surroundings(**bad)


class TestSurroundingsView:
    def test_the_camera_sees_the_wall_behind_and_the_floor_below(self):
        s = Surroundings(wall_distance=1.0, wall_top=0.6, floor_drop=1.2, wall_albedo=(0.5, 0.5, 0.5),
                         floor_albedo=(0.2, 0.2, 0.2))
        rays = torch.tensor([[0.0, 0.0, -1.0], [0.0, 0.5, -1.0], [0.0, -0.9, -1.0]], dtype=torch.float64)
        rays = rays / rays.norm(dim=-1, keepdim=True)
        mask, radiance = surroundings_view(torch.ones(3, 16, 32), s, rays, camera_distance=1.0)
        # straight ahead: the wall 2 m away; up 0.5 per metre: 1 m up at the wall, over its top; steeply down:
        # 1.2 m down after 1.33 m along, before the wall (2 m): the floor
        assert mask.tolist() == [True, False, True]
        torch.testing.assert_close(radiance[:, 0], torch.full((3,), 0.5), rtol=1e-2, atol=0)  # 16 rows
        torch.testing.assert_close(radiance[:, 2], torch.full((3,), 0.2), rtol=1e-2, atol=0)
        assert float(radiance[:, 1].abs().max()) == 0.0

    def test_image_shaped_rays(self):
        rays = torch.nn.functional.normalize(torch.randn(4, 5, 3) - torch.tensor([0.0, 0.0, 3.0]), dim=-1)
        mask, radiance = surroundings_view(torch.ones(3, 8, 16), Surroundings(wall_distance=1.0), rays, 1.5)
        assert mask.shape == (4, 5) and radiance.shape == (3, 4, 5) and bool(mask.all())

    def test_bad_distance(self):
        with pytest.raises(ValueCheckError):
            surroundings_view(torch.ones(3, 8, 16), Surroundings(wall_distance=1.0), torch.ones(2, 3), 0.0)


class TestDrawBackdrops:
    def test_a_share_of_walls_that_fill_the_frame(self):
        drops = draw_backdrops(400, 0.25, torch.Generator().manual_seed(1), albedo=(0.05, 0.5))
        walls = [d for d in drops if d is not None]
        assert 70 < len(walls) < 130
        assert all(d.has_wall and not d.has_floor and d.wall_top == math.inf for d in walls)
        assert all(0.5 <= d.wall_distance <= 3.0 for d in walls)
        greys = torch.tensor([d.wall_albedo for d in walls]).mean(1)
        assert 0.04 < float(greys.min()) and float(greys.max()) < 0.6  # the range, tinted by exp(N(0, 0.1))
        rays = torch.tensor([[0.3, 0.4, -0.866], [-0.5, -0.5, -0.707]])
        mask, radiance = surroundings_view(torch.ones(3, 8, 16), walls[0], rays, 1.0)
        assert mask.all() and torch.allclose(radiance[:, 0], radiance[:, 1])  # one colour everywhere

    def test_same_generator_same_draws_and_errors(self):
        a = draw_backdrops(8, 0.5, torch.Generator().manual_seed(3))
        assert a == draw_backdrops(8, 0.5, torch.Generator().manual_seed(3))
        for share, albedo in ((1.5, (0.1, 0.5)), (0.5, (0.0, 0.5)), (0.5, (0.5, 0.95)), (0.5, (0.6, 0.5))):
            with pytest.raises(ValueCheckError):
                draw_backdrops(4, share, torch.Generator(), albedo=albedo)
