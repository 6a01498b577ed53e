r"""Where a figure comes from: a stamp inside the image file that names the command that made it, the code it
shows (by fingerprint) and the data it plots, so that a test can tell a figure made by other code.

A figure of the docs shows what some code makes: a contact sheet shows the light stage, a curve shows a log
through its plotting code. :func:`stamp_figure` writes into a PNG (a ``tEXt`` chunk) or a JPEG (a ``COM``
segment) the command, the packages it shows with their :func:`code_fingerprint`, and the SHA-256 of the files it
plots; the pixels are left as they are, byte for byte. :func:`figure_problems` reads the stamp back and says
what no longer matches the code and data of the working tree (``tests/test_figures.py`` runs it on every
figure of the docs and the README).

The fingerprint is that of the code, not of its text: the SHA-256 of each module's syntax tree with its
docstrings removed (comments and formatting are not in the tree), so rewording a docstring leaves every figure
current, and any change to what the code does makes the figures that show it stale.
"""

from __future__ import annotations

import ast
import hashlib
import importlib.util
import json
import os
import struct
import zlib
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from kornia_ilum.core.errors import TypeCheckError, ValueCheckError
from kornia_ilum.core.files import atomic_write, sha256_file

__all__ = ["STAMP_KEY", "code_fingerprint", "figure_problems", "read_stamp", "stamp_figure"]

#: The key of the stamp: the PNG ``tEXt`` keyword, and the JPEG comment's prefix.
STAMP_KEY = "kornia_ilum.provenance"

_PNG = b"\x89PNG\r\n\x1a\n"


def _module_files(name: str) -> list[tuple[str, Path]]:
    """``(module name, file)`` of the module ``name``, or of every module of the package ``name``, sorted."""
    spec = importlib.util.find_spec(name)
    if spec is None or spec.origin is None:
        raise ValueCheckError(f"no module or package {name!r} to fingerprint")
    origin = Path(spec.origin)
    if origin.name != "__init__.py":
        return [(name, origin)]
    root = origin.parent
    return sorted((name + "." + ".".join(p.relative_to(root).with_suffix("").parts), p)
                  for p in root.rglob("*.py"))


def _without_docstrings(tree: ast.AST) -> ast.AST:
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if (isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and body
                and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant)
                and isinstance(body[0].value.value, str)):
            node.body = body[1:] or [ast.Pass()]
    return tree


def code_fingerprint(modules: Sequence[str]) -> str:
    r"""The fingerprint of the code of ``modules``: SHA-256 over each module's name and its syntax tree without
    docstrings (:func:`ast.dump`), in name order; a package stands for all its modules.

    Args:
        modules: dotted module or package names (``"kornia_ilum_lab.synth.lightstage"``).

    Returns:
        64 hexadecimal digits.

    Raises:
        ValueCheckError: a name is no importable module (the module is found, not imported).

    Examples:
        >>> a = code_fingerprint(["kornia_ilum.core.files"])
        >>> len(a), a == code_fingerprint(["kornia_ilum.core.files"]), a == code_fingerprint(["kornia_ilum.core"])
        (64, True, False)
    """
    if isinstance(modules, str):
        raise TypeCheckError("modules must be a sequence of names, not one str")
    digest = hashlib.sha256()
    for name, path in sorted({f for m in modules for f in _module_files(m)}):
        tree = _without_docstrings(ast.parse(path.read_text(encoding="utf-8")))
        digest.update(name.encode() + b"\0" + ast.dump(tree).encode() + b"\0")
    return digest.hexdigest()


def _png_chunks(data: bytes) -> list[tuple[bytes, bytes]]:
    chunks, pos = [], len(_PNG)
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        chunks.append((data[pos + 4 : pos + 8], data[pos + 8 : pos + 8 + length]))
        pos += 12 + length
    return chunks


def _png_chunk(kind: bytes, body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))


def _jpeg_segments(data: bytes) -> list[tuple[int, int, bytes]]:
    """The JPEG's marker segments before the image data: ``(start, end, body)`` of each ``COM`` segment."""
    out, pos = [], 2
    while pos + 4 <= len(data) and data[pos] == 0xFF:
        marker = data[pos + 1]
        if marker == 0xDA:  # start of scan: the entropy-coded data follows
            break
        (length,) = struct.unpack(">H", data[pos + 2 : pos + 4])
        if marker == 0xFE:
            out.append((pos, pos + 2 + length, data[pos + 4 : pos + 2 + length]))
        pos += 2 + length
    return out


def read_stamp(path: str | os.PathLike[str]) -> dict[str, Any] | None:
    """The stamp of the PNG or JPEG at ``path`` (:func:`stamp_figure`), or ``None`` where it has none.

    Raises:
        ValueCheckError: the file is neither a PNG nor a JPEG.
    """
    data = Path(path).read_bytes()
    if data.startswith(_PNG):
        for kind, body in _png_chunks(data):
            if kind == b"tEXt" and body.startswith(STAMP_KEY.encode() + b"\0"):
                return json.loads(body[len(STAMP_KEY) + 1 :].decode("latin-1"))
        return None
    if data.startswith(b"\xff\xd8"):
        for _, _, body in _jpeg_segments(data):
            if body.startswith(STAMP_KEY.encode() + b"\0"):
                return json.loads(body[len(STAMP_KEY) + 1 :].decode("utf-8"))
        return None
    raise ValueCheckError(f"{str(path)!r} is neither a PNG nor a JPEG")


def stamp_figure(path: str | os.PathLike[str], *, command: str, shows: Sequence[str],
                 inputs: Sequence[str | os.PathLike[str]] = ()) -> dict[str, Any]:
    r"""Write the provenance stamp into the PNG or JPEG at ``path`` (replacing an earlier one; the pixels' bytes
    are untouched), atomically.

    Args:
        path: the figure, a ``.png`` or ``.jpg`` file.
        command: the command that made it, as one would run it again.
        shows: the modules and packages whose output it shows (:func:`code_fingerprint`).
        inputs: files it plots or was made from (logs, reports), recorded by their path relative to the
            figure's folder and their SHA-256.

    Returns:
        the stamp written.

    Examples:
        >>> import tempfile
        >>> from PIL import Image
        >>> with tempfile.TemporaryDirectory() as d:
        ...     Image.new("RGB", (4, 4)).save(f"{d}/a.png")
        ...     _ = stamp_figure(f"{d}/a.png", command="make a", shows=["kornia_ilum.core.files"])
        ...     read_stamp(f"{d}/a.png")["command"], figure_problems(f"{d}/a.png")
        ('make a', [])
    """
    path = Path(path)
    stamp = {"command": command,
             "shows": {m: code_fingerprint([m]) for m in shows},
             "inputs": {os.path.relpath(Path(i).resolve(), path.resolve().parent).replace(os.sep, "/"):
                        sha256_file(i) for i in inputs}}
    text = STAMP_KEY.encode() + b"\0" + json.dumps(stamp, sort_keys=True).encode()
    data = path.read_bytes()
    if data.startswith(_PNG):
        chunks = [(k, b) for k, b in _png_chunks(data)
                  if not (k == b"tEXt" and b.startswith(STAMP_KEY.encode() + b"\0"))]
        chunks.insert(len(chunks) - 1, (b"tEXt", text))  # before IEND
        out = _PNG + b"".join(_png_chunk(k, b) for k, b in chunks)
    elif data.startswith(b"\xff\xd8"):
        for start, end, body in reversed(_jpeg_segments(data)):
            if body.startswith(STAMP_KEY.encode() + b"\0"):
                data = data[:start] + data[end:]
        out = data[:2] + b"\xff\xfe" + struct.pack(">H", len(text) + 2) + text + data[2:]
    else:
        raise ValueCheckError(f"{str(path)!r} is neither a PNG nor a JPEG")
    atomic_write(path, lambda tmp: tmp.write_bytes(out))
    return stamp


def figure_problems(path: str | os.PathLike[str]) -> list[str]:
    """What makes the figure at ``path`` stale: no stamp, code it shows that changed since it was made (or no longer
    exists), or an input file that changed or is gone. Empty when the figure is current.

    Args:
        path: a PNG or JPEG figure.

    Returns:
        one sentence per problem, each naming the command that makes the figure again.
    """
    path = Path(path)
    stamp = read_stamp(path)
    if stamp is None:
        return [f"{path} has no provenance stamp (kornia_ilum_lab.provenance.stamp_figure)"]
    again = f"; make it again with: {stamp['command']}"
    problems = []
    for module, fingerprint in stamp["shows"].items():
        try:
            now = code_fingerprint([module])
        except ValueCheckError:
            problems.append(f"{path} shows {module}, which no longer exists{again}")
            continue
        if now != fingerprint:
            problems.append(f"{path} was made by another version of {module}{again}")
    for name, digest in stamp["inputs"].items():
        source = path.parent / name
        if not source.is_file():
            problems.append(f"{path} was made from {name}, which is gone{again}")
        elif sha256_file(source) != digest:
            problems.append(f"{path} was made from another version of {name}{again}")
    return problems
