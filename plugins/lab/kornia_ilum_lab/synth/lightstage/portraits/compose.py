r"""The pure steps of a training portrait: relight, frame the background, crop, expose, and the targets.

Small functions that :class:`~kornia_ilum_lab.synth.lightstage.portraits.PortraitDataset` chains (the package
docstring tells the whole recipe): :func:`relight_portraits` (a reflectance field times mirror-ball lightings),
the face and detector boxes (:func:`detector_boxes`, :func:`face_crop_boxes`, :func:`random_crop_boxes`),
:func:`crop_images`, the background as the field's camera sees it (:func:`frame_background` for maps at the
lighting's resolution, :func:`background_pyramid` and :func:`frame_backgrounds` for full-resolution maps with a
per-sample depth of field), :func:`auto_exposure` and the ground-truth :func:`sphere_targets`.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from typing import Any

import torch
import torch.nn.functional as F

from kornia_ilum.color import centre_weights
from kornia_ilum.core.check import check_positive_int, check_tensor
from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.detection.crop import CROP_SCALE, square_crop_boxes
from kornia_ilum.geometry import mirror_ball_to_lights
from kornia_ilum.render import SPHERE_SIZES, SparseField, relight, relight_sparse, sphere_pyramid
from kornia_ilum_lab.synth.background import LUMINANCE, camera_rays, latlong_grid, lookup_latlong
from kornia_ilum_lab.synth.camera_effects import lens_blur
from kornia_ilum_lab.synth.lightstage.field import ReflectanceField
from kornia_ilum_lab.synth.lightstage.scene import PIVOT_RAISE, Camera
from kornia_ilum_lab.synth.lightstage.subjects import LANDMARK_NAMES

__all__ = [
    "DETECTOR_BOX",
    "PHOTO_ASPECTS",
    "add_relit",
    "aspect_windows",
    "auto_exposure",
    "background_pyramid",
    "crop_images",
    "detector_boxes",
    "face_crop_boxes",
    "frame_background",
    "frame_backgrounds",
    "inner_crop_boxes",
    "random_crop_boxes",
    "relight_portraits",
    "sphere_targets",
    "uniform_draws",
]

#: The box OpenCV's Haar detector draws around a light-stage face, in terms of the *inner* face landmarks
#: (brows, outer eye corners, nose tip, mouth corners, chin; ears, cheeks and jaw excluded because they swing
#: out when the head turns): a square of side ``scale * h`` centred at the inner box's centre raised by
#: ``raise_ * h``, ``h`` the inner box's height. Fitted on the 16 detections in 36 renders (12 subjects x 3
#: views, 192 x 192): side 1.13 +- 0.14 h, centre raised 0.19 +- 0.04 h (the cameras aim there:
#: :data:`~kornia_ilum_lab.synth.lightstage.scene.PIVOT_RAISE`), horizontal offset -0.02 +- 0.03 h.
DETECTOR_BOX: dict[str, Any] = {
    "landmarks": (
        "brow_right_top", "brow_left_top", "eye_right_outer", "eye_left_outer", "nose_tip",
        "mouth_right", "mouth_left", "chin",
    ),
    "scale": 1.13,
    "raise_": PIVOT_RAISE,
}  # fmt: skip

_INNER = [LANDMARK_NAMES.index(n) for n in DETECTOR_BOX["landmarks"]]


def uniform_draws(n: int, lo: float, hi: float, generator: torch.Generator) -> torch.Tensor:
    """``n`` float64 draws uniform in ``[lo, hi)`` from ``generator`` (one ``torch.rand`` call).

    Args:
        n: the number of draws.
        lo: the lower end of the range.
        hi: the upper end of the range (``lo`` itself when ``hi == lo``).
        generator: the source of randomness; it advances by one call of ``n`` numbers.

    Returns:
        the draws ``(n,)``, float64, on the CPU.

    Examples:
        >>> uniform_draws(3, 2.0, 4.0, torch.Generator().manual_seed(0)).shape
        torch.Size([3])
    """
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

    Shape:
        - landmarks: :math:`(B, K, 2)`
        - Output: :math:`(B, 4)`

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
    *,
    generator: torch.Generator | None = None,
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

    Shape:
        - face_boxes: :math:`(B, 4)`
        - Output: :math:`(B, 4)`

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
        side = side * torch.exp(uniform_draws(b, -extent, extent, generator))
        cx = cx + side * uniform_draws(b, -position, position, generator)
        cy = cy + side * uniform_draws(b, -position, position, generator)
    return _fit_inside(torch.stack([cx - side / 2, cy - side / 2, cx + side / 2, cy + side / 2], -1), size)


def inner_crop_boxes(
    n: int,
    size: int,
    *,
    generator: torch.Generator,
    position: float = 0.10,
    extent: float = 0.15,
) -> torch.Tensor:
    r"""Square boxes inside a ``size x size`` crop: a second, jittered crop of the same face (crop consistency).

    The side is ``size * exp(-U(0, 2 extent))`` and the centre moves by ``U(-position, position)`` times
    ``size`` along each axis, then the box is shifted back inside the crop: the two crops of a pair then differ
    as two draws of :func:`face_crop_boxes`' jitter do (their log sides by up to ``2 extent``), with the smaller
    one inside the larger, so it needs nothing that the crop does not hold.

    Args:
        n: the number of boxes.
        size: the crop's side, in pixels.
        generator: the random source.
        position: the largest centre shift, a fraction of ``size``.
        extent: half the largest log-scale change of the side.

    Returns:
        ``(n, 4)`` float64 boxes ``(x0, y0, x1, y1)`` in the crop's pixels.

    Examples:
        >>> box = inner_crop_boxes(3, 256, generator=torch.Generator().manual_seed(0))
        >>> side = box[:, 2] - box[:, 0]
        >>> bool((box >= 0).all() and (box <= 256).all()), bool((side >= 256 * math.exp(-0.3) - 1e-9).all())
        (True, True)
    """
    check_positive_int(n, "n")
    check_positive_int(size, "size")
    if not (position >= 0 and extent >= 0):
        raise ValueCheckError(f"position and extent must be non-negative, got {position!r}, {extent!r}")
    side = size * torch.exp(-uniform_draws(n, 0.0, 2.0 * extent, generator))
    cx = size / 2 + size * uniform_draws(n, -position, position, generator)
    cy = size / 2 + size * uniform_draws(n, -position, position, generator)
    return _fit_inside(torch.stack([cx - side / 2, cy - side / 2, cx + side / 2, cy + side / 2], -1), size)


#: Photo aspects (width over height) of :func:`aspect_windows`, each landscape or portrait alike.
PHOTO_ASPECTS: tuple[float, ...] = (1.0, 4.0 / 3.0, 3.0 / 2.0, 16.0 / 9.0)


def aspect_windows(boxes: torch.Tensor, size: int, *, generator: torch.Generator) -> torch.Tensor:
    r"""Windows of a square ``size x size`` frame with a common photo's aspect, around each face: what a photo of
    that shape would show of the scene (the scene branch's training input, ``PortraitConfig.frame``).

    The aspect is one of :data:`PHOTO_ASPECTS`, landscape or portrait with equal odds; the window's longer side
    is the frame's, and along the shorter it is placed uniformly among the positions that keep the face's box
    inside (centred on the box where none does).

    Args:
        boxes: ``(N, 4)`` face boxes ``(x0, y0, x1, y1)`` in the frame's pixels.
        size: the frame's side.
        generator: the random source (three draws of ``N``).

    Returns:
        ``(N, 4)`` float32 windows ``(x0, y0, x1, y1)`` in whole pixels.

    Examples:
        >>> w = aspect_windows(torch.tensor([[40.0, 40, 80, 80]] * 8), 128, generator=torch.Generator().manual_seed(0))
        >>> bool(((w[:, 2] - w[:, 0] == 128) | (w[:, 3] - w[:, 1] == 128)).all())  # the longer side: the frame's
        True
        >>> bool(((w[:, :2] <= 40) & (w[:, 2:] >= 80)).all())  # the face inside
        True
    """
    check_positive_int(size, "size")
    if boxes.ndim != 2 or boxes.shape[-1] != 4:
        raise ValueCheckError(f"boxes must be (N, 4), got {tuple(boxes.shape)}")
    n = boxes.shape[0]
    aspect = torch.tensor(PHOTO_ASPECTS, dtype=torch.float64)[torch.randint(len(PHOTO_ASPECTS), (n,),
                                                                            generator=generator)]
    tall = torch.rand(n, generator=generator) < 0.5
    u = torch.rand(n, generator=generator, dtype=torch.float64)
    short = torch.round(size / aspect)
    b = boxes.double()
    low, high = torch.where(tall, b[:, 0], b[:, 1]), torch.where(tall, b[:, 2], b[:, 3])
    first, last = (high - short).clamp(min=0.0), torch.minimum(low, size - short)
    centred = ((low + high - short) / 2).clamp(min=0.0).minimum(size - short)
    start = torch.floor(torch.where(first <= last, first + u * (last - first), centred))
    zero, full = torch.zeros_like(start), torch.full_like(start, float(size))
    windows = torch.where(tall[:, None], torch.stack([start, zero, start + short, full], -1),
                          torch.stack([zero, start, full, start + short], -1))
    return windows.float()


def random_crop_boxes(
    face_boxes: torch.Tensor,
    size: int,
    *,
    generator: torch.Generator,
    side: tuple[float, float] = (0.25, 0.5),
    max_overlap: float = 0.2,
    tries: int = 32,
) -> torch.Tensor:
    r"""Random square crops that miss the face: at most ``max_overlap`` of each face box's area inside.

    Each crop has a side of ``U(side) * size`` and a uniform position in the image; a crop that covers more
    than ``max_overlap`` of the face box is drawn again, up to ``tries`` times, after which the candidate with
    the least overlap is kept.

    Args:
        face_boxes: ``(B, 4)`` face boxes ``(x0, y0, x1, y1)`` in pixels.
        size: the image side in pixels.
        generator: the source of randomness.
        side: the range of the crop side, as fractions of ``size``.
        max_overlap: the largest fraction of a face box's area that a crop may cover.
        tries: draws per crop before the least-overlapping one is kept.

    Returns:
        ``(B, 4)`` float64 crop boxes inside the image.

    Shape:
        - face_boxes: :math:`(B, 4)`
        - Output: :math:`(B, 4)`

    Examples:
        >>> g = torch.Generator().manual_seed(0)
        >>> box = random_crop_boxes(torch.tensor([[32.0, 32.0, 96.0, 96.0]]), 128, generator=g)
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
        s = uniform_draws(b, side[0] * size, side[1] * size, generator)
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
        field: the reflectance field, dense or compact (:func:`~kornia_ilum_lab.synth.lightstage.read_field`).
        lighting: ``(B, 3, S, S)`` mirror-ball radiance in the camera frame, ``S`` the field's lighting size.

    Returns:
        ``(image, alpha)``: ``(B, 3, H, W)`` float32 linear, premultiplied by ``alpha`` (background 0), and the
        ``(1, 1, H, W)`` matte (the same for every lighting).

    Shape:
        - lighting: :math:`(B, 3, S, S)`
        - Output: :math:`(B, 3, H, W)` and :math:`(1, 1, H, W)`

    Convention:
        The units of docs/conventions.rst (:mod:`~kornia_ilum_lab.synth.lightstage.field`):
        ``image = sum_n R[:, :, n] L[n]``. One batched product per call: relight many lightings of one field
        together.

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
    image = add_relit(lighting.new_zeros(lighting.shape[0], 3, field.size, field.size, dtype=torch.float32),
                       field, lighting=lighting)
    return image, field.alpha.float().reshape(1, 1, field.size, field.size)


def add_relit(frame: torch.Tensor, field: ReflectanceField, *, lighting: torch.Tensor,
              sparse: SparseField | None = None, eps: float = 0.0) -> torch.Tensor:
    """Add the relit subject (premultiplied) to ``frame`` ``(B, 3, H, W)`` in place; only covered pixels.

    Unchecked (the callers check): ``lighting`` is ``(B, 3, S, S)`` with the field's ``S``. Returns ``frame``.

    Args:
        frame: ``(B, 3, H, W)`` contiguous float32 images, ``H = W`` the field's size; changed in place.
        field: the reflectance field, dense or compact.
        lighting: ``(B, 3, S, S)`` mirror-ball radiance in the camera frame.
        sparse: the field's sparse sidecar (:func:`~kornia_ilum_lab.synth.lightstage.read_sparse`); with ``eps > 0``
            it relights sparsely (:func:`~kornia_ilum.render.relight_sparse`), otherwise densely.
        eps: the threshold of :func:`~kornia_ilum.render.relight_sparse`.

    Returns:
        ``frame``, with the relit subject added (the background is not attenuated by the matte: see
        :func:`relight_portraits` for the matte).

    Shape:
        - frame: :math:`(B, 3, H, W)`
        - lighting: :math:`(B, 3, S, S)`
        - Output: :math:`(B, 3, H, W)`

    Convention:
        Mirror-ball lighting and units of docs/conventions.rst, as in :func:`relight_portraits`.

    Examples:
        >>> from kornia_ilum.geometry import mirror_ball_valid
        >>> rf = ReflectanceField(torch.ones(3, 4, 16, dtype=torch.bfloat16), torch.ones(1, 2, 2),
        ...                       torch.tensor([0.0, 0.0, 2.0, 2.0]), Camera(30.0, 1.0, 0.0, 0.0, size=2), 7)
        >>> frame = torch.ones(1, 3, 2, 2)
        >>> lighting = torch.ones(1, 3, 4, 4) * mirror_ball_valid(4)  # 12 valid lights
        >>> out = add_relit(frame, rf, lighting=lighting)
        >>> out is frame, frame[0, 0].flatten().tolist()
        (True, [13.0, 13.0, 13.0, 13.0])
    """
    lights = mirror_ball_to_lights(lighting.float())
    if field.light_index is not None:
        lights = lights[:, field.light_index]
    if sparse is not None and eps > 0:
        image = relight_sparse(sparse, lights, eps)  # (B, 3, P')
    else:
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

    Shape:
        - images: :math:`(B, C, H, W)` or :math:`(1, C, H, W)`
        - boxes: :math:`(B, 4)`
        - Output: :math:`(B, C, size, size)`

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

    Separable, so built from two 1-D coordinate vectors (cheaper than
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

    The pixels' rays of the pinhole ``camera`` (:func:`~kornia_ilum_lab.synth.background.camera_rays`: the frame
    of docs/conventions.rst, looking along -Z; the environment is in the camera frame, so no rotation) looked
    up bilinearly in the lat-long maps (:func:`~kornia_ilum_lab.synth.background.lookup_latlong`). The rays'
    lat-long coordinates are computed once per camera and cached
    (:func:`~kornia_ilum_lab.synth.background.latlong_grid`), so a frame costs one
    :func:`~torch.nn.functional.grid_sample`.

    Args:
        latlong: ``(B, 3, H, 2H)`` linear lat-long maps in the camera frame.
        camera: the render's camera (its ``fov_deg`` and ``size``; the frame is square).
        mirror: ``(B,)`` bool: view the mirrored environment (``x -> -x``,
            :func:`~kornia_ilum.geometry.flip_lighting_horizontal`) for these maps, by mirroring the rays.

    Returns:
        ``(B, 3, size, size)`` linear.

    Shape:
        - latlong: :math:`(B, 3, H, 2H)`
        - Output: :math:`(B, 3, size, size)`

    Convention:
        Lat-long grid and camera frame of docs/conventions.rst ("Lat-long", "Frames"); the values keep the
        units of the maps (point sampling: a picture, not lighting).

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


def auto_exposure(
    linear: torch.Tensor, key: torch.Tensor | float = 0.18, *, white: float | None = 1.0
) -> torch.Tensor:
    r"""A camera's centre-weighted metering of what its sensor records: the gain ``g`` that maps the weighted
    mean of ``min(g Y, white)`` to ``key``.

    The weights are :func:`kornia_ilum.color.centre_weights`, a Gaussian of standard deviation 0.25 of the image
    side around its centre (where the face is); the luminance is Rec. 709 ``Y``. A sensor saturates, so a pixel at or above ``white`` after the
    gain counts as ``white``, however bright the scene is there: a sun or a window in the metered area
    darkens the exposure no more than a white wall would (a plain mean of the HDR values lets a sun of a few
    pixels expose a backlit face as a black silhouette). ``sum w min(g Y, white)`` is concave, increasing
    and linear between the pixels' clipping points, so Newton's steps from the plain mean's gain reach its root
    from below, exactly once the set of clipped pixels stops growing (a few steps). Where ``key`` cannot be
    reached (more than ``1 - key / white`` of the weight on black pixels) and with ``white=None``, the gain is
    ``key`` over the plain weighted mean. A black image gets a gain of 1.

    Args:
        linear: ``(B, 3, H, W)`` linear images.
        key: the target mean, a float or ``(B,)`` (0.18: middle grey).
        white: the sensor's saturation after the gain (1: the 8-bit encoding's white), or ``None`` for no
            clipping.

    Returns:
        ``(B,)`` gains (float64).

    Shape:
        - linear: :math:`(B, 3, H, W)`
        - key: a float or :math:`(B,)`
        - Output: :math:`(B,)`

    Convention:
        Linear images of docs/conventions.rst ("Images"); multiplying an image and its lighting by the same
        gain keeps the lighting in the image's units ("Units of lighting").

    Examples:
        >>> auto_exposure(torch.full((1, 3, 8, 8), 0.5)).tolist()
        [0.36]
        >>> sun = torch.full((1, 3, 8, 8), 0.5)
        >>> sun[..., 3, 3] = 1e4  # one pixel of sun near the centre
        >>> f"{auto_exposure(sun).item():.2f} clipped, {auto_exposure(sun, white=None).item():.1e} not"
        '0.29 clipped, 4.4e-04 not'
    """
    check_tensor(linear, "linear", ["B", "3", "H", "W"], finite=True, nonnegative=True)
    if white is not None and not (math.isfinite(white) and white > 0):
        raise ValueCheckError(f"white must be a positive finite float or None, got {white!r}")
    h, w = linear.shape[-2:]
    weight = centre_weights(h, w).flatten()
    lum = torch.einsum("bchw,c->bhw", linear.double(), torch.tensor(LUMINANCE, dtype=torch.float64)).flatten(1)
    mean = lum @ weight
    key = torch.as_tensor(key, dtype=torch.float64).expand_as(mean)
    gain = key / mean.clamp(min=1e-30)
    if white is not None:
        reachable = white * ((lum > 0).double() @ weight) > key
        for _ in range(64):  # Newton (docstring): stops once the set of clipped pixels stops growing
            unclipped = lum * gain[:, None] < white
            slope = (lum * unclipped) @ weight
            value = gain * slope + white * ((~unclipped).double() @ weight)
            step = torch.where(reachable & (slope > 0), (key - value) / slope.clamp(min=1e-300), 0.0)
            if not bool((step > 1e-12 * gain).any()):
                break
            gain = gain + step.clamp(min=0.0)
    return torch.where(mean > 0, gain, torch.ones_like(mean))


def sphere_targets(mirror_ball: torch.Tensor, sizes: Sequence[int] = (4, 8, 16, 32)) -> dict[str, torch.Tensor]:
    r"""The reference spheres as the loss sees them: ``softclip(render)^(1/2.2)`` at each size.

    Args:
        mirror_ball: ``(B, 3, S, S)`` linear lighting in image units.
        sizes: sphere sides (:data:`~kornia_ilum.render.SPHERE_SIZES`).

    Returns:
        ``{f"{brdf}_{size}": (B, 3, size, size)}`` for each of :data:`~kornia_ilum.render.BRDFS`; off-sphere
        pixels are 0. Exactly what the training loss compares (:func:`~kornia_ilum.render.sphere_pyramid`,
        ``gamma="safe"``): spheres of size ``s`` rendered from the energy-keeping lighting of size ``s``.

    Shape:
        - mirror_ball: :math:`(B, 3, S, S)`
        - Output: each :math:`(B, 3, size, size)`

    Convention:
        Mirror-ball lighting and reference spheres of docs/conventions.rst ("Mirror ball", "Reference
        spheres"), sizes as in its multi-scale rule.

    Examples:
        >>> sorted(sphere_targets(torch.ones(1, 3, 32, 32), sizes=(4,)))
        ['diffuse_4', 'matte_silver_4', 'mirror_4']
    """
    check_tensor(mirror_ball, "mirror_ball", ["B", "3", "S", "S"], nonnegative=True)
    s_l = mirror_ball.shape[-2]
    if mirror_ball.shape[-1] != s_l or s_l not in SPHERE_SIZES:
        raise ShapeError(f"mirror_ball must be (B, 3, S, S) with S in {SPHERE_SIZES}, got {tuple(mirror_ball.shape)}")
    for size in sizes:
        check_positive_int(size, "sizes", allowed=SPHERE_SIZES)
    return sphere_pyramid(mirror_ball, sizes=tuple(sizes), gamma="safe") if sizes else {}



# ----------------------------------------------------------------------------------------------
# full-resolution backgrounds with depth of field


def background_pyramid(latlong: torch.Tensor, levels: int = 4) -> tuple[torch.Tensor, ...]:
    r"""A lat-long map and its 2 x 2 averages, each padded for :func:`frame_backgrounds`.

    Level ``k`` is the map averaged over ``2^k x 2^k`` pixels (kept while it has at least 8 rows); each is padded
    by one pixel on every side as :func:`~kornia_ilum_lab.synth.background.lookup_latlong` pads (the azimuth wraps,
    the row beyond a pole is the same row half a turn on), so a lookup is one
    :func:`~torch.nn.functional.grid_sample` without a copy of the map. Build it once per environment.

    Args:
        latlong: ``(3, H, 2H)`` linear lat-long map, ``H`` even at every level that is kept.
        levels: the most levels.

    Returns:
        ``levels`` (or fewer) padded maps ``(1, 3, H / 2^k + 2, 2 H / 2^k + 2)``, float32.

    Shape:
        - latlong: :math:`(3, H, 2H)`
        - Output: level :math:`k` is :math:`(1, 3, H / 2^k + 2, 2H / 2^k + 2)`

    Convention:
        Lat-long grid of docs/conventions.rst ("Lat-long"); plain 2 x 2 means of the pixels (a picture, not
        lighting: not weighted by solid angle).

    Examples:
        >>> [tuple(m.shape) for m in background_pyramid(torch.ones(3, 32, 64), levels=3)]
        [(1, 3, 34, 66), (1, 3, 18, 34), (1, 3, 10, 18)]
    """
    check_tensor(latlong, "latlong", ["3", "H", "2H"], nonnegative=True)
    if latlong.shape[-1] != 2 * latlong.shape[-2]:
        raise ShapeError(f"latlong must have shape (3, H, 2H), got {tuple(latlong.shape)}")
    check_positive_int(levels, "levels")
    x = latlong.float()[None]
    out = []
    for k in range(levels):
        if k:
            if x.shape[-2] % 2 or x.shape[-2] < 16:
                break
            x = F.avg_pool2d(x, 2)
        w = x.shape[-1]
        top, bottom = x[..., :1, :].roll(w // 2, dims=-1), x[..., -1:, :].roll(w // 2, dims=-1)
        padded = torch.cat([top, x, bottom], dim=-2)
        out.append(torch.cat([padded[..., -1:], padded, padded[..., :1]], dim=-1).contiguous())
    return tuple(out)


def _view_matrices(b: int, mirror: list[bool], turn: list[float], rotation: torch.Tensor | None) -> torch.Tensor:
    """``(B, 3, 3)`` float64 ``Q = M^T T^{-1} F``: a camera ray ``r`` of sample ``b`` looks up direction ``Q r`` of
    its map (``F`` the mirror ``x -> -x`` or the identity, ``T`` the turn, ``M`` the map's direction map)."""
    alpha = 2.0 * math.pi * torch.tensor(turn, dtype=torch.float64)
    c, s = torch.cos(alpha), torch.sin(alpha)
    q = torch.zeros(b, 3, 3, dtype=torch.float64)  # T^{-1}: azimuth phi -> phi - alpha (the column u -> u - turn)
    q[:, 0, 0], q[:, 0, 2], q[:, 1, 1], q[:, 2, 0], q[:, 2, 2] = c, s, 1.0, -s, c
    q[:, :, 0] *= torch.tensor([-1.0 if m else 1.0 for m in mirror], dtype=torch.float64)[:, None]  # T^{-1} F
    if rotation is not None:
        q = rotation.to(torch.float64).transpose(-1, -2) @ q
    return q


def _rotated_grid(fov_deg: float, size: int, rows: int, q: torch.Tensor) -> torch.Tensor:
    """The padded map's ``grid_sample`` grid (``align_corners=True``) of the directions ``q r`` of a square camera's
    rays ``r``, ``(1, size, size, 2)`` (a permuted view of planar ``(2, size, size)`` coordinates).

    The rays need no normalising (``q`` is orthogonal and the angles are ratios): the unnormalised ray of pixel
    ``(i, j)`` is ``(x_j, y_i, -f)``, so each rotated coordinate is a row term plus a column term (one broadcast
    add for all three), then two ``atan2`` and a ``hypot``. In the padded map, column ``u W + 1/2`` of
    ``W + 2`` and row ``t H + 1/2`` of ``H + 2`` (:func:`background_pyramid`) are simply
    ``phi W / (pi (W + 1))`` and ``-el 2 H / (pi (H + 1))`` in normalised coordinates.
    """
    focal = (size / 2.0) / math.tan(math.radians(fov_deg) / 2.0)
    centres = torch.arange(size, dtype=torch.float32) + (0.5 - size / 2.0)  # x_j; y_i = -centres[i]
    q = q.float() * torch.tensor([1.0, 1.0, -1.0])[:, None]  # rows: x, y, -z of the direction
    d = (centres[None, :, None] * -q[:, 1:2, None] - focal * q[:, 2:3, None]) + centres[None, None, :] * q[:, 0:1, None]
    w = 2 * rows
    grid = torch.empty(2, size, size)
    torch.atan2(d[0], d[2], out=grid[0]).mul_(w / (math.pi * (w + 1)))
    torch.atan2(d[1], torch.hypot(d[0], d[2]), out=grid[1]).mul_(-2.0 * rows / (math.pi * (rows + 1)))
    return grid.permute(1, 2, 0)[None]


#: Blurs of more than this many frame pixels are made at a coarser level of :func:`background_pyramid`.
_SHARP_SIGMA = 0.5


def frame_backgrounds(
    pyramids: Sequence[Sequence[torch.Tensor]],
    camera: Camera,
    *,
    mirror: torch.Tensor | None = None,
    turn: torch.Tensor | None = None,
    sigma: torch.Tensor | None = None,
    rotation: torch.Tensor | None = None,
) -> torch.Tensor:
    r"""The camera's view of each environment from full-resolution maps, rotated, turned, mirrored, with depth of
    field.

    Sample ``b`` sees environment ``pyramids[b]`` (:func:`background_pyramid`) rotated by ``rotation[b]`` (a
    direction map ``M``: a light from ``d`` now comes from ``M d``, as the sampler's augmentation records it in
    ``params["augment"]["direction_map"]``; a rotation, possibly times a mirror), then turned about the vertical
    axis by ``turn[b]`` of a full turn (what rolling the lat-long map by ``turn * W`` columns does:
    ``x.roll(k, -1)`` is ``turn = k / W``) and mirrored (``x -> -x``) when ``mirror[b]``. Without a rotation this
    is what :func:`frame_background` would see of the rolled map; with one, what it would see of the map
    resampled by ``M`` first (the same up to interpolation: here the map is looked up once, at the frame's rays
    ``M^T T^{-1} F r``, computed per sample in one pass of trigonometry, instead of resampling the whole map).

    Depth of field: the background is blurred by a Gaussian of ``sigma[b]`` pixels of the frame (0.5 or less:
    sharp). The blur is made at a coarser level ``k = max(1, ceil(log2 sigma))`` of the pyramid: the view is
    looked up at ``size / 2^k`` in the map averaged ``2^k`` times, blurred by the rest
    (:func:`~kornia_ilum_lab.synth.camera_effects.lens_blur` of ``sqrt((sigma / 2^k)^2 - 1/6)``, the bilinear
    enlargement's own spread subtracted; a per-image separable kernel, cheaper than
    :func:`kornia.filters.gaussian_blur2d` with per-image sigmas) and enlarged to ``size`` (bilinear, OpenCV's
    ``resize`` on CPU float32): a blurred frame costs less than a sharp one. The widths are approximate (the
    averaged map and the enlargement blur a little in their own ways, and blurs below 0.8 pixel come out at
    about 0.8); the blur is the same everywhere (a distant background).

    Args:
        pyramids: ``B`` pyramids of padded maps (the same map may appear several times).
        camera: the render's camera (``fov_deg``, ``size``).
        mirror: ``(B,)`` bool, default none.
        turn: ``(B,)`` fractions of a turn, default 0.
        sigma: ``(B,)`` blur in frame pixels, default 0.
        rotation: ``(B, 3, 3)`` direction maps ``M`` (orthogonal), default the identity.

    Returns:
        ``(B, 3, size, size)`` linear float32.

    Shape:
        - pyramids: ``B`` tuples of :func:`background_pyramid` levels
        - mirror, turn, sigma: :math:`(B,)`
        - rotation: :math:`(B, 3, 3)`
        - Output: :math:`(B, 3, size, size)`

    Convention:
        Lat-long grid and camera frame of docs/conventions.rst ("Lat-long", "Frames"); ``rotation`` acts on
        the directions light arrives from, as in "Rotation".

    Examples:
        >>> maps = [background_pyramid(torch.ones(3, 32, 64))] * 2
        >>> view = frame_backgrounds(maps, Camera(40.0, 1.0, 0.0, 0.0, size=16), sigma=torch.tensor([0.0, 5.0]))
        >>> tuple(view.shape), bool(torch.allclose(view, torch.ones(())))
        ((2, 3, 16, 16), True)
    """
    if not isinstance(camera, Camera):
        raise TypeCheckError(f"camera must be a Camera, got {type(camera).__name__}")
    b = len(pyramids)
    _check_mirror(mirror, b)
    size, fov = camera.size, float(camera.fov_deg)
    mirror_l = [False] * b if mirror is None else mirror.tolist()
    turn_l = [0.0] * b if turn is None else [float(x) for x in turn.tolist()]
    sigma_l = [0.0] * b if sigma is None else [max(0.0, float(x)) for x in sigma.tolist()]
    if len(turn_l) != b or len(sigma_l) != b:
        raise ShapeError(f"turn and sigma must have shape ({b},)")
    if rotation is not None:
        check_tensor(rotation, "rotation", [str(b), "3", "3"], finite=True)
    views = _view_matrices(b, [bool(m) for m in mirror_l], turn_l, rotation)
    out = torch.empty(b, 3, size, size)
    groups: dict[int, list[int]] = {}
    for j, s in enumerate(sigma_l):
        k = 0 if s <= _SHARP_SIGMA else max(1, math.ceil(math.log2(s)))
        k = min(k, len(pyramids[j]) - 1, max(0, int(math.log2(size / 4))))
        groups.setdefault(k, []).append(j)
    for k, members in sorted(groups.items()):
        side = max(1, round(size / 2**k))
        frames = torch.empty(len(members), 3, side, side) if k else out[members[0] : members[0]]
        for n, j in enumerate(members):
            level = pyramids[j][k]
            grid = _rotated_grid(fov, side, level.shape[-2] - 2, views[j])
            view = F.grid_sample(level, grid, mode="bilinear", padding_mode="border", align_corners=True)[0]
            if k:
                frames[n] = view
            else:
                out[j] = view
        if k == 0:
            continue
        rest = torch.tensor([math.sqrt(max((sigma_l[j] / 2**k) ** 2 - 1 / 6, 0.0)) for j in members])
        sel = torch.nonzero(rest >= 0.3).flatten()
        if len(sel) and side > 3:
            frames[sel] = lens_blur(frames[sel], rest[sel])
        _enlarge(frames, out, members)
    return out


def _enlarge(frames: torch.Tensor, out: torch.Tensor, members: list[int]) -> None:
    """``out[members] = `` the frames enlarged to ``out``'s size, bilinear (``align_corners=False``).

    On CPU float32 with OpenCV's ``resize`` plane by plane (``INTER_LINEAR`` with float weights on float images:
    the same values up to float rounding, cheaper than :func:`~torch.nn.functional.interpolate` on one core:
    docs/lightstage.rst, "Measured").
    """
    size = out.shape[-2:]
    if frames.dtype != torch.float32 or frames.device.type != "cpu" or out.dtype != torch.float32:
        out[members] = F.interpolate(frames, size=tuple(size), mode="bilinear", align_corners=False)
        return
    import cv2  # lazy: OpenCV is slow to import, and only this CPU path needs it

    frames = frames.contiguous()
    for n, j in enumerate(members):
        for c in range(frames.shape[1]):
            cv2.resize(frames[n, c].numpy(), (size[1], size[0]), dst=out[j, c].numpy(),
                       interpolation=cv2.INTER_LINEAR)
