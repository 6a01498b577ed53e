"""Does the encoder know the skin's albedo? A linear probe of ``ours``' bottleneck on the eval portraits.

Run: ``python benchmarks/probe_albedo.py --cache EVAL_CACHE ... --hdri ../shared/data/hdri ../shared/data/hdri_more
[--weights ours=RUN/ours.safetensors] [--samples 1024] [--json probe.json]``

The eval portraits of ``kornia-ilum evaluate`` (the same ``build_eval_set``) go through the estimator's raw
network (``OursEstimator.decode``), which gives its 1024-d bottleneck (``latent``) with the estimate. Ridge regressions from the
standardised bottleneck, fitted and scored by 5-fold cross-validation **over subjects** (no face is in both the
fit and the score), predict:

- ``log albedo``: the log of the subject's face albedo (the cache's ``face_albedo``, mean over R, G, B): does
  the encoder tell a dark skin from a light one under any light?
- ``log E``: the log of the true lighting's energy in the units of the crop after the network's exposure
  normalisation (``log E_true - log scale``): what the scale of the estimate has to be.

Each prints its cross-validated R^2 (1: perfect; 0: no better than the mean), and per Monk tone the median of
``exp(probe - truth)`` for ``log E`` beside the network's own ``E_pred / E_true``: where the probe's ratio is
flat across tones and the network's is not, the information is in the bottleneck and the head does not use it;
where both fall with the tone, the encoder does not carry it. The ridge's strength is the one of
``--alphas`` with the best cross-validated R^2 (reported with it).

This is a measurement on held-out portraits, not a test: it asserts nothing, and nothing is fitted for use.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np
import torch

from kornia_ilum.metrics import lighting_energy
from kornia_ilum_lab.evaluation import build_eval_set, load_checkpoint, load_estimator
from kornia_ilum_lab.evaluation.cli import parse_weights
from kornia_ilum_lab.synth.lightstage import read_manifest

FOLDS = 5


def bottleneck(estimator: torch.nn.Module, images: torch.Tensor, batch: int = 32
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The bottleneck of each crop, the estimate's log energy and the exposure normalisation's log scale, from
    one pass of :meth:`~kornia_ilum.estimators.OursEstimator.decode`."""
    latent, log_e, log_s = [], [], []
    with torch.inference_mode():
        for i in range(0, len(images), batch):
            out = estimator.decode(images[i : i + batch].float() / 255.0)
            latent.append(out.latent.float())
            log_e.append(lighting_energy(out.log_radiance.double().exp()).log())  # 0 solid angle off the ball
            log_s.append(out.log_scale.double().flatten())
    return torch.cat(latent).numpy(), torch.cat(log_e).numpy(), torch.cat(log_s).numpy()


def ridge_cv(x: np.ndarray, y: np.ndarray, groups: np.ndarray, alphas: list[float]) -> tuple[np.ndarray, float, float]:
    """Out-of-fold predictions of ridge regression, folds by group; the best alpha and its R^2."""
    ids = np.unique(groups)
    rng = np.random.default_rng(0)
    fold_of = dict(zip(rng.permutation(ids).tolist(), np.arange(len(ids)) % FOLDS, strict=True))
    fold = np.array([fold_of[g] for g in groups.tolist()])
    best = (None, -math.inf, None)
    for alpha in alphas:
        pred = np.empty_like(y)
        for f in range(FOLDS):
            fit, held = fold != f, fold == f
            mu, sd = x[fit].mean(0), x[fit].std(0) + 1e-6
            a = (x[fit] - mu) / sd
            w = np.linalg.solve(a.T @ a + alpha * np.eye(a.shape[1]), a.T @ (y[fit] - y[fit].mean()))
            pred[held] = ((x[held] - mu) / sd) @ w + y[fit].mean()
        r2 = 1.0 - float(((pred - y) ** 2).sum() / ((y - y.mean()) ** 2).sum())
        if r2 > best[1]:
            best = (pred, r2, alpha)
    return best[0], best[1], best[2]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cache", nargs="+", required=True)
    parser.add_argument("--hdri", nargs="*", default=[])
    parser.add_argument("--samples", type=int, default=1024)
    parser.add_argument("--weights", type=parse_weights, default=None,
                        help="ours=FILE: a run's weights instead of the shipped ones")
    parser.add_argument("--alphas", type=float, nargs="+", default=[1.0, 10.0, 100.0, 1000.0, 10000.0])
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    if args.weights:
        estimator = load_checkpoint(*args.weights)[0]
    else:
        estimator = load_estimator("ours")
    eval_set = build_eval_set(args.cache, args.hdri, samples=args.samples)
    albedo = {}
    for cache in args.cache:
        for entry in read_manifest(cache)["entries"]:
            if entry.get("face_albedo"):
                albedo[int(entry["subject_seed"])] = float(np.mean(entry["face_albedo"]))
    latent, log_pred, log_scale = bottleneck(estimator, eval_set.images)
    subjects = np.array(eval_set.subject_seed)
    tones = np.array(eval_set.skin_tone)
    log_albedo = np.log([albedo[s] for s in subjects.tolist()])
    log_true = lighting_energy(eval_set.mirror_ball.double()).log().numpy()
    report: dict = {"samples": len(eval_set), "subjects": len(set(subjects.tolist()))}
    pred_a, r2_a, alpha_a = ridge_cv(latent, log_albedo, subjects, args.alphas)
    pred_e, r2_e, alpha_e = ridge_cv(latent, log_true - log_scale, subjects, args.alphas)
    own = log_pred - log_scale
    r2_own = 1.0 - float(((own - (log_true - log_scale)) ** 2).sum()
                         / (((log_true - log_scale) - (log_true - log_scale).mean()) ** 2).sum())
    report["log_albedo"] = {"r2": r2_a, "alpha": alpha_a}
    report["log_energy"] = {"r2_probe": r2_e, "alpha": alpha_e, "r2_network": r2_own}
    print(f"{len(eval_set)} portraits of {report['subjects']} eval subjects; folds over subjects: {FOLDS}")
    print(f"log albedo from the bottleneck: R^2 {r2_a:.3f} (alpha {alpha_a:g})")
    print(f"log E (normalised) from the bottleneck: R^2 {r2_e:.3f} (alpha {alpha_e:g}); the network's own: "
          f"R^2 {r2_own:.3f}")
    print(f"{'tone':>4} {'n':>4} {'albedo':>7} {'probe albedo':>12} {'probe E/true':>12} {'network E/true':>14}")
    rows = {}
    for t in sorted(set(tones.tolist())):
        m = tones == t
        row = {"count": int(m.sum()), "albedo": float(np.exp(np.median(log_albedo[m]))),
               "probe_albedo": float(np.exp(np.median(pred_a[m]))),
               "probe_e_over_true": float(np.exp(np.median(pred_e[m] - (log_true - log_scale)[m]))),
               "network_e_over_true": float(np.exp(np.median(log_pred[m] - log_true[m])))}
        rows[str(t)] = row
        print(f"{t:>4} {row['count']:>4} {row['albedo']:>7.3f} {row['probe_albedo']:>12.3f} "
              f"{row['probe_e_over_true']:>12.3f} {row['network_e_over_true']:>14.3f}")
    report["per_tone"] = rows
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=1) + "\n")


if __name__ == "__main__":
    main()
