"""What the training tests share: the small data settings of their runs, the ``kornia-ilum train`` command."""

from __future__ import annotations

import os
import sys

import safetensors.torch
import torch

#: Small chunks, so that a few steps do not make a whole 256-sample group of the default settings.
SMALL = ("fields_per_chunk=1", "lightings_per_field=4", "shuffle=1", "env_pool=2", "env_refresh=1")


def small_data() -> dict[str, int]:
    """:data:`SMALL` as ``TrainConfig.data``."""
    return {k: int(v) for k, v in (s.split("=") for s in SMALL)}


def cli(*args: str) -> list[str]:
    """The command line of ``kornia-ilum train ARGS`` in this interpreter."""
    return [sys.executable, "-m", "kornia_ilum", "train", *args]


def env() -> dict[str, str]:
    """The environment of a training subprocess: one thread, kornia_ilum's debug checks on."""
    return {**os.environ, "OMP_NUM_THREADS": "1", "KORNIA_ILUM_DEBUG": "1"}


def common(cache, out, steps: int, workers: int = 1) -> list[str]:
    """The arguments of a small run: batch 2, one thread, a checkpoint every 3 steps, a log row every step."""
    return ["--cache", str(cache), "--out", str(out), "--steps", str(steps), "--batch", "2", "--threads", "1",
            "--workers", str(workers), "--checkpoint-every", "3", "--log-every", "1", "--data", *SMALL]


def weights(out) -> dict[str, torch.Tensor]:
    """The exported ``ours.safetensors`` of the run in ``out``."""
    return safetensors.torch.load_file(out / "ours.safetensors")
