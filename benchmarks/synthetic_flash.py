"""The real-flash check's flashes rendered on the light stage's own faces: whose error is it?

Run: ``python benchmarks/synthetic_flash.py --cache EVAL_CACHE --flash ../shared/data/yaleb_dev
[--views 12] [--estimator ours] [--weights FILE ...]``

The real-flash check (:mod:`kornia_ilum_lab.evaluation.flash`) finds every estimator putting near-frontal
flashes far above where they are. This renders the same flashes (their directions only, read from the
photographs' names) on the eval cache's frontal views (``|yaw| <= 12`` degrees): one small white disk light
(2 degrees across) in a dark room (a uniform ambient of 1/100 of its irradiance), exposed on the face and cut
through the view's face box as training crops are, and feeds each estimator three versions of each photo:

- ``colour``: the photo as rendered (sRGB);
- ``greyscale``: its luma in all three channels (:func:`~kornia_ilum_lab.synth.colour_looks.greyscale`);
- ``linear grey``: the greyscale photo's values made linear (a camera with a linear response, as the
  real-flash photographs have), fed as they are.

It prints, per estimator and version, the median direction error over all flashes and within 25 degrees of the
camera axis, the elevation bias there (estimate minus flash) and the up/down sign agreement; then, in colour,
the estimated elevation of flashes straight in front of the face at elevations from 40 degrees below the eyes
to 45 above (:data:`SWEEP_DEG`; the range over the views), which shows whether an estimator can put a light
below the eyes at all. A bias that the
rendered faces share with the real photographs is the estimator's (its prior, its reading of shading); one
that only the real photographs show is theirs (real skin, the database's crops). A measurement, not a test.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import torch
from kornia_ilum_lab.evaluation.evaluate import load_estimator
from kornia_ilum_lab.evaluation.flash import SIGN_MARGIN_DEG, flash_direction, load_flash_set
from kornia_ilum_lab.evaluation.measures import angle_degrees, estimates
from kornia_ilum_lab.synth.colour_looks import greyscale
from kornia_ilum_lab.synth.environments import Environment
from kornia_ilum_lab.synth.environments.sky import splat_disk
from kornia_ilum_lab.synth.lightstage.cache import read_field, read_manifest
from kornia_ilum_lab.synth.lightstage.preview import compose_portrait

from kornia_ilum.color import srgb_to_linear
from kornia_ilum.detection.crop import CROP_SCALE, crop_faces, square_crop_boxes
from kornia_ilum.geometry import latlong_to_mirror_ball

AMBIENT = 0.01  # the room's irradiance on any surface, a fraction of the flash's at normal incidence
SWEEP_DEG = (-40.0, -25.0, -15.0, 0.0, 20.0, 45.0)  # flashes straight in front (azimuth 0), by elevation
RADIUS = math.radians(1.0)


def flash_environment(direction: torch.Tensor, height: int = 64) -> Environment:
    """One white disk of irradiance 1 along ``direction`` over a uniform ambient of irradiance ``AMBIENT``."""
    latlong = torch.full((3, height, 2 * height), AMBIENT / math.pi)
    splat_disk(latlong, direction.tolist(), RADIUS, torch.ones(3))
    ball = latlong_to_mirror_ball(latlong[None], 32)[0].clamp(min=0.0)
    return Environment(latlong, ball, "indoor", "flash:synthetic")


def elevation(d: torch.Tensor) -> torch.Tensor:
    return torch.rad2deg(torch.asin(d[:, 1].clamp(-1.0, 1.0)))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cache", required=True, help="a light-stage cache (the eval split's)")
    parser.add_argument("--flash", required=True, help="the real-flash folder (only its names are read)")
    parser.add_argument("--views", type=int, default=12, help="frontal views to render (12)")
    parser.add_argument("--estimator", default="ours")
    parser.add_argument("--weights", nargs="*", default=[None], help="weight files (default: the shipped)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    flashes = load_flash_set(args.flash)
    pairs = sorted({(float(a), float(e))
                    for a, e in zip(flashes.azimuth, flashes.elevation, strict=True)})
    sweep = len(pairs)
    pairs += [(0.0, e) for e in SWEEP_DEG]
    angles = torch.tensor(pairs, dtype=torch.float64)
    dirs = flash_direction(angles[:, 0], angles[:, 1])
    root = Path(args.cache)
    entries = read_manifest(root)["entries"]
    crops, truth = [], []
    for entry in entries:
        if len(crops) >= args.views * len(dirs):
            break
        field = read_field(root / entry["path"], dense=False)
        if abs(field.camera.yaw_deg) > 12.0:
            continue
        box = square_crop_boxes(field.face_box[None].float(), CROP_SCALE)
        for d in dirs:
            shot = compose_portrait(field, flash_environment(d.float()))
            crops.append(crop_faces(shot["image"][None].float() / 255.0, box, size=256)[0])
            truth.append(d)
    if not crops:
        print("no frontal view in the cache", file=sys.stderr)
        return 1
    views = len(crops) // len(dirs)
    images = torch.stack(crops).reshape(views, len(dirs), *crops[0].shape)
    swept = images[:, sweep:].reshape(-1, *crops[0].shape)  # (views x sweep): the straight-ahead flashes
    colour = images[:, :sweep].reshape(-1, *crops[0].shape)
    grey = greyscale(colour)
    versions = {"colour": colour, "greyscale": grey, "linear grey": srgb_to_linear(grey)}
    truth_d = torch.stack(truth).reshape(views, len(dirs), 3)[:, :sweep].reshape(-1, 3)
    dirs = dirs[:sweep]
    axis = torch.rad2deg(torch.acos(truth_d[:, 2].clamp(-1.0, 1.0)))
    front, off = axis < 25.0, truth_d[:, 1].abs() > math.sin(math.radians(SIGN_MARGIN_DEG))
    print(f"{views} frontal views x {len(dirs)} flashes = {len(colour)} crops; "
          f"{int(front.sum())} within 25 degrees of the camera axis")
    print("| estimator | version | all | within 25 | elevation bias, within 25 | up/down |")
    print("|---|---|---:|---:|---:|---:|")
    loaded = {}  # name -> estimator, loaded once for both tables
    for weights in args.weights:
        name = args.estimator if weights is None else f"{args.estimator}@{Path(weights).name}"
        est = loaded[name] = load_estimator(args.estimator, weights)
        for version, images in versions.items():
            batches = (images[i:i + 64] for i in range(0, len(images), 64))
            _, pred, _ = estimates(est, batches, directions=True)
            err = angle_degrees(pred, truth_d)
            bias = (elevation(pred) - elevation(truth_d))[front].median()
            up_down = ((pred[:, 1] > 0) == (truth_d[:, 1] > 0))[off].double().mean()
            print(f"| {name} | {version} | {err.median():.1f} | {err[front].median():.1f} | {bias:+.1f} | "
                  f"{up_down:.3f} |", flush=True)
    print("\nStraight in front, in colour: the estimated elevation (degrees; lowest to highest over the views)")
    print("| estimator | " + " | ".join(f"flash {e:+.0f}" for e in SWEEP_DEG) + " |")
    print("|---|" + "---:|" * len(SWEEP_DEG))
    for name, est in loaded.items():
        _, pred, _ = estimates(est, iter([swept]), directions=True)
        el = elevation(pred).reshape(views, len(SWEEP_DEG))
        cells = [f"{float(c.min()):+.0f} to {float(c.max()):+.0f}" for c in el.T]
        print(f"| {name} | " + " | ".join(cells) + " |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
