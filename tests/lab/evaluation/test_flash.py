"""The real-flash check: flash directions, reading a folder by its names, the error of a known estimate."""

from __future__ import annotations

import argparse
import contextlib
import io
import math
from pathlib import Path

import numpy as np
import pytest
import torch

from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.geometry import direction_to_mirror_ball, uv_to_pixel
from kornia_ilum_lab.evaluation.cli import run_evaluate
from kornia_ilum_lab.evaluation.measures import angle_degrees, dominant_direction
from kornia_ilum_lab.evaluation.flash import (
    flash_crops,
    flash_direction,
    flash_markdown,
    load_flash_set,
    real_flash_check,
)

FLASHES = [(0, 0), (35, 40), (-35, 40), (70, -20), (-70, -20), (110, 15), (0, -35), (-10, 10)]


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    """Three people under eight flashes: noise photos in the database's names, and a file that is not one."""
    cv2 = pytest.importorskip("cv2")
    root = tmp_path_factory.mktemp("flash")
    rng = np.random.default_rng(0)
    for person in ("yaleB01", "yaleB02", "yaleB03"):
        (root / person).mkdir()
        for a, e in FLASHES:
            name = f"{person}_P00A{a:+04d}E{e:+03d}.pgm"
            cv2.imwrite(str(root / person / name), rng.integers(20, 200, (48, 40), dtype=np.uint8))
    (root / "README.md").write_text("not a photograph")
    return root


def test_flash_direction_in_the_projects_frame() -> None:
    d = flash_direction(torch.tensor([0.0, 90.0, 0.0]), torch.tensor([0.0, 0.0, 90.0]))
    torch.testing.assert_close(d, torch.tensor([[0.0, 0, 1], [-1.0, 0, 0], [0.0, 1, 0]], dtype=torch.float64),
                               atol=1e-12, rtol=0)


def test_load_reads_the_names(folder: Path) -> None:
    found = load_flash_set(folder)
    assert len(found) == 3 * len(FLASHES) and set(found.subjects) == {"yaleB01", "yaleB02", "yaleB03"}
    assert sorted(set(found.people)) == [0, 1, 2]
    assert found.axis_angle.min() == 0 and found.axis_angle.max() > 100
    with pytest.raises(ValueCheckError, match="does not exist"):
        load_flash_set(folder / "missing")
    with pytest.raises(ValueCheckError, match="no photograph"):
        load_flash_set(Path(__file__).parent)


class Straight:
    """An estimator whose main light is always straight ahead (+Z, from the camera)."""

    def __call__(self, crops: torch.Tensor) -> torch.Tensor:
        ball = torch.zeros(len(crops), 3, 32, 32)
        col, row = uv_to_pixel(direction_to_mirror_ball(torch.tensor([0.0, 0.0, 1.0])), 32).long().tolist()
        ball[..., row, col] = 10.0
        return ball * (1 + crops.mean((1, 2, 3)))[:, None, None, None]


def test_the_error_of_a_frontal_estimate_is_the_flashs_angle_to_the_axis(folder: Path) -> None:
    flash_set = load_flash_set(folder)
    crops, fell_back = flash_crops(flash_set, "none", size=32)
    assert crops.shape == (len(flash_set), 3, 32, 32) and not fell_back.any()
    out = real_flash_check(Straight(), flash_set, crops=crops, fell_back=fell_back)
    main = dominant_direction(Straight()(crops[:1]))  # the centre pixel's direction: within 5 degrees of +Z
    expected = angle_degrees(main.expand(len(flash_set), 3), flash_set.directions)
    torch.testing.assert_close(out["error"], expected)
    assert float((expected - flash_set.axis_angle).abs().max()) < 6
    table = out["table"]
    assert table["people"] == 3 and table["photos"] == 24 and table["no_direction"] == 0
    front = table["direction"]["within 25"]
    assert front["count"] == 3 * 2  # (0, 0) and (-10, 10)
    elevation = torch.rad2deg(torch.asin(main[0, 1])).item()  # the straight estimate's own elevation
    assert front["elevation_bias"] == pytest.approx(elevation - 5.0, abs=0.01)  # the median of -0 and -10
    assert 0 <= front["azimuth_error"] < 12
    sided = flash_set.directions[:, 0].abs() >= math.sin(math.radians(10))
    agree = (flash_set.directions[sided, 0] > 0) == (main[0, 0] > 0)
    assert table["left_right"]["count"] == int(sided.sum()) == 15  # the five flashes 10 degrees or more aside
    assert table["left_right"]["rate"] == pytest.approx(float(agree.double().mean()))
    spread = table["energy_spread"]
    assert spread["flashes"] == len(FLASHES) and "frontal" in spread
    lines = flash_markdown({"straight": table})
    assert lines[-1].startswith("| straight | ")


def test_the_cli_without_a_cache_runs_the_real_flash_checks(folder: Path, tmp_path: Path) -> None:
    args = argparse.Namespace(flash=str(folder), estimator=["uniform"], detector="none", out=str(tmp_path / "o"))
    with contextlib.redirect_stdout(io.StringIO()) as out:
        assert run_evaluate(args) == 0
    text = out.getvalue()
    assert "Real-flash check" in text and "Colour check" in text and "| uniform |" in text
    assert (tmp_path / "o" / "evaluation.md").read_text().startswith("# Real photographs")
    with pytest.raises(ValueCheckError, match="needs --flash"):
        run_evaluate(argparse.Namespace(cache=["x"], checks=("flash",)))
