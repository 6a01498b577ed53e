"""Lighting for video, measured: a light-stage clip, its flicker and lag, and the rows of the bench's video skip.

**video** (:class:`~kornia_ilum.video.LightingTracker`): a clip of an eval subject under a held-out map turning by
2.8 degrees a frame, then a cut to another held-out map (:func:`video_clip`); per-frame estimation against the
tracker's defaults (and the ``auto`` runtime): ms per frame, and as error the median ``|log(E_est / E_true)|``, the
flicker over the truth's own (:func:`flicker`) and the lag after the cut (:func:`lag`). ``benchmarks/bench_video.py``
prints the same measurements per setting.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from kornia_ilum.color import linear_to_srgb
from kornia_ilum.detection import crop_faces
from kornia_ilum.geometry import latlong_to_mirror_ball
from kornia_ilum.metrics import lighting_energy
from kornia_ilum.video import LightingTracker, frame_tensor
from kornia_ilum_lab.bench.maps import small_latlong
from kornia_ilum_lab.synth.lightstage.portraits import relight_portraits

__all__ = ["VIDEO_SETTINGS", "flicker", "lag", "video_clip", "video_rows", "video_skips"]


def video_clip(field: Any, maps: Sequence[Path], frames: tuple[int, int] = (60, 30)
               ) -> tuple[list[np.ndarray], torch.Tensor, int]:
    """A 640 x 480 clip of ``field`` (a :class:`~kornia_ilum_lab.synth.lightstage.ReflectanceField`) under ``maps[0]``
    turning by one column of a 64 x 128 lat-long (2.8 degrees) a frame for ``frames[0]`` frames, then a cut to
    ``maps[1]`` for ``frames[1]``: the face over a grey backdrop in the frame's middle, exposed once per shot so
    that the face's mean is 0.18, 8-bit sRGB. Returns the frames, their true mirror balls and the cut's index.

    Args:
        field: the subject-view to relight.
        maps: at least two real lat-long maps (the first two are used).
        frames: the frames of the first shot and of the second.

    Returns:
        ``(frames, truth, cut)``: the frames as ``(480, 640, 3)`` uint8 arrays, their true mirror balls
        ``(T, 3, 32, 32)`` (exposed as the frames are) and the index of the cut's first frame, ``frames[0]``.

    Convention:
        The frames are sRGB codes and the truth is linear lighting in their units (docs/conventions.rst,
        "Images", "Mirror ball" and "Units of lighting").

    Examples:
        >>> round(360 / 128, 2)  # the map turns by one of its 128 columns a frame, in degrees
        2.81

        The clip needs a light-stage cache with an eval subject and two held-out maps:

        >>> field = eval_fields(["lightstage/"])[0]  # doctest: +SKIP
        >>> maps = held_out_maps(["hdri/"])  # doctest: +SKIP
        >>> clip, truth, cut = video_clip(field, maps, (12, 6))  # doctest: +SKIP
        >>> len(clip), clip[0].shape, tuple(truth.shape), cut  # doctest: +SKIP
        (18, (480, 640, 3), (18, 3, 32, 32), 12)
    """
    shots, truths = [], []
    for path, count in zip(maps[:2], frames, strict=True):
        latlong = small_latlong(path)
        balls = latlong_to_mirror_ball(torch.cat([latlong.roll(t, dims=-1) for t in range(count)]), 32)
        image, alpha = relight_portraits(field, balls)
        backdrop = 0.3 * float(balls.mean())
        gain = 0.18 / float(image[0].sum() / (3 * alpha.sum()).clamp(min=1))
        canvas = torch.full((count, 3, 480, 640), backdrop * gain)
        top, left = (480 - field.size) // 2, (640 - field.size) // 2
        canvas[:, :, top : top + field.size, left : left + field.size] = (image + (1 - alpha) * backdrop) * gain
        srgb = linear_to_srgb(canvas.clamp(0, 1))
        shots += [(f.permute(1, 2, 0).numpy() * 255).round().astype(np.uint8) for f in srgb]
        truths.append(balls * gain)
    return shots, torch.cat(truths), frames[0]


def flicker(balls: torch.Tensor, cut: int) -> float:
    """The mean over consecutive frames (not across the cut) of the mean absolute change of ``log(1 + L)``.

    Args:
        balls: the lighting of consecutive frames.
        cut: the index of the first frame after the cut (the change from frame ``cut - 1`` to it is left out).

    Returns:
        the flicker, in ``log(1 + L)`` per frame.

    Shape:
        - balls: :math:`(T, C, H, W)`, mirror balls :math:`(T, 3, 32, 32)` in the bench

    Examples:
        >>> flicker(torch.ones(4, 3, 8, 8), cut=2)
        0.0
        >>> balls = (torch.arange(4, dtype=torch.float64).exp() - 1).view(4, 1, 1, 1).expand(4, 3, 8, 8)
        >>> round(flicker(balls, cut=2), 4)  # log(1 + L) steps by 1 a frame
        1.0
    """
    logs = torch.log1p(balls.double())
    steps = (logs[1:] - logs[:-1]).abs().mean((1, 2, 3))
    return float(torch.cat([steps[: cut - 1], steps[cut:]]).mean())


def lag(energy: torch.Tensor, reference: torch.Tensor, cut: int) -> int:
    """Frames after the cut until ``energy`` stays within 10 % of ``reference`` (the per-frame estimate's, or
    that of the same crops estimated on every frame: :func:`video_rows`).

    Args:
        energy: the energy of each frame's estimate.
        reference: the energy it is compared with, frame by frame.
        cut: the index of the first frame after the cut.

    Returns:
        the number of frames from the cut on before ``energy`` stays within 10 % of ``reference`` to the end;
        all the frames after the cut when it never does.

    Shape:
        - energy, reference: :math:`(T,)` (:func:`~kornia_ilum.metrics.lighting_energy`)

    Examples:
        >>> lag(torch.tensor([1.0, 1.0, 2.0, 1.5, 1.05, 1.0]), torch.ones(6), cut=2)
        2
    """
    close = torch.log(energy[cut:] / reference[cut:]).abs() <= math.log(1.1)
    return next((k for k in range(len(close)) if bool(close[k:].all())), len(close))


#: The video settings of the bench: the per-frame baseline (the reference of the lag) comes first.
VIDEO_SETTINGS = {"per frame": {"detect_every": 1, "reuse_below": 0.0, "time_constant": 0.0},
                  "tracker defaults": {}, "tracker defaults, runtime auto": {"runtime": "auto"}}


def _own_crops_energy(tracker: LightingTracker, frames: Sequence[np.ndarray], results: Sequence[Any]
                      ) -> torch.Tensor:
    """The energy of each frame's estimate from the box the tracker used for it, estimated anew on every frame
    (no reuse, no smoothing): the reference of the tracker's own lag."""
    size = tracker.estimator.info.input_size
    energy = []
    with torch.inference_mode():
        for frame, result in zip(frames, results, strict=True):
            crop = crop_faces(frame_tensor(frame), result.lighting.boxes, size=size, check_values=False)
            energy.append(lighting_energy(tracker.estimator(crop, check_values=False).mirror_ball.double()))
    return torch.cat(energy)


def video_rows(frames: Sequence[np.ndarray], truth: torch.Tensor, cut: int, settings: dict[str, dict[str, Any]],
               estimator: str = "ours") -> list[dict[str, Any]]:
    """One row per :class:`~kornia_ilum.video.LightingTracker` setting (the first is the baseline of the speed-up
    and the reference of the lag): ``ms`` per frame, ``speedup``, and in ``error`` the median
    ``|log(E_est / E_true)|``, the flicker over the truth's, the frames taken for a cut, detected and estimated,
    and two lags after the cut (:func:`lag`): behind the per-frame estimate of the same runtime (``lag``: the
    first setting's options with the row's ``runtime``; this also counts a box held between detections, which
    crops the face a little differently), and behind the same crops estimated on every frame
    (``lag_own_crops``: the delay of the reuse and the smoothing alone).

    Args:
        frames: the clip (:func:`video_clip`), ``(H, W, 3)`` uint8 sRGB arrays.
        truth: the frames' true mirror balls, ``(T, 3, 32, 32)``.
        cut: the index of the first frame after the cut.
        settings: setting name -> options of :class:`~kornia_ilum.video.LightingTracker` (:data:`VIDEO_SETTINGS`).
        estimator: the registered estimator the trackers run.

    Returns:
        one row per setting: ``skip`` (``"video"``), ``setting``, ``ms``, ``speedup`` and ``error`` (``energy``,
        ``flicker_x_truth``, ``lag``, ``lag_own_crops``, ``cuts``, ``detected``, ``estimated``).

    Examples:
        >>> list(VIDEO_SETTINGS)  # the per-frame baseline first
        ['per frame', 'tracker defaults', 'tracker defaults, runtime auto']

        The rows need a light-stage cache with an eval subject and two held-out maps:

        >>> field = eval_fields(["lightstage/"])[0]  # doctest: +SKIP
        >>> maps = held_out_maps(["hdri/"])  # doctest: +SKIP
        >>> clip, truth, cut = video_clip(field, maps)  # doctest: +SKIP
        >>> [r["setting"] for r in video_rows(clip, truth, cut, VIDEO_SETTINGS)]  # doctest: +SKIP
        ['per frame', 'tracker defaults', 'tracker defaults, runtime auto']
    """
    true_energy = lighting_energy(truth.double())
    rows, references, base = [], {}, None
    first = next(iter(settings.values()))

    def run(options: dict[str, Any]) -> tuple[LightingTracker, list, float]:
        tracker = LightingTracker(estimator=estimator, fallback="full_image", **options)
        tracker(frames[0])  # built and warm: not part of the time
        tracker.reset()
        t0 = time.perf_counter()
        results = [tracker(f) for f in frames]
        return tracker, results, 1e3 * (time.perf_counter() - t0) / len(frames)

    for name, options in settings.items():
        tracker, results, ms = run(options)
        balls = torch.cat([r.lighting.mirror_ball for r in results])
        energy = lighting_energy(balls.double())
        runtime = options.get("runtime", "eager")
        if not references:
            references[first.get("runtime", "eager")] = energy
        if runtime not in references:  # the lag is behind the per-frame estimate of the same runtime
            _, baseline, _ = run({**first, "runtime": runtime})
            references[runtime] = lighting_energy(torch.cat([r.lighting.mirror_ball for r in baseline]).double())
        reference = references[runtime]
        base = base or ms
        rows.append({"skip": "video", "setting": name, "ms": ms, "speedup": base / ms, "error": {
            "energy": float(torch.log(energy / true_energy).abs().median()),
            "flicker_x_truth": flicker(balls, cut) / flicker(truth, cut), "lag": lag(energy, reference, cut),
            "lag_own_crops": lag(energy, _own_crops_energy(tracker, frames, results), cut),
            "cuts": sum(r.cut for r in results), "detected": sum(r.detected for r in results),
            "estimated": sum(r.estimated for r in results)}})
    return rows


def video_skips(field: Any, maps: Sequence[Path], estimator: str = "ours", quick: bool = False
                ) -> list[dict[str, Any]]:
    """The video rows (module docstring).

    Args:
        field: the subject-view of the clip (:func:`video_clip`).
        maps: at least two held-out maps (:func:`held_out_maps`).
        estimator: the registered estimator the trackers run.
        quick: a clip of 12 + 6 frames and the first two settings of :data:`VIDEO_SETTINGS` (CI), instead of
            60 + 30 frames and all of them.

    Returns:
        the rows of :func:`video_rows`.

    Examples:
        >>> list(VIDEO_SETTINGS)[:2]  # what quick=True measures
        ['per frame', 'tracker defaults']

        The rows need a light-stage cache with an eval subject and two held-out maps:

        >>> field = eval_fields(["lightstage/"])[0]  # doctest: +SKIP
        >>> maps = held_out_maps(["hdri/"])  # doctest: +SKIP
        >>> [r["setting"] for r in video_skips(field, maps, quick=True)]  # doctest: +SKIP
        ['per frame', 'tracker defaults']
    """
    frames, truth, cut = video_clip(field, maps, (12, 6) if quick else (60, 30))
    settings = dict(list(VIDEO_SETTINGS.items())[:2]) if quick else VIDEO_SETTINGS
    return video_rows(frames, truth, cut, settings, estimator)
