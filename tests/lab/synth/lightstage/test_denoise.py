"""Tests of kornia_ilum_lab.synth.lightstage.denoise: linearity, constants, noise, edges, texture, errors."""

from __future__ import annotations

import pytest
import torch

from kornia_ilum.core.errors import NonFiniteError, ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum_lab.synth.lightstage.denoise import (
    DenoiseField,
    _denoise_reference,
    denoise_field,
    denoise_operator,
)
from kornia_ilum_lab.synth.lightstage.gbuffer import GBuffer

F64 = torch.float64
SIZE = 24


def flat_gbuffer(size: int = SIZE, albedo: float | torch.Tensor = 0.5, depth: float = 0.5) -> GBuffer:
    """A fronto-parallel opaque patch filling the image."""
    alb = albedo if isinstance(albedo, torch.Tensor) else torch.full((3, size, size), albedo)
    normal = torch.zeros(3, size, size)
    normal[2] = 1
    ones = torch.ones(1, size, size)
    no_skin = torch.zeros(1, size, size)
    return GBuffer(alb.float(), normal, ones * depth, ones.clone(), no_skin, focal_px=250.0)


def random_gbuffer(size: int = 10, seed: int = 0) -> GBuffer:
    g = torch.Generator().manual_seed(seed)
    albedo = 0.1 + 0.8 * torch.rand(3, size, size, generator=g)
    normal = torch.randn(3, size, size, generator=g) * 0.2 + torch.tensor([0.0, 0.0, 1.0])[:, None, None]
    depth = 0.5 + 0.01 * torch.rand(1, size, size, generator=g)
    alpha = torch.rand(1, size, size, generator=g).clamp(0.3, 1.0)
    alpha = alpha * (torch.rand(1, size, size, generator=g) > 0.1)
    return GBuffer(albedo, normal, depth * (alpha > 0), alpha, alpha.clone(), focal_px=250.0)


def as_field(img: torch.Tensor) -> torch.Tensor:
    """``(3, H, W, N)`` -> ``(3, H*W, N)``."""
    return img.reshape(3, -1, img.shape[-1])


class TestDenoiseField:
    def test_smoke_and_cardinality(self) -> None:
        g = random_gbuffer()
        for dtype in (torch.float32, F64):
            f = torch.rand(3, 100, 6, dtype=dtype)
            out = denoise_field(f, g)
            assert out.shape == f.shape and out.dtype == dtype and torch.isfinite(out).all()

    def test_linearity(self) -> None:
        g = random_gbuffer(seed=1)
        gen = torch.Generator().manual_seed(2)
        r = torch.rand(3, 100, 9, dtype=F64, generator=gen)
        light = torch.rand(9, 3, dtype=F64, generator=gen) * 5
        for it in (1, 2):
            after = torch.einsum("cpn,nc->cp", denoise_field(r, g, iterations=it), light)
            before = denoise_field(torch.einsum("cpn,nc->cp", r, light)[..., None], g, iterations=it)[..., 0]
            torch.testing.assert_close(after, before, atol=1e-12, rtol=1e-12)

    def test_matches_reference(self) -> None:
        g = random_gbuffer(seed=3)
        f = torch.rand(3, 100, 2, dtype=F64, generator=torch.Generator().manual_seed(4))
        for kw in ({}, {"iterations": 2}, {"demodulate": False, "radius": 1}):
            ref = _denoise_reference(f, g, **kw)
            torch.testing.assert_close(denoise_field(f, g, **kw), ref, atol=1e-12, rtol=1e-12)

    def test_constant_stays_constant(self) -> None:
        g = random_gbuffer(seed=5)
        alpha = g.alpha.reshape(1, -1, 1).double()
        # a constant irradiance: field = albedo * alpha * E stays exactly the same, whatever the albedo
        irradiance = torch.tensor([1.0, 2.0, 3.0], dtype=F64)[:, None, None]
        f = g.albedo.reshape(3, -1, 1).double() * alpha * irradiance
        torch.testing.assert_close(denoise_field(f, g, iterations=3), f, atol=1e-12, rtol=1e-12)
        # without demodulation, a constant radiance (times alpha) does
        c = alpha.expand(3, -1, 4) * 0.7
        torch.testing.assert_close(denoise_field(c, g, demodulate=False), c, atol=1e-12, rtol=1e-12)

    def test_noise_variance_drops(self) -> None:
        g = flat_gbuffer()
        noise = 0.1 * torch.randn(3, SIZE * SIZE, 8, dtype=F64, generator=torch.Generator().manual_seed(6))
        f = 0.5 * (1.0 + noise)
        inner = torch.zeros(3, SIZE, SIZE, 8, dtype=torch.bool)
        inner[:, 4:-4, 4:-4] = True
        var0 = f.reshape(3, SIZE, SIZE, 8)[inner].var()
        var1 = denoise_field(f, g).reshape(3, SIZE, SIZE, 8)[inner].var()
        var3 = denoise_field(f, g, iterations=3).reshape(3, SIZE, SIZE, 8)[inner].var()
        assert var1 < var0 / 8  # measured 20x for white noise (5 x 5 taps, sigma 1.5); 3 iterations: 400x
        assert var3 < var1 / 3

    @pytest.mark.parametrize("edge", ["albedo", "normal", "depth"])
    def test_edge_preserved(self, edge: str) -> None:
        g = flat_gbuffer()
        half = slice(SIZE // 2, None)
        if edge == "albedo":
            g.albedo[:, :, half] = 0.1  # 0.5 | 0.1
        elif edge == "normal":
            g.normal[0, :, half], g.normal[2, :, half] = 0.7071, 0.7071  # 45 degrees
        else:
            g.depth[:, :, half] += 0.05  # a 5 cm step
        irr = torch.ones(3, SIZE, SIZE, 1, dtype=F64)
        irr[:, :, half] = 4.0  # a different irradiance on each side
        f = as_field(g.albedo.double()[..., None] * irr)
        out = denoise_field(f, g)
        # a 45-degree crease has weight exp(-0.765^2 / (2 * 0.2^2)) = 7e-4; the others ~1e-6 or less
        assert ((out - f).abs() / f).max() < (3e-3 if edge == "normal" else 1e-4)
        # the same field on an edge-free G-buffer does blur across
        assert (denoise_field(f, flat_gbuffer(albedo=g.albedo)) - f).abs().max() > 0.1 or edge == "albedo"

    def test_texture_preserved(self) -> None:
        # albedo variations within sigma_albedo
        tex = 0.45 + 0.1 * torch.rand(3, SIZE, SIZE, generator=torch.Generator().manual_seed(7))
        g = flat_gbuffer(albedo=tex)
        f = as_field(g.albedo.double()[..., None] * 2.0)  # a textured surface under a constant irradiance
        torch.testing.assert_close(denoise_field(f, g), f, atol=1e-12, rtol=1e-12)
        blurred = denoise_field(f, g, demodulate=False)  # filtering the radiance itself blurs the texture
        assert (blurred - f).abs().max() > 0.02

    def test_background_untouched(self) -> None:
        g = random_gbuffer(seed=8)
        f = torch.rand(3, 100, 3, dtype=F64)
        out = denoise_field(f, g)
        bg = g.alpha.reshape(-1) == 0
        assert bg.any()
        torch.testing.assert_close(out[:, bg], f[:, bg], atol=0, rtol=0)

    def test_operator_reuse_and_radius_zero(self) -> None:
        g = random_gbuffer(seed=9)
        f = torch.rand(3, 100, 5, dtype=F64)
        op = denoise_operator(g, iterations=2)
        direct = denoise_field(f, g, iterations=2)
        torch.testing.assert_close(op.apply(f, chunk=2), direct, atol=1e-14, rtol=0)
        torch.testing.assert_close(denoise_field(f, g, radius=0), f, atol=0, rtol=0)

    def test_module_equals_functional(self) -> None:
        g = random_gbuffer(seed=10)
        f = torch.rand(3, 100, 3)
        mod = DenoiseField(radius=1, sigma_spatial=2.0, iterations=2, demodulate=False)
        torch.testing.assert_close(
            mod(f, g), denoise_field(f, g, radius=1, sigma_spatial=2.0, iterations=2, demodulate=False)
        )
        assert "iterations=2" in repr(mod)

    def test_exceptions(self) -> None:
        g = random_gbuffer()
        with pytest.raises(ShapeError, match=r"\(3, P, N\)"):
            denoise_field(torch.rand(3, 100), g)
        with pytest.raises(ShapeError, match="P = 100"):
            denoise_field(torch.rand(3, 99, 2), g)
        with pytest.raises(TypeCheckError, match="float32 or float64"):
            denoise_field(torch.ones(3, 100, 2, dtype=torch.int32), g)
        bad = torch.rand(3, 100, 2)
        bad[1, 3, 0] = float("inf")
        with pytest.raises(NonFiniteError, match="field"):
            denoise_field(bad, g)
        nan_depth = GBuffer(g.albedo, g.normal, g.depth * float("nan"), g.alpha, g.subsurface, g.focal_px)
        with pytest.raises(NonFiniteError, match="gbuffer.depth"):
            denoise_field(torch.rand(3, 100, 2), nan_depth)
        with pytest.raises(ValueCheckError, match="sigma_depth"):
            denoise_field(torch.rand(3, 100, 2), g, sigma_depth=0.0)
        with pytest.raises(ValueCheckError, match="iterations"):
            DenoiseField(iterations=0)
        with pytest.raises(ValueCheckError, match="radius"):
            denoise_field(torch.rand(3, 100, 2), g, radius=-1)
