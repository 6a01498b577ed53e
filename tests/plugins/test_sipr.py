"""Tests of the `sipr` plugin (package kornia_ilum_sipr, installed from plugins/sipr)."""

from __future__ import annotations

import csv
import doctest
import importlib.metadata
import math

import kornia_ilum_sipr
import pytest
import safetensors.torch
import torch
from kornia_ilum.color import normalize_exposure
from kornia_ilum_sipr import (
    ENCODER_DEPTHS,
    INPUT_SIZE,
    LIGHTING_SHAPE,
    ConvNormAct,
    Encoder,
    LightingHead,
    SIPREstimator,
    SIPRRecipe,
    SIPRTrainer,
    log_latlong_target,
    masked_l1,
)

from kornia_ilum.core.files import sha256_file
from kornia_ilum.estimators import LightingEstimator, create_estimator, list_estimators
from kornia_ilum.geometry import latlong_solid_angles, mirror_ball_solid_angles, mirror_ball_valid
from kornia_ilum_lab.synth.camera_effects import CameraEffects
from kornia_ilum_lab.synth.lightstage.portraits import PortraitConfig, PortraitDataset, load_fields
from kornia_ilum_lab.train import TrainConfig, read_log, train
from kornia_ilum_lab.train.data import collate
import kornia_ilum_lab.train.recipes
from kornia_ilum_lab.train.recipes import get_recipe, list_recipes
from tests.lab.train.helpers import small_data


@pytest.fixture(scope="module")
def net() -> SIPREstimator:
    torch.manual_seed(0)
    return SIPREstimator().eval()


def crops(batch: int = 2, seed: int = 0, size: int = INPUT_SIZE) -> torch.Tensor:
    return torch.rand(batch, 3, size, size, generator=torch.Generator().manual_seed(seed))


class TestRegistry:
    def test_discovered_by_entry_point(self):
        assert "sipr" in list_estimators()
        est = create_estimator("sipr", pretrained=False)
        assert isinstance(est, SIPREstimator) and isinstance(est, LightingEstimator)
        assert est.info.name == "sipr" and est.info.input_size == INPUT_SIZE == 128 and est.info.needs_weights
        assert "Sun et al. 2019" in est.info.paper and kornia_ilum_sipr.__version__

    def test_shipped_weights(self):
        """The weights of the budget run (issue 22) load, SHA-256 checked, in float16, and give lighting."""
        (weights,) = SIPREstimator.info.weights
        path = SIPREstimator.default_weights_dir() / weights.name
        assert path.is_file() and sha256_file(path) == weights.sha256
        assert (SIPREstimator.default_weights_dir() / "MODEL_CARD.md").is_file()
        est = create_estimator("sipr")
        assert isinstance(est, SIPREstimator) and not est.training
        state = safetensors.torch.load_file(path)
        assert {v.dtype for v in state.values()} == {torch.float16} and state.keys() == est.state_dict().keys()
        with torch.no_grad():
            out = est(crops(1))
        valid = mirror_ball_valid(32)
        assert torch.isfinite(out.mirror_ball).all() and (out.mirror_ball[:, :, valid] > 0).all()

    def test_training_names_load_on_first_use(self):
        assert kornia_ilum_sipr.SIPRRecipe is SIPRRecipe and kornia_ilum_sipr.masked_l1 is masked_l1
        assert {"SIPRRecipe", "SIPRTrainer", "masked_l1"} <= set(kornia_ilum_sipr.__all__)
        with pytest.raises(AttributeError, match="has no attribute 'nope'"):
            kornia_ilum_sipr.nope  # noqa: B018

    def test_training_recipe(self):
        # the recipe is found through its own entry point; the estimator does not know it (inference never
        # imports the training code)
        (ep,) = [ep for ep in importlib.metadata.entry_points(group="kornia_ilum.recipes") if ep.name == "sipr"]
        assert ep.load() is SIPRRecipe and not hasattr(SIPREstimator, "training_recipe")
        assert "sipr" in list_recipes() and isinstance(get_recipe("sipr"), SIPRRecipe)
        model, disc = get_recipe("sipr").build()
        assert isinstance(model, SIPRTrainer) and disc is None

    def test_doctests(self):
        for module in (kornia_ilum_sipr.network, kornia_ilum_sipr.estimator, kornia_ilum_sipr.recipe):
            failures, _ = doctest.testmod(module, extraglobs={"torch": torch}, optionflags=doctest.ELLIPSIS)
            assert failures == 0, module.__name__


class TestNetwork:
    def test_encoder_blocks_as_nelf(self):
        enc = Encoder()
        feats = enc(crops(1, size=256))
        assert [f.shape[1] for f in feats] == list(ENCODER_DEPTHS)
        assert [f.shape[-1] for f in feats] == [256, 128, 128, 64, 64, 32, 32, 16, 16, 16]  # strides at 1, 3, 5, 7
        first = enc.blocks[0]
        assert first[0].kernel_size == (7, 7) and first[0].out_channels == 29
        for block in enc.blocks:
            conv, norm, act = block
            assert isinstance(norm, torch.nn.GroupNorm) and norm.num_groups == min(32, conv.out_channels)
            assert isinstance(act, torch.nn.PReLU)
        x = crops(1, size=256)
        assert torch.equal(feats[0][:, :3], x)  # the input joins block 0's 29 channels

    def test_lighting_head_is_the_confidence_weighted_mean(self):
        torch.manual_seed(1)
        head = LightingHead((2, 4)).eval()
        bottleneck = torch.randn(2, 512, 3, 3)
        y = torch.nn.functional.softplus(head.out(head.hidden(bottleneck))).reshape(2, 4, 2, 4, 9)
        light, conf = y[:, :3], y[:, 3:] + 1e-6
        expected = (light * conf).sum(-1) / conf.sum(-1)
        torch.testing.assert_close(head(bottleneck), expected)
        assert (head(bottleneck) >= 0).all()

    def test_no_light_and_no_confidence_is_black(self):
        head = LightingHead((2, 4))
        with torch.no_grad():
            head.out.weight.zero_()
            head.out.bias.fill_(-30.0)  # softplus ~ 0: no light, no confidence
        bottleneck = torch.zeros(1, 512, 4, 4)
        with torch.no_grad():
            out = head(bottleneck)
        assert out.shape == (1, 3, 2, 4) and float(out.abs().max()) < 1e-6

    def test_any_batch_size_and_samples_independent(self, net):
        x = crops(3, seed=2)
        with torch.no_grad():
            together = net(x).mirror_ball
            alone = torch.cat([net(x[i : i + 1]).mirror_ball for i in range(3)])
        torch.testing.assert_close(together, alone, rtol=1e-4, atol=1e-5)

    def test_estimate_keeps_the_latlong_energy(self, net):
        with torch.no_grad():
            x = crops(2, seed=3)
            latlong = net.latlong(normalize_exposure(x)[0]) * normalize_exposure(x)[1][:, None, None, None]
            est = net(x)  # the network on the crop re-exposed to 0.18, the estimate scaled back
        e_ll = (latlong * latlong_solid_angles(LIGHTING_SHAPE[0])).sum((-2, -1))
        e_mb = (est.mirror_ball * mirror_ball_solid_angles(32)).sum((-2, -1))
        torch.testing.assert_close(e_mb, e_ll, rtol=1e-4, atol=1e-6)
        valid = mirror_ball_valid(32)
        assert (est.mirror_ball[..., ~valid] == 0).all() and (est.mirror_ball >= 0).all()
        torch.testing.assert_close(est.log_mirror_ball, torch.log1p(est.mirror_ball))

    def test_autocast_keeps_the_parameter_dtype(self, net):
        with torch.no_grad(), torch.autocast("cpu", dtype=torch.bfloat16):
            est = net(crops(1))
        assert est.mirror_ball.dtype == torch.float32 and torch.isfinite(est.mirror_ball).all()

    def test_decoder_is_training_only(self, net):
        trainer = SIPRTrainer()
        exported = set(trainer.estimator.state_dict())
        assert exported == set(SIPREstimator().state_dict())
        assert not any(k.startswith("decoder") for k in exported)
        assert all(k.startswith(("estimator.", "decoder.")) for k in trainer.state_dict())

    def test_relit_image_depends_on_the_target_lighting(self):
        torch.manual_seed(4)
        trainer = SIPRTrainer().eval()
        x = crops(1, size=64)
        with torch.no_grad():
            dark, z1 = trainer(x, torch.zeros(1, 3, 16, 32))
            bright, z2 = trainer(x, torch.full((1, 3, 16, 32), 3.0))
        assert dark.shape == (1, 3, 64, 64) and 0 <= float(dark.min()) and float(dark.max()) <= 1
        assert not torch.allclose(dark, bright) and torch.equal(z1, z2)  # the estimate ignores the target


class TestLosses:
    def test_log_latlong_target_keeps_energy(self):
        valid = mirror_ball_valid(32)
        ball = torch.rand(2, 3, 32, 32, generator=torch.Generator().manual_seed(5)) * valid * 4
        z = log_latlong_target(ball)
        e_ll = (torch.expm1(z) * latlong_solid_angles(16)).sum((-2, -1))
        torch.testing.assert_close(e_ll, (ball * mirror_ball_solid_angles(32)).sum((-2, -1)), rtol=1e-4, atol=1e-5)

    def test_masked_l1_ignores_the_background(self):
        alpha = torch.zeros(1, 1, 4, 4)
        alpha[..., :2, :] = 1.0
        pred, target = torch.zeros(1, 3, 4, 4), torch.zeros(1, 3, 4, 4)
        pred[..., 2:, :] = 1.0  # wrong only where alpha is 0
        assert float(masked_l1(pred, target, alpha)) == 0.0
        pred[..., 0, 0] = 0.5
        assert math.isclose(float(masked_l1(pred, target, alpha)), 0.5 * 3 / 24, rel_tol=1e-6)


@pytest.mark.slow  # the tiny_cache fixture renders with Mitsuba
class TestData:
    def test_pairs_give_the_matte_and_a_second_lighting(self, tiny_cache):
        fields = load_fields(tiny_cache, split=None)
        config = PortraitConfig(split=None, background="black", pairs=True, camera=CameraEffects.off(),
                                flip_probability=0.5, length=8, **small_data())
        samples = list(PortraitDataset(fields, config, seed=3))
        for s in samples:
            alpha = s["alpha"]
            assert alpha.shape == (1, 256, 256) and alpha.dtype == torch.uint8
            assert 0 < int((alpha > 0).sum()) < alpha.numel()
            near = torch.nn.functional.max_pool2d((alpha > 0).float()[None], 5, stride=1, padding=2)[0, 0]
            outside = near == 0  # two pixels off the matte (its edge pixels round to 0 but are not black)
            for image in (s["image"], s["pair"]["image"]):
                assert int(image[:, outside].max()) == 0  # black background: nothing outside the matte
                assert float(image[:, alpha[0] == 255].float().mean()) > 0
            assert not torch.equal(s["mirror_ball"], s["pair"]["mirror_ball"])
        batch = collate(samples)
        assert batch["alpha"].shape == (8, 1, 256, 256) and batch["pair_image"].shape == (8, 3, 256, 256)
        assert batch["pair_mirror_ball"].shape == (8, 3, 32, 32)

    def test_recipe_dataset_is_sipr_training_data(self, tiny_cache):
        base = PortraitDataset(load_fields(tiny_cache, split=None), PortraitConfig(split=None), seed=1)
        data = SIPRRecipe().dataset(base)
        assert data.config.background == "black" and data.config.pairs and data.config.crop == "face"
        assert data.config.crop_position > base.config.crop_position and data.config.size == INPUT_SIZE
        assert data.seed == base.seed and all(a is b for a, b in zip(data.fields, base.fields, strict=True))


class TestTraining:
    @pytest.mark.slow  # trains, on a cache that the tiny_cache fixture renders with Mitsuba
    def test_two_steps_end_to_end(self, tiny_cache, tmp_path, monkeypatch):
        monkeypatch.setattr(kornia_ilum_lab.train.recipes, "PROBE_SIZE", 4)  # the float16 probe: 4 crops, not 32
        threads = torch.get_num_threads()
        data = small_data()
        config = TrainConfig(out=str(tmp_path / "run"), cache=(str(tiny_cache),), estimator="sipr", steps=2,
                             batch=2, workers=0, threads=2, checkpoint_every=3, log_every=1, data=data)
        try:
            summary = train(config)
        finally:
            torch.set_num_threads(threads)
        final = summary["final"]
        assert summary["steps"] == 2 and final["adv"] == 0 and final["disc"] == 0
        assert math.isclose(final["loss"], final["relit"] + final["lighting"], rel_tol=1e-4)
        assert all(math.isfinite(final[k]) and final[k] > 0 for k in ("relit", "lighting", "rec_diffuse"))
        with open(tmp_path / "run" / "log.csv", newline="") as f:
            assert {"relit", "lighting"} <= set(next(csv.reader(f)))
        assert len(read_log(tmp_path / "run")) == 2
        state = safetensors.torch.load_file(tmp_path / "run" / "sipr.safetensors")
        est = SIPREstimator()
        est.load_state_dict({k: v.float() for k, v in state.items()}, strict=True)  # the export loads
        assert not any(k.startswith("decoder") for k in state)

    @pytest.mark.slow  # fits, on a cache that the tiny_cache fixture renders with Mitsuba
    def test_spread_fitted_at_export_leaves_the_lighting(self, tiny_cache, tmp_path, monkeypatch):
        """``--steps 0 --init W --model spread_head=True --fit-spread N``: no step, the spread head fitted on
        portraits at the estimator's input size, every other weight as in ``W``."""
        monkeypatch.setattr(kornia_ilum_lab.train.recipes, "PROBE_SIZE", 4)
        torch.manual_seed(0)
        init = tmp_path / "init.safetensors"
        safetensors.torch.save_file(SIPREstimator().state_dict(), init)
        threads = torch.get_num_threads()
        config = TrainConfig(out=str(tmp_path / "run"), cache=(str(tiny_cache),), estimator="sipr", steps=0,
                             init=str(init), model={"spread_head": True}, fit_spread=8, batch=2, workers=0,
                             threads=2, data=small_data())
        try:
            summary = train(config)
        finally:
            torch.set_num_threads(threads)
        assert summary["steps"] == 0 and summary["spread_fit"]["samples"] == 8
        assert summary["spread_fit"]["nll_after"] <= summary["spread_fit"]["nll_before"]
        state = safetensors.torch.load_file(tmp_path / "run" / "sipr.safetensors")
        before = safetensors.torch.load_file(init)
        assert set(state) == set(before) | {"spread.weight", "spread.bias"}
        assert all(torch.allclose(state[k].float(), before[k].float(), rtol=1e-3, atol=1e-3) for k in before)
        est = SIPREstimator()
        est.load_state_dict({k: v.float() for k, v in state.items()}, strict=True)  # the head turns on
        out = est(torch.rand(2, 3, 128, 128))
        assert est.spread is not None and out.log_energy_spread.shape == (2,) and (out.log_energy_spread > 0).all()
