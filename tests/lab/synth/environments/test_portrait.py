"""Tests of the portrait lights: flash, studio, window and street; shares, ratios, energy, determinism."""

from __future__ import annotations

import json
import math

import pytest
import torch

from kornia_ilum.core.errors import TypeCheckError, ValueCheckError
from kornia_ilum.geometry import latlong_directions, latlong_solid_angles
from kornia_ilum_lab.synth.environments import (
    Augment,
    EnvironmentSampler,
    EnvironmentSource,
    PortraitLightSource,
    key_direction,
    render_portrait,
)
from kornia_ilum_lab.synth.environments.portrait import (
    AMBIENT_RATIOS,
    PORTRAIT_KIND_WEIGHTS,
    PORTRAIT_KINDS,
    PORTRAIT_SHARE,
)

LUMA = torch.tensor([0.2126729, 0.7151522, 0.0721750], dtype=torch.float64)


def gen(seed: int) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


def irradiance(latlong: torch.Tensor, normal: torch.Tensor) -> float:
    """Luminance irradiance of a map on a surface facing ``normal``, on the grid."""
    h = latlong.shape[-2]
    d = latlong_directions(h, dtype=torch.float64).reshape(-1, 3)
    om = latlong_solid_angles(h, dtype=torch.float64).reshape(-1)
    lum = LUMA @ latlong.double().reshape(3, -1)
    return float((lum * om * (d @ normal.double()).clamp(min=0.0)).sum())


def energy(latlong: torch.Tensor) -> torch.Tensor:
    """``sum(L Omega)`` per channel, float64."""
    om = latlong_solid_angles(latlong.shape[-2], dtype=torch.float64)
    return (latlong.double() * om).sum((-2, -1))


def params_of(kind: str, count: int, start: int = 0) -> list[dict]:
    source = PortraitLightSource((kind,))
    return [source.sample_params(gen(start + s)) for s in range(count)]


class TestPortraitLightSource:
    @pytest.mark.parametrize("kind", PORTRAIT_KINDS)
    def test_deterministic_finite_nonnegative_labelled(self, kind):
        source = PortraitLightSource((kind,), height=32)
        for seed in range(3):
            a, b = source.sample(gen(seed)), source.sample(gen(seed))
            assert torch.equal(a.latlong, b.latlong) and torch.equal(a.mirror_ball, b.mirror_ball)
            assert a.params == b.params and a.source == f"portrait:{kind}"
            assert a.latlong.shape == (3, 32, 64) and a.mirror_ball.shape == (3, 32, 32)
            assert a.latlong.dtype == torch.float32
            assert bool(a.latlong.isfinite().all()) and bool(a.mirror_ball.isfinite().all())
            assert float(a.latlong.min()) >= 0.0 and float(a.mirror_ball.min()) >= 0.0
            assert float(a.latlong.sum()) > 0.0
            assert a.label == ("outdoor" if kind == "street" else "indoor")
            assert a.params["camera_anchored"] is (kind != "street")
            json.dumps(a.params)  # JSON-serialisable
        other = source.sample(gen(99))
        assert not torch.equal(other.latlong, source.sample(gen(0)).latlong)

    def test_protocol_and_defaults(self):
        source = PortraitLightSource()
        assert isinstance(source, EnvironmentSource)
        assert source.label == "indoor" and source.default_share == PORTRAIT_SHARE == 0.25
        assert source.kinds == PORTRAIT_KINDS and source.weights == PORTRAIT_KIND_WEIGHTS
        assert sum(PORTRAIT_KIND_WEIGHTS) == pytest.approx(1.0)
        assert "PortraitLightSource(" in repr(source)

    @pytest.mark.slow
    def test_kinds_appear_with_their_share(self):
        """600 draws: each kind within 6 points of its share (over 4 standard deviations)."""
        source = PortraitLightSource()
        kinds = [source.sample_params(gen(s))["kind"] for s in range(600)]
        for kind, share in zip(PORTRAIT_KINDS, PORTRAIT_KIND_WEIGHTS, strict=True):
            assert abs(kinds.count(kind) / 600 - share) < 0.06, (kind, kinds.count(kind))
        only = PortraitLightSource(("flash", "street"), weights=(0.0, 1.0))
        assert {only.sample_params(gen(s))["kind"] for s in range(20)} == {"street"}

    def test_the_flash_is_on_the_camera_axis(self):
        """The brightest direction is the flash, within 7 degrees of +Z (the camera) and a pixel."""
        variants = set()
        for params in params_of("flash", 6):
            variants.add(params["variant"])
            key = key_direction(params)
            assert math.degrees(math.acos(float(key[2]))) < 7.0
            env = render_portrait(params, 64)
            lum = (LUMA.float() @ env.reshape(3, -1)).reshape(64, 128)
            brightest = latlong_directions(64, dtype=torch.float64)[divmod(int(lum.argmax()), 128)]
            assert math.degrees(math.acos(min(1.0, float(brightest[2])))) < 7.0 + 2.9  # a pixel: 2.8 degrees
        assert variants == {"speedlight", "diffused", "phone"}
        source = PortraitLightSource(("flash",), height=32)
        for seed in range(3):  # the mirror ball's brightest pixel is a central one (the ball's centre is +Z)
            ball = LUMA.float() @ source.sample(gen(seed)).mirror_ball.reshape(3, -1)
            i, j = divmod(int(ball.argmax()), 32)
            assert 14 <= i <= 17 and 14 <= j <= 17

    @pytest.mark.parametrize("kind", ["flash", "studio", "window"])
    def test_ambient_to_key_ratio_is_the_drawn_one(self, kind):
        lo, hi = AMBIENT_RATIOS[kind]
        for params in params_of(kind, 6):
            assert lo <= params["ambient_ratio"] <= hi
            n = key_direction(params)
            key = params["lights"][0]["irradiance_klux"]
            ambient = irradiance(render_portrait(params, 32, ("ambient",)), n)
            assert ambient / key == pytest.approx(params["ambient_ratio"], rel=1e-4)
            # the key's light on the grid is the stated irradiance (to the grid's cosines: a pixel is 5.6 deg)
            assert irradiance(render_portrait(params, 32, ("key",)), n) == pytest.approx(key, rel=0.03)

    def test_street_ambient_is_below_its_bound(self):
        source = PortraitLightSource(("street",), height=32)
        ratios = []
        for seed in range(6):
            env = source.sample(gen(seed))
            n = key_direction(env.params)
            key = irradiance(render_portrait(env.params, 32, ("key",)), n)
            rest = irradiance(render_portrait(env.params, 32, ("ambient",)), n)
            assert rest / key == pytest.approx(env.params["ambient_ratio"], rel=1e-4)
            ratios.append(env.params["ambient_ratio"])
            lamps = env.params["outdoor"]["lamps"]
            assert 1.0 <= lamps[0]["distance_m"] <= 8.0 and float(n[1]) > math.sin(math.radians(16.0))
        assert max(ratios) < AMBIENT_RATIOS["street"][1] and min(ratios) > 0

    def test_studio_fill_ratio_and_placement(self):
        seen, clamshells = set(), 0
        for params in params_of("studio", 80):
            key, *fill = params["lights"]
            seen.add(params["pattern"])
            d = key_direction(params)
            off = math.degrees(math.atan2(abs(float(d[0])), float(d[2])))
            elev = math.degrees(math.asin(float(d[1])))
            if params["pattern"] == "under":  # an uplight: 10 to 45 degrees below the eyes
                assert off <= 45.0 + 1e-6 and -45.0 - 1e-6 <= elev <= -10.0 + 1e-6
            else:
                assert off <= 95.0 + 1e-6 and 10.0 - 1e-6 <= elev <= 50.0 + 1e-6
            if key["shape"] == "rect":  # a softbox: 15 to 45 degrees across (its longer side), at 1 to 3 m
                dist = math.dist(key["position_m"], [0.0, 0.0, 0.0])
                span = 2 * math.degrees(math.atan(key["height_m"] / (2 * dist)))
                assert 1.0 <= dist <= 3.0 and 15.0 - 1e-6 <= span <= 45.0 + 1e-6
                assert 0.6 - 1e-6 <= key["height_m"] <= 1.5 + 1e-6
            else:
                assert 2700.0 <= key["cct_k"] <= 3200.0
            if fill:
                ratio = params["lighting_ratio"]
                assert 2.0 <= ratio <= 8.0
                assert (key["irradiance_klux"] + fill[0]["irradiance_klux"]) / fill[0]["irradiance_klux"] == (
                    pytest.approx(ratio)
                )
                assert key["position_m"][0] * fill[0]["position_m"][0] <= 0  # on the other side
                if fill[0]["position_m"][1] < 0:  # a clamshell reflector, under a butterfly or loop key only
                    assert params["pattern"] in ("butterfly", "loop")
                    clamshells += 1
        assert seen == {"butterfly", "loop", "rembrandt", "split", "under"}
        assert clamshells > 0

    def test_screen_lights_from_below_or_eye_level(self):
        """A phone, laptop or monitor facing the subject near the camera axis, at or below the eyes, 20 to 100
        lux, in a room that gives 1/20 to 1/2 of it."""
        variants = set()
        for params in params_of("screen", 30):
            key = params["lights"][0]
            variants.add(params["variant"])
            d = key_direction(params)
            off = math.degrees(math.atan2(abs(float(d[0])), float(d[2])))
            elev = math.degrees(math.asin(float(d[1])))
            assert off <= 25.0 + 1e-6 and -35.0 - 1e-6 <= elev <= 5.0 + 1e-6
            assert key["shape"] == "rect" and 5500.0 <= key["cct_k"] <= 9000.0
            assert 0.01 <= key["irradiance_klux"] <= 0.15, params["variant"]
            lo, hi = AMBIENT_RATIOS["screen"]
            assert lo <= params["ambient_ratio"] <= hi and params["practicals"]
        assert variants == {"phone", "laptop", "monitor"}

    def test_window_is_on_one_side_with_no_sun_coming_in(self):
        for params in params_of("window", 8):
            window = params["lights"][0]
            d = key_direction(params)
            assert abs(float(d[0])) > 0.2  # on one side
            outward = torch.tensor(window["outward"], dtype=torch.float64)
            phi = math.radians(params["outdoor"]["sun_azimuth_deg"])
            sun = torch.tensor([math.sin(phi), 0.0, -math.cos(phi)], dtype=torch.float64)
            assert float(sun @ outward) <= -0.5 + 1e-9
            assert 5000.0 > window["irradiance_klux"] > 0.0

    def test_small_sources_keep_their_energy_on_the_grid(self):
        """A flash smaller than a pixel: the same energy sum(L Omega) at every height, L Omega_disk."""
        for params in params_of("flash", 4):
            light = params["lights"][0]
            dist = math.dist(light["position_m"], [0.0, 0.0, 0.0])
            r = math.asin(light["radius_m"] / dist)
            # irradiance facing the disk pi L sin^2 r; energy L Omega = L 2 pi (1 - cos r)
            expected = light["irradiance_klux"] * 2 * (1 - math.cos(r)) / math.sin(r) ** 2
            for height in (16, 32, 128):
                e = float(LUMA @ energy(render_portrait(params, height, ("key",))))
                assert e == pytest.approx(expected, rel=1e-5), (height, params["variant"])

    def test_softbox_energy_is_exact(self):
        params = next(p for p in params_of("studio", 40) if p["lights"][0]["shape"] == "rect")
        e = [energy(render_portrait(params, h, ("key",))) for h in (16, 64)]
        torch.testing.assert_close(e[0], e[1], rtol=1e-5, atol=0.0)

    def test_parts_add_up(self):
        for kind in PORTRAIT_KINDS:
            params = params_of(kind, 1, start=5)[0]
            whole = render_portrait(params, 16)
            parts = sum(render_portrait(params, 16, (p,)) for p in ("key", "fill", "ambient"))
            torch.testing.assert_close(whole, parts, rtol=1e-5, atol=1e-12)

    def test_camera_anchored_lights_are_not_turned(self):
        """The sampler's augmentation flips, exposes and white-balances the flash but keeps it on the axis."""
        sampler = EnvironmentSampler([PortraitLightSource(("flash",), height=32)], seed=4)
        for i in range(4):
            env = sampler.sample(i)
            record = env.params["augment"]
            assert record["yaw_deg"] == 0.0 and record["pitch_deg"] == 0.0
            m = torch.tensor(record["direction_map"], dtype=torch.float64)
            assert torch.equal(m.abs(), torch.eye(3, dtype=torch.float64))
            ball = LUMA.float() @ env.mirror_ball.reshape(3, -1)
            i_row, j_col = divmod(int(ball.argmax()), 32)
            assert 14 <= i_row <= 17 and 14 <= j_col <= 17
        street = PortraitLightSource(("street",), height=16).sample(gen(0))
        turned = Augment()(street, gen(1))
        assert turned.params["augment"]["yaw_deg"] != 0.0  # the street is turned as any outdoor scene

    def test_exception(self):
        with pytest.raises(ValueCheckError, match="kinds must be a non-empty subset"):
            PortraitLightSource(("disco",))
        with pytest.raises(ValueCheckError, match="kinds must be a non-empty subset"):
            PortraitLightSource(())
        with pytest.raises(ValueCheckError, match="weights must be 2 finite"):
            PortraitLightSource(("flash", "studio"), weights=(1.0,))
        with pytest.raises(ValueCheckError, match="weights must be 1 finite"):
            PortraitLightSource(("flash",), weights=(-1.0,))
        with pytest.raises(ValueCheckError, match="share must be a number in"):
            PortraitLightSource(share=1.0)
        with pytest.raises(TypeCheckError, match="generator must be a torch.Generator"):
            PortraitLightSource().sample_params(0)
        with pytest.raises(ValueCheckError, match="unknown kind"):
            PortraitLightSource().sample_params(gen(0), kind="disco")
        with pytest.raises(ValueCheckError, match="parts must be"):
            render_portrait(params_of("flash", 1)[0], 16, ("sun",))
