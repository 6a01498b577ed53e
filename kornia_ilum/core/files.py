"""File helpers: atomic writes (a file appears complete under its name, or not at all) and file digests."""

from __future__ import annotations

import hashlib
import os
import uuid
from collections.abc import Callable
from pathlib import Path

__all__ = ["atomic_write", "sha256_file"]


def atomic_write(path: str | os.PathLike[str], write: Callable[[Path], None]) -> None:
    """Call ``write(tmp)`` for a hidden temporary file beside ``path``, flush it to disk, move it to ``path``.

    The temporary file is in the same folder (so the rename is atomic) and keeps ``path``'s extension (so
    writers that pick a format by extension, such as OpenImageIO, pick the right one). It is removed if
    ``write`` fails, and ``path`` is then left as it was. The file gets the default permissions (umask), even
    where ``write`` makes its own private file (safetensors writes mode 0600).

    Args:
        path: the destination; its folder must exist.
        write: writes the whole file at the path it is given.

    Returns:
        ``None``; the file is at ``path`` when it returns.

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as d:
        ...     atomic_write(Path(d) / "a.txt", lambda tmp: tmp.write_text("done"))
        ...     print((Path(d) / "a.txt").read_text(), len(os.listdir(d)))
        done 1
    """
    path = Path(path)
    tmp = path.with_name(f".{path.stem}.{uuid.uuid4().hex[:12]}.tmp{path.suffix}")
    try:
        with open(tmp, "x"):  # created empty first: the mode the umask gives, whatever ``write`` then does
            pass
        mode = tmp.stat().st_mode & 0o777
        write(tmp)
        os.chmod(tmp, mode)
        with open(tmp, "rb") as f:
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def sha256_file(path: str | os.PathLike[str]) -> str:
    """The SHA-256 hex digest of a file's bytes, read in blocks (weights, cached fields).

    Args:
        path: the file.

    Returns:
        the digest, 64 lowercase hex digits.

    Examples:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as d:
        ...     (Path(d) / "a.txt").write_bytes(b"abc")
        ...     sha256_file(Path(d) / "a.txt")[:16]
        3
        'ba7816bf8f01cfea'
    """
    with open(path, "rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()
