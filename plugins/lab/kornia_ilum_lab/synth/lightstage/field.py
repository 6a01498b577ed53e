r"""The OLAT reflectance field of a subject seen by a camera: what the renderers return and the cache stores.

A reflectance field ``R`` holds, for every image pixel ``p`` and every light ``n`` of the ``S x S``
mirror-ball lighting basis (docs/conventions.rst, "Mirror ball"), the pixel's linear response to unit radiance
arriving from the solid angle of mirror-ball pixel ``n``. Any lighting ``L`` (a mirror ball in radiance) then
relights the subject exactly as the renderer would have: ``I[c, p] = sum_n R[c, p, n] L[n, c]``
(:func:`kornia_ilum.render.relight`). The renderers are :func:`~kornia_ilum_lab.synth.lightstage.olat.render_olat`
and :func:`~kornia_ilum_lab.synth.lightstage.reference.render_olat_reference`; the cache is
:mod:`~kornia_ilum_lab.synth.lightstage.cache`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from dataclasses import field as dataclass_field
from typing import Any

import numpy as np
import torch

from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum_lab.synth.lightstage.scene import Camera

__all__ = ["ReflectanceField"]


@dataclass
class ReflectanceField:
    r"""An OLAT reflectance field of one subject seen by one camera.

    Attributes:
        field: ``(3, P, N)`` bfloat16, channel-major, ``P = size * size`` pixels in row-major order and
            ``N = lighting_size ** 2`` lights in the row-major order of the mirror-ball grid. The columns of
            invalid mirror-ball pixels are zero. Linear, premultiplied by ``alpha``, in the units of
            docs/conventions.rst ("Units of lighting"): relight with
            ``kornia_ilum.render.relight(field, lights)`` where ``lights`` is ``(B, N, 3)`` radiance.
        alpha: ``(1, size, size)`` float32 matte in ``[0, 1]`` (pixel coverage).
        face_box: ``(4,)`` float32 ``(x0, y0, x1, y1)`` box of the projected face landmarks, in continuous
            pixel coordinates (:func:`~kornia_ilum_lab.synth.lightstage.scene.project_points`).
        camera: the camera.
        subject_seed: the subject's seed.
        meta: JSON-ready facts: renderer settings, timings, the subject's split and skin tone when known.
        pixel_index: ``None`` for the dense layout above. In the *compact* layout of the cache
            (:func:`kornia_ilum_lab.synth.lightstage.cache.read_field` with ``dense=False``), int64 ``(P',)`` flat
            indices of the stored pixels (the others are 0: background), and ``field`` is ``(3, P', N')``.
        light_index: ``None``, or in the compact layout int64 ``(N',)`` indices of the stored lights (the
            valid ones).
        gbuffer: the renderer's :class:`~kornia_ilum_lab.synth.lightstage.gbuffer.GBuffer` (one-pass renders), or
            ``None`` (not cached).
        albedo: ``None``, or ``(3, size, size)`` float32: the linear diffuse albedo of what each pixel sees (the
            G-buffer's, kept by the cache), for the uniform-white check
            (:mod:`~kornia_ilum_lab.synth.lightstage.calibration`).
        skin: ``None``, or ``(1, size, size)`` float32: the fraction of each pixel that is skin (the G-buffer's
            ``subsurface``, kept by the cache).

    Examples:
        >>> rf = ReflectanceField(torch.zeros(3, 4, 16, dtype=torch.bfloat16), torch.ones(1, 2, 2),
        ...                       torch.tensor([0.0, 0.0, 2.0, 2.0]), Camera(30.0, 1.0, 0.0, 0.0, size=2), 7)
        >>> rf.size, rf.lighting_size, rf.is_compact
        (2, 4, False)
    """

    field: torch.Tensor
    alpha: torch.Tensor
    face_box: torch.Tensor
    camera: Camera
    subject_seed: int
    meta: dict[str, Any] = dataclass_field(default_factory=dict)
    pixel_index: torch.Tensor | None = None
    light_index: torch.Tensor | None = None
    gbuffer: Any = dataclass_field(default=None, repr=False, compare=False)
    albedo: torch.Tensor | None = dataclass_field(default=None, repr=False)
    skin: torch.Tensor | None = dataclass_field(default=None, repr=False)

    @property
    def size(self) -> int:
        """The image side in pixels."""
        return int(self.alpha.shape[-1])

    @property
    def lighting_size(self) -> int:
        """The mirror-ball side ``S`` of the basis: ``meta["lighting_size"]``, else ``sqrt(N)`` (dense)."""
        if "lighting_size" in self.meta:
            return int(self.meta["lighting_size"])
        if self.is_compact:  # N' valid lights do not give S
            raise ValueCheckError("a compact ReflectanceField needs meta['lighting_size']")
        return math.isqrt(self.field.shape[-1])

    @property
    def is_compact(self) -> bool:
        """Whether ``field`` holds only the ``pixel_index`` rows and ``light_index`` columns."""
        return self.pixel_index is not None or self.light_index is not None

    def to_dense(self) -> ReflectanceField:
        """This field in the dense ``(3, size^2, S^2)`` layout (itself if it already is)."""
        if not self.is_compact:
            return self
        p, n = self.size**2, self.lighting_size**2
        rows = torch.arange(p) if self.pixel_index is None else self.pixel_index
        cols = torch.arange(n) if self.light_index is None else self.light_index
        dense = torch.zeros(3, p, n, dtype=self.field.dtype)
        dense[:, rows[:, None], cols] = self.field
        return ReflectanceField(dense, self.alpha, self.face_box, self.camera, self.subject_seed,
                                dict(self.meta), albedo=self.albedo, skin=self.skin)

    def to_compact(self) -> ReflectanceField:
        """Only the pixels with coverage or any response, and only the valid lights (lossless)."""
        if self.is_compact:
            return self
        cols = torch.from_numpy(np.flatnonzero(mirror_ball_valid(self.lighting_size).flatten().numpy()))
        keep = (self.alpha.flatten() > 0) | (self.field != 0).any(dim=2).any(dim=0)
        rows = torch.nonzero(keep).flatten()
        compact = self.field[:, rows[:, None], cols]
        return ReflectanceField(compact, self.alpha, self.face_box, self.camera, self.subject_seed,
                                dict(self.meta), rows, cols, albedo=self.albedo, skin=self.skin)
