"""Tests of kornia_ilum.metrics.lighting: L_rec (single and multi-scale) and relative radiance."""

from __future__ import annotations

import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from kornia_ilum.color import gamma_encode
from kornia_ilum.core.errors import NonFiniteError, ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.filters import soft_clip
from kornia_ilum.geometry import mirror_ball_solid_angles, mirror_ball_valid
from kornia_ilum.metrics import (
    MultiscaleReconstructionLoss,
    ReconstructionLoss,
    RelativeRadiance,
    TotalRadiance,
    multiscale_reconstruction_loss,
    reconstruction_loss,
    relative_radiance,
    total_radiance,
)
from kornia_ilum.render import BRDFS, render_spheres
from tests.conftest import assert_close_dtype, hdr_lighting

F64 = torch.float64


def _l_rec_reference(pred, target, brdf, size):
    """The definition of docs/conventions.rst, written out from render_spheres and the transfer functions."""
    valid = mirror_ball_valid(size)
    a = gamma_encode(soft_clip(render_spheres(pred, size, (brdf,))[brdf]), 2.2)
    b = gamma_encode(soft_clip(render_spheres(target, size, (brdf,))[brdf]), 2.2)
    return (a - b).abs()[..., valid].mean((1, 2))


def test_loss_modules_keep_float64_exact():
    """float64 inputs are not rounded through the modules' float32 buffers (issue 24)."""
    pred, target = hdr_lighting(2, seed=1, dtype=F64), hdr_lighting(2, seed=2, dtype=F64)
    expected = reconstruction_loss(pred, target, brdf="mirror", size=16).item()
    assert ReconstructionLoss("mirror", size=16)(pred, target).item() == expected
    assert (MultiscaleReconstructionLoss("diffuse")(pred, target).item()
            == multiscale_reconstruction_loss(pred, target, brdf="diffuse").item())


class TestReconstructionLoss:
    def test_smoke(self, device, dtype):
        pred = hdr_lighting(seed=1, dtype=dtype).to(device)
        target = hdr_lighting(seed=2, dtype=dtype).to(device)
        loss = reconstruction_loss(pred, target, brdf="diffuse")
        assert loss.shape == () and loss.dtype == dtype and loss.device == pred.device
        assert loss.item() > 0

    @pytest.mark.parametrize("brdf", BRDFS)
    @pytest.mark.parametrize("size", [4, 16, 32])
    def test_cardinality(self, brdf, size):
        pred, target = hdr_lighting(3, seed=1, dtype=F64), hdr_lighting(3, seed=2, dtype=F64)
        per_item = reconstruction_loss(pred, target, brdf=brdf, size=size, reduction="none")
        assert per_item.shape == (3,)
        torch.testing.assert_close(per_item, _l_rec_reference(pred, target, brdf, size))
        torch.testing.assert_close(reconstruction_loss(pred, target, brdf=brdf, size=size), per_item.mean())
        torch.testing.assert_close(
            reconstruction_loss(pred, target, brdf=brdf, size=size, reduction="sum"), per_item.sum()
        )

    def test_other_lighting_sizes(self):
        pred, target = hdr_lighting(s=16, seed=1), hdr_lighting(s=16, seed=2)
        assert reconstruction_loss(pred, target, brdf="mirror", size=8).item() > 0

    def test_exception(self):
        pred = hdr_lighting()
        with pytest.raises(ShapeError, match=r"pred and target must have the same shape"):
            reconstruction_loss(pred, pred[:1], brdf="diffuse")
        with pytest.raises(ShapeError, match=r"target must have shape \(B, 3, S, S\)"):
            reconstruction_loss(pred, pred[:, :1], brdf="diffuse")
        with pytest.raises(ValueCheckError, match="brdf must be one of"):
            reconstruction_loss(pred, pred, brdf="velvet")
        with pytest.raises(ValueCheckError, match=r"reduction must be one of \('mean', 'sum', 'none'\)"):
            reconstruction_loss(pred, pred, brdf="diffuse", reduction="max")
        with pytest.raises(ValueCheckError, match="size must be one of"):
            reconstruction_loss(pred, pred, brdf="diffuse", size=33)
        with pytest.raises(NonFiniteError, match="pred must be finite"):
            reconstruction_loss(pred.log() * 0 + float("inf"), pred, brdf="diffuse")
        with pytest.raises(TypeCheckError, match="target must be a floating-point tensor"):
            reconstruction_loss(pred, pred.long(), brdf="diffuse")
        with pytest.raises(ShapeError, match=r"pred must have shape \(B, 3, 32, 32\), got \(2, 3, 16, 16\)"):
            ReconstructionLoss("diffuse")(pred[..., :16, :16], pred[..., :16, :16])

    def test_gradcheck(self):
        pred = (hdr_lighting(1, s=4, seed=1, dtype=F64) + 0.05).requires_grad_()
        target = hdr_lighting(1, s=4, seed=2, dtype=F64)
        for brdf in BRDFS:
            assert torch.autograd.gradcheck(
                lambda p, b=brdf: reconstruction_loss(p, target, brdf=b, size=4), (pred,)
            )

    def test_finite_gradient_on_black(self):
        """The training form ("safe") has a useful gradient at black; the metric's ("exact") is finite too."""
        pred = torch.zeros(1, 3, 32, 32, requires_grad=True)
        reconstruction_loss(pred, hdr_lighting(1), brdf="matte_silver", gamma="safe").backward()
        assert torch.isfinite(pred.grad).all() and pred.grad.abs().sum() > 0
        pred.grad = None
        reconstruction_loss(pred, hdr_lighting(1), brdf="matte_silver").backward()
        assert torch.isfinite(pred.grad).all()

    @pytest.mark.parametrize("brdf", BRDFS)
    def test_module_matches_functional(self, brdf):
        pred, target = hdr_lighting(seed=1), hdr_lighting(seed=2)
        module = ReconstructionLoss(brdf, size=16, reduction="none")
        torch.testing.assert_close(
            module(pred, target), reconstruction_loss(pred, target, brdf=brdf, size=16, reduction="none")
        )
        assert not module.state_dict()

    @pytest.mark.parametrize("dt", [torch.float16, torch.bfloat16, torch.float32])
    def test_dtypes(self, dt):
        pred, target = hdr_lighting(seed=1, dtype=F64), hdr_lighting(seed=2, dtype=F64)
        expected = reconstruction_loss(pred, target, brdf="matte_silver", reduction="none")
        out = reconstruction_loss(pred.to(dt), target.to(dt), brdf="matte_silver", reduction="none")
        assert out.dtype == dt
        assert_close_dtype(out, expected, dt)
        module = ReconstructionLoss("matte_silver", reduction="none").to(dt)
        assert_close_dtype(module(pred.to(dt), target.to(dt)), expected, dt)

    def test_compile(self):
        pred, target = hdr_lighting(seed=1), hdr_lighting(seed=2)
        compiled = torch.compile(reconstruction_loss)
        torch.testing.assert_close(
            compiled(pred, target, brdf="diffuse", size=8),
            reconstruction_loss(pred, target, brdf="diffuse", size=8),
        )

    @given(st.integers(0, 2**16), st.sampled_from(BRDFS), st.sampled_from([4, 8, 32]))
    def test_zero_for_identical_lightings(self, seed, brdf, size):
        x = hdr_lighting(2, seed=seed)
        assert reconstruction_loss(x, x, brdf=brdf, size=size).item() == 0.0

    @given(st.integers(0, 2**16), st.sampled_from(BRDFS))
    def test_symmetric_and_bounded(self, seed, brdf):
        """|a - b| of values in [0, 1]: symmetric, in [0, 1]."""
        a, b = hdr_lighting(2, s=8, seed=seed, dtype=F64), hdr_lighting(2, s=8, seed=seed + 1, dtype=F64)
        ab = reconstruction_loss(a, b, brdf=brdf, size=8, reduction="none")
        torch.testing.assert_close(ab, reconstruction_loss(b, a, brdf=brdf, size=8, reduction="none"))
        assert (ab >= 0).all() and (ab <= 1).all()


class TestMultiscaleReconstructionLoss:
    def test_smoke(self):
        pred, target = hdr_lighting(seed=1), hdr_lighting(seed=2)
        loss = multiscale_reconstruction_loss(pred, target, brdf="diffuse")
        assert loss.shape == () and loss.item() > 0

    @pytest.mark.parametrize("sizes", [(4, 8, 16, 32), (32,), (8, 64)])
    def test_cardinality(self, sizes):
        pred, target = hdr_lighting(3, seed=1, dtype=F64), hdr_lighting(3, seed=2, dtype=F64)
        out = multiscale_reconstruction_loss(pred, target, brdf="mirror", sizes=sizes, reduction="none")
        assert out.shape == (3,)
        per_scale = [
            reconstruction_loss(pred, target, brdf="mirror", size=s, reduction="none") for s in sizes
        ]
        torch.testing.assert_close(out, torch.stack(per_scale).mean(0))

    def test_exception(self):
        pred = hdr_lighting()
        with pytest.raises(ValueCheckError, match="sizes must name at least one"):
            multiscale_reconstruction_loss(pred, pred, brdf="diffuse", sizes=())
        with pytest.raises(ValueCheckError, match=r"sizes must be one of \(4, 8, 16, 32, 64\), got 5"):
            multiscale_reconstruction_loss(pred, pred, brdf="diffuse", sizes=(4, 5))
        with pytest.raises(ValueCheckError, match="brdf must be one of"):
            MultiscaleReconstructionLoss("glass")

    def test_gradcheck(self):
        pred = (hdr_lighting(1, s=4, seed=1, dtype=F64) + 0.05).requires_grad_()
        target = hdr_lighting(1, s=4, seed=2, dtype=F64)
        fn = lambda p: multiscale_reconstruction_loss(p, target, brdf="matte_silver", sizes=(4, 8))
        assert torch.autograd.gradcheck(fn, (pred,))

    def test_module_matches_functional(self):
        pred, target = hdr_lighting(seed=1), hdr_lighting(seed=2)
        module = MultiscaleReconstructionLoss("diffuse", sizes=(4, 16))
        torch.testing.assert_close(
            module(pred, target), multiscale_reconstruction_loss(pred, target, brdf="diffuse", sizes=(4, 16))
        )

    @pytest.mark.parametrize("dt", [torch.float16, torch.bfloat16, torch.float32])
    def test_dtypes(self, dt):
        pred, target = hdr_lighting(seed=1, dtype=F64), hdr_lighting(seed=2, dtype=F64)
        expected = multiscale_reconstruction_loss(pred, target, brdf="mirror", reduction="none")
        out = multiscale_reconstruction_loss(pred.to(dt), target.to(dt), brdf="mirror", reduction="none")
        assert out.dtype == dt
        assert_close_dtype(out, expected, dt)

    def test_compile(self):
        pred, target = hdr_lighting(seed=1), hdr_lighting(seed=2)
        compiled = torch.compile(MultiscaleReconstructionLoss("diffuse", sizes=(4, 8)))
        expected = multiscale_reconstruction_loss(pred, target, brdf="diffuse", sizes=(4, 8))
        torch.testing.assert_close(compiled(pred, target), expected)

    @given(st.integers(0, 2**16))
    def test_zero_for_identical_lightings(self, seed):
        x = hdr_lighting(1, seed=seed)
        assert multiscale_reconstruction_loss(x, x, brdf="matte_silver").item() == 0.0


class TestRelativeRadiance:
    def test_smoke(self, device, dtype):
        target = hdr_lighting(dtype=dtype).to(device)
        out = relative_radiance(0.5 * target, target)
        assert out.shape == (2, 3) and out.dtype == dtype and out.device == target.device
        torch.testing.assert_close(out, torch.full_like(out, 0.5))

    @pytest.mark.parametrize("b, s", [(1, 4), (3, 16), (2, 32)])
    def test_cardinality(self, b, s):
        pred, target = hdr_lighting(b, s, seed=1, dtype=F64), hdr_lighting(b, s, seed=2, dtype=F64)
        omega = mirror_ball_solid_angles(s, dtype=F64)
        sum_gt, sum_pred = (target * omega).sum((-2, -1)), (pred * omega).sum((-2, -1))
        torch.testing.assert_close(relative_radiance(pred, target), (sum_gt - sum_pred) / sum_gt)

    def test_solid_angle_weighting(self):
        """Light moved from an interior pixel to a rim pixel of smaller solid angle loses radiance."""
        omega = mirror_ball_solid_angles(8, dtype=F64)
        target = torch.zeros(1, 3, 8, 8, dtype=F64)
        target[..., 4, 4] = 1.0
        pred = torch.zeros_like(target)
        pred[..., 0, 2] = 1.0
        expected = 1 - omega[0, 2] / omega[4, 4]
        torch.testing.assert_close(relative_radiance(pred, target), expected.expand(1, 3))

    def test_exception(self):
        target = hdr_lighting()
        with pytest.raises(
            ValueCheckError, match="target must have a positive total radiance in every channel"
        ):
            relative_radiance(target, target * torch.tensor([1.0, 0.0, 1.0])[:, None, None])
        with pytest.raises(ValueCheckError, match="target must be non-negative"):
            relative_radiance(target, target - 1.0)
        with pytest.raises(ShapeError, match="pred and target must have the same shape"):
            relative_radiance(target[:1], target)
        with pytest.raises(NonFiniteError, match="pred must be finite"):
            relative_radiance(target * float("nan"), target)

    def test_gradcheck(self):
        pred = hdr_lighting(1, 4, seed=1, dtype=F64).requires_grad_()
        target = (hdr_lighting(1, 4, seed=2, dtype=F64) + 0.1).requires_grad_()
        assert torch.autograd.gradcheck(relative_radiance, (pred, target))

    def test_module_matches_functional(self):
        pred, target = hdr_lighting(seed=1), hdr_lighting(seed=2)
        torch.testing.assert_close(RelativeRadiance()(pred, target), relative_radiance(pred, target))

    @pytest.mark.parametrize("dt", [torch.float16, torch.bfloat16, torch.float32])
    def test_dtypes(self, dt):
        pred, target = hdr_lighting(seed=1, dtype=F64), hdr_lighting(seed=2, dtype=F64)
        out = relative_radiance(pred.to(dt), target.to(dt))
        assert out.dtype == dt
        assert_close_dtype(out, relative_radiance(pred, target), dt)
        # a float16 sun whose total would overflow a float16 sum
        sun = torch.zeros(1, 3, 32, 32)
        sun[..., 16, 16] = 6e4
        sun[..., 16, 15] = 6e4
        assert torch.isfinite(relative_radiance(sun.half(), sun.half())).all()

    def test_compile(self):
        pred, target = hdr_lighting(seed=1), hdr_lighting(seed=2)
        torch.testing.assert_close(
            torch.compile(relative_radiance)(pred, target), relative_radiance(pred, target)
        )

    @given(st.integers(0, 2**16), st.floats(0.0, 100.0, allow_nan=False))
    def test_scaling(self, seed, k):
        """x vs x is 0, k x vs x is 1 - k (2x gives -1: the estimate added light)."""
        x = hdr_lighting(2, 8, seed=seed, dtype=F64)
        assert relative_radiance(x, x).abs().max().item() == 0.0
        torch.testing.assert_close(relative_radiance(k * x, x), torch.full((2, 3), 1.0 - k, dtype=F64))
        torch.testing.assert_close(relative_radiance(2 * x, x), torch.full((2, 3), -1.0, dtype=F64))


class TestTotalRadiance:
    @pytest.mark.parametrize("dtype", [None, F64])
    def test_module_matches_functional(self, dtype):
        x = hdr_lighting(2, seed=3)
        torch.testing.assert_close(TotalRadiance(dtype)(x), total_radiance(x, dtype), rtol=0.0, atol=0.0)
        assert TotalRadiance(dtype)(x.half()).dtype == (torch.float16 if dtype is None else dtype)


def test_lighting_energy_is_the_mean_of_total_radiance_and_has_a_twin() -> None:
    from kornia_ilum.metrics import LightingEnergy, lighting_energy, total_radiance

    x = torch.rand(4, 3, 32, 32, dtype=torch.float64)
    torch.testing.assert_close(lighting_energy(x), total_radiance(x).mean(-1))
    assert torch.equal(LightingEnergy()(x), lighting_energy(x))
