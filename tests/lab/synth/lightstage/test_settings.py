"""Settings of the OLAT renderers (kornia_ilum_lab.synth.lightstage.settings): defaults, checks, resolution."""

from __future__ import annotations

import dataclasses
import json

import pytest

from kornia_ilum.core.errors import TypeCheckError, ValueCheckError
from kornia_ilum_lab.synth.lightstage.settings import (
    ONEPASS_CHUNK_LANES,
    ONEPASS_EDGE_SPP,
    ONEPASS_SHADE_SPP,
    ONEPASS_SPP,
    REFERENCE_MAX_DEPTH,
    REFERENCE_SPP,
    Auto,
    OnePass,
    Reference,
    is_vectorised,
)


class TestOnePass:
    def test_defaults_are_resolved(self) -> None:
        s = OnePass()
        expected = (ONEPASS_SPP, ONEPASS_SHADE_SPP, ONEPASS_EDGE_SPP, True)
        assert (s.spp, s.shade_spp, s.edge_spp, s.demodulate) == expected
        assert s.lighting_size == 32 and s.seed == 0 and s.subsurface and not s.denoise
        assert s.chunk_lanes == ONEPASS_CHUNK_LANES
        assert OnePass(spp=16) == OnePass(spp=16, shade_spp=4, edge_spp=16, demodulate=True)

    def test_every_sample_traced(self) -> None:
        """shade_spp = spp: no demodulation, and the mixed pixels trace what the others trace."""
        s = OnePass(spp=4)
        assert (s.shade_spp, s.edge_spp, s.demodulate) == (4, 4, False)
        assert OnePass(spp=8, shade_spp=8, edge_spp=2).edge_spp == 8  # without demodulation: shade_spp

    def test_frozen_and_json(self) -> None:
        s = OnePass(spp=8, shade_spp=2)
        with pytest.raises(dataclasses.FrozenInstanceError):
            s.spp = 4  # type: ignore[misc]
        d = s.to_dict()
        assert d["method"] == "onepass" and d["shade_spp"] == 2 and json.loads(json.dumps(d)) == d
        assert hash(s) == hash(OnePass(spp=8, shade_spp=2))

    @pytest.mark.parametrize(
        ("kwargs", "error", "match"),
        [
            ({"spp": 0}, ValueCheckError, "spp must be positive"),
            ({"spp": 4, "shade_spp": 8}, ValueCheckError, "shade_spp must be at most spp"),
            ({"spp": 8, "shade_spp": 2, "demodulate": False}, ValueCheckError, "demodulate=False needs"),
            ({"spp": 8, "edge_spp": 16}, ValueCheckError, "edge_spp must be at most spp"),
            ({"seed": -1}, ValueCheckError, "seed must be a non-negative int"),
            ({"seed": True}, ValueCheckError, "seed must be a non-negative int"),
            ({"lighting_size": 0}, ValueCheckError, "lighting_size must be positive"),
            ({"chunk_lanes": 0}, ValueCheckError, "chunk_lanes must be positive"),
            ({"subsurface": 1}, TypeCheckError, "subsurface must be a bool"),
            ({"demodulate": "yes"}, TypeCheckError, "demodulate must be a bool"),
        ],
    )
    def test_exception(self, kwargs: dict, error: type, match: str) -> None:
        with pytest.raises(error, match=match):
            OnePass(**kwargs)
        with pytest.raises(TypeError):
            OnePass(16)  # type: ignore[misc]  # keyword-only


class TestReference:
    def test_defaults(self) -> None:
        s = Reference(lighting_size=8)
        expected = (REFERENCE_SPP, REFERENCE_MAX_DEPTH, 32, None)
        assert (s.spp, s.max_depth, s.envmap_height, s.lights) == expected
        assert Reference(lighting_size=4, lights=[6, 5, 6]).lights == (6, 5, 6)  # order and repeats kept
        assert Reference(lighting_size=4, lights=[5]).to_dict()["lights"] == [5]

    @pytest.mark.parametrize(
        ("kwargs", "match"),
        [
            ({"spp": 0}, "spp must be positive"),
            ({"max_depth": 0}, "max_depth must be positive"),
            ({"envmap_height": 0}, "envmap_height must be positive"),
            ({"lighting_size": 4, "lights": [0]}, "lights must be valid light indices of the 4"),
            ({"lighting_size": 4, "lights": []}, "lights must be valid light indices"),
            ({"seed": 1.5}, "seed must be a non-negative int"),
        ],
    )
    def test_exception(self, kwargs: dict, match: str) -> None:
        with pytest.raises(ValueCheckError, match=match):
            Reference(**kwargs)


class TestAuto:
    def test_resolve(self) -> None:
        assert Auto().resolve("llvm_ad_rgb") == OnePass()
        assert Auto(lighting_size=8, spp=4, seed=2).resolve("cuda_ad_rgb") == OnePass(lighting_size=8, spp=4,
                                                                                       seed=2)
        assert Auto().resolve("scalar_rgb") == Reference()
        assert Auto(spp=4).resolve("scalar_rgb") == Reference(spp=4)
        assert is_vectorised("llvm_ad_rgb") and not is_vectorised("scalar_rgb")
        assert Auto(spp=4).to_dict() == {"method": "auto", "lighting_size": 32, "spp": 4, "seed": 0}

    def test_exception(self) -> None:
        with pytest.raises(ValueCheckError, match="spp must be positive"):
            Auto(spp=0)
        with pytest.raises(ValueCheckError, match="lighting_size must be positive"):
            Auto(lighting_size=-1)
