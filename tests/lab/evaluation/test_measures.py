"""kornia_ilum_lab.evaluation.measures: the dominant direction, angles, the estimator passes and quantiles."""

from __future__ import annotations

import math

import torch

from kornia_ilum.geometry import direction_to_mirror_ball, mirror_ball_valid, uv_to_pixel
from kornia_ilum_lab.evaluation.measures import (
    angle_degrees,
    as_floats,
    dominant_direction,
    estimates,
    median_of,
    quantiles,
)

VALID = mirror_ball_valid(32).float()


def source(direction: tuple[float, float, float], value: float = 100.0) -> torch.Tensor:
    ball = torch.zeros(1, 3, 32, 32)
    col, row = uv_to_pixel(direction_to_mirror_ball(torch.tensor(direction)), 32).long().tolist()
    ball[..., row, col] = value
    return ball


def test_direction() -> None:
    for d in ((0.0, 0.0, 1.0), (0.6, 0.8, 0.0), (-0.8, 0.0, -0.6)):
        got = dominant_direction(source(d))[0]
        assert float(got @ torch.tensor(d)) > 0.99 and math.isclose(float(got.norm()), 1.0, rel_tol=1e-6)
    both = source((1.0, 0.0, 0.0)) + source((0.0, 1.0, 0.0))
    assert float(dominant_direction(both)[0] @ torch.tensor([0.7071, 0.7071, 0.0])) > 0.99
    assert dominant_direction(torch.zeros(1, 3, 32, 32)).abs().max() == 0
    assert dominant_direction(torch.ones(1, 3, 32, 32) * VALID).abs().max() == 0


def test_angles() -> None:
    a = torch.tensor([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0], [0, 0, 0]])
    b = torch.tensor([[1.0, 0, 0], [0, -1.0, 0], [0, 1.0, 0], [0, 0, 1.0]])
    got = angle_degrees(a, b)
    torch.testing.assert_close(got[:3], torch.tensor([0.0, 180.0, 90.0], dtype=torch.float64), atol=1e-4, rtol=0)
    assert math.isnan(float(got[3]))  # no direction


def test_estimates_in_batches() -> None:
    def light_up(crops: torch.Tensor) -> torch.Tensor:
        return source((0.0, 1.0, 0.0)).expand(len(crops), -1, -1, -1) * crops.mean((1, 2, 3))[:, None, None, None]

    crops = torch.rand(5, 3, 8, 8)
    energy, direction, spread = estimates(light_up, iter([crops[:3], crops[3:]]), directions=True)
    assert energy.shape == (5,) and energy.dtype == torch.float64 and spread is None
    torch.testing.assert_close(energy / energy[0], (crops.mean((1, 2, 3)) / crops[0].mean()).double())
    assert bool((direction[:, 1] > 0.99).all())
    codes = torch.full((1, 3, 2, 2), 255, dtype=torch.uint8)
    assert as_floats(codes).dtype == torch.float32 and float(as_floats(codes).max()) == 1.0


def test_quantiles_leave_out_what_is_not_finite() -> None:
    q = quantiles(torch.tensor([1.0, 2.0, 3.0, float("nan"), float("inf")]))
    assert q == {"median": 2.0, "q25": 1.5, "q75": 2.5, "count": 3}
    assert quantiles(torch.tensor([float("nan")]))["median"] is None and median_of(torch.tensor([4.0])) == 4.0
