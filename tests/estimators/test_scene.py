"""The scene branch (kornia_ilum.estimators.scene): its input, its network's units, and the fusion of strengths."""

from __future__ import annotations

import math

import pytest
import torch

from kornia_ilum.color import linear_to_srgb
from kornia_ilum.core.errors import ShapeError
from kornia_ilum.estimators import LightingEstimate
from kornia_ilum.estimators.ours import LOG_SPREAD_RANGE
from kornia_ilum.estimators.scene import MIN_REST, SCENE_SIZE, SceneStrength, fuse_strength, scene_input
from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum.metrics import total_radiance


class TestSceneInput:
    def test_letterbox_and_box_channel(self):
        tall = torch.rand(1, 3, 200, 100)
        x = scene_input(tall, torch.tensor([[0.0, 0.0, 100.0, 100.0]]), torch.zeros(1, dtype=torch.int64))
        assert x.shape == (1, 5, SCENE_SIZE, SCENE_SIZE)
        assert x[0, 4, :, 32:96].all() and x[0, 4].sum() == 64 * SCENE_SIZE  # the photo's extent
        # the longer side fits: 64 columns of photo in the middle, 32 of padding each side
        assert x[0, :3, :, :32].abs().sum() == 0 and x[0, :3, :, 96:].abs().sum() == 0
        assert x[0, :3, :, 32:96].min() >= 0 and x[0, :3, :, 32:96].max() <= 1
        mask = x[0, 3]
        assert mask[:64, 32:96].all() and mask.sum() == 64 * 64  # the top half of the photo

    def test_several_faces_of_one_photo(self):
        photos = torch.rand(2, 3, 64, 64)
        boxes = torch.tensor([[0.0, 0.0, 32.0, 32.0], [32.0, 32.0, 64.0, 64.0], [0.0, 0.0, 64.0, 64.0]])
        x = scene_input(photos, boxes, torch.tensor([0, 0, 1]), size=64)
        torch.testing.assert_close(x[0, :3], x[1, :3])  # one photo, two faces: two masks
        assert not torch.equal(x[0, 3], x[1, 3]) and x[2, 3].all()
        torch.testing.assert_close(x[2, :3], photos[1], atol=1e-5, rtol=0)

    def test_bad_shapes(self):
        with pytest.raises(ShapeError, match="boxes"):
            scene_input(torch.rand(1, 3, 8, 8), torch.zeros(4), torch.zeros(1, dtype=torch.int64))
        with pytest.raises(ShapeError, match="boxes"):
            scene_input(torch.rand(1, 3, 8, 8), torch.zeros(2, 4), torch.zeros(1, dtype=torch.int64))


class TestSceneStrength:
    def test_scales_exactly_with_the_exposure(self):
        """Half the light in the photo (no pixel clipped): the same network input, the log energy down by log 2."""
        torch.manual_seed(0)
        net = SceneStrength().eval()
        linear = 0.4 * torch.rand(2, 3, 96, 128)
        boxes, index = torch.tensor([[24.0, 24.0, 72.0, 72.0]] * 2), torch.tensor([0, 1])
        with torch.no_grad():
            e1, b1 = net(scene_input(linear_to_srgb(linear), boxes, index))
            e2, b2 = net(scene_input(linear_to_srgb(0.5 * linear), boxes, index))
        torch.testing.assert_close(e2, e1 - torch.log(torch.tensor(2.0)), atol=2e-4, rtol=0)
        torch.testing.assert_close(b2, b1, atol=2e-4, rtol=1e-3)

    def test_blind_to_the_face(self):
        """Whatever is inside the face's box (a light skin or a dark one), the branch says the same."""
        torch.manual_seed(0)
        net = SceneStrength().eval()
        photo = torch.rand(1, 3, 96, 96)
        dark = photo.clone()
        dark[..., 24:72, 24:72] *= 0.2
        box, index = torch.tensor([[24.0, 24.0, 72.0, 72.0]]), torch.tensor([0])
        with torch.no_grad():
            torch.testing.assert_close(net(scene_input(photo, box, index)), net(scene_input(dark, box, index)),
                                       atol=1e-3, rtol=1e-3)

    def test_trains(self):
        """The branch is differentiable end to end and its spread is positive and bounded."""
        net = SceneStrength()
        frames = scene_input(torch.rand(3, 3, 64, 80), torch.tensor([[10.0, 10, 40, 40]] * 3), torch.arange(3))
        e, b = net(frames)
        (e.sum() + b.sum()).backward()
        assert all(p.grad is not None for p in net.parameters())
        assert bool(((b > 0) & (b < 21)).all())

    def test_a_photo_with_little_besides_the_face_tells_nothing(self):
        """The face filling the photo, or a panorama's strip: the widest spread, so the face stays in charge."""
        torch.manual_seed(0)
        net = SceneStrength().eval()
        widest = math.exp(LOG_SPREAD_RANGE[1])
        cases = {"face fills it": (torch.rand(1, 3, 90, 120), [[5.0, 0, 115, 90]]),
                 "panorama 4:1": (torch.rand(1, 3, 100, 400), [[180.0, 30, 220, 70]]),
                 "4:3 portrait": (torch.rand(1, 3, 90, 120), [[45.0, 20, 75, 60]])}
        with torch.no_grad():
            spreads = {k: net(scene_input(p, torch.tensor(b), torch.tensor([0])))[1].item() for k, (p, b) in
                       cases.items()}
        assert spreads["face fills it"] == pytest.approx(widest) and spreads["panorama 4:1"] == pytest.approx(widest)
        assert spreads["4:3 portrait"] < widest * 0.99
        assert MIN_REST == pytest.approx(1 / 3)

    def test_bad_frames(self):
        with pytest.raises(ShapeError):
            SceneStrength()(torch.rand(1, 4, 16, 16))


class TestFuseStrength:
    @staticmethod
    def face(spread: float, sh: bool = False) -> LightingEstimate:
        valid = mirror_ball_valid(32)
        ball = torch.rand(2, 3, 32, 32) * valid
        return LightingEstimate(mirror_ball=ball, valid=valid, log_energy_spread=torch.full((2,), spread),
                                sh=torch.rand(2, 9, 3) if sh else None)

    def test_weights_by_inverse_variance(self):
        face = self.face(0.3, sh=True)
        e_face = torch.log(total_radiance(face.mirror_ball))
        target = e_face + torch.tensor([1.0, 0.0, -1.0])
        sure = fuse_strength(face, target, torch.full((2,), 1e-3))  # the scene sure: its energy
        torch.testing.assert_close(torch.log(total_radiance(sure.mirror_ball)), target, atol=1e-4, rtol=0)
        gain = sure.mirror_ball.sum((2, 3)) / face.mirror_ball.sum((2, 3))
        torch.testing.assert_close(sure.sh, face.sh * gain[:, None, :], rtol=1e-4, atol=1e-6)
        unsure = fuse_strength(face, target, torch.full((2,), 20.0))  # the scene knows nothing: the face's
        torch.testing.assert_close(unsure.mirror_ball, face.mirror_ball, rtol=1e-3, atol=1e-6)
        assert torch.allclose(unsure.log_energy_spread, torch.full((2,), 0.3), rtol=1e-3)
        torch.testing.assert_close(sure.log_mirror_ball, torch.log1p(sure.mirror_ball) * face.valid)

    def test_one_strength_per_photo(self):
        """Two faces of one photo: each keeps its shape, both get the photo's strength; the scene counts once."""
        face = self.face(0.5)
        e_face = torch.log(total_radiance(face.mirror_ball))
        scene = torch.zeros(2, 3)
        shared = fuse_strength(face, scene, torch.full((2,), 0.5), torch.zeros(2, dtype=torch.int64))
        e = torch.log(total_radiance(shared.mirror_ball))
        torch.testing.assert_close(e[0], e[1], rtol=0, atol=1e-5)
        torch.testing.assert_close(e[0], (e_face.sum(0) + scene[0]) / 3, rtol=0, atol=1e-5)  # 3 equal weights
        ratio = shared.mirror_ball[:, :, face.valid] / face.mirror_ball[:, :, face.valid]
        torch.testing.assert_close(ratio, ratio[..., :1].expand_as(ratio), rtol=1e-4, atol=0)  # shapes kept
        torch.testing.assert_close(shared.log_energy_spread, torch.full((2,), 0.5 / 3**0.5), rtol=1e-5, atol=0)
        torch.testing.assert_close(shared.scene_share, torch.full((2,), 1 / 3), rtol=1e-5, atol=0)
        alone = fuse_strength(face, scene, torch.full((2,), 0.5), torch.tensor([0, 1]))
        torch.testing.assert_close(alone.mirror_ball, fuse_strength(face, scene, torch.full((2,), 0.5)).mirror_ball)
        torch.testing.assert_close(alone.scene_share, torch.full((2,), 0.5), rtol=1e-5, atol=0)

    def test_needs_the_face_spread(self):
        face = self.face(0.3)
        with pytest.raises(ShapeError, match="spread"):
            fuse_strength(LightingEstimate(mirror_ball=face.mirror_ball, valid=face.valid), torch.zeros(2, 3),
                          torch.ones(2))
        with pytest.raises(ShapeError):
            fuse_strength(face, torch.zeros(3, 3), torch.ones(3))
        with pytest.raises(ShapeError, match="photo"):
            fuse_strength(face, torch.zeros(2, 3), torch.ones(2), torch.zeros(3, dtype=torch.int64))
