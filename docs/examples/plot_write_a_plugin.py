r"""
Write and register an estimator plugin
======================================

Every estimator, built in or third party, is a :class:`~kornia_ilum.estimators.LightingEstimator` with an
:class:`~kornia_ilum.estimators.EstimatorInfo` and a ``predict(crops)`` that returns a
:class:`~kornia_ilum.estimators.LightingEstimate`. A package registers it under the entry-point group
``kornia_ilum.estimators`` of its ``pyproject.toml``::

    [project.entry-points."kornia_ilum.estimators"]
    grey = "my_package:GreyEstimator"

After ``pip install``, ``kornia-ilum estimate --estimator grey`` and ``estimate_lighting(img, estimator="grey")``
find it. At runtime, :func:`~kornia_ilum.estimators.register_estimator` does the same, as here.
"""

import skimage.data
import torch

import kornia_ilum
from kornia_ilum.color import srgb_to_linear
from kornia_ilum.estimators import EstimatorInfo, LightingEstimate, LightingEstimator, register_estimator
from kornia_ilum.geometry import mirror_ball_valid


class GreyEstimator(LightingEstimator):
    """Uniform grey lighting whose level is the crop's mean linear luminance over an albedo of 0.5."""

    info = EstimatorInfo("grey", "uniform grey from the crop's mean", "none: an example", needs_weights=False)

    def predict(self, crops: torch.Tensor) -> LightingEstimate:
        level = srgb_to_linear(crops).mean(dim=(1, 2, 3)) / 0.5  # (B,)
        valid = mirror_ball_valid(32, device=crops.device)
        ball = level[:, None, None, None] * valid * crops.new_ones(len(crops), 3, 32, 32)
        return LightingEstimate(mirror_ball=ball, valid=valid)


register_estimator("grey", GreyEstimator, clobber=True)
print(kornia_ilum.estimators.list_estimators())

# %%
# It now runs like any other estimator, through the same API, checks and outputs.

image = torch.from_numpy(skimage.data.astronaut()).permute(2, 0, 1).float() / 255
estimate = kornia_ilum.estimate_lighting(image, estimator="grey")
print("grey level:", round(float(estimate.mirror_ball[0, 0, 16, 16]), 4))
