"""Face detection and the paper's face crop.

Detectors by name (:func:`list_detectors`, :func:`create_detector`, :func:`register_detector`):
``"yunet"`` (Kornia's YuNet, the default, with its MIT weights inside the package, never downloaded; it detects
on a copy of at most 240 pixels), ``"opencv"`` (OpenCV's Haar cascade, offline) and ``"none"`` (the input
already is a crop). Every detector's
:meth:`FaceDetector.detect` returns ``(N, 5)`` boxes ``(x0, y0, x1, y1, score)`` per image.
:func:`square_crop_boxes` and :func:`crop_faces` make the paper's crop: a square centred on the face box,
side 1.25 x max(w, h), zero padding outside the image, resized to 256 with antialiasing.
"""

from kornia_ilum.detection.crop import CropFaces, SquareCropBoxes, crop_faces, square_crop_boxes
from kornia_ilum.detection.detectors import (
    FaceDetector,
    NoFaceDetector,
    OpenCVFaceDetector,
    YuNetFaceDetector,
    convert_yunet_weights,
)
from kornia_ilum.detection.registry import (
    DEFAULT_DETECTOR,
    DETECTORS,
    create_detector,
    describe_detector,
    list_detectors,
    register_detector,
)

__all__ = [
    "FaceDetector",
    "OpenCVFaceDetector",
    "YuNetFaceDetector",
    "NoFaceDetector",
    "convert_yunet_weights",
    "DEFAULT_DETECTOR",
    "DETECTORS",
    "list_detectors",
    "create_detector",
    "register_detector",
    "describe_detector",
    "square_crop_boxes",
    "SquareCropBoxes",
    "crop_faces",
    "CropFaces",
]
