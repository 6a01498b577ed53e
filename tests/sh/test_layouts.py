"""Tests of kornia_ilum.sh.layouts: the SH layouts of DPR, SfSNet, DECA, ARCore and WebXR, and the table.

Each project's shading formula is restated from its own code, in its own axes, and compared with our
Lambertian shading ``E(n) / pi`` (:func:`kornia_ilum.sh.sh_irradiance_at`, docs/conventions.rst) of the
converted lighting on random normals, with the axis flips between their frames and ours applied to the
normals. The converters are plain functions without module twins (they are data-layout adapters, not
network ops), so the classes have no module test.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from kornia_ilum.core.errors import NonFiniteError, ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.geometry import mirror_ball_directions
from kornia_ilum.sh import (
    DPR_CHANNELS,
    sh_from_arcore,
    sh_from_deca,
    sh_from_dpr,
    sh_from_sfsnet,
    sh_from_webxr,
    sh_irradiance_at,
    sh_project,
    sh_to_arcore,
    sh_to_deca,
    sh_to_dpr,
    sh_to_sfsnet,
    sh_to_webxr,
)
from tests.conftest import assert_close_dtype

F64 = torch.float64
HALF_AND_F32 = [torch.float16, torch.bfloat16, torch.float32]

coeffs_f64 = st.lists(st.floats(-100, 100, allow_nan=False), min_size=27, max_size=27).map(
    lambda v: torch.tensor(v, dtype=F64).reshape(1, 9, 3)
)


def _light_from(direction: tuple[float, float, float], size: int = 32) -> torch.Tensor:
    """Our SH of a mirror ball lit by the few pixels within 20 degrees of ``direction``."""
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


def _seeded_normals(n: int = 400) -> torch.Tensor:
    """A fixed set of random unit normals, from their own generator."""
    g = torch.Generator().manual_seed(1)
    return torch.nn.functional.normalize(torch.randn(n, 3, generator=g, dtype=F64), dim=-1)


def _spec_shading(sh: torch.Tensor, n: torch.Tensor) -> np.ndarray:
    """Ours (docs/conventions.rst): a white Lambertian surface shows E(n) / pi; (B, N, 3)."""
    return (sh_irradiance_at(sh, n[None]) / math.pi).numpy()


# ---- DPR, utils/utils_SH.py (SH_basis, get_shading), in DPR's (shtools) axes -------------------------------
def _dpr_sh_basis(normal: np.ndarray) -> np.ndarray:
    x, y, z = normal[:, 0], normal[:, 1], normal[:, 2]
    att = np.pi * np.array([1, 2.0 / 3.0, 1 / 4.0])
    b = np.zeros((normal.shape[0], 9))
    b[:, 0] = 0.5 / np.sqrt(np.pi) * att[0]
    b[:, 1] = np.sqrt(3) / 2 / np.sqrt(np.pi) * y * att[1]
    b[:, 2] = np.sqrt(3) / 2 / np.sqrt(np.pi) * z * att[1]
    b[:, 3] = np.sqrt(3) / 2 / np.sqrt(np.pi) * x * att[1]
    b[:, 4] = np.sqrt(15) / 2 / np.sqrt(np.pi) * y * x * att[2]
    b[:, 5] = np.sqrt(15) / 2 / np.sqrt(np.pi) * y * z * att[2]
    b[:, 6] = np.sqrt(5) / 4 / np.sqrt(np.pi) * (3 * z**2 - 1) * att[2]
    b[:, 7] = np.sqrt(15) / 2 / np.sqrt(np.pi) * x * z * att[2]
    b[:, 8] = np.sqrt(15) / 4 / np.sqrt(np.pi) * (x**2 - y**2) * att[2]
    return b


def _dpr_get_shading(normal: np.ndarray, sh: np.ndarray) -> np.ndarray:
    return _dpr_sh_basis(normal) @ sh


def _spec_to_dpr_axes(n: np.ndarray) -> np.ndarray:
    """DPR / shtools: x right, y away from the camera, z up."""
    return np.stack([n[:, 0], -n[:, 2], n[:, 1]], -1)


def _dpr_half_sphere(size: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """testNetwork_demo_512.py's half sphere (DPR axes, image rows top to bottom) and its pixels' validity."""
    x = np.linspace(-1, 1, size)
    z = np.linspace(1, -1, size)
    x, z = np.meshgrid(x, z)
    valid = np.sqrt(x**2 + z**2) <= 1
    y = -np.sqrt(np.clip(1 - (x * valid) ** 2 - (z * valid) ** 2, 0, None))
    return np.stack([x * valid, y * valid, z * valid], -1), valid


# ---- SfSNet, SfSNet_train/python/Shading_Layer.py (forward), in SfSNet's axes ------------------------------
def _sfsnet_shading(normal: np.ndarray, light: np.ndarray) -> np.ndarray:
    """(N, 3) normals, (27,) light -> (N, 3) shading; light[j*9:(j+1)*9] shades channel j (R, G, B)."""
    att = np.pi * np.array([1, 2.0 / 3, 0.25])
    c1 = att[0] * (1.0 / np.sqrt(4 * np.pi))
    c2 = att[1] * (np.sqrt(3.0 / (4 * np.pi)))
    c3 = att[2] * 0.5 * (np.sqrt(5.0 / (4 * np.pi)))
    c4 = att[2] * (3.0 * (np.sqrt(5.0 / (12 * np.pi))))
    c5 = att[2] * (3.0 * (np.sqrt(5.0 / (48 * np.pi))))
    nx, ny, nz = normal[:, 0], normal[:, 1], normal[:, 2]
    h = [
        c1 * np.ones_like(nx),
        c2 * nz,
        c2 * nx,
        c2 * ny,
        c3 * (2 * nz * nz - nx * nx - ny * ny),
        c4 * nx * nz,
        c4 * ny * nz,
        c5 * (nx * nx - ny * ny),
        c4 * nx * ny,
    ]
    out = np.zeros((normal.shape[0], 3))
    for j in range(3):
        lj = light[j * 9 : (j + 1) * 9]
        out[:, j] = sum(lj[k] * h[k] for k in range(9))
    return out


def _spec_to_sfsnet_axes(n: np.ndarray) -> np.ndarray:
    """SfSNet: x down (image rows), y right (columns), z toward the camera."""
    return np.stack([-n[:, 1], n[:, 0], n[:, 2]], -1)


def _sfsnet_sphere_normals(size: int = 64, radius: int = 28) -> np.ndarray:
    """spherical_harmonics.py get_sphere_normals: x from the row index, y from the column index."""
    c = size // 2
    out = np.zeros((size, size, 3))
    for i in range(size):
        for j in range(size):
            x, y = (i - c) / radius, (j - c) / radius
            if 1 - x * x - y * y > 0:
                out[i, j] = (x, y, math.sqrt(1 - x * x - y * y))
    return out


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
        """A light from +Y lands on DECA's y coefficient (index 2), positive: DECA's frame is ours."""
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


class TestDpr:
    def test_smoke(self, device, dtype):
        sh = torch.randn(2, 9, 3, device=device, dtype=dtype)
        c = sh_to_dpr(sh)
        assert c.shape == (2, 9) and c.device == sh.device and c.dtype == dtype
        out = sh_from_dpr(c)
        assert out.shape == (2, 9, 3) and out.dtype == dtype

    def test_cardinality(self):
        assert sh_to_dpr(torch.randn(4, 9, 3), "r").shape == (4, 9)
        assert sh_from_dpr(torch.randn(4, 9)).shape == (4, 9, 3)

    @pytest.mark.parametrize("channel", list(DPR_CHANNELS))
    def test_matches_dpr_get_shading(self, channel):
        """DPR's get_shading (its axes) of the converted code == that channel of our E(n) / pi."""
        sh = torch.randn(3, 9, 3, dtype=F64)
        n = _seeded_normals()
        ours = _spec_shading(sh, n) @ np.array(DPR_CHANNELS[channel])  # (B, N)
        c = sh_to_dpr(sh, channel).numpy()
        theirs = np.stack([_dpr_get_shading(_spec_to_dpr_axes(n.numpy()), c[b]) for b in range(3)])
        np.testing.assert_allclose(theirs, ours, atol=1e-12, rtol=1e-12)

    def test_from_dpr_matches_dpr_half_sphere(self):
        """DPR's demo half sphere, shaded by DPR, equals our shading of sh_from_dpr on the same pixels."""
        c = np.random.default_rng(0).normal(size=9)
        normal, valid = _dpr_half_sphere()
        theirs = _dpr_get_shading(normal[valid], c)
        # the demo's pixels in our axes: X = x, Y = z, Z = -y (toward the camera: the visible half)
        spec_n = torch.from_numpy(
            np.stack([normal[valid][:, 0], normal[valid][:, 2], -normal[valid][:, 1]], -1)
        )
        assert (spec_n[:, 2] >= 0).all()  # DPR's visible half sphere faces our camera (+Z)
        top = normal[1, normal.shape[1] // 2]  # (row 0 lies just outside the disk)
        assert top[2] > 0.9  # DPR's image top is its +z: up
        ours = _spec_shading(sh_from_dpr(torch.from_numpy(c)[None]), spec_n)[0]
        for ch in range(3):
            np.testing.assert_allclose(ours[:, ch], theirs, atol=1e-12, rtol=1e-12)

    @pytest.mark.parametrize(
        ("direction", "index", "sign"),
        [((0, 1, 0), 2, 1.0), ((0, 0, 1), 1, -1.0), ((0, 0, -1), 1, 1.0), ((1, 0, 0), 3, 1.0)],
    )
    def test_known_light(self, direction, index, sign):
        """Light from above lands on DPR's z (index 2); from the camera on its -y (index 1, negative)."""
        c = sh_to_dpr(_light_from(direction))[0]
        assert c[1:4].abs().argmax().item() + 1 == index
        assert math.copysign(1.0, c[index].item()) == sign
        assert c[0] > 0

    @given(coeffs_f64)
    def test_round_trip(self, sh):
        grey = sh.mean(-1, keepdim=True).expand(-1, -1, 3)
        for ch in ("r", "g", "b"):
            torch.testing.assert_close(sh_to_dpr(sh_from_dpr(sh_to_dpr(grey, ch)), ch), sh_to_dpr(grey, ch))
        torch.testing.assert_close(sh_from_dpr(sh_to_dpr(grey, "luminance")), grey, atol=1e-10, rtol=1e-12)
        c = sh[:, :, 0]
        torch.testing.assert_close(sh_to_dpr(sh_from_dpr(c)), c, atol=1e-10, rtol=1e-12)

    def test_luminance_of_colour(self):
        sh = torch.randn(2, 9, 3, dtype=F64)
        w = torch.tensor(DPR_CHANNELS["luminance"], dtype=F64)
        torch.testing.assert_close(sh_to_dpr(sh), sh_to_dpr((sh @ w)[..., None].expand(-1, -1, 3), "r"))

    def test_exception(self):
        with pytest.raises(ShapeError, match=r"sh must have shape \(B, 9, 3\), got \(1, 9\)"):
            sh_to_dpr(torch.zeros(1, 9))
        with pytest.raises(ShapeError, match=r"coefficients must have shape \(B, 9\), got \(1, 9, 1, 1\)"):
            sh_from_dpr(torch.zeros(1, 9, 1, 1))
        with pytest.raises(ValueCheckError, match="channel"):
            sh_to_dpr(torch.zeros(1, 9, 3), "grey")
        with pytest.raises(NonFiniteError, match="coefficients must be finite"):
            sh_from_dpr(torch.full((1, 9), float("inf")))

    def test_gradcheck(self):
        sh = torch.randn(2, 9, 3, dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(sh_to_dpr, (sh,))
        c = torch.randn(2, 9, dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(sh_from_dpr, (c,))

    @pytest.mark.parametrize("dt", HALF_AND_F32)
    def test_dtypes(self, dt):
        sh = torch.randn(2, 9, 3, dtype=F64)
        out = sh_to_dpr(sh.to(dt))
        assert out.dtype == dt
        assert_close_dtype(out, sh_to_dpr(sh.to(dt).to(F64)), dt)
        back = sh_from_dpr(out)
        assert back.dtype == dt
        assert_close_dtype(back, sh_from_dpr(out.to(F64)), dt, scale=4.0)

    def test_compile(self):
        sh = torch.randn(2, 9, 3)
        torch.testing.assert_close(torch.compile(sh_to_dpr)(sh), sh_to_dpr(sh))
        c = torch.randn(2, 9)
        torch.testing.assert_close(torch.compile(sh_from_dpr)(c), sh_from_dpr(c))


class TestSfsnet:
    def test_smoke(self, device, dtype):
        sh = torch.randn(2, 9, 3, device=device, dtype=dtype)
        light = sh_to_sfsnet(sh)
        assert light.shape == (2, 27) and light.device == sh.device and light.dtype == dtype
        torch.testing.assert_close(sh_from_sfsnet(light), sh)

    def test_cardinality(self):
        assert sh_to_sfsnet(torch.randn(5, 9, 3)).shape == (5, 27)
        assert sh_from_sfsnet(torch.randn(5, 27)).shape == (5, 9, 3)

    def test_matches_sfsnet_shading_layer(self):
        """SfSNet's Shading_Layer (its axes) of the converted 27 values == our E(n) / pi, per channel."""
        sh = torch.randn(3, 9, 3, dtype=F64)
        n = _seeded_normals()
        ours = _spec_shading(sh, n)
        light = sh_to_sfsnet(sh).numpy()
        theirs = np.stack([_sfsnet_shading(_spec_to_sfsnet_axes(n.numpy()), light[b]) for b in range(3)])
        np.testing.assert_allclose(theirs, ours, atol=1e-12, rtol=1e-12)

    def test_from_sfsnet_matches_sfsnet_sphere(self):
        """SfSNet's demo sphere: its row axis is our -Y (down), its column axis +X, its z +Z."""
        light = np.random.default_rng(2).normal(size=27)
        normal = _sfsnet_sphere_normals()
        valid = np.abs(normal).sum(-1) > 0
        theirs = _sfsnet_shading(normal[valid], light)
        rows, cols = np.nonzero(valid)
        c = normal.shape[0] // 2
        # our normal of pixel (row, col) of a sphere seen from +Z: X grows to the right, Y grows upwards
        x, y = (cols - c) / 28, -(rows - c) / 28
        spec_n = torch.from_numpy(np.stack([x, y, np.sqrt(1 - x * x - y * y)], -1))
        ours = _spec_shading(sh_from_sfsnet(torch.from_numpy(light)[None]), spec_n)[0]
        np.testing.assert_allclose(ours, theirs, atol=1e-12, rtol=1e-12)

    def test_channel_major(self):
        sh = torch.zeros(1, 9, 3)
        sh[0, 0] = torch.tensor([1.0, 2.0, 3.0])
        light = sh_to_sfsnet(sh)[0] * math.pi
        torch.testing.assert_close(light[[0, 9, 18]], torch.tensor([1.0, 2.0, 3.0]))

    @pytest.mark.parametrize(
        ("direction", "index", "sign"),
        [((0, 1, 0), 2, -1.0), ((0, -1, 0), 2, 1.0), ((1, 0, 0), 3, 1.0), ((0, 0, 1), 1, 1.0)],
    )
    def test_known_light(self, direction, index, sign):
        """Light from above is light from SfSNet's -x (index 2, negative); from the right its +y (3)."""
        light = sh_to_sfsnet(_light_from(direction))[0, 9:18]  # green
        assert light[1:4].abs().argmax().item() + 1 == index
        assert math.copysign(1.0, light[index].item()) == sign
        assert light[0] > 0

    @given(coeffs_f64)
    def test_round_trip(self, sh):
        torch.testing.assert_close(sh_from_sfsnet(sh_to_sfsnet(sh)), sh, atol=1e-12, rtol=1e-14)
        flat = sh.reshape(1, 27)
        torch.testing.assert_close(sh_to_sfsnet(sh_from_sfsnet(flat)), flat, atol=1e-12, rtol=1e-14)

    def test_exception(self):
        with pytest.raises(ShapeError, match=r"light must have shape \(B, 27\), got \(27,\)"):
            sh_from_sfsnet(torch.zeros(27))
        with pytest.raises(ShapeError, match=r"sh must have shape \(B, 9, 3\), got \(1, 27\)"):
            sh_to_sfsnet(torch.zeros(1, 27))

    def test_gradcheck(self):
        sh = torch.randn(2, 9, 3, dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(sh_to_sfsnet, (sh,))
        light = torch.randn(2, 27, dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(sh_from_sfsnet, (light,))

    @pytest.mark.parametrize("dt", HALF_AND_F32)
    def test_dtypes(self, dt):
        sh = torch.randn(2, 9, 3, dtype=F64)
        out = sh_to_sfsnet(sh.to(dt))
        assert out.dtype == dt
        assert_close_dtype(out, sh_to_sfsnet(sh.to(dt).to(F64)), dt)
        assert_close_dtype(sh_from_sfsnet(out), sh.to(dt), dt, scale=4.0)

    def test_compile(self):
        sh = torch.randn(2, 9, 3)
        torch.testing.assert_close(torch.compile(sh_to_sfsnet)(sh), sh_to_sfsnet(sh))
        light = torch.randn(2, 27)
        torch.testing.assert_close(torch.compile(sh_from_sfsnet)(light), sh_from_sfsnet(light))


class TestAcrossLayouts:
    def test_same_lighting_same_shading(self):
        """One lighting of ours through DPR (grey), SfSNet and DECA gives the same white-surface shading."""
        sh = torch.randn(1, 9, 1, dtype=F64).expand(-1, -1, 3)
        n = _seeded_normals(100)
        spec = sh_from_sfsnet(sh_to_sfsnet(sh))
        torch.testing.assert_close(sh_from_dpr(sh_to_dpr(sh)), spec)
        torch.testing.assert_close(sh_from_deca(sh_to_deca(sh)), spec)
        dpr = _dpr_get_shading(_spec_to_dpr_axes(n.numpy()), sh_to_dpr(sh)[0].numpy())
        sfs = _sfsnet_shading(_spec_to_sfsnet_axes(n.numpy()), sh_to_sfsnet(sh)[0].numpy())[:, 0]
        np.testing.assert_allclose(dpr, sfs, atol=1e-12, rtol=1e-12)

    def test_arcore_is_spec_up_to_signs(self):
        sh = torch.randn(1, 9, 3, dtype=F64)
        assert torch.equal(sh_to_arcore(sh).reshape(1, 9, 3).abs(), sh.abs())
