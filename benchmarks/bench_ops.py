"""Benchmark of kornia_ilum's ops: medians, each as a ratio against a baseline timed in the same run.

Run: ``python benchmarks/bench_ops.py [--quick] [--threads N]``

Sections
    relight     dense vs sparse, float32 vs bf16, the chosen layout vs a naive einsum, and the
                memory-bandwidth bound measured in the same run (a plain read of the basis). Dense
                relighting must reach at least 0.7x that bound.
    resample    lat-long 1024x512 -> 32x32 mirror ball (area) and back (bilinear), vs point sampling.
    sh          SH projection of a 32x32 mirror ball, vs a naive per-pixel loop in torch.
    spheres     rendering the three reference spheres from a batch of lightings, vs the naive einsum.
    images      the portrait dataset's image ops: 8-bit sRGB codes (encode_srgb8's table) vs
                linear_to_srgb and quantize; background frames through a cached camera grid vs
                sample_latlong; face crops (crop_images) vs kornia's crop_and_resize.

This is a benchmark, not a test: it prints numbers and asserts nothing except the bandwidth target,
which it reports as PASS/FAIL (exit code 1 on FAIL).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable

import torch

from kornia_ilum.bench import median_seconds
from kornia_ilum.color import encode_srgb8, linear_to_srgb, quantize
from kornia_ilum.geometry import latlong_to_mirror_ball, mirror_ball_to_latlong, mirror_ball_to_lights
from kornia_ilum.render import Relight, relight, render_spheres, sphere_reflectance_field
from kornia_ilum.sh import sh_basis, sh_project


def median_ms(fn: Callable[[], object], repeats: int, warmup: int = 2) -> float:
    """Median wall time of ``fn`` in milliseconds (:func:`kornia_ilum.bench.median_seconds`)."""
    return 1e3 * median_seconds(fn, repeats, warmup)


def row(name: str, ms: float, base_ms: float, extra: str = "") -> None:
    print(f"  {name:<46s} {ms:10.3f} ms   x{base_ms / ms:7.2f} vs baseline  {extra}")


def bench_relight(quick: bool) -> bool:
    h = w = 128 if quick else 256
    n, c = 1024, 3
    reps = 5 if quick else 9
    print(f"\n[relight] field (C={c}, P={h}x{w}, N={n}), channel-major")
    gen = torch.Generator().manual_seed(0)
    field32 = torch.rand(c, h * w, n, generator=gen) * (1.0 / n)
    field16 = field32.to(torch.bfloat16)
    light1 = torch.rand(1, n, c, generator=gen)
    light32 = torch.rand(32, n, c, generator=gen)
    # a realistic sparse lighting: a few bright lights carry most of the energy
    sparse_light = torch.rand(1, n, c, generator=gen) * 0.01
    sparse_light[:, torch.randperm(n, generator=gen)[:24]] += 50.0

    # The bound: the fastest of several plain reads of the bf16 basis (sum() pays for the bf16 conversion).
    reads16 = {
        "sum()": lambda: field16.sum(),
        "view(int32).amax()": lambda: field16.view(torch.int32).amax(),
        "view(int64).sum()": lambda: field16.view(torch.int64).sum(),
    }
    read_ms = {k: median_ms(fn, reps) for k, fn in reads16.items()}
    best_read = min(read_ms, key=read_ms.get)
    read16 = read_ms[best_read]
    read32 = median_ms(lambda: field32.view(torch.int32).amax(), reps)
    gb16 = field16.numel() * 2 / 1e9
    gb32 = field32.numel() * 4 / 1e9
    print("  bandwidth bound, plain reads of the bf16 basis: "
          + ", ".join(f"{k} {v:.2f} ms" for k, v in read_ms.items()))
    print(f"  -> bf16 bound {read16:.2f} ms ({gb16 / read16 * 1e3:.1f} GB/s, {best_read});"
          f" f32 bound {read32:.2f} ms ({gb32 / read32 * 1e3:.1f} GB/s)")

    naive_reps = 2 if quick else 3
    olat32 = field32.permute(2, 1, 0).contiguous()  # (N, P, C): the natural stack of OLAT images
    naive = median_ms(lambda: torch.einsum("npc,bnc->bcp", olat32, light1), naive_reps, warmup=1)
    del olat32
    print("  baseline: naive einsum 'npc,bnc->bcp' over the OLAT image stack (N, P, C), float32, B=1")
    row("naive einsum, image-stack layout (baseline)", naive, naive)
    row("einsum, channel-major f32 B=1", median_ms(lambda: torch.einsum("cpn,bnc->bcp", field32, light1), naive_reps),
        naive)
    # einsum has no mixed-dtype kernel: a bf16 field with f32 lighting is upcast whole on every call
    e16 = median_ms(lambda: torch.einsum("cpn,bnc->bcp", field16.float(), light1), naive_reps)
    row("einsum bf16->f32 field, f32 lighting B=1", e16, naive)
    e16b = median_ms(lambda: torch.einsum("cpn,bnc->bcp", field16.float(), light32), naive_reps)
    row("einsum bf16->f32 field, B=32 (per portrait)", e16b / 32, naive, f"{e16b:.2f} ms per batch")
    d32 = median_ms(lambda: relight(field32, light1), reps)
    row("dense f32 B=1", d32, naive, f"{read32 / d32:.2f}x of f32 read bound")
    d16 = median_ms(lambda: relight(field16, light1), reps)
    row("dense bf16 B=1", d16, naive, f"{read16 / d16:.2f}x of bf16 read bound")
    d16b = median_ms(lambda: relight(field16, light32), reps)
    row("dense bf16 B=32 (per portrait)", d16b / 32, naive, f"{d16b:.2f} ms per batch")
    d32b = median_ms(lambda: relight(field32, light32), reps)
    row("dense f32 B=32 (per portrait)", d32b / 32, naive, f"{d32b:.2f} ms per batch")
    dense = relight(field16, sparse_light).float()
    print("  sparse mode (Relight module, light-major copy), peaky lighting: 24 bright lights + dim sky")
    row("dense bf16 B=1, same lighting", median_ms(lambda: relight(field16, sparse_light), reps), naive)
    for eps in (1e-3, 1e-2, 5e-2):
        module = Relight(field16, eps=eps)
        sp = median_ms(lambda: module(sparse_light), reps)
        approx = module(sparse_light).float()
        err = ((dense - approx).abs().sum() / dense.abs().sum()).item()
        row(f"sparse bf16 B=1 eps={eps:g}", sp, naive, f"rel. L1 error {err:.2e} (bound {eps:g})")
        del module
    # a sun over 2 pixels carries 97.5% of the energy, a dim sky the rest: eps = 0.05 keeps the 2 sun lights
    sun = torch.rand(32, n, c, generator=gen) * 0.01
    sun[:, :2] += 100.0
    module = Relight(field16, eps=5e-2)
    for b in (1, 32):
        sp = median_ms(lambda: module(sun[:b]), reps)
        ref = relight(field16, sun[:b]).float()
        err = ((ref - module(sun[:b]).float()).abs().sum() / ref.abs().sum()).item()
        row(f"sparse bf16 B={b} eps=0.05, sun (per portrait)", sp / b, naive, f"rel. L1 error {err:.2e}")
    del module
    ratio = read16 / d16
    ok = ratio >= 0.7
    print(f"  dense bf16 relighting reaches {ratio:.2f}x the memory-bandwidth bound: {'PASS' if ok else 'FAIL'} (>= 0.7)")
    return ok


def bench_resample(quick: bool) -> None:
    reps = 5 if quick else 15
    print("\n[resample] lat-long 512x1024 <-> mirror ball 32x32")
    from kornia_ilum.geometry import angles_to_latlong_pixel, direction_to_latlong, mirror_ball_directions
    from kornia_ilum.geometry.resample import _area_operator_f64

    env = torch.rand(1, 3, 512, 1024)
    ball = latlong_to_mirror_ball(env, 32)
    # baseline: the same energy-conserving table applied as a plain scatter (index_select + index_add)
    coo = _area_operator_f64(("latlong", 512), ("mirror_ball", 32))[0].float().to_sparse_coo().coalesce()
    t_idx, s_idx = coo.indices()
    w = coo.values()

    def scatter(x: torch.Tensor) -> torch.Tensor:
        xf = x.reshape(x.shape[0] * x.shape[1], -1)
        out = torch.zeros(xf.shape[0], 32 * 32).index_add_(1, t_idx, xf.index_select(1, s_idx) * w)
        return out.reshape(x.shape[0], x.shape[1], 32, 32)

    torch.testing.assert_close(scatter(env), ball, rtol=1e-4, atol=1e-5)
    base = median_ms(lambda: scatter(env), reps)
    row("scatter index_add, same table (baseline)", base, base)
    row("latlong_to_mirror_ball area (CSR), B=1", median_ms(lambda: latlong_to_mirror_ball(env, 32), reps), base)
    env8 = env.expand(8, -1, -1, -1).contiguous()
    t8 = median_ms(lambda: latlong_to_mirror_ball(env8, 32), reps)
    row("latlong_to_mirror_ball area (CSR), B=8, per map", t8 / 8, base)
    d, _ = mirror_ball_directions(32)
    phi, el = direction_to_latlong(d)
    px = angles_to_latlong_pixel(phi, el, 512)
    grid = torch.stack([(px[..., 0] + 0.5) / 1024 * 2 - 1, (px[..., 1] + 0.5) / 512 * 2 - 1], -1)[None]
    point = median_ms(lambda: torch.nn.functional.grid_sample(env, grid, align_corners=False), reps)
    row("point sampling grid_sample (not energy-preserving)", point, base)
    row("mirror_ball_to_latlong bilinear H=256", median_ms(lambda: mirror_ball_to_latlong(ball, 256), reps), base)


def bench_sh(quick: bool) -> None:
    reps = 10 if quick else 50
    print("\n[sh] projection of a batch of 64 mirror balls 32x32")
    ball = torch.rand(64, 3, 32, 32)
    from kornia_ilum.geometry import mirror_ball_directions, mirror_ball_solid_angles

    d, _ = mirror_ball_directions(32)
    omega = mirror_ball_solid_angles(32)

    def naive() -> torch.Tensor:  # basis rebuilt every call, then a weighted sum
        y = sh_basis(d)  # (32, 32, 9)
        return torch.einsum("bchw,hwk,hw->bkc", ball, y, omega)

    base = median_ms(naive, reps)
    row("rebuild basis + einsum (baseline)", base, base)
    row("sh_project", median_ms(lambda: sh_project(ball), reps), base)


def bench_spheres(quick: bool) -> None:
    reps = 5 if quick else 20
    print("\n[spheres] three reference spheres at 32x32 from a batch of 32 lightings")
    lighting = torch.rand(32, 3, 32, 32)
    fields = {k: sphere_reflectance_field(k, 32) for k in ("diffuse", "matte_silver", "mirror")}
    lights = mirror_ball_to_lights(lighting)

    def naive() -> list[torch.Tensor]:
        return [torch.einsum("pn,bnc->bcp", f, lights) for f in fields.values()]

    base = median_ms(naive, reps)
    row("naive einsum per sphere (baseline)", base, base)
    row("render_spheres", median_ms(lambda: render_spheres(lighting, 32), reps), base)
    from kornia_ilum.render.spheres import _field_f64

    _field_f64.cache_clear()
    t0 = time.perf_counter()
    for k in ("diffuse", "matte_silver", "mirror"):
        sphere_reflectance_field(k, 64)
    print(f"  building the three 64x64 fields from scratch (once per process, then cached): "
          f"{time.perf_counter() - t0:.2f} s")


def bench_images(quick: bool) -> None:
    reps = 5 if quick else 20
    print("\n[images] 8-bit sRGB codes of 8 linear images 3x256x256")
    x = torch.rand(8, 3, 256, 256) ** 2.2 * 1.2

    def exact() -> torch.Tensor:
        return torch.round(quantize(linear_to_srgb(x.clamp(0.0, 1.0)), 8) * 255.0).to(torch.uint8)

    base = median_ms(exact, reps)
    row("linear_to_srgb + quantize + round (baseline)", base, base)
    row("encode_srgb8 (65536-cell table)", median_ms(lambda: encode_srgb8(x), reps), base)

    from kornia_ilum_lab.synth.background import camera_rays, sample_latlong
    from kornia_ilum_lab.synth.lightstage import Camera
    from kornia_ilum_lab.synth.lightstage.portraits import frame_background

    print("[images] background frames 192x192 of 16 lat-long maps 128x256 through a 30-degree camera")
    maps = torch.rand(16, 3, 128, 256)
    camera = Camera(30.0, 0.56, 0.0, 0.0, size=192)
    rays = camera_rays((192, 192), 30.0, torch.eye(3, dtype=torch.float64))[None]
    base = median_ms(lambda: sample_latlong(maps, rays), reps)
    row("sample_latlong, rays converted per call (baseline)", base, base)
    row("frame_background (cached camera grid)", median_ms(lambda: frame_background(maps, camera), reps), base)

    from kornia.geometry.transform import crop_and_resize

    from kornia_ilum_lab.synth.lightstage.portraits import crop_images

    print("[images] 8 square crops of 4 x 192 x 192 frames resized to 256 x 256")
    frames = torch.rand(8, 4, 192, 192)
    boxes = torch.tensor([[20.0 + k, 25.0, 180.0 + k, 185.0] for k in range(8)])
    half = (boxes[:, 2] - boxes[:, 0]) / 512  # kornia's corners are pixel centres: the same crops as crop_images
    lo, hi = boxes[:, :2] + half[:, None] - 0.5, boxes[:, 2:] - half[:, None] - 0.5
    corners = torch.stack([lo, torch.stack([hi[:, 0], lo[:, 1]], -1), hi, torch.stack([lo[:, 0], hi[:, 1]], -1)], 1)
    base = median_ms(lambda: crop_and_resize(frames, corners, (256, 256), align_corners=True), reps)
    row("kornia crop_and_resize (baseline)", base, base)
    row("crop_images (separable grid + grid_sample)", median_ms(lambda: crop_images(frames, boxes, 256), reps), base)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller sizes and fewer repeats")
    parser.add_argument("--threads", type=int, default=torch.get_num_threads())
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    print(f"kornia_ilum bench_ops: torch {torch.__version__}, {torch.get_num_threads()} threads, medians")
    ok = bench_relight(args.quick)
    bench_resample(args.quick)
    bench_sh(args.quick)
    bench_spheres(args.quick)
    bench_images(args.quick)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
