"""Tests of the `uniform` plugin (package kornia_ilum_uniform, installed from plugins/uniform)."""

from __future__ import annotations

import doctest
import math

import pytest
import torch

import kornia_ilum_uniform
from kornia_ilum.color import srgb_to_linear
from kornia_ilum.core.errors import ShapeError, ValueCheckError
from kornia_ilum.estimators import LightingEstimator, create_estimator
from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum.sh import sh_project
from kornia_ilum_uniform import SKIN_ALBEDO, UniformEstimator, face_ellipse, uniform_lighting
from tests.conftest import TOL, assert_close_dtype

ALBEDO = torch.tensor(SKIN_ALBEDO)
VALID = mirror_ball_valid(32)


def grey(g: float, batch: int = 1, size: int = 256, dtype=torch.float32) -> torch.Tensor:
    return torch.full((batch, 3, size, size), g, dtype=dtype)


def face_like(batch: int = 2, seed: int = 0, size: int = 256) -> torch.Tensor:
    """Random crops with values away from the clip and dark thresholds (so gradients are smooth)."""
    g = torch.Generator().manual_seed(seed)
    return 0.15 + 0.7 * torch.rand(batch, 3, size, size, generator=g)


class TestUniformEstimator:
    def test_smoke(self):
        est = UniformEstimator()
        assert isinstance(est, LightingEstimator) and list(est.parameters()) == []
        assert est.info.name == "uniform" and est.info.weights == () and not est.info.needs_weights
        assert est.info.paper.startswith("none: a baseline") and est.info.input_size == 256
        assert kornia_ilum_uniform.__version__

    def test_cardinality(self):
        out = UniformEstimator()(face_like(3))
        assert out.mirror_ball.shape == out.log_mirror_ball.shape == (3, 3, 32, 32)
        assert out.sh.shape == (3, 9, 3) and out.valid.shape == (32, 32) and out.valid.dtype == torch.bool
        assert out.mirror_ball.dtype == torch.float32 and len(out) == 3

    @pytest.mark.parametrize("g", [0.1, 0.5, 0.8])
    def test_constant_grey(self, g):
        """A constant sRGB grey g gives L = srgb_to_linear(g) / albedo on every pixel of the ball."""
        out = UniformEstimator()(grey(g, 2))
        want = srgb_to_linear(torch.full((3, 1, 1), g)).flatten() / ALBEDO  # (3,)
        expected = want[None, :, None, None] * VALID
        torch.testing.assert_close(out.mirror_ball, expected.expand(2, 3, 32, 32))
        torch.testing.assert_close(out.log_mirror_ball, torch.log1p(expected).expand(2, 3, 32, 32))
        assert (out.mirror_ball[:, :, ~VALID] == 0).all()
        torch.testing.assert_close(out.sh[:, 0], want.expand(2, 3) * math.sqrt(4 * math.pi))
        assert (out.sh[:, 1:] == 0).all()

    def test_sh_matches_projection(self):
        out = UniformEstimator()(face_like(2))
        torch.testing.assert_close(out.sh, sh_project(out.mirror_ball), atol=1e-4, rtol=1e-4)

    def test_units(self):
        """A white Lambertian surface (albedo 1) under the estimate shows mean / albedo (docs/conventions.rst,
        "Units of lighting")."""
        crops = face_like(1)
        out = UniformEstimator(albedo=1.0)(crops)
        spheres = out.render_spheres(16)
        # the diffuse sphere has albedo 0.8; its centre pixel sees the whole upper hemisphere of a constant L
        torch.testing.assert_close(
            spheres["diffuse"][0, :, 8, 8] / 0.8, out.mirror_ball[0, :, 16, 16], rtol=1e-3, atol=0
        )

    @pytest.mark.parametrize("value", [0.0, 1.0, 0.99, 0.01])
    def test_no_nan_on_flat_extremes(self, value):
        """All clipped (white) or all dark (black): the whole-ellipse mean is used, never NaN."""
        out = UniformEstimator()(grey(value, 2))
        assert torch.isfinite(out.mirror_ball).all() and torch.isfinite(out.sh).all()
        want = srgb_to_linear(torch.full((3, 1, 1), value)).flatten() / ALBEDO
        torch.testing.assert_close(out.mirror_ball[:, :, 16, 16], want.expand(2, 3))

    def test_batch_independence(self):
        crops = torch.cat([grey(1.0), face_like(1), grey(0.0)])
        together = UniformEstimator()(crops)
        for i in range(3):
            alone = UniformEstimator()(crops[i : i + 1])
            torch.testing.assert_close(together.mirror_ball[i : i + 1], alone.mirror_ball, atol=0, rtol=0)

    def test_excluded_pixels(self):
        """Clipped and dark pixels in the ellipse, and anything outside it, do not change the estimate."""
        base = grey(0.5)
        want = uniform_lighting(base)
        crops = base.clone()
        crops[..., 120:130, 100:110] = 1.0  # specular highlight (clipped)
        crops[..., 120:130, 150:160] = 0.0  # nostril / pupil (dark)
        crops[:, 0, 140:150, 125:135] = 0.99  # one clipped channel suffices
        crops[..., :20, :] = 0.9  # above the ellipse
        crops[..., :, :40] = 0.2  # left of the ellipse
        torch.testing.assert_close(uniform_lighting(crops), want)
        crops[..., 128, 128] = 0.6  # but a face pixel does
        assert not torch.equal(uniform_lighting(crops), want)

    def test_face_ellipse(self):
        mask = face_ellipse(256)
        # semi-axes 0.35 and 0.45 of the face box (0.8 of the crop): 71.68 and 92.16 pixels around 128
        rows, cols = mask.nonzero().unbind(1)
        assert (cols.min().item(), cols.max().item()) == (56, 199)
        assert (rows.min().item(), rows.max().item()) == (36, 219)
        assert abs(mask.sum().item() - math.pi * 0.28 * 0.36 * 256**2) < 200

    def test_exception(self):
        with pytest.raises(
            ShapeError, match=r"crops must have shape \(B, 3, 256, 256\), got \(1, 3, 128, 128\)"
        ):
            UniformEstimator()(grey(0.5, size=128))
        with pytest.raises(ShapeError, match=r"crops must have shape \(B, 3, S, S\)"):
            uniform_lighting(torch.rand(1, 3, 8, 6))
        with pytest.raises(ValueCheckError, match="albedo must be one or three positive finite values"):
            UniformEstimator(albedo=(0.5, 0.0, 0.5))
        with pytest.raises(ValueCheckError, match="albedo must be one or three positive finite values"):
            uniform_lighting(grey(0.5, size=8), albedo=(0.5, 0.5))

    def test_gradcheck(self):
        crops = face_like(2, size=16).double().requires_grad_()
        assert torch.autograd.gradcheck(uniform_lighting, (crops,), fast_mode=True)

    def test_module_matches_functional(self):
        crops = face_like(2)
        out = UniformEstimator(albedo=(0.4, 0.3, 0.2), clip_threshold=0.9, dark_threshold=0.1)(crops)
        want = uniform_lighting(crops, (0.4, 0.3, 0.2), 0.9, 0.1)
        torch.testing.assert_close(out.mirror_ball[:, :, 16, 16], want, atol=0, rtol=0)

    @pytest.mark.parametrize("dtype", [torch.float16, torch.bfloat16, torch.float32])
    def test_dtypes(self, dtype):
        crops = face_like(2).to(dtype)
        out = UniformEstimator()(crops)
        reference = UniformEstimator()(crops.double())
        assert out.mirror_ball.dtype == out.sh.dtype == dtype
        assert_close_dtype(out.mirror_ball, reference.mirror_ball, dtype)
        assert_close_dtype(out.sh, reference.sh, dtype, scale=4)

    def test_compile(self):
        crops = face_like(2, size=32)
        compiled = torch.compile(uniform_lighting)
        torch.testing.assert_close(compiled(crops), uniform_lighting(crops), **TOL[torch.float32])

    def test_created_by_name(self):
        est = create_estimator("uniform", albedo=0.5)
        assert isinstance(est, UniformEstimator)
        torch.testing.assert_close(
            est(grey(0.5)).mirror_ball[0, :, 16, 16], torch.full((3,), 0.2140 / 0.5), rtol=1e-3, atol=0
        )

    def test_doctests(self):
        result = doctest.testmod(kornia_ilum_uniform.estimator, extraglobs={"torch": torch})
        assert result.failed == 0 and result.attempted >= 3
