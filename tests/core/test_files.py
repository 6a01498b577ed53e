"""Tests of kornia_ilum.core.files: atomic writes and file digests."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import pytest

from kornia_ilum.core.files import atomic_write, sha256_file


class TestAtomicWrite:
    def test_writes_the_file_and_leaves_no_temporary(self, tmp_path):
        seen: list[Path] = []

        def write(tmp: Path) -> None:
            seen.append(tmp)
            tmp.write_bytes(b"pixels")

        atomic_write(tmp_path / "image.exr", write)
        assert (tmp_path / "image.exr").read_bytes() == b"pixels"
        assert os.listdir(tmp_path) == ["image.exr"]
        # a hidden file beside the destination, with its extension (writers pick the format by it)
        (tmp,) = seen
        assert tmp.parent == tmp_path and tmp.name.startswith(".") and tmp.suffix == ".exr"

    def test_replaces_an_existing_file(self, tmp_path):
        path = tmp_path / "a.txt"
        path.write_text("old")
        atomic_write(path, lambda tmp: tmp.write_text("new"))
        assert path.read_text() == "new" and os.listdir(tmp_path) == ["a.txt"]

    def test_the_file_gets_the_umask_mode_even_from_a_private_writer(self, tmp_path):
        import safetensors.torch
        import torch

        old = os.umask(0o022)
        try:
            atomic_write(tmp_path / "w.safetensors", lambda tmp: safetensors.torch.save_file({"a": torch.ones(2)}, str(tmp)))
            atomic_write(tmp_path / "a.txt", lambda tmp: tmp.write_text("x"))
        finally:
            os.umask(old)
        # safetensors alone writes 0600: weights that others on the machine cannot read
        assert (tmp_path / "w.safetensors").stat().st_mode & 0o777 == 0o644
        assert (tmp_path / "a.txt").stat().st_mode & 0o777 == 0o644
        assert sorted(os.listdir(tmp_path)) == ["a.txt", "w.safetensors"]

    def test_failed_write_leaves_the_destination_as_it_was(self, tmp_path):
        path = tmp_path / "a.txt"
        path.write_text("old")

        def write(tmp: Path) -> None:
            tmp.write_text("half")
            raise RuntimeError("disk full")

        with pytest.raises(RuntimeError, match="disk full"):
            atomic_write(path, write)
        assert path.read_text() == "old" and os.listdir(tmp_path) == ["a.txt"]


class TestSha256File:
    def test_known_digest(self, tmp_path):
        path = tmp_path / "abc"
        path.write_bytes(b"abc")
        assert sha256_file(path) == "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"

    def test_matches_hashlib_on_a_file_larger_than_a_block(self, tmp_path):
        data = bytes(range(256)) * 5000  # 1.28 MB
        path = tmp_path / "weights.bin"
        path.write_bytes(data)
        assert sha256_file(str(path)) == hashlib.sha256(data).hexdigest()
