"""The light's strength per skin tone from the face alone, the scene branch alone and the two fused (issue 47).

Run: ``python benchmarks/scene_strength.py --cache EVAL_CACHE --hdri ../shared/data/hdri ../shared/data/hdri_more
--scene runs/scene/scene.safetensors [--weights ours.safetensors] [--samples 512]``

The eval split's portraits with their whole frames (:func:`~kornia_ilum_lab.evaluation.evaluate.build_eval_set`
with ``frame=128``: the same subjects, maps and draws every time), four ways: in front of the far environment,
in front of a plain backdrop, with a wall and a floor lit by the same environment (``surroundings=1``), and with
a second subject beside (``companions=1``). For
each: :func:`~kornia_ilum_lab.evaluation.scene.scene_check`, the median of the estimated over the true energy per
Monk tone, the tone spread (largest over smallest per-tone median) with its 95 % interval over subjects, and how
often the truth lies within one spread of each estimate (nominal 0.63). A measurement, not a test.
"""

from __future__ import annotations

import argparse

import torch
from kornia_ilum_lab.evaluation.evaluate import build_eval_set, load_estimator
from kornia_ilum_lab.evaluation.scene import NOMINAL_COVERAGE, scene_check

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


if __name__ == "__main__":
    main()
