"""Benchmark of test-time augmentation: an estimator plain vs wrapped in TestTimeAugmented, per crop.

Run: ``python benchmarks/bench_tta.py [--estimator ours] [--batch 1 8] [--runs 10] [--threads 1]``

The crops are the astronaut's face (scikit-image), cut as the paper does (square of 1.25 x the face box,
256 x 256), repeated to each batch size. For each batch size ``B``, each row is the median over ``--runs``
timed calls (after 2 warm-up calls) of the estimator on the ``B`` crops, on the CPU, in float32, under
:func:`torch.inference_mode`:

- ``plain``: the estimator alone (the baseline of its batch size, timed in the same run);
- ``tta KxM``: :class:`kornia_ilum.estimators.TestTimeAugmented` with ``jitters=K`` and the mirror
  (``M = 2`` views per window): ``2K`` passes per crop in one batch of ``2K B`` crops, plus the windows'
  resampling and the average. ``--tta 1 4`` gives ``1x2`` (the crop and its mirror, 2 passes) and ``4x2``
  (8 passes, the default of ``TestTimeAugmented`` and of ``kornia-ilum estimate --tta 4``).

Columns: the median per call and per crop, ``x plain`` (the ratio to the plain row of the same batch size)
and ``x plain / pass`` (that ratio divided by the passes: 1.0 means the wrapper costs exactly its passes;
above 1 is the resampling and averaging overhead, below 1 the gain of a larger batch). One thread by
default, so that the ratios do not depend on how busy the other cores are.

This is a benchmark, not a test: it asserts nothing.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import skimage.data
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_ops import median_ms  # noqa: E402  (the shared timing helper)

from kornia_ilum.detection import crop_faces, square_crop_boxes  # noqa: E402
from kornia_ilum.estimators import TestTimeAugmented, create_estimator  # noqa: E402

#: The astronaut's face box (the Haar cascade's, as in tests/test_api.py).
FACE_BOX = (177.0, 66.0, 274.0, 163.0)


def face_crops(batch: int, size: int) -> torch.Tensor:
    """The astronaut's face crop, ``(batch, 3, size, size)``."""
    image = torch.from_numpy(skimage.data.astronaut()).permute(2, 0, 1).float() / 255
    crop = crop_faces(image, square_crop_boxes(torch.tensor([FACE_BOX])), size=size).clamp(0, 1)
    return crop.expand(batch, -1, -1, -1).contiguous()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--estimator", default="ours", help="registered estimator (default ours, trained)")
    parser.add_argument("--batch", type=int, nargs="+", default=[1, 8], help="batch sizes (default 1 8)")
    parser.add_argument("--tta", type=int, nargs="+", default=[1, 4], help="jitters per row (default 1 4)")
    parser.add_argument("--runs", type=int, default=10, help="timed calls per row (default 10)")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (default 1)")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)

    estimator = create_estimator(args.estimator).eval()
    size = estimator.info.input_size
    variants = [("plain", estimator, 1)] + [
        (f"tta {k}x2", tta, tta.passes) for k in args.tta for tta in [TestTimeAugmented(estimator, jitters=k)]
    ]
    print(
        f"torch {torch.__version__}, {torch.get_num_threads()} thread(s), estimator {args.estimator!r}, "
        f"{size}x{size} crops, float32, median of {args.runs} runs"
    )
    print(f"  {'batch':>5s}  {'variant':<10s} {'passes':>6s} {'ms/call':>10s} {'ms/crop':>10s} "
          f"{'x plain':>8s} {'x plain / pass':>15s}")
    for batch in args.batch:
        crops = face_crops(batch, size)
        base = None
        for name, module, passes in variants:

            def run(module=module):
                with torch.inference_mode():
                    return module(crops)

            ms = median_ms(run, args.runs)
            base = ms if base is None else base
            print(f"  {batch:5d}  {name:<10s} {passes:6d} {ms:10.2f} {ms / batch:10.2f} "
                  f"{ms / base:8.2f} {ms / base / passes:15.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
