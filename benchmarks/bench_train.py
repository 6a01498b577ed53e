"""Benchmark of one training step: ``ours`` in float32 vs bfloat16 autocast vs channels_last, and the recipes.

Run: ``python benchmarks/bench_train.py [--batch 32] [--threads 2] [--repeats 5]``, or
``python benchmarks/bench_train.py --recipes ours sh sipr --batch 8`` for the step of each trainable estimator
(its recipe's :meth:`~kornia_ilum_lab.train.recipes.Recipe.step`, at the training defaults), as a ratio to the
first, with the projected wall time of the shipped run (3600 steps of 32 samples) on this machine and the
steps of 32 that sipr's budget (``BUDGET_H``) buys. Each recipe's step runs at its estimator's input size
(``info.input_size``: sipr 128, the others 256), as its training data does.

A step of ``ours`` is what :func:`kornia_ilum_lab.train.train_step` does (through its recipe): the multi-scale
generator forward, the rendering losses at 4-32 px, one discriminator step and one generator step (Adam), on
random uint8 crops and lightings (no data pipeline). Prints the median step time of each variant and its ratio against float32 contiguous, measured in
the same process, plus samples/s. The training defaults (``--bf16``, ``--channels-last``) follow these numbers.
"""

from __future__ import annotations

import argparse

import torch
from bench_ops import median_ms  # the benchmarks' one timer (run from benchmarks/)

from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum_lab.train import TrainConfig, get_recipe, resolve_runtime


#: sipr's training budget on the project's 2 cores (issue 22), in hours: the steps of 32 it buys are printed.
BUDGET_H = 2.5


def _step_seconds(name: str, batch: int, repeats: int, **precision: bool | None) -> float:
    """Seconds per step of ``name``'s recipe (:meth:`Recipe.step`) on random data (uint8 crops, pairs, mattes
    and lightings), at the training defaults unless ``bf16`` / ``channels_last`` are given."""
    torch.manual_seed(0)
    config = TrainConfig(out="-", cache=("-",), estimator=name, **precision)
    runtime = resolve_runtime(config, torch.device("cpu"))
    recipe = get_recipe(name)
    memory = runtime.memory_format
    model, disc = (None if m is None else m.to(memory_format=memory) for m in recipe.build())
    opt_g = torch.optim.Adam(model.parameters(), lr=config.lr)
    opt_d = torch.optim.Adam(disc.parameters(), lr=config.lr * config.disc_lr_ratio) if disc is not None else None

    size = recipe.estimator(model).info.input_size  # the crops of the recipe's data: sipr 128, the others 256

    def images(channels: int) -> torch.Tensor:
        return torch.randint(0, 256, (batch, channels, size, size), dtype=torch.uint8)

    def lighting() -> torch.Tensor:
        return torch.rand(batch, 3, 32, 32).exp() * mirror_ball_valid(32)

    data = {"image": images(3), "mirror_ball": lighting(), "pair_image": images(3), "pair_mirror_ball": lighting(),
            "alpha": images(1)}
    step = lambda: recipe.step(model=model, disc=disc, opt_g=opt_g, opt_d=opt_d, batch=data,  # noqa: E731
                               device=torch.device("cpu"), config=config, runtime=runtime)
    return median_ms(step, repeats, warmup=2) / 1e3


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
            t = _step_seconds(name, args.batch, args.repeats)
            base = t if base is None else base
            hours = 3600 * 32 / (args.batch / t) / 3600
            budget = int(BUDGET_H * 3600 * args.batch / t / 32)
            print(f"  {name:<8} {1e3 * t:9.0f} ms   {t / base:6.2f}x {args.recipes[0]}   {args.batch / t:6.2f} samples/s"
                  f"   3600 steps x 32: {hours:6.1f} h   in {BUDGET_H} h: {budget} steps x 32")
        return
    print(f"one training step of ours, batch {args.batch}, {args.threads} threads, median of {args.repeats}")
    base = None
    for bf16, cl in ((False, False), (True, False), (False, True), (True, True)):
        t = _step_seconds("ours", args.batch, args.repeats, bf16=bf16, channels_last=cl)
        base = t if base is None else base
        name = f"{'bf16' if bf16 else 'fp32'} {'channels_last' if cl else 'contiguous'}"
        print(f"  {name:<24} {1e3 * t:8.0f} ms   {t / base:5.2f}x fp32   {args.batch / t:6.1f} samples/s")


if __name__ == "__main__":
    main()
