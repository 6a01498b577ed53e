"""Sparse relighting against dense, on real maps: time saved against error added, per map.

Run: ``python benchmarks/bench_relight.py --cache CACHE [--hdri DIR] [--eps 0.005 0.01 0.02] [--batch 16]
[--blocks 4 6] [--threads 2]``

One light-stage subject-view of ``CACHE`` (the first field, compact bfloat16 layout, as the training data
relights it) is relit by every map of ``--hdri`` (default ``../shared/data/hdri``), resampled to a 32 x 32
mirror ball and turned to ``--batch`` yaws, once densely (:func:`kornia_ilum.render.relight_product`, the
light stage's path) and once by :func:`kornia_ilum.render.relight_sparse` at each ``eps``, the lights not kept
relit through clusters of ``B x B`` pixels of the ball for each ``--blocks B``
(:func:`kornia_ilum.render.light_clusters`). The ``skips`` section of ``kornia-ilum bench`` sums the same over
the held-out maps (:func:`kornia_ilum.bench.skips.relight_skips`).

Per map and setting: the median time of ``--runs`` calls and its ratio to dense in the same process; the
lights kept per lighting (mean); the share of the map's energy in its brightest 1 % of directions (how
sun-dominated it is, :func:`kornia_ilum.bench.skips.top_share`); and two errors of the relit image against dense: ``L1`` (relative, linear) and
``L_rec-like`` (the paper's sphere loss applied to the portrait: mean absolute difference of the
gamma-encoded images, each exposed so that its 99th percentile is 1 and soft-clipped, over the mean of the
dense one). The target of issue 24: at least 5x faster on sun-dominated maps at 1 % of ``L_rec``.

This is a benchmark, not a test.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import torch

from kornia_ilum.bench import median_seconds
from kornia_ilum.bench.skips import lrec_like, top_share, turned_lights
from kornia_ilum.io import read_hdr
from kornia_ilum.render import light_clusters, prepare_sparse, relight_product, relight_sparse, sparse_kept
from kornia_ilum.synth.lightstage.portraits import load_fields


def _median_ms(fn, runs: int) -> float:
    return 1e3 * median_seconds(fn, runs, warmup=1)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cache", required=True)
    parser.add_argument("--hdri", default=str(Path(__file__).resolve().parents[1].parent / "shared/data/hdri"))
    parser.add_argument("--eps", type=float, nargs="+", default=[0.005, 0.01, 0.02])
    parser.add_argument("--blocks", type=int, nargs="+", default=[4, 6])
    parser.add_argument("--batch", type=int, default=16)
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args(argv)
    torch.set_num_threads(args.threads)

    field = load_fields(args.cache)[0]
    index = field.light_index
    settings = [(f"blocks {b}", prepare_sparse(field.field, light_clusters(field.lighting_size, b, index)))
                for b in args.blocks]
    print(f"field: seed {field.subject_seed}, {tuple(field.field.shape)} {field.field.dtype}; batch {args.batch}, "
          f"{args.threads} threads")
    print(f"{'map':28s} {'top 1%':>7s} {'setting':18s} {'ms':>8s} {'x dense':>8s} {'kept':>6s} "
          f"{'L1':>8s} {'L_rec-like':>10s}")
    for path in sorted(Path(args.hdri).glob("*")):
        if path.suffix not in (".exr", ".hdr"):
            continue
        latlong = read_hdr(path).float()[None]
        latlong = latlong / latlong.mean()
        lights = turned_lights(latlong, field, args.batch)
        top = top_share(lights)
        dense_lights = lights.to(field.field.dtype)
        reference = relight_product(field.field, dense_lights).float()
        base = _median_ms(lambda: relight_product(field.field, dense_lights), args.runs)
        print(f"{path.name:28s} {top:7.2f} {'dense':18s} {base:8.2f} {1.0:8.2f} {lights.shape[1]:6d} {0.0:8.4f} "
              f"{0.0:10.4f}")
        for eps in args.eps:
            for name, prepared in settings:
                out = relight_sparse(prepared, lights, eps)
                ms = _median_ms(lambda p=prepared, e=eps: relight_sparse(p, lights, e), args.runs)
                kept = float(sparse_kept(prepared, lights, eps).float().mean())
                l1 = float((out - reference).abs().sum() / reference.abs().sum())
                print(f"{'':28s} {'':7s} {f'eps {eps:g} {name}':18s} {ms:8.2f} {base / ms:8.2f} {kept:6.1f} "
                      f"{l1:8.4f} {lrec_like(out, reference):10.4f}")


if __name__ == "__main__":
    main()
