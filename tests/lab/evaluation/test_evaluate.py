"""kornia_ilum_lab.evaluation.evaluate: the eval set, the oracles, the scores and the estimators' weights."""

from __future__ import annotations

import pytest
import safetensors.torch
import torch

from kornia_ilum.core.errors import MissingWeightsError, ValueCheckError
from kornia_ilum.core.files import sha256_file
from kornia_ilum.estimators import create_estimator
from kornia_ilum_lab.evaluation import (
    BRDF_NAMES,
    EVAL_SEED,
    ORACLES,
    build_eval_set,
    evaluate,
    fit_crops,
    load_checkpoint,
    load_estimator,
    oracle_predictions,
    score,
)
from kornia_ilum.metrics import relative_radiance
from kornia_ilum.sh import sh_project
from kornia_ilum_lab.synth.lightstage import subject_split
from tests.lab.evaluation.helpers import N


class TestEvalSet:
    def test_contents(self, eval_set, hdri) -> None:
        assert eval_set.images.shape == (N, 3, 256, 256) and eval_set.images.dtype == torch.uint8
        assert eval_set.mirror_ball.shape == (N, 3, 32, 32)
        assert all(subject_split(s) == "eval" for s in eval_set.subject_seed)
        assert "real:interior.exr" not in eval_set.source  # a train map never shows up
        d = eval_set.description
        assert d["samples"] == N and d["seed"] == EVAL_SEED and sum(d["labels"].values()) == N
        assert d["eval_maps"] == {str(hdri): {"forest.exr": "outdoor", "studio.exr": "indoor"}}
        assert set(d["skin_tones"]) <= {"3", "6", "9"} and len(d["subjects"]) == 3

    def test_deterministic(self, eval_set, caches, hdri) -> None:
        again = build_eval_set(caches, [hdri], samples=N, fields_per_chunk=2, lightings_per_field=4)
        assert torch.equal(again.images, eval_set.images) and torch.equal(again.mirror_ball, eval_set.mirror_ball)
        assert again.label == eval_set.label and again.source == eval_set.source

    def test_black_background_variant_is_the_same_portraits(self, eval_set, caches, hdri) -> None:
        black = build_eval_set(caches, [hdri], samples=N, fields_per_chunk=2, lightings_per_field=4,
                               background="black")
        assert black.description["background"] == "black" and eval_set.description["background"] == "environment"
        assert black.label == eval_set.label and black.subject_seed == eval_set.subject_seed
        assert black.source == eval_set.source
        assert not torch.equal(black.images, eval_set.images)
        # the same lighting up to the exposure, which meters the (now black) background too
        ratio = black.mirror_ball.sum((1, 2, 3)) / eval_set.mirror_ball.sum((1, 2, 3))
        rescaled = eval_set.mirror_ball * ratio[:, None, None, None]
        torch.testing.assert_close(black.mirror_ball, rescaled, rtol=1e-3, atol=1e-6)


    def test_matte(self, eval_set) -> None:
        alpha = eval_set.alpha
        assert alpha.shape == (N, 1, 256, 256) and alpha.dtype == torch.uint8
        assert alpha.max() == 255 and alpha.min() == 0  # the subject, and background around it
        assert eval_set.nominal_boxes is None and eval_set.description["context"] is None

    def test_context_crops_are_the_same_portraits_wider(self, eval_set, context_set) -> None:
        n = len(context_set)
        assert context_set.images.shape == (n, 3, 384, 384) and context_set.alpha.shape == (n, 1, 384, 384)
        assert context_set.label == eval_set.label[:n]
        assert context_set.subject_seed == eval_set.subject_seed[:n]
        assert context_set.source == eval_set.source[:n] and context_set.skin_tone == eval_set.skin_tone[:n]
        d = context_set.description
        assert d["context"] == 1.5 and d["size"] == 384 and d["crop"]["scale"] == 1.875
        # the tiny renders are smaller than 1.5 nominal crops: the context crop is the render, the nominal
        # crop a square inside it, larger than 256 pixels
        boxes = context_set.nominal_boxes
        side = boxes[:, 2] - boxes[:, 0]
        torch.testing.assert_close(side, boxes[:, 3] - boxes[:, 1])
        assert (side > 256).all() and (boxes[:, :2] >= -1e-4).all() and (boxes[:, 2:] <= 384 + 1e-4).all()
        # the ground truth differs from the usual set's by the exposure alone (the context crop is metered)
        ratio = context_set.mirror_ball.sum((1, 2, 3)) / eval_set.mirror_ball[:n].sum((1, 2, 3))
        rescaled = eval_set.mirror_ball[:n] * ratio[:, None, None, None]
        torch.testing.assert_close(context_set.mirror_ball, rescaled, rtol=1e-4, atol=1e-6)

    def test_context_one_is_the_nominal_crop(self, caches, hdri) -> None:
        one = build_eval_set(caches, [hdri], samples=4, fields_per_chunk=2, lightings_per_field=4,
                             context=1.0)
        assert one.images.shape[-1] == 256
        torch.testing.assert_close(one.nominal_boxes, torch.tensor([[0.0, 0.0, 256.0, 256.0]] * 4,
                                                                   dtype=torch.float64), atol=1e-3, rtol=0)
        with pytest.raises(ValueCheckError, match="context"):
            build_eval_set(caches, [hdri], samples=4, context=0.5)


class TestScores:
    def test_oracles(self) -> None:
        gt = torch.rand(3, 3, 32, 32) * 2
        out = oracle_predictions(gt)
        assert set(out) == set(ORACLES)
        assert relative_radiance(out["mean of GT"], gt).abs().max() < 1e-5
        assert relative_radiance(out["SH of GT"], gt).abs().max() < 1e-3
        torch.testing.assert_close(sh_project(out["SH of GT"]), sh_project(gt), atol=1e-4, rtol=1e-4)
        sun = torch.zeros(1, 3, 32, 32)
        sun[..., 16, 5] = 1000.0
        assert oracle_predictions(sun)["SH of GT"].min() < 0  # unclamped: the ringing stays negative

    def test_score_shapes(self) -> None:
        gt = torch.rand(4, 3, 32, 32)
        s = score(gt * 0.5, gt)
        assert all(s[b].shape == (4,) for b in BRDF_NAMES) and s["relative_radiance"].shape == (4, 3)
        torch.testing.assert_close(s["relative_radiance"], torch.full((4, 3), 0.5))


def _checkpoint(path):
    net = create_estimator("ours", pretrained=False)
    safetensors.torch.save_file({k: v.contiguous() for k, v in net.state_dict().items()}, str(path))
    return net


class TestFitCrops:
    class Sized:
        def __init__(self, size: int) -> None:
            self.info = type("Info", (), {"input_size": size})

    def test_crops_at_the_estimators_size_pass_unchanged(self) -> None:
        crops = torch.rand(2, 3, 16, 16)
        assert fit_crops(self.Sized(16), crops) is crops and fit_crops(object(), crops) is crops

    def test_a_resize_is_crop_faces_on_the_whole_crop(self) -> None:
        from kornia_ilum.detection import crop_faces

        crops = torch.rand(3, 3, 16, 16)
        out = fit_crops(self.Sized(8), crops)
        assert out.shape == (3, 3, 8, 8) and 0.0 <= out.min() and out.max() <= 1.0
        whole = torch.tensor([[0.0, 0.0, 16.0, 16.0]])
        torch.testing.assert_close(out[1], crop_faces(crops[1], whole, size=8)[0])


class TestWeights:
    def test_weights_checkpoint(self, tmp_path) -> None:
        path = tmp_path / "ckpt.safetensors"
        _checkpoint(path)
        loaded = load_estimator("ours", path)
        assert not loaded.training
        with pytest.raises(MissingWeightsError):
            load_estimator("ours", tmp_path / "missing.safetensors")
        with pytest.raises(ValueCheckError, match="safetensors"):
            load_estimator("ours", tmp_path / "ckpt.pt")

    def test_a_checkpoint_is_loaded_with_its_sha256(self, tmp_path) -> None:
        """A user's file goes through the SHA-256 path of the shipped weights, which returns its digest."""
        path = tmp_path / "ckpt.safetensors"
        net = _checkpoint(path)
        loaded, digest = load_checkpoint("ours", path)
        assert digest == sha256_file(path) and not loaded.training
        assert all(torch.equal(a, b) for a, b in zip(net.state_dict().values(), loaded.state_dict().values(),
                                                       strict=True))
        with pytest.raises(ValueError, match="unknown estimator 'nope'"):
            load_checkpoint("nope", path)

    def test_evaluate_records_the_sha256_of_a_weight_file(self, eval_set, tmp_path) -> None:
        path = tmp_path / "ckpt.safetensors"
        _checkpoint(path)
        results = evaluate(eval_set, ["uniform"], weights={"ours": path}, oracles=False)
        assert set(results["methods"]) == {"uniform", "ours@ckpt.safetensors"}
        assert results["methods"]["ours@ckpt.safetensors"]["sha256"] == sha256_file(path)
        assert "sha256" not in results["methods"]["uniform"]  # nothing to record: no weight file
        assert results["skipped"] == {}

    def test_several_files_of_one_class_are_all_scored(self, eval_set, tmp_path) -> None:
        (tmp_path / "b").mkdir()
        first, second = tmp_path / "a.safetensors", tmp_path / "c.safetensors"
        same_name = tmp_path / "b" / "a.safetensors"
        for path in (first, second, same_name):
            _checkpoint(path)
        results = evaluate(eval_set, [], weights=[("ours", first), ("ours", second)], oracles=False)
        assert set(results["methods"]) == {"ours@a.safetensors", "ours@c.safetensors"}
        with pytest.raises(ValueCheckError, match="different names"):
            evaluate(eval_set, [], weights=[("ours", first), ("ours", same_name)], oracles=False)


def test_evaluate_scores_each_estimator_with_test_time_augmentation_too(eval_set) -> None:
    """``tta=N`` adds ``name+ttaN``: the wrapped estimator's scores and checks, beside the plain ones."""
    seen = []
    results = evaluate(eval_set, ["uniform"], oracles=False, tta=2,
                       checks=lambda model, pred: seen.append(type(model).__name__) or {"n": len(pred)})
    assert set(results["methods"]) == {"uniform", "uniform+tta2"}
    assert seen[1] == "TestTimeAugmented" and results["methods"]["uniform+tta2"]["checks"] == {"n": N}
    with pytest.raises(ValueCheckError, match="tta"):
        evaluate(eval_set, ["uniform"], oracles=False, tta=0)
