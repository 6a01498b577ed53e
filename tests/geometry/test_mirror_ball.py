"""Tests of the mirror-ball grid: coordinates, directions, solid angles, owners.

The grid is that of docs/conventions.rst, "Mirror ball".
"""

from __future__ import annotations

import math

import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from kornia_ilum.core.errors import NonFiniteError, ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.geometry import (
    direction_to_mirror_ball,
    lights_to_mirror_ball,
    mirror_ball_directions,
    mirror_ball_pixel_index,
    mirror_ball_solid_angles,
    mirror_ball_to_direction,
    mirror_ball_to_lights,
    mirror_ball_uv,
    mirror_ball_valid,
    pixel_to_uv,
    uv_to_pixel,
)

F64 = torch.float64
SQRT_HALF = 1.0 / math.sqrt(2.0)

# points strictly inside the unit disk, as polar coordinates
disk_points = st.tuples(st.floats(0.0, 0.999), st.floats(-math.pi, math.pi))
unit_vectors = st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)).filter(
    lambda v: 0.1 < math.sqrt(sum(c * c for c in v)) <= 1.0
)


class TestMirrorBallUV:
    def test_smoke(self):
        uv = mirror_ball_uv(4, dtype=F64)
        assert uv[0, 0].tolist() == [-0.75, 0.75]  # top-left: u left, v up
        assert uv[3, 3].tolist() == [0.75, -0.75]

    def test_cardinality(self):
        assert mirror_ball_uv(5).shape == (5, 5, 2)
        assert mirror_ball_uv(1).tolist() == [[[0.0, 0.0]]]

    @given(st.integers(1, 64))
    def test_spec_pixel_centres(self, size):
        uv = mirror_ball_uv(size, dtype=F64)
        i, j = torch.meshgrid(torch.arange(size), torch.arange(size), indexing="ij")
        torch.testing.assert_close(uv[..., 0], (2 * j + 1).to(F64) / size - 1)
        torch.testing.assert_close(uv[..., 1], 1 - (2 * i + 1).to(F64) / size)

    def test_exception(self):
        with pytest.raises(ValueCheckError, match="size must be positive"):
            mirror_ball_uv(0)
        with pytest.raises(TypeCheckError, match="size must be an int"):
            mirror_ball_uv(4.0)

    def test_dtypes(self, dtype):
        assert mirror_ball_uv(8, dtype=dtype).dtype == dtype


class TestMirrorBallValid:
    def test_smoke(self):
        assert int(mirror_ball_valid(4).sum()) == 12
        assert int(mirror_ball_valid(32).sum()) == 812

    @given(st.integers(1, 64))
    def test_matches_radius(self, size):
        uv = mirror_ball_uv(size, dtype=F64)
        assert torch.equal(mirror_ball_valid(size), uv.square().sum(-1) <= 1.0 + 1e-12)

    @given(st.integers(1, 64))
    def test_symmetric(self, size):
        valid = mirror_ball_valid(size)
        assert torch.equal(valid, valid.flip(-1)) and torch.equal(valid, valid.flip(-2))


class TestMirrorBallDirections:
    def test_spec_anchors(self):
        d, valid = mirror_ball_to_direction(
            torch.tensor(
                [[0.0, 0.0], [SQRT_HALF, 0.0], [0.0, SQRT_HALF], [-SQRT_HALF, 0.0], [1.0, 0.0], [0.0, -1.0]],
                dtype=F64,
            )
        )
        expected = torch.tensor(
            [[0, 0, 1], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, 0, -1], [0, 0, -1]], dtype=F64
        )
        torch.testing.assert_close(
            d, expected, atol=1e-12, rtol=0
        )  # centre +Z, r = 1/sqrt2 the equator, rim -Z
        assert bool(valid.all())

    def test_centre_pixel_is_plus_z(self):
        d, valid = mirror_ball_directions(33, dtype=F64)
        torch.testing.assert_close(d[16, 16], torch.tensor([0.0, 0.0, 1.0], dtype=F64))
        d, _ = mirror_ball_directions(32, dtype=F64)  # even size: the four centre pixels surround +Z
        assert bool((d[15:17, 15:17, 2] > 0.99).all())
        assert d[15, 16, 0] > 0 and d[15, 16, 1] > 0  # upper right pixel: light from right and above

    def test_rim_is_minus_z(self):
        d, valid = mirror_ball_directions(32, dtype=F64)
        r2 = mirror_ball_uv(32, dtype=F64).square().sum(-1)
        torch.testing.assert_close(d[..., 2][valid], (1 - 2 * r2)[valid])  # z falls from +1 to -1 with r
        assert d[..., 2][valid].min().item() < -0.95

    @given(disk_points)
    def test_theta_is_two_asin_r(self, point):
        r, az = point
        uv = torch.tensor([r * math.cos(az), r * math.sin(az)], dtype=F64)
        d, valid = mirror_ball_to_direction(uv)
        assert bool(valid)
        theta = math.acos(max(-1.0, min(1.0, d[2].item())))  # angle from +Z
        assert abs(theta - 2 * math.asin(r)) < 1e-6
        assert abs(d.norm().item() - 1.0) < 1e-12
        if r > 1e-6:  # the azimuth of (x, y) is the azimuth of (u, v)
            assert abs(math.remainder(math.atan2(d[1].item(), d[0].item()) - az, 2 * math.pi)) < 1e-9

    @given(disk_points)
    def test_uv_direction_uv_round_trip(self, point):
        r, az = point
        uv = torch.tensor([r * math.cos(az), r * math.sin(az)], dtype=F64)
        back = direction_to_mirror_ball(mirror_ball_to_direction(uv)[0])
        torch.testing.assert_close(back, uv, atol=1e-9, rtol=0)

    @given(unit_vectors)
    def test_direction_uv_direction_round_trip(self, v):
        d = torch.tensor(v, dtype=F64)
        d = d / d.norm()
        uv = direction_to_mirror_ball(d)
        assert uv.square().sum().item() <= 1.0 + 1e-12
        back, valid = mirror_ball_to_direction(uv)
        # near -Z the map compresses a whole neighbourhood onto the rim: compare with a tolerance on the angle
        assert bool(valid) and torch.dot(back, d).item() > 1 - 1e-9

    def test_outside_disk_is_clamped(self):
        d, valid = mirror_ball_to_direction(torch.tensor([[1.0, 1.0]]))
        assert not bool(valid[0]) and torch.isfinite(d).all()

    def test_minus_z_maps_to_bottom_rim(self):
        torch.testing.assert_close(
            direction_to_mirror_ball(torch.tensor([0.0, 0.0, -1.0])), torch.tensor([0.0, -1.0])
        )

    def test_exception(self):
        with pytest.raises(ShapeError, match=r"uv must have shape \(\*, 2\)"):
            mirror_ball_to_direction(torch.zeros(4, 3))
        with pytest.raises(ShapeError, match=r"d must have shape \(\*, 3\)"):
            direction_to_mirror_ball(torch.zeros(4, 2))
        with pytest.raises(NonFiniteError, match="d must be finite"):
            direction_to_mirror_ball(torch.tensor([float("nan"), 0.0, 1.0]))

    def test_gradcheck(self):
        uv = torch.tensor([[0.1, 0.2], [-0.5, 0.3]], dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(lambda x: mirror_ball_to_direction(x)[0], (uv,))
        d = torch.tensor([[0.1, 0.2, 0.9], [-0.5, 0.3, 0.2]], dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(direction_to_mirror_ball, (d,))

    def test_dtypes(self, dtype):
        d, valid = mirror_ball_directions(8, dtype=dtype)
        assert d.dtype == dtype and valid.dtype == torch.bool and d.shape == (8, 8, 3)


class TestMirrorBallSolidAngles:
    @settings(max_examples=10)
    @given(st.integers(1, 128))
    def test_sum_is_four_pi(self, size):
        self.test_sum_is_four_pi_at_loss_scales(size)

    @pytest.mark.parametrize("size", [4, 8, 16, 32, 64])
    def test_sum_is_four_pi_at_loss_scales(self, size):
        omega = mirror_ball_solid_angles(size, dtype=F64)
        assert abs(omega.sum().item() / (4 * math.pi) - 1.0) < 1e-4
        assert bool((omega >= 0).all())
        assert bool((omega[~mirror_ball_valid(size)] == 0).all())

    @settings(max_examples=10)
    @given(st.integers(1, 128))
    def test_fully_inside_pixels(self, size):
        """docs/conventions.rst: every pixel whose square lies fully inside the disk spans exactly 16 / S^2 sr
        (slivers of invalid pixels go only to rim pixels, whose squares cross the circle)."""
        omega = mirror_ball_solid_angles(size, dtype=F64)
        edges = torch.linspace(-1, 1, size + 1, dtype=F64)
        far = torch.maximum(edges[:-1].abs(), edges[1:].abs())  # farthest |u| of each column
        inside = far[None, :].square() + far.flip(0)[:, None].square() <= 1.0
        if bool(inside.any()):
            torch.testing.assert_close(omega[inside], torch.full_like(omega[inside], 16.0 / size**2))

    @pytest.mark.parametrize("size", [3, 4, 5, 8, 16, 32, 33, 64])
    def test_symmetric(self, size):
        """Ties in the sliver split are shared equally, so the solid angles keep all 8 grid symmetries."""
        omega = mirror_ball_solid_angles(size, dtype=F64)
        for sym in (omega.flip(0), omega.flip(1), omega.T):
            torch.testing.assert_close(sym, omega, atol=1e-14, rtol=0)

    def test_spec_value_at_32(self):
        assert mirror_ball_solid_angles(32, dtype=F64)[16, 16].item() == 1 / 64


    def test_exception(self):
        with pytest.raises(ValueCheckError, match="size must be positive"):
            mirror_ball_solid_angles(-1)

    def test_dtypes(self, dtype):
        omega = mirror_ball_solid_angles(16, dtype=dtype)
        assert omega.dtype == dtype
        torch.testing.assert_close(
            omega.to(F64), mirror_ball_solid_angles(16, dtype=F64), atol=1e-7, rtol=1e-6
        )


class TestPixelCoordinates:
    @given(st.integers(1, 64), st.floats(-1, 1), st.floats(-1, 1))
    def test_round_trip(self, size, u, v):
        uv = torch.tensor([u, v], dtype=F64)
        torch.testing.assert_close(pixel_to_uv(uv_to_pixel(uv, size), size), uv, atol=1e-12, rtol=0)

    def test_centres_are_integers(self):
        px = uv_to_pixel(mirror_ball_uv(8, dtype=F64), 8)
        i, j = torch.meshgrid(torch.arange(8), torch.arange(8), indexing="ij")
        torch.testing.assert_close(px, torch.stack([j, i], -1).to(F64))


class TestMirrorBallPixelIndex:
    def test_smoke(self):
        idx = mirror_ball_pixel_index(torch.tensor([[0.0, 0.0], [0.99, 0.0], [0.0, -1.0]]), 4)
        assert idx.tolist() == [10, 11, 14]

    @given(st.integers(1, 64), disk_points)
    def test_owner_is_valid_and_near(self, size, point):
        r, az = point
        uv = torch.tensor([[r * math.cos(az), r * math.sin(az)]], dtype=F64)
        idx = mirror_ball_pixel_index(uv, size)
        valid = mirror_ball_valid(size).flatten()
        assert bool(valid[idx].all())
        px = uv_to_pixel(uv, size)[0]
        row, col = divmod(int(idx), size)
        assert abs(col - px[0].item()) <= 2.5 and abs(row - px[1].item()) <= 2.5
        own_row, own_col = round(px[1].item()), round(px[0].item())
        if 0 <= own_row < size and 0 <= own_col < size and bool(valid[own_row * size + own_col]):
            assert (row, col) == (own_row, own_col)  # inside a valid square: that square

    @pytest.mark.parametrize("size", [4, 8, 32])
    def test_partition_areas_are_the_solid_angles(self, size):
        """Counting the owners of a fine uv grid reproduces mirror_ball_solid_angles (dOmega = 4 du dv)."""
        n = 2048
        c = (torch.arange(n, dtype=F64) + 0.5) / n * 2 - 1
        vv, uu = torch.meshgrid(c, c, indexing="ij")
        uv = torch.stack([uu, vv], -1).reshape(-1, 2)
        uv = uv[uv.square().sum(-1) <= 1]
        counts = torch.bincount(mirror_ball_pixel_index(uv, size), minlength=size * size).to(F64)
        area = counts * 4 * (2 / n) ** 2
        omega = mirror_ball_solid_angles(size, dtype=F64).flatten()
        # measured: within 0.3 % of a pixel (16 / S^2); the grid resolves the rim to 1/1024 of the uv range
        torch.testing.assert_close(area, omega, atol=0.01 * 16 / size**2, rtol=0)

    def test_exception(self):
        with pytest.raises(ShapeError, match=r"uv must have shape \(\*, 2\)"):
            mirror_ball_pixel_index(torch.zeros(3), 4)
        with pytest.raises(NonFiniteError, match="uv must be finite"):
            mirror_ball_pixel_index(torch.tensor([float("inf"), 0.0]), 4)


class TestLightsLayout:
    def test_round_trip(self):
        x = torch.rand(2, 3, 8, 8)
        lights = mirror_ball_to_lights(x)
        assert lights.shape == (2, 64, 3)
        torch.testing.assert_close(lights[1, 8 * 2 + 5], x[1, :, 2, 5])
        torch.testing.assert_close(lights_to_mirror_ball(lights), x)

    def test_exception(self):
        with pytest.raises(ShapeError, match="lights must have N = S\\*S lights"):
            lights_to_mirror_ball(torch.zeros(1, 10, 3))
        with pytest.raises(ShapeError, match=r"x must have shape \(B, C, S, S\)"):
            mirror_ball_to_lights(torch.zeros(3, 8, 8))
