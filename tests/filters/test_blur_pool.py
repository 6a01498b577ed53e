"""Tests of the blur-pool re-exported by kornia_ilum.filters (Kornia's, Zhang 2019)."""

from __future__ import annotations

import math

import kornia
import pytest
import torch

from kornia_ilum.core.errors import ShapeError, TypeCheckError
from kornia_ilum.filters import BlurPool2D, MaxBlurPool2D, blur_pool2d, max_blur_pool2d
from tests.conftest import assert_close_dtype

F64 = torch.float64
HALF_AND_F32 = [torch.float16, torch.bfloat16, torch.float32]
OPS = [(blur_pool2d, BlurPool2D), (max_blur_pool2d, MaxBlurPool2D)]
IDS = ["blur_pool2d", "max_blur_pool2d"]


class TestBlurPool:
    def test_is_kornia(self):
        x = torch.rand(2, 3, 9, 9)
        torch.testing.assert_close(blur_pool2d(x, 3), kornia.filters.blur_pool2d(x, 3), atol=0, rtol=0)
        assert isinstance(BlurPool2D(3), kornia.filters.BlurPool2D)
        torch.testing.assert_close(max_blur_pool2d(x, 3), kornia.filters.max_blur_pool2d(x, 3), atol=0, rtol=0)
        assert isinstance(MaxBlurPool2D(3), kornia.filters.MaxBlurPool2D)

    def test_smoke(self, device, dtype):
        x = torch.ones(1, 2, 8, 8, device=device, dtype=dtype)
        y = blur_pool2d(x, 3)
        assert y.device == x.device and y.dtype == dtype
        # the normalised Pascal kernel keeps a constant image's interior constant
        torch.testing.assert_close(y[..., 1:-1, 1:-1], torch.ones_like(y[..., 1:-1, 1:-1]))

    @pytest.mark.parametrize(("op", "module", "shrink"), [OPS[0] + (0,), OPS[1] + (1,)], ids=IDS)
    @pytest.mark.parametrize(("hw", "stride"), [((8, 8), 2), ((7, 9), 2), ((32, 32), 4)])
    def test_cardinality(self, op, module, shrink, hw, stride):
        """ceil(H / stride); max-blur-pool first max-pools 2 x 2 at stride 1 (H - 1)."""
        x = torch.rand(2, 3, *hw)
        out = (2, 3) + tuple(math.ceil((n - shrink) / stride) for n in hw)
        assert op(x, 3, stride=stride).shape == out
        assert module(3, stride=stride)(x).shape == out

    def test_exception(self):
        message = "input must be a floating-point tensor, got dtype torch.int64"
        with pytest.raises(TypeCheckError, match=message):
            blur_pool2d(torch.zeros(1, 3, 8, 8, dtype=torch.long), 3)
        # Kornia 0.9.2's max_blur_pool2d pools an unbatched (C, H, W) map; ours asks for the batch
        with pytest.raises(ShapeError, match=r"input must have shape \(B, C, H, W\), got \(3, 8, 8\)"):
            max_blur_pool2d(torch.rand(3, 8, 8), 3)
        with pytest.raises(ShapeError, match=r"input must have shape \(B, C, H, W\)"):
            MaxBlurPool2D(3)(torch.rand(3, 8, 8))
        # Kornia's blur_pool2d lets this reach conv2d (bare RuntimeError); ours names the argument
        with pytest.raises(ShapeError, match=r"input must have shape \(B, C, H, W\), got \(3, 8, 8\)"):
            blur_pool2d(torch.rand(3, 8, 8), 3)
        with pytest.raises(ShapeError, match=r"input must have shape \(B, C, H, W\)"):
            BlurPool2D(3)(torch.rand(8, 8))

    def test_gradcheck(self):
        x = torch.rand(1, 2, 6, 6, dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(lambda t: blur_pool2d(t, 3), (x,), fast_mode=True)

    @pytest.mark.parametrize(("op", "module"), OPS, ids=IDS)
    def test_module_matches_functional(self, op, module):
        x = torch.rand(2, 3, 16, 16)
        m = module(3)
        assert dict(m.state_dict()) == {}  # the kernel is a non-persistent buffer
        torch.testing.assert_close(m(x), op(x, 3), atol=0, rtol=0)

    @pytest.mark.parametrize(("op", "module"), OPS, ids=IDS)
    @pytest.mark.parametrize("dt", HALF_AND_F32)
    def test_dtypes(self, op, module, dt):
        x = torch.rand(2, 3, 16, 16, dtype=F64)
        out = op(x.to(dt), 3)
        assert out.dtype == dt
        assert_close_dtype(out, op(x.to(dt).to(F64), 3), dt)
        assert module(3)(x.to(dt)).dtype == dt  # the float32 kernel buffer follows the input

    @pytest.mark.parametrize(("op", "module"), OPS, ids=IDS)
    def test_channels_last_bfloat16(self, op, module):
        x = torch.rand(2, 4, 16, 16).to(torch.bfloat16).to(memory_format=torch.channels_last)
        for y in (op(x, 3), module(3)(x)):
            assert y.dtype == torch.bfloat16
            assert y.is_contiguous(memory_format=torch.channels_last)
            assert_close_dtype(y, op(x.float().contiguous(), 3), torch.bfloat16)

    def test_compile(self):
        x = torch.rand(2, 3, 16, 16)
        torch.testing.assert_close(torch.compile(blur_pool2d)(x, 3), blur_pool2d(x, 3))
        module = BlurPool2D(3)
        torch.testing.assert_close(torch.compile(module)(x), module(x))
