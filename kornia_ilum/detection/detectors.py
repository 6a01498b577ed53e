r"""Face detectors: one interface, :meth:`FaceDetector.detect`, for OpenCV's Haar cascade, Kornia's YuNet
and ``"none"`` (the input already is a face crop).

Every detector takes sRGB images in ``[0, 1]`` and returns, per image, an ``(N, 5)`` float32 tensor of
face boxes ``(x0, y0, x1, y1, score)`` sorted by score, most confident first. Detection is not
differentiable; it runs under :func:`torch.no_grad`.

Convention:
    Boxes are in continuous pixel coordinates of the input image: ``(0, 0)`` is its top-left corner,
    ``(W, H)`` its bottom-right corner (see :mod:`kornia_ilum.detection.crop`). A box may reach slightly
    beyond the image (YuNet regresses boxes, it does not clip them); :func:`~kornia_ilum.detection.crop_faces`
    pads with zeros there.
"""

from __future__ import annotations

import functools
import math
import os
import xml.etree.ElementTree as ET
from pathlib import Path
from collections.abc import Sequence
from typing import ClassVar

import numpy as np
import torch
from kornia.geometry.bbox import nms
from kornia.models.yunet import YuNet
from kornia.models.yunet.processors import PriorBox, decode
import torch.nn.functional as F
from torch import nn

from kornia_ilum.core.check import check_tensor, value_range
from kornia_ilum.core.errors import (
    MissingWeightsError,
    ShapeError,
    ValueCheckError,
    WeightsChecksumError,
)
from kornia_ilum.core.files import atomic_write, sha256_file
from kornia_ilum.detection.crop import CROP_SCALE

__all__ = [
    "FaceDetector",
    "OpenCVFaceDetector",
    "YuNetFaceDetector",
    "NoFaceDetector",
    "YUNET_WEIGHTS_ENV",
    "YUNET_WEIGHTS",
    "YUNET_SHA256",
    "YUNET_SAFETENSORS_SHA256",
    "convert_yunet_weights",
]

#: Environment variable naming other YuNet weights (a ``.safetensors`` or Kornia's ``yunet_final.pth``), used
#: instead of the packaged file when no ``weights_path`` is given.
YUNET_WEIGHTS_ENV = "KORNIA_ILUM_YUNET_WEIGHTS"
#: The packaged weights: Kornia's ``yunet_final.pth`` converted to safetensors by :func:`convert_yunet_weights`
#: (MIT; origin and licence in ASSETS.md and ``weights/LICENSE-yunet.txt`` beside the file).
YUNET_WEIGHTS = Path(__file__).resolve().parent / "weights" / "yunet.safetensors"
#: SHA-256 of Kornia's ``yunet_final.pth`` (https://huggingface.co/kornia/yunet, 406 kB).
YUNET_SHA256 = "ee0a3035c5cbfc9484a31332223c9fd9c0ddcdb7c46b6a19e558ed393b6f2c67"
#: The smallest side YuNet's network takes; a smaller image (or detection copy) is padded with black to it.
YUNET_MIN_SIDE = 64
#: SHA-256 of the packaged :data:`YUNET_WEIGHTS` (the same tensors as ``yunet_final.pth``).
YUNET_SAFETENSORS_SHA256 = "4d7dd0394279cb4e5190630d1b3dea45a316dded92640e07efebf09bcec8091a"


class FaceDetector(nn.Module):
    r"""Base class of the face detectors.

    Subclasses set the class attributes and implement :meth:`_detect`; :meth:`detect` does the input
    checks, :func:`torch.no_grad`, and returns every result as float32 on the input's device, sorted by
    score. It is an :class:`~torch.nn.Module` so that a detector with a network (YuNet) moves between
    devices and switches to eval mode like any model (``.to("cuda")``, ``.eval()``, ``state_dict``), and
    all detectors can be held, swapped and called (``detector(image)``) the same way.

    Attributes:
        name: the registry name.
        description: one line for ``kornia-ilum list``.
        crop_scale: side of the crop square relative to ``max(w, h)`` of a returned box (passed to
            :func:`~kornia_ilum.detection.square_crop_boxes`): the paper's 1.25 for face detectors, 1 for
            ``"none"``, whose box already is the crop.
        max_side: ``None`` (the default) detects at the image's resolution; ``N`` detects on a copy whose
            longer side is at most ``N`` pixels (area-averaged) and scales the boxes back, so the crop is
            still cut from the full-resolution image. A detector's cost grows with the pixels it scans (Haar's
            on a half-size copy: about a third, ``kornia-ilum bench``), but the smallest face it finds grows by
            the same factor (Haar's 24-pixel window becomes 48 pixels of the photo), so an image in whose copy
            no face is found is searched again at full size (a second pass only where the first found nothing).
            Set it with ``create_detector(name, max_side=N)`` or ``kornia-ilum estimate --detect-side N``.
        default_max_side: the ``max_side`` that :func:`~kornia_ilum.detection.create_detector` gives by default
            (``max_side="auto"``): ``None`` here, 240 for YuNet.

    Examples:
        A detector that takes the central half of every image:

        >>> class Centre(FaceDetector):
        ...     name, description = "centre", "the central half of each image"
        ...     def _detect(self, image):
        ...         h, w = image.shape[-2:]
        ...         return [torch.tensor([[w / 4, h / 4, 3 * w / 4, 3 * h / 4, 1.0]])] * image.shape[0]
        >>> Centre().detect(torch.rand(2, 3, 40, 80))
        [tensor([[20., 10., 60., 30.,  1.]]), tensor([[20., 10., 60., 30.,  1.]])]
    """

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    crop_scale: ClassVar[float] = CROP_SCALE
    default_max_side: ClassVar[int | None] = None
    max_side: int | None = None

    def detect(self, image: torch.Tensor, *, check_values: bool = True) -> list[torch.Tensor]:
        r"""Find the faces in each image.

        Args:
            image: sRGB-encoded RGB images in ``[0, 1]``, ``(B, 3, H, W)`` or one ``(3, H, W)``. Any
                floating dtype; any device (a detector with a network runs on its own device and returns
                the boxes on the image's).
            check_values: scan the values (NaN/Inf, the ``[0, 1]`` range). ``False`` is for a caller that
                has scanned this very image already (:func:`kornia_ilum.estimate_lighting`); the shape and
                dtype are checked either way.

        Returns:
            one ``(N_i, 5)`` float32 tensor per image, on the image's device: ``(x0, y0, x1, y1, score)``
            in input pixels, sorted by score, most confident first; ``N_i = 0`` where no face is found.

        Shape:
            - Input: :math:`(B, 3, H, W)` or :math:`(3, H, W)`
            - Output: a list of :math:`B` tensors :math:`(N_i, 5)`

        Raises:
            ShapeError: ``image`` is not ``(3, H, W)`` or ``(B, 3, H, W)``.
            TypeCheckError: ``image`` is not a floating-point tensor (divide ``uint8`` images by 255).
            EmptyTensorError: ``image`` is empty.
            NonFiniteError: ``image`` holds NaN or Inf.
            ValueCheckError: ``image`` has values outside ``[0, 1]``.

        Convention:
            Input sRGB-encoded in ``[0, 1]`` (docs/conventions.rst, "Images"). Boxes in continuous pixel
            coordinates, ``(0, 0)`` at the image's top-left corner.
        """
        if isinstance(image, torch.Tensor) and image.dim() not in (3, 4):
            raise ShapeError(f"image must have shape (3, H, W) or (B, 3, H, W), got {tuple(image.shape)}")
        check_tensor(image, "image", ["*", "3", "H", "W"], finite=False)
        values = value_range(image, "image") if check_values else None
        if values is not None:
            lo, hi = values
            if lo < 0 or hi > 1:
                raise ValueCheckError(
                    f"image must be sRGB in [0, 1], got values in [{lo:g}, {hi:g}]"
                    + ("; divide 8-bit images by 255" if hi > 1.5 else "")
                )
        full = image if image.dim() == 4 else image[None]
        height, width = full.shape[-2:]
        side = self.max_side
        small = side is not None and max(height, width) > side
        batch = full
        if small:
            size = (max(1, round(height * side / max(height, width))), max(1, round(width * side / max(height, width))))
            batch = F.interpolate(full, size=size, mode="area")
        with torch.no_grad():
            found = [dets.to(torch.float32).reshape(-1, 5) for dets in self._detect(batch)]
            if small:
                scale = torch.tensor([width / size[1], height / size[0]] * 2 + [1.0])
                found = [dets * scale.to(dets.device) if len(dets)  # back to the input's pixels
                         else self._detect(full[i : i + 1])[0]  # no face in the copy: look again at full size
                         for i, dets in enumerate(found)]
        out = []
        for dets in found:
            dets = dets.to(device=image.device, dtype=torch.float32).reshape(-1, 5)
            out.append(dets[dets[:, 4].argsort(descending=True, stable=True)])
        return out

    def forward(self, image: torch.Tensor, *, check_values: bool = True) -> list[torch.Tensor]:
        """Same as :meth:`detect`."""
        return self.detect(image, check_values=check_values)

    def _detect(self, image: torch.Tensor) -> list[torch.Tensor]:
        """Detect in a checked ``(B, 3, H, W)`` batch; return ``B`` tensors ``(N_i, 5)`` in any order."""
        raise NotImplementedError


# ---------------------------------------------------------------------------------------------- OpenCV
def _last_stage_threshold(path: Path) -> float | None:
    """The last stage's ``stageThreshold`` of an OpenCV cascade XML (new format), or ``None``."""
    try:
        stages = ET.parse(path).getroot().findall("./cascade/stages/_")
        return float(stages[-1].findtext("stageThreshold"))
    except (ET.ParseError, IndexError, TypeError, ValueError, OSError):
        return None


class OpenCVFaceDetector(FaceDetector):
    r"""Viola-Jones face detection with a Haar cascade that ships with OpenCV 4.x (CPU, offline).

    The RGB image is quantised to 8 bits (``round(255 x)``), converted to grey
    (:func:`cv2.cvtColor`, ``COLOR_RGB2GRAY``: ``0.299 R + 0.587 G + 0.114 B`` on the sRGB values, as the
    cascades were trained) and scanned by :meth:`cv2.CascadeClassifier.detectMultiScale3`.

    Defaults, measured on scikit-image's astronaut (at 0.5x, 0.75x, 1x, 1.25x, 2x and mirrored) and on
    18 synthetic group images (72 faces: the astronaut's face pasted 4 times at scales 0.6-1.3 on grey,
    noise and ``coffee`` backgrounds), plus 19 face-free scikit-image photographs (``coffee``, ``chelsea``,
    ``coins``, ``rocket``, ``moon``, ...): ``haarcascade_frontalface_alt2`` with ``scale_factor=1.1`` and
    ``min_neighbors=5`` found every face (72/72, and exactly one on every astronaut) with no false
    positive. ``haarcascade_frontalface_default`` fired on ``coins`` (6 boxes) and found the astronaut
    twice at ``scale_factor=1.05``; ``alt`` was as good as ``alt2`` only without equalisation. Histogram
    equalisation (``equalize=True``) lost faces on the group images with ``alt`` and ``alt2`` and added
    false positives with ``default``, so it is off by default.

    Score:
        ``sigmoid(2 (w - t))``, where ``w`` is the face's ``levelWeights`` from ``detectMultiScale3`` (the
        boosted sum of the cascade's last stage, the largest over the grouped windows) and ``t`` that
        stage's ``stageThreshold`` from the cascade file. A boosted sum estimates half the log-odds
        (Friedman, Hastie & Tibshirani, "Additive logistic regression", Ann. Statist. 2000), so this maps
        the margin over the acceptance threshold to ``(0.5, 1)``: monotone, comparable within a cascade,
        not a calibrated probability. The astronaut scores 0.997. Without a readable threshold (an
        old-format cascade file), every score is 1.

    Args:
        cascade: a file name in :data:`cv2.data.haarcascades`, or a path to a cascade XML.
        scale_factor: the image pyramid's step (``> 1``); smaller finds more faces, slower.
        min_neighbors: overlapping detections needed to keep a face; larger rejects more false positives.
        min_face: smallest face side as a fraction of the image's shorter side (never below the cascade's
            window). 0.05 is 24 pixels at 480 lines; smaller faces make blurry 256 x 256 crops anyway.
        equalize: histogram-equalise the grey image first.

    Raises:
        FileNotFoundError: the cascade file does not exist.
        ValueCheckError: OpenCV cannot load the cascade file, or a parameter is out of range.

    Examples:
        >>> import skimage.data
        >>> image = torch.from_numpy(skimage.data.astronaut()).permute(2, 0, 1) / 255
        >>> faces = OpenCVFaceDetector().detect(image)[0]
        >>> faces.shape, faces[0, :4].tolist()
        (torch.Size([1, 5]), [177.0, 66.0, 274.0, 163.0])
    """

    name: ClassVar[str] = "opencv"
    description: ClassVar[str] = (
        "OpenCV 4.x Haar cascade (haarcascade_frontalface_alt2, Viola-Jones); frontal faces, CPU, no download"
    )

    def __init__(
        self,
        cascade: str | os.PathLike[str] = "haarcascade_frontalface_alt2.xml",
        *,
        scale_factor: float = 1.1,
        min_neighbors: int = 5,
        min_face: float = 0.05,
        equalize: bool = False,
    ) -> None:
        super().__init__()
        if not (isinstance(scale_factor, (int, float)) and scale_factor > 1 and math.isfinite(scale_factor)):
            raise ValueCheckError(f"scale_factor must be a finite number > 1, got {scale_factor!r}")
        if isinstance(min_neighbors, bool) or not isinstance(min_neighbors, int) or min_neighbors < 0:
            raise ValueCheckError(f"min_neighbors must be a non-negative int, got {min_neighbors!r}")
        if not (isinstance(min_face, (int, float)) and 0 <= min_face <= 1):
            raise ValueCheckError(f"min_face must be a fraction in [0, 1], got {min_face!r}")
        # lazy: OpenCV is a heavy import (docs/api/detection.rst, "Measured"), paid when a detector is built
        import cv2

        path = Path(cascade)
        if not path.is_file():
            path = Path(cv2.data.haarcascades) / cascade
        if not path.is_file():
            raise FileNotFoundError(
                f"cascade {str(cascade)!r} not found (looked for it as a path and in {path.parent})"
            )
        try:
            classifier = cv2.CascadeClassifier(str(path))
        except (cv2.error, SystemError) as e:  # an XML file that is no cascade
            raise ValueCheckError(f"OpenCV could not load the cascade {str(path)!r}: {e}") from None
        if classifier.empty():
            raise ValueCheckError(f"OpenCV could not load the cascade {str(path)!r}")
        self.cascade_path = path
        self.scale_factor = float(scale_factor)
        self.min_neighbors = min_neighbors
        self.min_face = float(min_face)
        self.equalize = bool(equalize)
        self._classifier = classifier
        self._window = int(max(classifier.getOriginalWindowSize()))
        self._threshold = _last_stage_threshold(path)

    def _detect(self, image: torch.Tensor) -> list[torch.Tensor]:
        import cv2  # lazy: as in __init__ (loaded by then)

        rgb8 = (image.float() * 255).round_().to(torch.uint8).permute(0, 2, 3, 1).cpu().numpy()
        out = []
        for rgb in rgb8:
            grey = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
            if self.equalize:
                grey = cv2.equalizeHist(grey)
            side = max(self._window, round(self.min_face * min(grey.shape)))
            rects, _, weights = self._classifier.detectMultiScale3(
                grey,
                scaleFactor=self.scale_factor,
                minNeighbors=self.min_neighbors,
                minSize=(side, side),
                outputRejectLevels=True,
            )
            rects = np.asarray(rects, dtype=np.float32).reshape(-1, 4)
            weights = np.asarray(weights, dtype=np.float64).reshape(-1)
            if self._threshold is not None and weights.shape[0] == rects.shape[0]:
                score = 1.0 / (1.0 + np.exp(-2.0 * (weights - self._threshold)))
            else:
                score = np.ones(rects.shape[0])
            xyxy = np.concatenate([rects[:, :2], rects[:, :2] + rects[:, 2:]], axis=1)
            out.append(torch.from_numpy(np.concatenate([xyxy, score[:, None].astype(np.float32)], axis=1)))
        return out

    def extra_repr(self) -> str:
        return (
            f"cascade={self.cascade_path.name!r}, scale_factor={self.scale_factor}, "
            f"min_neighbors={self.min_neighbors}, min_face={self.min_face}, equalize={self.equalize}"
        )


# ----------------------------------------------------------------------------------------------- YuNet
def _yunet_weights(weights_path: str | os.PathLike[str] | None) -> tuple[str, Path]:
    """Which YuNet weights to read and why: the argument, else the environment's override, else the package's
    (an override that names a missing file is an error, not a silent fall-back to the package's)."""
    if weights_path is not None:
        return "weights_path", Path(weights_path).expanduser()
    if os.environ.get(YUNET_WEIGHTS_ENV):
        return f"${YUNET_WEIGHTS_ENV}", Path(os.environ[YUNET_WEIGHTS_ENV]).expanduser()
    return "the package", YUNET_WEIGHTS


def _read_yunet_state(path: Path) -> dict[str, torch.Tensor]:
    """The state dict in a ``.safetensors`` file (no pickle), or in a ``.pth`` (``torch.load`` restricted to
    tensors, ``weights_only=True``)."""
    if path.suffix == ".safetensors":
        from safetensors.torch import load_file  # lazy: as the estimators' weights

        return load_file(str(path))
    return torch.load(path, map_location="cpu", weights_only=True)


def convert_yunet_weights(source: str | os.PathLike[str], out: str | os.PathLike[str]) -> str:
    r"""Convert Kornia's ``yunet_final.pth`` to the safetensors file the package ships (:data:`YUNET_WEIGHTS`).

    The tensors are copied unchanged (float32, and batch norm's int64 counters); the file's metadata names the
    source and its SHA-256 (``"source"``). The output is written atomically and is the same, byte for byte, for the same source,
    so ``convert_yunet_weights("yunet_final.pth", "yunet.safetensors")`` remakes the packaged file exactly
    (``tests/detection/test_detectors.py``).

    Args:
        source: Kornia's ``yunet_final.pth`` (its SHA-256 must be :data:`YUNET_SHA256`).
        out: the ``.safetensors`` file to write.

    Returns:
        the SHA-256 of the written file.

    Raises:
        FileNotFoundError: ``source`` does not exist.
        WeightsChecksumError: ``source`` is not Kornia's file.
    """
    from safetensors.torch import save_file  # lazy: as in _read_yunet_state

    source = Path(source)
    if not source.is_file():
        raise FileNotFoundError(f"no YuNet weights at {str(source)!r}")
    digest = sha256_file(source)
    if digest != YUNET_SHA256:
        raise WeightsChecksumError(f"{str(source)!r} has SHA-256 {digest}, not that of Kornia's yunet_final.pth "
                                   f"({YUNET_SHA256})")
    state = {k: v.contiguous() for k, v in _read_yunet_state(source).items()}
    # one metadata entry: safetensors writes several in a random order, and the file must come out the same
    atomic_write(out, lambda tmp: save_file(state, str(tmp), metadata={"source": f"yunet_final.pth sha256 {digest}"}))
    return sha256_file(out)


#: The anchors of Kornia's YuNet weights: their sizes per feature map and the maps' strides.
_YUNET_MIN_SIZES = ((10, 16, 24), (32, 48), (64, 96), (128, 192, 256))
_YUNET_STEPS = (8, 16, 32, 64)


@functools.lru_cache(maxsize=8)
def _yunet_priors(height: int, width: int, device: torch.device, dtype: torch.dtype) -> torch.Tensor:
    """YuNet's anchors for an input of ``height x width`` (:class:`kornia.models.yunet.processors.PriorBox`), made
    once per size, device and dtype (Kornia's post-processing builds them in a Python loop at every call); shared,
    so never modified in place."""
    priors = PriorBox([list(m) for m in _YUNET_MIN_SIZES], list(_YUNET_STEPS), False, image_size=(height, width))
    return priors.to(device, dtype)()


class YuNetFaceDetector(FaceDetector):
    r"""Kornia's YuNet face detector (Wu, Peng & Yu, "YuNet: A Tiny Millisecond-level Face Detector",
    Machine Intelligence Research 2023), with the weights that ship inside the package.

    The network is :class:`kornia.models.yunet.YuNet` built with ``pretrained=False``; its state dict is read
    from the package's ``weights/yunet.safetensors`` (:data:`YUNET_WEIGHTS`: Kornia's ``yunet_final.pth``,
    MIT, converted by :func:`convert_yunet_weights`; no pickle) after checking the file's SHA-256. Nothing is
    ever downloaded (unlike :class:`kornia.contrib.FaceDetector`, whose constructor downloads), and no
    environment variable is needed. Other weights are read from ``weights_path``, else from the path in
    ``$KORNIA_ILUM_YUNET_WEIGHTS`` (an override): a ``.safetensors`` file, or a ``.pth`` read with
    ``torch.load(weights_only=True)``.

    As Kornia documents, YuNet takes BGR in ``[0, 255]``: the image is scaled by 255 and flipped to BGR.
    Decoding, score (``sqrt(cls x iou)``), confidence filtering and NMS give the detections of Kornia's
    :meth:`kornia.contrib.FaceDetector.postprocess`, with its anchors made once per image size.

    ``confidence_threshold=0.93`` sits between the faces and the false faces measured here (Kornia's 0.3
    keeps too much, and the 0.9 of OpenCV's ``FaceDetectorYN`` demo let a motorcycle's headlights through,
    as a new user's photograph of dogs was let through):

    - faces: every face of the astronaut images, scikit-image's cameraman (0.944), and 17 of the 18
      synthetic group images described in :class:`OpenCVFaceDetector` scored >= 0.94 (one on a noise
      background, 0.77); all 120 light-stage renders of ``benchmarks/bench_detection.py`` are found at 0.93
      and at 0.95;
    - false faces on 19 face-free scikit-image photographs (``benchmarks/bench_detection.py
      --yunet-thresholds``): a motorcycle's headlights 0.92 (``stereo_motorcycle``), the others <= 0.78 (a
      cat, 0.78).

    Args:
        weights_path: other weights (``.safetensors`` or ``.pth``); ``None``: ``$KORNIA_ILUM_YUNET_WEIGHTS`` if
            set, else the packaged file.
        sha256: the file's expected SHA-256, or several accepted ones (by default the packaged file's and
            Kornia's ``yunet_final.pth``'s); ``None`` skips the check.
        confidence_threshold: minimum score of a face.
        nms_threshold: IoU above which NMS drops the weaker of two boxes (Kornia's 0.3).
        top_k: candidates kept before NMS (Kornia's 5000).
        keep_top_k: faces kept after NMS (Kornia's 750).

    Raises:
        MissingWeightsError: the weight file was not found; the message says where it looked.
        WeightsChecksumError: the file's SHA-256 is not ``sha256``.
        ValueCheckError: a threshold is out of range.

    Examples:
        >>> import skimage.data
        >>> image = torch.from_numpy(skimage.data.astronaut()).permute(2, 0, 1) / 255
        >>> faces = YuNetFaceDetector().detect(image)[0]  # the packaged weights
        >>> faces.shape
        torch.Size([1, 5])

        A missing file is reported, never fetched:

        >>> YuNetFaceDetector(weights_path="no/such/yunet_final.pth")  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        kornia_ilum.core.errors.MissingWeightsError: YuNet weights not found; looked at ...
    """

    name: ClassVar[str] = "yunet"
    #: Detection on a copy of at most 240 pixels by default (a 640 x 480 photo at three eighths), then at full size
    #: where that copy shows no face: on the light stage's eval portraits it finds every face that full size finds
    #: and more (YuNet's scores dip at some scales), in a third of the time (docs/bench.rst, "The default
    #: detector").
    default_max_side: ClassVar[int | None] = 240
    description: ClassVar[str] = (
        "Kornia's YuNet CNN (Wu et al. 2023); more poses and smaller faces; weights shipped in the package "
        f"(MIT), never downloaded (override: weights_path= or ${YUNET_WEIGHTS_ENV})"
    )

    def __init__(
        self,
        weights_path: str | os.PathLike[str] | None = None,
        *,
        sha256: str | Sequence[str] | None = (YUNET_SAFETENSORS_SHA256, YUNET_SHA256),
        confidence_threshold: float = 0.93,
        nms_threshold: float = 0.3,
        top_k: int = 5000,
        keep_top_k: int = 750,
    ) -> None:
        super().__init__()
        for name, value in (("confidence_threshold", confidence_threshold), ("nms_threshold", nms_threshold)):
            if not (isinstance(value, (int, float)) and 0 <= value <= 1):
                raise ValueCheckError(f"{name} must be in [0, 1], got {value!r}")
        where, path = _yunet_weights(weights_path)
        if not path.is_file():
            raise MissingWeightsError(
                f"YuNet weights not found; looked at {where}: {path}. They are never downloaded: pass weights_path=... "
                f"or set ${YUNET_WEIGHTS_ENV} to a .safetensors or yunet_final.pth file, or unset it to use the "
                "weights that ship with kornia_ilum"
            )
        if sha256 is not None:
            accepted = [sha256] if isinstance(sha256, str) else list(sha256)
            digest = sha256_file(path)
            if digest not in {a.lower() for a in accepted}:
                raise WeightsChecksumError(
                    f"YuNet weights {str(path)!r} have SHA-256 {digest}, expected {' or '.join(accepted)}; "
                    "pass sha256=None to load other weights on purpose"
                )
        self.weights_path = path
        self.model = YuNet("test", pretrained=False)
        self.model.load_state_dict(_read_yunet_state(path), strict=True)
        self.model.eval()
        # Kornia's post-processing settings for these weights (kornia.contrib.FaceDetector).
        self.min_sizes = [list(m) for m in _YUNET_MIN_SIZES]
        self.steps = list(_YUNET_STEPS)
        self.variance = [0.1, 0.2]
        self.clip = False
        self.confidence_threshold = float(confidence_threshold)
        self.nms_threshold = float(nms_threshold)
        self.top_k = int(top_k)
        self.keep_top_k = int(keep_top_k)

    def _postprocess(self, out: dict[str, torch.Tensor], height: int, width: int) -> list[torch.Tensor]:
        """Kornia's :meth:`kornia.contrib.FaceDetector.postprocess`, the same detections, with cached anchors and
        only the candidates above the confidence threshold decoded: ``B`` tensors ``(N, 15)`` (box, five
        landmarks, score)."""
        loc_all, conf_all, iou_all = out["loc"], out["conf"], out["iou"]
        priors = _yunet_priors(height, width, loc_all.device, loc_all.dtype)
        scale = loc_all.new_tensor([width, height] * 7)
        found = []
        for loc, conf, iou in zip(loc_all, conf_all, iou_all, strict=True):
            scores = (conf[:, 1] * iou[:, 0].clamp(0.0, 1.0)).sqrt()
            keep = scores > self.confidence_threshold
            scores, order = scores[keep].sort(descending=True)
            order, scores = order[: self.top_k], scores[: self.top_k]
            boxes = decode(loc[keep][order], priors[keep][order], self.variance) * scale
            dets = torch.cat((boxes, scores[:, None]), dim=-1)
            kept = nms(boxes[:, :4], scores, self.nms_threshold)
            found.append((dets[kept] if len(kept) else dets)[: self.keep_top_k])
        return found

    def _detect(self, image: torch.Tensor) -> list[torch.Tensor]:
        weight = next(self.model.parameters())
        bgr = image.flip(-3).to(device=weight.device, dtype=weight.dtype) * 255.0
        height, width = bgr.shape[-2:]
        if min(height, width) < YUNET_MIN_SIDE:  # its five poolings need 64 pixels: pad below and right with black
            bgr = F.pad(bgr, (0, max(0, YUNET_MIN_SIDE - width), 0, max(0, YUNET_MIN_SIDE - height)))
        with torch.inference_mode():
            found = self._postprocess(self.model(bgr), bgr.shape[-2], bgr.shape[-1])
        out = []
        for dets in found:
            dets = dets[:, [0, 1, 2, 3, 14]]
            keep = (dets[:, 2] > dets[:, 0]) & (dets[:, 3] > dets[:, 1]) & dets.isfinite().all(dim=1)
            out.append(dets[keep].clone())  # a normal tensor, not an inference tensor
        return out

    def train(self, mode: bool = True) -> YuNetFaceDetector:
        """Detection always runs the network in eval mode (batch norm with its running statistics)."""
        super().train(mode)
        self.model.eval()
        return self

    def extra_repr(self) -> str:
        return f"weights_path={str(self.weights_path)!r}, confidence_threshold={self.confidence_threshold}"


# ------------------------------------------------------------------------------------------------ none
class NoFaceDetector(FaceDetector):
    r"""No detection: the input already is a face crop; each image gives one box covering all of it.

    The box is ``(0, 0, W, H)`` with score 1, and :attr:`crop_scale` is 1, so the crop square is the
    centred ``max(W, H)`` square: the image itself when it is square, zero-padded on its short side
    otherwise.

    Examples:
        >>> NoFaceDetector().detect(torch.rand(3, 480, 640))
        [tensor([[  0.,   0., 640., 480.,   1.]])]
    """

    name: ClassVar[str] = "none"
    description: ClassVar[str] = "no detection: each input already is a face crop (one box, the whole image)"
    crop_scale: ClassVar[float] = 1.0

    def _detect(self, image: torch.Tensor) -> list[torch.Tensor]:
        height, width = image.shape[-2:]
        box = torch.tensor([[0.0, 0.0, float(width), float(height), 1.0]])
        return [box.clone() for _ in range(image.shape[0])]
