"""Whether the light's colour tells its direction in the environments training draws, and in real maps.

Run: ``python benchmarks/colour_tells_direction.py --hdri ../shared/data/hdri ../shared/data/hdri_more
[--samples 1000]``

A network can read where the light comes from out of the shading, or out of the colours: if the warm light
always comes from the main light's side and the cool light from above (a low sun under a blue sky), the colour
across a face points at the main light, and an estimator may learn that cue instead of the shading, which a
black-and-white photo then lacks. This draws environments of each kind (the training sampler's procedural
sources, seed 0, each alone; the ``"train"`` and ``"eval"`` real maps of ``--hdri``, each turned at random about
the vertical) and prints, per kind, how the light's colour is laid out around its main light:

- ``cos(warm, main)``: the cosine between the luminance dipole ``sum Omega Y omega`` (the main light) and the
  "warm" dipole ``sum Omega (R - B) / 3 omega`` (where the light is redder than it is blue), averaged over the
  environments; near 0, colour says nothing of the direction; near 1, the warm side is the lit side;
- ``|warm| / |main|``: how strong the colour's own dipole is against the luminance's (a colour cue that is
  faint next to the shading matters little);
- ``up(warm)``: the mean vertical component of the warm dipole's direction (negative: the blue light is above).

Equal figures for the procedural sources and the real maps say the light stage's colours teach no more than
real light does. A second table gives, per source (each procedural kind apart), the share of environments whose
main light is more than 15 degrees below the eyes (the dipole's elevation): light from below, which a model
never shown it cannot learn to read. This is a measurement, not a test: it asserts nothing.
"""

from __future__ import annotations

import argparse
from collections import defaultdict

import torch

from kornia_ilum.color import LUMINANCE
from kornia_ilum.sh import sh_project
from kornia_ilum_lab.synth.environments import EnvironmentSampler, HDRFolderSource, default_sources


def dipoles(ball: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The luminance and warm dipoles ``(3,)`` of a mirror ball ``(3, S, S)``, as ``(x, y, z)``: the l = 1 band of
    their SH (:func:`~kornia_ilum.sh.sh_project`, in the order y, z, x), up to a constant."""
    sh = sh_project(ball[None].double())[0]  # (9, 3)
    y = sh[1:4] @ torch.tensor(LUMINANCE, dtype=torch.float64)
    warm = (sh[1:4, 0] - sh[1:4, 2]) / 3.0
    order = [2, 0, 1]  # (y, z, x) -> (x, y, z)
    return y[order], warm[order]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hdri", nargs="*", default=[])
    parser.add_argument("--samples", type=int, default=1000, help="environments per procedural kind (1000)")
    args = parser.parse_args()
    kinds: dict[str, list[tuple[torch.Tensor, torch.Tensor]]] = defaultdict(list)
    by_source: dict[str, list[torch.Tensor]] = defaultdict(list)
    for source in default_sources():
        sampler = EnvironmentSampler(sources=[source], seed=0)
        for i in range(args.samples):
            env = sampler.sample(i)
            pair = dipoles(env.mirror_ball)
            kinds[f"procedural {env.source.split(':')[0]}"].append(pair)
            by_source[env.source].append(pair[0])
    for split in ("train", "eval"):
        for folder in args.hdri:
            sampler = EnvironmentSampler(sources=[HDRFolderSource(folder, split=split)], seed=0)
            for i in range(args.samples // 4):
                pair = dipoles(sampler.sample(i).mirror_ball)
                kinds[f"real maps ({split})"].append(pair)
                by_source[f"real maps ({split})"].append(pair[0])
    print("| environments | count | cos(warm, main) | abs(warm) / abs(main) | up(warm) |")
    print("|---|---:|---:|---:|---:|")
    for kind, pairs in kinds.items():
        main_d = torch.stack([m for m, _ in pairs])
        warm_d = torch.stack([w for _, w in pairs])
        cos = torch.nn.functional.cosine_similarity(main_d, warm_d, dim=-1, eps=1e-12)
        ratio = warm_d.norm(dim=-1) / main_d.norm(dim=-1).clamp(min=1e-12)
        up = warm_d[:, 1] / warm_d.norm(dim=-1).clamp(min=1e-12)
        print(f"| {kind} | {len(pairs)} | {cos.mean():.2f} | {ratio.median():.3f} | {up.mean():+.2f} |")
    print("\n| source | count | main light below -15 deg | median elevation (deg) |")
    print("|---|---:|---:|---:|")
    for name, mains in sorted(by_source.items()):
        d = torch.stack(mains)
        elevation = torch.rad2deg(torch.asin((d[:, 1] / d.norm(dim=-1).clamp(min=1e-12)).clamp(-1.0, 1.0)))
        below = (elevation < -15.0).double().mean()
        print(f"| {name} | {len(mains)} | {100 * below:.1f} % | {elevation.median():+.1f} |")


if __name__ == "__main__":
    main()
