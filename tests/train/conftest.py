"""A tiny light-stage cache for the training tests: two train mannequins, one 48 px view each."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def tiny_cache(tmp_path_factory):
    from kornia_ilum.synth.lightstage import build_cache

    out = tmp_path_factory.mktemp("train_cache")
    build_cache("mannequin", [0, 2], out, views_per_subject=1, size=48, spp=4, workers=1, progress=False)
    return out
