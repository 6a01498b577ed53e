"""Fixtures of the light-stage tests."""

from __future__ import annotations

import pytest

_SOURCES: dict = {}


@pytest.fixture
def mh(shared_data):
    """One MakeHuman source per test session (the asset parse is cached inside it)."""
    from kornia_ilum.synth.lightstage.subjects import MakeHumanSource

    if shared_data not in _SOURCES:
        _SOURCES[shared_data] = MakeHumanSource.from_assets(shared_data / "makehuman")
    return _SOURCES[shared_data]
