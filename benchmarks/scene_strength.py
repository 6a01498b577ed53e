"""The light's strength per skin tone from the face alone, the scene branch alone and the two fused (issue 47).

Run: ``python benchmarks/scene_strength.py --cache EVAL_CACHE --hdri ../shared/data/hdri ../shared/data/hdri_more
--scene runs/scene/scene.safetensors [--weights ours.safetensors] [--samples 512]``

The eval split's portraits with their whole frames (:func:`~kornia_ilum_lab.evaluation.evaluate.build_eval_set`
with ``frame=128``: the same subjects, maps and draws every time), four ways: in front of the far environment,
in front of a plain backdrop, with a wall and a floor lit by the same environment (``surroundings=1``), and with
a second subject beside (``companions=1``). For
each: :func:`~kornia_ilum_lab.evaluation.scene.scene_check`, the median of the estimated over the true energy per
Monk tone, the tone spread (largest over smallest per-tone median) with its 95 % interval over subjects, and how
often the truth lies within one spread of each estimate (nominal 0.63).

**Two faces under one light** (a group photo, FAIR's design): the far-environment set again with the eval
fields rotated by half their number, so that each portrait's draws (lighting, exposure key, crop, camera) are the
same and its subject another (the truths then differ by the exposure alone: checked). Per pair, the absolute
difference of the two faces' log ratios (estimated over true energy, which the exposure does not change), each
face estimated alone: today's within-photo disagreement; one strength per photo
(:func:`~kornia_ilum.estimators.fuse_strength` with the photo's faces) makes it 0 by construction, so what is
reported beside it is the error of that one strength (the faces' and the mean scene estimate pooled by inverse
variance). A measurement, not a test.
"""

from __future__ import annotations

import argparse

import torch
from kornia_ilum_lab.evaluation.evaluate import EvalSet, build_eval_set, load_estimator
from kornia_ilum_lab.evaluation.scene import NOMINAL_COVERAGE, scene_check
from kornia_ilum_lab.evaluation.split import eval_fields

from kornia_ilum.estimators.scene import SCENE_SIZE, SceneStrength

KINDS = {"far environment": {}, "plain backdrop": {"plain_background": 1.0},
         "wall and floor": {"surroundings": 1.0}, "a companion beside": {"companions": 1.0}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cache", nargs="+", required=True)
    parser.add_argument("--hdri", nargs="*", default=[])
    parser.add_argument("--scene", required=True,
                        help="the scene branch's weights (kornia-ilum train --estimator scene)")
    parser.add_argument("--weights", default=None, help="ours' weights (default: the shipped)")
    parser.add_argument("--samples", type=int, default=512)
    args = parser.parse_args()
    face = load_estimator("ours", args.weights)
    scene = SceneStrength.from_file(args.scene)
    print(f"# The strength per skin tone: face, scene, fused ({args.samples} eval portraits per kind)\n")
    for kind, portraits in KINDS.items():
        eval_set = build_eval_set(args.cache, args.hdri, samples=args.samples,
                                  portraits={**portraits, "frame": SCENE_SIZE})
        with torch.inference_mode():
            result = scene_check(face, scene, eval_set)
        table = result["table"]
        tones = [g for g in table if g != "all"]
        print(f"## {kind}\n")
        print("| estimate | " + " | ".join(f"tone {t}" for t in tones) + " | tone spread [95 %] | within 1 spread |")
        print("|---|" + "---:|" * (len(tones) + 2))
        for k in ("face", "scene", "fused"):
            spread = result["tone_spread"][k]
            low, high = spread["interval"]
            print(f"| {k} | " + " | ".join(f"{table[t][k]['ratio']:.2f}" for t in tones)
                  + f" | {spread['ratio']:.2f} [{low:.2f}, {high:.2f}] | {table['all'][k]['coverage']:.2f} |")
        print(f"\nwithin one spread, per tone (nominal {NOMINAL_COVERAGE:.2f}):\n")
        for k in ("face", "scene", "fused"):
            print(f"- {k}: " + ", ".join(f"{t}: {table[t][k]['coverage']:.2f}" for t in tones))
        print()
        if kind == "far environment":
            first = (eval_set, result)
    groups(args, face, scene, *first)


def groups(args: argparse.Namespace, face: torch.nn.Module, scene: SceneStrength, first: EvalSet,
           one: dict) -> None:
    """The two-faces-under-one-light part of the module docstring."""
    fields = eval_fields(args.cache)
    half = len(fields) // 2
    second = build_eval_set([], args.hdri, samples=args.samples, fields=fields[half:] + fields[:half],
                            portraits={"frame": SCENE_SIZE})
    with torch.inference_mode():
        two = scene_check(face, scene, second)
    valid = first.mirror_ball[0, 0] > 0
    gain = first.mirror_ball[:, :, valid] / second.mirror_ball[:, :, valid].clamp(min=1e-12)
    same_light = float((gain / gain.median(-1, keepdim=True).values - 1).abs().median())
    other = [a != b for a, b in zip(first.subject_seed, second.subject_seed, strict=True)]
    log = {k: torch.stack([torch.log(r["samples"][k]["ratio"]) for r in (one, two)]) for k in ("face", "scene")}
    w = {k: torch.stack([r["samples"][k]["spread"] for r in (one, two)]) ** -2 for k in ("face", "scene")}
    today = (log["face"][0] - log["face"][1]).abs()
    faces = (w["face"] * log["face"]).sum(0) / w["face"].sum(0)
    w_scene = w["scene"].mean(0)  # one scene: the two views' mean, counted once
    pooled = ((w["face"] * log["face"]).sum(0) + w_scene * log["scene"].mean(0)) / (w["face"].sum(0) + w_scene)
    print(f"## Two faces under one light ({len(today)} pairs; other subject in {sum(other)}; the truths' "
          f"per-pixel ratio off constant by {same_light:.1e} in the median)\n")
    print("| | mean abs. difference of the faces' log ratios | median abs. log ratio of the photo's strength |")
    print("|---|---:|---:|")
    print(f"| each face alone (today) | {float(today.mean()):.3f} | "
          f"{float(log['face'].abs().median()):.3f} (each face's) |")
    print(f"| one strength, the two faces pooled | 0 | {float(faces.abs().median()):.3f} |")
    print(f"| one strength, faces and scene pooled | 0 | {float(pooled.abs().median()):.3f} |\n")


if __name__ == "__main__":
    main()
