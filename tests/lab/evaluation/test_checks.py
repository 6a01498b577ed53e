"""kornia_ilum_lab.evaluation.checks: energy, the transfer check, exposure equivariance, crop
stability, the real photos' crops and run_checks."""

from __future__ import annotations

import math

import numpy as np
import pytest
import skimage.data
import torch

from kornia_ilum.color import srgb_to_linear
from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum_lab.evaluation import (
    BACKGROUNDS,
    CHECKS,
    EXPOSURE_FACTORS,
    INTERVAL_RATIOS,
    SPREAD_NOMINAL,
    check_runner,
    composite_background,
    crop_stability,
    darken,
    default_photos,
    evaluate,
    exposure_equivariance,
    face_crops,
    jitter_boxes,
    run_checks,
    spread_calibration,
    transfer_check,
)
from kornia_ilum.estimators import LightingEstimate
from kornia_ilum.geometry import direction_to_mirror_ball, mirror_ball_valid, uv_to_pixel
from kornia_ilum.io import write_ldr
from kornia_ilum.metrics import lighting_energy

VALID = mirror_ball_valid(32).float()


def constant(crops: torch.Tensor) -> torch.Tensor:
    """An estimator that ignores its input: uniform radiance 2 (energy 8 pi)."""
    return torch.full((len(crops), 3, 32, 32), 2.0) * VALID


def brightness(crops: torch.Tensor) -> torch.Tensor:
    """An estimator proportional to the crop's mean linear value (energy 4 pi times it)."""
    return VALID.expand(3, 32, 32) * srgb_to_linear(crops).mean((1, 2, 3))[:, None, None, None]


def source(direction: tuple[float, float, float], value: float = 100.0) -> torch.Tensor:
    ball = torch.zeros(1, 3, 32, 32)
    col, row = uv_to_pixel(direction_to_mirror_ball(torch.tensor(direction)), 32).long().tolist()
    ball[..., row, col] = value
    return ball


def fixed_light(crops: torch.Tensor) -> torch.Tensor:
    """A crop-invariant estimator with a direction: a small source up-left, whatever the crop."""
    return source((-0.6, 0.8, 0.0)).expand(len(crops), -1, -1, -1)


def _median(x: torch.Tensor) -> float:
    return float(torch.quantile(x.double(), 0.5))


class TestEnergyAndDirection:
    def test_energy(self) -> None:
        torch.testing.assert_close(lighting_energy(torch.ones(2, 3, 32, 32) * VALID),
                                   torch.full((2,), 4 * math.pi), rtol=1e-6, atol=0)
        rgb = torch.rand(3, 3, 32, 32) * VALID
        torch.testing.assert_close(lighting_energy(rgb * 3), 3 * lighting_energy(rgb))
        channel = torch.zeros(1, 3, 32, 32)
        channel[:, 0] = VALID  # red only: a third of the mean
        torch.testing.assert_close(lighting_energy(channel), torch.tensor([4 * math.pi / 3]))
        ones = torch.ones(1, 3, 32, 32)
        assert lighting_energy(ones)[0] == lighting_energy(ones * VALID)[0]  # the invalid pixels count for 0


class TestTransfer:
    def test_composite(self) -> None:
        x = torch.randint(0, 256, (2, 3, 4, 4), dtype=torch.uint8)
        a = torch.randint(0, 256, (2, 1, 4, 4), dtype=torch.uint8)
        got = composite_background(x, a, 0.5)
        torch.testing.assert_close(got, x.float() / 255 * (a.float() / 255) + (1 - a.float() / 255) * 0.5)
        with pytest.raises(ValueCheckError):
            composite_background(x, a, 2.0)

    def test_constant_energy(self, eval_set) -> None:
        out = transfer_check(constant, eval_set)
        truth = lighting_energy(eval_set.mirror_ball.double())
        torch.testing.assert_close(out["energy"]["true"], truth)
        for k in ("with", "black", "grey"):
            torch.testing.assert_close(out["energy"][k], torch.full_like(truth, 8 * math.pi))
        tones = torch.tensor(eval_set.skin_tone)
        for group, row in out["table"].items():
            m = torch.ones_like(tones, dtype=torch.bool) if group == "all" else tones == int(group)
            assert row["count"] == int(m.sum())
            expected = _median(8 * math.pi / truth[m])
            for key in ("with/true", "black/true", "grey/true"):
                assert math.isclose(row[key], expected, rel_tol=1e-9)
            assert row["black/with"] == row["grey/with"] == 1.0
        assert set(out["table"]) == {"all", *(str(t) for t in set(eval_set.skin_tone))}

    def test_ratios_are_those_of_the_composites(self, eval_set) -> None:
        out = transfer_check(brightness, eval_set, batch_size=5)
        x, a = eval_set.images.float() / 255, eval_set.alpha.float() / 255
        energy = {"with": x}
        energy.update({name: x * a + (1 - a) * v for name, v in BACKGROUNDS.items()})
        energy = {k: 4 * math.pi * srgb_to_linear(v).double().mean((1, 2, 3)) for k, v in energy.items()}
        for k in ("with", "black", "grey"):
            torch.testing.assert_close(out["energy"][k], energy[k], rtol=1e-5, atol=0)
        expected = _median(energy["black"] / energy["with"])
        assert math.isclose(out["table"]["all"]["black/with"], expected, rel_tol=1e-5)
        assert out["table"]["all"]["black/with"] < 1  # the background was brighter than black
        again = transfer_check(brightness, eval_set, prediction=brightness(x))  # the scores' pass reused
        assert math.isclose(again["table"]["all"]["grey/true"], out["table"]["all"]["grey/true"],
                            rel_tol=1e-5)

    def test_needs_the_matte(self, eval_set) -> None:
        import dataclasses  # only here

        with pytest.raises(ValueCheckError, match="matte"):
            transfer_check(constant, dataclasses.replace(eval_set, alpha=None))


class TestExposure:
    def test_darken(self) -> None:
        x = torch.rand(2, 3, 8, 8)
        torch.testing.assert_close(darken(x, 1.0), x, rtol=0, atol=1e-5)
        torch.testing.assert_close(srgb_to_linear(darken(x, 0.25)), 0.25 * srgb_to_linear(x), rtol=1e-4,
                                   atol=1e-6)
        with pytest.raises(ValueCheckError):
            darken(x, 0.0)

    def test_an_estimator_that_scales_with_the_photo(self, eval_set) -> None:
        out = exposure_equivariance(brightness, eval_set.images)
        assert set(out["table"]) == {f"{k:g}" for k in EXPOSURE_FACTORS}
        for row in out["table"].values():
            assert row["count"] == len(eval_set) and abs(row["median"] - 1) < 1e-4
            assert abs(row["q25"] - 1) < 1e-4 and abs(row["q75"] - 1) < 1e-4

    def test_an_estimator_that_ignores_the_exposure(self) -> None:
        out = exposure_equivariance(constant, torch.rand(3, 3, 16, 16), ks=(0.5, 0.1))
        assert math.isclose(out["table"]["0.5"]["median"], 2.0)  # 1 / k: no scaling at all
        assert math.isclose(out["table"]["0.1"]["median"], 10.0)
        with pytest.raises(ValueCheckError, match="ks"):
            exposure_equivariance(constant, torch.rand(3, 3, 16, 16), ks=(0.0,))


class TestPhotos:
    def test_face_crops(self, tmp_path) -> None:
        photos = default_photos()
        assert list(photos) == ["skimage.data.astronaut"]
        crops, names, skipped = face_crops(photos)
        assert crops.shape == (1, 3, 256, 256) and names == ["skimage.data.astronaut"] and skipped == {}
        assert 0 <= float(crops.min()) and float(crops.max()) <= 1
        path = tmp_path / "astronaut.png"
        write_ldr(path, torch.from_numpy(skimage.data.astronaut()).permute(2, 0, 1).float() / 255)
        flat = np.full((64, 64), 128, dtype=np.uint8)  # no face
        crops2, names2, skipped2 = face_crops([path, flat])
        assert names2 == [str(path)] and list(skipped2) == ["photo 1"] and "no face" in skipped2["photo 1"]
        assert (crops2 - crops).abs().mean() < 0.02  # the same crop, through an 8-bit PNG


class TestCrop:
    def test_jitter_boxes(self) -> None:
        nominal = torch.tensor([[100.0, 100.0, 200.0, 200.0], [0.0, 0.0, 120.0, 120.0]])
        g = torch.Generator().manual_seed(3)
        boxes = jitter_boxes(nominal, 64, height=300, width=300, generator=g)
        again = jitter_boxes(nominal, 64, height=300, width=300, generator=torch.Generator().manual_seed(3))
        assert torch.equal(boxes, again) and boxes.shape == (2, 64, 4)
        side = boxes[..., 2] - boxes[..., 0]
        torch.testing.assert_close(side, boxes[..., 3] - boxes[..., 1])
        assert (side >= (nominal[:, 2:3] - nominal[:, 0:1]) * math.exp(-0.15) - 1e-9).all()
        assert (side <= (nominal[:, 2:3] - nominal[:, 0:1]) * math.exp(0.15) + 1e-9).all()
        centre = 0.5 * (boxes[0, :, :2] + boxes[0, :, 2:])  # the first never touches the border
        assert ((centre - 150).abs() <= 0.10 * side[0, :, None] + 1e-9).all()
        assert (centre - 150).abs().max() > 5
        assert (boxes[1, :, :2] >= 0).all() and (boxes[..., 2:] <= 300).all()  # the second is shifted inside
        assert (jitter_boxes(nominal, 4, height=100, width=100)[..., 2:] <= 100 + 1e-9).all()  # and shrunk

    def test_a_crop_invariant_estimator_has_no_spread(self, context_set) -> None:
        out = crop_stability(fixed_light, context_set, jitters=3)
        for row in out["table"].values():
            assert row["std_log_energy"] == 0 and row["max_min_ratio"] == 1
            assert row["angle_deg"] == pytest.approx(0, abs=1e-3)
        assert out["table"]["all"]["count"] == len(context_set)
        assert out["boxes"].shape == (len(context_set), 3, 4)

    def test_spread_and_seed(self, context_set) -> None:
        out = crop_stability(brightness, context_set, jitters=3, seed=5, batch_size=4)
        assert out["table"]["all"]["std_log_energy"] > 0 and out["table"]["all"]["max_min_ratio"] > 1
        assert out["table"]["all"]["angle_deg"] is None  # a uniform lighting has no direction
        e = out["energy"]
        torch.testing.assert_close(out["per_portrait"]["max_min_ratio"], e.amax(1) / e.amin(1))
        torch.testing.assert_close(out["per_portrait"]["std_log_energy"], e.log().std(1))
        assert torch.equal(out["boxes"], crop_stability(constant, context_set, jitters=3, seed=5)["boxes"])
        other = crop_stability(constant, context_set, jitters=3, seed=6)
        assert not torch.equal(out["boxes"], other["boxes"])

    def test_needs_context_crops(self, eval_set, context_set) -> None:
        with pytest.raises(ValueCheckError, match="context"):
            crop_stability(constant, eval_set)
        with pytest.raises(ValueCheckError, match="at least 2"):
            crop_stability(constant, context_set, jitters=1)


class TestRunChecks:
    def test_tables(self, eval_set, context_set) -> None:
        photos = torch.rand(2, 3, 256, 256)
        checks = [c for c in CHECKS if c != "flash"]  # the real-flash check: tests/lab/evaluation/test_flash.py
        out = run_checks(brightness, eval_set, checks=checks, context_set=context_set, photos=photos,
                         jitters=2, colour_samples=6)
        assert set(out) == {*checks, "tone_spread", "seconds"} and set(out["seconds"]) == set(checks)
        assert set(out["exposure"]) == {"eval", "photos"} and out["exposure"]["photos"]["0.5"]["count"] == 2
        assert set(out["colour"]) == {"eval", "photos"}
        assert out["colour"]["eval"]["greyscale"]["angle"]["count"] + out["colour"]["eval"]["greyscale"][
            "no_direction"] == 6
        with pytest.raises(ValueCheckError, match="needs flash"):
            run_checks(constant, eval_set, checks=["flash"])
        transfer = run_checks(constant, eval_set, checks=["transfer"])
        assert set(transfer) == {"transfer", "tone_spread", "seconds"}
        with pytest.raises(ValueCheckError, match="unknown checks"):
            run_checks(constant, eval_set, checks=["speed"])
        with pytest.raises(ValueCheckError, match="context_set"):
            run_checks(constant, eval_set, checks=["crop"])

    def test_evaluate_runs_them_on_the_estimators(self, eval_set, context_set) -> None:
        runner = check_runner(eval_set, ["transfer", "crop"], context_set=context_set, jitters=2)
        results = evaluate(eval_set, ["uniform"], checks=runner)
        assert set(results["methods"]["uniform"]["checks"]) == {"transfer", "tone_spread", "crop", "seconds"}
        assert all("checks" not in results["methods"][o] for o in ("SH of GT", "mean of GT"))
        with pytest.raises(ValueCheckError, match="context_set"):
            check_runner(eval_set, ["crop"])
        with pytest.raises(ValueCheckError, match="unknown checks"):
            check_runner(eval_set, ["speed"])
        with pytest.raises(ValueCheckError, match="at least 2"):
            check_runner(eval_set, ["crop"], context_set=context_set, jitters=1)


class TestIntervalsAndSpread:
    def test_transfer_intervals_bracket_the_medians(self, eval_set) -> None:
        out = transfer_check(brightness, eval_set)
        for group, row in out["table"].items():
            for key in INTERVAL_RATIOS:
                low, high = row[f"{key}_ci"]
                assert low <= row[key] + 1e-12 and row[key] <= high + 1e-12, (group, key)
            assert row["subjects"] >= 1
        spread = out["tone_spread"]["with/true"]
        medians = [row["with/true"] for g, row in out["table"].items() if g != "all"]
        assert math.isclose(spread["ratio"], max(medians) / min(medians), rel_tol=1e-9)
        assert spread["interval"][0] >= 1.0 - 1e-12

    def test_spread_calibration(self, eval_set) -> None:
        truth = lighting_energy(eval_set.mirror_ball.double())
        error = torch.linspace(-1.9, 1.9, len(eval_set), dtype=torch.float64)

        def off(crops: torch.Tensor, start: list[int] = [0]) -> LightingEstimate:  # noqa: B006 (a counter)
            i = start[0]
            start[0] += len(crops)
            e = (truth[i : i + len(crops)] * error[i : i + len(crops)].exp()).float()
            ball = VALID.expand(len(crops), 3, 32, 32) * (e / (4 * math.pi))[:, None, None, None]
            return LightingEstimate(mirror_ball=ball, valid=VALID.bool(), log_energy_spread=torch.ones(len(crops)))

        out = spread_calibration(off, eval_set, batch_size=4)
        row = out["table"]["all"]
        inside = float((error.abs() <= 1 + 1e-6).double().mean())
        assert math.isclose(row["within_1"], inside, abs_tol=1e-9) and row["within_2"] == 1.0
        assert row["nominal_1"] == SPREAD_NOMINAL[1] and row["spread"] == 1.0
        assert row["within_1_ci"][0] <= row["within_1"] <= row["within_1_ci"][1]
        none = spread_calibration(constant, eval_set)
        assert none["table"] is None and "no log_energy_spread" in none["reason"]
