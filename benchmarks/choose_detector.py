"""Which face detector should be the default: Haar (``opencv``) against YuNet (``yunet``), measured as a user meets
them, on 640 x 480 photos at the detection sizes of the fast path.

Run: ``python benchmarks/choose_detector.py --cache /work/cache/mh192_eval [--hdri DIR ...] [--count 216]
[--frame 240] [--sides full 320 240 160] [--json OUT]``

**The photos.** Each of ``--count`` eval subject-views of the caches (spread evenly over them, so every Monk
tone, pose and accessory the eval split has is in) is relit under an environment of
:class:`~kornia_ilum_lab.synth.environments.EnvironmentSampler` (procedural skies and rooms and the real maps of
``--hdri``) over its background and encoded to 8-bit sRGB
(:func:`~kornia_ilum_lab.synth.lightstage.preview.compose_portrait`); the 192-pixel frame is resized to ``--frame``
pixels and centred on a black 640 x 480 canvas, as ``kornia-ilum bench`` builds its photo (a face of about half
the frame's side, 120 pixels at the default). The same subject-view is also made under a second environment
(another light) and shifted right by one pixel.

**Per detector and detection size** (``full``: the photo itself; ``N``: a copy of at most ``N`` pixels, as
``create_detector(name, max_side=N)`` and ``kornia-ilum estimate --detect-side N``):

- ``recall``: photos in which a box overlaps the true face box (the projected landmarks' box) with IoU >= 0.3 or
  has its centre inside it, within +-30 degrees of yaw and beyond, and per group of Monk tones;
- ``photos``: the two photographs of people that ship with scikit-image (the astronaut, and the cameraman, whose
  face is turned), each at four sizes (a face of 35 to 115 pixels) and mirrored, centred on the 640 x 480 canvas:
  in how many of the 16 a box hits the face (the faces' boxes as measured once at full size);
- ``false``: face-free photographs that ship with scikit-image (the 19 of ``benchmarks/bench_detection.py``)
  on which it finds a face;
- ``ms``: the median time of :meth:`~kornia_ilum.detection.FaceDetector.detect` on the 640 x 480 photo (one
  thread per core, as the CLI);
- ``box: light`` and ``box: 1 px``: how far the matched box moves when only the light changes, and when the
  photo moves by one pixel (the box's own move of one pixel taken out): the median and 90th percentile of the
  centre's move plus the side's change, in per cent of the box's side;
- ``estimate: light`` and ``estimate: 1 px``: how far that move takes the estimate: ``ours`` on the photo under
  the first light, from the crop of its own box against the crop of the box found under the second light (or
  on the shifted photo, moved back by the pixel), as the median ``|log E_a / E_b|`` of the lighting's energy, in
  per cent. Same photo, same light: only the box differs.

This is a benchmark, not a test: it prints numbers and asserts nothing; ``docs/bench.rst`` ("The default
detector") holds the run that chose the default.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import torch
import torch.nn.functional as F

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_detection import default_hdri, eval_entries, face_free_photos, iou, is_hit  # noqa: E402

from kornia_ilum.detection import create_detector, crop_faces, square_crop_boxes  # noqa: E402
from kornia_ilum.estimators import create_estimator  # noqa: E402
from kornia_ilum.metrics import total_radiance  # noqa: E402
from kornia_ilum_lab.synth.environments import EnvironmentSampler, default_sources  # noqa: E402
from kornia_ilum_lab.synth.environments.real import HDRFolderSource  # noqa: E402
from kornia_ilum_lab.synth.lightstage.cache import read_field  # noqa: E402
from kornia_ilum_lab.synth.lightstage.preview import compose_portrait  # noqa: E402

WIDTH, HEIGHT = 640, 480
TONE_GROUPS = ((1, 3), (4, 6), (7, 8), (9, 10))


def place(image: torch.Tensor, box: torch.Tensor, frame: int, shift: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
    """The ``(3, S, S)`` uint8 image resized to ``frame`` pixels and centred on a black 640 x 480 photo (cropped where
    larger: ``F.pad`` crops by negative amounts), moved right by ``shift`` pixels: the photo ``(1, 3, 480, 640)`` in
    ``[0, 1]`` and the face box in its pixels."""
    side = image.shape[-1]
    x = F.interpolate(image.float()[None] / 255.0, size=(frame, frame), mode="bilinear", antialias=True,
                      align_corners=False).clamp(0, 1)
    left, top = (WIDTH - frame) // 2 + shift, (HEIGHT - frame) // 2
    photo = F.pad(x, (left, WIDTH - frame - left, top, HEIGHT - frame - top))
    scale = frame / side
    return photo, box * scale + torch.tensor([left, top, left, top], dtype=box.dtype)


def matched(dets: torch.Tensor, box: torch.Tensor) -> torch.Tensor | None:
    """The detection that overlaps the true ``box`` most (``(4,)``), or ``None`` where none hits it."""
    if not is_hit(dets, box):
        return None
    return dets[int(iou(dets[:, :4], box).argmax()), :4]


def box_move(a: torch.Tensor, b: torch.Tensor) -> float:
    """How far box ``b`` is from box ``a``: the centre's move plus the change of the side, in per cent of ``a``'s side."""
    side = float(torch.sqrt((a[2] - a[0]) * (a[3] - a[1])))
    ca, cb = (a[:2] + a[2:]) / 2, (b[:2] + b[2:]) / 2
    sb = float(torch.sqrt((b[2] - b[0]) * (b[3] - b[1])))
    return 100.0 * (float(torch.linalg.vector_norm(ca - cb)) + abs(sb - side)) / side


def energy(estimator, photo: torch.Tensor, box: torch.Tensor, crop_scale: float) -> float:
    """The energy of ``ours``' estimate from the crop of ``box`` (``(4,)``) of ``photo``."""
    crop = crop_faces(photo, square_crop_boxes(box[None], scale=crop_scale), size=estimator.info.input_size)
    with torch.inference_mode():
        ball = estimator(crop).mirror_ball
    return float(total_radiance(ball.double()).mean())


#: scikit-image's photographs of people and their faces' boxes in the original pixels (the astronaut's as
#: tests/detection/test_detectors.py gives it; the cameraman's as YuNet finds it at full size, score 0.94).
PEOPLE = {"astronaut": (177.0, 62.0, 273.0, 170.0), "camera": (199.0, 111.0, 259.0, 197.0)}


def people_photos() -> list[tuple[str, torch.Tensor, torch.Tensor]]:
    """:data:`PEOPLE` at four scales, as they are and mirrored, centred on a black 640 x 480 canvas (:func:`place`;
    cropped where larger): ``(name, (1, 3, 480, 640) photo, face box)``."""
    import skimage.data

    out = []
    for name, face in PEOPLE.items():
        pixels = torch.from_numpy(getattr(skimage.data, name)())
        image = pixels[None].expand(3, -1, -1) if pixels.dim() == 2 else pixels.permute(2, 0, 1)
        side = image.shape[-1]
        box = torch.tensor(face)
        for scale in (0.35, 0.5, 0.7, 0.94):
            for mirrored in (False, True):
                x, b = (image.flip(-1), torch.stack([side - box[2], box[1], side - box[0], box[3]])) if mirrored \
                    else (image, box)
                photo, placed = place(x, b, round(side * scale))
                out.append((f"{name} x{scale}{' mirrored' if mirrored else ''}", photo, placed))
    return out


def pct(values: list[float], q: float) -> float:
    if not values:
        return float("nan")
    values = sorted(values)
    return values[min(len(values) - 1, int(q * len(values)))]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cache", required=True, type=Path, nargs="+", help="light-stage caches with eval subjects")
    p.add_argument("--hdri", nargs="*", default=None, help="folders of real maps (default: shared hdri, hdri_more)")
    p.add_argument("--count", type=int, default=216, help="subject-views (216: all of the eval cache's)")
    p.add_argument("--frame", type=int, default=240, help="the portrait's side in the 640 x 480 photo (240)")
    p.add_argument("--sides", nargs="+", default=["full", "320", "240", "160"], help="detection sizes")
    p.add_argument("--detectors", nargs="+", default=["yunet", "opencv"])
    p.add_argument("--seed", type=int, default=0, help="environment seed (0)")
    p.add_argument("--json", type=Path, default=None, help="also write the rows as JSON")
    args = p.parse_args(argv)

    entries = eval_entries(args.cache)
    if not entries:
        print("no eval subject-view in the caches: nothing to measure", file=sys.stderr)
        return 1
    picks = [entries[i * len(entries) // min(args.count, len(entries))] for i in range(min(args.count, len(entries)))]
    folders = default_hdri() if args.hdri is None else args.hdri
    sampler = EnvironmentSampler(default_sources() + [HDRFolderSource(f) for f in folders], seed=args.seed)
    configs = {}
    for name in args.detectors:
        for side in args.sides:
            max_side = None if side == "full" else int(side)
            configs[f"{name}@{side}"] = create_detector(name, max_side=max_side)
    estimator = create_estimator("ours", pretrained=True).eval()
    stats = {k: {"hit": [], "yaw": [], "tone": [], "light": [], "shift": [], "e_light": [], "e_shift": [], "ms": []}
             for k in configs}
    t0 = time.perf_counter()
    for i, e in enumerate(picks):
        field = read_field(e["root"] / e["path"], dense=False)
        shots = [compose_portrait(field, sampler.sample(2 * i + k)) for k in (0, 1)]
        photo_a, box = place(shots[0]["image"], shots[0]["face_box"], args.frame)
        photo_b, _ = place(shots[1]["image"], shots[1]["face_box"], args.frame)
        photo_s, box_s = place(shots[0]["image"], shots[0]["face_box"], args.frame, shift=1)
        for name, det in configs.items():
            s = stats[name]
            t = time.perf_counter()
            found_a = det.detect(photo_a)[0]
            s["ms"].append(1e3 * (time.perf_counter() - t))
            a = matched(found_a, box)
            s["hit"].append(a is not None)
            s["yaw"].append(abs(e["camera"]["yaw_deg"]))
            s["tone"].append(int(e.get("skin_tone", -1)))
            if a is None:
                continue
            b = matched(det.detect(photo_b)[0], box)
            shifted = matched(det.detect(photo_s)[0], box_s)
            ea = energy(estimator, photo_a, a, det.crop_scale)
            if b is not None:
                s["light"].append(box_move(a, b))
                s["e_light"].append(100 * abs(torch.log(torch.tensor(energy(estimator, photo_a, b, det.crop_scale)
                                                                      / ea)).item()))
            if shifted is not None:
                back = shifted - torch.tensor([1.0, 0.0, 1.0, 0.0])
                s["shift"].append(box_move(a, back))
                s["e_shift"].append(100 * abs(torch.log(torch.tensor(energy(estimator, photo_a, back, det.crop_scale)
                                                                      / ea)).item()))
        if (i + 1) % 24 == 0:
            print(f"  {i + 1} of {len(picks)} photos, {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    free = face_free_photos()
    false = {name: sorted(p for p, x in free.items() if len(det.detect(x)[0])) for name, det in configs.items()}
    people = people_photos()
    found = {name: [label for label, x, box in people if is_hit(det.detect(x)[0], box)]
             for name, det in configs.items()}

    rows = []
    for name, s in stats.items():
        hits = s["hit"]
        near = [h for h, y in zip(hits, s["yaw"], strict=True) if y <= 30]
        far = [h for h, y in zip(hits, s["yaw"], strict=True) if y > 30]
        tones = {f"{lo}-{hi}": [h for h, t in zip(hits, s["tone"], strict=True) if lo <= t <= hi]
                 for lo, hi in TONE_GROUPS}
        rows.append({
            "detector": name, "photos": len(hits),
            "recall_30": sum(near) / max(len(near), 1), "n_30": len(near),
            "recall_beyond": sum(far) / max(len(far), 1), "n_beyond": len(far),
            "recall_tones": {k: sum(v) / max(len(v), 1) for k, v in tones.items()},
            "people": found[name], "people_photos": len(people),
            "false": false[name], "face_free": len(free),
            "ms": statistics.median(s["ms"]),
            "box_light": (pct(s["light"], 0.5), pct(s["light"], 0.9)),
            "box_shift": (pct(s["shift"], 0.5), pct(s["shift"], 0.9)),
            "estimate_light": (pct(s["e_light"], 0.5), pct(s["e_light"], 0.9)),
            "estimate_shift": (pct(s["e_shift"], 0.5), pct(s["e_shift"], 0.9)),
        })
    print(f"{len(picks)} eval subject-views of {len({e['subject_seed'] for e in picks})} subjects, each in a 640 x 480 "
          f"photo ({args.frame}-pixel portrait), under two lights and shifted by a pixel; {len(free)} face-free "
          f"photographs; {time.perf_counter() - t0:.0f} s; torch threads {torch.get_num_threads()}")
    tone_head = " | ".join(f"tones {k}" for k in rows[0]["recall_tones"])
    print(f"\n| detector @ side | recall +-30 deg | beyond 30 | {tone_head} | photos of people | false faces | "
          "ms (640x480) | box: light (median / p90, %) | box: 1 px | estimate: light (%) | estimate: 1 px |")
    print("|---" * (11 + len(rows[0]["recall_tones"])) + "|")
    for r in rows:
        tones = " | ".join(f"{100 * v:.1f}" for v in r["recall_tones"].values())
        print(f"| {r['detector']} | {100 * r['recall_30']:.1f} ({r['n_30']}) | {100 * r['recall_beyond']:.1f} "
              f"({r['n_beyond']}) | {tones} | {len(r['people'])} of {r['people_photos']} | "
              f"{len(r['false'])} of {r['face_free']} | {r['ms']:.1f} | "
              f"{r['box_light'][0]:.1f} / {r['box_light'][1]:.1f} | {r['box_shift'][0]:.1f} / {r['box_shift'][1]:.1f} | "
              f"{r['estimate_light'][0]:.1f} / {r['estimate_light'][1]:.1f} | "
              f"{r['estimate_shift'][0]:.1f} / {r['estimate_shift'][1]:.1f} |")
    for r in rows:
        if r["false"]:
            print(f"false faces of {r['detector']}: {', '.join(r['false'])}")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
