"""Tests of kornia_ilum_lab.synth.sheets: contact sheets and captioned grids."""

from __future__ import annotations

import sys

import pytest
import torch
from PIL import Image

from kornia_ilum.core.errors import IlumError
from kornia_ilum_lab.synth.environments import EnvironmentSampler, default_sources
from kornia_ilum_lab.synth.sheets import require_matplotlib, tone_map_tile, write_contact_sheet, write_grid

PNG = b"\x89PNG\r\n\x1a\n"


def test_tone_map_tile():
    tile = tone_map_tile(torch.ones(3, 32, 32))
    assert tile.shape == (3, 32, 134) and 0.0 <= float(tile.min()) and float(tile.max()) <= 1.0


def test_tone_map_tile_exposure():
    """The diffuse sphere's brightest pixel is exposed to 0.8 whatever the lighting's scale; black stays black."""
    ball = torch.rand(3, 32, 32, generator=torch.Generator().manual_seed(0))
    torch.testing.assert_close(tone_map_tile(ball), tone_map_tile(ball * 7.0), atol=1e-5, rtol=0)
    dark = tone_map_tile(torch.zeros(3, 32, 32))
    assert float(dark[:, :, :32].max()) == 0.0
    gaps = dark[:, :, 32:34]
    assert (gaps == 1).all()  # the white gap between tiles


@pytest.mark.parametrize("palette", [True, False])
def test_write_grid(tmp_path, palette):
    tiles = [torch.rand(3, 20, 30), torch.zeros(3, 20, 30), torch.ones(3, 20, 30)]
    path = tmp_path / "sub" / "grid.png"  # a missing parent folder is created
    write_grid(tiles, ["a", "b\nc", "d"], title="title", path=path, columns=2, cell=(1.0, 0.8), fontsize=5,
               dpi=50,
               palette=palette)
    assert path.read_bytes()[:8] == PNG
    image = Image.open(path)
    assert image.size == (100, int(50 * (0.8 * 2 + 0.35)))  # 2 columns x 2 rows of cells, plus the title
    assert image.mode == ("P" if palette else "RGBA")


def test_write_contact_sheet(tmp_path):
    sampler = EnvironmentSampler(default_sources(height=16), seed=0)
    path = tmp_path / "sheet.png"
    write_contact_sheet([sampler.sample(i) for i in range(3)], path, columns=2)
    assert path.read_bytes()[:8] == PNG and Image.open(path).mode == "P"


def test_require_matplotlib(monkeypatch):
    require_matplotlib("synth environments")  # installed: nothing happens
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    with pytest.raises(IlumError, match=r"synth environments draws its figures with matplotlib.*pip install"):
        require_matplotlib("synth environments")
