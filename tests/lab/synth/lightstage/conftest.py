"""Fixtures of the light-stage tests."""

from __future__ import annotations

import pytest

from kornia_ilum_lab.synth.lightstage.materials import select_mitsuba_variant
from kornia_ilum_lab.synth.lightstage.subjects import MakeHumanSource

_SOURCES: dict = {}


@pytest.fixture
def mh(shared_data):
    """One MakeHuman source per test session (the asset parse is cached inside it)."""
    if shared_data not in _SOURCES:
        _SOURCES[shared_data] = MakeHumanSource.from_assets(shared_data / "makehuman")
    return _SOURCES[shared_data]


@pytest.fixture(scope="module")
def variant() -> str:
    """The Mitsuba variant that the renderers pick (probed once per process, in a child process)."""
    return select_mitsuba_variant()
