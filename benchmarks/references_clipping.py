"""Whether the eval portraits show the references a face carries, per Monk tone: clipped pixels with and without
the camera's highlight roll-off.

Run: ``python benchmarks/references_clipping.py --cache EVAL_CACHE ... --hdri ../shared/data/hdri
../shared/data/hdri_more [--samples 1024]``

The exposure meters the face, so the darker the skin, the brighter everything else is in the photo: the whites
of the eyes (0.36 linear, ten times the skin's albedo at tone 10), the teeth, the specular highlights and the
background, the references for the strength of the light. An 8-bit encoding that clips at white loses them where
they are needed most. The same eval portraits of ``kornia-ilum evaluate`` (same subjects, views, lightings, crops
and camera draws) are built twice, with the camera's roll-off (``CameraEffects()``, the default since issue 39:
half the photos) and without it (``rolloff_p=0``); for each tone the share of the subject's pixels (its matte)
and of the background's that have a channel at code 255, and the share of photos with more than 1 % of the
subject's pixels clipped.

This is a measurement, not a test: it asserts nothing.
"""

from __future__ import annotations

import argparse

import torch

from kornia_ilum_lab.evaluation import build_eval_set
from kornia_ilum_lab.synth.camera_effects import CameraEffects


def clipped_shares(images: torch.Tensor, alpha: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Per image: the share of subject pixels and of background pixels with a channel at 255."""
    clipped = (images == 255).any(1).float()
    subject = (alpha[:, 0] >= 128).float()
    share = lambda w: (clipped * w).sum((1, 2)) / w.sum((1, 2)).clamp(min=1.0)  # noqa: E731
    return share(subject), share(1.0 - subject)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cache", nargs="+", required=True)
    parser.add_argument("--hdri", nargs="*", default=[])
    parser.add_argument("--samples", type=int, default=1024)
    args = parser.parse_args()
    rows = {}
    for name, camera in (("roll-off off", CameraEffects(rolloff_p=0.0)), ("default", CameraEffects())):
        eval_set = build_eval_set(args.cache, args.hdri, samples=args.samples, portraits={"camera": camera})
        rows[name] = clipped_shares(eval_set.images, eval_set.alpha)
    tones = torch.tensor(eval_set.skin_tone)
    print(f"{len(tones)} eval portraits; share of pixels at code 255 (subject / background), and of photos with "
          "over 1 % of the subject clipped")
    print("tone | " + " | ".join(f"{name}: subject, background, photos" for name in rows))
    for tone in sorted(set(tones.tolist())):
        sel = tones == tone
        cells = [f"{float(s[sel].mean()):.4f}, {float(b[sel].mean()):.3f}, {float((s[sel] > 0.01).float().mean()):.2f}"
                 for s, b in rows.values()]
        print(f"{tone:>4} | " + " | ".join(cells))


if __name__ == "__main__":
    torch.set_grad_enabled(False)
    main()
