"""Tests of ``kornia-ilum synth environments``: parser, files written, progress output."""

from __future__ import annotations

import argparse
import csv
import sys

import pytest
import torch

from kornia_ilum.core.errors import HDRIOError
from kornia_ilum.synth.cli import add_synth_environments_parser, run_synth_environments, tone_map_tile

PNG = b"\x89PNG\r\n\x1a\n"


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="kornia-ilum")
    add_synth_environments_parser(p.add_subparsers(dest="command"))
    return p


def read_csv(path) -> list[dict[str, str]]:
    with path.open() as f:
        return list(csv.DictReader(f))


class TestParser:
    def test_defaults(self):
        args = parser().parse_args(["synth", "environments"])
        assert (args.folder, args.n, args.seed, args.out, args.height, args.sheet, args.no_augment) == (
            None, 48, 0, "synth_environments", 128, 48, False,
        )  # fmt: skip
        assert args.func is run_synth_environments

    def test_options(self):
        args = parser().parse_args(
            ["synth", "environments", "--folder", "maps", "-n", "7", "--seed", "3", "--out", "o",
             "--height", "64", "--sheet", "0", "--no-augment"]
        )  # fmt: skip
        assert (args.folder, args.n, args.seed, args.out, args.height, args.sheet, args.no_augment) == (
            "maps", 7, 3, "o", 64, 0, True,
        )  # fmt: skip

    def test_bad_values(self, capsys):
        for bad in (["-n", "0"], ["--height", "x"], ["--sheet", "-1"]):
            with pytest.raises(SystemExit):
                parser().parse_args(["synth", "environments", *bad])
        assert "must be a positive integer" in capsys.readouterr().err

    def test_reuses_an_existing_synth_command(self):
        p = argparse.ArgumentParser(prog="kornia-ilum")
        sub = p.add_subparsers(dest="command")
        synth = sub.add_parser("synth")
        synth.add_subparsers(dest="synth_command").add_parser("promote")
        add_synth_environments_parser(sub)
        assert p.parse_args(["synth", "environments"]).func is run_synth_environments
        assert p.parse_args(["synth", "promote"]).synth_command == "promote"


def test_writes_files_procedural(tmp_path, capsys):
    argv = ["synth", "environments", "-n", "4", "--height", "16", "--out", str(tmp_path / "o")]
    args = parser().parse_args(argv)
    assert args.func(args) == 0
    out = tmp_path / "o"
    for name in ("contact_sheet.png", "stats.png"):
        assert (out / name).read_bytes()[:8] == PNG
    rows = read_csv(out / "stats.csv")
    assert len(rows) == 4 and {r["group"] for r in rows} <= {"procedural outdoor", "procedural indoor"}
    text = (out / "stats.txt").read_text()
    captured = capsys.readouterr()
    assert "environments/s" in text and "dynamic range (stops)" in text
    assert "dynamic range (stops)" in captured.out and f"wrote {out / 'stats.csv'}" in captured.out
    assert "sampling environments" in captured.err  # the progress bar


def test_writes_files_with_real_maps(shared_data, tmp_path):
    folder = str(shared_data / "hdri")
    args = argparse.Namespace(folder=folder, n=2, seed=1, out=str(tmp_path), height=16, sheet=0)
    assert run_synth_environments(args) == 0
    rows = read_csv(tmp_path / "stats.csv")
    assert [r["group"] for r in rows[:10]] == ["real"] * 10 and len(rows) == 12
    assert not (tmp_path / "contact_sheet.png").exists()  # --sheet 0


def test_progress_without_tqdm(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "tqdm", None)  # import tqdm -> ImportError
    args = argparse.Namespace(folder=None, n=2, seed=0, out=str(tmp_path), height=8, sheet=1, no_augment=True)
    assert run_synth_environments(args) == 0
    assert "sampling environments: 2/2" in capsys.readouterr().err


def test_missing_folder(tmp_path):
    args = argparse.Namespace(folder=str(tmp_path / "nope"), n=1, seed=0, out=str(tmp_path), height=8)
    with pytest.raises(HDRIOError, match="nope does not exist"):
        run_synth_environments(args)


def test_tone_map_tile():
    tile = tone_map_tile(torch.ones(3, 32, 32))
    assert tile.shape == (3, 32, 134) and 0.0 <= float(tile.min()) and float(tile.max()) <= 1.0


def test_missing_matplotlib(tmp_path, monkeypatch):
    from kornia_ilum.core.errors import IlumError

    monkeypatch.setitem(sys.modules, "matplotlib", None)
    args = argparse.Namespace(folder=None, n=1, seed=0, out=str(tmp_path), height=8)
    with pytest.raises(IlumError, match="pip install matplotlib"):
        run_synth_environments(args)
