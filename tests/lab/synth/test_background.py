"""Tests of background rendering: camera geometry of docs/conventions.rst, rotation convention, tone
mapping."""

from __future__ import annotations

import math

import pytest
import torch

from kornia_ilum.core.errors import NonFiniteError, ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.geometry import latlong_directions
from kornia_ilum_lab.synth.background import (
    RenderBackground,
    axis_rotation,
    camera_rays,
    camera_rotation,
    render_background,
    sample_latlong,
)

F64 = torch.float64


def angle_deg(a: torch.Tensor, b: torch.Tensor) -> float:
    return math.degrees(math.acos(float((a / a.norm()) @ (b / b.norm())).__round__(15)))


def coloured_map(height: int = 32) -> torch.Tensor:
    """Red from the right (+X), green from the left (-X), blue from behind (+Z), bright sky above."""
    d = latlong_directions(height, dtype=F64)
    x, y, z = d.unbind(-1)
    env = torch.stack([x.clamp(min=0), (-x).clamp(min=0), z.clamp(min=0)]) + 0.01
    return env * (1.0 + 3.0 * (y > 0.3))


class TestCameraGeometry:
    def test_centre_sees_minus_z(self):
        rays = camera_rays((5, 7), 60.0, camera_rotation())
        torch.testing.assert_close(rays[2, 3], torch.tensor([0.0, 0.0, -1.0], dtype=F64))

    def test_right_edge_sees_half_fov_toward_plus_x(self):
        w, fov = 8, 70.0
        rays = camera_rays((1, w), fov, camera_rotation())
        focal = (w / 2) / math.tan(math.radians(fov / 2))
        right = rays[0, -1]  # pixel centre half a pixel inside the right edge
        assert right[0] > 0 and abs(right[1]) < 1e-12
        assert math.isclose(angle_deg(right, torch.tensor([0.0, 0.0, -1.0], dtype=F64)),
                            math.degrees(math.atan((w / 2 - 0.5) / focal)), rel_tol=1e-9)  # fmt: skip
        edge = camera_rays((1, 2 * w), fov, camera_rotation(), supersample=8)[0, -1]  # ~ at the edge itself
        assert abs(angle_deg(edge, torch.tensor([0.0, 0.0, -1.0], dtype=F64)) - fov / 2) < 0.5

    def test_top_sees_plus_y(self):
        rays = camera_rays((9, 9), 90.0, camera_rotation())
        top, bottom = rays[0, 4], rays[-1, 4]
        assert top[1] > 0.6 and bottom[1] < -0.6 and abs(top[0]) < 1e-12

    def test_rotation_convention(self):
        forward = torch.tensor([0.0, 0.0, -1.0], dtype=F64)
        left, up = torch.tensor([-1.0, 0.0, 0.0], dtype=F64), torch.tensor([0.0, 1.0, 0.0], dtype=F64)
        torch.testing.assert_close(camera_rotation(yaw_deg=90.0) @ forward, left)
        torch.testing.assert_close(camera_rotation(pitch_deg=90.0) @ forward, up)
        right = torch.tensor([1.0, 0.0, 0.0], dtype=F64)  # positive roll lifts the image's right side
        assert (camera_rotation(roll_deg=30.0) @ right)[1] > 0.49
        centre = camera_rays((3, 3), 60.0, camera_rotation(yaw_deg=90.0))[1, 1]
        torch.testing.assert_close(centre, torch.tensor([-1.0, 0.0, 0.0], dtype=F64))

    @pytest.mark.parametrize("axis", [0, 1, 2])
    def test_axis_rotation(self, axis):
        """Right-handed: +90 deg about an axis takes the next axis to the one after it (X -> Y -> Z -> X)."""
        r = axis_rotation(axis, 90.0)
        assert r.dtype == F64
        torch.testing.assert_close(r @ r.T, torch.eye(3, dtype=F64))
        torch.testing.assert_close(torch.linalg.det(r), torch.tensor(1.0, dtype=F64))
        e = torch.eye(3, dtype=F64)
        torch.testing.assert_close(r @ e[axis], e[axis])
        torch.testing.assert_close(r @ e[(axis + 1) % 3], e[(axis + 2) % 3])
        torch.testing.assert_close(axis_rotation(axis, 0.0), e)

    def test_camera_rotation_is_product_of_axis_rotations(self):
        expected = axis_rotation(1, 20.0) @ axis_rotation(0, -10.0) @ axis_rotation(2, 5.0)
        assert torch.equal(camera_rotation(yaw_deg=20.0, pitch_deg=-10.0, roll_deg=5.0), expected)

    @pytest.mark.parametrize("axis", [3, -1, 1.0, True, "y"])
    def test_axis_rotation_rejects_bad_axis(self, axis):
        with pytest.raises(ValueCheckError, match="axis must be 0, 1 or 2"):
            axis_rotation(axis, 10.0)


class TestSampleLatLong:
    def test_wraps_in_azimuth(self):
        env = torch.zeros(1, 4, 8, dtype=F64)
        env[0, :, 0], env[0, :, -1] = 1.0, 3.0  # the two columns beside the seam (behind, +Z)
        behind = torch.tensor([[0.0, -0.2, 1.0]], dtype=F64)
        torch.testing.assert_close(sample_latlong(env, behind), torch.tensor([[2.0]], dtype=F64))

    def test_pixel_centres_exact(self):
        env = torch.rand(3, 8, 16, dtype=F64)
        out = sample_latlong(env, latlong_directions(8, dtype=F64))
        torch.testing.assert_close(out, env)


class TestRenderBackground:
    def test_smoke(self):
        img = render_background(coloured_map(), size=(12, 16))
        assert img.dtype == torch.uint8 and img.shape == (3, 12, 16)

    def test_cardinality(self):
        assert render_background(torch.ones(3, 8, 16), size=(5, 9), fov_deg=120.0).shape == (3, 5, 9)
        assert RenderBackground(size=(2, 3))(torch.ones(3, 8, 16)).shape == (3, 2, 3)

    def test_views_the_right_directions(self):
        env = coloured_map()
        img = render_background(env, size=(16, 32), fov_deg=100.0, exposure=1.0).int()
        assert img[0, 8, -1] > img[1, 8, -1] + 50  # right edge: red (+X)
        assert img[1, 8, 0] > img[0, 8, 0] + 50  # left edge: green (-X)
        assert img[:, 0].sum() > img[:, -1].sum()  # top: the bright sky (+Y)
        back = render_background(env, size=(8, 8), yaw_deg=180.0, exposure=1.0).int()
        assert back[2, 4, 4] > 200 and back[0, 4, 4] < 50  # behind the camera: blue (+Z)
        left = render_background(env, size=(8, 8), yaw_deg=90.0, exposure=1.0).int()
        assert left[1, 4, 4] > 200 and left[0, 4, 4] < 50  # yaw +90: the centre sees -X (green)

    def test_roll_turns_the_horizon(self):
        env = coloured_map()
        view = dict(size=(32, 32), fov_deg=90.0, pitch_deg=30.0, exposure=1.0)
        level = render_background(env, **view).int().sum(0)
        rolled = render_background(env, roll_deg=30.0, **view).int().sum(0)
        assert torch.equal(level[:, 0], level[:, -1])  # level horizon: left and right columns alike
        assert not torch.equal(rolled[:, 0], rolled[:, -1])

    def test_auto_exposure_maps_median_to_grey(self):
        img = render_background(torch.full((3, 8, 16), 7.0), size=(4, 4))
        assert torch.all(img == 118)  # 0.18 -> sRGB 0.4614 -> 118
        black = render_background(torch.zeros(3, 8, 16), size=(2, 2))
        assert torch.all(black == 0)

    def test_exposure_clips(self):
        assert torch.all(render_background(torch.full((3, 8, 16), 2.0), size=(2, 2), exposure=1.0) == 255)

    def test_exception(self):
        env = torch.ones(3, 8, 16)
        with pytest.raises(ShapeError, match=r"latlong must have shape \(3, H, 2H\)"):
            render_background(torch.ones(3, 8, 8))
        with pytest.raises(ShapeError, match=r"latlong must have shape \(3, H, 2H\)"):
            render_background(torch.ones(1, 3, 8, 16))
        with pytest.raises(ValueCheckError, match="latlong must be non-negative"):
            render_background(-env)
        with pytest.raises(NonFiniteError, match="latlong must be finite"):
            render_background(env * math.nan)
        with pytest.raises(ValueCheckError, match=r"fov_deg must be in \(0, 180\)"):
            render_background(env, fov_deg=180.0)
        with pytest.raises(ValueCheckError, match="exposure must be None"):
            render_background(env, exposure=0.0)
        with pytest.raises(TypeCheckError, match=r"size must be a pair \(height, width\)"):
            render_background(env, size=64)
        with pytest.raises(ValueCheckError, match=r"size\[1\] \(width\) must be positive"):
            render_background(env, size=(4, 0))
        with pytest.raises(TypeCheckError, match="yaw_deg must be a number"):
            render_background(env, yaw_deg="left")

    def test_module_matches_functional(self):
        env = coloured_map().float()
        module = RenderBackground(size=(6, 10), fov_deg=75.0, yaw_deg=20.0, pitch_deg=-5.0, roll_deg=3.0)
        expected = render_background(
            env, size=(6, 10), fov_deg=75.0, yaw_deg=20.0, pitch_deg=-5.0, roll_deg=3.0
        )
        assert torch.equal(module(env), expected)

    @pytest.mark.parametrize("dtype", [torch.float16, torch.bfloat16, torch.float32])
    def test_dtypes(self, dtype):
        env = coloured_map()
        ref = render_background(env, size=(8, 12), yaw_deg=30.0).int()
        out = render_background(env.to(dtype), size=(8, 12), yaw_deg=30.0).int()
        tol = 1 if dtype == torch.float32 else 6  # 8-bit codes; half inputs are rounded first
        assert (out - ref).abs().max() <= tol
