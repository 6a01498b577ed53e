"""How ``L_rec`` charges a lighting that is too dark against one too bright by the same factor.

Run: ``python benchmarks/lrec_scale.py [--folder ../shared/data/hdri] [--maps N] [--mean 0.3]``

The maps of ``--folder`` (sorted by name; the first ``--maps`` of them) are brought to 32 x 32 mirror balls and each scaled
to a mean radiance of ``--mean`` over the ball (about what a metered portrait's lighting has in the photo's
units, where the soft clip at 1 matters). Each row is the mean ``L_rec`` per sphere
(:func:`kornia_ilum.metrics.reconstruction_loss`, the metric form) of the lighting times ``c`` against the
lighting itself. A loss symmetric in scale would give the same row for ``c`` and ``1 / c``; where ``c < 1``
costs less, training on it drifts towards too little light (docs/training.rst, "Why the energy drifts low,
and the energy term").

This is a measurement, not a test: it asserts nothing.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import torch

from kornia_ilum.geometry import latlong_to_mirror_ball, mirror_ball_valid
from kornia_ilum.io import read_hdr
from kornia_ilum.metrics import reconstruction_loss

BRDFS = ("diffuse", "matte_silver", "mirror")
FACTORS = (0.8, 1.25, 0.5, 2.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--folder", default=str(Path(__file__).parents[1] / ".." / "shared" / "data" / "hdri"))
    parser.add_argument("--maps", type=int, default=None, help="the first N maps (default: all)")
    parser.add_argument("--mean", type=float, default=0.3)
    args = parser.parse_args()
    files = sorted(p for p in Path(args.folder).iterdir() if p.suffix in (".exr", ".hdr"))[: args.maps]
    valid = mirror_ball_valid(32)
    balls = []
    for f in files:
        ball = latlong_to_mirror_ball(read_hdr(f)[None, :3], 32) * valid
        balls.append(ball * args.mean / (ball.sum() / (3 * valid.sum())))
    truth = torch.cat(balls)
    print(f"{len(files)} maps of {args.folder}, mean radiance {args.mean}; mean L_rec of c x truth")
    print("| c | " + " | ".join(BRDFS) + " |")
    print("|---:|" + "---:|" * len(BRDFS))
    for c in FACTORS:
        row = [float(reconstruction_loss(c * truth, truth, brdf=b, size=32).mean()) for b in BRDFS]
        print(f"| {c} | " + " | ".join(f"{v:.4f}" for v in row) + " |")


if __name__ == "__main__":
    main()
