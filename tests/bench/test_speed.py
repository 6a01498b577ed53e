"""kornia_ilum.bench.speed: per-crop timing, flops, the test photo, one photo end to end."""

from __future__ import annotations

from kornia_ilum.bench import end_to_end, estimator_flops, estimator_speed, portrait_photo
from kornia_ilum.detection import create_detector
from kornia_ilum.estimators import create_estimator


def test_estimator_speed_reports_each_batch() -> None:
    speed = estimator_speed(create_estimator("uniform"), batches=(1, 3), repeats=2)
    assert set(speed) == {"b1_ms", "b1_ms_per_crop", "b1_crops_per_s", "b3_ms", "b3_ms_per_crop", "b3_crops_per_s"}
    assert abs(speed["b3_ms_per_crop"] * 3 - speed["b3_ms"]) < 1e-9 and speed["b1_crops_per_s"] > 0


def test_ours_costs_what_the_paper_network_costs() -> None:
    assert 0.65e9 < estimator_flops(create_estimator("ours", pretrained=False)) < 0.75e9  # 0.70 GFLOP per crop


def test_end_to_end_names_every_stage() -> None:
    photo = portrait_photo(320, 240)
    assert photo.shape == (240, 320, 3) and photo.dtype.name == "uint8" and photo[:, :20].max() == 0
    ms = end_to_end(photo, create_estimator("uniform"), create_detector("none"), repeats=2)
    assert set(ms) == {"read", "check", "detect", "crop", "estimate", "write", "total"}
    assert all(v >= 0 for v in ms.values()) and ms["total"] >= ms["detect"]
