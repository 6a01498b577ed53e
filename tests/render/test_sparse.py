"""kornia_ilum.render.sparse: sparse relighting equals dense at eps 0, is exact for lighting that is constant
within each cluster apart from its kept lights, keeps the image's energy, and keeps only what it must."""

from __future__ import annotations

import math

import pytest
import torch

from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.geometry import mirror_ball_to_lights, mirror_ball_valid
from kornia_ilum.render import (
    KEPT_FRACTION,
    light_clusters,
    prepare_sparse,
    relight_product,
    relight_sparse,
    sparse_kept,
)

S = 8


def _field(shared: bool = False) -> torch.Tensor:
    torch.manual_seed(0)
    field = torch.rand((50, S * S) if shared else (3, 50, S * S), dtype=torch.float64)
    return field * mirror_ball_valid(S).flatten()  # no light off the ball


def _blocky_sky_and_sun(batch: int = 2) -> torch.Tensor:
    """A lighting constant on each 2 x 2 block of the ball, plus a sun on one pixel."""
    torch.manual_seed(1)
    blocks = torch.rand(batch, 3, S // 2, S // 2, dtype=torch.float64)
    ball = blocks.repeat_interleave(2, -1).repeat_interleave(2, -2) * mirror_ball_valid(S)
    ball[:, :, 3, 4] += 5000.0
    return mirror_ball_to_lights(ball)


@pytest.mark.parametrize("shared", [False, True])
def test_eps_zero_is_dense(shared) -> None:
    field, lights = _field(shared), _blocky_sky_and_sun()
    prepared = prepare_sparse(field, light_clusters(S, 2))
    torch.testing.assert_close(relight_sparse(prepared, lights, 0.0), relight_product(field, lights).float())


@pytest.mark.parametrize("shared", [False, True])
def test_exact_where_the_lighting_is_constant_on_each_cluster_but_its_sun(shared) -> None:
    field, lights = _field(shared), _blocky_sky_and_sun()
    prepared = prepare_sparse(field, light_clusters(S, 2))
    assert sparse_kept(prepared, lights, 0.01).tolist() == [1, 1]  # the sun alone
    dense = relight_product(field, lights).float()
    torch.testing.assert_close(relight_sparse(prepared, lights, 0.01), dense, rtol=1e-5, atol=1e-5)
    # coarser clusters than the sky's blocks: no longer exact, but the image's energy is kept
    coarse = relight_sparse(prepare_sparse(field, light_clusters(S, 4)), lights, 0.01)
    assert not torch.allclose(coarse, dense, rtol=1e-3)
    torch.testing.assert_close(coarse.sum(-1), dense.sum(-1), rtol=1e-5, atol=0.0)


def test_keeps_only_lights_above_eps_and_at_most_the_cap() -> None:
    field = _field()
    prepared = prepare_sparse(field, light_clusters(S, 2))
    flat = mirror_ball_to_lights(torch.ones(1, 3, S, S, dtype=torch.float64) * mirror_ball_valid(S))
    assert sparse_kept(prepared, flat, 0.05).tolist() == [0]  # an overcast sky: the means alone
    torch.testing.assert_close(relight_sparse(prepared, flat, 0.05), relight_product(field, flat).float())
    assert sparse_kept(prepared, flat, 1e-6).tolist() == [math.ceil(KEPT_FRACTION * S * S)]


def test_light_clusters_blocks_and_compact_lights() -> None:
    assert light_clusters(S, S).unique().tolist() == [0]
    index = mirror_ball_valid(S).flatten().nonzero().flatten()
    clusters = light_clusters(S, 2, index)
    assert clusters.shape == index.shape and clusters.unique().tolist() == list(range(int(clusters.max()) + 1))


def test_refusals() -> None:
    field = _field()
    prepared = prepare_sparse(field, light_clusters(S, 2))
    lights = _blocky_sky_and_sun()
    with pytest.raises(ValueCheckError, match="eps"):
        relight_sparse(prepared, lights, 1.0)
    with pytest.raises(ValueCheckError, match="non-negative"):
        relight_sparse(prepared, -lights, 0.1)
    with pytest.raises(ShapeError):
        relight_sparse(prepared, lights[:, :10], 0.1)
    with pytest.raises(ShapeError):
        prepare_sparse(field, light_clusters(S, 2)[:10])
    with pytest.raises(TypeCheckError, match="integer"):
        prepare_sparse(field, light_clusters(S, 2).float())
    with pytest.raises(ValueCheckError):
        prepare_sparse(field, -light_clusters(S, 2) - 1)
