r"""Checks that ``kornia-ilum evaluate`` keeps running for every estimator: transfer, exposure, crop, spread.

Each works for any estimator: a callable that takes ``(B, 3, 256, 256)`` float sRGB crops in ``[0, 1]`` and
returns a :class:`~kornia_ilum.estimators.LightingEstimate` (or a tensor) whose ``mirror_ball`` ``(B, 3, 32,
32)`` is linear lighting in the units of the photo (docs/conventions.rst, "Units of lighting"). They compare
the lighting's energy (:func:`lighting_energy`, the integral over the sphere of the mean over R, G, B) and its
dominant direction (:func:`dominant_direction`).

- :func:`transfer_check`, the **label-free transfer check**: the energy estimated from each eval portrait as
  it is (``E_with``), with its background replaced by black (``E_black``) or by sRGB grey 0.5 (``E_grey``),
  against the truth (``E_true``). ``E_black / E_with`` and ``E_grey / E_with`` need no label, so they can be
  measured on any photo with a matte: an estimator that reads the strength of the light from the face keeps
  them near 1, one that reads it from the background does not.
- :func:`exposure_equivariance`: the photo darkened by ``k`` in linear light, without new clipping (the sRGB
  codes decoded, scaled by ``k`` and encoded again, in floating point) must give ``k`` times the energy:
  the median over photos of ``E(k x) / (k E(x))`` should be 1. Run on the eval portraits and on real photos
  cut by the project's own detection and crop (:func:`face_crops`).
- :func:`crop_stability`: the spread of the estimate over square crops jittered as a face detector's boxes
  are (centre moved by up to 10 % of the side, side scaled by up to ``e^0.15``), cut from the wider context
  crops of :func:`~kornia_ilum_lab.evaluation.build_eval_set` (``context``): per portrait the standard deviation
  of the log energy, the ratio of the largest to the smallest energy and the mean angle between each crop's
  dominant direction and their mean direction.
- :func:`spread_calibration`: for estimators that give the spread of their log energy
  (:attr:`~kornia_ilum.estimators.LightingEstimate.log_energy_spread`), the share of portraits whose true
  energy lies within one and two spreads, per skin tone, against the share a calibrated spread gives.
- ``"colour"``, the colour check (:func:`~kornia_ilum_lab.evaluation.colour.colour_check`): the same portraits
  greyscale, desaturated, white-balanced warmer and cooler and graded; how far the main light turns and how its
  strength changes, on the eval crops and on the real photos (and the real-flash photographs, when given).
- ``"flash"``, the real-flash check (:func:`~kornia_ilum_lab.evaluation.flash.real_flash_check`): real faces
  under one flash of known direction each; the main light's direction error, its sign agreement, the spread of
  the strength across people under one flash.

The per-tone figures of the transfer and spread checks carry 95 % intervals over subjects
(:mod:`~kornia_ilum_lab.evaluation.bootstrap`): the portraits of one face are not independent.

:func:`run_checks` runs the chosen ones for one estimator and returns their JSON-ready tables (medians per
skin tone and over all samples); :func:`check_runner` makes the ``checks`` callable with which
:func:`~kornia_ilum_lab.evaluation.evaluate` runs them on every scored estimator, and
:func:`~kornia_ilum_lab.evaluation.summarize` reports them.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from typing import Any

import numpy as np
import torch

from kornia_ilum.color import linear_to_srgb, srgb_to_linear
from kornia_ilum.core.check import check_positive_int, check_tensor
from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.detection import (
    DEFAULT_DETECTOR,
    FaceDetector,
    create_detector,
    crop_faces,
    square_crop_boxes,
)
from kornia_ilum_lab.evaluation.bootstrap import ratio_interval, subject_interval
from kornia_ilum_lab.evaluation.colour import colour_check
from kornia_ilum_lab.evaluation.flash import FlashSet, real_flash_check
from kornia_ilum_lab.evaluation.evaluate import EvalSet
from kornia_ilum_lab.evaluation.measures import Estimator, as_floats, dominant_direction, estimates, median_of, quantiles
from kornia_ilum.io import read_ldr
from kornia_ilum.metrics import lighting_energy
from kornia_ilum_lab.synth.lightstage.portraits import crop_images

__all__ = [
    "BACKGROUNDS",
    "CHECKS",
    "EXPOSURE_FACTORS",
    "INTERVAL_RATIOS",
    "SPREAD_NOMINAL",
    "check_runner",
    "flash_checks",
    "composite_background",
    "crop_stability",
    "darken",
    "default_photos",
    "dominant_direction",
    "exposure_equivariance",
    "face_crops",
    "jitter_boxes",
    "run_checks",
    "spread_calibration",
    "transfer_check",
]

#: The checks by name, in the order :func:`run_checks` runs them.
CHECKS: tuple[str, ...] = ("transfer", "exposure", "crop", "spread", "colour", "flash")
#: The share of portraits whose true log energy lies within ``+-k b`` of the estimate's, for a calibrated
#: Laplace spread ``b``: ``1 - e^-k`` (:func:`spread_calibration`).
SPREAD_NOMINAL: dict[int, float] = {k: 1.0 - math.exp(-k) for k in (1, 2)}
#: The darkening factors of :func:`exposure_equivariance`.
EXPOSURE_FACTORS: tuple[float, ...] = (0.5, 0.25)
#: The ratios of :func:`transfer_check` that get an interval over subjects and a spread across tones.
INTERVAL_RATIOS: tuple[str, ...] = ("with/true", "black/with")
#: The backgrounds of :func:`transfer_check`: name to the sRGB value that replaces the background.
BACKGROUNDS: dict[str, float] = {"black": 0.0, "grey": 0.5}

def _check_images(images: Any, name: str = "images") -> None:
    if not isinstance(images, torch.Tensor):
        raise TypeCheckError(f"{name} must be a tensor, got {type(images).__name__}")
    check_tensor(images, name, ["N", "3", "H", "W"], floating=images.dtype != torch.uint8,
                 finite=images.dtype != torch.uint8)


# ----------------------------------------------------------------------------------------------
# summaries


def _groups(skin_tone: Sequence[int]) -> dict[str, torch.Tensor]:
    """``"all"`` and each skin tone (as a string, sorted) to a boolean mask."""
    tones = torch.tensor(list(skin_tone), dtype=torch.long)
    out = {"all": torch.ones(len(tones), dtype=torch.bool)}
    out.update({str(t): tones == t for t in sorted(set(tones.tolist()))})
    return out


# ----------------------------------------------------------------------------------------------
# transfer


def composite_background(images: torch.Tensor, alpha: torch.Tensor, value: float) -> torch.Tensor:
    r"""The crops with their background replaced by a constant, composited in sRGB codes.

    ``x a + (1 - a) value`` with ``x`` the sRGB codes in ``[0, 1]`` and ``a = alpha / 255``: the face as the
    photo shows it over a flat background (no new quantisation: the result stays float).

    Args:
        images: ``(N, 3, H, W)`` uint8 codes or float in ``[0, 1]``.
        alpha: ``(N, 1, H, W)`` uint8 matte (255: subject) or float in ``[0, 1]``.
        value: the background's sRGB value in ``[0, 1]`` (0 black, 0.5 grey).

    Returns:
        ``(N, 3, H, W)`` float32 in ``[0, 1]``.

    Raises:
        ShapeError: ``alpha`` does not match ``images``.
        ValueCheckError: ``value`` is outside ``[0, 1]``.

    Shape:
        - images: :math:`(N, 3, H, W)`; alpha: :math:`(N, 1, H, W)`
        - Output: :math:`(N, 3, H, W)`

    Convention:
        sRGB-encoded images (docs/conventions.rst, "Images"); the compositing is done on the codes, not in linear
        light, as an image editor would.

    Examples:
        >>> x = torch.full((1, 3, 2, 2), 255, dtype=torch.uint8)
        >>> a = torch.tensor([[[[255, 0], [0, 0]]]], dtype=torch.uint8)
        >>> composite_background(x, a, 0.5)[0, 0]
        tensor([[1.0000, 0.5000],
                [0.5000, 0.5000]])
    """
    _check_images(images)
    if not isinstance(alpha, torch.Tensor) or alpha.shape != (images.shape[0], 1, *images.shape[-2:]):
        raise ShapeError(f"alpha must have shape {(images.shape[0], 1, *images.shape[-2:])}, got "
                         f"{getattr(alpha, 'shape', type(alpha).__name__)}")
    if not 0.0 <= value <= 1.0:
        raise ValueCheckError(f"value must be in [0, 1], got {value!r}")
    a = as_floats(alpha)
    return as_floats(images) * a + (1.0 - a) * value


def transfer_check(estimator: Estimator, eval_set: EvalSet, *, prediction: torch.Tensor | None = None,
                   batch_size: int = 32) -> dict[str, Any]:
    r"""The label-free transfer check: the energy estimated with the background, over black and over grey.

    For every sample: ``E_with`` (the crop as it is), ``E_black`` and ``E_grey`` (its background replaced by
    :data:`BACKGROUNDS`, :func:`composite_background` with the set's ``alpha``) and ``E_true`` (the ground
    truth's); all by :func:`lighting_energy`.

    Args:
        estimator: the estimator (module docstring).
        eval_set: an eval set with its matte (:func:`~kornia_ilum_lab.evaluation.build_eval_set` fills it).
        prediction: the estimator's ``(N, 3, S, S)`` lighting on the crops as they are, if already made (it
            saves a pass: ``E_with`` is its energy).
        batch_size: crops per forward pass.

    Returns:
        ``{"energy": {"with", "black", "grey", "true": (N,) float64}, "table": {group: row}}`` and
        ``"tone_spread"``; the groups are ``"all"`` and each skin tone; a row holds ``count``, ``subjects`` and
        the medians over its samples of the ratios ``with/true``, ``black/true``, ``grey/true``, ``black/with``
        and ``grey/with``, and for :data:`INTERVAL_RATIOS` their 95 % interval over subjects (``"with/true_ci"``,
        ...: :func:`~kornia_ilum_lab.evaluation.bootstrap.subject_interval`). ``tone_spread`` holds, for the same
        ratios, the largest over the smallest per-tone median with its interval
        (:func:`~kornia_ilum_lab.evaluation.bootstrap.ratio_interval`; tones ``-1``, unknown, left out).

    Raises:
        ValueCheckError: the set has no matte.

    Shape:
        - eval_set.images: :math:`(N, 3, H, W)`; prediction: :math:`(N, 3, S, S)`
        - Output: each energy :math:`(N,)`

    Convention:
        Crops are sRGB (docs/conventions.rst, "Images"); energies are in the units of the lighting times
        steradians (docs/conventions.rst, "Units of lighting", :func:`lighting_energy`).

    Examples:
        An "estimator" that reads the light from the crop's mean brightness, background included, on white
        crops whose right half is background:

        >>> from kornia_ilum_lab.evaluation import EvalSet
        >>> def brightness(crops):
        ...     return torch.ones(len(crops), 3, 32, 32) * srgb_to_linear(crops).mean((1, 2, 3))[:, None, None, None]
        >>> alpha = torch.zeros(2, 1, 8, 8, dtype=torch.uint8)
        >>> alpha[..., :4] = 255
        >>> white = EvalSet(torch.full((2, 3, 8, 8), 255, dtype=torch.uint8), torch.ones(2, 3, 32, 32),
        ...                 ["indoor"] * 2, [3, 3], [0, 1], ["room"] * 2, alpha=alpha)
        >>> table = transfer_check(brightness, white)["table"]
        >>> sorted(table), round(table["all"]["black/with"], 4), round(table["all"]["with/true"], 4)
        (['3', 'all'], 0.5, 1.0)
    """
    if eval_set.alpha is None:
        raise ValueCheckError("transfer_check needs the eval set's matte (alpha), as build_eval_set makes it")
    check_positive_int(batch_size, "batch_size")
    images, alpha, n = eval_set.images, eval_set.alpha, len(eval_set)

    def batches(value: float | None) -> Iterator[torch.Tensor]:
        for i in range(0, n, batch_size):
            x = images[i : i + batch_size]
            yield as_floats(x) if value is None else composite_background(x, alpha[i : i + batch_size], value)

    energy: dict[str, torch.Tensor] = {}
    if prediction is not None:
        check_tensor(prediction, "prediction", [str(n), "3", "S", "S"])
        energy["with"] = lighting_energy(prediction.double())
    else:
        energy["with"] = estimates(estimator, batches(None))[0]
    for name, value in BACKGROUNDS.items():
        energy[name] = estimates(estimator, batches(value))[0]
    energy["true"] = lighting_energy(eval_set.mirror_ball.double())
    ratios = {"with/true": energy["with"] / energy["true"], "black/true": energy["black"] / energy["true"],
              "grey/true": energy["grey"] / energy["true"], "black/with": energy["black"] / energy["with"],
              "grey/with": energy["grey"] / energy["with"]}
    groups = _groups(eval_set.skin_tone)
    subjects = torch.tensor(list(eval_set.subject_seed))
    table = {g: {"count": int(m.sum()), "subjects": len(set(subjects[m].tolist())),
                 **{k: median_of(r[m]) for k, r in ratios.items()},
                 **{f"{k}_ci": subject_interval(ratios[k][m], subjects[m]) for k in INTERVAL_RATIOS}}
             for g, m in groups.items() if m.any()}
    tones = {g: m for g, m in groups.items() if g != "all" and int(g) > 0 and m.any()}
    spread = {k: ratio_interval({g: (ratios[k][m], subjects[m]) for g, m in tones.items()})
              for k in INTERVAL_RATIOS} if tones else {}
    return {"energy": energy, "table": table, "tone_spread": spread}


# ----------------------------------------------------------------------------------------------
# exposure


def darken(images: torch.Tensor, k: float) -> torch.Tensor:
    r"""Darken sRGB crops by ``k`` in linear light, without new clipping and without quantising again.

    ``linear_to_srgb(k * srgb_to_linear(x))``: for ``k <= 1`` nothing that was below white clips, and what
    was clipped stays at the value it had, times ``k``.

    Args:
        images: ``(N, 3, H, W)`` uint8 codes or float sRGB in ``[0, 1]``.
        k: the factor, positive.

    Returns:
        ``(N, 3, H, W)`` float32 sRGB.

    Raises:
        ValueCheckError: ``k`` is not a positive finite number.

    Shape:
        - images: :math:`(N, 3, H, W)`
        - Output: :math:`(N, 3, H, W)`

    Convention:
        sRGB-encoded in and out (docs/conventions.rst, "Images"); ``k`` applies in linear light.

    Examples:
        >>> darken(torch.full((1, 3, 1, 1), 0.5), 0.5).flatten()
        tensor([0.3608, 0.3608, 0.3608])
    """
    _check_images(images)
    if not (isinstance(k, (int, float)) and math.isfinite(k) and k > 0):
        raise ValueCheckError(f"k must be a positive finite number, got {k!r}")
    return linear_to_srgb(srgb_to_linear(as_floats(images)) * k)


def exposure_equivariance(
    estimator: Estimator,
    images: torch.Tensor,
    *,
    ks: Sequence[float] = EXPOSURE_FACTORS,
    prediction: torch.Tensor | None = None,
    batch_size: int = 32,
) -> dict[str, Any]:
    r"""How the estimate scales with the photo's exposure: ``E(k x) / (k E(x))`` for each ``k`` of ``ks``.

    The lighting is in the photo's units, so a photo darkened by ``k`` in linear light (:func:`darken`) must
    give ``k`` times the energy: the ratio is 1 for an estimator that scales with the exposure, above 1 for
    one that pulls dark photos towards a typical brightness.

    Args:
        estimator: the estimator (module docstring).
        images: ``(N, 3, H, W)`` crops: uint8 codes (an eval set's ``images``) or float sRGB in ``[0, 1]``
            (:func:`face_crops` of real photos).
        ks: the darkening factors.
        prediction: the estimator's lighting on ``images`` as they are, if already made (saves a pass).
        batch_size: crops per forward pass.

    Returns:
        ``{"energy": {"1": (N,), f"{k:g}": (N,) ...}, "ratio": {f"{k:g}": (N,)}, "table": {f"{k:g}": row}}``;
        a row holds the ``median``, ``q25`` and ``q75`` of the ratio over the images and their ``count`` (the
        finite ratios).

    Raises:
        ValueCheckError: an empty ``ks`` or a factor that is not positive and finite.

    Shape:
        - images: :math:`(N, 3, H, W)`; prediction: :math:`(N, 3, S, S)`
        - Output: each energy and ratio :math:`(N,)`

    Convention:
        Crops are sRGB (docs/conventions.rst, "Images"); the lighting is in their units (docs/conventions.rst,
        "Units of lighting"), which is what makes the ratio 1.

    Examples:
        >>> def brightness(crops):  # lighting proportional to the crop's mean linear value
        ...     mean = srgb_to_linear(crops).mean((1, 2, 3))
        ...     return torch.ones(len(crops), 3, 32, 32) * mean[:, None, None, None]
        >>> out = exposure_equivariance(brightness, torch.rand(4, 3, 8, 8))
        >>> round(out["table"]["0.5"]["median"], 4), round(out["table"]["0.25"]["median"], 4)
        (1.0, 1.0)
    """
    _check_images(images)
    check_positive_int(batch_size, "batch_size")
    ks = [float(k) for k in ks]
    if not ks or not all(math.isfinite(k) and k > 0 for k in ks):
        raise ValueCheckError(f"ks must be positive finite factors, got {ks!r}")
    n = len(images)

    def batches(k: float | None) -> Iterator[torch.Tensor]:
        for i in range(0, n, batch_size):
            x = images[i : i + batch_size]
            yield as_floats(x) if k is None else darken(x, k)

    if prediction is not None:
        check_tensor(prediction, "prediction", [str(n), "3", "S", "S"])
        base = lighting_energy(prediction.double())
    else:
        base = estimates(estimator, batches(None))[0]
    energy, ratio, table = {"1": base}, {}, {}
    for k in ks:
        key = f"{k:g}"
        energy[key] = estimates(estimator, batches(k))[0]
        ratio[key] = energy[key] / (k * base)
        table[key] = quantiles(ratio[key])
    return {"energy": energy, "ratio": ratio, "table": table}


def default_photos() -> dict[str, np.ndarray]:
    r"""The real photos the exposure check uses by default: the colour photograph of a face among scikit-image's
    sample data.

    That is the astronaut (Eileen Collins, :func:`skimage.data.astronaut`). The cameraman
    (:func:`skimage.data.camera`) holds a face too, turned and in grey, which only ``"yunet"`` finds; it is left
    out, so that the check is the same with either detector. The other sample images hold none (or a cat's).

    Returns:
        ``{name: (H, W, 3) uint8 array}``.

    Examples:
        >>> photos = default_photos()
        >>> list(photos), photos["skimage.data.astronaut"].shape
        (['skimage.data.astronaut'], (512, 512, 3))
    """
    import skimage.data  # here: importing kornia_ilum_lab.evaluation stays cheap

    return {"skimage.data.astronaut": skimage.data.astronaut()}


def _photo_tensor(photo: Any) -> torch.Tensor:
    """A path, an ``(H, W[, C])`` array or a ``(3, H, W)`` float tensor -> ``(1, 3, H, W)`` float32."""
    if isinstance(photo, (str, os.PathLike)):
        return read_ldr(photo)[None]
    if isinstance(photo, np.ndarray):
        a = photo[..., None] if photo.ndim == 2 else photo
        if a.ndim != 3 or a.shape[2] not in (1, 3, 4):
            raise ShapeError(f"a photo array must be (H, W), (H, W, 1), (H, W, 3) or (H, W, 4), got "
                             f"{photo.shape}")
        if a.dtype in (np.uint8, np.uint16):
            x = a.astype(np.float32) / np.float32(np.iinfo(a.dtype).max)
        elif a.dtype in (np.float16, np.float32, np.float64):
            x = a.astype(np.float32)
        else:
            raise TypeCheckError(f"a photo array must be uint8, uint16 or float, got {a.dtype}")
        x = np.repeat(x, 3, axis=2) if x.shape[2] == 1 else x[..., :3]
        return torch.from_numpy(np.ascontiguousarray(x.transpose(2, 0, 1)))[None]
    if isinstance(photo, torch.Tensor):
        check_tensor(photo, "photo", ["3", "H", "W"])
        return photo.float()[None]
    raise TypeCheckError(f"a photo must be a path, a NumPy array or a (3, H, W) tensor, got "
                         f"{type(photo).__name__}")


def face_crops(photos: Mapping[str, Any] | Sequence[Any], detector: str | FaceDetector = DEFAULT_DETECTOR,
               size: int = 256) -> tuple[torch.Tensor, list[str], dict[str, str]]:
    r"""The face crops the estimators see of real photos, by the project's own detection and crop.

    As :func:`kornia_ilum.estimate_lighting` cuts them: the detector's largest face box, the square of
    :func:`~kornia_ilum.detection.square_crop_boxes` (the detector's ``crop_scale``) and
    :func:`~kornia_ilum.detection.crop_faces` (zero padding outside the photo, antialiased resize).

    Args:
        photos: ``{name: photo}`` or a sequence of photos (named by their path, else ``"photo <i>"``); a photo
            is a path that :func:`~kornia_ilum.io.read_ldr` reads, an ``(H, W[, C])`` uint8, uint16 or
            float array in ``[0, 1]`` (grey replicated, alpha dropped) or a ``(3, H, W)`` float tensor in
            ``[0, 1]``.
        detector: a registered detector name or a :class:`~kornia_ilum.detection.FaceDetector`.
        size: the crops' side.

    Returns:
        ``(crops, names, skipped)``: ``(M, 3, size, size)`` float32 sRGB crops, the name of each, and
        ``{name: reason}`` for the photos without a detected face.

    Raises:
        TypeCheckError: a photo or the detector of an unknown type.
        ShapeError: a photo array of a wrong shape.

    Shape:
        - Output: crops :math:`(M, 3, size, size)`, ``M`` the photos with a face

    Convention:
        sRGB in ``[0, 1]`` (docs/conventions.rst, "Images"); as a NumPy image, a photo array is channels-last RGB.

    Examples:
        >>> crops, names, skipped = face_crops([torch.rand(3, 40, 60)], "none", size=32)
        >>> tuple(crops.shape), names, skipped
        ((1, 3, 32, 32), ['photo 0'], {})
    """
    check_positive_int(size, "size")
    if isinstance(photos, Mapping):
        items = list(photos.items())
    else:
        items = [(os.fspath(p) if isinstance(p, (str, os.PathLike)) else f"photo {i}", p)
                 for i, p in enumerate(photos)]
    det = create_detector(detector) if isinstance(detector, str) else detector
    if not isinstance(det, FaceDetector):
        raise TypeCheckError(f"detector must be a name or a FaceDetector, got {type(detector).__name__}")
    detector_name = detector if isinstance(detector, str) else type(det).__name__
    crops, names, skipped = [], [], {}
    for name, photo in items:
        image = _photo_tensor(photo)
        found = det.detect(image)[0]
        if found.shape[0] == 0:
            skipped[name] = f"no face found by the detector {detector_name}"
            continue
        boxes = found[:, :4].float()
        area = (boxes[:, 2] - boxes[:, 0]) * (boxes[:, 3] - boxes[:, 1])
        box = square_crop_boxes(boxes[int(torch.argmax(area))][None], scale=det.crop_scale)
        crops.append(crop_faces(image, box, size=size).clamp(0.0, 1.0))  # resampling round-off
        names.append(name)
    out = torch.cat(crops) if crops else torch.zeros(0, 3, size, size)
    return out, names, skipped


# ----------------------------------------------------------------------------------------------
# crop


def jitter_boxes(nominal: torch.Tensor, jitters: int, *, height: int, width: int, position: float = 0.10,
                 extent: float = 0.15, generator: torch.Generator | None = None) -> torch.Tensor:
    r"""Square crops jittered around nominal boxes, as a face detector's boxes move.

    The side is ``side(nominal) * exp(U(-extent, extent))`` and the centre moves by ``U(-position, position)``
    times that side along each axis (:func:`~kornia_ilum_lab.synth.lightstage.portraits.face_crop_boxes`' jitter);
    a box that leaves the ``height x width`` image is shifted back inside it (and shrunk to it if larger), as
    the dataset keeps its crops inside the render.

    Args:
        nominal: ``(N, 4)`` square boxes ``(x0, y0, x1, y1)``.
        jitters: boxes per nominal box.
        height, width: the image the boxes are cut from.
        position: the largest centre shift, a fraction of the side.
        extent: the largest log-scale change of the side.
        generator: the random source (``None``: the global one).

    Returns:
        ``(N, jitters, 4)`` float64 boxes.

    Raises:
        ValueCheckError: a negative ``position`` or ``extent``.

    Shape:
        - nominal: :math:`(N, 4)`
        - Output: :math:`(N, jitters, 4)`

    Convention:
        Continuous pixel coordinates of the image, ``(0, 0)`` its top-left corner, x to the right and y down,
        as the boxes of :mod:`kornia_ilum.detection`.

    Examples:
        >>> boxes = jitter_boxes(torch.tensor([[64.0, 64.0, 192.0, 192.0]]), 4, height=256, width=256,
        ...                      generator=torch.Generator().manual_seed(0))
        >>> boxes.shape, bool(((boxes[..., 2] - boxes[..., 0]) <= 128 * math.exp(0.15) + 1e-9).all())
        (torch.Size([1, 4, 4]), True)
    """
    check_tensor(nominal, "nominal", ["N", "4"])
    check_positive_int(jitters, "jitters")
    if not (position >= 0 and extent >= 0):
        raise ValueCheckError(f"position and extent must be non-negative, got {position!r}, {extent!r}")
    b = nominal.double()
    u = torch.rand(len(b), jitters, 3, generator=generator, dtype=torch.float64) * 2.0 - 1.0
    side = (b[:, 2:3] - b[:, 0:1]) * torch.exp(extent * u[..., 0])
    cx = 0.5 * (b[:, 0:1] + b[:, 2:3]) + side * position * u[..., 1]
    cy = 0.5 * (b[:, 1:2] + b[:, 3:4]) + side * position * u[..., 2]
    side = side.clamp(max=min(height, width))
    x0 = (cx - side / 2).clamp(min=0.0).minimum(width - side)
    y0 = (cy - side / 2).clamp(min=0.0).minimum(height - side)
    return torch.stack([x0, y0, x0 + side, y0 + side], -1)


def crop_stability(
    estimator: Estimator,
    context_set: EvalSet,
    *,
    jitters: int = 8,
    position: float = 0.10,
    extent: float = 0.15,
    seed: int = 0,
    size: int = 256,
    batch_size: int = 32,
) -> dict[str, Any]:
    r"""The spread of the estimate over jittered crops of each portrait.

    For each portrait of ``context_set`` (:func:`~kornia_ilum_lab.evaluation.build_eval_set` with ``context``),
    ``jitters`` boxes around its nominal crop (:func:`jitter_boxes`, drawn from ``seed``: the same boxes for
    every estimator), each cut from the context crop and resampled to ``size`` (bilinear,
    :func:`~kornia_ilum_lab.synth.lightstage.portraits.crop_images`), and estimated. Per portrait: the standard
    deviation of the log energy (``std_log_energy``; unbiased), the ratio of the largest to the smallest
    energy (``max_min_ratio``) and the mean angle in degrees between each crop's :func:`dominant_direction`
    and the normalised mean of them (``angle_deg``; the crops whose lighting has no direction, such as a
    uniform one, are left out, and a portrait without any gets NaN, left out of the medians).

    Args:
        estimator: the estimator (module docstring).
        context_set: a set of context crops (its ``nominal_boxes`` set).
        jitters: crops per portrait (at least 2).
        position: the largest centre shift, a fraction of the side.
        extent: the largest log-scale change of the side.
        seed: the seed of the boxes.
        size: the crops' side (the estimators take 256).
        batch_size: crops per forward pass (whole portraits: at least ``jitters``).

    Returns:
        a dict: ``boxes`` ``(N, J, 4)``, ``energy`` ``(N, J)``, ``direction`` ``(N, J, 3)``,
        ``per_portrait`` (``{name: (N,)}``) and ``table`` (``{group: row}``): the groups are ``"all"`` and each
        skin tone; a row holds ``count`` and the medians over its portraits of the three measures.

    Raises:
        ValueCheckError: the set has no ``nominal_boxes``, ``jitters < 2``.

    Convention:
        Crops are sRGB (docs/conventions.rst, "Images"); energies and directions as :func:`lighting_energy` and
        :func:`dominant_direction` (docs/conventions.rst, "Frames", "Mirror ball" and "Units of lighting").

    Examples:
        An "estimator" that always sees one lamp above is perfectly stable:

        >>> from kornia_ilum_lab.evaluation import EvalSet
        >>> def lamp(crops):
        ...     ball = torch.zeros(len(crops), 3, 32, 32)
        ...     ball[..., 8, 16] = 100.0
        ...     return ball
        >>> context = EvalSet(torch.zeros(2, 3, 16, 16, dtype=torch.uint8), torch.ones(2, 3, 32, 32),
        ...                   ["indoor"] * 2, [3, 3], [0, 1], ["room"] * 2,
        ...                   nominal_boxes=torch.tensor([[4.0, 4.0, 12.0, 12.0]] * 2, dtype=torch.float64))
        >>> out = crop_stability(lamp, context, jitters=3, size=8)
        >>> row = out["table"]["all"]
        >>> tuple(out["boxes"].shape), row["count"], round(row["std_log_energy"], 6), round(row["angle_deg"], 3)
        ((2, 3, 4), 2, 0.0, 0.0)
    """
    if context_set.nominal_boxes is None:
        raise ValueCheckError("crop_stability needs a set of context crops: build_eval_set(..., context=1.5)")
    check_positive_int(jitters, "jitters")
    check_positive_int(size, "size")
    check_positive_int(batch_size, "batch_size")
    if jitters < 2:
        raise ValueCheckError(f"jitters must be at least 2 (a spread), got {jitters}")
    images = context_set.images
    n, (h, w) = len(images), images.shape[-2:]
    boxes = jitter_boxes(context_set.nominal_boxes, jitters, height=h, width=w, position=position,
                         extent=extent,
                         generator=torch.Generator().manual_seed(seed))
    per = max(1, batch_size // jitters)

    def batches() -> Iterator[torch.Tensor]:
        for i in range(0, n, per):
            x = as_floats(images[i : i + per]).repeat_interleave(jitters, 0)
            yield crop_images(x, boxes[i : i + per].reshape(-1, 4), size).clamp_(0.0, 1.0)

    flat_energy, flat_direction, _ = estimates(estimator, batches(), directions=True)
    energy = flat_energy.reshape(n, jitters)
    direction = flat_direction.reshape(n, jitters, 3)  # type: ignore[union-attr]
    log_e = torch.where(energy > 0, energy.clamp(min=1e-300).log(), torch.nan)
    has_dir = direction.norm(dim=-1) > 0.5  # unit, or zero where the lighting has no direction
    mean_dir = torch.nn.functional.normalize(direction.mean(1, keepdim=True), dim=-1)
    angle = torch.rad2deg(torch.acos((direction * mean_dir).sum(-1).clamp(-1.0, 1.0)))
    angle = torch.where(has_dir & (mean_dir.norm(dim=-1) > 0.5), angle, torch.nan).nanmean(1)
    per_portrait = {
        "std_log_energy": log_e.std(1),
        "max_min_ratio": energy.amax(1) / energy.amin(1),
        "angle_deg": angle,
    }
    table = {g: {"count": int(m.sum()), **{k: median_of(v[m]) for k, v in per_portrait.items()}}
             for g, m in _groups(context_set.skin_tone).items()}
    return {"boxes": boxes, "energy": energy, "direction": direction, "per_portrait": per_portrait,
            "table": table}


# ----------------------------------------------------------------------------------------------
# spread


def spread_calibration(estimator: Estimator, eval_set: EvalSet, *, batch_size: int = 32) -> dict[str, Any]:
    r"""Whether the estimator's spread of the log energy says how far its strength is off.

    For every sample, ``z = |log E_true - log E_pred| / b`` with ``b`` the estimate's
    :attr:`~kornia_ilum.estimators.LightingEstimate.log_energy_spread` (the scale of a Laplace distribution of
    the true log energy). A calibrated spread puts the truth within ``+-b`` for ``1 - 1/e`` (63.2 %) of the
    portraits and within ``+-2b`` for ``1 - 1/e^2`` (86.5 %) (:data:`SPREAD_NOMINAL`), in every skin tone:
    the share measured per tone, with its interval over subjects, against those.

    Args:
        estimator: the estimator (module docstring).
        eval_set: the eval set.
        batch_size: crops per forward pass.

    Returns:
        ``{"table": {group: row} or None, "reason": str}``: ``None`` (and why) for an estimator without a
        spread; a row holds ``count``, ``subjects``, the median ``b`` (``spread``), and for ``k`` = 1 and 2 the
        share ``within_k`` with its 95 % interval over subjects (``within_k_ci``) and the nominal share
        (``nominal_k``).

    Shape:
        - eval_set.images: :math:`(N, 3, H, W)`

    Convention:
        Energies as :func:`lighting_energy`, natural log (docs/conventions.rst, "Units of lighting").

    Examples:
        A spread of 1 for an estimate off by ``e^0.5`` for half the portraits and ``e^1.5`` for the others:

        >>> from kornia_ilum.estimators import LightingEstimate
        >>> from kornia_ilum_lab.evaluation import EvalSet
        >>> from kornia_ilum.geometry import mirror_ball_valid
        >>> valid = mirror_ball_valid(32)
        >>> def off(crops):
        ...     scale = torch.tensor([0.5, 1.5]).exp()[:, None, None, None]
        ...     return LightingEstimate(mirror_ball=torch.ones(2, 3, 32, 32) * valid * scale, valid=valid,
        ...                             log_energy_spread=torch.ones(2))
        >>> tiny = EvalSet(torch.zeros(2, 3, 8, 8, dtype=torch.uint8), torch.ones(2, 3, 32, 32) * valid,
        ...                ["indoor"] * 2, [3, 3], [0, 1], ["room"] * 2)
        >>> row = spread_calibration(off, tiny, batch_size=2)["table"]["all"]
        >>> row["within_1"], row["within_2"], round(row["nominal_1"], 3)
        (0.5, 1.0, 0.632)
    """
    check_positive_int(batch_size, "batch_size")
    images = eval_set.images
    batches = (as_floats(images[i : i + batch_size]) for i in range(0, len(images), batch_size))
    energy, _, b = estimates(estimator, batches, spreads=True)
    if b is None:
        return {"table": None, "reason": "the estimator gives no log_energy_spread"}
    z = (lighting_energy(eval_set.mirror_ball.double()).log() - energy.log()).abs() / b
    subjects = torch.tensor(list(eval_set.subject_seed))
    table = {}
    for g, m in _groups(eval_set.skin_tone).items():
        if not m.any():
            continue
        row: dict[str, Any] = {"count": int(m.sum()), "subjects": len(set(subjects[m].tolist())),
                               "spread": median_of(b[m])}
        for k, nominal in SPREAD_NOMINAL.items():
            inside = (z[m] <= k).double()
            row[f"within_{k}"] = float(inside.mean())
            row[f"within_{k}_ci"] = subject_interval(inside, subjects[m], statistic=torch.mean)
            row[f"nominal_{k}"] = nominal
        table[g] = row
    return {"table": table, "reason": ""}


# ----------------------------------------------------------------------------------------------
# all of them


def _check_names(checks: Sequence[str], *, context_set: EvalSet | None, flash: Any) -> None:
    unknown = [c for c in checks if c not in CHECKS]
    if unknown:
        raise ValueCheckError(f"unknown checks {unknown}; the checks are {', '.join(CHECKS)}")
    if "crop" in checks and context_set is None:
        raise ValueCheckError("the crop check needs context_set (build_eval_set(..., context=...))")
    if "flash" in checks and flash is None:
        raise ValueCheckError("the flash check needs flash: the real-flash photographs and their crops "
                              "(load_flash_set, flash_crops)")


#: The colour check on real-flash photographs takes every ``COLOUR_FLASH_STEP``-th of them (each person's
#: flashes spread over the sphere): seven looks on every photograph would cost seven real-flash checks.
COLOUR_FLASH_STEP = 4


def flash_checks(estimator: Estimator, flash: tuple[FlashSet, torch.Tensor, torch.Tensor], checks: Sequence[str],
                 *, batch_size: int = 32) -> dict[str, Any]:
    r"""The checks on real-flash photographs: ``"flash"`` (the real-flash check) and ``"colour"`` (the colour
    check on every :data:`COLOUR_FLASH_STEP`-th photograph).

    Args:
        estimator: the estimator.
        flash: the photographs, their crops and which fell back
            (:func:`~kornia_ilum_lab.evaluation.flash.load_flash_set`,
            :func:`~kornia_ilum_lab.evaluation.flash.flash_crops`).
        checks: ``"flash"`` and / or ``"colour"``.
        batch_size: crops per pass.

    Returns:
        ``{"flash": table, "colour": {"flash": table}}``, the checks asked for.
    """
    flash_set, crops, fell_back = flash
    out: dict[str, Any] = {}
    if "flash" in checks:
        out["flash"] = real_flash_check(estimator, flash_set, crops=crops, fell_back=fell_back,
                                        batch_size=batch_size)["table"]
    if "colour" in checks:
        step = slice(None, None, COLOUR_FLASH_STEP)
        out["colour"] = {"flash": colour_check(estimator, crops[step], subjects=flash_set.people[step],
                                               batch_size=batch_size)["table"]}
    return out


def run_checks(
    estimator: Estimator,
    eval_set: EvalSet,
    *,
    checks: Sequence[str] = CHECKS,
    context_set: EvalSet | None = None,
    photos: torch.Tensor | None = None,
    flash: tuple[FlashSet, torch.Tensor, torch.Tensor] | None = None,
    prediction: torch.Tensor | None = None,
    ks: Sequence[float] = EXPOSURE_FACTORS,
    jitters: int = 8,
    colour_samples: int | None = None,
    position: float = 0.10,
    extent: float = 0.15,
    seed: int = 0,
    batch_size: int = 32,
) -> dict[str, Any]:
    r"""The chosen checks for one estimator, as JSON-ready tables.

    Args:
        estimator: the estimator (module docstring).
        eval_set: the eval set (its crops and matte).
        checks: names of :data:`CHECKS`.
        context_set: the context crops for ``"crop"`` (required by it).
        photos: ``(M, 3, 256, 256)`` float crops of real photos (:func:`face_crops`) for ``"exposure"`` and
            ``"colour"``.
        flash: the real-flash photographs, their crops and which fell back
            (:func:`~kornia_ilum_lab.evaluation.flash.load_flash_set`,
            :func:`~kornia_ilum_lab.evaluation.flash.flash_crops`), for ``"flash"`` (required by it) and
            ``"colour"``.
        prediction: the estimator's lighting on ``eval_set.images``, if already made (saves two passes).
        colour_samples: the colour check runs on the first ``colour_samples`` eval portraits (``None``: all).
        ks, jitters, position, extent, seed, batch_size: the settings of the checks.

    Returns:
        a dict of the checks run, ``transfer`` (a table) and ``tone_spread``, ``exposure``
        (``{"eval": table, "photos": table}``, ``"photos"`` only with photos), ``crop`` (a table), ``spread``
        (``{"table", "reason"}``), ``colour`` (``{"eval": table, "photos": table, "flash": table}``, the last two
        where given), ``flash`` (a table) and ``seconds`` (``{name: float}``): the tables are the ``"table"`` of
        :func:`transfer_check`, :func:`exposure_equivariance`, :func:`crop_stability`,
        :func:`spread_calibration`, :func:`~kornia_ilum_lab.evaluation.colour.colour_check` and
        :func:`~kornia_ilum_lab.evaluation.flash.real_flash_check`.

    Raises:
        ValueCheckError: an unknown check, ``"crop"`` without ``context_set`` or ``"flash"`` without ``flash``.

    Shape:
        - photos: :math:`(M, 3, 256, 256)`; prediction: :math:`(N, 3, S, S)`

    Convention:
        As the checks: sRGB crops (docs/conventions.rst, "Images") and lighting in their units
        (docs/conventions.rst, "Units of lighting").

    Examples:
        >>> from kornia_ilum_lab.evaluation import probe_eval_set
        >>> from kornia_ilum.estimators import create_estimator
        >>> out = run_checks(create_estimator("uniform"), probe_eval_set(slice(64, 68)), checks=["exposure"])
        >>> sorted(out), sorted(out["exposure"]["eval"]), out["exposure"]["eval"]["0.5"]["count"]
        (['exposure', 'seconds'], ['0.25', '0.5'], 4)
    """
    _check_names(checks, context_set=context_set, flash=flash)
    out: dict[str, Any] = {}
    seconds: dict[str, float] = {}
    for name in (c for c in CHECKS if c in checks):
        t0 = time.perf_counter()
        if name == "transfer":
            transfer = transfer_check(estimator, eval_set, prediction=prediction, batch_size=batch_size)
            out[name] = transfer["table"]
            out["tone_spread"] = transfer["tone_spread"]
        elif name == "spread":
            out[name] = spread_calibration(estimator, eval_set, batch_size=batch_size)
        elif name == "exposure":
            on_eval = exposure_equivariance(estimator, eval_set.images, ks=ks, prediction=prediction,
                                            batch_size=batch_size)
            out[name] = {"eval": on_eval["table"]}
            if photos is not None and len(photos):
                on_photos = exposure_equivariance(estimator, photos, ks=ks, batch_size=batch_size)
                out[name]["photos"] = on_photos["table"]
        elif name == "colour":
            first = slice(None, colour_samples)
            out[name] = {"eval": colour_check(estimator, eval_set.images[first],
                                              subjects=list(eval_set.subject_seed)[first],
                                              prediction=None if prediction is None else prediction[first],
                                              batch_size=batch_size)["table"]}
            if photos is not None and len(photos):
                out[name]["photos"] = colour_check(estimator, photos, batch_size=batch_size)["table"]
            if flash is not None:
                out[name].update(flash_checks(estimator, flash, ["colour"], batch_size=batch_size)["colour"])
        elif name == "flash" and flash is not None:  # with its photographs (checked above)
            out[name] = flash_checks(estimator, flash, ["flash"], batch_size=batch_size)["flash"]
        elif context_set is not None:  # "crop", with its set (checked above)
            out[name] = crop_stability(estimator, context_set, jitters=jitters, position=position,
                                       extent=extent, seed=seed,
                                       batch_size=batch_size)["table"]
        seconds[name] = round(time.perf_counter() - t0, 2)
    out["seconds"] = seconds
    return out


def check_runner(eval_set: EvalSet, checks: Sequence[str] = CHECKS, **options: Any
                 ) -> Callable[[Estimator, torch.Tensor], dict[str, Any]]:
    r"""The ``checks`` argument of :func:`~kornia_ilum_lab.evaluation.evaluate`: :func:`run_checks` on
    ``eval_set`` for each scored estimator, reusing its lighting on the eval crops (``prediction``).

    Args:
        eval_set: the eval set that is scored.
        checks: names of :data:`CHECKS`.
        **options: the keyword arguments of :func:`run_checks` (``context_set``, ``photos``, ``flash``,
            ``colour_samples``, ``ks``,
            ``jitters``, ``position``, ``extent``, ``seed``, ``batch_size``).

    Returns:
        ``checks(estimator, prediction)``: :func:`run_checks`'s tables for ``estimator``, whose lighting on
        ``eval_set.images`` is ``prediction``.

    Raises:
        ValueCheckError: an unknown check, ``"crop"`` without ``context_set`` or with ``jitters`` below 2, or
            ``"flash"`` without ``flash`` (at once, before any estimator runs).

    Shape:
        - prediction (of the returned callable): :math:`(N, 3, S, S)`, ``N = len(eval_set)``

    Convention:
        As :func:`run_checks` (docs/conventions.rst, "Images" and "Units of lighting").

    Examples:
        >>> from kornia_ilum_lab.evaluation import predict, probe_eval_set
        >>> from kornia_ilum.estimators import create_estimator
        >>> eval_set, net = probe_eval_set(slice(64, 68)), create_estimator("uniform")
        >>> runner = check_runner(eval_set, ["exposure"], ks=[0.5])
        >>> sorted(runner(net, predict(net, eval_set.images))["exposure"]["eval"])
        ['0.5']
        >>> check_runner(eval_set, ["crop"])
        Traceback (most recent call last):
        ...
        kornia.core.exceptions.ValueCheckError: the crop check needs context_set (build_eval_set(..., context=...))
    """
    _check_names(checks, context_set=options.get("context_set"), flash=options.get("flash"))
    if "crop" in checks and options.get("jitters", 8) < 2:
        raise ValueCheckError(f"jitters must be at least 2 (a spread), got {options['jitters']}")
    names = list(checks)

    def run(estimator: Estimator, prediction: torch.Tensor) -> dict[str, Any]:
        return run_checks(estimator, eval_set, checks=names, prediction=prediction, **options)

    return run
