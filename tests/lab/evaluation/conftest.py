"""Fixtures of the evaluation tests: two tiny caches, tiny maps and the eval set built from them."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from kornia_ilum_lab.evaluation import build_eval_set
from kornia_ilum.io import write_hdr
from kornia_ilum_lab.synth.lightstage import subject_split
from tests.lab.evaluation.helpers import N, write_cache


@pytest.fixture(scope="package")
def caches(tmp_path_factory) -> list[Path]:
    """Two caches: seeds 0 (train), 1 and 3 (eval); and an eval-only one with seed 5 (train) and 7 (eval)."""
    assert [subject_split(s) for s in (0, 1, 3, 5)] == ["train", "eval", "eval", "train"]
    eval_seven = next(s for s in range(6, 100) if subject_split(s) == "eval")
    a = write_cache(tmp_path_factory.mktemp("cache_a"), [(0, 2), (1, 3), (3, 6)])
    b = write_cache(tmp_path_factory.mktemp("cache_b"), [(5, 4), (eval_seven, 9)])
    return [a, b]


@pytest.fixture(scope="package")
def hdri(tmp_path_factory) -> Path:
    """Tiny maps: studio.exr, forest.exr (eval) and interior.exr (train)."""
    folder = tmp_path_factory.mktemp("hdri")
    for name, value in (("studio.exr", 1.0), ("forest.exr", 2.0), ("interior.exr", 50.0)):
        write_hdr(folder / name, torch.full((3, 16, 32), value))
    return folder


@pytest.fixture(scope="package")
def eval_set(caches, hdri):
    return build_eval_set(caches, [hdri], samples=N, fields_per_chunk=2, lightings_per_field=4)


@pytest.fixture(scope="package")
def context_set(caches, hdri):
    """The first 8 portraits of ``eval_set`` as context crops (1.5 times the nominal face crop)."""
    return build_eval_set(caches, [hdri], samples=8, fields_per_chunk=2, lightings_per_field=4, context=1.5)
