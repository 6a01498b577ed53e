"""Tests of kornia_ilum.filters.soft_clip.

docs/conventions.rst, L_rec: a smooth, monotone, differentiable min(x, 1).
"""

from __future__ import annotations

import math

import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from kornia_ilum.core.errors import NonFiniteError, TypeCheckError, ValueCheckError
from kornia_ilum.filters import SoftClip, soft_clip
from tests.conftest import assert_close_dtype

F64 = torch.float64
HALF_AND_F32 = [torch.float16, torch.bfloat16, torch.float32]


class TestSoftClip:
    def test_smoke(self, device, dtype):
        x = torch.tensor([0.0, 0.5, 1.0, 1e6], device=device, dtype=dtype)
        y = soft_clip(x)
        assert y.shape == x.shape and y.dtype == dtype and y.device == x.device
        beta = 20.0
        c = math.log1p(math.exp(-beta)) / beta
        # f(1) = 1 - ln 2 / beta, up to the (tiny) normalisation c
        assert y[2].item() == pytest.approx((1 - math.log(2) / beta + c) / (1 + c), rel=1e-6)
        assert y[3].item() == 1.0

    @pytest.mark.parametrize("shape", [(5,), (2, 3, 4, 4), (1, 1, 1, 1, 7)])
    def test_cardinality(self, shape):
        assert soft_clip(torch.rand(shape)).shape == shape

    def test_zero_maps_to_zero(self, dtype):
        assert soft_clip(torch.zeros(3, dtype=dtype)).abs().max().item() == 0.0

    @pytest.mark.parametrize("beta", [5.0, 20.0, 100.0])
    def test_identity_below_the_knee(self, beta):
        """|f(x) - x| <= exp(-beta (1 - x)) / beta for x in [0, 1] (the documented bound)."""
        x = torch.linspace(0, 1, 1001, dtype=F64)
        err = (soft_clip(x, beta) - x).abs()
        assert (err <= torch.exp(-beta * (1 - x)) / beta + 1e-15).all()
        small = torch.linspace(0, 0.5, 101, dtype=F64)
        torch.testing.assert_close(soft_clip(small, beta), small, atol=math.exp(-beta / 2) / beta, rtol=0)

    def test_saturates_to_one(self):
        x = torch.tensor([2.0, 10.0, 1e3, 1e30, float("inf")], dtype=F64)
        y = soft_clip(x)
        assert (y <= 1).all() and y[1:].eq(1).all()
        assert 1 - y[0].item() < math.exp(-20) / 20 * 1.01

    @given(
        st.lists(st.floats(0.0, 1e6, allow_nan=False), min_size=2, max_size=64),
        st.sampled_from(HALF_AND_F32),
        st.sampled_from([1.0, 20.0, 200.0]),
    )
    def test_monotone_and_bounded(self, values, dt, beta):
        x = torch.tensor(sorted(values), dtype=F64).to(dt)  # 1e6 becomes inf in float16
        y = soft_clip(x, beta)
        assert y.dtype == dt
        assert (y.diff() >= 0).all()  # non-decreasing (strictly increasing in exact arithmetic)
        assert (y >= 0).all() and (y <= 1).all()
        assert torch.isfinite(y).all()

    def test_strictly_increasing_below_saturation(self):
        x = torch.linspace(0, 1.5, 20001, dtype=F64)
        assert (soft_clip(x).diff() > 0).all()

    @pytest.mark.parametrize("dt", HALF_AND_F32 + [F64])
    def test_finite_gradients_everywhere(self, dt):
        x = torch.tensor([0.0, 1e-6, 0.5, 1.0, 1.0001, 2.0, 60.0, 1e3, 1e6, float("inf")], dtype=F64)
        x = x.to(dt).requires_grad_()  # in float16, 1e6 is inf
        soft_clip(x).sum().backward()
        assert torch.isfinite(x.grad).all()
        assert (x.grad >= 0).all() and (x.grad <= 1 + 1e-3).all()
        assert x.grad[-1].item() == 0.0  # inf maps to 1 with zero gradient

    def test_exception(self):
        with pytest.raises(NonFiniteError, match="x must not hold NaN"):
            soft_clip(torch.tensor([0.5, float("nan")]))
        for bad in (0.0, -1.0, float("nan"), float("inf"), "20"):
            with pytest.raises(ValueCheckError, match="sharpness must be a finite positive number"):
                soft_clip(torch.tensor([0.5]), bad)
        with pytest.raises(ValueCheckError, match="sharpness must be a finite positive number, got -2"):
            SoftClip(-2)(torch.tensor([0.5]))
        with pytest.raises(TypeCheckError, match="x must be a floating-point tensor"):
            soft_clip(torch.tensor([1, 2]))
        with pytest.raises(TypeCheckError, match="x must be a torch.Tensor"):
            soft_clip([0.5])

    def test_gradcheck(self):
        # not at 0: the clamp of negatives puts a kink there (tested in test_negatives_count_as_zero)
        x = torch.tensor([-0.5, 0.01, 0.3, 0.95, 1.0, 1.05, 2.0], dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(soft_clip, (x,))
        assert torch.autograd.gradcheck(lambda t: soft_clip(t, 3.0), (x,))
        assert torch.autograd.gradgradcheck(soft_clip, (x,))

    def test_module_matches_functional(self):
        x = torch.rand(2, 3, 8, 8) * 3
        torch.testing.assert_close(SoftClip()(x), soft_clip(x), atol=0, rtol=0)
        torch.testing.assert_close(SoftClip(sharpness=5.0)(x), soft_clip(x, 5.0), atol=0, rtol=0)
        assert "sharpness=5.0" in repr(SoftClip(sharpness=5.0))

    @pytest.mark.parametrize("dt", HALF_AND_F32)
    def test_dtypes(self, dt):
        x = torch.rand(2, 3, 16, 16, dtype=F64) * 3
        out = soft_clip(x.to(dt))
        assert out.dtype == dt
        assert_close_dtype(out, soft_clip(x.to(dt).to(F64)), dt)

    def test_compile(self):
        x = torch.rand(2, 3, 8, 8) * 3
        torch.testing.assert_close(torch.compile(soft_clip)(x), soft_clip(x))
        module = SoftClip(10.0)
        torch.testing.assert_close(torch.compile(module)(x), module(x))


class TestSoftClipNegatives:
    def test_negatives_count_as_zero(self):
        """Negative sphere values count as 0 (docs/conventions.rst); monotone, f(0) = 0, finite gradients."""
        x = torch.tensor([-1e6, -1.0, -1e-9, 0.0, 1e-9, 0.5], dtype=F64, requires_grad=True)
        y = soft_clip(x)
        assert (y[:4] == 0).all() and (y.diff() >= 0).all()
        y.sum().backward()
        assert torch.isfinite(x.grad).all()
        assert (x.grad[:3] == 0).all() and x.grad[3].item() == pytest.approx(1.0, abs=1e-6)
