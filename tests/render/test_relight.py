"""Tests of kornia_ilum.render.relight: I = R . L, dense and energy-truncated."""

from __future__ import annotations

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
from kornia_ilum.render import Relight, relight
from kornia_ilum.render.relight import kept_lights, light_norms
from tests.conftest import assert_close_dtype

F64 = torch.float64


def _reference(field: torch.Tensor, lighting: torch.Tensor, h: int, w: int) -> torch.Tensor:
    """The definition, written as plainly as possible (float64)."""
    f = field.to(F64)
    if f.dim() == 2:
        f = f.expand(lighting.shape[2], *f.shape)
    out = torch.einsum("cpn,bnc->bcp", f, lighting.to(F64))
    return out.reshape(lighting.shape[0], lighting.shape[2], h, w)


def _data(shared: bool, b: int = 2, c: int = 3, p: int = 16, n: int = 7, seed: int = 0, dtype=torch.float32):
    g = torch.Generator().manual_seed(seed)
    field = torch.rand((p, n) if shared else (c, p, n), generator=g, dtype=F64).to(dtype)
    lighting = torch.rand(b, n, c, generator=g, dtype=F64).to(dtype)
    return field, lighting


def _hdr_lighting(b: int, n: int, c: int, seed: int) -> torch.Tensor:
    """Non-negative lighting with a few bright lights and a dim floor, like an HDR environment."""
    g = torch.Generator().manual_seed(seed)
    lighting = 0.05 * torch.rand(b, n, c, generator=g, dtype=F64)
    for i in range(b):
        idx = torch.randperm(n, generator=g)[:3]
        lighting[i, idx] += 50.0 * torch.rand(3, c, generator=g, dtype=F64)
    return lighting


class TestRelight:
    def test_smoke(self, device, dtype):
        field, lighting = _data(shared=False, dtype=dtype)
        field, lighting = field.to(device), lighting.to(device)
        out = relight(field, lighting)
        assert out.shape == (2, 3, 4, 4) and out.dtype == dtype and out.device == field.device
        torch.testing.assert_close(out, _reference(field, lighting, 4, 4).to(device, dtype))

    @pytest.mark.parametrize("shared", [True, False])
    @pytest.mark.parametrize("size, hw", [(None, (4, 4)), (4, (4, 4)), ((2, 8), (2, 8)), ((16, 1), (16, 1))])
    @pytest.mark.parametrize("b", [1, 3])
    def test_cardinality(self, shared, size, hw, b):
        field, lighting = _data(shared, b=b)
        out = relight(field, lighting, size)
        assert out.shape == (b, 3, *hw)
        torch.testing.assert_close(out, _reference(field, lighting, *hw).float())

    def test_shared_field_any_channel_count(self):
        field, _ = _data(shared=True)
        lighting = torch.rand(2, 7, 5)
        assert relight(field, lighting).shape == (2, 5, 4, 4)

    def test_exception(self):
        field, lighting = _data(shared=False)
        with pytest.raises(ShapeError, match=r"field must have shape \(C, P, N\), got \(2, 3, 16, 7\)"):
            relight(field[None].expand(2, -1, -1, -1), lighting)
        with pytest.raises(ShapeError, match=r"lighting must have shape \(B, N, C\)"):
            relight(field, lighting[0])
        with pytest.raises(ShapeError, match="lighting must have N = 7 lights"):
            relight(field, lighting[:, :5])
        with pytest.raises(ShapeError, match="lighting must have C = 3 channels"):
            relight(field, lighting[..., :2])
        with pytest.raises(ShapeError, match="P = 12 pixels, which is no square"):
            relight(field[:, :12], lighting)
        with pytest.raises(ShapeError, match=r"size \(3, 5\) has 15 pixels but field has P = 16"):
            relight(field, lighting, (3, 5))
        with pytest.raises(ValueCheckError, match="size must be a positive int or a pair"):
            relight(field, lighting, (4, 4, 1))
        with pytest.raises(NonFiniteError, match="lighting must be finite"):
            relight(field, lighting.index_fill(1, torch.tensor([2]), float("nan")))
        with pytest.raises(TypeCheckError, match="field must be a floating-point tensor"):
            relight(field.long(), lighting)
        with pytest.raises(TypeCheckError, match="lighting must be a torch.Tensor"):
            relight(field, lighting.tolist())
        with pytest.raises(EmptyTensorError, match="lighting must not be empty"):
            relight(field, lighting[:0])
        with pytest.raises(ValueCheckError, match=r"eps must be a number in \[0, 1\), got 1.0"):
            relight(field, lighting, eps=1.0)
        with pytest.raises(ValueCheckError, match="eps must be a number"):
            relight(field, lighting, eps=-0.1)
        with pytest.raises(ShapeError, match="field must have shape"):
            Relight(field[None])
        with pytest.raises(NonFiniteError, match="field must be finite"):
            Relight(field.index_fill(2, torch.tensor([0]), float("inf")))
        with pytest.raises(ShapeError, match="lighting must have N = 7 lights"):
            Relight(field, eps=0.1)(lighting[:, :5])

    def test_negative_lighting_is_allowed(self):
        field, lighting = _data(shared=False)
        out = relight(field, lighting - 0.5)
        torch.testing.assert_close(out, _reference(field, lighting - 0.5, 4, 4).float())

    @pytest.mark.parametrize("shared", [True, False])
    def test_gradcheck(self, shared):
        field, lighting = _data(shared, b=2, p=4, n=5, dtype=F64)
        field.requires_grad_()
        lighting.requires_grad_()
        assert torch.autograd.gradcheck(lambda f, l: relight(f, l), (field, lighting))
        # truncated mode: the kept set is stable under the finite-difference steps, so it is linear there
        lighting = torch.tensor([[[5.0], [0.001], [3.0], [0.002], [4.0]]], dtype=F64, requires_grad=True)
        field = field.detach()[:1] if not shared else field.detach()
        assert torch.autograd.gradcheck(lambda l: relight(field, l, eps=0.01), (lighting,))
        # the module's sparse path (2 of 10 lights kept: weighted bags of field rows)
        lighting = torch.full((2, 10, 1), 1e-4, dtype=F64)
        lighting[0, 3] = lighting[1, 7] = 2.0
        lighting[0, 8] = lighting[1, 0] = 3.0
        field = torch.rand((4, 10) if shared else (1, 4, 10), dtype=F64)
        module = Relight(field, eps=0.01)
        assert torch.autograd.gradcheck(module, (lighting.requires_grad_(),))

    @pytest.mark.parametrize("shared", [True, False])
    @pytest.mark.parametrize("eps", [0.0, 0.02, 0.3])
    def test_module_matches_functional(self, shared, eps):
        field, _ = _data(shared, b=3, p=16, n=40)
        lighting = _hdr_lighting(3, 40, 3, seed=1).float()
        module = Relight(field, eps=eps)
        torch.testing.assert_close(module(lighting), relight(field, lighting, eps=eps))

    def test_module_gather_and_dense_paths(self):
        """With few kept lights the module gathers them; with many it multiplies densely: same numbers."""
        field, _ = _data(shared=False, b=2, p=16, n=40, dtype=F64)
        module = Relight(field, eps=0.05)
        few = _hdr_lighting(2, 40, 3, seed=2)  # 3 bright lights per item: gathered
        many = torch.rand(2, 40, 3, dtype=F64) + 1.0  # near-uniform: most lights kept, dense path
        for lighting in (few, many):
            torch.testing.assert_close(module(lighting), relight(field, lighting, eps=0.05))
        module.to(torch.float32)
        torch.testing.assert_close(module(few.float()), relight(field.float(), few.float(), eps=0.05))

    @pytest.mark.parametrize("dt", [torch.float16, torch.bfloat16, torch.float32])
    @pytest.mark.parametrize("shared", [True, False])
    def test_dtypes(self, dt, shared):
        field, lighting = _data(shared, p=64, n=32, dtype=F64)
        expected = relight(field, lighting)
        # sums of 32 products of values in [0, 1]: scale the tolerance to the output's magnitude (~8)
        assert_close_dtype(relight(field.to(dt), lighting.to(dt)), expected, dt, scale=8.0)
        assert relight(field.to(dt), lighting.to(dt)).dtype == dt

    def test_mixed_dtypes(self):
        """A bfloat16 field with float32 lighting computes in bfloat16 and returns float32."""
        field, lighting = _data(shared=False, p=64, n=32, dtype=F64)
        out = relight(field.bfloat16(), lighting.float())
        assert out.dtype == torch.float32
        assert_close_dtype(out, relight(field, lighting), torch.bfloat16, scale=8.0)
        assert relight(field.float(), lighting).dtype == F64

    def test_compile(self):
        field, lighting = _data(shared=False)
        compiled = torch.compile(relight)
        torch.testing.assert_close(compiled(field, lighting), relight(field, lighting))

    @given(
        st.integers(0, 2**16),
        st.floats(-10, 10, allow_nan=False),
        st.floats(-10, 10, allow_nan=False),
    )
    def test_linear_in_lighting(self, seed, a, b):
        field, l1 = _data(shared=False, b=2, p=9, n=6, seed=seed, dtype=F64)
        shared_field, l2 = _data(shared=True, b=2, p=9, n=6, seed=seed + 1, dtype=F64)
        f = shared_field if seed % 2 else field
        torch.testing.assert_close(relight(f, a * l1 + b * l2), a * relight(f, l1) + b * relight(f, l2))

    @given(st.integers(0, 2**16), st.floats(1e-4, 0.9), st.booleans())
    def test_truncation_error_bound(self, seed, eps, shared):
        """Non-negative R and L: 0 <= I - I_eps, sum(I - I_eps) <= eps * sum(I), and the per-pixel bound."""
        g = torch.Generator().manual_seed(seed)
        n, p = 48, 25
        field = torch.rand((p, n) if shared else (3, p, n), generator=g, dtype=F64) ** 4
        lighting = _hdr_lighting(2, n, 3, seed)
        dense = relight(field, lighting)
        sparse = relight(field, lighting, eps=eps)
        loss = dense - sparse
        assert (loss >= -1e-12).all()
        total = dense.sum((1, 2, 3))
        assert (loss.sum((1, 2, 3)) <= eps * total + 1e-9 * total).all()
        # per pixel: |I - I_eps| <= sum over the dropped lights of |R| |L|
        keep = kept_lights(lighting, light_norms(field), eps)
        dropped = lighting * (~keep)[..., None]
        assert (loss.abs() <= relight(field.abs(), dropped.abs()) + 1e-12).all()
        assert (keep.sum(1) >= 1).all()
        torch.testing.assert_close(Relight(field, eps=eps)(lighting), sparse)

    @given(st.integers(0, 2**16), st.floats(1e-3, 0.5))
    def test_truncation_bound_any_sign(self, seed, eps):
        """Signed R and L: sum |I - I_eps| <= eps * sum_n E[n], E[n] = sum_c |L[n, c]| ||R[c, :, n]||_1."""
        g = torch.Generator().manual_seed(seed)
        field = torch.randn(3, 16, 30, generator=g, dtype=F64)
        lighting = (
            torch.randn(2, 30, 3, generator=g, dtype=F64) * torch.rand(2, 30, 1, generator=g, dtype=F64) ** 6
        )
        err = (relight(field, lighting) - relight(field, lighting, eps=eps)).abs().sum((1, 2, 3))
        energy = (lighting.abs() * field.abs().sum(1).T[None]).sum((1, 2))
        assert (err <= eps * energy * (1 + 1e-12)).all()

    def test_truncation_drops_the_weakest_lights(self):
        """Per pixel, the error is exactly the dropped terms; here the two dim lights (1% of the energy)."""
        field = torch.rand(3, 4, 5, dtype=F64)
        lighting = torch.tensor([[[10.0] * 3, [0.01] * 3, [8.0] * 3, [0.02] * 3, [9.0] * 3]], dtype=F64)
        field[:, :, [1, 3]] = field[:, :, [1, 3]].clamp(max=0.5)
        energy = (lighting.abs() * field.abs().sum(1).T[None]).sum(-1)[0]
        eps = 1.5 * energy[[1, 3]].sum().item() / energy.sum().item()
        out = relight(field, lighting, eps=eps, size=(2, 2))
        dropped = torch.zeros_like(lighting)
        dropped[:, [1, 3]] = lighting[:, [1, 3]]
        torch.testing.assert_close(
            relight(field, lighting, size=(2, 2)) - out, relight(field, dropped, size=(2, 2))
        )

    def test_truncation_is_per_item(self):
        """An item's truncated result does not depend on the other items of the batch."""
        field, _ = _data(shared=False, p=16, n=40, dtype=F64)
        lighting = _hdr_lighting(4, 40, 3, seed=3)
        batch = relight(field, lighting, eps=0.1)
        module = Relight(field, eps=0.1)
        for i in range(4):
            torch.testing.assert_close(batch[i : i + 1], relight(field, lighting[i : i + 1], eps=0.1))
            torch.testing.assert_close(module(lighting)[i : i + 1], module(lighting[i : i + 1]))

    def test_black_lighting_truncates_to_black(self):
        field, lighting = _data(shared=False)
        assert relight(field, torch.zeros_like(lighting), eps=0.1).abs().max().item() == 0.0
        assert Relight(field, eps=0.1)(torch.zeros_like(lighting)).abs().max().item() == 0.0
