"""Tests of the lat-long grid: angles, directions, solid angles, pixel coordinates.

The grid is that of docs/conventions.rst, "Lat-long".
"""

from __future__ import annotations

import math

import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.geometry import (
    angles_to_latlong_pixel,
    direction_to_latlong,
    latlong_angles,
    latlong_directions,
    latlong_solid_angles,
    latlong_to_direction,
)

F64 = torch.float64
unit_vectors = st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)).filter(
    lambda v: 0.1 < math.sqrt(sum(c * c for c in v)) <= 1.0
)


class TestLatLongAngles:
    def test_smoke(self):
        phi, el = latlong_angles(2, dtype=F64)
        assert phi.shape == el.shape == (2, 4)
        torch.testing.assert_close(phi[0], torch.tensor([-0.75, -0.25, 0.25, 0.75], dtype=F64) * math.pi)
        torch.testing.assert_close(el[:, 0], torch.tensor([0.25, -0.25], dtype=F64) * math.pi)

    @given(st.integers(1, 64))
    def test_spec_pixel_centres(self, height):
        phi, el = latlong_angles(height, dtype=F64)
        w = 2 * height
        j = torch.arange(w, dtype=F64)
        i = torch.arange(height, dtype=F64)
        torch.testing.assert_close(phi[0], 2 * math.pi * (j + 0.5) / w - math.pi)
        torch.testing.assert_close(el[:, 0], math.pi / 2 - math.pi * (i + 0.5) / height)

    def test_exception(self):
        with pytest.raises(ValueCheckError, match="height must be positive"):
            latlong_angles(0)
        with pytest.raises(TypeCheckError, match="height must be an int"):
            latlong_directions(2.5)


class TestLatLongDirections:
    def test_spec_anchors(self):
        h = 8
        d = latlong_directions(h, dtype=F64)
        # the centre column (between columns h-1 and h) looks forward, -Z; phi = 0 is exactly -Z
        torch.testing.assert_close(
            latlong_to_direction(torch.tensor(0.0, dtype=F64), torch.tensor(0.0, dtype=F64)),
            torch.tensor([0.0, 0.0, -1.0], dtype=F64),
        )
        mid = d[h // 2 - 1 : h // 2 + 1, h - 1 : h + 1]
        assert bool((mid[..., 2] < -0.9).all())
        # the left half is -X, the right half +X
        assert bool((d[:, 1 : h - 1, 0] < 0).all()) and bool((d[:, h + 1 : 2 * h - 1, 0] > 0).all())
        # the top row is +Y, the bottom row -Y
        top = math.cos(math.pi / (2 * h))  # the row centre is half a row below the pole
        torch.testing.assert_close(d[0, :, 1], torch.full((2 * h,), top, dtype=F64))
        torch.testing.assert_close(d[-1, :, 1], torch.full((2 * h,), -top, dtype=F64))
        # the edge columns look backward, +Z
        assert bool((d[h // 2 - 1 : h // 2 + 1, [0, -1], 2] > 0.9).all())

    def test_unit_length(self):
        d = latlong_directions(16, dtype=F64)
        torch.testing.assert_close(d.norm(dim=-1), torch.ones(16, 32, dtype=F64))

    @given(unit_vectors)
    def test_direction_angles_direction(self, v):
        d = torch.tensor(v, dtype=F64)
        d = d / d.norm()
        phi, el = direction_to_latlong(d)
        assert -math.pi <= phi.item() <= math.pi and -math.pi / 2 <= el.item() <= math.pi / 2
        torch.testing.assert_close(latlong_to_direction(phi, el), d, atol=1e-9, rtol=0)

    @given(st.floats(-math.pi + 1e-6, math.pi), st.floats(-1.5, 1.5))
    def test_angles_direction_angles(self, phi, el):
        p, e = direction_to_latlong(
            latlong_to_direction(torch.tensor(phi, dtype=F64), torch.tensor(el, dtype=F64))
        )
        assert abs(e.item() - el) < 1e-9
        assert abs(math.remainder(p.item() - phi, 2 * math.pi)) < 1e-9

    def test_exception(self):
        with pytest.raises(ShapeError, match=r"d must have shape \(\*, 3\)"):
            direction_to_latlong(torch.zeros(2, 2))

    def test_gradcheck(self):
        phi = torch.tensor([0.1, -2.0], dtype=F64, requires_grad=True)
        el = torch.tensor([0.3, -0.7], dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(latlong_to_direction, (phi, el))

    def test_dtypes(self, dtype):
        assert latlong_directions(4, dtype=dtype).dtype == dtype


class TestLatLongPixel:
    @given(st.integers(1, 64))
    def test_centres_round_trip(self, height):
        """Directions of pixel centres map back to integer pixel coordinates (col, row)."""
        phi, el = direction_to_latlong(latlong_directions(height, dtype=F64))
        px = angles_to_latlong_pixel(phi, el, height)
        i, j = torch.meshgrid(torch.arange(height), torch.arange(2 * height), indexing="ij")
        col = torch.remainder(px[..., 0], 2 * height)  # +-pi wraps
        col = torch.where(col > 2 * height - 0.75, col - 2 * height, col)
        torch.testing.assert_close(col, j.to(F64), atol=1e-9, rtol=0)
        torch.testing.assert_close(px[..., 1], i.to(F64), atol=1e-9, rtol=0)

    def test_edges(self):
        px = angles_to_latlong_pixel(torch.tensor([-math.pi, 0.0]), torch.tensor([math.pi / 2, 0.0]), 4)
        torch.testing.assert_close(px, torch.tensor([[-0.5, -0.5], [3.5, 1.5]]))


class TestLatLongSolidAngles:
    @given(st.integers(1, 512))
    def test_sum_is_four_pi(self, height):
        omega = latlong_solid_angles(height, dtype=F64)
        assert omega.shape == (height, 2 * height)
        assert abs(omega.sum().item() / (4 * math.pi) - 1) < 1e-12

    @given(st.integers(1, 64))
    def test_row_formula(self, height):
        """``(2 pi / W)(sin el_top - sin el_bottom)``, about ``cos(el) dphi del`` away from the poles."""
        omega = latlong_solid_angles(height, dtype=F64)
        _, el = latlong_angles(height, dtype=F64)
        step = math.pi / height
        top, bottom = el[:, 0] + step / 2, el[:, 0] - step / 2
        torch.testing.assert_close(omega[:, 0], (torch.sin(top) - torch.sin(bottom)) * step)
        torch.testing.assert_close(omega[:, 0], torch.cos(el[:, 0]) * step * step, rtol=step**2, atol=0)
        assert torch.equal(omega, omega.flip(-1))
        torch.testing.assert_close(omega, omega.flip(-2), atol=1e-15, rtol=0)

    def test_dtypes(self, dtype):
        assert latlong_solid_angles(4, dtype=dtype).dtype == dtype
