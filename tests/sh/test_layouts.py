"""Tests of kornia_ilum.sh.layouts: DECA, ARCore and WebXR SH layouts.

The converters are plain functions without module twins (they are data-layout adapters, not network ops),
so the classes have no module test.
"""

from __future__ import annotations

import math

import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from kornia_ilum.core.errors import NonFiniteError, ShapeError, TypeCheckError
from kornia_ilum.geometry import mirror_ball_directions
from kornia_ilum.sh import (
    sh_from_arcore,
    sh_from_deca,
    sh_from_webxr,
    sh_irradiance_at,
    sh_project,
    sh_to_arcore,
    sh_to_deca,
    sh_to_webxr,
)
from tests.conftest import assert_close_dtype

F64 = torch.float64
HALF_AND_F32 = [torch.float16, torch.bfloat16, torch.float32]

coeffs_f64 = st.lists(st.floats(-100, 100, allow_nan=False), min_size=27, max_size=27).map(
    lambda v: torch.tensor(v, dtype=F64).reshape(1, 9, 3)
)


def _light_from(direction: tuple[float, float, float], size: int = 32) -> torch.Tensor:
    """SPEC SH of a mirror ball lit by the few pixels within 20 degrees of ``direction``."""
    d, valid = mirror_ball_directions(size, dtype=F64)
    axis = torch.tensor(direction, dtype=F64)
    lit = ((d @ axis) > math.cos(math.radians(20))) & valid
    img = torch.zeros(1, 3, size, size, dtype=F64)
    img[..., lit] = 10.0
    return sh_project(img)


def _normals(n: int = 300) -> torch.Tensor:
    torch.manual_seed(0)
    return torch.nn.functional.normalize(torch.randn(n, 3, dtype=F64), dim=-1)


def _deca_add_shlight(normals: torch.Tensor, light: torch.Tensor) -> torch.Tensor:
    """DECA's SRenderY.add_SHlight (decalib/utils/renderer.py), restated for (N, 3) normals -> (B, N, 3)."""
    pi = math.pi
    constant_factor = torch.tensor(
        [
            1 / math.sqrt(4 * pi),
            ((2 * pi) / 3) * math.sqrt(3 / (4 * pi)),
            ((2 * pi) / 3) * math.sqrt(3 / (4 * pi)),
            ((2 * pi) / 3) * math.sqrt(3 / (4 * pi)),
            (pi / 4) * 3 * math.sqrt(5 / (12 * pi)),
            (pi / 4) * 3 * math.sqrt(5 / (12 * pi)),
            (pi / 4) * 3 * math.sqrt(5 / (12 * pi)),
            (pi / 4) * (3 / 2) * math.sqrt(5 / (12 * pi)),
            (pi / 4) * (1 / 2) * math.sqrt(5 / (4 * pi)),
        ],
        dtype=F64,
    )
    x, y, z = normals.unbind(-1)
    sh = torch.stack([x * 0 + 1, x, y, z, x * y, x * z, y * z, x**2 - y**2, 3 * z**2 - 1], -1)
    return torch.einsum("nk,k,bkc->bnc", sh, constant_factor, light)


def _arcore_sample_shader(normals: torch.Tensor, coefficients: torch.Tensor) -> torch.Tensor:
    """ARCore hello_ar_java: coefficients * sphericalHarmonicFactors, then environmental_hdr.frag."""
    factors = torch.tensor(
        [0.282095, -0.325735, 0.325735, -0.325735, 0.273137, -0.273137, 0.078848, -0.273137, 0.136569],
        dtype=F64,
    )
    c = coefficients.reshape(coefficients.shape[0], 9, 3) * factors[:, None]
    x, y, z = normals.unbind(-1)
    poly = torch.stack([x * 0 + 1, y, z, x, y * x, y * z, 3 * z * z - 1, z * x, x * x - y * y], -1)
    return torch.einsum("nk,bkc->bnc", poly, c)


class TestDeca:
    def test_smoke(self, device, dtype):
        sh = torch.randn(2, 9, 3, device=device, dtype=dtype)
        light = sh_to_deca(sh)
        assert light.device == sh.device and light.dtype == dtype
        torch.testing.assert_close(sh_from_deca(light), sh)

    def test_cardinality(self):
        assert sh_to_deca(torch.randn(4, 9, 3)).shape == (4, 9, 3)
        assert sh_from_deca(torch.randn(4, 9, 3)).shape == (4, 9, 3)

    def test_matches_deca_renderer(self):
        """DECA's shading of the converted code is what a white Lambertian surface shows: E(n) / pi."""
        sh = torch.randn(3, 9, 3, dtype=F64)
        n = _normals()
        torch.testing.assert_close(
            _deca_add_shlight(n, sh_to_deca(sh)), sh_irradiance_at(sh, n[None]) / math.pi
        )

    @pytest.mark.parametrize(
        ("direction", "index"),
        [((0, 1, 0), 2), ((0, -1, 0), 2), ((1, 0, 0), 1), ((0, 0, 1), 3), ((0, 0, -1), 3)],
    )
    def test_known_light(self, direction, index):
        """A light from +Y lands on DECA's y coefficient (index 2), positive: DECA's frame is SPEC's."""
        light = sh_to_deca(_light_from(direction))[0, :, 0]
        band1 = light[1:4].abs()
        assert band1.argmax().item() + 1 == index
        assert math.copysign(1.0, light[index].item()) == sum(direction)
        assert light[0] > 0

    @given(coeffs_f64)
    def test_round_trip(self, sh):
        torch.testing.assert_close(sh_from_deca(sh_to_deca(sh)), sh, atol=1e-12, rtol=1e-15)
        torch.testing.assert_close(sh_to_deca(sh_from_deca(sh)), sh, atol=1e-12, rtol=1e-15)

    def test_exception(self):
        with pytest.raises(ShapeError, match=r"sh must have shape \(B, 9, 3\), got \(1, 27\)"):
            sh_to_deca(torch.zeros(1, 27))
        with pytest.raises(ShapeError, match=r"light must have shape \(B, 9, 3\), got \(9, 3\)"):
            sh_from_deca(torch.zeros(9, 3))
        with pytest.raises(NonFiniteError, match="light must be finite"):
            sh_from_deca(torch.full((1, 9, 3), float("nan")))

    def test_gradcheck(self):
        sh = torch.randn(2, 9, 3, dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(sh_to_deca, (sh,))
        assert torch.autograd.gradcheck(sh_from_deca, (sh,))

    @pytest.mark.parametrize("dt", HALF_AND_F32)
    def test_dtypes(self, dt):
        sh = torch.randn(2, 9, 3, dtype=F64)
        out = sh_to_deca(sh.to(dt))
        assert out.dtype == dt
        assert_close_dtype(out, sh_to_deca(sh.to(dt).to(F64)), dt)
        assert_close_dtype(sh_from_deca(out), sh.to(dt), dt, scale=4.0)

    def test_compile(self):
        sh = torch.randn(2, 9, 3)
        torch.testing.assert_close(torch.compile(sh_to_deca)(sh), sh_to_deca(sh))
        torch.testing.assert_close(torch.compile(sh_from_deca)(sh), sh_from_deca(sh))


class TestArcore:
    def test_smoke(self, device, dtype):
        sh = torch.randn(2, 9, 3, device=device, dtype=dtype)
        x = sh_to_arcore(sh)
        assert x.shape == (2, 27) and x.dtype == dtype and x.device == sh.device
        torch.testing.assert_close(sh_from_arcore(x), sh, atol=0, rtol=0)

    def test_cardinality(self):
        assert sh_to_arcore(torch.randn(5, 9, 3)).shape == (5, 27)
        assert sh_from_arcore(torch.randn(5, 27)).shape == (5, 9, 3)

    def test_interleaved_rgb_per_coefficient(self):
        sh = torch.arange(27.0).reshape(1, 9, 3)
        x = sh_to_arcore(sh)[0]
        assert x[:3].tolist() == [0.0, 1.0, 2.0]  # c0 = (r, g, b)
        assert x[3:6].tolist() == [-3.0, -4.0, -5.0]  # c1 = (r, g, b), Condon-Shortley sign

    def test_matches_arcore_sample_shader(self):
        """ARCore's sample (factors * sign-free polynomials) yields E(n) / pi from the converted array."""
        sh = torch.randn(3, 9, 3, dtype=F64)
        n = _normals()
        torch.testing.assert_close(
            _arcore_sample_shader(n, sh_to_arcore(sh)),
            sh_irradiance_at(sh, n[None]) / math.pi,
            atol=3e-6,
            rtol=1e-5,
        )  # the sample's factors have 6 significant digits

    @pytest.mark.parametrize(
        ("direction", "index", "sign"), [((0, 1, 0), 1, -1.0), ((0, 0, 1), 2, 1.0), ((1, 0, 0), 3, -1.0)]
    )
    def test_known_light(self, direction, index, sign):
        """A light from +Y lands on ARCore coefficient 1 with a negative sign (Condon-Shortley phase)."""
        x = sh_to_arcore(_light_from(direction))[0].reshape(9, 3)[:, 1]  # green channel
        assert x[1:4].abs().argmax().item() + 1 == index
        assert math.copysign(1.0, x[index].item()) == sign

    @given(coeffs_f64)
    def test_round_trip(self, sh):
        torch.testing.assert_close(sh_from_arcore(sh_to_arcore(sh)), sh, atol=0, rtol=0)
        flat = sh.reshape(1, 27)
        torch.testing.assert_close(sh_to_arcore(sh_from_arcore(flat)), flat, atol=0, rtol=0)

    def test_exception(self):
        with pytest.raises(ShapeError, match=r"coefficients must have shape \(B, 27\), got \(27,\)"):
            sh_from_arcore(torch.zeros(27))
        with pytest.raises(ShapeError, match=r"coefficients must have shape \(B, 27\), got \(1, 9, 3\)"):
            sh_from_arcore(torch.zeros(1, 9, 3))
        with pytest.raises(TypeCheckError, match="sh must be a floating-point tensor"):
            sh_to_arcore(torch.zeros(1, 9, 3, dtype=torch.int64))

    def test_gradcheck(self):
        sh = torch.randn(2, 9, 3, dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(sh_to_arcore, (sh,))
        x = torch.randn(2, 27, dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(sh_from_arcore, (x,))

    @pytest.mark.parametrize("dt", HALF_AND_F32)
    def test_dtypes(self, dt):
        sh = torch.randn(2, 9, 3, dtype=F64).to(dt)
        out = sh_to_arcore(sh)
        assert out.dtype == dt
        torch.testing.assert_close(sh_from_arcore(out), sh, atol=0, rtol=0)  # signs only: exact

    def test_compile(self):
        sh = torch.randn(2, 9, 3)
        torch.testing.assert_close(torch.compile(sh_to_arcore)(sh), sh_to_arcore(sh))
        x = torch.randn(2, 27)
        torch.testing.assert_close(torch.compile(sh_from_arcore)(x), sh_from_arcore(x))


class TestWebxr:
    def test_smoke(self):
        sh = torch.randn(2, 9, 3)
        torch.testing.assert_close(sh_from_webxr(sh_to_webxr(sh)), sh, atol=0, rtol=0)

    def test_is_arcore(self):
        """Chromium copies ARCore's 27 floats into WebXR unchanged: the converters are aliases."""
        assert sh_to_webxr is sh_to_arcore and sh_from_webxr is sh_from_arcore

    def test_known_light(self):
        x = sh_to_webxr(_light_from((0, 1, 0)))[0]
        assert (x[3:6] < 0).all()  # C1-1, RGB: light from +Y is negative

    def test_cardinality(self):
        assert sh_to_webxr(torch.randn(3, 9, 3)).shape == (3, 27)
