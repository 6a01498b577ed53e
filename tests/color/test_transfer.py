"""Tests of kornia_ilum.color.transfer: sRGB (IEC 61966-2-1), gamma with a finite slope at 0, quantisation."""

from __future__ import annotations

import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from kornia_ilum.color import (
    GAMMA_KNEE,
    GammaDecode,
    GammaEncode,
    LinearToSrgb,
    Quantize,
    SrgbToLinear,
    encode_srgb8,
    gamma_decode,
    gamma_encode,
    linear_to_srgb,
    quantize,
    srgb_to_linear,
)
from kornia_ilum.core.errors import (
    EmptyTensorError,
    NonFiniteError,
    ShapeError,
    TypeCheckError,
    ValueCheckError,
)
from tests.conftest import assert_close_dtype

F64 = torch.float64
HALF_AND_F32 = [torch.float16, torch.bfloat16, torch.float32]


def _img(values, dtype=F64) -> torch.Tensor:
    """A (1, 3, 1, N) image with the same values in every channel."""
    v = torch.as_tensor(values, dtype=dtype)
    return v.reshape(1, 1, 1, -1).expand(1, 3, 1, -1).contiguous()


def _iec_encode(x: float) -> float:
    return 12.92 * x if x <= 0.0031308 else 1.055 * x ** (1 / 2.4) - 0.055


class TestLinearToSrgb:
    def test_smoke(self, device, dtype):
        y = linear_to_srgb(_img([0.0, 0.5, 1.0], dtype).to(device))
        assert y.dtype == dtype and y.device.type == device.type
        torch.testing.assert_close(
            y[0, 0, 0], torch.tensor([0.0, 0.735357, 1.0], device=device, dtype=dtype), atol=1e-6, rtol=0
        )

    def test_iec_61966_2_1_reference_values(self):
        y = linear_to_srgb(_img([0.5, 0.0031308, 0.001, 0.18, 0.9]))[0, 0, 0]
        assert y[0].item() == pytest.approx(0.735357, abs=5e-7)
        assert y[1].item() == pytest.approx(0.040449936, abs=1e-9)  # the knee, from the linear segment
        assert y[2].item() == pytest.approx(0.01292, abs=1e-12)
        for got, x in zip(y[2:].tolist(), [0.001, 0.18, 0.9], strict=True):
            assert got == pytest.approx(_iec_encode(x), abs=1e-12)

    @pytest.mark.parametrize("shape", [(3, 4, 5), (2, 3, 8, 8), (2, 2, 3, 4, 4)])
    def test_cardinality(self, shape):
        assert linear_to_srgb(torch.rand(shape)).shape == shape

    def test_exception(self):
        with pytest.raises(ShapeError, match=r"image must have shape \(\*, 3, H, W\), got \(2, 4, 4\)"):
            linear_to_srgb(torch.rand(2, 4, 4))
        with pytest.raises(NonFiniteError, match="image must be finite"):
            linear_to_srgb(torch.full((1, 3, 2, 2), float("nan")))
        with pytest.raises(TypeCheckError, match="image must be a floating-point tensor"):
            linear_to_srgb(torch.zeros(1, 3, 2, 2, dtype=torch.uint8))
        with pytest.raises(EmptyTensorError, match="image must not be empty"):
            linear_to_srgb(torch.zeros(0, 3, 2, 2))

    def test_gradcheck(self):
        x = torch.tensor([0.001, 0.2, 0.5, 0.9], dtype=F64).reshape(1, 1, 1, 4).expand(1, 3, 1, 4).clone()
        assert torch.autograd.gradcheck(linear_to_srgb, (x.requires_grad_(),))

    def test_module_matches_functional(self):
        x = torch.rand(2, 3, 8, 8)
        torch.testing.assert_close(LinearToSrgb()(x), linear_to_srgb(x), atol=0, rtol=0)

    @pytest.mark.parametrize("dt", HALF_AND_F32)
    def test_dtypes(self, dt):
        x = torch.rand(2, 3, 8, 8, dtype=F64)
        out = linear_to_srgb(x.to(dt))
        assert out.dtype == dt
        assert_close_dtype(out, linear_to_srgb(x.to(dt).to(F64)), dt)

    def test_compile(self):
        x = torch.rand(2, 3, 8, 8)
        torch.testing.assert_close(torch.compile(linear_to_srgb)(x), linear_to_srgb(x))


class TestSrgbToLinear:
    def test_smoke(self, device, dtype):
        y = srgb_to_linear(_img([0.0, 0.5, 1.0], dtype).to(device))
        torch.testing.assert_close(
            y[0, 0, 0], torch.tensor([0.0, 0.214041, 1.0], device=device, dtype=dtype), atol=1e-6, rtol=0
        )

    def test_reference_values(self):
        y = srgb_to_linear(_img([0.735357, 0.040449936, 0.04045]))[0, 0, 0]
        assert y[0].item() == pytest.approx(0.5, abs=1e-6)
        assert y[1].item() == pytest.approx(0.0031308, abs=1e-9)
        assert y[2].item() == pytest.approx(0.04045 / 12.92, abs=1e-9)  # IEC decode knee at 0.04045

    @given(st.lists(st.floats(0.0, 1.0), min_size=1, max_size=32))
    def test_round_trip(self, values):
        x = _img(values)
        torch.testing.assert_close(srgb_to_linear(linear_to_srgb(x)), x, atol=1e-12, rtol=1e-12)
        torch.testing.assert_close(linear_to_srgb(srgb_to_linear(x)), x, atol=1e-12, rtol=1e-12)

    def test_cardinality(self):
        assert srgb_to_linear(torch.rand(4, 3, 5, 6)).shape == (4, 3, 5, 6)

    def test_exception(self):
        with pytest.raises(ShapeError, match=r"image must have shape \(\*, 3, H, W\), got \(1, 4, 2, 2\)"):
            srgb_to_linear(torch.rand(1, 4, 2, 2))
        with pytest.raises(NonFiniteError, match="image must be finite"):
            srgb_to_linear(torch.full((3, 2, 2), float("inf")))

    def test_gradcheck(self):
        x = torch.tensor([0.02, 0.3, 0.6, 0.95], dtype=F64).reshape(1, 1, 1, 4).expand(1, 3, 1, 4).clone()
        assert torch.autograd.gradcheck(srgb_to_linear, (x.requires_grad_(),))

    def test_module_matches_functional(self):
        x = torch.rand(2, 3, 8, 8)
        torch.testing.assert_close(SrgbToLinear()(x), srgb_to_linear(x), atol=0, rtol=0)

    @pytest.mark.parametrize("dt", HALF_AND_F32)
    def test_dtypes(self, dt):
        x = torch.rand(2, 3, 8, 8, dtype=F64)
        out = srgb_to_linear(x.to(dt))
        assert out.dtype == dt
        assert_close_dtype(out, srgb_to_linear(x.to(dt).to(F64)), dt)

    def test_compile(self):
        x = torch.rand(2, 3, 8, 8)
        torch.testing.assert_close(torch.compile(srgb_to_linear)(x), srgb_to_linear(x))


class TestGammaEncode:
    def test_smoke(self, device, dtype):
        y = gamma_encode(torch.tensor([0.0, 0.25, 1.0], device=device, dtype=dtype))
        torch.testing.assert_close(y, torch.tensor([0.0, 0.25 ** (1 / 2.2), 1.0], device=device, dtype=dtype))

    @given(st.floats(GAMMA_KNEE, 1e4), st.sampled_from([1.0, 2.2, 2.4]))
    def test_exact_above_the_knee(self, x, gamma):
        y = gamma_encode(torch.tensor([x], dtype=F64), gamma)
        assert y.item() == pytest.approx(x ** (1 / gamma), rel=1e-14)

    def test_chord_below_the_knee(self):
        slope = GAMMA_KNEE ** (1 / 2.2 - 1)
        assert slope == pytest.approx(533.67, rel=1e-4)
        x = torch.tensor([0.0, 1e-8, 1e-6, 0.5 * GAMMA_KNEE, -1e-3], dtype=F64)
        torch.testing.assert_close(gamma_encode(x), x * slope)
        # continuous at the knee
        knee = torch.tensor([GAMMA_KNEE * (1 - 1e-12), GAMMA_KNEE], dtype=F64)
        y = gamma_encode(knee)
        assert abs(y[0].item() - y[1].item()) < 1e-12

    @pytest.mark.parametrize("dt", HALF_AND_F32 + [F64])
    def test_finite_gradient_at_zero(self, dt):
        x = torch.zeros(4, dtype=dt, requires_grad=True)
        gamma_encode(x).sum().backward()
        assert torch.isfinite(x.grad).all()
        assert x.grad[0].item() == pytest.approx(GAMMA_KNEE ** (1 / 2.2 - 1), rel=1e-2)

    @given(st.floats(0.0, 100.0))
    def test_decode_inverts_encode(self, x):
        t = torch.tensor([x], dtype=F64)
        torch.testing.assert_close(gamma_decode(gamma_encode(t)), t, atol=1e-15, rtol=1e-12)

    @pytest.mark.parametrize("shape", [(), (7,), (2, 3, 4, 4)])
    def test_cardinality(self, shape):
        assert gamma_encode(torch.rand(shape)).shape == shape
        assert gamma_decode(torch.rand(shape)).shape == shape

    def test_exception(self):
        for bad in (0.0, -2.2, float("nan")):
            with pytest.raises(ValueCheckError, match="gamma must be positive"):
                gamma_encode(torch.rand(3), bad)
            with pytest.raises(ValueCheckError, match="gamma must be positive"):
                gamma_decode(torch.rand(3), bad)
        with pytest.raises(NonFiniteError, match="x must be finite"):
            gamma_encode(torch.tensor([float("inf")]))
        with pytest.raises(TypeCheckError, match="x must be a floating-point tensor"):
            gamma_encode(torch.tensor([1]))

    def test_gradcheck(self):
        x = torch.tensor([0.0, 2e-6, 3e-5, 0.1, 0.7, 3.0], dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(gamma_encode, (x,))
        assert torch.autograd.gradcheck(gamma_decode, (x,))

    def test_module_matches_functional(self):
        x = torch.rand(2, 3, 8, 8)
        torch.testing.assert_close(GammaEncode()(x), gamma_encode(x), atol=0, rtol=0)
        torch.testing.assert_close(GammaEncode(2.4)(x), gamma_encode(x, 2.4), atol=0, rtol=0)
        torch.testing.assert_close(GammaDecode()(x), gamma_decode(x), atol=0, rtol=0)
        torch.testing.assert_close(GammaDecode(2.4)(x), gamma_decode(x, 2.4), atol=0, rtol=0)

    @pytest.mark.parametrize("dt", HALF_AND_F32)
    def test_dtypes(self, dt):
        x = torch.rand(2, 3, 8, 8, dtype=F64) * 2
        out = gamma_encode(x.to(dt))
        assert out.dtype == dt
        assert_close_dtype(out, gamma_encode(x.to(dt).to(F64)), dt)

    def test_compile(self):
        x = torch.rand(2, 3, 8, 8)
        torch.testing.assert_close(torch.compile(gamma_encode)(x), gamma_encode(x))


class TestQuantize:
    def test_smoke(self, device, dtype):
        y = quantize(torch.tensor([-0.2, 0.0, 0.5, 0.999, 3.0], device=device, dtype=dtype))
        torch.testing.assert_close(
            y, torch.tensor([0.0, 0.0, 128 / 255, 1.0, 1.0], device=device, dtype=dtype)
        )

    @given(st.integers(1, 16), st.lists(st.floats(-2.0, 3.0), min_size=1, max_size=32))
    def test_levels_and_clipping(self, bits, values):
        levels = 2**bits - 1
        x = torch.tensor(values, dtype=F64)
        y = quantize(x, bits)
        assert (y >= 0).all() and (y <= 1).all()
        codes = y * levels
        torch.testing.assert_close(codes, codes.round(), atol=1e-9, rtol=0)  # on the grid of 2^bits levels
        assert ((y - x.clamp(0, 1)).abs() <= 0.5 / levels + 1e-12).all()  # nearest level
        assert (
            len(torch.unique(quantize(torch.linspace(0, 1, 4 * levels + 1, dtype=F64), bits))) == levels + 1
        )

    def test_straight_through_gradient(self):
        x = torch.tensor([-0.5, 0.0, 0.3, 0.5, 1.0, 1.5], requires_grad=True)
        quantize(x, 8, straight_through=True).sum().backward()
        assert x.grad.tolist() == [0.0, 1.0, 1.0, 1.0, 1.0, 0.0]  # the clip still blocks outside [0, 1]
        x.grad = None
        quantize(x, 8).sum().backward()
        assert x.grad.abs().max().item() == 0.0  # plain rounding has zero gradient

    def test_cardinality(self):
        assert quantize(torch.rand(2, 3, 4, 4)).shape == (2, 3, 4, 4)

    def test_exception(self):
        with pytest.raises(ValueCheckError, match="bits must be positive, got 0"):
            quantize(torch.rand(3), 0)
        with pytest.raises(ValueCheckError, match="bits must be one of"):
            quantize(torch.rand(3), 17)
        with pytest.raises(TypeCheckError, match="bits must be an int, got float"):
            quantize(torch.rand(3), 8.0)
        with pytest.raises(NonFiniteError, match="x must be finite"):
            quantize(torch.tensor([float("nan")]))

    def test_gradcheck(self):
        x = torch.tensor([0.11, 0.4, 0.77], dtype=F64, requires_grad=True)  # away from the rounding steps
        assert torch.autograd.gradcheck(quantize, (x,))
        # the straight-through estimator's gradient is the identity inside [0, 1]
        jac = torch.autograd.functional.jacobian(lambda t: quantize(t, 8, straight_through=True), x)
        torch.testing.assert_close(jac, torch.eye(3, dtype=F64))

    def test_module_matches_functional(self):
        x = torch.rand(2, 3, 8, 8) * 1.2 - 0.1
        torch.testing.assert_close(Quantize()(x), quantize(x), atol=0, rtol=0)
        torch.testing.assert_close(Quantize(4, True)(x), quantize(x, 4, True), atol=0, rtol=0)

    @pytest.mark.parametrize("dt", HALF_AND_F32)
    def test_dtypes(self, dt):
        x = torch.rand(2, 3, 8, 8, dtype=F64)
        out = quantize(x.to(dt))
        assert out.dtype == dt
        # low precision may land on the neighbouring level
        assert_close_dtype(out, quantize(x.to(dt).to(F64)), dt, scale=1.0 + 1 / 255 / 0.01)

    def test_compile(self):
        x = torch.rand(2, 3, 8, 8)
        torch.testing.assert_close(torch.compile(quantize)(x), quantize(x))
        module = Quantize(6, straight_through=True)
        torch.testing.assert_close(torch.compile(module)(x), module(x))


class TestEncodeSrgb8:
    def test_matches_srgb_and_quantize(self):
        x = torch.rand(2, 3, 64, 64) ** 2.2 * 1.3
        ours = encode_srgb8(x).int()
        reference = torch.round(quantize(linear_to_srgb(x.clamp(0, 1)), 8) * 255).int()
        assert (ours - reference).abs().max() <= 1 and (ours != reference).float().mean() < 0.005
        assert encode_srgb8(x).dtype == torch.uint8 and encode_srgb8(x.double()).shape == x.shape

    def test_every_code_boundary(self):
        codes = torch.arange(256, dtype=torch.float64) / 255
        linear = srgb_to_linear(codes.reshape(1, 1, 1, -1).expand(1, 3, 1, -1))[0, 0, 0]
        assert torch.equal(encode_srgb8(linear).long(), torch.arange(256))  # each code's own value
        assert encode_srgb8(torch.tensor([-1.0, 0.0, 1.0, 9.0])).tolist() == [0, 0, 255, 255]

    def test_inplace_overwrites_only_when_asked(self):
        x = torch.rand(3, 8, 8)
        before = x.clone()
        codes = encode_srgb8(x)
        assert torch.equal(x, before)
        assert torch.equal(encode_srgb8(x, inplace=True), codes) and not torch.equal(x, before)
        with pytest.raises(ValueCheckError, match="inplace"):
            encode_srgb8(torch.rand(3, 8, 8, dtype=torch.float64), inplace=True)

    def test_errors(self):
        with pytest.raises(NonFiniteError):
            encode_srgb8(torch.tensor([float("nan")]))
        with pytest.raises(TypeCheckError):
            encode_srgb8(torch.tensor([1, 2]))


def test_the_exported_srgb_curves_are_the_eager_ones():
    """Under torch.export the sRGB pair is a blend by the mask, not where (ONNX Runtime's Where is slow)."""
    from kornia_ilum.color import linear_to_srgb, srgb_to_linear

    class RoundTrip(torch.nn.Module):
        def forward(self, x):
            return srgb_to_linear(x), linear_to_srgb(x)

    x = torch.cat([torch.linspace(0, 1, 3 * 64 * 64 - 4), torch.tensor([0.0, 0.0031308, 0.04045, 1.0])])
    x = x.reshape(1, 3, 64, 64)
    program = torch.export.export(RoundTrip(), (x,))
    assert not any(n.target is torch.ops.aten.where.self for n in program.graph.nodes)
    for got, want in zip(program.module()(x), RoundTrip()(x)):
        torch.testing.assert_close(got, want, atol=1e-7, rtol=1e-6)
