"""Benchmark: how often the face detectors find the light stage's eval subjects in composited portraits.

Run: ``python benchmarks/bench_detection.py --cache DIR [DIR ...] [--count 120] [--upscale 512] [--max-side N ...]
[--render-eval K]``

For ``--count`` renders (cycling over the caches' EVAL-split subject-views, :func:`subject_split`) it relights
the field under an environment of :class:`EnvironmentSampler` (procedural skies and rooms plus the real maps
of ``--hdri`` folders, default ``$KORNIA_ILUM_SHARED_DATA/{hdri,hdri_more}``; random rotation, flip, exposure
and white balance), composites it over that environment seen through the view's camera, auto-exposes and
encodes 8-bit sRGB (:func:`kornia_ilum_lab.synth.lightstage.preview.compose_portrait`), upscales the frame to
``--upscale`` pixels (bilinear with antialiasing; 0 keeps it: Haar's smallest window is 30 px and YuNet was
trained on larger faces, so 192-pixel frames with 96-pixel faces are upscaled by default), and runs YuNet and
OpenCV's Haar cascade on the full frame. A detection counts when one of its boxes overlaps the true face box
(the projected face landmarks' box, brow tops to chin and ear to ear) with IoU >= 0.3, or has its centre inside
it. Prints the detection rate per |yaw| bin (< 10, 10-20, 20-30, 30-35 degrees) and overall, and Haar's within
+-30 degrees, then within +-30 degrees by the subjects' look (glasses, facial hair, a hat, a fringe over an
eye). Targets: YuNet >= 95 %, Haar >= 85 % within +-30 degrees.

With fewer than ``--min-subjects`` eval subjects in the cache it says so; ``--render-eval K`` then renders the
first ``K`` eval seeds missing from it into the cache (``--source``, ``--views``, ``--size``, ``--spp``,
``--lighting-size``; resumable) before measuring.

This is a benchmark, not a test: it prints numbers and asserts nothing.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import torch
import torch.nn.functional as F

from kornia_ilum.detection import create_detector
from kornia_ilum_lab.synth.environments import EnvironmentSampler, default_sources
from kornia_ilum_lab.synth.environments.real import HDRFolderSource
from kornia_ilum_lab.synth.lightstage.cache import SampledViews, Workers, build_cache, read_field, read_manifest
from kornia_ilum_lab.synth.lightstage.preview import compose_portrait
from kornia_ilum_lab.synth.lightstage.settings import Auto
from kornia_ilum_lab.synth.lightstage.subjects import subject_split
from kornia_ilum_lab.synth.lightstage.subjects.makehuman import SWEPT_FRINGE_STYLES

BINS = ((0.0, 10.0), (10.0, 20.0), (20.0, 30.0), (30.0, 35.01))


def iou(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """IoU of boxes ``a`` ``(N, 4)`` with one box ``b`` ``(4,)``."""
    lo = torch.maximum(a[:, :2], b[:2])
    hi = torch.minimum(a[:, 2:4], b[2:4])
    inter = (hi - lo).clamp(min=0).prod(-1)
    area = lambda x: (x[..., 2] - x[..., 0]) * (x[..., 3] - x[..., 1])  # noqa: E731
    return inter / (area(a) + area(b) - inter)


def is_hit(dets: torch.Tensor, box: torch.Tensor, min_iou: float = 0.3) -> bool:
    """Whether a detection overlaps ``box`` with IoU >= ``min_iou`` or has its centre inside it."""
    if len(dets) == 0:
        return False
    cx, cy = (dets[:, 0] + dets[:, 2]) / 2, (dets[:, 1] + dets[:, 3]) / 2
    inside = (cx >= box[0]) & (cx <= box[2]) & (cy >= box[1]) & (cy <= box[3])
    return bool((iou(dets[:, :4], box) >= min_iou).any() or inside.any())


def yaw_bin(yaw: float) -> int:
    return next(i for i, (lo, hi) in enumerate(BINS) if lo <= abs(yaw) < hi)


def format_table(rows: list[dict], names: list[str]) -> str:
    """Detection rate per |yaw| bin and overall, per detector; Haar (opencv) also within +-30 degrees."""
    head = f"{'|yaw| (deg)':<14}{'renders':>8}" + "".join(f"{n:>10}" for n in names)
    lines = [head, "-" * len(head)]

    def line(label: str, sel: list[dict]) -> str:
        cells = "".join(f"{100 * sum(r[n] for r in sel) / len(sel):>9.1f}%" if sel else f"{'-':>10}" for n in names)
        return f"{label:<14}{len(sel):>8}" + cells

    for i, (lo, hi) in enumerate(BINS):
        lines.append(line(f"{lo:.0f}-{min(hi, 35):.0f}", [r for r in rows if r["bin"] == i]))
    lines.append(line("all", rows))
    lines.append(line("within +-30", [r for r in rows if abs(r["yaw"]) <= 30]))
    return "\n".join(lines)


def _appearance(params: dict) -> list[str]:
    """The groups a subject falls in for the by-appearance table (MakeHuman subjects' accessories and fringe)."""
    groups = []
    if params.get("glasses"):
        groups.append("glasses")
    if params.get("facial_hair", "none") != "none":
        groups.append("facial hair")
    if params.get("hat", "none") != "none":
        groups.append("hat")
    if params.get("fringe") == "swept" and params.get("hair") in SWEPT_FRINGE_STYLES:
        groups.append("fringe over an eye")
    return groups or ["none of these"]


def format_groups(rows: list[dict], names: list[str]) -> str:
    """Detection rate within +-30 degrees of yaw, by the subject's accessories."""
    near = [r for r in rows if abs(r["yaw"]) <= 30]
    head = f"{'within +-30, by look':<22}{'renders':>8}" + "".join(f"{n:>10}" for n in names)
    lines = [head, "-" * len(head)]
    for g in ("none of these", "glasses", "facial hair", "hat", "fringe over an eye"):
        sel = [r for r in near if g in r["groups"]]
        if sel:
            lines.append(f"{g:<22}{len(sel):>8}" + "".join(f"{100 * sum(r[n] for r in sel) / len(sel):>9.1f}%" for n in names))
    return "\n".join(lines)


def eval_entries(caches: list[Path]) -> list[dict]:
    """The EVAL-split entries of every cache, each with its ``"root"``, in subject-view order."""
    out = [dict(e, root=c) for c in caches for e in read_manifest(c)["entries"] if e.get("split") == "eval"]
    return sorted(out, key=lambda e: (e["subject_seed"], e["view_index"]))


def render_missing_eval(args: argparse.Namespace, have: set[int]) -> None:
    seeds, s = [], 0
    while len(seeds) < args.render_eval:
        if subject_split(s) == "eval" and s not in have:
            seeds.append(s)
        s += 1
    print(f"rendering eval seeds {seeds} into {args.cache[0]} ({args.views} views, {args.size} px, spp {args.spp}, "
          f"lighting {args.lighting_size})")
    build_cache(args.source, seeds, out_dir=args.cache[0],
                renderer=Auto(spp=args.spp, lighting_size=args.lighting_size),
                views=SampledViews(args.views, size=args.size), workers=Workers(processes=args.workers),
                summary=True)


def _shared() -> Path:
    return Path(os.environ.get("KORNIA_ILUM_SHARED_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))


def default_hdri() -> list[str]:
    root = _shared()
    return [str(root / d) for d in ("hdri", "hdri_more") if (root / d).is_dir()]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cache", required=True, type=Path, nargs="+",
                   help="reflectance-field caches (their eval subjects are pooled; --render-eval adds to the first)")
    p.add_argument("--count", type=int, default=120, help="renders (120)")
    p.add_argument("--upscale", type=int, default=512, help="frame side before detection (512; 0: as rendered)")
    p.add_argument("--hdri", nargs="*", default=None, help="folders of real maps (default: shared hdri, hdri_more)")
    p.add_argument("--detectors", nargs="+", default=["yunet", "opencv"], choices=("yunet", "opencv"))
    p.add_argument("--yunet-weights", default=None, help="other YuNet weights (default: the package's)")
    p.add_argument("--yunet-thresholds", type=float, nargs="*", default=[], metavar="T",
                   help="also YuNet with these confidence thresholds, and their false faces on face-free photos")
    p.add_argument("--max-side", type=int, nargs="*", default=[], metavar="N",
                   help="also run each detector on a copy of each frame at most N px on its longer side (the "
                   "fast path's downscaled detection; columns NAME@N), on the same renders")
    p.add_argument("--seed", type=int, default=0, help="environment seed (0)")
    p.add_argument("--min-subjects", type=int, default=10, help="eval subjects wanted (10)")
    p.add_argument("--render-eval", type=int, default=0, metavar="K", help="render K more eval seeds first")
    p.add_argument("--source", default="makehuman", help="subject source for --render-eval (makehuman)")
    p.add_argument("--views", type=int, default=4)
    p.add_argument("--size", type=int, default=192)
    p.add_argument("--spp", type=int, default=None, help="camera samples per pixel (the renderer's default)")
    p.add_argument("--lighting-size", type=int, default=32)
    p.add_argument("--workers", type=int, default=2)
    args = p.parse_args(argv)
    torch.set_num_threads(1)
    entries = eval_entries(args.cache)
    subjects = {e["subject_seed"] for e in entries}
    if args.render_eval:
        render_missing_eval(args, subjects)
        entries = eval_entries(args.cache)
        subjects = {e["subject_seed"] for e in entries}
    if len(subjects) < args.min_subjects:
        print(f"note: the cache has {len(subjects)} eval subjects ({len(entries)} subject-views), fewer than "
              f"{args.min_subjects}: renders repeat subject-views; add some with --render-eval K")
    if not entries:
        print("no eval subject-view in the cache: nothing to measure", file=sys.stderr)
        return 1
    folders = default_hdri() if args.hdri is None else args.hdri
    sources = default_sources() + [HDRFolderSource(f) for f in folders]
    sampler = EnvironmentSampler(sources, seed=args.seed)
    detectors = {}
    for name in args.detectors:
        kw = {"weights_path": args.yunet_weights} if name == "yunet" and args.yunet_weights else {}
        for side in [None, *args.max_side]:  # full size, then the same detector on downscaled copies
            detectors[name if side is None else f"{name}@{side}"] = create_detector(name, max_side=side, **kw)
        for threshold in args.yunet_thresholds if name == "yunet" else []:
            detectors[f"yunet>={threshold:g}"] = create_detector(name, confidence_threshold=threshold, **kw)

    rows, t0, fields = [], time.perf_counter(), {}
    seconds = {n: 0.0 for n in detectors}
    for i in range(args.count):
        e = entries[i % len(entries)]
        key = (e["root"], e["path"])
        if key not in fields:
            fields[key] = read_field(e["root"] / e["path"], dense=False)
        field = fields[key]
        env = sampler.sample(i)
        out = compose_portrait(field, env)
        image = out["image"].float()[None] / 255.0
        box = out["face_box"].clone()
        side = image.shape[-1]
        if args.upscale and args.upscale != side:
            image = F.interpolate(image, size=(args.upscale, args.upscale), mode="bilinear", antialias=True,
                                  align_corners=False).clamp(0, 1)
            box = box * (args.upscale / side)
        row = {"seed": e["subject_seed"], "view": e["view_index"], "yaw": e["camera"]["yaw_deg"],
               "bin": yaw_bin(e["camera"]["yaw_deg"]), "env": env.source, "groups": _appearance(e.get("params", {}))}
        for name, det in detectors.items():
            t = time.perf_counter()
            row[name] = is_hit(det.detect(image)[0], box)
            seconds[name] += time.perf_counter() - t
        rows.append(row)
    wall = time.perf_counter() - t0
    print(f"{len(rows)} renders of {len(subjects)} eval subjects ({len(entries)} subject-views) under "
          f"{len({r['env'] for r in rows})} kinds of environment ({', '.join(Path(f).name for f in folders) or 'procedural'}"
          f" + procedural); frames {side} px"
          + (f" upscaled to {args.upscale}" if args.upscale and args.upscale != side else "")
          + f"; {wall:.1f} s (" + ", ".join(f"{n} {1e3 * s / len(rows):.0f} ms/frame" for n, s in seconds.items())
          + ")")
    print("hit: IoU >= 0.3 with the face-landmark box, or the detection's centre inside it")
    print(format_table(rows, list(detectors)))
    print(format_groups(rows, list(detectors)))
    missed = [f"s{r['seed']}v{r['view']} yaw {r['yaw']:+.0f}" for r in rows if not all(r[n] for n in detectors)]
    if missed:
        print(f"missed by some detector ({len(missed)}): {', '.join(missed[:12])}{' ...' if len(missed) > 12 else ''}")
    if args.yunet_thresholds:
        print(false_faces({n: d for n, d in detectors.items() if n.startswith("yunet") and "@" not in n}))
    return 0


#: scikit-image's photographs without a human face (animals, objects, textures, scans), as the false faces'
#: test set: a cat, a horse's silhouette, a motorcycle's headlights, coffee, a rocket, coins, a clock, ...
FACE_FREE = ("chelsea", "horse", "stereo_motorcycle", "coffee", "rocket", "coins", "clock", "brick", "grass",
             "gravel", "moon", "page", "text", "logo", "retina", "colorwheel", "cell", "hubble_deep_field",
             "immunohistochemistry")


def face_free_photos() -> dict[str, torch.Tensor]:
    """scikit-image's face-free photographs of :data:`FACE_FREE` as ``(1, 3, H, W)`` in ``[0, 1]`` (those this
    scikit-image can give offline)."""
    import skimage.data  # lazy: only the false-face sections read scikit-image's photographs

    photos = {}
    for name in FACE_FREE:
        try:
            pixels = getattr(skimage.data, name)()
        except Exception:  # a photograph this scikit-image cannot give offline
            continue
        pixels = pixels[0] if isinstance(pixels, tuple) else pixels
        image = torch.from_numpy(pixels).float() / (1.0 if pixels.dtype == bool else 255.0)  # the horse: 0 / 1
        image = image[..., None].expand(-1, -1, 3) if image.dim() == 2 else image[..., :3]
        photos[name] = image.permute(2, 0, 1)[None].contiguous()
    return photos


def false_faces(detectors: dict) -> str:
    """For each detector, the face-free photographs of :data:`FACE_FREE` on which it finds a face, with the
    highest score of each."""
    lines = ["false faces on scikit-image's face-free photographs (highest score):"]
    photos = face_free_photos()
    for name, det in detectors.items():
        scores = {p: det.detect(x)[0][:, 4] for p, x in photos.items()}  # one detection per photo
        found = {p: float(v.max()) for p, v in scores.items() if len(v)}
        listed = ", ".join(f"{p} {v:.2f}" for p, v in sorted(found.items(), key=lambda kv: -kv[1]))
        lines.append(f"  {name}: {len(found)} of {len(photos)}{': ' + listed if listed else ''}")
    return "\n".join(lines)


if __name__ == "__main__":
    raise SystemExit(main())
