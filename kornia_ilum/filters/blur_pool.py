r"""Blur-pool, the network's anti-aliased downsampling (Zhang 2019, "Making convolutional networks
shift-invariant again").

The maths is Kornia's :func:`kornia.filters.blur_pool2d` / :class:`kornia.filters.BlurPool2D`
(normalised Pascal kernel as a non-persistent buffer, zero padding, input dtype kept). The thin wrappers
here exist for one reason: Kornia lets a wrong-rank input fall through to ``conv2d``, which raises a bare
``RuntimeError`` (and since Kornia 0.9.2 :func:`kornia.filters.max_blur_pool2d` quietly pools an unbatched
``(C, H, W)`` map); kornia_ilum's entry points raise a typed :class:`~kornia.core.exceptions.ShapeError`
that names the argument and the expected shape instead, whichever Kornia release is installed.
"""

from __future__ import annotations

import kornia.filters
import torch

from kornia_ilum.core.check import check_tensor

__all__ = ["blur_pool2d", "BlurPool2D", "max_blur_pool2d", "MaxBlurPool2D"]


def blur_pool2d(input: torch.Tensor, kernel_size: int = 3, stride: int = 2) -> torch.Tensor:
    r"""Blur with a normalised ``kernel_size`` Pascal kernel, then subsample every ``stride`` pixels.

    Args:
        input: feature map.
        kernel_size: side of the square binomial kernel.
        stride: subsampling step.

    Returns:
        the pooled map, same dtype and device.

    Raises:
        ShapeError: ``input`` is not ``(B, C, H, W)``.
        TypeCheckError: ``input`` is not a floating-point tensor.
        NonFiniteError: NaN or Inf in ``input``.

    Shape:
        - Input: :math:`(B, C, H, W)`
        - Output: :math:`(B, C, \lceil H / s \rceil, \lceil W / s \rceil)`

    Examples:
        >>> blur_pool2d(torch.ones(1, 2, 8, 8)).shape
        torch.Size([1, 2, 4, 4])
    """
    check_tensor(input, "input", ["B", "C", "H", "W"])
    return kornia.filters.blur_pool2d(input, kernel_size, stride)


class BlurPool2D(kornia.filters.BlurPool2D):
    r"""Module twin of :func:`blur_pool2d` (Kornia's module plus the typed shape check).

    Args:
        kernel_size: side of the square binomial kernel.
        stride: subsampling step.

    Shape:
        - Input: :math:`(B, C, H, W)`
        - Output: :math:`(B, C, \lceil H / s \rceil, \lceil W / s \rceil)`

    Examples:
        >>> BlurPool2D(3, stride=2)(torch.ones(1, 2, 8, 8)).shape
        torch.Size([1, 2, 4, 4])
    """

    def forward(self, input: torch.Tensor) -> torch.Tensor:
        check_tensor(input, "input", ["B", "C", "H", "W"])
        return super().forward(input)


def max_blur_pool2d(input: torch.Tensor, kernel_size: int = 3, stride: int = 2,
                    max_pool_size: int = 2) -> torch.Tensor:
    r"""Max-pool ``max_pool_size`` at stride 1, then blur-pool (Kornia's
    :func:`kornia.filters.max_blur_pool2d`).

    Args:
        input: feature map.
        kernel_size: side of the square binomial kernel.
        stride: subsampling step.
        max_pool_size: side of the max-pooling window.

    Returns:
        the pooled map, same dtype and device.

    Raises:
        ShapeError: ``input`` is not ``(B, C, H, W)``.
        TypeCheckError: ``input`` is not a floating-point tensor.
        NonFiniteError: NaN or Inf in ``input``.

    Shape:
        - Input: :math:`(B, C, H, W)`
        - Output: :math:`(B, C, \lceil (H - m + 1) / s \rceil, \lceil (W - m + 1) / s \rceil)`

    Examples:
        >>> max_blur_pool2d(torch.ones(1, 2, 8, 8)).shape
        torch.Size([1, 2, 4, 4])
    """
    check_tensor(input, "input", ["B", "C", "H", "W"])
    return kornia.filters.max_blur_pool2d(input, kernel_size, stride, max_pool_size)


class MaxBlurPool2D(kornia.filters.MaxBlurPool2D):
    r"""Module twin of :func:`max_blur_pool2d` (Kornia's module plus the typed shape check).

    Args:
        kernel_size: side of the square binomial kernel.
        stride: subsampling step.
        max_pool_size: side of the max-pooling window.

    Shape:
        - Input: :math:`(B, C, H, W)`
        - Output: :math:`(B, C, \lceil (H - m + 1) / s \rceil, \lceil (W - m + 1) / s \rceil)`

    Examples:
        >>> MaxBlurPool2D(3)(torch.ones(1, 2, 8, 8)).shape
        torch.Size([1, 2, 4, 4])
    """

    def forward(self, input: torch.Tensor) -> torch.Tensor:
        check_tensor(input, "input", ["B", "C", "H", "W"])
        return super().forward(input)
