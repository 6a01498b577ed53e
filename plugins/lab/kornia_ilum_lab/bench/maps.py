"""The real maps of the bench's light-stage clips: the held-out maps of a folder, and a map read small.

``kornia-ilum bench --cache ... --hdri ...`` lights its clips (:mod:`~kornia_ilum_lab.bench.video`,
:mod:`~kornia_ilum_lab.bench.relight`) with the held-out maps (``hdri_split`` "eval") of ``--hdri``.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import torch

from kornia_ilum.io import read_hdr
from kornia_ilum_lab.synth.environments.real import folder_splits

__all__ = ["held_out_maps", "small_latlong"]


def held_out_maps(folders: Sequence[str | os.PathLike[str]]) -> list[Path]:
    """The real maps of ``folders`` whose split is ``"eval"`` (:func:`~kornia_ilum_lab.synth.environments.hdri_split`),
    sorted by name.

    Args:
        folders: folders of real lat-long maps (``.exr`` and ``.hdr`` files; other files are skipped).

    Returns:
        the paths of the held-out maps, sorted by file name.

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     for name in ("studio.exr", "interior.exr", "notes.txt"):
        ...         (Path(tmp) / name).touch()
        ...     [p.name for p in held_out_maps([tmp])]
        ['studio.exr']
    """
    maps = [Path(f) / name for f in folders for name, split in folder_splits(f).items() if split == "eval"]
    return sorted(maps, key=lambda p: p.name)


def small_latlong(path: str | os.PathLike[str], height: int = 64) -> torch.Tensor:
    """A real map read and reduced by area to ``height x 2 height``: the lighting of the skips' clips and
    relighting rows (a 32 x 32 ball needs no more).

    Args:
        path: an ``.exr`` or ``.hdr`` lat-long map.
        height: the reduced map's height.

    Returns:
        ``(1, 3, height, 2 height)`` float32, linear.

    Raises:
        HDRIOError: the map cannot be read.

    Examples:
        >>> import tempfile
        >>> from kornia_ilum.io import write_hdr
        >>> with tempfile.TemporaryDirectory() as d:
        ...     _ = write_hdr(f"{d}/sky.exr", torch.ones(3, 128, 256))
        ...     small = small_latlong(f"{d}/sky.exr")
        >>> tuple(small.shape), float(small.mean())
        ((1, 3, 64, 128), 1.0)
    """
    x = read_hdr(path).float()[None]
    return torch.nn.functional.interpolate(x, size=(height, 2 * height), mode="area")
