"""sh and sipr follow the photo's exposure by design (issue 39): a crop darkened k times in linear light, without
new clipping, gives k times the lighting, exactly up to float round-off; without the normalisation they do not."""

from __future__ import annotations

import pytest
import torch

from kornia_ilum.estimators import create_estimator
from kornia_ilum.metrics import lighting_energy
from kornia_ilum_lab.evaluation import darken


@pytest.mark.parametrize("name", ["sh", "sipr"])
def test_darker_photo_darker_light(name: str) -> None:
    torch.manual_seed(0)
    ratios = {}
    for design in (True, False):
        net = create_estimator(name, normalize_exposure=design)
        size = net.info.input_size  # at the network's own size: no resampling between the two exposures
        crops = torch.rand(2, 3, size, size) * 0.8  # nothing at white: darkening clips nothing anew
        with torch.inference_mode():
            bright = lighting_energy(net(crops).mirror_ball.double())
            dark = lighting_energy(net(darken(crops, 0.25)).mirror_ball.double())
        ratios[design] = dark / (0.25 * bright)
    torch.testing.assert_close(ratios[True], torch.ones(2, dtype=torch.float64), rtol=2e-3, atol=0)
    assert (ratios[False] - 1).abs().max() > 0.05  # the networks alone do not
