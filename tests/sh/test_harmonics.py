"""Tests of kornia_ilum.sh.harmonics: basis, projection, reconstruction, irradiance."""

from __future__ import annotations

import math

import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from kornia_ilum.core.errors import (
    EmptyTensorError,
    NonFiniteError,
    ShapeError,
    TypeCheckError,
    ValueCheckError,
)
from kornia_ilum.geometry import (
    latlong_directions,
    latlong_solid_angles,
    mirror_ball_directions,
    mirror_ball_solid_angles,
)
from kornia_ilum.sh import (
    SH_CONSTANTS,
    SHIrradiance,
    SHIrradianceAt,
    SHProject,
    SHReconstruct,
    sh_basis,
    sh_irradiance,
    sh_irradiance_at,
    sh_project,
    sh_reconstruct,
)
from tests.conftest import assert_close_dtype

F64 = torch.float64
HALF_AND_F32 = [torch.float16, torch.bfloat16, torch.float32]
LAYOUT_SIZES = [
    ("mirror_ball", 8),
    ("mirror_ball", 16),
    ("mirror_ball", 32),
    ("latlong", 4),
    ("latlong", 8),
    ("latlong", 16),
]


def _grid(layout: str, size: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Pixel-centre directions (N, 3) and exact solid angles (N,), float64; invalid pixels have 0 sr."""
    if layout == "mirror_ball":
        d, _ = mirror_ball_directions(size, dtype=F64)
        w = mirror_ball_solid_angles(size, dtype=F64)
    else:
        d = latlong_directions(size, dtype=F64)
        w = latlong_solid_angles(size, dtype=F64)
    return d.reshape(-1, 3), w.reshape(-1)


def _image(values: torch.Tensor, layout: str, size: int) -> torch.Tensor:
    """(B, N) or (B, 3, N) per-pixel values to a lighting image."""
    if values.dim() == 2:
        values = values[:, None].expand(-1, 3, -1)
    w = size if layout == "mirror_ball" else 2 * size
    return values.reshape(values.shape[0], 3, size, w).contiguous()


def _gram(layout: str, size: int) -> torch.Tensor:
    d, w = _grid(layout, size)
    y = sh_basis(d) * (w > 0)[:, None]
    return (y.T * w) @ y


coeffs_f64 = st.lists(st.floats(-10, 10, allow_nan=False), min_size=27, max_size=27).map(
    lambda v: torch.tensor(v, dtype=F64).reshape(1, 9, 3)
)


class TestShBasis:
    def test_smoke(self, device, dtype):
        y = sh_basis(torch.tensor([0.0, 0.0, 1.0], device=device, dtype=dtype))
        c = SH_CONSTANTS
        expected = torch.tensor([c[0], 0, c[2], 0, 0, 0, 2 * c[6], 0, 0], device=device, dtype=dtype)
        torch.testing.assert_close(y, expected)
        # the usual rounded constants
        torch.testing.assert_close(
            torch.tensor(c),
            torch.tensor(
                [0.282095, 0.488603, 0.488603, 0.488603, 1.092548, 1.092548, 0.315392, 1.092548, 0.546274]
            ),
            atol=1e-6,
            rtol=0,
        )

    def test_frame(self):
        """Each axis lands on our coefficient with a positive sign (no Condon-Shortley phase)."""
        c = SH_CONSTANTS
        y = sh_basis(torch.eye(3, dtype=F64))  # rows: +X, +Y, +Z
        assert (
            y[0, 3] == pytest.approx(c[3])
            and y[1, 1] == pytest.approx(c[1])
            and y[2, 2] == pytest.approx(c[2])
        )
        assert y[0, 8] == pytest.approx(c[8]) and y[1, 8] == pytest.approx(-c[8])  # x^2 - y^2
        d = torch.nn.functional.normalize(
            torch.tensor([[1.0, 1.0, 0.0], [0.0, 1.0, 1.0], [1.0, 0.0, 1.0]], dtype=F64), dim=1
        )
        y = sh_basis(d)
        assert (
            y[0, 4] == pytest.approx(c[4] / 2)
            and y[1, 5] == pytest.approx(c[5] / 2)
            and y[2, 7] == pytest.approx(c[7] / 2)
        )

    @pytest.mark.parametrize("shape", [(3,), (5, 3), (2, 4, 6, 3)])
    def test_cardinality(self, shape):
        assert sh_basis(torch.randn(shape)).shape == shape[:-1] + (9,)

    def test_normalises(self):
        d = torch.randn(10, 3, dtype=F64)
        torch.testing.assert_close(sh_basis(3.5 * d), sh_basis(d))

    def test_exception(self):
        with pytest.raises(ShapeError, match=r"directions must have shape \(\*, 3\), got \(4, 2\)"):
            sh_basis(torch.zeros(4, 2))
        with pytest.raises(TypeCheckError, match="directions must be a floating-point tensor"):
            sh_basis(torch.zeros(4, 3, dtype=torch.long))
        with pytest.raises(TypeCheckError, match="directions must be a torch.Tensor"):
            sh_basis([0.0, 0.0, 1.0])
        with pytest.raises(NonFiniteError, match="directions must be finite"):
            sh_basis(torch.tensor([float("nan"), 0.0, 1.0]))
        with pytest.raises(EmptyTensorError, match="directions must not be empty"):
            sh_basis(torch.zeros(0, 3))

    def test_gradcheck(self):
        d = torch.randn(4, 3, dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(sh_basis, (d,))

    @pytest.mark.parametrize("dt", HALF_AND_F32)
    def test_dtypes(self, dt):
        d = torch.randn(64, 3, dtype=F64)
        out = sh_basis(d.to(dt))
        assert out.dtype == dt
        assert_close_dtype(out, sh_basis(d.to(dt).to(F64)), dt)

    def test_compile(self):
        d = torch.randn(8, 3)
        torch.testing.assert_close(torch.compile(sh_basis)(d), sh_basis(d))

    @pytest.mark.parametrize(
        ("layout", "size", "bound"),
        # measured max |G - I|: 1.02e-2, 5.67e-3, 1.11e-3, 2.77e-4 (see the module docstring)
        [
            ("mirror_ball", 32, 1.1e-2),
            ("mirror_ball", 64, 6.0e-3),
            ("latlong", 32, 1.2e-3),
            ("latlong", 64, 3.0e-4),
        ],
    )
    def test_orthonormal_under_exact_solid_angles(self, layout, size, bound):
        err = (_gram(layout, size) - torch.eye(9, dtype=F64)).abs().max().item()
        assert 1e-5 < err < bound  # orthonormal up to the (nonzero) pixel-centre quadrature error

    def test_orthonormal_converges(self):
        err = (_gram("latlong", 256) - torch.eye(9, dtype=F64)).abs().max().item()
        assert err < 2e-5  # second order in the pixel size: 2.77e-4 at H = 64, 1.73e-5 (a 16th) at 256


class TestShProject:
    def test_smoke(self, device, dtype):
        sh = sh_project(torch.full((2, 3, 32, 32), 2.0, device=device, dtype=dtype))
        expected = torch.zeros(2, 9, 3, device=device, dtype=dtype)
        expected[:, 0] = 2.0 * math.sqrt(4 * math.pi)
        torch.testing.assert_close(sh, expected, atol=1e-5, rtol=1e-5)

    @pytest.mark.parametrize(
        ("layout", "shape"), [("mirror_ball", (2, 3, 16, 16)), ("latlong", (1, 3, 8, 16))]
    )
    def test_cardinality(self, layout, shape):
        assert sh_project(torch.rand(shape), layout).shape == (shape[0], 9, 3)

    def test_exception(self):
        with pytest.raises(
            ValueCheckError, match=r"layout must be one of \('mirror_ball', 'latlong'\), got 'cube'"
        ):
            sh_project(torch.rand(1, 3, 8, 8), "cube")
        with pytest.raises(
            ShapeError,
            match=r"lighting must have shape \(B, 3, S, S\), got \(1, 3, 8, 16\) \(its two S sizes differ",
        ):
            sh_project(torch.rand(1, 3, 8, 16))
        with pytest.raises(
            ShapeError, match=r"lighting must have shape \(B, 3, H, 2H\) for layout 'latlong'"
        ):
            sh_project(torch.rand(1, 3, 8, 8), "latlong")
        with pytest.raises(ShapeError, match=r"lighting must have shape \(B, 3, S, S\), got \(3, 8, 8\)"):
            sh_project(torch.rand(3, 8, 8))
        with pytest.raises(NonFiniteError, match="lighting must be finite"):
            sh_project(torch.full((1, 3, 8, 8), float("inf")))
        with pytest.raises(ValueCheckError, match="mirror_ball grid of size S = 4 is too small"):
            sh_project(torch.rand(1, 3, 4, 4))
        with pytest.raises(ValueCheckError, match="latlong grid of size H = 2 is too small"):
            sh_project(torch.rand(1, 3, 2, 4), "latlong")
        with pytest.raises(ShapeError, match=r"lighting must have size 32 for this SHProject"):
            SHProject(32)(torch.rand(1, 3, 16, 16))

    @given(coeffs_f64, st.sampled_from(LAYOUT_SIZES))
    def test_reproduces_order2_exactly(self, sh, layout_size):
        """Random coefficients -> reconstruct -> project gives them back (least squares, both layouts)."""
        layout, size = layout_size
        back = sh_project(sh_reconstruct(sh, size, layout), layout)
        torch.testing.assert_close(back, sh, atol=1e-11, rtol=0)

    @pytest.mark.parametrize(("layout", "quad_bound"), [("mirror_ball", 1.3e-2), ("latlong", 2.0e-3)])
    def test_least_squares_vs_quadrature(self, layout, quad_bound):
        """Pixel-centre quadrature is not exact for order 2 at 32; least squares is (measured numbers)."""
        torch.manual_seed(0)
        sh = torch.randn(50, 9, 3, dtype=F64)
        img = sh_reconstruct(sh, 32, layout)
        d, w = _grid(layout, 32)
        quad = torch.einsum("bcn,nk->bkc", img.flatten(2), sh_basis(d) * w[:, None])
        rel_quad = ((quad - sh).norm(dim=1) / sh.norm(dim=1)).max().item()
        assert 1e-4 < rel_quad < quad_bound  # measured 1.23e-2 (mirror ball), 1.82e-3 (lat-long)
        assert (sh_project(img, layout) - sh).abs().max().item() < 1e-12
        # a one-pixel sun (not order 2): least squares and quadrature differ by about the quadrature error
        valid = torch.nonzero(w > 0).flatten()
        n = valid[:: max(1, valid.numel() // 97)]
        suns = torch.zeros(n.numel(), d.shape[0], dtype=F64)
        suns[torch.arange(n.numel()), n] = 1.0
        sun_img = _image(suns, layout, 32)
        ls = sh_project(sun_img, layout)
        q = torch.einsum("bcn,nk->bkc", sun_img.flatten(2), sh_basis(d) * w[:, None])
        diff = ((ls - q).norm(dim=1) / q.norm(dim=1))[:, 0]
        assert diff.max().item() < 1.5e-2  # measured: mirror ball median 4.0e-3, max 1.4e-2

    def test_ignores_invalid_pixels(self):
        img = torch.rand(2, 3, 16, 16, dtype=F64)
        _, valid = mirror_ball_directions(16)
        garbage = img.clone()
        garbage[..., ~valid] = 1e3
        torch.testing.assert_close(sh_project(garbage), sh_project(img))

    def test_gradcheck(self):
        img = torch.rand(1, 3, 8, 8, dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(sh_project, (img,), fast_mode=True)
        img = torch.rand(1, 3, 4, 8, dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(lambda x: sh_project(x, "latlong"), (img,), fast_mode=True)

    @pytest.mark.parametrize(("layout", "size"), [("mirror_ball", 16), ("latlong", 8)])
    def test_module_matches_functional(self, layout, size):
        img = torch.rand(2, 3, size, size if layout == "mirror_ball" else 2 * size, dtype=F64)
        module = SHProject(size, layout, dtype=F64)
        assert "projection" not in module.state_dict()
        torch.testing.assert_close(module(img), sh_project(img, layout), atol=0, rtol=0)
        torch.testing.assert_close(SHProject(size, layout)(img.float()), sh_project(img.float(), layout))

    @pytest.mark.parametrize("dt", HALF_AND_F32)
    def test_dtypes(self, dt):
        img = torch.rand(2, 3, 32, 32, dtype=F64)
        out = sh_project(img.to(dt))
        assert out.dtype == dt
        assert_close_dtype(out, sh_project(img.to(dt).to(F64)), dt, scale=4.0)  # |c| up to 4 pi

    def test_compile(self):
        img = torch.rand(2, 3, 16, 16)
        torch.testing.assert_close(torch.compile(sh_project)(img), sh_project(img))
        module = SHProject(16)
        torch.testing.assert_close(torch.compile(module)(img), module(img))


class TestShReconstruct:
    def test_smoke(self, device, dtype):
        sh = torch.zeros(1, 9, 3, device=device, dtype=dtype)
        sh[:, 0] = math.sqrt(4 * math.pi)  # uniform radiance 1
        img = sh_reconstruct(sh, 8)
        _, valid = mirror_ball_directions(8, device=device)
        torch.testing.assert_close(img[..., valid], torch.ones_like(img[..., valid]))
        assert (img[..., ~valid] == 0).all()

    @pytest.mark.parametrize(
        ("layout", "size", "hw"),
        [("mirror_ball", 4, (4, 4)), ("mirror_ball", 32, (32, 32)), ("latlong", 16, (16, 32))],
    )
    def test_cardinality(self, layout, size, hw):
        assert sh_reconstruct(torch.randn(3, 9, 3), size, layout).shape == (3, 3) + hw

    def test_values_at_pixel_centres(self):
        sh = torch.randn(2, 9, 3, dtype=F64)
        d, w = _grid("latlong", 8)
        expected = torch.einsum("nk,bkc->bcn", sh_basis(d), sh).reshape(2, 3, 8, 16)
        torch.testing.assert_close(sh_reconstruct(sh, 8, "latlong"), expected)

    def test_clamp_negative(self):
        sh = torch.zeros(1, 9, 3, dtype=F64)
        sh[:, 0], sh[:, 2] = 1.0, 2.0  # light from +Z, negative towards -Z
        exact = sh_reconstruct(sh, 16)
        clamped = sh_reconstruct(sh, 16, clamp_negative=True)
        assert exact.min() < 0 and clamped.min() == 0
        torch.testing.assert_close(clamped, exact.clamp(min=0))

    def test_exception(self):
        with pytest.raises(ShapeError, match=r"sh must have shape \(B, 9, 3\), got \(1, 4, 3\)"):
            sh_reconstruct(torch.zeros(1, 4, 3))
        with pytest.raises(ValueCheckError, match="size must be positive, got 0"):
            sh_reconstruct(torch.zeros(1, 9, 3), 0)
        with pytest.raises(TypeCheckError, match="size must be an int, got float"):
            sh_reconstruct(torch.zeros(1, 9, 3), 8.0)
        with pytest.raises(ValueCheckError, match="layout must be one of"):
            sh_reconstruct(torch.zeros(1, 9, 3), 8, "equirect")
        with pytest.raises(NonFiniteError, match="sh must be finite"):
            sh_reconstruct(torch.full((1, 9, 3), float("nan")))

    def test_gradcheck(self):
        sh = torch.randn(1, 9, 3, dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(lambda s: sh_reconstruct(s, 4, "latlong"), (sh,))
        assert torch.autograd.gradcheck(lambda s: sh_reconstruct(s, 6, clamp_negative=True), (sh,))

    @pytest.mark.parametrize(("layout", "clamp"), [("mirror_ball", False), ("latlong", True)])
    def test_module_matches_functional(self, layout, clamp):
        sh = torch.randn(2, 9, 3, dtype=F64)
        module = SHReconstruct(8, layout=layout, clamp_negative=clamp, dtype=F64)
        assert "basis" not in module.state_dict()
        torch.testing.assert_close(module(sh), sh_reconstruct(sh, 8, layout, clamp), atol=0, rtol=0)

    @pytest.mark.parametrize("dt", HALF_AND_F32)
    def test_dtypes(self, dt):
        sh = torch.randn(2, 9, 3, dtype=F64)
        out = sh_reconstruct(sh.to(dt), 16)
        assert out.dtype == dt
        assert_close_dtype(out, sh_reconstruct(sh.to(dt).to(F64), 16), dt, scale=4.0)

    def test_compile(self):
        sh = torch.randn(2, 9, 3)
        torch.testing.assert_close(torch.compile(sh_reconstruct)(sh, 8), sh_reconstruct(sh, 8))


class TestShIrradiance:
    def test_smoke(self, device, dtype):
        sh = torch.ones(1, 9, 3, device=device, dtype=dtype)
        a = sh_irradiance(sh)[0, :, 0]
        expected = torch.tensor(
            [math.pi] + [2 * math.pi / 3] * 3 + [math.pi / 4] * 5, device=device, dtype=dtype
        )
        torch.testing.assert_close(a, expected)

    def test_cardinality(self):
        assert sh_irradiance(torch.randn(5, 9, 3)).shape == (5, 9, 3)

    @given(st.floats(0.0, 1e4), st.sampled_from([("mirror_ball", 16), ("latlong", 8)]))
    def test_uniform_lighting_gives_pi_l(self, radiance, layout_size):
        layout, size = layout_size
        w = size if layout == "mirror_ball" else 2 * size
        sh = sh_project(torch.full((1, 3, size, w), radiance, dtype=F64), layout)
        normals = torch.nn.functional.normalize(torch.randn(1, 16, 3, dtype=F64), dim=-1)
        e = sh_irradiance_at(sh, normals)
        torch.testing.assert_close(
            e, torch.full_like(e, math.pi * radiance), atol=1e-9 * (1 + radiance), rtol=1e-12
        )

    @pytest.mark.parametrize(("layout", "size"), [("mirror_ball", 8), ("latlong", 4)])
    def test_irradiance_map(self, layout, size):
        """The irradiance map is sh_reconstruct(sh_irradiance(sh)): E at every pixel-centre normal."""
        sh = torch.randn(2, 9, 3, dtype=F64)
        d, w = _grid(layout, size)
        expected = sh_irradiance_at(sh, d[None]) * (w > 0)[None, :, None]
        got = sh_reconstruct(sh_irradiance(sh), size, layout).flatten(2).transpose(1, 2)
        torch.testing.assert_close(got, expected)

    def test_exception(self):
        with pytest.raises(ShapeError, match=r"sh must have shape \(B, 9, 3\), got \(9, 3\)"):
            sh_irradiance(torch.zeros(9, 3))
        with pytest.raises(TypeCheckError, match="sh must be a floating-point tensor"):
            sh_irradiance(torch.zeros(1, 9, 3, dtype=torch.int32))

    def test_gradcheck(self):
        sh = torch.randn(2, 9, 3, dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(sh_irradiance, (sh,))

    def test_module_matches_functional(self):
        sh = torch.randn(2, 9, 3)
        torch.testing.assert_close(SHIrradiance()(sh), sh_irradiance(sh), atol=0, rtol=0)

    @pytest.mark.parametrize("dt", HALF_AND_F32)
    def test_dtypes(self, dt):
        sh = torch.randn(2, 9, 3, dtype=F64)
        out = sh_irradiance(sh.to(dt))
        assert out.dtype == dt
        assert_close_dtype(out, sh_irradiance(sh.to(dt).to(F64)), dt, scale=4.0)

    def test_compile(self):
        sh = torch.randn(2, 9, 3)
        torch.testing.assert_close(torch.compile(sh_irradiance)(sh), sh_irradiance(sh))


class TestShIrradianceAt:
    def test_smoke(self, device, dtype):
        sh = torch.zeros(1, 9, 3, device=device, dtype=dtype)
        sh[:, 0] = math.sqrt(4 * math.pi)
        e = sh_irradiance_at(sh, torch.tensor([[[0.0, 1.0, 0.0]]], device=device, dtype=dtype))
        torch.testing.assert_close(e, torch.full((1, 1, 3), math.pi, device=device, dtype=dtype))

    def test_cardinality(self):
        assert sh_irradiance_at(torch.randn(4, 9, 3), torch.randn(4, 7, 3)).shape == (4, 7, 3)
        assert sh_irradiance_at(torch.randn(4, 9, 3), torch.randn(1, 7, 3)).shape == (4, 7, 3)

    def test_exception(self):
        with pytest.raises(
            ShapeError, match=r"normals must have batch size 1 or 4 \(that of sh\), got shape \(2, 7, 3\)"
        ):
            sh_irradiance_at(torch.randn(4, 9, 3), torch.randn(2, 7, 3))
        with pytest.raises(ShapeError, match=r"normals must have shape \(B, N, 3\), got \(7, 3\)"):
            sh_irradiance_at(torch.randn(4, 9, 3), torch.randn(7, 3))
        with pytest.raises(NonFiniteError, match="normals must be finite"):
            sh_irradiance_at(torch.randn(1, 9, 3), torch.full((1, 2, 3), float("nan")))

    def test_directional_light_is_truncated_clamped_cosine(self):
        """A delta light: E(n) = e * sum_l A_l (2l + 1) / (4 pi) P_l(n . d) (addition theorem), exactly."""
        torch.manual_seed(0)
        light = torch.nn.functional.normalize(torch.randn(3, dtype=F64), dim=0)
        sh = 2.5 * sh_basis(light)[None, :, None].expand(1, 9, 3)  # exact SH of a delta of energy 2.5
        n = torch.nn.functional.normalize(torch.randn(1, 200, 3, dtype=F64), dim=-1)
        t = n[0] @ light
        legendre = 0.25 + 0.5 * t + 0.3125 * (1.5 * t * t - 0.5)  # A_l (2l+1)/(4 pi) = 1/4, 1/2, 5/16
        torch.testing.assert_close(sh_irradiance_at(sh, n)[0, :, 0], 2.5 * legendre)
        # against the true clamped cosine: at most 0.094 E_0 off (reached at 90 degrees)
        err = (sh_irradiance_at(sh, n)[0, :, 0] - 2.5 * t.clamp(min=0)).abs().max().item()
        assert err <= 0.09375 * 2.5 + 1e-12

    @pytest.mark.parametrize(("layout", "size"), [("mirror_ball", 32), ("latlong", 32)])
    def test_cosine_lobe_lighting_against_numeric_integral(self, layout, size):
        """Lighting L(d) = max(0, d . l): order-2 irradiance vs sum_p L_p max(0, n . d_p) omega_p.

        Stated tolerance: 1% of the peak irradiance (2 pi / 3). Measured: 0.95% (mirror ball 32), 0.82%
        (lat-long 32); about 0.78% remains at fine grids (the lobe's irradiance above order 2).
        """
        torch.manual_seed(1)
        d, w = _grid(layout, size)
        worst = 0.0
        for _ in range(5):
            light = torch.nn.functional.normalize(torch.randn(3, dtype=F64), dim=0)
            radiance = (d @ light).clamp(min=0) * (w > 0)
            sh = sh_project(_image(radiance[None], layout, size), layout)
            n = torch.nn.functional.normalize(torch.randn(300, 3, dtype=F64), dim=-1)
            numeric = ((n @ d.T).clamp(min=0) * (radiance * w)).sum(-1)
            e = sh_irradiance_at(sh, n[None])[0]
            torch.testing.assert_close(e[:, 0], e[:, 2])
            worst = max(worst, (e[:, 0] - numeric).abs().max().item())
        assert worst < 0.01 * 2 * math.pi / 3

    def test_gradcheck(self):
        sh = torch.randn(2, 9, 3, dtype=F64, requires_grad=True)
        n = torch.randn(2, 5, 3, dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(sh_irradiance_at, (sh, n))

    def test_module_matches_functional(self):
        sh, n = torch.randn(2, 9, 3), torch.randn(2, 5, 3)
        torch.testing.assert_close(SHIrradianceAt()(sh, n), sh_irradiance_at(sh, n), atol=0, rtol=0)

    @pytest.mark.parametrize("dt", HALF_AND_F32)
    def test_dtypes(self, dt):
        sh, n = torch.randn(2, 9, 3, dtype=F64), torch.randn(2, 50, 3, dtype=F64)
        out = sh_irradiance_at(sh.to(dt), n.to(dt))
        assert out.dtype == dt
        assert_close_dtype(out, sh_irradiance_at(sh.to(dt).to(F64), n.to(dt).to(F64)), dt, scale=4.0)

    def test_compile(self):
        sh, n = torch.randn(2, 9, 3), torch.randn(2, 5, 3)
        torch.testing.assert_close(torch.compile(sh_irradiance_at)(sh, n), sh_irradiance_at(sh, n))
