"""Filters of the network and the loss: soft clip, and Kornia's blur-pool re-exported.

Blur-pool is Kornia's own :func:`kornia.filters.blur_pool2d` / :class:`kornia.filters.BlurPool2D`
(Zhang 2019, "Making convolutional networks shift-invariant again"), re-exported unchanged: since
Kornia 0.8 the module registers its Pascal kernel as a non-persistent buffer and follows the input's
device and dtype, so there is nothing to wrap.
"""

from kornia.filters import BlurPool2D, MaxBlurPool2D, blur_pool2d, max_blur_pool2d

from kornia_ilum.filters.soft_clip import SoftClip, soft_clip

__all__ = ["soft_clip", "SoftClip", "blur_pool2d", "BlurPool2D", "max_blur_pool2d", "MaxBlurPool2D"]
