"""The on-the-fly portrait dataset (kornia_ilum_lab.synth.lightstage.portraits.dataset): samples, splits,
reproducibility, variants, configuration and full-resolution backgrounds."""

from __future__ import annotations

import dataclasses
import math

import pytest
import torch
from torch.utils.data import DataLoader

from kornia_ilum.color import LUMINANCE, srgb_to_linear
from kornia_ilum.core.errors import TypeCheckError, ValueCheckError
from kornia_ilum.filters import soft_clip
from kornia_ilum.geometry import mirror_ball_to_latlong, mirror_ball_valid
from kornia_ilum_lab.synth.environments import EnvironmentSampler, HDRFolderSource, SkySource, resize_latlong
from kornia_ilum_lab.synth.lightstage import LANDMARK_NAMES, subject_split
from kornia_ilum_lab.synth.lightstage.field import ReflectanceField
from kornia_ilum_lab.synth.lightstage.portraits import (
    PortraitConfig,
    PortraitDataset,
    background_pyramid,
    crop_images,
    environment_background,
    frame_backgrounds,
    load_fields,
    sphere_targets,
)
from kornia_ilum_lab.synth.lightstage.scene import Camera
from kornia_ilum_lab.synth.surroundings import plane_radiance
from kornia_ilum_lab.train.data import collate
from tests.lab.synth.lightstage.portraits.common import OFF, OUT, S, small, uniform_sampler
from tests.lab.synth.lightstage.spheres import ALBEDO

@pytest.mark.slow
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
                         background="black", camera=OFF, flip_probability=p, lightings_per_field=8, matte=True)
            for sample in data.chunk(0, 0):
                assert sample["flip"] == bool(p)
                image = sample["image"].float().sum(0)
                ball = sample["mirror_ball"].sum(0)  # the light's side in the truth: -X is the ball's left half
                ball_left, ball_right = ball[:, : S // 2].sum(), ball[:, S // 2 :].sum()
                if max(ball_left, ball_right) < 10 * min(ball_left, ball_right):
                    continue  # the light was turned to the front or the back
                # the lit side is the side of the sphere's centre (its matte's centroid, wherever the crop's
                # jitter puts it) where the image's brightness lies
                x = torch.arange(OUT, dtype=torch.float32)
                alpha = sample["alpha"][0].float()
                centre = (alpha.sum(0) * x).sum() / alpha.sum()
                lit = (image * alpha).sum(0)
                assert ((lit * x).sum() / lit.sum() < centre) == bool(ball_left > ball_right)
                checked += 1
        assert checked >= 8

@pytest.mark.slow
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
            ({"plain_background": 1.5}, ValueCheckError, "plain_background"),
            ({"plain_albedo": (0.0, 0.5)}, ValueCheckError, "plain_albedo"),
            ({"plain_albedo": (0.5, 0.95)}, ValueCheckError, "plain_albedo"),
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

@pytest.mark.slow
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
        assert sorted(with_fx[0]["camera"]) == ["blur", "jpeg", "noise", "rolloff", "tone", "vignette"]
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

class TestEnvironmentBackground:
    def test_dataset_background_is_the_augmented_map_framed(self, shared_data) -> None:
        """The dataset's pyramid (source map times the gains) and direction map frame what the augmented full map
        of :func:`environment_background` frames: a real map, augmented (rotated, flipped, white-balanced)."""
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
                                mirror=mirror, turn=turn)

        def errors(view: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
            scale = old.abs().mean((1, 2, 3))
            pooled = torch.nn.functional.avg_pool2d(view - old, 4).abs().mean((1, 2, 3)) / scale
            return (view - old).abs().mean((1, 2, 3)) / scale, pooled, (view.mean((2, 3)) / old.mean((2, 3)) - 1).abs()

        # a real map's sharp detail: bilinear twice (old) against once (new); measured 0.024 and 0.039, pooled over
        # 4 x 4 pixels 0.009 and 0.015, mean colour 0.014
        raw, pooled, colour = errors(frame_backgrounds([pyramid] * 2, camera, mirror=mirror, turn=turn,
                                                       rotation=m.expand(2, 3, 3)))
        assert (raw < 0.1).all() and (pooled < 0.04).all() and (colour < 0.04).all(), (raw, pooled, colour)
        _, pooled, _ = errors(frame_backgrounds([pyramid] * 2, camera, mirror=mirror,
                                                turn=turn))  # without the rotation
        assert (pooled > 0.2).all(), pooled

    def test_environment_background_is_the_environment_at_higher_resolution(self) -> None:
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
        sampler = EnvironmentSampler([HDRFolderSource(shared_data / "hdri", height=32)], seed=0)
        env = sampler.sample(1)
        full = environment_background(env, sampler, height=256)
        assert full.shape == (3, 256, 512)
        err = (resize_latlong(full, 32) - env.latlong).abs().mean() / env.latlong.abs().mean()
        assert err < 0.15


def _disc_field(seed: int = 7, gain: float = 1.0) -> ReflectanceField:
    """A written-down 24 x 24 subject (no Mitsuba): a lit disc on black, with a ring of landmarks; ``gain`` times
    as bright as a white sphere under the same light."""
    n = 24
    c = (torch.arange(n, dtype=torch.float64) + 0.5) / n * 2 - 1
    y, x = torch.meshgrid(-c, c, indexing="ij")
    alpha = ((x**2 + y**2) <= 0.6).float()[None]
    field = (alpha.flatten()[None, :, None] * torch.full((3, 1, S * S), gain / (S * S))).to(torch.bfloat16)
    ring = torch.arange(len(LANDMARK_NAMES)) * 2 * math.pi / len(LANDMARK_NAMES)
    landmarks = torch.stack([12 + 5 * ring.cos(), 13 + 6 * ring.sin()], -1)
    camera = Camera(30.0, 1.0, 0.0, 0.0, size=n)
    return ReflectanceField(field, alpha, torch.tensor([6.0, 6.0, 18.0, 18.0]), camera, seed,
                            {"landmarks": landmarks.tolist(), "skin_tone": 3})


class TestMatte:
    def test_matte_adds_the_alpha_and_changes_nothing_else(self) -> None:
        config = PortraitConfig(split=None, size=32, sphere_sizes=(4, 8), env_pool=4, env_refresh=2,
                                fields_per_chunk=1, lightings_per_field=4, shuffle=1, length=8)
        plain = list(PortraitDataset([_disc_field()], config, seed=2))
        matte = list(PortraitDataset([_disc_field()], dataclasses.replace(config, matte=True), seed=2))
        assert "alpha" not in plain[0] and "pair" not in matte[0]
        for a, b in zip(plain, matte, strict=True):
            assert set(b) == set(a) | {"alpha"}
            for key, value in a.items():
                if isinstance(value, torch.Tensor):
                    assert torch.equal(value, b[key]), key
                elif isinstance(value, dict):
                    assert all(torch.equal(v, b[key][k]) for k, v in value.items()), key
                else:
                    assert value == b[key], key
            alpha = b["alpha"]
            assert alpha.dtype == torch.uint8 and alpha.shape == (1, 32, 32) and alpha.max() == 255
            rf = _disc_field()  # the matte is the subject's coverage of the crop, as with pairs
            source = rf.alpha.flip(-1) if b["flip"] else rf.alpha
            expected = crop_images(source[None], b["crop_box"][None].double(), 32)[0]
            assert (alpha.float() - 255 * expected).abs().max() <= 1.0


class TestSecondCrop:
    def test_drawn_last_inside_the_crop_and_only_when_asked(self) -> None:
        base = list(small([_disc_field()], split=None, camera=OFF, size=32, env_refresh=2, length=8))
        with_second = list(small([_disc_field()], split=None, camera=OFF, size=32, env_refresh=2, length=8,
                                 second_crop=True))
        assert all("second_crop" not in b for b in base)
        for a, b in zip(base, with_second, strict=True):
            assert torch.equal(a["image"], b["image"]) and torch.equal(a["mirror_ball"], b["mirror_ball"])
            box = b["second_crop"]
            assert box.shape == (4,) and bool((box >= 0).all() and (box <= 32).all())
        sides = torch.stack([b["second_crop"][2] - b["second_crop"][0] for b in with_second])
        assert sides.std() > 0  # jittered


class TestColourLooks:
    def test_drawn_last_with_their_lighting_and_only_when_asked(self) -> None:
        """A look changes a sample's photo and its lighting target together, and nothing else; at 0 no look
        is drawn, so every other draw is what it was."""
        base = list(small([_disc_field()], split=None, camera=OFF, size=32, env_refresh=2, length=16,
                          sphere_sizes=(4,)))
        looked = list(small([_disc_field()], split=None, camera=OFF, size=32, env_refresh=2, length=16,
                            sphere_sizes=(4,), colour_looks=1.0))
        assert all("look" not in b for b in base)
        kinds = {b["look"] for b in looked}
        assert kinds <= {1, 2, 4} and len(kinds) > 1
        for a, b in zip(base, looked, strict=True):
            assert torch.equal(a["crop_box"], b["crop_box"]) and a["exposure"] == b["exposure"]
            luminance = (a["mirror_ball"] * torch.tensor(LUMINANCE).view(3, 1, 1)).sum(0)
            if b["look"] == 1:  # greyscale: a grey photo, a grey lighting of the same luminance
                assert torch.equal(b["image"][0], b["image"][1]) and torch.equal(b["image"][1], b["image"][2])
                torch.testing.assert_close(b["mirror_ball"][0], luminance, rtol=1e-5, atol=1e-7)
                torch.testing.assert_close(b["spheres"]["diffuse_4"][0], b["spheres"]["diffuse_4"][2])
            if b["look"] == 4:  # a colour grade keeps the lighting; a toned black and white makes it grey
                assert torch.equal(a["mirror_ball"], b["mirror_ball"]) or torch.allclose(
                    b["mirror_ball"], luminance.expand(3, -1, -1), rtol=1e-5, atol=1e-7)


class TestLinearResponse:
    def test_a_linear_camera_darkens_the_midtones_and_keeps_the_lighting(self) -> None:
        """Every photo of a linear camera (``linear_response=1``) has the sRGB curve undone: its codes are about
        proportional to the light, so darker than the encoded photo's; the lighting target is the same."""
        base = list(small([_disc_field()], split=None, camera=OFF, size=32, env_refresh=2, length=8,
                          sphere_sizes=(4,)))
        linear = list(small([_disc_field()], split=None, camera=OFF, size=32, env_refresh=2, length=8,
                            sphere_sizes=(4,), linear_response=1.0))
        for a, b in zip(base, linear, strict=True):
            assert torch.equal(a["mirror_ball"], b["mirror_ball"]) and a["exposure"] == b["exposure"]
            lit = a["image"] > 20
            assert bool(lit.any()) and bool((b["image"][lit] < a["image"][lit]).all())
            want = (srgb_to_linear(a["image"].float()[None] / 255.0)[0] * 255.0)[lit]
            torch.testing.assert_close(b["image"][lit].float(), want, rtol=0.1, atol=2.0)
        with pytest.raises(ValueCheckError, match="linear_response"):
            PortraitConfig(linear_response=1.5)


class TestSurroundings:
    def test_a_wall_and_a_floor_darken_the_light_from_behind_and_below_and_show_behind_the_face(self) -> None:
        """Under a uniform sky, near surfaces of albedo below 1 send back less than the sky: the lighting target
        loses light from behind and below, keeps the light from the front and above, and the background
        changes; nothing else is drawn differently."""
        kw = {"split": None, "camera": OFF, "size": 32, "env_refresh": 2, "length": 8, "sphere_sizes": (4,),
              "environments": uniform_sampler(), "crop_scale": 2.5, "flip_probability": 0.0}
        base = list(small([_disc_field()], **kw))
        rooms = list(small([_disc_field()], surroundings=1.0, **kw))
        assert all("surroundings" not in b for b in base) and all(r["surroundings"] for r in rooms)
        for a, b in zip(base, rooms, strict=True):
            assert torch.equal(a["crop_box"], b["crop_box"])
            la, lb = a["mirror_ball"] / a["exposure"], b["mirror_ball"] / b["exposure"]
            assert bool((lb <= la * (1 + 1e-5) + 1e-9).all()) and bool((lb < la * 0.99).any())
            s = la.shape[-1]  # above the ball's centre: toward the camera and up, neither wall nor floor
            torch.testing.assert_close(lb[:, s // 2 - s // 6, s // 2], la[:, s // 2 - s // 6, s // 2])
            assert not torch.equal(a["image"], b["image"])
        with pytest.raises(ValueCheckError, match="surroundings"):
            PortraitConfig(surroundings=-0.1)


class TestFrame:
    def test_the_whole_frame_beside_the_crop(self) -> None:
        """``frame=N`` gives the rendered frame shrunk to N pixels, mirrored and exposed as the crop, with the
        face box in its pixels; every other field is what it was without it."""
        kw = {"split": None, "camera": OFF, "size": 32, "env_refresh": 2, "length": 8, "sphere_sizes": (4,),
              "environments": uniform_sampler(), "crop_scale": 2.5, "flip_probability": 0.5}
        base = list(small([_disc_field()], **kw))
        whole = list(small([_disc_field()], frame=16, **kw))
        assert any(w["flip"] for w in whole) and not all(w["flip"] for w in whole)
        for a, b in zip(base, whole, strict=True):
            assert "frame" not in a and b["frame"].shape == (3, 16, 16) and b["frame"].dtype == torch.uint8
            for key in ("image", "mirror_ball", "crop_box", "face_box", "exposure"):
                assert torch.equal(a[key], b[key])
            side = _disc_field().size
            torch.testing.assert_close(b["frame_box"], b["face_box"] * 16 / side)
            # the face is where its box says: brighter inside the box than at the frame's corners under the sky
            x0, y0, x1, y1 = b["frame_box"].round().long().tolist()
            face = b["frame"][:, max(y0, 0):y1, max(x0, 0):x1].float().mean()
            assert face > 0
            x0, y0, x1, y1 = b["frame_window"].tolist()  # a photo's window around the face, its long side 16
            assert 0 <= x0 < x1 <= 16 and 0 <= y0 < y1 <= 16 and max(x1 - x0, y1 - y0) == 16
        batch = collate(whole)
        assert batch["frame"].shape == (8, 3, 16, 16) and batch["frame_box"].shape == batch["frame_window"].shape
        with pytest.raises(ValueCheckError, match="frame"):
            PortraitConfig(frame=-1)


class TestCompanions:
    def test_a_second_person_beside_the_subject(self) -> None:
        """``companions=1``: another subject stands beside each one, in the frame and under the same light; the
        lighting target and every draw are what they were, and the sitter is never their own companion."""
        kw = {"split": None, "camera": OFF, "size": 32, "env_refresh": 2, "length": 8, "sphere_sizes": (4,),
              "environments": uniform_sampler(), "crop_scale": 2.5, "frame": 24}
        fields = [_disc_field(7), _disc_field(8, gain=3.0)]  # the second brighter than the sky behind
        base = list(small(fields, **kw))
        group = list(small(fields, companions=1.0, **kw))
        brighter = []
        for a, b in zip(base, group, strict=True):
            assert b["companion"] and "companion" not in a
            for key in ("crop_box", "face_box", "flip", "subject_seed"):
                assert torch.equal(torch.as_tensor(a[key]), torch.as_tensor(b[key]))
            torch.testing.assert_close(a["mirror_ball"] / a["exposure"], b["mirror_ball"] / b["exposure"])
            if a["subject_seed"] == 7:  # the bright one beside: more light in the frame, in the scene's units
                radiance = [srgb_to_linear(x["frame"].float() / 255.0).mean() / x["exposure"] for x in (a, b)]
                assert radiance[1] >= radiance[0] * (1 - 1e-4)
                brighter.append(bool(radiance[1] > radiance[0] * (1 + 1e-3)))
        assert any(brighter)  # some stand in view (0.3 to 0.5 m beside: at this framing, the frame's edge)
        alone = list(small([_disc_field(7)], companions=1.0, **kw))  # nobody else in the set: nobody beside
        assert not any(s["companion"] for s in alone)
        with pytest.raises(ValueCheckError, match="companions"):
            PortraitConfig(companions=1.5)


class TestPlainBackdrop:
    def _data(self, **kw) -> list[dict]:
        return list(small([_disc_field()], split=None, camera=OFF, size=32, env_refresh=2, flip_probability=0.0,
                          crop_scale=2.5, length=8, **kw))

    def test_backdrop_is_a_matte_wall_under_the_same_light(self) -> None:
        """Behind every face a uniform colour: a wall of albedo ``plain_albedo`` (times a tint) lit by the far
        environment, ``rho / pi * E(+Z)``, whatever the subject; the lighting target is the environment with the
        wall behind (its front half unchanged)."""
        plain = self._data(plain_background=1.0, plain_albedo=(0.5, 0.5), matte=True)
        scene = self._data(matte=True)
        for p, s in zip(plain, scene, strict=True):
            assert p["plain"] and "plain" not in s
            far = mirror_ball_to_latlong((s["mirror_ball"] / s["exposure"])[None], 16)[0]
            wall = plane_radiance(far.clamp(min=0.0), (0.0, 0.0, 1.0), (0.5, 0.5, 0.5))
            linear = srgb_to_linear(p["image"].float() / 255.0) / p["exposure"]
            alpha = p["alpha"][0].float() / 255.0
            inside = torch.zeros_like(alpha, dtype=torch.bool)
            inside[4:-4, 4:-4] = True  # the crop reaches past the rendered frame at its rim
            back = linear[:, (alpha == 0) & inside]
            assert back.shape[1] > 20
            assert (back - back.mean(1, keepdim=True)).abs().max() < 0.02 * back.mean()  # one colour (8 bits)
            ratio = back.mean(1).double() / wall
            assert bool(((ratio > math.exp(-0.4)) & (ratio < math.exp(0.4))).all())  # exp(N(0, 0.1)), resampling
            centre = slice(3, 5)  # the ball's middle reflects what is in front, within 41 deg of +Z
            torch.testing.assert_close((p["mirror_ball"] / p["exposure"])[:, centre, centre],
                                       (s["mirror_ball"] / s["exposure"])[:, centre, centre], rtol=1e-4, atol=0)
            assert not torch.equal(p["mirror_ball"], s["mirror_ball"])  # the wall behind is in the light

    def test_off_by_default_and_a_fraction_when_asked(self) -> None:
        base = self._data(matte=True)
        none = self._data(matte=True, plain_background=0.0)
        assert all(torch.equal(a["image"], b["image"]) for a, b in zip(base, none, strict=True))
        half = self._data(matte=True, plain_background=0.5)
        for h, b in zip(half, base, strict=True):  # a stream of its own: only the backdrop's samples change
            same = torch.equal(h["image"], b["image"]) and torch.equal(h["mirror_ball"], b["mirror_ball"])
            assert same != h["plain"]
        assert 0 < sum(h["plain"] for h in half) < len(half)
