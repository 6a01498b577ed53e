"""What in a portrait's frame tells a dark skin under much light from a light skin under less (issue 47).

Run: ``python benchmarks/what_tells_the_tone.py --cache EVAL_CACHE --hdri ../shared/data/hdri
../shared/data/hdri_more [--samples 512]``

An auto-exposed photo brings every face to about the same brightness, so the face alone says little of its
tone; what the same light falls on, whose reflectance has nothing to do with the skin, can. This builds the
eval split's portraits (:func:`~kornia_ilum_lab.evaluation.evaluate.build_eval_set`, the same subjects, maps
and draws every time) as wide context crops (1.4 times the usual crop: as much of the 192-pixel render as a
crop holds) three ways: in front of the far environment (the light stage's default), in front of a plain
backdrop, and with near surfaces lit by the same environment (``surroundings=1``: a wall behind, a floor or
table below; :mod:`kornia_ilum_lab.synth.surroundings`). From each 8-bit photo, made linear, it takes the
face's mean luminance (the subject's matte above one half, in the crop's central half) and the background's
(matte below 0.02), and regresses the subject's Monk tone (1 light ... 10 dark) on ``log(face / background)``
by least squares: the R^2 over portraits says how much of the tone that ratio tells (issue 47 measured 0.12
for the far background and 0.86 for a plain wall on a held-out scanned head). A measurement, not a test.
"""

from __future__ import annotations

import argparse

import kornia
import torch

from kornia_ilum.color import LUMINANCE, srgb_to_linear
from kornia_ilum_lab.evaluation.evaluate import build_eval_set

KINDS = {"far environment": {}, "plain backdrop": {"plain_background": 1.0},
         "wall and floor": {"surroundings": 1.0}}


def log_ratios(images: torch.Tensor, alpha: torch.Tensor) -> torch.Tensor:
    """``log(face / background)`` mean linear luminance per photo (module docstring), float64 ``(N,)``."""
    linear = srgb_to_linear(images.double() / 255.0)
    y = kornia.color.rgb_to_grayscale(linear, torch.tensor(LUMINANCE, dtype=linear.dtype))[:, 0]
    a = alpha[:, 0].double() / 255.0
    s = a.shape[-1]
    centre = torch.zeros_like(a, dtype=torch.bool)
    centre[:, s // 4 : 3 * s // 4, s // 4 : 3 * s // 4] = True
    face, back = (a > 0.5) & centre, a < 0.02
    mean_face = (y * face).sum((1, 2)) / face.sum((1, 2)).clamp(min=1)
    mean_back = (y * back).sum((1, 2)) / back.sum((1, 2)).clamp(min=1)
    return torch.log(mean_face.clamp(min=1e-6) / mean_back.clamp(min=1e-6))


def r_squared(x: torch.Tensor, y: torch.Tensor) -> float:
    """R^2 of the least-squares line ``y ~ a x + b``."""
    design = torch.stack([x, torch.ones_like(x)], -1)
    coef = torch.linalg.lstsq(design, y[:, None]).solution
    residual = y - (design @ coef)[:, 0]
    return float(1.0 - residual.var() / y.var())


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cache", nargs="+", required=True, help="light-stage caches (their eval subjects)")
    parser.add_argument("--hdri", nargs="*", default=[], help="folders of real maps (their eval maps)")
    parser.add_argument("--samples", type=int, default=512, help="portraits per kind (512)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    print("| background | portraits | R^2 of tone on log(face / background) "
          "| median log ratio, tones 1 ... 10 |")
    print("|---|---:|---:|---|")
    for kind, settings in KINDS.items():
        data = build_eval_set(args.cache, args.hdri, samples=args.samples, size=128, context=1.4,
                              portraits=settings)
        ratio = log_ratios(data.images, data.alpha)
        tone = torch.tensor(data.skin_tone, dtype=torch.float64)
        known = tone > 0
        per_tone = [f"{ratio[tone == t].median():+.2f}" if bool((tone == t).any()) else "-"
                    for t in range(1, 11)]
        print(f"| {kind} | {int(known.sum())} | {r_squared(ratio[known], tone[known]):.2f} | "
              f"{', '.join(per_tone)} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
