r"""Portrait synthesis from cached reflectance fields, and the on-the-fly training dataset.

A training portrait is made the way LeGendre et al. 2020 made theirs from light-stage captures:

1. **Relight** a subject's OLAT reflectance field (:mod:`~kornia_ilum.synth.lightstage.olat`) with a lighting
   environment's 32 x 32 mirror ball, in SPEC units (:func:`relight_portraits`). Half of the samples are
   mirrored left-right: the mirrored subject under the lighting ``L`` is the mirror image of the subject under
   the mirrored lighting (:func:`~kornia_ilum.geometry.flip_lighting_horizontal`), so one field serves as two
   subjects and the ground truth stays exact.
2. **Crop** the square face box expanded by 25 % (:data:`~kornia_ilum.detection.CROP_SCALE`, as at inference),
   with random jitter of position and extent, and resize to 256 (:func:`face_crop_boxes`, :func:`crop_images`).
   The face box comes from the geometry: the projected face landmarks, mapped to the box that OpenCV's Haar
   detector (the default detector at inference) draws around our renders (:data:`DETECTOR_BOX`), so training
   crops are framed like the crops the estimator will see.
3. **Composite** over a background rendered from the same environment, through the same camera: the frame's
   rays looked up in the lat-long map (:func:`frame_background`) and cropped with the same sampling grid as
   the subject, ``I + (1 - alpha) B``.
4. **Expose, clip and encode to 8-bit sRGB** (:func:`auto_exposure`, :func:`~kornia_ilum.color.encode_srgb8`):
   a centre-weighted auto-exposure (a camera's metering) with a random key, optional sensor noise, then the HDR
   is discarded.
   The ground-truth lighting is multiplied by the same exposure, so it is in the units of the image
   (SPEC.md, "Units of lighting"): a white Lambertian surface rendered with it gives the recorded pixel values.

Ground truth per sample: the 32 x 32 mirror ball in the camera frame, the reference spheres at 4, 8, 16 and
32 pixels as the loss uses them (``softclip(I)^(1/2.2)``, :func:`sphere_targets`), the subject's seed and
skin tone, the view, and the environment's indoor/outdoor label and source.

:class:`PortraitDataset` draws samples from cached fields (:func:`~kornia_ilum.synth.lightstage.build_cache`)
deterministically per ``(seed, worker)``, in chunks: each chunk relights a few fields with several lightings
each (one batched matrix product per field, the layout of :func:`kornia_ilum.render.relight`), from a pool of
environments that is refreshed a little at every chunk (a procedural environment costs about 20 ms, four
times the budget of a sample). Variants: a black background (as SIPR was trained), random crops that miss
the face box, the background alone (no subject), and pairs of one subject under two lightings (for SIPR).
"""

from __future__ import annotations

import functools
import math
import os
from collections import OrderedDict
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import torch
import torch.nn.functional as F
from torch.utils.data import IterableDataset, get_worker_info

from kornia_ilum.color import encode_srgb8, gamma_encode
from kornia_ilum.core.check import check_choice, check_positive_int, check_tensor, trusted
from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.core.seeding import hashed_generator
from kornia_ilum.detection.crop import CROP_SCALE, square_crop_boxes
from kornia_ilum.filters import soft_clip
from kornia_ilum.geometry import (
    flip_lighting_horizontal,
    latlong_to_mirror_ball,
    mirror_ball_to_lights,
    mirror_ball_valid,
)
from kornia_ilum.render import BRDFS, SPHERE_SIZES, relight
from kornia_ilum.render.spheres import _shared_field
from kornia_ilum.synth.background import LUMINANCE, camera_rays, latlong_grid, lookup_latlong
from kornia_ilum.synth.environments import Environment, EnvironmentSampler
from kornia_ilum.synth.lightstage.olat import ReflectanceField
from kornia_ilum.synth.lightstage.scene import PIVOT_RAISE, Camera
from kornia_ilum.synth.lightstage.subjects import LANDMARK_NAMES

__all__ = [
    "DETECTOR_BOX",
    "MAX_WORKERS",
    "PortraitDataset",
    "auto_exposure",
    "crop_images",
    "detector_boxes",
    "face_crop_boxes",
    "frame_background",
    "load_fields",
    "random_crop_boxes",
    "relight_portraits",
    "sphere_targets",
]

#: The box OpenCV's Haar detector draws around a light-stage face, in terms of the *inner* face landmarks
#: (brows, outer eye corners, nose tip, mouth corners, chin; ears, cheeks and jaw excluded because they swing
#: out when the head turns): a square of side ``scale * h`` centred at the inner box's centre raised by
#: ``raise_ * h``, ``h`` the inner box's height. Fitted on the 16 detections in 36 renders (12 subjects x 3
#: views, 192 x 192): side 1.13 +- 0.14 h, centre raised 0.19 +- 0.04 h (the cameras aim there:
#: :data:`~kornia_ilum.synth.lightstage.olat.PIVOT_RAISE`), horizontal offset -0.02 +- 0.03 h.
DETECTOR_BOX: dict[str, Any] = {
    "landmarks": (
        "brow_right_top", "brow_left_top", "eye_right_outer", "eye_left_outer", "nose_tip",
        "mouth_right", "mouth_left", "chin",
    ),
    "scale": 1.13,
    "raise_": PIVOT_RAISE,
}  # fmt: skip

#: Workers per dataset at most: worker ``w`` draws environment ``j`` of its own stream as the sampler's index
#: ``j * MAX_WORKERS + w``, so workers never draw the same environment.
MAX_WORKERS = 1024

_INNER = [LANDMARK_NAMES.index(n) for n in DETECTOR_BOX["landmarks"]]


def _generator(seed: int, *key: int) -> torch.Generator:
    return hashed_generator("kornia_ilum.portraits:" + ":".join(str(int(k)) for k in (seed, *key)))


def _uniform(n: int, lo: float, hi: float, generator: torch.Generator) -> torch.Tensor:
    return lo + (hi - lo) * torch.rand(n, generator=generator, dtype=torch.float64)


# ----------------------------------------------------------------------------------------------
# boxes


def detector_boxes(landmarks: torch.Tensor) -> torch.Tensor:
    r"""The face box a face detector would draw, from projected face landmarks (:data:`DETECTOR_BOX`).

    Args:
        landmarks: ``(B, K, 2)`` pixel coordinates ``(x, y)`` of the :data:`LANDMARK_NAMES` landmarks (the
            ``meta["landmarks"]`` of a reflectance field).

    Returns:
        ``(B, 4)`` square boxes ``(x0, y0, x1, y1)`` in continuous pixel coordinates.

    Examples:
        >>> lm = torch.full((1, len(LANDMARK_NAMES), 2), 50.0)
        >>> lm[0, LANDMARK_NAMES.index("brow_left_top"), 1] = 0.0  # the inner box: 100 tall, centred at y = 50
        >>> lm[0, LANDMARK_NAMES.index("chin"), 1] = 100.0
        >>> detector_boxes(lm)  # side 113, centre raised 19
        tensor([[ -6.5000, -25.5000, 106.5000,  87.5000]])
    """
    check_tensor(landmarks, "landmarks", ["B", str(len(LANDMARK_NAMES)), "2"], finite=True)
    inner = landmarks[:, _INNER].double()
    lo, hi = inner.amin(1), inner.amax(1)
    h = hi[:, 1] - lo[:, 1]
    cx, cy = 0.5 * (lo[:, 0] + hi[:, 0]), 0.5 * (lo[:, 1] + hi[:, 1]) - DETECTOR_BOX["raise_"] * h
    half = 0.5 * DETECTOR_BOX["scale"] * h
    return torch.stack([cx - half, cy - half, cx + half, cy + half], -1).to(landmarks.dtype)


def _fit_inside(boxes: torch.Tensor, size: int) -> torch.Tensor:
    """Shrink square boxes to at most the image and shift them inside it."""
    side = (boxes[:, 2] - boxes[:, 0]).clamp(max=size)
    x0 = ((boxes[:, 0] + boxes[:, 2] - side) / 2).clamp(0.0, None)
    y0 = ((boxes[:, 1] + boxes[:, 3] - side) / 2).clamp(0.0, None)
    x0, y0 = torch.minimum(x0, size - side), torch.minimum(y0, size - side)
    return torch.stack([x0, y0, x0 + side, y0 + side], -1)


def face_crop_boxes(
    face_boxes: torch.Tensor,
    size: int,
    generator: torch.Generator | None = None,
    *,
    scale: float = CROP_SCALE,
    position: float = 0.06,
    extent: float = 0.15,
) -> torch.Tensor:
    r"""Square crops around face boxes: expanded by ``scale``, jittered, and kept inside the image.

    The side is ``scale * side(face_box) * exp(U(-extent, extent))`` and the centre moves by
    ``U(-position, position)`` times the side along each axis; a crop that leaves the ``size x size`` render
    is shifted back inside it (and shrunk to the image if larger), so every crop pixel has rendered content.

    Args:
        face_boxes: ``(B, 4)`` square boxes ``(x0, y0, x1, y1)`` (:func:`detector_boxes`).
        size: the side of the rendered image, in pixels.
        generator: the jitter's random source; ``None``: no jitter.
        scale: the expansion (1.25, as the crops at inference: :func:`kornia_ilum.detection.square_crop_boxes`).
        position: the largest centre shift, as a fraction of the crop's side.
        extent: the largest log-scale change of the side.

    Returns:
        ``(B, 4)`` float64 crop boxes.

    Examples:
        >>> face_crop_boxes(torch.tensor([[40.0, 40.0, 80.0, 80.0]]), 128)
        tensor([[35., 35., 85., 85.]], dtype=torch.float64)
    """
    check_tensor(face_boxes, "face_boxes", ["B", "4"], finite=True)
    check_positive_int(size, "size")
    boxes = square_crop_boxes(face_boxes.double(), scale)  # the crop at inference
    b = boxes.shape[0]
    side = boxes[:, 2] - boxes[:, 0]
    cx, cy = 0.5 * (boxes[:, 0] + boxes[:, 2]), 0.5 * (boxes[:, 1] + boxes[:, 3])
    if generator is not None:
        side = side * torch.exp(_uniform(b, -extent, extent, generator))
        cx = cx + side * _uniform(b, -position, position, generator)
        cy = cy + side * _uniform(b, -position, position, generator)
    return _fit_inside(torch.stack([cx - side / 2, cy - side / 2, cx + side / 2, cy + side / 2], -1), size)


def random_crop_boxes(
    face_boxes: torch.Tensor,
    size: int,
    generator: torch.Generator,
    *,
    side: tuple[float, float] = (0.25, 0.5),
    max_overlap: float = 0.2,
    tries: int = 32,
) -> torch.Tensor:
    r"""Random square crops that miss the face: at most ``max_overlap`` of each face box's area inside.

    Each crop has a side of ``U(side) * size`` and a uniform position in the image; a crop that covers more
    than ``max_overlap`` of the face box is drawn again, up to ``tries`` times, after which the candidate with
    the least overlap is kept.

    Returns:
        ``(B, 4)`` float64 crop boxes inside the image.

    Examples:
        >>> g = torch.Generator().manual_seed(0)
        >>> box = random_crop_boxes(torch.tensor([[32.0, 32.0, 96.0, 96.0]]), 128, g)
        >>> bool(((box[:, 2] - box[:, 0]) <= 64).all())
        True
    """
    check_tensor(face_boxes, "face_boxes", ["B", "4"], finite=True)
    check_positive_int(size, "size")
    faces = face_boxes.double()
    b = faces.shape[0]
    area = ((faces[:, 2] - faces[:, 0]) * (faces[:, 3] - faces[:, 1])).clamp(min=1e-9)
    best = torch.zeros(b, 4, dtype=torch.float64)
    best_overlap = torch.full((b,), math.inf, dtype=torch.float64)
    for _ in range(tries):
        s = _uniform(b, side[0] * size, side[1] * size, generator)
        x0 = torch.rand(b, generator=generator, dtype=torch.float64) * (size - s)
        y0 = torch.rand(b, generator=generator, dtype=torch.float64) * (size - s)
        cand = torch.stack([x0, y0, x0 + s, y0 + s], -1)
        w = (torch.minimum(cand[:, 2], faces[:, 2]) - torch.maximum(cand[:, 0], faces[:, 0])).clamp(min=0)
        h = (torch.minimum(cand[:, 3], faces[:, 3]) - torch.maximum(cand[:, 1], faces[:, 1])).clamp(min=0)
        overlap = w * h / area
        better = (overlap < best_overlap) & (best_overlap > max_overlap)
        best[better], best_overlap[better] = cand[better], overlap[better]
    return best


# ----------------------------------------------------------------------------------------------
# images


def relight_portraits(field: ReflectanceField, lighting: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    r"""Relight one subject-view with a batch of mirror-ball lightings.

    Args:
        field: the reflectance field, dense or compact (:func:`~kornia_ilum.synth.lightstage.read_field`).
        lighting: ``(B, 3, S, S)`` mirror-ball radiance in the camera frame, ``S`` the field's lighting size.

    Returns:
        ``(image, alpha)``: ``(B, 3, H, W)`` float32 linear, premultiplied by ``alpha`` (background 0), and the
        ``(1, 1, H, W)`` matte (the same for every lighting).

    Convention:
        SPEC units (:mod:`~kornia_ilum.synth.lightstage.olat`): ``image = sum_n R[:, :, n] L[n]``. One batched
        product per call: relight many lightings of one field together.

    Examples:
        >>> rf = ReflectanceField(torch.ones(3, 4, 16, dtype=torch.bfloat16), torch.ones(1, 2, 2),
        ...                       torch.tensor([0.0, 0.0, 2.0, 2.0]), Camera(30.0, 1.0, 0.0, 0.0, size=2), 7)
        >>> from kornia_ilum.geometry import mirror_ball_valid
        >>> image, alpha = relight_portraits(rf, torch.ones(1, 3, 4, 4) * mirror_ball_valid(4))
        >>> image[0, :, 0, 0]  # the 12 valid lights of a 4 x 4 mirror ball
        tensor([12., 12., 12.])
    """
    if not isinstance(field, ReflectanceField):
        raise TypeCheckError(f"field must be a ReflectanceField, got {type(field).__name__}")
    s = field.lighting_size
    check_tensor(lighting, "lighting", ["B", "3", str(s), str(s)], finite=True, nonnegative=True)
    image = _add_relit(lighting.new_zeros(lighting.shape[0], 3, field.size, field.size, dtype=torch.float32),
                       field, lighting)
    return image, field.alpha.float().reshape(1, 1, field.size, field.size)


def _add_relit(frame: torch.Tensor, field: ReflectanceField, lighting: torch.Tensor) -> torch.Tensor:
    """Add the relit subject (premultiplied) to ``frame`` ``(B, 3, H, W)`` in place; only covered pixels."""
    lights = mirror_ball_to_lights(lighting.float())
    if field.light_index is not None:
        lights = lights[:, field.light_index]
    image = relight(field.field, lights, (1, field.field.shape[1]))[:, :, 0]  # (B, 3, P')
    flat = frame.view(frame.shape[0], 3, -1)
    if field.pixel_index is None:
        flat.add_(image)
    else:
        flat.index_add_(2, field.pixel_index, image)
    return frame


def crop_images(images: torch.Tensor, boxes: torch.Tensor, size: int, mirror: torch.Tensor | None = None
                ) -> torch.Tensor:
    r"""Crop boxes out of images and resize them to ``size x size`` (bilinear), optionally mirrored.

    Args:
        images: ``(B, C, H, W)``, or ``(1, C, H, W)`` for one image shared by all boxes.
        boxes: ``(B, 4)`` ``(x0, y0, x1, y1)`` in continuous pixel coordinates (pixel ``(i, j)`` spans
            ``[j, j + 1] x [i, i + 1]``); the output pixels tile the box exactly.
        size: the output side.
        mirror: ``(B,)`` bool: flip crop ``b`` left-right (free: part of the sampling grid); default none.

    Returns:
        ``(B, C, size, size)``; outside the image, 0.

    Convention:
        Bilinear, without antialiasing: meant for enlarging or mild shrinking (the light-stage crops of 130 to
        190 pixels are enlarged to 256). One separable sampling grid and
        :func:`~torch.nn.functional.grid_sample`: the same result as
        :func:`kornia.geometry.transform.crop_and_resize`, which builds a perspective warp and is slower
        (``benchmarks/bench_ops.py``, section images).

    Examples:
        >>> crop_images(torch.arange(16.0).reshape(1, 1, 4, 4), torch.tensor([[0.0, 0.0, 2.0, 2.0]]), 2)
        tensor([[[[0., 1.],
                  [4., 5.]]]])
    """
    check_tensor(images, "images", ["B", "C", "H", "W"])
    check_tensor(boxes, "boxes", ["B", "4"], finite=True)
    check_positive_int(size, "size")
    if images.shape[0] not in (1, boxes.shape[0]):
        raise ShapeError(f"images must hold 1 or {boxes.shape[0]} images, got {images.shape[0]}")
    _check_mirror(mirror, len(boxes))
    grid = _crop_grid(boxes, images.shape[-2:], size, mirror).to(images.dtype)
    images = images.expand(len(boxes), -1, -1, -1)
    return F.grid_sample(images, grid, mode="bilinear", padding_mode="zeros", align_corners=False)


def _check_mirror(mirror: object, n: int) -> None:
    if mirror is not None and (
        not isinstance(mirror, torch.Tensor) or mirror.dtype != torch.bool or mirror.shape != (n,)
    ):
        raise TypeCheckError(f"mirror must be a bool tensor of shape ({n},), got {mirror!r}")


def _crop_grid(boxes: torch.Tensor, hw: Sequence[int], size: int, mirror: torch.Tensor | None) -> torch.Tensor:
    """The ``grid_sample`` grid (normalised, ``align_corners=False``) of axis-aligned crops of an ``hw`` frame.

    Separable, so built from two 1-D coordinate vectors (6 times faster than
    :func:`~torch.nn.functional.affine_grid`, which multiplies every output pixel by a matrix).
    """
    h, w = hw
    b = boxes.double()
    t = (torch.arange(size, dtype=torch.float64) + 0.5) / size  # output pixel centres in [0, 1]
    x0, x1 = b[:, :1], b[:, 2:3]
    if mirror is not None:
        x0, x1 = torch.where(mirror[:, None], x1, x0), torch.where(mirror[:, None], x0, x1)
    gx = (2.0 * (x0 + t * (x1 - x0)) / w - 1.0).float()  # (B, size)
    gy = (2.0 * (b[:, 1:2] + t * (b[:, 3:4] - b[:, 1:2])) / h - 1.0).float()
    return torch.stack(torch.broadcast_tensors(gx[:, None, :], gy[:, :, None]), -1)


def frame_background(latlong: torch.Tensor, camera: Camera, mirror: torch.Tensor | None = None) -> torch.Tensor:
    r"""What the camera sees of each environment, linear, one ray per pixel of its frame.

    The pixels' rays of the pinhole ``camera`` (:func:`~kornia_ilum.synth.background.camera_rays`: SPEC frame,
    looking along -Z; the environment is in the camera frame, so no rotation) looked up bilinearly in the
    lat-long maps (:func:`~kornia_ilum.synth.background.lookup_latlong`). The rays' lat-long coordinates are
    computed once per camera and cached (:func:`~kornia_ilum.synth.background.latlong_grid`), so a frame costs
    one :func:`~torch.nn.functional.grid_sample`.

    Args:
        latlong: ``(B, 3, H, 2H)`` linear lat-long maps in the camera frame.
        camera: the render's camera (its ``fov_deg`` and ``size``; the frame is square).
        mirror: ``(B,)`` bool: view the mirrored environment (``x -> -x``,
            :func:`~kornia_ilum.geometry.flip_lighting_horizontal`) for these maps, by mirroring the rays.

    Returns:
        ``(B, 3, size, size)`` linear.

    Examples:
        >>> frame_background(torch.ones(2, 3, 8, 16), Camera(30.0, 1.0, 0.0, 0.0, size=64)).shape
        torch.Size([2, 3, 64, 64])
    """
    check_tensor(latlong, "latlong", ["B", "3", "H", "2H"], nonnegative=True)
    if latlong.shape[-1] != 2 * latlong.shape[-2]:
        raise ShapeError(f"latlong must have shape (B, 3, H, 2H), got {tuple(latlong.shape)}")
    if not isinstance(camera, Camera):
        raise TypeCheckError(f"camera must be a Camera, got {type(camera).__name__}")
    _check_mirror(mirror, len(latlong))
    rows = latlong.shape[-2]
    grid = _frame_grid(float(camera.fov_deg), camera.size, rows, False)
    if mirror is not None and bool(mirror.any()):
        grid = torch.where(mirror[:, None, None, None], _frame_grid(float(camera.fov_deg), camera.size, rows, True),
                           grid)
    return lookup_latlong(latlong, grid)


@functools.lru_cache(maxsize=32)
def _frame_grid(fov_deg: float, size: int, rows: int, mirrored: bool) -> torch.Tensor:
    """The :func:`lookup_latlong` grid ``(1, size, size, 2)`` of a square camera's rays (float32)."""
    rays = camera_rays((size, size), fov_deg, torch.eye(3, dtype=torch.float64))
    if mirrored:
        rays[..., 0] = -rays[..., 0]
    return latlong_grid(rays, rows)[None].float()


def auto_exposure(linear: torch.Tensor, key: torch.Tensor | float = 0.18) -> torch.Tensor:
    r"""A camera's centre-weighted metering: the gain that maps the weighted mean luminance to ``key``.

    The weights are a Gaussian of standard deviation 0.25 of the image side around its centre (where the
    face is); the luminance is Rec. 709 ``Y``. A black image gets a gain of 1.

    Args:
        linear: ``(B, 3, H, W)`` linear images.
        key: the target mean, a float or ``(B,)`` (0.18: middle grey).

    Returns:
        ``(B,)`` gains (float64).

    Examples:
        >>> auto_exposure(torch.full((1, 3, 8, 8), 0.5)).tolist()
        [0.36]
    """
    check_tensor(linear, "linear", ["B", "3", "H", "W"], finite=True, nonnegative=True)
    h, w = linear.shape[-2:]
    yy = (torch.arange(h, dtype=torch.float64) + 0.5) / h - 0.5
    xx = (torch.arange(w, dtype=torch.float64) + 0.5) / w - 0.5
    weight = torch.exp(-(yy[:, None] ** 2 + xx[None] ** 2) / (2 * 0.25**2))
    lum = torch.einsum("bchw,c->bhw", linear.double(), torch.tensor(LUMINANCE, dtype=torch.float64))
    mean = (lum * weight).sum((1, 2)) / weight.sum()
    key = torch.as_tensor(key, dtype=torch.float64).expand_as(mean)
    return torch.where(mean > 0, key / mean.clamp(min=1e-30), torch.ones_like(mean))


def sphere_targets(mirror_ball: torch.Tensor, sizes: Sequence[int] = (4, 8, 16, 32)) -> dict[str, torch.Tensor]:
    r"""The reference spheres as the loss sees them: ``softclip(render)^(1/2.2)`` at each size.

    Args:
        mirror_ball: ``(B, 3, S, S)`` linear lighting in image units.
        sizes: sphere sides (:data:`~kornia_ilum.render.SPHERE_SIZES`).

    Returns:
        ``{f"{brdf}_{size}": (B, 3, size, size)}`` for each of :data:`~kornia_ilum.render.BRDFS`; off-sphere
        pixels are 0. Exactly what :func:`~kornia_ilum.metrics.reconstruction_loss` compares.

    Examples:
        >>> sorted(sphere_targets(torch.ones(1, 3, 32, 32), sizes=(4,)))
        ['diffuse_4', 'matte_silver_4', 'mirror_4']
    """
    check_tensor(mirror_ball, "mirror_ball", ["B", "3", "S", "S"], nonnegative=True)
    b, _, s_l = mirror_ball.shape[:3]
    if mirror_ball.shape[-1] != s_l or s_l not in SPHERE_SIZES:
        raise ShapeError(f"mirror_ball must be (B, 3, S, S) with S in {SPHERE_SIZES}, got {tuple(mirror_ball.shape)}")
    lights = mirror_ball_to_lights(mirror_ball)
    keys, masks, parts = [], [], []
    for s in sizes:  # render the on-sphere pixels only, then encode all the renders in one pass
        check_positive_int(s, "sizes", allowed=SPHERE_SIZES)
        for brdf in BRDFS:
            field = _shared_field(brdf, s, s_l, mirror_ball.device, mirror_ball.dtype, on_sphere=True)
            keys.append(f"{brdf}_{s}")
            masks.append(mirror_ball_valid(s, device=mirror_ball.device).flatten())
            parts.append(relight(field, lights, (1, field.shape[0]))[:, :, 0])
    if not parts:
        return {}
    encoded = gamma_encode(soft_clip(torch.cat(parts, -1)), 2.2)
    out, start = {}, 0
    for key, mask, part in zip(keys, masks, parts, strict=True):
        image = encoded.new_zeros(b, 3, mask.numel())
        image[:, :, mask] = encoded[:, :, start : start + part.shape[-1]]
        start += part.shape[-1]
        side = math.isqrt(mask.numel())
        out[key] = image.reshape(b, 3, side, side)
    return out


# ----------------------------------------------------------------------------------------------
# dataset


def load_fields(source: str | os.PathLike | Sequence[ReflectanceField], split: str | None = None
                ) -> list[ReflectanceField]:
    r"""Reflectance fields from a cache folder (:func:`~kornia_ilum.synth.lightstage.build_cache`) or a list.

    Args:
        source: a cache folder (its manifest's entries, sorted by seed and view, in the compact layout and
            memory-mapped: :func:`~kornia_ilum.synth.lightstage.read_field` with ``mmap=True``) or a sequence
            of :class:`~kornia_ilum.synth.lightstage.ReflectanceField`.
        split: keep only the subjects of this split (``"train"`` or ``"eval"``,
            :func:`~kornia_ilum.synth.lightstage.subject_split`); ``None``: all.

    Raises:
        ValueCheckError: no field is left, fields of different lighting sizes, or an unknown split.
    """
    from kornia_ilum.synth.lightstage.cache import read_field, read_manifest

    if split not in (None, "train", "eval"):
        raise ValueCheckError(f"split must be 'train', 'eval' or None, got {split!r}")
    if isinstance(source, (str, os.PathLike)):
        entries = read_manifest(source)["entries"]
        entries = [e for e in entries if split is None or e.get("split") == split]
        fields = [read_field(Path(source) / e["path"], dense=False, mmap=True) for e in entries]
        for f, e in zip(fields, entries, strict=True):
            f.meta.setdefault("view_index", e["view_index"])
    else:
        fields = list(source)
        if not all(isinstance(f, ReflectanceField) for f in fields):
            raise TypeCheckError("source must be a cache folder or a sequence of ReflectanceField")
        fields = [f for f in fields if split is None or f.meta.get("split") == split]
    if not fields:
        raise ValueCheckError(f"no reflectance field in {source!r} for split {split!r}")
    if len({f.lighting_size for f in fields}) != 1:
        raise ValueCheckError("all fields must share one lighting size")
    if any("landmarks" not in f.meta for f in fields):
        raise ValueCheckError("every field needs meta['landmarks'] (rendered by render_olat)")
    return fields


class PortraitDataset(IterableDataset):
    r"""Training portraits synthesised on the fly from cached reflectance fields (module docstring).

    Iteration yields sample dicts, deterministically per ``(seed, worker)``: worker ``w`` of a
    :class:`~torch.utils.data.DataLoader` yields the samples of :meth:`chunk` ``(w, 0)``, ``(w, 1)``, ... (without
    workers, ``w = 0``), shuffled within groups of ``shuffle`` chunks. A chunk takes ``fields_per_chunk`` fields at random and relights each with
    ``lightings_per_field`` lightings in one batched product. Lightings come from a pool of the last
    ``env_pool`` environments of the worker's stream, ``env_refresh`` of them new at every chunk, each used
    with a random rotation about the vertical axis (a whole number of lat-long columns, exact).

    Args:
        fields: a cache folder or a list of fields (:func:`load_fields`).
        split: the subjects to use (``"train"``, ``"eval"`` or ``None`` for all).
        environments: the environment sampler; default :class:`~kornia_ilum.synth.environments.EnvironmentSampler`
            with its procedural sources and ``seed``.
        seed: the seed of everything random.
        size: the output side (256).
        background: ``"environment"`` (the matching background) or ``"black"`` (as SIPR was trained).
        crop: ``"face"`` (the jittered face crop) or ``"random"`` (:func:`random_crop_boxes`, missing the face).
        subject: ``False`` renders the background alone (no face), framed as with the subject.
        pairs: also render each sample's subject, view, crop and flip under a second lighting, as
            ``sample["pair"]`` (for SIPR).
        flip_probability: the fraction of samples mirrored left-right.
        exposure_key: the range of the auto-exposure's key (log-uniform).
        noise: the range of the sensor noise's standard deviation, linear units of the exposed image (uniform):
            0.002 is about 7 codes of 255 in black and half a code in mid-grey.
        sphere_sizes: the sizes of the sphere targets.
        fields_per_chunk, lightings_per_field, env_pool, env_refresh: the batching (class docstring).
        shuffle: iteration shuffles the samples of every ``shuffle`` consecutive chunks together, so a batch of
            a data loader mixes ``shuffle * fields_per_chunk`` subject-views.
        length: samples per worker and pass (``None``: endless).

    Sample keys:
        ``image`` ``(3, size, size)`` sRGB 8-bit values in ``[0, 1]``; ``mirror_ball`` ``(3, S, S)`` linear
        lighting in image units, camera frame; ``spheres`` ``{f"{brdf}_{s}": (3, s, s)}``
        (:func:`sphere_targets`); ``exposure`` (the gain applied to the HDR render and to ``mirror_ball``);
        ``crop_box`` and ``face_box`` ``(4,)`` in the render's pixels (after the flip); ``subject_seed``,
        ``skin_tone``, ``view_index``, ``flip``; ``label`` (``"indoor"``/``"outdoor"``) and ``source`` of the
        environment; ``chunk`` ``(worker, index)``; with ``pairs``, ``pair`` holds ``image``, ``mirror_ball``,
        ``spheres``, ``exposure``, ``label`` and ``source`` of the second lighting.

    Examples:
        >>> rf = ReflectanceField(torch.ones(3, 16, 64, dtype=torch.bfloat16) / 64, torch.ones(1, 4, 4),
        ...                       torch.tensor([1.0, 1.0, 3.0, 3.0]), Camera(30.0, 1.0, 0.0, 0.0, size=4), 7,
        ...                       {"landmarks": [[1.0 + i % 3, 1.0 + i % 2] for i in range(20)]})
        >>> data = PortraitDataset([rf], split=None, size=16, sphere_sizes=(4, 8), env_pool=2, env_refresh=1,
        ...                        lightings_per_field=2, shuffle=1, length=3)
        >>> samples = list(data)
        >>> len(samples), tuple(samples[0]["image"].shape), tuple(samples[0]["mirror_ball"].shape)
        (3, (3, 16, 16), (3, 8, 8))
    """

    def __init__(
        self,
        fields: str | os.PathLike | Sequence[ReflectanceField],
        split: str | None = "train",
        environments: EnvironmentSampler | None = None,
        seed: int = 0,
        *,
        size: int = 256,
        background: str = "environment",
        crop: str = "face",
        subject: bool = True,
        pairs: bool = False,
        flip_probability: float = 0.5,
        exposure_key: tuple[float, float] = (0.1, 0.3),
        noise: tuple[float, float] = (0.0, 0.002),
        sphere_sizes: Sequence[int] = (4, 8, 16, 32),
        fields_per_chunk: int = 4,
        lightings_per_field: int = 16,
        env_pool: int = 32,
        env_refresh: int = 1,
        shuffle: int = 4,
        length: int | None = None,
    ) -> None:
        super().__init__()
        self.fields = load_fields(fields, split)
        self.lighting_size = self.fields[0].lighting_size
        if environments is not None and not isinstance(environments, EnvironmentSampler):
            raise TypeCheckError(f"environments must be an EnvironmentSampler, got {type(environments).__name__}")
        self.environments = EnvironmentSampler(seed=seed) if environments is None else environments
        if isinstance(seed, bool) or not isinstance(seed, int):
            raise TypeCheckError(f"seed must be an int, got {type(seed).__name__}")
        check_choice(background, "background", ("environment", "black"))
        check_choice(crop, "crop", ("face", "random"))
        for name in ("size", "fields_per_chunk", "lightings_per_field", "env_pool", "env_refresh"):
            check_positive_int(locals()[name], name)
        check_positive_int(shuffle, "shuffle")
        if length is not None:
            check_positive_int(length, "length")
        if env_refresh > env_pool:
            raise ValueCheckError(f"env_refresh ({env_refresh}) must not exceed env_pool ({env_pool})")
        if not 0.0 <= flip_probability <= 1.0:
            raise ValueCheckError(f"flip_probability must be in [0, 1], got {flip_probability}")
        if not 0.0 < exposure_key[0] <= exposure_key[1]:
            raise ValueCheckError(f"exposure_key must be an increasing pair of positive numbers, got {exposure_key}")
        if not 0.0 <= noise[0] <= noise[1]:
            raise ValueCheckError(f"noise must be an increasing pair of non-negative numbers, got {noise}")
        if any(s > self.lighting_size for s in sphere_sizes):
            raise ValueCheckError(f"sphere_sizes {tuple(sphere_sizes)} exceed the lighting size {self.lighting_size}")
        self.seed = seed
        self.settings = {
            "size": size, "background": background, "crop": crop, "subject": subject, "pairs": pairs,
            "flip_probability": flip_probability, "exposure_key": tuple(exposure_key), "noise": tuple(noise),
            "sphere_sizes": tuple(sphere_sizes), "fields_per_chunk": fields_per_chunk,
            "lightings_per_field": lightings_per_field, "env_pool": env_pool, "env_refresh": env_refresh,
        }  # fmt: skip
        self.length = length
        self.shuffle = shuffle
        self._envs: OrderedDict[int, Environment] = OrderedDict()
        self._noise_bank: torch.Tensor | None = None

    def __repr__(self) -> str:
        subjects = len({f.subject_seed for f in self.fields})
        return (f"PortraitDataset({len(self.fields)} fields of {subjects} subjects, seed={self.seed}, "
                f"{', '.join(f'{k}={v}' for k, v in self.settings.items())})")

    def __iter__(self) -> Iterator[dict[str, Any]]:
        info = get_worker_info()
        worker = 0 if info is None else info.id
        if worker >= MAX_WORKERS:
            raise ValueCheckError(f"at most {MAX_WORKERS} workers, got worker {worker}")
        count, group = 0, 0
        while True:
            samples = [s for index in range(group * self.shuffle, (group + 1) * self.shuffle)
                       for s in self.chunk(worker, index)]
            order = torch.randperm(len(samples), generator=_generator(self.seed, worker, group, -2)).tolist()
            for k in order:
                if self.length is not None and count >= self.length:
                    return
                yield samples[k]
                count += 1
            group += 1

    def _environment(self, worker: int, j: int) -> Environment:
        key = j * MAX_WORKERS + worker
        env = self._envs.get(key)
        if env is None:
            env = self.environments.sample(key)
            self._envs[key] = env
            while len(self._envs) > 2 * self.settings["env_pool"]:
                self._envs.popitem(last=False)
        return env

    def _lightings(self, worker: int, index: int, n: int, g: torch.Generator) -> tuple[torch.Tensor, list[Environment]]:
        """``n`` lat-long maps from the pool of chunk ``index``, each turned by a random whole column count."""
        pool, refresh = self.settings["env_pool"], self.settings["env_refresh"]
        last = (index + 1) * refresh
        window = list(range(max(0, last - pool), last))
        picks = torch.randint(len(window), (n,), generator=g).tolist()
        envs = [self._environment(worker, window[p]) for p in picks]
        width = envs[0].latlong.shape[-1]
        shifts = torch.randint(width, (n,), generator=g).tolist()
        latlongs = torch.empty(n, *envs[0].latlong.shape)
        for out, env, k in zip(latlongs, envs, shifts, strict=True):  # out = env.latlong.roll(k, dims=-1)
            x = env.latlong.float()
            torch.cat([x[..., width - k :], x[..., : width - k]], -1, out=out)  # two block copies
        return latlongs, envs

    def chunk(self, worker: int, index: int) -> list[dict[str, Any]]:
        """The samples of chunk ``index`` of ``worker``: a pure function of ``(seed, worker, index)``."""
        with trusted():  # no value scans: its inputs are the loaded fields and the sampler's checked environments
            return self._chunk(worker, index)

    def _chunk(self, worker: int, index: int) -> list[dict[str, Any]]:
        st = self.settings
        g = _generator(self.seed, worker, index)
        nf, nl = st["fields_per_chunk"], st["lightings_per_field"]
        n = nf * nl
        field_ids = torch.randint(len(self.fields), (nf,), generator=g).tolist()
        flips = torch.rand(n, generator=g) < st["flip_probability"]
        lightings = [self._lightings(worker, index, n, g) for _ in range(2 if st["pairs"] else 1)]
        keys = [torch.exp(_uniform(n, *map(math.log, st["exposure_key"]), g)) for _ in lightings]
        noise = _uniform(n, *st["noise"], g)
        boxes, faces, renders = [], [], [[] for _ in lightings]
        for k, fid in enumerate(field_ids):
            rows = slice(k * nl, (k + 1) * nl)
            rf = self.fields[fid]
            landmarks = torch.tensor(rf.meta["landmarks"], dtype=torch.float64).expand(nl, -1, -1).clone()
            landmarks[flips[rows], :, 0] = rf.size - landmarks[flips[rows], :, 0]  # in the mirrored image
            faces.append(detector_boxes(landmarks))
            if st["crop"] == "face":
                boxes.append(face_crop_boxes(faces[-1], rf.size, g))
            else:
                boxes.append(random_crop_boxes(faces[-1], rf.size, g))
            for out, (latlong, _), key in zip(renders, lightings, keys, strict=True):
                out.append(self._render(rf, latlong[rows], flips[rows], boxes[-1], key[rows], noise[rows], g))
        views = []
        for out, (_, envs) in zip(renders, lightings, strict=True):
            image, truth, gain = (torch.cat(parts) for parts in zip(*out, strict=True))
            views.append({"image": image, "mirror_ball": truth, "exposure": gain,
                          "spheres": sphere_targets(truth, st["sphere_sizes"]),
                          "label": [e.label for e in envs], "source": [e.source for e in envs]})
        boxes, faces = torch.cat(boxes).float(), torch.cat(faces).float()
        samples = []
        for j in range(n):
            rf = self.fields[field_ids[j // nl]]
            one = [{**{k: v[j] for k, v in view.items() if k != "spheres"},
                    "spheres": {k: v[j] for k, v in view["spheres"].items()}} for view in views]
            sample = {
                **one[0],
                "crop_box": boxes[j],
                "face_box": faces[j],
                "subject_seed": rf.subject_seed,
                "skin_tone": int(rf.meta.get("skin_tone", -1)),
                "view_index": int(rf.meta.get("view_index", -1)),
                "flip": bool(flips[j]),
                "chunk": (worker, index),
            }
            if st["pairs"]:
                sample["pair"] = one[1]
            samples.append(sample)
        return samples

    def _add_noise(self, images: torch.Tensor, sigma: torch.Tensor, g: torch.Generator) -> None:
        """Add sensor noise of standard deviation ``sigma[b]`` to ``images`` in place.

        Drawing fresh Gaussian noise for every pixel costs more than the rest of the encoding; windows at random
        offsets of one ``(3, size + 64, size + 64)`` Gaussian texture (seeded by the dataset's seed), with random
        signs, look the same and cost one addition.
        """
        size = images.shape[-1]
        if self._noise_bank is None or self._noise_bank.shape[-1] != size + 64:
            self._noise_bank = torch.randn(3, size + 64, size + 64, generator=_generator(self.seed, -1))
        offsets = torch.randint(65, (len(sigma), 2), generator=g).tolist()
        signs = torch.where(torch.rand(len(sigma), generator=g) < 0.5, -sigma, sigma).tolist()
        for image, (i, j), s in zip(images, offsets, signs, strict=True):
            image.add_(self._noise_bank[:, i : i + size, j : j + size], alpha=s)

    def _render(self, rf: ReflectanceField, latlong: torch.Tensor, flip: torch.Tensor, boxes: torch.Tensor,
                key: torch.Tensor, sigma: torch.Tensor, g: torch.Generator
                ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """``(image, mirror_ball, exposure)`` of one field under a batch of lightings (module docstring).

        ``boxes`` are in the mirrored image for the mirrored samples. A mirrored sample is the subject relit
        with the mirrored lighting over the mirrored environment's background (mirrored rays), cropped through
        the mirrored box and flipped (in the crop's sampling grid): the mirrored subject under the true lighting.
        """
        st = self.settings
        size = st["size"]
        lighting = latlong_to_mirror_ball(latlong, self.lighting_size)
        source_boxes = boxes.clone()
        source_boxes[flip, 0], source_boxes[flip, 2] = rf.size - boxes[flip, 2], rf.size - boxes[flip, 0]
        if st["background"] == "environment":
            frame = frame_background(latlong, rf.camera, flip)
            if st["subject"]:
                frame.mul_(1.0 - rf.alpha.float())  # I + (1 - alpha) B, I added below
        else:
            frame = latlong.new_zeros(len(latlong), 3, rf.size, rf.size)
        if st["subject"]:
            _add_relit(frame, rf, torch.where(flip[:, None, None, None], flip_lighting_horizontal(lighting), lighting))
        linear = crop_images(frame, source_boxes, size, flip)
        step = max(1, size // 64)  # meter on a 64 x 64 subsample
        gain = auto_exposure(linear[:, :, step // 2 :: step, step // 2 :: step].clamp(min=0.0), key)
        linear.mul_(gain[:, None, None, None].to(linear))
        self._add_noise(linear, sigma, g)
        image = encode_srgb8(linear, inplace=True)
        return image, lighting * gain[:, None, None, None].to(lighting), gain.float()
