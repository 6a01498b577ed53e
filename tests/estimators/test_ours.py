"""Tests of the built-in `ours` network (LeGendre et al. 2020), untrained: shapes, dtypes, gradients."""

from __future__ import annotations

import pytest
import torch

from kornia_ilum.color import linear_to_srgb, normalize_exposure, srgb_to_linear
from kornia_ilum.core.errors import MissingWeightsError, ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.estimators import LightingEstimator, OursEstimator, create_estimator
from kornia_ilum.filters import BlurPool2D
from kornia_ilum.geometry import mirror_ball_valid

PAPER_PARAMETERS = 9.2e6
OURS_PARAMETERS = 9_219_779
VALID = mirror_ball_valid(32)


@pytest.fixture(scope="module")
def net() -> OursEstimator:
    torch.manual_seed(0)
    return OursEstimator().eval()


def crops(batch: int = 2, seed: int = 0, dtype=torch.float32) -> torch.Tensor:
    return torch.rand(batch, 3, 256, 256, generator=torch.Generator().manual_seed(seed), dtype=dtype)


def count(module: torch.nn.Module) -> int:
    return sum(p.numel() for p in module.parameters())


class TestOursEstimator:
    def test_parameter_count_9_219_779_within_15_percent_of_9_2M(self, net):
        """9,219,779 parameters: 0.2 % above the paper's 9.2 M (asserted within 15 %)."""
        n = count(net)
        print(f"OursEstimator parameters: {n:,}")
        assert n == OURS_PARAMETERS
        assert abs(n - PAPER_PARAMETERS) / PAPER_PARAMETERS < 0.15

    def test_architecture(self, net):
        """Five 3x3 conv + blur-pool stages (16..256), 8x8 conv, FC to 1024, decoder 64/32/16, head 3."""
        convs = [m for m in net.encoder if isinstance(m, torch.nn.Conv2d)]
        assert [c.out_channels for c in convs] == [16, 32, 64, 128, 256, 256]
        assert [c.kernel_size for c in convs] == [(3, 3)] * 5 + [(8, 8)]
        assert sum(isinstance(m, BlurPool2D) for m in net.encoder) == 5
        assert net.to_latent.out_features == 1024
        assert [m.out_channels for b in net.decoder for m in b if isinstance(m, torch.nn.Conv2d)] == [64, 32, 16]
        assert not any(isinstance(m, torch.nn.LeakyReLU) for m in net.modules())  # the paper's ReLU
        assert net.head.out_channels == 3
        # two fully-connected layers and the 8x8 convolution hold most of the parameters
        assert (count(net.to_latent) + count(net.from_latent) + count(convs[-1])) / count(net) > 0.9

    def test_smoke(self, net):
        assert isinstance(net, LightingEstimator) and net.info.name == "ours"
        assert "LeGendre" in net.info.paper and net.info.input_size == 256 and len(net.info.weights) == 1
        # the one persistent buffer: how the weights were trained (TestExposure)
        assert net.state_dict().keys() == {k for k, _ in net.named_parameters()} | {"exposure_normalized"}

    def test_cardinality(self, net):
        with torch.no_grad():
            out = net(crops(3))
        assert out.mirror_ball.shape == out.log_mirror_ball.shape == (3, 3, 32, 32)
        assert out.sh is None and out.valid.shape == (32, 32) and out.valid.dtype == torch.bool
        assert out.mirror_ball.dtype == torch.float32 and out.mirror_ball.is_contiguous()
        assert torch.equal(out.valid, VALID)

    def test_log_linear_consistency(self, net):
        """mirror_ball = expm1(log_mirror_ball), log_mirror_ball = log(1 + L) >= 0, both 0 off the ball."""
        with torch.no_grad():
            out = net(crops(2))
        torch.testing.assert_close(torch.expm1(out.log_mirror_ball), out.mirror_ball, rtol=1e-5, atol=1e-7)
        torch.testing.assert_close(torch.log1p(out.mirror_ball), out.log_mirror_ball, rtol=1e-5, atol=1e-7)
        assert (out.mirror_ball[:, :, VALID] > 0).all() and (out.log_mirror_ball >= 0).all()
        assert (out.mirror_ball[:, :, ~VALID] == 0).all() and (out.log_mirror_ball[:, :, ~VALID] == 0).all()
        assert torch.isfinite(out.mirror_ball).all()

    def test_batch_independence(self, net):
        x = crops(3)
        with torch.no_grad():
            together = net(x).mirror_ball
            alone = torch.cat([net(x[i : i + 1]).mirror_ball for i in range(3)])
        torch.testing.assert_close(together, alone, rtol=1e-4, atol=1e-6)

    def test_exception(self, net):
        with pytest.raises(
            ShapeError, match=r"crops must have shape \(B, 3, 256, 256\), got \(1, 3, 128, 128\)"
        ):
            net(torch.rand(1, 3, 128, 128))
        with pytest.raises(ValueCheckError, match=r"crops must be sRGB-encoded values in \[0, 1\]"):
            net(torch.full((1, 3, 256, 256), 2.0))
        with pytest.raises(TypeCheckError, match="latent_dim must be an int"):
            OursEstimator(latent_dim=10.0)
        with pytest.raises(ValueCheckError, match="latent_dim must be positive"):
            OursEstimator(latent_dim=0)

    def test_shipped_weights(self):
        """The shipped weights load (SHA-256 checked, safetensors) and give finite, positive lighting."""
        (weight,) = OursEstimator.info.weights
        path = OursEstimator.default_weights_dir() / weight.name
        assert path.is_file() and weight.name == "ours.safetensors"
        net = create_estimator("ours")
        assert isinstance(net, OursEstimator) and not net.training
        with torch.no_grad():
            est = net(crops(2))
        assert torch.isfinite(est.mirror_ball).all() and (est.mirror_ball[:, :, VALID] > 0).all()
        trained = {k: v.float() for k, v in net.state_dict().items()}
        fresh = OursEstimator().state_dict()
        assert any(not torch.equal(trained[k], fresh[k]) for k in fresh)
        assert count(create_estimator("ours", pretrained=False, latent_dim=64)) < OURS_PARAMETERS

    def test_missing_weights(self, untrained_name):
        with pytest.raises(MissingWeightsError, match="'untrained' is registered but ships no trained weights yet"):
            create_estimator(untrained_name)

    def test_gradients_flow(self):
        torch.manual_seed(1)
        model = OursEstimator().train()
        out = model(crops(2))
        (out.log_mirror_ball.mean() + out.mirror_ball.mean()).backward()
        for name, p in model.named_parameters():
            assert p.grad is not None and torch.isfinite(p.grad).all(), name
            assert p.grad.abs().sum() > 0, name

    def test_gradcheck(self):
        """Gradients with respect to the crops, float64, against finite differences (fast mode)."""
        torch.manual_seed(2)
        model = OursEstimator(latent_dim=32).double()
        x = (0.2 + 0.6 * crops(1, dtype=torch.float64)).requires_grad_()
        assert torch.autograd.gradcheck(lambda c: model(c).log_mirror_ball, (x,), fast_mode=True)

    def test_module_matches_functional(self, net):
        """forward = check + predict: the estimate is the network's exp(head output) on the ball."""
        x = crops(1)
        with torch.no_grad():
            normalised, scale = normalize_exposure(x)
            h = net.from_latent(net.to_latent(net.encoder(normalised - 0.5))).reshape(1, 256, 4, 4)
            for block in net.decoder:
                h = net.upsample(block(h))
            y = net.head(h) + torch.log(scale)
            y2, features, log_scale, _, _ = net.decode(x)
            torch.testing.assert_close(y2, y, atol=0, rtol=0)
            torch.testing.assert_close(log_scale.flatten(), torch.log(scale), atol=0, rtol=0)
            assert [tuple(f.shape[1:]) for f in features] == [(64, 4, 4), (32, 8, 8), (16, 16, 16)]
            torch.testing.assert_close(net(x).mirror_ball, torch.exp(y) * VALID)
            torch.testing.assert_close(net.predict(x).log_mirror_ball, net(x).log_mirror_ball, atol=0, rtol=0)

    def test_bf16_autocast(self, net):
        """Autocast runs the layers in bfloat16; the estimate stays float32 and close to the float32 one."""
        x = crops(2)
        with torch.no_grad():
            reference = net(x)
            with torch.autocast("cpu", dtype=torch.bfloat16):
                out = net(x)
        assert out.mirror_ball.dtype == out.log_mirror_ball.dtype == torch.float32
        assert torch.isfinite(out.mirror_ball).all()
        torch.testing.assert_close(out.log_mirror_ball, reference.log_mirror_ball, atol=0.05, rtol=0.05)

    def test_channels_last(self, net):
        x = crops(2)
        model = OursEstimator()
        model.load_state_dict(net.state_dict())
        model = model.to(memory_format=torch.channels_last).eval()
        assert model.encoder[0].weight.is_contiguous(memory_format=torch.channels_last)
        with torch.no_grad():
            out = model(x.contiguous(memory_format=torch.channels_last))
            reference = net(x)
        assert out.mirror_ball.is_contiguous()
        torch.testing.assert_close(out.mirror_ball, reference.mirror_ball, rtol=1e-4, atol=1e-6)

    @pytest.mark.parametrize("dtype", [torch.bfloat16, torch.float32])
    def test_dtypes(self, net, dtype):
        """A module cast to ``dtype`` returns ``dtype``; compared with float64 on the log scale."""
        x = crops(1)
        model = OursEstimator()
        model.load_state_dict(net.state_dict())
        with torch.no_grad():
            out = model.to(dtype).eval()(x)
            reference = model.double()(x.double())
        assert out.mirror_ball.dtype == out.log_mirror_ball.dtype == dtype
        # ten layers accumulate rounding: bfloat16 (8-bit mantissa) within 0.1 on log(1 + L)
        tol = {torch.bfloat16: 0.1, torch.float32: 1e-5}[dtype]
        torch.testing.assert_close(
            out.log_mirror_ball.double(), reference.log_mirror_ball, atol=tol, rtol=tol
        )

    def test_compile(self, net):
        x = crops(1)
        compiled = torch.compile(net)
        with torch.no_grad():
            torch.testing.assert_close(compiled(x).mirror_ball, net(x).mirror_ball, rtol=1e-4, atol=1e-6)


class TestExposure:
    """normalize_exposure=True (the default): the estimate follows the photo's exposure by design."""

    @pytest.mark.parametrize("k", [0.5, 0.25])
    def test_equivariant(self, net, k):
        x = 0.05 + 0.9 * crops(2)
        dark = linear_to_srgb(k * srgb_to_linear(x))  # k times less light, nothing clips anew
        with torch.no_grad():
            ratio = net(dark).mirror_ball.sum((1, 2, 3)) / (k * net(x).mirror_ball.sum((1, 2, 3)))
        torch.testing.assert_close(ratio, torch.ones(2), atol=2e-3, rtol=0)

    def test_off_is_the_papers_network(self):
        torch.manual_seed(0)
        net = OursEstimator(latent_dim=32, normalize_exposure=False).eval()
        x = crops(1)
        with torch.no_grad():
            y, _, log_scale, _, _ = net.decode(x)
            assert float(log_scale.abs().max()) == 0.0
            h = net.from_latent(net.to_latent(net.encoder(x - 0.5))).reshape(1, 256, 4, 4)
            for block in net.decoder:
                h = net.upsample(block(h))
            torch.testing.assert_close(y, net.head(h), atol=0, rtol=0)

    def test_the_weights_say_how_they_were_trained(self):
        """The flag travels in the state dict; a state dict without it (older files) loads as the paper's network."""
        torch.manual_seed(0)
        trained = OursEstimator(latent_dim=32, normalize_exposure=False).state_dict()
        net = OursEstimator(latent_dim=32)
        assert net.normalize_exposure
        net.load_state_dict(trained, strict=True)
        assert not net.normalize_exposure
        legacy = {k: v for k, v in trained.items() if k != "exposure_normalized"}
        net = OursEstimator(latent_dim=32)
        net.load_state_dict(legacy, strict=True)
        assert not net.normalize_exposure and float(net.exposure_normalized) == 0.0
        net.load_state_dict(OursEstimator(latent_dim=32).state_dict(), strict=True)
        assert net.normalize_exposure
