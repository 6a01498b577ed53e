"""kornia_ilum_lab.bench.skips: the held-out maps, the clip, the video and sparse-relighting rows, and the report's
section."""

from __future__ import annotations

import torch

from kornia_ilum.bench.report import format_skips
from kornia_ilum_lab.bench.skips import (
    RELIGHT_SETTINGS,
    SUNNY,
    flicker,
    held_out_maps,
    lag,
    lrec_like,
    relight_skips,
    skip_rows,
    video_clip,
    video_skips,
)
from kornia_ilum.io import write_hdr
from kornia_ilum_lab.synth.environments.real import hdri_split
from kornia_ilum_lab.synth.lightstage.portraits import load_fields


def _maps(folder):
    folder.mkdir()
    for i, name in enumerate(("studio.exr", "forest.exr", "interior.exr")):  # eval, eval, train
        sky = torch.full((3, 16, 32), 0.2)
        sky[:, 3, 5 + 7 * i] = 50.0
        write_hdr(folder / name, sky)
    return folder


def test_held_out_maps_are_the_eval_split(tmp_path) -> None:
    maps = held_out_maps([_maps(tmp_path / "hdri")])
    assert [p.name for p in maps] == ["forest.exr", "studio.exr"]
    assert all(hdri_split(p.name) == "eval" for p in maps)


def test_the_measures() -> None:
    balls = torch.ones(4, 3, 8, 8)
    balls[1] *= 2.0
    assert flicker(balls, 2) > 0 and flicker(torch.ones(4, 3, 8, 8), 2) == 0.0
    energy = torch.tensor([1.0, 1.0, 5.0, 1.2, 1.0, 1.0])
    assert lag(energy, torch.ones(6), 2) == 2  # off by more than 10 % at frames 2 and 3
    image = torch.rand(2, 3, 100)
    assert lrec_like(image, image) == 0.0 and lrec_like(0.5 * image, image) > 0.05


def test_rows_on_a_tiny_subject(tiny_cache, tmp_path) -> None:
    field = load_fields(tiny_cache)[0]
    maps = held_out_maps([_maps(tmp_path / "hdri")])
    frames, truth, cut = video_clip(field, maps, (3, 2))
    assert len(frames) == 5 and frames[0].shape == (480, 640, 3) and truth.shape == (5, 3, 32, 32) and cut == 3
    video = video_skips(field, maps, estimator="uniform", quick=True)
    assert [r["setting"] for r in video] == ["per frame", "tracker defaults"] and video[0]["speedup"] == 1.0
    relit = relight_skips(field, maps, quick=True)
    assert [r["setting"] for r in relit][:len(RELIGHT_SETTINGS)] == [name for name, _, _ in RELIGHT_SETTINGS]
    assert relit[0]["setting"] == "dense" and relit[0]["error"]["l_rec_like"] == 0.0
    assert all(r["ms"] > 0 and 0.0 <= r["error"]["l_rec_like"] <= r["error"]["l_rec_like_max"] for r in relit)
    assert {r["skip"] for r in relit} <= {"sparse relighting, all held-out maps",
                                          f"sparse relighting, sun-dominated maps (top 1 % >= {SUNNY:g})",
                                          "sparse relighting, sun-dominated outdoor maps"}
    text = format_skips(video + relit, "a tiny subject")
    assert "## Skips: time saved against error added" in text and "sparse relighting" in text
    assert format_skips([], "skips: not measured") == "skips: not measured."


def test_nothing_to_measure_says_why(tmp_path) -> None:
    rows, what = skip_rows([tmp_path], [_maps(tmp_path / "hdri")], quick=True)
    assert rows == [] and "not measured" in what
