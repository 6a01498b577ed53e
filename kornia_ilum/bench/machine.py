r"""The machine's own limits, measured in the run that uses them: matmul peaks per precision and memory bandwidth.

Every timing of ``kornia-ilum bench`` is reported against these, so that a number read on one machine (the
project's CPUs change from session to session: AMD EPYC Zen 3 with AVX2 only, Zen 4 with AVX-512 BF16, Intel
Xeon with AMX) says how close it came to what that machine can do.

- fp32 and bf16: :func:`torch.mm` of two ``n x n`` matrices into a reused output (bf16 only where the CPU has it
  natively, :func:`~kornia_ilum.estimators.native_bf16`: elsewhere it is emulated and no peak);
- int8: :func:`torch._int_mm` (int8 in, int32 out), oneDNN's VNNI / AMX kernels where the CPU has them;
- memory bandwidth: a copy of 256 MiB into a reused buffer (read plus write bytes per second), and the same into
  fresh memory (pages faulted in on first touch: what an eager framework's new activations pay).
"""

from __future__ import annotations

import platform
import statistics
import time
from collections.abc import Callable, Sequence
from typing import Any

import torch

from kornia_ilum.core.check import check_positive_int
from kornia_ilum.estimators import native_bf16

__all__ = ["cpu_model", "machine_limits", "median_seconds", "paired_median_seconds"]


def median_seconds(fn: Callable[[], object], repeats: int, warmup: int = 2) -> float:
    """Median wall time of ``fn()`` in seconds, after ``warmup`` calls.

    Args:
        fn: what is timed, called without arguments (its result is dropped).
        repeats: timed calls.
        warmup: untimed calls first.

    Returns:
        the median of the ``repeats`` timed calls, by :func:`time.perf_counter`.

    Examples:
        >>> calls = []
        >>> seconds = median_seconds(lambda: calls.append(1), repeats=3)
        >>> len(calls), seconds >= 0
        (5, True)
    """
    return paired_median_seconds([fn], repeats, rounds=1, warmup=warmup)[0]


def paired_median_seconds(fns: Sequence[Callable[[], object]], repeats: int, rounds: int = 3, warmup: int = 1
                          ) -> list[float]:
    """Median wall time of each of ``fns`` in seconds, timed in turns: ``rounds`` rounds, in each of which every
    function in order gets ``warmup`` untimed calls and then its share of the ``repeats`` timed calls.

    The ratio of two functions' times is what a benchmark reports; timing them in turns, each warm in its own
    block, puts a slow spell of a shared machine on both instead of on whichever ran during it.

    Args:
        fns: what is timed, each called without arguments (the results are dropped).
        repeats: timed calls of each function, split evenly over the rounds (at least one per round).
        rounds: how many turns each function gets.
        warmup: untimed calls at the start of each turn.

    Returns:
        the median of each function's timed calls, in the order of ``fns``.

    Examples:
        >>> calls = {"a": 0, "b": 0}
        >>> times = paired_median_seconds([lambda: calls.update(a=calls["a"] + 1),
        ...                                lambda: calls.update(b=calls["b"] + 1)], repeats=6, rounds=3)
        >>> calls, len(times), min(times) >= 0  # 3 rounds of 1 warm-up and 2 timed calls each
        ({'a': 9, 'b': 9}, 2, True)
    """
    check_positive_int(repeats, "repeats")
    check_positive_int(rounds, "rounds")
    times: list[list[float]] = [[] for _ in fns]
    for _ in range(rounds):
        for fn, own in zip(fns, times, strict=True):
            for _ in range(warmup):
                fn()
            for _ in range(max(1, repeats // rounds)):
                t0 = time.perf_counter()
                fn()
                own.append(time.perf_counter() - t0)
    return [statistics.median(own) for own in times]


def cpu_model() -> str:
    """The CPU's model name (``lscpu``'s "Model name", from ``/proc/cpuinfo``), else :func:`platform.processor`.

    Returns:
        the name (else :func:`platform.machine`, such as ``"x86_64"``, where neither says).

    Examples:
        >>> isinstance(cpu_model(), str)
        True
    """
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _cpu_flags() -> list[str]:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("flags"):
                    have = set(line.split(":", 1)[1].split())
                    wanted = ("avx2", "avx512f", "avx512_vnni", "avx512_bf16", "amx_bf16", "amx_int8", "avx_vnni")
                    return [w for w in wanted if w in have]
    except OSError:
        pass
    return []


def machine_limits(quick: bool = False) -> dict[str, Any]:
    r"""Measure the machine's matmul peaks and memory bandwidth on the current torch thread count.

    Args:
        quick: smaller matrices and buffers, fewer repeats (CI): the same code path, a rougher number.

    Returns:
        ``cpu`` (model name), ``flags`` (the SIMD extensions that matter here), ``threads``, ``fp32_gflops``,
        ``bf16_gflops`` (``None`` without native bfloat16), ``int8_gops``, ``copy_gbps`` (into a reused buffer)
        and ``fresh_copy_gbps`` (into newly allocated memory).

    Examples:
        >>> limits = machine_limits(quick=True)
        >>> limits["fp32_gflops"] > 0 and limits["copy_gbps"] > 0
        True
    """
    n = 512 if quick else 2048
    repeats = 3 if quick else 10
    out: dict[str, Any] = {"cpu": cpu_model(), "flags": _cpu_flags(), "threads": torch.get_num_threads()}
    gen = torch.Generator().manual_seed(0)
    for key, dtype in (("fp32_gflops", torch.float32), ("bf16_gflops", torch.bfloat16)):
        if dtype == torch.bfloat16 and not native_bf16("cpu"):
            out[key] = None
            continue
        a = torch.randn(n, n, generator=gen).to(dtype)
        b = torch.randn(n, n, generator=gen).to(dtype)
        c = torch.empty(n, n, dtype=dtype)
        out[key] = 2 * n**3 / median_seconds(lambda a=a, b=b, c=c: torch.mm(a, b, out=c), repeats) / 1e9
    a8 = torch.randint(-128, 128, (n, n), generator=gen, dtype=torch.int8)
    b8 = torch.randint(-128, 128, (n, n), generator=gen, dtype=torch.int8)
    out["int8_gops"] = 2 * n**3 / median_seconds(lambda: torch._int_mm(a8, b8), repeats) / 1e9
    numel = (16 if quick else 256) * 2**20 // 4
    src, dst = torch.ones(numel), torch.empty(numel)
    out["copy_gbps"] = 2 * numel * 4 / median_seconds(lambda: dst.copy_(src), repeats) / 1e9
    out["fresh_copy_gbps"] = 2 * numel * 4 / median_seconds(lambda: src.clone(), repeats) / 1e9
    return out
