"""Whether ``ours`` reads the light per skin tone on the faces it was trained on: generalisation or reading?

Run: ``python benchmarks/tones_on_training.py --cache TRAIN_CACHE ... --hdri ../shared/data/hdri
../shared/data/hdri_more --weights A.safetensors B.safetensors [--samples 1024]``

``kornia-ilum evaluate`` scores E with / true per Monk tone on held-out subjects. Where a tone reads too little
light there, the network may fail to generalise to new faces, or fail to read the tone at all. This draws fresh
portraits of the *training* subjects (the calibration stream of :mod:`kornia_ilum_lab.train.calibration`: training
environments, lightings and crops that no training step drew) and prints, per weights file, the median of E /
true per tone (``E`` the lighting's radiance summed over the sphere, averaged over R, G, B) and the tone spread
(largest over smallest). Equal spreads on training and eval subjects say the network cannot read the tone even
on faces it has seen.

This is a measurement, not a test: it asserts nothing.
"""

from __future__ import annotations

import argparse
from collections import defaultdict

import torch

from kornia_ilum.estimators import OursEstimator
from kornia_ilum.estimators.base import read_weights
from kornia_ilum.metrics import total_radiance
from kornia_ilum_lab.train import TrainConfig
from kornia_ilum_lab.train.calibration import CALIBRATION_STREAM
from kornia_ilum_lab.train.data import collate, training_dataset


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cache", nargs="+", required=True)
    parser.add_argument("--hdri", nargs="*", default=[])
    parser.add_argument("--weights", nargs="+", required=True)
    parser.add_argument("--samples", type=int, default=1024)
    args = parser.parse_args()
    dataset = training_dataset(TrainConfig(out="unused", cache=tuple(args.cache), hdri=tuple(args.hdri)))
    stream = dataset.samples(CALIBRATION_STREAM)
    chunks = [collate([next(stream) for _ in range(32)]) for _ in range(max(1, args.samples // 32))]
    for path in args.weights:
        estimator = OursEstimator()
        tensors, sha = read_weights(path, expected_by="--weights")
        estimator.load_state_dict({k: v.float() for k, v in tensors.items()}, strict=True)
        estimator.eval()
        ratios = defaultdict(list)
        for chunk in chunks:
            pred = estimator(chunk["image"].float() / 255.0).mirror_ball
            ratio = total_radiance(pred, torch.float64).mean(1) / total_radiance(chunk["mirror_ball"],
                                                                                 torch.float64).mean(1)
            for tone, value in zip(chunk["skin_tone"].tolist(), ratio.tolist(), strict=True):
                ratios[tone].append(value)
        medians = {t: float(torch.tensor(v).median()) for t, v in sorted(ratios.items())}
        cells = ", ".join(f"{t}: {m:.2f} ({len(ratios[t])})" for t, m in medians.items())
        print(f"{path} (sha256 {sha[:8]}...): E / true per tone (portraits) {cells}; "
              f"tone spread {max(medians.values()) / min(medians.values()):.2f}")


if __name__ == "__main__":
    torch.set_grad_enabled(False)
    torch.set_num_threads(1)
    main()
