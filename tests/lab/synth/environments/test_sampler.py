"""Tests of the environment sampler: exact reproducibility per (seed, index), defaults, weights."""

from __future__ import annotations

import pytest
import torch

from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum_lab.synth.environments import (
    Augment,
    Environment,
    EnvironmentSampler,
    EnvironmentSource,
    HDRFolderSource,
    default_sources,
    default_weights,
)
from kornia_ilum_lab.synth.environments.indoor import IndoorSource
from kornia_ilum_lab.synth.environments.portrait import PortraitLightSource
from kornia_ilum_lab.synth.environments.sampler import generator_for
from kornia_ilum_lab.synth.environments.sky import SkySource


class Flat:
    """A fast source: a constant map whose value is drawn from the generator."""

    def __init__(self, label: str = "outdoor", name: str = "flat", height: int = 8) -> None:
        self.label, self.name, self.height = label, name, height

    def sample(self, generator: torch.Generator) -> Environment:
        value = float(torch.rand(1, generator=generator)) + 0.5
        return Environment(
            torch.full((3, self.height, 2 * self.height), value),
            torch.full((3, 32, 32), value),
            self.label,
            f"{self.name}:flat",
            {"value": value},
        )


def same(a: Environment, b: Environment) -> bool:
    return (
        torch.equal(a.latlong, b.latlong)
        and torch.equal(a.mirror_ball, b.mirror_ball)
        and (a.label, a.source, a.params) == (b.label, b.source, b.params)
    )


class TestEnvironmentSampler:
    def test_smoke(self):
        env = EnvironmentSampler([Flat()]).sample(0)
        assert env.source == "flat:flat" and env.params["sampler"] == {"seed": 0, "index": 0, "source": 0}
        assert "augment" in env.params

    def test_cardinality(self):
        env = EnvironmentSampler([Flat(height=6)], augment=None).sample(3)
        assert env.latlong.shape == (3, 6, 12) and env.mirror_ball.shape == (3, 32, 32)

    def test_reproducible_per_seed_and_index(self):
        sources = [Flat("outdoor", "a"), Flat("indoor", "b")]
        first = EnvironmentSampler(sources, seed=5)
        forward = [first.sample(i) for i in range(6)]
        second = EnvironmentSampler(sources, seed=5)  # a fresh sampler, indices in another order
        backward = [second.sample(i) for i in reversed(range(6))][::-1]
        assert all(same(a, b) for a, b in zip(forward, backward, strict=True))
        assert not same(forward[0], forward[1])
        assert not same(forward[2], EnvironmentSampler(sources, seed=6).sample(2))

    def test_procedural_defaults_reproduce_exactly(self):
        sampler = EnvironmentSampler(default_sources(height=32), seed=1)
        envs = [sampler.sample(i) for i in range(4)]
        again = EnvironmentSampler(default_sources(height=32), seed=1)
        assert all(same(again.sample(i), envs[i]) for i in (3, 1, 0, 2))
        assert all(e.latlong.shape == (3, 32, 64) for e in envs)
        assert {e.label for e in envs} == {"indoor", "outdoor"}

    def test_default_sources(self, tmp_path):
        sky, indoor, portrait = default_sources()
        assert isinstance(sky, SkySource) and isinstance(indoor, IndoorSource)
        assert isinstance(portrait, PortraitLightSource) and portrait.height == 128
        assert all(isinstance(s, EnvironmentSource) for s in (sky, indoor, portrait))
        from kornia_ilum.io import write_hdr

        write_hdr(tmp_path / "field.exr", torch.ones(3, 8, 16))
        sources = default_sources(tmp_path, height=16)
        assert isinstance(sources[-1], HDRFolderSource) and sources[-1].height == 16 and len(sources) == 4
        assert sources[2].height == 16
        # the portrait lights take a quarter; the rest is shared half indoor, half outdoor as before
        # (it was [0.5, 0.5] and [0.25, 0.5, 0.25] without the portrait lights: the same ratios, times 0.75)
        assert EnvironmentSampler().weights == [0.375, 0.375, 0.25]
        assert EnvironmentSampler(sources).weights == [0.1875, 0.375, 0.25, 0.1875]

    def test_default_weights(self):
        assert default_weights([Flat("indoor")] * 3) == pytest.approx([1 / 3] * 3)
        assert default_weights([Flat("outdoor"), Flat("indoor"), Flat("indoor")]) == [0.5, 0.25, 0.25]

    def test_default_weights_with_shares(self):
        """A source with a default_share gets it whatever its label; the others share the rest by label."""
        shared = Flat("outdoor")
        shared.default_share = 0.25
        assert default_weights([Flat("outdoor"), Flat("indoor"), shared]) == [0.375, 0.375, 0.25]
        shared.label = "indoor"  # its label takes no part in the balance
        assert default_weights([Flat("outdoor"), Flat("indoor"), shared]) == [0.375, 0.375, 0.25]
        assert default_weights([Flat("indoor"), shared]) == [0.75, 0.25]
        assert default_weights([shared]) == [0.25]  # alone: the sampler normalises it to 1
        other = Flat("indoor")
        other.default_share = 0.75
        assert default_weights([Flat("outdoor"), shared, other]) == [0.0, 0.25, 0.75]
        other.default_share = 1.5
        with pytest.raises(ValueCheckError, match=r"sources\[1\].default_share must be a number in \[0, 1\]"):
            default_weights([Flat("outdoor"), other])

    def test_default_weights_pick_the_portrait_lights_a_quarter_of_the_time(self):
        shared = Flat("indoor", "portrait")
        shared.default_share = 0.25
        sampler = EnvironmentSampler([Flat("outdoor", "sky"), Flat("indoor", "room"), shared], augment=None)
        picks = [sampler.sample(i).source for i in range(800)]
        assert abs(picks.count("portrait:flat") / 800 - 0.25) < 0.05
        assert abs(picks.count("sky:flat") / 800 - 0.375) < 0.05

    def test_weights_pick_sources(self):
        sources = [Flat("outdoor", "a"), Flat("outdoor", "b")]
        only_b = EnvironmentSampler(sources, [0, 1], augment=None)
        assert {only_b.sample(i).source for i in range(20)} == {"b:flat"}
        picks = [EnvironmentSampler(sources, [1, 3], augment=None).sample(i).source for i in range(400)]
        assert 0.68 < picks.count("b:flat") / 400 < 0.82

    def test_augment_none_passes_source_output(self):
        env = EnvironmentSampler([Flat()], augment=None).sample(2)
        assert set(env.params) == {"value", "sampler"}
        assert float(env.latlong[0, 0, 0]) == env.params["value"]

    def test_custom_augment(self):
        env = EnvironmentSampler([Flat()], augment=Augment(exposure_stops=(1.0, 1.0))).sample(0)
        assert env.params["augment"]["exposure_stops"] == 1.0

    def test_exception(self):
        with pytest.raises(ValueCheckError, match="sources must not be empty"):
            EnvironmentSampler([])
        with pytest.raises(TypeCheckError, match=r"sources\[1\] must have a sample\(generator\) method"):
            EnvironmentSampler([Flat(), object()])
        with pytest.raises(ValueCheckError, match="weights must be 2 finite non-negative numbers"):
            EnvironmentSampler([Flat(), Flat()], [1.0])
        with pytest.raises(ValueCheckError, match="weights must be 1 finite non-negative numbers"):
            EnvironmentSampler([Flat()], [-1.0])
        with pytest.raises(ValueCheckError, match="not all 0"):
            EnvironmentSampler([Flat()], [0.0])
        with pytest.raises(TypeCheckError, match="augment must be callable or None"):
            EnvironmentSampler([Flat()], augment=3)
        with pytest.raises(TypeCheckError, match="seed must be an int"):
            EnvironmentSampler([Flat()], seed=1.5)
        with pytest.raises(ValueCheckError, match="index must be non-negative"):
            EnvironmentSampler([Flat()]).sample(-1)

        class Bad(Flat):
            def sample(self, generator):
                env = super().sample(generator)
                env.mirror_ball = env.mirror_ball[:, :16, :16]
                return env

        with pytest.raises(ShapeError, match=r"sources\[0\]: mirror_ball must have shape \(3, 32, 32\)"):
            EnvironmentSampler([Bad()], augment=None).sample(0)


def test_generator_for():
    a, b = generator_for(0, 1), generator_for(0, 1)
    assert torch.equal(torch.rand(4, generator=a), torch.rand(4, generator=b))
    draws = {float(torch.rand(1, generator=generator_for(s, i))) for s in range(3) for i in range(30)}
    assert len(draws) == 90
    with pytest.raises(TypeCheckError, match="index must be an int"):
        generator_for(0, "3")
