"""Benchmark of one training step of ``ours``: float32 vs bfloat16 autocast vs channels_last, same process.

Run: ``python benchmarks/bench_train.py [--batch 32] [--threads 2] [--repeats 5]``

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
from kornia_ilum.train.loop import train_step


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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=32)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    print(f"one training step of ours, batch {args.batch}, {args.threads} threads, median of {args.repeats}")
    base = None
    for bf16, cl in ((False, False), (True, False), (False, True), (True, True)):
        t = _variant(bf16, cl, args.batch, args.repeats)
        base = t if base is None else base
        name = f"{'bf16' if bf16 else 'fp32'} {'channels_last' if cl else 'contiguous'}"
        print(f"  {name:<24} {1e3 * t:8.0f} ms   {t / base:5.2f}x fp32   {args.batch / t:6.1f} samples/s")


if __name__ == "__main__":
    main()
