r"""On-disk cache of OLAT reflectance fields: safetensors files, a manifest, resumable and sharded generation.

Layout of a cache folder::

    out_dir/
        fields/s000007_v01.safetensors   one (subject seed, view) per file
        manifest.json                    every entry (merged from the workers' manifests)
        manifest.w000of004.json          what worker 0 of 4 wrote (one per worker)

A field file (:func:`write_field`) holds the *compact* layout of :class:`~.olat.ReflectanceField`, which is
lossless: ``field`` bfloat16 ``(3, P', N')``, channel-major, with only the ``P'`` pixels that the subject
covers or lights (``pixel_index`` int32) and only the ``N'`` valid lights (``light_index`` int32; 812 of 1024 at
``S = 32``); ``alpha`` float16 ``(1, size, size)``; ``face_box`` float32 ``(4,)``; and, as the file's JSON
metadata, the camera, the subject seed and the render's ``meta``. Measured on the default views of
:func:`~kornia_ilum.synth.lightstage.subjects.make_subject` subjects at 256 x 256 (``benchmarks/bench_olat.py``):
the dense bfloat16 field is 403 MB (3 x 65536 x 1024 x 2 bytes); keeping the valid lights cuts 21 %, and keeping
the covered pixels (53 to 58 % of the image) cuts the rest about in half: a compact file is 170 to 183 MB per
subject and view (0.42 to 0.45 of dense), 11 to 12 MB at 64 x 64.

``manifest.json`` is ``{"format": ..., "entries": [...]}``; each entry has ``subject_seed``, ``view_index``,
``camera``, ``path`` (relative to the folder), ``sha256``, ``shape``, ``dtype``, ``bytes``, ``render_seconds``,
and the subject's ``split`` and ``skin_tone``. :func:`read_manifest` returns the union of ``manifest.json`` and
the workers' manifests, so an entry is never lost to two workers merging at the same time.

Every file is written atomically (to a temporary name in the same folder, flushed, then renamed), so a killed
worker leaves no half-written field or manifest. :func:`build_cache` skips the (seed, view) pairs whose file
is on disk with the manifest's hash and the requested settings, so rerunning it resumes an interrupted run.
"""

from __future__ import annotations

import dataclasses
import json
import os
import time
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import torch

from kornia_ilum.core.check import check_positive_int
from kornia_ilum.core.errors import HDRIOError, TypeCheckError, ValueCheckError
from kornia_ilum.core.files import atomic_write, sha256_file
from kornia_ilum.geometry import mirror_ball_valid
from kornia_ilum.synth.lightstage.olat import ReflectanceField, render_olat
from kornia_ilum.synth.lightstage.scene import Camera

__all__ = [
    "DEFAULT_VIEWS",
    "FORMAT",
    "build_cache",
    "field_path",
    "read_field",
    "read_manifest",
    "shard",
    "write_field",
]

FORMAT = "kornia_ilum.olat.v1"
MANIFEST_FORMAT = "kornia_ilum.olat-cache.v1"

#: The default camera views, framed for the subjects of :func:`~kornia_ilum.synth.lightstage.make_subject`
#: (face landmarks 0.14 to 0.17 m tall: the face-landmark box is 0.5 to 0.6 of the image height and the
#: detector-style crop of :mod:`~kornia_ilum.synth.lightstage.portraits`, 1.25 x 1.13 of that, 0.7 to 0.85,
#: leaving room for its jitter): frontal
#: at 30 degrees of field of view; turned +25 degrees with a slightly high, longer (25 degree) lens; turned -25
#: degrees with a slightly low, wider (35 degree) lens. Distances keep the framing about equal across the lenses.
DEFAULT_VIEWS: tuple[Camera, ...] = (
    Camera(fov_deg=30.0, distance=0.56, yaw_deg=0.0, pitch_deg=0.0),
    Camera(fov_deg=25.0, distance=0.68, yaw_deg=25.0, pitch_deg=5.0),
    Camera(fov_deg=35.0, distance=0.47, yaw_deg=-25.0, pitch_deg=-5.0),
)


def field_path(seed: int, view_index: int) -> str:
    """The file of one (subject seed, view) relative to the cache folder.

    Examples:
        >>> field_path(7, 1)
        'fields/s000007_v01.safetensors'
    """
    return f"fields/s{seed:06d}_v{view_index:02d}.safetensors"


def _write_json(path: Path, obj: Any) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, lambda tmp: tmp.write_text(json.dumps(obj, indent=1, sort_keys=True)))


def write_field(path: str | os.PathLike, field: ReflectanceField) -> dict[str, Any]:
    r"""Write a reflectance field to a safetensors file, atomically, in the compact layout (module docstring).

    Args:
        path: the file to write (its folder is created).
        field: the field, dense or compact.

    Returns:
        the file's facts: ``sha256``, ``bytes``, ``shape`` and ``dtype`` of the stored field.

    Examples:
        >>> import tempfile, torch
        >>> rf = ReflectanceField(torch.zeros(3, 4, 4, dtype=torch.bfloat16), torch.ones(1, 2, 2),
        ...                       torch.tensor([0.0, 0.0, 2.0, 2.0]), Camera(30.0, 1.0, 0.0, 0.0, size=2), 7)
        >>> with tempfile.TemporaryDirectory() as d:
        ...     info = write_field(f"{d}/a.safetensors", rf)
        ...     back = read_field(f"{d}/a.safetensors")
        >>> info["shape"], back.field.shape, back.subject_seed
        ([3, 4, 4], torch.Size([3, 4, 4]), 7)
    """
    from safetensors.torch import save_file

    if not isinstance(field, ReflectanceField):
        raise TypeCheckError(f"field must be a ReflectanceField, got {type(field).__name__}")
    compact = field.to_compact()
    tensors = {
        "field": compact.field.to(torch.bfloat16).contiguous(),
        "pixel_index": compact.pixel_index.to(torch.int32).contiguous(),
        "light_index": compact.light_index.to(torch.int32).contiguous(),
        "alpha": field.alpha.to(torch.float16).contiguous(),
        "face_box": field.face_box.to(torch.float32).contiguous(),
    }
    metadata = {
        "format": FORMAT,
        "camera": json.dumps(field.camera.to_dict()),
        "subject_seed": str(int(field.subject_seed)),
        "lighting_size": str(field.lighting_size),
        "meta": json.dumps(field.meta),
    }
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, lambda tmp: save_file(tensors, str(tmp), metadata=metadata))
    return {
        "sha256": sha256_file(path),
        "bytes": path.stat().st_size,
        "shape": list(tensors["field"].shape),
        "dtype": "bfloat16",
    }


def read_field(path: str | os.PathLike, *, dense: bool = True, mmap: bool = False) -> ReflectanceField:
    r"""Read a field written by :func:`write_field`.

    Args:
        path: the safetensors file.
        dense: return the dense ``(3, size^2, S^2)`` layout (403 MB at 256 x 256, ``S = 32``); ``False`` keeps
            the compact layout with its ``pixel_index`` and ``light_index`` (faster to relight: relight the
            ``P'`` pixels with the ``N'`` lights, scatter into the image, zero elsewhere).
        mmap: with ``dense=False``, map the field's bytes from the file instead of reading them: nothing is
            read until it is used, and processes that map the same file (data-loader workers) share one copy
            in the page cache. safetensors' own reader always copies, so the tensor is a copy-on-write
            :class:`numpy.memmap` of the file's data (the format is a JSON header and raw little-endian bytes).

    Raises:
        HDRIOError: the file is missing, unreadable or not a field of this format (the message names it).
    """
    from safetensors import safe_open

    path = Path(path)
    try:
        with safe_open(str(path), framework="pt") as fh:
            metadata = fh.metadata() or {}
            if metadata.get("format") != FORMAT:
                raise HDRIOError(f"{path} is not a reflectance field of format {FORMAT!r}")
            names = [k for k in fh.keys() if not (mmap and k == "field")]  # noqa: SIM118 - no iterator
            tensors = {k: fh.get_tensor(k) for k in names}
        if mmap:
            tensors["field"] = _mapped_bfloat16(path, "field")
    except HDRIOError:
        raise
    except Exception as exc:  # safetensors raises its own error types, OSError for a missing file
        raise HDRIOError(f"cannot read the reflectance field {path}: {exc}") from exc
    meta = json.loads(metadata["meta"])
    meta.setdefault("lighting_size", int(metadata["lighting_size"]))
    field = ReflectanceField(
        tensors["field"],
        tensors["alpha"].float(),
        tensors["face_box"],
        Camera(**json.loads(metadata["camera"])),
        int(metadata["subject_seed"]),
        meta,
        tensors["pixel_index"].long(),
        tensors["light_index"].long(),
    )
    return field.to_dense() if dense else field


def _mapped_bfloat16(path: Path, name: str) -> torch.Tensor:
    """Tensor ``name`` of a safetensors file, mapped (copy-on-write) rather than read; bfloat16 only."""
    import numpy as np

    with open(path, "rb") as fh:
        length = int.from_bytes(fh.read(8), "little")
        info = json.loads(fh.read(length))[name]
    if info["dtype"] != "BF16":
        raise HDRIOError(f"{path}: {name} is {info['dtype']}, not BF16")
    start, end = info["data_offsets"]
    array = np.memmap(path, dtype="<i2", mode="c", offset=8 + length + start, shape=((end - start) // 2,))
    return torch.from_numpy(array).view(torch.bfloat16).reshape(info["shape"])


def _read_manifest_file(path: Path) -> list[dict[str, Any]]:
    """The entries of one manifest file (none if it does not exist)."""
    if not path.is_file():
        return []
    try:
        return list(json.loads(path.read_text()).get("entries", []))
    except (OSError, json.JSONDecodeError, AttributeError) as exc:
        raise HDRIOError(f"cannot read the cache manifest {path}: {exc}") from exc


def _manifest_name(worker_index: int, worker_count: int) -> str:
    return f"manifest.w{worker_index:03d}of{worker_count:03d}.json"


def read_manifest(out_dir: str | os.PathLike) -> dict[str, Any]:
    r"""The cache's manifest: the union of ``manifest.json`` and every worker's manifest.

    Entries are keyed by ``(subject_seed, view_index)``; where two files list the same key, the most recently
    written entry wins. A folder without manifests gives no entries.

    Returns:
        ``{"format": ..., "entries": [...]}``, entries sorted by ``(subject_seed, view_index)``.
    """
    out_dir = Path(out_dir)
    entries: dict[tuple[int, int], dict[str, Any]] = {}
    for file in [out_dir / "manifest.json", *sorted(out_dir.glob("manifest.w*of*.json"))]:
        for entry in _read_manifest_file(file):
            key = (int(entry["subject_seed"]), int(entry["view_index"]))
            if key not in entries or entry.get("written", 0) >= entries[key].get("written", 0):
                entries[key] = entry
    return {"format": MANIFEST_FORMAT, "entries": [entries[k] for k in sorted(entries)]}


def shard(items: Sequence[Any], worker_index: int, worker_count: int) -> list[Any]:
    r"""The items of worker ``worker_index`` of ``worker_count``: every ``worker_count``-th, round robin.

    Examples:
        >>> shard(list(range(7)), 1, 3)
        [1, 4]
    """
    check_positive_int(worker_count, "worker_count")
    if isinstance(worker_index, bool) or not isinstance(worker_index, int) or not 0 <= worker_index < worker_count:
        raise ValueCheckError(f"worker_index must be an int in [0, {worker_count}), got {worker_index!r}")
    return list(items[worker_index::worker_count])


def _entry_ok(entry: dict[str, Any] | None, out_dir: Path, camera: Camera, spp: int, lighting_size: int) -> bool:
    """Whether a manifest entry is a finished render with these settings whose file is intact."""
    if entry is None or entry.get("camera") != camera.to_dict():
        return False
    if entry.get("spp_requested") != spp or entry.get("lighting_size") != lighting_size:
        return False
    path = out_dir / entry["path"]
    return path.is_file() and path.stat().st_size == entry["bytes"] and sha256_file(path) == entry["sha256"]


def build_cache(
    out_dir: str | os.PathLike,
    seeds: Iterable[int],
    views: Sequence[Camera] | None = None,
    *,
    worker_index: int = 0,
    worker_count: int = 1,
    size: int = 256,
    spp: int = 16,
    lighting_size: int = 32,
    variant: str | None = None,
    threads: int | None = None,
    progress: bool = True,
) -> dict[str, Any]:
    r"""Render and cache the reflectance fields of subjects x views; resumable, one shard per worker.

    The (seed, view) pairs, seed-major, are dealt round robin to the workers (:func:`shard`); this worker renders
    its pairs that the manifest does not already hold intact with the same camera, ``spp`` and
    ``lighting_size``, writes each field (:func:`write_field`), records it in its own manifest
    ``manifest.w<i>of<n>.json`` right away, and finally merges all manifests into ``manifest.json``. Workers can
    share one folder (a network file system) or write to separate folders that are copied together later.

    Args:
        out_dir: the cache folder (created).
        seeds: subject seeds for :func:`~kornia_ilum.synth.lightstage.subjects.make_subject`.
        views: the cameras; default :data:`DEFAULT_VIEWS`. The view index is the position in this list.
        worker_index: this worker, in ``[0, worker_count)``.
        worker_count: how many workers share the work.
        size: image side; replaces each view's ``size``.
        spp: samples per pixel per light.
        lighting_size: the mirror-ball side ``S`` of the lighting basis.
        variant: the Mitsuba variant (:func:`~.olat.select_mitsuba_variant`).
        threads: Dr.Jit threads (process-global); default Dr.Jit's (all cores).
        progress: show a progress bar of the lights rendered on stderr.

    Returns:
        the merged manifest (:func:`read_manifest`).

    Examples:
        >>> shard([(s, v) for s in (1, 2) for v in range(3)], 0, 2)  # what worker 0 of 2 renders
        [(1, 0), (1, 2), (2, 1)]
    """
    from kornia_ilum.synth.lightstage.subjects import make_subject  # lazy: the subject generator is heavy

    out_dir = Path(out_dir)
    views = tuple(DEFAULT_VIEWS if views is None else views)
    if not views or not all(isinstance(v, Camera) for v in views):
        raise TypeCheckError("views must be a non-empty sequence of Camera")
    check_positive_int(size, "size")
    check_positive_int(spp, "spp")
    check_positive_int(lighting_size, "lighting_size")
    seeds = [int(s) for s in seeds]
    pairs = shard([(s, v) for s in seeds for v in range(len(views))], worker_index, worker_count)
    cameras = [dataclasses.replace(v, size=size) for v in views]

    known = {(e["subject_seed"], e["view_index"]): e for e in read_manifest(out_dir)["entries"]}
    own_file = out_dir / _manifest_name(worker_index, worker_count)
    own = {(e["subject_seed"], e["view_index"]): e for e in _read_manifest_file(own_file)}
    todo = [(s, v) for s, v in pairs if not _entry_ok(known.get((s, v)), out_dir, cameras[v], spp, lighting_size)]

    subject, subject_seed = None, None
    bar = None
    if progress and todo:
        from kornia_ilum.core.progress import ProgressBar

        bar = ProgressBar(len(todo) * int(mirror_ball_valid(lighting_size).sum()), "OLAT renders", "light")
    for seed, view in todo:
        if subject_seed != seed:
            subject, subject_seed = make_subject(seed), seed
        rf = render_olat(subject, cameras[view], lighting_size=lighting_size, spp=spp, variant=variant,
                         threads=threads, callback=None if bar is None else bar.update)
        rel = field_path(seed, view)
        info = write_field(out_dir / rel, rf)
        own[(seed, view)] = {
            "subject_seed": seed,
            "view_index": view,
            "camera": cameras[view].to_dict(),
            "path": rel,
            **info,
            "layout": "compact",
            "render_seconds": rf.meta["render_seconds"],
            "spp_requested": spp,
            "spp": rf.meta["spp"],
            "lighting_size": lighting_size,
            "variant": rf.meta["variant"],
            "split": getattr(subject, "split", None),
            "skin_tone": getattr(subject, "skin_tone", None),
            "written": time.time(),
        }
        _write_json(own_file, {"format": MANIFEST_FORMAT, "entries": [own[k] for k in sorted(own)]})
    if bar is not None:
        bar.close()
    manifest = read_manifest(out_dir)
    _write_json(out_dir / "manifest.json", manifest)
    return manifest
