"""Benchmark of the one-pass OLAT renderer: seconds per subject-view and the noise of relit portraits.

Run: ``python benchmarks/bench_olat.py [--source makehuman] [--seed 1] [--view 0] [--size 192] [--out bench_out/olat]``

For one subject-view (``subject_source(--source).sample(--seed)``, view ``--view`` of
:func:`~kornia_ilum_lab.synth.lightstage.scene.sample_views` at ``--size``):

1. **Timing** of :func:`render_olat` (``OnePass()``, the default settings: :data:`ONEPASS_SPP` camera
   samples, 4 or 16 of them tracing the lights, subsurface on, denoise off) with one Dr.Jit thread and one
   torch thread: the median of ``--repeats`` (3) renders in this process, with the renderer's breakdown
   (scene, camera, lights, post) and the subject-building time.
2. **Noise table**: relit 8-bit sRGB portraits under a sun-dominated real map (``--sun``, default
   ``pedestrian_overpass_1k.hdr``) and an overcast one (``--overcast``, default ``hdri_more/phalzer_forest_01_1k.hdr``:
   soft light, no sun disc), each lat-long map taken to a 32 px mirror ball with
   :func:`~kornia_ilum.geometry.latlong_to_mirror_ball` (``mode="area"``, energy-conserving) and relit with
   :func:`kornia_ilum.render.relight` (float32). The reference is the per-light renderer
   (:func:`render_olat_reference`) at 64 spp, ``max_depth = 2`` (direct light, the same BSDFs), cached under
   ``--out`` (the first run at 192 px takes 10 to 20 minutes on one core; reruns are instant). Exposure: the
   linear image is scaled so that the median luminance of the reference's subject pixels (alpha > 0.5) is
   0.18, then clipped to [0, 1], sRGB-encoded and rounded to 8 bits. Background: black (the fields are
   premultiplied). PSNR is over the pixels that either image covers (alpha > 0), not the whole frame (the
   black background would add about 4 dB). Rows: spp 1/2/4/8 x denoise on/off, subsurface off (the reference
   has none); then the subsurface's own change (on vs off, both denoised, at each spp) in dB.
3. **Interreflection**: the reference at ``max_depth = 4`` (two bounces) against ``max_depth = 2``, both rendered
   directly under each map with :func:`render_lighting` at ``--direct-spp`` (256) spp, in dB (the one-pass
   renderer is direct only). And, as a check of the per-light reference itself, :func:`render_lighting` at
   ``max_depth = 2`` against the relit per-light reference.

4. ``--reference onepass``: the reference is the mean of two one-pass fields (render seeds 101 and 102) at
   ``--ref-spp`` (32) camera samples that all trace every light (no demodulation), cached under ``--out``
   (about a minute each at 192 px); their PSNR against each other is printed (the mean's own noise is about
   6 dB lower), and ``--check-direct`` scores the mean against ``render_lighting`` at ``--direct-spp``.
   ``--configs C:T[:E] ...`` then replaces the table of step 2: one row per setting (``spp = C``,
   ``shade_spp = T``, ``edge_spp = E``; demodulated when ``T < C``; no subsurface, render seed 0), with the
   traced samples per pixel, the median render and light-stage seconds of ``--repeats`` renders, and the PSNR
   over interior pixels (both alphas 1) and partly covered ones (silhouettes).

Example (the numbers of ``ONEPASS_SPP``): ``python benchmarks/bench_olat.py --reference onepass --configs 4:4
16:4:16 32:4:8 32:4:16``.

This is a benchmark, not a test: it prints numbers and asserts nothing.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np
import torch

from kornia_ilum.color import linear_to_srgb
from kornia_ilum.geometry import latlong_to_mirror_ball, mirror_ball_to_lights
from kornia_ilum.io import read_hdr
from kornia_ilum.render import relight
from kornia_ilum_lab.synth.lightstage.field import ReflectanceField
from kornia_ilum_lab.synth.lightstage.materials import select_mitsuba_variant
from kornia_ilum_lab.synth.lightstage.olat import render_olat
from kornia_ilum_lab.synth.lightstage.reference import render_lighting, render_olat_reference
from kornia_ilum_lab.synth.lightstage.scene import sample_views
from kornia_ilum_lab.synth.lightstage.settings import ONEPASS_SPP, OnePass, Reference
from kornia_ilum_lab.synth.lightstage.subjects import subject_source

HDRI = Path("/work/shared/data/hdri")
SUN = HDRI / "pedestrian_overpass_1k.hdr"
OVERCAST = HDRI.parent / "hdri_more" / "phalzer_forest_01_1k.hdr"
MIDDLE_GREY = 0.18


def subject_view(source: str, seed: int, view: int, size: int):
    """The subject and camera of the benchmark, and the seconds the subject took to build."""
    t0 = time.perf_counter()
    src = subject_source(source, "/work/shared/data/makehuman") if source == "makehuman" else subject_source(source)
    subj = src.sample(seed)
    build = time.perf_counter() - t0
    cam = sample_views(seed, 4, size=size, landmarks=subj.face_landmarks)[view]
    return subj, cam, build


def cached_reference(out: Path, source: str, seed: int, view: int, subj, cam, spp: int = 64,
                     max_depth: int = 2) -> ReflectanceField:
    """The per-light reference field (compact), rendered once and cached to ``out``."""
    path = out / f"ref_{source}_s{seed}_v{view}_{cam.size}px_{spp}spp_d{max_depth}.pt"
    if path.exists():
        d = torch.load(path)
        return ReflectanceField(d["field"], d["alpha"], d["face_box"], cam, seed, d["meta"], d["pixel_index"],
                                d["light_index"])
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    rf = render_olat_reference(subj, cam, settings=Reference(spp=spp, max_depth=max_depth),
                               threads=1).to_compact()
    print(f"  reference rendered in {time.perf_counter() - t0:.0f} s -> {path}", flush=True)
    torch.save({"field": rf.field, "alpha": rf.alpha, "face_box": rf.face_box, "meta": rf.meta,
                "pixel_index": rf.pixel_index, "light_index": rf.light_index}, path.with_suffix(".tmp"))
    path.with_suffix(".tmp").rename(path)
    return rf


def cached_onepass(out: Path, source: str, seed: int, view: int, subj, cam, spp: int,
                   render_seed: int) -> ReflectanceField:
    """A one-pass field with every camera sample tracing every light (no demodulation), cached to ``out``."""
    path = out / f"onepass_{source}_s{seed}_v{view}_{cam.size}px_{spp}spp_seed{render_seed}.pt"
    if path.exists():
        d = torch.load(path)
        return ReflectanceField(d["field"], d["alpha"], d["face_box"], cam, seed, d["meta"])
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    rf = render_olat(subj, cam, settings=OnePass(spp=spp, shade_spp=spp, demodulate=False, subsurface=False,
                                        seed=render_seed), threads=1)
    print(f"  one-pass reference ({spp} spp, seed {render_seed}) rendered in {time.perf_counter() - t0:.0f} s "
          f"-> {path}", flush=True)
    torch.save({"field": rf.field, "alpha": rf.alpha, "face_box": rf.face_box, "meta": rf.meta},
               path.with_suffix(".tmp"))
    path.with_suffix(".tmp").rename(path)
    return rf


def map_lights(path: Path, lighting_size: int = 32) -> torch.Tensor:
    """``(1, S^2, 3)`` radiance of a lat-long map as a mirror ball (energy-conserving area resampling)."""
    latlong = read_hdr(path)
    ball = latlong_to_mirror_ball(latlong[None].double(), lighting_size, mode="area").float()
    return mirror_ball_to_lights(ball)


def relit(rf: ReflectanceField, lights: torch.Tensor) -> torch.Tensor:
    """``(3, P)`` float32 linear image of a field (dense or compact) under ``lights``."""
    size = rf.size
    rows = rf.pixel_index if rf.pixel_index is not None else torch.arange(size * size)
    cols = rf.light_index if rf.light_index is not None else torch.arange(lights.shape[1])
    field = rf.field.float() if rf.light_index is not None else rf.field.float()[:, :, cols]
    if rf.pixel_index is None:
        field = field[:, rows]
    img = relight(field, lights[:, cols], size=(1, len(rows)))[0, :, 0]
    out = torch.zeros(3, size * size)
    out[:, rows] = img
    return out


def luminance(img: torch.Tensor) -> torch.Tensor:
    return 0.2126 * img[0] + 0.7152 * img[1] + 0.0722 * img[2]


def to_srgb8(img: torch.Tensor, exposure: float) -> torch.Tensor:
    return (linear_to_srgb((img * exposure).clamp(0, 1)[..., None])[..., 0] * 255).round()


def psnr8(a: torch.Tensor, b: torch.Tensor, mask: torch.Tensor) -> float:
    mse = (a - b).pow(2)[:, mask].mean().item()
    return float("inf") if mse == 0 else 10 * np.log10(255.0**2 / mse)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--source", default="makehuman", choices=["makehuman", "mannequin"])
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--view", type=int, default=0)
    parser.add_argument("--size", type=int, default=192)
    parser.add_argument("--out", type=Path, default=Path("bench_out/olat"))
    parser.add_argument("--sun", type=Path, default=SUN)
    parser.add_argument("--overcast", type=Path, default=OVERCAST)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--spps", type=int, nargs="+", default=[1, 2, 4, 8])
    parser.add_argument("--direct-spp", type=int, default=256)
    parser.add_argument("--reference", default="perlight", choices=["perlight", "direct", "onepass"],
                        help="perlight: the cached 64-spp per-light field, relit; direct: render_lighting under "
                             "each map at --direct-spp, max_depth 2 (minutes instead of a quarter of an hour); "
                             "onepass: the mean of two one-pass fields (seeds 101, 102) at --ref-spp camera "
                             "samples that all trace every light, no demodulation (cached)")
    parser.add_argument("--ref-spp", type=int, default=32)
    parser.add_argument("--configs", nargs="+", default=[],
                        help="one-pass settings to score, each 'C:T[:E]' (spp C, shade_spp T, edge_spp E; "
                             "demodulated when T < C), "
                             "subsurface off; replaces the --spps x denoise table when given")
    parser.add_argument("--check-direct", action="store_true",
                        help="with --reference onepass: also score the reference against render_lighting at "
                             "--direct-spp (max_depth 2) under each map")
    parser.add_argument("--reference-only", action="store_true", help="render and cache the reference, then stop")
    parser.add_argument("--skip-timing", action="store_true")
    parser.add_argument("--skip-interreflection", action="store_true")
    args = parser.parse_args()

    torch.set_num_threads(1)
    variant = select_mitsuba_variant()
    subj, cam, build = subject_view(args.source, args.seed, args.view, args.size)
    ntri = sum(len(p.faces) for p in subj.parts)
    print(f"OLAT benchmark: {args.source} seed {args.seed} view {args.view} ({ntri} triangles, built in "
          f"{build:.2f} s), {args.size} px, fov {cam.fov_deg:.1f}, yaw {cam.yaw_deg:+.1f}; variant {variant}, "
          f"1 thread", flush=True)
    maps = {"sun": map_lights(args.sun), "overcast": map_lights(args.overcast)}
    balls = {k: v.transpose(1, 2).reshape(3, 32, 32) for k, v in maps.items()}
    if args.reference == "perlight":
        ref = cached_reference(args.out, args.source, args.seed, args.view, subj, cam)
        if args.reference_only:
            return 0
        ref_img = {k: relit(ref, v) for k, v in maps.items()}
        alpha_ref = ref.alpha.flatten()
    elif args.reference == "onepass":
        refs = [cached_onepass(args.out, args.source, args.seed, args.view, subj, cam, args.ref_spp, sd)
                for sd in (101, 102)]
        if args.reference_only:
            return 0
        pair = [{k: relit(r, v) for k, v in maps.items()} for r in refs]
        ref_img = {k: 0.5 * (pair[0][k] + pair[1][k]) for k in maps}
        alpha_ref = 0.5 * (refs[0].alpha.flatten() + refs[1].alpha.flatten())
    else:  # one render under each map (the OLAT basis weighted by the map: the same envmap, importance-sampled)
        ref_img = {}
        for k, ball in balls.items():
            img, alpha = render_lighting(subj, cam, lighting=ball, spp=args.direct_spp, max_depth=2,
                                         threads=1, seed=7)
            ref_img[k] = img.reshape(3, -1)
        alpha_ref = alpha.flatten()

    if not args.skip_timing:
        runs = []
        for _ in range(args.repeats):
            rf = render_olat(subj, cam, settings=OnePass(), threads=1)
            runs.append(rf.meta["timings"] | {"render": rf.meta["render_seconds"]})
        med = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
        print(f"\none-pass at the defaults (spp {ONEPASS_SPP}, shade_spp {rf.meta['shade_spp']}, edge_spp "
              f"{rf.meta['edge_spp']}, traced {rf.meta['traced_per_pixel']} per pixel, post {rf.meta['post']}), "
              f"median of "
              f"{args.repeats}: {med['render'] + build:.1f} s per subject-view incl. subject build {build:.2f} s; "
              + ", ".join(f"{k} {v:.2f}" for k, v in med.items()), flush=True)

    print(f"reference: {args.reference}; maps: sun = {args.sun.name}, overcast = {args.overcast.name}; "
          f"exposure: median subject luminance "
          f"of the reference -> {MIDDLE_GREY}; background black; PSNR over covered pixels")
    exposure = {k: MIDDLE_GREY / luminance(v)[alpha_ref > 0.5].median().item() for k, v in ref_img.items()}
    ref8 = {k: to_srgb8(v, exposure[k]) for k, v in ref_img.items()}

    def scores(rf: ReflectanceField) -> dict[str, float]:
        mask = (alpha_ref > 0) | (rf.alpha.flatten() > 0)
        return {k: psnr8(to_srgb8(relit(rf, v), exposure[k]), ref8[k], mask) for k, v in maps.items()}

    def region_scores(img: dict[str, torch.Tensor], alpha: torch.Tensor) -> str:
        """PSNR over interior pixels (both alphas 1) and over partly covered ones (the silhouettes, cards)."""
        full = (alpha_ref > 0.999) & (alpha > 0.999)
        part = ((alpha_ref > 0) | (alpha > 0)) & ~full
        out = []
        for k in maps:
            a = to_srgb8(img[k], exposure[k])
            out.append(f"{k} interior {psnr8(a, ref8[k], full):.2f} / partial {psnr8(a, ref8[k], part):.2f}")
        return "; ".join(out) + f" ({int(full.sum())} interior, {int(part.sum())} partial pixels)"

    if args.reference == "onepass":
        mask = (refs[0].alpha.flatten() > 0) | (refs[1].alpha.flatten() > 0)
        own = {k: psnr8(to_srgb8(pair[0][k], exposure[k]), to_srgb8(pair[1][k], exposure[k]), mask) for k in maps}
        print(f"reference: mean of two one-pass fields at {args.ref_spp} spp (all lights per sample); the two "
              f"against each other: sun {own['sun']:.2f} dB, overcast {own['overcast']:.2f} dB (the mean's own "
              f"noise is about 6 dB below that)", flush=True)
        if args.check_direct:
            for k, ball in balls.items():
                img, alpha = render_lighting(subj, cam, lighting=ball, spp=args.direct_spp, max_depth=2,
                                             threads=1, seed=7)
                m = (alpha_ref > 0) | (alpha.flatten() > 0)
                direct8 = to_srgb8(img.reshape(3, -1), exposure[k])
                print(f"  {k}: render_lighting {args.direct_spp} spp vs the one-pass reference "
                      f"{psnr8(to_srgb8(img.reshape(3, -1), exposure[k]), ref8[k], m):.2f} dB; one reference field "
                      f"vs the direct render {psnr8(direct8, to_srgb8(pair[0][k], exposure[k]), m):.2f} dB",
                      flush=True)

    if args.configs:
        print(f"\n{'C':>4} {'T':>4} {'E':>4} {'traced':>6} {'demod':>6} {'sun dB':>8} {'overcast dB':>12} "
              f"{'render s':>9} {'lights s':>9}  regions")
        for cfg in args.configs:
            c, t, e = ([int(x) for x in cfg.split(":")] + [None])[:3]
            times, rf = [], None
            for _ in range(args.repeats):
                settings = OnePass(spp=c, shade_spp=t, edge_spp=e, subsurface=False)
                rf = render_olat(subj, cam, settings=settings, threads=1)
                times.append((rf.meta["render_seconds"], rf.meta["timings"]["lights"]))
            sc = scores(rf)
            reg = region_scores({k: relit(rf, v) for k, v in maps.items()}, rf.alpha.flatten())
            print(f"{c:>4} {t:>4} {rf.meta['edge_spp']:>4} {rf.meta['traced_per_pixel']:>6.2f} "
                  f"{str(rf.meta['demodulate']):>6} {sc['sun']:>8.2f} {sc['overcast']:>12.2f} "
                  f"{statistics.median(x[0] for x in times):>9.1f} {statistics.median(x[1] for x in times):>9.1f}"
                  f"  {reg}", flush=True)
        return 0

    print(f"\n{'spp':>4} {'denoise':>8} {'sss':>4} {'sun dB':>8} {'overcast dB':>12} {'render s':>9}")
    sss_rows = []
    for spp in args.spps:
        on = None
        for dn in (False, True):
            rf = render_olat(subj, cam, settings=OnePass(spp=spp, subsurface=False, denoise=dn), threads=1)
            sc = scores(rf)
            print(f"{spp:>4} {str(dn):>8} {'off':>4} {sc['sun']:>8.2f} {sc['overcast']:>12.2f} "
                  f"{rf.meta['render_seconds']:>9.1f}", flush=True)
            if dn:
                on = rf
        rs = render_olat(subj, cam, settings=OnePass(spp=spp, subsurface=True, denoise=True), threads=1)
        sc = scores(rs)
        # the subsurface's own change: PSNR of (sss on) against (sss off), both denoised, same spp and seed
        mask = (alpha_ref > 0) | (rs.alpha.flatten() > 0)
        own = {k: psnr8(to_srgb8(relit(rs, v), exposure[k]), to_srgb8(relit(on, v), exposure[k]), mask)
               for k, v in maps.items()}
        print(f"{spp:>4} {'True':>8} {'on':>4} {sc['sun']:>8.2f} {sc['overcast']:>12.2f} "
              f"{rs.meta['render_seconds']:>9.1f}", flush=True)
        sss_rows.append((spp, own))
    print("\nsubsurface's own change (sss on vs off, both denoised), PSNR dB:")
    for spp, own in sss_rows:
        print(f"  spp {spp}: sun {own['sun']:.2f}, overcast {own['overcast']:.2f}")

    if not args.skip_interreflection:
        print(f"\ndirect renders under each map (render_lighting, {args.direct_spp} spp, 1 thread):")
        for k in maps:
            ball = balls[k]
            t0 = time.perf_counter()
            d2, _ = render_lighting(subj, cam, lighting=ball, spp=args.direct_spp, max_depth=2, threads=1)
            d4, a4 = render_lighting(subj, cam, lighting=ball, spp=args.direct_spp, max_depth=4, threads=1,
                                     seed=1)
            d2b, _ = render_lighting(subj, cam, lighting=ball, spp=args.direct_spp, max_depth=2, threads=1,
                                     seed=1)
            mask = (alpha_ref > 0) | (a4.flatten() > 0)
            e8 = {n: to_srgb8(x.reshape(3, -1), exposure[k]) for n, x in (("d2", d2), ("d4", d4), ("d2b", d2b))}
            print(f"  {k}: depth 4 vs depth 2 {psnr8(e8['d4'], e8['d2b'], mask):.2f} dB (same seed); "
                  f"depth 2 seed 0 vs seed 1 (their noise) {psnr8(e8['d2'], e8['d2b'], mask):.2f} dB; "
                  f"depth 2 (seed 0) vs the table's reference {psnr8(e8['d2'], ref8[k], mask):.2f} dB "
                  f"({time.perf_counter() - t0:.0f} s)", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
