"""kornia_ilum.sh.dominant: the main light of maps with a known sun (direction, solid angle, irradiance), the
ambient SH of the rest, nothing lost between the two, and the refusals."""

from __future__ import annotations

import math

import pytest
import torch

from kornia_ilum.core.errors import NonFiniteError, ShapeError, ValueCheckError
from kornia_ilum.geometry import (
    latlong_directions,
    latlong_solid_angles,
    latlong_to_mirror_ball,
    mirror_ball_solid_angles,
    mirror_ball_valid,
)
from kornia_ilum.sh import SplitDominantLight, dominant_light, sh_project

SKY = torch.tensor([0.2, 0.3, 0.5], dtype=torch.float64)
SUN = torch.tensor([3000.0, 2600.0, 2000.0], dtype=torch.float64)
RADIUS = 3.0  # the sun's angular radius in degrees: a few pixels of a 32-pixel ball


def _sky_with_sun(direction: torch.Tensor, height: int = 256) -> tuple[torch.Tensor, torch.Tensor]:
    """A 32 x 32 mirror ball of a uniform sky and a disc sun toward ``direction``, made from a fine lat-long
    map (energy-conserving), and the sun's true irradiance ``(3,)``."""
    dirs = latlong_directions(height, dtype=torch.float64)  # (H, 2H, 3)
    omega = latlong_solid_angles(height, dtype=torch.float64)  # (H, 2H)
    disc = (dirs @ (direction / direction.norm())) >= math.cos(math.radians(RADIUS))
    latlong = SKY[:, None, None] + SUN[:, None, None] * disc
    truth = SUN * float((disc * omega).sum())
    return latlong_to_mirror_ball(latlong[None], 32), truth


@pytest.mark.parametrize("direction", [(0.0, 0.7, 0.7), (0.8, 0.2, -0.3), (-0.5, 0.6, 0.4), (0.1, -0.2, 0.95)])
def test_a_known_sun_is_found_with_its_irradiance_and_the_sky_is_the_ambient(direction) -> None:
    direction = torch.tensor(direction, dtype=torch.float64)
    ball, truth = _sky_with_sun(direction)
    light = dominant_light(ball)
    cosine = float(light.direction[0] @ (direction / direction.norm()))
    assert math.degrees(math.acos(min(cosine, 1.0))) < 3.0  # a 32-pixel ball's pixels span 5 to 11 degrees
    torch.testing.assert_close(light.irradiance[0], truth, rtol=0.03, atol=0.0)
    torch.testing.assert_close(light.color[0], truth / float(truth @ truth.new_tensor((0.212671, 0.71516, 0.072169))),
                               rtol=0.01, atol=0.0)
    assert 0.0 < float(light.solid_angle[0]) < 0.1
    sky = sh_project(SKY[None, :, None, None].expand(1, 3, 32, 32) * mirror_ball_valid(32))
    # the ambient's integral is the sky's, plus what the sun left in pixels below the threshold: within 1 % of
    # the sun's own irradiance (the sun carries 10 times the sky's energy)
    leftover = (light.ambient_sh[0, 0] - sky[0, 0]) * 2 * math.sqrt(math.pi)
    assert bool((leftover.abs() <= 0.01 * truth).all())
    # nothing lost: the light's irradiance plus the ambient's integral is the map's integral
    total = (ball * mirror_ball_solid_angles(32, dtype=torch.float64)).sum((-2, -1))[0]
    ambient_integral = light.ambient_sh[0, 0] * 2 * math.sqrt(math.pi)  # integral = c00 / Y00
    torch.testing.assert_close(light.irradiance[0] + ambient_integral, total, rtol=2e-3, atol=0.0)


def test_no_light_in_black_or_uniform_lighting_and_a_batch_is_per_item() -> None:
    black = torch.zeros(1, 3, 32, 32)
    uniform = torch.ones(1, 3, 32, 32) * mirror_ball_valid(32)
    ball, _ = _sky_with_sun(torch.tensor([0.0, 1.0, 0.0], dtype=torch.float64))
    light = dominant_light(torch.cat([black, uniform, ball.float()]))
    assert light.direction[:2].abs().max() == 0 and light.irradiance[:2].abs().max() == 0
    assert light.ambient_sh[0].abs().max() == 0 and float(light.ambient_sh[1, 0, 0]) > 0
    assert float(light.direction[2, 1]) > 0.99 and light.color[0].tolist() == [1.0, 1.0, 1.0]
    assert light.to_dict(2)["direction"] == light.direction[2].double().tolist()


def test_half_precision_is_computed_in_float32() -> None:
    ball, _ = _sky_with_sun(torch.tensor([0.3, 0.5, 0.8], dtype=torch.float64))
    full = dominant_light(ball.float())
    for dtype in (torch.float16, torch.bfloat16):
        half = dominant_light(ball.to(dtype))
        assert half.irradiance.dtype == dtype and half.ambient_sh.dtype == dtype
        torch.testing.assert_close(half.irradiance.float(), full.irradiance, rtol=0.02, atol=0.0)


def test_refusals() -> None:
    ball = torch.ones(1, 3, 32, 32)
    with pytest.raises(ValueCheckError, match="non-negative"):
        dominant_light(-ball)
    with pytest.raises(NonFiniteError):
        dominant_light(ball * torch.nan)
    with pytest.raises(ShapeError):
        dominant_light(ball[:, :2])
    for bad in ({"threshold": 0.0}, {"threshold": 1.5}, {"max_angle": 0.0}, {"max_angle": 100.0}, {"threshold": True}):
        with pytest.raises(ValueCheckError):
            dominant_light(ball, **bad)
    with pytest.raises(ValueCheckError, match="index"):
        dominant_light(ball).to_dict(1)


def test_module_matches_functional() -> None:
    ball, _ = _sky_with_sun(torch.tensor([0.8, 0.2, -0.3], dtype=torch.float64))
    module, expected = SplitDominantLight(threshold=0.05, max_angle=15.0)(ball), dominant_light(
        ball, threshold=0.05, max_angle=15.0)
    for name in ("direction", "solid_angle", "irradiance", "ambient_sh"):
        torch.testing.assert_close(getattr(module, name), getattr(expected, name), rtol=0.0, atol=0.0)
    with pytest.raises(ValueCheckError, match="max_angle"):  # checked when built, not on the first call
        SplitDominantLight(max_angle=100.0)
