"""Benchmark of the on-the-fly portrait dataset: samples per second on one core, against an unbatched baseline.

Run: ``python benchmarks/bench_portraits.py [--cache DIR] [--chunks 6] [--repeats 3] [--threads 1] [--loader-workers 2]``

It times :meth:`PortraitDataset.chunk` (everything a training sample needs: environments drawn from the pool,
relighting, background, crop, exposure, 8-bit encoding, the 12 ground-truth sphere renders) with the default
settings (4 fields x 16 lightings per chunk, one fresh environment per chunk), and, in the same process, the
same code one sample at a time (``fields_per_chunk=1, lightings_per_field=1``, a fresh environment per
sample: each sample pays for a whole read of its field and for a procedural environment). Medians over
``--repeats`` runs of ``--chunks`` chunks (after a warm-up chunk); 256 x 256 portraits, ``torch`` limited to
``--threads`` threads (1: the issue's "one core").

``--relight-eps EPS`` (with ``--cache`` and ``--max-fields``) also times the training draws relit sparsely
(``PortraitConfig(relight_eps=EPS)``, from the fields' sidecars, written first where missing:
:func:`kornia_ilum_lab.synth.lightstage.write_sparse`), interleaved with the exact ones in the same run, and prints
how far their 8-bit images are from the exact ones.

``--loader-workers N`` also times what a training loop sees: its own loader
(:func:`kornia_ilum_lab.train.data.batch_loader`, a :class:`~torch.utils.data.DataLoader` of the training portraits
with ``N`` worker processes of one torch thread each) and batches of 32, over 64 batches after 8.

With ``--cache`` (a folder written by ``kornia-ilum synth subjects``) it uses the cached reflectance fields
and also prints the cache's render time and disk per subject-view (medians over the manifest). Without it,
it builds stand-in fields of the shape of a 192 x 192 light-stage view (17 116 covered pixels x 812 lights,
bfloat16; random values), which cost the same to relight (their images are noisier than faces, so their JPEG
round trips cost more: a conservative stand-in for the camera effects).

This is a benchmark, not a test: it prints numbers and asserts nothing.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import time
from pathlib import Path

import cv2
import torch
from bench_ops import median_ms as _median_ms  # the benchmarks' one timer (run from benchmarks/)

from kornia_ilum.color import encode_srgb8
from kornia_ilum.core.errors import HDRIOError
from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum_lab.synth import camera_effects as fx
from kornia_ilum_lab.synth.camera_effects import CameraEffects
from kornia_ilum_lab.synth.environments import EnvironmentSampler, lighting_rotation
from kornia_ilum_lab.synth.lightstage import (
    LANDMARK_NAMES,
    Camera,
    PortraitDataset,
    ReflectanceField,
    read_manifest,
)
from kornia_ilum_lab.synth.lightstage import read_sparse, write_sparse
from kornia_ilum_lab.synth.lightstage.portraits import (
    PortraitConfig,
    background_pyramid,
    frame_background,
    frame_backgrounds,
    load_fields,
)
from kornia_ilum_lab.train.data import TRAINING_PORTRAITS, batch_loader


def stand_in_fields(count: int = 4, size: int = 192, covered: int = 17116) -> list[ReflectanceField]:
    """Random fields with the layout and size of cached 192 x 192 light-stage views (compact, bfloat16)."""
    g = torch.Generator().manual_seed(0)
    lights = torch.nonzero(mirror_ball_valid(32).flatten()).flatten()
    fields = []
    for k in range(count):
        yy, xx = torch.meshgrid(torch.arange(size), torch.arange(size), indexing="ij")
        disk = ((yy - size * 0.55) ** 2 + (xx - size / 2) ** 2).flatten().argsort()[:covered].sort().values
        alpha = torch.zeros(size * size)
        alpha[disk] = 1.0
        field = (torch.rand(3, covered, len(lights), generator=g) * 2e-3).to(torch.bfloat16)
        angles = torch.linspace(0, 6.28, len(LANDMARK_NAMES))
        landmarks = torch.stack([size / 2 + 50 * angles.cos(), size / 2 + 55 * angles.sin()], -1)
        meta = {"landmarks": landmarks.tolist(), "lighting_size": 32, "split": "train", "skin_tone": 5}
        fields.append(ReflectanceField(field, alpha.reshape(1, size, size), torch.tensor([40.0, 40.0, 150.0, 150.0]),
                                       Camera(30.0, 0.56, 0.0, 0.0, size=size), k, meta, disk, lights))
    return fields


def rate(data: PortraitDataset, chunks: int, repeats: int) -> tuple[float, int]:
    """Median samples per second over ``repeats`` runs of ``chunks`` chunks, and the samples per chunk.

    The warm-up reads every field once (a memory-mapped field's first use maps its pages, about 30 ms for
    87 MB; a training run pays that once per field in its first minute) and draws a first chunk.
    """
    for field in data.fields:
        field.field.view(torch.int16).amax()
    per_chunk = len(data.chunk(0, 0))
    rates, index = [], 1
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(chunks):
            data.chunk(0, index)
            index += 1
        rates.append(chunks * per_chunk / (time.perf_counter() - start))
    return statistics.median(rates), per_chunk


def median_ms(fn, repeats: int) -> float:
    """:func:`bench_ops.median_ms` with one warm-up call and at least 3 repeats."""
    return _median_ms(fn, max(3, repeats), warmup=1)


def effect_costs(repeats: int) -> None:
    """Each camera effect and the background steps, per 256 x 256 sample (batches of 16, always on)."""
    g = torch.Generator().manual_seed(0)
    x = torch.rand(16, 3, 256, 256, generator=g) * 0.8
    codes = encode_srgb8(x)
    ones = torch.ones(16)
    noise = torch.randn(x.shape, generator=g)
    rows = {
        "encode_srgb8 (reference)": lambda: encode_srgb8(x),
        "lens blur (sigma 1)": lambda: fx.lens_blur(x, ones),
        "vignette": lambda: fx.vignette(x, 0.3 * ones),
        "sensor noise (given normals)": lambda: fx.sensor_noise(x, 1e-4 * ones, noise=noise),
        "tone curve + sRGB + 8 bit (encode_tone8)": lambda: fx.encode_tone8(x, 0.3 * ones, 1.1 * ones),
        "JPEG round trip (quality 70)": lambda: fx.jpeg_compress(codes, 70 * ones),
    }
    cam, off = fx.CameraEffects(), fx.CameraEffects.off()
    drawn = [cam.draw(16, torch.Generator().manual_seed(k)) for k in range(8)]
    off_params, gain = off.draw(16, g), torch.full((16,), 1.1, dtype=torch.float64)
    bank = [noise[k] for k in range(16)]
    rows["CameraEffects.off().apply (fused)"] = lambda: off.apply(x, off_params, gain=gain)
    rows["CameraEffects().apply, 8 draws (fused)"] = lambda: [cam.apply(x, p, noise=bank, gain=gain) for p in drawn]
    no_rolloff = [{**p, "rolloff": torch.zeros_like(p["rolloff"])} for p in drawn]  # the same draws, no roll-off
    rows["the same without the roll-off (fused)"] = lambda: [cam.apply(x, p, noise=bank, gain=gain)
                                                             for p in no_rolloff]
    rows["CameraEffects().apply_reference (unfused)"] = lambda: [cam.apply_reference(x, p, noise=noise, gain=gain)
                                                                 for p in drawn]
    per = {"CameraEffects().apply, 8 draws (fused)": 8, "the same without the roll-off (fused)": 8,
           "CameraEffects().apply_reference (unfused)": 8}
    print("\nper-sample costs (ms, median, one 256 x 256 image out of a batch of 16):")
    for name, fn in rows.items():
        print(f"  {name:44s} {median_ms(fn, repeats) / 16 / per.get(name, 1):6.3f}")
    camera = Camera(30.0, 0.56, 0.0, 0.0, size=192)
    big = torch.rand(3, 256, 512, generator=g)
    pyramids = [background_pyramid(big)] * 16
    turn = torch.rand(16, generator=g, dtype=torch.float64)
    small = torch.rand(16, 3, 128, 256, generator=g)
    print("background at 192 x 192 (ms per sample):")
    print(f"  {'frame_background, 128-row maps (before)':44s} {median_ms(lambda: frame_background(small, camera), repeats) / 16:6.3f}")
    for sigma in (0.0, 0.8, 2.0, 8.0):
        blur = torch.full((16,), sigma)
        ms = median_ms(lambda blur=blur: frame_backgrounds(pyramids, camera, mirror=None, turn=turn,
                                                           sigma=blur), repeats)
        print(f"  {f'frame_backgrounds, 256-row map, sigma {sigma:g}':44s} {ms / 16:6.3f}")
    flip = torch.diag(torch.tensor([-1.0, 1.0, 1.0], dtype=torch.float64))
    rotation = (flip @ lighting_rotation(37.0, 21.0)).expand(16, 3, 3)  # an augment's pitch, yaw and flip
    ms = median_ms(lambda: frame_backgrounds(pyramids, camera, mirror=None, turn=turn, sigma=None,
                                             rotation=rotation), repeats)
    print(f"  {'frame_backgrounds, 256-row map, rotated':44s} {ms / 16:6.3f}")
    print(f"  {'background_pyramid (per environment)':44s} {median_ms(lambda: background_pyramid(big), repeats):6.3f}")


def interleaved_rates(datasets: list[PortraitDataset], chunks: int, repeats: int) -> tuple[list[float], int]:
    """Median samples per second of each dataset, timed in turns (one run of ``chunks`` chunks each, ``repeats``
    rounds), so that a change of the machine's load hits all of them alike."""
    for data in datasets:
        for field in data.fields:
            field.field.view(torch.int16).amax()
        data.chunk(0, 0)
    per_chunk = len(datasets[0].chunk(0, 0))
    rates: list[list[float]] = [[] for _ in datasets]
    index = 1
    for _ in range(repeats):
        for data, out in zip(datasets, rates, strict=True):
            start = time.perf_counter()
            for c in range(chunks):
                data.chunk(0, index + c)
            out.append(chunks * per_chunk / (time.perf_counter() - start))
        index += chunks
    return [statistics.median(r) for r in rates], per_chunk


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cache", help="a light-stage cache folder (default: stand-in fields)")
    parser.add_argument("--chunks", type=int, default=6, help="chunks per timed run (6)")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs; the median is reported (3)")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (1)")
    parser.add_argument("--loader-workers", type=int, default=0, help="also time the training loader with N workers")
    parser.add_argument("--max-fields", type=int, default=None,
                        help="use only the first N fields of the cache, read once before timing: the rate with the "
                        "fields in the page cache (a 60-subject cache is 20 GB, about the machine's RAM)")
    parser.add_argument("--relight-eps", type=float, default=0.0,
                        help="also time the training draws relit sparsely at this eps, in the same run (needs --cache "
                        "and --max-fields; writes the fields' sparse sidecars beside them first)")
    args = parser.parse_args()
    if args.relight_eps and not (args.cache and args.max_fields):
        parser.error("--relight-eps needs --cache and --max-fields")
    torch.set_num_threads(args.threads)
    cv2.setNumThreads(args.threads)  # the lens blur, sqrt and JPEG run in OpenCV: one core means its threads too

    fields = args.cache if args.cache else stand_in_fields()
    if args.cache and args.max_fields:
        fields = load_fields(args.cache)[: args.max_fields]
        for f in fields:  # touch every page once, so that timing sees the page cache, not the disk
            float(f.field.float().sum())
    config = PortraitConfig(split=None, environments=EnvironmentSampler(seed=0))
    batched = PortraitDataset(fields, config, seed=0)
    print(f"{batched!r}\n{torch.get_num_threads()} torch thread(s); 256 x 256 portraits")
    if args.cache:
        entries = read_manifest(args.cache)["entries"]
        seconds = statistics.median(e["render_seconds"] for e in entries)
        megabytes = statistics.median(e["bytes"] for e in entries) / 1e6
        sizes = sorted({e["camera"]["size"] for e in entries})
        print(f"cache: {len(entries)} subject-views, {len({e['subject_seed'] for e in entries})} subjects, "
              f"{sizes} px; median render {seconds:.0f} s and {megabytes:.0f} MB on disk per subject-view")
    else:
        print("stand-in fields: 4 random fields shaped like 192 x 192 light-stage views")

    no_fx = PortraitDataset(batched.fields, dataclasses.replace(config, camera=CameraEffects.off()), seed=0)
    plain = PortraitDataset(batched.fields, dataclasses.replace(config, camera=CameraEffects.off(),
                                                                background_sharp_probability=1.0), seed=0)
    low = PortraitDataset(batched.fields, dataclasses.replace(config, camera=CameraEffects.off(),
                                                              background_sharp_probability=1.0,
                                                              procedural_background_height=128), seed=0)
    training = PortraitDataset(batched.fields, dataclasses.replace(config, **TRAINING_PORTRAITS), seed=0)
    timed = [batched, no_fx, plain, low, training]
    if args.relight_eps:
        for f in batched.fields:  # the sidecars of the fields used, written once (write_sparse_cache: all of them)
            path = Path(f.meta["path"])
            try:
                read_sparse(path)
            except HDRIOError:
                write_sparse(path)
        sparse = PortraitDataset(batched.fields, dataclasses.replace(config, **TRAINING_PORTRAITS,
                                                                      relight_eps=args.relight_eps), seed=0)
        for f in batched.fields:  # the sidecars' pages in the page cache too
            float(read_sparse(f.meta["path"]).rows.view(torch.int16).amax())
        timed.append(sparse)
    rates, per_chunk = interleaved_rates(timed, args.chunks, args.repeats)
    fast, off, bare, old, trained = rates[:5]
    single = PortraitDataset(batched.fields, dataclasses.replace(config, fields_per_chunk=1, lightings_per_field=1,
                                                                 env_pool=1, env_refresh=1), seed=0)
    slow, _ = rate(single, args.chunks * 8, args.repeats)
    print(f"\nbatched (defaults, {per_chunk} samples per chunk): {fast:7.1f} samples/s ({1000 / fast:.2f} ms each)")
    print(f"  without camera effects (CameraEffects.off()):    {off:7.1f} samples/s ({1000 / off:.2f} ms each); "
          f"defaults / this = {fast / off:.2f} (target >= 0.85)")
    print(f"  without camera effects and depth of field:      {bare:7.1f} samples/s ({1000 / bare:.2f} ms each); "
          f"defaults / this = {fast / bare:.2f}")
    print(f"  ... and backgrounds at the lighting's 128 rows:  {old:7.1f} samples/s ({1000 / old:.2f} ms each)")
    print(f"one sample at a time (baseline: a new environment per sample): {slow:5.1f} samples/s "
          f"({1000 / slow:.2f} ms each)")
    print(f"as kornia-ilum train draws them (no sphere targets: {TRAINING_PORTRAITS}): {trained:7.1f} samples/s "
          f"({1000 / trained:.2f} ms each)")
    print(f"speed-up x{fast / slow:.1f}; target >= 200 samples/s on one core: defaults {'PASS' if fast >= 200 else 'FAIL'}, "
          f"training {'PASS' if trained >= 200 else 'FAIL'}")
    if args.relight_eps:
        exact, approx = training.chunk(0, 10**6), timed[-1].chunk(0, 10**6)
        codes = torch.stack([(a["image"].float() - b["image"].float()).abs().mean()
                             for a, b in zip(exact, approx, strict=True)])
        print(f"as training draws them, relit sparsely (relight_eps {args.relight_eps:g}, the fields' sidecars): "
              f"{rates[5]:7.1f} samples/s ({1000 / rates[5]:.2f} ms each), x{rates[5] / trained:.2f} the exact draws; "
              f"images differ by {float(codes.mean()):.2f} 8-bit codes on average (max over a chunk's samples "
              f"{float(codes.max()):.2f})")
    effect_costs(args.repeats)
    if args.loader_workers:
        batches = batch_loader(training, 32, workers=args.loader_workers)  # the training loop's own loader
        for _ in range(8):  # start-up: workers, the first group of shuffled chunks, the environments' first reads
            next(batches)
        start = time.perf_counter()
        for _ in range(64):
            next(batches)
        loaded = 64 * 32 / (time.perf_counter() - start)
        print(f"training loader (kornia_ilum_lab.train.data.batch_loader), {args.loader_workers} workers, batches of 32:  "
              f"{loaded:7.1f} samples/s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
