"""Tests of kornia_ilum.detection.registry: detectors by name."""

from __future__ import annotations

import pytest

from kornia_ilum.core.errors import TypeCheckError
from kornia_ilum.detection import (
    DEFAULT_DETECTOR,
    DETECTORS,
    FaceDetector,
    NoFaceDetector,
    OpenCVFaceDetector,
    YuNetFaceDetector,
    create_detector,
    describe_detector,
    list_detectors,
    register_detector,
    registry,
)


@pytest.fixture
def restore_registry():
    """Leave the process-wide registry as it was, whatever the test registers."""
    saved = dict(registry._REGISTRY)
    yield
    registry._REGISTRY.clear()
    registry._REGISTRY.update(saved)


class TestListDetectors:
    def test_smoke(self):
        assert list_detectors() == ["none", "opencv", "yunet"]
        assert DEFAULT_DETECTOR == "yunet" and DEFAULT_DETECTOR in list_detectors()

    def test_pattern(self):
        assert list_detectors("*n*") == ["none", "opencv", "yunet"]
        assert list_detectors("y*") == ["yunet"]
        assert list_detectors("nothing*") == []

    def test_read_only_view(self):
        assert set(DETECTORS) == {"none", "opencv", "yunet"}
        with pytest.raises(TypeError):
            DETECTORS["x"] = NoFaceDetector  # type: ignore[index]


class TestCreateDetector:
    def test_smoke(self):
        assert isinstance(create_detector(), YuNetFaceDetector) and create_detector().max_side == 240
        assert isinstance(create_detector("opencv"), OpenCVFaceDetector)
        assert isinstance(create_detector("none"), NoFaceDetector)

    def test_kwargs_are_forwarded(self):
        det = create_detector("opencv", min_neighbors=3, scale_factor=1.2)
        assert det.min_neighbors == 3 and det.scale_factor == 1.2

    def test_exception(self):
        with pytest.raises(
            ValueError, match=r"unknown detector 'haar'; registered detectors: none, opencv, yunet"
        ):
            create_detector("haar")
        with pytest.raises(TypeCheckError, match="detector name must be a str, got int"):
            create_detector(3)
        with pytest.raises(TypeError, match="unexpected keyword"):
            create_detector("none", size=3)


class TestRegisterDetector:
    def test_register_and_create(self, restore_registry):
        class Whole(NoFaceDetector):
            name = "whole"
            description = "the whole image, again"

        assert register_detector("whole", Whole) is Whole
        assert "whole" in list_detectors()
        assert isinstance(create_detector("whole"), Whole)
        assert describe_detector("whole") == "the whole image, again"

    def test_clobber(self, restore_registry):
        with pytest.raises(ValueError, match="detector 'opencv' is already registered; pass clobber=True"):
            register_detector("opencv", NoFaceDetector)
        assert DETECTORS["opencv"] is OpenCVFaceDetector
        register_detector("opencv", NoFaceDetector, clobber=True)
        assert isinstance(create_detector("opencv"), NoFaceDetector)

    def test_function_factory(self, restore_registry):
        def tight() -> FaceDetector:
            """OpenCV with fewer neighbours."""
            return OpenCVFaceDetector(min_neighbors=2)

        register_detector("tight", tight)
        assert create_detector("tight").min_neighbors == 2
        assert describe_detector("tight") == "OpenCV with fewer neighbours."

    def test_exception(self, restore_registry):
        with pytest.raises(TypeCheckError, match="detector name must be a non-empty str"):
            register_detector("", NoFaceDetector)
        with pytest.raises(TypeCheckError, match="factory must be callable"):
            register_detector("x", 3)  # type: ignore[arg-type]
        register_detector("bad", lambda: "not a detector")
        with pytest.raises(TypeCheckError, match="detector 'bad' must build a FaceDetector, got str"):
            create_detector("bad")


class TestDescribeDetector:
    @pytest.mark.parametrize("name", ["none", "opencv", "yunet"])
    def test_smoke(self, name):
        text = describe_detector(name)
        assert text and "\n" not in text and text == DETECTORS[name].description

    def test_does_not_build(self, monkeypatch):
        """Describing yunet needs no weights (the CLI lists it on machines without them)."""
        monkeypatch.setenv("KORNIA_ILUM_YUNET_WEIGHTS", "/no/such/file.pth")
        assert "never downloaded" in describe_detector("yunet")

    def test_exception(self):
        with pytest.raises(
            ValueError, match="unknown detector 'x'; registered detectors: none, opencv, yunet"
        ):
            describe_detector("x")
