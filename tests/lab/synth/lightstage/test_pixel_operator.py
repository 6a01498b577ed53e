"""The light stage's image-space filter machinery (:mod:`kornia_ilum_lab.synth.lightstage._pixel_operator`)."""

from __future__ import annotations

import pytest
import torch

from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum_lab.synth.lightstage._pixel_operator import (
    PixelOperator,
    check_field,
    check_gbuffer,
    csr,
    neighbours,
    window_offsets,
)
from kornia_ilum_lab.synth.lightstage.gbuffer import GBuffer


def _gbuffer(size: int = 4, focal_px: float = 3.0) -> GBuffer:
    z3, z1 = torch.zeros(3, size, size), torch.zeros(1, size, size)
    return GBuffer(z3, z3.clone(), z1, z1.clone(), z1.clone(), focal_px=focal_px)


def test_window_offsets_cover_the_window_row_by_row() -> None:
    offsets = window_offsets(1, step=2)
    assert offsets.shape == (9, 2) and offsets.dtype == torch.int64
    assert offsets[0].tolist() == [-2, -2] and offsets[4].tolist() == [0, 0] and offsets[-1].tolist() == [2, 2]


def test_neighbours_are_positions_in_the_pixel_subset() -> None:
    size, pixels = 3, torch.tensor([0, 1, 4, 8])  # a subset of the 3 x 3 image, flat row-major
    idx, valid = neighbours(size, torch.tensor([4]), window_offsets(1), pixels)
    # around the centre pixel 4: (-1,-1) is pixel 0 (position 0), (-1,0) is pixel 1 (position 1), itself is
    # position 2, (1,1) is pixel 8 (position 3); the others are not in the subset
    assert valid[0].tolist() == [True, True, False, False, True, False, False, False, True]
    assert idx[0][valid[0]].tolist() == [0, 1, 2, 3]
    idx, valid = neighbours(size, torch.tensor([0]), window_offsets(1), pixels)
    assert not valid[0, :3].any() and not valid[0, 3]  # above and left of the corner: outside the image


def test_csr_sums_duplicate_triplets() -> None:
    m = csr(torch.tensor([0, 0, 1]), torch.tensor([1, 1, 0]), torch.tensor([0.5, 0.25, 2.0]), 2)
    assert m.layout == torch.sparse_csr
    assert torch.equal(m.to_dense(), torch.tensor([[0.0, 0.75], [2.0, 0.0]]))


def test_apply_acts_on_the_subset_only_and_matches_dense() -> None:
    torch.manual_seed(0)
    size, pixels = 3, torch.tensor([2, 4, 5])
    rows, cols = torch.tensor([0, 1, 2, 2]), torch.tensor([1, 1, 0, 2])
    first = csr(rows, cols, torch.rand(4, dtype=torch.float64), 3)
    second = csr(torch.arange(3), torch.arange(3), torch.tensor([2.0, 3.0, 4.0], dtype=torch.float64), 3)
    op = PixelOperator(pixels, [[first, second], [second], [first]], size)
    field = torch.rand(3, size * size, 5, dtype=torch.float64)

    out = op.apply(field, chunk=2)
    outside = torch.ones(size * size, dtype=torch.bool)
    outside[pixels] = False
    assert torch.equal(out[:, outside], field[:, outside])
    for c in range(3):
        torch.testing.assert_close(out[c], op.dense()[c] @ field[c])
    torch.testing.assert_close(out[0, pixels], second.to_dense() @ first.to_dense() @ field[0, pixels])


def test_apply_rejects_bad_arguments() -> None:
    op = PixelOperator(torch.tensor([0]), [[csr(torch.tensor([0]), torch.tensor([0]), torch.ones(1), 1)]] * 3, 2)
    with pytest.raises(ValueCheckError, match="chunk"):
        op.apply(torch.zeros(3, 4, 1), chunk=0)
    with pytest.raises(ShapeError, match="P = 9"):
        op.apply(torch.zeros(3, 9, 1))


def test_checks_name_the_argument() -> None:
    gbuffer = _gbuffer(4)
    assert check_gbuffer(gbuffer) == 4 and check_field(torch.zeros(3, 16, 2), gbuffer, "field") == 4
    with pytest.raises(ValueCheckError, match="focal_px must be positive"):
        check_gbuffer(_gbuffer(4, focal_px=0.0))
    with pytest.raises(TypeCheckError, match="must be a GBuffer"):
        check_gbuffer("not a gbuffer")
    with pytest.raises(ShapeError, match=r"P = 9 pixels but the gbuffer is 4 x 4"):
        check_field(torch.zeros(3, 9, 2), gbuffer, "field")
    with pytest.raises(TypeCheckError, match="bfloat16 field"):
        check_field(torch.zeros(3, 16, 2, dtype=torch.bfloat16), gbuffer, "field")
