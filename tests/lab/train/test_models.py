"""kornia_ilum_lab.train.models: the training-only networks of ``ours``."""

from __future__ import annotations

import torch

from kornia_ilum.estimators import OursEstimator
from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum_lab.train import SCALES, MSGDiscriminator, MultiScaleOurs


class TestModels:
    def test_side_branches_are_not_exported(self) -> None:
        model = MultiScaleOurs()
        out = model(torch.rand(2, 3, 256, 256))
        for s in SCALES:
            valid = mirror_ball_valid(s)
            assert out[s].shape == (2, 3, s, s) and out[s].dtype == torch.float32
            assert (out[s][:, :, valid] > 0).all() and (out[s][:, :, ~valid] == 0).all()
        assert model.estimator.state_dict().keys() == OursEstimator().state_dict().keys()
        assert not any(k.startswith("sides") for k in model.estimator.state_dict())

    def test_discriminator(self) -> None:
        d = MSGDiscriminator()
        x = {s: torch.rand(3, 3, s, s, requires_grad=True) for s in SCALES}
        logits = d(x)
        assert logits.shape == (3,)
        logits.sum().backward()
        assert all(x[s].grad is not None and x[s].grad.abs().sum() > 0 for s in SCALES)  # every scale is seen
