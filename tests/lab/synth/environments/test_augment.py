"""Tests of environment augmentation: energy-conserving rotation, flip, exposure, white balance
(docs/conventions.rst)."""

from __future__ import annotations

import json
import math

import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from kornia_ilum.core.errors import NonFiniteError, ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.geometry import (
    direction_to_mirror_ball,
    flip_lighting_horizontal,
    latlong_directions,
    latlong_solid_angles,
    latlong_to_mirror_ball,
    mirror_ball_pixel_index,
    mirror_ball_solid_angles,
    rotate_lighting,
)
from kornia_ilum_lab.synth.environments import (
    Augment,
    Environment,
    HDRFolderSource,
    lighting_rotation,
    rotate_latlong,
    white_balance_gains,
)
from kornia_ilum_lab.synth.environments.augment import REFERENCE_KELVIN, RotateLatLong, weighted_quantile
from kornia_ilum_lab.synth.environments.sky import cct_to_rgb
from kornia_ilum_lab.synth.stats import cct_mccamy
from tests.conftest import TOL

F64 = torch.float64
LUMA = torch.tensor([0.212671, 0.715160, 0.072169], dtype=F64)


def energy(x: torch.Tensor, omega: torch.Tensor) -> torch.Tensor:
    return (x.double() * omega.double()).sum((-2, -1))


def sun_map(height: int, row: int, col: int, sun: float = 1e4, sky: float = 0.1) -> torch.Tensor:
    env = torch.full((3, height, 2 * height), sky, dtype=F64)
    env[:, 2 * height // 3 :, :] *= 0.3  # darker ground
    env[:, row, col] = sun
    return env


def make_env(latlong: torch.Tensor) -> Environment:
    ball = latlong_to_mirror_ball(latlong[None], 32, mode="area")[0]
    return Environment(latlong, ball, "outdoor", "test", {"origin": "unit test"})


def centroid(latlong: torch.Tensor, frac: float = 0.01) -> torch.Tensor:
    """Energy-weighted mean direction of the pixels above ``frac`` of the peak."""
    h = latlong.shape[-2]
    e = latlong.sum(0).double() * latlong_solid_angles(h, dtype=F64)
    w = torch.where(e > frac * e.max(), e, torch.zeros_like(e))
    c = (w[..., None] * latlong_directions(h, dtype=F64)).sum((0, 1))
    return c / c.norm()


def angle_deg(a: torch.Tensor, b: torch.Tensor) -> float:
    return math.degrees(math.acos(float((a @ b).clamp(-1, 1))))


class TestRotateLatLong:
    def test_smoke(self):
        out = rotate_latlong(torch.rand(3, 8, 16), lighting_rotation(30.0, 10.0))
        assert out.shape == (3, 8, 16) and (out >= 0).all()

    def test_cardinality(self):
        assert rotate_latlong(torch.rand(1, 4, 8), lighting_rotation(10.0)).shape == (1, 4, 8)
        assert rotate_latlong(torch.rand(5, 6, 12), lighting_rotation(0.0, 20.0)).shape == (5, 6, 12)

    def test_exception(self):
        with pytest.raises(ShapeError, match=r"latlong must have shape \(C, H, 2H\)"):
            rotate_latlong(torch.rand(3, 4, 4), torch.eye(3))
        with pytest.raises(ShapeError, match=r"rotation must have shape \(3, 3\)"):
            rotate_latlong(torch.rand(3, 4, 8), torch.eye(4))
        with pytest.raises(ValueCheckError, match="latlong must be non-negative"):
            rotate_latlong(-torch.ones(3, 4, 8), torch.eye(3))
        with pytest.raises(NonFiniteError, match="latlong must be finite"):
            rotate_latlong(torch.full((3, 4, 8), math.inf), torch.eye(3))

    def test_identity(self):
        x = torch.rand(3, 8, 16)
        assert torch.equal(rotate_latlong(x, torch.eye(3)), x)

    @given(yaw=st.floats(0, 360), pitch=st.floats(-30, 30), seed=st.integers(0, 50))
    def test_energy_conserved(self, yaw, pitch, seed):
        g = torch.Generator().manual_seed(seed)
        x = torch.rand(3, 16, 32, generator=g, dtype=F64) ** 4
        x[:, int(torch.randint(16, (1,), generator=g)), int(torch.randint(32, (1,), generator=g))] = 1e5
        out = rotate_latlong(x, lighting_rotation(yaw, pitch))
        omega = latlong_solid_angles(16, dtype=F64)
        torch.testing.assert_close(energy(out, omega), energy(x, omega), rtol=1e-10, atol=0)
        assert out.min() >= 0

    def test_constant_stays_constant(self):
        out = rotate_latlong(torch.full((3, 24, 48), 0.7, dtype=F64), lighting_rotation(123.0, -27.0))
        torch.testing.assert_close(out, torch.full_like(out, 0.7))

    @pytest.mark.parametrize("yaw,pitch", [(90.0, 0.0), (37.0, 21.0), (200.0, -28.0)])
    def test_sun_moves_to_rotated_direction(self, yaw, pitch):
        x = sun_map(32, 11, 45)
        rot = lighting_rotation(yaw, pitch)
        d = latlong_directions(32, dtype=F64)[11, 45]
        assert angle_deg(centroid(rotate_latlong(x, rot)), rot @ d) < 0.1

    def test_yaw_convention(self):
        """docs/conventions.rst / rotate_lighting: +90 deg about +Y moves light from straight ahead (-Z) to
        the left (-X)."""
        rot = lighting_rotation(yaw_deg=90.0)
        forward, left = torch.tensor([0.0, 0.0, -1.0], dtype=F64), torch.tensor([-1.0, 0.0, 0.0], dtype=F64)
        torch.testing.assert_close(rot @ forward, left)
        x = sun_map(16, 7, 16)  # just above the horizon, just right of forward
        assert centroid(rotate_latlong(x, rot))[0] < -0.95

    def test_close_to_rotate_lighting(self):
        """The library's area rotation (exact, slow) and the fast one agree: smooth parts and sun position."""
        d = latlong_directions(32, dtype=F64)
        x = (1.0 + 0.6 * d[..., 1] + 0.3 * d[..., 0] * d[..., 2]).expand(3, -1, -1).clone()
        x[:, 10, 40] = 3e3
        x = x.float()
        rot = lighting_rotation(70.0, 25.0)
        fast, exact = rotate_latlong(x, rot), rotate_lighting(x[None], rot.float(), "latlong")[0]
        assert angle_deg(centroid(fast, 0.05), centroid(exact, 0.05)) < 1.0
        smooth = (fast - exact).abs() < 0.5  # away from the sun
        assert smooth.float().mean() > 0.99
        assert ((fast - exact).abs()[smooth].mean() / exact[smooth].mean()) < 0.02

    def test_gradcheck(self):
        x = (torch.rand(1, 4, 8, dtype=F64) + 0.5).requires_grad_()
        assert torch.autograd.gradcheck(lambda t: rotate_latlong(t, lighting_rotation(40.0, 15.0)), (x,))

    def test_module_matches_functional(self):
        x, rot = torch.rand(3, 8, 16), lighting_rotation(20.0, 5.0)
        torch.testing.assert_close(RotateLatLong(rot)(x), rotate_latlong(x, rot))

    @pytest.mark.parametrize("dtype", [torch.float16, torch.bfloat16, torch.float32])
    def test_dtypes(self, dtype):
        x, rot = torch.rand(3, 8, 16, dtype=F64) + 0.1, lighting_rotation(50.0, -12.0)
        out = rotate_latlong(x.to(dtype), rot)
        assert out.dtype == dtype
        tol = {k: 2 * v for k, v in TOL[dtype].items()}
        torch.testing.assert_close(out.double(), rotate_latlong(x, rot), **tol)

    def test_compile(self):
        x, rot = torch.rand(3, 4, 8) + 0.1, lighting_rotation(30.0, 10.0)
        compiled = torch.compile(rotate_latlong)
        torch.testing.assert_close(compiled(x, rot), rotate_latlong(x, rot), **TOL[torch.float32])


class TestWhiteBalance:
    def test_reference_is_neutral(self):
        torch.testing.assert_close(white_balance_gains(REFERENCE_KELVIN), torch.ones(3, dtype=F64))

    @pytest.mark.parametrize("kelvin", [2500.0, 4000.0, 9000.0, 15000.0])
    @pytest.mark.parametrize("tint", [-0.25, 0.0, 0.25])
    def test_luminance_kept(self, kelvin, tint):
        assert abs(float(white_balance_gains(kelvin, tint) @ LUMA) - 1.0) < 1e-12

    def test_warm_cool_tint(self):
        warm, cool = white_balance_gains(3000.0), white_balance_gains(12000.0)
        assert warm[0] > 1 > warm[2] and cool[2] > 1 > cool[0]
        magenta, green = white_balance_gains(6500.0, 0.25), white_balance_gains(6500.0, -0.25)
        assert magenta[1] < 1 < green[1]

    @pytest.mark.parametrize("kelvin", [3000.0, 4000.0, 5000.0, 8000.0])
    def test_shifts_colour_temperature(self, kelvin):
        """White light (~6500 K) shifted to T measures close to T with McCamy's formula."""
        neutral = cct_to_rgb(torch.tensor(REFERENCE_KELVIN, dtype=F64))
        assert abs(cct_mccamy(neutral * white_balance_gains(kelvin)) - kelvin) / kelvin < 0.02

    def test_exception(self):
        with pytest.raises(ValueCheckError, match=r"kelvin must be a number in \[1000, 40000\] K"):
            white_balance_gains(500.0)
        with pytest.raises(ValueCheckError, match="tint must be a finite number of stops"):
            white_balance_gains(5000.0, math.nan)


class TestAugment:
    def test_smoke(self):
        env = make_env(sun_map(16, 5, 9).float())
        out = Augment()(env, torch.Generator().manual_seed(0))
        assert out.latlong.shape == env.latlong.shape and out.mirror_ball.shape == (3, 32, 32)
        assert out.params["origin"] == "unit test" and "augment" not in env.params
        json.dumps(out.params)  # JSON-serialisable

    def test_reproducible_and_recorded(self):
        env = make_env(sun_map(16, 5, 9).float())
        a = Augment()(env, torch.Generator().manual_seed(3))
        b = Augment()(env, torch.Generator().manual_seed(3))
        c = Augment()(env, torch.Generator().manual_seed(4))
        assert torch.equal(a.latlong, b.latlong) and torch.equal(a.mirror_ball, b.mirror_ball)
        assert a.params == b.params != c.params
        p = a.params["augment"]
        assert 0 <= p["yaw_deg"] < 360 and abs(p["pitch_deg"]) <= 30 and -2 <= p["exposure_stops"] <= 2
        assert 4000 <= p["kelvin"] <= 40000 and -0.25 <= p["tint"] <= 0.25
        keys = ("yaw_deg", "pitch_deg", "flip", "exposure_stops", "kelvin", "tint")
        again = Augment.apply(env, **{k: p[k] for k in keys})
        assert torch.equal(again.latlong, a.latlong)

    def test_draws_cover_ranges(self):
        draws = [Augment().draw(torch.Generator().manual_seed(s)) for s in range(200)]
        assert 0.35 < sum(d["flip"] for d in draws) / 200 < 0.65
        assert min(d["pitch_deg"] for d in draws) < -25 and max(d["pitch_deg"] for d in draws) > 25
        assert min(d["kelvin"] for d in draws) < 4300 and max(d["kelvin"] for d in draws) > 20000
        mireds = torch.tensor([1e6 / d["kelvin"] for d in draws])
        assert abs(float(mireds.median()) - 137.5) < 15  # uniform in mired over [25, 250]

    def test_disabled_is_identity(self):
        env = make_env(sun_map(16, 5, 9).float())
        off = Augment(yaw=False, pitch_deg=0.0, flip=False, exposure_stops=None, white_balance=False)
        out = off(env, torch.Generator().manual_seed(1))
        torch.testing.assert_close(out.latlong, env.latlong, rtol=1e-6, atol=0)
        torch.testing.assert_close(out.mirror_ball, env.mirror_ball, rtol=1e-6, atol=1e-9)

    def test_switching_one_off_keeps_the_others(self):
        g = lambda: torch.Generator().manual_seed(9)  # noqa: E731
        full, no_flip = Augment().draw(g()), Augment(flip=False).draw(g())
        full.pop("flip"), no_flip.pop("flip")
        assert full == no_flip

    def test_camera_anchored_is_not_turned(self):
        """Lights placed relative to the camera (the portrait lights) keep their place: no yaw, no pitch; the
        other draws are those of any environment."""
        env = make_env(sun_map(16, 5, 9))
        anchored = Environment(env.latlong, env.mirror_ball, env.label, env.source, {"camera_anchored": True})
        out = Augment()(anchored, torch.Generator().manual_seed(3))
        free = Augment()(env, torch.Generator().manual_seed(3))
        assert out.params["augment"]["yaw_deg"] == out.params["augment"]["pitch_deg"] == 0.0
        assert free.params["augment"]["yaw_deg"] != 0.0
        for key in ("flip", "exposure_stops", "kelvin", "tint"):
            assert out.params["augment"][key] == free.params["augment"][key]
        kept = {k: free.params["augment"][k] for k in ("flip", "exposure_stops", "kelvin", "tint")}
        expected = Augment.apply(env, **kept)
        torch.testing.assert_close(out.latlong, expected.latlong)

    def test_exposure_scales_energy(self):
        env = make_env(sun_map(16, 5, 9))
        out = Augment.apply(env, exposure_stops=1.5)
        torch.testing.assert_close(out.latlong, env.latlong * 2**1.5)
        torch.testing.assert_close(out.mirror_ball, env.mirror_ball * 2**1.5)

    def test_flip_is_spec_flip(self):
        env = make_env(sun_map(16, 5, 9))
        out = Augment.apply(env, flip=True)
        torch.testing.assert_close(out.latlong, flip_lighting_horizontal(env.latlong[None], "latlong")[0])
        flipped_ball = flip_lighting_horizontal(env.mirror_ball[None], "mirror_ball")[0]
        torch.testing.assert_close(out.mirror_ball, flipped_ball, rtol=1e-6, atol=1e-9)
        assert out.params["augment"]["direction_map"][0][0] == -1.0

    @pytest.mark.parametrize("yaw,pitch,flip", [(90.0, 0.0, False), (37.0, 21.0, True), (250.0, -28.0, True)])
    def test_rotation_and_flip_consistent_with_spec(self, yaw, pitch, flip):
        """A sun from d ends at M d = F R d in the lat-long map and in the mirror ball; energy is kept."""
        x = sun_map(32, 9, 44)
        d = latlong_directions(32, dtype=F64)[9, 44]
        out = Augment.apply(make_env(x), yaw_deg=yaw, pitch_deg=pitch, flip=flip)
        m = torch.tensor(out.params["augment"]["direction_map"], dtype=F64)
        want = m @ d
        assert angle_deg(centroid(out.latlong), want) < 0.1
        owner = int(mirror_ball_pixel_index(direction_to_mirror_ball(want), 32))
        assert int(out.mirror_ball.sum(0).flatten().argmax()) == owner
        e_in = energy(x, latlong_solid_angles(32, dtype=F64))
        torch.testing.assert_close(energy(out.latlong, latlong_solid_angles(32, dtype=F64)), e_in)
        e_ball = energy(out.mirror_ball, mirror_ball_solid_angles(32, dtype=F64))
        torch.testing.assert_close(e_ball, e_in, rtol=1e-6, atol=0)

    def test_exception(self):
        with pytest.raises(ValueCheckError, match=r"pitch_deg must be in \[0, 90\]"):
            Augment(pitch_deg=120.0)
        with pytest.raises(ValueCheckError, match="exposure_stops must satisfy"):
            Augment(exposure_stops=(2.0, -2.0))
        with pytest.raises(ValueCheckError, match="kelvin must satisfy"):
            Augment(kelvin=(500.0, 6000.0))
        with pytest.raises(TypeCheckError, match="tint must be a pair"):
            Augment(tint=0.2)
        with pytest.raises(TypeCheckError, match="generator must be a torch.Generator"):
            Augment()(make_env(torch.ones(3, 4, 8)), 42)
        with pytest.raises(TypeCheckError, match="env must be an Environment"):
            Augment.apply(torch.ones(3, 4, 8))


@pytest.mark.parametrize("name", ["pedestrian_overpass_1k.hdr", "interior.exr"])
def test_real_map_augmentation_consistent(shared_data, name):
    """On real maps: the sun's pixel moves to M d in both layouts, energy (over the gains) is kept to 1e-3."""
    source = HDRFolderSource(shared_data / "hdri")
    env = source.environment(source.names.index(name))
    lum = torch.einsum("chw,c->hw", env.latlong.double(), LUMA)
    k = int(lum.flatten().argmax())
    d = latlong_directions(128, dtype=F64)[k // 256, k % 256]
    out = Augment()(env, torch.Generator().manual_seed(11))
    p = out.params["augment"]
    want = torch.tensor(p["direction_map"], dtype=F64) @ d
    lum_out = torch.einsum("chw,c->hw", out.latlong.double(), LUMA)
    k_out = int(lum_out.flatten().argmax())
    assert angle_deg(latlong_directions(128, dtype=F64)[k_out // 256, k_out % 256], want) < 2.0
    owner = int(mirror_ball_pixel_index(direction_to_mirror_ball(want), 32))
    ball_lum = torch.einsum("chw,c->hw", out.mirror_ball.double(), LUMA)
    assert int(ball_lum.flatten().argmax()) == owner
    gains = torch.tensor(p["gains"], dtype=F64)
    e_in = energy(env.latlong, latlong_solid_angles(128, dtype=F64)) * gains
    assert ((energy(out.latlong, latlong_solid_angles(128, dtype=F64)) - e_in).abs() / e_in).max() < 1e-5
    e_ball = energy(out.mirror_ball, mirror_ball_solid_angles(32, dtype=F64))
    assert ((e_ball - e_in).abs() / e_in).max() < 1e-3


def test_white_balance_keeps_median_colour_temperature(shared_data):
    """The default shifts balance warm and cool on the real maps (module docstring): within 10 mired."""
    source = HDRFolderSource(shared_data / "hdri", height=32)
    omega = mirror_ball_solid_angles(32, dtype=F64)
    means = [(source.environment(i).mirror_ball.double() * omega).sum((1, 2)) for i in range(len(source))]
    captured = torch.tensor([1e6 / cct_mccamy(m) for m in means]).median()
    shifted = []
    for seed in range(100):
        p = Augment().draw(torch.Generator().manual_seed(seed))
        gains = white_balance_gains(p["kelvin"], p["tint"])
        shifted += [1e6 / cct_mccamy(m * gains) for m in means]
    assert abs(float(torch.tensor(shifted).median()) - float(captured)) < 10.0


def test_weighted_quantile():
    v, w = torch.tensor([4.0, 1.0, 3.0, 2.0]), torch.tensor([1.0, 1.0, 1.0, 1.0])
    assert float(weighted_quantile(v, w, 0.5)) == 2.0 and float(weighted_quantile(v, w, 1.0)) == 4.0
    assert float(weighted_quantile(v, torch.tensor([0.0, 0.0, 0.0, 1.0]), 0.01)) == 2.0
