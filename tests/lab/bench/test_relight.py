"""kornia_ilum_lab.bench.relight: the relighting measure and the sparse-relighting skip's rows."""

from __future__ import annotations

import torch

from kornia_ilum.bench.report import format_skips
from kornia_ilum_lab.bench.maps import held_out_maps
from kornia_ilum_lab.bench.relight import RELIGHT_SETTINGS, SUNNY, lrec_like, relight_skips
from kornia_ilum_lab.synth.lightstage.portraits import load_fields
from tests.lab.bench.maps_helper import three_maps


def test_lrec_like() -> None:
    image = torch.rand(2, 3, 100)
    assert lrec_like(image, image) == 0.0 and lrec_like(0.5 * image, image) > 0.05


def test_rows_on_a_tiny_subject(tiny_cache, tmp_path) -> None:
    field = load_fields(tiny_cache)[0]
    maps = held_out_maps([three_maps(tmp_path / "hdri")])
    relit = relight_skips(field, maps, quick=True)
    assert [r["setting"] for r in relit][:len(RELIGHT_SETTINGS)] == [name for name, _, _ in RELIGHT_SETTINGS]
    assert relit[0]["setting"] == "dense" and relit[0]["error"]["l_rec_like"] == 0.0
    assert all(r["ms"] > 0 and 0.0 <= r["error"]["l_rec_like"] <= r["error"]["l_rec_like_max"] for r in relit)
    assert {r["skip"] for r in relit} <= {"sparse relighting, all held-out maps",
                                          f"sparse relighting, sun-dominated maps (top 1 % >= {SUNNY:g})",
                                          "sparse relighting, sun-dominated outdoor maps"}
    text = format_skips(relit, "a tiny subject")
    assert "## Skips: time saved against error added" in text and "sparse relighting" in text
    assert format_skips([], "skips: not measured") == "skips: not measured."
