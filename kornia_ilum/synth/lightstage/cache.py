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

``manifest.json`` is ``{"format": ..., "entries": [...]}``; each entry (format v2) has ``subject_seed``,
``view_index``, ``camera``, ``path`` (relative to the folder), ``sha256``, ``shape``, ``dtype``, ``bytes``, the
settings (``source``, ``spp_requested``, ``spp``, ``lighting_size``, ``size``, ``views``: ``"fixed"`` or
``"sample_views(n=4)"``, ``variant``), the costs (``render_seconds`` of the view, ``subject_seconds`` to build
the subject, counted on its first view, ``peak_rss_mb`` of the worker process so far), and the subject's
``split``, ``skin_tone``, ``face_albedo`` and ``params`` (its scalar parameters). v2 field files equal v1's
plus ``meta["source"]``; :func:`read_field` reads both. :func:`read_manifest` returns the union of ``manifest.json`` and
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
from kornia_ilum.synth.lightstage.olat import ReflectanceField, render_olat
from kornia_ilum.synth.lightstage.scene import Camera

__all__ = [
    "DEFAULT_VIEWS",
    "FORMAT",
    "READABLE_FORMATS",
    "build_cache",
    "cache_summary",
    "field_path",
    "read_field",
    "read_manifest",
    "shard",
    "write_field",
]

FORMAT = "kornia_ilum.olat.v2"
MANIFEST_FORMAT = "kornia_ilum.olat-cache.v2"
#: Field formats that :func:`read_field` reads: v1 files have the same tensors, without ``meta["source"]``.
READABLE_FORMATS = ("kornia_ilum.olat.v1", FORMAT)

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
            if metadata.get("format") not in READABLE_FORMATS:
                raise HDRIOError(f"{path} is not a reflectance field of format {FORMAT!r} (or v1)")
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


def _file_ok(entry: dict[str, Any], out_dir: Path) -> bool:
    path = out_dir / entry["path"]
    return path.is_file() and path.stat().st_size == entry["bytes"] and sha256_file(path) == entry["sha256"]


def _entry_ok(entry: dict[str, Any] | None, out_dir: Path, settings: dict[str, Any],
              camera: Camera | None) -> bool:
    """Whether a manifest entry is a finished render with these settings (and camera, for fixed views) whose
    file is intact. Sampled views are checked by their sampler settings (the camera needs the subject)."""
    if entry is None or any(entry.get(k) != v for k, v in settings.items()):
        return False
    if camera is not None and entry.get("camera") != camera.to_dict():
        return False
    return _file_ok(entry, out_dir)


def _resolve_source(source: Any, assets: str | os.PathLike | None = None) -> Any:
    """A subject source from an object with ``name`` and ``sample``, or from its name."""
    if isinstance(source, str):
        from kornia_ilum.synth.lightstage.subjects import subject_source

        return subject_source(source, assets=assets)
    if not (hasattr(source, "sample") and hasattr(source, "name")):
        raise TypeCheckError(f"source must be a SubjectSource (name and sample(seed)) or its name, got "
                             f"{type(source).__name__}")
    return source


class _LegacyMannequins:
    """:func:`~kornia_ilum.synth.lightstage.subjects.make_subject`, looked up at each call (tests replace it)."""

    name = "mannequin"

    def sample(self, seed: int) -> Any:
        from kornia_ilum.synth.lightstage import subjects

        return subjects.make_subject(seed)


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
    import resource
    import sys

    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return round(peak / (1e6 if sys.platform == "darwin" else 1e3), 1)


def _render_subjects(job: dict[str, Any], report: Any) -> None:
    """Render the subject-views of ``job["todo"]`` ({seed: [view indices]}) into one worker manifest.

    Each subject is built once and all its views rendered in this process; ``report(kind, payload)`` is told
    of every finished view (``"view"``, the entry).
    """
    import dataclasses as dc

    from kornia_ilum.synth.lightstage.scene import sample_views

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
        if job["views"] is None:
            cameras = sample_views(seed, job["views_per_subject"], job["size"], landmarks=subject.face_landmarks)
        else:
            cameras = [dc.replace(v, size=job["size"]) for v in job["views"]]
        for view in view_indices:
            rf = render_olat(subject, cameras[view], lighting_size=job["lighting_size"], spp=job["spp"],
                             variant=job["variant"], threads=job["threads"])
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
    import traceback

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
        import sys

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


def _is_legacy_call(source: Any, out_dir: Any) -> bool:
    """``build_cache(out_dir, seeds[, views])``, the v1 call: a folder first, the cameras (or nothing) third."""
    if not isinstance(source, (str, os.PathLike)):
        return False
    if out_dir is None:
        return not (isinstance(source, str) and source in ("mannequin", "makehuman"))
    return not isinstance(out_dir, (str, os.PathLike))


def build_cache(
    source: Any = "mannequin",
    seeds: Iterable[int] = (),
    out_dir: str | os.PathLike | Sequence[Camera] | None = None,
    *,
    views: Sequence[Camera] | None = None,
    views_per_subject: int = 4,
    size: int = 192,
    spp: int | None = None,
    lighting_size: int = 32,
    workers: int = 2,
    worker_index: int = 0,
    worker_count: int = 1,
    variant: str | None = None,
    threads: int | None = 1,
    progress: bool = True,
    summary: bool = False,
) -> dict[str, Any]:
    r"""Render and cache the reflectance fields of subjects x views; resumable, sharded, in worker processes.

    Every subject is built once (``source.sample(seed)``) and all its views are rendered in the same process.
    Views: ``views_per_subject`` random views per subject (:func:`~.scene.sample_views`, framed for the
    subject's own landmarks), or the fixed cameras ``views``. The subjects that this machine renders (every
    ``worker_count``-th seed from ``worker_index``, :func:`shard`) and that still lack a view (not in the
    manifest, intact, with the same settings) are dealt round robin to ``workers`` processes; process ``j``
    writes each field (:func:`write_field`) and records it in its manifest
    ``manifest.w<worker_index * workers + j>of<worker_count * workers>.json`` right away, and finally all the
    manifests are merged into ``manifest.json``. So rerunning resumes, and machines can share one folder.

    ``workers > 1`` spawns that many processes (``multiprocessing`` spawn), each with one torch thread and one
    Dr.Jit thread: two one-thread processes render 1.15 to 1.7 times as fast as one two-thread process.
    ``workers = 1`` renders in this process with ``threads`` threads.

    Args:
        source: a :class:`~kornia_ilum.synth.lightstage.subjects.SubjectSource` or its name (``"mannequin"``,
            ``"makehuman"``); it is pickled to the worker processes.
        seeds: subject seeds.
        out_dir: the cache folder (created).
        views: fixed cameras (view index = position); ``None``: random views.
        views_per_subject: random views per subject.
        size: image side; replaces each view's ``size``.
        spp: camera samples per pixel (:func:`~.olat.render_olat`); ``None``: the renderer's default.
        lighting_size: the mirror-ball side ``S`` of the lighting basis.
        workers: render processes on this machine.
        worker_index: this machine's share, in ``[0, worker_count)``.
        worker_count: machines sharing the work.
        variant: the Mitsuba variant (:func:`~.materials.select_mitsuba_variant`).
        threads: with ``workers = 1``, torch and Dr.Jit threads (``None``: leave them); processes use 1.
        progress: a progress bar of subject-views with an ETA on stderr.
        summary: print a summary at the end (entries, wall time, disk bytes, render seconds, peak memory).

    Returns:
        the merged manifest (:func:`read_manifest`) with ``"run"``: this call's ``rendered`` count,
        ``wall_seconds`` and the cache's ``bytes``.

    Raises:
        TypeCheckError, ValueCheckError: bad arguments. IlumError: a worker process failed (with its error).

    Note:
        The call ``build_cache(out_dir, seeds, views, ...)`` of format v1 still works: a path first and the
        cameras third means the mannequins, those views, and ``workers = 1``.

    Examples:
        >>> shard([1, 2, 3, 4, 5], 0, 2)  # the subjects that machine 0 of 2 renders
        [1, 3, 5]
    """
    if _is_legacy_call(source, out_dir):
        source, out_dir, views = _LegacyMannequins(), source, DEFAULT_VIEWS if out_dir is None else out_dir
        workers = 1
    if out_dir is None:
        raise ValueCheckError("out_dir is required")
    source = _resolve_source(source)
    out_dir = Path(out_dir)
    if views is not None:
        views = tuple(views)
        if not views or not all(isinstance(v, Camera) for v in views):
            raise TypeCheckError("views must be a non-empty sequence of Camera")
    check_positive_int(size, "size")
    if spp is not None:
        check_positive_int(spp, "spp")
    check_positive_int(lighting_size, "lighting_size")
    check_positive_int(views_per_subject, "views_per_subject")
    check_positive_int(workers, "workers")
    seeds = list(dict.fromkeys(int(s) for s in seeds))
    mine = shard(seeds, worker_index, worker_count)
    n_views = len(views) if views is not None else views_per_subject
    cameras = None if views is None else [dataclasses.replace(v, size=size) for v in views]
    sampler = "fixed" if views is not None else f"sample_views(n={views_per_subject})"
    settings = {"source": getattr(source, "name", None), "spp_requested": spp, "lighting_size": lighting_size,
                "views": sampler, "size": size}

    t0 = time.perf_counter()
    known = {(e["subject_seed"], e["view_index"]): e for e in read_manifest(out_dir)["entries"]}
    todo = []
    for seed in mine:
        left = [v for v in range(n_views)
                if not _entry_ok(known.get((seed, v)), out_dir, settings, None if cameras is None else cameras[v])]
        if left:
            todo.append((seed, left))
    total = sum(len(v) for _, v in todo)
    bar = _ViewProgress(total, progress)
    procs = min(workers, len(todo)) if todo else 0
    jobs = [{
        "source": source, "out_dir": str(out_dir), "todo": todo[j::max(procs, 1)], "views": cameras,
        "views_per_subject": views_per_subject, "size": size, "spp": spp, "lighting_size": lighting_size,
        "variant": variant, "threads": threads if procs <= 1 else 1, "settings": settings,
        "manifest": _manifest_name(worker_index * max(workers, 1) + j, worker_count * max(workers, 1)),
    } for j in range(procs)]
    out_dir.mkdir(parents=True, exist_ok=True)
    if procs == 1 and workers == 1:
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
    import multiprocessing as mp
    import queue as queue_module

    from kornia_ilum.core.errors import IlumError

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
    """One paragraph about a cache: entries, subjects, eval share, disk bytes, render seconds, peak memory."""
    import statistics

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
