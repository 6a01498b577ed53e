"""Benchmark of the lighting environments: rotation of a lat-long map and the sampler's rate.

Run: ``python benchmarks/bench_environments.py [--height H] [--samples N] [--folder DIR] [--no-augment]
[--threads 1]``

- rotation of an ``H x 2H`` map by yaw 37, pitch 21 degrees:
  :func:`~kornia_ilum_lab.synth.environments.rotate_latlong` (the sampler's, energy-conserving, no tables)
  against :func:`~kornia_ilum.geometry.rotate_lighting` (``layout="latlong"``, exact, its tables built per
  call; the baseline, once per repeat);
- sampling: :class:`~kornia_ilum_lab.synth.environments.EnvironmentSampler` (the default sources at height ``H``:
  procedural skies and rooms, plus the real maps of ``--folder``; with augmentation unless ``--no-augment``),
  environments per second of CPU time over ``N`` fresh indices.

``torch`` is limited to ``--threads`` threads (1: the "one CPU core" of docs/environments.rst, "Measured").
This is a benchmark, not a test: it prints numbers and asserts nothing.
"""

from __future__ import annotations

import argparse
import time

import torch
from bench_ops import median_ms, row  # the benchmarks' one timer (run from benchmarks/)

from kornia_ilum.geometry import rotate_lighting
from kornia_ilum_lab.synth.environments import (
    EnvironmentSampler,
    default_sources,
    lighting_rotation,
    rotate_latlong,
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--height", type=int, default=128, help="lat-long height H (width 2H)")
    parser.add_argument("--samples", type=int, default=200, help="environments drawn for the rate")
    parser.add_argument("--folder", default=None, help="a folder of real lat-long maps to add to the sources")
    parser.add_argument("--no-augment", action="store_true", help="sample without augmentation")
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    h = args.height
    print(f"kornia_ilum bench_environments: torch {torch.__version__}, {torch.get_num_threads()} threads")

    print(f"\n[rotation] lat-long {h}x{2 * h}, yaw 37, pitch 21 degrees")
    m, r = torch.rand(1, 3, h, 2 * h), lighting_rotation(37.0, 21.0)
    base = median_ms(lambda: rotate_lighting(m, r, layout="latlong"), repeats=3, warmup=0)
    row("rotate_lighting latlong (baseline)", base, base)
    row("rotate_latlong", median_ms(lambda: rotate_latlong(m[0], r), repeats=50), base)

    print(f"\n[sampling] EnvironmentSampler(seed=0), {args.samples} fresh indices, {h}x{2 * h} maps")
    kwargs = {"augment": None} if args.no_augment else {}
    sampler = EnvironmentSampler(default_sources(args.folder, height=h), seed=0, **kwargs)
    sampler.sample(0)  # warm-up: the cached grids and tables
    t0 = time.process_time()
    for index in range(1, args.samples + 1):
        sampler.sample(index)
    print(f"  {args.samples / (time.process_time() - t0):.1f} environments per second (CPU time)")


if __name__ == "__main__":
    main()
