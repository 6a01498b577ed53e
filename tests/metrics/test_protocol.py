"""Tests of kornia_ilum.metrics.protocol: the three-sphere protocol of StyleLight and DiffusionLight."""

from __future__ import annotations

import functools

import numpy as np
import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.geometry import mirror_ball_to_lights, mirror_ball_valid
from kornia_ilum.metrics import (
    METRICS,
    ThreeSphereMetrics,
    TonemapStylelight,
    three_sphere_metrics,
    tonemap_stylelight,
)
from kornia_ilum.metrics.protocol import _sphere_metrics
from kornia_ilum.render import BRDFS, relight, sphere_reflectance_field
from tests.conftest import assert_close_dtype, hdr_lighting

F64 = torch.float64
_lighting = functools.partial(hdr_lighting, coloured=True)  # a bright light of a random colour


# --- StyleLight's evaluation/fast_rmse.py and TonemapHDR, ported to NumPy unchanged in substance --------


def stylelight_rmse(pred, gt, mask):
    num_pixel = mask.sum()
    error = ((pred - gt) ** 2 * mask[:, :, None]).sum() / num_pixel
    return np.sqrt(error)


def stylelight_si_rmse(pred, gt, mask):
    num_pixel = mask.sum()
    m = mask[:, :, None]
    a = (pred**2 * m).sum()
    b = (-(2 * pred * gt) * m).sum()
    c = (gt**2 * m).sum()
    return np.sqrt((4 * a * c - b**2) / (4 * a) / num_pixel)


def stylelight_angular(pred, gt, mask):
    num_pixel = mask.sum()
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = np.sum(gt * pred, axis=2) / (np.linalg.norm(gt, axis=2) * np.linalg.norm(pred, axis=2))
    cos = np.clip(cos, 0, 1)
    angular = np.nan_to_num(np.arccos(cos) * mask)
    return np.degrees(angular.sum() / num_pixel)


def stylelight_tonemap(img, gamma=2.4, percentile=50, max_mapping=0.5):
    power = np.power(img, 1 / gamma)
    non_zero = power > 0
    r = np.percentile(power[non_zero], percentile) if non_zero.any() else np.percentile(power, percentile)
    return max_mapping / (r + 1e-10) * power


def _plain_renders(lighting: np.ndarray, size: int) -> dict[str, torch.Tensor]:
    lights = mirror_ball_to_lights(torch.from_numpy(lighting)[None])
    return {
        b: relight(
            sphere_reflectance_field(b, size, lighting_size=32, dtype=F64, multiscale=True), lights, size
        )
        for b in BRDFS
    }


class TestThreeSphereMetrics:
    def test_smoke(self, device, dtype):
        pred, target = _lighting(seed=1, dtype=dtype).to(device), _lighting(seed=2, dtype=dtype).to(device)
        scores = three_sphere_metrics(pred, target, size=16)
        assert set(scores) == {(b, m) for b in BRDFS for m in METRICS}
        for value in scores.values():
            assert value.shape == (2,) and value.dtype == dtype and value.device == pred.device
            assert (value > 0).all()

    @pytest.mark.parametrize("tonemap", [True, False])
    @pytest.mark.parametrize("size", [8, 32])
    def test_matches_stylelight_code(self, tonemap, size):
        """The published formulas (fast_rmse.py, TonemapHDR) on our renders give the same numbers."""
        pred, target = _lighting(2, seed=3, dtype=F64), _lighting(2, seed=4, dtype=F64)
        pred[1, :, 10:12, 10:12] = 0.0  # black patches: zero RGB vectors on some sphere pixels
        scores = three_sphere_metrics(pred, target, size=size, tonemap=tonemap)
        mask = mirror_ball_valid(size).numpy().astype(np.float64)
        for i in range(2):
            p, t = pred[i].numpy(), target[i].numpy()
            if tonemap:
                p, t = stylelight_tonemap(p), stylelight_tonemap(t)
            # the protocol renders as render_spheres does (docs/conventions.rst, multi-scale: lighting brought
            # down to the sphere's size first when it is smaller)
            renders_p, renders_t = _plain_renders(p, size), _plain_renders(t, size)
            for brdf in BRDFS:
                rp = renders_p[brdf][0].permute(1, 2, 0).numpy()
                rt = renders_t[brdf][0].permute(1, 2, 0).numpy()
                ours = {m: scores[(brdf, m)][i].item() for m in METRICS}
                assert ours["rmse"] == pytest.approx(stylelight_rmse(rp, rt, mask), rel=1e-9)
                assert ours["si_rmse"] == pytest.approx(stylelight_si_rmse(rp, rt, mask), rel=1e-6)
                assert ours["angular_error"] == pytest.approx(
                    stylelight_angular(rp, rt, mask), rel=1e-7, abs=1e-9
                )

    def test_angular_edge_cases(self):
        """Zero vectors count as 0 degrees, opposite-ish vectors are clipped to 90 degrees."""
        pred = torch.tensor([[[1.0, 0.0, 1.0, 1.0], [0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 0.0]]], dtype=F64)
        target = torch.tensor(
            [[[1.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, -1.0]]], dtype=F64
        )
        angle = _sphere_metrics(pred, target)["angular_error"]
        # pixels: 0 deg, 0 (zero pred), 0 (zero target), 180 -> clipped to 90
        torch.testing.assert_close(angle, torch.tensor([90.0 / 4], dtype=F64))

    def test_exception(self):
        pred = _lighting()
        with pytest.raises(ShapeError, match="pred and target must have the same shape"):
            three_sphere_metrics(pred, pred[:1])
        with pytest.raises(ValueCheckError, match="pred must be non-negative"):
            three_sphere_metrics(pred - 1.0, pred)
        with pytest.raises(ValueCheckError, match="size must be one of"):
            three_sphere_metrics(pred, pred, size=48)
        with pytest.raises(ValueCheckError, match="tonemap must be a bool"):
            three_sphere_metrics(pred, pred, tonemap="yes")
        with pytest.raises(TypeCheckError, match="pred must be a torch.Tensor"):
            three_sphere_metrics(pred.numpy(), pred)
        with pytest.raises(ShapeError, match=r"pred must have shape \(B, 3, 32, 32\), got \(2, 3, 8, 8\)"):
            ThreeSphereMetrics(size=8)(pred[..., :8, :8], pred[..., :8, :8])

    def test_gradcheck(self):
        pred = (_lighting(1, s=4, seed=1, dtype=F64) + 0.1).requires_grad_()
        target = _lighting(1, s=4, seed=2, dtype=F64) + 0.1

        def fn(p):
            scores = three_sphere_metrics(p, target, size=4, tonemap=False)
            return torch.stack([scores[k] for k in sorted(scores)])

        assert torch.autograd.gradcheck(fn, (pred,))

    def test_module_matches_functional(self):
        pred, target = _lighting(seed=1), _lighting(seed=2)
        module = ThreeSphereMetrics(size=16)
        expected = three_sphere_metrics(pred, target, size=16)
        for key, value in module(pred, target).items():
            torch.testing.assert_close(value, expected[key])
        assert not module.state_dict()

    @pytest.mark.parametrize("dt", [torch.float16, torch.bfloat16, torch.float32])
    def test_dtypes(self, dt):
        """Half inputs are evaluated in float32, so only the input rounding is left."""
        pred, target = _lighting(seed=1, dtype=F64), _lighting(seed=2, dtype=F64)
        expected = three_sphere_metrics(pred.to(dt).to(F64), target.to(dt).to(F64), size=8)
        out = three_sphere_metrics(pred.to(dt), target.to(dt), size=8)
        for key, value in out.items():
            assert value.dtype == (torch.float32 if dt != torch.float32 else dt)
            assert_close_dtype(value, expected[key], torch.float32, scale=100.0)

    def test_compile(self):
        pred, target = _lighting(seed=1), _lighting(seed=2)
        compiled = torch.compile(three_sphere_metrics)
        expected = three_sphere_metrics(pred, target, size=8, tonemap=False)
        for key, value in compiled(pred, target, size=8, tonemap=False).items():
            torch.testing.assert_close(value, expected[key])

    @given(st.integers(0, 2**16), st.booleans(), st.sampled_from([torch.float32, F64]))
    def test_zero_for_identical_inputs(self, seed, tonemap, dt):
        """0 up to rounding: the cross product of two equal vectors is not exactly 0 with fused multiply-adds,
        which leaves angles of ~1e-8 rad in float32."""
        x = _lighting(2, seed=seed, dtype=dt)
        for key, value in three_sphere_metrics(x, x, size=8, tonemap=tonemap).items():
            assert value.abs().max().item() <= (1e-5 if dt == torch.float32 else 1e-12), key

    @given(st.integers(0, 2**16), st.floats(1e-3, 1e3))
    def test_si_rmse_scale_invariant(self, seed, k):
        """si-RMSE ignores the prediction's scale; with the tone map every metric does."""
        pred, target = _lighting(1, seed=seed, dtype=F64), _lighting(1, seed=seed + 1, dtype=F64)
        both, targets = torch.cat([pred, k * pred]), torch.cat([target, target])  # items: pred, k * pred
        linear = three_sphere_metrics(both, targets, size=8, tonemap=False)
        for brdf in BRDFS:
            for metric in ("si_rmse", "angular_error"):
                value = linear[(brdf, metric)]
                torch.testing.assert_close(value[1], value[0])
        for key, value in three_sphere_metrics(both, targets, size=8).items():
            torch.testing.assert_close(value[1], value[0], rtol=1e-6, atol=1e-9)


class TestTonemapStylelight:
    def test_smoke(self):
        x = _lighting(2, seed=5, dtype=F64)
        out = tonemap_stylelight(x)
        assert out.shape == x.shape and out.dtype == x.dtype
        for i in range(2):
            torch.testing.assert_close(out[i], torch.from_numpy(stylelight_tonemap(x[i].numpy())))

    @pytest.mark.parametrize("shape", [(1, 3, 4, 4), (3, 1, 8, 16)])
    def test_cardinality(self, shape):
        assert tonemap_stylelight(torch.rand(shape)).shape == shape

    def test_black_stays_black(self):
        out = tonemap_stylelight(torch.zeros(2, 3, 4, 4))
        assert out.abs().max().item() == 0.0

    def test_exception(self):
        with pytest.raises(ValueCheckError, match="lighting must be non-negative"):
            tonemap_stylelight(-torch.ones(1, 3, 4, 4))
        with pytest.raises(ShapeError, match=r"lighting must have shape \(B, C, H, W\)"):
            tonemap_stylelight(torch.ones(3, 4, 4))

    def test_module_matches_functional(self):
        x = _lighting(2, s=8, seed=7)
        torch.testing.assert_close(TonemapStylelight(2.2, 0.18)(x), tonemap_stylelight(x, 2.2, 0.18))

    def test_gradcheck(self):
        x = (torch.rand(1, 3, 3, 3, dtype=F64) + 0.1).requires_grad_()
        assert torch.autograd.gradcheck(tonemap_stylelight, (x,))

    @pytest.mark.parametrize("dt", [torch.float16, torch.bfloat16, torch.float32])
    def test_dtypes(self, dt):
        x = _lighting(1, s=8, seed=6, dtype=F64)
        out = tonemap_stylelight(x.to(dt))
        assert out.dtype == dt
        assert_close_dtype(out, tonemap_stylelight(x), dt)

    def test_compile(self):
        x = _lighting(1, s=8, seed=6)
        torch.testing.assert_close(torch.compile(tonemap_stylelight)(x), tonemap_stylelight(x))
