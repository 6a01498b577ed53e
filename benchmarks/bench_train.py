"""Benchmark of one training step: ``ours`` in float32 vs bfloat16 autocast vs channels_last, and the recipes.

Run: ``python benchmarks/bench_train.py [--batch 32] [--threads 2] [--repeats 5]``, or
``python benchmarks/bench_train.py --recipes ours sh sipr --batch 8`` for the step of each trainable estimator
(its recipe's :meth:`~kornia_ilum.train.recipes.Recipe.step`, at the training defaults), as a ratio to the
first, with the projected wall time of the shipped run (3600 steps of 32 samples) on this machine.

A step is what :func:`kornia_ilum.train.train_step` does: the multi-scale generator forward, the rendering
losses at 4-32 px, one discriminator step and one generator step (Adam), on random crops and lightings (no data
pipeline). Prints the median step time of each variant and its ratio against float32 contiguous, measured in
the same process, plus samples/s. The training defaults (``--bf16``, ``--channels-last``) follow these numbers.
"""

from __future__ import annotations

import argparse

import torch
from bench_ops import median_ms  # the benchmarks' one timer (run from benchmarks/)

from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum.train import MSGDiscriminator, MultiScaleOurs, TrainConfig
from kornia_ilum.train.loop import resolve_defaults, train_step
from kornia_ilum.train.recipes import get_recipe


def _variant(bf16: bool, channels_last: bool, batch: int, repeats: int) -> float:
    torch.manual_seed(0)
    config = TrainConfig(out="-", cache=("-",), bf16=bf16, channels_last=channels_last)
    memory = torch.channels_last if channels_last else torch.contiguous_format
    model, disc = MultiScaleOurs().to(memory_format=memory), MSGDiscriminator().to(memory_format=memory)
    opt_g = torch.optim.Adam(model.parameters(), lr=config.lr)
    opt_d = torch.optim.Adam(disc.parameters(), lr=config.lr * config.disc_lr_ratio)
    crops = torch.rand(batch, 3, 256, 256).contiguous(memory_format=memory)
    target = torch.rand(batch, 3, 32, 32).exp() * mirror_ball_valid(32)
    return median_ms(lambda: train_step(model, disc, opt_g, opt_d, crops, target, config), repeats, warmup=2) / 1e3


def _recipe_step(name: str, batch: int, repeats: int) -> float:
    """Seconds per step of ``name``'s recipe on random data (crops, pairs and mattes) at the training defaults."""
    torch.manual_seed(0)
    config = resolve_defaults(TrainConfig(out="-", cache=("-",), estimator=name), torch.device("cpu"))
    recipe = get_recipe(name)
    memory = torch.channels_last if config.channels_last else torch.contiguous_format
    model, disc = recipe.build()
    model = model.to(memory_format=memory)
    disc = disc.to(memory_format=memory) if disc is not None else None
    opt_g = torch.optim.Adam(model.parameters(), lr=config.lr)
    opt_d = torch.optim.Adam(disc.parameters(), lr=config.lr * config.disc_lr_ratio) if disc is not None else None
    light = lambda: torch.rand(batch, 3, 32, 32).exp() * mirror_ball_valid(32)  # noqa: E731
    image = lambda c: torch.randint(0, 256, (batch, c, 256, 256), dtype=torch.uint8)  # noqa: E731
    data = {"image": image(3), "mirror_ball": light(), "pair_image": image(3), "pair_mirror_ball": light(),
            "alpha": image(1)}
    step = lambda: recipe.step(model, disc, opt_g, opt_d, data, torch.device("cpu"), config)  # noqa: E731
    return median_ms(step, repeats, warmup=1) / 1e3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=32)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--recipes", nargs="+", metavar="NAME", help="time these recipes' steps instead")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    if args.recipes:
        print(f"one training step per recipe, batch {args.batch}, {args.threads} threads, median of {args.repeats}")
        base = None
        for name in args.recipes:
            t = _recipe_step(name, args.batch, args.repeats)
            base = t if base is None else base
            hours = 3600 * 32 / (args.batch / t) / 3600
            print(f"  {name:<8} {1e3 * t:9.0f} ms   {t / base:6.2f}x {args.recipes[0]}   {args.batch / t:6.2f} samples/s"
                  f"   3600 steps x 32: {hours:6.1f} h")
        return
    print(f"one training step of ours, batch {args.batch}, {args.threads} threads, median of {args.repeats}")
    base = None
    for bf16, cl in ((False, False), (True, False), (False, True), (True, True)):
        t = _variant(bf16, cl, args.batch, args.repeats)
        base = t if base is None else base
        name = f"{'bf16' if bf16 else 'fp32'} {'channels_last' if cl else 'contiguous'}"
        print(f"  {name:<24} {1e3 * t:8.0f} ms   {t / base:5.2f}x fp32   {args.batch / t:6.1f} samples/s")


if __name__ == "__main__":
    main()
