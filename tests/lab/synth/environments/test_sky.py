"""Tests of the procedural outdoor environments (Preetham sky, sun, ground, conditions)."""

from __future__ import annotations

import json
import math

import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st
from kornia.color import rgb_to_xyz

from kornia_ilum.core.errors import NonFiniteError, ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.geometry import (
    direction_to_mirror_ball,
    latlong_directions,
    latlong_solid_angles,
    latlong_to_mirror_ball,
    mirror_ball_pixel_index,
    mirror_ball_solid_angles,
)
from kornia_ilum_lab.synth.environments import EnvironmentSource
from kornia_ilum_lab.synth.environments.sky import (
    CONDITIONS,
    CctToRgb,
    SkyRadiance,
    SkySource,
    cct_to_rgb,
    outdoor_scene,
    preetham_zenith,
    render_outdoor,
    sky_radiance,
    splat_disk,
    sun_irradiance,
)
from tests.conftest import assert_close_dtype

F64 = torch.float64
HALF_AND_F32 = [torch.float16, torch.bfloat16, torch.float32]
LUMA = torch.tensor([0.2126729, 0.7151522, 0.0721750])
H = 64  # lat-long height of most scene tests (the default 128 is timed in benchmarks)


def luminance(x: torch.Tensor, dim: int = 0) -> torch.Tensor:
    return (x.movedim(dim, -1) * LUMA.to(x.dtype)).sum(-1)


def energy(latlong: torch.Tensor) -> torch.Tensor:
    return (latlong.double() * latlong_solid_angles(latlong.shape[-2], dtype=F64)).sum((-2, -1))


def ball_energy(ball: torch.Tensor) -> torch.Tensor:
    return (ball.double() * mirror_ball_solid_angles(ball.shape[-1], dtype=F64)).sum((-2, -1))


def gen(seed: int) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


# ----------------------------------------------------------------------------------------------
# Preetham et al. 1999, appendix A.2, transcribed independently as scalar formulas

PAPER_Y = [(0.1787, -1.4630), (-0.3554, 0.4275), (-0.0227, 5.3251), (0.1206, -2.5771), (-0.0670, 0.3703)]
PAPER_X = [(-0.0193, -0.2592), (-0.0665, 0.0008), (-0.0004, 0.2125), (-0.0641, -0.8989), (-0.0033, 0.0452)]
PAPER_YC = [(-0.0167, -0.2608), (-0.0950, 0.0092), (-0.0079, 0.2102), (-0.0441, -1.6537), (-0.0109, 0.0529)]
PAPER_MX = [
    [0.00166, -0.00375, 0.00209, 0.0],
    [-0.02903, 0.06377, -0.03202, 0.00394],
    [0.11693, -0.21196, 0.06052, 0.25886],
]
PAPER_MY = [
    [0.00275, -0.00610, 0.00317, 0.0],
    [-0.04214, 0.08970, -0.04153, 0.00516],
    [0.15346, -0.26756, 0.06670, 0.26688],
]


def paper_zenith(t: float, ts: float) -> tuple[float, float, float]:
    chi = (4 / 9 - t / 120) * (math.pi - 2 * ts)
    yz = (4.0453 * t - 4.9710) * math.tan(chi) - 0.2155 * t + 2.4192
    tv, sv = [t * t, t, 1.0], [ts**3, ts**2, ts, 1.0]
    xz = sum(tv[i] * PAPER_MX[i][j] * sv[j] for i in range(3) for j in range(4))
    yc = sum(tv[i] * PAPER_MY[i][j] * sv[j] for i in range(3) for j in range(4))
    return yz, xz, yc


def paper_perez(rows, t: float, theta: float, gamma: float) -> float:
    a, b, c, d, e = (s * t + i for s, i in rows)
    return (1 + a * math.exp(b / math.cos(theta))) * (1 + c * math.exp(d * gamma) + e * math.cos(gamma) ** 2)


def paper_sky(t: float, ts: float, theta: float, gamma: float) -> tuple[float, float, float]:
    """(Y, x, y) of the sky at zenith angle theta and sun angle gamma."""
    zen = paper_zenith(t, ts)
    return tuple(
        z * paper_perez(rows, t, theta, gamma) / paper_perez(rows, t, 0.0, ts)
        for z, rows in zip(zen, (PAPER_Y, PAPER_X, PAPER_YC), strict=True)
    )


def to_xyY(rgb: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    xyz = rgb_to_xyz(rgb.reshape(-1, 3).T.reshape(3, -1, 1)).reshape(3, -1)
    s = xyz.sum(0)
    return xyz[1], xyz[0] / s, xyz[1] / s


PAIRS = [
    (2.0, 0.0),
    (2.0, math.radians(30)),
    (3.0, math.radians(45)),
    (5.0, math.radians(60)),
    (8.0, math.radians(80)),
    (10.0, math.radians(89)),
]


class TestPreethamReference:
    @pytest.mark.parametrize("t, ts", PAIRS)
    def test_zenith_formulas(self, t, ts):
        got = preetham_zenith(torch.tensor(t, dtype=F64), torch.tensor(ts, dtype=F64))
        for g, want in zip(got, paper_zenith(t, ts), strict=True):
            assert float(g) == pytest.approx(want, rel=1e-12)

    def test_zenith_anchor_values(self):
        # hand-evaluated from the paper's formulas: T = 2, theta_s = 30 deg
        yz, xz, yc = preetham_zenith(torch.tensor(2.0, dtype=F64), torch.tensor(math.radians(30), dtype=F64))
        assert float(yz) == pytest.approx(5.8873, abs=1e-3)  # kcd/m^2
        assert float(xz) == pytest.approx(0.25142, abs=1e-5)  # bluer than D65 (0.3127, 0.3290)
        assert float(yc) == pytest.approx(0.25592, abs=1e-5)

    @pytest.mark.parametrize(
        "t, ts", [(2.0, math.radians(30)), (3.0, math.radians(45)), (6.0, math.radians(20))]
    )
    def test_sky_matches_paper(self, t, ts):
        """Luminance and chromaticity at many directions, back-converted from linear sRGB."""
        sun = torch.tensor([0.0, math.cos(ts), -math.sin(ts)], dtype=F64)
        d = latlong_directions(16, dtype=F64)[:7].reshape(-1, 3)  # upper hemisphere rows
        lum, x, y = to_xyY(sky_radiance(d, sun, t))
        for k in range(0, len(d), 5):
            theta = math.acos(float(d[k, 1]))
            gamma = math.acos(max(-1.0, min(1.0, float(d[k] @ sun))))
            want = paper_sky(t, ts, theta, gamma)
            assert float(lum[k]) == pytest.approx(want[0], rel=1e-9)
            assert float(x[k]) == pytest.approx(want[1], abs=1e-9)
            assert float(y[k]) == pytest.approx(want[2], abs=1e-9)

    def test_perez_ratio_properties(self):
        t, ts = 2.5, math.radians(40)
        sun = torch.tensor([math.sin(ts) * 0.6, math.cos(ts), -math.sin(ts) * 0.8], dtype=F64)
        zenith = to_xyY(sky_radiance(torch.tensor([0.0, 1.0, 0.0], dtype=F64), sun, t))[0]
        assert float(zenith) == pytest.approx(paper_zenith(t, ts)[0], rel=1e-9)  # F(0, ts) / F(0, ts) = 1
        # symmetric about the sun's vertical plane: mirror directions across it
        d = torch.nn.functional.normalize(torch.randn(64, 3, dtype=F64, generator=gen(0)), dim=-1)
        d[:, 1] = d[:, 1].abs()
        normal = torch.tensor([0.8, 0.0, 0.6], dtype=F64)  # horizontal, perpendicular to the sun's azimuth
        mirrored = d - 2 * (d @ normal)[:, None] * normal
        torch.testing.assert_close(
            sky_radiance(d, sun, t), sky_radiance(mirrored, sun, t), rtol=1e-9, atol=1e-12
        )
        # circumsolar brightening: brighter near the sun than 90 degrees of azimuth away at the same height
        el, phi_s = math.pi / 2 - ts, math.atan2(float(sun[0]), -float(sun[2]))
        phi = torch.tensor([phi_s + 0.1, phi_s + math.pi / 2], dtype=F64)
        around = torch.stack(
            [
                torch.sin(phi) * math.cos(el),
                torch.full_like(phi, math.sin(el)),
                -torch.cos(phi) * math.cos(el),
            ],
            -1,
        )
        lum = to_xyY(sky_radiance(around, sun, t))[0]
        assert float(lum[0]) > 2 * float(lum[1])

    def test_turbidity_brightens_and_whitens_the_zenith(self):
        ts = torch.tensor(math.radians(30), dtype=F64)
        y2, x2, _ = preetham_zenith(torch.tensor(2.0, dtype=F64), ts)
        y8, x8, _ = preetham_zenith(torch.tensor(8.0, dtype=F64), ts)
        assert y8 > y2 and x8 > x2


class TestSkyRadiance:
    def test_smoke(self, device, dtype):
        d = torch.tensor([[0.0, 1.0, 0.0], [0.3, 0.2, -0.9]], device=device, dtype=dtype)
        out = sky_radiance(d, torch.tensor([0.0, 0.6, -0.8], device=device, dtype=dtype), 3.0)
        assert out.dtype == dtype and out.device.type == device.type
        assert bool((out > 0).all()) and bool(out.isfinite().all())

    @pytest.mark.parametrize("shape", [(3,), (5, 3), (2, 4, 3)])
    def test_cardinality(self, shape):
        out = sky_radiance(torch.randn(shape), torch.tensor([0.0, 0.5, -0.8]), 2.0)
        assert out.shape == shape
        per_sun = sky_radiance(torch.randn(4, 3), torch.randn(4, 3), torch.full((4,), 4.0))
        assert per_sun.shape == (4, 3)

    def test_exception(self):
        sun = torch.tensor([0.0, 1.0, 0.0])
        with pytest.raises(ShapeError, match=r"directions must have shape \(\*, 3\), got \(4, 2\)"):
            sky_radiance(torch.randn(4, 2), sun, 3.0)
        with pytest.raises(ShapeError, match=r"sun_direction must have shape \(\*, 3\)"):
            sky_radiance(torch.randn(4, 3), torch.randn(2), 3.0)
        with pytest.raises(NonFiniteError, match="directions must be finite"):
            sky_radiance(torch.full((2, 3), float("nan")), sun, 3.0)
        with pytest.raises(ValueCheckError, match=r"turbidity must lie in \[1.7, 10\]"):
            sky_radiance(torch.randn(2, 3), sun, 12.0)
        with pytest.raises(TypeCheckError, match="directions must be a torch.Tensor"):
            sky_radiance([[0.0, 1.0, 0.0]], sun, 3.0)
        with pytest.raises(ValueCheckError, match="turbidity must lie in"):
            SkyRadiance(1.0)

    @given(
        st.lists(st.tuples(*[st.floats(-1.0, 1.0)] * 3), min_size=1, max_size=8),
        st.tuples(*[st.floats(-1.0, 1.0)] * 3),
        st.floats(1.7, 10.0),
    )
    def test_nonnegative_and_finite(self, dirs, sun, turbidity):
        d = torch.tensor(dirs, dtype=F64) + torch.tensor([0.0, 1e-3, 0.0], dtype=F64)  # no zero vectors
        s = torch.tensor(sun, dtype=F64) + torch.tensor([0.0, 0.0, 1e-3], dtype=F64)
        out = sky_radiance(d, s, turbidity)
        assert bool(out.isfinite().all()) and float(out.min()) >= 0.0

    def test_gradcheck(self):
        d = torch.tensor([[0.1, 0.9, -0.3], [0.5, 0.3, 0.4]], dtype=F64, requires_grad=True)
        sun = torch.tensor([0.2, 0.7, -0.6], dtype=F64, requires_grad=True)
        t = torch.tensor(3.0, dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(sky_radiance, (d, sun, t))

    def test_module_matches_functional(self):
        d, sun = torch.randn(8, 3), torch.tensor([0.0, 0.4, -0.9])
        torch.testing.assert_close(SkyRadiance(4.5)(d, sun), sky_radiance(d, sun, 4.5), atol=0, rtol=0)

    @pytest.mark.parametrize("dt", HALF_AND_F32)
    def test_dtypes(self, dt):
        d = torch.randn(16, 3, dtype=F64, generator=gen(1))
        sun = torch.tensor([0.3, 0.5, -0.8], dtype=F64)
        out = sky_radiance(d.to(dt), sun.to(dt), 3.0)
        assert out.dtype == dt
        ref = sky_radiance(d.to(dt).to(F64), sun.to(dt).to(F64), 3.0)
        assert_close_dtype(out / ref.mean(), ref / ref.mean(), dt)

    @pytest.mark.slow  # torch.compile (Inductor): compiles, slow on a cold cache
    def test_compile(self):
        d, sun = torch.randn(8, 3), torch.tensor([0.0, 0.4, -0.9])
        torch.testing.assert_close(torch.compile(sky_radiance)(d, sun, 3.0), sky_radiance(d, sun, 3.0))


class TestCctToRgb:
    def test_smoke(self, device, dtype):
        out = cct_to_rgb(torch.tensor([2700.0, 6500.0], device=device, dtype=dtype))
        assert out.dtype == dtype and out.device.type == device.type
        assert bool(out[0, 0] > out[0, 2]) and bool((out >= 0).all())
        torch.testing.assert_close(
            luminance(out, -1), torch.ones(2, device=device, dtype=dtype), rtol=1e-4, atol=1e-5
        )

    @pytest.mark.parametrize(
        "kelvin, xy",
        [(2856.0, (0.44757, 0.40745)), (6500.0, (0.31352, 0.32363)), (4000.0, (0.38045, 0.37674))],
    )
    def test_planckian_locus_reference(self, kelvin, xy):
        """CIE illuminant A (a 2856 K blackbody) and tabulated Planckian chromaticities, within 0.002."""
        _, x, y = to_xyY(cct_to_rgb(torch.tensor([kelvin], dtype=F64)))
        assert abs(float(x[0]) - xy[0]) < 2e-3 and abs(float(y[0]) - xy[1]) < 2e-3

    def test_daylight_locus_d65_is_white(self):
        torch.testing.assert_close(
            cct_to_rgb(torch.tensor(6504.0, dtype=F64), "daylight"),
            torch.ones(3, dtype=F64),
            atol=1e-3,
            rtol=0,
        )

    @pytest.mark.parametrize("shape", [(), (4,), (2, 3)])
    def test_cardinality(self, shape):
        assert cct_to_rgb(torch.full(shape, 5000.0)).shape == (*shape, 3)

    def test_exception(self):
        with pytest.raises(
            ValueCheckError, match=r"kelvin must lie in \[1000, 40000\] for the planckian locus"
        ):
            cct_to_rgb(torch.tensor([500.0]))
        with pytest.raises(
            ValueCheckError, match=r"kelvin must lie in \[4000, 25000\] for the daylight locus"
        ):
            cct_to_rgb(torch.tensor([3000.0]), "daylight")
        with pytest.raises(ValueCheckError, match="locus must be 'planckian' or 'daylight'"):
            cct_to_rgb(torch.tensor([3000.0]), "sodium")
        with pytest.raises(NonFiniteError, match="kelvin must be finite"):
            cct_to_rgb(torch.tensor([float("inf")]))
        with pytest.raises(TypeCheckError, match="kelvin must be a floating-point tensor"):
            cct_to_rgb(torch.tensor([3000]))

    def test_gradcheck(self):
        k = torch.tensor([2500.0, 6500.0, 12000.0], dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(cct_to_rgb, (k,))
        k = torch.tensor([4500.0, 6500.0, 12000.0], dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(lambda x: cct_to_rgb(x, "daylight"), (k,))

    def test_module_matches_functional(self):
        k = torch.tensor([3000.0, 5000.0])
        torch.testing.assert_close(
            CctToRgb("daylight")(k + 2000), cct_to_rgb(k + 2000, "daylight"), atol=0, rtol=0
        )
        torch.testing.assert_close(CctToRgb()(k), cct_to_rgb(k), atol=0, rtol=0)

    @pytest.mark.parametrize("dt", HALF_AND_F32)
    def test_dtypes(self, dt):
        k = torch.tensor([2200.0, 4000.0, 6504.0, 9000.0], dtype=F64)
        out = cct_to_rgb(k.to(dt))
        assert out.dtype == dt
        assert_close_dtype(out, cct_to_rgb(k.to(dt).to(F64)), dt)

    @pytest.mark.slow  # torch.compile (Inductor): compiles, slow on a cold cache
    def test_compile(self):
        k = torch.tensor([3000.0, 5000.0])
        torch.testing.assert_close(torch.compile(cct_to_rgb)(k), cct_to_rgb(k))


class TestSun:
    def test_levels(self):
        noon = float(luminance(sun_irradiance(60.0, 2.0), -1))
        assert 95.0 < noon < 115.0  # klux: clear-sky direct normal illuminance
        assert float(luminance(sun_irradiance(60.0, 8.0), -1)) < 0.6 * noon  # haze
        assert float(luminance(sun_irradiance(2.0, 3.0), -1)) < 0.01 * noon  # sunset
        assert float(sun_irradiance(-1.0, 3.0).sum()) == 0.0

    def test_redder_when_low(self):
        rb = [float(e[0] / e[2]) for e in (sun_irradiance(el, 3.0) for el in (70.0, 30.0, 10.0))]
        assert rb[0] < rb[1] < rb[2]


class TestSplatDisk:
    @pytest.mark.parametrize("radius_deg", [0.265, 3.0, 12.0])
    def test_energy_is_exact(self, radius_deg):
        env = torch.zeros(3, 32, 64, dtype=F64)
        e = torch.tensor([1.0, 2.0, 0.5], dtype=F64)
        splat_disk(env, [0.3, 0.5, -0.7], math.radians(radius_deg), e)
        torch.testing.assert_close(energy(env), e, rtol=1e-12, atol=0)

    @given(
        st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda v: sum(x * x for x in v) > 1e-2),
        st.floats(1e-3, 0.3),
        st.sampled_from([4, 8, 16]),
    )
    def test_energy_is_exact_anywhere(self, direction, radius, height):
        env = splat_disk(
            torch.zeros(3, height, 2 * height, dtype=F64), direction, radius, torch.ones(3, dtype=F64)
        )
        torch.testing.assert_close(energy(env), torch.ones(3, dtype=F64), rtol=1e-12, atol=0)
        assert float(env.min()) >= 0.0

    def test_straddling_sun_is_split_by_area(self):
        h = 16
        # exactly on the boundary between two columns, at a row centre: half in each
        phi = 2 * math.pi * 8 / (2 * h) - math.pi
        el = math.pi / 2 - math.pi * 5.5 / h
        d = [math.sin(phi) * math.cos(el), math.sin(el), -math.cos(phi) * math.cos(el)]
        env = splat_disk(
            torch.zeros(3, h, 2 * h, dtype=F64), d, math.radians(0.265), torch.ones(3, dtype=F64)
        )
        shares = (env[0] * latlong_solid_angles(h, dtype=F64))[5, 7:9]
        torch.testing.assert_close(shares, torch.full((2,), 0.5, dtype=F64), atol=0.03, rtol=0)


class TestSkySource:
    def test_protocol_and_labels(self):
        source = SkySource(height=H)
        assert isinstance(source, EnvironmentSource) and source.label == "outdoor"
        for cond in CONDITIONS:
            env = SkySource((cond,), height=H).sample(gen(3))
            assert env.label == "outdoor" and env.source == f"sky:{cond}"
            assert env.params["condition"] == cond
            assert {"sun_azimuth_deg", "sun_elevation_deg", "turbidity", "ground", "occluders"} <= set(
                env.params
            )
            json.dumps(env.params)  # JSON-serialisable
            assert env.latlong.shape == (3, H, 2 * H) and env.mirror_ball.shape == (3, 32, 32)

    def test_reproducible(self):
        source = SkySource(height=H)
        a, b, c = source.sample(gen(7)), source.sample(gen(7)), source.sample(gen(8))
        assert torch.equal(a.latlong, b.latlong) and torch.equal(a.mirror_ball, b.mirror_ball)
        assert a.params == b.params
        assert not torch.equal(a.latlong, c.latlong)
        # params re-render to the same map
        assert torch.equal(render_outdoor(a.params, H), a.latlong)

    @pytest.mark.parametrize("cond", CONDITIONS)
    def test_nonnegative_finite_and_energy_into_ball(self, cond):
        source = SkySource((cond,), height=H)
        for seed in range(3):
            env = source.sample(gen(seed))
            assert bool(env.latlong.isfinite().all()) and float(env.latlong.min()) >= 0.0
            e_ll, e_ball = energy(env.latlong), ball_energy(env.mirror_ball)
            torch.testing.assert_close(e_ball, e_ll, rtol=1e-4, atol=0)

    def test_sun_energy_preserved(self):
        """The splatted sun carries exactly its irradiance, into the lat-long and into the mirror ball."""
        params = SkySource(("clear",)).sample_params(gen(11))
        scene = outdoor_scene(params)
        ((sun_dir, _, sun_e),) = scene.disks
        for height in (32, H):
            with_sun = render_outdoor(params, height)
            d = latlong_directions(height).reshape(-1, 3)
            no_sun = scene.radiance(d).T.reshape(3, height, 2 * height)
            torch.testing.assert_close(energy(with_sun) - energy(no_sun), sun_e.double(), rtol=1e-4, atol=0)
            ball = latlong_to_mirror_ball(with_sun[None], 32)[0]
            ball_no_sun = latlong_to_mirror_ball(no_sun[None], 32)[0]
            torch.testing.assert_close(
                ball_energy(ball) - ball_energy(ball_no_sun), sun_e.double(), rtol=1e-4, atol=0
            )
            # the sun's ball pixel is the brightest and holds its energy
            idx = int(mirror_ball_pixel_index(direction_to_mirror_ball(sun_dir[None].double()), 32)[0])
            assert int(luminance(ball).flatten().argmax()) == idx

    def test_clear_has_a_dominant_sun(self):
        source = SkySource(("clear",), height=H)
        for seed in range(4):
            env = source.sample(gen(seed))
            y = luminance(env.latlong)
            assert float(y.max() / y.mean()) >= 1e3
            yb = luminance(env.mirror_ball)
            assert float(yb.max() / yb[yb > 0].mean()) >= 1e2
            sky = luminance(outdoor_scene(env.params).sky(latlong_directions(H).reshape(-1, 3)), -1)
            sun = luminance(outdoor_scene(env.params).disks[0][2], -1) / (
                2 * math.pi * (1 - math.cos(math.radians(0.265)))
            )
            assert 2e4 < float(sun / sky.mean()) < 3e5  # disk radiance vs the mean sky: about 1e5

    def test_overcast_follows_cie(self):
        params = SkySource(("overcast",)).sample_params(gen(5))
        params["occluders"] = []
        env = render_outdoor(params, H)
        y = luminance(env)
        el = math.pi / 2 - math.pi * (torch.arange(H // 2, dtype=F64) + 0.5) / H
        profile = y[: H // 2].mean(1).double()
        torch.testing.assert_close(
            profile / profile[0], (1 + 2 * torch.sin(el)) / (1 + 2 * torch.sin(el[0])), rtol=1e-5, atol=0
        )
        assert 2.8 < float(profile[0] / profile[-1]) < 3.1  # zenith about 3x the horizon
        assert float(y.max()) <= 10 * float(y.mean())
        # with occluders too, low contrast
        for seed in range(4):
            full = luminance(SkySource(("overcast",), height=H).sample(gen(seed)).latlong)
            assert float(full.max()) <= 10 * float(full.mean())

    def test_night_is_much_darker_than_day(self):
        def levels(cond: str) -> tuple[list[float], list[float]]:
            ys = [luminance(SkySource((cond,), height=H).sample(gen(s)).latlong) for s in range(4)]
            return [float(y.mean()) for y in ys], [float(y.median()) for y in ys]

        day = [levels(c) for c in ("clear", "hazy", "overcast")]
        day_mean, day_median = min(min(m) for m, _ in day), min(min(m) for _, m in day)
        night_mean, night_median = (max(v) for v in levels("night"))
        assert night_median < 1e-3 * day_median  # the sky and ground: 4 to 6 decades darker
        assert night_mean < 1e-2 * day_mean  # street lamps and the moon included
        dusk_mean, _ = levels("dusk")
        assert max(dusk_mean) < max(m for ms, _ in day for m in ms)

    def test_dusk_is_warm_toward_the_sun(self):
        source = SkySource(("dusk",))
        d = latlong_directions(H).reshape(H, 2 * H, 3)
        for seed in range(4):
            params = source.sample_params(gen(seed))
            params["occluders"] = []
            rad = outdoor_scene(params).radiance(d.reshape(-1, 3)).reshape(H, 2 * H, 3)
            col = int((params["sun_azimuth_deg"] + 180.0) / 360.0 * 2 * H) % (2 * H)
            cols = [(col + k) % (2 * H) for k in range(-2, 3)]
            anti = [(col + H + k) % (2 * H) for k in range(-2, 3)]
            rows = slice(H // 2 - 3, H // 2)  # 0 to 8 degrees above the horizon

            def rb(x: torch.Tensor) -> float:
                return float(x[..., 0].sum() / x[..., 2].sum())

            toward, away, zenith = rb(rad[rows][:, cols]), rb(rad[rows][:, anti]), rb(rad[:2])
            assert zenith < 1.0  # blue zenith
            assert toward > 3 * zenith and toward > 1.5 * away

    def test_condition_weights(self):
        source = SkySource(("clear", "night"), height=8, weights=(1.0, 0.0))
        assert all(source.sample_params(gen(s))["condition"] == "clear" for s in range(5))

    def test_exception(self):
        with pytest.raises(ValueCheckError, match=r"unknown conditions \['rainy'\]"):
            SkySource(("clear", "rainy"))
        with pytest.raises(ValueCheckError, match="conditions must name at least one"):
            SkySource(())
        with pytest.raises(ValueCheckError, match=r"weights must have one entry per condition \(5\), got 2"):
            SkySource(weights=(1.0, 2.0))
        with pytest.raises(ValueCheckError, match="weights must be finite, non-negative and not all zero"):
            SkySource(("clear",), weights=(0.0,))
        with pytest.raises(ValueCheckError, match="height must be"):
            SkySource(height=0)
        with pytest.raises(TypeCheckError, match="generator must be a torch.Generator, got int"):
            SkySource().sample(0)
