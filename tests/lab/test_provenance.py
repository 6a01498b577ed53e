"""kornia_ilum_lab.provenance: the stamp of a figure, read back, and the fingerprint of the code it shows."""

from __future__ import annotations

from pathlib import Path

import pytest
from PIL import Image

from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum_lab.provenance import code_fingerprint, figure_problems, read_stamp, stamp_figure


def _png(path: Path) -> Path:
    Image.new("RGB", (8, 4), (200, 10, 10)).save(path)
    return path


def test_stamp_round_trip_keeps_the_pixels(tmp_path):
    png = _png(tmp_path / "a.png")
    before = Image.open(png).tobytes()
    data = tmp_path / "data.csv"
    data.write_text("x\n1\n")
    stamp = stamp_figure(png, command="make a", shows=["kornia_ilum.core.files"], inputs=[data])
    assert read_stamp(png) == stamp and stamp["inputs"] == {"data.csv": stamp["inputs"]["data.csv"]}
    assert Image.open(png).tobytes() == before
    assert figure_problems(png) == []
    stamp_figure(png, command="make a again", shows=["kornia_ilum.core.files"], inputs=[data])  # replaces it
    assert read_stamp(png)["command"] == "make a again" and png.read_bytes().count(b"kornia_ilum.provenance") == 1
    data.write_text("x\n2\n")
    assert figure_problems(png) == [f"{png} was made from another version of data.csv; make it again with: "
                                    "make a again"]
    data.unlink()
    assert "which is gone" in figure_problems(png)[0]


def test_jpeg_stamp(tmp_path):
    jpg = tmp_path / "a.jpg"
    Image.new("RGB", (16, 16), (10, 120, 30)).save(jpg, quality=90)
    pixels = Image.open(jpg).tobytes()
    stamp_figure(jpg, command="make b", shows=["kornia_ilum.core"])
    stamp_figure(jpg, command="make b", shows=["kornia_ilum.core"])
    assert read_stamp(jpg)["command"] == "make b" and Image.open(jpg).tobytes() == pixels
    assert jpg.read_bytes().count(b"kornia_ilum.provenance") == 1 and figure_problems(jpg) == []


def test_unstamped_and_unknown(tmp_path):
    png = _png(tmp_path / "plain.png")
    assert read_stamp(png) is None and "no provenance stamp" in figure_problems(png)[0]
    other = tmp_path / "x.gif"
    other.write_bytes(b"GIF89a")
    with pytest.raises(ValueCheckError, match="neither a PNG nor a JPEG"):
        read_stamp(other)
    with pytest.raises(ValueCheckError, match="no module"):
        code_fingerprint(["kornia_ilum.no_such_module"])


def test_fingerprint_ignores_docstrings_and_comments(tmp_path, monkeypatch):
    pkg = tmp_path / "fp_pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text('"""A package."""\n')
    (pkg / "mod.py").write_text('"""Doc."""\n\ndef f(x):\n    """Doc."""\n    return x + 1  # one\n')
    monkeypatch.syspath_prepend(str(tmp_path))
    before = code_fingerprint(["fp_pkg"])
    (pkg / "mod.py").write_text('"""Other words."""\n\n\ndef f(x):\n    """More."""\n    return x + 1\n')
    assert code_fingerprint(["fp_pkg"]) == before
    (pkg / "mod.py").write_text('def f(x):\n    return x + 2\n')
    assert code_fingerprint(["fp_pkg"]) != before
