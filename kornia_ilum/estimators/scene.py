r"""The light's strength from the whole photograph: a scene branch beside the face's estimate.

A face crop cannot tell a dark skin under much light from a light skin under less; the rest of the photo often
can, through whatever the same light falls on whose reflectance has nothing to do with the skin: a wall or a
floor beside the subject, the clothes, other people (docs/training.rst, issue 47). :class:`SceneStrength` is a
small network on the whole photo, letterboxed to :data:`SCENE_SIZE` pixels (:func:`scene_input`), that gives
the light's log energy per channel and its spread; :func:`fuse_strength` combines it with the face estimate's
own by their spreads, so that the face network gives the lighting's shape and both give its strength. Where the
photo shows nothing that helps (a plain backdrop, a tight crop), the scene's spread should be wide and the face
stays in charge.

The branch does not see the face: the face's box, grown by two pixels, is blanked (and given as a channel of
its own, so the network knows where the face was), and the frame is metered on the rest of the photo:
re-exposed so that its mean luminance outside the box is the crop's key
(:data:`~kornia_ilum.color.EXPOSURE_KEY`), the factor added back to the log energy. So its error has nothing to
do with the skin's albedo, which is what makes the fusion of two estimates worth more than either (a branch
that sees and meters the face learns the face's own tone bias, and worse: docs/training.rst, issue 47), and it
scales exactly with the photo's exposure, as the face's does. The energy of a lighting is each channel's
radiance summed over the sphere (:func:`~kornia_ilum.metrics.total_radiance`).

No branch ships yet: trained on the light stage (dressed subjects, walls, floors, backdrops, companions), the
branch does not improve the face's strength: it either reads the skin it still sees (a neck, arms) as the face
does, or, kept from following the tone, is too unsure of the unknown reflectances around the face to move it
(docs/training.rst, issue 47); :func:`~kornia_ilum.estimate_lighting` uses one only when given it.
"""

from __future__ import annotations

import dataclasses
import os

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from kornia_ilum.color import EXPOSURE_KEY, LUMINANCE, linear_to_srgb, srgb_to_linear
from kornia_ilum.core.check import check_tensor
from kornia_ilum.core.errors import ShapeError, ValueCheckError
from kornia_ilum.estimators.base import LightingEstimate, read_weights
from kornia_ilum.estimators.ours import LOG_SPREAD_RANGE
from kornia_ilum.metrics import total_radiance

__all__ = ["MIN_REST", "SCENE_DEPTHS", "SCENE_SIZE", "SceneStrength", "fuse_strength", "scene_input"]

#: Side of the square the photo is letterboxed into for :class:`SceneStrength`.
SCENE_SIZE = 128
#: The least share of the square that the photo must show besides the face for :class:`SceneStrength` to read it:
#: below it (a face that fills the photo, a strip of a panorama wider than about 3:1) the branch gives its widest
#: spread, and the face's own estimate stays in charge.
MIN_REST = 1.0 / 3.0
#: Depths of the scene network's five stride-2 convolutions.
SCENE_DEPTHS: tuple[int, ...] = (16, 32, 64, 96, 128)


def scene_input(images: Tensor, boxes: Tensor, index: Tensor, size: int = SCENE_SIZE) -> Tensor:
    r"""Each face's photo letterboxed into a ``size`` square (the longer side fits, the rest 0), its box as a
    fourth channel (1 inside, 0 outside) and the photo's extent as a fifth (1 on the photo, 0 on the padding).

    Args:
        images: :math:`(B, 3, H, W)` sRGB photos in ``[0, 1]``.
        boxes: :math:`(N, 4)` face boxes ``(x0, y0, x1, y1)`` in the photos' pixels.
        index: :math:`(N,)` int64, the photo of each box.
        size: the square's side.

    Returns:
        :math:`(N, 5, size, size)` in the dtype of ``images``.

    Examples:
        >>> box = torch.tensor([[30.0, 15.0, 60.0, 45.0]])  # 30 px in a 120 x 60 photo, halved
        >>> x = scene_input(torch.rand(1, 3, 60, 120), box, torch.zeros(1, dtype=torch.int64), 64)
        >>> x.shape, x[0, 3].sum().item(), x[0, :3, :16].abs().sum().item(), x[0, 4].sum().item()  # padded above
        (torch.Size([1, 5, 64, 64]), 256.0, 0.0, 2048.0)
    """
    if boxes.ndim != 2 or boxes.shape[-1] != 4 or index.shape != boxes.shape[:1]:
        raise ShapeError(f"boxes must be (N, 4) with one index each, got {tuple(boxes.shape)}, "
                         f"{tuple(index.shape)}")
    h, w = images.shape[-2:]
    s = size / max(h, w)
    nh, nw = max(1, round(h * s)), max(1, round(w * s))
    top, left = (size - nh) // 2, (size - nw) // 2
    # shrunk by averaging whole blocks of pixels (the light stage's frames are area-averaged), then a bilinear step
    block = max(1, int(1.0 / s))
    small = F.avg_pool2d(images, block) if block > 1 else images
    if small.shape[-2:] != (nh, nw):  # already at size (a training frame, a photo of 5 x 128): nothing to resample
        small = F.interpolate(small, size=(nh, nw), mode="bilinear", align_corners=False)
    small = small.clamp(0, 1)
    frame = F.pad(small, (left, size - nw - left, top, size - nh - top))[index]
    b = boxes.to(frame) * s + torch.tensor([left, top, left, top], dtype=frame.dtype, device=frame.device)
    centres = torch.arange(size, dtype=frame.dtype, device=frame.device) + 0.5
    inside_x = (centres >= b[:, None, 0]) & (centres < b[:, None, 2])
    inside_y = (centres >= b[:, None, 1]) & (centres < b[:, None, 3])
    mask = (inside_y[:, :, None] & inside_x[:, None, :]).to(frame.dtype)[:, None]
    extent = torch.zeros_like(mask)
    extent[..., top : top + nh, left : left + nw] = 1.0
    return torch.cat([frame, mask, extent], 1)


class SceneStrength(nn.Module):
    r"""The light's log energy per channel and its spread from the whole photo (module docstring).

    Five stride-2 3x3 convolutions (:data:`SCENE_DEPTHS`) on :func:`scene_input`'s :math:`(N, 5, 128, 128)` (the
    face blanked, the frame metered without it: module docstring), global average pooling and two linear layers:
    18 M multiply-adds per face, about 1/40 of ``ours``.

    Args:
        hidden: the width of the hidden linear layer.

    Examples:
        >>> net = SceneStrength().eval()
        >>> frames = scene_input(torch.rand(2, 3, 96, 128), torch.tensor([[40.0, 20, 80, 70], [10, 10, 50, 60]]),
        ...                      torch.tensor([0, 1]))
        >>> log_energy, spread = net(frames)
        >>> log_energy.shape, spread.shape, bool((spread > 0).all())
        (torch.Size([2, 3]), torch.Size([2]), True)
    """

    def __init__(self, hidden: int = 64) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        depth_in = 5
        for depth in SCENE_DEPTHS:
            layers += [nn.Conv2d(depth_in, depth, 3, stride=2, padding=1), nn.ReLU()]
            depth_in = depth
        self.features = nn.Sequential(*layers, nn.AdaptiveAvgPool2d(1), nn.Flatten())
        self.head = nn.Sequential(nn.Linear(depth_in, hidden), nn.ReLU(), nn.Linear(hidden, 4))

    @classmethod
    def from_file(cls, path: str | os.PathLike[str]) -> SceneStrength:
        """A trained branch, in eval mode, from its weight file (``kornia-ilum train --estimator scene``), read
        by :func:`~kornia_ilum.estimators.read_weights` (no pickle).

        Raises:
            OSError: the file cannot be read; ValueCheckError: its tensors are not this network's.
        """
        net = cls()
        try:
            net.load_state_dict(read_weights(path, expected_by="SceneStrength.from_file")[0], strict=True)
        except RuntimeError as e:  # missing, unexpected or misshapen tensors
            raise ValueCheckError(f"{os.fspath(path)} holds no scene branch's weights: {e}") from None
        return net.eval()

    def forward(self, frames: Tensor) -> tuple[Tensor, Tensor]:
        r"""``(log_energy, spread)`` of each face's photo.

        Args:
            frames: :math:`(N, 5, S, S)` of :func:`scene_input`.

        Returns:
            :math:`(N, 3)` natural-log energy per channel in the photo's units, and :math:`(N,)` the spread ``b``
            of a Laplace distribution of the true log energy around it (``log b`` clamped to ``ours``'
            :data:`~kornia_ilum.estimators.ours.LOG_SPREAD_RANGE`; its top, ``e^3``, where the photo shows less
            than :data:`MIN_REST` of the square besides the face).
        """
        check_tensor(frames, "frames", ["N", "5", "S", "S"])
        work = torch.promote_types(frames.dtype, torch.float32)
        # the box grown by 2 pixels: the resampling of scene_input spreads the face's pixels about one pixel out;
        # a box is a rectangle, so it grows along its rows and its columns apart (cheaper than a 5 x 5 max-pool)
        inside = frames[:, 3].to(work)
        rows = F.max_pool1d(inside.amax(-1)[:, None], 5, stride=1, padding=2)
        cols = F.max_pool1d(inside.amax(-2)[:, None], 5, stride=1, padding=2)
        box, extent = (rows[..., :, None] * cols[..., None, :]), frames[:, 4:5].to(work)
        rest = extent * (1.0 - box)  # the photo without the face
        linear = srgb_to_linear(frames[:, :3].to(work)) * rest
        luma = torch.einsum("nchw,c->n", linear, torch.tensor(LUMINANCE, dtype=work, device=linear.device))
        scale = (luma / rest.sum((1, 2, 3)).clamp(min=1.0) / EXPOSURE_KEY).clamp(min=1e-6)
        x = torch.cat([linear_to_srgb((linear / scale[:, None, None, None]).clamp(max=1.0)), box, extent], 1)
        out = self.head(self.features(x.to(self.head[0].weight.dtype) - 0.5)).to(work)
        void = rest.sum((1, 2, 3)) < MIN_REST * frames.shape[-2] * frames.shape[-1]  # too little to read
        log_spread = torch.where(void, LOG_SPREAD_RANGE[1], out[:, 3].clamp(*LOG_SPREAD_RANGE))
        return out[:, :3] + torch.log(scale)[:, None], torch.exp(log_spread)


def fuse_strength(estimate: LightingEstimate, log_energy: Tensor, spread: Tensor,
                  image_index: Tensor | None = None) -> LightingEstimate:
    r"""The face estimates with one strength per photo: the faces' own and the scene's, fused per channel by
    inverse variance.

    With face :math:`f`'s log energy :math:`e_f` (:func:`~kornia_ilum.metrics.total_radiance`) and spread
    :math:`b_f`, and the photo's scene estimate :math:`e_s`, :math:`b_s` (the mean of the scene branch's outputs
    for the photo's faces: one scene, one piece of evidence, however many faces look at it),
    :math:`e = (\sum_f e_f / b_f^2 + e_s / b_s^2) / (\sum_f 1 / b_f^2 + 1 / b_s^2)`; every face's mirror ball
    (and SH) is scaled by :math:`\exp(e - e_f)`, so each keeps its own shape and all share the photo's strength,
    and its spread becomes :math:`(\sum_f 1 / b_f^2 + 1 / b_s^2)^{-1/2}`. ``scene_share`` says how much of the
    weight was the scene's: :math:`b_s^{-2} / (\sum_f b_f^{-2} + b_s^{-2})`.

    Args:
        estimate: ``N`` face estimates with ``log_energy_spread``.
        log_energy: :math:`(N, 3)` the scene branch's, per face.
        spread: :math:`(N,)` the scene branch's, per face.
        image_index: :math:`(N,)` int64, the photo of each face; ``None``: every face a photo of its own.

    Returns:
        the fused :class:`~kornia_ilum.estimators.LightingEstimate`.

    Raises:
        ShapeError: shapes that do not match, or an estimate without ``log_energy_spread``.

    Examples:
        >>> from kornia_ilum.geometry import mirror_ball_valid
        >>> valid = mirror_ball_valid(32)
        >>> face = LightingEstimate(mirror_ball=valid.expand(1, 3, 32, 32).float(), valid=valid,
        ...                         log_energy_spread=torch.tensor([0.5]))
        >>> e_face = torch.log(total_radiance(face.mirror_ball))
        >>> fused = fuse_strength(face, e_face + 1.0, torch.tensor([0.5]))  # equally sure, e times brighter
        >>> bool(torch.allclose(fused.mirror_ball[0, :, 16, 16], torch.full((3,), 0.5).exp()))
        True
        >>> round(fused.log_energy_spread.item(), 4), round(fused.scene_share.item(), 4)  # 0.5 / sqrt(2)
        (0.3536, 0.5)
    """
    n = estimate.mirror_ball.shape[0]
    index = torch.arange(n, device=spread.device) if image_index is None else image_index.to(spread.device)
    if estimate.log_energy_spread is None or log_energy.shape != (n, 3) or spread.shape != (n,) or \
            index.shape != (n,):
        raise ShapeError(f"fuse_strength needs the face's spread and ({n}, 3), ({n},) of the scene (and ({n},) "
                         f"photo indices), got {tuple(log_energy.shape)}, {tuple(spread.shape)}, "
                         f"{tuple(index.shape)}")
    work = torch.promote_types(estimate.mirror_ball.dtype, torch.float32)
    light = estimate.mirror_ball.to(work)
    e_face = torch.log(total_radiance(light).clamp(min=torch.finfo(work).tiny))
    photos = int(index.max()) + 1 if n else 0

    def per_photo(x: Tensor) -> Tensor:  # sums over each photo's faces
        return x.new_zeros((photos, *x.shape[1:])).index_add_(0, index, x)

    faces = per_photo(torch.ones(n, dtype=work, device=light.device)).clamp(min=1.0)
    w_scene = (per_photo(spread.to(work)) / faces) ** -2
    e_scene = per_photo(log_energy.to(work)) / faces[:, None]
    w_face = estimate.log_energy_spread.to(work) ** -2
    weight = per_photo(w_face) + w_scene
    fused = ((per_photo(w_face[:, None] * e_face) + w_scene[:, None] * e_scene) / weight[:, None])[index]
    gain = torch.exp(fused - e_face)
    ball = light * gain[:, :, None, None]
    sh = None if estimate.sh is None else (estimate.sh.to(work) * gain[:, None, :]).to(estimate.sh.dtype)
    return dataclasses.replace(
        estimate, mirror_ball=ball.to(estimate.mirror_ball.dtype), sh=sh,
        log_mirror_ball=torch.where(estimate.valid, torch.log1p(ball), 0.0).to(estimate.mirror_ball.dtype),
        log_energy_spread=weight.rsqrt()[index].to(estimate.log_energy_spread.dtype),
        scene_share=(w_scene / weight)[index].to(estimate.log_energy_spread.dtype))
