"""kornia_ilum_lab.train.recipes: recipes by entry point, the default step, and the one-way loop -> recipe."""

from __future__ import annotations

import ast
import importlib.metadata
import inspect
import subprocess
import sys
from pathlib import Path

import kornia_ilum_sh.recipe
import kornia_ilum_sipr.recipe
import pytest
import torch
from torch import nn

import kornia_ilum_lab.train.recipes as recipes
from kornia_ilum.color import LUMINANCE
from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum.render import mirror_ball_pyramid
from kornia_ilum_lab.train import (
    BRDF_WEIGHTS,
    SCALES,
    MSGDiscriminator,
    MultiScaleOurs,
    Recipe,
    RuntimeSettings,
    TrainConfig,
    get_recipe,
    list_recipes,
    train_step,
)
from kornia_ilum_lab.synth.colour_looks import greyscale
from kornia_ilum_lab.train.losses import log_l2_loss
from kornia_ilum_lab.train.recipes import (
    RECIPE_ENTRY_POINT_GROUP,
    OursRecipe,
    batch_images,
    crop_consistency,
    colour_consistency,
    colour_pairs,
    crop_pairs,
)


class TestDiscovery:
    def test_recipes_by_entry_point(self) -> None:
        assert RECIPE_ENTRY_POINT_GROUP == "kornia_ilum.recipes"
        eps = importlib.metadata.entry_points(group=RECIPE_ENTRY_POINT_GROUP)
        declared = {ep.name: ep.value for ep in eps}
        assert declared["ours"] == "kornia_ilum_lab.train.recipes:OursRecipe"
        assert list_recipes() == ["ours", "scene", "sh", "sipr"]  # scene: the scene branch (train/scene.py)
        recipe = get_recipe("ours")
        assert isinstance(recipe, OursRecipe) and recipe.name == "ours" and recipe.log_fields == ()

    def test_unknown_name(self) -> None:
        message = r"no training recipe for estimator 'uniform'; trainable: ours, scene, sh, sipr"
        with pytest.raises(ValueCheckError, match=message):
            get_recipe("uniform")

    def test_broken_entry_points_warn_and_are_skipped(self, monkeypatch) -> None:
        group = RECIPE_ENTRY_POINT_GROUP
        eps = [importlib.metadata.EntryPoint("ours", "kornia_ilum_lab.train.recipes:OursRecipe", group),
               importlib.metadata.EntryPoint("gone", "kornia_ilum_no_such_module:Recipe", group),
               importlib.metadata.EntryPoint("model", "kornia_ilum_lab.train.models:MSGDiscriminator", group),
               importlib.metadata.EntryPoint("ours", "kornia_ilum_lab.train.recipes:Recipe", group)]
        monkeypatch.setattr(recipes.importlib.metadata, "entry_points", lambda group: eps)
        with pytest.warns(RuntimeWarning) as caught:
            assert list_recipes() == ["ours"]
        messages = " ".join(str(w.message) for w in caught)
        assert "'gone = kornia_ilum_no_such_module:Recipe'" in messages and "not a subclass" in messages
        with pytest.warns(RuntimeWarning):
            assert type(get_recipe("ours")) is OursRecipe  # the first 'ours' wins

    def test_ours_builds_the_multi_scale_generator_and_the_discriminator(self) -> None:
        recipe = get_recipe("ours")
        model, disc = recipe.build()
        assert isinstance(model, MultiScaleOurs) and isinstance(disc, MSGDiscriminator)
        assert recipe.estimator(model) is model.estimator
        assert model.estimator.normalize_exposure  # the default

    def test_model_options_reach_the_estimator(self) -> None:
        model, _ = get_recipe("ours").build(normalize_exposure=False)
        assert not model.estimator.normalize_exposure
        with pytest.raises(ValueCheckError, match="not OursEstimator's"):
            get_recipe("ours").build(no_such_option=1)


class TestOneWay:
    def test_recipes_never_import_the_loop(self) -> None:
        """The loop calls the recipe; no recipe module imports the loop, at the top or in a function."""
        for module in (recipes, kornia_ilum_sh.recipe, kornia_ilum_sipr.recipe):
            tree = ast.parse(Path(module.__file__).read_text())
            imported = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
            imported |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
            assert not {m for m in imported if m and m.startswith("kornia_ilum_lab.train.loop")}, module.__name__
            assert "kornia_ilum_lab.train" not in imported, module.__name__  # the package imports the loop

    def test_train_step_takes_keywords_and_a_typed_recipe(self) -> None:
        params = inspect.signature(train_step).parameters
        assert all(p.kind is inspect.Parameter.KEYWORD_ONLY for p in params.values())
        assert params["recipe"].annotation == "Recipe | None" and params["recipe"].default is None
        step = inspect.signature(Recipe.step).parameters
        assert all(p.kind is inspect.Parameter.KEYWORD_ONLY for n, p in step.items() if n != "self")
        assert {"config", "runtime"} <= set(step)

    @pytest.mark.slow  # subprocesses
    @pytest.mark.parametrize("name", ["ours", "sh", "sipr", "uniform"])
    def test_creating_an_estimator_never_imports_training(self, name) -> None:
        code = (f"import sys, kornia_ilum; kornia_ilum.create_estimator({name!r}); "
                "print(sorted(m for m in sys.modules "
                "if m.startswith('kornia_ilum_lab.train') or m.endswith('.recipe')))")
        r = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
        assert r.stdout.strip() == "[]"


class _Tiny(nn.Module):
    """A two-scale generator of constant lighting, for steps that take no time."""

    def __init__(self) -> None:
        super().__init__()
        self.level = nn.Parameter(torch.tensor(0.5))

    def forward(self, crops: torch.Tensor) -> dict[int, torch.Tensor]:
        brightness = self.level.exp() * crops.mean((1, 2, 3))[:, None, None, None]  # (B, 1, 1, 1)
        return {s: (brightness * mirror_ball_valid(s)).expand(-1, 3, -1, -1) for s in (16, 32)}


class _Penalised(Recipe):
    def extra_losses(self, pred: dict[int, torch.Tensor]) -> dict[str, torch.Tensor]:
        return {"bright": 0.25 * pred[32].mean()}


@pytest.mark.parametrize("lighting", ["sun 1e5 over 1e-3", "all 1e-6", "all 1e4"])
def test_ours_steps_stay_finite_on_extreme_lighting(lighting) -> None:
    """A sun-dominated environment and exposure extremes: finite losses, gradients and weights (issue 24)."""
    torch.manual_seed(0)
    model, disc = OursRecipe().build()
    valid = mirror_ball_valid(32)
    target = {"sun 1e5 over 1e-3": torch.full((2, 3, 32, 32), 1e-3), "all 1e-6": torch.full((2, 3, 32, 32), 1e-6),
              "all 1e4": torch.full((2, 3, 32, 32), 1e4)}[lighting]
    if lighting.startswith("sun"):
        target[:, :, 9, 20] = 1e5
    target = target * valid
    crops = torch.rand(2, 3, 256, 256)
    opt_g = torch.optim.Adam(model.parameters(), lr=1.5e-4)
    opt_d = torch.optim.Adam(disc.parameters(), lr=1.5e-6)
    config = TrainConfig(out="-", cache=("-",), lambda_energy=0.5)
    runtime = RuntimeSettings(bf16=False, channels_last=False, workers=0)
    losses = train_step(model=model, disc=disc, opt_g=opt_g, opt_d=opt_d, crops=crops, target=target,
                        config=config, runtime=runtime, recipe=OursRecipe())
    assert all(torch.isfinite(v).all() for v in losses.values()), losses
    for net in (model, disc):
        assert all(p.grad is None or torch.isfinite(p.grad).all() for p in net.parameters())
        assert all(torch.isfinite(p).all() for p in net.parameters())


class TestTrainStep:
    def _run(self, recipe: Recipe | None, disc: nn.Module | None = None) -> tuple[dict, nn.Module]:
        torch.manual_seed(0)
        model = _Tiny()
        opt_g = torch.optim.Adam(model.parameters(), lr=1e-2)
        opt_d = torch.optim.Adam(disc.parameters(), lr=1e-4) if disc is not None else None
        crops = torch.rand(2, 3, 8, 8)
        target = torch.rand(2, 3, 32, 32) * mirror_ball_valid(32)
        config = TrainConfig(out="-", cache=("-",))
        runtime = RuntimeSettings(bf16=False, channels_last=False, workers=0)
        losses = train_step(model=model, disc=disc, opt_g=opt_g, opt_d=opt_d, crops=crops, target=target,
                            config=config, runtime=runtime, recipe=recipe)
        return losses, model

    def test_the_generator_steps_on_rec_plus_the_recipes_extra_terms(self) -> None:
        plain, moved = self._run(None)
        assert set(plain) == {"loss", "rec", "adv", "disc", "extra", "crop", "colour", "energy", "nll", "spread", "albedo",
                              "rec_diffuse", "rec_matte_silver", "rec_mirror"}
        assert plain["adv"] == 0 and plain["disc"] == 0 and plain["extra"] == 0 and plain["crop"] == 0
        assert plain["energy"] == 0
        assert torch.equal(plain["loss"], plain["rec"]) and moved.level.item() != 0.5
        penalised, _ = self._run(_Penalised())
        assert penalised["extra"] > 0
        assert torch.isclose(penalised["loss"], penalised["rec"] + penalised["extra"])
        assert all(not v.requires_grad for v in penalised.values())

    def test_the_discriminator_steps_first(self) -> None:
        disc = MSGDiscriminator()

        class TwoScales(nn.Module):  # MSGDiscriminator wants all four scales
            def __init__(self) -> None:
                super().__init__()
                self.disc = disc

            def forward(self, images):
                return self.disc({s: images[max(images)][..., :: 32 // s, :: 32 // s] for s in SCALES})

        before = [p.detach().clone() for p in disc.parameters()]
        losses, _ = self._run(None, TwoScales())
        assert losses["disc"] > 0 and losses["adv"] > 0
        assert any(not torch.equal(a, b) for a, b in zip(before, disc.parameters(), strict=True))

    def test_batch_images(self) -> None:
        batch = {"image": torch.full((1, 3, 2, 2), 255, dtype=torch.uint8)}
        x = batch_images(batch, "image", torch.device("cpu"), torch.channels_last)
        assert x.dtype == torch.float32 and bool((x == 1).all())
        assert x.is_contiguous(memory_format=torch.channels_last)


class TestCropConsistency:
    def test_crop_pairs_replace_the_last_samples_by_second_crops_of_the_first(self) -> None:
        torch.manual_seed(0)
        crops, target = torch.rand(6, 3, 16, 16), torch.rand(6, 3, 32, 32)
        boxes = torch.tensor([[0.0, 0.0, 16.0, 16.0], [4.0, 4.0, 12.0, 12.0]]).repeat(3, 1)
        before = crops.clone()
        c, t, p = crop_pairs(crops, target, boxes, 2)
        assert p == 2 and c.shape == crops.shape and torch.equal(crops, before)  # the inputs are left alone
        assert torch.equal(c[:4], crops[:4]) and torch.equal(t[4:], target[:2]) and torch.equal(t[:4], target[:4])
        torch.testing.assert_close(c[4], crops[0], atol=1e-6, rtol=0)  # the whole crop: the same image
        zoom = torch.nn.functional.interpolate(crops[1:2, :, 4:12, 4:12], size=16, mode="bilinear",
                                               align_corners=False)
        assert (c[5] - zoom[0]).abs().mean() < 0.05  # the centre half, enlarged
        assert crop_pairs(crops, target, boxes, 8)[2] == 3  # at most half the batch

    def test_consistency_is_zero_for_equal_predictions_and_pulls_both_together(self) -> None:
        a = torch.full((2, 3, 32, 32), 1.0, requires_grad=True)
        b = torch.full((2, 3, 32, 32), 2.0, requires_grad=True)
        same = crop_consistency({32: torch.cat([a, a])}, 2, {"diffuse": 1.0})
        assert same.item() == 0.0
        apart = crop_consistency({16: torch.zeros(4, 3, 16, 16), 32: torch.cat([a, b])}, 2, {"diffuse": 1.0})
        apart.backward()
        assert apart > 0 and a.grad.abs().sum() > 0 and b.grad.abs().sum() > 0

    def test_consistency_has_no_gradient_along_a_shared_scale(self) -> None:
        torch.manual_seed(0)
        x = (torch.rand(4, 3, 32, 32) * mirror_ball_valid(32)).requires_grad_()
        loss = crop_consistency({32: x}, 2, BRDF_WEIGHTS)
        loss.backward()
        # scaling pair i (samples i and 2 + i) by c: d/dc loss at c = 1 is the sum of grad * x over both samples;
        # it is zero, so the term never darkens the two estimates together
        along = (x.grad * x.detach()).sum((1, 2, 3))
        assert loss > 0 and along.abs().min() > 1e-4  # each crop alone is pulled
        torch.testing.assert_close(along[:2] + along[2:], torch.zeros(2), atol=1e-6, rtol=0)

    @staticmethod
    def _default_step(**weights: float) -> dict:
        """One default step of a tiny model on 4 samples (2 crop pairs) with the loss weights ``weights``."""
        torch.manual_seed(0)
        model = _Tiny()
        batch = {"image": torch.randint(0, 256, (4, 3, 8, 8), dtype=torch.uint8),
                 "mirror_ball": torch.rand(4, 3, 32, 32) * mirror_ball_valid(32),
                 "second_crop": torch.tensor([[2.0, 2.0, 6.0, 6.0]]).repeat(4, 1)}
        config = TrainConfig(out="-", cache=("-",), batch=4, crop_pairs=2, **weights)
        runtime = RuntimeSettings(bf16=False, channels_last=True, workers=0)
        return Recipe().step(model=model, disc=None, opt_g=torch.optim.Adam(model.parameters()), opt_d=None,
                             batch=batch, device=torch.device("cpu"), config=config, runtime=runtime)

    @pytest.mark.parametrize(("weight", "column", "value"), [("lambda_crop", "crop", 2.0),
                                                              ("lambda_energy", "energy", 0.5)])
    def test_the_default_step_adds_each_weight_times_its_term(self, weight: str, column: str,
                                                               value: float) -> None:
        off, on = self._default_step(**{weight: 0.0}), self._default_step(**{weight: value})
        assert off[column] == 0 and on[column] > 0
        torch.testing.assert_close(on["loss"], on["rec"] + value * on[column])

    def test_the_colour_term_joins_with_its_weight(self) -> None:
        """Greyscale twins between the crop pairs' ends, with their term."""
        torch.manual_seed(0)
        model = _Tiny()
        batch = {"image": torch.randint(0, 256, (8, 3, 8, 8), dtype=torch.uint8),
                 "mirror_ball": torch.rand(8, 3, 32, 32) * mirror_ball_valid(32),
                 "second_crop": torch.tensor([[2.0, 2.0, 6.0, 6.0]]).repeat(8, 1)}
        config = TrainConfig(out="-", cache=("-",), batch=8, crop_pairs=2, lambda_crop=1.0, lambda_colour=3.0,
                             colour_pairs=2)
        runtime = RuntimeSettings(bf16=False, channels_last=True, workers=0)
        out = Recipe().step(model=model, disc=None, opt_g=torch.optim.Adam(model.parameters()), opt_d=None,
                            batch=batch, device=torch.device("cpu"), config=config, runtime=runtime)
        assert out["colour"] > 0
        torch.testing.assert_close(out["loss"], out["rec"] + out["crop"] + 3.0 * out["colour"])
        with pytest.raises(ValueCheckError, match="must fit in the batch"):
            TrainConfig(out="-", cache=("-",), batch=8, crop_pairs=2, lambda_crop=1.0, lambda_colour=1.0,
                        colour_pairs=3)

    def test_the_ablations_change_the_lighting_loss_only(self) -> None:
        full = self._default_step()
        finest = self._default_step(multi_scale=False)
        logl2 = self._default_step(loss="log_l2")
        parts = ("rec_diffuse", "rec_matte_silver", "rec_mirror")
        for k in parts:  # L_rec at 32 px is logged the same way by every variant
            torch.testing.assert_close(finest[k], full[k])
            torch.testing.assert_close(logl2[k], full[k])
        # without the multi-scale loss, rec is the 32 px scale's weighted sum alone
        torch.testing.assert_close(finest["rec"], sum(BRDF_WEIGHTS[k[4:]] * finest[k] for k in parts))
        assert full["rec"] > finest["rec"] > 0
        # log-L2 in place of L_rec: _Tiny's 16 and 32 px lightings against the truth's pyramid
        torch.manual_seed(0)
        model = _Tiny()
        crops = torch.randint(0, 256, (4, 3, 8, 8), dtype=torch.uint8).float() / 255
        target = torch.rand(4, 3, 32, 32) * mirror_ball_valid(32)
        with torch.no_grad():
            pred = model(crops)
        expected = log_l2_loss(pred, mirror_ball_pyramid(target, tuple(pred)))
        torch.testing.assert_close(logl2["rec"], expected)
        torch.testing.assert_close(logl2["loss"], logl2["rec"])

    @pytest.mark.parametrize("weight", ["lambda_crop", "lambda_energy", "lambda_nll", "lambda_albedo"])
    def test_sipr_refuses_the_terms(self, weight: str) -> None:
        config = TrainConfig(out="-", cache=("-",), **{weight: 1.0})
        with pytest.raises(ValueCheckError, match="crop-consistency or energy"):
            kornia_ilum_sipr.recipe.SIPRRecipe().step(model=None, disc=None, opt_g=None, opt_d=None, batch={},
                                                      device=torch.device("cpu"), config=config,
                                                      runtime=RuntimeSettings(False, False, 0))


class TestTheScaleApart:
    @staticmethod
    def _step(model: nn.Module, **weights: float) -> dict:
        torch.manual_seed(0)
        crops = torch.rand(2, 3, 256, 256)
        target = (torch.rand(2, 3, 32, 32) + 0.5) * mirror_ball_valid(32)
        config = TrainConfig(out="-", cache=("-",), lambda_adv=0.0, **weights)
        runtime = RuntimeSettings(bf16=False, channels_last=False, workers=0)
        return train_step(model=model, disc=None, opt_g=torch.optim.SGD(model.parameters(), lr=0.0), opt_d=None,
                          crops=crops, target=target, config=config, runtime=runtime,
                          skin_tone=torch.tensor([2, 9]))

    def test_the_scale_leaves_l_rec_and_the_likelihood_learns_it(self) -> None:
        torch.manual_seed(0)
        model, _ = OursRecipe().build(spread_head=True)
        out = self._step(model, lambda_nll=0.5)
        assert out["nll"] > 0 and out["spread"] > 0
        torch.testing.assert_close(out["loss"], out["rec"] + 0.5 * out["nll"])
        with torch.no_grad():  # a brighter head: the same L_rec, another likelihood
            model.estimator.head.bias += 2.0
        brighter = self._step(model, lambda_nll=0.5)
        torch.testing.assert_close(brighter["rec"], out["rec"], rtol=1e-4, atol=1e-6)
        assert not torch.isclose(brighter["nll"], out["nll"])

    def test_the_albedo_task(self) -> None:
        torch.manual_seed(0)
        model, _ = OursRecipe().build(albedo_head=True)
        out = self._step(model, lambda_albedo=0.25)
        assert out["albedo"] > 0 and out["nll"] == 0
        torch.testing.assert_close(out["loss"], out["rec"] + 0.25 * out["albedo"])
        assert not any(k.startswith("albedo") for k in model.estimator.state_dict())  # training only

    def test_the_terms_need_their_heads(self) -> None:
        torch.manual_seed(0)
        model, _ = OursRecipe().build()
        with pytest.raises(ValueCheckError, match="spread head"):
            self._step(model, lambda_nll=1.0)
        with pytest.raises(ValueCheckError, match="albedo head"):
            self._step(model, lambda_albedo=1.0)


class TestColourConsistency:
    def test_twins_are_greyscale_with_a_grey_target_and_leave_the_crop_pairs_alone(self) -> None:
        torch.manual_seed(0)
        crops, target = torch.rand(10, 3, 8, 8), torch.rand(10, 3, 32, 32)
        c, t, p = colour_pairs(crops, target, 2, start=2)
        assert p == 2 and torch.equal(c[:6], crops[:6]) and torch.equal(c[8:], crops[8:])
        assert torch.equal(t[:6], target[:6]) and torch.equal(t[8:], target[8:])
        torch.testing.assert_close(c[6:8], greyscale(crops[2:4]))
        luminance = (target[2:4] * torch.tensor(LUMINANCE).view(1, 3, 1, 1)).sum(1, keepdim=True)
        torch.testing.assert_close(t[6:8], luminance.expand(2, 3, 32, 32))
        assert colour_pairs(crops, target, 9, start=2)[2] == 3  # at most what lies between the crop pairs

    def test_the_term_compares_main_lights_only(self) -> None:
        torch.manual_seed(0)
        light = torch.rand(4, 3, 32, 32) * mirror_ball_valid(32)
        same_shape = torch.cat([light[:2], 5.0 * light[:2]])  # the same lights, brighter: no term
        assert abs(float(colour_consistency({32: same_shape}, 2))) < 1e-6
        x = light.clone().requires_grad_()
        term = colour_consistency({32: x}, 2)
        term.backward()
        assert term > 0 and x.grad[:2].abs().sum() > 0 and x.grad[2:].abs().sum() > 0

    def test_with_a_teacher_only_the_twin_moves(self) -> None:
        torch.manual_seed(0)
        x = (torch.rand(4, 3, 32, 32) * mirror_ball_valid(32)).requires_grad_()
        term = colour_consistency({32: x}, 2, teacher=True)
        term.backward()
        torch.testing.assert_close(term, colour_consistency({32: x.detach()}, 2))  # the same value
        assert x.grad[:2].abs().sum() == 0 and x.grad[2:].abs().sum() > 0
