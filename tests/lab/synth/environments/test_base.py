"""Tests of the environment record and the source protocol."""

from __future__ import annotations

import torch

from kornia_ilum_lab.synth.environments import Environment, EnvironmentSource, IndoorSource, SkySource


def test_environment_params_default_to_a_fresh_dict():
    a = Environment(torch.zeros(3, 4, 8), torch.zeros(3, 32, 32), "indoor", "indoor:room")
    b = Environment(torch.zeros(3, 4, 8), torch.zeros(3, 32, 32), "outdoor", "sky:clear")
    a.params["x"] = 1
    assert b.params == {} and a.params == {"x": 1}


def test_source_protocol_is_structural():
    class Source:
        label = "indoor"

        def sample(self, generator: torch.Generator) -> Environment:
            return Environment(torch.zeros(3, 4, 8), torch.zeros(3, 32, 32), self.label, "test")

    assert isinstance(Source(), EnvironmentSource)
    assert isinstance(SkySource(height=8), EnvironmentSource)
    assert isinstance(IndoorSource(height=8), EnvironmentSource)
    assert not isinstance(object(), EnvironmentSource)
