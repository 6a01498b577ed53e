"""Tests of lighting rotation and horizontal flip (frame of docs/conventions.rst: light arriving *from* d)."""

from __future__ import annotations

import math

import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from kornia.geometry.conversions import axis_angle_to_rotation_matrix

from kornia_ilum.core.errors import NonFiniteError, ShapeError, ValueCheckError
from kornia_ilum.geometry import (
    FlipLightingHorizontal,
    RotateLighting,
    flip_lighting_horizontal,
    latlong_directions,
    latlong_solid_angles,
    mirror_ball_directions,
    mirror_ball_solid_angles,
    mirror_ball_valid,
    rotate_lighting,
)
from tests.conftest import TOL, assert_close_dtype

F64 = torch.float64
FLIP_X = torch.diag(torch.tensor([-1.0, 1.0, 1.0], dtype=F64))


def rotation(axis: tuple[float, float, float], degrees: float, dtype: torch.dtype = F64) -> torch.Tensor:
    a = torch.tensor(axis, dtype=F64)
    a = a / a.norm() * math.radians(degrees)
    return axis_angle_to_rotation_matrix(a[None])[0].to(dtype)


def grid(layout: str, size: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Pixel-centre directions, valid mask and solid angles of a grid, float64."""
    if layout == "mirror_ball":
        d, valid = mirror_ball_directions(size, dtype=F64)
        return d, valid, mirror_ball_solid_angles(size, dtype=F64)
    d = latlong_directions(size, dtype=F64)
    return d, torch.ones(d.shape[:2], dtype=torch.bool), latlong_solid_angles(size, dtype=F64)


def lighting_shape(layout: str, size: int, batch: int = 1, channels: int = 3) -> tuple[int, ...]:
    return (batch, channels, size, size) if layout == "mirror_ball" else (batch, channels, size, 2 * size)


def smooth_lighting(d: torch.Tensor) -> torch.Tensor:
    x, y, z = d.unbind(-1)
    return torch.stack([1 + 0.5 * y + 0.3 * x * z, 1 + 0.4 * x - 0.2 * y * y, 1.2 - 0.3 * z + 0.2 * x * y])


def energy(x: torch.Tensor, omega: torch.Tensor) -> torch.Tensor:
    return (x * omega.to(x.dtype)).sum((-2, -1))


TURN = rotation((0.3, 1.0, 0.2), 40.0)
LAYOUTS = [("mirror_ball", 16), ("latlong", 8)]


class TestRotateLighting:
    def test_smoke(self):
        out = rotate_lighting(torch.rand(1, 3, 16, 16), TURN.float())
        assert out.shape == (1, 3, 16, 16) and bool((out >= 0).all())
        assert bool((out[..., ~mirror_ball_valid(16)] == 0).all())

    @pytest.mark.parametrize("layout,size", LAYOUTS)
    def test_cardinality(self, layout, size):
        x = torch.rand(lighting_shape(layout, size, batch=3, channels=2), dtype=F64)
        assert rotate_lighting(x, TURN, layout).shape == x.shape
        per_map = torch.stack([TURN, TURN.T, torch.eye(3, dtype=F64)])
        out = rotate_lighting(x, per_map, layout)
        assert out.shape == x.shape
        torch.testing.assert_close(out[1], rotate_lighting(x[1:2], TURN.T, layout)[0])

    def test_exception(self):
        x = torch.rand(2, 3, 8, 8)
        with pytest.raises(ValueCheckError, match="rotation must be orthonormal"):
            rotate_lighting(x, 2 * torch.eye(3))
        with pytest.raises(ValueCheckError, match="rotation must be a proper rotation with det \\+1"):
            rotate_lighting(x, torch.diag(torch.tensor([-1.0, 1.0, 1.0])))
        with pytest.raises(ShapeError, match=r"rotation must have shape \(\*, 3, 3\)"):
            rotate_lighting(x, torch.eye(2))
        with pytest.raises(ShapeError, match=r"rotation must have shape \(3, 3\) or \(2, 3, 3\)"):
            rotate_lighting(x, torch.eye(3).expand(3, 3, 3))
        with pytest.raises(NonFiniteError, match="rotation must be finite"):
            rotate_lighting(x, torch.full((3, 3), float("nan")))
        with pytest.raises(ValueCheckError, match="layout must be one of"):
            rotate_lighting(x, torch.eye(3), layout="cube")
        with pytest.raises(ShapeError, match=r"lighting must have shape \(B, C, H, 2H\)"):
            rotate_lighting(x, torch.eye(3), layout="latlong")
        with pytest.raises(ValueCheckError, match="lighting must be non-negative"):
            rotate_lighting(-x, torch.eye(3))
        with pytest.raises(ValueCheckError, match="rotation must be orthonormal"):
            RotateLighting(torch.ones(3, 3))

    @pytest.mark.parametrize("layout,size", [("mirror_ball", 4), ("latlong", 2)])
    def test_gradcheck(self, layout, size):
        x = torch.rand(lighting_shape(layout, size, channels=2), dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(lambda t: rotate_lighting(t, TURN, layout), (x,), fast_mode=True)

    def test_module_matches_functional(self):
        x = torch.rand(2, 3, 8, 8)
        module = RotateLighting(TURN.float())
        assert "rotation" not in module.state_dict()  # a non-persistent buffer: follows .to(), not saved
        torch.testing.assert_close(module(x), rotate_lighting(x, TURN.float()))
        module = RotateLighting(TURN, layout="latlong").to(F64)
        env = torch.rand(2, 3, 4, 8, dtype=F64)
        torch.testing.assert_close(module(env), rotate_lighting(env, TURN, "latlong"))

    @pytest.mark.parametrize("dtype", [torch.float16, torch.bfloat16, torch.float32])
    def test_dtypes(self, dtype):
        x = torch.rand(2, 3, 8, 8).to(dtype)
        out = rotate_lighting(x, TURN.to(dtype) if dtype == torch.float32 else TURN.float(), "mirror_ball")
        assert out.dtype == dtype
        assert_close_dtype(out, rotate_lighting(x.to(F64), TURN), dtype)

    def test_compile(self):
        x = torch.rand(2, 3, 8, 8)
        rot = TURN.float()
        torch.testing.assert_close(
            torch.compile(rotate_lighting)(x, rot), rotate_lighting(x, rot), **TOL[torch.float32]
        )

    @pytest.mark.parametrize("layout,size", LAYOUTS + [("mirror_ball", 5)])
    def test_identity_is_a_no_op(self, layout, size):
        _, valid, _ = grid(layout, size)
        x = torch.rand(lighting_shape(layout, size, batch=2), dtype=F64) * valid
        torch.testing.assert_close(
            rotate_lighting(x, torch.eye(3, dtype=F64), layout), x, atol=1e-12, rtol=1e-12
        )

    @settings(max_examples=10)
    @given(
        st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)).filter(
            lambda a: sum(c * c for c in a) > 0.01
        ),
        st.floats(-180, 180),
        st.sampled_from(LAYOUTS),
    )
    def test_energy_conserved(self, axis, degrees, layout_size):
        layout, size = layout_size
        _, valid, omega = grid(layout, size)
        x = torch.rand(lighting_shape(layout, size, batch=2), dtype=F64) ** 4 * valid
        out = rotate_lighting(x, rotation(axis, degrees), layout)
        torch.testing.assert_close(energy(out, omega), energy(x, omega), rtol=1e-12, atol=0)

    def test_spec_semantics(self):
        """+90 degrees about +Y (R(-Z) = -X): light from straight ahead then arrives from the left."""
        r = rotation((0.0, 1.0, 0.0), 90.0)
        torch.testing.assert_close(
            r @ torch.tensor([0.0, 0.0, -1.0], dtype=F64), torch.tensor([-1.0, 0.0, 0.0], dtype=F64)
        )
        d = latlong_directions(16, dtype=F64)
        env = torch.zeros(1, 1, 16, 32, dtype=F64)
        env[0, 0, 7:9, 15:17] = 1.0  # around -Z
        out = rotate_lighting(env, r, "latlong")
        centroid = (out[0, 0, ..., None] * latlong_solid_angles(16, dtype=F64)[..., None] * d).sum((0, 1))
        centroid = centroid / centroid.norm()
        assert centroid[0].item() < -0.999  # -X: the left half of the map

    @pytest.mark.parametrize("layout,size", [("mirror_ball", 32), ("latlong", 32)])
    @pytest.mark.parametrize("pixel", [(9, 20), (20, 7), (16, 16)])
    def test_sun_moves_to_r_d(self, layout, size, pixel):
        """A one-pixel sun keeps its energy and lands around R d: its centroid is within a tenth of a pixel
        of R d (measured at most 0.72 degree for 7-degree pixels), and at least 96.6 % of it (measured) in
        the four pixels nearest R d."""
        d, valid, omega = grid(layout, size)
        x = torch.zeros(lighting_shape(layout, size, channels=1), dtype=F64)
        x[0, 0, pixel[0], pixel[1]] = 1000.0
        out = rotate_lighting(x, TURN, layout)
        e = out[0, 0] * omega
        torch.testing.assert_close(e.sum(), (x[0, 0] * omega).sum(), rtol=1e-12, atol=0)
        target = TURN @ d[pixel]
        centroid = (e[..., None] * d).sum((0, 1))
        angle = math.degrees(math.acos(min(1.0, (centroid / centroid.norm() @ target).item())))
        pixel_deg = math.degrees(math.sqrt(omega[pixel].item()))
        assert angle < 0.15 * pixel_deg
        near = torch.topk((d @ target).flatten().masked_fill(~valid.flatten(), -2), 4).indices
        assert e.flatten()[near].sum().item() > 0.95 * e.sum().item()

    @pytest.mark.parametrize("layout,size", [("mirror_ball", 32), ("latlong", 16)])
    def test_rotation_matches_the_rotated_function(self, layout, size):
        """L'(d) = L(R^T d) for a smooth map, relative error of the worst channel. Measured: solid-angle-
        weighted mean 0.80 % (mirror ball 32), 0.44 % (lat-long 16); worst pixel 4.0 % / 4.3 % for
        z > -0.5, 11.6 % at the mirror-ball rim (its long rim pixels average over some 30 degrees)."""
        d, valid, omega = grid(layout, size)
        x = smooth_lighting(d)[None] * valid
        out = rotate_lighting(x, TURN, layout)
        expected = smooth_lighting(d @ TURN)[None] * valid  # row vectors: d @ R is (R^T d)^T
        rel = ((out - expected).abs() / expected.clamp(min=1e-12))[0].amax(0)
        assert ((rel * omega).sum() / omega.sum()).item() < 0.011
        assert rel[valid & (d[..., 2] > -0.5)].max().item() < 0.055
        assert rel[valid].max().item() < 0.15

    @pytest.mark.parametrize("layout,size", [("mirror_ball", 32), ("latlong", 16)])
    def test_rotate_and_back(self, layout, size):
        """R then R^T returns a smooth map. Measured (worst channel): solid-angle-weighted mean 1.15 %
        (mirror ball 32), 0.56 % (lat-long 16); worst pixel 4.1 % / 4.6 % for z > -0.5."""
        d, valid, omega = grid(layout, size)
        x = smooth_lighting(d)[None] * valid
        back = rotate_lighting(rotate_lighting(x, TURN, layout), TURN.T, layout)
        rel = ((back - x).abs() / x.clamp(min=1e-12))[0].amax(0)
        assert ((rel * omega).sum() / omega.sum()).item() < 0.015
        assert rel[valid & (d[..., 2] > -0.5)].max().item() < 0.06

    def test_constant_stays_constant(self):
        """Measured worst pixel 1.26 % (mirror ball 32), 0.30 % (lat-long 32) for this one turn."""
        for layout, size in (("mirror_ball", 32), ("latlong", 32)):
            _, valid, _ = grid(layout, size)
            out = rotate_lighting(
                torch.ones(lighting_shape(layout, size, channels=1), dtype=F64) * valid, TURN, layout
            )
            assert (out[0, 0][valid] - 1).abs().max().item() < 0.017

    @settings(max_examples=25, deadline=None)
    @given(st.floats(-180, 180), st.floats(-90, 90))
    def test_constant_stays_constant_to_the_documented_bounds(self, yaw, pitch):
        """The docstring's numbers: mean error at most 0.3 %, any rim pixel at most 7.2 % (worst on a 15-degree
        grid of yaws and pitches; 4.5 % at yaw 37, pitch 21)."""
        _, valid, _ = grid("mirror_ball", 32)
        turn = rotation((1.0, 0.0, 0.0), pitch) @ rotation((0.0, 1.0, 0.0), yaw)
        out = rotate_lighting(torch.ones(1, 1, 32, 32, dtype=F64) * valid, turn)
        err = (out[0, 0][valid] - 1).abs()
        assert err.mean().item() < 0.003 and err.max().item() < 0.08


class TestFlipLightingHorizontal:
    def test_smoke(self):
        x = torch.rand(1, 3, 8, 8)
        torch.testing.assert_close(flip_lighting_horizontal(x), x.flip(-1))

    @pytest.mark.parametrize("layout,size", LAYOUTS)
    def test_cardinality(self, layout, size):
        x = torch.rand(lighting_shape(layout, size, batch=2))
        assert flip_lighting_horizontal(x, layout).shape == x.shape

    def test_exception(self):
        with pytest.raises(ShapeError, match=r"lighting must have shape \(B, C, S, S\)"):
            flip_lighting_horizontal(torch.rand(1, 3, 4, 8))
        with pytest.raises(ShapeError, match=r"lighting must have shape \(B, C, H, 2H\)"):
            flip_lighting_horizontal(torch.rand(1, 3, 4, 4), "latlong")
        with pytest.raises(ValueCheckError, match="layout must be one of"):
            FlipLightingHorizontal("equirect")
        with pytest.raises(NonFiniteError, match="lighting must be finite"):
            flip_lighting_horizontal(torch.full((1, 1, 4, 4), float("nan")))
        with pytest.raises(ValueCheckError, match="lighting must be non-negative"):
            flip_lighting_horizontal(-torch.ones(1, 1, 4, 4))

    def test_gradcheck(self):
        x = torch.rand(1, 2, 4, 4, dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(flip_lighting_horizontal, (x,))

    def test_module_matches_functional(self):
        x = torch.rand(2, 3, 4, 8)
        torch.testing.assert_close(
            FlipLightingHorizontal("latlong")(x), flip_lighting_horizontal(x, "latlong")
        )

    @pytest.mark.parametrize("dtype", [torch.float16, torch.bfloat16, torch.float32])
    def test_dtypes(self, dtype):
        x = torch.rand(2, 3, 8, 8).to(dtype)
        out = flip_lighting_horizontal(x)
        assert out.dtype == dtype
        assert_close_dtype(out, flip_lighting_horizontal(x.to(F64)), dtype)

    def test_compile(self):
        x = torch.rand(2, 3, 8, 8)
        torch.testing.assert_close(torch.compile(flip_lighting_horizontal)(x), flip_lighting_horizontal(x))

    @pytest.mark.parametrize("layout,size", LAYOUTS + [("mirror_ball", 7), ("latlong", 5)])
    def test_twice_is_identity(self, layout, size):
        x = torch.rand(lighting_shape(layout, size))
        assert torch.equal(flip_lighting_horizontal(flip_lighting_horizontal(x, layout), layout), x)

    @pytest.mark.parametrize(
        "layout,size", [("mirror_ball", 32), ("mirror_ball", 7), ("latlong", 16), ("latlong", 3)]
    )
    def test_negates_x(self, layout, size):
        """Column j of the flipped grid looks along the direction of column W-1-j with x negated, so
        flipping samples L(-x, y, z): the pixel-centre values of any function are mapped exactly."""
        d, valid, _ = grid(layout, size)
        torch.testing.assert_close(d.flip(1), d @ FLIP_X, atol=1e-12, rtol=0)
        assert torch.equal(valid.flip(1), valid)
        x = smooth_lighting(d)[None] * valid
        expected = smooth_lighting(d @ FLIP_X)[None] * valid
        torch.testing.assert_close(flip_lighting_horizontal(x, layout), expected, atol=1e-12, rtol=0)

    @pytest.mark.parametrize("layout,size", [("mirror_ball", 16), ("latlong", 8)])
    def test_conjugates_rotations(self, layout, size):
        """flip(rotate(L, R)) = rotate(flip(L), F R F) with F = diag(-1, 1, 1): the flip is the reflection
        x -> -x of the directions, the same maths as rotate_lighting."""
        _, valid, omega = grid(layout, size)
        x = torch.rand(lighting_shape(layout, size, batch=2), dtype=F64) * valid
        left = flip_lighting_horizontal(rotate_lighting(x, TURN, layout), layout)
        right = rotate_lighting(flip_lighting_horizontal(x, layout), FLIP_X @ TURN @ FLIP_X, layout)
        torch.testing.assert_close(left, right, atol=1e-9, rtol=1e-9)
        torch.testing.assert_close(energy(flip_lighting_horizontal(x, layout), omega), energy(x, omega))
