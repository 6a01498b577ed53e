r"""Run time of the estimators and of the whole photo-to-file path, as ``kornia-ilum bench`` measures it.

- :func:`estimator_speed`: ms per crop at batch 1 and per crop at batch 32 (crops per second), of one estimator
  under one runtime, on the probe's real face crops (the time does not depend on the content, but a crop of a
  face is what the estimator sees), after warm-up calls, under :func:`torch.inference_mode`;
- :func:`estimator_flops`: the multiply-adds of one crop (PyTorch's :class:`~torch.utils.flop_counter.FlopCounterMode`
  on the eager estimator), to turn a time into a rate against the machine's peak;
- :func:`end_to_end`: one photograph from its file to the written ``.exr``: read, check, detect, crop,
  estimate, write, each stage's median and the median of the whole, as :func:`~kornia_ilum.estimate_lighting`
  reports its stages (``on_stage=``).
"""

from __future__ import annotations

import platform
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import skimage.data
import torch
import torch.nn.functional as F
from torch.utils.flop_counter import FlopCounterMode

from kornia_ilum.api import estimate_lighting
from kornia_ilum.bench.machine import median_seconds
from kornia_ilum.detection import FaceDetector
from kornia_ilum.estimators import LightingEstimator, SceneStrength
from kornia_ilum.estimators.probe import CHECK, fit_crops, load_probe
from kornia_ilum.io import read_ldr, write_ldr

__all__ = ["E2E_SIZES", "end_to_end", "estimator_flops", "estimator_speed", "portrait_photo", "run_info"]

#: The photo sizes of the end-to-end rows (width, height).
E2E_SIZES: tuple[tuple[int, int], ...] = ((640, 480), (1280, 720))


def _crops(estimator: LightingEstimator, batch: int) -> torch.Tensor:
    crops = load_probe().part(CHECK).crops
    crops = crops.repeat((batch + len(crops) - 1) // len(crops), 1, 1, 1)[:batch]
    return fit_crops(estimator, crops).contiguous()


def estimator_speed(estimator: LightingEstimator, batches: tuple[int, ...] = (1, 32), repeats: int = 20
                    ) -> dict[str, float]:
    r"""Median ms per call and per crop of ``estimator`` at each batch size.

    Args:
        estimator: the estimator, under the runtime to time (:func:`~kornia_ilum.estimators.with_runtime`).
        batches: the batch sizes, of the probe's check crops (repeated to fill a batch).
        repeats: timed calls at batch 1, after two warm-up calls.

    Returns:
        ``{"b{B}_ms": ms per call, "b{B}_ms_per_crop": ms per crop, "b{B}_crops_per_s": crops per second}`` for
        every ``B`` of ``batches``; larger batches are timed ``max(3, repeats // 4)`` times.

    Examples:
        A timing, so it is not run here:

        >>> from kornia_ilum.estimators import create_estimator
        >>> speed = estimator_speed(create_estimator("uniform"), (1, 4), repeats=3)  # doctest: +SKIP
        >>> sorted(speed)  # doctest: +SKIP
        ['b1_crops_per_s', 'b1_ms', 'b1_ms_per_crop', 'b4_crops_per_s', 'b4_ms', 'b4_ms_per_crop']
    """
    out: dict[str, float] = {}
    for batch in batches:
        crops = _crops(estimator, batch)
        with torch.inference_mode():
            seconds = median_seconds(lambda c=crops: estimator(c), repeats if batch == 1 else max(3, repeats // 4))
        out[f"b{batch}_ms"] = 1e3 * seconds
        out[f"b{batch}_ms_per_crop"] = 1e3 * seconds / batch
        out[f"b{batch}_crops_per_s"] = batch / seconds
    return out


def estimator_flops(estimator: LightingEstimator) -> float:
    """Floating-point operations of one crop (a multiply-add counts two), by PyTorch's flop counter.

    Args:
        estimator: the eager estimator; it runs once on one of the probe's check crops.

    Returns:
        the operations of one forward pass of one crop (0 for an estimator without matmuls or convolutions).

    Examples:
        It loads the probe and runs the estimator once, so it is not run here:

        >>> from kornia_ilum.estimators import create_estimator
        >>> estimator_flops(create_estimator("ours", pretrained=False)) > 1e8  # doctest: +SKIP
        True
    """

    counter = FlopCounterMode(display=False)
    with torch.inference_mode(), counter:
        estimator(_crops(estimator, 1))
    return float(counter.get_total_flops())


def portrait_photo(width: int, height: int) -> np.ndarray:
    """scikit-image's astronaut scaled to the photo's height and centred on a black ``width x height`` canvas:
    ``(height, width, 3)`` uint8, one face of about a fifth of the height.

    Args:
        width: the photo's width in pixels.
        height: its height in pixels.

    Returns:
        the photo, an ``(height, width, 3)`` uint8 sRGB array (the astronaut scaled to the shorter side).

    Examples:
        >>> photo = portrait_photo(64, 48)
        >>> photo.shape, photo.dtype, int(photo[:, :8].max())  # black beside the square portrait
        ((48, 64, 3), dtype('uint8'), 0)
    """

    astronaut = torch.from_numpy(skimage.data.astronaut()).permute(2, 0, 1)[None].float() / 255
    side = min(width, height)
    face = F.interpolate(astronaut, size=(side, side), mode="bilinear", antialias=True, align_corners=False)
    left, top = (width - side) // 2, (height - side) // 2
    canvas = F.pad(face.clamp(0, 1), (left, width - side - left, top, height - side - top))
    return (canvas[0].permute(1, 2, 0) * 255).round().to(torch.uint8).numpy()


def end_to_end(photo: np.ndarray, estimator: LightingEstimator, detector: FaceDetector, repeats: int = 10,
               scene: SceneStrength | None = None) -> dict[str, float]:
    r"""One photograph from its JPEG file to its ``.exr``, stage by stage: medians in ms.

    The photo is written once as a JPEG (quality 95) into a temporary folder (removed afterwards); each run
    reads it (:func:`~kornia_ilum.io.read_ldr`), estimates its lighting (:func:`~kornia_ilum.estimate_lighting`
    with the given estimator and detector, which reports ``check``, ``detect``, ``crop`` and ``estimate``)
    and writes the estimate (:meth:`~kornia_ilum.estimators.LightingEstimate.save`, float32 ``.exr``).

    Args:
        photo: an ``(H, W, 3)`` uint8 sRGB photo (:func:`portrait_photo`).
        estimator: the estimator, under the runtime to time.
        detector: the face detector (the bench's: :func:`~kornia_ilum.api.cached_detector`, possibly detecting
            on a downscaled copy).
        repeats: timed runs.
        scene: a scene branch for :func:`~kornia_ilum.estimate_lighting` (its time is in ``estimate``).

    Returns:
        ``{"read", "check", "detect", "crop", "estimate", "write", "total"}`` in ms, each the median over
        ``repeats`` runs (after one warm-up run); ``total`` is the median of the whole run, not the sum.

    Examples:
        A timing, so it is not run here:

        >>> from kornia_ilum.detection import create_detector
        >>> from kornia_ilum.estimators import create_estimator
        >>> estimator, detector = create_estimator("ours"), create_detector("opencv")  # doctest: +SKIP
        >>> sorted(end_to_end(portrait_photo(640, 480), estimator, detector, repeats=3))  # doctest: +SKIP
        ['check', 'crop', 'detect', 'estimate', 'read', 'total', 'write']
    """
    stages: dict[str, list[float]] = {}
    with tempfile.TemporaryDirectory(prefix="kornia_ilum_bench_") as tmp:
        src, dst = Path(tmp) / "photo.jpg", Path(tmp) / "lighting.exr"
        write_ldr(src, torch.from_numpy(photo).permute(2, 0, 1).float() / 255, quality=95)
        for run in range(repeats + 1):
            t0 = time.perf_counter()
            image = read_ldr(src)
            times = {"read": 1e3 * (time.perf_counter() - t0)}
            light = estimate_lighting(image, estimator=estimator, detector=detector, on_stage=times.__setitem__,
                                      scene=scene)
            t1 = time.perf_counter()
            light.save(dst)
            t2 = time.perf_counter()
            times["write"], times["total"] = 1e3 * (t2 - t1), 1e3 * (t2 - t0)
            if run:  # the first run warms up
                for key, value in times.items():
                    stages.setdefault(key, []).append(value)
    return {key: statistics.median(values) for key, values in stages.items()}


def run_info() -> dict[str, Any]:
    """The software of the run: versions and thread counts.

    Returns:
        ``python``, ``torch``, ``torch_threads``, ``onnxruntime`` (``None`` without the onnx extra) and
        ``opencv``.

    Examples:
        >>> sorted(run_info())
        ['onnxruntime', 'opencv', 'python', 'torch', 'torch_threads']
    """
    info: dict[str, Any] = {"python": platform.python_version(), "torch": torch.__version__,
                            "torch_threads": torch.get_num_threads()}
    try:
        import onnxruntime  # lazy: optional (the onnx extra)

        info["onnxruntime"] = onnxruntime.__version__
    except ImportError:
        info["onnxruntime"] = None
    info["opencv"] = cv2.__version__
    return info
