r"""Geometry buffers of a light-stage render: what the camera sees, independent of the lighting.

The renderer (:mod:`~kornia_ilum_lab.synth.lightstage.olat`) writes them beside the reflectance field; the
subsurface step (:mod:`~kornia_ilum_lab.synth.lightstage.subsurface`) and the denoiser
(:mod:`~kornia_ilum_lab.synth.lightstage.denoise`) take their weights from them only, never from the radiance, so
both stay linear in the lighting.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

__all__ = ["GBuffer"]


@dataclass
class GBuffer:
    r"""Per-pixel buffers of the first opaque camera hit, averaged over each pixel's samples.

    Attributes:
        albedo: ``(3, H, W)`` float32 linear diffuse albedo (0 where nothing is hit).
        normal: ``(3, H, W)`` float32 shading normal in the camera frame of docs/conventions.rst ("Frames":
            +Z toward the camera), the mean over the pixel's hits (not renormalised; 0 where nothing is hit).
        depth: ``(1, H, W)`` float32 mean distance along the camera's -Z axis in metres (0 where nothing is hit).
        alpha: ``(1, H, W)`` float32 coverage in ``[0, 1]``.
        subsurface: ``(1, H, W)`` float32 fraction of the pixel's samples that hit a part whose material has
            ``subsurface=True`` (skin).
        focal_px: pixels per unit of ``x / depth``: ``size / 2 / tan(fov / 2)``; a length ``r`` metres at
            depth ``z`` spans ``focal_px * r / z`` pixels.

    Examples:
        >>> g = GBuffer(torch.zeros(3, 2, 2), torch.zeros(3, 2, 2), torch.zeros(1, 2, 2), torch.zeros(1, 2, 2),
        ...             torch.zeros(1, 2, 2), focal_px=3.0)
        >>> g.size
        2
    """

    albedo: torch.Tensor
    normal: torch.Tensor
    depth: torch.Tensor
    alpha: torch.Tensor
    subsurface: torch.Tensor
    focal_px: float

    @property
    def size(self) -> int:
        """The image side in pixels."""
        return int(self.alpha.shape[-1])
