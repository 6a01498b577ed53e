"""kornia_ilum_lab.evaluation.scene: the face's, the scene's and the fused strength per skin tone."""

from __future__ import annotations

import pytest
import torch

from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.estimators import LightingEstimate
from kornia_ilum.estimators.scene import SceneStrength
from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum_lab.evaluation import EvalSet
from kornia_ilum_lab.evaluation.scene import NOMINAL_COVERAGE, scene_check

VALID = mirror_ball_valid(32)


class Face(torch.nn.Module):
    """Reads the light as twice the truth for dark crops: a face estimate biased by tone, spread 0.5."""

    def forward(self, crops: torch.Tensor) -> LightingEstimate:
        level = 1.0 + (crops.mean((1, 2, 3)) < 0.3).float()
        ball = level[:, None, None, None] * VALID.expand(len(crops), 3, 32, 32).float()
        return LightingEstimate(mirror_ball=ball, valid=VALID, log_energy_spread=torch.full((len(crops),), 0.5))


def _set(frames: bool = True) -> EvalSet:
    n = 8
    images = torch.zeros(n, 3, 16, 16, dtype=torch.uint8)
    images[:4] = 200  # light crops: tone 1; dark: tone 9
    truth = VALID.expand(n, 3, 32, 32).float().clone()
    return EvalSet(images, truth, ["indoor"] * n, [1] * 4 + [9] * 4, list(range(n)), ["room"] * n,
                   frames=torch.zeros(n, 3, 32, 32, dtype=torch.uint8) if frames else None,
                   frame_boxes=torch.tensor([[8.0, 8.0, 24.0, 24.0]] * n) if frames else None)


def test_the_fusion_removes_the_face_s_tone_bias_when_the_scene_is_sure():
    from kornia_ilum.metrics import total_radiance

    truth_log = torch.log(total_radiance(VALID.expand(1, 3, 32, 32).float()))[0]

    class Sure(torch.nn.Module):
        def forward(self, frames):
            return truth_log.expand(len(frames), 3), torch.full((len(frames),), 0.01)

    result = scene_check(Face(), Sure(), _set())
    table = result["table"]
    assert table["1"]["face"]["ratio"] == pytest.approx(1.0) and table["9"]["face"]["ratio"] == pytest.approx(2.0)
    assert result["tone_spread"]["face"]["ratio"] == pytest.approx(2.0)
    assert result["tone_spread"]["fused"]["ratio"] == pytest.approx(1.0, abs=1e-3)
    assert table["9"]["fused"]["coverage"] == 1.0 and table["9"]["face"]["coverage"] == 0.0  # log 2 > 0.5
    assert table["all"]["count"] == 8 and 0 < NOMINAL_COVERAGE < 1


def test_real_scene_network_runs_and_bad_sets_are_refused():
    result = scene_check(Face(), SceneStrength().eval(), _set())
    assert set(result["tone_spread"]) == {"face", "scene", "fused"}
    with pytest.raises(ValueCheckError, match="frames"):
        scene_check(Face(), SceneStrength(), _set(frames=False))
