"""End-to-end tests of kornia_ilum.estimate_lighting: inputs, detection, faces, fallback, files, preview."""

from __future__ import annotations

import numpy as np
import OpenImageIO as oiio
import pytest
from hypothesis import given
from hypothesis import strategies as st
import skimage.data
import torch

import kornia_ilum
from kornia_ilum import api
from kornia_ilum.api import estimate_lighting, full_image_box
from kornia_ilum.core.errors import (
    EmptyTensorError,
    HDRIOError,
    MissingWeightsError,
    NoFaceError,
    NonFiniteError,
    ShapeError,
    TruncatedImageError,
    TypeCheckError,
    ValueCheckError,
)
from kornia_ilum.detection import create_detector, crop_faces
from kornia_ilum.estimators import PARITY_ATOL, LightingEstimate, TestTimeAugmented, create_estimator
from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum.io import read_hdr, read_ldr, write_ldr
from kornia_ilum.metrics import total_radiance
from kornia_ilum_uniform import SKIN_ALBEDO

# The astronaut's face box found by the Haar cascade is (177, 66, 274, 163); this region holds the face.
FACE = (slice(40, 200), slice(150, 300))  # rows, columns of skimage.data.astronaut()


@pytest.fixture(scope="module")
def astronaut() -> np.ndarray:
    return skimage.data.astronaut()  # (512, 512, 3) uint8 RGB, one face


@pytest.fixture(scope="module")
def astronaut_estimate(astronaut) -> LightingEstimate:
    return estimate_lighting(astronaut)


def _tensor(array: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(array).permute(2, 0, 1).float() / 255


def _paste(canvas: np.ndarray, face: np.ndarray, x: int, y: int) -> None:
    canvas[y : y + face.shape[0], x : x + face.shape[1]] = face


def _write_png(path, pixels: np.ndarray) -> None:
    """Write an (H, W[, C]) uint8 / uint16 array as PNG through OpenImageIO, keeping its channels and depth."""
    pixels = pixels if pixels.ndim == 3 else pixels[..., None]
    out = oiio.ImageOutput.create(str(path))
    spec = oiio.ImageSpec(pixels.shape[1], pixels.shape[0], pixels.shape[2], "uint16" if pixels.dtype == np.uint16 else "uint8")
    spec.attribute("oiio:UnassociatedAlpha", 1)  # store the colours as given (no division by alpha)
    assert out.open(str(path), spec) and out.write_image(pixels) and out.close()


def _no_face() -> np.ndarray:
    """A smooth colour gradient: no face for any detector."""
    y, x = np.mgrid[0:240, 0:320].astype(np.float32)
    return np.stack([x / 320, y / 240, 0.5 + 0 * x], axis=-1)


class TestEstimateLighting:
    def test_smoke(self, astronaut_estimate):
        est = astronaut_estimate
        assert isinstance(est, LightingEstimate)
        assert len(est) == 1
        assert est.image_index.tolist() == [0]
        assert est.image_index.dtype == torch.int64

    def test_astronaut_box(self, astronaut_estimate):
        x0, y0, x1, y1 = astronaut_estimate.boxes[0].tolist()
        assert 0 <= x0 < x1 <= 512 and 0 <= y0 < y1 <= 512
        assert 150 < (x0 + x1) / 2 < 300 and 60 < (y0 + y1) / 2 < 190  # the face, not the flag or the suit
        assert 60 < x1 - x0 < 160 and 60 < y1 - y0 < 160

    def test_astronaut_lighting(self, astronaut_estimate, astronaut):
        """The default (ours, trained): HDR lighting on the ball; brighter above the astronaut than below."""
        mb, valid = astronaut_estimate.mirror_ball, astronaut_estimate.valid
        assert mb.shape == (1, 3, 32, 32) and mb.dtype == torch.float32
        assert torch.isfinite(mb).all() and (mb >= 0).all()
        assert torch.equal(valid, mirror_ball_valid(32))
        assert (mb[..., ~valid] == 0).all()
        assert astronaut_estimate.log_mirror_ball is not None and mb[0][:, valid].std() > 0
        mb = estimate_lighting(astronaut, estimator="uniform").mirror_ball  # the uniform baseline
        colour = mb[0][:, valid]  # (3, P): uniform lighting is one colour over the ball
        torch.testing.assert_close(colour, colour[:, :1].expand_as(colour))
        rgb = colour[:, 0]
        # a bright, near-white (slightly blue) studio light: plausible magnitude and colour
        assert ((rgb > 0.3) & (rgb < 10)).all(), rgb
        assert rgb.max() / rgb.min() < 2.0, rgb

    def test_cardinality_batch(self, astronaut):
        image = _tensor(astronaut)
        est = estimate_lighting(torch.stack([image, image.flip(-1)]))
        assert est.mirror_ball.shape == (2, 3, 32, 32)
        assert est.boxes.shape == (2, 4) and est.image_index.tolist() == [0, 1]
        x0, _, x1, _ = est.boxes[1].tolist()  # mirrored image: the face box is mirrored too
        ref = estimate_lighting(image).boxes[0]
        assert abs((x0 + x1) / 2 - (512 - (ref[0] + ref[2]).item() / 2)) < 8

    def test_multi_face_all(self, astronaut):
        face = astronaut[FACE]
        big = torch.nn.functional.interpolate(_tensor(face)[None], scale_factor=1.3, mode="bilinear")[0]
        big = (big.clamp(0, 1) * 255).round().byte().permute(1, 2, 0).numpy()
        canvas = np.full((420, 960, 3), 128, np.uint8)
        places = [(20, 40), (330, 200), (640, 100)]
        _paste(canvas, face, *places[0])
        _paste(canvas, big, *places[1])  # the largest face
        _paste(canvas, face, *places[2])
        single = np.full((300, 300, 3), 90, np.uint8)
        _paste(single, face, 70, 60)
        batch = torch.stack([_tensor(canvas), torch.nn.functional.pad(_tensor(single), (0, 660, 0, 120))])

        est = estimate_lighting(batch, faces="all")
        assert len(est) == 4 and est.mirror_ball.shape == (4, 3, 32, 32)
        assert est.image_index.tolist() == [0, 0, 0, 1]
        centres = ((est.boxes[:, :2] + est.boxes[:, 2:]) / 2).tolist()
        expected = [(x + 75 * s, y + 80 * s) for (x, y), s in zip(places, (1, 1.3, 1))]
        for cx, cy in expected:  # every pasted face found once, in image 0
            assert sum(abs(cx - c[0]) < 40 and abs(cy - c[1]) < 40 for c in centres[:3]) == 1
        assert abs(centres[3][0] - 145) < 40 and abs(centres[3][1] - 140) < 40
        assert torch.isfinite(est.mirror_ball).all()

        largest = estimate_lighting(batch, faces="largest")
        assert largest.image_index.tolist() == [0, 1]
        cx = (largest.boxes[0, 0] + largest.boxes[0, 2]).item() / 2
        assert abs(cx - expected[1][0]) < 40  # the 1.3x face

    def test_no_face(self):
        with pytest.raises(NoFaceError, match=r"no face found in image by detector 'opencv'.*yunet.*fallback='full_image'"):
            estimate_lighting(_no_face(), detector="opencv")
        with pytest.raises(NoFaceError, match=r"no face found in image by detector 'yunet'; try detector='none'"):
            estimate_lighting(_no_face())
        batch = torch.stack([_tensor(skimage.data.astronaut()[:240, :320]), torch.from_numpy(_no_face()).permute(2, 0, 1)])
        with pytest.raises(NoFaceError, match=r"image 1 of the batch of 2"):
            estimate_lighting(batch)

    def test_fallback_full_image(self):
        est = estimate_lighting(_no_face(), fallback="full_image")
        torch.testing.assert_close(est.boxes, torch.tensor([[40.0, 0.0, 280.0, 240.0]]))
        assert est.image_index.tolist() == [0]
        assert torch.isfinite(est.mirror_ball).all() and (est.mirror_ball >= 0).all()
        assert est.mirror_ball.amax() > 0

    def test_fallback_only_where_needed(self, astronaut):
        image = _tensor(astronaut)
        grad = torch.nn.functional.interpolate(torch.from_numpy(_no_face()).permute(2, 0, 1)[None], size=(512, 512))[0]
        est = estimate_lighting(torch.stack([image, grad]), fallback="full_image")
        assert est.image_index.tolist() == [0, 1]
        torch.testing.assert_close(est.boxes[0], estimate_lighting(image).boxes[0])
        torch.testing.assert_close(est.boxes[1], torch.tensor([0.0, 0.0, 512.0, 512.0]))

    def test_full_image_box(self):
        torch.testing.assert_close(full_image_box(480, 640), torch.tensor([[80.0, 0.0, 560.0, 480.0]]))
        torch.testing.assert_close(full_image_box(301, 200), torch.tensor([[0.0, 50.5, 200.0, 250.5]]))

    @given(height=st.integers(1, 5000), width=st.integers(1, 5000))
    def test_full_image_box_property(self, height, width):
        x0, y0, x1, y1 = full_image_box(height, width)[0].tolist()
        assert x1 - x0 == y1 - y0 == min(height, width)  # the largest square ...
        assert 0 <= x0 and 0 <= y0 and x1 <= width and y1 <= height  # ... inside the image ...
        assert x0 + x1 == width and y0 + y1 == height  # ... centred

    def test_detector_none_and_instances(self, astronaut):
        crop = astronaut[FACE][:150, :150]
        est = estimate_lighting(crop, detector="none", estimator="uniform")
        torch.testing.assert_close(est.boxes, torch.tensor([[0.0, 0.0, 150.0, 150.0]]))
        estimator = create_estimator("uniform")
        estimator.train()
        again = estimate_lighting(crop, estimator=estimator, detector=create_detector("none"))
        assert estimator.training  # the caller's mode is restored
        torch.testing.assert_close(again.mirror_ball, est.mirror_ball)

    def test_estimator_cached(self, astronaut, monkeypatch):
        calls = []
        real = api.create_estimator

        def counting(name, pretrained=True, **kw):
            calls.append(name)
            return real(name, pretrained=pretrained, **kw)

        api.cached_estimator.cache_clear()
        monkeypatch.setattr(api, "create_estimator", counting)
        estimate_lighting(astronaut, estimator="ours")
        estimate_lighting(astronaut)  # None = DEFAULT_ESTIMATOR = "ours": the same cached model
        assert calls == ["ours"]
        api.cached_estimator.cache_clear()

    def test_runtime_and_stage_timings(self, astronaut, astronaut_estimate):
        timings = {}
        fast = estimate_lighting(astronaut, runtime="onnx", on_stage=timings.__setitem__)
        assert list(timings) == ["check", "detect", "crop", "estimate"] and all(v >= 0 for v in timings.values())
        a, b = torch.log1p(fast.mirror_ball), torch.log1p(astronaut_estimate.mirror_ball)
        assert float((a - b).abs().amax()) <= PARITY_ATOL
        with pytest.raises(ValueCheckError, match="runtime must be one of"):
            estimate_lighting(astronaut, runtime="tensorrt")
        with pytest.raises(ValueCheckError, match="applies to an estimator given by name"):
            estimate_lighting(astronaut, estimator=create_estimator("uniform"), runtime="onnx")

    def test_downscaled_detection_crops_from_the_full_image(self, astronaut):
        small = create_detector("opencv", max_side=256)  # the astronaut is 512 x 512
        est = estimate_lighting(astronaut, detector=small)
        full = estimate_lighting(astronaut, detector="opencv")
        torch.testing.assert_close(est.boxes, full.boxes, atol=12, rtol=0)  # in full-image pixels
        assert api.cached_detector("opencv", torch.device("cpu"), 256).max_side == 256
        with pytest.raises(ValueCheckError, match="max_side"):
            create_detector("opencv", max_side=0)

    def test_yunet(self, astronaut, shared_data):
        detector = create_detector("yunet", weights_path=shared_data / "weights" / "yunet_final.pth")
        est = estimate_lighting(astronaut, detector=detector)
        ref = estimate_lighting(astronaut)
        centre = (est.boxes[0, :2] + est.boxes[0, 2:]) / 2
        torch.testing.assert_close(centre, (ref.boxes[0, :2] + ref.boxes[0, 2:]) / 2, atol=15, rtol=0)

    def test_ours_untrained(self, astronaut):
        net = create_estimator("ours", pretrained=False)
        est = estimate_lighting(astronaut, estimator=net)
        assert est.mirror_ball.shape == (1, 3, 32, 32) and est.log_mirror_ball is not None
        assert torch.isfinite(est.mirror_ball).all()

    def test_device(self, astronaut, device):
        est = estimate_lighting(_tensor(astronaut).to(device))
        assert est.mirror_ball.device.type == device.type
        assert est.boxes.device.type == device.type and est.image_index.device.type == device.type

    def test_exception(self, astronaut, untrained_name):
        with pytest.raises(TypeCheckError, match=r"image must be .*torch.Tensor.*NumPy array.*path.*got list"):
            estimate_lighting([astronaut])
        with pytest.raises(TypeCheckError, match=r"image \(NumPy array\) must be uint8, uint16 or float.*int32"):
            estimate_lighting(astronaut.astype(np.int32))
        with pytest.raises(ShapeError, match=r"image \(NumPy array\) must have shape .*got \(512, 512, 2\)"):
            estimate_lighting(astronaut[..., :2])
        with pytest.raises(ShapeError, match=r"image must have shape \(\*, 3, H, W\)"):
            estimate_lighting(torch.rand(4, 64, 64))
        with pytest.raises(ShapeError, match=r"image must have shape \(3, H, W\) or \(B, 3, H, W\)"):
            estimate_lighting(torch.rand(1, 1, 3, 64, 64))
        with pytest.raises(TypeCheckError, match=r"image must be a floating-point tensor"):
            estimate_lighting(torch.from_numpy(astronaut).permute(2, 0, 1))
        with pytest.raises(ValueCheckError, match=r"image must be sRGB-encoded in \[0, 1\], got values in \[0, 255\]"):
            estimate_lighting(astronaut.astype(np.float32))
        with pytest.raises(ValueCheckError, match=r"in \[0, 1\]"):
            estimate_lighting(torch.full((3, 64, 64), -0.1))
        nan = _tensor(astronaut)
        nan[0, 0, 0] = float("nan")
        with pytest.raises(NonFiniteError, match=r"image must be finite"):
            estimate_lighting(nan)
        with pytest.raises(EmptyTensorError, match=r"image must not be empty"):
            estimate_lighting(np.zeros((0, 10, 3), np.uint8))
        with pytest.raises(ValueCheckError,
                           match=r"faces must be one of \('largest', 'all', 'fused'\), got 'many'"):
            estimate_lighting(astronaut, faces="many")
        with pytest.raises(ValueCheckError, match=r"fallback must be None or 'full_image', got 'crop'"):
            estimate_lighting(astronaut, fallback="crop")
        with pytest.raises(ValueCheckError, match=r"bgr=True applies to NumPy arrays only"):
            estimate_lighting(_tensor(astronaut), bgr=True)
        with pytest.raises(TypeCheckError, match=r"bgr must be a bool"):
            estimate_lighting(astronaut, bgr="yes")
        with pytest.raises(TypeCheckError, match=r"estimator must be None .*got int"):
            estimate_lighting(astronaut, estimator=3)
        with pytest.raises(ValueCheckError, match=r"estimator is on meta but the image is processed on cpu"):
            estimate_lighting(astronaut, estimator=create_estimator("uniform").to("meta"))
        with pytest.raises(TypeCheckError, match=r"detector must be a registered name .*got NoneType"):
            estimate_lighting(astronaut, detector=None)
        with pytest.raises(ValueError, match=r"unknown estimator 'nope'.*uniform"):
            estimate_lighting(astronaut, estimator="nope")
        with pytest.raises(ValueError, match=r"unknown detector 'haar'.*opencv"):
            estimate_lighting(astronaut, detector="haar")
        with pytest.raises(MissingWeightsError, match=r"'untrained' is registered but ships no trained weights"):
            estimate_lighting(astronaut, estimator=untrained_name)
        with pytest.raises(HDRIOError, match=r"cannot read .*missing.png: no such file"):
            estimate_lighting("missing.png")

    def test_top_level_export(self):
        assert kornia_ilum.estimate_lighting is estimate_lighting
        assert "estimate_lighting" in kornia_ilum.__all__
        assert kornia_ilum.create_estimator is create_estimator and "ours" in kornia_ilum.list_estimators()
        assert {"create_estimator", "list_estimators"} <= set(kornia_ilum.__all__)


class TestChecksOnce:
    """estimate_lighting scans the image's values once per call (NaN/Inf and the [0, 1] range together);
    the detector, the crop and the estimator, called directly, still check their own input."""

    @pytest.fixture
    def scans(self, monkeypatch) -> list[tuple[int, ...]]:
        """The shape of every tensor torch.aminmax scans (the value checks' one pass) during the test."""
        shapes, real = [], torch.aminmax

        def counting(x, *args, **kw):
            shapes.append(tuple(x.shape))
            return real(x, *args, **kw)

        monkeypatch.setattr(torch, "aminmax", counting)
        return shapes

    @pytest.mark.parametrize("form", ["array", "tensor", "batch", "file"])
    def test_one_scan_per_call(self, astronaut, astronaut_estimate, tmp_path, scans, form):
        forms = {"array": astronaut, "tensor": _tensor(astronaut), "batch": _tensor(astronaut)[None]}
        image = forms.get(form)
        if form == "file":
            write_ldr(tmp_path / "a.png", _tensor(astronaut))
            image = tmp_path / "a.png"
        scans.clear()
        est = estimate_lighting(image)  # the default detector and estimator (opencv, ours)
        image_scans = [s for s in scans if s[-2:] == (512, 512)]
        crop_scans = [s for s in scans if s[-2:] == (256, 256)]
        assert len(image_scans) == 1 and crop_scans == [], scans
        torch.testing.assert_close(est.mirror_ball, astronaut_estimate.mirror_ball, atol=1e-5, rtol=1e-5)

    def test_the_scan_runs_first(self, scans):
        """The one scan still stops a bad image before detection and estimation, with the same errors."""
        message = r"image must be sRGB-encoded in \[0, 1\], got values in \[2, 2\]"
        with pytest.raises(ValueCheckError, match=message):
            estimate_lighting(torch.full((3, 64, 64), 2.0), estimator="uniform")
        inf = torch.zeros(1, 3, 64, 64)
        inf[0, 1, 2, 3] = float("inf")
        with pytest.raises(NonFiniteError, match=r"image must be finite, but it holds NaN or Inf"):
            estimate_lighting(inf, estimator="uniform")
        with pytest.raises(NonFiniteError, match=r"image must be finite"):  # before the shape's upper bound
            estimate_lighting(torch.full((1, 1, 3, 8, 8), float("nan")))
        assert len(scans) == 3

    def test_direct_calls_still_check(self, scans):
        bright, nan = torch.full((1, 3, 256, 256), 1.5), torch.full((1, 3, 256, 256), float("nan"))
        detector, estimator = create_detector("none"), create_estimator("uniform")
        with pytest.raises(ValueCheckError, match=r"image must be sRGB in \[0, 1\]"):
            detector.detect(bright)
        with pytest.raises(NonFiniteError, match=r"image must be finite"):
            detector(nan)
        with pytest.raises(ValueCheckError, match=r"crops must be sRGB-encoded values in \[0, 1\]"):
            estimator(bright)
        with pytest.raises(NonFiniteError, match=r"crops must be finite"):
            estimator(nan)
        with pytest.raises(NonFiniteError, match=r"image must be finite"):
            crop_faces(nan, torch.tensor([[0.0, 0.0, 8.0, 8.0]]))
        assert len(scans) == 5  # one pass each

    def test_check_values_false_skips_only_the_scan(self, scans):
        """The keyword estimate_lighting passes: no scan, but shapes and dtypes are still checked."""
        bright = torch.full((1, 3, 256, 256), 1.5)
        assert len(create_detector("none").detect(bright, check_values=False)) == 1
        box = torch.tensor([[0.0, 0.0, 8.0, 8.0]])
        assert crop_faces(bright, box, size=4, check_values=False).shape == (1, 3, 4, 4)
        assert [s for s in scans if s[-2:] == (256, 256)] == []  # only the (1, 4) boxes are scanned
        with pytest.raises(ShapeError):
            create_detector("none").detect(torch.rand(1, 4, 8, 8), check_values=False)
        with pytest.raises(TypeCheckError):
            create_estimator("uniform")(torch.zeros(1, 3, 256, 256, dtype=torch.uint8), check_values=False)
        with pytest.raises(ShapeError):
            create_estimator("uniform")(torch.rand(1, 3, 128, 128), check_values=False)


class TestInputs:
    """Every accepted input form gives the same estimate as the uint8 RGB array."""

    def test_numpy_forms(self, astronaut, astronaut_estimate):
        ref = astronaut_estimate.mirror_ball
        for image, bgr in [
            (np.ascontiguousarray(astronaut[..., ::-1]), True),  # OpenCV's BGR
            (astronaut.astype(np.float32) / 255, False),
            (astronaut.astype(np.float64) / 255, False),
            (astronaut.astype(np.uint16) * 257, False),
            (np.concatenate([astronaut, np.full((512, 512, 1), 7, np.uint8)], axis=-1), False),  # RGBA
            (_tensor(astronaut), False),
            (_tensor(astronaut).double(), False),
            (_tensor(astronaut)[None], False),
        ]:
            est = estimate_lighting(image, bgr=bgr)
            torch.testing.assert_close(est.mirror_ball, ref, atol=1e-5, rtol=1e-5)
            torch.testing.assert_close(est.boxes, astronaut_estimate.boxes)

    def test_bgr_flag_matters(self, astronaut, astronaut_estimate):
        swapped = estimate_lighting(astronaut, bgr=True)  # an RGB array read as BGR: red and blue swap
        torch.testing.assert_close(swapped.mirror_ball, estimate_lighting(np.ascontiguousarray(astronaut[..., ::-1])).mirror_ball)
        assert not torch.allclose(swapped.mirror_ball, astronaut_estimate.mirror_ball, rtol=0.05)

    def test_png_8_and_16_bit(self, astronaut, astronaut_estimate, tmp_path):
        write_ldr(tmp_path / "a8.png", _tensor(astronaut))
        _write_png(tmp_path / "a16.png", astronaut.astype(np.uint16) * 257)
        assert read_ldr(tmp_path / "a16.png").shape == (3, 512, 512)
        for name in ("a8.png", "a16.png"):
            for path in (str(tmp_path / name), tmp_path / name):  # str and os.PathLike
                est = estimate_lighting(path)
                torch.testing.assert_close(est.mirror_ball, astronaut_estimate.mirror_ball, atol=1e-5, rtol=1e-5)

    def test_grey(self, astronaut, tmp_path):
        grey = np.rint(skimage.color.rgb2gray(astronaut) * 255).astype(np.uint8)
        _write_png(tmp_path / "grey.png", grey)
        from_file = estimate_lighting(tmp_path / "grey.png")
        for image in (grey, grey[..., None]):
            torch.testing.assert_close(estimate_lighting(image).mirror_ball, from_file.mirror_ball)
        rgb = estimate_lighting(tmp_path / "grey.png", estimator="uniform").mirror_ball[0, :, 16, 16]
        # a grey photo: the same linear mean in R, G and B, divided by the coloured skin albedo
        torch.testing.assert_close(rgb * torch.tensor(SKIN_ALBEDO), (rgb * torch.tensor(SKIN_ALBEDO))[:1].expand(3))

    def test_rgba_file(self, astronaut, astronaut_estimate, tmp_path):
        rgba = np.concatenate([astronaut, np.linspace(0, 255, 512, dtype=np.uint8)[None, :, None].repeat(512, 0)], -1)
        _write_png(tmp_path / "rgba.png", rgba)
        est = estimate_lighting(tmp_path / "rgba.png")  # alpha dropped, colours as stored
        torch.testing.assert_close(est.mirror_ball, astronaut_estimate.mirror_ball, atol=1e-5, rtol=1e-5)

    def test_unreadable_file(self, tmp_path):
        (tmp_path / "bad.png").write_text("not a png")
        with pytest.raises(HDRIOError, match=r"cannot read .*bad.png"):
            estimate_lighting(tmp_path / "bad.png")


    @staticmethod
    def _truncated(astronaut: np.ndarray, tmp_path, name: str):
        """The astronaut written as ``name`` (a valid file), then cut in half."""
        write_ldr(tmp_path / ("whole_" + name), _tensor(astronaut))
        data = (tmp_path / ("whole_" + name)).read_bytes()
        (tmp_path / name).write_bytes(data[: len(data) // 2])
        (tmp_path / ("whole_" + name)).unlink()
        return tmp_path / name

    @pytest.mark.parametrize("name", ["half.jpg", "half.png"])
    def test_truncated_file(self, astronaut, tmp_path, name):
        path = self._truncated(astronaut, tmp_path, name)
        with pytest.raises(TruncatedImageError, match=rf"cannot read .*{name[:-4]}\.{name[-3:]}: the file is truncated"):
            estimate_lighting(path)

    @pytest.mark.parametrize("name", ["half.jpg", "half.png"])
    def test_truncated_file_cli(self, astronaut, tmp_path, capsys, name):
        from kornia_ilum.cli import main

        path = self._truncated(astronaut, tmp_path, name)
        assert main(["estimate", str(path), "-o", str(tmp_path / "light.exr"), "--preview", str(tmp_path / "p.png")]) == 1
        captured = capsys.readouterr()
        lines = captured.err.strip().splitlines()
        assert len(lines) == 1 and "Traceback" not in captured.err, captured.err
        assert lines[0].startswith(f"kornia-ilum: error: cannot read {path}: the file is truncated"), lines[0]
        assert sorted(p.name for p in tmp_path.iterdir()) == [name]  # no lighting, no preview, no temporary


class TestOutputs:
    def test_exr_round_trip(self, astronaut_estimate, tmp_path):
        path = astronaut_estimate.save(tmp_path / "light.exr")
        torch.testing.assert_close(read_hdr(path), astronaut_estimate.mirror_ball[0], atol=0, rtol=0)
        latlong = astronaut_estimate.save(tmp_path / "light_ll.exr", latlong_height=16)
        torch.testing.assert_close(read_hdr(latlong), astronaut_estimate.to_latlong(16)[0], atol=0, rtol=0)

    def test_hdr_round_trip(self, astronaut_estimate, tmp_path):
        path = astronaut_estimate.save(tmp_path / "light.hdr")
        expected = astronaut_estimate.mirror_ball[0]
        back = read_hdr(path)
        assert back.shape == (3, 32, 32)
        assert (back <= expected + 1e-6).all()  # RGBE truncates: at most 1/128 of the pixel's largest channel
        assert (expected - back <= expected.amax(0, keepdim=True) / 128 + 1e-6).all()

    def test_preview(self, astronaut_estimate, tmp_path):
        size = 32
        path = astronaut_estimate.preview(tmp_path / "preview.png", size=size)
        image = read_ldr(path)
        assert image.shape == (3, size, 3 * size)
        disk = mirror_ball_valid(size)
        for k in range(3):  # diffuse, matte silver, mirror: lit inside the disc, black outside
            tile = image[:, :, k * size : (k + 1) * size]
            assert (tile[:, disk].amax(0) > 0.05).all(), k
            assert (tile[:, ~disk] == 0).all(), k
        diffuse = image[:, :, :size][:, disk]
        assert 0.5 < diffuse.amax() <= 1.0  # exposed so the diffuse sphere's 99th percentile is near 0.9


class TestTTA:
    """``tta=N``: the estimator wrapped in TestTimeAugmented(jitters=N), 2N passes per face."""

    def test_tta(self, astronaut, astronaut_estimate):
        est = estimate_lighting(astronaut, tta=2)
        assert est.mirror_ball.shape == (1, 3, 32, 32) and est.log_mirror_ball is not None
        torch.testing.assert_close(est.boxes, astronaut_estimate.boxes)  # the same face, the same crop
        assert est.image_index.tolist() == [0]
        wrapped = TestTimeAugmented(create_estimator("ours"), jitters=2)
        torch.testing.assert_close(est.mirror_ball, estimate_lighting(astronaut, estimator=wrapped).mirror_ball)
        assert not torch.equal(est.mirror_ball, astronaut_estimate.mirror_ball)
        ratio = est.mirror_ball.sum() / astronaut_estimate.mirror_ball.sum()
        assert 0.5 < ratio < 2.0, ratio  # an average of views of the same face: the same light, roughly

    def test_tta_one_pass_per_view(self, astronaut, monkeypatch):
        estimator = create_estimator("uniform")
        sizes, real = [], type(estimator).predict

        def counting(self, crops):
            sizes.append(len(crops))
            return real(self, crops)

        monkeypatch.setattr(type(estimator), "predict", counting)
        estimator.train()
        est = estimate_lighting(astronaut, estimator=estimator, tta=3)
        assert sizes == [6] and len(est) == 1  # 3 windows and their mirrors, one batch
        assert estimator.training  # the caller's mode is restored

    def test_tta_exception(self, astronaut):
        with pytest.raises(ValueCheckError, match=r"tta must be positive, got 0"):
            estimate_lighting(astronaut, tta=0)
        with pytest.raises(TypeCheckError, match=r"tta must be an int, got str"):
            estimate_lighting(astronaut, tta="4")
        with pytest.raises(TypeCheckError, match=r"tta must be an int, got bool"):
            estimate_lighting(astronaut, tta=True)


class TestScene:
    """``scene=SceneStrength``: each face's strength fused with the whole photo's, its shape kept."""

    def test_the_shape_is_the_face_s_and_the_spread_narrows(self, astronaut, astronaut_estimate):
        from kornia_ilum.estimators import SceneStrength

        torch.manual_seed(0)
        scene = SceneStrength()
        est = estimate_lighting(astronaut, scene=scene)
        face = astronaut_estimate
        valid = face.valid
        ratio = est.mirror_ball[:, :, valid] / face.mirror_ball[:, :, valid]  # one gain per channel
        torch.testing.assert_close(ratio, ratio[..., :1].expand_as(ratio), rtol=1e-4, atol=0)
        assert bool((est.log_energy_spread < face.log_energy_spread).all())
        fused = estimate_lighting(astronaut, scene=scene, faces="fused")
        assert len(fused) == 1 and fused.log_energy_spread is not None and fused.scene_share is not None
        assert est.scene_share is not None and bool(((est.scene_share > 0) & (est.scene_share < 1)).all())

    def test_a_crop_leaves_the_face_in_charge(self, astronaut):
        """``detector="none"``: the photo is the face, nothing besides it to read: the face's own strength."""
        from kornia_ilum.estimators import SceneStrength

        crop = torch.from_numpy(astronaut[30:230, 140:340].copy()).permute(2, 0, 1).float() / 255
        alone = estimate_lighting(crop, detector="none")
        est = estimate_lighting(crop, detector="none", scene=SceneStrength())
        assert float(est.scene_share) < 1e-3
        torch.testing.assert_close(est.mirror_ball, alone.mirror_ball, rtol=2e-2, atol=1e-5)  # an untrained branch

    def test_the_faces_of_a_photo_share_its_strength(self):
        from kornia_ilum.estimators import SceneStrength

        face = skimage.data.astronaut()
        photo = np.zeros((512, 768, 3), np.uint8)
        photo[:256, :256] = face[::2, ::2]
        photo[:, 256:] = face
        torch.manual_seed(0)
        scene = SceneStrength()
        alone = estimate_lighting(photo, faces="all")
        every = estimate_lighting(photo, faces="all", scene=scene)
        assert len(every) == len(alone) >= 2
        e = torch.log(total_radiance(every.mirror_ball))
        torch.testing.assert_close(e, e[:1].expand_as(e), rtol=0, atol=1e-4)  # one strength
        valid = every.valid
        ratio = every.mirror_ball[:, :, valid] / alone.mirror_ball[:, :, valid]  # each face's own shape
        torch.testing.assert_close(ratio, ratio[..., :1].expand_as(ratio), rtol=1e-3, atol=0)
        torch.testing.assert_close(every.boxes, alone.boxes)

    def test_bad_scene(self, astronaut):
        with pytest.raises(TypeCheckError, match="scene must be a SceneStrength"):
            estimate_lighting(astronaut, scene="default")
        from kornia_ilum.estimators import SceneStrength

        with pytest.raises(ShapeError, match="spread"):  # the uniform estimator gives no spread
            estimate_lighting(astronaut, estimator="uniform", scene=SceneStrength())


@pytest.mark.parametrize("estimator", ["ours", "uniform"])
def test_an_estimate_computes_no_sphere_render_and_no_sh(estimator, monkeypatch) -> None:
    """Issue 24: inference runs no training-only branch, renders no sphere and projects no SH unless asked."""
    import kornia_ilum.estimators.base as base  # the preview's and render_spheres' own reference
    import kornia_ilum.render.spheres as spheres  # noqa: F401 - the module patched below
    import kornia_ilum.sh.harmonics as harmonics  # noqa: F401 - the module patched below

    def refuse(*args, **kwargs):
        raise AssertionError("computed without being asked for")

    for module, name in ((base, "render_spheres"), (spheres, "render_spheres"), (spheres, "render_plan"),
                         (harmonics, "sh_project"), (harmonics, "sh_reconstruct")):
        monkeypatch.setattr(module, name, refuse)
    est = estimate_lighting(skimage.data.astronaut(), estimator=estimator)
    assert torch.isfinite(est.mirror_ball).all()
    if estimator == "ours":  # uniform's own output is its SH DC term
        assert est.sh is None
        names = create_estimator("ours").state_dict()
        assert not any(k.startswith("sides") for k in names)  # MultiScaleOurs.sides, the training branches


def test_all_faces_come_largest_first_so_face_0_is_the_largest() -> None:
    """Issue 25: face 0 of faces='all' is the face of the default faces='largest'."""
    face = skimage.data.astronaut()
    small = face[::2, ::2]
    photo = np.zeros((512, 768, 3), np.uint8)
    photo[:256, :256] = small  # the small face first, where a detector scanning rows meets it first
    photo[:, 256:] = face
    every = estimate_lighting(photo, faces="all")
    largest = estimate_lighting(photo)
    sides = (every.boxes[:, 2] - every.boxes[:, 0]).tolist()
    assert len(every) >= 2 and sides == sorted(sides, reverse=True)
    torch.testing.assert_close(every.boxes[0], largest.boxes[0])
    # the same crop, estimated in a batch of two against alone: float32 rounding may differ by a few ulps
    torch.testing.assert_close(every.mirror_ball[0], largest.mirror_ball[0], rtol=1e-5, atol=1e-4)

