"""Tests of kornia_ilum.detection.detectors: OpenCV's Haar cascade, Kornia's YuNet and "none".

Reference face boxes were measured once (x0, y0, x1, y1 in pixels): scikit-image's astronaut has one face
at about (177, 62, 273, 170) (OpenCV: (177, 66, 274, 163); YuNet: (179.6, 58.4, 271.0, 175.6)).
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
import skimage.data
import torch
import torch.nn.functional as F

from kornia_ilum.core.errors import (
    EmptyTensorError,
    MissingWeightsError,
    NonFiniteError,
    ShapeError,
    TypeCheckError,
    ValueCheckError,
    WeightsChecksumError,
)
from kornia_ilum.detection import (
    FaceDetector,
    NoFaceDetector,
    OpenCVFaceDetector,
    YuNetFaceDetector,
    create_detector,
    crop_faces,
    square_crop_boxes,
)
from kornia_ilum.core.files import sha256_file
from kornia_ilum.detection.detectors import (
    YUNET_SAFETENSORS_SHA256,
    YUNET_SHA256,
    YUNET_WEIGHTS,
    YUNET_WEIGHTS_ENV,
    convert_yunet_weights,
)

ASTRONAUT_FACE = torch.tensor([177.0, 62.0, 273.0, 170.0])
#: (x, y, scale) of the astronaut's face pasted into the group image.
GROUP_LAYOUT = [(20, 30, 1.0), (300, 60, 0.8), (560, 250, 1.2), (80, 380, 0.7)]


def iou(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """IoU matrix of (N, 4) and (M, 4) xyxy boxes."""
    lt = torch.maximum(a[:, None, :2], b[None, :, :2])
    rb = torch.minimum(a[:, None, 2:4], b[None, :, 2:4])
    inter = (rb - lt).clamp(min=0).prod(-1)
    area = lambda x: (x[:, 2] - x[:, 0]) * (x[:, 3] - x[:, 1])  # noqa: E731
    return inter / (area(a)[:, None] + area(b)[None] - inter)


def to_tensor(array) -> torch.Tensor:
    return torch.from_numpy(array).permute(2, 0, 1).float() / 255


@pytest.fixture(scope="module")
def astronaut() -> torch.Tensor:
    return to_tensor(skimage.data.astronaut())


@pytest.fixture(scope="module")
def coffee() -> torch.Tensor:
    """A cup of coffee on a table: no face."""
    return to_tensor(skimage.data.coffee())


@pytest.fixture(scope="module")
def gradient() -> torch.Tensor:
    """A smooth colour gradient: no face."""
    y, x = torch.meshgrid(torch.linspace(0, 1, 240), torch.linspace(0, 1, 320), indexing="ij")
    return torch.stack([x, y, 0.5 * (x + y)])


@pytest.fixture(scope="module")
def group(astronaut) -> tuple[torch.Tensor, torch.Tensor]:
    """A (3, 600, 900) image: the astronaut's face pasted 4 times at 4 scales on grey; and the face boxes."""
    face = astronaut[:, 40:200, 150:300]
    canvas = torch.full((3, 600, 900), 0.5)
    boxes = []
    for x, y, s in GROUP_LAYOUT:
        h, w = round(160 * s), round(150 * s)
        patch = F.interpolate(face[None], size=(h, w), mode="bilinear", antialias=True, align_corners=False)[
            0
        ]
        canvas[:, y : y + h, x : x + w] = patch.clamp(0, 1)
        fx0, fy0, fx1, fy1 = (ASTRONAUT_FACE - torch.tensor([150.0, 40.0, 150.0, 40.0])).tolist()
        boxes.append([x + fx0 * s, y + fy0 * s, x + fx1 * s, y + fy1 * s])
    return canvas, torch.tensor(boxes)


@pytest.fixture(scope="module")
def yunet_weights() -> Path:
    from tests.conftest import SHARED_DATA

    path = SHARED_DATA / "weights" / "yunet_final.pth"
    if not path.is_file():
        pytest.skip(f"YuNet weights not found at {path} (set KORNIA_ILUM_SHARED_DATA)")
    return path


@pytest.fixture(scope="module")
def yunet(yunet_weights) -> YuNetFaceDetector:
    return YuNetFaceDetector(weights_path=yunet_weights)


@pytest.fixture(scope="module")
def opencv() -> OpenCVFaceDetector:
    return OpenCVFaceDetector()


def assert_detections(found: list[torch.Tensor], batch: int) -> None:
    """The documented output format: B tensors (N, 5) float32, positive boxes, sorted by score."""
    assert isinstance(found, list) and len(found) == batch
    for dets in found:
        assert dets.dtype == torch.float32 and dets.dim() == 2 and dets.shape[1] == 5
        assert (dets[:, 2] > dets[:, 0]).all() and (dets[:, 3] > dets[:, 1]).all()
        assert (dets[:, 4].diff() <= 0).all() and ((dets[:, 4] > 0) & (dets[:, 4] <= 1)).all()


def assert_matches(dets: torch.Tensor, reference: torch.Tensor, min_iou: float) -> None:
    """Exactly one detection per reference face, each overlapping its face by at least min_iou."""
    assert dets.shape[0] == reference.shape[0], dets
    overlap = iou(dets[:, :4], reference)
    assert (overlap.amax(dim=0) >= min_iou).all(), overlap
    assert overlap.argmax(dim=0).unique().numel() == reference.shape[0]


@pytest.fixture(params=["opencv", "yunet"])
def detector(request) -> FaceDetector:
    return request.getfixturevalue(request.param)


class TestFaceDetectors:
    """Behaviour shared by the two real detectors (parametrised over opencv and yunet)."""

    def test_smoke(self, detector, astronaut):
        found = detector.detect(astronaut)
        assert_detections(found, 1)
        assert_matches(found[0], ASTRONAUT_FACE[None], min_iou=0.75)

    def test_group(self, detector, group):
        image, faces = group
        found = detector.detect(image)
        assert_detections(found, 1)
        assert_matches(found[0], faces, min_iou=0.7)

    def test_no_face(self, detector, coffee, gradient):
        assert detector.detect(coffee)[0].shape == (0, 5)
        assert detector.detect(gradient)[0].shape == (0, 5)

    def test_cardinality(self, detector, astronaut):
        """A batch gives one result per image, each as if detected alone; (3, H, W) is a batch of one."""
        batch = torch.stack([astronaut, torch.full_like(astronaut, 0.25), astronaut.flip(-1)])
        found = detector.detect(batch)
        assert_detections(found, 3)
        assert [d.shape[0] for d in found] == [1, 0, 1]
        torch.testing.assert_close(found[0], detector.detect(astronaut)[0], atol=1e-4, rtol=0)
        mirrored = found[2][0, :4]
        torch.testing.assert_close(found[0][0, [0, 2]], 512 - mirrored[[2, 0]], atol=4.0, rtol=0)

    def test_module_call(self, detector, astronaut):
        torch.testing.assert_close(detector(astronaut[None])[0], detector.detect(astronaut)[0])

    def test_dtypes(self, detector, astronaut):
        ref = detector.detect(astronaut)[0]
        for dt in (torch.float64, torch.float16, torch.bfloat16):
            dets = detector.detect(astronaut.to(dt))[0]
            assert dets.dtype == torch.float32 and dets.shape == ref.shape
            torch.testing.assert_close(
                dets[:, :4], ref[:, :4], atol=4.0 if dt != torch.float64 else 1e-3, rtol=0
            )

    def test_exception(self, detector, astronaut):
        with pytest.raises(
            ShapeError, match=r"image must have shape \(3, H, W\) or \(B, 3, H, W\), got \(512, 512\)"
        ):
            detector.detect(astronaut[0])
        with pytest.raises(ShapeError, match=r"image must have shape \(\*, 3, H, W\), got \(1, 4, 8, 8\)"):
            detector.detect(torch.rand(1, 4, 8, 8))
        with pytest.raises(
            TypeCheckError, match="image must be a floating-point tensor, got dtype torch.uint8"
        ):
            detector.detect((astronaut * 255).to(torch.uint8))
        with pytest.raises(
            ValueCheckError, match=r"image must be sRGB in \[0, 1\], got values in \[0, 255\]; divide 8-bit"
        ):
            detector.detect(astronaut * 255)
        with pytest.raises(ValueCheckError, match=r"got values in \[-0.1, 1\]"):
            detector.detect(astronaut - 0.1 * (astronaut == 0).float())
        with pytest.raises(NonFiniteError, match="image must be finite"):
            detector.detect(torch.full((3, 8, 8), float("nan")))
        with pytest.raises(EmptyTensorError, match="image must not be empty"):
            detector.detect(torch.rand(0, 3, 8, 8))
        with pytest.raises(TypeCheckError, match="image must be a torch.Tensor"):
            detector.detect(skimage.data.astronaut())

    def test_check_values(self, detector, astronaut, monkeypatch):
        """One scan of the values (NaN/Inf and range together); check_values=False skips only that scan."""
        scans, real = [], torch.aminmax
        monkeypatch.setattr(torch, "aminmax", lambda x, *a, **k: scans.append(x.shape) or real(x, *a, **k))
        ref = detector.detect(astronaut)[0]
        assert scans == [astronaut.shape]
        torch.testing.assert_close(detector.detect(astronaut, check_values=False)[0], ref)
        torch.testing.assert_close(detector(astronaut, check_values=False)[0], ref)
        assert scans == [astronaut.shape]
        with pytest.raises(ShapeError, match=r"image must have shape \(\*, 3, H, W\)"):
            detector.detect(torch.rand(1, 4, 8, 8), check_values=False)
        with pytest.raises(TypeCheckError, match="image must be a floating-point tensor"):
            detector.detect((astronaut * 255).to(torch.uint8), check_values=False)

    def test_crop_pipeline(self, detector, astronaut):
        """Detection -> the paper's square (inside the image here) -> a 256 x 256 crop of it."""
        boxes = detector.detect(astronaut)[0][:, :4]
        square = square_crop_boxes(boxes, detector.crop_scale)
        assert (square[:, :2] >= 0).all() and (square[:, 2:] <= 512).all()
        side = square[0, 2] - square[0, 0]
        assert 1.25 * 90 < side < 1.25 * 125
        crops = crop_faces(astronaut, square)
        assert crops.shape == (1, 3, 256, 256) and crops.std() > 0.1


class TestOpenCVFaceDetector:
    def test_smoke(self, opencv, astronaut):
        dets = opencv.detect(astronaut)[0]
        torch.testing.assert_close(dets[0, :4], torch.tensor([177.0, 66.0, 274.0, 163.0]))
        assert 0.99 < dets[0, 4] < 1.0  # sigmoid(2 (56.6 - 53.76))

    def test_score_without_threshold(self, astronaut, monkeypatch):
        det = OpenCVFaceDetector()
        det._threshold = None  # as for a cascade file whose last stage threshold cannot be read
        assert det.detect(astronaut)[0][:, 4].tolist() == [1.0]

    def test_other_cascade(self, astronaut):
        det = OpenCVFaceDetector("haarcascade_frontalface_default.xml", equalize=True)
        assert_matches(det.detect(astronaut)[0], ASTRONAUT_FACE[None], min_iou=0.75)

    def test_min_face(self, astronaut):
        """min_face is relative to the shorter side: a ~100 px face is lost when the minimum is 0.25 x 512."""
        assert OpenCVFaceDetector(min_face=0.25).detect(astronaut)[0].shape == (0, 5)

    def test_exception(self, tmp_path):
        with pytest.raises(FileNotFoundError, match="cascade 'nope.xml' not found"):
            OpenCVFaceDetector("nope.xml")
        bad = tmp_path / "bad.xml"
        bad.write_text("<opencv_storage></opencv_storage>")
        with pytest.raises(ValueCheckError, match="OpenCV could not load the cascade"):
            OpenCVFaceDetector(bad)
        with pytest.raises(ValueCheckError, match="scale_factor must be a finite number > 1, got 1.0"):
            OpenCVFaceDetector(scale_factor=1.0)
        with pytest.raises(ValueCheckError, match="min_neighbors must be a non-negative int"):
            OpenCVFaceDetector(min_neighbors=-1)
        with pytest.raises(ValueCheckError, match=r"min_face must be a fraction in \[0, 1\]"):
            OpenCVFaceDetector(min_face=2.0)


class TestYuNetFaceDetector:
    def test_smoke(self, yunet, astronaut):
        dets = yunet.detect(astronaut)[0]
        torch.testing.assert_close(dets[0, :4], torch.tensor([179.6, 58.4, 271.0, 175.6]), atol=0.5, rtol=0)
        assert dets[0, 4] > 0.99
        assert not yunet.model.training

    def test_no_face_in_a_motorcycle_or_a_cat(self, yunet, astronaut):
        """The default threshold rejects the false faces measured on scikit-image's face-free photographs
        (``benchmarks/bench_detection.py --yunet-thresholds``: a motorcycle's headlights 0.92, the only one above
        0.9 of 19; a cat 0.78), and keeps real faces (the astronaut 1.0, the cameraman 0.94)."""
        motorcycle = to_tensor(skimage.data.stereo_motorcycle()[0])
        cat = to_tensor(skimage.data.chelsea())
        for image in (motorcycle, cat):
            assert yunet.detect(image)[0].shape == (0, 5)
        looser = YuNetFaceDetector(weights_path=yunet.weights_path, confidence_threshold=0.9)
        assert looser.detect(motorcycle)[0].shape[0] == 1  # the earlier default let it through
        cameraman = torch.from_numpy(skimage.data.camera().astype("float32") / 255)[None].expand(3, -1, -1)
        for image in (astronaut, cameraman.contiguous()):
            assert yunet.detect(image)[0].shape[0] == 1

    def test_device(self, yunet_weights, astronaut, device):
        """The network runs on its own device; boxes come back on the image's device."""
        det = YuNetFaceDetector(weights_path=yunet_weights).to(device)
        on_device = det.detect(astronaut.to(device))[0]
        assert on_device.device.type == device.type
        from_cpu_image = det.detect(astronaut)[0]
        assert from_cpu_image.device.type == "cpu"
        torch.testing.assert_close(on_device.cpu(), from_cpu_image, atol=0.5, rtol=1e-3)

    def test_train_keeps_network_in_eval(self, yunet_weights):
        det = YuNetFaceDetector(weights_path=yunet_weights).train()
        assert det.training and not det.model.training

    def test_never_downloads(self, yunet_weights, monkeypatch):
        """Kornia's download path must not be reached, whatever happens."""
        import kornia.models.yunet.model as yunet_model

        def refuse(*args, **kwargs):
            raise AssertionError("YuNet weights must never be downloaded")

        monkeypatch.setattr(yunet_model, "load_state_dict_from_url", refuse)
        YuNetFaceDetector(weights_path=yunet_weights)
        with pytest.raises(MissingWeightsError):
            YuNetFaceDetector(weights_path=yunet_weights.parent / "missing.pth")

    def test_weights_from_environment(self, yunet_weights, monkeypatch, astronaut):
        monkeypatch.setenv(YUNET_WEIGHTS_ENV, str(yunet_weights))
        det = create_detector("yunet")
        assert det.weights_path == yunet_weights
        assert det.detect(astronaut)[0].shape == (1, 5)

    def test_yunet_exception(self, yunet_weights, monkeypatch, tmp_path):
        monkeypatch.setenv(YUNET_WEIGHTS_ENV, str(tmp_path / "env.pth"))
        with pytest.raises(
            MissingWeightsError,
            match=r"looked at \$KORNIA_ILUM_YUNET_WEIGHTS: .*env\.pth\. They are never downloaded",
        ):
            YuNetFaceDetector()
        with pytest.raises(MissingWeightsError, match=r"looked at weights_path: .*other\.pth\. "):
            YuNetFaceDetector(weights_path=tmp_path / "other.pth")
        with pytest.raises(WeightsChecksumError, match=f"have SHA-256 {YUNET_SHA256}, expected {'0' * 64}"):
            YuNetFaceDetector(weights_path=yunet_weights, sha256="0" * 64)
        with pytest.raises(ValueCheckError, match=r"confidence_threshold must be in \[0, 1\], got 2"):
            YuNetFaceDetector(weights_path=yunet_weights, confidence_threshold=2)

    def test_packaged_weights(self, monkeypatch, astronaut):
        """With no argument and no environment variable, the weights that ship in the package: safetensors only."""
        monkeypatch.delenv(YUNET_WEIGHTS_ENV, raising=False)
        monkeypatch.setattr(torch, "load", lambda *a, **k: pytest.fail("the packaged weights are not unpickled"))
        det = YuNetFaceDetector()
        assert det.weights_path == YUNET_WEIGHTS and YUNET_WEIGHTS.suffix == ".safetensors"
        assert sha256_file(YUNET_WEIGHTS) == YUNET_SAFETENSORS_SHA256
        assert (YUNET_WEIGHTS.parent / "LICENSE-yunet.txt").read_text().count("MIT License") == 1
        assert det.detect(astronaut)[0].shape == (1, 5)

    def test_packaged_weights_are_kornias(self, yunet_weights, tmp_path):
        """convert_yunet_weights remakes the packaged file from Kornia's yunet_final.pth, byte for byte."""
        out = tmp_path / "yunet.safetensors"
        assert convert_yunet_weights(yunet_weights, out) == YUNET_SAFETENSORS_SHA256
        assert out.read_bytes() == YUNET_WEIGHTS.read_bytes()
        with pytest.raises(WeightsChecksumError, match="not that of Kornia's yunet_final.pth"):
            convert_yunet_weights(out, tmp_path / "again.safetensors")
        with pytest.raises(FileNotFoundError):
            convert_yunet_weights(tmp_path / "missing.pth", tmp_path / "x.safetensors")
        assert sorted(p.name for p in tmp_path.iterdir()) == ["yunet.safetensors"]

    def test_postprocess_is_kornias(self, astronaut):
        """The cached-anchor post-processing gives Kornia's detections exactly, at a low threshold too."""
        from kornia.contrib import FaceDetector as KorniaFaceDetector
        from kornia.geometry.bbox import nms

        det = YuNetFaceDetector(confidence_threshold=0.3)
        det.nms = nms  # what Kornia's postprocess reads
        for image in (astronaut, astronaut[..., :200, :300], torch.rand(3, 120, 200)):
            bgr = image[None].flip(-3) * 255.0
            with torch.inference_mode():
                out = det.model(bgr)
                ours = det._postprocess(out, *bgr.shape[-2:])[0]
                theirs = KorniaFaceDetector.postprocess(det, out, *bgr.shape[-2:])[0]
            assert torch.equal(ours, theirs)

    @pytest.mark.parametrize("size", [(1, 1), (31, 100), (48, 480), (63, 2000)])
    def test_small_images(self, size):
        """YuNet's network needs 64 pixels a side: smaller images are padded, not a crash inside torch."""
        found = YuNetFaceDetector().detect(torch.rand(3, *size))
        assert found[0].shape == (0, 5)
        assert create_detector("yunet", max_side=40).detect(torch.rand(3, 300, 2000))[0].shape[1] == 5

    def test_default_detection_size(self):
        assert create_detector("yunet").max_side == YuNetFaceDetector.default_max_side == 240
        assert create_detector("yunet", max_side=None).max_side is None
        assert create_detector("opencv").max_side is None and create_detector("yunet", max_side=200).max_side == 200

    def test_sha256_can_be_skipped(self, yunet_weights, tmp_path):
        assert YuNetFaceDetector(weights_path=yunet_weights, sha256=None).weights_path == yunet_weights

    def test_confidence_threshold(self, yunet_weights, coffee):
        """Kornia's 0.3 keeps a spurious box in the coffee photograph (score ~0.5); the default 0.9 not."""
        assert (
            YuNetFaceDetector(weights_path=yunet_weights, confidence_threshold=0.3).detect(coffee)[0].shape[0]
            >= 1
        )


class TestNoFaceDetector:
    def test_smoke(self):
        found = NoFaceDetector().detect(torch.rand(2, 3, 48, 64, dtype=torch.float64))
        assert_detections(found, 2)
        for dets in found:
            assert dets.tolist() == [[0.0, 0.0, 64.0, 48.0, 1.0]]

    def test_crop_is_the_image(self):
        """crop_scale 1: a square input is cropped to exactly itself."""
        image = torch.rand(3, 256, 256)
        det = NoFaceDetector()
        boxes = square_crop_boxes(det.detect(image)[0][:, :4], det.crop_scale)
        assert boxes.tolist() == [[0.0, 0.0, 256.0, 256.0]]
        torch.testing.assert_close(crop_faces(image, boxes)[0], image, atol=0, rtol=0)

    def test_exception(self):
        with pytest.raises(ShapeError, match="image must have shape"):
            NoFaceDetector().detect(torch.rand(3, 4))


def test_no_network_access_needed(monkeypatch):
    """The default detector works offline, with no environment variable: YuNet's weights ship inside the package,
    as Haar's cascade ships inside OpenCV's wheel."""
    monkeypatch.delenv(YUNET_WEIGHTS_ENV, raising=False)
    det = create_detector()
    assert det.name == "yunet" and det.weights_path == YUNET_WEIGHTS and os.access(det.weights_path, os.R_OK)
    haar = create_detector("opencv")
    assert haar.cascade_path.is_file() and os.access(haar.cascade_path, os.R_OK)
