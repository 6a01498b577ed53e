"""kornia_ilum_lab.bench.maps: the held-out maps of the bench's clips."""

from __future__ import annotations

import torch

from kornia_ilum_lab.bench.maps import held_out_maps, small_latlong
from kornia_ilum_lab.synth.environments.real import hdri_split
from tests.lab.bench.maps_helper import three_maps


def test_held_out_maps_are_the_eval_split(tmp_path) -> None:
    maps = held_out_maps([three_maps(tmp_path / "hdri")])
    assert [p.name for p in maps] == ["forest.exr", "studio.exr"]
    assert all(hdri_split(p.name) == "eval" for p in maps)


def test_small_latlong(tmp_path) -> None:
    small = small_latlong(held_out_maps([three_maps(tmp_path / "hdri")])[0], height=8)
    assert small.shape[-3:] == (3, 8, 16) and torch.isfinite(small).all()
