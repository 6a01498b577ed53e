r"""On-disk cache of OLAT reflectance fields: safetensors files, a manifest, resumable and sharded generation.

Layout of a cache folder::

    out_dir/
        fields/s000007_v01.safetensors   one (subject seed, view) per file
        manifest.json                    every entry (merged from the workers' manifests)
        manifest.w000of004.json          what worker 0 of 4 wrote (one per worker)

A field file (:func:`write_field`) holds the *compact* layout of :class:`~.field.ReflectanceField`, which is
lossless: ``field`` bfloat16 ``(3, P', N')``, channel-major, with only the ``P'`` pixels that the subject
covers or lights (``pixel_index`` int32) and only the ``N'`` valid lights (``light_index`` int32; 812 of 1024 at
``S = 32``); ``alpha`` float16 ``(1, size, size)``; ``face_box`` float32 ``(4,)``; and, as the file's JSON
metadata, the camera, the subject seed and the render's ``meta``. Measured on the default views of
:func:`~kornia_ilum_lab.synth.lightstage.subjects.make_subject` subjects at 256 x 256 (``benchmarks/bench_olat.py``):
the dense bfloat16 field is 403 MB (3 x 65536 x 1024 x 2 bytes); keeping the valid lights cuts 21 %, and keeping
the covered pixels (53 to 58 % of the image) cuts the rest about in half: a compact file is 170 to 183 MB per
subject and view (0.42 to 0.45 of dense), 11 to 12 MB at 64 x 64.

``manifest.json`` is ``{"format": ..., "entries": [...]}``; each entry (format v2) has ``subject_seed``,
``view_index``, ``camera``, ``path`` (relative to the folder), ``sha256``, ``shape``, ``dtype``, ``bytes``, the
settings (``source``, ``spp_requested``, ``spp``, ``lighting_size``, ``size``, ``views``: ``"fixed"`` or
``"sample_views(n=4)"``, ``variant``, and ``renderer``: the renderer's settings, e.g. :meth:`OnePass.to_dict
<kornia_ilum_lab.synth.lightstage.settings.OnePass.to_dict>`, unless they are ``Auto`` with seed 0, which the
other keys describe), the costs (``render_seconds`` of the view, ``subject_seconds`` to build
the subject, counted on its first view, ``peak_rss_mb`` of the worker process so far), and the subject's
``split``, ``skin_tone``, ``face_albedo`` and ``params`` (its scalar parameters). v2 field files equal v1's
plus ``meta["source"]``, and (one-pass renders, since issue 21) ``albedo`` and ``skin``, the G-buffer's diffuse
albedo and skin coverage for the uniform-white check; :func:`read_field` reads both. :func:`read_manifest` returns the union of ``manifest.json`` and
the workers' manifests, so an entry is never lost to two workers merging at the same time.

Every file is written atomically (to a temporary name in the same folder, flushed, then renamed), so a killed
worker leaves no half-written field or manifest. :func:`build_cache` skips the (seed, view) pairs whose file
is on disk with the manifest's hash and the requested settings, so rerunning it resumes an interrupted run.
"""

from __future__ import annotations

import dataclasses
import json
import multiprocessing as mp
import os
import queue as queue_module
import statistics
import sys
import time
import traceback
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import safetensors.torch
import torch
from safetensors import safe_open

from kornia_ilum.core.check import check_positive_int
from kornia_ilum.core.errors import HDRIOError, IlumError, TypeCheckError, ValueCheckError
from kornia_ilum.core.files import atomic_write, sha256_file
from kornia_ilum_lab.synth.lightstage.field import ReflectanceField
from kornia_ilum_lab.synth.lightstage.olat import render_olat
from kornia_ilum_lab.synth.lightstage.scene import FACE_FRACTION, Camera, sample_views
from kornia_ilum_lab.synth.lightstage.settings import Auto, OnePass, Reference
from kornia_ilum_lab.synth.lightstage.subjects import subject_source

__all__ = [
    "DEFAULT_VIEWS",
    "FORMAT",
    "READABLE_FORMATS",
    "FixedViews",
    "SampledViews",
    "Workers",
    "build_cache",
    "cache_summary",
    "field_path",
    "map_bfloat16",
    "read_field",
    "read_manifest",
    "shard",
    "write_field",
]

FORMAT = "kornia_ilum.olat.v2"
MANIFEST_FORMAT = "kornia_ilum.olat-cache.v2"
#: Field formats that :func:`read_field` reads: v1 files have the same tensors, without ``meta["source"]``.
READABLE_FORMATS = ("kornia_ilum.olat.v1", FORMAT)

#: The default camera views, framed for the subjects of :func:`~kornia_ilum_lab.synth.lightstage.make_subject`
#: (face landmarks 0.14 to 0.17 m tall: the face-landmark box is 0.5 to 0.6 of the image height and the
#: detector-style crop of :mod:`~kornia_ilum_lab.synth.lightstage.portraits`, 1.25 x 1.13 of that, 0.7 to 0.85,
#: leaving room for its jitter): frontal
#: at 30 degrees of field of view; turned +25 degrees with a slightly high, longer (25 degree) lens; turned -25
#: degrees with a slightly low, wider (35 degree) lens. Distances keep the framing about equal across the lenses.
DEFAULT_VIEWS: tuple[Camera, ...] = (
    Camera(fov_deg=30.0, distance=0.56, yaw_deg=0.0, pitch_deg=0.0),
    Camera(fov_deg=25.0, distance=0.68, yaw_deg=25.0, pitch_deg=5.0),
    Camera(fov_deg=35.0, distance=0.47, yaw_deg=-25.0, pitch_deg=-5.0),
)


@dataclass(frozen=True)
class FixedViews:
    r"""The same cameras for every subject of a cache (view index = position), each at ``size`` pixels.

    Args:
        cameras: the cameras; their own ``size`` is replaced by ``size``.
        size: the image side.

    Raises:
        TypeCheckError: ``cameras`` is not a non-empty sequence of :class:`Camera`.
        ValueCheckError: ``size`` is not positive.

    Examples:
        >>> FixedViews().count, FixedViews(size=64).cameras[0].size
        (3, 64)
    """

    cameras: tuple[Camera, ...] = DEFAULT_VIEWS
    size: int = 192

    def __post_init__(self) -> None:
        if isinstance(self.cameras, (str, bytes)) or not isinstance(self.cameras, Sequence):
            raise TypeCheckError("views must be a non-empty sequence of Camera")
        cameras = tuple(self.cameras)
        if not cameras or not all(isinstance(v, Camera) for v in cameras):
            raise TypeCheckError("views must be a non-empty sequence of Camera")
        check_positive_int(self.size, "size")
        object.__setattr__(self, "cameras", tuple(dataclasses.replace(v, size=self.size) for v in cameras))

    @property
    def count(self) -> int:
        """Views per subject."""
        return len(self.cameras)

    @property
    def label(self) -> str:
        """The manifest's ``views`` setting."""
        return "fixed"


@dataclass(frozen=True)
class SampledViews:
    r"""``per_subject`` random views of each subject (:func:`~.scene.sample_views`, framed for its landmarks).

    Args:
        per_subject: views per subject.
        size: the image side.
        fraction: the face-landmark box's height over the image height (:data:`~.scene.FACE_FRACTION`, 0.5);
            smaller shows more of the body and of what is around it.

    Raises:
        ValueCheckError: a count or size that is not positive, a fraction outside ``(0, 1)``.

    Examples:
        >>> SampledViews(2, size=64).label
        'sample_views(n=2)'
        >>> SampledViews(2, size=64, fraction=0.25).label
        'sample_views(n=2, fraction=0.25)'
    """

    per_subject: int = 4
    size: int = 192
    fraction: float = FACE_FRACTION

    def __post_init__(self) -> None:
        check_positive_int(self.per_subject, "views_per_subject")
        check_positive_int(self.size, "size")
        if not 0.0 < self.fraction < 1.0:
            raise ValueCheckError(f"fraction must be in (0, 1), got {self.fraction!r}")

    @property
    def count(self) -> int:
        """Views per subject."""
        return self.per_subject

    @property
    def label(self) -> str:
        """The manifest's ``views`` setting."""
        more = f", fraction={self.fraction:g}" if self.fraction != FACE_FRACTION else ""
        return f"sample_views(n={self.per_subject}{more})"


@dataclass(frozen=True, kw_only=True)
class Workers:
    r"""Who renders a cache: processes on this machine, this machine's share, threads.

    Args:
        processes: render processes on this machine. More than one spawns them (``multiprocessing`` spawn),
            each with one torch thread and one Dr.Jit thread (faster than one process with as many threads:
            docs/lightstage.rst, "Measured"); one renders in the calling process with ``threads`` threads.
        index: this machine's share of the seeds, in ``[0, count)``: every ``count``-th seed from ``index``
            (:func:`shard`), for machines that share one cache folder.
        count: machines sharing the work.
        threads: with one process, torch and Dr.Jit threads (``None``: leave them); processes use 1.

    Raises:
        ValueCheckError: a count out of its range.

    Examples:
        >>> Workers(processes=1, index=1, count=2).index
        1
    """

    processes: int = 2
    index: int = 0
    count: int = 1
    threads: int | None = 1

    def __post_init__(self) -> None:
        check_positive_int(self.processes, "processes")
        check_positive_int(self.count, "count")
        index = self.index
        if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < self.count:
            raise ValueCheckError(f"index must be an int in [0, {self.count}), got {self.index!r}")
        if self.threads is not None:
            check_positive_int(self.threads, "threads")


def field_path(seed: int, view_index: int) -> str:
    """The file of one (subject seed, view) relative to the cache folder.

    Args:
        seed: the subject seed.
        view_index: the view's index among the subject's views.

    Returns:
        the relative path, with ``/`` separators.

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
    albedo = field.albedo if field.gbuffer is None else field.gbuffer.albedo
    skin = field.skin if field.gbuffer is None else field.gbuffer.subsurface
    if albedo is not None and skin is not None:  # for the uniform-white check (calibration.py)
        tensors["albedo"] = albedo.to(torch.float16).contiguous()
        tensors["skin"] = skin.to(torch.float16).contiguous()
    metadata = {
        "format": FORMAT,
        "camera": json.dumps(field.camera.to_dict()),
        "subject_seed": str(int(field.subject_seed)),
        "lighting_size": str(field.lighting_size),
        "meta": json.dumps(field.meta),
    }
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, lambda tmp: safetensors.torch.save_file(tensors, str(tmp), metadata=metadata))
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

    Returns:
        the field, dense or compact; its ``field`` is bfloat16 (as stored), its ``alpha``, ``albedo`` and
        ``skin`` float32 (``albedo`` and ``skin`` ``None`` in files written without them).

    Raises:
        HDRIOError: the file is missing, unreadable or not a field of this format (the message names it).

    Examples:
        >>> import tempfile
        >>> rf = ReflectanceField(torch.zeros(3, 4, 4, dtype=torch.bfloat16), torch.ones(1, 2, 2),
        ...                       torch.tensor([0.0, 0.0, 2.0, 2.0]), Camera(30.0, 1.0, 0.0, 0.0, size=2), 7)
        >>> with tempfile.TemporaryDirectory() as d:
        ...     _ = write_field(f"{d}/a.safetensors", rf)
        ...     back = read_field(f"{d}/a.safetensors", dense=False)
        >>> back.subject_seed, back.field.dtype, back.camera.size
        (7, torch.bfloat16, 2)
    """
    path = Path(path)
    try:
        with safe_open(str(path), framework="pt") as fh:
            metadata = fh.metadata() or {}
            if metadata.get("format") not in READABLE_FORMATS:
                raise HDRIOError(f"{path} is not a reflectance field of format {FORMAT!r} (or v1)")
            names = [k for k in fh.keys() if not (mmap and k == "field")]  # noqa: SIM118 - no iterator
            tensors = {k: fh.get_tensor(k) for k in names}
        if mmap:
            tensors["field"] = map_bfloat16(path, "field")
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
        albedo=tensors["albedo"].float() if "albedo" in tensors else None,
        skin=tensors["skin"].float() if "skin" in tensors else None,
    )
    return field.to_dense() if dense else field


def map_bfloat16(path: str | os.PathLike, name: str) -> torch.Tensor:
    """Tensor ``name`` of a safetensors file, mapped (copy-on-write) rather than read; bfloat16 only.

    Args:
        path: the safetensors file.
        name: the tensor's name in it.

    Returns:
        the tensor, backed by a :class:`numpy.memmap` of the file: nothing is read until it is used.

    Raises:
        HDRIOError: the tensor is not bfloat16.
        KeyError: no tensor of that name.

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as d:
        ...     safetensors.torch.save_file({"x": torch.ones(2, 3, dtype=torch.bfloat16)}, f"{d}/a.safetensors")
        ...     x = map_bfloat16(f"{d}/a.safetensors", "x")
        ...     shape, total = tuple(x.shape), float(x.sum())
        ...     del x
        >>> shape, total
        ((2, 3), 6.0)
    """
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

    Args:
        out_dir: the cache folder.

    Returns:
        ``{"format": ..., "entries": [...]}``, entries sorted by ``(subject_seed, view_index)``.

    Raises:
        HDRIOError: a manifest file is unreadable or not JSON.

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as d:
        ...     manifest = read_manifest(d)
        >>> manifest["format"] == MANIFEST_FORMAT, manifest["entries"]
        (True, [])
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

    Args:
        items: the items to share out (subject seeds).
        worker_index: this worker's index, in ``[0, worker_count)``.
        worker_count: the number of workers, positive.

    Returns:
        the items ``worker_index``, ``worker_index + worker_count``, ... in order.

    Raises:
        ValueCheckError: ``worker_count`` is not positive, or ``worker_index`` not in ``[0, worker_count)``.

    Examples:
        >>> shard(list(range(7)), 1, 3)
        [1, 4]
    """
    check_positive_int(worker_count, "worker_count")
    if isinstance(worker_index, bool) or not isinstance(worker_index, int) or not 0 <= worker_index < worker_count:
        raise ValueCheckError(f"worker_index must be an int in [0, {worker_count}), got {worker_index!r}")
    return list(items[worker_index::worker_count])


def _file_ok(entry: dict[str, Any], out_dir: Path) -> bool:
    path = out_dir / entry["path"]
    return path.is_file() and path.stat().st_size == entry["bytes"] and sha256_file(path) == entry["sha256"]


def _entry_ok(entry: dict[str, Any] | None, out_dir: Path, settings: dict[str, Any],
              camera: Camera | None) -> bool:
    """Whether a manifest entry is a finished render with these settings (and camera, for fixed views) whose
    file is intact. Sampled views are checked by their sampler settings (the camera needs the subject)."""
    if entry is None or any(entry.get(k) != v for k, v in settings.items()):
        return False
    if entry.get("renderer") != settings.get("renderer"):  # explicit renderer settings, or none
        return False
    if camera is not None and entry.get("camera") != camera.to_dict():
        return False
    return _file_ok(entry, out_dir)


def _resolve_source(source: Any, assets: str | os.PathLike | None = None) -> Any:
    """A subject source from an object with ``name`` and ``sample``, or from its name."""
    if isinstance(source, str):
        return subject_source(source, assets=assets)
    if not (hasattr(source, "sample") and hasattr(source, "name")):
        raise TypeCheckError(f"source must be a SubjectSource (name and sample(seed)) or its name, got "
                             f"{type(source).__name__}")
    return source


def _params_summary(params: dict[str, Any]) -> dict[str, Any]:
    """The scalar parameters of a subject (strings, ints, bools, floats to 4 digits), for the manifest."""
    out: dict[str, Any] = {}
    for key, value in sorted((params or {}).items()):
        if isinstance(value, (bool, int, str)) or value is None:
            out[str(key)] = value
        elif isinstance(value, float):
            out[str(key)] = round(value, 4)
    return out


def _peak_rss_mb() -> float:
    """This process's peak resident set size, MB (Linux and macOS)."""
    import resource  # lazy: a Unix-only module, needed for the manifest's memory figure only

    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return round(peak / (1e6 if sys.platform == "darwin" else 1e3), 1)


def _render_subjects(job: dict[str, Any], report: Any) -> None:
    """Render the subject-views of ``job["todo"]`` ({seed: [view indices]}) into one worker manifest.

    Each subject is built once and all its views rendered in this process; ``report(kind, payload)`` is told
    of every finished view (``"view"``, the entry).
    """
    out_dir = Path(job["out_dir"])
    if job["threads"] is not None:
        torch.set_num_threads(job["threads"])
    own_file = out_dir / job["manifest"]
    own = {(e["subject_seed"], e["view_index"]): e for e in _read_manifest_file(own_file)}
    source = job["source"]
    for seed, view_indices in job["todo"]:
        t0 = time.perf_counter()
        subject = source.sample(seed)
        subject_seconds = time.perf_counter() - t0
        views = job["views"]
        if isinstance(views, SampledViews):
            cameras = sample_views(seed, views.per_subject, size=views.size, landmarks=subject.face_landmarks,
                                   fraction=views.fraction)
        else:
            cameras = list(views.cameras)
        for view in view_indices:
            rf = render_olat(subject, cameras[view], settings=job["renderer"], variant=job["variant"],
                             threads=job["threads"])
            rf.meta["source"] = getattr(source, "name", None)
            rel = field_path(seed, view)
            info = write_field(out_dir / rel, rf)
            albedo = getattr(subject, "face_albedo", None)
            entry = {
                "subject_seed": seed,
                "view_index": view,
                "camera": cameras[view].to_dict(),
                "path": rel,
                **info,
                "layout": "compact",
                **job["settings"],
                "render_seconds": round(float(rf.meta["render_seconds"]), 3),
                "subject_seconds": round(subject_seconds, 3),
                "peak_rss_mb": _peak_rss_mb(),
                "spp": rf.meta["spp"],
                "variant": rf.meta["variant"],
                "split": getattr(subject, "split", None),
                "skin_tone": getattr(subject, "skin_tone", None),
                "face_albedo": None if albedo is None else [round(float(c), 4) for c in albedo],
                "params": _params_summary(getattr(subject, "params", {})),
                "written": time.time(),
            }
            own[(seed, view)] = entry
            _write_json(own_file, {"format": MANIFEST_FORMAT, "entries": [own[k] for k in sorted(own)]})
            report("view", entry)
            subject_seconds = 0.0  # counted with the subject's first view


def _worker_process(job: dict[str, Any], queue: Any) -> None:
    """A spawned worker: one torch and one Dr.Jit thread, reporting to the parent through ``queue``."""
    torch.set_num_threads(1)
    try:
        _render_subjects(job, lambda kind, payload: queue.put((kind, payload)))
    except BaseException as exc:  # noqa: BLE001 - reported to the parent, which raises
        queue.put(("error", f"{type(exc).__name__}: {exc}\n{traceback.format_exc()}"))
        raise SystemExit(1) from None
    queue.put(("exit", None))


class _ViewProgress:
    """``subject-views: 3/8 (38 %), 12.1 s/view, ETA 1 min`` on stderr, at most once a second and at the end."""

    def __init__(self, total: int, enabled: bool) -> None:
        self.total, self.done, self.enabled = total, 0, enabled and total > 0
        self.t0 = self.last = time.perf_counter()
        if self.enabled:
            self._show()

    def update(self, n: int = 1) -> None:
        self.done += n
        now = time.perf_counter()
        if self.enabled and (now - self.last >= 1.0 or self.done == self.total):
            self.last = now
            self._show()

    def _show(self) -> None:
        elapsed = time.perf_counter() - self.t0
        text = f"\rsubject-views: {self.done}/{self.total} ({100 * self.done // self.total} %)"
        if self.done:
            rate = elapsed / self.done
            left = rate * (self.total - self.done)
            text += f", {rate:.1f} s/view, ETA {_duration(left)}"
        print(text, end="\n" if self.done == self.total else "", file=sys.stderr, flush=True)


def _duration(seconds: float) -> str:
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def _cache_settings(source: Any, renderer: OnePass | Reference | Auto, views: FixedViews | SampledViews
                    ) -> dict[str, Any]:
    """The settings that a manifest entry must match to be reused (module docstring)."""
    settings = {"source": getattr(source, "name", None), "spp_requested": renderer.spp,
                "lighting_size": renderer.lighting_size, "views": views.label, "size": views.size}
    if not (isinstance(renderer, Auto) and renderer.seed == 0):  # what the keys above do not pin down
        settings["renderer"] = renderer.to_dict()
    return settings


def build_cache(
    source: Any,
    seeds: Iterable[int],
    *,
    out_dir: str | os.PathLike,
    renderer: OnePass | Reference | Auto | None = None,
    views: FixedViews | SampledViews | None = None,
    workers: Workers | None = None,
    variant: str | None = None,
    progress: bool = True,
    summary: bool = False,
) -> dict[str, Any]:
    r"""Render and cache the reflectance fields of subjects x views; resumable, sharded, in worker processes.

    Every subject is built once (``source.sample(seed)``) and all its views are rendered in the same process.
    The subjects that this machine renders (its share of the seeds, :class:`Workers`) and that still lack a
    view (not in the manifest, intact, with the same settings) are dealt round robin to the worker
    processes; process ``j`` writes each field (:func:`write_field`) and records it in its manifest
    ``manifest.w<index * processes + j>of<count * processes>.json`` right away, and finally all the manifests
    are merged into ``manifest.json``. So rerunning resumes, and machines can share one folder.

    Args:
        source: a :class:`~kornia_ilum_lab.synth.lightstage.subjects.SubjectSource` or its name (``"mannequin"``,
            ``"makehuman"``); it is pickled to the worker processes.
        seeds: subject seeds.
        out_dir: the cache folder (created).
        renderer: the renderer's settings (:mod:`~kornia_ilum_lab.synth.lightstage.settings`, as for
            :func:`~.olat.render_olat`); ``None``: ``Auto()``, the one-pass renderer at its defaults where the
            Mitsuba variant is vectorised.
        views: :class:`SampledViews` (random views per subject, framed for its own landmarks) or
            :class:`FixedViews` (the same cameras for every subject), with the image side; ``None``:
            ``SampledViews()``, 4 views at 192 x 192.
        workers: processes, this machine's share and threads (:class:`Workers`); ``None``: ``Workers()``, two
            one-thread processes rendering every seed.
        variant: the Mitsuba variant (:func:`~.materials.select_mitsuba_variant`).
        progress: a progress bar of subject-views with an ETA on stderr.
        summary: print a summary at the end (entries, wall time, disk bytes, render seconds, peak memory).

    Returns:
        the merged manifest (:func:`read_manifest`) with ``"run"``: this call's ``rendered`` count,
        ``wall_seconds`` and the cache's ``bytes``.

    Raises:
        TypeCheckError, ValueCheckError: bad arguments. IlumError: a worker process failed (with its error).

    Examples:
        >>> shard([1, 2, 3, 4, 5], 0, 2)  # the subjects that machine 0 of 2 renders
        [1, 3, 5]
    """
    renderer = Auto() if renderer is None else renderer
    views = SampledViews() if views is None else views
    workers = Workers() if workers is None else workers
    if not isinstance(renderer, (OnePass, Reference, Auto)):
        raise TypeCheckError(f"renderer must be OnePass, Reference or Auto, got {type(renderer).__name__}")
    if not isinstance(views, (FixedViews, SampledViews)):
        raise TypeCheckError(f"views must be FixedViews or SampledViews, got {type(views).__name__}")
    if not isinstance(workers, Workers):
        raise TypeCheckError(f"workers must be Workers, got {type(workers).__name__}")
    if not isinstance(out_dir, (str, os.PathLike)):
        raise TypeCheckError(f"out_dir must be a folder path, got {type(out_dir).__name__}")
    source = _resolve_source(source)
    out_dir = Path(out_dir)
    seeds = list(dict.fromkeys(int(s) for s in seeds))
    mine = shard(seeds, workers.index, workers.count)
    cameras = views.cameras if isinstance(views, FixedViews) else None
    settings = _cache_settings(source, renderer, views)

    t0 = time.perf_counter()
    known = {(e["subject_seed"], e["view_index"]): e for e in read_manifest(out_dir)["entries"]}
    todo = []
    for seed in mine:
        left = [v for v in range(views.count)
                if not _entry_ok(known.get((seed, v)), out_dir, settings, None if cameras is None else cameras[v])]
        if left:
            todo.append((seed, left))
    total = sum(len(v) for _, v in todo)
    bar = _ViewProgress(total, progress)
    procs = min(workers.processes, len(todo)) if todo else 0
    jobs = [{
        "source": source, "out_dir": str(out_dir), "todo": todo[j::max(procs, 1)], "views": views,
        "renderer": renderer, "variant": variant, "threads": workers.threads if procs <= 1 else 1,
        "settings": settings,
        "manifest": _manifest_name(workers.index * workers.processes + j, workers.count * workers.processes),
    } for j in range(procs)]
    out_dir.mkdir(parents=True, exist_ok=True)
    if procs == 1 and workers.processes == 1:
        _render_subjects(jobs[0], lambda kind, payload: bar.update())
    elif procs:
        _run_processes(jobs, bar)
    manifest = read_manifest(out_dir)
    _write_json(out_dir / "manifest.json", manifest)
    entries = manifest["entries"]
    disk = sum(int(e["bytes"]) for e in entries)
    manifest["run"] = {"rendered": total, "wall_seconds": round(time.perf_counter() - t0, 2), "bytes": disk}
    if summary:
        print(cache_summary(manifest))
    return manifest


def _run_processes(jobs: list[dict[str, Any]], bar: _ViewProgress) -> None:
    """Run each job in a spawned process; forward their progress; raise the first failure."""
    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    procs = [ctx.Process(target=_worker_process, args=(job, queue), daemon=True) for job in jobs]
    for p in procs:
        p.start()
    errors: list[str] = []
    running = len(procs)
    try:
        while running:
            try:
                kind, payload = queue.get(timeout=0.5)
            except queue_module.Empty:
                if not any(p.is_alive() for p in procs):
                    break
                continue
            if kind == "view":
                bar.update()
            elif kind == "error":
                errors.append(payload)
                running -= 1
            elif kind == "exit":
                running -= 1
    finally:
        for p in procs:
            p.join(timeout=None if not errors else 5)
            if p.is_alive():
                p.terminate()
    if errors:
        raise IlumError(f"a cache worker process failed: {errors[0].splitlines()[0]}\n{errors[0]}")
    failed = [p.exitcode for p in procs if p.exitcode]
    if failed:
        raise IlumError(f"a cache worker process died (exit code {failed[0]})")


def cache_summary(manifest: dict[str, Any]) -> str:
    """One paragraph about a cache: entries, subjects, eval share, disk bytes, render seconds, peak memory.

    Args:
        manifest: a manifest of :func:`read_manifest` (or :func:`build_cache`); ``manifest["run"]``, when
            there, adds what the last run rendered.

    Returns:
        the text: a first line for the cache, a second (when it has entries) for the median subject-view.

    Examples:
        >>> manifest = {"entries": [{"subject_seed": 3, "view_index": 0, "split": "eval", "bytes": 2_000_000,
        ...                          "render_seconds": 1.0}]}
        >>> cache_summary(manifest).splitlines()[0]
        '1 subject-views of 1 subjects (1 eval subjects), 2.0 MB on disk'
    """
    entries = manifest["entries"]
    subjects = {e["subject_seed"] for e in entries}
    evals = {e["subject_seed"] for e in entries if e.get("split") == "eval"}
    disk = sum(int(e["bytes"]) for e in entries)
    text = (f"{len(entries)} subject-views of {len(subjects)} subjects ({len(evals)} eval subjects), "
            f"{disk / 1e6:.1f} MB on disk")
    run = manifest.get("run")
    if run:
        text += f"; this run rendered {run['rendered']} in {run['wall_seconds']:.1f} s"
    if entries:
        seconds = [float(e["render_seconds"]) for e in entries]
        rss = [float(e["peak_rss_mb"]) for e in entries if "peak_rss_mb" in e]
        text += (f"\nper subject-view: render median {statistics.median(seconds):.1f} s (max {max(seconds):.1f} s), "
                 f"{statistics.median(int(e['bytes']) for e in entries) / 1e6:.2f} MB")
        if rss:
            text += f"; worker peak RSS max {max(rss):.0f} MB"
    return text
