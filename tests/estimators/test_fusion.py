"""kornia_ilum.estimators.fusion: several faces' estimates fused in log space, one lighting per photo."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from kornia_ilum import estimate_lighting
from kornia_ilum.core.errors import ShapeError, ValueCheckError
from kornia_ilum.estimators import LightingEstimate, fuse_faces
from kornia_ilum.geometry import mirror_ball_valid

VALID = mirror_ball_valid(32)


def _faces(*levels: float) -> LightingEstimate:
    light = torch.stack([torch.rand(3, 32, 32) * v + v for v in levels]) * VALID
    boxes = torch.tensor([[0.0, 0.0, 10.0 * (i + 1), 10.0 * (i + 1)] for i in range(len(levels))])
    return LightingEstimate(mirror_ball=light, valid=VALID, boxes=boxes)


def test_weighted_geometric_mean_per_group() -> None:
    torch.manual_seed(0)
    faces = _faces(1.0, 4.0, 2.0)
    weights, groups = torch.tensor([1.0, 3.0, 2.0]), torch.tensor([0, 0, 1])
    out = fuse_faces(faces, weights, groups)
    expected = torch.exp((faces.mirror_ball[0].log() * 1 + faces.mirror_ball[1].log() * 3) / 4) * VALID
    torch.testing.assert_close(out.mirror_ball[0], expected)
    torch.testing.assert_close(out.mirror_ball[1], faces.mirror_ball[2])  # a group of one is itself
    torch.testing.assert_close(out.log_mirror_ball, torch.log1p(out.mirror_ball))
    assert out.image_index.tolist() == [0, 1] and out.sh is None
    assert out.boxes.tolist() == [faces.boxes[1].tolist(), faces.boxes[2].tolist()]  # most confident face


def test_scale_errors_cancel_and_zeros_do_not_win() -> None:
    faces = _faces(2.0, 0.5)
    faces.mirror_ball[0, :, 16, 16] = 0.0  # one estimator left a pixel black
    out = fuse_faces(faces, torch.ones(2), torch.zeros(2, dtype=torch.int64))
    assert out.mirror_ball[0, 0, 16, 16] > 0 and torch.isfinite(out.mirror_ball).all()


def test_refusals() -> None:
    faces = _faces(1.0, 2.0)
    with pytest.raises(ValueCheckError, match="non-negative"):
        fuse_faces(faces, torch.tensor([1.0, -1.0]), torch.zeros(2, dtype=torch.int64))
    with pytest.raises(ValueCheckError, match="positive total"):
        fuse_faces(faces, torch.tensor([0.0, 0.0]), torch.zeros(2, dtype=torch.int64))
    with pytest.raises(ShapeError, match="groups"):
        fuse_faces(faces, torch.ones(2), torch.zeros(3, dtype=torch.int64))
    with pytest.raises(ValueCheckError, match="every index"):
        fuse_faces(faces, torch.ones(2), torch.tensor([0, 2]))


def test_estimate_lighting_fuses_every_face_of_each_photo() -> None:
    import skimage.data  # the astronaut, twice side by side: two faces, one light

    face = skimage.data.astronaut()
    photo = np.concatenate([face, face[:, ::-1]], axis=1)
    every = estimate_lighting(photo, faces="all")
    fused = estimate_lighting(photo, faces="fused")
    assert len(every) >= 2 and len(fused) == 1 and fused.image_index.tolist() == [0]
    lo, hi = every.mirror_ball.min(0).values, every.mirror_ball.max(0).values
    assert ((fused.mirror_ball >= lo * (1 - 1e-5)) & (fused.mirror_ball <= hi * (1 + 1e-5))).all()


def test_spreads_weigh_as_inverse_variances() -> None:
    torch.manual_seed(1)
    faces = _faces(1.0, 4.0)
    spread = torch.tensor([0.2, 0.4])
    sure = LightingEstimate(mirror_ball=faces.mirror_ball, valid=VALID, boxes=faces.boxes, log_energy_spread=spread)
    out = fuse_faces(sure, torch.ones(2), torch.zeros(2, dtype=torch.int64))
    plain = fuse_faces(faces, torch.tensor([1 / 0.2**2, 1 / 0.4**2]), torch.zeros(2, dtype=torch.int64))
    torch.testing.assert_close(out.mirror_ball, plain.mirror_ball)  # the same as weights 1 / b^2
    expected = 1 / (1 / 0.2**2 + 1 / 0.4**2) ** 0.5  # independent faces: the spread narrows
    assert out.log_energy_spread.item() == pytest.approx(expected, rel=1e-5)
    assert fuse_faces(faces, torch.ones(2), torch.zeros(2, dtype=torch.int64)).log_energy_spread is None
