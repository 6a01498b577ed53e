"""Colour looks: each look's effect on a photo, the lighting it implies, the random draws."""

from __future__ import annotations

import pytest
import torch

from kornia_ilum.color import LUMINANCE, linear_to_srgb, srgb_to_linear
from kornia_ilum.core.errors import ShapeError, ValueCheckError
from kornia_ilum_lab.synth.colour_looks import (
    LOOK_KINDS,
    LOOKS,
    Look,
    apply_look,
    apply_looks,
    desaturate,
    draw_looks,
    grade,
    greyscale,
    look_lighting,
    white_balance,
)


@pytest.fixture
def photo() -> torch.Tensor:
    return torch.rand(3, 3, 16, 16, generator=torch.Generator().manual_seed(0))


def test_greyscale_is_opencvs_luma(photo: torch.Tensor) -> None:
    cv2 = pytest.importorskip("cv2")
    codes = (photo[0].permute(1, 2, 0) * 255).round().byte().numpy()
    theirs = torch.from_numpy(cv2.cvtColor(codes, cv2.COLOR_RGB2GRAY)).float()
    ours = greyscale(torch.from_numpy(codes).permute(2, 0, 1)[None].float() / 255)[0, 0] * 255
    assert (ours - theirs).abs().max() <= 1.0


def test_desaturate_ends(photo: torch.Tensor) -> None:
    torch.testing.assert_close(desaturate(photo, 0.0), photo)
    torch.testing.assert_close(desaturate(photo, 1.0), greyscale(photo))
    with pytest.raises(ShapeError):
        desaturate(photo, torch.ones(2))


def test_white_balance_is_a_linear_gain_that_keeps_the_luminance() -> None:
    linear = torch.full((1, 3, 2, 2), 0.2)
    out = srgb_to_linear(white_balance(linear_to_srgb(linear), torch.tensor([2.0, 1.0, 0.5])))
    gains = out[0, :, 0, 0] / 0.2
    assert gains[0] / gains[1] == pytest.approx(2.0, rel=1e-4) and gains[2] / gains[1] == pytest.approx(0.5, rel=1e-4)
    assert float((gains * torch.tensor(LUMINANCE)).sum()) == pytest.approx(1.0, rel=1e-4)
    with pytest.raises(ValueCheckError):
        white_balance(linear, torch.tensor([1.0, 0.0, 1.0]))


def test_grade_identity_and_range(photo: torch.Tensor) -> None:
    one, zero = torch.ones(3), torch.zeros(3)
    torch.testing.assert_close(grade(photo, one, zero, one), photo)
    out = grade(photo, torch.tensor([2.0, 1.0, 0.5]), torch.tensor([0.1, -0.1, 0.0]), torch.tensor([0.5, 1.0, 2.0]),
                saturation=1.5)
    assert out.min() >= 0 and out.max() <= 1
    with pytest.raises(ValueCheckError):
        grade(photo, one, zero, zero)


@pytest.mark.parametrize("name", sorted(LOOKS))
def test_every_named_look_changes_the_colours_not_the_shape(name: str, photo: torch.Tensor) -> None:
    out = apply_look(photo, Look.named(name, 3))
    assert out.shape == photo.shape and out.min() >= 0 and out.max() <= 1
    assert not torch.equal(out, photo)


def test_unknown_look_and_wrong_count(photo: torch.Tensor) -> None:
    with pytest.raises(ValueCheckError, match="unknown look"):
        Look.named("vivid")
    with pytest.raises(ShapeError):
        apply_look(photo, Look.named("warm", 2))


def test_the_lighting_of_each_look() -> None:
    ball = torch.rand(4, 3, 8, 8, generator=torch.Generator().manual_seed(1))
    luminance = (ball * torch.tensor(LUMINANCE).view(1, 3, 1, 1)).sum(1, keepdim=True).expand_as(ball)
    torch.testing.assert_close(look_lighting(ball, Look.named("greyscale", 4)), luminance)
    torch.testing.assert_close(look_lighting(ball, Look.named("sepia", 4)), luminance)  # a toned black and white
    torch.testing.assert_close(look_lighting(ball, Look.named("desaturated", 4)), torch.lerp(ball, luminance, 0.6))
    torch.testing.assert_close(look_lighting(ball, Look.named("teal_orange", 4)), ball)
    warm = look_lighting(ball, Look.named("warm", 4)) / ball
    gains = torch.tensor(LOOKS["warm"]["gains"])
    gains = gains / (gains * torch.tensor(LUMINANCE)).sum()
    torch.testing.assert_close(warm[:, :, 0, 0], gains.expand(4, 3))
    torch.testing.assert_close(look_lighting(ball, Look.identity(4)), ball)


def test_uint8_photos_stay_uint8() -> None:
    codes = torch.randint(0, 256, (2, 3, 8, 8), dtype=torch.uint8)
    image, _ = apply_looks(codes, torch.rand(2, 3, 4, 4), Look.named("greyscale", 2))
    assert image.dtype == torch.uint8 and torch.equal(image[:, 0], image[:, 2])


def test_draws_are_reproducible_and_cover_the_kinds() -> None:
    a = draw_looks(400, 0.5, torch.Generator().manual_seed(3))
    b = draw_looks(400, 0.5, torch.Generator().manual_seed(3))
    assert torch.equal(a.kind, b.kind) and torch.equal(a.slope, b.slope)
    drawn = {LOOK_KINDS[k] for k in a.kind.tolist()}
    assert drawn == {"none", "greyscale", "desaturate", "grade"}
    assert bool(a.grey_first.any()) and bool((a.saturation[a.grey_first] == 1).all())
    assert not bool(draw_looks(50, 0.0, torch.Generator()).kind.any())
    with pytest.raises(ValueCheckError):
        draw_looks(4, 1.5, torch.Generator())
