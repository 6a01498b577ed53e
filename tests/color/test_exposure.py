"""Exposure (kornia_ilum.color.exposure): centre-weighted metering and exposure normalisation."""

from __future__ import annotations

import pytest
import torch

from kornia_ilum.color import (
    EXPOSURE_KEY,
    MeteredLuminance,
    NormalizeExposure,
    centre_weights,
    linear_to_srgb,
    metered_luminance,
    normalize_exposure,
    srgb_to_linear,
)
from kornia_ilum.core.errors import ShapeError, ValueCheckError
from kornia_ilum_lab.synth.lightstage.portraits.compose import auto_exposure


def test_weights_are_the_cameras():
    """The same weights as the light stage's auto-exposure: a plain image meters to its luminance there too."""
    w = centre_weights(16, 12)
    assert w.shape == (16, 12) and abs(float(w.sum()) - 1.0) < 1e-12
    torch.testing.assert_close(w[7:9, 5:7], w.max().expand(2, 2)) and torch.testing.assert_close(w, w.flip(0).flip(1))
    image = torch.rand(1, 3, 16, 12, dtype=torch.float64)
    gain = auto_exposure(image, 0.18, white=None)
    torch.testing.assert_close(gain * metered_luminance(image), torch.tensor([0.18], dtype=torch.float64))


def test_metering_is_linear():
    x = torch.rand(3, 3, 8, 8)
    torch.testing.assert_close(metered_luminance(0.25 * x), 0.25 * metered_luminance(x))


@pytest.mark.parametrize("k", [0.5, 0.25, 0.1])
def test_exposure_comes_back_exactly(k):
    """k times less light (nothing clips anew): the same normalised crop, k times the factor."""
    x = torch.rand(2, 3, 32, 32, dtype=torch.float64)
    x[0, :, :4, :4] = 1.0  # clipped in the photo: stays what it is
    a, s = normalize_exposure(x)
    b, t = normalize_exposure(linear_to_srgb(k * srgb_to_linear(x)))
    torch.testing.assert_close(b, a, atol=1e-9, rtol=0)
    torch.testing.assert_close(t, k * s)
    torch.testing.assert_close(metered_luminance(srgb_to_linear(a).clamp(max=1.0)).min(),
                               torch.tensor(EXPOSURE_KEY, dtype=torch.float64), atol=0.05, rtol=0)


def test_black_and_bright_crops_stay_finite():
    out, scale = normalize_exposure(torch.zeros(1, 3, 8, 8))
    assert torch.equal(out, torch.zeros(1, 3, 8, 8)) and float(scale) > 0
    out, scale = normalize_exposure(torch.ones(1, 3, 8, 8))
    assert float(out.max()) <= 1.0 and torch.isfinite(scale).all()


def test_gradients_flow():
    x = (0.1 + 0.8 * torch.rand(1, 3, 8, 8, dtype=torch.float64)).requires_grad_()
    assert torch.autograd.gradcheck(lambda c: normalize_exposure(c)[0], (x,), fast_mode=True)


def test_module_and_errors():
    x = torch.rand(2, 3, 8, 8)
    a, s = NormalizeExposure()(x)
    b, t = normalize_exposure(x)
    assert torch.equal(a, b) and torch.equal(s, t)
    assert torch.equal(MeteredLuminance(0.1)(x), metered_luminance(x, 0.1))
    with pytest.raises(ValueCheckError, match="key"):
        normalize_exposure(x, key=0.0)
    with pytest.raises(ValueCheckError, match="sigma"):
        centre_weights(4, 4, sigma=0.0)
    with pytest.raises(ShapeError):
        metered_luminance(torch.rand(3, 8, 8))


def test_the_cached_metering_map_serves_autograd_after_inference_mode():
    from kornia_ilum.color.exposure import _metering_map

    _metering_map.cache_clear()
    with torch.inference_mode():
        metered_luminance(torch.rand(1, 3, 8, 8, dtype=torch.float64))  # built here first
    x = torch.rand(1, 3, 8, 8, dtype=torch.float64, requires_grad=True)
    metered_luminance(x).sum().backward()
    assert x.grad is not None and torch.isfinite(x.grad).all()
