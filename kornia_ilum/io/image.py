r"""Reading and writing images through OpenImageIO: linear HDR (EXR, Radiance HDR) and sRGB LDR.

Every function returns or takes one ``(3, H, W)`` float image (``(1, 3, H, W)`` is accepted on write),
on the CPU. HDR files are read as stored (linear, scene-referred); LDR files as stored (sRGB-encoded,
display-referred, in ``[0, 1]``). No colour management happens: decode LDR pixels with
:func:`kornia_ilum.color.srgb_to_linear` when linear values are needed.

Every failure caused by a file (missing, a directory, empty, corrupt, truncated, an unknown or unsuitable
format, NaN/Inf inside, a value that the format cannot hold) raises
:class:`~kornia_ilum.core.errors.HDRIOError`, an :class:`OSError` whose message names the path; OpenImageIO's
own messages are appended, never raised raw. A file that ends before its image data does raises the
subclass :class:`~kornia_ilum.core.errors.TruncatedImageError`, also where OpenImageIO would return the
pixels it could decode: a PNG whose chunks stop before ``IEND``, a JPEG whose data stop early (libjpeg's
"Premature end of JPEG file", which OpenImageIO reports but does not fail on). Truncated EXR, HDR and TIFF
files fail to decode and raise :class:`~kornia_ilum.core.errors.HDRIOError`. Bad tensors given to the writers
raise the usual typed input errors (:class:`~kornia_ilum.core.errors.ShapeError`,
:class:`~kornia_ilum.core.errors.NonFiniteError`, :class:`~kornia_ilum.core.errors.ValueCheckError`) naming
the argument.

Writes are atomic: pixels go to a hidden temporary file in the destination's folder, which replaces the
destination (:func:`os.replace`) only once it is complete. A failed write leaves the destination as it
was and removes the temporary file.

These are file functions, not tensor ops, so they have no :class:`torch.nn.Module` twins (STYLE.md's
functional + module rule applies to the differentiable ops only).

Convention:
    Images are RGB, channel-first (docs/conventions.rst, "Images"). Lat-long files keep their orientation on
    disk (centre column = forward, -Z); the EXIF ``Orientation`` tag of photographs is applied on read, so a
    portrait comes back upright.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import torch

from kornia_ilum.core.check import check_tensor
from kornia_ilum.core.errors import HDRIOError, ShapeError, TruncatedImageError, ValueCheckError
from kornia_ilum.core.files import atomic_write

if TYPE_CHECKING:
    import OpenImageIO as oiio

__all__ = ["HALF_MAX", "check_ldr", "read_hdr", "read_ldr", "write_hdr", "write_ldr"]

#: Largest finite half-float value; larger values become ``inf`` in a half EXR.
HALF_MAX = 65504.0

_HDR_WRITE_EXTENSIONS = (".exr", ".hdr")
_LDR_WRITE_EXTENSIONS = (".png", ".jpg", ".jpeg")


def _as_path(path: str | os.PathLike[str]) -> Path:
    return Path(os.fspath(path))


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: libjpeg's warning for data that stop before the image does (JWRN_JPEG_EOF); OpenImageIO records it as
#: the reader's error but still returns the pixels, the missing part filled in (grey, or a blurred last scan).
_JPEG_EOF_MESSAGE = "Premature end of JPEG file"


def _one_line(message: str) -> str:
    """OpenImageIO's message on one line (it joins libpng's and libjpeg's with newlines): the CLI prints one
    readable line per error."""
    return "; ".join(line.strip() for line in message.splitlines() if line.strip())


def _png_truncation(path: Path) -> str | None:
    """Why the PNG ``path`` is truncated (its chunks stop before ``IEND``), or ``None``.

    Walks the chunk headers (length, type) without reading the data. ``None`` also for a file that is not
    a PNG, or whose chunk list is corrupt rather than cut short (a chunk type that is not 4 letters): those
    are left to OpenImageIO. Bytes after ``IEND`` are allowed.
    """
    size = path.stat().st_size
    with open(path, "rb") as f:
        if f.read(8) != _PNG_SIGNATURE:
            return None
        pos = 8
        while True:
            header = f.read(8)
            if len(header) < 8:
                return f"it ends after {size} bytes, before the PNG's IEND chunk"
            length, kind = int.from_bytes(header[:4], "big"), header[4:]
            if not kind.isalpha():
                return None  # corrupt, not truncated
            if kind == b"IEND":
                if pos + 12 <= size:
                    return None
                return f"it ends after {size} bytes, inside the PNG's IEND chunk"
            pos += 12 + length  # header, data, CRC
            if pos > size:
                return (
                    f"its {kind.decode('ascii')} chunk needs {pos} bytes, the file has {size}, "
                    "and the IEND chunk is missing"
                )
            f.seek(pos)


def _read(path: Path, *, hdr: bool, header_only: bool = False) -> tuple[np.ndarray | None, oiio.ImageSpec]:
    """Read subimage 0 of ``path`` as float ``(H, W, C)``, upright, and its spec; file errors -> HDRIOError.

    ``hdr`` selects the pixel types accepted: floating point (HDR) or 8/16-bit integers (LDR).
    ``header_only``: check the file and return ``(None, spec)`` without decoding the pixels.
    """
    import OpenImageIO as oiio  # lazy: keeps import kornia_ilum cheap

    if not path.exists():
        raise HDRIOError(f"cannot read {path}: no such file")
    if path.is_dir():
        raise HDRIOError(f"cannot read {path}: it is a directory, not an image file")
    if path.stat().st_size == 0:
        raise HDRIOError(f"cannot read {path}: the file is empty")
    try:
        cut = _png_truncation(path)
    except OSError as e:
        raise HDRIOError(f"cannot read {path}: {_one_line(str(e))}") from e
    if cut is not None:
        raise TruncatedImageError(f"cannot read {path}: the file is truncated ({cut})")
    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)  # colours as stored: do not premultiply PNG alpha
    try:
        inp = oiio.ImageInput.open(str(path), config)
        if inp is None:
            err = oiio.geterror()
            if _JPEG_EOF_MESSAGE in err:
                raise TruncatedImageError(
                    f"cannot read {path}: the file is truncated (OpenImageIO: {_one_line(err)})"
                )
            raise HDRIOError(f"cannot read {path}: {_one_line(err) or 'unknown or unsupported format'}")
        try:
            spec = inp.spec()
            if hdr and spec.format.basetype not in (oiio.HALF, oiio.FLOAT, oiio.DOUBLE):
                raise HDRIOError(
                    f"cannot read {path} as HDR: it holds {spec.format} (display-referred LDR) pixels; "
                    "use read_ldr"
                )
            if not hdr and spec.format.basetype not in (oiio.UINT8, oiio.UINT16):
                raise HDRIOError(
                    f"cannot read {path} as LDR: it holds {spec.format} pixels, not 8-bit or 16-bit "
                    "integers; use read_hdr for floating-point (HDR) files"
                )
            if header_only:
                return None, spec
            # LDR: native integer codes, divided below (exactly code / 255 or code / 65535)
            pixels = inp.read_image(0, 0, 0, spec.nchannels, "float" if hdr else spec.format)
            err = inp.geterror()
        finally:
            inp.close()
    except HDRIOError:
        raise
    except (OSError, RuntimeError, ValueError, TypeError) as e:  # the file system's or OpenImageIO's errors
        raise HDRIOError(f"cannot read {path}: {_one_line(str(e))}") from e
    if _JPEG_EOF_MESSAGE in err:  # pixels came back, partly made up: refuse them
        raise TruncatedImageError(
            f"cannot read {path}: the file is truncated, its JPEG data end before the image does "
            f"(OpenImageIO: {_one_line(err)})"
        )
    if pixels is None:
        raise HDRIOError(f"cannot read {path}: the file is corrupt or truncated ({_one_line(err) or 'no pixels'})")
    pixels = pixels.reshape(spec.height, spec.width, spec.nchannels)
    if not hdr:
        pixels = pixels.astype(np.float32) / np.float32(np.iinfo(pixels.dtype).max)
    orientation = spec.get_int_attribute("Orientation", 1)
    if orientation != 1:
        buf = oiio.ImageBuf(oiio.ImageSpec(spec.width, spec.height, spec.nchannels, "float"))
        buf.set_pixels(oiio.ROI(), pixels)
        buf.specmod().attribute("Orientation", orientation)
        pixels = oiio.ImageBufAlgo.reorient(buf).get_pixels(oiio.FLOAT)
    return pixels, spec


def _to_rgb(pixels: np.ndarray, spec: oiio.ImageSpec, path: Path) -> torch.Tensor:
    """Pick R, G, B (or replicate grey), drop alpha / depth / extra channels; ``(3, H, W)`` float32."""
    names = list(spec.channelnames)
    if all(c in names for c in "RGB"):
        idx = [names.index(c) for c in "RGB"]
    else:
        colour = [i for i in range(spec.nchannels) if i not in (spec.alpha_channel, spec.z_channel)]
        if not colour:
            raise HDRIOError(f"cannot read {path}: no colour channel among {tuple(names)}")
        idx = colour[:3] if len(colour) >= 3 else [colour[0]] * 3
    rgb = np.ascontiguousarray(pixels[..., idx].transpose(2, 0, 1))
    return torch.from_numpy(rgb)


def read_hdr(path: str | os.PathLike[str], *, clamp_negative: bool = True) -> torch.Tensor:
    r"""Read a linear HDR image (OpenEXR, Radiance ``.hdr``, or any floating-point file OpenImageIO reads).

    Args:
        path: the file.
        clamp_negative: clamp negative values to 0. Lossy EXR compression (DWAA/DWAB) stores small
            negative values (down to about -0.004 in the shared maps) that HDR data never has
            (docs/conventions.rst, "Images"). Pass ``False`` to get the stored values unchanged.

    Returns:
        ``(3, H, W)`` float32 CPU tensor, linear, as stored in the file. Alpha, depth and extra
        channels are dropped; a single grey channel (``Y``) is replicated to R, G, B. Only the first
        subimage (part) of a multi-part file is read.

    Raises:
        HDRIOError: the file is missing, a directory, empty, corrupt or truncated, not an image format
            OpenImageIO knows, holds integer (LDR) pixels (use :func:`read_ldr`), or holds NaN or Inf.
            The message names the path.

    Shape:
        - Output: :math:`(3, H, W)`

    Convention:
        Linear, unbounded above (docs/conventions.rst, "Images"). A lat-long map comes back with the
        orientation it has on disk; the usual one (centre column = forward) is the library's lat-long
        convention (docs/conventions.rst, "Lat-long"). Add the batch dimension with ``image[None]``.

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     write_hdr(Path(tmp) / "sky.exr", torch.full((3, 4, 8), 2.5))
        ...     sky = read_hdr(Path(tmp) / "sky.exr")
        >>> sky.shape, sky.dtype, sky.max().item()
        (torch.Size([3, 4, 8]), torch.float32, 2.5)
    """
    path = _as_path(path)
    pixels, spec = _read(path, hdr=True)
    finite = np.isfinite(pixels)
    if not finite.all():
        raise HDRIOError(f"cannot read {path}: it holds {int((~finite).sum())} NaN or Inf values")
    image = _to_rgb(pixels, spec, path)
    return image.clamp_(min=0.0) if clamp_negative else image


def check_ldr(path: str | os.PathLike[str]) -> tuple[int, int]:
    r"""Check that :func:`read_ldr` can read ``path``, from the file's header (the pixels are not decoded).

    For a command that should refuse a bad input before it loads its models. A file whose data end after a
    valid header is found only by reading it (:class:`~kornia_ilum.core.errors.TruncatedImageError` from
    :func:`read_ldr`), except a PNG's, whose chunks are checked here too.

    Args:
        path: the file.

    Returns:
        ``(height, width)`` as stored (before the EXIF orientation).

    Raises:
        HDRIOError: as :func:`read_ldr`: missing, a directory, empty, not an image, a truncated PNG, or HDR
            pixels.

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     write_ldr(Path(tmp) / "face.png", torch.full((3, 2, 5), 0.5))
        ...     _ = (Path(tmp) / "notes.png").write_text("not an image")
        ...     size = check_ldr(Path(tmp) / "face.png")
        ...     try:
        ...         check_ldr(Path(tmp) / "notes.png")
        ...     except HDRIOError:
        ...         refused = True
        >>> size, refused
        ((2, 5), True)
    """
    _, spec = _read(_as_path(path), hdr=False, header_only=True)
    return spec.height, spec.width


def read_ldr(path: str | os.PathLike[str]) -> torch.Tensor:
    r"""Read an 8-bit or 16-bit LDR image (PNG, JPEG, TIFF, ...) as sRGB-encoded values in ``[0, 1]``.

    Args:
        path: the file.

    Returns:
        ``(3, H, W)`` float32 CPU tensor in ``[0, 1]``: the stored code values divided by 255 (8-bit) or
        65535 (16-bit), not linearised. Greyscale is replicated to R, G, B; palette images are expanded
        to their colours; the EXIF ``Orientation`` tag is applied. **Alpha is dropped**, not composited:
        the colours come back as stored (as :func:`kornia.io.load_image` and PIL's ``convert("RGB")`` do),
        also under fully transparent pixels; multiply by the alpha yourself to composite over black.

    Raises:
        HDRIOError: the file is missing, a directory, empty, corrupt or truncated, not an image format
            OpenImageIO knows, or holds floating-point (HDR) pixels (use :func:`read_hdr`).
        TruncatedImageError: (an :class:`HDRIOError`) a PNG or JPEG file ends before its image data do;
            never a partly decoded image.

    Shape:
        - Output: :math:`(3, H, W)`

    Convention:
        sRGB-encoded, display-referred (docs/conventions.rst, "Images");
        :func:`kornia_ilum.color.srgb_to_linear` decodes it. No ICC profile or PNG gamma chunk is applied.

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     write_ldr(Path(tmp) / "face.png", torch.full((3, 2, 2), 0.5))
        ...     face = read_ldr(Path(tmp) / "face.png")
        >>> face[:, 0, 0]  # 0.5 is stored as code value 128
        tensor([0.5020, 0.5020, 0.5020])
    """
    path = _as_path(path)
    pixels, spec = _read(path, hdr=False)
    return _to_rgb(pixels, spec, path)


def _check_image(image: torch.Tensor, *, ldr: bool) -> torch.Tensor:
    """Validate a ``(3, H, W)`` / ``(1, 3, H, W)`` image and return it as float32 ``(H, W, 3)`` numpy."""
    check_tensor(image, "image", ["*", "3", "H", "W"], nonnegative=True)
    if image.dim() > 4 or (image.dim() == 4 and image.shape[0] != 1):
        raise ShapeError(f"image must have shape (3, H, W) or (1, 3, H, W), got {tuple(image.shape)}")
    image = image.reshape(image.shape[-3:])
    if ldr and bool((image > 1).any()):
        raise ValueCheckError(
            f"image must be in [0, 1] to be written as LDR, got max {image.max().item():g}; "
            "clip or tone-map it first"
        )
    return image.detach().to("cpu", torch.float32).permute(1, 2, 0).contiguous().numpy()


def _check_extension(path: Path, allowed: tuple[str, ...], function: str) -> None:
    if path.suffix.lower() not in allowed:
        raise HDRIOError(
            f"cannot write {path}: {function} writes {', '.join(allowed)} files, not {path.suffix!r}"
        )


def _atomic_write(path: Path, pixels: np.ndarray, pixel_type: str, attributes: dict[str, str | int]) -> None:
    """Write ``pixels`` ``(H, W, C)`` to a temporary file beside ``path``, then move it over ``path``."""
    if path.is_dir():
        raise HDRIOError(f"cannot write {path}: it is a directory")
    if not path.parent.is_dir():
        raise HDRIOError(f"cannot write {path}: the folder {path.parent} does not exist")

    import OpenImageIO as oiio  # lazy: keeps import kornia_ilum cheap

    def write(tmp: Path) -> None:
        out = oiio.ImageOutput.create(str(tmp))
        if out is None:
            raise HDRIOError(f"cannot write {path}: {_one_line(oiio.geterror())}")
        height, width, channels = pixels.shape
        spec = oiio.ImageSpec(width, height, channels, pixel_type)
        for key, value in attributes.items():
            spec.attribute(key, value)
        ok = False
        try:
            ok = bool(out.open(str(tmp), spec)) and bool(out.write_image(pixels))
        finally:
            ok = bool(out.close()) and ok
            err = out.geterror()
        if not ok:
            raise HDRIOError(f"cannot write {path}: {_one_line(err) or 'OpenImageIO reported a failure'}")

    try:
        atomic_write(path, write)
    except HDRIOError:
        raise
    except (OSError, RuntimeError, ValueError, TypeError) as e:  # the file system's or OpenImageIO's errors
        raise HDRIOError(f"cannot write {path}: {_one_line(str(e))}") from e


def write_hdr(
    path: str | os.PathLike[str], image: torch.Tensor, *, half: bool = False, clamp_overflow: bool = False
) -> None:
    r"""Write a linear HDR image as OpenEXR (``.exr``) or Radiance RGBE (``.hdr``), atomically.

    Args:
        path: destination; its extension picks the format. An existing file is replaced.
        image: linear, non-negative, finite RGB image.
        half: EXR only: store half floats (16-bit, about 3 significant digits, finite up to
            :data:`HALF_MAX` = 65504) instead of float32. EXR files are ZIP-compressed (lossless).
        clamp_overflow: with ``half=True``, clamp values above 65504 to 65504 instead of raising.

    Returns:
        ``None``; the file is complete at ``path`` when it returns.

    Raises:
        HDRIOError: the extension is not ``.exr``/``.hdr``; the folder is missing; ``half=True`` with a
            value above 65504 and ``clamp_overflow=False`` (the message names the path and the maximum;
            half would store ``inf``); or OpenImageIO fails. The destination is then left untouched.
        ShapeError: ``image`` is not ``(3, H, W)`` or ``(1, 3, H, W)``.
        NonFiniteError: ``image`` holds NaN or Inf.
        ValueCheckError: ``image`` holds negative values, or ``half=True`` for a ``.hdr`` file.

    Shape:
        - Input: :math:`(3, H, W)` or :math:`(1, 3, H, W)`, any floating dtype and device (copied to
          float32 on the CPU; gradients are not tracked).

    Convention:
        Linear, non-negative (docs/conventions.rst, "Images"). Radiance RGBE keeps an 8-bit mantissa per
        channel with a shared exponent, truncated by OpenImageIO: each channel comes back at most 1/128 of the
        pixel's largest channel below the value written (0.78 %). EXR float32 is exact; EXR half has a
        relative error of at most 2^-11 in the normal range.

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     sun = torch.full((1, 3, 2, 2), 1e5)
        ...     write_hdr(Path(tmp) / "sun.exr", sun, half=True, clamp_overflow=True)
        ...     read_hdr(Path(tmp) / "sun.exr").max().item()
        65504.0
    """
    path = _as_path(path)
    pixels = _check_image(image, ldr=False)
    _check_extension(path, _HDR_WRITE_EXTENSIONS, "write_hdr")
    exr = path.suffix.lower() == ".exr"
    if half and not exr:
        raise ValueCheckError(f"half=True applies to .exr files only, got {path}")
    if half:
        peak = float(pixels.max())
        if peak > HALF_MAX:
            if not clamp_overflow:
                raise HDRIOError(
                    f"cannot write {path} as half-float EXR: max value {peak:g} exceeds {HALF_MAX:g} "
                    "(it would become inf); pass clamp_overflow=True to clamp, or half=False"
                )
            pixels = np.minimum(pixels, HALF_MAX)
    attributes: dict[str, str | int] = {"compression": "zip"} if exr else {}
    _atomic_write(path, pixels, "half" if half else "float", attributes)


def write_ldr(path: str | os.PathLike[str], image: torch.Tensor, *, quality: int = 95) -> None:
    r"""Write an sRGB-encoded image in ``[0, 1]`` as an 8-bit PNG or JPEG, atomically.

    Args:
        path: destination, ``.png``, ``.jpg`` or ``.jpeg``. An existing file is replaced.
        image: sRGB-encoded RGB image in ``[0, 1]`` (encode linear data with
            :func:`kornia_ilum.color.linear_to_srgb` first).
        quality: JPEG quality, 1 to 100 (ignored for PNG).

    Returns:
        ``None``; the file is complete at ``path`` when it returns.

    Raises:
        HDRIOError: the extension is not supported, the folder is missing, or OpenImageIO fails; the
            destination is then left untouched.
        ShapeError: ``image`` is not ``(3, H, W)`` or ``(1, 3, H, W)``.
        NonFiniteError: ``image`` holds NaN or Inf.
        ValueCheckError: ``image`` has values outside ``[0, 1]``, or ``quality`` is out of range.

    Shape:
        - Input: :math:`(3, H, W)` or :math:`(1, 3, H, W)`.

    Convention:
        sRGB-encoded, display-referred (docs/conventions.rst, "Images"); nothing is encoded here.
        Each value ``x`` is stored as the code value ``round(255 x)``, so :func:`read_ldr` returns it
        within ``1/510``. PNG is lossless; JPEG is lossy and subsamples chroma.

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     write_ldr(Path(tmp) / "ramp.png", torch.linspace(0, 1, 6).expand(3, 1, 6))
        ...     read_ldr(Path(tmp) / "ramp.png")[0, 0]
        tensor([0.0000, 0.2000, 0.4000, 0.6000, 0.8000, 1.0000])
    """
    path = _as_path(path)
    pixels = _check_image(image, ldr=True)
    _check_extension(path, _LDR_WRITE_EXTENSIONS, "write_ldr")
    if isinstance(quality, bool) or not isinstance(quality, int) or not 1 <= quality <= 100:
        raise ValueCheckError(f"quality must be an int in [1, 100], got {quality!r}")
    codes = np.rint(pixels * 255.0).astype(np.uint8)
    attributes: dict[str, str | int] = {}
    if path.suffix.lower() in (".jpg", ".jpeg"):
        attributes["compression"] = f"jpeg:{quality}"
    _atomic_write(path, codes, "uint8", attributes)
