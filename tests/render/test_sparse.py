"""kornia_ilum.render.sparse: sparse relighting equals dense at eps 0, equals relight's truncation without a
fold, is exact with an SH fold for SH lighting, and falls back to dense for lightings that keep many lights."""

from __future__ import annotations

import pytest
import torch

from kornia_ilum.core.errors import ShapeError, ValueCheckError
from kornia_ilum.geometry import mirror_ball_to_lights, mirror_ball_valid
from kornia_ilum.render import DENSE_FRACTION, kept_lights, prepare_sparse, relight, relight_product, relight_sparse
from kornia_ilum.sh import sh_light_basis, sh_reconstruct

S = 8


def _field(shared: bool = False) -> torch.Tensor:
    torch.manual_seed(0)
    field = torch.rand((50, S * S) if shared else (3, 50, S * S), dtype=torch.float64)
    return field * mirror_ball_valid(S).flatten()  # no light off the ball


def _sun(batch: int = 2) -> torch.Tensor:
    ball = torch.full((batch, 3, S, S), 0.01, dtype=torch.float64) * mirror_ball_valid(S)
    ball[:, :, 3, 4] = 50.0
    return mirror_ball_to_lights(ball)


@pytest.mark.parametrize("shared", [False, True])
def test_eps_zero_is_dense_and_drop_is_relights_truncation(shared) -> None:
    field, lights = _field(shared), _sun()
    prepared = prepare_sparse(field)
    torch.testing.assert_close(relight_sparse(prepared, lights, 0.0), relight_product(field, lights).float())
    truncated = relight(field, lights, (1, 50), eps=0.05)[:, :, 0].float()
    torch.testing.assert_close(relight_sparse(prepared, lights, 0.05), truncated)


def test_the_sh_fold_recovers_an_order_2_sky_under_a_sun() -> None:
    field = _field()
    sh = 0.1 * torch.randn(2, 9, 3, dtype=torch.float64)
    sh[:, 0] = 5.0  # positive everywhere
    smooth = sh_reconstruct(sh, S) * mirror_ball_valid(S)
    assert (smooth >= 0).all()
    ball = smooth.clone()
    ball[:, :, 3, 4] += 5000.0  # a sun with most of the energy: kept exactly, the whole sky folded
    lights = mirror_ball_to_lights(ball)
    folded = prepare_sparse(field, sh_light_basis(S))
    dense = relight_product(field, lights).float()
    got = relight_sparse(folded, lights, 0.5)
    folded_error = ((got - dense).abs().sum() / dense.abs().sum()).item()
    dropped = relight_sparse(prepare_sparse(field), lights, 0.5)
    dropped_error = ((dropped - dense).abs().sum() / dense.abs().sum()).item()
    # the sky without the sun's own pixel is not quite order 2: the fold keeps it to 2e-4 of the image, where
    # dropping it loses about 1 %
    assert folded_error < 3e-4 and dropped_error > 30 * folded_error


def test_a_lighting_that_keeps_many_lights_is_relit_densely() -> None:
    field = _field()
    flat = mirror_ball_to_lights(torch.ones(1, 3, S, S, dtype=torch.float64) * mirror_ball_valid(S))
    prepared = prepare_sparse(field, sh_light_basis(S))
    assert int(kept_lights(flat, prepared.norms, 0.01).sum()) > DENSE_FRACTION * S * S
    torch.testing.assert_close(relight_sparse(prepared, flat, 0.01), relight_product(field, flat).float())


def test_refusals() -> None:
    field = _field()
    prepared = prepare_sparse(field)
    with pytest.raises(ValueCheckError, match="eps"):
        relight_sparse(prepared, _sun(), 1.0)
    with pytest.raises(ValueCheckError, match="non-negative"):
        relight_sparse(prepared, -_sun(), 0.1)
    with pytest.raises(ShapeError):
        relight_sparse(prepared, _sun()[:, :10], 0.1)
    projection, values = sh_light_basis(S)
    with pytest.raises(ShapeError, match="one shape"):
        prepare_sparse(field, (projection, values[:, :4]))
