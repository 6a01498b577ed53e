r"""What each skip saves against what it costs, on the held-out split: the ``skips`` section of ``kornia-ilum bench``.

With ``--cache``, ``kornia-ilum bench`` takes the first eval subject-view of the caches and the held-out real maps
(``hdri_split`` "eval") of ``--hdri``, and measures, each against its own baseline in the same process:

- **video** (:class:`~kornia_ilum.video.LightingTracker`): a clip of the subject under a held-out map turning by
  2.8 degrees a frame, then a cut to another held-out map (:func:`video_clip`); per-frame estimation against
  the tracker's defaults (and the ``auto`` runtime): ms per frame, and as error the median
  ``|log(E_est / E_true)|``, the flicker over the truth's own (:func:`flicker`) and the lag after the cut
  (:func:`lag`);
- **sparse relighting** (:func:`~kornia_ilum.render.relight_sparse`): the subject relit by each held-out map
  at 16 yaws, dense against sparse (:data:`RELIGHT_SETTINGS`): ms per batch, and as error the paper's
  ``L_rec`` applied to the portrait (:func:`lrec_like`), over all the maps, the sun-dominated ones and the
  sun-dominated outdoor ones.

Detection at a reduced side, the other skip of the estimate, is the end-to-end section of the bench.
``benchmarks/bench_video.py`` and ``benchmarks/bench_relight.py`` print the same measurements per map and
setting.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from kornia_ilum.bench.machine import paired_median_seconds
from kornia_ilum.color import gamma_encode, linear_to_srgb
from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.detection import crop_faces
from kornia_ilum_lab.evaluation.checks import lighting_energy
from kornia_ilum_lab.evaluation.split import eval_fields
from kornia_ilum.filters import soft_clip
from kornia_ilum.geometry import latlong_to_mirror_ball, mirror_ball_to_lights
from kornia_ilum.io import read_hdr
from kornia_ilum.render import prepare_sparse, relight_product, relight_sparse, sparse_kept
from kornia_ilum_lab.synth.environments.real import folder_splits, guess_label
from kornia_ilum_lab.synth.lightstage.portraits import relight_portraits
from kornia_ilum.video import LightingTracker, frame_tensor

__all__ = ["RELIGHT_SETTINGS", "SUNNY", "VIDEO_SETTINGS", "flicker", "held_out_maps", "lag", "lrec_like",
           "relight_groups", "relight_skips", "skip_rows", "small_latlong", "top_share", "turned_lights",
           "video_clip", "video_rows", "video_skips"]


def held_out_maps(folders: Sequence[str | os.PathLike[str]]) -> list[Path]:
    """The real maps of ``folders`` whose split is ``"eval"`` (:func:`~kornia_ilum_lab.synth.environments.hdri_split`),
    sorted by name.

    Args:
        folders: folders of real lat-long maps (``.exr`` and ``.hdr`` files; other files are skipped).

    Returns:
        the paths of the held-out maps, sorted by file name.

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     for name in ("studio.exr", "interior.exr", "notes.txt"):
        ...         (Path(tmp) / name).touch()
        ...     [p.name for p in held_out_maps([tmp])]
        ['studio.exr']
    """
    maps = [Path(f) / name for f in folders for name, split in folder_splits(f).items() if split == "eval"]
    return sorted(maps, key=lambda p: p.name)


def small_latlong(path: str | os.PathLike[str], height: int = 64) -> torch.Tensor:
    """A real map read and reduced by area to ``height x 2 height``: the lighting of the skips' clips and
    relighting rows (a 32 x 32 ball needs no more).

    Args:
        path: an ``.exr`` or ``.hdr`` lat-long map.
        height: the reduced map's height.

    Returns:
        ``(1, 3, height, 2 height)`` float32, linear.

    Raises:
        HDRIOError: the map cannot be read.

    Examples:
        >>> import tempfile
        >>> from kornia_ilum.io import write_hdr
        >>> with tempfile.TemporaryDirectory() as d:
        ...     _ = write_hdr(f"{d}/sky.exr", torch.ones(3, 128, 256))
        ...     small = small_latlong(f"{d}/sky.exr")
        >>> tuple(small.shape), float(small.mean())
        ((1, 3, 64, 128), 1.0)
    """
    x = read_hdr(path).float()[None]
    return torch.nn.functional.interpolate(x, size=(height, 2 * height), mode="area")


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
        - energy, reference: :math:`(T,)` (:func:`~kornia_ilum_lab.evaluation.checks.lighting_energy`)

    Examples:
        >>> lag(torch.tensor([1.0, 1.0, 2.0, 1.5, 1.05, 1.0]), torch.ones(6), cut=2)
        2
    """
    close = torch.log(energy[cut:] / reference[cut:]).abs() <= math.log(1.1)
    return next((k for k in range(len(close)) if bool(close[k:].all())), len(close))


def lrec_like(image: torch.Tensor, reference: torch.Tensor) -> float:
    """The paper's ``L_rec`` applied to relit portraits ``(B, C, P)``: the mean absolute difference of the
    gamma-encoded images, each exposed so that the reference's 99th percentile is 1 and soft-clipped, over the
    mean of the encoded reference.

    Args:
        image: the portraits to score (sparse relighting's).
        reference: the same portraits relit densely.

    Returns:
        the relative error (0 for ``image`` equal to ``reference``).

    Shape:
        - image, reference: :math:`(B, C, P)`, ``P`` pixels

    Convention:
        Both are linear images in the same units; the exposure is the reference's, per portrait.

    Examples:
        >>> reference = torch.rand(2, 3, 100, generator=torch.Generator().manual_seed(0))
        >>> lrec_like(reference, reference), lrec_like(2 * reference, reference) > 0
        (0.0, True)
    """
    scale = torch.quantile(reference.flatten(1).float(), 0.99, dim=1).clamp(min=1e-12)[:, None, None]

    def encode(x: torch.Tensor) -> torch.Tensor:
        return gamma_encode(soft_clip((x / scale).clamp(min=0)))

    ref = encode(reference)
    return float((encode(image) - ref).abs().mean() / ref.mean())


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


#: The sparse-relighting settings of the bench: (name, rank, eps); rank ``None`` is dense.
RELIGHT_SETTINGS = (("dense", None, 0.0), ("eps 0.005, rank 48", 48, 0.005), ("eps 0.01, rank 48", 48, 0.01),
                    ("eps 0.02, rank 48", 48, 0.02), ("eps 0.01, rank 16", 16, 0.01), ("eps 0.01, rank 32", 32, 0.01))

#: A map is sun-dominated when its brightest 1 % of directions carry at least this share of its energy.
SUNNY = 0.5


def top_share(lights: torch.Tensor) -> float:
    """The share of the energy in the brightest 1 % of directions of the first light list of ``(B, N, C)``.

    Args:
        lights: light lists (:func:`~kornia_ilum.geometry.mirror_ball_to_lights`); only the first is read.

    Returns:
        the share in ``[0, 1]``, by the mean over the channels (at least one direction is counted).

    Shape:
        - lights: :math:`(B, N, C)`

    Examples:
        >>> lights = torch.ones(1, 200, 3)
        >>> round(top_share(lights), 4)  # uniform: the top 1 % holds 1 %
        0.01
        >>> lights[0, 0] = 1000.0
        >>> top_share(lights) >= SUNNY  # one sun
        True
    """
    energy = lights[0].mean(-1).sort(descending=True).values
    return float(energy[: max(1, len(energy) // 100)].sum() / energy.sum())


def relight_groups(lights: torch.Tensor, name: str) -> list[str]:
    """The groups of maps a relighting row counts a map in, beyond all of them: the sun-dominated maps
    (:data:`SUNNY`), and those of them that are outdoor (:func:`~kornia_ilum_lab.synth.environments.guess_label`),
    issue 24's target.

    Args:
        lights: the map's light lists (:func:`turned_lights`); only the first is read.
        name: the map's file name.

    Returns:
        the group names, from none to both.

    Examples:
        >>> lights = torch.ones(1, 200, 3)
        >>> relight_groups(lights, "meadow.exr")  # uniform: not sun-dominated
        []
        >>> lights[0, 0] = 1000.0
        >>> relight_groups(lights, "meadow.exr")
        ['sun-dominated maps (top 1 % >= 0.5)', 'sun-dominated outdoor maps']
    """
    if top_share(lights) < SUNNY:
        return []
    return [f"sun-dominated maps (top 1 % >= {SUNNY:g})"] + (["sun-dominated outdoor maps"]
                                                             if guess_label(name) == "outdoor" else [])


def turned_lights(latlong: torch.Tensor, field: Any, batch: int) -> torch.Tensor:
    """``(batch, N, 3)``: a lat-long map turned to ``batch`` evenly spaced yaws, as light lists in the layout of
    ``field`` (its ``lighting_size`` mirror ball, and its ``light_index`` where the field is compact): the batch
    that the relighting rows (:func:`relight_skips`, ``benchmarks/bench_relight.py``) relight.

    Args:
        latlong: ``(1, 3, H, 2H)`` linear lat-long map.
        field: a :class:`~kornia_ilum_lab.synth.lightstage.ReflectanceField`.
        batch: how many yaws.

    Returns:
        the light lists.

    Examples:
        >>> from types import SimpleNamespace
        >>> field = SimpleNamespace(lighting_size=8, light_index=None)
        >>> tuple(turned_lights(torch.ones(1, 3, 8, 16), field, 4).shape)
        (4, 64, 3)
    """
    turns = [latlong.roll(int(k * latlong.shape[-1] / batch), dims=-1) for k in range(batch)]
    lights = mirror_ball_to_lights(latlong_to_mirror_ball(torch.cat(turns), field.lighting_size))
    return lights[:, field.light_index] if field.light_index is not None else lights


def relight_skips(field: Any, maps: Sequence[Path], quick: bool = False, batch: int = 16) -> list[dict[str, Any]]:
    """The sparse-relighting rows (module docstring): times summed and errors averaged over all ``maps``, over
    the sun-dominated ones (:data:`SUNNY`), and over those of them that are outdoor
    (:func:`~kornia_ilum_lab.synth.environments.guess_label`): issue 24's target.

    Args:
        field: the subject-view to relight.
        maps: the held-out maps (:func:`held_out_maps`).
        quick: the first two maps and fewer timed calls (CI).
        batch: yaws per map (a relit batch).

    Returns:
        one row per group of maps and setting of :data:`RELIGHT_SETTINGS`: ``skip``, ``setting``, ``ms``,
        ``speedup`` (over ``"dense"``) and ``error`` (``l_rec_like``, its mean over the maps, and
        ``l_rec_like_max``, of :func:`lrec_like`; ``lights_kept``; ``maps``).

    Examples:
        >>> [name for name, _, _ in RELIGHT_SETTINGS][:2]  # the baseline first
        ['dense', 'eps 0.005, rank 48']

        The rows need a light-stage cache with an eval subject and two held-out maps:

        >>> field = eval_fields(["lightstage/"])[0]  # doctest: +SKIP
        >>> maps = held_out_maps(["hdri/"])  # doctest: +SKIP
        >>> rows = relight_skips(field, maps, quick=True)  # doctest: +SKIP
        >>> rows[0]["skip"], rows[0]["setting"], rows[0]["speedup"]  # doctest: +SKIP
        ('sparse relighting, all held-out maps', 'dense', 1.0)
    """
    prepared = {r: prepare_sparse(field.field, r) for r in {r for _, r, _ in RELIGHT_SETTINGS if r is not None}}
    groups: dict[str, dict[str, dict[str, Any]]] = {}
    repeats = 3 if quick else 15
    for path in maps[:2] if quick else maps:
        lights = turned_lights(small_latlong(path), field, batch)
        dense_lights = lights.to(field.field.dtype)
        reference = relight_product(field.field, dense_lights).float()
        names = ["all held-out maps"] + relight_groups(lights, path.name)
        calls = [(lambda: relight_product(field.field, dense_lights)) if rank is None else
                 (lambda p=prepared[rank], e=eps: relight_sparse(p, lights, e)) for _, rank, eps in RELIGHT_SETTINGS]
        times = paired_median_seconds(calls, repeats)  # in turns: a slow spell hits every setting alike
        for (setting, rank, eps), seconds in zip(RELIGHT_SETTINGS, times, strict=True):
            ms = 1e3 * seconds
            if rank is None:
                out, kept = reference, float(lights.shape[1])
            else:
                out = relight_sparse(prepared[rank], lights, eps)
                kept = float(sparse_kept(prepared[rank], lights, eps).float().mean())
            for name in names:
                t = groups.setdefault(name, {}).setdefault(setting, {"ms": 0.0, "err": [], "kept": [], "maps": 0})
                t["ms"] += ms
                t["err"].append(lrec_like(out, reference))
                t["kept"].append(kept)
                t["maps"] += 1
    return [{"skip": f"sparse relighting, {name}", "setting": setting, "ms": t["ms"],
             "speedup": totals["dense"]["ms"] / t["ms"],
             "error": {"l_rec_like": float(np.mean(t["err"])), "l_rec_like_max": float(np.max(t["err"])),
                       "lights_kept": float(np.mean(t["kept"])), "maps": t["maps"]}}
            for name, totals in groups.items() for setting, t in totals.items()]


def skip_rows(caches: Sequence[str | os.PathLike[str]], hdri: Sequence[str | os.PathLike[str]],
              quick: bool = False) -> tuple[list[dict[str, Any]], str]:
    """Every skip's rows, and one line saying what they were measured on (or why nothing was).

    Args:
        caches: light-stage caches; the first of their eval subject-views is relit.
        hdri: folders of real maps; their held-out maps light it (two at least).
        quick: the short form of each skip (CI).

    Returns:
        ``(rows, what)``: the rows of :func:`video_skips` then :func:`relight_skips`, and the line; no rows
        without an eval subject or two held-out maps.

    Examples:
        >>> skip_rows([], [])
        ([], 'skips: not measured (needs an eval subject in --cache and two held-out maps in --hdri)')
    """
    try:
        fields = eval_fields(caches)
    except ValueCheckError:
        fields = []
    maps = held_out_maps(hdri)
    if not fields or len(maps) < 2:
        return [], "skips: not measured (needs an eval subject in --cache and two held-out maps in --hdri)"
    field = fields[0]
    what = (f"eval subject {field.subject_seed} (view {field.meta.get('view_index', 0)}) under the held-out maps "
            f"{', '.join(p.name for p in maps)}")
    return video_skips(field, maps, quick=quick) + relight_skips(field, maps, quick=quick), what
