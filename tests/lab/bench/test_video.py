"""kornia_ilum_lab.bench.video: the clip, the flicker and lag, and the video skip's rows."""

from __future__ import annotations

import torch

from kornia_ilum_lab.bench.maps import held_out_maps
from kornia_ilum_lab.bench.video import flicker, lag, video_clip, video_skips
from kornia_ilum_lab.synth.lightstage.portraits import load_fields
from tests.lab.bench.maps_helper import three_maps


def test_the_measures() -> None:
    balls = torch.ones(4, 3, 8, 8)
    balls[1] *= 2.0
    assert flicker(balls, 2) > 0 and flicker(torch.ones(4, 3, 8, 8), 2) == 0.0
    energy = torch.tensor([1.0, 1.0, 5.0, 1.2, 1.0, 1.0])
    assert lag(energy, torch.ones(6), 2) == 2  # off by more than 10 % at frames 2 and 3


def test_rows_on_a_tiny_subject(tiny_cache, tmp_path) -> None:
    field = load_fields(tiny_cache)[0]
    maps = held_out_maps([three_maps(tmp_path / "hdri")])
    frames, truth, cut = video_clip(field, maps, (3, 2))
    assert len(frames) == 5 and frames[0].shape == (480, 640, 3) and truth.shape == (5, 3, 32, 32) and cut == 3
    video = video_skips(field, maps, estimator="uniform", quick=True)
    assert [r["setting"] for r in video] == ["per frame", "tracker defaults"] and video[0]["speedup"] == 1.0
