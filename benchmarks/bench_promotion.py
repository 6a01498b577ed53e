"""Validation and timing of LDR-to-HDR sphere promotion (LeGendre et al. 2020, Eq. 1-3).

Run: ``python benchmarks/bench_promotion.py [FOLDER] [--rotations N] [--size S] [--quick] [--threads N]``

``FOLDER`` holds lat-long ``.hdr``/``.exr`` maps (default: ``$KORNIA_ILUM_SHARED_DATA/hdri``, else
``../shared/data/hdri`` beside the repository). For every map and ``N`` yaw rotations of it (exact column
rolls of the lat-long map by ``k / N`` of a turn plus a seeded random offset; yaw moves the bright sources
across the mirror ball between its centre and its rim):

1. resample to an ``S x S`` mirror ball (energy-conserving,
   :func:`kornia_ilum.geometry.latlong_to_mirror_ball`);
2. expose: scale so that the 98th percentile of the mirror sphere's pixels (``0.827 L``, channel mean, over
   the ball) is 0.5, which clips the brightest directions (7 of the 804 on the ball in the median probe, 15
   at most);
3. render the three spheres (:func:`kornia_ilum.render.render_spheres`), clip to ``[0, 1]``, encode with
   gamma 2.2 and quantise to 8 bits;
4. promote and compare with the exposed truth.

Sets: ``real`` (the maps as they are), ``real+red`` and ``real+blue`` (the clipped directions of each
probe strongly tinted, channel mean kept: the paper's motivating case of strongly hued lights),
``synthetic 2-colour`` (a dim sky with a saturated red and a saturated blue light, 2 x 2 pixels each, at
seeded random places), and ``real, noisy`` / ``real+red, noisy`` (sensor-like noise added to the linear
sphere renders before clipping: variance ``1e-3 x + 3e-5``).

Methods: ``ours`` (NNLS + cross-colour regulariser, lambda = 0.5, colour of the diffuse ball's residual
light), ``ours, w=ball`` (the same with the colour of the whole diffuse ball), ``per-channel NNLS`` (lambda =
0), and ``naive`` (clipped lighting, no solve).

Columns: ``|rel rad|`` mean absolute relative radiance error over channels
(:func:`kornia_ilum.metrics.relative_radiance`); ``L_rec d/m/mi`` the paper's sphere loss of the diffuse,
matte-silver and mirror spheres (:func:`kornia_ilum.metrics.reconstruction_loss`), x 1000; ``hue err`` the
angle in degrees between the RGB vectors of the true and recovered energy of the clipped directions; all
means over the probes of the set (probes with a clipped direction only).

Timing, at this exposure and at a brighter one (90th percentile at 0.5: 35 clipped directions in the median
probe): median time per probe of the whole promotion with ``method="torch"`` (batched) and ``"scipy"``, and
of the solvers alone on the same systems: the batched torch solver, :func:`scipy.optimize.nnls` per probe
on the ``3K x 3K`` square-root form that ``method="scipy"`` uses, and :func:`scipy.optimize.nnls` on the
stacked least-squares rows (the straightforward use, about ``5 S^2`` rows).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import torch
from bench_ops import median_ms  # the same timer as the op benchmarks (this folder is on sys.path)
from scipy.optimize import nnls

from kornia_ilum.color import gamma_encode, quantize
from kornia_ilum.geometry import latlong_to_mirror_ball, mirror_ball_solid_angles, mirror_ball_valid
from kornia_ilum.io import read_hdr
from kornia_ilum.metrics import reconstruction_loss, relative_radiance
from kornia_ilum.render import MIRROR_REFLECTIVITY, render_spheres
from kornia_ilum.promotion import (
    CLIP_THRESHOLD,
    _build_system,
    _fields,
    _nnls_scipy,
    _nnls_torch,
    _prepare,
    _stacked_rows,
    promote_spheres,
)

F64 = torch.float64
NOISE = 1e-3  # noisy sets: sigma = 3.2 % of white at white, 0.55 % at black, about 4 8-bit codes at 0.2
TINTS = {"real+red": (1.0, 0.22, 0.06), "real+blue": (0.08, 0.3, 1.0)}


def default_folder() -> Path:
    if "KORNIA_ILUM_SHARED_DATA" in os.environ:
        return Path(os.environ["KORNIA_ILUM_SHARED_DATA"]) / "hdri"
    return Path(__file__).resolve().parents[2] / "shared" / "data" / "hdri"


def load_real(folder: Path, rotations: int, size: int, seed: int) -> tuple[list[str], torch.Tensor]:
    files = sorted(p for p in folder.iterdir() if p.suffix.lower() in (".hdr", ".exr"))
    if not files:
        raise SystemExit(f"no .hdr/.exr maps in {folder}")
    gen = torch.Generator().manual_seed(seed)
    names, balls = [], []
    for path in files:
        env = read_hdr(path)[None].to(F64)
        width = env.shape[-1]
        for k in range(rotations):
            shift = (k * width) // rotations + int(torch.randint(width // rotations, (1,), generator=gen))
            balls.append(latlong_to_mirror_ball(torch.roll(env, shift, dims=-1), size))
            names.append(f"{path.stem}@{360.0 * shift / width:.0f}deg")
    return names, torch.cat(balls)


def expose(balls: torch.Tensor, level: float = 0.5, percentile: float = 0.98) -> torch.Tensor:
    valid = mirror_ball_valid(balls.shape[-1])
    seen = (MIRROR_REFLECTIVITY * balls.mean(1))[:, valid]  # (B, V)
    scale = level / seen.quantile(percentile, dim=1).clamp(min=1e-12)
    return balls * scale[:, None, None, None]


def tint_clipped(balls: torch.Tensor, tint: tuple[float, float, float]) -> torch.Tensor:
    """Tint the directions the mirror clips (any channel of ``0.827 L`` >= 1), keeping their channel mean."""
    colour = torch.tensor(tint, dtype=balls.dtype)
    colour = colour / colour.mean()
    clipped = (MIRROR_REFLECTIVITY * balls).amax(1, keepdim=True) >= 1.0
    tinted = balls.mean(1, keepdim=True) * colour[None, :, None, None]
    return torch.where(clipped, tinted, balls)


def synthetic_two_colour(count: int, size: int, seed: int) -> torch.Tensor:
    """A dim blue-grey sky over a grey ground with a saturated red and a saturated blue light (2x2 pixels)."""
    gen = torch.Generator().manual_seed(seed)
    valid = mirror_ball_valid(size)
    i = torch.arange(size, dtype=F64)
    up = (1.0 - (2 * i + 1) / size)[:, None].expand(size, size)  # v: > 0 in the upper half
    sky = torch.stack([0.25 + 0.1 * up, 0.3 + 0.1 * up, 0.4 + 0.15 * up]) * (up > 0) + 0.15 * (up <= 0)
    out = []
    candidates = valid.clone()
    candidates[[0, -1], :] = False
    candidates[:, [0, -1]] = False
    cells = candidates[:-1, :-1] & candidates[1:, :-1] & candidates[:-1, 1:] & candidates[1:, 1:]
    where = cells.nonzero()
    for _ in range(count):
        ball = (sky * valid).clone()
        for colour in ((1.0, 0.05, 0.02), (0.03, 0.12, 1.0)):
            r, c = where[int(torch.randint(len(where), (1,), generator=gen))].tolist()
            power = float(20 + 180 * torch.rand((), generator=gen, dtype=F64))
            ball[:, r : r + 2, c : c + 2] += power * torch.tensor(colour, dtype=F64)[:, None, None]
        out.append(ball)
    return torch.stack(out) * valid


def encode(spheres: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    return {k: torch.round(quantize(gamma_encode(v)) * 255).to(torch.uint8) for k, v in spheres.items()}


def hue_error(pred: torch.Tensor, truth: torch.Tensor, clipped: torch.Tensor) -> torch.Tensor:
    omega = mirror_ball_solid_angles(truth.shape[-1], dtype=F64)
    mask = clipped[:, None].to(F64) * omega
    a, b = (pred.to(F64) * mask).sum((-2, -1)), (truth * mask).sum((-2, -1))
    cos = (a * b).sum(-1) / (a.norm(dim=-1) * b.norm(dim=-1)).clamp(min=1e-300)
    return torch.rad2deg(torch.acos(cos.clamp(-1.0, 1.0)))


METHODS = {
    "ours (lam=0.5)": {"lam": 0.5, "balance": "residual"},
    "ours, w=ball": {"lam": 0.5, "balance": "diffuse"},
    "per-channel NNLS": {"lam": 0.0},
    "naive (no solve)": None,
}


def add_noise(spheres: dict[str, torch.Tensor], gain: float, seed: int) -> dict[str, torch.Tensor]:
    """Sensor-like noise on the linear renders: variance ``gain * x + (0.03 * gain)`` (shot + read noise)."""
    gen = torch.Generator().manual_seed(seed)
    out = {}
    for k, v in spheres.items():
        sigma = (gain * v.clamp(min=0.0) + 0.03 * gain).sqrt()
        out[k] = (v + sigma * torch.randn(v.shape, generator=gen, dtype=v.dtype)).clamp(min=0.0)
    return out


def evaluate(truth: torch.Tensor, size: int, noise: float = 0.0) -> dict[str, list[float]]:
    spheres = render_spheres(truth, size)
    ldr = encode(add_noise(spheres, noise, seed=1) if noise > 0 else spheres)
    rows = {}
    for label, kw in METHODS.items():
        if kw is None:
            out = promote_spheres(ldr["mirror"], ldr["diffuse"], ldr["matte_silver"])
            pred = out.lighting.to(F64) - out.residual.to(F64)
        else:
            out = promote_spheres(ldr["mirror"], ldr["diffuse"], ldr["matte_silver"], method="torch", **kw)
            pred = out.lighting.to(F64)
        keep = out.solved
        p, t = pred[keep], truth[keep]
        rel = relative_radiance(p, t).abs().mean(1)
        lrec = [
            reconstruction_loss(p, t, brdf=b, size=size, reduction="none") * 1e3
            for b in ("diffuse", "matte_silver", "mirror")
        ]
        hue = hue_error(p, t, out.clipped[keep])
        rows[label] = [
            rel.mean().item(),
            *(x.mean().item() for x in lrec),
            hue.mean().item(),
            int(keep.sum()),
        ]
    return rows


def systems(truth: torch.Tensor, size: int):
    """The promotion inputs, and their NNLS systems (lambda = 0.5) built as ``promote_spheres`` builds them but in
    one batch padded to the largest probe (``promote_spheres`` sorts the probes by size into chunks of 32)."""
    ldr = encode(render_spheres(truth, size))
    args = (ldr["mirror"], ldr["diffuse"], ldr["matte_silver"])
    enc, lin, clipped, base, thr = _prepare(*args, gamma=2.2, threshold=CLIP_THRESHOLD)
    keep = clipped.any(1)
    fields = _fields(size, torch.device("cpu"))
    system = _build_system(
        fields,
        enc[:, keep],
        lin=lin[:, keep],
        base=base[keep],
        clipped=clipped[keep],
        thr_enc=thr,
        lam=0.5,
        balance="residual",
    )
    return args, system


def timing(truth: torch.Tensor, size: int, repeats: int) -> list[tuple[str, float]]:
    args, system = systems(truth, size)
    n = system.rhs.shape[0]
    k = system.counts.to(F64)
    print(
        f"  {n} probes with clipping, clipped directions per probe: median {k.median().item():.0f}, "
        f"max {k.max().item():.0f} ({3 * k.max().item():.0f} unknowns)"
    )
    rows = [_stacked_rows(system, i) for i in range(n)]
    ref = _nnls_scipy(system.gram, system.rhs, system.free)
    x, ok = _nnls_torch(system.gram, system.rhs, system.free, 10_000)
    err = ((x - ref).abs().amax(1) / ref.abs().amax(1).clamp(min=1e-300)).max().item()
    print(
        f"  torch vs scipy solutions: max relative difference {err:.1e}; torch converged {int(ok.sum())}/{n}"
    )

    def naive_rows() -> None:
        for a, b in rows:
            nnls(a.numpy(), b.numpy(), maxiter=50 * a.shape[1] + 100)

    times = [
        (
            "promote_spheres(method='torch')",
            median_ms(lambda: promote_spheres(*args, method="torch"), repeats),
        ),
        (
            "promote_spheres(method='scipy')",
            median_ms(lambda: promote_spheres(*args, method="scipy"), repeats),
        ),
        (
            "promote_spheres(method='auto')",
            median_ms(lambda: promote_spheres(*args, method="auto"), repeats),
        ),
        (
            "solve: torch batched BPP",
            median_ms(lambda: _nnls_torch(system.gram, system.rhs, system.free, 10_000), repeats),
        ),
        (
            "solve: scipy nnls, n x n form",
            median_ms(lambda: _nnls_scipy(system.gram, system.rhs, system.free), repeats),
        ),
        ("solve: scipy nnls, stacked rows", median_ms(naive_rows, repeats)),
    ]
    return [(label, ms / n) for label, ms in times]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", nargs="?", type=Path, default=default_folder())
    parser.add_argument("--rotations", type=int, default=4, help="yaw rotations per map")
    parser.add_argument("--size", type=int, default=32, help="mirror-ball side")
    parser.add_argument("--synthetic", type=int, default=20, help="synthetic two-colour probes")
    parser.add_argument("--quick", action="store_true", help="2 rotations, fewer repeats")
    parser.add_argument("--threads", type=int, default=torch.get_num_threads())
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    rotations = 2 if args.quick else args.rotations
    repeats = 3 if args.quick else 7
    print(
        f"kornia_ilum bench_promotion: torch {torch.__version__}, {torch.get_num_threads()} threads; "
        f"{args.folder}, {rotations} yaw rotations per map, {args.size}x{args.size} mirror balls"
    )
    _, raw = load_real(args.folder, rotations, args.size, args.seed)
    real = expose(raw)
    sets = {"real": real}
    for label, tint in TINTS.items():
        sets[label] = tint_clipped(real, tint)
    sets["synthetic 2-colour"] = synthetic_two_colour(args.synthetic, args.size, args.seed)
    noisy = {"real, noisy": "real", "real+red, noisy": "real+red"}

    columns = ("|rel rad|", "L_rec d", "L_rec m", "L_rec mi", "hue err")
    head = f"{'set':<20s} {'method':<18s} " + " ".join(f"{c:>9s}" for c in columns) + f" {'n':>4s}"
    print("\nAccuracy (L_rec x 1000, hue error in degrees; means over probes with clipping)")
    print(head)
    print("-" * len(head))
    for name in [*sets, *noisy]:
        truth = sets[noisy.get(name, name)]
        noise = NOISE if name in noisy else 0.0
        for label, (rel, ld, lm, lmi, hue, n) in evaluate(truth, args.size, noise).items():
            print(f"{name:<20s} {label:<18s} {rel:9.4f} {ld:9.3f} {lm:9.3f} {lmi:9.3f} {hue:9.2f} {n:4d}")
        print()

    print("Time per probe, ms (medians of repeated runs over the whole batch, divided by the probes solved)")
    timed = {"real (p98 -> 0.5)": sets["real"], "real (p90 -> 0.5)": expose(raw, 0.5, 0.9)}
    for name, truth in timed.items():
        print(f" {name}:")
        results = timing(truth, args.size, repeats)
        ref = dict(results)["solve: torch batched BPP"]
        for label, ms in results:
            print(f"  {label:<34s} {ms:9.3f} ms   x{ms / ref:6.2f} vs torch solve")
    return 0


if __name__ == "__main__":
    sys.exit(main())
