r"""Reduced precision, one rule for the library: compute half precision in float32, and saturate on the way back.

float16 holds at most 65504 and bfloat16 has 8 bits of mantissa, while lighting spans eight orders of
magnitude. The ops that can overflow or lose a sum in half precision compute in :func:`work_dtype` and cast
their result back with :func:`saturating_cast`: a value the dtype cannot hold becomes its largest finite
value (with the sign), never ``inf``. NaN stays NaN (the input checks refuse NaN before it gets that far).
The stress table (:mod:`kornia_ilum.bench.stress`) checks every public op against this rule.
"""

from __future__ import annotations

import torch

__all__ = ["HALF", "saturating_cast", "work_dtype"]

#: The half-precision dtypes.
HALF = (torch.float16, torch.bfloat16)


def work_dtype(dtype: torch.dtype) -> torch.dtype:
    """The dtype to compute in: float32 for half precision, else ``dtype`` itself.

    Args:
        dtype: the dtype of the data.

    Returns:
        ``torch.float32`` for a dtype in :data:`HALF`, else ``dtype``.

    Examples:
        >>> work_dtype(torch.float16), work_dtype(torch.float64)
        (torch.float32, torch.float64)
    """
    return torch.float32 if dtype in HALF else dtype


class _Cast(torch.autograd.Function):
    """``x.to(dtype)`` whose gradient saturates in ``x``'s dtype on the way back."""

    @staticmethod
    def forward(x: torch.Tensor, dtype: torch.dtype) -> torch.Tensor:
        return x.to(dtype)

    @staticmethod
    def setup_context(ctx, inputs, output) -> None:
        ctx.source = inputs[0].dtype

    @staticmethod
    def backward(ctx, grad: torch.Tensor):
        return saturating_cast(grad, ctx.source), None


def _clamp_to(x: torch.Tensor, dtype: torch.dtype) -> torch.Tensor:
    if dtype.is_floating_point and x.is_floating_point() and torch.finfo(dtype).max < torch.finfo(x.dtype).max:
        top = torch.finfo(dtype).max
        return x.clamp(-top, top)
    return x


def saturating_cast(x: torch.Tensor, dtype: torch.dtype) -> torch.Tensor:
    """``x`` in ``dtype``, with values beyond the dtype's finite range clamped to it (``x`` itself when it
    already has that dtype). Differentiable: the gradient that flows back into ``x``'s dtype saturates too, so
    a float16 input computed in float32 never gets an infinite gradient.

    Args:
        x: the tensor to cast.
        dtype: the dtype to cast to.

    Returns:
        ``x`` in ``dtype``, same shape and device; NaN stays NaN.

    Shape:
        - x: :math:`(*)`
        - Output: :math:`(*)`

    Examples:
        >>> y = saturating_cast(torch.tensor([1e6, -1e6, 1.0]), torch.float16)
        >>> y.dtype, y.tolist()
        (torch.float16, [65504.0, -65504.0, 1.0])
    """
    if x.dtype == dtype:
        return x
    x = _clamp_to(x, dtype)
    if x.requires_grad and torch.is_grad_enabled():
        return _Cast.apply(x, dtype)
    return x.to(dtype)
