"""Shared settings and stand-ins of the portrait tests."""

from __future__ import annotations

import torch

from kornia_ilum.geometry import latlong_to_mirror_ball
from kornia_ilum_lab.synth.camera_effects import CameraEffects
from kornia_ilum_lab.synth.environments import Environment, EnvironmentSampler
from kornia_ilum_lab.synth.lightstage.portraits import PortraitConfig, PortraitDataset

S = 8  # lighting size of the tests

SIZE = 48  # render side

OUT = 64  # portrait side

class Uniform:
    """An environment source of constant radiance (or a bright patch on one side, for the flip test)."""

    label = "indoor"

    def __init__(self, radiance: float = 1.0, left_light: float = 0.0) -> None:
        self.radiance, self.left_light = radiance, left_light

    def sample(self, generator: torch.Generator) -> Environment:
        latlong = torch.full((3, 16, 32), self.radiance)
        if self.left_light:
            latlong[:, 6:10, 7:9] = self.left_light  # azimuth about -90 degrees: light from -X (image left)
        return Environment(latlong, latlong_to_mirror_ball(latlong[None], 32)[0], self.label, "test:uniform")

def uniform_sampler(**kw: float) -> EnvironmentSampler:
    return EnvironmentSampler([Uniform(**kw)], augment=None, seed=0)

OFF = CameraEffects.off()

def small(fields, seed: int = 0, **kw) -> PortraitDataset:
    settings = {"size": OUT, "sphere_sizes": (4, 8), "fields_per_chunk": 2, "lightings_per_field": 4,
                "env_pool": 4, "env_refresh": 1, "shuffle": 2, "environments": EnvironmentSampler(seed=0)}
    settings.update(kw)
    return PortraitDataset(fields, PortraitConfig(**settings), seed=seed)
