r"""Test-time augmentation for every estimator: average the lighting over jittered sub-crops and the mirror.

The same face, cropped from the boxes of two detectors, can give estimates far apart in energy, and even
with the light flipped from left to right (issue 21, point 3). :class:`TestTimeAugmented` wraps any
:class:`~kornia_ilum.estimators.LightingEstimator` and answers the same ``forward(crops) ->
LightingEstimate`` contract with an estimate averaged over several views of each crop:

- :func:`jitter_windows`: ``K`` deterministic square sub-crops ("windows") of the crop, the first the crop
  itself, the others zoomed in by up to ``exp(zoom)`` around a centre shifted by up to ``shift`` of the
  side; every window stays inside the crop, so no pixel is invented;
- :func:`crop_windows`: each window resampled to the crop's size (bilinear; enlarging only, so no
  antialiasing is needed), and, with ``mirror=True``, the same windows of the mirrored crop;
- the wrapped estimator runs once on the batch of all ``P = K`` (or ``2K``) views of all ``B`` crops;
  the estimates of mirrored views are mirrored back
  (:func:`~kornia_ilum.geometry.flip_lighting_horizontal`), and the ``P`` estimates of each crop are
  averaged (:func:`average_estimates`).

Why the arithmetic mean of radiance (not the geometric mean, i.e. the mean of the log):

- it adds no bias to the energy: the energy (and every diffuse or specular sphere render, and the SH
  coefficients) of the mean lighting is the mean of the views' energies, as each of them is linear in the
  lighting. The per-pixel geometric mean is never above the arithmetic one (AM-GM), and far below it where
  the views disagree on where the light is: two views with the light 30 degrees apart keep little of either
  lobe, so the averaged estimate loses energy exactly when the crop makes the estimator unsure;
- it commutes with the exposure: ``k x`` gives ``k`` times the average wherever each view does (the
  geometric mean needs an ``eps`` inside the log, which breaks this near black);
- the two means reduce the spread of the log energy under the crop about equally (measured with ``ours``
  on real and rendered faces), so the geometric mean buys no stability for its loss of energy.

What averaging can and cannot do: it smooths the estimate over neighbouring crops, so it removes the part of
the crop sensitivity that changes quickly from one crop to the next, and, with the mirror, any left-right
inconsistency. A steady trend with the crop (an estimator that reads less light the less background a crop
shows) survives any average of nearby crops, and the windows, being zoomed in, lean slightly towards the
face: that calls for training with jittered crops.

The SH coefficients of an estimator that has them (the ``sh`` plugin) are averaged the same way, those of
mirrored views mirrored back first (:func:`mirror_sh`); ``log_mirror_ball`` is ``log1p`` of the averaged
mirror ball, so ``mirror_ball == expm1(log_mirror_ball)`` holds as for every estimator.

Cost: ``P`` passes of the wrapped estimator per crop (plus the resampling), in one batched call; see
``benchmarks/bench_tta.py``.

Convention:
    Crops are ``(B, 3, S, S)`` sRGB in ``[0, 1]`` (docs/conventions.rst, "Images"), the lighting in the units
    of the photograph (docs/conventions.rst, "Units of lighting"). Window offsets are in image axes (x to the
    right, y down), in fractions of the crop's side. Mirroring the crop left-right mirrors the lighting
    ``x -> -x`` in the camera frame (docs/conventions.rst, "Mirror ball").
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import ClassVar

import torch
import torch.nn.functional as F
from torch import Tensor

from kornia_ilum.core.check import check_positive_int, check_tensor
from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.estimators.base import EstimatorInfo, LightingEstimate, LightingEstimator
from kornia_ilum.geometry import flip_lighting_horizontal
from kornia_ilum.sh import sh_basis

__all__ = [
    "DEFAULT_ZOOM",
    "DEFAULT_SHIFT",
    "jitter_windows",
    "crop_windows",
    "mirror_sh",
    "average_estimates",
    "TestTimeAugmented",
]

#: Largest zoom of a window, as a log factor: its side is at least ``exp(-0.15)`` (0.86) of the crop's.
DEFAULT_ZOOM = 0.15
#: Largest shift of a window's centre, as a fraction of the crop's side (capped so the window stays inside).
DEFAULT_SHIFT = 0.10


def _check_number(value: object, name: str, upper: float = math.inf) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise TypeCheckError(f"{name} must be a number, got {type(value).__name__}")
    if not (math.isfinite(value) and 0.0 <= value < upper):
        raise ValueCheckError(f"{name} must be finite and in [0, {upper:g}), got {value!r}")
    return float(value)


def jitter_windows(
    jitters: int, zoom: float = DEFAULT_ZOOM, shift: float = DEFAULT_SHIFT, seed: int = 0
) -> Tensor:
    r"""Deterministic square sub-crops of a crop: the crop itself, then ``jitters - 1`` zoomed in and shifted.

    Window ``k >= 1`` has side ``exp(-u_k zoom)`` of the crop's, with ``u_k`` stratified over ``[0, 1]``
    (one uniform draw in each of ``jitters - 1`` equal intervals, so that a few windows already span the
    zoom range), and a centre offset drawn uniformly in the square of half-width
    ``min(shift, (1 - side) / 2)``: at most ``shift`` of the side, and never so far that the window leaves
    the crop. Zooming only in keeps every window inside the crop (a crop holds no pixels beyond itself);
    a modest ``zoom`` keeps the face's scale close to the 1.25 x face box that estimators are trained on.

    Args:
        jitters: the number of windows ``K``, the first the identity.
        zoom: the largest zoom, as a log factor (``0`` keeps the side).
        shift: the largest centre offset, as a fraction of the crop's side, in ``[0, 0.5)``.
        seed: seed of the draws (a :class:`torch.Generator` on the CPU): the same arguments give the same
            windows on every machine.

    Returns:
        ``(K, 3)`` float64 rows ``(side, dx, dy)``: the window's side and its centre's offset from the
        crop's centre (x to the right, y down), all in fractions of the crop's side;
        ``|dx| + side / 2 <= 1 / 2`` (same for ``dy``).

    Raises:
        TypeCheckError, ValueCheckError: ``jitters`` is not a positive int, ``zoom`` or ``shift`` is not a
            finite number in range, or ``seed`` is not an int.

    Shape:
        - Output: :math:`(K, 3)`, ``K = jitters``

    Convention:
        Offsets in the image's axes, x to the right and y down (the rows of docs/conventions.rst, "Images"), not
        the lighting frame's +Y up (docs/conventions.rst, "Frames").

    Examples:
        >>> w = jitter_windows(4)
        >>> w.shape, w[0].tolist()
        (torch.Size([4, 3]), [1.0, 0.0, 0.0])
        >>> bool((w[:, 1:].abs().amax(dim=1) + w[:, 0] / 2 <= 0.5).all())
        True
    """
    check_positive_int(jitters, "jitters")
    zoom = _check_number(zoom, "zoom")
    shift = _check_number(shift, "shift", 0.5)
    if isinstance(seed, bool) or not isinstance(seed, int):
        raise TypeCheckError(f"seed must be an int, got {type(seed).__name__}")
    n = jitters - 1
    gen = torch.Generator().manual_seed(seed)
    draws = torch.rand(n, 3, generator=gen, dtype=torch.float64)
    u = (torch.arange(n, dtype=torch.float64) + draws[:, 0]) / max(n, 1)
    side = torch.exp(-u * zoom)
    reach = torch.minimum(torch.full_like(side, shift), (1.0 - side) / 2)
    offset = (2.0 * draws[:, 1:] - 1.0) * reach[:, None]
    jittered = torch.cat([side[:, None], offset], dim=1)
    return torch.cat([torch.tensor([[1.0, 0.0, 0.0]], dtype=torch.float64), jittered])


def crop_windows(crops: Tensor, windows: Tensor, mirror: bool = False) -> Tensor:
    r"""Resample windows of square crops to the crops' size, bilinearly; optionally of the mirrored crops.

    Window ``(side, dx, dy)`` of a crop of side ``S`` spans ``[(1/2 + dx - side/2) S, (1/2 + dx + side/2) S]``
    horizontally in continuous pixel coordinates (pixel ``j`` spans ``[j, j + 1]``), the same vertically with
    ``dy``; the output pixels tile it exactly (:func:`torch.nn.functional.grid_sample`, bilinear,
    ``align_corners=False``). Windows are no larger than the crop, so this only enlarges and needs no
    antialiasing. The identity window ``(1, 0, 0)`` is the crop itself, exactly. ``mirror=True`` takes the
    windows of the left-right mirrored crops (``crops.flip(-1)``).

    Args:
        crops: square crops, any values.
        windows: ``(K, 3)`` rows ``(side, dx, dy)`` (:func:`jitter_windows`).
        mirror: take the windows of the mirrored crops.

    Returns:
        ``(K B, C, S, S)``, window-major (the ``B`` crops of window 0 first), dtype and device of ``crops``
        (float16 and bfloat16 are resampled in float32 and cast back).

    Raises:
        ShapeError: ``crops`` is not ``(B, C, S, S)`` with square ``S``, or ``windows`` is not ``(K, 3)``.
        TypeCheckError: a tensor is not floating point.

    Shape:
        - crops: :math:`(B, C, S, S)`; windows: :math:`(K, 3)`
        - Output: :math:`(K B, C, S, S)`

    Convention:
        Continuous pixel coordinates as above; crops are images, ``(B, C, H, W)`` (docs/conventions.rst,
        "Images"), and ``mirror`` flips them left-right, ``x -> -x`` of docs/conventions.rst, "Frames"
        (:func:`mirror_sh` mirrors the lighting to match).

    Examples:
        >>> x = torch.arange(16.0).reshape(1, 1, 4, 4)
        >>> crop_windows(x, torch.tensor([[0.5, -0.25, -0.25]]))  # the top-left quarter, enlarged 2x
        tensor([[[[0.0000, 0.2500, 0.7500, 1.2500],
                  [1.0000, 1.2500, 1.7500, 2.2500],
                  [3.0000, 3.2500, 3.7500, 4.2500],
                  [5.0000, 5.2500, 5.7500, 6.2500]]]])
        >>> torch.equal(crop_windows(x, torch.tensor([[1.0, 0.0, 0.0]]), mirror=True), x.flip(-1))
        True
    """
    check_tensor(crops, "crops", ["B", "C", "S", "S"], finite=False)
    if crops.shape[-1] != crops.shape[-2]:
        raise ShapeError(f"crops must be square (B, C, S, S), got {tuple(crops.shape)}")
    check_tensor(windows, "windows", ["K", "3"])
    work = crops.float() if crops.dtype in (torch.float16, torch.bfloat16) else crops
    if mirror:
        work = work.flip(-1)
    size, batch = work.shape[-1], work.shape[0]
    t = (torch.arange(size, dtype=torch.float64, device=crops.device) + 0.5) / size - 0.5  # centres, in sides
    views = []
    for side, dx, dy in windows.detach().to(torch.float64).tolist():
        if (side, dx, dy) == (1.0, 0.0, 0.0):
            views.append(work)
            continue
        gx = 2.0 * (dx + side * t)  # normalised grid coordinates in [-1, 1]
        gy = 2.0 * (dy + side * t)
        grid = torch.stack(torch.broadcast_tensors(gx[None, :], gy[:, None]), -1).to(work.dtype)
        views.append(
            F.grid_sample(
                work,
                grid[None].expand(batch, -1, -1, -1),
                mode="bilinear",
                padding_mode="border",
                align_corners=False,
            )
        )
    return torch.cat(views).to(crops.dtype)


@lru_cache(maxsize=1)
def _sh_mirror_signs() -> tuple[float, ...]:
    """``+-1`` per SH coefficient: ``Y_i(-x, y, z) = sign_i Y_i(x, y, z)``, read off :func:`sh_basis`."""
    d = torch.tensor([0.3, 0.5, 0.7], dtype=torch.float64)  # a direction where no basis function is 0
    ratio = sh_basis(d * torch.tensor([-1.0, 1.0, 1.0], dtype=torch.float64)) / sh_basis(d)
    return tuple(float(torch.sign(r)) for r in ratio)


def mirror_sh(sh: Tensor) -> Tensor:
    r"""The order-2 SH coefficients of the mirrored lighting ``L'(x, y, z) = L(-x, y, z)``.

    Real SH basis functions are even or odd in ``x``; mirroring flips the sign of the odd ones (those of
    ``x``, ``x y`` and ``x z`` in the order of docs/conventions.rst). The signs are read off
    :func:`~kornia_ilum.sh.sh_basis`, so they follow its order and convention.

    Args:
        sh: SH coefficients, the 9 of order 2 in the order of docs/conventions.rst.

    Returns:
        the mirrored coefficients, same shape, dtype and device.

    Raises:
        ShapeError: ``sh`` is not ``(*, 9, C)``.

    Shape:
        - sh: :math:`(*, 9, C)`
        - Output: as ``sh``

    Convention:
        docs/conventions.rst, "Spherical harmonics" (the order of the coefficients) and "Frames" (``x`` is +X,
        to the right).

    Examples:
        >>> mirror_sh(torch.ones(9, 1)).flatten().tolist()
        [1.0, 1.0, 1.0, -1.0, -1.0, 1.0, 1.0, -1.0, 1.0]
    """
    check_tensor(sh, "sh", ["*", "9", "C"], finite=False)
    signs = torch.tensor(_sh_mirror_signs(), dtype=sh.dtype, device=sh.device)
    return sh * signs[:, None]


def average_estimates(estimates: LightingEstimate, passes: int) -> LightingEstimate:
    r"""Average ``passes`` aligned estimates of each crop: the arithmetic mean of radiance per pixel.

    The energy, the sphere renders and the SH coefficients of the average are the averages of the passes'
    (each is linear in the lighting); the module docstring gives the reasons for this mean.

    Args:
        estimates: ``P B`` estimates, pass-major (the ``B`` crops of pass 0 first), all in the frame of the
            unmirrored crops.
        passes: ``P``.

    Returns:
        ``B`` estimates: ``mirror_ball``, ``sh`` and ``log_energy_spread`` (where present) averaged in float32
        or float64 and cast back (the spread: the passes' mean, since their errors are far from independent);
        ``log_mirror_ball`` is ``log1p`` of the averaged mirror ball where the input has it.

    Raises:
        ValueCheckError: ``len(estimates)`` is not a multiple of ``passes``.

    Examples:
        >>> from kornia_ilum.geometry import mirror_ball_valid
        >>> valid = mirror_ball_valid(32)
        >>> balls = torch.tensor([1.0, 3.0]).view(2, 1, 1, 1) * valid.expand(2, 3, 32, 32)
        >>> est = LightingEstimate(balls, valid)  # two passes of one crop
        >>> average_estimates(est, 2).mirror_ball.amax().item()
        2.0
    """
    check_positive_int(passes, "passes")
    if len(estimates) % passes:
        raise ValueCheckError(f"{len(estimates)} estimates cannot be {passes} passes of the same crops")

    def mean(x: Tensor) -> Tensor:
        work = x.float() if x.dtype in (torch.float16, torch.bfloat16) else x
        return work.reshape(passes, -1, *x.shape[1:]).mean(dim=0).to(x.dtype)

    mirror_ball = mean(estimates.mirror_ball)
    log_mirror_ball = None
    if estimates.log_mirror_ball is not None:
        log_mirror_ball = torch.log1p(mirror_ball.float()).to(estimates.log_mirror_ball.dtype)
    return LightingEstimate(
        mirror_ball=mirror_ball,
        valid=estimates.valid,
        log_mirror_ball=log_mirror_ball,
        sh=None if estimates.sh is None else mean(estimates.sh),
        log_energy_spread=None if estimates.log_energy_spread is None else mean(estimates.log_energy_spread),
    )


class TestTimeAugmented(LightingEstimator):
    r"""Any lighting estimator, averaged over jittered sub-crops and the mirror of each crop at test time.

    For each crop, the wrapped estimator sees ``jitters`` windows of it (:func:`jitter_windows`: the crop
    itself, then windows zoomed in by up to ``exp(zoom)`` and shifted by up to ``shift`` of the side, inside
    the crop), each resampled to the input size (:func:`crop_windows`), and, with ``mirror=True``, the same
    windows of the mirrored crop, whose estimates are mirrored back. All ``P = jitters`` (or ``2 jitters``)
    views of all ``B`` crops go through the wrapped estimator in one batch of ``P B``; the ``P`` estimates of
    each crop are averaged in radiance (:func:`average_estimates`; the module docstring says why).

    It is a :class:`~kornia_ilum.estimators.LightingEstimator`, so it goes wherever an estimator goes: the
    :func:`kornia_ilum.estimate_lighting` pipeline (its ``tta`` argument builds one), the evaluation. Its
    :attr:`info` is the wrapped estimator's, renamed ``"<name>+tta"``; it has no parameters of its own, and
    ``.to()``, ``.eval()`` and ``state_dict()`` reach the wrapped estimator (``estimator.*``). It starts in
    the wrapped estimator's training mode. It is not registered by name: wrap a created estimator.

    Args:
        estimator: the estimator to wrap.
        jitters: the number of windows per crop, the first the crop itself.
        mirror: also estimate from the mirrored crop (doubles the passes; makes the result exactly
            mirror-equivariant: the estimate of the mirrored crop is the mirrored estimate).
        zoom: the largest zoom, as a log factor.
        shift: the largest centre shift, as a fraction of the crop's side.
        seed: seed of the windows (they are drawn once, here).

    Raises:
        TypeCheckError: ``estimator`` is not a :class:`~kornia_ilum.estimators.LightingEstimator`, or an
            argument has a wrong type.
        ValueCheckError: an argument is out of range (see :func:`jitter_windows`).

    Note:
        ``jitters=1, mirror=False`` is the wrapped estimator itself (its estimate is returned as it is). The
        SH coefficients of an estimator that has them are averaged too, mirrored views' mirrored back
        (:func:`mirror_sh`). Windows zoom in only, so the face looks up to ``exp(zoom)`` larger than in the
        1.25 x face-box crops estimators are trained on: keep ``zoom`` modest.

    Examples:
        >>> from kornia_ilum.estimators import create_estimator
        >>> tta = TestTimeAugmented(create_estimator("ours", pretrained=False).eval(), jitters=2)
        >>> tta.passes, tta.info.name, tta.info.input_size
        (4, 'ours+tta', 256)
        >>> est = tta(torch.rand(3, 3, 256, 256))
        >>> tuple(est.mirror_ball.shape)
        (3, 3, 32, 32)
    """

    __test__ = False  # not a pytest test class, whatever its name says
    info: ClassVar[EstimatorInfo] = EstimatorInfo(
        "tta",
        "test-time averaging of a wrapped estimator over jittered sub-crops and the mirror",
        "none: a wrapper",
        needs_weights=False,
    )

    def __init__(
        self,
        estimator: LightingEstimator,
        *,
        jitters: int = 4,
        mirror: bool = True,
        zoom: float = DEFAULT_ZOOM,
        shift: float = DEFAULT_SHIFT,
        seed: int = 0,
    ) -> None:
        super().__init__()
        if not isinstance(estimator, LightingEstimator):
            raise TypeCheckError(
                f"estimator must be a LightingEstimator instance, got {type(estimator).__name__}"
            )
        if not isinstance(mirror, bool):
            raise TypeCheckError(f"mirror must be a bool, got {type(mirror).__name__}")
        windows = jitter_windows(jitters, zoom, shift, seed)  # checks jitters, zoom, shift, seed
        self.estimator = estimator
        self.jitters, self.mirror, self.zoom, self.shift, self.seed = jitters, mirror, zoom, shift, seed
        self.windows: tuple[tuple[float, float, float], ...] = tuple(map(tuple, windows.tolist()))
        inner = estimator.info
        self.info = EstimatorInfo(  # type: ignore[misc]  # per instance: derived from the wrapped estimator
            name=f"{inner.name}+tta",
            description=f"{inner.description} (averaged over {self.passes} views of each crop)",
            paper=inner.paper,
            input_size=inner.input_size,
            install_hint=inner.install_hint,
            needs_weights=False,
        )
        self.training = estimator.training  # not .train(): that would reset the wrapped modules' modes

    @property
    def passes(self) -> int:
        """The views per crop: ``jitters``, twice that with ``mirror``."""
        return self.jitters * (2 if self.mirror else 1)

    def estimate_views(self, crops: Tensor) -> LightingEstimate:
        r"""The estimates of every view of every crop, aligned to the unmirrored crops, not yet averaged.

        For measuring the spread of an estimator under the crop; :meth:`forward` averages them.

        Args:
            crops: checked crops ``(B, 3, S, S)``, ``S = info.input_size``.

        Returns:
            ``P B`` estimates, view-major: the ``B`` crops of the windows ``0 .. K - 1``, then (with
            ``mirror``) those of the mirrored crops' windows, their lighting and SH mirrored back.
        """
        windows = torch.tensor(self.windows, dtype=torch.float64)
        views = [crop_windows(crops, windows)]
        if self.mirror:
            views.append(crop_windows(crops, windows, mirror=True))
        # windows of checked crops are convex combinations of their values: nothing new to scan
        est = self.estimator(torch.cat(views), check_values=False)
        if not self.mirror:
            return est
        n = self.jitters * crops.shape[0]
        mirror_ball = torch.cat([est.mirror_ball[:n], flip_lighting_horizontal(est.mirror_ball[n:])])
        log_mirror_ball = est.log_mirror_ball
        if log_mirror_ball is not None:
            log_mirror_ball = torch.cat([log_mirror_ball[:n], flip_lighting_horizontal(log_mirror_ball[n:])])
        sh = est.sh if est.sh is None else torch.cat([est.sh[:n], mirror_sh(est.sh[n:])])
        return LightingEstimate(
            mirror_ball=mirror_ball, valid=est.valid, log_mirror_ball=log_mirror_ball, sh=sh,
            log_energy_spread=est.log_energy_spread,
        )

    def predict(self, crops: Tensor) -> LightingEstimate:
        if self.passes == 1:
            return self.estimator(crops, check_values=False)
        return average_estimates(self.estimate_views(crops), self.passes)

    def extra_repr(self) -> str:
        return (
            f"jitters={self.jitters}, mirror={self.mirror}, zoom={self.zoom}, shift={self.shift}, "
            f"seed={self.seed}"
        )
