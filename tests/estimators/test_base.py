"""Tests of kornia_ilum.estimators.base: LightingEstimate (files, preview), metadata, checks, weights."""

from __future__ import annotations

import hashlib
import math
from pathlib import Path

import pytest
import safetensors.torch
import torch
from torch import nn

from kornia_ilum.core.errors import (
    EmptyTensorError,
    HDRIOError,
    MissingWeightsError,
    NonFiniteError,
    ShapeError,
    TypeCheckError,
    ValueCheckError,
    WeightsChecksumError,
)
from kornia_ilum.estimators import (
    EstimatorInfo,
    LightingEstimate,
    LightingEstimator,
    OursEstimator,
    WeightFile,
    check_crops,
    create_estimator,
    read_weights,
)
import kornia_ilum.estimators.ours as ours
from kornia_ilum.estimators import registry
from kornia_ilum.geometry import mirror_ball_directions, mirror_ball_valid
from kornia_ilum.io import read_hdr, read_ldr, write_hdr

#: Radiance RGBE keeps 8-bit mantissas: channels come back within 2^-7 of the pixel's largest channel.
RGBE_TOL = 2.0**-7
VALID = mirror_ball_valid(32)


def random_estimate(batch: int = 2, seed: int = 0) -> LightingEstimate:
    g = torch.Generator().manual_seed(seed)
    mirror_ball = 10.0 ** (torch.rand(batch, 3, 32, 32, generator=g) * 4 - 2) * VALID
    return LightingEstimate(mirror_ball=mirror_ball, valid=VALID, log_mirror_ball=torch.log1p(mirror_ball))


def lit_from(direction: tuple[float, float, float], batch: int = 1) -> LightingEstimate:
    """Lighting of 20 within 45 degrees of ``direction``, 0.01 elsewhere."""
    d, valid = mirror_ball_directions(32)
    near = (d @ torch.tensor(direction)) > math.cos(math.radians(45))
    mirror_ball = torch.where(near & valid, 20.0, 0.01 * valid).expand(batch, 3, 32, 32).clone()
    return LightingEstimate(mirror_ball=mirror_ball, valid=valid)


def listing(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


class TestLightingEstimate:
    def test_smoke(self):
        est = random_estimate(3)
        assert len(est) == 3 and est.sh is None and est.boxes is None and est.image_index is None

    @pytest.mark.parametrize("height", [8, 64])
    def test_cardinality(self, height):
        est = random_estimate(2)
        assert est.to_latlong(height).shape == (2, 3, height, 2 * height)
        spheres = est.render_spheres(16)
        assert sorted(spheres) == ["diffuse", "matte_silver", "mirror"]
        assert all(v.shape == (2, 3, 16, 16) for v in spheres.values())

    def test_latlong_of_uniform_lighting(self):
        est = LightingEstimate(mirror_ball=torch.full((1, 3, 32, 32), 1.5) * VALID, valid=VALID)
        # the area resampling of the op library is exact to 4e-4 for a constant map
        torch.testing.assert_close(est.to_latlong(16), torch.full((1, 3, 16, 32), 1.5), atol=0, rtol=1e-3)

    def test_exception(self):
        with pytest.raises(
            ShapeError, match=r"mirror_ball must have shape \(B, 3, S, S\), got \(3, 32, 32\)"
        ):
            LightingEstimate(mirror_ball=torch.zeros(3, 32, 32), valid=VALID)
        with pytest.raises(ShapeError, match=r"mirror_ball must have shape .*it must be square"):
            LightingEstimate(mirror_ball=torch.zeros(1, 3, 32, 16), valid=VALID)
        with pytest.raises(ShapeError, match=r"valid must have shape \(16, 16\), got \(32, 32\)"):
            LightingEstimate(mirror_ball=torch.zeros(1, 3, 16, 16), valid=VALID)
        with pytest.raises(TypeCheckError, match="valid must be a bool tensor, got dtype torch.float32"):
            LightingEstimate(mirror_ball=torch.zeros(1, 3, 32, 32), valid=VALID.float())
        with pytest.raises(ShapeError, match=r"sh must have shape \(2, 9, 3\), got \(1, 9, 3\)"):
            LightingEstimate(mirror_ball=torch.zeros(2, 3, 32, 32), valid=VALID, sh=torch.zeros(1, 9, 3))
        with pytest.raises(ShapeError, match=r"log_mirror_ball must have shape \(1, 3, 32, 32\)"):
            LightingEstimate(
                mirror_ball=torch.zeros(1, 3, 32, 32), valid=VALID, log_mirror_ball=torch.zeros(1, 3, 8, 8)
            )
        with pytest.raises(ShapeError, match=r"boxes must have shape \(1, 4\)"):
            LightingEstimate(mirror_ball=torch.zeros(1, 3, 32, 32), valid=VALID, boxes=torch.zeros(1, 5))
        with pytest.raises(ShapeError, match=r"image_index must have shape \(1\)"):
            LightingEstimate(
                mirror_ball=torch.zeros(1, 3, 32, 32),
                valid=VALID,
                image_index=torch.zeros(2, dtype=torch.long),
            )


class TestSave:
    @pytest.mark.parametrize("index", [0, 1, -1])
    def test_exr_round_trip(self, tmp_path, index):
        est = random_estimate(2)
        out = est.save(str(tmp_path / "light.exr"), index=index)
        assert out == tmp_path / "light.exr" and isinstance(out, Path)
        torch.testing.assert_close(read_hdr(out), est.mirror_ball[index], atol=0, rtol=0)

    def test_exr_half(self, tmp_path):
        est = random_estimate(1)
        back = read_hdr(est.save(tmp_path / "light.exr", half=True))
        torch.testing.assert_close(back, est.mirror_ball[0], atol=0, rtol=2.0**-11)

    def test_hdr_round_trip(self, tmp_path):
        est = random_estimate(2)
        back = read_hdr(est.save(tmp_path / "light.HDR", index=1))
        want = est.mirror_ball[1]
        assert (back <= want * (1 + 1e-6)).all()
        assert ((want - back) <= RGBE_TOL * want.amax(0, keepdim=True)).all()

    def test_latlong(self, tmp_path):
        est = random_estimate(2)
        back = read_hdr(est.save(tmp_path / "env.exr", index=1, latlong_height=16))
        assert back.shape == (3, 16, 32)
        torch.testing.assert_close(back, est.to_latlong(16)[1])

    def test_bad_suffix(self, tmp_path):
        est = random_estimate(1)
        with pytest.raises(
            ValueCheckError,
            match=r"cannot write HDR lighting to .*light\.png: the file name must end "
            r"in \.exr or \.hdr, got '\.png'",
        ):
            est.save(tmp_path / "light.png")
        with pytest.raises(
            ValueCheckError, match=r"light'?: the file name must end in \.exr or \.hdr, got ''"
        ):
            est.save(tmp_path / "light")
        assert listing(tmp_path) == []

    def test_bad_index(self, tmp_path):
        with pytest.raises(
            ValueCheckError, match=r"index must be in \[-2, 2\) for an estimate of 2 lightings, got 2"
        ):
            random_estimate(2).save(tmp_path / "light.exr", index=2)
        with pytest.raises(TypeCheckError, match="index must be an int, got float"):
            random_estimate(2).save(tmp_path / "light.exr", index=1.0)
        with pytest.raises(ValueCheckError, match="half=True applies to .exr files only"):
            random_estimate(2).save(tmp_path / "light.hdr", half=True)
        assert listing(tmp_path) == []

    def test_atomic(self, tmp_path):
        """A failed write leaves nothing new, and an existing file unchanged."""
        bright = LightingEstimate(mirror_ball=torch.full((1, 3, 32, 32), 1e6) * VALID, valid=VALID)
        with pytest.raises(HDRIOError, match="exceeds 65504"):
            bright.save(tmp_path / "sun.exr", half=True)
        assert listing(tmp_path) == []
        with pytest.raises(HDRIOError, match="does not exist"):
            bright.save(tmp_path / "missing" / "sun.exr")
        assert listing(tmp_path) == []
        write_hdr(tmp_path / "sun.exr", torch.ones(3, 2, 2))
        before = (tmp_path / "sun.exr").read_bytes()
        with pytest.raises(HDRIOError):
            bright.save(tmp_path / "sun.exr", half=True)
        assert listing(tmp_path) == ["sun.exr"] and (tmp_path / "sun.exr").read_bytes() == before


class TestPreview:
    @pytest.mark.parametrize("size", [16, 12, 128])
    def test_cardinality(self, tmp_path, size):
        """Three spheres side by side: 3 * size wide, size high; off-sphere pixels black."""
        out = random_estimate(2).preview(tmp_path / "spheres.png", index=1, size=size)
        image = read_ldr(out)
        assert out == tmp_path / "spheres.png" and image.shape == (3, size, 3 * size)
        assert image[:, 0, 0].eq(0).all() and image[:, -1, -1].eq(0).all()
        assert image.amax() > 0.5

    @pytest.mark.parametrize(
        ("direction", "brighter", "darker"),
        [
            ((0.0, 1.0, 0.0), (slice(0, 8), slice(None)), (slice(8, 16), slice(None))),  # +Y: top half
            ((1.0, 0.0, 0.0), (slice(None), slice(8, 16)), (slice(None), slice(0, 8))),  # +X: right half
        ],
        ids=["up", "right"],
    )
    def test_content(self, tmp_path, direction, brighter, darker):
        """The diffuse sphere (left panel) is brighter on the side the light comes from."""
        image = read_ldr(lit_from(direction).preview(tmp_path / "p.png", size=16))
        diffuse = image[:, :, :16]
        on = mirror_ball_valid(16)
        lit, unlit = diffuse[(slice(None),) + brighter], diffuse[(slice(None),) + darker]
        lit_mean = lit.sum() / on[brighter].sum()
        unlit_mean = unlit.sum() / on[darker].sum()
        assert lit_mean > 2 * unlit_mean
        # exposure: the diffuse sphere's 99th percentile maps to 0.9 linear = 0.95 sRGB, within 8-bit rounding
        assert abs(diffuse.amax().item() - 0.955) < 0.04

    def test_black_lighting(self, tmp_path):
        est = LightingEstimate(mirror_ball=torch.zeros(1, 3, 32, 32), valid=VALID)
        assert read_ldr(est.preview(tmp_path / "black.png", size=16)).amax() == 0

    def test_exception(self, tmp_path):
        est = random_estimate(1)
        with pytest.raises(
            ValueCheckError, match=r"cannot write a preview to .*p\.exr: .*\.png or \.jpg or \.jpeg"
        ):
            est.preview(tmp_path / "p.exr")
        with pytest.raises(ValueCheckError, match=r"index must be in \[-1, 1\)"):
            est.preview(tmp_path / "p.png", index=3)
        with pytest.raises(ValueCheckError, match="size must be positive"):
            est.preview(tmp_path / "p.png", size=0)
        with pytest.raises(HDRIOError, match="does not exist"):
            est.preview(tmp_path / "missing" / "p.png", size=16)
        assert listing(tmp_path) == []


class TestMetadata:
    def test_weight_file(self):
        assert WeightFile("a.safetensors", "ab" * 32).sha256 == "ab" * 32
        with pytest.raises(ValueCheckError, match="WeightFile.sha256 must be 64 lowercase hex digits"):
            WeightFile("a.safetensors", "AB" * 32)
        with pytest.raises(
            ValueCheckError, match="WeightFile.name must be a plain file name, got '../a.safetensors'"
        ):
            WeightFile("../a.safetensors", "ab" * 32)
        with pytest.raises(ValueCheckError, match="plain file name"):
            WeightFile("", "ab" * 32)

    def test_estimator_info(self):
        info = EstimatorInfo("x", "d", "p")
        assert info.input_size == 256 and info.weights == () and info.needs_weights
        assert not info.pretrained_available
        assert EstimatorInfo(
            "x", "d", "p", weights=(WeightFile("w.safetensors", "0" * 64),)
        ).pretrained_available
        assert EstimatorInfo("x", "d", "p", needs_weights=False).pretrained_available
        with pytest.raises(AttributeError):
            info.name = "y"  # frozen


class Toy(LightingEstimator):
    """A tiny trainable estimator: lighting = exp(linear(mean crop colour)) on the ball."""

    info = EstimatorInfo("toy", "a toy", "none: a test double", input_size=8, needs_weights=True)

    def __init__(self, hidden: int = 3):
        super().__init__()
        self.linear = nn.Linear(3, hidden)
        self.register_buffer("valid", mirror_ball_valid(32), persistent=False)

    def predict(self, crops):
        light = self.linear(crops.mean((-2, -1)))[:, :3].exp()
        return LightingEstimate(light[:, :, None, None] * self.valid, self.valid)


def toy_with_file(folder: Path, *, sha256: str | None = None) -> tuple[type[Toy], dict[str, torch.Tensor]]:
    """Save random Toy weights to folder/toy.safetensors; return a Toy subclass declaring that file."""
    state = {"linear.weight": torch.randn(3, 3), "linear.bias": torch.randn(3)}
    path = folder / "toy.safetensors"
    safetensors.torch.save_file(state, path)
    digest = sha256 or hashlib.sha256(path.read_bytes()).hexdigest()
    info = EstimatorInfo("toy", "a toy", "none", input_size=8, weights=(WeightFile(path.name, digest),))
    return type("ToyWithWeights", (Toy,), {"info": info}), state


class TestFromPretrained:
    def test_success(self, tmp_path):
        cls, state = toy_with_file(tmp_path)
        model = cls.from_pretrained(tmp_path)
        assert isinstance(model, cls) and not model.training
        torch.testing.assert_close(
            model.state_dict()["linear.weight"], state["linear.weight"], atol=0, rtol=0
        )
        torch.testing.assert_close(model.linear.bias, state["linear.bias"], atol=0, rtol=0)
        assert len(model(torch.rand(2, 3, 8, 8))) == 2
        assert isinstance(cls.from_pretrained(str(tmp_path)), cls)

    def test_through_registry(self, tmp_path):
        cls, state = toy_with_file(tmp_path)
        registry.register_estimator("toy_test_pretrained", cls)
        try:
            model = create_estimator("toy_test_pretrained", weights_dir=tmp_path)
            torch.testing.assert_close(model.linear.bias, state["linear.bias"], atol=0, rtol=0)
            assert not create_estimator("toy_test_pretrained", pretrained=False).linear.bias.equal(
                state["linear.bias"]
            )
        finally:
            registry._reset()

    def test_checksum_mismatch(self, tmp_path):
        cls, _ = toy_with_file(tmp_path, sha256="0" * 64)
        actual = hashlib.sha256((tmp_path / "toy.safetensors").read_bytes()).hexdigest()
        with pytest.raises(
            WeightsChecksumError,
            match=rf"toy\.safetensors: SHA-256 is {actual}, but estimator 'toy' expects {'0' * 64}; "
            "the file is corrupt, truncated or from another release, and was not loaded",
        ):
            cls.from_pretrained(tmp_path)

    def test_tampered_file(self, tmp_path):
        cls, _ = toy_with_file(tmp_path)
        path = tmp_path / "toy.safetensors"
        data = bytearray(path.read_bytes())
        data[-1] ^= 0xFF
        path.write_bytes(bytes(data))
        with pytest.raises(WeightsChecksumError, match=str(path).replace(".", r"\.")):
            cls.from_pretrained(tmp_path)

    def test_missing_file(self, tmp_path):
        cls, _ = toy_with_file(tmp_path)
        (tmp_path / "toy.safetensors").unlink()
        with pytest.raises(
            MissingWeightsError,
            match=rf"weight file 'toy\.safetensors' of estimator 'toy' not found in "
            rf"{str(tmp_path)}",
        ):
            cls.from_pretrained(tmp_path)

    def test_default_weights_dir(self):
        assert Toy.default_weights_dir() == Path(__file__).resolve().parent / "weights"
        assert OursEstimator.default_weights_dir() == Path(ours.__file__).resolve().parent / "weights"

    def test_no_weights_shipped(self):
        with pytest.raises(
            MissingWeightsError,
            match=r"^'toy' ships no trained weights yet; pass pretrained=False for an untrained model",
        ):
            Toy.from_pretrained()

    def test_pickle_is_never_loaded(self, tmp_path):
        """A torch.save (pickle) file under the declared name and digest is refused by safetensors."""
        path = tmp_path / "toy.safetensors"
        torch.save({"linear.weight": torch.zeros(3, 3), "linear.bias": torch.zeros(3)}, path)
        info = EstimatorInfo(
            "toy",
            "a toy",
            "none",
            weights=(WeightFile(path.name, hashlib.sha256(path.read_bytes()).hexdigest()),),
        )
        cls = type("ToyPickle", (Toy,), {"info": info})
        with pytest.raises(Exception, match="(?i)header|safetensor|invalid"):
            cls.from_pretrained(tmp_path)


class TestReadWeights:
    """The one SHA-256-checked read that from_pretrained and the evaluation's checkpoints share."""

    def test_returns_the_tensors_and_the_digest(self, tmp_path):
        _, state = toy_with_file(tmp_path)
        path = tmp_path / "toy.safetensors"
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
        for expected in (None, digest):
            tensors, got = read_weights(path, expected)
            assert got == digest and tensors.keys() == state.keys()
            assert all(torch.equal(tensors[k], state[k]) and tensors[k].device.type == "cpu" for k in state)

    def test_mismatch_names_the_file_and_both_digests(self, tmp_path):
        toy_with_file(tmp_path)
        path = tmp_path / "toy.safetensors"
        actual = hashlib.sha256(path.read_bytes()).hexdigest()
        message = rf"SHA-256 is {actual}, but the caller expects {'1' * 64};"
        with pytest.raises(WeightsChecksumError, match=message):
            read_weights(path, "1" * 64)
        with pytest.raises(WeightsChecksumError, match=r"but run 'x' expects"):
            read_weights(path, "1" * 64, expected_by="run 'x'")

    def test_pickle_is_never_loaded(self, tmp_path):
        path = tmp_path / "w.safetensors"
        torch.save({"w": torch.zeros(3)}, path)
        with pytest.raises(Exception, match="(?i)header|safetensor|invalid"):
            read_weights(path)


class TestCheckCrops:
    def test_accepts(self):
        check_crops(torch.rand(2, 3, 256, 256))
        check_crops(torch.rand(1, 3, 64, 64, dtype=torch.float64), 64)
        check_crops(torch.rand(1, 3, 256, 256).clamp(1e-3, 1) - 1e-3 * 1.5 + 5e-4)  # within the slack

    def test_exception(self):
        with pytest.raises(
            TypeCheckError,
            match=r"crops must be a floating-point tensor of sRGB values in \[0, 1\], "
            r"got dtype torch.uint8; convert 8-bit images with image.float\(\) / 255",
        ):
            check_crops(torch.zeros(1, 3, 256, 256, dtype=torch.uint8))
        with pytest.raises(TypeCheckError, match="crops must be a torch.Tensor"):
            check_crops([[0.5]])
        with pytest.raises(
            ShapeError, match=r"crops must have shape \(B, 3, 256, 256\), got \(3, 256, 256\)"
        ):
            check_crops(torch.rand(3, 256, 256))
        with pytest.raises(ShapeError, match=r"got \(1, 4, 256, 256\)"):
            check_crops(torch.rand(1, 4, 256, 256))
        with pytest.raises(EmptyTensorError, match="crops must not be empty"):
            check_crops(torch.rand(0, 3, 256, 256))
        with pytest.raises(NonFiniteError, match="crops must be finite"):
            check_crops(torch.full((1, 3, 256, 256), float("nan")))
        with pytest.raises(
            ValueCheckError,
            match=r"crops must be sRGB-encoded values in \[0, 1\], got min 0 and max 255; "
            "divide 8-bit images by 255",
        ):
            check_crops(torch.linspace(0, 255, 3 * 256 * 256).reshape(1, 3, 256, 256))
        with pytest.raises(ValueCheckError, match="got min -0.01"):
            check_crops(torch.full((1, 3, 256, 256), -0.01))

    def test_forward_checks(self):
        model = Toy()
        with pytest.raises(ShapeError, match=r"crops must have shape \(B, 3, 8, 8\)"):
            model(torch.rand(1, 3, 256, 256))
        with pytest.raises(NotImplementedError, match="Bare must implement predict"):
            type("Bare", (LightingEstimator,), {"info": Toy.info})()(torch.rand(1, 3, 8, 8))
