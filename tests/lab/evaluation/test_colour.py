"""The colour check: an estimator that reads the shading keeps its main light under every look; one that reads
the colours does not."""

from __future__ import annotations

import pytest
import torch

from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.geometry import direction_to_mirror_ball, uv_to_pixel
from kornia_ilum_lab.evaluation.colour import COLOUR_LOOKS, colour_check, colour_markdown
from kornia_ilum_lab.synth.colour_looks import greyscale


def _ball(direction: torch.Tensor) -> torch.Tensor:
    """A light in each direction ``(B, 3)``."""
    ball = torch.zeros(len(direction), 3, 32, 32)
    for i, d in enumerate(direction):
        col, row = uv_to_pixel(direction_to_mirror_ball(d / d.norm()), 32).long().tolist()
        ball[i, :, row, col] = 10.0
    return ball


def shading(crops: torch.Tensor) -> torch.Tensor:
    """Reads the light from the grey image's left-right gradient."""
    g = greyscale(crops)[:, 0]
    w = g.shape[-1] // 2
    x = g[..., w:].mean((1, 2)) - g[..., :w].mean((1, 2))
    return _ball(torch.stack([4 * x, torch.full_like(x, 0.3), torch.ones_like(x)], -1))


def colours(crops: torch.Tensor) -> torch.Tensor:
    """Reads the light from the balance of red and blue."""
    x = crops[:, 0].mean((1, 2)) - crops[:, 2].mean((1, 2))
    return _ball(torch.stack([4 * x, torch.full_like(x, 0.3), torch.ones_like(x)], -1))


@pytest.fixture(scope="module")
def portraits() -> torch.Tensor:
    g = torch.Generator().manual_seed(0)
    ramp = torch.linspace(0.2, 0.8, 32).view(1, 1, 1, 32)
    tint = torch.rand(6, 3, 1, 1, generator=g) * 0.4 + 0.3
    return (ramp * tint * 1.5).clamp(0, 1).expand(6, 3, 32, 32).contiguous()


def test_greyscale_does_not_move_a_shading_reader(portraits: torch.Tensor) -> None:
    out = colour_check(shading, portraits, looks=["greyscale"], subjects=[0, 0, 1, 1, 2, 2])
    row = out["table"]["greyscale"]
    assert row["angle"]["median"] < 0.5 and row["angle_ci"] is not None and row["no_direction"] == 0


def test_greyscale_moves_a_colour_reader(portraits: torch.Tensor) -> None:
    out = colour_check(colours, portraits, looks=["greyscale", "warm"])
    assert out["table"]["greyscale"]["angle"]["median"] > 5
    assert out["angle"]["warm"].shape == (6,) and out["ratio"]["warm"].shape == (6,)


def test_every_look_runs_and_is_reported(portraits: torch.Tensor) -> None:
    out = colour_check(shading, (portraits * 255).round().to(torch.uint8))
    assert list(out["table"]) == list(COLOUR_LOOKS)
    lines = colour_markdown({"shading": {"eval": out["table"]}})
    assert any(line.startswith("| shading | eval crops |") for line in lines)


def test_bad_arguments(portraits: torch.Tensor) -> None:
    with pytest.raises(ValueCheckError, match="unknown looks"):
        colour_check(shading, portraits, looks=["vivid"])
    with pytest.raises(ValueCheckError, match="subjects"):
        colour_check(shading, portraits, subjects=[0, 1])
