"""The pure steps of portrait synthesis (kornia_ilum_lab.synth.lightstage.portraits.compose): relighting, boxes,
crops, exposure, backgrounds and sphere targets."""

from __future__ import annotations

import math

import pytest
import torch
from kornia.geometry.transform import crop_and_resize

from kornia_ilum.color import gamma_encode
from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.filters import soft_clip
from kornia_ilum.geometry import latlong_directions, mirror_ball_valid
from kornia_ilum.render import render_spheres, sphere_pyramid
from kornia_ilum_lab.synth.background import LUMINANCE, camera_rays, latlong_grid, lookup_latlong, sample_latlong
from kornia_ilum_lab.synth.environments import lighting_rotation
from kornia_ilum_lab.synth.lightstage import LANDMARK_NAMES
from kornia_ilum_lab.synth.lightstage.portraits import (
    PHOTO_ASPECTS,
    aspect_windows,
    auto_exposure,
    background_pyramid,
    crop_images,
    detector_boxes,
    face_crop_boxes,
    frame_background,
    frame_backgrounds,
    inner_crop_boxes,
    load_fields,
    random_crop_boxes,
    relight_portraits,
    sphere_targets,
)
from kornia_ilum_lab.synth.lightstage.portraits.compose import _enlarge, _rotated_grid, _view_matrices
from kornia_ilum_lab.synth.lightstage.scene import Camera
from tests.lab.synth.lightstage.portraits.common import SIZE, S

@pytest.mark.slow
class TestRelight:
    def test_white_environment_equals_sum_of_olats(self, sphere_field) -> None:
        """Relighting with a white environment is the sum of the OLAT images."""
        white = mirror_ball_valid(S).float().expand(1, 3, S, S)
        image, alpha = relight_portraits(sphere_field, white)
        expected = sphere_field.to_dense().field.float().sum(-1).reshape(3, SIZE, SIZE)
        torch.testing.assert_close(image[0], expected, rtol=1e-2, atol=1e-3)
        assert torch.equal(alpha[0], sphere_field.alpha)

    def test_compact_equals_dense(self, cache) -> None:
        field = load_fields(cache, None)[0]
        lighting = torch.rand(3, 3, S, S) * mirror_ball_valid(S)
        compact, a1 = relight_portraits(field, lighting)
        dense, a2 = relight_portraits(field.to_dense(), lighting)
        torch.testing.assert_close(compact, dense)
        assert torch.equal(a1, a2)

    def test_linear(self, sphere_field) -> None:
        a, b = torch.rand(2, 1, 3, S, S) * mirror_ball_valid(S)
        ia, ib, iab = (relight_portraits(sphere_field, x)[0] for x in (a, b, 2 * a + b))
        torch.testing.assert_close(iab, 2 * ia + ib, rtol=2e-2, atol=1e-3)

    def test_errors(self, sphere_field) -> None:
        with pytest.raises(ShapeError):
            relight_portraits(sphere_field, torch.ones(1, 3, 4, 4))
        with pytest.raises(TypeCheckError, match="ReflectanceField"):
            relight_portraits(torch.ones(3), torch.ones(1, 3, S, S))
        with pytest.raises(ValueCheckError):
            relight_portraits(sphere_field, -torch.ones(1, 3, S, S))

class TestBoxes:
    def test_detector_box_follows_the_inner_landmarks(self) -> None:
        lm = torch.rand(3, len(LANDMARK_NAMES), 2) * 10 + 40
        boxes = detector_boxes(lm)
        side = boxes[:, 2] - boxes[:, 0]
        torch.testing.assert_close(side, boxes[:, 3] - boxes[:, 1])
        assert (side > 0).all()
        with pytest.raises(ShapeError):
            detector_boxes(torch.zeros(1, 5, 2))

    def test_face_crops_stay_inside_and_jitter(self) -> None:
        g = torch.Generator().manual_seed(0)
        faces = torch.tensor([[60.0, 50.0, 140.0, 130.0]]).expand(500, 4)
        boxes = face_crop_boxes(faces, 192, generator=g)
        side = boxes[:, 2] - boxes[:, 0]
        assert (boxes[:, :2] >= 0).all() and (boxes[:, 2:] <= 192).all()
        torch.testing.assert_close(side, boxes[:, 3] - boxes[:, 1])
        assert side.min() >= 100 * math.exp(-0.15) - 1e-6 and side.max() <= 100 * math.exp(0.15) + 1e-6
        assert side.std() > 3 and boxes[:, 0].std() > 2  # jittered in extent and position
        torch.testing.assert_close(face_crop_boxes(faces[:1], 192), torch.tensor([[50.0, 40.0, 150.0, 140.0]],
                                                                                 dtype=torch.float64))

    def test_inner_crops_are_a_second_jittered_crop_inside_the_first(self) -> None:
        boxes = inner_crop_boxes(2000, 256, generator=torch.Generator().manual_seed(0))
        side = boxes[:, 2] - boxes[:, 0]
        torch.testing.assert_close(side, boxes[:, 3] - boxes[:, 1])
        assert (boxes[:, :2] >= 0).all() and (boxes[:, 2:] <= 256).all()
        # the log side ratio of the pair spans [-2 extent, 0]: two draws of the detector jitter of +-0.15
        log_ratio = torch.log(side / 256)
        assert log_ratio.min() >= -0.3 - 1e-9 and log_ratio.max() <= 1e-9 and log_ratio.min() < -0.29
        centre = 0.5 * (boxes[:, 0] + boxes[:, 2]) - 128
        assert centre.abs().max() <= 0.10 * 256 + 1e-9 and centre.std() > 5
        again = inner_crop_boxes(2000, 256, generator=torch.Generator().manual_seed(0))
        assert torch.equal(boxes, again)
        fixed = inner_crop_boxes(3, 64, generator=torch.Generator(), position=0.0, extent=0.0)
        torch.testing.assert_close(fixed, torch.tensor([[0.0, 0.0, 64.0, 64.0]], dtype=torch.float64).expand(3, 4))
        with pytest.raises(ValueCheckError):
            inner_crop_boxes(1, 64, generator=torch.Generator(), position=-0.1)

    def test_random_crops(self) -> None:
        g = torch.Generator().manual_seed(1)
        boxes = random_crop_boxes(torch.tensor([[40.0, 40.0, 88.0, 88.0]]).expand(64, 4), 128, generator=g)
        assert (boxes[:, :2] >= 0).all() and (boxes[:, 2:] <= 128).all()

class TestImageOps:
    def test_crop_images_matches_kornia(self) -> None:
        image = torch.rand(2, 3, 40, 40)
        boxes = torch.tensor([[5.0, 7.0, 25.0, 27.0], [0.0, 0.0, 40.0, 40.0]])
        ours = crop_images(image, boxes, 16)
        half = (boxes[:, 2] - boxes[:, 0]) / 32
        lo, hi = boxes[:, :2] + half[:, None] - 0.5, boxes[:, 2:] - half[:, None] - 0.5
        corners = torch.stack([lo, torch.stack([hi[:, 0], lo[:, 1]], -1), hi,
                               torch.stack([lo[:, 0], hi[:, 1]], -1)], 1)
        torch.testing.assert_close(ours, crop_and_resize(image, corners, (16, 16), align_corners=True),
                                   atol=1e-5, rtol=0)
        mirrored = crop_images(image, boxes, 16, torch.tensor([True, False]))
        torch.testing.assert_close(mirrored[0], ours[0].flip(-1))
        torch.testing.assert_close(mirrored[1], ours[1])

    def test_auto_exposure(self) -> None:
        gain = auto_exposure(torch.full((2, 3, 8, 8), 0.5), torch.tensor([0.18, 0.36]))
        torch.testing.assert_close(gain, torch.tensor([0.36, 0.72], dtype=torch.float64))
        assert auto_exposure(torch.zeros(1, 3, 4, 4)).item() == 1.0

    def test_auto_exposure_meters_what_the_sensor_records(self) -> None:
        # The gain solves mean_w(min(g Y, white)) = key exactly: check it against the definition on random HDR images
        torch.manual_seed(0)
        images = torch.rand(4, 3, 16, 16) ** 4 * torch.tensor([0.01, 1.0, 100.0, 1e4]).view(4, 1, 1, 1)
        images[2, :, :8] = 0.0  # half black
        keys = torch.tensor([0.18, 0.1, 0.3, 0.18])
        gain = auto_exposure(images, keys)
        yy = (torch.arange(16, dtype=torch.float64) + 0.5) / 16 - 0.5
        weight = torch.exp(-(yy[:, None] ** 2 + yy[None] ** 2) / (2 * 0.25**2))
        weight = weight / weight.sum()
        lum = torch.einsum("bchw,c->bhw", images.double(), torch.tensor(LUMINANCE, dtype=torch.float64))
        metered = (weight * (lum * gain[:, None, None]).clamp(max=1.0)).sum((1, 2))
        torch.testing.assert_close(metered, keys.double(), rtol=1e-9, atol=0)
        # Nothing clips: the plain weighted mean; white=None never clips
        dim = torch.full((1, 3, 8, 8), 0.5)
        assert auto_exposure(dim).item() == pytest.approx(auto_exposure(dim, white=None).item(), rel=1e-12)
        # A sun of one pixel in the metered area: a plain mean makes the face a silhouette, the sensor does not
        sun = dim.clone()
        sun[..., 4, 4] = 1e5
        assert auto_exposure(sun, white=None).item() < 1e-3 * auto_exposure(dim).item()
        assert auto_exposure(sun).item() > 0.8 * auto_exposure(dim).item()
        # Unreachable key (almost all black): the plain mean's gain; bad white
        speck = torch.zeros(1, 3, 8, 8)
        speck[..., 0, 0] = 1.0
        assert auto_exposure(speck).item() == pytest.approx(auto_exposure(speck, white=None).item())
        with pytest.raises(ValueCheckError, match="white"):
            auto_exposure(dim, white=0.0)

    def test_frame_background(self) -> None:
        latlong = torch.zeros(1, 3, 32, 64)
        latlong[:, :, :16] = 1.0  # sky above the horizon
        view = frame_background(latlong, Camera(60.0, 1.0, 0.0, 0.0, size=16))
        assert view[0, :, :6].min() > 0.99 and view[0, :, -6:].max() < 0.01

    def test_frame_background_is_the_cameras_rays_looked_up(self) -> None:
        latlong = torch.rand(2, 3, 16, 32)
        camera = Camera(40.0, 1.0, 0.0, 0.0, size=12)
        rays = camera_rays((12, 12), 40.0, torch.eye(3, dtype=torch.float64))
        mirrored = rays * torch.tensor([-1.0, 1.0, 1.0], dtype=torch.float64)
        view = frame_background(latlong, camera, torch.tensor([False, True]))
        torch.testing.assert_close(view[0], sample_latlong(latlong[0], rays))
        torch.testing.assert_close(view[1], sample_latlong(latlong[1], mirrored))
        with pytest.raises(TypeCheckError, match="mirror"):
            frame_background(latlong, camera, torch.tensor([True]))

    def test_sphere_targets_are_the_rendered_spheres_encoded(self) -> None:
        lighting = torch.rand(3, 3, 16, 16) * 4.0 * mirror_ball_valid(16)
        targets = sphere_targets(lighting, (4, 16))
        expected = sphere_pyramid(lighting, sizes=(4, 16), gamma="safe")
        assert len(targets) == 6
        assert targets.keys() == expected.keys()
        for key, value in expected.items():  # the training loss's targets: gamma="safe"
            torch.testing.assert_close(targets[key], value)
        for size in (4, 16):  # and the spheres of render_spheres, encoded
            for brdf, render in render_spheres(lighting, size=size).items():
                torch.testing.assert_close(targets[f"{brdf}_{size}"], gamma_encode(soft_clip(render), 2.2),
                                           atol=1e-3, rtol=0)
        with pytest.raises(ShapeError):
            sphere_targets(torch.ones(1, 3, 12, 12))

class TestFullResolutionBackgrounds:
    def test_pyramid_lookup_is_the_rolled_frame_background(self) -> None:
        """Turning by k columns and mirroring in the padded full map is what the rolled low-res path saw."""
        latlong = torch.rand(3, 3, 16, 32, generator=torch.Generator().manual_seed(0))
        camera = Camera(50.0, 1.0, 0.0, 0.0, size=12)
        shifts, mirror = [0, 5, 31], torch.tensor([False, True, True])
        rolled = torch.stack([x.roll(k, -1) for x, k in zip(latlong, shifts, strict=True)])
        expected = frame_background(rolled, camera, mirror)
        view = frame_backgrounds([background_pyramid(x) for x in latlong], camera, mirror=mirror,
                                 turn=torch.tensor(shifts, dtype=torch.float64) / 32)
        torch.testing.assert_close(view, expected, atol=1e-5, rtol=1e-5)

    def test_folded_rotation_is_the_rotated_map_looked_up(self) -> None:
        """The augment rotation folded into the frame's lookup (``rotation``) sees what the old path saw: the whole
        map resampled by ``M`` (as :func:`environment_background` does), then turned, mirrored and looked up."""
        g = torch.Generator().manual_seed(0)  # a smooth map (bilinear twice vs once differ little) with detail
        coarse = torch.rand(2, 3, 8, 16, generator=g) + 0.2
        latlong = torch.nn.functional.interpolate(coarse, size=(128, 256), mode="bicubic", align_corners=False)
        latlong = latlong.clamp(min=0.0)
        flip = torch.diag(torch.tensor([-1.0, 1.0, 1.0], dtype=torch.float64))
        maps = torch.stack([flip @ lighting_rotation(37.0, 21.0), lighting_rotation(250.0, -28.0)])  # rotated+flipped
        dirs = latlong_directions(128, dtype=torch.float64)
        rotated = torch.stack([lookup_latlong(x[None], latlong_grid(dirs @ m, 128).float()[None])[0]
                               for x, m in zip(latlong, maps, strict=True)])  # the old full-map resampling
        camera = Camera(45.0, 1.0, 0.0, 0.0, size=32)
        index = [0, 0, 1, 1, 0, 1]
        mirror = torch.tensor([False, True, False, True, True, False])
        turn = torch.tensor([0.0, 0.3, 0.71, 0.05, 0.5, 0.9], dtype=torch.float64)
        sigma = torch.tensor([0.0, 0.0, 0.0, 0.0, 3.0, 6.0])
        old = frame_backgrounds([background_pyramid(rotated[i]) for i in index], camera, mirror=mirror,
                                turn=turn, sigma=sigma)
        new = frame_backgrounds([background_pyramid(latlong[i]) for i in index], camera, mirror=mirror,
                                turn=turn, sigma=sigma,
                                rotation=maps[index])
        err = (new - old).abs().mean((1, 2, 3)) / old.abs().mean((1, 2, 3))
        assert (err[:4] < 0.005).all() and (err[4:] < 0.03).all(), err  # measured 0.0006 sharp, 0.009 and 0.013
        # blurred (the coarse levels: the map averaged before or after its rotation)
        unrotated = frame_backgrounds([background_pyramid(latlong[i]) for i in index], camera, mirror=mirror,
                                      turn=turn, sigma=sigma)
        assert ((unrotated - old).abs().mean((1, 2, 3)) / old.abs().mean((1, 2, 3)) > 0.05).all()  # it matters
        identity = torch.eye(3, dtype=torch.float64).expand(6, 3, 3)
        derotated = frame_backgrounds([background_pyramid(latlong[i]) for i in index], camera, mirror=mirror,
                                      turn=turn, sigma=sigma, rotation=identity)
        torch.testing.assert_close(derotated, unrotated, atol=1e-6, rtol=0)
        with pytest.raises(ShapeError):
            frame_backgrounds([background_pyramid(latlong[0])], camera, rotation=maps)

    def test_depth_of_field_blurs_more_with_sigma(self) -> None:
        latlong = torch.rand(3, 64, 128, generator=torch.Generator().manual_seed(1))
        pyramid = background_pyramid(latlong)
        assert len(pyramid) == 4 and pyramid[-1].shape[-2] == 8 + 2
        camera = Camera(60.0, 1.0, 0.0, 0.0, size=64)
        sigma = torch.tensor([0.0, 1.0, 2.5, 5.0, 8.0])
        views = frame_backgrounds([pyramid] * 5, camera, sigma=sigma)
        detail = (views[..., 1:] - views[..., :-1]).abs().mean((1, 2, 3))
        assert (detail[1:] < detail[:-1]).all()  # measured 0.067, 0.039, 0.021, 0.011, 0.007
        torch.testing.assert_close(views.mean((1, 2, 3)), views[0].mean().expand(5), rtol=0.05, atol=0)

class TestEnlarge:
    def test_enlarge_and_rotated_grid_match_torch(self) -> None:
        frames = torch.rand(3, 3, 12, 12, generator=torch.Generator().manual_seed(0))
        out = torch.zeros(5, 3, 40, 40)
        _enlarge(frames, out, [4, 0, 2])  # OpenCV's resize
        expected = torch.nn.functional.interpolate(frames, size=(40, 40), mode="bilinear", align_corners=False)
        torch.testing.assert_close(out[[4, 0, 2]], expected, rtol=0, atol=1e-5)
        assert (out[[1, 3]] == 0).all()
        q = torch.linalg.qr(torch.randn(3, 3, generator=torch.Generator().manual_seed(1), dtype=torch.float64))[0]
        reference = latlong_grid(camera_rays((16, 16), 40.0, torch.eye(3, dtype=torch.float64)) @ q.T, 32)[None]
        torch.testing.assert_close(_rotated_grid(40.0, 16, 32, q), reference.float(), rtol=0, atol=1e-5)
        views = _view_matrices(2, [True, False], [0.3, 0.0], None)  # mirror then turn: u -> (u(F r) - turn) mod 1
        rays = camera_rays((16, 16), 40.0, torch.eye(3, dtype=torch.float64))
        grid = latlong_grid(rays * torch.tensor([-1.0, 1.0, 1.0], dtype=torch.float64), 32)
        u = (grid[..., 0] + 1) * 65 / 2 - 0.5  # back to the map's column in [0, 64]
        shifted = torch.stack([((u - 0.3 * 64).remainder(64) + 0.5) * 2 / 65 - 1, grid[..., 1]], -1)
        got = _rotated_grid(40.0, 16, 32, views[0])[0]
        close = ((got - shifted).abs() < 1e-5) | ((got[..., :1] - shifted[..., :1]).abs() > 1.9)  # the seam
        assert close.all()
        torch.testing.assert_close(_rotated_grid(40.0, 16, 32, views[1])[0], latlong_grid(rays, 32).float(),
                                   rtol=0, atol=1e-5)


class TestAspectWindows:
    def test_photo_shapes_around_the_face(self):
        boxes = torch.tensor([[50.0, 20, 70, 45]]).expand(400, 4)
        w = aspect_windows(boxes, 128, generator=torch.Generator().manual_seed(0))
        width, height = w[:, 2] - w[:, 0], w[:, 3] - w[:, 1]
        assert bool((torch.maximum(width, height) == 128).all())
        ratio = torch.maximum(width, height) / torch.minimum(width, height)
        seen = {round(float(r), 2) for r in ratio}
        assert seen == {round(128 / round(128 / a), 2) for a in PHOTO_ASPECTS}
        wide, tall = int((width > height).sum()), int((width < height).sum())  # a quarter square
        assert 110 < wide < 190 and 110 < tall < 190  # landscape and portrait alike
        assert bool(((w[:, :2] <= boxes[:, :2]) & (w[:, 2:] >= boxes[:, 2:])).all())  # the face inside
        assert bool((w >= 0).all() and (w <= 128).all() and (w == w.round()).all())

    def test_a_face_larger_than_the_window_is_centred(self):
        w = aspect_windows(torch.tensor([[0.0, 10, 128, 110]] * 50), 128, generator=torch.Generator().manual_seed(1))
        wide = w[w[:, 2] - w[:, 0] == 128]
        short = wide[:, 3] - wide[:, 1]
        small = short < 100  # the 16:9 and 3:2 windows: narrower than the box
        torch.testing.assert_close((wide[small, 1] + wide[small, 3]) / 2, torch.full((int(small.sum()),), 60.0),
                                   atol=0.5, rtol=0)
        with pytest.raises(ValueCheckError):
            aspect_windows(torch.zeros(3), 128, generator=torch.Generator())
