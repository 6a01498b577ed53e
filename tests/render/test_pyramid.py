"""Tests of kornia_ilum.render.pyramid, and of the multi-scale rule in the renders and the loss.

The rule is that of docs/conventions.rst, "Multi-scale".
"""

from __future__ import annotations

import pytest
import torch

from kornia_ilum.core.errors import ShapeError, ValueCheckError
from kornia_ilum.geometry import mirror_ball_solid_angles, mirror_ball_valid
from kornia_ilum.geometry.mirror_ball import _rim_pixels
from kornia_ilum.metrics import (
    MultiscaleReconstructionLoss,
    ReconstructionLoss,
    multiscale_reconstruction_loss,
    reconstruction_loss,
)
from kornia_ilum.render import (
    BRDFS,
    MIRROR_REFLECTIVITY,
    MirrorBallPyramid,
    encode_sphere,
    mirror_ball_downsample_matrix,
    mirror_ball_pyramid,
    render_spheres,
    sphere_pyramid,
    sphere_reflectance_field,
)
from tests.conftest import hdr_lighting

F64 = torch.float64


def _energy(x: torch.Tensor) -> torch.Tensor:
    return (x * mirror_ball_solid_angles(x.shape[-1], dtype=x.dtype)).sum((-2, -1))


class TestMirrorBallPyramid:
    @pytest.mark.parametrize("size", [8, 16, 32, 64])
    def test_energy_kept_at_every_level(self, size):
        """sum(L omega) per channel is the same at every level, for random lighting and single pixels,
        rim pixels (which own the slivers) included."""
        lighting = hdr_lighting(2, s=size, seed=3, dtype=F64)
        sizes = tuple(s for s in (4, 8, 16, 32, 64) if s <= size)
        for s, level in mirror_ball_pyramid(lighting, sizes).items():
            torch.testing.assert_close(_energy(level), _energy(lighting), rtol=1e-12, atol=0)
        # every single fine pixel, interior and rim: the columns of D weighted by the coarse solid angles
        for s in sizes:
            d = mirror_ball_downsample_matrix(size, s, dtype=F64)
            kept = mirror_ball_solid_angles(s, dtype=F64).flatten() @ d
            omega = mirror_ball_solid_angles(size, dtype=F64).flatten()
            torch.testing.assert_close(kept, omega, rtol=1e-12, atol=1e-15)

    @pytest.mark.parametrize("size", [8, 16, 32])
    def test_block_mean_inside_the_rim(self, size):
        lighting = hdr_lighting(1, s=size, seed=5, dtype=F64)
        coarse = mirror_ball_pyramid(lighting, (size // 2,))[size // 2]
        blocks = torch.nn.functional.avg_pool2d(lighting, 2)
        inner = mirror_ball_valid(size // 2) & ~_rim_pixels(size // 2)
        torch.testing.assert_close(coarse[..., inner], blocks[..., inner], rtol=1e-13, atol=0)
        assert (coarse[..., ~mirror_ball_valid(size // 2)] == 0).all()

    def test_constant_stays_constant(self):
        lighting = torch.ones(1, 1, 32, 32, dtype=F64)
        for s, level in mirror_ball_pyramid(lighting, (4, 8, 16)).items():
            values = level[0, 0][mirror_ball_valid(s)]
            torch.testing.assert_close(values, torch.ones_like(values), rtol=4e-4, atol=0)

    def test_chained_halvings(self):
        d = mirror_ball_downsample_matrix(32, 4, dtype=F64)
        chain = (
            mirror_ball_downsample_matrix(8, 4, dtype=F64)
            @ mirror_ball_downsample_matrix(16, 8, dtype=F64)
            @ mirror_ball_downsample_matrix(32, 16, dtype=F64)
        )
        torch.testing.assert_close(d, chain, rtol=0, atol=1e-15)

    def test_identity_level_gradcheck_and_module(self):
        lighting = hdr_lighting(1, s=8, seed=1, dtype=F64).requires_grad_()
        out = mirror_ball_pyramid(lighting, (8, 4))
        assert out[8] is lighting and list(out) == [8, 4]
        assert torch.autograd.gradcheck(lambda x: mirror_ball_pyramid(x, (4,))[4], (lighting,))
        module = MirrorBallPyramid((4, 16))
        x = hdr_lighting(2, seed=2)
        for s, level in module(x).items():
            torch.testing.assert_close(level, mirror_ball_pyramid(x, (s,))[s])

    def test_exception(self):
        with pytest.raises(ValueCheckError, match="must not exceed"):
            mirror_ball_pyramid(torch.ones(1, 3, 16, 16), (32,))
        with pytest.raises(ShapeError):
            mirror_ball_pyramid(torch.ones(1, 3, 12, 12), (4,))
        with pytest.raises(ValueCheckError, match="sizes must name"):
            mirror_ball_pyramid(torch.ones(1, 3, 16, 16), ())


def _one_bright_pixel(row: int = 16, col: int = 16) -> tuple[torch.Tensor, torch.Tensor]:
    gt = torch.ones(1, 3, 32, 32) * mirror_ball_valid(32)
    pred = gt.clone()
    pred[0, :, row, col] = 50.0
    return pred, gt


class TestMultiscaleSpheres:
    @pytest.mark.parametrize("pixel", [(16, 16), (3, 20), (0, 15)])  # centre, off-centre, rim
    def test_coarse_mirror_sees_a_single_pixel(self, pixel):
        """Regression (issue 11): the 4, 8 and 16 px mirror spheres point-sampled the 32 px lighting."""
        pred, gt = _one_bright_pixel(*pixel)
        for s in (4, 8, 16, 32):
            assert reconstruction_loss(pred, gt, brdf="mirror", size=s).item() > 0
            assert ReconstructionLoss("mirror", size=s, gamma="safe")(pred, gt).item() > 0
        # and the mirror render keeps the energy of the lighting at every size
        for s in (4, 8, 16):
            render = render_spheres(pred.double(), s, ("mirror",))["mirror"]
            torch.testing.assert_close(
                _energy(render), MIRROR_REFLECTIVITY * _energy(pred.double()), rtol=1e-10, atol=0
            )

    @pytest.mark.parametrize("brdf", BRDFS)
    @pytest.mark.parametrize("size", [4, 8, 16])
    def test_rendered_from_the_pyramid(self, brdf, size):
        lighting = hdr_lighting(2, seed=7, dtype=F64)
        level = mirror_ball_pyramid(lighting, (size,))[size]
        direct = render_spheres(lighting, size, (brdf,))[brdf]
        if brdf == "mirror":  # the mirror at size == lighting_size is the lighting itself
            torch.testing.assert_close(direct, MIRROR_REFLECTIVITY * level)
        else:  # the coarse field R(s, s) on the coarse level, to the accuracy of its 8 x 8 samples per
            # coarse pixel (2.3 % at s = 4; the multi-scale field integrates with the fine samples instead)
            coarse = render_spheres(level, size, (brdf,))[brdf]
            torch.testing.assert_close(direct, coarse, rtol=3e-2, atol=0)
        field = sphere_reflectance_field(brdf, size, lighting_size=32, multiscale=True, dtype=F64)
        torch.testing.assert_close(direct.flatten(2), torch.einsum("pn,bcn->bcp", field, lighting.flatten(2)))

    def test_sphere_pyramid_is_what_the_loss_compares(self):
        pred, target = hdr_lighting(2, seed=1, dtype=F64), hdr_lighting(2, seed=2, dtype=F64)
        sizes = (4, 8, 16, 32)
        for gamma in ("exact", "safe"):
            a = sphere_pyramid(pred, sizes=sizes, gamma=gamma)
            b = sphere_pyramid(target, sizes=sizes, gamma=gamma)
            for brdf in BRDFS:
                per_scale = []
                for s in sizes:
                    valid = mirror_ball_valid(s)
                    diff = (a[f"{brdf}_{s}"] - b[f"{brdf}_{s}"]).abs()[..., valid].mean((1, 2))
                    per_scale.append(diff)
                    assert (a[f"{brdf}_{s}"][..., ~valid] == 0).all()
                    loss = reconstruction_loss(pred, target, brdf=brdf, size=s, reduction="none", gamma=gamma)
                    torch.testing.assert_close(diff, loss)
                expected = torch.stack(per_scale).mean(0)
                got = multiscale_reconstruction_loss(
                    pred, target, brdf=brdf, sizes=sizes, reduction="none", gamma=gamma
                )
                torch.testing.assert_close(got, expected)
                module = MultiscaleReconstructionLoss(
                    brdf, sizes=sizes, reduction="none", gamma=gamma
                ).double()
                torch.testing.assert_close(module(pred, target), expected)
        linear = sphere_pyramid(pred, sizes=(8,), brdfs=("diffuse",), encode=False)["diffuse_8"]
        torch.testing.assert_close(linear, render_spheres(pred, 8, ("diffuse",))["diffuse"])
        encoded = sphere_pyramid(pred, sizes=(8,), brdfs=("diffuse",))["diffuse_8"]
        torch.testing.assert_close(encoded, encode_sphere(linear) * mirror_ball_valid(8))


class TestNegativesAndGamma:
    def test_negative_lighting_counts_as_zero(self):
        """docs/conventions.rst: L_rec(-0.1, 1, diffuse) = mean |0 - softclip(0.8)^(1/2.2)| = 0.90
        (was 43.6)."""
        gt = torch.ones(2, 3, 32, 32)
        loss = reconstruction_loss(-0.1 * gt, gt, brdf="diffuse")
        assert loss.item() == pytest.approx(0.9031, abs=2e-4)
        safe = reconstruction_loss(-0.1 * gt, gt, brdf="diffuse", gamma="safe")
        assert safe.item() == pytest.approx(0.9031, abs=2e-4)
        assert multiscale_reconstruction_loss(-0.1 * gt, 0 * gt, brdf="mirror").item() == 0.0

    def test_exact_gamma_on_dark_scenes(self):
        """The metric uses the exact power; the training form is within 1e-3 of it (5.3e-4 at worst)."""
        x = torch.logspace(-12, 0, 20001, dtype=F64)
        exact = encode_sphere(x)
        small = x < 0.1  # soft_clip is the identity to 1e-9 there
        torch.testing.assert_close(exact[small], x[small].pow(1 / 2.2), rtol=1e-7, atol=0)
        assert (encode_sphere(x, "safe") - exact).abs().max().item() < 6e-4
        dark = 1e-7 * hdr_lighting(2, seed=4, dtype=F64)
        render = render_spheres(dark, 32, ("diffuse",))["diffuse"]
        ref = render.clamp(min=0).pow(1 / 2.2)[..., mirror_ball_valid(32)]
        loss = reconstruction_loss(dark, 0 * dark, brdf="diffuse", reduction="none")
        torch.testing.assert_close(loss, ref.mean((1, 2)), rtol=1e-6, atol=0)

    def test_safe_gradient_is_finite_at_zero(self):
        x = torch.tensor([-1.0, 0.0, 1e-9, 0.5], dtype=F64, requires_grad=True)
        encode_sphere(x, "safe").sum().backward()
        assert torch.isfinite(x.grad).all() and x.grad[1].item() > 0
        x.grad = None
        encode_sphere(x, "exact").sum().backward()
        assert torch.isfinite(x.grad).all()

    def test_exception(self):
        gt = torch.ones(1, 3, 32, 32)
        with pytest.raises(ValueCheckError, match="gamma must be one of"):
            reconstruction_loss(gt, gt, brdf="diffuse", gamma="approx")
        with pytest.raises(ValueCheckError, match="gamma must be one of"):
            sphere_pyramid(gt, gamma="fast")
