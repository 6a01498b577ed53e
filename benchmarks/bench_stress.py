"""The stress table: every public op on lighting from 1e-6 to 1e6 in float32, bfloat16 and float16, and on meta
tensors, with the outcome of each (:mod:`kornia_ilum.bench.stress`).

Run: ``python benchmarks/bench_stress.py [--out stress.md]``

Each row is one op on one input: ``ok`` (outputs and gradients finite), ``typed error`` (the library refused
with a typed error, the documented answer where a dtype cannot hold a value), or a failure, ``garbage`` (NaN
or Inf without an error) or ``untyped error`` (an exception from deep inside torch). The test suite runs the
same grid and fails on any failure (``tests/bench/test_stress.py``); this prints the whole table, failures
first, and exits 1 if there is one.

This is a benchmark, not a test.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from kornia_ilum.bench.stress import format_stress, stress_meta, stress_ops


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=None, metavar="FILE", help="also write the table to this Markdown file")
    args = parser.parse_args(argv)
    rows = stress_ops() + stress_meta()
    text = "# Stress table\n\n" + format_stress(rows)
    print(text, end="")
    if args.out:
        Path(args.out).write_text(text)
    return 1 if any(r.failed for r in rows) else 0


if __name__ == "__main__":
    sys.exit(main())
