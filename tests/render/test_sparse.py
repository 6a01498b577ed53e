"""kornia_ilum.render.sparse: sparse relighting equals dense at eps 0, relights the kept lights exactly and the
rest exactly where the field is of the prepared rank, comes closer as the rank grows, and keeps only what it
must."""

from __future__ import annotations

import math

import pytest
import torch

from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.geometry import mirror_ball_to_lights, mirror_ball_valid
from kornia_ilum.render import (
    KEPT_FRACTION,
    RelightSparse,
    prepare_sparse,
    relight_product,
    relight_sparse,
    sparse_kept,
)

S = 8


def _field(shared: bool = False, rank: int | None = None) -> torch.Tensor:
    """A random field of 50 pixels over the lights of an 8 x 8 ball; of rank ``rank`` per channel if given."""
    torch.manual_seed(0)
    channels = () if shared else (3,)
    if rank is None:
        field = torch.rand(*channels, 50, S * S, dtype=torch.float64)
    else:
        field = torch.rand(*channels, 50, rank, dtype=torch.float64) @ torch.rand(*channels, rank, S * S,
                                                                                 dtype=torch.float64)
    return field * mirror_ball_valid(S).flatten()  # no light off the ball


def _sky_and_sun(batch: int = 2) -> torch.Tensor:
    """A random sky plus a sun on one pixel; the last lighting has a second sun (so they keep different counts)."""
    torch.manual_seed(1)
    ball = torch.rand(batch, 3, S, S, dtype=torch.float64) * mirror_ball_valid(S)
    ball[:, :, 3, 4] += 5000.0
    ball[-1, :, 5, 2] += 3000.0
    return mirror_ball_to_lights(ball)


@pytest.mark.parametrize("shared", [False, True])
def test_eps_zero_is_dense(shared) -> None:
    field, lights = _field(shared), _sky_and_sun()
    torch.testing.assert_close(relight_sparse(prepare_sparse(field, rank=2), lights, 0.0),
                               relight_product(field, lights).float())


@pytest.mark.parametrize("shared", [False, True])
def test_exact_where_the_field_has_the_prepared_rank(shared) -> None:
    field, lights = _field(shared, rank=3), _sky_and_sun()
    prepared = prepare_sparse(field, rank=3)
    assert sparse_kept(prepared, lights, 0.01).tolist() == [1, 2]  # the suns alone
    torch.testing.assert_close(relight_sparse(prepared, lights, 0.01), relight_product(field, lights).float(),
                               rtol=1e-5, atol=1e-5)


def test_the_kept_lights_are_exact_at_any_rank() -> None:
    field = _field()
    sun = torch.zeros(1, S * S, 3, dtype=torch.float64)
    sun[0, 27] = 100.0  # a light on the ball, alone: kept, and nothing left for the low rank
    torch.testing.assert_close(relight_sparse(prepare_sparse(field, rank=1), sun, 0.01),
                               relight_product(field, sun).float())


def test_the_error_shrinks_as_the_rank_grows() -> None:
    field, lights = _field(), _sky_and_sun()
    dense = relight_product(field, lights).float()
    errors = [float((relight_sparse(prepare_sparse(field, rank=r), lights, 0.01) - dense).norm())
              for r in (1, 4, 16, S * S)]
    assert errors == sorted(errors, reverse=True) and errors[-1] < 1e-3 * float(dense.norm())


def test_prepared_alike_twice_and_rank_cut_to_the_lights() -> None:
    field = _field()
    a, b = prepare_sparse(field, rank=4), prepare_sparse(field, rank=4)
    assert torch.equal(a.basis, b.basis) and torch.equal(a.directions, b.directions)
    assert prepare_sparse(field, rank=10 * S * S).basis.shape[-1] == S * S


def test_keeps_only_lights_above_eps_and_at_most_the_cap() -> None:
    field = _field()
    prepared = prepare_sparse(field, rank=S * S)
    flat = mirror_ball_to_lights(torch.ones(1, 3, S, S, dtype=torch.float64) * mirror_ball_valid(S))
    assert sparse_kept(prepared, flat, 0.05).tolist() == [0]  # an overcast sky: the low rank alone
    torch.testing.assert_close(relight_sparse(prepared, flat, 0.05), relight_product(field, flat).float())
    assert sparse_kept(prepared, flat, 1e-6).tolist() == [math.ceil(KEPT_FRACTION * S * S)]


def test_refusals() -> None:
    field = _field()
    prepared = prepare_sparse(field, rank=2)
    lights = _sky_and_sun()
    with pytest.raises(ValueCheckError, match="eps"):
        relight_sparse(prepared, lights, 1.0)
    with pytest.raises(ValueCheckError, match="non-negative"):
        relight_sparse(prepared, -lights, 0.1)
    with pytest.raises(ShapeError):
        relight_sparse(prepared, lights[:, :10], 0.1)
    with pytest.raises(ShapeError):
        prepare_sparse(field[0, 0])
    with pytest.raises(ValueCheckError, match="rank"):
        prepare_sparse(field, rank=0)
    with pytest.raises(TypeCheckError, match="rank"):
        prepare_sparse(field, rank=2.0)


@pytest.mark.parametrize("shared", [False, True])
def test_module_matches_functional(shared) -> None:
    field, lights = _field(shared), _sky_and_sun()
    module = RelightSparse(field, eps=0.01, rank=4)
    torch.testing.assert_close(module(lights), relight_sparse(prepare_sparse(field, rank=4), lights, 0.01),
                               rtol=0.0, atol=0.0)
    assert module.state_dict() == {}  # the prepared field is a non-persistent buffer
    with pytest.raises(ValueCheckError, match="eps"):  # checked when built
        RelightSparse(field, eps=1.0)
