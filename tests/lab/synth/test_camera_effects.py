"""Phone-camera effects: shapes, ranges, determinism, identity at zero strength, and what each one does."""

from __future__ import annotations

import pytest
import torch

from kornia_ilum.color import encode_srgb8, linear_to_srgb
from kornia_ilum.core.errors import ShapeError, ValueCheckError
from kornia_ilum_lab.synth.camera_effects import (
    CameraEffects,
    RandomHighlightRolloff,
    RandomJpeg,
    RandomLensBlur,
    RandomSensorNoise,
    RandomToneCurve,
    RandomVignette,
    encode_tone8,
    highlight_rolloff,
    jpeg_compress,
    lens_blur,
    sensor_noise,
    tone_curve,
    vignette,
)


def gen(seed: int = 0) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


@pytest.fixture
def linear() -> torch.Tensor:
    """Smooth linear images with edges (a photo-like mix), in [0, 1.5]."""
    y, x = torch.meshgrid(torch.linspace(0, 1, 32), torch.linspace(0, 1, 32), indexing="ij")
    base = torch.stack([x, y, (x + y) / 2]) * 1.5
    base[:, 8:20, 8:20] = 0.05
    return torch.stack([base, base.flip(-1), base * 0.3, base.flip(-2)])


MODULES = [RandomLensBlur(p=1.0), RandomVignette(p=1.0), RandomSensorNoise(p=1.0), RandomToneCurve(p=1.0),
           RandomJpeg(p=1.0), RandomHighlightRolloff(p=1.0)]


@pytest.mark.parametrize("module", MODULES, ids=lambda m: type(m).__name__)
def test_modules_shape_determinism_and_identity(module, linear) -> None:
    x = linear.clamp(0, 1)
    a, b = module(x, gen(1)), module(x, gen(1))
    assert a.shape == x.shape and a.dtype == x.dtype and torch.isfinite(a).all()
    assert torch.equal(a, b)  # the generator decides everything
    assert not torch.equal(a, x)
    off = type(module)(p=0.0)
    assert torch.equal(off(x, gen(1)), x)  # probability 0: the identity


def test_functionals_identity_at_zero(linear) -> None:
    zero = torch.zeros(4)
    assert torch.equal(lens_blur(linear, zero), linear)
    assert torch.equal(vignette(linear, zero), linear)
    assert torch.equal(sensor_noise(linear, zero, read=zero, generator=gen()), linear)
    x = linear.clamp(0, 1)
    assert torch.equal(tone_curve(x, zero, torch.ones(4)), x)
    codes = encode_srgb8(linear)
    assert torch.equal(jpeg_compress(codes, zero), codes)
    assert torch.equal(highlight_rolloff(linear, zero), linear)
    assert torch.equal(encode_tone8(linear, zero, torch.ones(4)), codes)


def test_lens_blur_keeps_the_mean_and_smooths(linear) -> None:
    out = lens_blur(linear, torch.tensor([0.0, 0.5, 1.0, 1.0]))
    torch.testing.assert_close(out.mean((1, 2, 3)), linear.mean((1, 2, 3)), rtol=2e-3, atol=0)
    grad = lambda t: (t[..., 1:] - t[..., :-1]).abs().mean((1, 2, 3))  # noqa: E731
    assert (grad(out)[1:] < grad(linear)[1:]).all() and grad(out)[2] < grad(out)[1]
    with pytest.raises(ValueCheckError):
        lens_blur(linear, -1.0)


def test_vignette_darkens_the_corners_only() -> None:
    out = vignette(torch.ones(2, 3, 16, 16), torch.tensor([0.0, 0.3]))
    assert out[1, :, 0, 0].max() < 0.75 and out[1, :, 7:9, 7:9].min() > 0.99
    assert (out <= 1).all() and (out > 0).all()
    with pytest.raises(ValueCheckError):
        vignette(torch.ones(1, 3, 4, 4), 1.5)


def test_sensor_noise_is_signal_dependent() -> None:
    x = torch.cat([torch.full((1, 3, 64, 64), 0.01), torch.full((1, 3, 64, 64), 0.5)])
    out = sensor_noise(x, 1e-3, read=0.0, generator=gen())
    std = (out - x).std((1, 2, 3))
    torch.testing.assert_close(std, torch.tensor([0.01, 0.5]).mul(1e-3).sqrt(), rtol=0.05, atol=0)
    given = torch.randn(x.shape, generator=gen(3))
    torch.testing.assert_close(sensor_noise(x, 1e-3, read=0.0, noise=given), x + (x * 1e-3).sqrt() * given)
    with pytest.raises(ShapeError):
        sensor_noise(x, 1e-3, noise=torch.zeros(1, 3, 4, 4))


def test_tone_curve_is_monotone_with_fixed_ends() -> None:
    x = torch.linspace(0, 1, 257).reshape(1, 1, 1, -1).expand(3, 1, 1, -1)
    y = tone_curve(x, torch.tensor([0.6, -0.2, 0.9]), torch.tensor([0.8, 1.25, 1.0]))
    assert (y[..., 1:] >= y[..., :-1]).all() and (y[..., 0] == 0).all() and (y[..., -1] == 1).all()
    with pytest.raises(ValueCheckError, match="monotone"):
        tone_curve(x, 1.0)


def test_highlight_rolloff_keeps_highlights_apart_below_white() -> None:
    x = torch.logspace(-3, 4, 200, dtype=torch.float64).reshape(1, 1, 1, -1).expand(4, 3, 1, -1)
    s = torch.tensor([0.0, 0.25, 0.5, 0.6], dtype=torch.float64)
    y = highlight_rolloff(x, s)
    assert (y[1:].diff(dim=-1) > 0).all() and (y[1:] < 1).all()  # increasing, never white
    knee = x <= (1 - s).reshape(-1, 1, 1, 1)
    assert torch.equal(y[knee], x[knee])  # the identity below the knee: mid-grey and the skin stay where they are
    # slope 1 at the knee (continuous), and white at 1 compressed to k + s / 2
    k = 1 - 0.5
    eps = 1e-6
    at = torch.tensor([k - eps, k + eps], dtype=torch.float64).reshape(1, 1, 1, 2)
    assert highlight_rolloff(at, 0.5).diff().item() == pytest.approx(2 * eps, rel=1e-4)
    assert highlight_rolloff(torch.ones(1, 1, 1, 1), 0.5).item() == pytest.approx(0.75, abs=1e-6)
    # the 8-bit encoding now tells 1, 2, 4 and 8 times white apart, where plain sRGB clips them all to 255
    codes = encode_tone8(torch.tensor([1.0, 2.0, 4.0, 8.0]).reshape(1, 1, 1, 4), 0.0, rolloff=0.5).flatten()
    assert (codes.diff() > 0).all() and (codes < 255).all()
    for bad in (1.0, -0.1, float("nan")):
        with pytest.raises(ValueCheckError, match="strength"):
            highlight_rolloff(x, bad)
    with pytest.raises(ValueCheckError, match="rolloff"):
        encode_tone8(x, 0.0, rolloff=1.0)


def test_encode_tone8_matches_the_curve_on_srgb(linear) -> None:
    c, g = torch.tensor([0.5, -0.2, 0.0, 0.3]), torch.tensor([1.0, 1.2, 0.8, 1.0])
    codes = encode_tone8(linear, c, g)
    expected = (tone_curve(linear_to_srgb(linear.clamp(0, 1)), c, g) * 255).round()
    diff = (codes.float() - expected).abs()
    assert codes.dtype == torch.uint8 and diff.max() <= 1 and (diff > 0).float().mean() < 0.01


def test_jpeg_changes_bytes_more_at_low_quality(linear) -> None:
    codes = encode_srgb8(sensor_noise(linear, 1e-3, generator=gen()))
    low, high = jpeg_compress(codes, 40), jpeg_compress(codes, 95)
    assert low.dtype == torch.uint8 and low.shape == codes.shape
    err = lambda t: (t.float() - codes.float()).abs().mean()  # noqa: E731
    assert err(low) > err(high) > 0
    as_float = jpeg_compress(codes.float() / 255, torch.tensor([40, 40, 40, 40]))
    torch.testing.assert_close(as_float, low.float() / 255)
    with pytest.raises(ValueCheckError):
        jpeg_compress(codes, 101)


def test_camera_effects_pipeline(linear) -> None:
    fx = CameraEffects()
    p1, p2 = fx.draw(16, gen(5)), fx.draw(16, gen(5))
    assert all(torch.equal(p1[k], p2[k]) for k in p1)
    x = linear.repeat(4, 1, 1, 1)
    a = fx.apply(x, p1, generator=gen(6))
    assert a.dtype == torch.uint8 and a.shape == x.shape
    assert torch.equal(a, fx.apply(x, p2, generator=gen(6)))
    assert not torch.equal(a, encode_srgb8(x))
    off = CameraEffects.off()
    assert torch.equal(off.apply(x, off.draw(16, gen(5))), encode_srgb8(x))
    # switching one effect off leaves the other effects' draws unchanged
    q = CameraEffects(jpeg_p=0.0).draw(16, gen(5))
    assert torch.equal(q["noise"], p1["noise"]) and (q["jpeg"] == 0).all()
    # the roll-off, added last, is drawn last: the other effects' draws are those of the camera before it
    g = gen(5)
    before = {name: m.draw(16, g) for name, m in fx.modules().items() if name != "rolloff"}
    assert all(torch.equal(before[k], p1[k]) for k in before)
    assert 0.2 < (p1["rolloff"] > 0).float().mean() < 0.8
    with pytest.raises(ValueCheckError):
        CameraEffects(tone_contrast=(-0.5, 1.0))


# ----------------------------------------------------------------------------------------------
# the fused path of CameraEffects.apply against the unfused reference


def photo(n: int = 8, seed: int = 0) -> torch.Tensor:
    """Smooth linear images (upsampled noise) in [0, 1.2]: photo-like content for the JPEG."""
    g = gen(seed)
    return torch.nn.functional.interpolate(torch.rand(n, 3, 8, 8, generator=g), size=48, mode="bilinear") * 1.2


def code_diff(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    return (a.int() - b.int()).abs()


@pytest.mark.parametrize("kw", [{}, {"blur_p": 1.0, "vignette_p": 1.0, "noise_p": 1.0, "tone_p": 1.0},
                                {"noise_p": 0.0}, {"tone_p": 0.0, "blur_p": 1.0}],
                         ids=["defaults", "all", "no-noise", "untoned"])
def test_fused_apply_equals_the_reference(kw) -> None:
    fx = CameraEffects(**{**kw, "jpeg_p": 0.0})
    x = photo(16)
    params = fx.draw(16, gen(3))
    gain = torch.linspace(0.5, 2.0, 16, dtype=torch.float64)
    fused = fx.apply(x, params, generator=gen(4), gain=gain)
    ref = fx.apply_reference(x, params, generator=gen(4), gain=gain)
    diff = code_diff(fused, ref)
    assert fused.dtype == torch.uint8 and diff.max() <= 1 and (diff > 0).float().mean() < 1e-3
    assert torch.equal(fused, fx.apply(x, params, generator=gen(4), gain=gain))  # deterministic


def test_fused_apply_with_jpeg_stays_close_to_the_reference() -> None:
    fx = CameraEffects(jpeg_p=1.0)
    x = photo(8)
    params = fx.draw(8, gen(5))
    fused, ref = fx.apply(x, params, generator=gen(6)), fx.apply_reference(x, params, generator=gen(6))
    diff = code_diff(fused, ref)
    assert (diff > 0).float().mean() < 0.01 and diff.float().mean() < 0.01


def test_fused_apply_gain_noise_views_and_input() -> None:
    fx = CameraEffects(blur_p=0.5, vignette_p=0.5, noise_p=1.0, jpeg_p=0.0)
    x = photo(6)
    kept = x.clone()
    params = fx.draw(6, gen(7))
    bank = torch.randn(2, 3, 64, 64, generator=gen(8))
    views = [bank[k % 2, :, k : k + 48, 2 * k : 2 * k + 48] for k in range(6)]  # non-contiguous windows
    gain = torch.full((6,), 1.5, dtype=torch.float64)
    a = fx.apply(x, params, noise=views, gain=gain)
    assert torch.equal(x, kept)  # the input is never written
    assert torch.equal(a, fx.apply(x, params, noise=torch.stack(views), gain=gain))
    diff = code_diff(a, fx.apply(x * 1.5, params, noise=torch.stack(views)))  # gain = pre-exposed input
    assert diff.max() <= 1 and (diff > 0).float().mean() < 1e-3
    diff = code_diff(a, fx.apply(x.double(), params, noise=views, gain=gain))  # float64: the reference path
    assert diff.max() <= 1 and (diff > 0).float().mean() < 1e-3
    with pytest.raises(ShapeError):
        fx.apply(x, params, noise=views[:3])


def test_fused_noise_keeps_its_statistics() -> None:
    fx = CameraEffects(blur_p=0.0, vignette_p=0.0, noise_p=1.0, tone_p=0.0, jpeg_p=0.0, noise_shot=(1e-3, 1e-3))
    x = torch.full((2, 3, 64, 64), 0.2)
    codes = fx.apply(x, fx.draw(2, gen(9)), generator=gen(10))
    noisy = sensor_noise(x, 1e-3, generator=gen(10))  # the same normals: one randn of x's shape
    diff = code_diff(codes, encode_srgb8(noisy))
    assert diff.max() <= 1 and (diff > 0).float().mean() < 1e-3


def test_lens_blur_opencv_matches_the_convolutions(linear) -> None:
    sigma = torch.tensor([0.0, 0.3, 0.7, 1.0])
    fast = lens_blur(linear, sigma)  # float32 on CPU: OpenCV
    ref = lens_blur(linear.double(), sigma)  # grouped convolutions
    torch.testing.assert_close(fast.double(), ref, rtol=1e-5, atol=1e-6)
    assert torch.equal(fast[0], linear[0])


def test_encode_tone8_mixed_batch_matches_the_reference(linear) -> None:
    from kornia_ilum_lab.synth.camera_effects import _encode_tone8_reference

    c, g = torch.tensor([0.0, 0.4, 0.0, -0.1], dtype=torch.float64), torch.tensor([1.0, 1.0, 0.9, 1.1],
                                                                                  dtype=torch.float64)
    assert torch.equal(encode_tone8(linear, c, g), _encode_tone8_reference(linear, c, g))
    assert torch.equal(encode_tone8(linear, c, g)[0], encode_srgb8(linear[0]))
    s = torch.tensor([0.0, 0.3, 0.5, 0.0], dtype=torch.float64)
    diff = code_diff(encode_tone8(linear, c, g, s), _encode_tone8_reference(linear, c, g, s))
    assert diff.max() <= 1 and (diff > 0).float().mean() < 1e-3


def test_jpeg_compress_equals_the_strided_round_trip(linear) -> None:
    import cv2
    import numpy as np

    codes = encode_srgb8(linear)
    out = jpeg_compress(codes, torch.tensor([0, 40, 70, 95]))
    assert torch.equal(out[0], codes[0])
    for k, q in ((1, 40), (2, 70), (3, 95)):
        bgr = np.ascontiguousarray(codes[k].flip(0).permute(1, 2, 0).numpy())
        dec = cv2.imdecode(cv2.imencode(".jpg", bgr, [int(cv2.IMWRITE_JPEG_QUALITY), q])[1], cv2.IMREAD_COLOR)
        assert torch.equal(out[k], torch.from_numpy(dec).permute(2, 0, 1).flip(0))
