"""Tests of kornia_ilum.promotion: LDR-to-HDR promotion of three-sphere photographs.

The solver is an active-set NNLS on 8-bit thresholds, not differentiable: there is no gradcheck and no
torch.compile test (see the module docstring); the module twin is tested against the functional instead.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from kornia_ilum.color import gamma_decode, gamma_encode, quantize
from kornia_ilum.core.errors import (
    EmptyTensorError,
    NonFiniteError,
    ShapeError,
    TypeCheckError,
    ValueCheckError,
)
from kornia_ilum.geometry import latlong_to_mirror_ball, mirror_ball_valid
from kornia_ilum.io import read_hdr
from kornia_ilum.metrics import relative_radiance
from kornia_ilum.render import MIRROR_REFLECTIVITY, render_spheres
from kornia_ilum.promotion import (
    CLIP_THRESHOLD,
    PromoteSpheres,
    PromotionResult,
    _build_system,
    _fields,
    _nnls_scipy,
    _nnls_torch,
    _prepare,
    _stacked_rows,
    promote_spheres,
)
from tests.conftest import TOL

F64 = torch.float64


def encode(truth: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Render the three spheres of a mirror-ball lighting and write them as 8-bit gamma-2.2 codes."""
    spheres = render_spheres(truth, truth.shape[-1])
    codes = {k: torch.round(quantize(gamma_encode(v)) * 255).to(torch.uint8) for k, v in spheres.items()}
    return codes["mirror"], codes["diffuse"], codes["matte_silver"]


def sky(size: int, batch: int = 1, level: float = 0.3) -> torch.Tensor:
    """A smooth blue-grey sky over a darker ground, linear, 0 off the ball."""
    v = (1.0 - (2 * torch.arange(size, dtype=F64) + 1) / size)[:, None].expand(size, size)
    colour = torch.tensor([0.8, 0.9, 1.0], dtype=F64)[:, None, None]
    ball = level * colour * (0.6 + 0.4 * v) * torch.where(v > 0, 1.0, 0.5)
    return (ball * mirror_ball_valid(size)).expand(batch, 3, size, size).clone()


def sun_environment(size: int = 32, power: float = 2000.0, rgb=(1.0, 0.8, 0.55), at=None) -> torch.Tensor:
    """The sky with a sun filling one mirror-ball pixel (``power`` times the sky's level)."""
    truth = sky(size)
    at = at or (9 * size // 32, 21 * size // 32)
    truth[0, :, at[0], at[1]] = power * 0.3 * torch.tensor(rgb, dtype=F64)
    return truth


class TestPromoteSpheres:
    def test_smoke(self, device):
        mirror, diffuse, matte = (x.to(device) for x in encode(sun_environment(16)))
        out = promote_spheres(mirror, diffuse, matte)
        assert isinstance(out, PromotionResult)
        assert out.lighting.dtype == torch.float32 and out.lighting.device == mirror.device
        assert out.clipped.dtype == torch.bool and out.solved.dtype == torch.bool
        assert out.solved.tolist() == [True]
        assert (out.lighting >= 0).all() and (out.residual >= 0).all()

    @pytest.mark.parametrize("size", [16, 32])
    @pytest.mark.parametrize("batch", [1, 3])
    def test_cardinality(self, size, batch):
        truth = sky(size, batch)
        truth[0, :, size // 3, size // 2] = 500.0  # only the first probe clips
        out = promote_spheres(*encode(truth))
        assert out.lighting.shape == (batch, 3, size, size)
        assert out.residual.shape == (batch, 3, size, size)
        assert out.clipped.shape == (batch, size, size)
        assert out.solved.shape == (batch,)
        assert out.solved.tolist() == [True] + [False] * (batch - 1)

    def test_exception(self):
        good = torch.zeros(1, 3, 16, 16, dtype=torch.uint8)
        with pytest.raises(TypeCheckError, match="mirror_ldr must be a torch.Tensor"):
            promote_spheres(np.zeros((1, 3, 16, 16)), good, good)
        with pytest.raises(TypeCheckError, match="diffuse_ldr must be uint8 or floating point"):
            promote_spheres(good, good.to(torch.int32), good)
        with pytest.raises(ShapeError, match=r"matte_ldr must have shape \(B, 3, S, S\)"):
            promote_spheres(good, good, torch.zeros(1, 4, 16, 16, dtype=torch.uint8))
        with pytest.raises(ShapeError, match="mirror_ldr must have shape .* S in"):
            promote_spheres(*(torch.zeros(1, 3, 20, 20, dtype=torch.uint8),) * 3)
        with pytest.raises(ShapeError, match="mirror_ldr must have shape"):
            promote_spheres(*(torch.zeros(1, 3, 16, 8, dtype=torch.uint8),) * 3)
        with pytest.raises(ShapeError, match="diffuse_ldr must have the shape of mirror_ldr"):
            promote_spheres(good, torch.zeros(2, 3, 16, 16, dtype=torch.uint8), good)
        with pytest.raises(TypeCheckError, match="matte_ldr must have the dtype of mirror_ldr"):
            promote_spheres(good, good, good.float())
        nan = torch.zeros(1, 3, 16, 16)
        nan[0, 1, 3, 3] = float("nan")
        with pytest.raises(NonFiniteError, match="diffuse_ldr must be finite"):
            promote_spheres(nan.clone().zero_(), nan, nan.clone().zero_())
        with pytest.raises(ValueCheckError, match=r"mirror_ldr must hold encoded values in \[0, 1\]"):
            promote_spheres(torch.full((1, 3, 16, 16), 1.5), good.float(), good.float())
        with pytest.raises(EmptyTensorError, match="mirror_ldr must not be empty"):
            promote_spheres(*(torch.zeros(0, 3, 16, 16, dtype=torch.uint8),) * 3)
        with pytest.raises(ValueCheckError, match="lam must be finite and >= 0"):
            promote_spheres(good, good, good, lam=-0.1)
        with pytest.raises(TypeCheckError, match="gamma must be a float"):
            promote_spheres(good, good, good, gamma="2.2")
        with pytest.raises(ValueCheckError, match="gamma must be positive"):
            promote_spheres(good, good, good, gamma=0.0)
        with pytest.raises(ValueCheckError, match=r"clip_threshold must be in \(0, 1\]"):
            promote_spheres(good, good, good, clip_threshold=1.2)
        with pytest.raises(ValueCheckError, match="method must be one of"):
            promote_spheres(good, good, good, method="lbfgs")
        with pytest.raises(ValueCheckError, match="balance must be one of"):
            promote_spheres(good, good, good, balance="grey")

    def test_unclipped_recovers_exactly(self):
        """Nothing clipped: no solve, and the lighting is the truth to within 8-bit quantisation."""
        truth = sky(32, 2)
        truth[1] *= torch.tensor([1.5, 0.7, 0.4], dtype=F64)[:, None, None]
        mirror, diffuse, matte = encode(truth)
        out = promote_spheres(mirror, diffuse, matte)
        assert out.solved.tolist() == [False, False] and not out.clipped.any()
        assert (out.residual == 0).all()
        # half a code of gamma 2.2 at the encoded value e is at most 2.2 e^1.2 / 510 in linear units
        encoded = gamma_encode(MIRROR_REFLECTIVITY * truth)
        bound = (2.2 * encoded.clamp(min=1e-3) ** 1.2 / 510.0 + 1e-9) / MIRROR_REFLECTIVITY
        err = (out.lighting.to(F64) - truth).abs()
        assert (err <= bound).all(), float((err / bound).max())
        assert relative_radiance(out.lighting.to(F64), truth).abs().max() < 2e-3

    def test_skips_solve_when_unclipped(self):
        truth = torch.cat([sun_environment(16), sky(16)])
        mirror, diffuse, matte = encode(truth)
        both = promote_spheres(mirror, diffuse, matte)
        alone = promote_spheres(mirror[1:], diffuse[1:], matte[1:])
        assert both.solved.tolist() == [True, False] and alone.solved.tolist() == [False]
        torch.testing.assert_close(both.lighting[1:], alone.lighting, rtol=0, atol=0)
        expected = gamma_decode(mirror[1:].double() / 255.0) * mirror_ball_valid(16) / MIRROR_REFLECTIVITY
        torch.testing.assert_close(alone.lighting, expected.float())

    def test_only_clipped_directions_are_unknowns(self):
        truth = sun_environment(32)
        truth[0, :, 20:22, 5:8] = 150.0  # a clipped window beside the sun
        mirror, diffuse, matte = encode(truth)
        out = promote_spheres(mirror, diffuse, matte)
        valid = mirror_ball_valid(32)
        expected_clipped = (mirror[0] >= 254).any(0) & valid
        assert torch.equal(out.clipped[0], expected_clipped) and int(expected_clipped.sum()) == 7
        passthrough = gamma_decode(mirror.double() / 255.0) / MIRROR_REFLECTIVITY
        keep = ~out.clipped[:, None].expand(-1, 3, -1, -1) & valid
        torch.testing.assert_close(out.lighting[keep], passthrough[keep].float(), rtol=0, atol=0)
        assert (out.residual[~out.clipped[:, None].expand(-1, 3, -1, -1)] == 0).all()
        assert (out.lighting[..., ~valid] == 0).all()
        lower = gamma_decode(torch.tensor(CLIP_THRESHOLD, dtype=F64)).item() / MIRROR_REFLECTIVITY
        assert (out.lighting[0][:, out.clipped[0]] >= lower - 1e-6).all()

    def test_clipped_sun_energy(self):
        """A sun 2000 times the sky in one pixel: measured errors 0.04 % in total energy (per channel) and
        0.04 % on the sun itself (bounds 0.5 % and 1 %); the naive clipped lighting misses 73 to 86 %."""
        truth = sun_environment(32)
        out = promote_spheres(*encode(truth))
        assert out.clipped.sum() == 1
        assert relative_radiance(out.lighting.to(F64), truth).abs().max() < 5e-3
        sun = out.lighting[0, :, 9, 21].to(F64)
        torch.testing.assert_close(sun, truth[0, :, 9, 21], rtol=1e-2, atol=0)
        naive = (out.lighting - out.residual).to(F64)
        assert relative_radiance(naive, truth).min() > 0.7

    @pytest.mark.slow  # resamples a 1k map in float64 and builds the float64 sphere fields
    def test_real_map_energy(self, shared_data):
        """city.exr exposed as in benchmarks/bench_promotion.py (98th percentile of the mirror sphere at 0.5):
        its sun clips; total energy within 0.5 % (measured 0.04 %, per channel), against 17 to 26 % missing
        for the naive clipped lighting."""
        env = read_hdr(shared_data / "hdri" / "city.exr")[None].to(F64)
        truth = latlong_to_mirror_ball(env, 32)
        seen = (MIRROR_REFLECTIVITY * truth.mean(1))[:, mirror_ball_valid(32)]
        truth = truth * (0.5 / seen.quantile(0.98))
        out = promote_spheres(*encode(truth))
        assert out.solved.all() and out.clipped.sum() >= 1
        assert relative_radiance(out.lighting.to(F64), truth).abs().max() < 5e-3
        assert relative_radiance((out.lighting - out.residual).to(F64), truth).min() > 0.15

    @given(
        codes=st.integers(0, 2**31 - 1),
        lam=st.sampled_from([0.0, 0.5, 50.0]),
        balance=st.sampled_from(["residual", "diffuse"]),
    )
    def test_never_negative(self, codes, lam, balance):
        """Arbitrary, mutually inconsistent 8-bit spheres (many clipped): finite, non-negative light."""
        gen = torch.Generator().manual_seed(codes)
        images = torch.randint(0, 256, (3, 2, 3, 8, 8), generator=gen, dtype=torch.uint8)
        images[0] = torch.where(torch.rand(2, 1, 8, 8, generator=gen) < 0.3, 255, images[0])
        out = promote_spheres(*images, lam=lam, balance=balance)
        assert torch.isfinite(out.lighting).all()
        assert (out.lighting >= 0).all() and (out.residual >= 0).all()
        assert (out.residual[~out.clipped[:, None].expand(-1, 3, -1, -1)] == 0).all()

    @pytest.mark.parametrize("lam", [0.0, 0.5])
    def test_torch_and_scipy_agree(self, lam):
        truth = torch.cat([sun_environment(32), sun_environment(32, 800.0, (0.2, 0.5, 1.0), (14, 4))])
        truth[1, :, 22:24, 10:12] += torch.tensor([90.0, 20.0, 5.0], dtype=F64)[:, None, None]
        images = encode(truth)
        a = promote_spheres(*images, lam=lam, method="torch")
        b = promote_spheres(*images, lam=lam, method="scipy")
        c = promote_spheres(*images, lam=lam, method="auto")
        torch.testing.assert_close(a.lighting, b.lighting, rtol=1e-5, atol=1e-5)
        torch.testing.assert_close(a.lighting, c.lighting, rtol=1e-5, atol=1e-5)
        assert torch.equal(a.clipped, b.clipped)

    def test_normal_equations_match_stacked_rows(self):
        """The assembled G, c are A^T A, A^T b of the documented least-squares rows (Eq. 3)."""
        truth = sun_environment(16, 900.0)
        truth[0, :, 3, 7] = 300.0
        enc, lin, clipped, base, thr = _prepare(*encode(truth), gamma=2.2, threshold=CLIP_THRESHOLD)
        system = _build_system(
            _fields(16, torch.device("cpu")),
            enc,
            lin=lin,
            base=base,
            clipped=clipped,
            thr_enc=thr,
            lam=0.5,
            balance="residual",
        )
        a, b = _stacked_rows(system, 0)
        torch.testing.assert_close(system.gram[0], a.T @ a, rtol=1e-10, atol=1e-14)
        torch.testing.assert_close(system.rhs[0], a.T @ b, rtol=1e-10, atol=1e-14)
        x_torch, ok = _nnls_torch(system.gram, system.rhs, system.free, 100)
        x_scipy = _nnls_scipy(system.gram, system.rhs, system.free)
        assert ok.all()
        torch.testing.assert_close(x_torch, x_scipy, rtol=1e-7, atol=1e-9)

    def test_regulariser_ties_colour(self):
        """A large lambda gives every recovered light the colour w of the diffuse ball's missing light;
        lambda = 0 lets two differently hued lights keep their own colours."""
        truth = sky(32)
        truth[0, :, 9, 21] = torch.tensor([600.0, 60.0, 20.0], dtype=F64)
        truth[0, :, 16, 6] = torch.tensor([20.0, 80.0, 500.0], dtype=F64)
        images = encode(truth)
        free = promote_spheres(*images, lam=0.0).residual[0].to(F64)
        tied = promote_spheres(*images, lam=1e4).residual[0].to(F64)
        for u, close in ((free, False), (tied, True)):
            red, blue = u[:, 9, 21] / u[:, 9, 21].sum(), u[:, 16, 6] / u[:, 16, 6].sum()
            assert torch.allclose(red, blue, atol=2e-3) is close
        torch.testing.assert_close(free[:, 9, 21], truth[0, :, 9, 21], rtol=2e-2, atol=1.0)

    def test_module_matches_functional(self):
        truth = torch.cat([sun_environment(16), sky(16)])
        images = encode(truth)
        module = PromoteSpheres(size=16, lam=0.5)
        assert module.state_dict() == {} and "size=16" in repr(module)
        a, b = module(*images), promote_spheres(*images, lam=0.5)
        for name in ("lighting", "clipped", "residual", "solved"):
            assert torch.equal(getattr(a, name), getattr(b, name))
        with pytest.raises(ShapeError, match="mirror_ldr must have shape .* S = 16"):
            module(*encode(sky(32)))
        with pytest.raises(ValueCheckError, match="size must be one of"):
            PromoteSpheres(size=12)
        with pytest.raises(TypeCheckError, match="size must be an int"):
            PromoteSpheres(size=16.0)
        with pytest.raises(ValueCheckError, match="method must be one of"):
            PromoteSpheres(method="cvx")

    @pytest.mark.parametrize("dtype", [torch.float16, torch.bfloat16, torch.float32, torch.float64])
    def test_dtypes(self, dtype):
        """Float inputs (codes / 255) give the uint8 result in their own dtype."""
        images = encode(sun_environment(16, 1000.0))
        expected = promote_spheres(*images).lighting.to(F64)
        out = promote_spheres(*(x.to(dtype) / 255.0 for x in images))
        assert out.lighting.dtype == dtype and out.residual.dtype == dtype
        tol = TOL[dtype] if dtype in (torch.float16, torch.bfloat16) else {"rtol": 1e-6, "atol": 1e-6}
        torch.testing.assert_close(out.lighting.to(F64), expected, **tol)

    def test_solver_fallback_and_auto(self, monkeypatch):
        """Probes whose block pivoting does not settle within the step budget are finished by SciPy, and
        "auto" switches to SciPy above its size limit on the CPU: both give the same lighting."""
        from kornia_ilum import promotion

        truth = sun_environment(16, 700.0)
        truth[0, :, 3:6, 6:9] = 60.0
        images = encode(truth)
        reference = promote_spheres(*images, method="scipy").lighting
        calls = []
        scipy_solver = promotion._nnls_scipy
        monkeypatch.setattr(promotion, "_nnls_scipy", lambda *a: calls.append(1) or scipy_solver(*a))
        torch.testing.assert_close(promote_spheres(*images, method="auto").lighting, reference)
        assert calls == []  # small problem: torch alone
        monkeypatch.setattr(promotion, "_MAX_PIVOTS", 0)  # no step allowed: every probe is handed over
        torch.testing.assert_close(promote_spheres(*images, method="torch").lighting, reference)
        assert calls == [1]
        monkeypatch.setattr(promotion, "_AUTO_TORCH_MAX_UNKNOWNS", 0)
        torch.testing.assert_close(promote_spheres(*images, method="auto").lighting, reference)
        assert calls == [1, 1]

    def test_chunked_batches_match(self, monkeypatch):
        """Probes are sorted by size and solved in chunks: the result does not depend on the chunking."""
        from kornia_ilum import promotion

        truth = torch.cat([sun_environment(16, p) for p in (300.0, 900.0, 2000.0)] + [sky(16), sky(16)])
        truth[2, :, 3:5, 6:8] = 80.0
        truth[4, :, 10, 4] = 150.0
        images = encode(truth)
        whole = promote_spheres(*images)
        monkeypatch.setattr(promotion, "_CHUNK", 2)
        chunked = promote_spheres(*images)
        assert whole.solved.tolist() == [True, True, True, False, True]
        torch.testing.assert_close(chunked.lighting, whole.lighting, rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("case", ["every pixel clipped", "all dark", "one bright pixel"])
@pytest.mark.parametrize("method", ["torch", "scipy", "auto"])
def test_promotion_under_stress_converges_and_stays_non_negative(case, method):
    """Issue 24: the three degenerate probes give finite, non-negative lighting with every solver."""
    valid = mirror_ball_valid(32)

    def ball(code: int) -> torch.Tensor:
        return (torch.full((1, 3, 32, 32), code, dtype=torch.uint8) * valid).to(torch.uint8)

    if case == "every pixel clipped":
        spheres = (ball(255), ball(255), ball(255))
    elif case == "all dark":
        spheres = (ball(0), ball(0), ball(0))
    else:
        mirror = ball(10)
        mirror[0, :, 12, 20] = 255
        spheres = (mirror, ball(40), ball(40))
    out = promote_spheres(*spheres, method=method)
    assert torch.isfinite(out.lighting).all() and (out.lighting >= 0).all()
    assert out.solved.tolist() == [case != "all dark"]  # nothing clipped: nothing to solve
    clipped = {"every pixel clipped": int(valid.sum()), "all dark": 0, "one bright pixel": 1}[case]
    assert int(out.clipped.sum()) == clipped

