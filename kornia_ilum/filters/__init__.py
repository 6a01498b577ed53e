"""Filters of the network and the loss: soft clip and blur-pool.

Blur-pool and max-blur-pool are Kornia's (:func:`kornia.filters.blur_pool2d`,
:func:`kornia.filters.max_blur_pool2d`), wrapped only to add typed shape checks.
"""

from kornia_ilum.filters.blur_pool import BlurPool2D, MaxBlurPool2D, blur_pool2d, max_blur_pool2d
from kornia_ilum.filters.soft_clip import SoftClip, soft_clip, soft_clip_unchecked

__all__ = [
    "soft_clip",
    "soft_clip_unchecked",
    "SoftClip",
    "blur_pool2d",
    "BlurPool2D",
    "max_blur_pool2d",
    "MaxBlurPool2D",
]
