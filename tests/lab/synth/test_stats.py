"""Tests of the environment statistics on inputs with known answers."""

from __future__ import annotations

import csv
import math

import pytest
import torch

from kornia_ilum.core.errors import NonFiniteError, ShapeError, ValueCheckError
from kornia_ilum.geometry import mirror_ball_solid_angles
from kornia_ilum_lab.synth.environments import Environment, augment
from kornia_ilum_lab.synth.environments.sky import cct_to_rgb
from kornia_ilum_lab.synth.stats import (
    RGB_TO_XYZ,
    STATS,
    cct_mccamy,
    environment_group,
    format_table,
    lighting_stats,
    plot_histograms,
    source_group,
    stats_rows,
    summarize,
    weighted_quantile,
    write_csv,
)

F64 = torch.float64
#: linear sRGB of equal-energy white (X = Y = Z = 1)
EQUAL_ENERGY = torch.linalg.solve(torch.tensor(RGB_TO_XYZ, dtype=F64), torch.ones(3, dtype=F64))


def constant(layout: str, rgb: torch.Tensor) -> torch.Tensor:
    shape = (32, 32) if layout == "mirror_ball" else (16, 32)
    return rgb.to(F64)[:, None, None].expand(3, *shape).clone()


class TestLightingStats:
    @pytest.mark.parametrize("layout", ["mirror_ball", "latlong"])
    def test_constant_map(self, layout):
        s = lighting_stats(constant(layout, EQUAL_ENERGY), layout)
        assert s["dynamic_range_stops"] == 0.0
        assert s["peak_to_mean"] == pytest.approx(1.0, abs=1e-12)
        assert s["top1_energy"] == pytest.approx(0.01, abs=1e-12)
        assert s["cct_kelvin"] == pytest.approx(5455.0, abs=5.0)  # equal-energy white, McCamy: 5459 K

    def test_srgb_white_is_d65(self):
        assert lighting_stats(torch.ones(3, 32, 32))["cct_kelvin"] == pytest.approx(6504.0, abs=3.0)

    @pytest.mark.parametrize("kelvin", [3000.0, 4500.0, 6500.0])
    def test_cct_of_planckian_white(self, kelvin):
        rgb = cct_to_rgb(torch.tensor(kelvin, dtype=F64))
        assert cct_mccamy(rgb) == pytest.approx(kelvin, rel=0.015)

    def test_sun_map(self):
        ball = torch.full((3, 32, 32), 0.5, dtype=F64) * (mirror_ball_solid_angles(32, dtype=F64) > 0)
        ball[:, 10, 12] = 0.5 * 2**12  # a 12-stop sun in one pixel
        s = lighting_stats(ball)
        omega = mirror_ball_solid_angles(32, dtype=F64)
        mean = float((ball[1] * omega).sum()) / (4 * math.pi)
        assert s["dynamic_range_stops"] == pytest.approx(12.0)
        assert s["peak_to_mean"] == pytest.approx(0.5 * 2**12 / mean)
        sun = 0.5 * 2**12 / 64
        rest = 0.01 * 4 * math.pi - 1 / 64  # the rest of the top 1 %: sky pixels
        total = float((ball[1] * omega).sum())
        assert s["top1_energy"] == pytest.approx((sun + 0.5 * rest) / total)

    def test_black_pixels_are_left_out_of_the_range(self):
        ll = torch.ones(3, 16, 32, dtype=F64)
        ll[:, 8:] = 0.0  # black ground
        s = lighting_stats(ll, "latlong")
        assert s["dynamic_range_stops"] == 0.0 and s["peak_to_mean"] == pytest.approx(2.0)

    def test_scale_invariant(self):
        ball = torch.rand(3, 32, 32, generator=torch.Generator().manual_seed(0), dtype=F64) ** 3
        a, b = lighting_stats(ball), lighting_stats(ball * 16.0)
        assert all(a[k] == pytest.approx(b[k], rel=1e-9) for k in STATS)

    def test_black_map(self):
        assert all(math.isnan(v) for v in lighting_stats(torch.zeros(3, 32, 32)).values())

    def test_exception(self):
        with pytest.raises(ValueCheckError, match="layout must be 'mirror_ball' or 'latlong'"):
            lighting_stats(torch.ones(3, 32, 32), "cube")
        with pytest.raises(ShapeError, match=r"lighting must have shape \(3, H, 2H\) for layout 'latlong'"):
            lighting_stats(torch.ones(3, 32, 32), "latlong")
        with pytest.raises(ShapeError, match=r"lighting must have shape \(3, H, W\)"):
            lighting_stats(torch.ones(1, 3, 32, 32))
        with pytest.raises(ValueCheckError, match="lighting must be non-negative"):
            lighting_stats(-torch.ones(3, 32, 32))
        with pytest.raises(NonFiniteError, match="lighting must be finite"):
            lighting_stats(torch.full((3, 32, 32), math.inf))


def test_weighted_quantile_is_reexported():
    """The statistics use the augmentation's quantile (tested in tests/synth/environments/test_augment.py)."""
    assert weighted_quantile is augment.weighted_quantile


def envs() -> list[Environment]:
    ones = torch.ones(3, 8, 16)
    sun = torch.ones(3, 32, 32)
    sun[:, 16, 16] = 1e3
    return [
        Environment(ones, torch.ones(3, 32, 32), "outdoor", "real:a.exr", {}),
        Environment(ones, sun, "outdoor", "real:a.exr", {"augment": {}}),
        Environment(ones, sun, "outdoor", "sky:clear", {}),
        Environment(ones, sun * 2, "outdoor", "sky:hazy", {}),
        Environment(ones, torch.ones(3, 32, 32), "indoor", "indoor:room", {}),
        Environment(ones, sun * 3, "indoor", "portrait:flash", {}),
        Environment(ones, sun * 4, "outdoor", "portrait:street", {}),
    ]


def test_groups_rows_summary_table_csv_figure(tmp_path):
    assert [environment_group(e) for e in envs()] == [
        "real", "real, augmented", "procedural outdoor", "procedural outdoor", "procedural indoor",
        "portrait lights", "portrait lights",
    ]  # fmt: skip
    assert [source_group(e) for e in envs()] == [
        "real", "real, augmented", "sky: clear", "sky: hazy", "indoor: room", "portrait: flash",
        "portrait: street",
    ]  # fmt: skip
    rows = stats_rows(envs())
    assert len(rows) == 7 and set(STATS) <= set(rows[0])
    summary = summarize(rows)
    assert list(summary) == [
        "real", "real, augmented", "procedural outdoor", "procedural indoor", "portrait lights",
    ]  # fmt: skip
    assert summary["procedural outdoor"]["n"] == 2 and summary["portrait lights"]["n"] == 2
    assert summary["real"]["top1_energy"] == pytest.approx((0.01, 0.01, 0.01))
    table = format_table(summary)
    lines = table.splitlines()
    assert lines[0] == lines[2] == lines[-1] and lines[0].startswith("=====")
    assert "procedural indoor" in table and "1.0 %" in table
    write_csv(rows, tmp_path / "s.csv")
    with (tmp_path / "s.csv").open() as f:
        read = list(csv.DictReader(f))
    assert [r["group"] for r in read] == [r["group"] for r in rows]
    assert float(read[2]["peak_to_mean"]) == pytest.approx(rows[2]["peak_to_mean"])
    plot_histograms(rows, tmp_path / "h.png")
    assert (tmp_path / "h.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    latlong_rows = stats_rows(envs()[:1], layout="latlong")
    assert latlong_rows[0]["dynamic_range_stops"] == 0.0
