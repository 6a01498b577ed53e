"""Benchmark of the light stage's image-space filters on a 192 x 192 x 812 field, one thread.

Run: ``python benchmarks/bench_filters.py [--quick] [--threads N] [--size S] [--lights N]``

For :func:`~kornia_ilum_lab.synth.lightstage.subsurface.subsurface_scatter` and
:func:`~kornia_ilum_lab.synth.lightstage.denoise.denoise_field` (default settings, and the denoiser with 3 a-trous
iterations) it prints the median of 3 of: building the sparse operator, applying it, and the whole call; and
the direct per-light references (``_subsurface_reference``, ``_denoise_reference``: shifted whole images,
weights recomputed per light) timed on a few lights in the same process, extrapolated to all lights, with the
ratio. The G-buffer is a synthetic head: a skin ellipsoid (a nose bump on it) 0.4 m from a 30-degree camera in
front of a background, with a hair cap of another albedo, so about half of the pixels are covered and 40 %
are skin.
It also prints the peak resident memory above what the input field and the G-buffer took.

This is a benchmark, not a test: it prints numbers and asserts nothing.
"""

from __future__ import annotations

import argparse
import math
import resource
import sys
from collections.abc import Callable
from pathlib import Path

import torch

from kornia_ilum_lab.synth.lightstage.denoise import _denoise_reference, denoise_field, denoise_operator
from kornia_ilum_lab.synth.lightstage.gbuffer import GBuffer
from kornia_ilum_lab.synth.lightstage.subsurface import (
    _subsurface_reference,
    subsurface_operator,
    subsurface_scatter,
)

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_ops import median_ms  # noqa: E402  (the shared timing helper)


def synthetic_head(size: int = 192, fov_deg: float = 30.0, distance: float = 0.4) -> GBuffer:
    """A G-buffer of a ray-cast skin ellipsoid with a nose bump and a hair cap (no renderer needed)."""
    f = size / 2 / math.tan(math.radians(fov_deg) / 2)
    j, i = torch.meshgrid(torch.arange(size, dtype=torch.float64), torch.arange(size, dtype=torch.float64),
                          indexing="xy")
    d = torch.stack([(j + 0.5 - size / 2) / f, (size / 2 - i - 0.5) / f, -torch.ones_like(j)])
    d = d / d.norm(dim=0)
    radii = torch.tensor([0.075, 0.10, 0.085], dtype=torch.float64)[:, None, None]
    centre = torch.tensor([0.0, 0.0, -distance], dtype=torch.float64)[:, None, None]
    # ray / ellipsoid: |(t d - c) / radii| = 1
    a = ((d / radii) ** 2).sum(0)
    b = -2 * ((d * centre) / radii**2).sum(0)
    c = ((centre / radii) ** 2).sum(0) - 1
    disc = b * b - 4 * a * c
    hit = disc > 0
    t = (-b - disc.clamp_min(0).sqrt()) / (2 * a)
    p = t * d
    normal = (p - centre) / radii**2
    normal = normal / normal.norm(dim=0)
    z = -p[2]
    nose = torch.exp(-(((p[0]) / 0.012) ** 2 + ((p[1] + 0.01) / 0.025) ** 2))  # a bump toward the camera
    z = z - 0.02 * nose
    albedo_skin = torch.tensor([0.62, 0.42, 0.33], dtype=torch.float64)[:, None, None]
    albedo_hair = torch.tensor([0.10, 0.07, 0.05], dtype=torch.float64)[:, None, None]
    hair = (p[1] > 0.055) & hit
    freckles = 1 + 0.08 * torch.sin(400 * p[0]) * torch.sin(400 * p[1])
    albedo = torch.where(hair, albedo_hair, albedo_skin * freckles)
    alpha = hit.double()
    skin = (hit & ~hair).double()
    hit3 = hit.expand(3, -1, -1)
    zero = torch.zeros((), dtype=torch.float64)
    return GBuffer(
        torch.where(hit3, albedo, zero).float(),
        torch.where(hit3, normal, zero).float(),
        torch.where(hit, z, zero)[None].float(),
        alpha[None].float(),
        skin[None].float(),
        focal_px=float(f),
    )


def median_s(fn: Callable[[], object], repeats: int) -> float:
    """Median wall time of ``fn`` in seconds, no warm-up (:func:`bench_ops.median_ms`)."""
    return median_ms(fn, repeats, warmup=0) / 1e3


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="64 x 64 x 64, 1 repeat")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--size", type=int, default=192)
    ap.add_argument("--lights", type=int, default=812)
    ap.add_argument("--ref-lights", type=int, default=4, help="lights the slow references are timed on")
    args = ap.parse_args()
    size, lights, repeats = (64, 64, 1) if args.quick else (args.size, args.lights, 3)
    torch.set_num_threads(args.threads)
    g = synthetic_head(size)
    p = size * size
    field = torch.rand(3, p, lights, generator=torch.Generator().manual_seed(0)) * g.alpha.reshape(1, p, 1)
    print(f"field (3, {p}, {lights}) float32, {int(g.alpha.sum())} covered pixels, "
          f"{int(g.subsurface.sum())} skin; {args.threads} thread(s); median of {repeats}")
    ref_field = field[:, :, : args.ref_lights].contiguous()
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    cases = [
        ("subsurface", lambda: subsurface_operator(g), lambda x: subsurface_scatter(x, g),
         lambda x: _subsurface_reference(x, g)),
        ("denoise r=2", lambda: denoise_operator(g), lambda x: denoise_field(x, g),
         lambda x: _denoise_reference(x, g)),
        ("denoise r=2 x3 a-trous", lambda: denoise_operator(g, iterations=3),
         lambda x: denoise_field(x, g, iterations=3), lambda x: _denoise_reference(x, g, iterations=3)),
    ]
    for name, build, call, ref in cases:
        op = build()
        nnz = sum(m._nnz() for mats in op.matrices for m in mats)
        t_build = median_s(build, repeats)
        t_apply = median_s(lambda: op.apply(field), repeats)
        t_call = median_s(lambda: call(field), repeats)
        t_ref = median_s(lambda: ref(ref_field), 1) * lights / args.ref_lights
        err = float((call(ref_field) - ref(ref_field)).abs().max())
        print(f"{name:24s} build {t_build:6.2f} s  apply {t_apply:6.2f} s  call {t_call:6.2f} s  "
              f"({nnz / 3 / max(1, op.pixels.numel()):.0f} nnz/row)  reference ~{t_ref:8.1f} s  "
              f"-> {t_ref / t_call:5.0f}x faster; max |fast - ref| {err:.1e}")
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024 - rss0
    out_mib = field.numel() * 4 / 2**20
    print(f"peak resident memory above the input: {rss:.0f} MiB (one output field is {out_mib:.0f} MiB)")


if __name__ == "__main__":
    main()
