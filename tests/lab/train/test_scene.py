"""kornia_ilum_lab.train.scene: the scene branch's recipe trains, logs, exports and refuses what does not apply."""

from __future__ import annotations

import pytest
import safetensors.torch
import torch

import kornia_ilum_lab.train.recipes as recipes
from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.estimators.scene import SCENE_SIZE, SceneStrength
from kornia_ilum_lab.train import TrainConfig, read_log, train
from kornia_ilum_lab.train.recipes import get_recipe
from kornia_ilum_lab.train.scene import SceneRecipe, scene_batch, scene_nll, tone_slope
from tests.lab.train.helpers import small_data


def test_nll_is_lowest_at_the_error_and_the_spread_that_fit():
    truth = torch.zeros(4, 3)
    error = torch.full((4, 3), 0.5)
    at = {b: scene_nll(error, torch.full((4,), b), truth).item() for b in (0.25, 0.5, 1.0)}
    assert at[0.5] < at[0.25] and at[0.5] < at[1.0]  # the Laplace scale's optimum is the mean absolute error


def test_a_batch_is_cut_to_its_photo_windows():
    """``frame_window``: each frame is cut to its window and letterboxed as scene_input does a photo of that
    shape; without windows, the whole square frame."""
    frames = torch.full((2, 3, 16, 16), 128, dtype=torch.uint8)
    batch = {"frame": frames, "frame_box": torch.tensor([[4.0, 4, 8, 8], [6, 6, 10, 10]]),
             "mirror_ball": torch.ones(2, 3, 8, 8),
             "frame_window": torch.tensor([[0.0, 2, 16, 14], [4, 0, 13, 16]])}  # 16 x 12 and 9 x 16
    x, truth = scene_batch(batch, torch.device("cpu"))
    assert x.shape == (2, 5, 16, 16) and truth.shape == (2, 3)
    extent = x[:, 4]
    assert extent[0].sum() == 16 * 12 and bool((extent[0, :2] == 0).all())  # padded above and below
    assert extent[1].sum() == 9 * 16 and bool((extent[1][:, :3] == 0).all())  # padded left and right
    assert x[0, 3].sum() == 16 and x[1, 3].sum() == 16  # the face's box moved with the window, 4 x 4
    del batch["frame_window"]
    whole, _ = scene_batch(batch, torch.device("cpu"))
    assert bool((whole[:, 4] == 1).all())


def test_registered_and_strict():
    assert isinstance(get_recipe("scene"), SceneRecipe)
    with pytest.raises(ValueCheckError, match="one model option is tone_blind"):
        SceneRecipe().build(spread_head=True)
    with pytest.raises(ValueCheckError, match="tone_blind"):
        SceneRecipe().build(tone_blind=-1.0)
    recipe = SceneRecipe()
    recipe.build(tone_blind=10)
    assert recipe.tone_blind == 10.0 and SceneRecipe().tone_blind == 0.0


def test_tone_slope_is_zero_for_errors_that_do_not_follow_the_tone():
    tones = torch.tensor([1, 2, 3, 4, 5, 6, 7, 8, -1])
    flat = torch.tensor([0.3, -0.2, 0.1, 0.3, -0.2, 0.1, 0.3, -0.2, 5.0])  # no trend; the unknown tone ignored
    falling = -0.1 * tones.double()
    assert abs(tone_slope(flat.double() - flat[:8].double().mean(), tones).item()) < 0.08
    assert tone_slope(falling, tones).item() == pytest.approx(-0.1 * tones[:8].double().std(unbiased=False).item())
    assert tone_slope(torch.ones(3), torch.tensor([-1, -1, 4])).item() == 0.0


@pytest.mark.slow  # the tiny_cache fixture renders with Mitsuba; the test trains
def test_trains_logs_and_exports(tiny_cache, tmp_path, monkeypatch):
    monkeypatch.setattr(recipes, "PROBE_SIZE", 2)
    threads = torch.get_num_threads()
    config = TrainConfig(estimator="scene", out=str(tmp_path / "run"), cache=(str(tiny_cache),), steps=2, batch=2,
                         workers=0, threads=1, bf16=False, log_every=1, data={**small_data(), "surroundings": 0.5}, model={"tone_blind": 1.0})
    try:
        summary = train(config)
        again = train(config)  # complete: resumed at its end, the same file
        with pytest.raises(ValueCheckError, match="own NLL"):
            train(TrainConfig(estimator="scene", out=str(tmp_path / "fit"), cache=(str(tiny_cache),), steps=0,
                              init=str(tmp_path / "run" / "scene.safetensors"), fit_spread=4, workers=0,
                              threads=1, data=small_data()))
    finally:
        torch.set_num_threads(threads)
    w = summary["weights"]
    assert w["file"] == "scene.safetensors" and w["dtype"] == "float32" and w["spread_probe"] > 0
    assert again["weights"]["sha256"] == w["sha256"]
    net = SceneStrength()
    net.load_state_dict(safetensors.torch.load_file(tmp_path / "run" / "scene.safetensors"), strict=True)
    rows = read_log(tmp_path / "run")
    assert len(rows) == 2 and "spread" in rows[0] and "tone" in rows[0] and "rec_diffuse" not in rows[0]
    assert all(r["rec"] > 0 for r in rows)
    assert summary["config"]["estimator"] == "scene" and SCENE_SIZE == 128
