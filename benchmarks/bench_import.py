"""Benchmark: the cost of ``import kornia_ilum`` against ``import kornia`` (and ``import torch``).

Run: ``python benchmarks/bench_import.py [--runs 5] [--modules torch kornia kornia_ilum] [--against REF]``

Each module is imported in ``--runs`` fresh interpreters (interleaved, so that load from other processes
falls on all of them alike), each timing its own import with ``time.perf_counter`` (interpreter start-up
excluded). Prints the median per module, each median's ratio to the first two modules' (kornia_ilum /
kornia is the number to watch), and whether the import loaded Dynamo or wrote anything into a fresh
``TMPDIR``.

``--against REF`` also times ``import kornia_ilum`` from the git revision ``REF`` of this repository (checked
out into a temporary worktree, put first on ``PYTHONPATH``), interleaved with the others, and prints the
working tree's median as a ratio to that revision's: a change that must not make the import slower is
shown by ``--against <the commit before it>``.

This is a benchmark, not a test: it prints numbers and asserts nothing.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
from contextlib import ExitStack
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

_PROBE = (
    "import sys, time\n"
    "t = time.perf_counter()\n"
    "import {module}\n"
    "print(time.perf_counter() - t, 'torch._dynamo' in sys.modules)\n"
)


def time_import(module: str, pythonpath: str | None = None) -> tuple[float, bool, list[str]]:
    """Import time (s) of ``module`` in a fresh interpreter (with ``pythonpath`` first on its path), whether
    Dynamo got loaded, files left in TMPDIR."""
    with tempfile.TemporaryDirectory() as tmp:
        env = {k: v for k, v in os.environ.items() if k != "TORCHINDUCTOR_CACHE_DIR"}
        env["TMPDIR"] = tmp
        if pythonpath:
            env["PYTHONPATH"] = pythonpath
        out = subprocess.run(
            [sys.executable, "-c", _PROBE.format(module=module)],
            capture_output=True, text=True, env=env, check=True, cwd=tmp,
        ).stdout.split()
        return float(out[0]), out[1] == "True", sorted(os.listdir(tmp))


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5, help="fresh interpreters per module (default: 5)")
    parser.add_argument("--modules", nargs="+", default=["torch", "kornia", "kornia_ilum"])
    parser.add_argument("--against", metavar="REF", help="also time `import kornia_ilum` at this git revision")
    args = parser.parse_args(argv)

    with ExitStack() as stack:
        paths: dict[str, str | None] = dict.fromkeys(args.modules)
        if args.against:
            tree = stack.enter_context(tempfile.TemporaryDirectory())
            subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "-q", "--detach", tree, args.against],
                           check=True)
            stack.callback(subprocess.run, ["git", "-C", str(ROOT), "worktree", "remove", "--force", tree])
            paths[f"kornia_ilum@{args.against}"] = tree
        _measure(args, paths)


def _measure(args: argparse.Namespace, paths: dict[str, str | None]) -> None:
    labels = list(paths)
    times: dict[str, list[float]] = {m: [] for m in labels}
    dynamo: dict[str, bool] = dict.fromkeys(labels, False)
    written: dict[str, set[str]] = {m: set() for m in labels}

    def run(label: str) -> tuple[float, bool, list[str]]:
        return time_import(label.split("@")[0], paths[label])

    for label in labels:  # warm the file cache once
        run(label)
    for _ in range(args.runs):
        for label in labels:
            t, dyn, files = run(label)
            times[label].append(t)
            dynamo[label] |= dyn
            written[label].update(files)

    medians = {m: statistics.median(v) for m, v in times.items()}
    print(f"median import time over {args.runs} fresh processes each")
    for m in labels:
        print(f"  {m:12s} {medians[m]:6.2f} s   (min {min(times[m]):.2f}, max {max(times[m]):.2f})   "
              f"dynamo loaded: {dynamo[m]}   TMPDIR entries: {sorted(written[m]) or 'none'}")
    for ref in args.modules[:2]:
        for m in args.modules:
            if m != ref and args.modules.index(m) > args.modules.index(ref):
                print(f"  {m} / {ref}: {medians[m] / medians[ref]:.2f}x  (+{medians[m] - medians[ref]:.2f} s)")
    for label in labels[len(args.modules):]:
        print(f"  kornia_ilum (working tree) / {label}: {medians['kornia_ilum'] / medians[label]:.3f}x  "
              f"({medians['kornia_ilum'] - medians[label]:+.3f} s)")


if __name__ == "__main__":
    main()
