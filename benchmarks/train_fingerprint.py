"""Fingerprint of training: the SHA-256 of the weights after 3 steps on the test suite's tiny cache.

Run: ``python benchmarks/train_fingerprint.py [--estimators ours sh sipr] [--steps 3]``

Builds the cache of the training tests (two train mannequins, one 48 px view each; the ``tiny_cache``
fixture of ``tests/conftest.py``) in a temporary folder, trains each estimator for ``--steps`` steps with
the training tests' small data settings on one thread, and prints each weight file's SHA-256 (and the CPU),
as the run's own ``summary.json`` records them. A refactor
that must not change training is checked by running this before and after it on the same machine: the
hashes must be identical. (They differ between CPUs: float summation order depends on the SIMD width.)
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

#: The training tests' small data settings (``tests/train/helpers.py``'s ``SMALL``).
SMALL = ("fields_per_chunk=1", "lightings_per_field=4", "shuffle=1", "env_pool=2", "env_refresh=1")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--estimators", nargs="+", default=["ours", "sh", "sipr"])
    parser.add_argument("--steps", type=int, default=3)
    args = parser.parse_args(argv)

    from kornia_ilum_lab.synth.lightstage import Auto, SampledViews, Workers, build_cache

    with tempfile.TemporaryDirectory() as tmp:
        env = {**os.environ, "OMP_NUM_THREADS": "1", "TMPDIR": tmp}  # the runs' own temporary files go here too
        cache = Path(tmp) / "cache"
        build_cache("mannequin", [0, 2], out_dir=cache, renderer=Auto(spp=4), views=SampledViews(1, size=48),
                    workers=Workers(processes=1), progress=False)
        for name in args.estimators:
            out = Path(tmp) / name
            subprocess.run(
                [sys.executable, "-m", "kornia_ilum", "train", "--estimator", name, "--cache", str(cache),
                 "--out", str(out), "--steps", str(args.steps), "--batch", "2", "--threads", "1",
                 "--workers", "1", "--checkpoint-every", "3", "--log-every", "1", "--data", *SMALL],
                check=True, env=env, capture_output=True, text=True,
            )
            summary = json.loads((out / "summary.json").read_text())
            print(f"{name:5s} {args.steps} steps  sha256 {summary['weights']['sha256']}  cpu: {summary['cpu']}")


if __name__ == "__main__":
    main()
