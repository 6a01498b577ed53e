r"""Shared machinery of the light stage's image-space filters (:mod:`.subsurface`, :mod:`.denoise`).

Both filters are one fixed sparse linear operator over the pixels of a reflectance field, built once from
the :class:`~kornia_ilum_lab.synth.lightstage.gbuffer.GBuffer` (never from the radiance) and applied to every
``(channel, light)`` column. :class:`PixelOperator` holds it as one ``torch.sparse_csr`` matrix per channel
(or a sequence of them, applied in turn) over a subset of the pixels; the other pixels pass through.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import torch

from kornia_ilum.core.check import check_tensor, checks_active
from kornia_ilum.core.errors import ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum_lab.synth.lightstage.gbuffer import GBuffer

__all__ = ["PixelOperator", "check_field", "check_gbuffer"]

#: The field dtypes the filters accept (CSR products on the CPU need one of these).
FIELD_DTYPES = (torch.float32, torch.float64)


def check_gbuffer(gbuffer: GBuffer, name: str = "gbuffer") -> int:
    """Validate a :class:`GBuffer` (types, shapes, finite values, ``focal_px > 0``); return its side.

    Args:
        gbuffer: the buffers to check.
        name: the name used in error messages.

    Returns:
        the image side ``size`` (every buffer is ``(C, size, size)``).

    Raises:
        TypeCheckError: ``gbuffer`` is not a :class:`GBuffer`, or ``focal_px`` is not a number.
        ShapeError: a buffer has the wrong shape.
        NonFiniteError: a buffer holds NaN or Inf.
        ValueCheckError: ``focal_px`` is not positive.

    Examples:
        >>> g = GBuffer(torch.zeros(3, 2, 2), torch.zeros(3, 2, 2), torch.zeros(1, 2, 2), torch.zeros(1, 2, 2),
        ...             torch.zeros(1, 2, 2), focal_px=3.0)
        >>> check_gbuffer(g)
        2
    """
    if not isinstance(gbuffer, GBuffer):
        raise TypeCheckError(f"{name} must be a GBuffer, got {type(gbuffer).__name__}")
    size = gbuffer.size
    for attr, ch in (("albedo", 3), ("normal", 3), ("depth", 1), ("alpha", 1), ("subsurface", 1)):
        t = getattr(gbuffer, attr)
        check_tensor(t, f"{name}.{attr}", [str(ch), str(size), str(size)])
    fp = gbuffer.focal_px
    if isinstance(fp, bool) or not isinstance(fp, (int, float)):
        raise TypeCheckError(f"{name}.focal_px must be a float, got {type(fp).__name__}")
    if not fp > 0:
        raise ValueCheckError(f"{name}.focal_px must be positive, got {fp}")
    return size


def check_field(field: torch.Tensor, gbuffer: GBuffer, name: str) -> int:
    """Validate a ``(3, P, N)`` float32/float64 field against ``gbuffer``; return the image side.

    Args:
        field: a reflectance field ``(3, P, N)``: ``P = size * size`` pixels (row-major), ``N`` lights.
        gbuffer: the buffers of the same render (checked with :func:`check_gbuffer`).
        name: the field's name in error messages.

    Returns:
        the image side ``size``.

    Raises:
        TypeCheckError: ``field`` is not a float32 or float64 tensor.
        ShapeError: ``field`` is not ``(3, size * size, N)``.
        NonFiniteError: ``field`` holds NaN or Inf (when the checks are active).
        ValueCheckError: ``field`` and ``gbuffer`` are on different devices.

    Shape:
        - field: :math:`(3, P, N)`, :math:`P = size^2`

    Convention:
        The reflectance-field layout of :class:`~kornia_ilum_lab.synth.lightstage.ReflectanceField`: pixels in
        row-major order, lights in the row-major order of the mirror-ball grid (docs/conventions.rst).

    Examples:
        >>> g = GBuffer(torch.zeros(3, 2, 2), torch.zeros(3, 2, 2), torch.zeros(1, 2, 2), torch.zeros(1, 2, 2),
        ...             torch.zeros(1, 2, 2), focal_px=3.0)
        >>> check_field(torch.zeros(3, 4, 5), g, "field")
        2
    """
    size = check_gbuffer(gbuffer)
    if not isinstance(field, torch.Tensor):
        raise TypeCheckError(f"{name} must be a torch.Tensor of shape (3, P, N), got {type(field).__name__}")
    if field.dim() != 3 or field.shape[0] != 3:
        raise ShapeError(f"{name} must have shape (3, P, N), got {tuple(field.shape)}")
    if field.dtype not in FIELD_DTYPES:
        raise TypeCheckError(
            f"{name} must be float32 or float64, got dtype {field.dtype} "
            "(convert a bfloat16 field with .float())"
        )
    if field.shape[1] != size * size:
        raise ShapeError(
            f"{name} has P = {field.shape[1]} pixels but the gbuffer is {size} x {size} (P = {size * size})"
        )
    if checks_active():
        check_tensor(field, name, ["3", "P", "N"])
        if gbuffer.albedo.device != field.device:
            dev = gbuffer.albedo.device
            raise ValueCheckError(f"{name} is on {field.device} but the gbuffer is on {dev}")
    return size


def window_offsets(radius: int, step: int = 1) -> torch.Tensor:
    """``(K, 2)`` int64 ``(dy, dx)`` offsets of a ``(2 radius + 1)^2`` window, taps ``step`` pixels apart."""
    r = torch.arange(-radius, radius + 1) * step
    dy, dx = torch.meshgrid(r, r, indexing="ij")
    return torch.stack([dy.reshape(-1), dx.reshape(-1)], dim=1)


def neighbours(
    size: int, centres: torch.Tensor, offsets: torch.Tensor, pixels: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """Neighbours of ``centres`` (flat indices) at ``offsets``, as positions in ``pixels`` (flat indices).

    Returns:
        ``(idx, valid)``, both ``(len(centres), K)``: ``idx[a, k]`` is the position in ``pixels`` of the pixel
        at ``offsets[k]`` from ``centres[a]`` (0 where it is outside the image or not in ``pixels``: ``valid``
        False there).
    """
    dev = pixels.device
    pos = torch.full((size * size,), -1, dtype=torch.int64, device=dev)
    pos[pixels] = torch.arange(pixels.numel(), device=dev)
    y = (centres // size)[:, None] + offsets[None, :, 0].to(dev)
    x = (centres % size)[:, None] + offsets[None, :, 1].to(dev)
    inside = (y >= 0) & (y < size) & (x >= 0) & (x < size)
    flat = (y.clamp(0, size - 1) * size + x.clamp(0, size - 1)).reshape(-1)
    idx = pos[flat].reshape(y.shape)
    valid = inside & (idx >= 0)
    return idx.clamp_min(0), valid


def csr(rows: torch.Tensor, cols: torch.Tensor, vals: torch.Tensor, n: int) -> torch.Tensor:
    """An ``(n, n)`` ``torch.sparse_csr`` matrix from COO triplets (duplicates summed)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # "sparse CSR support is in beta"
        coo = torch.sparse_coo_tensor(torch.stack([rows, cols]), vals, (n, n)).coalesce()
        return coo.to_sparse_csr()


@dataclass
class PixelOperator:
    r"""A fixed linear operator over the pixels of a ``(3, P, N)`` field, the same for every light.

    ``out[c, pixels] = M_c[-1] @ ... @ M_c[0] @ field[c, pixels]`` and ``out[c, p] = field[c, p]`` for the
    pixels not in ``pixels``; every ``M`` is an ``(S, S)`` ``torch.sparse_csr`` matrix, ``S = len(pixels)``.

    Attributes:
        pixels: ``(S,)`` int64 flat row-major indices of the pixels the operator acts on.
        matrices: for each of the 3 channels, the matrices applied in turn.
        size: the image side (``P = size * size``).

    Examples:
        >>> double = csr(torch.tensor([0, 1]), torch.tensor([0, 1]), torch.tensor([2.0, 2.0]), 2)
        >>> op = PixelOperator(torch.tensor([0, 3]), [[double]] * 3, size=2)  # doubles two pixels of four
        >>> op.apply(torch.ones(3, 4, 1))[0, :, 0].tolist()
        [2.0, 1.0, 1.0, 2.0]
    """

    pixels: torch.Tensor
    matrices: Sequence[Sequence[torch.Tensor]]
    size: int

    def apply(self, field: torch.Tensor, chunk: int = 128) -> torch.Tensor:
        """Apply to ``field`` ``(3, P, N)``, ``chunk`` lights at a time; returns a new tensor.

        Extra memory beyond the result: two ``(S, chunk)`` blocks (the operator itself is built already).
        """
        if isinstance(chunk, bool) or not isinstance(chunk, int) or chunk <= 0:
            raise ValueCheckError(f"chunk must be a positive int, got {chunk!r}")
        if field.shape[1] != self.size * self.size:
            raise ShapeError(f"field has P = {field.shape[1]} pixels, the operator is for {self.size ** 2}")
        out = field.clone()
        if self.pixels.numel() == 0:
            return out
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            for c in range(3):
                mats = [m.to(field.dtype) for m in self.matrices[c]]
                src = field[c]
                for n0 in range(0, field.shape[2], chunk):
                    x = src[self.pixels, n0 : n0 + chunk]
                    for m in mats:
                        x = m @ x
                    out[c, self.pixels, n0 : n0 + chunk] = x
        return out

    def dense(self) -> torch.Tensor:
        """``(3, P, P)`` dense matrices (for tests on small images): ``out[c] = dense[c] @ field[c]``."""
        p = self.size * self.size
        dt = self.matrices[0][0].dtype if self.matrices and self.matrices[0] else torch.float64
        eye = torch.eye(p, dtype=dt)
        return self.apply(torch.stack([eye, eye, eye]), chunk=p)
