"""Benchmark of the OLAT renderer: seconds and disk bytes per subject and view.

Run: ``python benchmarks/bench_olat.py [--seeds 0] [--lights 64] [--full] [--threads 1] [--scalar-lights 4]``

For each subject (:func:`make_subject`) and each of the default views (:data:`DEFAULT_VIEWS`) at ``--size``
(256), ``--spp`` (16) and ``--lighting-size`` (32: 812 valid lights), it renders ``--lights`` evenly spaced
valid lights with ``llvm_ad_rgb`` and reports the set-up time (scene build, and the first light, which also
pays for compiling the kernels), the seconds per light over the others, and the time per subject-view
*extrapolated* to all valid lights (set-up + per light x 811: one render per light, the scene built once). ``--full`` also renders one view with every light, measured. ``--scalar-lights`` renders that many
lights with ``scalar_rgb`` (the fallback) on the first view, extrapolated the same way.

Disk per subject-view: the dense bfloat16 field ``(3, P, N)`` (computed, 3 x 65536 x 1024 x 2 bytes at 256 x 256)
and the file that :func:`write_field` writes (compact: covered pixels x valid lights, bfloat16; measured by
writing it: the stored layout has every valid light's column, rendered or not, so its size does not depend on
``--lights``). Medians over the subject-views are printed last.

This is a benchmark, not a test: it prints numbers and asserts nothing.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum.synth.lightstage.cache import DEFAULT_VIEWS, write_field
from kornia_ilum.synth.lightstage.olat import render_olat, select_mitsuba_variant


def timed_render(subject, camera, lights: np.ndarray, **kw) -> tuple[object, float, float]:
    """``render_olat`` of ``lights``; returns the field, the set-up seconds (scene build and the first light,
    which compiles the kernels) and the seconds per light over the other lights."""
    stamps: list[float] = []
    start = time.perf_counter()
    rf = render_olat(subject, camera, lights=lights, callback=lambda _: stamps.append(time.perf_counter()), **kw)
    per_light = (stamps[-1] - stamps[0]) / max(len(stamps) - 1, 1)
    return rf, stamps[0] - start, per_light


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0], help="subject seeds (default 0)")
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--lighting-size", type=int, default=32)
    parser.add_argument("--lights", type=int, default=64, help="lights rendered per view, then extrapolated")
    parser.add_argument("--full", action="store_true", help="also render one view with every light")
    parser.add_argument("--threads", type=int, default=1, help="Dr.Jit threads (default 1: per-core figures)")
    parser.add_argument("--scalar-lights", type=int, default=4, help="lights rendered with scalar_rgb (0: skip)")
    args = parser.parse_args()

    from kornia_ilum.synth.lightstage.subjects import make_subject

    variant = select_mitsuba_variant()
    valid = np.flatnonzero(mirror_ball_valid(args.lighting_size).flatten().numpy())
    subset = valid[np.linspace(0, len(valid) - 1, min(args.lights, len(valid))).round().astype(int)]
    print(f"OLAT benchmark: {args.size}x{args.size}, {args.spp} spp, S = {args.lighting_size} "
          f"({len(valid)} valid lights), variant {variant}, {args.threads} thread(s)")
    dense_bytes = 3 * args.size**2 * args.lighting_size**2 * 2
    seconds, files = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in args.seeds:
            t0 = time.perf_counter()
            subject = make_subject(seed)
            print(f"\nsubject {seed}: make_subject {time.perf_counter() - t0:.2f} s, "
                  f"{sum(len(p.faces) for p in subject.parts)} triangles")
            cams = [dataclasses.replace(view, size=args.size) for view in DEFAULT_VIEWS]
            for k, cam in enumerate(cams):
                rf, setup, per_light = timed_render(subject, cam, subset, lighting_size=args.lighting_size,
                                                    spp=args.spp, variant=variant, threads=args.threads)
                seconds.append(setup + per_light * (len(valid) - 1))
                nbytes = write_field(Path(tmp) / f"{seed}_{k}.safetensors", rf)["bytes"]
                files.append(nbytes)
                coverage = float((rf.alpha > 0).float().mean())
                print(f"  view {k} (yaw {cam.yaw_deg:+.0f}): setup {setup:.1f} s + {per_light:.3f} s/light over "
                      f"{len(subset)} lights "
                      f"-> {seconds[-1]:.0f} s per subject-view (extrapolated to {len(valid)}); "
                      f"coverage {coverage:.2f}; file {nbytes / 1e6:.1f} MB (dense bf16 {dense_bytes / 1e6:.1f} MB)")
            if args.scalar_lights > 0:
                rf, setup, per_light = timed_render(subject, cams[0], subset[: args.scalar_lights],
                                                    lighting_size=args.lighting_size, spp=args.spp,
                                                    variant="scalar_rgb", threads=args.threads)
                print(f"  scalar_rgb view 0: setup {setup:.1f} s + {per_light:.3f} s/light over {args.scalar_lights} "
                      f"lights -> {setup + per_light * (len(valid) - 1):.0f} s per subject-view (extrapolated)")
            if args.full:
                rf = render_olat(subject, cams[0], lighting_size=args.lighting_size, spp=args.spp, variant=variant,
                                 threads=args.threads)
                print(f"  full view 0: {rf.meta['render_seconds']:.0f} s for {rf.meta['lights_rendered']} lights "
                      f"(measured)")
    print(f"\nmedian over {len(seconds)} subject-views: {statistics.median(seconds):.0f} s per subject-view "
          f"(extrapolated from {len(subset)} lights, {variant}, {args.threads} thread(s)); "
          f"disk {statistics.median(files) / 1e6:.1f} MB per subject-view compact, "
          f"{dense_bytes / 1e6:.1f} MB dense bf16 ({statistics.median(files) / dense_bytes:.2f} of dense)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
