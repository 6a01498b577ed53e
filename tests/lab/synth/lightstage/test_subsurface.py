"""Tests of kornia_ilum_lab.synth.lightstage.subsurface: linearity, energy, spread, no bleeding, errors."""

from __future__ import annotations

import pytest
import torch

from kornia_ilum.core.errors import NonFiniteError, ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum_lab.synth.lightstage.gbuffer import GBuffer
from kornia_ilum_lab.synth.lightstage.subsurface import (
    SKIN_RADII_MM,
    SubsurfaceScatter,
    _subsurface_reference,
    subsurface_operator,
    subsurface_scatter,
)

F64 = torch.float64


def flat_gbuffer(
    size: int, depth: float = 0.5, focal: float = 250.0, albedo: float | torch.Tensor = 0.5
) -> GBuffer:
    """A fronto-parallel skin patch filling the image: ``depth / focal`` m per pixel (2 mm by default)."""
    alb = albedo if isinstance(albedo, torch.Tensor) else torch.full((3, size, size), albedo)
    normal = torch.zeros(3, size, size)
    normal[2] = 1
    ones = torch.ones(1, size, size)
    return GBuffer(alb.float(), normal, ones * depth, ones.clone(), ones.clone(), focal_px=focal)


def random_gbuffer(size: int = 10, seed: int = 0) -> GBuffer:
    """Random buffers: textured albedo, bumpy depth, partial coverage, some pixels without skin."""
    g = torch.Generator().manual_seed(seed)
    albedo = 0.1 + 0.8 * torch.rand(3, size, size, generator=g)
    normal = torch.randn(3, size, size, generator=g)
    depth = 0.5 + 0.004 * torch.rand(1, size, size, generator=g)
    def rand() -> torch.Tensor:
        return torch.rand(1, size, size, generator=g)

    alpha = rand().clamp(0.3, 1.0) * (rand() > 0.1)
    skin = alpha * (rand() > 0.25) * rand().clamp(0.5, 1)
    return GBuffer(albedo, normal, depth * (alpha > 0), alpha, skin, focal_px=250.0)


def rms_spread_mm(img: torch.Tensor, size: int, mm_per_px: float) -> float:
    """RMS distance from the image centre of a non-negative ``(P,)`` image, in mm."""
    c = torch.arange(size, dtype=F64) - (size - 1) / 2
    r2 = c[:, None] ** 2 + c[None, :] ** 2
    w = img.reshape(size, size).double()
    return float((w * r2).sum() / w.sum()) ** 0.5 * mm_per_px


class TestSubsurfaceScatter:
    def test_smoke_and_cardinality(self) -> None:
        g = random_gbuffer()
        for dtype in (torch.float32, F64):
            d = torch.rand(3, 100, 7, dtype=dtype)
            out = subsurface_scatter(d, g)
            assert out.shape == d.shape and out.dtype == dtype
            assert torch.isfinite(out).all()

    def test_linearity(self) -> None:
        g = random_gbuffer(seed=1)
        gen = torch.Generator().manual_seed(2)
        r = torch.rand(3, 100, 9, dtype=F64, generator=gen)
        light = torch.rand(9, 3, dtype=F64, generator=gen) * 5
        relit_after = torch.einsum("cpn,nc->cp", subsurface_scatter(r, g), light)
        relit_before = subsurface_scatter(torch.einsum("cpn,nc->cp", r, light)[..., None], g)[..., 0]
        torch.testing.assert_close(relit_after, relit_before, atol=1e-12, rtol=1e-12)

    def test_matches_reference(self) -> None:
        g = random_gbuffer(size=8, seed=3)
        d = torch.rand(3, 64, 2, dtype=F64, generator=torch.Generator().manual_seed(4))
        for texturing in ("post", "pre_post"):
            torch.testing.assert_close(
                subsurface_scatter(d, g, texturing=texturing),
                _subsurface_reference(d, g, texturing=texturing),
                atol=1e-12,
                rtol=1e-12,
            )

    @pytest.mark.parametrize("texturing", ["post", "pre_post"])
    def test_energy_conserved(self, texturing: str) -> None:
        # sum over pixels of diffuse / m, m = max(albedo, eps) (its sqrt for pre_post), per channel and light
        g = random_gbuffer(seed=5)
        d = torch.rand(3, 100, 4, dtype=F64, generator=torch.Generator().manual_seed(6))
        out = subsurface_scatter(d, g, texturing=texturing)
        m = g.albedo.reshape(3, -1, 1).double().clamp_min(1e-3)
        m = m.sqrt() if texturing == "pre_post" else m
        torch.testing.assert_close((out / m).sum(1), (d / m).sum(1), atol=1e-11, rtol=1e-12)
        assert (out - d).abs().max() > 1e-3  # it did scatter

    def test_constant_albedo_keeps_pixel_sum(self) -> None:
        size = 16
        g = flat_gbuffer(size, albedo=0.45)
        d = torch.zeros(3, size * size, 1, dtype=F64)
        d[:, 8 * size + 3] = 1.0  # near the left border
        out = subsurface_scatter(d, g)
        torch.testing.assert_close(out.sum(1), d.sum(1), atol=1e-12, rtol=0)
        assert (out >= 0).all()

    def test_constant_irradiance_stays_constant_inside(self) -> None:
        size, margin = 32, 10  # red window radius: ceil(3 * 2.72 mm / 2 mm per px) = 5 px; twice that
        albedo = 0.3 + 0.4 * torch.rand(3, size, size, generator=torch.Generator().manual_seed(7))
        g = flat_gbuffer(size, albedo=albedo)
        d = (albedo.double() * 2.5).reshape(3, -1, 1)  # diffuse = albedo * constant irradiance
        out = subsurface_scatter(d, g).reshape(3, size, size)
        inner = (slice(None), slice(margin, size - margin), slice(margin, size - margin))
        torch.testing.assert_close(out[inner], d.reshape(3, size, size)[inner], atol=1e-12, rtol=1e-12)

    def test_red_spreads_wider_than_blue(self) -> None:
        size, mm = 33, 0.5  # 0.5 mm per pixel
        g = flat_gbuffer(size, depth=0.5, focal=1000.0)
        d = torch.zeros(3, size * size, 1, dtype=F64)
        d[:, (size // 2) * size + size // 2] = 1.0
        out = subsurface_scatter(d, g)[:, :, 0]
        spread = [rms_spread_mm(out[c], size, mm) for c in range(3)]
        assert spread[0] > spread[1] > spread[2] > 0
        # the measured RMS radius is the asked one (sampled on 0.5 mm pixels)
        for c in range(3):
            assert abs(spread[c] - SKIN_RADII_MM[c]) < 0.1 * SKIN_RADII_MM[c] + 0.1 * mm

    def test_wider_radii_spread_wider(self) -> None:
        size = 21  # 1 mm per pixel
        g = flat_gbuffer(size, depth=0.5, focal=500.0)
        d = torch.zeros(3, size * size, 1, dtype=F64)
        d[:, (size // 2) * size + size // 2] = 1.0
        narrow = subsurface_scatter(d, g)[:, :, 0]
        # Jensen et al. 2001's 1 / sigma_tr for skin1
        wide = subsurface_scatter(d, g, radii_mm=(3.67, 1.37, 0.68))[:, :, 0]
        for c in range(3):
            assert rms_spread_mm(wide[c], size, 1.0) > 1.2 * rms_spread_mm(narrow[c], size, 1.0)

    def test_no_bleeding_across_depth_step(self) -> None:
        size = 16
        g = flat_gbuffer(size)
        g.depth[:, :, size // 2 :] += 0.05  # a 5 cm step between the left and the right halves
        d = torch.zeros(3, size, size, 1, dtype=F64)
        d[:, :, : size // 2] = 1.0  # only the left half is lit
        out = subsurface_scatter(d.reshape(3, -1, 1), g).reshape(3, size, size)
        assert out[:, :, size // 2 :].abs().max() == 0
        torch.testing.assert_close(out[:, :, : size // 2].sum(), d.sum(), atol=1e-10, rtol=0)

    def test_no_bleeding_into_non_skin(self) -> None:
        size = 16
        g = flat_gbuffer(size)
        g.subsurface[:, :, size // 2 :] = 0  # the right half is hair: opaque, not skin
        d = torch.rand(3, size * size, 2, dtype=F64, generator=torch.Generator().manual_seed(8))
        out = subsurface_scatter(d, g).reshape(3, size, size, 2)
        torch.testing.assert_close(out[:, :, size // 2 :], d.reshape(3, size, size, 2)[:, :, size // 2 :],
                                   atol=0, rtol=0)
        assert (out[:, :, : size // 2] - d.reshape(3, size, size, 2)[:, :, : size // 2]).abs().max() > 1e-3

    def test_zero_radius_is_identity(self) -> None:
        g = random_gbuffer()
        d = torch.rand(3, 100, 2, dtype=F64)
        torch.testing.assert_close(subsurface_scatter(d, g, radii_mm=(0.0, 0.0, 0.0)), d, atol=0, rtol=0)

    def test_operator_reuse(self) -> None:
        g = random_gbuffer(seed=9)
        d = torch.rand(3, 100, 5, dtype=F64)
        op = subsurface_operator(g)
        torch.testing.assert_close(op.apply(d, chunk=2), subsurface_scatter(d, g), atol=1e-14, rtol=0)
        dense = op.dense()
        torch.testing.assert_close(torch.einsum("cpq,cqn->cpn", dense, d), op.apply(d), atol=1e-12, rtol=0)

    def test_module_equals_functional(self) -> None:
        g = random_gbuffer(seed=10)
        d = torch.rand(3, 100, 3)
        mod = SubsurfaceScatter(radii_mm=(2.0, 1.0, 0.5), texturing="pre_post")
        torch.testing.assert_close(
            mod(d, g), subsurface_scatter(d, g, radii_mm=(2.0, 1.0, 0.5), texturing="pre_post")
        )
        assert "pre_post" in repr(mod)

    def test_exceptions(self) -> None:
        g = random_gbuffer()
        with pytest.raises(ShapeError, match=r"\(3, P, N\)"):
            subsurface_scatter(torch.rand(2, 100, 3), g)
        with pytest.raises(ShapeError, match="P = 81"):
            subsurface_scatter(torch.rand(3, 81, 3), g)
        with pytest.raises(TypeCheckError, match="float32 or float64"):
            subsurface_scatter(torch.rand(3, 100, 3).bfloat16(), g)
        with pytest.raises(TypeCheckError, match="torch.Tensor"):
            subsurface_scatter([1.0], g)  # type: ignore[arg-type]
        bad = torch.rand(3, 100, 3)
        bad[0, 5, 1] = float("nan")
        with pytest.raises(NonFiniteError, match="diffuse"):
            subsurface_scatter(bad, g)
        with pytest.raises(TypeCheckError, match="GBuffer"):
            subsurface_scatter(torch.rand(3, 100, 3), "g")  # type: ignore[arg-type]
        broken = GBuffer(g.albedo[:2], g.normal, g.depth, g.alpha, g.subsurface, g.focal_px)
        with pytest.raises(ShapeError, match="gbuffer.albedo"):
            subsurface_scatter(torch.rand(3, 100, 3), broken)
        with pytest.raises(ValueCheckError, match="focal_px"):
            no_focal = GBuffer(g.albedo, g.normal, g.depth, g.alpha, g.subsurface, 0.0)
            subsurface_scatter(torch.rand(3, 100, 3), no_focal)
        with pytest.raises(TypeCheckError, match="radii_mm"):
            SubsurfaceScatter(radii_mm=(1.0, 2.0))  # type: ignore[arg-type]
        with pytest.raises(ValueCheckError, match="radii_mm"):
            subsurface_scatter(torch.rand(3, 100, 3), g, radii_mm=(1.0, -2.0, 0.5))
        with pytest.raises(ValueCheckError, match="texturing"):
            subsurface_scatter(torch.rand(3, 100, 3), g, texturing="pre")
        with pytest.raises(ValueCheckError, match="chunk"):
            subsurface_scatter(torch.rand(3, 100, 3), g, chunk=0)
