r"""The paper's face crop: a square centred on the face box, side 1.25 x max(w, h), resized to 256.

LeGendre et al. (2020), Sec. 3: the network sees a square crop around the detected face, 1.25 times the
larger side of the face box, padded with zeros where it leaves the image, resized to 256 x 256.
:func:`square_crop_boxes` computes that square from face boxes; :func:`crop_faces` cuts any box region
out of an image (zero padding outside) and resizes it with antialiasing.

Convention:
    Boxes are ``(x0, y0, x1, y1)`` in continuous pixel coordinates of the input image: the image's top-left
    corner is ``(0, 0)`` and its bottom-right corner ``(W, H)``, so pixel ``(row i, column j)`` covers
    ``[j, j + 1) x [i, i + 1)`` and a box ``(0, 0, W, H)`` is the whole image. This is OpenCV's
    ``(x, y, w, h)`` rectangle as ``(x, y, x + w, y + h)``.

Reference: C. LeGendre, W.-C. Ma, R. Pandey, S. Fanello, C. Rhemann, J. Dourgarian, J. Busch,
P. Debevec, "Learning Illumination from Diverse Portraits", SIGGRAPH Asia 2020 Technical Communications.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import nn

from kornia_ilum.core.check import check_positive_int, check_same_device, check_tensor, checks_active
from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError

__all__ = ["square_crop_boxes", "SquareCropBoxes", "crop_faces", "CropFaces", "CROP_SCALE", "CROP_SIZE"]

#: Side of the paper's square crop relative to the larger side of the face box.
CROP_SCALE = 1.25
#: Side of the paper's network input, in pixels.
CROP_SIZE = 256


def _check_boxes(boxes: torch.Tensor, name: str = "boxes") -> None:
    """Typed checks of an ``(N, 4)`` xyxy box tensor: shape, float dtype, finite, ``x1 > x0``, ``y1 > y0``."""
    empty = isinstance(boxes, torch.Tensor) and boxes.numel() == 0
    check_tensor(boxes, name, ["N", "4"], nonempty=False, finite=not empty)  # aminmax fails on empty tensors
    if empty or not checks_active() or torch.compiler.is_compiling():
        return
    bad = ((boxes[:, 2] <= boxes[:, 0]) | (boxes[:, 3] <= boxes[:, 1])).nonzero()
    if bad.numel():
        i = int(bad[0, 0])
        raise ValueCheckError(
            f"{name} must be (x0, y0, x1, y1) with x1 > x0 and y1 > y0, but box {i} is {boxes[i].tolist()}"
        )


def square_crop_boxes(boxes: torch.Tensor, scale: float = CROP_SCALE) -> torch.Tensor:
    r"""The paper's square crop region around each face box.

    A square with the face box's centre and side ``scale * max(w, h)``:

    .. math::

        c = \tfrac{1}{2}(x_0 + x_1,\; y_0 + y_1), \qquad s = \text{scale} \cdot \max(x_1 - x_0,\; y_1 - y_0),
        \qquad \text{square} = (c_x - s/2,\; c_y - s/2,\; c_x + s/2,\; c_y + s/2)

    The square may extend beyond the image; :func:`crop_faces` pads it with zeros there.

    Args:
        boxes: face boxes ``(x0, y0, x1, y1)`` in input pixels (module docstring, Convention).
        scale: side of the square relative to the box's larger side; the paper's 1.25 by default.

    Returns:
        the squares ``(x0, y0, x1, y1)``, same dtype and device as ``boxes``; differentiable.

    Shape:
        - Input: :math:`(N, 4)`
        - Output: :math:`(N, 4)`

    Raises:
        ShapeError: ``boxes`` is not ``(N, 4)``.
        TypeCheckError: ``boxes`` is not a floating-point tensor.
        NonFiniteError: ``boxes`` holds NaN or Inf.
        ValueCheckError: a box has ``x1 <= x0`` or ``y1 <= y0``, or ``scale`` is not a positive number.

    Convention:
        Continuous pixel coordinates, ``(0, 0)`` at the image's top-left corner (module docstring).

    Examples:
        >>> square_crop_boxes(torch.tensor([[10.0, 20.0, 50.0, 100.0]]))  # w = 40, h = 80 -> side 100
        tensor([[-20.,  10.,  80., 110.]])
    """
    _check_boxes(boxes)
    if (
        isinstance(scale, bool)
        or not isinstance(scale, (int, float))
        or not (math.isfinite(scale) and scale > 0)
    ):
        raise ValueCheckError(f"scale must be a finite positive number, got {scale!r}")
    centre = 0.5 * (boxes[:, :2] + boxes[:, 2:])
    half = 0.5 * scale * (boxes[:, 2:] - boxes[:, :2]).amax(dim=1, keepdim=True)
    return torch.cat([centre - half, centre + half], dim=1)


class SquareCropBoxes(nn.Module):
    r"""Module twin of :func:`square_crop_boxes`.

    Args:
        scale: side of the square relative to the box's larger side (the paper's 1.25).

    Examples:
        >>> SquareCropBoxes()(torch.tensor([[0.0, 0.0, 8.0, 4.0]]))
        tensor([[-1., -3.,  9.,  7.]])
    """

    def __init__(self, scale: float = CROP_SCALE) -> None:
        super().__init__()
        self.scale = scale

    def forward(self, boxes: torch.Tensor) -> torch.Tensor:
        return square_crop_boxes(boxes, self.scale)

    def extra_repr(self) -> str:
        return f"scale={self.scale}"


def _pixel_region(box: list[float]) -> tuple[int, int, int, int]:
    """Snap a box to the pixel grid: round the top-left corner and the width and height separately."""
    x0, y0 = round(box[0]), round(box[1])
    w, h = max(1, round(box[2] - box[0])), max(1, round(box[3] - box[1]))
    return x0, y0, x0 + w, y0 + h


def _crop_padded(image: torch.Tensor, *, x0: int, y0: int, x1: int, y1: int) -> torch.Tensor:
    """``image[:, y0:y1, x0:x1]`` of a ``(C, H, W)`` image, with zeros where the region leaves the image."""
    _, height, width = image.shape
    if x1 <= 0 or y1 <= 0 or x0 >= width or y0 >= height:  # no overlap: all padding
        return image.new_zeros(image.shape[0], y1 - y0, x1 - x0)
    # F.pad with a negative amount crops, a positive one pads with zeros: one differentiable call does both.
    return F.pad(image, (-x0, x1 - width, -y0, y1 - height))


def crop_faces(
    image: torch.Tensor,
    boxes: torch.Tensor,
    *,
    size: int = CROP_SIZE,
    index: torch.Tensor | None = None,
    check_values: bool = True,
) -> torch.Tensor:
    r"""Cut box regions out of an image, zero-padded outside it, and resize them with antialiasing.

    Each box (typically from :func:`square_crop_boxes`) is first snapped to the pixel grid: its top-left
    corner ``(x0, y0)`` and its width and height are each rounded to the nearest integer
    (:func:`round`, ties to even; at least one pixel), so a square box gives a square region of whole
    pixels and every edge moves by at most half an input pixel (a 1-pixel change in side can add up to
    one more pixel at the far edge). The region's pixels are taken as they are, zeros where it leaves the
    image, and the ``(h, w)`` patch is resized to ``(size, size)`` by
    :func:`torch.nn.functional.interpolate` (``mode="bilinear"``, ``antialias=True``,
    ``align_corners=False``): a triangle filter widened by the downsampling factor, as PIL does, so
    detail finer than the output's pixels is averaged rather than aliased. A patch that already has the
    output size is returned unresampled (exactly the padded slice). A non-square box is stretched to the
    square output.

    Args:
        image: one image ``(C, H, W)``, or a batch ``(B, C, H, W)`` with ``index`` naming the image of
            each box (optional when ``B == 1``). Any values (sRGB or linear); ``C`` is usually 3.
        boxes: crop regions ``(x0, y0, x1, y1)`` in input pixels (module docstring, Convention).
        size: side of the output crops in pixels; the paper's 256 by default.
        index: ``(N,)`` integer tensor: the batch entry each box is cut from.
        check_values: scan ``image`` for NaN/Inf. ``False`` is for a caller that has scanned this very
            image already (:func:`kornia_ilum.estimate_lighting`); shapes, dtypes and boxes are checked
            either way.

    Returns:
        the crops, same dtype and device as ``image``; differentiable with respect to ``image`` (the
        snapped pixel bounds are constants, so there is no gradient with respect to ``boxes``).

    Shape:
        - Input: :math:`(C, H, W)` or :math:`(B, C, H, W)`, boxes :math:`(N, 4)`, index :math:`(N,)`
        - Output: :math:`(N, C, \text{size}, \text{size})`

    Raises:
        ShapeError: ``image`` is not ``(C, H, W)`` / ``(B, C, H, W)``, ``boxes`` is not ``(N, 4)``,
            ``index`` is not ``(N,)``, or a batch of more than one image comes without ``index``.
        TypeCheckError: ``image`` or ``boxes`` is not a floating-point tensor, ``index`` is not an integer
            tensor, ``size`` is not an int.
        NonFiniteError: ``image`` or ``boxes`` holds NaN or Inf.
        EmptyTensorError: ``image`` is empty.
        ValueCheckError: a box has ``x1 <= x0`` or ``y1 <= y0``, ``index`` is out of range,
            ``size`` is not positive, or the tensors are on different devices.

    Convention:
        Continuous pixel coordinates, ``(0, 0)`` at the image's top-left corner (module docstring). Float16
        and bfloat16 images are resampled in float32 (PyTorch's antialiased resize has no half kernels on
        the CPU) and cast back.

    Examples:
        >>> image = torch.arange(16.0).reshape(1, 4, 4)
        >>> crop_faces(image, torch.tensor([[-1.0, -1.0, 2.0, 2.0]]), size=3)  # zeros outside the image
        tensor([[[[0., 0., 0.],
                  [0., 0., 1.],
                  [0., 4., 5.]]]])
        >>> crop_faces(torch.rand(3, 480, 640), torch.tensor([[100.0, 50.0, 300.0, 250.0]])).shape
        torch.Size([1, 3, 256, 256])
    """
    if isinstance(image, torch.Tensor) and image.dim() not in (3, 4):
        raise ShapeError(f"image must have shape (C, H, W) or (B, C, H, W), got {tuple(image.shape)}")
    check_tensor(image, "image", ["*", "C", "H", "W"], finite=check_values)
    _check_boxes(boxes)
    check_positive_int(size, "size")
    batch = image if image.dim() == 4 else image[None]
    n = boxes.shape[0]
    if index is None:
        if batch.shape[0] != 1:
            raise ShapeError(
                f"index (N,) is required to crop from a batch of {batch.shape[0]} images "
                f"(image {tuple(image.shape)})"
            )
        index_list = [0] * n
    else:
        check_tensor(index, "index", [str(n)], floating=False, nonempty=False)
        if index.is_floating_point() or index.is_complex() or index.dtype == torch.bool:
            raise TypeCheckError(f"index must be an integer tensor, got dtype {index.dtype}")
        check_same_device(("image", image), ("index", index))
        index_list = index.tolist()
        if any(not 0 <= i < batch.shape[0] for i in index_list):
            raise ValueCheckError(f"index must be in [0, {batch.shape[0]}), got {index_list}")
    check_same_device(("image", image), ("boxes", boxes))
    work = batch.float() if batch.dtype in (torch.float16, torch.bfloat16) else batch
    crops = []
    for i, box in zip(index_list, boxes.detach().tolist(), strict=True):
        x0, y0, x1, y1 = _pixel_region(box)
        patch = _crop_padded(work[i], x0=x0, y0=y0, x1=x1, y1=y1)
        if patch.shape[-2:] != (size, size):
            patch = F.interpolate(
                patch[None], size=(size, size), mode="bilinear", antialias=True, align_corners=False
            )[0]
        crops.append(patch)
    if not crops:
        return image.new_zeros(0, batch.shape[1], size, size)
    return torch.stack(crops).to(image.dtype)


class CropFaces(nn.Module):
    r"""Module twin of :func:`crop_faces`.

    Args:
        size: side of the output crops in pixels (the paper's 256).

    Examples:
        >>> CropFaces(size=64)(torch.rand(3, 100, 120), torch.tensor([[10.0, 10.0, 90.0, 90.0]])).shape
        torch.Size([1, 3, 64, 64])
    """

    def __init__(self, size: int = CROP_SIZE) -> None:
        super().__init__()
        check_positive_int(size, "size")
        self.size = size

    def forward(
        self, image: torch.Tensor, boxes: torch.Tensor, index: torch.Tensor | None = None
    ) -> torch.Tensor:
        return crop_faces(image, boxes, size=self.size, index=index)

    def extra_repr(self) -> str:
        return f"size={self.size}"
