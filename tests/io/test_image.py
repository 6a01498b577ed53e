"""Tests of kornia_ilum.io.image: HDR/LDR round trips, channel handling, typed errors, atomic writes."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest
import torch
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from PIL import Image

from kornia_ilum.core.errors import (
    EmptyTensorError,
    HDRIOError,
    NonFiniteError,
    ShapeError,
    TruncatedImageError,
    TypeCheckError,
    ValueCheckError,
)
from kornia_ilum.io import HALF_MAX, check_ldr, read_hdr, read_ldr, write_hdr, write_ldr
from kornia_ilum.io import image as image_module

#: Radiance RGBE: 8-bit mantissas with a shared exponent, truncated by OpenImageIO. Every channel comes
#: back within 2^-7 of its pixel's largest channel (measured: 0.0078 of it, always from below).
RGBE_TOL = 2.0**-7


def oiio_write(path: Path, pixels: np.ndarray, pixel_type: str, names=None, **attributes) -> None:
    """Write ``(H, W, C)`` pixels with OpenImageIO directly, bypassing the checks of the library."""
    out = oiio.ImageOutput.create(str(path))
    height, width, channels = pixels.shape
    spec = oiio.ImageSpec(width, height, channels, pixel_type)
    if names is not None:
        spec.channelnames = names
        spec.alpha_channel = names.index("A") if "A" in names else -1
    for key, value in attributes.items():
        spec.attribute(key, value)
    assert out.open(str(path), spec) and out.write_image(pixels) and out.close(), out.geterror()


def random_hdr(shape=(3, 6, 10), seed: int = 0) -> torch.Tensor:
    """Log-uniform linear values over 8 decades, like a sky with a sun."""
    g = torch.Generator().manual_seed(seed)
    return 10.0 ** (torch.rand(shape, generator=g) * 8 - 3)


def folder_listing(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def bad_files(tmp_path: Path) -> dict[str, tuple[Path, str]]:
    """Files that no reader can read, each with a regex its error message must match."""
    (tmp_path / "empty.exr").write_bytes(b"")
    (tmp_path / "garbage.exr").write_bytes(b"\x76\x2f\x31\x01" + bytes(range(256)) * 4)
    (tmp_path / "notes.xyz").write_text("not an image")
    (tmp_path / "a_folder.exr").mkdir()
    write_hdr(tmp_path / "whole.exr", random_hdr((3, 64, 64)))
    data = (tmp_path / "whole.exr").read_bytes()
    (tmp_path / "truncated.exr").write_bytes(data[: len(data) // 2])
    write_ldr(tmp_path / "whole.png", random_hdr((3, 32, 32)).clamp(max=1.0))
    data = (tmp_path / "whole.png").read_bytes()
    (tmp_path / "truncated.png").write_bytes(data[: len(data) // 2])
    return {
        "missing": (tmp_path / "missing.exr", "no such file"),
        "directory": (tmp_path / "a_folder.exr", "is a directory"),
        "empty": (tmp_path / "empty.exr", "is empty"),
        "corrupt": (tmp_path / "garbage.exr", "cannot read"),
        "unsupported": (tmp_path / "notes.xyz", "could not find a format reader"),
        "truncated_exr": (tmp_path / "truncated.exr", "corrupt or truncated"),
        "truncated_png": (tmp_path / "truncated.png", "cannot read"),
    }


BAD_FILE_KINDS = ["missing", "directory", "empty", "corrupt", "unsupported", "truncated_exr", "truncated_png"]


class TestReadHdr:
    def test_smoke(self, tmp_path):
        x = random_hdr()
        write_hdr(tmp_path / "a.exr", x)
        y = read_hdr(tmp_path / "a.exr")
        assert y.dtype == torch.float32 and y.device.type == "cpu"
        torch.testing.assert_close(y, x, atol=0, rtol=0)

    def test_cardinality(self, tmp_path):
        x = random_hdr((3, 5, 7))
        write_hdr(tmp_path / "a.exr", x)
        assert read_hdr(tmp_path / "a.exr").shape == (3, 5, 7)
        assert read_hdr(str(tmp_path / "a.exr")).shape == (3, 5, 7)  # str paths too

    @pytest.mark.parametrize(
        ("names", "expect"),
        [
            (("Y",), [0, 0, 0]),  # grey replicated
            (("Y", "A"), [0, 0, 0]),  # grey + alpha
            (("R", "G", "B", "A"), [0, 1, 2]),  # alpha dropped
            (("R", "G", "B", "A", "Z"), [0, 1, 2]),  # alpha and depth dropped
            (("A", "B", "G", "R"), None),  # channel names, not positions, decide (OIIO may reorder)
        ],
    )
    def test_channels(self, tmp_path, names, expect):
        pixels = np.stack([np.full((2, 3), 1.0 + c, np.float32) for c in range(len(names))], axis=-1)
        oiio_write(tmp_path / "c.exr", pixels, "float", names=names)
        y = read_hdr(tmp_path / "c.exr")
        assert y.shape == (3, 2, 3)
        if expect is None:  # R, G, B by name
            expect = [names.index(c) for c in "RGB"]
        for k, c in enumerate(expect):
            assert torch.all(y[k] == 1.0 + c), (names, k, y[:, 0, 0])

    def test_negative_clamp(self, tmp_path):
        pixels = np.full((2, 2, 3), 0.5, np.float32)
        pixels[0, 0] = -0.004  # what DWAB-compressed EXRs hold near black
        oiio_write(tmp_path / "n.exr", pixels, "float")
        assert read_hdr(tmp_path / "n.exr").min().item() == 0.0
        raw = read_hdr(tmp_path / "n.exr", clamp_negative=False)
        assert raw.min().item() == pytest.approx(-0.004)
        assert raw[:, 1, 1].tolist() == [0.5, 0.5, 0.5]

    @pytest.mark.parametrize("bad", [float("nan"), float("inf")])
    def test_nonfinite_file(self, tmp_path, bad):
        pixels = np.ones((2, 2, 3), np.float32)
        pixels[1, 0, 2] = bad
        oiio_write(tmp_path / "nf.exr", pixels, "float")
        with pytest.raises(HDRIOError, match=r"nf\.exr.*1 NaN or Inf"):
            read_hdr(tmp_path / "nf.exr")

    @pytest.mark.parametrize("kind", BAD_FILE_KINDS)
    def test_exception(self, tmp_path, kind):
        path, message = bad_files(tmp_path)[kind]
        with pytest.raises(HDRIOError, match=message) as info:
            read_hdr(path)
        assert str(path) in str(info.value)
        assert isinstance(info.value, OSError)

    def test_exception_ldr_file(self, tmp_path):
        write_ldr(tmp_path / "photo.png", torch.zeros(3, 2, 2))
        with pytest.raises(HDRIOError, match=r"photo\.png as HDR.*use read_ldr"):
            read_hdr(tmp_path / "photo.png")

    def test_radiance_hdr(self, tmp_path):
        x = random_hdr((3, 16, 32))
        write_hdr(tmp_path / "a.hdr", x)
        y = read_hdr(tmp_path / "a.hdr")
        peak = x.amax(0, keepdim=True)
        assert ((x - y).abs() <= RGBE_TOL * peak).all()
        assert torch.equal(read_hdr(tmp_path / "a.hdr"), y)  # re-reading is deterministic

    def test_radiance_hdr_zero(self, tmp_path):
        write_hdr(tmp_path / "z.hdr", torch.zeros(3, 2, 2))
        assert torch.equal(read_hdr(tmp_path / "z.hdr"), torch.zeros(3, 2, 2))


class TestWriteHdr:
    def test_smoke(self, tmp_path):
        write_hdr(tmp_path / "a.exr", torch.ones(3, 2, 2))
        assert folder_listing(tmp_path) == ["a.exr"]

    def test_exr_float32_exact(self, tmp_path):
        x = random_hdr((3, 8, 16))
        x[0, 0, 0], x[1, 0, 0], x[2, 0, 0] = 0.0, 1e-30, 3e38  # float32 keeps them all
        write_hdr(tmp_path / "f.exr", x)
        inp = oiio.ImageInput.open(str(tmp_path / "f.exr"))
        assert inp.spec().format == oiio.FLOAT and inp.spec().get_string_attribute("compression") == "zip"
        inp.close()
        assert torch.equal(read_hdr(tmp_path / "f.exr"), x)

    def test_exr_half(self, tmp_path):
        x = random_hdr((3, 8, 16)).clamp(max=HALF_MAX)
        write_hdr(tmp_path / "h.exr", x, half=True)
        inp = oiio.ImageInput.open(str(tmp_path / "h.exr"))
        assert inp.spec().format == oiio.HALF
        inp.close()
        y = read_hdr(tmp_path / "h.exr")
        assert torch.equal(y, x.half().float())  # exactly torch's round-to-nearest-even
        normal = x >= 2.0**-14
        assert ((y - x).abs() <= 2.0**-11 * x)[normal].all()

    def test_half_overflow(self, tmp_path):
        x = torch.ones(3, 4, 4)
        x[1, 2, 3] = 1.2e5
        with pytest.raises(HDRIOError, match=r"sun\.exr.*max value 120000 exceeds 65504.*clamp_overflow"):
            write_hdr(tmp_path / "sun.exr", x, half=True)
        assert folder_listing(tmp_path) == []
        write_hdr(tmp_path / "sun.exr", x, half=True, clamp_overflow=True)
        y = read_hdr(tmp_path / "sun.exr")
        assert y[1, 2, 3].item() == HALF_MAX and torch.isfinite(y).all()
        assert torch.equal(y[0], x[0])
        write_hdr(
            tmp_path / "edge.exr", torch.full((3, 1, 1), HALF_MAX), half=True
        )  # the limit itself is fine
        write_hdr(tmp_path / "float.exr", x)  # float32 holds it
        assert read_hdr(tmp_path / "float.exr").max().item() == pytest.approx(1.2e5)

    def test_cardinality(self, tmp_path):
        write_hdr(tmp_path / "b.exr", torch.ones(1, 3, 5, 7))
        assert read_hdr(tmp_path / "b.exr").shape == (3, 5, 7)

    @pytest.mark.parametrize("dtype", [torch.float16, torch.bfloat16, torch.float32, torch.float64])
    def test_dtypes(self, tmp_path, dtype):
        x = (random_hdr((3, 4, 4)) / 1e3).clamp(max=100.0).to(dtype)
        write_hdr(tmp_path / "d.exr", x)
        assert torch.equal(read_hdr(tmp_path / "d.exr"), x.float())

    def test_requires_grad(self, tmp_path):
        x = torch.ones(3, 2, 2, requires_grad=True)
        write_hdr(tmp_path / "g.exr", x * 2)
        assert torch.equal(read_hdr(tmp_path / "g.exr"), torch.full((3, 2, 2), 2.0))

    def test_replaces_existing(self, tmp_path):
        write_hdr(tmp_path / "r.exr", torch.ones(3, 2, 2))
        write_hdr(tmp_path / "r.exr", torch.full((3, 4, 4), 3.0))
        assert torch.equal(read_hdr(tmp_path / "r.exr"), torch.full((3, 4, 4), 3.0))
        assert folder_listing(tmp_path) == ["r.exr"]

    @pytest.mark.parametrize(
        ("image", "error", "message"),
        [
            (torch.ones(2, 3, 2, 2), ShapeError, r"image must have shape \(3, H, W\) or \(1, 3, H, W\)"),
            (torch.ones(4, 2, 2), ShapeError, r"image must have shape \(\*, 3, H, W\)"),
            (torch.ones(2, 2), ShapeError, r"image must have shape"),
            (torch.ones(3, 0, 2), EmptyTensorError, r"image must not be empty"),
            (
                torch.ones(3, 2, 2, dtype=torch.int32),
                TypeCheckError,
                r"image must be a floating-point tensor",
            ),
            (np.ones((3, 2, 2), np.float32), TypeCheckError, r"image must be a torch.Tensor"),
            (torch.tensor(float("nan")).expand(3, 2, 2), NonFiniteError, r"image must be finite"),
            (torch.tensor(float("inf")).expand(3, 2, 2), NonFiniteError, r"image must be finite"),
            (-torch.ones(3, 2, 2), ValueCheckError, r"image must be non-negative"),
        ],
    )
    def test_exception(self, tmp_path, image, error, message):
        with pytest.raises(error, match=message):
            write_hdr(tmp_path / "x.exr", image)
        assert folder_listing(tmp_path) == []

    def test_exception_path(self, tmp_path):
        x = torch.ones(3, 2, 2)
        with pytest.raises(HDRIOError, match=r"x\.png: write_hdr writes \.exr, \.hdr files"):
            write_hdr(tmp_path / "x.png", x)
        with pytest.raises(ValueCheckError, match=r"half=True applies to \.exr files only"):
            write_hdr(tmp_path / "x.hdr", x, half=True)
        with pytest.raises(HDRIOError, match=r"the folder .*nowhere does not exist"):
            write_hdr(tmp_path / "nowhere" / "x.exr", x)
        (tmp_path / "d.exr").mkdir()
        with pytest.raises(HDRIOError, match=r"d\.exr: it is a directory"):
            write_hdr(tmp_path / "d.exr", x)
        assert folder_listing(tmp_path) == ["d.exr"]

    @given(
        h=st.integers(1, 5),
        w=st.integers(1, 5),
        data=st.data(),
    )
    def test_property_exr_float32_round_trip(self, h, w, data):
        values = data.draw(
            st.lists(
                st.floats(0.0, 2.0**127, allow_nan=False, allow_infinity=False, width=32),
                min_size=3 * h * w,
                max_size=3 * h * w,
            )
        )
        x = torch.tensor(values, dtype=torch.float32).reshape(3, h, w)
        with tempfile.TemporaryDirectory() as tmp:
            write_hdr(Path(tmp) / "p.exr", x)
            assert torch.equal(read_hdr(Path(tmp) / "p.exr"), x)


class TestAtomicWrite:
    """A write that fails half-way leaves the destination as it was and no temporary file behind."""

    @staticmethod
    def _write(path: Path, value: float) -> None:
        if path.suffix == ".png":
            write_ldr(path, torch.full((3, 8, 8), value))
        else:
            write_hdr(path, torch.full((3, 8, 8), value))

    @pytest.mark.parametrize("name", ["a.exr", "a.hdr", "a.png"])
    @pytest.mark.parametrize("existing", [True, False])
    def test_failure_mid_write(self, tmp_path, monkeypatch, name, existing):
        path = tmp_path / name
        if existing:
            self._write(path, 0.25)
        before = path.read_bytes() if existing else None
        listing = folder_listing(tmp_path)
        seen = []

        def failing_write(out, *args, **kwargs):
            seen.extend(p.name for p in tmp_path.iterdir())  # the temporary file exists by now
            raise RuntimeError("disk full (simulated)")

        monkeypatch.setattr(oiio.ImageOutput, "write_image", failing_write)
        with pytest.raises(HDRIOError, match=rf"cannot write .*{name}: disk full \(simulated\)"):
            self._write(path, 0.75)
        assert any(n.startswith(".a.") and ".tmp" in n for n in seen), seen
        assert folder_listing(tmp_path) == listing
        if existing:
            assert path.read_bytes() == before
        else:
            assert not path.exists()
        monkeypatch.undo()
        self._write(path, 0.75)  # and a later write works
        assert folder_listing(tmp_path) == [name]

    def test_failure_reported_by_oiio(self, tmp_path, monkeypatch):
        monkeypatch.setattr(oiio.ImageOutput, "write_image", lambda out, *a, **k: False)
        with pytest.raises(HDRIOError, match=r"cannot write .*b\.exr"):
            write_hdr(tmp_path / "b.exr", torch.ones(3, 2, 2))
        assert folder_listing(tmp_path) == []

    def test_failure_on_replace(self, tmp_path, monkeypatch):
        write_hdr(tmp_path / "c.exr", torch.ones(3, 2, 2))
        before = (tmp_path / "c.exr").read_bytes()

        def failing_replace(src, dst):
            raise OSError("read-only file system (simulated)")

        monkeypatch.setattr(image_module.os, "replace", failing_replace)
        with pytest.raises(HDRIOError, match=r"c\.exr: read-only file system \(simulated\)"):
            write_hdr(tmp_path / "c.exr", torch.full((3, 2, 2), 5.0))
        assert folder_listing(tmp_path) == ["c.exr"]
        assert (tmp_path / "c.exr").read_bytes() == before


class TestReadLdr:
    def test_smoke(self, tmp_path):
        codes = np.arange(2 * 3 * 3, dtype=np.uint8).reshape(2, 3, 3) * 13
        oiio_write(tmp_path / "a.png", codes, "uint8")
        y = read_ldr(tmp_path / "a.png")
        assert y.dtype == torch.float32 and y.shape == (3, 2, 3)
        assert torch.equal(y, torch.from_numpy(codes).permute(2, 0, 1).float() / 255)

    @pytest.mark.parametrize("name", ["a16.png", "a16.tif"])
    def test_16bit(self, tmp_path, name):
        codes = (np.arange(4 * 5 * 3).reshape(4, 5, 3) * 1090).astype(np.uint16)
        codes[0, 0] = 65535
        oiio_write(tmp_path / name, codes, "uint16")
        y = read_ldr(tmp_path / name)
        expected = torch.from_numpy(codes.astype(np.float32)).permute(2, 0, 1) / 65535
        torch.testing.assert_close(y, expected, atol=1e-7, rtol=0)

    @pytest.mark.parametrize("name", ["g.png", "g.jpg", "g.tif"])
    def test_grey(self, tmp_path, name):
        grey = np.linspace(0, 255, 64, dtype=np.uint8).reshape(8, 8)
        Image.fromarray(grey, "L").save(tmp_path / name)
        y = read_ldr(tmp_path / name)
        assert y.shape == (3, 8, 8)
        assert torch.equal(y[0], y[1]) and torch.equal(y[0], y[2])
        if name != "g.jpg":
            assert torch.equal(y[0], torch.from_numpy(grey).float() / 255)

    def test_rgba_alpha_dropped(self, tmp_path):
        rgba = np.zeros((2, 2, 4), np.uint8)
        rgba[..., 0], rgba[..., 1], rgba[..., 2] = 200, 100, 50
        rgba[..., 3] = [[0, 128], [255, 0]]  # colours under transparent pixels are kept as stored
        Image.fromarray(rgba, "RGBA").save(tmp_path / "rgba.png")
        y = read_ldr(tmp_path / "rgba.png")
        assert y.shape == (3, 2, 2)
        for k, code in enumerate((200, 100, 50)):
            assert torch.equal(y[k], torch.full((2, 2), code / 255))

    def test_palette(self, tmp_path):
        index = (np.arange(16, dtype=np.uint8) % 4).reshape(4, 4)
        palette = [255, 0, 0, 0, 255, 0, 0, 0, 255, 10, 20, 30]
        image = Image.fromarray(index, "P")
        image.putpalette(palette)
        image.save(tmp_path / "p.png")
        y = read_ldr(tmp_path / "p.png")
        expected = (
            torch.tensor(palette, dtype=torch.float32).reshape(4, 3)[torch.from_numpy(index).long()] / 255
        )
        assert torch.equal(y, expected.permute(2, 0, 1))

    def test_exif_orientation(self, tmp_path):
        # a phone portrait stored landscape with Orientation 6 ("rotate 90 clockwise to display")
        codes = np.zeros((2, 3, 3), np.uint8)
        codes[0, 0] = 255  # top-left stored pixel ends up top-right once upright
        oiio_write(tmp_path / "o.png", codes, "uint8", Orientation=6)
        y = read_ldr(tmp_path / "o.png")
        assert y.shape == (3, 3, 2)
        assert y[:, 0, 1].tolist() == [1.0, 1.0, 1.0] and y.sum().item() == 3.0

    def test_cmyk_jpeg(self, tmp_path):
        """A print shop's CMYK JPEG comes back as RGB (libjpeg's inverted Adobe CMYK, as PIL reads it)."""
        colours = [(0, 255, 255, 0), (255, 0, 255, 0), (0, 0, 0, 128)]  # red, green, 50 % grey
        for i, cmyk in enumerate(colours):
            Image.new("CMYK", (8, 6), cmyk).save(tmp_path / f"c{i}.jpg", quality=95)
            rgb = read_ldr(tmp_path / f"c{i}.jpg")
            expected = np.asarray(Image.open(tmp_path / f"c{i}.jpg").convert("RGB"), np.float32) / 255
            assert rgb.shape == (3, 6, 8)
            np.testing.assert_allclose(rgb.permute(1, 2, 0).numpy(), expected, atol=2 / 255)

    @pytest.mark.parametrize("kind", BAD_FILE_KINDS)
    def test_exception(self, tmp_path, kind):
        path, message = bad_files(tmp_path)[kind]
        if kind == "truncated_exr":  # its header says float pixels, which read_ldr refuses first
            message = r"as LDR: it holds float pixels.*use read_hdr"
        with pytest.raises(HDRIOError, match=message) as info:
            read_ldr(path)
        assert str(path) in str(info.value)

    @pytest.mark.parametrize("name", ["h.exr", "h.hdr"])
    def test_exception_hdr_file(self, tmp_path, name):
        write_hdr(tmp_path / name, torch.ones(3, 2, 2))
        with pytest.raises(HDRIOError, match=rf"{name[0]}\.{name[2:]} as LDR.*use read_hdr"):
            read_ldr(tmp_path / name)


def astronaut_file(folder: Path, name: str) -> Path:
    """The bundled astronaut (512 x 512) written to ``folder / name`` (JPEG or PNG)."""
    import skimage.data

    image = torch.from_numpy(skimage.data.astronaut()).permute(2, 0, 1) / 255
    write_ldr(folder / name, image)
    return folder / name


def cut(path: Path, keep: int | float, name: str) -> Path:
    """A copy of ``path`` holding its first ``keep`` bytes (a fraction of the file for a float)."""
    data = path.read_bytes()
    n = int(len(data) * keep) if isinstance(keep, float) else (keep if keep >= 0 else len(data) + keep)
    (path.parent / name).write_bytes(data[:n])
    return path.parent / name


class TestTruncated:
    """A file cut short raises TruncatedImageError, never a partly decoded image (libjpeg only warns)."""

    # the half of the brief; all but the EOI marker; the headers only; just after the first scan's start
    @pytest.mark.parametrize("keep", [0.5, -2, 200, 0.05, 0.99])
    def test_jpeg(self, tmp_path, keep):
        whole = astronaut_file(tmp_path, "astronaut.jpg")
        assert read_ldr(whole).shape == (3, 512, 512)
        path = cut(whole, keep, "half.jpg")
        message = r"cannot read .*half\.jpg: the file is truncated"
        with pytest.raises(TruncatedImageError, match=message) as info:
            read_ldr(path)
        assert str(path) in str(info.value) and "\n" not in str(info.value)
        assert isinstance(info.value, HDRIOError) and isinstance(info.value, OSError)

    # the half; just before IEND; inside IEND's CRC; in the 8-byte signature's next header
    @pytest.mark.parametrize("keep", [0.5, -12, -2, 12])
    def test_png(self, tmp_path, keep):
        path = cut(astronaut_file(tmp_path, "astronaut.png"), keep, "half.png")
        with pytest.raises(TruncatedImageError, match=r"half\.png: the file is truncated \(.*IEND") as info:
            read_ldr(path)
        assert str(path) in str(info.value)
        with pytest.raises(TruncatedImageError):  # the chunk walk comes before the pixel type check
            read_hdr(path)

    @pytest.mark.parametrize("name", ["astronaut.png", "astronaut.jpg"])
    def test_trailing_bytes_accepted(self, tmp_path, name):
        """Bytes after IEND / EOI (a Motion Photo's video, padding) are no truncation."""
        whole = astronaut_file(tmp_path, name)
        longer = tmp_path / ("long_" + name)
        longer.write_bytes(whole.read_bytes() + b"\x00" * 64 + b"ftypmp42" * 100)
        torch.testing.assert_close(read_ldr(longer), read_ldr(whole), atol=0, rtol=0)

    def test_corrupt_png_chunk_is_not_called_truncated(self, tmp_path):
        whole = astronaut_file(tmp_path, "astronaut.png")
        data = bytearray(whole.read_bytes())
        data[12:16] = b"\x01\x02\x03\x04"  # IHDR's type: no chunk type
        (tmp_path / "bad.png").write_bytes(bytes(data))
        with pytest.raises(HDRIOError) as info:
            read_ldr(tmp_path / "bad.png")
        assert not isinstance(info.value, TruncatedImageError)


class TestWriteLdr:
    def test_smoke(self, tmp_path):
        write_ldr(tmp_path / "a.png", torch.full((3, 2, 2), 0.5))
        assert folder_listing(tmp_path) == ["a.png"]
        inp = oiio.ImageInput.open(str(tmp_path / "a.png"))
        assert inp.spec().format == oiio.UINT8 and inp.spec().nchannels == 3
        inp.close()

    def test_png_round_trip(self, tmp_path):
        codes = torch.arange(3 * 16 * 16).reshape(3, 16, 16) % 256
        write_ldr(tmp_path / "exact.png", codes / 255.0)
        assert torch.equal(read_ldr(tmp_path / "exact.png"), codes / 255.0)
        x = torch.rand(1, 3, 16, 16, generator=torch.Generator().manual_seed(1), dtype=torch.float64)
        write_ldr(tmp_path / "any.png", x)
        y = read_ldr(tmp_path / "any.png")
        assert y.shape == (3, 16, 16)
        assert (y.double() - x[0]).abs().max().item() <= 1 / 510 + 1e-7  # round(255 x) / 255

    @pytest.mark.parametrize("name", ["a.jpg", "a.jpeg"])
    def test_jpeg_round_trip(self, tmp_path, name):
        ramp = torch.linspace(0.1, 0.9, 32)
        x = torch.stack([ramp.expand(32, 32), ramp.expand(32, 32).T, torch.full((32, 32), 0.5)])
        write_ldr(tmp_path / name, x)
        y = read_ldr(tmp_path / name)
        assert (y - x).abs().mean().item() < 0.01 and (y - x).abs().max().item() < 0.05
        write_ldr(tmp_path / ("low" + name), x, quality=20)
        assert (tmp_path / ("low" + name)).stat().st_size < (tmp_path / name).stat().st_size

    @pytest.mark.parametrize("dtype", [torch.float16, torch.bfloat16, torch.float32, torch.float64])
    def test_dtypes(self, tmp_path, dtype):
        x = (torch.arange(12).reshape(3, 2, 2) * 20 / 255).to(dtype)
        write_ldr(tmp_path / "d.png", x)
        assert (read_ldr(tmp_path / "d.png") - x.float()).abs().max().item() <= 1 / 510

    @pytest.mark.parametrize(
        ("image", "error", "message"),
        [
            (torch.full((3, 2, 2), 1.01), ValueCheckError, r"image must be in \[0, 1\].*max 1\.01"),
            (-torch.ones(3, 2, 2), ValueCheckError, r"image must be non-negative"),
            (torch.ones(1, 2, 2), ShapeError, r"image must have shape"),
            (torch.ones(2, 3, 2, 2), ShapeError, r"image must have shape \(3, H, W\) or \(1, 3, H, W\)"),
            (torch.tensor(float("nan")).expand(3, 2, 2), NonFiniteError, r"image must be finite"),
        ],
    )
    def test_exception(self, tmp_path, image, error, message):
        with pytest.raises(error, match=message):
            write_ldr(tmp_path / "x.png", image)
        assert folder_listing(tmp_path) == []

    def test_exception_path(self, tmp_path):
        x = torch.zeros(3, 2, 2)
        with pytest.raises(HDRIOError, match=r"x\.exr: write_ldr writes \.png, \.jpg, \.jpeg files"):
            write_ldr(tmp_path / "x.exr", x)
        for quality in (0, 101, 9.5, True):
            with pytest.raises(ValueCheckError, match=r"quality must be an int in \[1, 100\]"):
                write_ldr(tmp_path / "x.jpg", x, quality=quality)
        assert folder_listing(tmp_path) == []


class TestSharedMaps:
    """The real Poly Haven maps of ../shared/data/hdri (read in place, never copied)."""

    @pytest.mark.parametrize("name", ["city.exr", "pedestrian_overpass_1k.hdr"])
    def test_read(self, shared_data, name):
        image = read_hdr(shared_data / "hdri" / name)
        assert image.shape == (3, 512, 1024) and image.dtype == torch.float32
        assert image.min().item() >= 0.0
        assert image.max().item() > 1e3  # unclipped sun
        assert torch.isfinite(image).all()

    def test_dwab_negatives(self, shared_data):
        raw = read_hdr(shared_data / "hdri" / "city.exr", clamp_negative=False)
        assert -0.005 < raw.min().item() < 0.0  # lossy DWAB ringing, clamped by default
        torch.testing.assert_close(
            read_hdr(shared_data / "hdri" / "city.exr"), raw.clamp(min=0), atol=0, rtol=0
        )

    def test_read_only_source_untouched(self, shared_data):
        path = shared_data / "hdri" / "city.exr"
        stat = os.stat(path)
        read_hdr(path)
        assert os.stat(path).st_mtime_ns == stat.st_mtime_ns


class TestCheckLdr:
    """check_ldr: the header only; the same refusals as read_ldr for files that cannot be read."""

    def test_size_and_refusals(self, tmp_path):
        write_ldr(tmp_path / "a.png", torch.full((3, 4, 6), 0.5))
        assert check_ldr(tmp_path / "a.png") == (4, 6)
        (tmp_path / "text.png").write_text("not an image")
        (tmp_path / "empty.jpg").write_bytes(b"")
        write_hdr(tmp_path / "light.exr", torch.ones(3, 2, 2))
        for name, match in (("text.png", "cannot read"), ("empty.jpg", "empty"), ("missing.png", "no such file"),
                            ("light.exr", "HDR|LDR")):
            with pytest.raises(HDRIOError, match=match):
                check_ldr(tmp_path / name)


def _fuzz_seeds() -> dict[str, bytes]:
    """Small valid files of every format the readers meet, as bytes: the seeds of the fuzzing."""
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        image = random_hdr((3, 12, 16), seed=3)
        write_hdr(folder / "a.exr", image)
        write_hdr(folder / "a.hdr", image)
        write_ldr(folder / "a.png", image.clamp(max=1.0))
        write_ldr(folder / "a.jpg", image.clamp(max=1.0))
        oiio_write(folder / "a.tif", (np.arange(12 * 16 * 3) % 65535).astype(np.uint16).reshape(12, 16, 3), "uint16")
        return {p.suffix: p.read_bytes() for p in folder.iterdir()}


FUZZ_SEEDS = _fuzz_seeds()


def _check_outcome(read, path: Path) -> None:
    """A reader either returns a well-formed image or raises HDRIOError: nothing else, never a crash."""
    try:
        out = read(path)
    except HDRIOError as e:
        assert str(path) in str(e) and "\n" not in str(e)
        return
    if read is check_ldr:
        assert len(out) == 2 and all(isinstance(v, int) and v > 0 for v in out)
        return
    assert out.dtype == torch.float32 and out.dim() == 3 and out.shape[0] == 3 and out.numel() > 0
    assert bool(torch.isfinite(out).all()) and bool((out >= 0).all())
    if read is read_ldr:
        assert float(out.max()) <= 1.0


class TestFuzz:
    """The loaders on mutated files, for a bounded number of examples (hypothesis, about 5 s here): every
    outcome is a well-formed image or an :class:`HDRIOError` naming the path, never another exception."""

    @settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
    @given(data=st.data())
    def test_mutated_files(self, tmp_path, data):
        suffix = data.draw(st.sampled_from(sorted(FUZZ_SEEDS)), label="format")
        blob = bytearray(FUZZ_SEEDS[suffix])
        how = data.draw(st.sampled_from(["truncate", "flip", "overwrite", "insert", "random"]), label="how")
        if how == "truncate":
            blob = blob[: data.draw(st.integers(0, len(blob) - 1))]
        elif how == "flip":
            for at in data.draw(st.lists(st.integers(0, len(blob) - 1), min_size=1, max_size=8)):
                blob[at] ^= 1 << data.draw(st.integers(0, 7))
        elif how == "overwrite":
            at = data.draw(st.integers(0, len(blob) - 1))
            chunk = data.draw(st.binary(min_size=1, max_size=64))
            blob[at : at + len(chunk)] = chunk
        elif how == "insert":
            at = data.draw(st.integers(0, len(blob)))
            blob[at:at] = data.draw(st.binary(min_size=1, max_size=64))
        else:  # the format's first bytes (its magic number), then noise
            blob = blob[:8] + bytearray(data.draw(st.binary(max_size=512)))
        path = tmp_path / f"fuzz{suffix}"
        path.write_bytes(bytes(blob))
        for read in (check_ldr, read_ldr, read_hdr):
            _check_outcome(read, path)
