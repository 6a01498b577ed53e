"""kornia_ilum.estimators.probe: the shipped light-stage portraits that calibrate and check the runtimes."""

from __future__ import annotations

import pytest
import torch

from kornia_ilum.core.errors import ShapeError
from kornia_ilum.estimators import create_estimator
from kornia_ilum.estimators.probe import (
    CALIBRATION,
    CHECK,
    PROBE_SAMPLES,
    fit_crops,
    load_probe,
    probe_digest,
    probe_lrec_change,
    write_probe,
)
from kornia_ilum_lab.synth.environments.real import hdri_split
from kornia_ilum_lab.synth.lightstage.subjects import subject_split


def test_the_probe_holds_training_portraits_only_with_their_lighting() -> None:
    probe = load_probe()
    assert len(probe) == PROBE_SAMPLES and probe.crops.shape == (PROBE_SAMPLES, 3, 256, 256)
    assert probe.mirror_ball.shape == (PROBE_SAMPLES, 3, 32, 32) and float(probe.mirror_ball.amin()) >= 0
    assert 0.0 <= float(probe.crops.amin()) and float(probe.crops.amax()) <= 1.0
    assert probe.meta["split"] == "train"
    assert all(subject_split(s) == "train" for s in probe.meta["subjects"])  # never an eval subject
    real = [src.removeprefix("real:") for src in probe.meta["per_sample"]["source"] if src.startswith("real:")]
    assert real and all(hdri_split(name) == "train" for name in real)  # never an eval map
    assert CALIBRATION.stop == CHECK.start  # calibrated on one part, checked on the other


def test_write_probe_round_trips_and_checks_shapes(tmp_path) -> None:
    smooth = torch.rand(8, 3, 8, 8, generator=torch.Generator().manual_seed(0))  # JPEG keeps smooth images
    crops = torch.nn.functional.interpolate(smooth, size=(256, 256), mode="bilinear", align_corners=False)
    balls = torch.rand(8, 3, 32, 32) * 100
    per = {"label": ["indoor"] * 8, "skin_tone": [1] * 8, "subject_seed": [0] * 8, "source": ["sky"] * 8}
    write_probe(tmp_path, crops, balls, {"split": "train", "per_sample": per})
    back = load_probe(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["probe.jpg", "probe.safetensors"]
    assert float((back.crops - crops).abs().mean()) < 0.01  # JPEG
    torch.testing.assert_close(back.mirror_ball, balls, rtol=1e-2, atol=0.0)  # bfloat16
    with pytest.raises(ShapeError):
        write_probe(tmp_path, torch.rand(7, 3, 256, 256), torch.rand(7, 3, 32, 32), {})


def test_an_estimator_against_itself_changes_nothing_and_the_digest_names_the_files(tmp_path) -> None:
    net = create_estimator("uniform")
    assert probe_lrec_change(net, net) == 0.0
    assert len(probe_digest()) == 12 and probe_digest() == probe_digest()
    assert tuple(fit_crops(create_estimator("sipr", pretrained=False), load_probe().crops[:2]).shape) == (2, 3, 128, 128)
