"""Tests of the `sh` plugin (package kornia_ilum_sh, installed from plugins/sh)."""

from __future__ import annotations

import doctest
import importlib.metadata
import math

import kornia_ilum_sh
import pytest
import safetensors.torch
import torch
from kornia_ilum_sh import (
    INIT_RADIANCE,
    NEGATIVE_PENALTY,
    SCALES,
    MultiScaleSH,
    SHEstimator,
    SHRecipe,
    negative_penalty,
)

from kornia_ilum.core.files import sha256_file
from kornia_ilum.estimators import LightingEstimator, OursEstimator, create_estimator, list_estimators
from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum.render import mirror_ball_pyramid
from kornia_ilum.sh import sh_project, sh_reconstruct
from kornia_ilum_lab.train import BRDF_WEIGHTS, TrainConfig, train, training_losses
from kornia_ilum_lab.train.recipes import get_recipe, list_recipes
from tests.lab.train.helpers import small_data

VALID = mirror_ball_valid(32)


def crops(batch: int = 2, seed: int = 0) -> torch.Tensor:
    return torch.rand(batch, 3, 256, 256, generator=torch.Generator().manual_seed(seed))


def sun_sh(batch: int = 2) -> torch.Tensor:
    """Order-2 SH of a bright light from +Y over a dim constant: strongly negative below."""
    sh = torch.zeros(batch, 9, 3)
    sh[:, 0], sh[:, 1], sh[:, 6] = 0.3, 1.0, 0.4
    return sh


@pytest.fixture(scope="module")
def net() -> SHEstimator:
    torch.manual_seed(0)
    return SHEstimator().eval()


class TestRegistry:
    def test_discovered_by_entry_point(self):
        assert "sh" in list_estimators()
        est = create_estimator("sh", pretrained=False)
        assert isinstance(est, SHEstimator) and isinstance(est, LightingEstimator)
        info = est.info
        assert info.name == "sh" and info.input_size == 256 and info.needs_weights
        assert "LeGendre" in info.paper and kornia_ilum_sh.__version__

    def test_shipped_weights(self):
        (weights,) = SHEstimator.info.weights
        path = SHEstimator.default_weights_dir() / weights.name
        assert path.is_file() and sha256_file(path) == weights.sha256
        assert (SHEstimator.default_weights_dir() / "MODEL_CARD.md").is_file()
        est = create_estimator("sh")
        assert isinstance(est, SHEstimator) and not est.training
        state = safetensors.torch.load_file(path)
        assert {v.dtype for v in state.values()} == {torch.float16} and state.keys() == est.state_dict().keys()
        with torch.no_grad():
            out = est(crops(1))
        assert torch.isfinite(out.sh).all() and (out.mirror_ball[:, :, VALID] > 0).any()

    def test_training_names_load_on_first_use(self):
        assert kornia_ilum_sh.SHRecipe is SHRecipe and kornia_ilum_sh.MultiScaleSH is MultiScaleSH
        assert {"SHRecipe", "negative_penalty"} <= set(kornia_ilum_sh.__all__)
        with pytest.raises(AttributeError, match="has no attribute 'nope'"):
            kornia_ilum_sh.nope  # noqa: B018

    def test_training_recipe(self):
        # the recipe is found through its own entry point; the estimator does not know it (inference never
        # imports the training code)
        (ep,) = [ep for ep in importlib.metadata.entry_points(group="kornia_ilum.recipes") if ep.name == "sh"]
        assert ep.load() is SHRecipe and not hasattr(SHEstimator, "training_recipe")
        assert "sh" in list_recipes() and type(get_recipe("sh")) is SHRecipe
        recipe = get_recipe("sh")
        model, disc = recipe.build()
        assert isinstance(model, MultiScaleSH) and disc is None
        assert recipe.estimator(model) is model.estimator


class TestSHEstimator:
    def test_encoder_is_the_one_of_ours(self, net):
        ours = OursEstimator()
        for part in ("encoder", "to_latent"):
            mine = {k: v.shape for k, v in getattr(net, part).state_dict().items()}
            assert mine == {k: v.shape for k, v in getattr(ours, part).state_dict().items()}, part
        assert net.head.in_features == 1024 and net.head.out_features == 27
        assert set(net.state_dict()) == {k for k in net.state_dict() if k.split(".")[0] in
                                         ("encoder", "to_latent", "head")}  # the decoder of ours is dropped
        assert sum(p.numel() for p in net.parameters()) == 4878011

    def test_cardinality(self, net):
        with torch.no_grad():
            out = net(crops(3))
        assert out.sh.shape == (3, 9, 3) and out.mirror_ball.shape == out.log_mirror_ball.shape == (3, 3, 32, 32)
        assert out.valid.shape == (32, 32) and out.valid.dtype == torch.bool and len(out) == 3
        assert out.sh.dtype == out.mirror_ball.dtype == torch.float32
        assert (out.mirror_ball >= 0).all() and (out.mirror_ball[:, :, ~VALID] == 0).all()
        torch.testing.assert_close(out.log_mirror_ball, torch.log1p(out.mirror_ball))

    def test_sh_round_trip(self, net):
        """mirror_ball == clamp(sh_reconstruct(sh)); the unclamped reconstruction projects back to sh."""
        with torch.no_grad():
            out = net(crops(2, seed=1))
        assert torch.equal(out.mirror_ball, sh_reconstruct(out.sh, 32).clamp(min=0.0))
        torch.testing.assert_close(sh_project(sh_reconstruct(out.sh, 32)), out.sh, atol=1e-4, rtol=1e-4)

    def test_negative_lobes_clamped_in_the_estimate(self):
        """A head that predicts a sun's SH: .sh keeps the raw coefficients, mirror_ball is clamped at 0."""
        net = SHEstimator(normalize_exposure=False)  # the network's coefficients, not rescaled to the crop's exposure
        with torch.no_grad():
            net.head.weight.zero_()
            net.head.bias.copy_(sun_sh(1).flatten())
            out = net(crops(1))
        torch.testing.assert_close(out.sh, sun_sh(1))
        raw = sh_reconstruct(sun_sh(1), 32)
        assert (raw[:, :, VALID] < 0).any()  # the order-2 function really dips below 0
        assert torch.equal(out.mirror_ball, raw.clamp(min=0.0))

    def test_initial_bias_is_positive_uniform_lighting(self):
        net = SHEstimator()
        bias = net.head.bias.detach().reshape(9, 3)
        torch.testing.assert_close(bias[0], torch.full((3,), INIT_RADIANCE * math.sqrt(4 * math.pi)))
        assert (bias[1:] == 0).all()

    def test_autocast_keeps_the_parameter_dtype(self, net):
        with torch.no_grad(), torch.autocast("cpu", dtype=torch.bfloat16):
            out = net(crops(1))
        assert out.sh.dtype == out.mirror_ball.dtype == torch.float32

    def test_doctests(self):
        for module in (kornia_ilum_sh.estimator, kornia_ilum_sh.recipe):
            result = doctest.testmod(module, extraglobs={"torch": torch})
            assert result.failed == 0 and result.attempted >= 2, module.__name__


class TestMultiScaleSH:
    def test_unclamped_pyramid_of_the_reconstruction(self):
        torch.manual_seed(0)
        model = MultiScaleSH()
        x = crops(2)
        with torch.no_grad():
            out = model(x)
            want = mirror_ball_pyramid(sh_reconstruct(model.estimator.coefficients(x).float(), 32), SCALES)
        assert sorted(out) == list(SCALES)
        for s in SCALES:
            assert out[s].shape == (2, 3, s, s) and out[s].dtype == torch.float32
            torch.testing.assert_close(out[s], want[s])
            assert (out[s][:, :, ~mirror_ball_valid(s)] == 0).all()

    def test_gradients_finite_with_negative_lighting(self):
        """The training loss on negative SH lighting: finite gradients, into the network too."""
        sh = sun_sh().requires_grad_(True)
        lighting = sh_reconstruct(sh, 32)
        assert (lighting[:, :, VALID] < 0).float().mean() > 0.2
        truth = (torch.rand(2, 3, 32, 32, generator=torch.Generator().manual_seed(0)) + 0.1) * VALID
        loss, _ = training_losses(mirror_ball_pyramid(lighting, SCALES), truth, brdf_weights=BRDF_WEIGHTS)
        loss.backward()
        assert torch.isfinite(loss) and torch.isfinite(sh.grad).all() and sh.grad.abs().sum() > 0

        torch.manual_seed(0)
        model = MultiScaleSH()
        with torch.no_grad():
            model.estimator.head.bias.copy_(sun_sh(1).flatten())
        out = model(crops(2))
        assert (out[32][:, :, VALID] < 0).any()
        loss, _ = training_losses(out, truth, brdf_weights=BRDF_WEIGHTS)
        loss.backward()
        grads = [p.grad for p in model.parameters()]
        assert all(g is not None and torch.isfinite(g).all() for g in grads)

    def test_penalty_unsticks_all_negative_lighting(self):
        """All-negative lighting: softclip gives the loss no gradient; the recipe's penalty term does."""
        truth = torch.ones(1, 3, 32, 32) * VALID
        sh = torch.zeros(1, 9, 3)
        sh[:, 0] = -1.0
        plain = sh.clone().requires_grad_(True)
        training_losses(mirror_ball_pyramid(sh_reconstruct(plain, 32), SCALES), truth,
                        brdf_weights=BRDF_WEIGHTS)[0].backward()
        assert plain.grad.abs().max() == 0  # the stall the penalty is for
        pushed = sh.clone().requires_grad_(True)
        pred = mirror_ball_pyramid(sh_reconstruct(pushed, 32), SCALES)
        extras = SHRecipe().extra_losses(pred)
        (training_losses(pred, truth, brdf_weights=BRDF_WEIGHTS)[0] + sum(extras.values())).backward()
        assert pushed.grad[0, 0].lt(0).all()  # gradient descent raises the constant term

    def test_extra_loss_is_the_penalty(self):
        lighting = sh_reconstruct(sun_sh(), 32)
        extras = SHRecipe().extra_losses(mirror_ball_pyramid(lighting, SCALES))
        assert set(extras) == {"negative"} and float(extras["negative"]) > 0
        torch.testing.assert_close(extras["negative"], NEGATIVE_PENALTY * negative_penalty(lighting, VALID))


class TestSpreadHead:
    def test_the_head_adds_the_spread_and_changes_nothing_else(self):
        torch.manual_seed(0)
        plain = SHEstimator()
        torch.manual_seed(0)
        spread = SHEstimator(spread_head=True)
        x = crops(2)
        with torch.no_grad():
            a, b = plain(x), spread(x)
        assert a.log_energy_spread is None and b.log_energy_spread.shape == (2,)
        assert (b.log_energy_spread > 0).all()
        torch.testing.assert_close(a.sh, b.sh)  # the head is built last: the rest draws the same initial weights

    def test_a_file_with_the_head_turns_it_on_and_one_without_keeps_the_model(self):
        with_head = SHEstimator(spread_head=True).state_dict()
        net = SHEstimator()
        net.load_state_dict(with_head, strict=True)
        assert net.spread is not None
        older = SHEstimator().state_dict()
        net = SHEstimator(spread_head=True)
        net.load_state_dict(older, strict=True)
        assert net.spread is not None and net(crops(1)).log_energy_spread is not None

    def test_the_training_model_carries_the_spread_for_the_likelihood(self):
        from kornia_ilum_lab.train.losses import energy_nll

        model, disc = SHRecipe().build(spread_head=True)
        assert disc is None
        out = model(crops(2))
        assert out.log_spread.shape == (2,)
        truth = (torch.rand(2, 3, 32, 32, generator=torch.Generator().manual_seed(0)) + 0.1) * VALID
        nll = energy_nll(out[32], truth, out.log_spread)
        nll.backward()
        assert torch.isfinite(nll) and model.estimator.spread.weight.grad.abs().sum() > 0


class TestTraining:
    @pytest.mark.slow  # trains, on a cache that the tiny_cache fixture renders with Mitsuba
    def test_two_steps_end_to_end(self, tiny_cache, tmp_path):
        threads = torch.get_num_threads()
        data = small_data()
        config = TrainConfig(out=str(tmp_path / "run"), cache=(str(tiny_cache),), estimator="sh", steps=2, batch=2,
                             workers=0, threads=1, checkpoint_every=3, log_every=1, data=data)
        try:
            summary = train(config)
        finally:
            torch.set_num_threads(threads)
        assert summary["steps"] == 2 and summary["final"]["adv"] == 0 and summary["final"]["disc"] == 0
        assert math.isfinite(summary["final"]["loss"]) and summary["final"]["loss"] > 0
        state = safetensors.torch.load_file(tmp_path / "run" / "sh.safetensors")
        est = SHEstimator()
        est.load_state_dict({k: v.float() for k, v in state.items()}, strict=True)  # the export loads
        checkpoint = torch.load(tmp_path / "run" / "checkpoint.pt", weights_only=True)
        assert checkpoint["disc"] == {} and checkpoint["step"] == 2

    @pytest.mark.slow  # trains, on a cache that the tiny_cache fixture renders with Mitsuba
    def test_the_scale_apart_trains_and_exports_the_spread(self, tiny_cache, tmp_path):
        threads = torch.get_num_threads()
        config = TrainConfig(out=str(tmp_path / "run"), cache=(str(tiny_cache),), estimator="sh", steps=1, batch=2,
                             workers=0, threads=1, log_every=1, data=small_data(), model={"spread_head": True},
                             lambda_nll=0.25)
        try:
            summary = train(config)
        finally:
            torch.set_num_threads(threads)
        assert math.isfinite(summary["final"]["nll"]) and summary["final"]["spread"] > 0
        state = safetensors.torch.load_file(tmp_path / "run" / "sh.safetensors")
        assert {"spread.weight", "spread.bias"} <= set(state)
        est = SHEstimator()
        est.load_state_dict({k: v.float() for k, v in state.items()}, strict=True)
        assert est(crops(1)).log_energy_spread.shape == (1,)
