"""Do the eyes and the mouth tell the skin's albedo? The references probe of issue 47, before any branch for them.

Run: ``python benchmarks/references_probe.py --cache TRAIN_CACHE EVAL_CACHE --hdri ../shared/data/hdri
../shared/data/hdri_more [--samples 4096] [--json probe.json]``

The sclera, the teeth and the skin's specular sheen reflect the same light whatever the skin's melanin, so their
brightness against the skin's could tell a dark skin under much light from a light skin under less. Portraits
of the light stage (``PortraitDataset``: eval environments, the camera's effects, crops of 256 pixels, about the
renders' own resolution: an eye is some 20 pixels wide) of every subject of the caches, and from each crop
**landmark-aligned patches** at the landmarks the light stage knows (YuNet gives the same five at inference:
both eyes, the mouth's corners): each eye (a square 1.4 times the eye's width), the mouth (1.2 times its
width) and, as a control that holds only skin, both cheeks; each resampled to 12 x 12, linearised, logged.
Ridge regressions from them predict the subject's log face albedo (the cache's ``face_albedo``, mean of R, G, B),
fitted and scored by 5-fold cross-validation **over subjects** (``probe_albedo.ridge_cv``: no face is in both
the fit and the score). A linear model of log pixels can form "log sclera minus log skin" exactly, which is what
the physics offers.

It prints R^2 per feature set. The issue's gate: a references branch is built only if eyes and mouth reach
R^2 >= 0.8. A measurement, not a test; nothing is fitted for use.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import torch
from kornia.geometry.transform import crop_and_resize
from kornia_ilum_lab.evaluation.split import eval_environment_sources
from kornia_ilum_lab.synth.environments import EnvironmentSampler
from kornia_ilum_lab.synth.lightstage import LANDMARK_NAMES, read_manifest
from kornia_ilum_lab.synth.lightstage.portraits import PortraitConfig, PortraitDataset, load_fields
from probe_albedo import ridge_cv

from kornia_ilum.color import srgb_to_linear

PATCH = 12
GATE = 0.8


def _at(name: str) -> int:
    return LANDMARK_NAMES.index(name)


def patches(crops: torch.Tensor, marks: torch.Tensor) -> dict[str, torch.Tensor]:
    """``{"eyes", "mouth", "cheeks"}``: ``(N, D)`` log linear patches of the crops ``(N, 3, S, S)`` (uint8) at
    their landmarks ``(N, L, 2)`` (crop pixels)."""
    linear = srgb_to_linear(crops.float() / 255.0)

    def square(centre: torch.Tensor, side: torch.Tensor) -> torch.Tensor:
        h = side[:, None] / 2
        x, y = centre[:, :1], centre[:, 1:]
        corners = torch.stack([torch.cat([x - h, y - h], 1), torch.cat([x + h, y - h], 1),
                               torch.cat([x + h, y + h], 1), torch.cat([x - h, y + h], 1)], 1)
        out = crop_and_resize(linear, corners, (PATCH, PATCH), mode="bilinear", align_corners=False)
        return torch.log(out.clamp(min=0.0) + 1e-3).flatten(1)

    def pair(a: str, b: str) -> tuple[torch.Tensor, torch.Tensor]:
        p, q = marks[:, _at(a)], marks[:, _at(b)]
        return (p + q) / 2, (p - q).norm(dim=1)

    (right, wr), (left, wl) = pair("eye_right_outer", "eye_right_inner"), pair("eye_left_outer", "eye_left_inner")
    mouth, wm = pair("mouth_right", "mouth_left")
    eye_width = (wr + wl) / 2
    first_left = right[:, 0] > left[:, 0]  # the eye on the image's left first (mirrored crops swap them)
    a = torch.where(first_left[:, None], left, right)
    b = torch.where(first_left[:, None], right, left)
    cheeks = [marks[:, _at("cheek_right")], marks[:, _at("cheek_left")]]
    cheeks = sorted(cheeks, key=lambda c: float(c[:, 0].mean()))
    return {"eyes": torch.cat([square(a, 1.4 * eye_width), square(b, 1.4 * eye_width)], 1),
            "mouth": square(mouth, 1.2 * wm),
            "cheeks": torch.cat([square(c, eye_width) for c in cheeks], 1)}


def portraits(caches: list[str], hdri: list[str], samples: int, size: int
              ) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray]:
    """The patches, the subjects' log albedo, their seeds and Monk tones, of ``samples`` portraits."""
    fields, albedo = [], {}
    for cache in caches:
        fields += load_fields(cache, split=None)
        for entry in read_manifest(cache)["entries"]:
            albedo[int(entry["subject_seed"])] = float(np.mean(entry["face_albedo"]))
    by_view = {(f.subject_seed, int(f.meta.get("view_index", -1))): f for f in fields}
    config = PortraitConfig(split=None, environments=EnvironmentSampler(eval_environment_sources(hdri), seed=5),
                            size=size, length=samples, sphere_sizes=())
    seeds, tones, crops, marks = [], [], [], []
    for s in PortraitDataset(fields, config, seed=5):
        rf = by_view[s["subject_seed"], s["view_index"]]
        lm = torch.tensor(rf.meta["landmarks"], dtype=torch.float64)
        if s["flip"]:
            lm[:, 0] = rf.size - lm[:, 0]  # in the mirrored image, as the crop box
        box = s["crop_box"].double()
        marks.append(((lm - box[:2]) * size / (box[2] - box[0])).float())
        crops.append(s["image"])
        seeds.append(int(s["subject_seed"]))
        tones.append(int(s["skin_tone"]))
    parts = [patches(torch.stack(crops[i : i + 256]), torch.stack(marks[i : i + 256]))
             for i in range(0, len(crops), 256)]
    out = {k: torch.cat([p[k] for p in parts]).numpy().astype(np.float64) for k in parts[0]}
    return out, np.log([albedo[s] for s in seeds]), np.array(seeds), np.array(tones)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cache", nargs="+", required=True, help="light-stage caches (train and eval subjects)")
    parser.add_argument("--hdri", nargs="*", default=[])
    parser.add_argument("--samples", type=int, default=4096)
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--alphas", type=float, nargs="+", default=[1.0, 10.0, 100.0, 1000.0, 10000.0])
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    feats, log_albedo, seeds, tones = portraits(args.cache, args.hdri, args.samples, args.size)
    sets = {"eyes": ["eyes"], "mouth": ["mouth"], "eyes + mouth": ["eyes", "mouth"],
            "cheeks (skin only, control)": ["cheeks"], "eyes + mouth + cheeks": ["eyes", "mouth", "cheeks"]}
    report = {"samples": len(seeds), "subjects": len(set(seeds.tolist())), "size": args.size, "patch": PATCH,
              "gate": GATE, "r2": {}}
    print("# The references probe: the skin's log albedo from landmark-aligned patches\n")
    print(f"{len(seeds)} portraits of {report['subjects']} subjects, crops of {args.size} px, patches "
          f"{PATCH} x {PATCH}; ridge, 5 folds over subjects\n")
    print("| features | R^2 | alpha | median albedo error (x) |\n|---|---:|---:|---:|")
    for name, parts in sets.items():
        x = np.concatenate([feats[p] for p in parts], 1)
        pred, r2, alpha = ridge_cv(x, log_albedo, seeds, args.alphas)
        error = float(np.exp(np.median(np.abs(pred - log_albedo))))
        report["r2"][name] = {"r2": r2, "alpha": alpha, "median_factor": error}
        print(f"| {name} | {r2:.3f} | {alpha:g} | {error:.2f} |")
        if name == "eyes + mouth":
            asked = pred
    print("\nPer Monk tone, eyes + mouth: the median albedo, true and predicted (held-out folds):\n")
    print("| tone | portraits | albedo | predicted |\n|---:|---:|---:|---:|")
    report["per_tone"] = {}
    for t in sorted(set(tones.tolist())):
        m = tones == t
        row = {"count": int(m.sum()), "albedo": float(np.exp(np.median(log_albedo[m]))),
               "predicted": float(np.exp(np.median(asked[m])))}
        report["per_tone"][str(t)] = row
        print(f"| {t} | {row['count']} | {row['albedo']:.3f} | {row['predicted']:.3f} |")
    r2 = report["r2"]["eyes + mouth"]["r2"]
    print(f"\nThe gate (eyes + mouth, R^2 >= {GATE}): {'reached' if r2 >= GATE else 'not reached'} ({r2:.3f}).")
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=1) + "\n")


if __name__ == "__main__":
    main()
