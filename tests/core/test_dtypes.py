"""kornia_ilum.core.dtypes: the work dtype and the saturating cast."""

from __future__ import annotations

import torch

from kornia_ilum.core.dtypes import HALF, saturating_cast, work_dtype


def test_work_dtype() -> None:
    assert [work_dtype(d) for d in HALF] == [torch.float32, torch.float32]
    assert work_dtype(torch.float32) is torch.float32 and work_dtype(torch.float64) is torch.float64


def test_saturating_cast_clamps_keeps_nan_and_gradients() -> None:
    x = torch.tensor([1e6, -1e6, 3.0, float("inf"), float("nan")], requires_grad=True)
    y = saturating_cast(x, torch.float16)
    assert y.dtype == torch.float16
    assert y[:4].tolist() == [65504.0, -65504.0, 3.0, 65504.0] and torch.isnan(y[4])
    y[:3].float().sum().backward()
    assert x.grad[:3].tolist() == [0.0, 0.0, 1.0]  # the clamped ones get none
    big = torch.tensor([1e38])
    assert torch.isfinite(saturating_cast(big, torch.bfloat16)).all()
    assert saturating_cast(big, torch.float32) is big
    assert saturating_cast(torch.tensor([2.5], dtype=torch.float16), torch.float64).item() == 2.5


def test_the_gradient_back_into_half_precision_saturates() -> None:
    x = torch.tensor([1.0, 2.0], dtype=torch.float16, requires_grad=True)
    (saturating_cast(x, torch.float32) * torch.tensor([1e6, 3.0])).sum().backward()
    assert x.grad.dtype == torch.float16 and x.grad.tolist() == [65504.0, 3.0]
