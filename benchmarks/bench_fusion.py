"""Several faces, one light: how far apart are the faces of one photo, against photos apart?

Run: ``python benchmarks/bench_fusion.py --cache CACHE [CACHE ...] --hdri DIR [DIR ...] [--chunks 64]
[--estimator ours]``

Light-stage portraits of the eval subjects (the caches' eval fields) under the eval environments, drawn by
the training data's own :class:`~kornia_ilum_lab.synth.lightstage.portraits.PortraitDataset` with one environment
per chunk (``env_pool = env_refresh = 1``): each chunk holds 8 subject views (drawn at random, so now and
then one twice) under one environment, each turned about the vertical axis and auto-exposed on its own, as
different faces of one photo would be placed and lit. Each portrait's estimate is scored by the log of its energy over the truth's,
``r = log(E_est / E_true)`` (:func:`~kornia_ilum.metrics.lighting_energy`), which the turn and the
exposure leave alone.

It prints the standard deviation of ``r`` within a chunk (the spread between the faces of one photo), the
spread of a photo's shared error between photos (the chunks' means, less the part of the within spread that
their 8 faces leave in them: ``between^2 = var(means) - within^2 / 8``), and what fusing ``k`` faces of a photo
leaves, assuming the within-photo part averages out: ``sqrt(between^2 + within^2 / k)`` against a single
face's ``sqrt(between^2 + within^2)``. Fusion helps as much as the within-photo spread dominates.

This is a benchmark, not a test.
"""

from __future__ import annotations

import argparse
import math

import torch

from kornia_ilum.estimators import create_estimator
from kornia_ilum.estimators.probe import fit_crops
from kornia_ilum.metrics import lighting_energy
from kornia_ilum_lab.evaluation.split import EVAL_SEED, eval_environment_sources, eval_fields
from kornia_ilum_lab.synth.environments import EnvironmentSampler
from kornia_ilum_lab.synth.lightstage.portraits import PortraitConfig, PortraitDataset


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cache", nargs="+", required=True)
    parser.add_argument("--hdri", nargs="*", default=[])
    parser.add_argument("--chunks", type=int, default=64)
    parser.add_argument("--estimator", default="ours")
    args = parser.parse_args(argv)

    fields = eval_fields(args.cache)
    sampler = EnvironmentSampler(sources=eval_environment_sources(args.hdri), seed=EVAL_SEED)
    config = PortraitConfig(split="eval", environments=sampler, sphere_sizes=(), fields_per_chunk=8,
                            lightings_per_field=1, env_pool=1, env_refresh=1, shuffle=1)
    dataset = PortraitDataset(fields, config, seed=EVAL_SEED)
    net = create_estimator(args.estimator).eval()
    ratios = []
    for index in range(args.chunks):
        samples = dataset.chunk(0, index)
        crops = torch.stack([s["image"] for s in samples]).float() / 255.0
        truth = torch.stack([s["mirror_ball"] for s in samples]).double()
        with torch.inference_mode():
            pred = net(fit_crops(net, crops)).mirror_ball.double()
        ratios.append(torch.log(lighting_energy(pred) / lighting_energy(truth)))
    r = torch.stack(ratios)  # (chunks, faces per chunk)
    within = float(r.var(1, unbiased=True).mean().sqrt())
    between = math.sqrt(max(float(r.mean(1).var(unbiased=True)) - within**2 / r.shape[1], 0.0))
    single = math.sqrt(between**2 + within**2)
    print(f"{args.estimator}: {r.shape[0]} photos (environments) x {r.shape[1]} faces, log(E_est / E_true)")
    print(f"  mean {float(r.mean()):+.3f}; spread between faces of one photo (std within) {within:.3f}; "
          f"between photos (a photo's shared error) {between:.3f}")
    for k in (1, 2, 4, 8):
        fused = math.sqrt(between**2 + within**2 / k)
        print(f"  {k} face(s) fused: expected std of log energy error {fused:.3f} ({fused / single:.2f}x one face)")


if __name__ == "__main__":
    main()
