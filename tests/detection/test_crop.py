"""Tests of kornia_ilum.detection.crop: the paper's square face crop (LeGendre et al. 2020, Sec. 3)."""

from __future__ import annotations

import pytest
import torch
import torch.nn.functional as F
from hypothesis import given
from hypothesis import strategies as st

from kornia_ilum.core.errors import (
    EmptyTensorError,
    NonFiniteError,
    ShapeError,
    TypeCheckError,
    ValueCheckError,
)
from kornia_ilum.detection import CropFaces, SquareCropBoxes, crop_faces, square_crop_boxes
from tests.conftest import TOL, assert_close_dtype

F64 = torch.float64


def coordinate_image(height: int, width: int, channels: int = 3) -> torch.Tensor:
    """(C, H, W) float64 image whose value encodes its position: 1 + c * H * W + i * W + j (never 0)."""
    return torch.arange(1, channels * height * width + 1, dtype=F64).reshape(channels, height, width)


def padded_slice(image: torch.Tensor, x0: int, y0: int, x1: int, y1: int) -> torch.Tensor:
    """Reference crop by explicit indexing: image[:, y, x] inside the image, 0 outside."""
    channels, height, width = image.shape
    out = torch.zeros(channels, y1 - y0, x1 - x0, dtype=image.dtype)
    for r, y in enumerate(range(y0, y1)):
        for c, x in enumerate(range(x0, x1)):
            if 0 <= y < height and 0 <= x < width:
                out[:, r, c] = image[:, y, x]
    return out


class TestSquareCropBoxes:
    def test_smoke(self):
        """Hand-computed: (10, 20, 50, 100) has w 40, h 80, side 1.25 * 80 = 100, centre (30, 60)."""
        out = square_crop_boxes(torch.tensor([[10.0, 20.0, 50.0, 100.0]]))
        assert out.tolist() == [[-20.0, 10.0, 80.0, 110.0]]

    @pytest.mark.parametrize(
        "box, scale, expected",
        [
            ((0.0, 0.0, 8.0, 4.0), 1.25, (-1.0, -3.0, 9.0, 7.0)),  # wide: side 10 around (4, 2)
            (
                (100.0, 50.0, 200.0, 150.0),
                1.25,
                (87.5, 37.5, 212.5, 162.5),
            ),  # square: grows by 12.5 each side
            ((1.5, 2.5, 3.5, 3.0), 2.0, (0.5, 0.75, 4.5, 4.75)),  # side 2 * 2 = 4 around (2.5, 2.75)
            ((0.0, 0.0, 640.0, 480.0), 1.0, (0.0, -80.0, 640.0, 560.0)),  # the "none" detector's box
        ],
    )
    def test_hand_computed(self, box, scale, expected):
        assert square_crop_boxes(torch.tensor([box], dtype=F64), scale)[0].tolist() == list(expected)

    @pytest.mark.parametrize("n", [0, 1, 5])
    def test_cardinality(self, n, dtype):
        boxes = torch.tensor([[0.0, 0.0, 2.0, 3.0]], dtype=dtype).expand(n, 4)
        out = square_crop_boxes(boxes)
        assert out.shape == (n, 4) and out.dtype == dtype

    @given(
        st.floats(-1e3, 1e3),
        st.floats(-1e3, 1e3),
        st.floats(0.01, 1e3),
        st.floats(0.01, 1e3),
        st.floats(0.1, 4.0),
    )
    def test_square_centred_scaled(self, x0, y0, w, h, scale):
        box = torch.tensor([[x0, y0, x0 + w, y0 + h]], dtype=F64)
        out = square_crop_boxes(box, scale)[0]
        side = out[2:] - out[:2]
        torch.testing.assert_close(side, torch.full((2,), scale * max(w, h), dtype=F64))
        torch.testing.assert_close(out[:2] + out[2:], box[0, :2] + box[0, 2:])

    def test_exception(self):
        with pytest.raises(ShapeError, match=r"boxes must have shape \(N, 4\), got \(4,\)"):
            square_crop_boxes(torch.zeros(4))
        with pytest.raises(TypeCheckError, match="boxes must be a floating-point tensor"):
            square_crop_boxes(torch.tensor([[0, 0, 1, 1]]))
        with pytest.raises(NonFiniteError, match="boxes must be finite"):
            square_crop_boxes(torch.tensor([[0.0, 0.0, float("inf"), 1.0]]))
        with pytest.raises(
            ValueCheckError, match=r"x1 > x0 and y1 > y0, but box 1 is \[5.0, 0.0, 5.0, 1.0\]"
        ):
            square_crop_boxes(torch.tensor([[0.0, 0.0, 1.0, 1.0], [5.0, 0.0, 5.0, 1.0]]))
        with pytest.raises(ValueCheckError, match="but box 0 is"):
            square_crop_boxes(torch.tensor([[0.0, 3.0, 1.0, 1.0]]))
        with pytest.raises(ValueCheckError, match="scale must be a finite positive number, got 0"):
            square_crop_boxes(torch.tensor([[0.0, 0.0, 1.0, 1.0]]), scale=0)

    def test_gradcheck(self):
        boxes = torch.tensor([[1.0, 2.0, 4.0, 3.0], [0.0, 0.0, 2.0, 5.0]], dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(square_crop_boxes, (boxes,))

    def test_module_matches_functional(self):
        boxes = torch.tensor([[1.0, 2.0, 4.0, 3.0]])
        torch.testing.assert_close(SquareCropBoxes(1.5)(boxes), square_crop_boxes(boxes, 1.5))
        assert "scale=1.5" in repr(SquareCropBoxes(1.5))

    @pytest.mark.parametrize("dt", [torch.float16, torch.bfloat16, torch.float32])
    def test_dtypes(self, dt):
        boxes = torch.tensor([[10.0, 20.0, 50.0, 100.0], [0.0, 0.0, 8.0, 4.0]], dtype=F64)
        out = square_crop_boxes(boxes.to(dt))
        assert out.dtype == dt
        assert_close_dtype(out, square_crop_boxes(boxes), dt, scale=100.0)  # coordinates are ~100

    def test_compile(self):
        boxes = torch.tensor([[10.0, 20.0, 50.0, 100.0]])
        torch.testing.assert_close(torch.compile(square_crop_boxes)(boxes), square_crop_boxes(boxes))


class TestCropFaces:
    def test_smoke(self):
        """At the square's own size there is no resampling: the crop is exactly the zero-padded slice."""
        image = coordinate_image(64, 96)
        square = square_crop_boxes(torch.tensor([[10.0, 20.0, 50.0, 100.0]], dtype=F64))  # (-20, 10, 80, 110)
        crop = crop_faces(image, square, size=100)
        assert crop.shape == (1, 3, 100, 100) and crop.dtype == F64
        expected = padded_slice(image, -20, 10, 80, 110)
        torch.testing.assert_close(crop[0], expected, atol=0, rtol=0)
        # zeros exactly outside the image (x < 0, y >= 64), image content everywhere else
        assert (crop[0, :, :, :20] == 0).all() and (crop[0, :, 54:] == 0).all()
        assert (crop[0, :, :54, 20:] > 0).all()
        assert crop[0, 0, 0, 20].item() == 1 + 10 * 96 + 0  # row 10, column 0 of the image

    @pytest.mark.parametrize(
        "box, region",
        [
            ((-19.6, 10.4, 80.4, 110.4), (-20, 10, 80, 110)),  # corner rounded, side round(100.0) = 100
            ((-20.4, 9.6, 79.3, 109.3), (-20, 10, 80, 110)),  # side 99.7 -> 100: the far edge moves by 0.7
            ((5.2, 6.7, 9.9, 8.1), (5, 7, 10, 8)),  # w round(4.7) = 5, h round(1.4) = 1
            ((3.0, 3.0, 3.2, 3.2), (3, 3, 4, 4)),  # at least one pixel
        ],
    )
    def test_subpixel_snapping(self, box, region):
        """The top-left corner and the width and height are each rounded to whole pixels."""
        x0, y0 = round(box[0]), round(box[1])
        w, h = max(1, round(box[2] - box[0])), max(1, round(box[3] - box[1]))
        assert (x0, y0, x0 + w, y0 + h) == region
        image = coordinate_image(64, 96)
        crop = crop_faces(image, torch.tensor([box], dtype=F64), size=h)
        expected = padded_slice(image, x0, y0, x0 + w, y0 + h)
        if w == h:
            torch.testing.assert_close(crop[0], expected, atol=0, rtol=0)
        else:  # stretched to a square: same as resizing the slice
            ref = F.interpolate(
                expected[None], size=(h, h), mode="bilinear", antialias=True, align_corners=False
            )
            torch.testing.assert_close(crop, ref)

    def test_outside_the_image(self):
        image = coordinate_image(8, 8)
        crop = crop_faces(
            image, torch.tensor([[20.0, -30.0, 30.0, -20.0], [-8.0, -8.0, 0.0, 0.0]], dtype=F64), size=10
        )
        assert crop.shape == (2, 3, 10, 10) and (crop == 0).all()

    def test_whole_image_and_larger(self):
        image = coordinate_image(12, 12)
        whole = crop_faces(image, torch.tensor([[0.0, 0.0, 12.0, 12.0]], dtype=F64), size=12)
        torch.testing.assert_close(whole[0], image, atol=0, rtol=0)
        border = crop_faces(image, torch.tensor([[-2.0, -2.0, 14.0, 14.0]], dtype=F64), size=16)[0]
        torch.testing.assert_close(border[:, 2:14, 2:14], image, atol=0, rtol=0)
        assert border.sum() == image.sum()

    def test_resize_is_interpolate(self):
        """A resized crop is F.interpolate(bilinear, antialias) of the padded slice."""
        image = torch.rand(3, 40, 50, dtype=F64)
        crop = crop_faces(image, torch.tensor([[-5.0, 10.0, 25.0, 40.0]], dtype=F64), size=8)
        ref = F.interpolate(
            padded_slice(image, -5, 10, 25, 40)[None], size=(8, 8), mode="bilinear", antialias=True
        )
        torch.testing.assert_close(crop, ref, atol=0, rtol=0)

    def test_antialiasing(self):
        """A 1-pixel checkerboard downsampled 3x averages to ~0.5; point-sampling bilinear would alias it."""
        board = ((torch.arange(96)[:, None] + torch.arange(96)[None]) % 2).to(F64).expand(3, 96, 96)
        crop = crop_faces(board, torch.tensor([[0.0, 0.0, 96.0, 96.0]], dtype=F64), size=32)
        assert (crop - 0.5).abs().max() < 0.06
        aliased = F.interpolate(
            board[None], size=(32, 32), mode="bilinear", antialias=False, align_corners=False
        )
        assert (aliased - 0.5).abs().max() > 0.45  # what the crop would be without antialiasing

    def test_upsampling(self):
        image = torch.rand(3, 10, 10, dtype=F64)
        crop = crop_faces(image, torch.tensor([[2.0, 2.0, 6.0, 6.0]], dtype=F64), size=16)
        ref = F.interpolate(image[None, :, 2:6, 2:6], size=(16, 16), mode="bilinear", align_corners=False)
        torch.testing.assert_close(crop, ref)

    def test_device(self, device):
        image = coordinate_image(30, 40).to(device)
        boxes = torch.tensor([[-5.0, 3.0, 25.0, 33.0]], dtype=F64, device=device)
        out = crop_faces(image, boxes, size=30)
        assert out.device == image.device
        torch.testing.assert_close(out[0].cpu(), padded_slice(image.cpu(), -5, 3, 25, 33), atol=0, rtol=0)

    def test_cardinality(self, dtype):
        image = torch.rand(2, 3, 30, 40, dtype=dtype)
        boxes = torch.tensor(
            [[0.0, 0.0, 10.0, 10.0], [5.0, 5.0, 35.0, 35.0], [-5.0, -5.0, 50.0, 50.0]], dtype=dtype
        )
        index = torch.tensor([1, 0, 1])
        out = crop_faces(image, boxes, size=16, index=index)
        assert out.shape == (3, 3, 16, 16) and out.dtype == dtype
        torch.testing.assert_close(out[1], crop_faces(image[0], boxes[1:2], size=16)[0])
        torch.testing.assert_close(out[2], crop_faces(image[1], boxes[2:], size=16)[0])
        assert crop_faces(image[:1], boxes, size=5).shape == (3, 3, 5, 5)  # B = 1 needs no index
        assert crop_faces(image[0], boxes[:0], size=7).shape == (0, 3, 7, 7)
        assert crop_faces(torch.rand(1, 20, 20), boxes[:1], size=4).shape == (1, 1, 4, 4)  # any channel count

    def test_exception(self):
        image = torch.rand(2, 3, 8, 8)
        box = torch.tensor([[0.0, 0.0, 4.0, 4.0]])
        with pytest.raises(
            ShapeError, match=r"image must have shape \(C, H, W\) or \(B, C, H, W\), got \(8, 8\)"
        ):
            crop_faces(image[0, 0], box)
        with pytest.raises(ShapeError, match=r"index \(N,\) is required to crop from a batch of 2 images"):
            crop_faces(image, box)
        with pytest.raises(ShapeError, match=r"index must have shape \(1\), got \(2,\)"):
            crop_faces(image, box, index=torch.tensor([0, 1]))
        with pytest.raises(TypeCheckError, match="index must be an integer tensor, got dtype torch.float32"):
            crop_faces(image, box, index=torch.tensor([0.0]))
        with pytest.raises(ValueCheckError, match=r"index must be in \[0, 2\), got \[2\]"):
            crop_faces(image, box, index=torch.tensor([2]))
        with pytest.raises(ShapeError, match=r"boxes must have shape \(N, 4\), got \(1, 3\)"):
            crop_faces(image[0], box[:, :3])
        with pytest.raises(
            ValueCheckError, match=r"x1 > x0 and y1 > y0, but box 0 is \[4.0, 0.0, 0.0, 4.0\]"
        ):
            crop_faces(image[0], box[:, [2, 1, 0, 3]])
        with pytest.raises(NonFiniteError, match="boxes must be finite"):
            crop_faces(image[0], torch.tensor([[0.0, float("nan"), 4.0, 4.0]]))
        with pytest.raises(NonFiniteError, match="image must be finite"):
            crop_faces(torch.full((3, 8, 8), float("inf")), box)
        with pytest.raises(EmptyTensorError, match="image must not be empty"):
            crop_faces(torch.rand(3, 0, 8), box)
        with pytest.raises(TypeCheckError, match="image must be a floating-point tensor"):
            crop_faces(torch.zeros(3, 8, 8, dtype=torch.uint8), box)
        with pytest.raises(ValueCheckError, match="size must be positive, got 0"):
            crop_faces(image[0], box, size=0)
        with pytest.raises(TypeCheckError, match="size must be an int, got float"):
            crop_faces(image[0], box, size=256.0)

    def test_check_values(self, monkeypatch):
        """check_values=False skips the scan of the image's values, not the checks of shapes and boxes."""
        image, box = torch.full((3, 16, 16), float("nan")), torch.tensor([[2.0, 2.0, 10.0, 10.0]])
        with pytest.raises(NonFiniteError, match="image must be finite"):
            crop_faces(image, box, size=4)
        scans, real = [], torch.aminmax
        monkeypatch.setattr(torch, "aminmax", lambda x, *a, **k: scans.append(x.shape) or real(x, *a, **k))
        assert crop_faces(image, box, size=4, check_values=False).shape == (1, 3, 4, 4)
        assert scans == [box.shape]  # the boxes are still checked
        with pytest.raises(ValueCheckError, match="x1 > x0"):
            crop_faces(image, torch.tensor([[5.0, 2.0, 1.0, 10.0]]), size=4, check_values=False)
        with pytest.raises(ShapeError):
            crop_faces(torch.rand(16, 16), box, size=4, check_values=False)

    @pytest.mark.parametrize("size", [3, 9])  # downsampled (antialiased) and upsampled
    def test_gradcheck(self, size):
        image = torch.rand(1, 2, 6, 7, dtype=F64, requires_grad=True)
        boxes = torch.tensor([[-1.2, 0.6, 5.1, 6.9], [1.0, 1.0, 8.0, 8.0]], dtype=F64)
        assert torch.autograd.gradcheck(lambda x: crop_faces(x, boxes, size=size), (image,))

    def test_module_matches_functional(self):
        image, boxes = torch.rand(3, 20, 20), torch.tensor([[-3.0, 2.0, 15.0, 20.0]])
        torch.testing.assert_close(CropFaces(size=12)(image, boxes), crop_faces(image, boxes, size=12))
        assert "size=12" in repr(CropFaces(12))
        with pytest.raises(ValueCheckError, match="size must be positive"):
            CropFaces(-1)

    @pytest.mark.parametrize("dt", [torch.float16, torch.bfloat16, torch.float32])
    def test_dtypes(self, dt):
        image = torch.rand(3, 40, 40, dtype=F64)
        boxes = torch.tensor([[-5.0, 3.0, 35.0, 43.0], [10.0, 10.0, 20.0, 20.0]], dtype=F64)
        out = crop_faces(image.to(dt), boxes.to(dt), size=16)
        assert out.dtype == dt
        assert_close_dtype(out, crop_faces(image, boxes, size=16), dt)
        assert TOL[dt]["atol"] <= 3e-2

    def test_compile(self):
        image, boxes = torch.rand(3, 16, 16), torch.tensor([[-2.0, 1.0, 14.0, 17.0]])
        compiled = torch.compile(crop_faces)
        torch.testing.assert_close(compiled(image, boxes, size=8), crop_faces(image, boxes, size=8))
