"""kornia_ilum_lab.train.calibration: the energy calibration at export, exact for ours, refused where a recipe
cannot scale its output, and a finished run re-exported with it trains nothing."""

from __future__ import annotations

import dataclasses

import pytest
import torch

import kornia_ilum_lab.train.recipes as recipes
from kornia_ilum.color import LUMINANCE
from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.estimators import OursEstimator
from kornia_ilum_lab.train import Recipe, TrainConfig, read_log, train
from kornia_ilum_lab.train.calibration import CALIBRATION_STREAM, calibrate_energy, energy_log_ratios
from kornia_ilum_lab.train.data import training_dataset
from kornia_ilum_lab.train.recipes import PROBE_STREAM, OursRecipe
from tests.lab.train.helpers import small_data, weights


@pytest.fixture
def dataset(tiny_cache, tmp_path):
    return training_dataset(TrainConfig(out=str(tmp_path / "run"), cache=(str(tiny_cache),), data=small_data()))


def test_the_stream_is_neither_a_training_nor_the_probe_stream() -> None:
    assert CALIBRATION_STREAM not in (PROBE_STREAM, 0, 1) and CALIBRATION_STREAM > 64


def test_ours_gain_is_exact_and_brings_the_median_ratio_to_one(dataset) -> None:
    torch.manual_seed(0)
    est = OursEstimator().eval()
    crops = torch.rand(2, 3, 256, 256)
    with torch.no_grad():
        before = est(crops).mirror_ball
    ratios = energy_log_ratios(est, dataset, 4, batch=3)  # two chunks: 3 + 1
    assert ratios.shape == (4, 3) and ratios.dtype == torch.float64 and torch.isfinite(ratios).all()

    result = calibrate_energy(est, OursRecipe(), dataset, 4)
    gain = torch.tensor(result["gain"])
    torch.testing.assert_close(gain, torch.exp(ratios.median(0).values).float())
    torch.testing.assert_close(torch.tensor(result["median_ratio_after"]), torch.ones(3),
                               rtol=1e-5, atol=0)
    with torch.no_grad():
        after = est(crops).mirror_ball
    torch.testing.assert_close(after, before * gain.view(1, 3, 1, 1), rtol=1e-5, atol=1e-30)  # no direction moves


def test_the_white_balance_alone_keeps_the_luminance(dataset) -> None:
    """``keep_luminance``: the gains are the energy's, over their luminance-weighted geometric mean."""
    torch.manual_seed(0)
    est = OursEstimator().eval()
    ratios = energy_log_ratios(est, dataset, 4)
    result = calibrate_energy(est, OursRecipe(), dataset, 4, keep_luminance=True)
    log_gain = torch.tensor(result["gain"], dtype=torch.float64).log()
    luminance = torch.tensor(LUMINANCE, dtype=torch.float64)
    assert abs(float(log_gain @ luminance)) < 1e-6
    full = ratios.median(0).values
    torch.testing.assert_close(log_gain, full - full @ luminance, rtol=0, atol=1e-6)
    with pytest.raises(ValueCheckError, match="calibrate_colour"):
        TrainConfig(out="x", cache=("c",), calibrate_energy=4, calibrate_colour=4)


def test_refusals(dataset) -> None:
    est = OursEstimator().eval()
    with pytest.raises(ValueCheckError, match="cannot scale"):
        Recipe().scale_output(est, torch.ones(3))
    with pytest.raises(ValueCheckError, match="positive integer"):
        energy_log_ratios(est, dataset, 0)
    with pytest.raises(ValueCheckError, match="calibrate_energy"):
        TrainConfig(out="x", cache=("c",), calibrate_energy=-1)


@pytest.mark.slow  # trains a step
def test_a_finished_run_exported_again_with_it_trains_nothing(tiny_cache, tmp_path, monkeypatch) -> None:
    monkeypatch.setattr(recipes, "PROBE_SIZE", 2)
    threads = torch.get_num_threads()
    config = TrainConfig(out=str(tmp_path / "run"), cache=(str(tiny_cache),), steps=1, batch=2, workers=0,
                         threads=1, bf16=False, log_every=1, data=small_data())
    calibrated = dataclasses.replace(config, calibrate_energy=4)
    assert calibrated.data_key() == config.data_key()  # the export only: the run resumes either way
    try:
        train(config)
        plain = weights(tmp_path / "run")
        summary = train(calibrated)
    finally:
        torch.set_num_threads(threads)
    assert len(read_log(tmp_path / "run")) == 1 and summary["steps"] == 1
    gain = torch.tensor(summary["energy_calibration"]["gain"])
    got = weights(tmp_path / "run")
    assert all(torch.allclose(got[k].float(), plain[k].float(), rtol=1e-3, atol=1e-3) for k in plain
               if k != "head.bias")
    torch.testing.assert_close(got["head.bias"].float(), plain["head.bias"].float() + gain.log(), atol=2e-3,
                               rtol=1e-3)  # both may be float16


class _Known(torch.nn.Module):
    """A toy estimator whose error in log energy is set by its input: ``|log E_pred - log E_true| = 2 v u``, ``v``
    a brightness its spread head sees (as ``log v``, with a feature of noise) and ``u`` an exponential draw it
    does not see: the best spread is ``b = 2 v``, and ``+-b`` then holds ``1 - 1/e`` of the portraits."""

    def __init__(self, truth: torch.Tensor) -> None:
        super().__init__()
        self.spread = torch.nn.Linear(2, 1)
        self.truth = truth

    def forward(self, crops):
        from types import SimpleNamespace

        v, u = crops[:, 0, 0, 0].clamp(min=1e-3), -torch.log(crops[:, 1, 0, 0].clamp(min=1e-3))
        self.spread(torch.stack([v.log(), torch.randn_like(v)], 1))  # the estimator's own call, which the fit hooks
        sign = torch.where(crops[:, 2, 0, 0] > 0.5, 1.0, -1.0)
        return SimpleNamespace(mirror_ball=torch.exp(2 * v * u * sign)[:, None, None, None] * self.truth)


class _Stream:
    """A dataset stand-in: ``samples(stream)`` yields portraits whose first pixel holds ``v``, ``U`` and a sign."""

    def __init__(self, truth: torch.Tensor) -> None:
        self.truth = truth

    def samples(self, stream: int):
        g = torch.Generator().manual_seed(stream)
        while True:
            image = (torch.rand(3, 4, 4, generator=g) * 255).round().to(torch.uint8)
            yield {"image": image, "mirror_ball": self.truth[0], "label": "indoor", "skin_tone": 5}


def test_fit_spread_learns_where_the_strength_is_uncertain() -> None:
    from kornia_ilum_lab.train.calibration import fit_spread

    torch.manual_seed(0)
    truth = torch.ones(1, 3, 8, 8)
    est = _Known(truth)
    report = fit_spread(est, _Stream(truth), samples=2048, batch=256)
    assert report["nll_after"] < report["nll_before"] and report["features"] == 2
    assert abs(report["coverage_shift"]) < 0.1  # Laplace-like errors: the likelihood's b is already calibrated
    w = est.spread.weight.detach()[0]  # log b = log 2 + log v: weight 1 on log v, none on the noise
    assert abs(float(w[0]) - 1.0) < 0.15 and abs(float(w[1])) < 0.1
    assert abs(report["within_one_spread"] - (1 - 1 / torch.e)) < 0.01  # moved to it exactly
    with pytest.raises(ValueCheckError, match="spread head"):
        fit_spread(torch.nn.Identity(), _Stream(truth), samples=4)
    with pytest.raises(ValueCheckError, match="positive integer"):
        fit_spread(est, _Stream(truth), samples=0)
    with pytest.raises(ValueCheckError, match="fit_spread"):
        TrainConfig(out="x", cache=("c",), fit_spread=-1)
    with pytest.raises(ValueCheckError, match="0 only with init"):
        TrainConfig(out="x", cache=("c",), steps=0)
    assert TrainConfig(out="x", cache=("c",), steps=0, init="w.safetensors").steps == 0
