r"""The estimator contract: one ``forward(crops) -> LightingEstimate`` for every lighting estimator.

A lighting estimator is an :class:`torch.nn.Module` that maps face crops to HDR lighting. All of them
share one call signature and one typed result (as pytorch3d's light types do), so call sites never branch
on the method:

- :class:`LightingEstimate`: the result, a mirror ball in the units of the photograph, with the methods
  that use it (lat-long, sphere renders, ``.exr``/``.hdr`` files, a preview PNG).
- :class:`EstimatorInfo` and :class:`WeightFile`: the metadata of an estimator (description, paper, input
  size, weight files with their SHA-256), as timm's pretrained configs.
- :class:`LightingEstimator`: the base class. :meth:`LightingEstimator.forward` checks the crops and
  calls :meth:`LightingEstimator.predict`, which subclasses implement. Pretrained weights load only
  through :meth:`LightingEstimator.from_pretrained`, which checks each file's SHA-256 and reads it with
  :func:`safetensors.torch.load_file` (never by unpickling); a constructor never touches weight files.
- :func:`read_weights`: that SHA-256-checked read, the one path every weight file takes (also a
  user's checkpoint, whose digest it returns).

Convention:
    Crops are ``(B, 3, S, S)`` sRGB-encoded in ``[0, 1]`` (docs/conventions.rst, "Images") with ``S`` the
    estimator's ``info.input_size`` (256 for the paper's crops). Lighting is a linear mirror ball in
    radiance, in the units of the input image (docs/conventions.rst, "Mirror ball" and "Units of
    lighting"), 0 outside the ball. ``log_mirror_ball``, where an estimator has it, is ``log(1 + L)``
    (natural log) for every estimator, so ``mirror_ball == expm1(log_mirror_ball)``.
"""

from __future__ import annotations

import inspect
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Self

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from kornia_ilum.color import linear_to_srgb
from kornia_ilum.core.check import check_positive_int, check_tensor, checks_active
from kornia_ilum.core.errors import (
    MissingWeightsError,
    NonFiniteError,
    ShapeError,
    TypeCheckError,
    ValueCheckError,
    WeightsChecksumError,
)
from kornia_ilum.core.files import sha256_file
from kornia_ilum.geometry import mirror_ball_to_latlong, mirror_ball_valid
from kornia_ilum.io import write_hdr, write_ldr
from kornia_ilum.render import PREVIEW_SUPERSAMPLES, SPHERE_SIZES, render_spheres
from kornia_ilum.sh import DOMINANT_MAX_ANGLE, DOMINANT_THRESHOLD, DominantLight, dominant_light

__all__ = [
    "LightingEstimate",
    "WeightFile",
    "EstimatorInfo",
    "LightingEstimator",
    "check_crops",
    "check_crop_range",
    "adopt_spread_head",
    "read_weights",
    "PREVIEW_BRDFS",
    "CROP_RANGE_SLACK",
]

#: The spheres of :meth:`LightingEstimate.preview`, left to right.
PREVIEW_BRDFS: tuple[str, ...] = ("diffuse", "matte_silver", "mirror")
#: Crop values may exceed ``[0, 1]`` by this much (round-off of antialiased resampling) without an error.
CROP_RANGE_SLACK = 1e-3

_HDR_SUFFIXES = (".exr", ".hdr")
_LDR_SUFFIXES = (".png", ".jpg", ".jpeg")
_PREVIEW_PERCENTILE = 0.99  # of the diffuse sphere's linear values ...
_PREVIEW_TARGET = 0.9  # ... mapped to this linear display value before the sRGB encoding
_SHA256 = re.compile(r"[0-9a-f]{64}")


def _check_index(index: int, batch: int) -> int:
    if isinstance(index, bool) or not isinstance(index, int):
        raise TypeCheckError(f"index must be an int, got {type(index).__name__}")
    if not -batch <= index < batch:
        raise ValueCheckError(
            f"index must be in [{-batch}, {batch}) for an estimate of {batch} lightings, got {index}"
        )
    return index % batch


def _check_suffix(path: Path, allowed: tuple[str, ...], what: str) -> None:
    if path.suffix.lower() not in allowed:
        raise ValueCheckError(
            f"cannot write {what} to {path}: the file name must end in {' or '.join(allowed)}, "
            f"got {path.suffix!r}"
        )


@dataclass(eq=False)
class LightingEstimate:
    r"""Lighting estimated from face crops: HDR mirror balls plus what an estimator or the API adds.

    Args:
        mirror_ball: linear HDR lighting in radiance, in the units of the input image, 0 outside the ball.
        valid: the pixels on the ball (:func:`~kornia_ilum.geometry.mirror_ball_valid`).
        log_mirror_ball: ``log(1 + mirror_ball)`` (natural log), 0 outside the ball, where the estimator
            predicts log-HDR.
        sh: order-2 real SH coefficients of the lighting (the order of docs/conventions.rst), where the
            estimator has them.
        boxes: face boxes ``x0, y0, x1, y1`` in input-image pixels, filled by
            :func:`kornia_ilum.estimate_lighting`.
        image_index: which input image each lighting belongs to, filled by
            :func:`kornia_ilum.estimate_lighting`.
        log_energy_spread: how far the strength of each lighting may be off, where the estimator knows it:
            the scale ``b`` of a Laplace distribution of the true lighting's log energy (natural log of
            :func:`~kornia_ilum.metrics.total_radiance` averaged over R, G, B) around the estimate's. The truth
            lies within ``exp(+-b)`` times the estimate's energy with probability ``1 - 1/e`` (63.2 %), within
            ``exp(+-2b)`` with 86.5 %; a face that cannot settle the light's strength (a dark skin of unknown
            albedo, a crop that hides the face) gets a larger ``b``. ``None`` for estimators without it.
        scene_share: how much of the strength the whole photo set, where a scene branch was used
            (:func:`~kornia_ilum.estimators.fuse_strength`): the scene's share of the inverse-variance weight,
            0 (the face alone) to 1 (the scene alone). ``None`` without a scene branch.

    Shape:
        - mirror_ball, log_mirror_ball: :math:`(B, 3, S, S)`, ``S = 32`` for every estimator so far
        - valid: :math:`(S, S)` bool
        - sh: :math:`(B, 9, 3)`; boxes: :math:`(B, 4)`; image_index: :math:`(B,)` int64
        - log_energy_spread, scene_share: :math:`(B,)`

    Raises:
        ShapeError, TypeCheckError: on construction, when a field has the wrong shape or dtype.

    Convention:
        docs/conventions.rst, "Mirror ball" (frame, equal-area mapping) and "Units of lighting".
        ``len(estimate)`` is ``B``; ``index`` arguments select one lighting of the batch. Estimates compare
        by identity (``eq=False``: tensors have no single truth value) and print their fields' shapes, not
        values.

    Examples:
        >>> from kornia_ilum.geometry import mirror_ball_valid
        >>> valid = mirror_ball_valid(32)
        >>> est = LightingEstimate(mirror_ball=torch.ones(2, 3, 32, 32) * valid, valid=valid)
        >>> len(est), tuple(est.to_latlong(16).shape)
        (2, (2, 3, 16, 32))
        >>> est  # doctest: +NORMALIZE_WHITESPACE
        LightingEstimate(mirror_ball=<(2, 3, 32, 32) float32 cpu>, valid=<(32, 32) bool cpu>,
                         log_mirror_ball=None, sh=None, boxes=None, image_index=None, log_energy_spread=None,
                         scene_share=None)
        >>> round(est.render_spheres(16)["diffuse"][0, 0, 8, 8].item(), 3)  # albedo 0.8 under L = 1
        0.8
    """

    mirror_ball: Tensor
    valid: Tensor
    log_mirror_ball: Tensor | None = None
    sh: Tensor | None = None
    boxes: Tensor | None = None
    image_index: Tensor | None = None
    log_energy_spread: Tensor | None = None
    scene_share: Tensor | None = None

    def __post_init__(self) -> None:
        check_tensor(self.mirror_ball, "mirror_ball", ["B", "3", "S", "S"], finite=False)
        # sizes are 0-d tensors under torch.jit.trace, symbols under torch.export (kept: int() would fix them)
        batch, _, height, width = (int(d) if isinstance(d, Tensor) else d for d in self.mirror_ball.shape)
        if height != width:
            raise ShapeError(f"mirror_ball must be square (B, 3, S, S), got {tuple(self.mirror_ball.shape)}")
        check_tensor(self.valid, "valid", [str(height), str(width)], floating=False, finite=False)
        if self.valid.dtype != torch.bool:
            raise TypeCheckError(f"valid must be a bool tensor, got dtype {self.valid.dtype}")
        if self.log_mirror_ball is not None:
            check_tensor(
                self.log_mirror_ball,
                "log_mirror_ball",
                [str(batch), "3", str(height), str(width)],
                finite=False,
            )
        if self.sh is not None:
            check_tensor(self.sh, "sh", [str(batch), "9", "3"], finite=False)
        if self.boxes is not None:
            check_tensor(self.boxes, "boxes", [str(batch), "4"], finite=False)
        if self.image_index is not None:
            check_tensor(self.image_index, "image_index", [str(batch)], floating=False, finite=False)
        for name in ("log_energy_spread", "scene_share"):
            if getattr(self, name) is not None:
                check_tensor(getattr(self, name), name, [str(batch)], finite=False)

    def __len__(self) -> int:
        return self.mirror_ball.shape[0]

    def __repr__(self) -> str:
        def describe(t: Tensor | None) -> str:
            return (
                "None"
                if t is None
                else f"<{tuple(t.shape)} {str(t.dtype).removeprefix('torch.')} {t.device}>"
            )

        names = ("mirror_ball", "valid", "log_mirror_ball", "sh", "boxes", "image_index", "log_energy_spread",
                 "scene_share")
        return f"LightingEstimate({', '.join(f'{n}={describe(getattr(self, n))}' for n in names)})"

    def to_latlong(self, height: int = 64) -> Tensor:
        r"""The lighting as ``H x 2H`` lat-long maps (:func:`~kornia_ilum.geometry.mirror_ball_to_latlong`).

        Args:
            height: the maps' height ``H``.

        Returns:
            linear lat-long maps :math:`(B, 3, H, 2H)`, dtype and device of ``mirror_ball``.
        """
        return mirror_ball_to_latlong(self.mirror_ball, height)

    def dominant_light(self, *, threshold: float = DOMINANT_THRESHOLD,
                       max_angle: float = DOMINANT_MAX_ANGLE) -> DominantLight:
        r"""The main light (direction, solid angle, colour, intensity) and the order-2 SH of the rest, the
        shape of ARCore's Environmental HDR (:func:`~kornia_ilum.sh.dominant_light`).

        Args:
            threshold: the light's pixels reach at least this fraction of its brightest pixel's luminance.
            max_angle: the light's largest angular radius in degrees.

        Returns:
            a :class:`~kornia_ilum.sh.DominantLight` per lighting, in the units of the photograph;
            ``.to_dict(i)`` gives lighting ``i`` as plain numbers (``kornia-ilum estimate`` writes it as JSON
            beside the ``.exr``).

        Examples:
            >>> ball = torch.zeros(1, 3, 32, 32)
            >>> ball[0, :, 8, 16] = 1000.0
            >>> estimate = LightingEstimate(mirror_ball=ball, valid=mirror_ball_valid(32))
            >>> bool(estimate.dominant_light().direction[0, 1] > 0.8)  # from above
            True
        """
        return dominant_light(self.mirror_ball, threshold=threshold, max_angle=max_angle)

    def render_spheres(self, size: int = 32) -> dict[str, Tensor]:
        r"""The three reference spheres lit by the estimate (:func:`~kornia_ilum.render.render_spheres`).

        Args:
            size: side of the sphere renders, one of :data:`~kornia_ilum.render.SPHERE_SIZES`.

        Returns:
            ``{"diffuse", "matte_silver", "mirror"}`` -> linear renders :math:`(B, 3, size, size)`.
        """
        return render_spheres(self.mirror_ball, size)

    def save(
        self,
        path: str | os.PathLike[str],
        *,
        index: int = 0,
        latlong_height: int | None = None,
        half: bool = False,
    ) -> Path:
        r"""Write one lighting as a linear HDR file, atomically (:func:`~kornia_ilum.io.write_hdr`).

        Args:
            path: destination; ``.exr`` (OpenEXR, ZIP-compressed) or ``.hdr`` (Radiance RGBE).
            index: which lighting of the batch.
            latlong_height: write an ``H x 2H`` lat-long map of this height instead of the mirror ball.
            half: ``.exr`` only: store half floats.

        Returns:
            ``path`` as a :class:`~pathlib.Path`.

        Raises:
            ValueCheckError: the suffix is neither ``.exr`` nor ``.hdr`` (the message names the path),
                ``index`` is out of range, or ``half=True`` for ``.hdr``.
            HDRIOError: the folder is missing or the write fails; nothing is left at ``path`` then (an
                existing file there stays as it was).

        Convention:
            The file holds the estimate in the units of the input photograph (docs/conventions.rst,
            "Units of lighting"). The mirror ball is ``S x S`` with 0 outside the ball
            (docs/conventions.rst, "Mirror ball"); the lat-long map follows docs/conventions.rst,
            "Lat-long" (centre column = forward, -Z).
        """
        path = Path(os.fspath(path))
        _check_suffix(path, _HDR_SUFFIXES, "HDR lighting")
        i = _check_index(index, len(self))
        if latlong_height is None:
            image = self.mirror_ball[i]
        else:
            image = mirror_ball_to_latlong(self.mirror_ball[i : i + 1], latlong_height)[0]
        write_hdr(path, image.detach(), half=half)
        return path

    def preview(self, path: str | os.PathLike[str], *, index: int = 0, size: int = 128) -> Path:
        r"""Write the three reference spheres side by side as an 8-bit PNG (or JPEG), atomically.

        Left to right: diffuse, matte silver, mirror (docs/conventions.rst, "Reference spheres"), each
        ``size x size`` on black. One exposure for all three maps the 99th percentile of the diffuse
        sphere's linear values to 0.9; values are then clipped to ``[0, 1]`` and sRGB-encoded. Spheres are
        rendered at the nearest supported render size (:data:`~kornia_ilum.render.SPHERE_SIZES`) but at most
        the lighting's own (32: a larger mirror sphere only repeats its pixels), with the picture's
        quadrature (:data:`~kornia_ilum.render.PREVIEW_SUPERSAMPLES`, within 2 % of the metrics' renders), and
        resized bilinearly to ``size`` when it is not the render size; rendering runs in float32. Most of the
        first preview of a process is building those fields once (docs/bench.rst, "The preview").

        Args:
            path: destination, ``.png`` (or ``.jpg``/``.jpeg``).
            index: which lighting of the batch.
            size: side of each sphere in pixels.

        Returns:
            ``path`` as a :class:`~pathlib.Path`; the image is ``3 * size`` wide and ``size`` high.

        Raises:
            ValueCheckError: a suffix other than ``.png``, ``.jpg``, ``.jpeg``, or ``index`` out of range.
            HDRIOError: the folder is missing or the write fails; nothing is left at ``path`` then.
        """
        path = Path(os.fspath(path))
        _check_suffix(path, _LDR_SUFFIXES, "a preview")
        check_positive_int(size, "size")
        i = _check_index(index, len(self))
        lighting = self.mirror_ball[i : i + 1].detach().to(torch.float32)
        render_size = min(next((s for s in SPHERE_SIZES if s >= size), SPHERE_SIZES[-1]), lighting.shape[-1])
        spheres = render_spheres(lighting, render_size, PREVIEW_BRDFS, supersamples=PREVIEW_SUPERSAMPLES)
        disk = mirror_ball_valid(size, device=lighting.device)
        panels = []
        for name in PREVIEW_BRDFS:
            sphere = spheres[name]
            if render_size != size:
                sphere = F.interpolate(
                    sphere,
                    size=(size, size),
                    mode="bilinear",
                    align_corners=False,
                    antialias=size < render_size,
                )
            panels.append(sphere[0].clamp(min=0.0) * disk)
        diffuse = panels[0][:, disk]
        level = (
            torch.quantile(diffuse.flatten(), _PREVIEW_PERCENTILE)
            if diffuse.numel()
            else diffuse.new_zeros(())
        )
        exposure = _PREVIEW_TARGET / level if float(level) > 0 else torch.ones_like(level)
        image = torch.cat(panels, dim=-1) * exposure
        write_ldr(path, linear_to_srgb(image.clamp(0.0, 1.0)).clamp(0.0, 1.0))
        return path


# a pytree node: torch.export and torch.onnx.export(dynamo=True) take an estimator itself, its result flattened
torch.export.register_dataclass(LightingEstimate, serialized_type_name="kornia_ilum.LightingEstimate")


@dataclass(frozen=True)
class WeightFile:
    r"""One pretrained weight file of an estimator: a ``.safetensors`` file and its SHA-256.

    Args:
        name: the file name inside the weights folder (no folders in it).
        sha256: the file's SHA-256 digest, 64 lowercase hex digits.

    Raises:
        ValueCheckError: ``name`` holds a path separator or is empty, or ``sha256`` is not 64 hex digits.

    Examples:
        >>> WeightFile("ours.safetensors", "0" * 64).name
        'ours.safetensors'
    """

    name: str
    sha256: str

    def __post_init__(self) -> None:
        if not self.name or Path(self.name).name != self.name or self.name in (".", ".."):
            raise ValueCheckError(f"WeightFile.name must be a plain file name, got {self.name!r}")
        if not _SHA256.fullmatch(self.sha256):
            raise ValueCheckError(f"WeightFile.sha256 must be 64 lowercase hex digits, got {self.sha256!r}")


@dataclass(frozen=True)
class EstimatorInfo:
    r"""Metadata of an estimator, readable without building it (timm's pretrained config, reduced).

    Args:
        name: the registry name.
        description: one line on what the estimator does.
        paper: the citation of the method, or why there is none.
        input_size: side of the square sRGB face crops that ``forward`` takes.
        weights: the pretrained weight files, loaded by :meth:`LightingEstimator.from_pretrained`.
        install_hint: how to install the estimator or obtain its weights (shown in error messages).
        needs_weights: ``False`` for estimators without trained parameters (such as ``uniform``):
            ``pretrained=True`` then builds them as they are. ``True`` (the default) with ``weights=()``
            means trained weights are not shipped yet.

    Examples:
        >>> info = EstimatorInfo("toy", "a toy", "none", needs_weights=False)
        >>> info.pretrained_available
        True
    """

    name: str
    description: str
    paper: str
    input_size: int = 256
    weights: tuple[WeightFile, ...] = ()
    install_hint: str = ""
    needs_weights: bool = True

    @property
    def pretrained_available(self) -> bool:
        """Whether ``create_estimator(name, pretrained=True)`` can work: weights shipped or none needed."""
        return bool(self.weights) or not self.needs_weights


def check_crops(crops: Tensor, size: int = 256, *, values: bool = True) -> None:
    r"""Check estimator input: ``(B, 3, size, size)`` floating sRGB values in ``[0, 1]``.

    Values may exceed the range by :data:`CROP_RANGE_SLACK` (resampling round-off). The value checks
    (NaN/Inf, range) follow :func:`~kornia_ilum.core.check_tensor`: they honour Kornia's global switch and
    are skipped while :func:`torch.compile` traces.

    Args:
        crops: the face crops.
        size: the side the estimator takes.
        values: scan the values (NaN/Inf, range); ``False`` checks only the type and shape.

    Returns:
        None; the crops are valid when nothing is raised.

    Raises:
        TypeCheckError: ``crops`` is no tensor or not floating point (for ``uint8`` images divide by 255).
        ShapeError: the shape is not ``(B, 3, size, size)``.
        EmptyTensorError: ``B == 0``.
        NonFiniteError: NaN or Inf.
        ValueCheckError: values outside ``[0, 1]``.

    Shape:
        - crops: :math:`(B, 3, size, size)`, ``B >= 1``

    Convention:
        sRGB-encoded values in ``[0, 1]`` (docs/conventions.rst, "Images").

    Examples:
        >>> check_crops(torch.rand(2, 3, 256, 256))
        >>> check_crops(torch.rand(2, 3, 128, 128))
        Traceback (most recent call last):
        ...
        kornia.core.exceptions.ShapeError: crops must have shape (B, 3, 256, 256), got (2, 3, 128, 128)
    """
    if isinstance(crops, Tensor) and not crops.is_floating_point() and checks_active():
        raise TypeCheckError(
            f"crops must be a floating-point tensor of sRGB values in [0, 1], got dtype {crops.dtype}; "
            "convert 8-bit images with image.float() / 255"
        )
    check_tensor(crops, "crops", ["B", "3", str(size), str(size)], finite=False)
    if (not values or not checks_active() or torch.compiler.is_compiling() or torch.jit.is_tracing()
            or crops.is_meta):
        return
    lo, hi = (float(v) for v in torch.aminmax(crops.detach()))  # one pass; NaN propagates into both
    check_crop_range(lo, hi)


def check_crop_range(lo: float, hi: float) -> None:
    r"""The value half of :func:`check_crops`, on the crops' smallest and largest value (NaN where any is).

    Args:
        lo: the crops' smallest value.
        hi: the crops' largest value.

    Returns:
        None; the range is valid when nothing is raised.

    Raises:
        NonFiniteError: NaN or Inf.
        ValueCheckError: values outside ``[0, 1]`` by more than :data:`CROP_RANGE_SLACK`.

    Convention:
        sRGB-encoded values in ``[0, 1]`` (docs/conventions.rst, "Images").

    Examples:
        >>> check_crop_range(0.0, 1.0)
        >>> check_crop_range(0.0, 255.0)  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        kornia.core.exceptions.ValueCheckError: crops must be sRGB-encoded values in [0, 1], got min 0 and max 255; ...
    """
    if lo != lo or hi != hi or abs(lo) == float("inf") or abs(hi) == float("inf"):
        raise NonFiniteError("crops must be finite, but they hold NaN or Inf")
    if lo < -CROP_RANGE_SLACK or hi > 1.0 + CROP_RANGE_SLACK:
        raise ValueCheckError(
            f"crops must be sRGB-encoded values in [0, 1], got min {lo:g} and max {hi:g}; "
            "divide 8-bit images by 255"
        )


class LightingEstimator(nn.Module):
    r"""Base class of lighting estimators: ``forward(crops) -> LightingEstimate``.

    Subclasses set the class attribute :attr:`info` (:class:`EstimatorInfo`) and implement
    :meth:`predict`; :meth:`forward` checks the crops (:func:`check_crops`) and calls it. They register
    under the entry-point group ``kornia_ilum.estimators`` (see :mod:`kornia_ilum.estimators.registry`).

    Pretrained weights load only through :meth:`from_pretrained`; ``__init__`` builds an untrained
    (or, for estimators without trained parameters, the only) model and never reads files.

    Convention:
        Crops are ``(B, 3, S, S)`` sRGB in ``[0, 1]``, ``S = info.input_size``; the result's lighting is
        in the units of the input image (docs/conventions.rst, "Units of lighting").

    Examples:
        >>> from kornia_ilum.geometry import mirror_ball_valid
        >>> class Grey(LightingEstimator):
        ...     info = EstimatorInfo("grey", "constant grey", "none: an example", needs_weights=False)
        ...     def predict(self, crops):
        ...         valid = mirror_ball_valid(32, device=crops.device)
        ...         return LightingEstimate(crops.new_ones(len(crops), 3, 32, 32) * valid, valid)
        >>> est = Grey.from_pretrained()(torch.rand(2, 3, 256, 256))
        >>> len(est), est.mirror_ball.amax().item()
        (2, 1.0)
    """

    info: ClassVar[EstimatorInfo]
    #: What computes the estimate (:data:`~kornia_ilum.estimators.runtime.RUNTIMES`); the runtimes' wrappers
    #: set their own.
    runtime: str = "eager"

    def forward(self, crops: Tensor, *, check_values: bool = True) -> LightingEstimate:
        r"""Estimate lighting from face crops.

        Args:
            crops: sRGB face crops in ``[0, 1]``, the square of side ``info.input_size`` around each face
                (1.25 x the face box, LeGendre et al. 2020).
            check_values: scan the crops' values (NaN/Inf, range). ``False`` is for a caller whose crops
                are cut from an image it has checked already (:func:`kornia_ilum.estimate_lighting`); the
                type and shape are checked either way.

        Returns:
            a :class:`LightingEstimate` with ``mirror_ball`` :math:`(B, 3, 32, 32)` and ``valid``, plus
            ``log_mirror_ball`` / ``sh`` where the estimator has them.

        Raises:
            TypeCheckError, ShapeError, EmptyTensorError, NonFiniteError, ValueCheckError: see
                :func:`check_crops`.
        """
        check_crops(crops, self.info.input_size, values=check_values)
        return self.predict(crops)

    def predict(self, crops: Tensor) -> LightingEstimate:
        """The estimate for checked crops; subclasses implement it (call the module, not this)."""
        raise NotImplementedError(f"{type(self).__name__} must implement predict(crops)")

    @classmethod
    def default_weights_dir(cls) -> Path:
        """The folder searched for weight files: ``weights/`` beside the module that defines the class."""
        return Path(inspect.getfile(cls)).resolve().parent / "weights"

    @classmethod
    def from_pretrained(cls, weights_dir: str | os.PathLike[str] | None = None, **kw: Any) -> Self:
        r"""Build ``cls(**kw)`` and load its weight files, each checked against its SHA-256 first.

        Files are checked and read by :func:`read_weights` (:func:`safetensors.torch.load_file`: no pickle,
        no code execution) onto the CPU, merged, and loaded with ``load_state_dict(strict=True)``. The
        model is returned in ``eval()`` mode. Estimators with ``info.needs_weights == False`` are built as
        they are.

        Args:
            weights_dir: folder holding the files named in ``info.weights``; by default
                :meth:`default_weights_dir` (the package data of the estimator's module).
            **kw: constructor arguments.

        Returns:
            the estimator with its pretrained weights.

        Raises:
            MissingWeightsError: the estimator ships no trained weights yet, or a file is missing (the
                message names the file and folder).
            WeightsChecksumError: a file's SHA-256 differs from the declared one (the message names the
                file and both digests); nothing is loaded.
        """
        info = cls.info
        if not info.weights:
            if not info.needs_weights:
                return cls(**kw).eval()
            raise MissingWeightsError(_no_weights_message(info))
        folder = Path(os.fspath(weights_dir)) if weights_dir is not None else cls.default_weights_dir()
        state: dict[str, Tensor] = {}
        for weight in info.weights:
            path = folder / weight.name
            if not path.is_file():
                hint = f"; {info.install_hint}" if info.install_hint else ""
                raise MissingWeightsError(
                    f"weight file {weight.name!r} of estimator '{info.name}' not found in {folder}{hint}"
                )
            tensors, _ = read_weights(path, weight.sha256, expected_by=f"estimator '{info.name}'")
            clash = sorted(state.keys() & tensors.keys())
            if clash:
                raise ValueCheckError(
                    f"{path}: tensors {clash[:5]} also appear in an earlier weight file of '{info.name}'"
                )
            state.update(tensors)
        model = cls(**kw)
        model.load_state_dict(state, strict=True)
        return model.eval()


def read_weights(
    path: str | os.PathLike[str], sha256: str | None = None, *, expected_by: str = "the caller"
) -> tuple[dict[str, Tensor], str]:
    r"""Read a ``.safetensors`` weight file onto the CPU after checking its SHA-256: the one way weights load.

    :meth:`LightingEstimator.from_pretrained` reads every shipped file through it, and so does
    :func:`kornia_ilum_lab.evaluation.load_estimator` for a checkpoint given by the user. The file is read
    with :func:`safetensors.torch.load_file` (no pickle, no code execution), never with :func:`torch.load`.

    Args:
        path: the weight file.
        sha256: the digest the file must have (64 lowercase hex digits); ``None`` for a file whose digest
            is not known in advance (a training run's output): it is computed and returned, so that the
            caller can record which file it scored.
        expected_by: who declares ``sha256``, for the error message (e.g. ``"estimator 'ours'"``).

    Returns:
        ``(tensors, digest)``: the file's tensors by name, on the CPU, and its SHA-256.

    Raises:
        WeightsChecksumError: the file's SHA-256 is not ``sha256`` (the message names the file and both
            digests); nothing is read.
        OSError: the file cannot be read.

    Examples:
        >>> import tempfile, safetensors.torch
        >>> from kornia_ilum.core.files import sha256_file
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     path = Path(tmp) / "w.safetensors"
        ...     safetensors.torch.save_file({"w": torch.ones(2)}, str(path))
        ...     tensors, digest = read_weights(path)
        ...     checked, _ = read_weights(path, sha256_file(path))
        >>> tensors["w"].tolist(), len(digest), torch.equal(checked["w"], tensors["w"])
        ([1.0, 1.0], 64, True)
    """
    import safetensors.torch  # lazy: a weight file is read only when asked for

    digest = sha256_file(path)
    if sha256 is not None and digest != sha256:
        raise WeightsChecksumError(
            f"{path}: SHA-256 is {digest}, but {expected_by} expects {sha256}; "
            "the file is corrupt, truncated or from another release, and was not loaded"
        )
    return safetensors.torch.load_file(path, device="cpu"), digest


def _no_weights_message(info: EstimatorInfo) -> str:
    return (f"'{info.name}' ships no trained weights yet; pass pretrained=False for an untrained model "
            "(kornia_ilum.estimators.create_estimator names the registered estimators that ship weights)")


def adopt_spread_head(module: nn.Module, state_dict: dict[str, Any], prefix: str, in_features: int) -> None:
    """Match ``module.spread`` (an ``nn.Linear(in_features, 1)`` or ``None``) to a state dict about to be loaded.

    For an estimator's ``_load_from_state_dict``: a file with the spread head gives the module one (so that
    ``load_state_dict(strict=True)`` fills it); a file that predates the head keeps the module's own (its entries
    are added to ``state_dict`` as they are). See :attr:`LightingEstimate.log_energy_spread`.

    Args:
        module: the estimator, with a ``spread`` attribute.
        state_dict: the state dict being loaded (changed in place).
        prefix: the module's prefix in it.
        in_features: the head's input size.

    Examples:
        >>> m = nn.Module()
        >>> m.spread = None
        >>> adopt_spread_head(m, {"spread.weight": torch.zeros(1, 4), "spread.bias": torch.zeros(1)}, "", 4)
        >>> m.spread
        Linear(in_features=4, out_features=1, bias=True)
    """
    has_head = f"{prefix}spread.weight" in state_dict
    if has_head and module.spread is None:
        like = next(module.parameters(), None)
        module.spread = nn.Linear(in_features, 1) if like is None else nn.Linear(in_features, 1).to(like)
    elif not has_head and module.spread is not None:
        state_dict.update({f"{prefix}spread.{k}": v for k, v in module.spread.state_dict().items()})
