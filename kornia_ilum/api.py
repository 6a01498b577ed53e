r"""End to end: a portrait in, HDR lighting out, in one call.

:func:`estimate_lighting` takes a photograph (tensor, NumPy array or file), finds the faces with a
detector from :mod:`kornia_ilum.detection`, crops each face as the paper does (a square centred on the
face box, side 1.25 x max(w, h), zero padding outside the image, resized to the estimator's input size
with antialiasing) and runs a lighting estimator from :mod:`kornia_ilum.estimators` once on the batch of
all crops. Its three steps are public, for a caller who wants one of them alone: :func:`find_faces` (detect and
keep the faces), :func:`~kornia_ilum.detection.crop_faces` (cut the crops) and :func:`estimate_from_crops` (run
the estimator and attach the boxes). The result is a :class:`~kornia_ilum.estimators.LightingEstimate` that can be saved as
``.exr``/``.hdr``, converted to lat-long, rendered on the reference spheres or previewed as a PNG.

This is a pipeline, not a differentiable op, so it has no :class:`torch.nn.Module` twin: the estimators
themselves are the modules.

Reference: C. LeGendre, W.-C. Ma, R. Pandey, S. Fanello, C. Rhemann, J. Dourgarian, J. Busch,
P. Debevec, "Learning Illumination from Diverse Portraits", SIGGRAPH Asia 2020 Technical Communications.
"""

from __future__ import annotations

import dataclasses
import functools
import os
import time
from collections.abc import Callable
from typing import Any, Literal

import numpy as np
import torch

from kornia_ilum.core.check import check_choice, check_positive_int, check_tensor, value_range
from kornia_ilum.core.errors import NoFaceError, ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.detection import (
    DEFAULT_DETECTOR,
    FaceDetector,
    create_detector,
    crop_faces,
    square_crop_boxes,
)
from kornia_ilum.estimators import (
    AUTO_ORDER,
    DEFAULT_ESTIMATOR,
    LightingEstimate,
    RUNTIMES,
    LightingEstimator,
    SceneStrength,
    TestTimeAugmented,
    create_estimator,
    fuse_faces,
    fuse_strength,
    scene_input,
    with_runtime,
)
from kornia_ilum.io import read_ldr

__all__ = ["FoundFaces", "cached_detector", "cached_estimator", "estimate_from_crops", "estimate_lighting",
           "find_faces", "full_image_box", "no_face_message", "pick_faces"]

_FACES = ("largest", "all", "fused")
_FALLBACKS = (None, "full_image")
_ACCEPTED = (
    "a (3, H, W) or (B, 3, H, W) float torch.Tensor in [0, 1], a NumPy array (H, W), (H, W, 1), (H, W, 3) "
    "or (H, W, 4) of uint8, uint16 or float in [0, 1], or a path (str or os.PathLike)"
)


@functools.lru_cache(maxsize=8)
def cached_estimator(name: str, device: torch.device, runtime: str = "eager",
                     order: tuple[str, ...] = AUTO_ORDER) -> LightingEstimator:
    """The registered estimator ``name`` that :func:`estimate_lighting` uses: built with ``pretrained=True``
    once per ``(name, device, runtime, order)`` in this process (the 8 most recent are kept), in eval mode,
    computed by ``runtime`` (:func:`~kornia_ilum.estimators.with_runtime`).

    Args:
        name: a registered estimator name (:func:`~kornia_ilum.estimators.list_estimators`).
        device: where the estimator runs; a :class:`torch.device` (part of the cache key, so ``"cpu"`` and
            ``torch.device("cpu")`` are cached apart).
        runtime: one of :data:`~kornia_ilum.estimators.RUNTIMES`.
        order: the runtimes ``"auto"`` tries, in order (:data:`~kornia_ilum.estimators.AUTO_ORDER`).

    Returns:
        the shared estimator: the same object for the same arguments while it is cached, so do not modify it.

    Raises:
        ValueError: ``name`` is not registered.
        ValueCheckError: an unknown runtime, or one that cannot run on ``device``.
        MissingWeightsError: the estimator ships no trained weights yet.

    Examples:
        >>> net = cached_estimator("uniform", torch.device("cpu"))
        >>> net.info.name, net is cached_estimator("uniform", torch.device("cpu")), net.training
        ('uniform', True, False)
    """
    return with_runtime(create_estimator(name, pretrained=True).to(device).eval(), runtime, order=order)


@functools.lru_cache(maxsize=8)
def cached_detector(name: str, device: torch.device, max_side: int | None | Literal["auto"] = "auto"
                    ) -> FaceDetector:
    """The registered detector ``name`` that :func:`estimate_lighting` uses: built once per
    ``(name, device, max_side)`` in this process (the 8 most recent are kept), in eval mode; ``max_side``
    detects on a downscaled copy (:class:`~kornia_ilum.detection.FaceDetector`).

    Args:
        name: a registered detector name (:func:`~kornia_ilum.detection.list_detectors`).
        device: where the detector runs (part of the cache key).
        max_side: the longest side, in pixels, of the copy it detects on; ``None`` detects at full size;
            ``"auto"``: the detector's default (:func:`~kornia_ilum.detection.create_detector`).

    Returns:
        the shared detector: the same object for the same arguments while it is cached, so do not modify it.

    Raises:
        ValueError: ``name`` is not registered.

    Examples:
        >>> detector = cached_detector("none", torch.device("cpu"))
        >>> detector, detector is cached_detector("none", torch.device("cpu"))
        (NoFaceDetector(), True)
    """
    return create_detector(name, max_side=max_side).to(device).eval()


def _numpy_to_tensor(array: np.ndarray, bgr: bool) -> torch.Tensor:
    """``(H, W[, C])`` uint8 / uint16 / float array -> ``(3, H, W)`` float32 in [0, 1] (range checked
    later)."""
    if array.ndim == 2:
        array = array[..., None]
    if array.ndim != 3 or array.shape[2] not in (1, 3, 4):
        raise ShapeError(
            "image (NumPy array) must have shape (H, W), (H, W, 1), (H, W, 3) or (H, W, 4), "
            f"got {array.shape}"
        )
    if array.dtype == np.uint8 or array.dtype == np.uint16:
        pixels = array.astype(np.float32) / np.float32(np.iinfo(array.dtype).max)
    elif array.dtype in (np.float16, np.float32, np.float64):
        pixels = array.astype(np.float32)
    else:
        raise TypeCheckError(
            f"image (NumPy array) must be uint8, uint16 or float in [0, 1], got dtype {array.dtype}"
        )
    if pixels.shape[2] == 1:
        pixels = np.repeat(pixels, 3, axis=2)
    pixels = pixels[..., :3]  # RGBA / BGRA: alpha dropped, not composited (as kornia_ilum.io.read_ldr does)
    if bgr:
        pixels = pixels[..., ::-1]
    return torch.from_numpy(np.ascontiguousarray(pixels.transpose(2, 0, 1)))


def _as_batch(image: Any, bgr: bool) -> tuple[torch.Tensor, str]:
    """Any accepted input -> ``(B, 3, H, W)`` float tensor in [0, 1], and a name for messages.

    This is the one scan of the image's values in :func:`estimate_lighting` (NaN/Inf and the ``[0, 1]``
    range, one :func:`~kornia_ilum.core.check.value_range`); the detector, the crop and the estimator are then
    called with ``check_values=False``, as their input is made from this checked image.
    """
    values = None
    if isinstance(image, (str, os.PathLike)):
        if bgr:
            raise ValueCheckError("bgr=True applies to NumPy arrays only; files are read as RGB")
        batch, what = read_ldr(image)[None], f"image {os.fspath(image)!r}"
    elif isinstance(image, np.ndarray):
        batch, what = _numpy_to_tensor(image, bgr)[None], "image"
    elif isinstance(image, torch.Tensor):
        if bgr:
            raise ValueCheckError(
                "bgr=True applies to NumPy arrays only; tensors are RGB (flip them yourself)"
            )
        check_tensor(image, "image", ["*", "3", "H", "W"], finite=False)
        values = value_range(image, "image")  # NaN / Inf -> NonFiniteError before the shape's upper bound
        if image.dim() > 4:
            raise ShapeError(f"image must have shape (3, H, W) or (B, 3, H, W), got {tuple(image.shape)}")
        batch, what = (image[None] if image.dim() == 3 else image), "image"
    else:
        raise TypeCheckError(f"image must be {_ACCEPTED}; got {type(image).__name__}")
    check_tensor(batch, "image", ["B", "3", "H", "W"], finite=False)  # empty -> typed error
    if values is None:
        values = value_range(batch, "image")  # NaN / Inf -> NonFiniteError
    if values is not None:
        lo, hi = values
        if lo < 0.0 or hi > 1.0:
            raise ValueCheckError(
                f"image must be sRGB-encoded in [0, 1], got values in [{lo:g}, {hi:g}] "
                "(divide 8-bit data by 255, or pass the uint8 NumPy array as it is)"
            )
    return batch, what


def full_image_box(height: int, width: int) -> torch.Tensor:
    r"""The largest centred square of an image, as an ``xyxy`` box: the crop of the paper's no-face variant.

    Args:
        height: image height in pixels.
        width: image width in pixels.

    Returns:
        ``(1, 4)`` float32 box ``(x0, y0, x1, y1)`` in pixels (pixel edges: the full image is
        ``(0, 0, W, H)``), of side ``min(H, W)``, centred.

    Shape:
        - Output: :math:`(1, 4)`

    Convention:
        Continuous pixel coordinates of the image (``(0, 0)`` its top-left corner), as the boxes of
        :mod:`kornia_ilum.detection` and of :func:`~kornia_ilum.detection.crop_faces`.

    Examples:
        >>> full_image_box(480, 640)
        tensor([[ 80.,   0., 560., 480.]])
    """
    side = min(height, width)
    x0, y0 = (width - side) / 2.0, (height - side) / 2.0
    return torch.tensor([[x0, y0, x0 + side, y0 + side]], dtype=torch.float32)


def _module_device(module: torch.nn.Module) -> torch.device | None:
    for t in module.parameters():
        return t.device
    for t in module.buffers():
        return t.device
    return None


def _module_dtype(module: torch.nn.Module) -> torch.dtype:
    for t in list(module.parameters()) + list(module.buffers()):
        if t.is_floating_point():
            return t.dtype
    return torch.float32


def _resolve_estimator(estimator: str | LightingEstimator | None, device: torch.device,
                       runtime: str = "eager") -> LightingEstimator:
    if estimator is None:
        estimator = DEFAULT_ESTIMATOR
    if isinstance(estimator, str):
        return cached_estimator(estimator, device, runtime)
    if isinstance(estimator, LightingEstimator):
        if runtime != "eager":
            raise ValueCheckError(f"runtime={runtime!r} applies to an estimator given by name; wrap an instance "
                                  "yourself: kornia_ilum.estimators.with_runtime(estimator, runtime)")
        on = _module_device(estimator)
        if on is not None and (
            on.type != device.type or None not in (on.index, device.index) and on.index != device.index
        ):
            raise ValueCheckError(
                f"estimator is on {on} but the image is processed on {device}; move the estimator "
                f"(estimator.to({str(device)!r})) or pass device={str(on)!r}"
            )
        return estimator
    raise TypeCheckError(
        f"estimator must be None (the default, {DEFAULT_ESTIMATOR!r}), a registered name (str) or a "
        f"LightingEstimator instance, got {type(estimator).__name__}"
    )


def _resolve_detector(detector: str | FaceDetector, device: torch.device) -> FaceDetector:
    if isinstance(detector, str):
        return cached_detector(detector, device)
    if isinstance(detector, FaceDetector):
        return detector
    raise TypeCheckError(
        f"detector must be a registered name (str) or a FaceDetector instance, got {type(detector).__name__}"
    )


def pick_faces(detections: torch.Tensor, faces: str) -> torch.Tensor:
    """The faces an estimate keeps: the largest, or all of them largest first (so that face 0 is the same face
    either way); :func:`estimate_lighting` and :class:`~kornia_ilum.video.LightingTracker` pick with it.

    Args:
        detections: ``(N, 5)`` boxes ``x0, y0, x1, y1, score`` of one image.
        faces: ``"largest"``, or anything else for all of them.

    Returns:
        ``(K, 5)`` float32 detections: ``K = min(N, 1)`` for ``"largest"``, ``N`` otherwise.

    Examples:
        >>> found = torch.tensor([[0.0, 0.0, 10.0, 10.0, 0.9], [0.0, 0.0, 20.0, 20.0, 0.8]])
        >>> pick_faces(found, "largest")[:, 2].tolist(), pick_faces(found, "all")[:, 2].tolist()
        ([20.0], [20.0, 10.0])
    """
    found = detections.to(torch.float32)
    boxes = found[:, :4]
    area = (boxes[:, 2] - boxes[:, 0]) * (boxes[:, 3] - boxes[:, 1])
    order = torch.argsort(area, descending=True, stable=True)
    return found[order[:1]] if faces == "largest" else found[order]


@dataclasses.dataclass(frozen=True)
class FoundFaces:
    r"""The faces of a batch of photographs that an estimate keeps (:func:`find_faces`), in image order, then face
    order.

    Attributes:
        boxes: ``(N, 4)`` the face boxes ``(x0, y0, x1, y1)`` in the images' pixels (for the full-image fallback,
            the square used).
        crop_boxes: ``(N, 4)`` the squares the crops are cut from (:func:`~kornia_ilum.detection.square_crop_boxes`).
        image_index: ``(N,)`` int64, the image each face belongs to.
        scores: ``(N,)`` the detector's score of each face (1 for the fallback).
    """

    boxes: torch.Tensor
    crop_boxes: torch.Tensor
    image_index: torch.Tensor
    scores: torch.Tensor


def no_face_message(where: str, detector: str) -> str:
    """The message of the :class:`~kornia_ilum.core.errors.NoFaceError` that :func:`find_faces` raises: where no
    face was found, by which detector, and what to try (the Python arguments; the CLI names its options instead).

    Examples:
        >>> no_face_message("image", "opencv")
        "no face found in image by detector 'opencv'; try detector='yunet' (a stronger detector), or \
detector='none' if the image already is a face crop, or fallback='full_image' to estimate from the whole image"
    """
    hints = ["detector='yunet' (a stronger detector)"] if detector != "yunet" else []
    hints += ["detector='none' if the image already is a face crop",
              "fallback='full_image' to estimate from the whole image"]
    return f"no face found in {where} by detector {detector!r}; try " + ", or ".join(hints)


def find_faces(images: torch.Tensor, detector: str | FaceDetector = DEFAULT_DETECTOR, *,
               faces: Literal["largest", "all", "fused"] = "largest", fallback: Literal["full_image"] | None = None,
               name: str = "image", check_values: bool = True) -> FoundFaces:
    r"""The first step of :func:`estimate_lighting`: detect the faces of each image and keep those an estimate
    uses (the largest, or all of them largest first), with the square each crop is cut from.

    Args:
        images: ``(B, 3, H, W)`` sRGB in ``[0, 1]``.
        detector: a registered detector name (created once per name and device) or a
            :class:`~kornia_ilum.detection.FaceDetector`.
        faces: ``"largest"``, or ``"all"`` / ``"fused"`` for every face.
        fallback: ``"full_image"`` uses the largest centred square of an image without a face
            (:func:`full_image_box`); ``None`` raises.
        name: what the images are, for the error message (a file name).
        check_values: scan the images' values (``False`` where the caller has).

    Returns:
        the :class:`FoundFaces`.

    Raises:
        NoFaceError: an image has no face and ``fallback`` is ``None`` (:func:`no_face_message`).

    Examples:
        >>> import skimage.data
        >>> image = torch.from_numpy(skimage.data.astronaut()).permute(2, 0, 1)[None] / 255
        >>> found = find_faces(image)
        >>> found.boxes.shape, found.image_index.tolist()
        (torch.Size([1, 4]), [0])
    """
    check_choice(faces, "faces", _FACES)
    if fallback not in _FALLBACKS:
        raise ValueCheckError(f"fallback must be None or 'full_image', got {fallback!r}")
    dev = images.device
    det = _resolve_detector(detector, dev)
    height, width = images.shape[-2:]
    crop_boxes, boxes, index, scores = [], [], [], []
    for i, found in enumerate(det.detect(images, check_values=check_values)):
        if found.shape[0] > 0:
            picked = pick_faces(found, "all" if faces == "fused" else faces).to(dev)
            kept = picked[:, :4]
            scores.append(picked[:, 4])
            crop_boxes.append(square_crop_boxes(kept, scale=det.crop_scale))
        elif fallback == "full_image":
            kept = full_image_box(height, width).to(dev)
            scores.append(torch.ones(1, device=dev))
            crop_boxes.append(kept)
        else:
            where = name if images.shape[0] == 1 else f"{name} {i} of the batch of {images.shape[0]}"
            label = detector if isinstance(detector, str) else (det.name or type(detector).__name__)
            raise NoFaceError(no_face_message(where, label))
        boxes.append(kept)
        index.append(torch.full((kept.shape[0],), i, dtype=torch.int64, device=dev))
    return FoundFaces(torch.cat(boxes), torch.cat(crop_boxes), torch.cat(index), torch.cat(scores))


def estimate_from_crops(crops: torch.Tensor, found: FoundFaces, estimator: LightingEstimator, *,
                        faces: Literal["largest", "all", "fused"] = "largest",
                        scene: tuple[SceneStrength, torch.Tensor] | None = None) -> LightingEstimate:
    r"""The last step of :func:`estimate_lighting`: run ``estimator`` on the crops of the ``found`` faces (in eval
    mode, under :func:`torch.inference_mode`, restored afterwards) and attach their boxes; with ``"fused"``, one
    lighting per image (:func:`~kornia_ilum.estimators.fuse_faces`, weighed by score times the box's side).

    Args:
        crops: ``(N, 3, S, S)`` the faces' crops (:func:`~kornia_ilum.detection.crop_faces` of
            ``found.crop_boxes``), in ``[0, 1]``.
        found: the faces (:func:`find_faces`).
        estimator: a :class:`~kornia_ilum.estimators.LightingEstimator`.
        faces: ``"fused"`` fuses each image's faces; otherwise one entry per face.
        scene: ``(scene branch, photos)``: one strength per photo, its faces' own and the scene branch's fused
            by their spreads (:func:`~kornia_ilum.estimators.fuse_strength`; with ``"fused"``, the faces are
            fused first and the scene then); ``None``: each face's own.

    Returns:
        the :class:`~kornia_ilum.estimators.LightingEstimate` with ``boxes`` and ``image_index``.
    """
    was_training = estimator.training
    estimator.eval()
    try:
        with torch.inference_mode():
            # crops of a checked image are in [0, 1] (up to resampling round-off) and finite
            result = estimator(crops.to(_module_dtype(estimator)), check_values=False)
            if scene is not None:
                branch, photos = scene
                log_energy, spread = branch(scene_input(photos, found.boxes, found.image_index))
    finally:
        estimator.train(was_training)
    result = dataclasses.replace(result, boxes=found.boxes, image_index=found.image_index)
    index = found.image_index
    if faces == "fused":
        kept = result.boxes
        side = ((kept[:, 2] - kept[:, 0]) * (kept[:, 3] - kept[:, 1])).clamp(min=0).sqrt()
        result = fuse_faces(result, found.scores.float() * side, index)
        if scene is not None:  # the photo's scene evidence: the mean over its faces' views (one scene)
            count = torch.zeros(len(result), device=index.device).index_add_(0, index, torch.ones_like(spread))
            log_energy = torch.zeros_like(log_energy[: len(result)]).index_add_(0, index, log_energy) / count[:, None]
            spread, index = torch.zeros_like(count).index_add_(0, index, spread) / count, None
    if scene is not None:
        result = dataclasses.replace(fuse_strength(result, log_energy, spread, index),
                                     boxes=result.boxes, image_index=result.image_index)
    return result


def estimate_lighting(
    image: torch.Tensor | np.ndarray | str | os.PathLike[str],
    estimator: str | LightingEstimator | None = None,
    *,
    detector: str | FaceDetector = DEFAULT_DETECTOR,
    faces: Literal["largest", "all", "fused"] = "largest",
    fallback: Literal["full_image"] | None = None,
    bgr: bool = False,
    device: str | torch.device | None = None,
    tta: int | None = None,
    runtime: str = "eager",
    on_stage: Callable[[str, float], Any] | None = None,
    scene: SceneStrength | None = None,
) -> LightingEstimate:
    r"""Estimate HDR lighting from portrait photograph(s): detect the faces, crop them, run an estimator.

    Args:
        image: the photograph(s), one of:

            - a ``(3, H, W)`` or ``(B, 3, H, W)`` float tensor, sRGB-encoded in ``[0, 1]``;
            - a NumPy array ``(H, W, 3)`` as loaded by most libraries: ``uint8`` (divided by 255),
              ``uint16`` (divided by 65535) or float in ``[0, 1]``; ``(H, W)`` or ``(H, W, 1)`` grey is
              replicated to RGB; ``(H, W, 4)`` RGBA drops its alpha (not composited);
            - a path (``str`` or :class:`os.PathLike`) to an 8/16-bit image that
              :func:`kornia_ilum.io.read_ldr` reads (PNG, JPEG, TIFF, ...; EXIF orientation applied).
        estimator: ``None`` for the default (:data:`kornia_ilum.estimators.DEFAULT_ESTIMATOR`), a
            registered name (see :func:`kornia_ilum.estimators.list_estimators`), created with
            ``pretrained=True`` once per (name, device) in the process and then reused, or a
            :class:`~kornia_ilum.estimators.LightingEstimator` instance (used as given, on its device;
            it is switched to eval mode for the call and restored afterwards).
        detector: a registered detector name (``"yunet"``, the default, with its packaged weights, detecting on
            a copy of at most 240 pixels; ``"opencv"``, the Haar cascade; ``"none"``; see
            :func:`kornia_ilum.detection.list_detectors`; created once per name) or a
            :class:`~kornia_ilum.detection.FaceDetector` instance.
        faces: ``"largest"`` keeps the largest face box of each image; ``"all"`` keeps every face, largest
            first (so face 0 is the face that ``"largest"`` keeps); ``"fused"`` estimates from every face and returns
            one lighting per image, their weighted geometric mean (:func:`~kornia_ilum.estimators.fuse_faces`;
            weights: the detector's score times the box's side), for photos whose light is distant.
        fallback: ``None`` raises :class:`~kornia_ilum.core.errors.NoFaceError` when an image has no
            face; ``"full_image"`` uses the largest centred square of that image as the crop instead
            (the paper's no-face variant, see :func:`full_image_box`).
        bgr: the NumPy array's channels are in B, G, R order, as :func:`cv2.imread` returns them.
            Applies to NumPy arrays only.
        device: where detection cropping and estimation run. Default: the tensor's device, the CPU for
            arrays and paths.
        tta: test-time augmentation, off by default (``None``). ``N`` averages each face's estimate over
            ``N`` windows of its crop (the crop itself, then sub-crops zoomed in and shifted a little) and
            their mirror images: the estimator wrapped in
            :class:`~kornia_ilum.estimators.TestTimeAugmented` (``jitters=N``, its default zoom and shift),
            ``2N`` passes of the estimator per face, in one batch (``benchmarks/bench_tta.py`` measures
            the cost). The estimate of a mirrored crop is then exactly the mirrored estimate.
        runtime: what computes a named estimator (:data:`~kornia_ilum.estimators.RUNTIMES`, see
            :func:`~kornia_ilum.estimators.with_runtime`): ``"eager"`` (PyTorch float32, the default),
            ``"bf16"``, ``"onnx"``, ``"onnx-int8"`` or ``"auto"`` (the fastest that runs here and passes its
            parity check; ``kornia-ilum bench`` measures them).
        on_stage: a timing hook, called as ``on_stage(stage, ms)`` after each stage of this call: ``"check"``
            (the input's conversion and value scan), ``"detect"``, ``"crop"`` and ``"estimate"``
            (``on_stage=timings.__setitem__`` fills a dict).
        scene: a scene branch (:class:`~kornia_ilum.estimators.SceneStrength`, trained by ``kornia-ilum train
            --estimator scene``): one strength per photo, what its faces and the whole photo say of it fused
            by their spreads (:func:`~kornia_ilum.estimators.fuse_strength`; the estimator must give a spread,
            as ``ours`` does): with ``faces="all"`` every face keeps its own shape and shares the photo's
            strength, and ``scene_share`` says how much of it the photo set; ``None`` (the default): each face's
            own.

    Returns:
        A :class:`~kornia_ilum.estimators.LightingEstimate` with one entry per face kept (``B'``
        entries), in image order, then face order. Besides the estimator's outputs it holds
        ``boxes`` ``(B', 4)``: the face boxes ``(x0, y0, x1, y1)`` in the input image's pixels (for the
        full-image fallback, the square that was used), and ``image_index`` ``(B',)`` int64: the input
        image each entry belongs to.

    Raises:
        TypeCheckError: ``image`` is of no accepted type or dtype (the message lists the accepted
            ones), or ``estimator`` / ``detector`` / ``tta`` is of a wrong type.
        ShapeError: ``image`` has a wrong shape; :class:`~kornia_ilum.core.errors.EmptyTensorError`
            if it is empty.
        NonFiniteError: ``image`` holds NaN or Inf.
        ValueCheckError: a float ``image`` has values outside ``[0, 1]``; ``faces``, ``fallback``,
            ``bgr`` or ``tta`` has an invalid value (``tta`` is an int that is not positive); an estimator
            instance is on another device; ``runtime`` is unknown, cannot run here, or is given with an
            estimator instance.
        ValueError: ``estimator`` or ``detector`` is an unknown name (the message lists the valid ones).
        HDRIOError: the image file is missing or unreadable (the message names the path); its subclass
            :class:`~kornia_ilum.core.errors.TruncatedImageError` when the file ends before its image data do.
        NoFaceError: no face in an image and ``fallback=None``; the message names the image and the
            detector, and suggests ``detector="yunet"`` or ``fallback="full_image"``.
        MissingWeightsError: the named estimator is registered but ships no trained weights yet.

    Shape:
        - Input: :math:`(3, H, W)`, :math:`(B, 3, H, W)`, or an array :math:`(H, W[, C])`.
        - Output: ``mirror_ball`` :math:`(B', 3, 32, 32)`, ``boxes`` :math:`(B', 4)`,
          ``image_index`` :math:`(B',)`, with :math:`B'` the number of faces kept.

    Convention:
        Input sRGB-encoded in ``[0, 1]`` (docs/conventions.rst, "Images"). The lighting is linear HDR in
        the units of the input photograph, as a 32 x 32 equal-area mirror ball in the camera frame (+X
        right, +Y up, +Z toward the camera; docs/conventions.rst, "Mirror ball" and "Units of lighting").

    Note:
        The crops are cast to the estimator's floating dtype (float32 for estimators without
        parameters) and the estimator runs under :func:`torch.inference_mode`, so the result carries no
        autograd graph: call the estimator module on :func:`~kornia_ilum.detection.crop_faces` output
        directly to differentiate through it.

        The image's values (NaN/Inf and the ``[0, 1]`` range) are checked once per call, in one pass; the
        detector, the crop and the estimator, which then see only data made from that image, are called
        with ``check_values=False``.

    Examples:
        >>> import skimage.data
        >>> light = estimate_lighting(skimage.data.astronaut())    # (512, 512, 3) uint8 RGB array
        >>> light.mirror_ball.shape, light.image_index.tolist()
        (torch.Size([1, 3, 32, 32]), [0])
        >>> (light.mirror_ball >= 0).all().item()
        True
    """
    check_choice(faces, "faces", _FACES)
    if fallback not in _FALLBACKS:
        raise ValueCheckError(f"fallback must be None or 'full_image', got {fallback!r}")
    if not isinstance(bgr, bool):
        raise TypeCheckError(f"bgr must be a bool, got {type(bgr).__name__}")
    if tta is not None:
        check_positive_int(tta, "tta")
    if runtime not in RUNTIMES:
        raise ValueCheckError(f"runtime must be one of {', '.join(RUNTIMES)}, got {runtime!r}")
    if scene is not None and not isinstance(scene, SceneStrength):
        raise TypeCheckError(f"scene must be a SceneStrength or None, got {type(scene).__name__}")
    clock = [time.perf_counter()]

    def lap(stage: str) -> None:
        clock.append(time.perf_counter())
        if on_stage is not None:
            on_stage(stage, 1e3 * (clock[-1] - clock[-2]))

    batch, what = _as_batch(image, bgr)
    dev = torch.device(device) if device is not None else batch.device
    batch = batch.to(dev)
    est = _resolve_estimator(estimator, dev, runtime)
    clock[-1] = time.perf_counter()  # a first call builds the models: not a stage of the estimate
    lap("check")
    if tta is not None:
        est = TestTimeAugmented(est, jitters=tta)  # no state of its own: cheap to build per call
    # the image was checked once, in _as_batch: the steps skip the value scan
    found = find_faces(batch, detector, faces=faces, fallback=fallback, name=what, check_values=False)
    lap("detect")
    crops = crop_faces(batch, found.crop_boxes, size=est.info.input_size, index=found.image_index,
                       check_values=False)
    lap("crop")
    result = estimate_from_crops(crops, found, est, faces=faces, scene=None if scene is None else (scene, batch))
    lap("estimate")
    return result
