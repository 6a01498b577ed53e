r"""``kornia-ilum bench``: run time against error for every estimator and runtime, on the machine at hand.

:func:`add_bench_parser` adds the command to the subparsers of ``kornia-ilum``; :func:`run_bench_command` runs
:func:`~kornia_ilum.bench.run_bench` and writes ``bench.md``, ``bench.json`` and ``bench.png``
(:func:`~kornia_ilum.bench.write_bench`).
"""

from __future__ import annotations

import argparse
import time

import torch

from importlib.metadata import entry_points
from typing import Any

from kornia_ilum.bench.report import format_bench, write_bench
from kornia_ilum.bench.run import BENCH_RUNTIMES, run_bench
from kornia_ilum.core.cli import LAB_INSTALL, positive_int
from kornia_ilum.core.errors import UnknownNameError, ValueCheckError
from kornia_ilum.detection import list_detectors

__all__ = ["BENCH_ENTRY_POINT_GROUP", "add_bench_parser", "bench_error_part", "run_bench_command"]

#: The entry-point group of the bench's error part: ``error`` names a class built with ``(cache, hdri, *,
#: samples, quick)`` (the lab's :class:`kornia_ilum_lab.bench.error.BenchError`).
BENCH_ENTRY_POINT_GROUP = "kornia_ilum.bench"


def bench_error_part() -> Any | None:
    """The class of the bench's error part, from the ``kornia_ilum.bench`` entry point ``error`` (the lab's), or
    ``None`` where no installed package provides one (the bench then times only)."""
    found = entry_points(group=BENCH_ENTRY_POINT_GROUP, name="error")
    return next(iter(found)).load() if found else None

_HELP = """\
Time every registered estimator under every runtime that runs here (eager float32, bf16, ONNX Runtime float32
and int8), at batch 1 and 32, against the machine's own limits measured in the same run (fp32, bf16 and int8
matmul peaks, memory bandwidth); where the lab is installed, score each on the held-out eval split (--cache, as
kornia-ilum evaluate builds it) or, without a cache, on the shipped probe's 256 light-stage training portraits
(labelled so: no evidence of accuracy); and time one photo end to end (640x480 and 1280x720: read, check, detect, crop, estimate, write),
today's path against the fast one. Writes OUT/bench.md, OUT/bench.json and OUT/bench.png (run time against
error, the Pareto front outlined). --quick: batches 1 and 4, 3 timed calls, one photo size, 32 probe portraits:
the same code path in seconds (CI).

examples:
  kornia-ilum bench --out bench/
  kornia-ilum bench --cache lightstage/ --hdri ../shared/data/hdri ../shared/data/hdri_more --out bench/
  kornia-ilum bench --quick --estimator ours --estimator uniform --out /tmp/bench
"""


def add_bench_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Add ``bench`` to the subparsers of ``kornia-ilum``.

    Args:
        subparsers: the subparsers of ``kornia-ilum``'s parser (:meth:`argparse.ArgumentParser.add_subparsers`).

    Returns:
        the ``bench`` parser; its ``func`` default is :func:`run_bench_command`.

    Examples:
        >>> parser = argparse.ArgumentParser()
        >>> _ = add_bench_parser(parser.add_subparsers())
        >>> args = parser.parse_args(["bench", "--quick", "--estimator", "ours", "--out", "bench/"])
        >>> args.quick, args.estimator, args.samples, args.func is run_bench_command
        (True, ['ours'], 1024, True)
    """
    cmd = subparsers.add_parser("bench", help="run time against error: every estimator and runtime, this machine",
                                description=_HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    cmd.add_argument("--out", default="bench", metavar="DIR", help="where the reports go (default: bench/)")
    cmd.add_argument("--estimator", action="append", default=None, metavar="NAME",
                     help="an estimator to bench (repeat; default: all that ship weights)")
    cmd.add_argument("--runtime", action="append", default=None, choices=BENCH_RUNTIMES,
                     help="a runtime to bench (repeat; default: all; eager is always timed)")
    cmd.add_argument("--cache", action="append", default=[], metavar="DIR",
                     help="light-stage caches: score on their held-out eval split (repeat for several)")
    cmd.add_argument("--hdri", nargs="*", default=[], metavar="DIR", help="the real maps' folders, with --cache")
    cmd.add_argument("--samples", type=positive_int, default=1024, metavar="N",
                     help="eval portraits with --cache (default 1024, as kornia-ilum evaluate)")
    cmd.add_argument("--detector", action="append", default=None, metavar="NAME",
                     help=f"a detector of the end-to-end rows (repeat; default: {' and '.join(E2E_DETECTORS)}; the "
                     "first one's eager path is the baseline)")
    cmd.add_argument("--detect-side", type=positive_int, default=320, metavar="N",
                     help="the longer side of the fast rows' downscaled detection (default 320)")
    cmd.add_argument("--threads", type=positive_int, default=None, metavar="N",
                     help="torch and ONNX Runtime threads (default: torch's, one per core)")
    cmd.add_argument("--compile", action="store_true", help="also time the eager estimator under torch.compile")
    cmd.add_argument("--quick", action="store_true", help="a few crops and calls, the same code path (CI)")
    cmd.set_defaults(func=run_bench_command)
    return cmd


#: The detectors of the end-to-end rows by default: Haar first (its eager path is the baseline), then YuNet.
E2E_DETECTORS = ("opencv", "yunet")


def _detectors(asked: list[str] | None) -> list[str]:
    if asked:
        unknown = [d for d in asked if d not in list_detectors()]
        if unknown:
            raise UnknownNameError(f"unknown detector {unknown[0]!r}; registered detectors: "
                                   f"{', '.join(list_detectors())}")
        return asked
    return list(E2E_DETECTORS)


def run_bench_command(args: argparse.Namespace) -> int:
    """Run ``kornia-ilum bench`` with parsed ``args``; returns the exit status.

    Scores on the eval split of ``args.cache`` (and measures the skips there), else on the shipped probe's
    check part; prints the report and writes ``bench.md``, ``bench.json`` and ``bench.png`` into ``args.out``.

    Args:
        args: the options of :func:`add_bench_parser`'s parser.

    Returns:
        the exit status, 0 (a failure raises).

    Raises:
        UnknownNameError: a ``--detector`` that is not registered.

    Examples:
        A bench run times every estimator and runtime, so it is not run here:

        >>> parser = argparse.ArgumentParser()
        >>> _ = add_bench_parser(parser.add_subparsers())
        >>> run_bench_command(parser.parse_args(["bench", "--quick", "--out", "bench/"]))  # doctest: +SKIP
        0
    """

    if args.threads is not None:
        torch.set_num_threads(args.threads)
    t0 = time.perf_counter()
    part = bench_error_part()
    if part is None and args.cache:
        raise ValueCheckError(f"--cache needs the lab, which scores the error on the eval split: {LAB_INSTALL}")
    error = None if part is None else part(args.cache, args.hdri, samples=args.samples, quick=args.quick)
    result = run_bench(error, args.estimator, runtimes=args.runtime or BENCH_RUNTIMES, quick=args.quick,
                       e2e_detectors=_detectors(args.detector), detect_side=args.detect_side, compile=args.compile)
    skips = None if error is None else error.skips()
    if skips is not None:
        result["skips"], result["skips_what"] = skips
    print(format_bench(result))
    for path in write_bench(result, args.out):
        print(f"wrote {path}")
    print(f"bench took {time.perf_counter() - t0:.0f} s")
    return 0
