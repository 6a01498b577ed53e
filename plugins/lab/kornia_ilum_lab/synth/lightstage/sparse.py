r"""The sparse-relighting sidecar of a cached reflectance field: the training data relit sparsely.

:func:`~kornia_ilum.render.relight_sparse` needs the field light-major (a light's column as one row) and its
low-rank factors (:func:`~kornia_ilum.render.prepare_sparse`). The cache stores fields channel-major, and
transposing one on the fly costs more than relighting it densely (docs/skipping.rst), so :func:`write_sparse`
writes that preparation once, beside the field: ``view.safetensors`` gets ``view.sparse.safetensors`` with the
light-major ``rows`` and the ``basis`` of the low rank (both bfloat16, memory-mapped on read: only the rows
a lighting keeps are read), the lights' ``norms`` and the singular ``directions``. :func:`read_sparse` maps it back
as a :class:`~kornia_ilum.render.SparseField`; the portrait dataset uses it with
``PortraitConfig(relight_eps=...)``. The sidecar records the field file's size and modification time, and a
stale one is refused.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import safetensors.torch
import torch
from safetensors import safe_open

from kornia_ilum.core.check import check_positive_int
from kornia_ilum.core.errors import HDRIOError
from kornia_ilum.core.files import atomic_write
from kornia_ilum.render import SPARSE_RANK, SparseField, prepare_sparse
from kornia_ilum_lab.synth.lightstage.cache import map_bfloat16, read_field, read_manifest

__all__ = ["SPARSE_FORMAT", "read_sparse", "sparse_path", "write_sparse", "write_sparse_cache"]

#: The sidecar's format tag (v1, with light clusters instead of the low rank, is refused: write it again).
SPARSE_FORMAT = "kornia_ilum.sparse_field.v2"


def sparse_path(field_path: str | os.PathLike) -> Path:
    """The sidecar of a field file: ``view.safetensors`` -> ``view.sparse.safetensors``.

    Args:
        field_path: the field's file.

    Returns:
        the sidecar's path, beside it.

    Examples:
        >>> sparse_path("cache/s0001_v0.safetensors").as_posix()
        'cache/s0001_v0.sparse.safetensors'
    """
    path = Path(field_path)
    return path.with_name(path.name.removesuffix(".safetensors") + ".sparse.safetensors")


def _stamp(field_path: Path) -> str:
    stat = field_path.stat()
    return f"{stat.st_size}:{stat.st_mtime_ns}"


def write_sparse(field_path: str | os.PathLike, rank: int = SPARSE_RANK) -> Path:
    r"""Write the sparse-relighting sidecar of one cached field, atomically (module docstring).

    Args:
        field_path: the field's file (:func:`~kornia_ilum_lab.synth.lightstage.write_field`).
        rank: the rank of the lights not kept (:func:`~kornia_ilum.render.prepare_sparse`).

    Returns:
        the sidecar's path (:func:`sparse_path`).

    Raises:
        HDRIOError: the field cannot be read.

    Examples:
        >>> import tempfile
        >>> from kornia_ilum_lab.synth.lightstage import Camera, ReflectanceField, write_field
        >>> rf = ReflectanceField(torch.rand(3, 4, 16).bfloat16(), torch.ones(1, 2, 2),
        ...                       torch.tensor([0.0, 0.0, 2.0, 2.0]), Camera(30.0, 1.0, 0.0, 0.0, size=2), 7)
        >>> with tempfile.TemporaryDirectory() as d:
        ...     _ = write_field(f"{d}/v.safetensors", rf)
        ...     name = write_sparse(f"{d}/v.safetensors", rank=2).name
        >>> name
        'v.sparse.safetensors'
    """
    check_positive_int(rank, "rank")
    field_path = Path(field_path)
    field = read_field(field_path, dense=False, mmap=True)
    prepared = prepare_sparse(field.field, rank)
    tensors = {"rows": prepared.rows.contiguous(), "basis": prepared.basis.contiguous(),
               "norms": prepared.norms.contiguous(), "directions": prepared.directions.contiguous()}
    metadata = {"format": SPARSE_FORMAT, "rank": str(rank), "field": field_path.name,
                "field_stamp": _stamp(field_path), "field_shape": json.dumps(list(field.field.shape))}
    target = sparse_path(field_path)
    atomic_write(target, lambda tmp: safetensors.torch.save_file(tensors, str(tmp), metadata=metadata))
    return target


def read_sparse(field_path: str | os.PathLike) -> SparseField:
    r"""Map the sidecar of a cached field back as a :class:`~kornia_ilum.render.SparseField`.

    The rows and the basis are memory-mapped; the field itself is not read (``SparseField.field`` is a
    ``meta`` tensor of its shape, enough for :func:`~kornia_ilum.render.relight_sparse` at ``eps > 0``).

    Args:
        field_path: the field's file (not the sidecar's).

    Returns:
        the prepared field.

    Raises:
        HDRIOError: no sidecar, or one written for another version of the field file (run
            :func:`write_sparse_cache` again).

    Examples:
        >>> import tempfile
        >>> from kornia_ilum.render import relight_sparse
        >>> from kornia_ilum_lab.synth.lightstage import Camera, ReflectanceField, write_field
        >>> rf = ReflectanceField(torch.rand(3, 4, 16).bfloat16(), torch.ones(1, 2, 2),
        ...                       torch.tensor([0.0, 0.0, 2.0, 2.0]), Camera(30.0, 1.0, 0.0, 0.0, size=2), 7)
        >>> with tempfile.TemporaryDirectory() as d:
        ...     _ = write_field(f"{d}/v.safetensors", rf)
        ...     _ = write_sparse(f"{d}/v.safetensors", rank=2)
        ...     prepared = read_sparse(f"{d}/v.safetensors")
        ...     relit = relight_sparse(prepared, torch.ones(2, 12, 3), eps=0.1)  # the 12 lights of a 4 x 4 ball
        ...     del prepared
        >>> tuple(relit.shape)
        (2, 3, 4)
    """
    field_path = Path(field_path)
    path = sparse_path(field_path)
    if not path.is_file():
        raise HDRIOError(f"no sparse-relighting sidecar {path}: write it with "
                         "kornia_ilum_lab.synth.lightstage.write_sparse_cache(CACHE)")
    try:
        with safe_open(str(path), framework="pt") as fh:
            metadata = fh.metadata() or {}
            norms, directions = fh.get_tensor("norms"), fh.get_tensor("directions")
    except Exception as exc:  # safetensors' own error types
        raise HDRIOError(f"cannot read the sparse-relighting sidecar {path}: {exc}") from exc
    if metadata.get("format") != SPARSE_FORMAT or metadata.get("field_stamp") != _stamp(field_path):
        raise HDRIOError(f"the sparse-relighting sidecar {path} does not match {field_path.name} (another format "
                         "or an older field): write it again with write_sparse_cache")
    shape = json.loads(metadata["field_shape"])
    field = torch.empty(shape, dtype=torch.bfloat16, device="meta")
    return SparseField(field, map_bfloat16(path, "rows"), norms, map_bfloat16(path, "basis"), directions)


def write_sparse_cache(cache: str | os.PathLike, rank: int = SPARSE_RANK, split: str | None = None) -> int:
    r"""Write the sidecar of every field of a cache that lacks an up-to-date one (module docstring); an
    up-to-date sidecar is kept whatever its ``rank``.

    Args:
        cache: the cache folder (:func:`~kornia_ilum_lab.synth.lightstage.build_cache`).
        rank: the rank of the lights not kept.
        split: only the subjects of this split (``"train"``, ``"eval"``); ``None``: all.

    Returns:
        how many sidecars it wrote.

    Raises:
        HDRIOError: the cache's manifest or a field cannot be read.

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as d:
        ...     write_sparse_cache(d)  # an empty cache: nothing to write
        0
    """
    written = 0
    for entry in read_manifest(cache)["entries"]:
        if split is not None and entry.get("split") != split:
            continue
        field_path = Path(cache) / entry["path"]
        try:
            read_sparse(field_path)
            continue  # up to date
        except HDRIOError:
            pass
        write_sparse(field_path, rank)
        written += 1
    return written
