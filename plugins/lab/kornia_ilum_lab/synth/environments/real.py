r"""Real HDR environment maps from a folder of lat-long ``.hdr`` / ``.exr`` files.

:class:`HDRFolderSource` lists the maps of a folder (for example the 10 real maps of
``../shared/data/hdri``), reads each once with :func:`kornia_ilum.io.read_hdr` (negative values, which lossy
EXR compression stores, are clamped to 0), resamples it to the working height with an exact
energy-conserving area average (:func:`resize_latlong`), computes its 32 x 32 mirror ball with
:func:`kornia_ilum.geometry.latlong_to_mirror_ball` (``mode="area"``, energy-conserving) and keeps both in
memory. :meth:`HDRFolderSource.sample` picks a map uniformly.

Held-out maps: :func:`hdri_split` puts about one map in four in the ``"eval"`` split, by a stable hash of its
file name (``blake2b(f"kornia_ilum.hdri:{name}")`` modulo 4 is 0), whatever folder it is in;
``HDRFolderSource(folder, split="train")`` keeps the others, and :func:`folder_splits` lists a folder's
splits. On the shared folders the eval maps are, in ``hdri/`` (10 maps): ``forest.exr``, ``sunrise.exr``
(outdoor), ``studio.exr`` (indoor); in ``hdri_more/`` (39 maps): ``blocky_photo_studio``,
``drachenfels_cellar``, ``leadenhall_market``, ``parking_garage``, ``royal_esplanade``, ``thatch_chapel``
(indoor), ``evening_meadow``, ``studio_garden``, ``urban_street_01`` (outdoor; all ``_1k.hdr``): 12 of 49,
7 indoor and 5 outdoor.

Convention:
    The files use the common lat-long orientation: the centre column looks forward, the left half of the
    image is to the left, the top row is up. That is exactly the lat-long grid of docs/conventions.rst (the
    camera frame +X right, +Y up, +Z toward the camera; centre column = -Z, left half = -X, top row = +Y, see
    :mod:`kornia_ilum.geometry.latlong`), so a file's pixels are used as they are, with no rotation or flip
    (tested with a synthetic map written to disk). Lighting is linear HDR radiance in the units of the file.
    Both ``latlong`` and ``mirror_ball`` keep ``sum(L * Omega)`` per channel of the file: measured within
    2.2e-7 (lat-long) and 1.6e-7 (mirror ball) relative on the 10 shared maps, float32 (the tests require
    1e-5 and 1e-3).
"""

from __future__ import annotations

import hashlib
import math
import os
from collections.abc import Callable, Mapping
from functools import lru_cache
from pathlib import Path

import torch
from torch import nn

from kornia_ilum.core.check import check_positive_int, check_tensor
from kornia_ilum.core.compiler import compiler_disable
from kornia_ilum.core.errors import HDRIOError, ShapeError, TypeCheckError, ValueCheckError
from kornia_ilum.geometry import latlong_to_mirror_ball
from kornia_ilum.io import read_hdr
from kornia_ilum_lab.synth.environments.base import Environment, Label

__all__ = [
    "DEFAULT_LABELS",
    "HDRI_SPLITS",
    "HDR_EXTENSIONS",
    "INDOOR_KEYWORDS",
    "HDRFolderSource",
    "ResizeLatLong",
    "folder_splits",
    "guess_label",
    "hdri_split",
    "resize_latlong",
]

#: File extensions that :class:`HDRFolderSource` lists (case-insensitive).
HDR_EXTENSIONS: tuple[str, ...] = (".hdr", ".exr")

#: Labels of the 49 shared real maps (``../shared/data/hdri`` and ``hdri_more``, Poly Haven, CC0; see their
#: READMEs): the keyword heuristic of :func:`guess_label` gets 11 of the 39 ``hdri_more`` maps wrong.
DEFAULT_LABELS: Mapping[str, Label] = {
    "blouberg_sunrise_2_1k.hdr": "outdoor",
    "moonless_golf_1k.hdr": "outdoor",
    "pedestrian_overpass_1k.hdr": "outdoor",
    "quarry_01_1k.hdr": "outdoor",
    "city.exr": "outdoor",
    "forest.exr": "outdoor",
    "sunrise.exr": "outdoor",
    "courtyard.exr": "outdoor",
    "interior.exr": "indoor",
    "studio.exr": "indoor",
    # the 39 maps of ../shared/data/hdri_more (Poly Haven, CC0), as its README labels them
    "aerodynamics_workshop_1k.hdr": "indoor",
    "artist_workshop_1k.hdr": "indoor",
    "autoshop_01_1k.hdr": "indoor",
    "blocky_photo_studio_1k.hdr": "indoor",
    "brown_photostudio_01_1k.hdr": "indoor",
    "brown_photostudio_02_1k.hdr": "indoor",
    "brown_photostudio_06_1k.hdr": "indoor",
    "brown_photostudio_07_1k.hdr": "indoor",
    "chinese_garden_1k.hdr": "outdoor",
    "christmas_photo_studio_07_1k.hdr": "indoor",
    "circus_arena_1k.hdr": "indoor",
    "comfy_cafe_1k.hdr": "indoor",
    "dancing_hall_1k.hdr": "indoor",
    "drachenfels_cellar_1k.hdr": "indoor",
    "dry_hay_field_1k.hdr": "outdoor",
    "evening_meadow_1k.hdr": "outdoor",
    "fireplace_1k.hdr": "indoor",
    "hilly_terrain_01_1k.hdr": "outdoor",
    "kloppenheim_05_1k.hdr": "outdoor",
    "leadenhall_market_1k.hdr": "indoor",
    "modern_buildings_2_1k.hdr": "outdoor",
    "narrow_moonlit_road_1k.hdr": "outdoor",
    "noon_grass_1k.hdr": "outdoor",
    "parking_garage_1k.hdr": "indoor",
    "peppermint_powerplant_1k.hdr": "indoor",
    "phalzer_forest_01_1k.hdr": "outdoor",
    "rainforest_trail_1k.hdr": "outdoor",
    "royal_esplanade_1k.hdr": "indoor",
    "sepulchral_chapel_rotunda_1k.hdr": "indoor",
    "shanghai_bund_1k.hdr": "outdoor",
    "st_peters_square_night_1k.hdr": "outdoor",
    "studio_garden_1k.hdr": "outdoor",
    "studio_small_05_1k.hdr": "indoor",
    "studio_small_08_1k.hdr": "indoor",
    "studio_small_09_1k.hdr": "indoor",
    "thatch_chapel_1k.hdr": "indoor",
    "urban_street_01_1k.hdr": "outdoor",
    "vestibule_1k.hdr": "indoor",
    "vignaioli_night_1k.hdr": "outdoor",
}

#: Words in a file name that make :func:`guess_label` answer ``"indoor"``.
INDOOR_KEYWORDS: tuple[str, ...] = (
    "interior", "indoor", "studio", "room", "office", "hall", "kitchen", "lobby", "church", "museum",
    "garage", "warehouse", "workshop", "hangar", "theater", "theatre", "library", "corridor", "attic",
)  # fmt: skip

_LABELS = ("indoor", "outdoor")

#: The splits of :func:`hdri_split`.
HDRI_SPLITS: tuple[str, ...] = ("train", "eval")


def hdri_split(name: str) -> str:
    """The split of a real map, by its file name: ``"eval"`` for about one name in four, else ``"train"``.

    ``"eval"`` when the first 8 bytes of ``blake2b(f"kornia_ilum.hdri:{name}")`` (little-endian) are 0 modulo
    4. Only the file name counts (a path's folders are dropped), so a map keeps its split in any folder.

    Args:
        name: the map's file name, or a path to it.

    Returns:
        ``"train"`` or ``"eval"`` (:data:`HDRI_SPLITS`).

    Raises:
        TypeCheckError: ``name`` is not a string or path.

    Examples:
        >>> hdri_split("studio.exr"), hdri_split("interior.exr"), hdri_split("/any/where/studio.exr")
        ('eval', 'train', 'eval')
    """
    if not isinstance(name, (str, os.PathLike)):
        raise TypeCheckError(f"name must be a file name, got {type(name).__name__}")
    key = f"kornia_ilum.hdri:{Path(name).name}".encode()
    return "eval" if int.from_bytes(hashlib.blake2b(key, digest_size=8).digest(), "little") % 4 == 0 else "train"


def _map_names(folder: Path) -> tuple[str, ...]:
    if not folder.is_dir():
        raise HDRIOError(f"HDR map folder {folder} does not exist or is not a folder")
    files = (p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in HDR_EXTENSIONS)
    return tuple(sorted(p.name for p in files))


def folder_splits(folder: str | os.PathLike[str]) -> dict[str, str]:
    """``{name: split}`` (:func:`hdri_split`) for the maps of a folder, sorted by name.

    Args:
        folder: a folder of lat-long maps (the files with an extension of :data:`HDR_EXTENSIONS`).

    Returns:
        the split of each map, by file name, in name order.

    Raises:
        HDRIOError: the folder does not exist.

    Examples:
        >>> import tempfile
        >>> from kornia_ilum.io import write_hdr
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     for name in ("studio.exr", "interior.exr"):
        ...         write_hdr(Path(tmp) / name, torch.ones(3, 4, 8))
        ...     folder_splits(tmp)
        {'interior.exr': 'train', 'studio.exr': 'eval'}
    """
    return {name: hdri_split(name) for name in _map_names(Path(folder))}


def guess_label(name: str) -> Label:
    """The default label of a map file: :data:`DEFAULT_LABELS`, else a keyword heuristic, else outdoor.

    Names in :data:`DEFAULT_LABELS` (the shared maps) get their label. Any other name is ``"indoor"`` when
    its lower-cased file name contains one of :data:`INDOOR_KEYWORDS` (Poly Haven names indoor maps this
    way, e.g. ``hotel_room``, ``photo_studio``), and ``"outdoor"`` otherwise.

    Args:
        name: the map's file name (with its extension, without folders).

    Returns:
        ``"indoor"`` or ``"outdoor"``.

    Note:
        Unknown names without an indoor keyword are labelled ``"outdoor"``, which may be wrong: pass
        ``label_of`` to :class:`HDRFolderSource` for your own maps.

    Examples:
        >>> guess_label("studio.exr"), guess_label("small_hotel_room_4k.hdr"), guess_label("meadow.exr")
        ('indoor', 'indoor', 'outdoor')
    """
    if name in DEFAULT_LABELS:
        return DEFAULT_LABELS[name]
    lower = name.lower()
    return "indoor" if any(k in lower for k in INDOOR_KEYWORDS) else "outdoor"


@compiler_disable
@lru_cache(maxsize=32)
def _overlap_matrices(h_src: int, h_tgt: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Row ``(h_tgt, h_src)`` and column ``(2 h_tgt, 2 h_src)`` area-weight matrices, float64.

    ``rows[I, i]``: the part of the band ``sin(el)`` of target row ``I`` covered by source row ``i``, over
    the target row's band; ``cols[J, j]``: the same for azimuth intervals. Each row of both sums to 1 and
    each source interval is shared out completely, so ``rows @ L @ cols.T`` conserves ``sum(L * Omega)``.
    """

    def overlap(src_edges: torch.Tensor, tgt_edges: torch.Tensor) -> torch.Tensor:
        lo = torch.maximum(tgt_edges[:-1, None], src_edges[None, :-1])
        hi = torch.minimum(tgt_edges[1:, None], src_edges[None, 1:])
        ov = (hi - lo).clamp(min=0.0)
        return ov / (tgt_edges[1:] - tgt_edges[:-1])[:, None]

    def sin_edges(h: int) -> torch.Tensor:  # -sin(el) of the row edges, top first: increasing
        return -torch.sin(math.pi / 2 - math.pi * torch.arange(h + 1, dtype=torch.float64) / h)

    def phi_edges(h: int) -> torch.Tensor:
        return torch.arange(2 * h + 1, dtype=torch.float64) / (2 * h)

    return overlap(sin_edges(h_src), sin_edges(h_tgt)), overlap(phi_edges(h_src), phi_edges(h_tgt))


def resize_latlong(latlong: torch.Tensor, height: int) -> torch.Tensor:
    r"""Resize an ``H x 2H`` lat-long map to ``height x 2 height`` by exact area averaging.

    Each target pixel is the solid-angle-weighted mean of the source pixels it overlaps, with the overlaps
    computed exactly: a lat-long pixel is a rectangle in ``(phi, sin(el))``, where solid angle is area
    (``dOmega = dphi d(sin el)``), so the operator is separable, ``L' = A_rows L A_cols^T``. Hence
    ``sum(L * Omega)`` per channel is conserved to float precision, a constant map stays constant, and a sun
    keeps its energy in the target pixel that contains it. Upsampling repeats values (piecewise constant).

    Args:
        latlong: linear HDR lat-long map, non-negative.
        height: the new height ``H'``.

    Returns:
        the resized map in the dtype and on the device of ``latlong``.

    Shape:
        - latlong: :math:`(*, C, H, 2H)`
        - Output: :math:`(*, C, H', 2H')`

    Convention:
        Lat-long grid of docs/conventions.rst; the edges of row ``i`` are at ``el = pi/2 - pi i / H``.

    Examples:
        >>> from kornia_ilum.geometry import latlong_solid_angles
        >>> env = torch.rand(3, 8, 16)
        >>> small = resize_latlong(env, 4)
        >>> e0 = (env * latlong_solid_angles(8)).sum((-1, -2))
        >>> e1 = (small * latlong_solid_angles(4)).sum((-1, -2))
        >>> torch.allclose(e0, e1)
        True
    """
    check_tensor(latlong, "latlong", ["*", "C", "H", "2H"], nonnegative=True)
    check_positive_int(height, "height")
    h, w = latlong.shape[-2:]
    if w != 2 * h:
        raise ShapeError(f"latlong must have shape (*, C, H, 2H), got {tuple(latlong.shape)}")
    if h == height:
        return latlong
    rows, cols = _overlap_matrices(h, height)
    work = latlong.float() if latlong.dtype in (torch.float16, torch.bfloat16) else latlong
    rows = rows.to(device=work.device, dtype=work.dtype)
    cols = cols.to(device=work.device, dtype=work.dtype)
    return (rows @ work @ cols.T).to(latlong.dtype)


class ResizeLatLong(nn.Module):
    r"""Module twin of :func:`resize_latlong`.

    Args:
        height: the new height ``H'``.

    Examples:
        >>> ResizeLatLong(4)(torch.rand(2, 3, 8, 16)).shape
        torch.Size([2, 3, 4, 8])
    """

    def __init__(self, height: int) -> None:
        super().__init__()
        check_positive_int(height, "height")
        self.height = height

    def forward(self, latlong: torch.Tensor) -> torch.Tensor:
        return resize_latlong(latlong, self.height)

    def extra_repr(self) -> str:
        return f"height={self.height}"


def _label_function(label_of: Callable[[str], str] | Mapping[str, str] | None) -> Callable[[str], str]:
    if label_of is None:
        return guess_label
    if isinstance(label_of, Mapping):
        table = dict(label_of)
        return lambda name: table.get(name, table.get(Path(name).stem, guess_label(name)))
    if callable(label_of):
        return label_of
    raise TypeCheckError(
        f"label_of must be None, a callable or a dict name -> label, got {type(label_of).__name__}"
    )


class HDRFolderSource:
    r"""Environments from the lat-long HDR maps (``.hdr``, ``.exr``) of a folder.

    The folder is listed once (sorted file names, not recursive). Each map is read on first use with
    :func:`kornia_ilum.io.read_hdr` (negatives clamped to 0), resized to ``height x 2 height`` with
    :func:`resize_latlong` (exact area averaging, energy-conserving), turned into a 32 x 32 mirror ball with
    :func:`~kornia_ilum.geometry.latlong_to_mirror_ball` (``mode="area"``), and cached in memory (a
    128 x 256 map and its ball take 0.4 MB).

    Args:
        folder: the folder of maps.
        height: the working height ``H`` of the lat-long maps (``H x 2H``).
        label_of: the label of each map: a callable ``name -> "indoor" | "outdoor"``, or a dict keyed by
            file name (or stem); names missing from the dict, and all names when ``None``, get
            :func:`guess_label` (the table of the 49 shared maps, else a keyword heuristic, else outdoor).
        split: keep only the maps of this split of :func:`hdri_split` (``"train"`` or ``"eval"``); ``None``:
            all. Train on ``split="train"`` to keep the ``"eval"`` maps held out.

    Attributes:
        names: the map file names (of ``split``), sorted.
        split: the split kept, or ``None``.
        labels: ``{name: label}``.
        label: the source's label for :class:`~kornia_ilum_lab.synth.environments.EnvironmentSampler`'s
            weights: the label of most maps (``"outdoor"`` on a tie); each environment carries its own.

    Raises:
        HDRIOError: the folder does not exist, or holds no ``.hdr`` / ``.exr`` file (of ``split``; the message
            names it); a map cannot be read (on first use).
        ValueCheckError: ``label_of`` gives something other than ``"indoor"`` or ``"outdoor"``; an unknown
            ``split``.

    Convention:
        The files' orientation (centre column = forward) is the lat-long of docs/conventions.rst: no
        rotation is applied (module docstring). ``Environment.params`` holds ``{"map": name, "index": i}``;
        ``source`` is ``"real:<name>"``.

    Examples:
        >>> import tempfile
        >>> from kornia_ilum.io import write_hdr
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     write_hdr(Path(tmp) / "meadow.exr", torch.ones(3, 16, 32))
        ...     source = HDRFolderSource(tmp, height=8)
        ...     env = source.sample(torch.Generator().manual_seed(0))
        >>> env.source, env.label, tuple(env.latlong.shape), tuple(env.mirror_ball.shape)
        ('real:meadow.exr', 'outdoor', (3, 8, 16), (3, 32, 32))
    """

    def __init__(
        self,
        folder: str | os.PathLike[str],
        height: int = 128,
        label_of: Callable[[str], str] | Mapping[str, str] | None = None,
        split: str | None = None,
    ) -> None:
        check_positive_int(height, "height")
        if split is not None and split not in HDRI_SPLITS:
            raise ValueCheckError(f"split must be 'train', 'eval' or None, got {split!r}")
        self.folder = Path(folder)
        self.split = split
        names = _map_names(self.folder)
        self.names: tuple[str, ...] = tuple(n for n in names if split is None or hdri_split(n) == split)
        if not self.names:
            kept = f" of split {split!r}" if split is not None and names else ""
            raise HDRIOError(
                f"HDR map folder {self.folder} holds no lat-long map{kept} ({' or '.join(HDR_EXTENSIONS)} file)"
            )
        self.height = height
        label_fn = _label_function(label_of)
        self.labels: dict[str, Label] = {}
        for name in self.names:
            label = label_fn(name)
            if label not in _LABELS:
                raise ValueCheckError(f"label_of({name!r}) must be 'indoor' or 'outdoor', got {label!r}")
            self.labels[name] = label  # type: ignore[assignment]
        n_indoor = sum(v == "indoor" for v in self.labels.values())
        self.label: Label = "indoor" if 2 * n_indoor > len(self.names) else "outdoor"
        self._cache: dict[int, tuple[torch.Tensor, torch.Tensor]] = {}

    def __len__(self) -> int:
        return len(self.names)

    def __repr__(self) -> str:
        split = "" if self.split is None else f", split={self.split!r}"
        return f"HDRFolderSource(folder={str(self.folder)!r}, height={self.height}{split}, maps={len(self)})"

    def _load(self, index: int) -> tuple[torch.Tensor, torch.Tensor]:
        if index not in self._cache:
            image = read_hdr(self.folder / self.names[index])  # (3, H, W), negatives clamped
            if image.shape[-1] != 2 * image.shape[-2]:
                raise HDRIOError(
                    f"{self.folder / self.names[index]} is not a lat-long map: expected width 2 x height, "
                    f"got {image.shape[-2]} x {image.shape[-1]} (height x width)"
                )
            latlong = resize_latlong(image, self.height)
            ball = latlong_to_mirror_ball(latlong[None], 32, mode="area")[0]
            self._cache[index] = (latlong, ball)
        return self._cache[index]

    def environment(self, index: int) -> Environment:
        """The map ``index`` (in :attr:`names` order) as an :class:`Environment`, without randomness."""
        if isinstance(index, bool) or not isinstance(index, int) or not -len(self) <= index < len(self):
            raise ValueCheckError(f"index must be an int in [0, {len(self)}), got {index!r}")
        index %= len(self)
        latlong, ball = self._load(index)
        name = self.names[index]
        return Environment(
            latlong=latlong.clone(),
            mirror_ball=ball.clone(),
            label=self.labels[name],
            source=f"real:{name}",
            params={"map": name, "index": index},
        )

    def sample(self, generator: torch.Generator) -> Environment:
        """A map picked uniformly with ``generator`` (one ``torch.randint`` draw)."""
        if not isinstance(generator, torch.Generator):
            raise TypeCheckError(f"generator must be a torch.Generator, got {type(generator).__name__}")
        index = int(torch.randint(len(self), (1,), generator=generator).item())
        return self.environment(index)
