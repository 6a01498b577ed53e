"""Tests of kornia_ilum.estimators.tta: windows, their resampling, SH mirroring, the average, the wrapper."""

from __future__ import annotations

import math

import pytest
import skimage.data
import torch
import torch.nn.functional as F

from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.detection import crop_faces
from kornia_ilum.estimators import (
    EstimatorInfo,
    LightingEstimate,
    LightingEstimator,
    TestTimeAugmented,
    average_estimates,
    create_estimator,
    crop_windows,
    jitter_windows,
    mirror_sh,
)
from kornia_ilum.geometry import flip_lighting_horizontal, mirror_ball_valid
from kornia_ilum.sh import sh_project, sh_reconstruct

VALID = mirror_ball_valid(32)
SIZE = 16  # the input size of the small fake estimators below


class Probe(LightingEstimator):
    """Sensitive to position and not mirror-symmetric: the crop's area-downsampled colours, weighted by an
    asymmetric ramp, as the mirror ball (plus a constant, so it is positive). Counts its calls."""

    info = EstimatorInfo("probe", "a test probe", "none: a test", input_size=SIZE, needs_weights=False)

    def __init__(self) -> None:
        super().__init__()
        self.calls: list[int] = []

    def predict(self, crops):
        self.calls.append(crops.shape[0])
        ramp = torch.linspace(1.0, 3.0, 32, dtype=crops.dtype, device=crops.device)
        ball = (F.interpolate(crops, size=(32, 32), mode="area") * ramp + 0.25) * VALID.to(crops.device)
        valid = VALID.to(crops.device)
        return LightingEstimate(mirror_ball=ball, valid=valid, log_mirror_ball=torch.log1p(ball))


class Constant(LightingEstimator):
    """The same lighting for every crop (crop-invariant), with its SH coefficients."""

    info = EstimatorInfo("constant", "a test constant", "none: a test", input_size=SIZE, needs_weights=False)

    def __init__(self, ball: torch.Tensor, sh: torch.Tensor | None = None) -> None:
        super().__init__()
        self.ball, self.sh = ball, sh

    def predict(self, crops):
        n = crops.shape[0]
        sh = None if self.sh is None else self.sh.expand(n, 9, 3)
        return LightingEstimate(mirror_ball=self.ball.expand(n, 3, 32, 32), valid=VALID, sh=sh)


def _asymmetric_ball() -> torch.Tensor:
    """Dyadic values (exact sums), brighter on the right: light from +X."""
    cols = torch.where(torch.arange(32) < 16, 0.5, 2.0)
    return (cols.expand(1, 3, 32, 32) * VALID).clone()


def _crops(batch: int = 3, size: int = SIZE, seed: int = 0, dtype=torch.float32) -> torch.Tensor:
    return torch.rand(batch, 3, size, size, generator=torch.Generator().manual_seed(seed), dtype=dtype)


class TestJitterWindows:
    def test_smoke(self):
        w = jitter_windows(4)
        assert w.shape == (4, 3) and w.dtype == torch.float64
        assert w[0].tolist() == [1.0, 0.0, 0.0]

    @pytest.mark.parametrize("jitters, zoom, shift", [(8, 0.15, 0.10), (16, 0.5, 0.3), (5, 0.0, 0.2)])
    def test_inside_the_crop(self, jitters, zoom, shift):
        w = jitter_windows(jitters, zoom, shift, seed=3)
        side, offset = w[:, 0], w[:, 1:]
        assert (side <= 1.0).all() and (side >= math.exp(-zoom) - 1e-12).all()
        assert (offset.abs() <= shift + 1e-12).all()
        assert (offset.abs().amax(dim=1) + side / 2 <= 0.5 + 1e-12).all()

    def test_zoom_stratified(self):
        side = jitter_windows(5, zoom=0.4)[1:, 0]
        u = -torch.log(side) / 0.4
        assert ((u >= torch.arange(4) / 4) & (u <= torch.arange(1, 5) / 4)).all()  # one per quarter

    def test_deterministic(self):
        torch.testing.assert_close(jitter_windows(6, seed=7), jitter_windows(6, seed=7), rtol=0, atol=0)
        assert not torch.equal(jitter_windows(6, seed=7), jitter_windows(6, seed=8))
        identities = torch.tensor([[1.0, 0.0, 0.0]] * 6, dtype=torch.float64)
        assert torch.equal(jitter_windows(6, zoom=0.0, shift=0.0), identities)

    def test_exception(self):
        with pytest.raises(TypeCheckError, match="jitters must be an int"):
            jitter_windows(2.0)
        with pytest.raises(ValueCheckError, match="jitters must be positive"):
            jitter_windows(0)
        with pytest.raises(ValueCheckError, match=r"zoom must be finite and in \[0, inf\)"):
            jitter_windows(2, zoom=-0.1)
        with pytest.raises(ValueCheckError, match=r"shift must be finite and in \[0, 0.5\)"):
            jitter_windows(2, shift=0.5)
        with pytest.raises(TypeCheckError, match="zoom must be a number"):
            jitter_windows(2, zoom="big")
        with pytest.raises(TypeCheckError, match="seed must be an int"):
            jitter_windows(2, seed=1.5)


class TestCropWindows:
    def test_identity_is_exact(self):
        x = _crops(2)
        ident = torch.tensor([[1.0, 0.0, 0.0]])
        assert torch.equal(crop_windows(x, ident), x)
        assert torch.equal(crop_windows(x, ident, mirror=True), x.flip(-1))

    def test_cardinality_window_major(self):
        x = _crops(3)
        w = jitter_windows(4)
        out = crop_windows(x, w)
        assert out.shape == (12, 3, SIZE, SIZE)
        assert torch.equal(out[:3], x)
        torch.testing.assert_close(out[3:6], crop_windows(x, w[1:2]))

    def test_linear_ramp(self, dtype):
        """Bilinear resampling reproduces a linear image exactly: the window's pixel centres."""
        size = 32
        j = torch.arange(size, dtype=dtype) + 0.5  # continuous coordinate of each pixel's centre
        ramp = torch.stack(torch.broadcast_tensors(j[None, :], j[:, None]))[None]  # (1, 2, S, S): x, y
        side, dx, dy = 0.75, 0.05, -0.08
        out = crop_windows(ramp, torch.tensor([[side, dx, dy]]))
        i = torch.arange(size, dtype=dtype) + 0.5
        x_expected = (0.5 + dx - side / 2) * size + i * side
        y_expected = (0.5 + dy - side / 2) * size + i * side
        torch.testing.assert_close(out[0, 0], x_expected[None, :].expand(size, size))
        torch.testing.assert_close(out[0, 1], y_expected[:, None].expand(size, size))

    def test_mirror(self):
        x, w = _crops(2), jitter_windows(3, seed=1)
        torch.testing.assert_close(crop_windows(x, w, mirror=True), crop_windows(x.flip(-1), w))

    def test_values_stay_in_range(self):
        x = _crops(2)
        out = crop_windows(x, jitter_windows(6, zoom=0.5, shift=0.3))
        assert out.min() >= x.min() and out.max() <= x.max()

    @pytest.mark.parametrize("dt", [torch.float16, torch.bfloat16, torch.float64])
    def test_dtypes(self, dt):
        x = _crops(2)
        w = jitter_windows(3)
        out = crop_windows(x.to(dt), w)
        assert out.dtype == dt
        tol = {torch.float16: 2e-3, torch.bfloat16: 2e-2, torch.float64: 1e-6}[dt]
        torch.testing.assert_close(out.float(), crop_windows(x, w), atol=tol, rtol=0)

    def test_gradcheck(self):
        x = _crops(1, size=6, dtype=torch.float64).requires_grad_()
        w = torch.tensor([[0.8, 0.05, -0.05], [1.0, 0.0, 0.0]], dtype=torch.float64)
        assert torch.autograd.gradcheck(lambda t: crop_windows(t, w, mirror=True), (x,))

    def test_exception(self):
        with pytest.raises(ShapeError, match="crops must have shape .*it must be square"):
            crop_windows(torch.rand(1, 3, 8, 9), jitter_windows(2))
        with pytest.raises(ShapeError, match=r"windows must have shape \(K, 3\)"):
            crop_windows(_crops(1), torch.ones(2, 2))


class TestMirrorSh:
    def test_signs(self):
        assert mirror_sh(torch.ones(9, 1)).flatten().tolist() == [1, 1, 1, -1, -1, 1, 1, -1, 1]

    def test_agrees_with_the_mirrored_lighting(self):
        g = torch.Generator().manual_seed(0)
        lighting = torch.rand(2, 3, 32, 32, generator=g, dtype=torch.float64) * VALID
        torch.testing.assert_close(
            sh_project(flip_lighting_horizontal(lighting)), mirror_sh(sh_project(lighting))
        )

    def test_involution_and_dtype(self):
        sh = torch.randn(4, 9, 3, dtype=torch.float16)
        assert mirror_sh(sh).dtype == torch.float16
        assert torch.equal(mirror_sh(mirror_sh(sh)), sh)

    def test_exception(self):
        with pytest.raises(ShapeError):
            mirror_sh(torch.ones(4, 3))


class TestAverageEstimates:
    def test_arithmetic_mean(self):
        balls = torch.tensor([1.0, 4.0, 3.0, 0.0]).view(4, 1, 1, 1) * VALID.expand(4, 3, 32, 32)
        sh = torch.arange(4.0).view(4, 1, 1).expand(4, 9, 3)
        est = LightingEstimate(mirror_ball=balls, valid=VALID, log_mirror_ball=torch.log1p(balls), sh=sh)
        avg = average_estimates(est, 2)  # passes of 2 crops: crop 0 = (1, 3), crop 1 = (4, 0)
        assert len(avg) == 2
        torch.testing.assert_close(avg.mirror_ball[:, 0, 16, 16], torch.tensor([2.0, 2.0]))
        torch.testing.assert_close(avg.log_mirror_ball, torch.log1p(avg.mirror_ball))
        torch.testing.assert_close(avg.sh[:, 0, 0], torch.tensor([1.0, 2.0]))
        assert avg.valid is est.valid

    def test_energy_is_the_mean_energy(self):
        g = torch.Generator().manual_seed(0)
        balls = torch.rand(8, 3, 32, 32, generator=g) * VALID * 10
        avg = average_estimates(LightingEstimate(mirror_ball=balls, valid=VALID), 4)
        torch.testing.assert_close(avg.mirror_ball.sum((1, 2, 3)), balls.sum((1, 2, 3)).view(4, 2).mean(0))

    def test_half(self):
        balls = torch.ones(4, 3, 32, 32, dtype=torch.bfloat16) * VALID
        avg = average_estimates(LightingEstimate(mirror_ball=balls, valid=VALID, log_mirror_ball=balls), 4)
        assert avg.mirror_ball.dtype == avg.log_mirror_ball.dtype == torch.bfloat16

    def test_exception(self):
        est = LightingEstimate(mirror_ball=torch.ones(3, 3, 32, 32) * VALID, valid=VALID)
        with pytest.raises(ValueCheckError, match="3 estimates cannot be 2 passes"):
            average_estimates(est, 2)


class TestTestTimeAugmented:
    def test_smoke_and_info(self):
        probe = Probe()
        tta = TestTimeAugmented(probe, jitters=3)
        assert tta.passes == 6
        assert tta.info.name == "probe+tta" and tta.info.input_size == SIZE
        assert type(tta).info.name == "tta" and Probe.info.name == "probe"  # class metadata untouched
        assert "jitters=3, mirror=True" in repr(tta)
        est = tta(_crops(2))
        assert isinstance(est, LightingEstimate) and len(est) == 2

    def test_one_batched_call(self):
        probe = Probe()
        TestTimeAugmented(probe, jitters=4)(_crops(3))
        assert probe.calls == [24]

    def test_identity(self):
        """jitters=1 and mirror=False is the wrapped estimator itself."""
        net = create_estimator("ours", pretrained=False).eval()
        x = torch.rand(2, 3, 256, 256, generator=torch.Generator().manual_seed(0))
        with torch.inference_mode():
            ref, got = net(x), TestTimeAugmented(net, jitters=1, mirror=False)(x)
        assert torch.equal(got.mirror_ball, ref.mirror_ball)
        assert torch.equal(got.log_mirror_ball, ref.log_mirror_ball)
        probe = Probe()
        x = _crops(2)
        assert torch.equal(
            TestTimeAugmented(probe, jitters=1, mirror=False)(x).mirror_ball, probe(x).mirror_ball
        )

    def test_is_the_mean_of_the_views(self):
        probe = Probe()
        x = _crops(2)
        tta = TestTimeAugmented(probe, jitters=3)
        windows = jitter_windows(3)
        plain = [probe(v).mirror_ball for v in crop_windows(x, windows).split(2)]
        mirrored = [probe(v).mirror_ball for v in crop_windows(x, windows, mirror=True).split(2)]
        expected = torch.stack(plain + [flip_lighting_horizontal(m) for m in mirrored]).mean(0)
        got = tta(x)
        torch.testing.assert_close(got.mirror_ball, expected)
        torch.testing.assert_close(got.log_mirror_ball, torch.log1p(expected))
        views = tta.estimate_views(x)
        assert len(views) == 12
        torch.testing.assert_close(views.mirror_ball.view(6, 2, 3, 32, 32).mean(0), expected)

    def test_mirror_equivariant(self):
        """With mirror=True, the estimate of the mirrored crop is the mirrored estimate, for any estimator."""
        probe = Probe()
        x = _crops(3)
        tta = TestTimeAugmented(probe, jitters=4)
        assert not torch.allclose(probe(x.flip(-1)).mirror_ball, probe(x).mirror_ball.flip(-1))  # not alone
        torch.testing.assert_close(tta(x.flip(-1)).mirror_ball, flip_lighting_horizontal(tta(x).mirror_ball))

    def test_mirror_equivariant_ours(self):
        net = create_estimator("ours")
        image = torch.from_numpy(skimage.data.astronaut()).permute(2, 0, 1).float() / 255
        x = crop_faces(image, torch.tensor([[165.0, 54.0, 286.0, 175.0]]))  # the paper's crop of the face
        tta = TestTimeAugmented(net, jitters=2)
        with torch.inference_mode():
            a, b = tta(x), tta(x.flip(-1))
        expected = flip_lighting_horizontal(a.mirror_ball)
        torch.testing.assert_close(b.mirror_ball, expected, rtol=1e-4, atol=1e-5)

    def test_deterministic(self):
        x = _crops(2)
        a = TestTimeAugmented(Probe(), jitters=4, seed=5)(x).mirror_ball
        assert torch.equal(a, TestTimeAugmented(Probe(), jitters=4, seed=5)(x).mirror_ball)
        assert not torch.equal(a, TestTimeAugmented(Probe(), jitters=4, seed=6)(x).mirror_ball)

    @pytest.mark.parametrize("mirror", [False, True])
    def test_crop_invariant_estimator_keeps_its_value(self, mirror):
        """A crop-invariant estimator gives exactly its value (mirror-symmetric, or mirror=False)."""
        ball = _asymmetric_ball() if not mirror else (_asymmetric_ball() + _asymmetric_ball().flip(-1)) / 2
        est = TestTimeAugmented(Constant(ball), jitters=4, mirror=mirror)(_crops(2))
        assert torch.equal(est.mirror_ball, ball.expand(2, 3, 32, 32))

    def test_mirror_symmetrises_a_constant(self):
        ball = _asymmetric_ball()
        est = TestTimeAugmented(Constant(ball), jitters=2)(_crops(1))
        assert torch.equal(est.mirror_ball, (ball + ball.flip(-1)) / 2)

    def test_sh_averaged_with_the_mirror(self):
        """SH coefficients are mirrored back like the mirror ball: the two stay consistent."""
        g = torch.Generator().manual_seed(0)
        sh = torch.randn(1, 9, 3, generator=g, dtype=torch.float64) * 0.1
        sh[:, 0] = 3.0  # a positive lighting
        ball = sh_reconstruct(sh, 32, "mirror_ball")
        assert (ball[:, :, VALID] > 0).all()
        est = TestTimeAugmented(Constant(ball, sh), jitters=3)(_crops(2, dtype=torch.float64))
        torch.testing.assert_close(est.sh, ((sh + mirror_sh(sh)) / 2).expand(2, 9, 3))
        torch.testing.assert_close(sh_reconstruct(est.sh, 32, "mirror_ball"), est.mirror_ball)
        assert est.log_mirror_ball is None  # the wrapped estimator has none

    def test_uniform_plugin(self):
        pytest.importorskip("kornia_ilum_uniform")
        uniform = create_estimator("uniform")
        x = torch.full((2, 3, 256, 256), 0.5)
        x[1] = 0.3
        ref = uniform(x)
        est = TestTimeAugmented(uniform, jitters=4)(x)
        torch.testing.assert_close(est.mirror_ball, ref.mirror_ball)
        assert est.mirror_ball[:, :, VALID].std(dim=-1).max() == 0  # still constant over the ball

    def test_dtypes(self, dtype):
        probe = Probe()
        x = _crops(2, dtype=dtype)
        est = TestTimeAugmented(probe, jitters=3)(x)
        assert est.mirror_ball.dtype == est.log_mirror_ball.dtype == dtype
        ref = TestTimeAugmented(probe, jitters=3)(x.double())
        torch.testing.assert_close(est.mirror_ball, ref.mirror_ball.to(dtype))

    def test_device(self, device):
        probe = Probe()
        est = TestTimeAugmented(probe, jitters=2).to(device)(_crops(1).to(device))
        assert est.mirror_ball.device.type == device.type

    def test_gradcheck(self):
        class Small(Probe):
            info = EstimatorInfo("small", "a test", "none: a test", input_size=6, needs_weights=False)

        tta = TestTimeAugmented(Small(), jitters=2)
        x = torch.rand(1, 3, 6, 6, dtype=torch.float64).clamp(0.05, 0.95).requires_grad_()
        weight = torch.rand(3, 32, 32, dtype=torch.float64)  # one scalar output: a cheap numerical Jacobian
        assert torch.autograd.gradcheck(lambda t: (tta(t).mirror_ball * weight).sum(), (x,))

    def test_modes(self):
        net = create_estimator("ours", pretrained=False)  # training mode
        assert TestTimeAugmented(net).training
        net.eval()
        tta = TestTimeAugmented(net)
        assert not tta.training
        tta.train()
        assert net.training
        assert set(tta.state_dict()) == {f"estimator.{k}" for k in net.state_dict()}

    def test_checks_the_crops(self):
        tta = TestTimeAugmented(Probe())
        with pytest.raises(ShapeError, match=r"crops must have shape \(B, 3, 16, 16\)"):
            tta(torch.rand(1, 3, 32, 32))
        with pytest.raises(ValueCheckError, match=r"crops must be sRGB-encoded values in \[0, 1\]"):
            tta(torch.full((1, 3, SIZE, SIZE), 2.0))

    def test_exception(self):
        with pytest.raises(TypeCheckError, match="must be a LightingEstimator instance, got Linear"):
            TestTimeAugmented(torch.nn.Linear(1, 1))
        with pytest.raises(TypeCheckError, match="mirror must be a bool"):
            TestTimeAugmented(Probe(), mirror=1)
        with pytest.raises(ValueCheckError, match="jitters must be positive"):
            TestTimeAugmented(Probe(), jitters=0)
        with pytest.raises(ValueCheckError, match="zoom must be finite"):
            TestTimeAugmented(Probe(), zoom=float("nan"))
