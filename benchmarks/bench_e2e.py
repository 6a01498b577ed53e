"""End-to-end benchmark: face detection and lighting estimation per 640x480 image, as ratios to a baseline.

Run: ``python benchmarks/bench_e2e.py [--threads 2] [--repeats 10] [--yunet PATH]``

The image is scikit-image's astronaut (512 x 512), resized to 480 x 480 (antialiased) and centred on a
black 640 x 480 canvas: one face, about 90 x 90 pixels. Each row is the median over ``--repeats`` runs (after
2 warm-up runs) of one step on that image, on the CPU, in float32:

- ``detect <name>``: :meth:`FaceDetector.detect` on the image (``opencv``, ``yunet``);
- ``crop``: :func:`square_crop_boxes` + :func:`crop_faces` of the face to 256 x 256;
- ``estimate <name>``: the estimator on the one crop, under :func:`torch.inference_mode` (``uniform``, the
  default; ``ours``, untrained: ``pretrained=False``, same cost as trained);
- ``estimate_lighting <detector> + <estimator>``: the whole call, from the image tensor to the
  :class:`LightingEstimate` (detection, crop, estimator; models built beforehand, as the API caches them).

The baseline is ``detect opencv``, measured in the same run; every row prints ``x<ratio>`` = its time
divided by the baseline's. This is a benchmark, not a test: it asserts nothing.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_ops import median_ms  # noqa: E402  (the shared timing helper)

from kornia_ilum import estimate_lighting  # noqa: E402
from kornia_ilum.bench import portrait_photo  # noqa: E402
from kornia_ilum.detection import create_detector, crop_faces, square_crop_boxes  # noqa: E402
from kornia_ilum.estimators import create_estimator  # noqa: E402



def test_image() -> torch.Tensor:
    """The astronaut, resized to 480 x 480 and centred on a black 640 x 480 canvas: ``(1, 3, 480, 640)``
    (:func:`kornia_ilum.bench.portrait_photo`, the photo of ``kornia-ilum bench``'s end-to-end rows)."""
    return torch.from_numpy(portrait_photo(640, 480)).permute(2, 0, 1)[None].float() / 255


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--threads", type=int, default=2, help="torch threads (default 2)")
    parser.add_argument("--repeats", type=int, default=10, help="timed runs per row (default 10)")
    parser.add_argument("--yunet", type=Path, default=None, help="other YuNet weights (default: the package's)")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    cv2.setNumThreads(args.threads)

    image = test_image()
    detectors = {"opencv": create_detector("opencv")}
    if args.yunet is None or args.yunet.is_file():
        detectors["yunet"] = create_detector("yunet", max_side=None, **({"weights_path": args.yunet} if args.yunet else {}))
    else:
        print(f"(yunet skipped: no weights at {args.yunet})")
    estimators = {"uniform": create_estimator("uniform"), "ours": create_estimator("ours", pretrained=False).eval()}
    reps = args.repeats
    print(f"torch {torch.__version__}, {args.threads} threads, image {tuple(image.shape)}, median of {reps} runs")

    rows: list[tuple[str, float]] = []
    for name, det in detectors.items():
        faces = det.detect(image)[0]
        assert faces.shape[0] == 1, f"{name} found {faces.shape[0]} faces"
        rows.append((f"detect {name}", median_ms(lambda det=det: det.detect(image), reps)))
    box = detectors["opencv"].detect(image)[0][:1, :4]
    rows.append(("crop (square 1.25x, 256x256, antialiased)", median_ms(lambda: crop_faces(image, square_crop_boxes(box)), reps)))
    crops = crop_faces(image, square_crop_boxes(box))

    def run(est):
        with torch.inference_mode():
            return est(crops)

    for name, est in estimators.items():
        rows.append((f"estimate {name}" + (" (untrained)" if name == "ours" else ""), median_ms(lambda est=est: run(est), reps)))
    for dname, det in detectors.items():
        for ename, est in estimators.items():
            rows.append((
                f"estimate_lighting {dname} + {ename}",
                median_ms(lambda det=det, est=est: estimate_lighting(image, estimator=est, detector=det), reps),
            ))

    base = rows[0][1]
    print(f"baseline: {rows[0][0]} = {base:.2f} ms")
    for name, ms in rows:
        print(f"  {name:<44s} {ms:9.2f} ms   x{ms / base:6.2f} of baseline")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
