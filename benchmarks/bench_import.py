"""Benchmark: the cost of ``import kornia_ilum`` against ``import kornia`` (and ``import torch``).

Run: ``python benchmarks/bench_import.py [--runs 5] [--modules torch kornia kornia_ilum]``

Each module is imported in ``--runs`` fresh interpreters (interleaved, so that load from other processes
falls on all of them alike), each timing its own import with ``time.perf_counter`` (interpreter start-up
excluded). Prints the median per module, each median's ratio to the first two modules' (kornia_ilum /
kornia is the number to watch), and whether the import loaded Dynamo or wrote anything into a fresh
``TMPDIR``.

This is a benchmark, not a test: it prints numbers and asserts nothing.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile

_PROBE = (
    "import sys, time\n"
    "t = time.perf_counter()\n"
    "import {module}\n"
    "print(time.perf_counter() - t, 'torch._dynamo' in sys.modules)\n"
)


def time_import(module: str) -> tuple[float, bool, list[str]]:
    """Import time (s) of ``module`` in a fresh interpreter, whether Dynamo got loaded, files left in TMPDIR."""
    with tempfile.TemporaryDirectory() as tmp:
        env = {k: v for k, v in os.environ.items() if k != "TORCHINDUCTOR_CACHE_DIR"}
        env["TMPDIR"] = tmp
        out = subprocess.run(
            [sys.executable, "-c", _PROBE.format(module=module)],
            capture_output=True, text=True, env=env, check=True, cwd=tmp,
        ).stdout.split()
        return float(out[0]), out[1] == "True", sorted(os.listdir(tmp))


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5, help="fresh interpreters per module (default: 5)")
    parser.add_argument("--modules", nargs="+", default=["torch", "kornia", "kornia_ilum"])
    args = parser.parse_args(argv)

    times: dict[str, list[float]] = {m: [] for m in args.modules}
    dynamo: dict[str, bool] = dict.fromkeys(args.modules, False)
    written: dict[str, set[str]] = {m: set() for m in args.modules}
    for module in args.modules:  # warm the file cache once
        time_import(module)
    for _ in range(args.runs):
        for module in args.modules:
            t, dyn, files = time_import(module)
            times[module].append(t)
            dynamo[module] |= dyn
            written[module].update(files)

    medians = {m: statistics.median(v) for m, v in times.items()}
    print(f"median import time over {args.runs} fresh processes each")
    for m in args.modules:
        print(f"  {m:12s} {medians[m]:6.2f} s   (min {min(times[m]):.2f}, max {max(times[m]):.2f})   "
              f"dynamo loaded: {dynamo[m]}   TMPDIR entries: {sorted(written[m]) or 'none'}")
    for ref in args.modules[:2]:
        for m in args.modules:
            if m != ref and args.modules.index(m) > args.modules.index(ref):
                print(f"  {m} / {ref}: {medians[m] / medians[ref]:.2f}x  (+{medians[m] - medians[ref]:.2f} s)")


if __name__ == "__main__":
    main()
