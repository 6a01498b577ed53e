"""Portrait synthesis and the on-the-fly dataset of the virtual light stage."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import torch
from torch.utils.data import DataLoader

from kornia_ilum.color import gamma_encode, srgb_to_linear
from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.filters import soft_clip
from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum.render import render_spheres, sphere_pyramid
from kornia_ilum.synth.background import LUMINANCE, camera_rays, sample_latlong
from kornia_ilum.synth.camera_effects import CameraEffects
from kornia_ilum.synth.environments import Environment, EnvironmentSampler
from kornia_ilum.synth.lightstage import (
    DEFAULT_VIEWS,
    LANDMARK_NAMES,
    build_cache,
    render_olat,
    select_mitsuba_variant,
    subject_split,
)
from kornia_ilum.synth.lightstage.portraits import (
    PortraitConfig,
    PortraitDataset,
    auto_exposure,
    background_pyramid,
    crop_images,
    detector_boxes,
    environment_background,
    face_crop_boxes,
    frame_background,
    frame_backgrounds,
    load_fields,
    random_crop_boxes,
    relight_portraits,
    sphere_targets,
)
from kornia_ilum.synth.lightstage.scene import PIVOT_RAISE, Camera
from tests.synth.test_olat import ALBEDO, sphere_subject

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
        from kornia_ilum.geometry import latlong_to_mirror_ball

        return Environment(latlong, latlong_to_mirror_ball(latlong[None], 32)[0], self.label, "test:uniform")


def uniform_sampler(**kw: float) -> EnvironmentSampler:
    return EnvironmentSampler([Uniform(**kw)], augment=None, seed=0)


@pytest.fixture(scope="module")
def variant() -> str:
    return select_mitsuba_variant()


@pytest.fixture(scope="module")
def sphere_field(variant: str):
    """A white Lambertian sphere (albedo 0.7) filling most of a 48 x 48 frontal view, with 20 landmarks (denoised:
    render_olat no longer denoises by default, and the 16-spp noise would exceed test_uniform_environment's bound)."""
    angles = 2 * math.pi * np.arange(len(LANDMARK_NAMES)) / len(LANDMARK_NAMES)
    rho = 0.8
    ring = np.stack([rho * np.cos(angles), rho * np.sin(angles), np.zeros_like(angles)], -1)
    inner_height = np.ptp(ring[:, 1])
    landmarks = (ring - [0.0, PIVOT_RAISE * inner_height, 0.0]).astype(np.float32)
    camera = Camera(fov_deg=40.0, distance=4.0, yaw_deg=0.0, pitch_deg=0.0, size=SIZE)
    subject = sphere_subject(landmarks=landmarks)
    return render_olat(subject, camera, lighting_size=S, spp=16, variant=variant, threads=1, denoise=True)


@pytest.fixture(scope="module")
def cache(tmp_path_factory, variant: str):
    """Two light-stage subjects, seed 0 (train) and seed 1 (eval), one small view each."""
    out = tmp_path_factory.mktemp("lightstage")
    view = dataclasses.replace(DEFAULT_VIEWS[0], size=SIZE)
    build_cache(out, [0, 1], [view], size=SIZE, spp=4, lighting_size=S, variant=variant, threads=1, progress=False)
    return out


OFF = CameraEffects.off()


def small(fields, seed: int = 0, **kw) -> PortraitDataset:
    settings = {"size": OUT, "sphere_sizes": (4, 8), "fields_per_chunk": 2, "lightings_per_field": 4,
                "env_pool": 4, "env_refresh": 1, "shuffle": 2, "environments": EnvironmentSampler(seed=0)}
    settings.update(kw)
    return PortraitDataset(fields, PortraitConfig(**settings), seed=seed)


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


class TestAnalytic:
    def test_uniform_environment(self, sphere_field) -> None:
        """A white Lambertian sphere under uniform radiance L over the matching background reads, exposed by g,
        ``g L (a alpha + 1 - alpha)`` (alpha: the cropped matte), and its ground truth is ``g L``."""
        data = small([sphere_field], split=None, environments=uniform_sampler(), camera=OFF,
                     exposure_key=(0.18, 0.18), flip_probability=0.0, shuffle=1)
        sample = data.chunk(0, 0)[0]
        gain = float(sample["exposure"])
        valid = mirror_ball_valid(S)
        torch.testing.assert_close(sample["mirror_ball"][:, valid], torch.full((3, int(valid.sum())), gain),
                                   rtol=1e-3, atol=0)  # resampling a constant map is exact to 4e-4
        alpha = crop_images(sphere_field.alpha[None], sample["crop_box"][None], OUT)[0]
        expected = gain * (ALBEDO * alpha + 1.0 - alpha)
        measured = srgb_to_linear(sample["image"].float()[None] / 255.0)[0]
        err = (measured - expected) / expected
        assert err.mean().abs() < 0.01  # measured 0.1 % or less
        assert err.abs().max() < 0.12  # Monte-Carlo noise of the 16-spp OLATs (measured 7 %) and 8-bit rounding
        assert err[:, alpha[0] == 0].abs().max() < 0.01  # the background alone: 8-bit rounding (measured 0.7 %)
        assert (alpha == 0).any() and (alpha == 1).any()  # the crop shows both the sphere and the background
        # the diffuse reference sphere (albedo 0.8) of the ground truth: softclip(0.8 g L)^(1/2.2) at its centre
        centre = sample["spheres"]["diffuse_8"][:, 3:5, 3:5]
        from kornia_ilum.filters import soft_clip

        expected_sphere = soft_clip(torch.tensor(0.8 * gain)) ** (1 / 2.2)
        torch.testing.assert_close(centre, expected_sphere.expand_as(centre), rtol=2e-3, atol=0)

    def test_exposure_meters_the_key(self, sphere_field) -> None:
        data = small([sphere_field], split=None, environments=uniform_sampler(radiance=50.0), camera=OFF,
                     exposure_key=(0.25, 0.25))
        sample = data.chunk(0, 0)[0]
        assert 0.25 / 50.0 < float(sample["exposure"]) < 0.25 / (50.0 * ALBEDO)

    def test_flip_keeps_the_light_where_the_ground_truth_says(self, sphere_field) -> None:
        """A mirrored sample is the mirrored subject under the true lighting: the (symmetric) sphere is lit on
        the side where the ground truth has its light, whether the sample is mirrored or not."""
        checked = 0
        for p in (0.0, 1.0):
            data = small([sphere_field], split=None, environments=uniform_sampler(radiance=0.05, left_light=40.0),
                         background="black", camera=OFF, flip_probability=p, lightings_per_field=8)
            for sample in data.chunk(0, 0):
                assert sample["flip"] == bool(p)
                image = sample["image"].float()
                ball = sample["mirror_ball"].sum(0)  # the light's side in the truth: -X is the ball's left half
                ball_left, ball_right = ball[:, : S // 2].sum(), ball[:, S // 2 :].sum()
                if max(ball_left, ball_right) < 10 * min(ball_left, ball_right):
                    continue  # the light was turned to the front or the back
                left, right = image[:, :, : OUT // 2].mean(), image[:, :, OUT // 2 :].mean()
                assert (left > right) == (ball_left > ball_right)
                checked += 1
        assert checked >= 8


class TestDataset:
    def test_sample_contents(self, cache) -> None:
        data = small(cache)
        sample = next(iter(data))
        assert sample["image"].dtype == torch.uint8 and sample["image"].shape == (3, OUT, OUT)
        assert sample["mirror_ball"].shape == (3, S, S) and sample["mirror_ball"].dtype == torch.float32
        assert sorted(sample["spheres"]) == sorted(f"{b}_{s}" for b in ("diffuse", "matte_silver", "mirror")
                                                   for s in (4, 8))
        assert sample["subject_seed"] == 0 and subject_split(0) == "train"
        assert sample["skin_tone"] in range(1, 11) and sample["view_index"] == 0
        assert sample["label"] in ("indoor", "outdoor") and isinstance(sample["source"], str)
        assert float(sample["exposure"]) > 0 and sample["crop_box"].shape == (4,)
        valid = mirror_ball_valid(S)
        assert (sample["mirror_ball"][:, ~valid] == 0).all() and (sample["mirror_ball"] >= 0).all()
        # the ground-truth spheres are exactly what the loss compares: softclip(render)^(1/2.2)
        torch.testing.assert_close(sample["spheres"]["mirror_8"], sphere_targets(sample["mirror_ball"][None],
                                                                                 (8,))["mirror_8"][0])

    def test_train_and_eval_subjects_are_disjoint(self, cache) -> None:
        train = {f.subject_seed for f in load_fields(cache, "train")}
        evaluation = {f.subject_seed for f in load_fields(cache, "eval")}
        assert train == {0} and evaluation == {1} and not train & evaluation
        assert {s["subject_seed"] for s in small(cache, split="eval", length=8)} == {1}
        seeds = range(2000)
        assert not {s for s in seeds if subject_split(s) == "train"} & {s for s in seeds if subject_split(s) == "eval"}

    def test_each_seed_reproduces_exactly(self, cache) -> None:
        a, b, c = small(cache, seed=3), small(cache, seed=3), small(cache, seed=4)
        first = a.chunk(0, 2)
        a.chunk(1, 5)  # other chunks and workers in between change nothing
        for x, y in zip(first, b.chunk(0, 2), strict=True):
            assert torch.equal(x["image"], y["image"]) and torch.equal(x["mirror_ball"], y["mirror_ball"])
        assert torch.equal(first[0]["image"], a.chunk(0, 2)[0]["image"])
        assert not torch.equal(first[0]["image"], c.chunk(0, 2)[0]["image"])
        assert not torch.equal(first[0]["image"], a.chunk(1, 2)[0]["image"])  # workers draw different samples

    def test_data_loader_workers_reproduce(self, cache) -> None:
        def run() -> list[torch.Tensor]:
            loader = DataLoader(small(cache, length=6), batch_size=None, num_workers=2)
            return [s["image"] for s in loader]

        first, second = run(), run()
        assert len(first) == 12
        assert all(torch.equal(x, y) for x, y in zip(first, second, strict=True))
        assert not torch.equal(first[0], first[1])  # worker 0, then worker 1

    def test_black_background(self, cache) -> None:
        field = load_fields(cache, "train")[0]
        for sample in small(cache, background="black", camera=OFF, length=4):
            alpha = crop_images(field.alpha[None], sample["crop_box"][None], OUT,
                                torch.tensor([sample["flip"]]))[0]
            if sample["flip"]:  # crop_box is in the mirrored image
                alpha = crop_images(field.alpha.flip(-1)[None], sample["crop_box"][None], OUT)[0]
            assert (sample["image"][:, alpha[0] == 0] == 0).all()

    def test_background_only(self, cache) -> None:
        with_subject, without = (small(cache, subject=flag, camera=OFF).chunk(0, 0) for flag in (True, False))
        for a, b in zip(with_subject, without, strict=True):
            torch.testing.assert_close(a["mirror_ball"] / a["exposure"], b["mirror_ball"] / b["exposure"])
            assert not torch.equal(a["image"], b["image"])
        image = without[0]["image"].float()
        assert image.std() < 40  # a smooth background, no face

    def test_random_crops_miss_the_face(self, cache) -> None:
        for sample in small(cache, crop="random", length=8):
            box, face = sample["crop_box"].double(), sample["face_box"].double()
            w = (torch.minimum(box[2], face[2]) - torch.maximum(box[0], face[0])).clamp(min=0)
            h = (torch.minimum(box[3], face[3]) - torch.maximum(box[1], face[1])).clamp(min=0)
            assert w * h <= 0.2 * (face[2] - face[0]) * (face[3] - face[1]) + 1e-6

    def test_pairs(self, cache) -> None:
        for sample in small(cache, pairs=True, length=4):
            pair = sample["pair"]
            assert pair["image"].shape == sample["image"].shape and sorted(pair["spheres"]) == sorted(sample["spheres"])
            assert not torch.equal(pair["mirror_ball"], sample["mirror_ball"])

    def test_length_and_repr(self, cache) -> None:
        data = small(cache, length=5)
        assert len(list(data)) == 5
        assert "2 fields of 2 subjects" in repr(small(cache, split=None))

    @pytest.mark.parametrize(
        ("kwargs", "error", "match"),
        [
            ({"background": "white"}, ValueCheckError, "background must be one of"),
            ({"crop": "body"}, ValueCheckError, "crop must be one of"),
            ({"split": "test"}, ValueCheckError, "split must be"),
            ({"env_refresh": 9}, ValueCheckError, "must not exceed env_pool"),
            ({"exposure_key": (0.0, 1.0)}, ValueCheckError, "exposure_key"),
            ({"sphere_sizes": (16,)}, ValueCheckError, "exceed the lighting size"),
            ({"seed": 1.5}, TypeCheckError, "seed must be an int"),
            ({"environments": "sky"}, TypeCheckError, "EnvironmentSampler"),
            ({"lightings_per_field": 0}, ValueCheckError, "lightings_per_field"),
        ],
    )
    def test_errors(self, cache, kwargs, error, match) -> None:
        with pytest.raises(error, match=match):
            small(cache, **kwargs)

    def test_no_fields(self, tmp_path, sphere_field) -> None:
        with pytest.raises(ValueCheckError, match="no reflectance field"):
            PortraitDataset([sphere_field], split="train")  # the sphere is an eval subject
        with pytest.raises(TypeCheckError, match="sequence of ReflectanceField"):
            load_fields([1, 2])


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
        boxes = face_crop_boxes(faces, 192, g)
        side = boxes[:, 2] - boxes[:, 0]
        assert (boxes[:, :2] >= 0).all() and (boxes[:, 2:] <= 192).all()
        torch.testing.assert_close(side, boxes[:, 3] - boxes[:, 1])
        assert side.min() >= 100 * math.exp(-0.15) - 1e-6 and side.max() <= 100 * math.exp(0.15) + 1e-6
        assert side.std() > 3 and boxes[:, 0].std() > 2  # jittered in extent and position
        torch.testing.assert_close(face_crop_boxes(faces[:1], 192), torch.tensor([[50.0, 40.0, 150.0, 140.0]],
                                                                                 dtype=torch.float64))

    def test_random_crops(self) -> None:
        g = torch.Generator().manual_seed(1)
        boxes = random_crop_boxes(torch.tensor([[40.0, 40.0, 88.0, 88.0]]).expand(64, 4), 128, g)
        assert (boxes[:, :2] >= 0).all() and (boxes[:, 2:] <= 128).all()


class TestImageOps:
    def test_crop_images_matches_kornia(self) -> None:
        from kornia.geometry.transform import crop_and_resize

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
        expected = sphere_pyramid(lighting, (4, 16), gamma="safe")
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
        view = frame_backgrounds([background_pyramid(x) for x in latlong], camera, mirror,
                                 torch.tensor(shifts, dtype=torch.float64) / 32)
        torch.testing.assert_close(view, expected, atol=1e-5, rtol=1e-5)

    def test_folded_rotation_is_the_rotated_map_looked_up(self) -> None:
        """The augment rotation folded into the frame's lookup (``rotation``) sees what the old path saw: the whole
        map resampled by ``M`` (as :func:`environment_background` does), then turned, mirrored and looked up."""
        from kornia_ilum.geometry import latlong_directions
        from kornia_ilum.synth.background import latlong_grid, lookup_latlong
        from kornia_ilum.synth.environments import lighting_rotation

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
        old = frame_backgrounds([background_pyramid(rotated[i]) for i in index], camera, mirror, turn, sigma)
        new = frame_backgrounds([background_pyramid(latlong[i]) for i in index], camera, mirror, turn, sigma,
                                maps[index])
        err = (new - old).abs().mean((1, 2, 3)) / old.abs().mean((1, 2, 3))
        assert (err[:4] < 0.005).all() and (err[4:] < 0.03).all(), err  # measured 0.0006 sharp, 0.009 and 0.013
        # blurred (the coarse levels: the map averaged before or after its rotation)
        unrotated = frame_backgrounds([background_pyramid(latlong[i]) for i in index], camera, mirror, turn, sigma)
        assert ((unrotated - old).abs().mean((1, 2, 3)) / old.abs().mean((1, 2, 3)) > 0.05).all()  # it matters
        identity = torch.eye(3, dtype=torch.float64).expand(6, 3, 3)
        torch.testing.assert_close(frame_backgrounds([background_pyramid(latlong[i]) for i in index], camera, mirror,
                                                     turn, sigma, identity), unrotated, atol=1e-6, rtol=0)
        with pytest.raises(ShapeError):
            frame_backgrounds([background_pyramid(latlong[0])], camera, rotation=maps)

    def test_dataset_background_is_the_augmented_map_framed(self, shared_data) -> None:
        """The dataset's pyramid (source map times the gains) and direction map frame what the augmented full map
        of :func:`environment_background` frames: a real map, augmented (rotated, flipped, white-balanced)."""
        from kornia_ilum.synth.environments import HDRFolderSource

        sampler = EnvironmentSampler([HDRFolderSource(shared_data / "hdri", height=32)], seed=0)
        env = next(e for e in map(sampler.sample, range(32)) if e.params["augment"]["flip"])
        assert abs(env.params["augment"]["pitch_deg"]) > 5.0 and env.params["augment"]["gains"] != [1.0] * 3
        data = PortraitDataset.__new__(PortraitDataset)  # only what _background needs
        data.config = PortraitConfig(background_height=256)
        data.environments, data._backgrounds = sampler, {}
        pyramid, m = data._background(0, env)
        torch.testing.assert_close(m, torch.tensor(env.params["augment"]["direction_map"], dtype=torch.float64))
        camera = Camera(30.0, 1.0, 0.0, 0.0, size=48)
        mirror, turn = torch.tensor([False, True]), torch.tensor([0.2, 0.6], dtype=torch.float64)
        old = frame_backgrounds([background_pyramid(environment_background(env, sampler, height=256))] * 2, camera,
                                mirror, turn)

        def errors(view: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
            scale = old.abs().mean((1, 2, 3))
            pooled = torch.nn.functional.avg_pool2d(view - old, 4).abs().mean((1, 2, 3)) / scale
            return (view - old).abs().mean((1, 2, 3)) / scale, pooled, (view.mean((2, 3)) / old.mean((2, 3)) - 1).abs()

        # a real map's sharp detail: bilinear twice (old) against once (new); measured 0.024 and 0.039, pooled over
        # 4 x 4 pixels 0.009 and 0.015, mean colour 0.014
        raw, pooled, colour = errors(frame_backgrounds([pyramid] * 2, camera, mirror, turn, rotation=m.expand(2, 3, 3)))
        assert (raw < 0.1).all() and (pooled < 0.04).all() and (colour < 0.04).all(), (raw, pooled, colour)
        _, pooled, _ = errors(frame_backgrounds([pyramid] * 2, camera, mirror, turn))  # without the rotation
        assert (pooled > 0.2).all(), pooled

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

    def test_environment_background_is_the_environment_at_higher_resolution(self) -> None:
        from kornia_ilum.synth.environments import SkySource, resize_latlong

        sampler = EnvironmentSampler([SkySource(height=32)], seed=0)
        env = sampler.sample(3)
        full = environment_background(env, sampler, procedural_height=64)
        assert full.shape == (3, 64, 128)
        small_again = resize_latlong(full, 32)
        err = (small_again - env.latlong).abs().mean() / env.latlong.abs().mean()
        assert err < 0.15  # the same sky, turned and white-balanced alike (measured 0.03)
        assert environment_background(env, sampler, procedural_height=32) is not None
        torch.testing.assert_close(environment_background(env, sampler, procedural_height=16), env.latlong)

    def test_real_map_background_at_full_resolution(self, shared_data) -> None:
        from kornia_ilum.synth.environments import HDRFolderSource, resize_latlong

        sampler = EnvironmentSampler([HDRFolderSource(shared_data / "hdri", height=32)], seed=0)
        env = sampler.sample(1)
        full = environment_background(env, sampler, height=256)
        assert full.shape == (3, 256, 512)
        err = (resize_latlong(full, 32) - env.latlong).abs().mean() / env.latlong.abs().mean()
        assert err < 0.15


class TestConfig:
    def test_frozen_replace_and_overrides(self, cache) -> None:
        config = PortraitConfig(size=OUT, sphere_sizes=(4, 8))
        with pytest.raises(dataclasses.FrozenInstanceError):
            config.size = 32  # type: ignore[misc]
        assert dataclasses.replace(config, crop="random").crop == "random" and config.crop == "face"
        data = PortraitDataset(cache, config, seed=1, split=None, env_pool=4)
        assert data.config.env_pool == 4 and data.config.size == OUT and data.seed == 1
        with pytest.raises(TypeCheckError, match="PortraitConfig"):
            PortraitDataset(cache, {"size": 32})
        with pytest.raises(ValueCheckError, match="background_blur"):
            PortraitConfig(background_blur=(3.0, 1.0))
        with pytest.raises(TypeCheckError, match="CameraEffects"):
            PortraitConfig(camera="phone")

    def test_samples_record_the_effects(self, cache) -> None:
        with_fx = small(cache).chunk(0, 0)
        without = small(cache, camera=OFF, background_sharp_probability=1.0).chunk(0, 0)
        assert all(s["background_blur"] == 0 for s in without)
        assert any(s["background_blur"] > 0 for s in with_fx)
        assert sorted(with_fx[0]["camera"]) == ["blur", "jpeg", "noise", "tone", "vignette"]
        assert any(s["camera"]["jpeg"] > 0 for s in with_fx)
        # the lighting and crops are drawn before the effects: the same with and without them (the exposure
        # meters the blurred or sharp background, so it differs)
        for a, b in zip(with_fx, without, strict=True):
            torch.testing.assert_close(a["mirror_ball"] / a["exposure"], b["mirror_ball"] / b["exposure"])
            assert torch.equal(a["crop_box"], b["crop_box"])

    def test_noise_windows_are_signed_views_of_the_bank(self, cache) -> None:
        data = small(cache)
        g1, g2 = torch.Generator().manual_seed(3), torch.Generator().manual_seed(3)
        views = data._noise(5, OUT, g1, True)
        bank = data._noise_bank[0]
        offsets = torch.randint(65, (5, 2), generator=g2).tolist()  # the draws of _noise, in its order
        signs = torch.where(torch.rand(5, generator=g2) < 0.5, -1.0, 1.0)
        for view, (i, j), sign in zip(views, offsets, signs, strict=True):
            assert view.shape == (3, OUT, OUT)
            assert view.untyped_storage().data_ptr() == bank.untyped_storage().data_ptr()  # a view, no copy
            assert torch.equal(view, sign * bank[:, i : i + OUT, j : j + OUT])
        assert data._noise(5, OUT, torch.Generator().manual_seed(3), False) is None
        # the draws are the same whether the noise is needed or not
        assert torch.equal(g1.get_state(), (data._noise(5, OUT, g2.manual_seed(3), False), g2)[1].get_state())

    def test_enlarge_and_rotated_grid_match_torch(self) -> None:
        from kornia_ilum.synth.lightstage.portraits.compose import _enlarge, _rotated_grid, _view_matrices

        frames = torch.rand(3, 3, 12, 12, generator=torch.Generator().manual_seed(0))
        out = torch.zeros(5, 3, 40, 40)
        _enlarge(frames, out, [4, 0, 2])  # OpenCV's resize
        expected = torch.nn.functional.interpolate(frames, size=(40, 40), mode="bilinear", align_corners=False)
        torch.testing.assert_close(out[[4, 0, 2]], expected, rtol=0, atol=1e-5)
        assert (out[[1, 3]] == 0).all()
        from kornia_ilum.synth.background import latlong_grid

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
