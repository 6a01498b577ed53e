"""What exposure normalisation at inference costs and gives: ``sh`` and ``sipr`` with and without it.

Run: ``python benchmarks/exposure_by_design.py --cache EVAL_CACHE ... --hdri ../shared/data/hdri
../shared/data/hdri_more [--samples 1024] [--estimator sh sipr]``

For each estimator, the shipped weights twice: as trained (``normalize_exposure=False``) and by design
(``True``: the crop re-exposed to a metered 0.18, the estimate scaled back; the default since issue 39). Both
are scored on the same eval portraits of ``kornia-ilum evaluate`` (``L_rec`` per sphere, and the paired
difference with its 95 % interval, :func:`kornia_ilum_lab.evaluation.paired_differences`), and on exposure
equivariance, ``E(k x) / (k E(x))`` at ``k = 0.5`` and ``0.25``, median over the eval crops and over the real
photos of the evaluation (scikit-image's astronaut). The shipping rule of issue 39 lets a change through when
diffuse and matte silver ``L_rec`` rise by at most 3 % (relative) and mirror by at most 10 %.

This is a measurement, not a test: it asserts nothing.
"""

from __future__ import annotations

import argparse

import torch

from kornia_ilum.estimators import create_estimator
from kornia_ilum_lab.evaluation import (
    BRDF_NAMES,
    build_eval_set,
    default_photos,
    exposure_equivariance,
    face_crops,
    paired_differences,
    predict,
    score,
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cache", nargs="+", required=True)
    parser.add_argument("--hdri", nargs="*", default=[])
    parser.add_argument("--samples", type=int, default=1024)
    parser.add_argument("--estimator", nargs="+", default=["sh", "sipr"])
    args = parser.parse_args()
    eval_set = build_eval_set(args.cache, args.hdri, samples=args.samples)
    photos = face_crops(default_photos())[0]
    print(f"{len(eval_set)} eval portraits; {len(photos)} real photo(s)")
    for name in args.estimator:
        scores = {}
        for design in (False, True):
            estimator = create_estimator(name, normalize_exposure=design)
            pred = predict(estimator, eval_set.images)
            scores[design] = score(pred, eval_set.mirror_ball)
            on_eval = exposure_equivariance(estimator, eval_set.images, prediction=pred)["table"]
            on_photos = exposure_equivariance(estimator, photos)["table"]
            rec = " / ".join(f"{float(scores[design][b].mean()):.4f}" for b in BRDF_NAMES)
            eq = ", ".join(f"k={k}: eval {on_eval[k]['median']:.3f}, photos {on_photos[k]['median']:.3f}"
                           for k in on_eval)
            print(f"{name} normalize_exposure={design}: L_rec {rec}; E(kx)/(kE(x)) {eq}")
        paired = paired_differences(scores[True], scores[False])
        rel = {b: float(scores[True][b].mean() / scores[False][b].mean()) - 1 for b in BRDF_NAMES}
        print(f"{name} by design - as trained: " + "; ".join(
            f"{b} {p['mean']:+.4f} [{p['low']:+.4f}, {p['high']:+.4f}] ({100 * rel[b]:+.1f} %)"
            for b, p in paired.items()))


if __name__ == "__main__":
    torch.set_grad_enabled(False)
    main()
