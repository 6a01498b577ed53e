r"""Lighting for video: one estimate per frame, with the work that a repeated frame does not need skipped.

Most frames of a video repeat the last one, and a per-frame estimator then flickers: its estimates jump
by more than the light does. :class:`LightingTracker` takes frames one at a time and:

- **tracks the face box**: it detects the face every ``detect_every`` frames (and whenever it has no box, or
  after a cut), and keeps the last box in between;
- **skips the estimate when the crop barely changed**: the crop is compared with the last estimated one at
  32 x 32 (mean absolute difference of the sRGB values); below ``reuse_below`` the last raw estimate is
  reused;
- **smooths in log space** with a time constant of ``time_constant`` frames: ``s_t = a s_{t-1} + (1 - a)
  log L_t`` with ``a = exp(-1 / time_constant)`` (0: no smoothing), which treats a light twice too bright and
  one twice too dark alike. Where the estimator gives the spread of its log energy ``b_t``
  (:attr:`~kornia_ilum.estimators.LightingEstimate.log_energy_spread`), a frame counts as ``(B_t / b_t)^2``
  frames, ``B_t`` the smoothed spread so far: its weight is ``1 - a^((B_t / b_t)^2)`` instead of ``1 - a``, so a
  frame that cannot settle the light's strength (the face turned away, in shadow) moves the estimate less,
  and a clear one more; the smoothed spread (a geometric mean with the same ``a``) is the output's
  ``log_energy_spread``. With a scene branch (``scene=``, :class:`~kornia_ilum.estimators.SceneStrength`), each
  estimated frame's strength is first fused with the whole frame's
  (:func:`~kornia_ilum.estimators.fuse_strength`), and that is what is smoothed;
- **resets at a cut**: where the crop changed by more than ``cut_above``, the smoothing restarts from the
  new estimate (and the next frame is detected again), so a cut is followed at once. A detection whose face
  box overlaps the tracked one by less than :data:`SWITCH_IOU` (the tracked face left the frame, and the
  tracker took another) is a cut too: the new face's lighting starts afresh, not as a jump that the smoothing
  carries over several frames.

:func:`read_frames` reads a video file (OpenCV's ``VideoCapture``) or an image sequence (a folder or a glob,
sorted by name); :func:`estimate_video` chains the two. ``kornia-ilum video IN -o OUT`` writes one ``.exr``
per frame. ``benchmarks/bench_video.py`` measures the frame rate, the flicker against the truth's own change,
and the lag after a cut on a light-stage clip.
"""

from __future__ import annotations

import glob
import itertools
import math
import os
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from kornia.metrics import mean_iou_bbox

from kornia_ilum.api import (
    FoundFaces,
    cached_detector,
    cached_estimator,
    estimate_from_crops,
    full_image_box,
    pick_faces,
)
from kornia_ilum.core.check import check_positive_int
from kornia_ilum.core.errors import HDRIOError, NoFaceError, ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.detection import DEFAULT_DETECTOR, FaceDetector, crop_faces, square_crop_boxes
from kornia_ilum.estimators import DEFAULT_ESTIMATOR, LightingEstimate, LightingEstimator, SceneStrength

__all__ = ["IMAGE_SUFFIXES", "SWITCH_IOU", "TRACKER_AUTO_ORDER", "LightingTracker", "VideoFrame", "estimate_video",
           "frame_tensor", "read_frames"]

#: What the tracker's ``runtime="auto"`` tries, in order: the float runtimes. The int8 runtime is left out: its
#: estimates move more with the crop, so a box held between detections keeps it more than 10 % from a fresh box's
#: for up to 19 frames after a cut, against none for the float runtimes (the tuning clips of docs/skipping.rst).
TRACKER_AUTO_ORDER = ("onnx", "bf16")

#: The image files of an image sequence.
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".webp")


def read_frames(source: str | os.PathLike[str]) -> Iterator[np.ndarray]:
    r"""The frames of a video file or an image sequence, as ``(H, W, 3)`` uint8 RGB arrays.

    Args:
        source: a video file (anything OpenCV's ``VideoCapture`` opens), a folder of images, or a glob
            pattern of images (``frames/*.png``); images are read in name order.

    Returns:
        an iterator over the frames, read lazily one at a time (a video file stays open until it is exhausted
        or closed).

    Raises:
        HDRIOError: nothing to read: no such file or folder, a folder that cannot be listed, a file that does
            not open as a video or holds no frame, a folder or pattern with no image, or an image that does not
            decode (raised on the first ``next`` that meets it, as the frames are read lazily).

    Shape:
        - Output: each frame :math:`(H, W, 3)` uint8, channels last, as NumPy images are

    Convention:
        sRGB-encoded RGB (docs/conventions.rst, "Images"), in ``0 .. 255``; :class:`LightingTracker` turns each
        into a ``(3, H, W)`` float in ``[0, 1]``.

    Examples:
        >>> import tempfile, cv2
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     for i in range(3):
        ...         _ = cv2.imwrite(f"{tmp}/{i:03d}.png", np.full((8, 8, 3), 40 * i, np.uint8))
        ...     [int(f[0, 0, 0]) for f in read_frames(tmp)]
        [0, 40, 80]
    """
    import cv2  # OpenCV only for reading video

    text = os.fspath(source)
    path = Path(text)
    if path.is_dir() or any(c in text for c in "*?["):
        try:
            files = sorted(p for p in (path.iterdir() if path.is_dir() else map(Path, glob.glob(text)))
                           if p.suffix.lower() in IMAGE_SUFFIXES)
        except OSError as e:
            raise HDRIOError(f"cannot list the folder {text}: {e.strerror or e}") from None
        if not files:
            raise HDRIOError(f"no image ({', '.join(IMAGE_SUFFIXES)}) in {text}")
        for file in files:
            frame = cv2.imread(str(file), cv2.IMREAD_COLOR)
            if frame is None:
                raise HDRIOError(f"cannot read the image {file}: missing, corrupt or not an image")
            yield cv2.cvtColor(frame, cv2.COLOR_BGR2RGB)
        return
    if not path.is_file():
        raise HDRIOError(f"no such video file or folder: {text}")
    capture = cv2.VideoCapture(text)
    try:
        if not capture.isOpened():
            raise HDRIOError(f"cannot open {text} as a video")
        for index in itertools.count():
            ok, frame = capture.read()
            if not ok:
                if index == 0:
                    raise HDRIOError(f"no frame in {text}: an empty or corrupt video")
                return
            yield cv2.cvtColor(frame, cv2.COLOR_BGR2RGB)
    finally:
        capture.release()


@dataclass(frozen=True)
class VideoFrame:
    """One frame's result.

    Attributes:
        index: the frame's number, from 0.
        lighting: the smoothed estimate (one lighting, with its ``boxes``).
        detected: the face was detected on this frame (not carried over).
        estimated: the estimator ran on this frame (not reused).
        cut: the crop changed by more than ``cut_above``: the smoothing restarted here.

    Convention:
        ``lighting`` is a mirror ball in the units of the frame (docs/conventions.rst, "Mirror ball" and
        "Units of lighting").

    Examples:
        >>> from kornia_ilum.geometry import mirror_ball_valid
        >>> valid = mirror_ball_valid(32)
        >>> lighting = LightingEstimate(mirror_ball=torch.ones(1, 3, 32, 32) * valid, valid=valid)
        >>> frame = VideoFrame(0, lighting, detected=True, estimated=True, cut=False)
        >>> frame.index, len(frame.lighting), frame.cut
        (0, 1, False)
    """

    index: int
    lighting: LightingEstimate
    detected: bool
    estimated: bool
    cut: bool


#: A detection whose box overlaps the tracked face's box by less than this IoU is another face: a cut.
SWITCH_IOU = 0.3


class LightingTracker:
    r"""Per-frame lighting with temporal reuse (the module docstring says how).

    Args:
        estimator: a registered name (default :data:`~kornia_ilum.estimators.DEFAULT_ESTIMATOR`) or an
            estimator instance.
        detector: a registered detector name (default :data:`~kornia_ilum.detection.DEFAULT_DETECTOR`) or a
            :class:`~kornia_ilum.detection.FaceDetector`.
        detect_every: detect the face every this many frames (1: every frame); 5 by default, since 10 left a
            box held 19 frames after a cut on a tuning clip (docs/skipping.rst).
        reuse_below: reuse the last raw estimate while the crop differs from the last estimated one by less
            than this (mean absolute sRGB difference at 32 x 32; 0: estimate every frame). Consecutive frames
            of a still face under a turning light differ by 0.001 to 0.004 on the benchmark's clip.
        time_constant: the smoothing's time constant in frames (0: none).
        cut_above: a crop difference above this is a cut: detect again and restart the smoothing (the
            benchmark's cut, the same face under another light, differs by 0.06).
        fallback: ``"full_image"`` to estimate from the frame's centred square while no face is found;
            ``None`` raises :class:`~kornia_ilum.core.errors.NoFaceError` until a face was seen (after that,
            a frame without a face keeps the last box).
        runtime: the runtime of a named estimator (:data:`~kornia_ilum.estimators.RUNTIMES`); ``"auto"`` here
            tries only :data:`TRACKER_AUTO_ORDER`.
        scene: a scene branch: the strength from the whole frame, fused with the face's before the smoothing.

    Raises:
        ValueCheckError: a setting out of range, or an unknown ``fallback``.

    Convention:
        Frames are sRGB (docs/conventions.rst, "Images"); each frame's lighting is a mirror ball in the units of
        the frame (docs/conventions.rst, "Mirror ball" and "Units of lighting"), smoothed over time in log space.

    Examples:
        >>> import skimage.data
        >>> tracker = LightingTracker(estimator="uniform", time_constant=2.0)
        >>> frames = [tracker(skimage.data.astronaut()) for _ in range(3)]
        >>> [(f.detected, f.estimated) for f in frames]  # detected once, estimated once, then reused
        [(True, True), (False, False), (False, False)]
    """

    def __init__(self, estimator: str | LightingEstimator | None = None,
                 detector: str | FaceDetector = DEFAULT_DETECTOR, *, detect_every: int = 5,
                 reuse_below: float = 0.002, time_constant: float = 2.0,
                 cut_above: float = 0.03, fallback: str | None = None, runtime: str = "eager",
                 scene: SceneStrength | None = None) -> None:
        check_positive_int(detect_every, "detect_every")
        for name, value in (("reuse_below", reuse_below), ("time_constant", time_constant),
                            ("cut_above", cut_above)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ValueCheckError(f"{name} must be a finite number >= 0, got {value!r}")
        if fallback not in (None, "full_image"):
            raise ValueCheckError(f"fallback must be None or 'full_image', got {fallback!r}")
        device = torch.device("cpu")
        if isinstance(estimator, LightingEstimator):
            self.estimator = estimator.eval()
        else:
            self.estimator = cached_estimator(estimator or DEFAULT_ESTIMATOR, device, runtime, TRACKER_AUTO_ORDER)
        self.detector = cached_detector(detector, device) if isinstance(detector, str) else detector
        self.detect_every, self.reuse_below, self.cut_above = detect_every, float(reuse_below), float(cut_above)
        self.time_constant, self.fallback, self.scene = float(time_constant), fallback, scene
        self.reset()

    def reset(self) -> None:
        """Forget the past: the next frame is detected and estimated afresh, and the smoothing restarts."""
        self._frame, self._since = 0, 0
        self._face = self._box = self._thumb = self._raw = self._valid = self._smooth = None
        self._raw_spread = self._spread = self._share = None

    def _box_of(self, image: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor] | None:
        """The largest face's box and its crop's (the fallback's square for both; else the tracked ones)."""
        found = self.detector.detect(image[None], check_values=False)[0]
        if found.shape[0] > 0:
            face = pick_faces(found, "largest")[:, :4]
            return face, square_crop_boxes(face, scale=self.detector.crop_scale)
        if self.fallback == "full_image":
            return full_image_box(*image.shape[-2:]), full_image_box(*image.shape[-2:])
        return None if self._box is None else (self._face, self._box)

    def __call__(self, frame: np.ndarray | torch.Tensor) -> VideoFrame:
        """The lighting of the next frame: ``(H, W, 3)`` uint8 RGB, or ``(3, H, W)`` sRGB float in ``[0, 1]``.

        Args:
            frame: the next frame of the video.

        Returns:
            the frame's :class:`VideoFrame`; its ``lighting`` holds one lighting and the crop box it came from.

        Raises:
            ShapeError, TypeCheckError, ValueCheckError: the frame is not one of the two forms above.
            NoFaceError: no face found yet and ``fallback`` is ``None``.
        """
        image = frame_tensor(frame)
        index = self._frame
        self._frame += 1
        detect = self._box is None or self._since >= self.detect_every
        switched = False  # the detection found another face than the tracked one
        if detect:
            boxes = self._box_of(image)
            if boxes is None:
                raise NoFaceError(f"no face found in frame {index} by detector {self.detector.name!r}, and none "
                                  "before it; try fallback='full_image'")
            switched = self._box is not None and float(mean_iou_bbox(boxes[1], self._box)) < SWITCH_IOU
            (self._face, self._box), self._since = boxes, 0
        self._since += 1
        size = self.estimator.info.input_size
        crop = crop_faces(image, self._box, size=size, check_values=False)
        thumb = F.adaptive_avg_pool2d(crop, 32)
        change = math.inf if self._thumb is None else float((thumb - self._thumb).abs().mean())
        cut = self._thumb is not None and (change > self.cut_above or switched)
        if cut and not detect:  # the scene changed: find the face again, in this very frame
            boxes = self._box_of(image)
            if boxes is not None:
                self._face, self._box = boxes
                crop = crop_faces(image, self._box, size=size, check_values=False)
                thumb = F.adaptive_avg_pool2d(crop, 32)
            self._since, detect = 1, True
        estimated = self._raw is None or change >= self.reuse_below or switched
        if estimated:
            found = FoundFaces(self._face, self._box, torch.zeros(1, dtype=torch.int64), torch.ones(1))
            out = estimate_from_crops(crop, found, self.estimator,
                                      scene=None if self.scene is None else (self.scene, image[None]))
            self._raw, self._valid, self._thumb = out.mirror_ball, out.valid, thumb
            self._raw_spread, self._share = out.log_energy_spread, out.scene_share
        light = self._raw.float()
        mean = light.mean().clamp(min=1e-30)
        log = torch.log(torch.maximum(light, 1e-6 * mean))
        b = None if self._raw_spread is None else self._raw_spread.float().clamp(min=1e-6)
        if self._smooth is None or cut or self.time_constant == 0:
            self._smooth, self._spread = log, b
        else:
            a = math.exp(-1.0 / self.time_constant)
            gain = 1.0 - a
            if b is not None and self._spread is not None:  # the frame counts as (B / b)^2 frames
                gain = (1.0 - a ** ((self._spread / b) ** 2)).view(-1, 1, 1, 1)
            self._smooth = self._smooth + gain * (log - self._smooth)
            if b is not None:
                self._spread = b if self._spread is None else torch.exp(a * self._spread.log() + (1 - a) * b.log())
        ball = torch.where(self._valid, torch.exp(self._smooth), 0.0)
        lighting = LightingEstimate(mirror_ball=ball, valid=self._valid, log_mirror_ball=torch.log1p(ball),
                                    boxes=self._box.clone(), image_index=torch.zeros(1, dtype=torch.int64),
                                    log_energy_spread=self._spread, scene_share=self._share)
        return VideoFrame(index, lighting, detect, estimated, cut)


def frame_tensor(frame: np.ndarray | torch.Tensor) -> torch.Tensor:
    """A video frame as the ``(3, H, W)`` float sRGB image in ``[0, 1]`` that the tracker works on.

    Args:
        frame: ``(H, W, 3)`` uint8 RGB, or ``(3, H, W)`` sRGB float in ``[0, 1]``.

    Returns:
        the image, float32 (a float tensor is checked and returned as it is).

    Raises:
        ShapeError: a wrong shape or dtype.
        ValueCheckError: a float frame outside ``[0, 1]`` or not finite.
        TypeCheckError: neither an array nor a tensor.

    Examples:
        >>> frame_tensor(np.full((2, 4, 3), 255, np.uint8)).shape
        torch.Size([3, 2, 4])
    """
    if isinstance(frame, np.ndarray):
        if frame.dtype != np.uint8 or frame.ndim != 3 or frame.shape[-1] != 3:
            raise ShapeError(f"a frame array must be (H, W, 3) uint8 RGB, got {frame.shape} {frame.dtype}")
        return torch.from_numpy(np.ascontiguousarray(frame)).permute(2, 0, 1).float().div_(255.0)
    if isinstance(frame, torch.Tensor):
        if frame.dim() != 3 or frame.shape[0] != 3 or not frame.is_floating_point():
            raise ShapeError(f"a frame tensor must be (3, H, W) float, got {tuple(frame.shape)} {frame.dtype}")
        lo, hi = float(frame.min()), float(frame.max())
        if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 <= lo and hi <= 1.0):
            raise ValueCheckError(f"a frame tensor must be finite sRGB in [0, 1], got [{lo:g}, {hi:g}]")
        return frame.float()
    raise TypeCheckError(f"a frame must be a NumPy array or a torch.Tensor, got {type(frame).__name__}")


def estimate_video(source: str | os.PathLike[str] | Iterable[np.ndarray], **settings) -> Iterator[VideoFrame]:
    r"""The lighting of every frame of ``source`` (a path for :func:`read_frames`, or frames), through one
    :class:`LightingTracker` made with ``settings``.

    Args:
        source: a video file, a folder or glob of images (:func:`read_frames`), or an iterable of frames in a
            form :class:`LightingTracker` takes (``(H, W, 3)`` uint8 RGB arrays or ``(3, H, W)`` float tensors).
        settings: keyword arguments of :class:`LightingTracker`.

    Returns:
        an iterator of one :class:`VideoFrame` per frame, in order, computed lazily as it is consumed.

    Raises:
        HDRIOError: ``source`` is a path with nothing to read (raised on the first ``next``).
        NoFaceError: as :class:`LightingTracker`.

    Convention:
        As :class:`LightingTracker`: sRGB frames in, mirror balls in the units of the frames out
        (docs/conventions.rst, "Images", "Mirror ball" and "Units of lighting").

    Examples:
        >>> import skimage.data
        >>> frames = [skimage.data.astronaut()] * 4
        >>> [f.estimated for f in estimate_video(frames, estimator="uniform", reuse_below=0.0)]
        [True, True, True, True]
    """
    tracker = LightingTracker(**settings)
    frames = read_frames(source) if isinstance(source, (str, os.PathLike)) else source
    for frame in frames:
        yield tracker(frame)
