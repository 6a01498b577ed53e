"""Tests of ``kornia-ilum synth environments`` and ``synth subjects``: parser, files written, progress output.

The contact sheets' drawing is tested in ``tests/synth/test_sheets.py``.
"""

from __future__ import annotations

import argparse
import csv
import sys

import pytest
from kornia_ilum_lab.synth.cli import (
    add_synth_environments_parser,
    add_synth_subjects_parser,
    parse_seeds,
    run_synth_environments,
    run_synth_subjects,
)

from kornia_ilum.core.errors import HDRIOError, IlumError, ValueCheckError

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
    groups = {"procedural outdoor", "procedural indoor", "portrait lights"}  # the portrait lights: issue 21
    assert len(rows) == 4 and {r["group"] for r in rows} <= groups
    text = (out / "stats.txt").read_text()
    assert "Per source of the sampled environments" in text
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


def test_missing_matplotlib(tmp_path, monkeypatch):
    from kornia_ilum.core.errors import IlumError

    monkeypatch.setitem(sys.modules, "matplotlib", None)
    args = argparse.Namespace(folder=None, n=1, seed=0, out=str(tmp_path), height=8)
    with pytest.raises(IlumError, match="pip install matplotlib"):
        run_synth_environments(args)


class TestSubjects:
    def parser(self) -> argparse.ArgumentParser:
        p = argparse.ArgumentParser(prog="kornia-ilum")
        add_synth_subjects_parser(p.add_subparsers(dest="command"))
        return p

    def test_defaults_and_options(self):
        args = self.parser().parse_args(["synth", "subjects"])
        assert (args.out, args.seeds, args.views, args.size, args.spp, args.lighting_size, args.worker) == (
            "lightstage", list(range(10)), 4, 192, None, 32, (0, 1),
        )  # fmt: skip
        assert (args.source, args.assets, args.workers) == (None, None, 2)
        assert (args.sheet, args.split, args.folder, args.func) == (64, "train", None, run_synth_subjects)
        args = self.parser().parse_args(["synth", "subjects", "--seeds", "4,1-2,4", "--worker", "2/3",
                                         "--source", "mannequin", "--workers", "1"])
        assert args.seeds == [4, 1, 2] and args.worker == (2, 3) and args.source == "mannequin"
        assert args.device is None and self.parser().parse_args(["synth", "subjects", "--device", "cuda"]).device == "cuda"
        args = self.parser().parse_args(["synth", "subjects", "--clothes", "--cut-below-chin", "0.6",
                                         "--face-fraction", "0.3"])
        assert (args.clothes, args.cut_below_chin, args.face_fraction) == (True, 0.6, 0.3)

    def test_bad_values(self, capsys):
        for bad in (["--seeds", "a-b"], ["--seeds", ""], ["--worker", "3/3"], ["--worker", "1"], ["--size", "0"],
                    ["--source", "clay"], ["--workers", "0"], ["--device", "tpu"]):
            with pytest.raises(SystemExit):
                self.parser().parse_args(["synth", "subjects", *bad])
        err = capsys.readouterr().err
        assert "seeds must look like" in err and "worker must be I/N" in err and "invalid choice" in err

    def test_main_exit_status(self, tmp_path, capsys, monkeypatch):
        """Bad options exit 2 with one line; missing MakeHuman assets exit 1 with one line."""
        from kornia_ilum.cli import main

        assert main(["synth", "subjects", "--source", "clay", "--out", str(tmp_path)]) == 2
        err = capsys.readouterr().err
        assert err.startswith("kornia-ilum: error:") and err.count("\n") == 1
        monkeypatch.setenv("KORNIA_ILUM_MAKEHUMAN", str(tmp_path / "nowhere"))
        monkeypatch.setenv("KORNIA_ILUM_SHARED_DATA", str(tmp_path / "nowhere"))
        status = main(["synth", "subjects", "--source", "makehuman", "--assets", str(tmp_path / "nowhere"),
                       "--sheet", "0", "--out", str(tmp_path / "o")])
        err = capsys.readouterr().err
        assert status == 1 and err.startswith("kornia-ilum: error:") and err.count("\n") == 1
        assert "makehuman" in err.lower()

    def test_parse_seeds(self):
        assert parse_seeds("7") == [7] and parse_seeds("0-2, 5") == [0, 1, 2, 5]

    @pytest.mark.slow  # Mitsuba renders
    def test_renders_resumes_and_writes_the_sheet(self, tmp_path, capsys):
        argv = ["synth", "subjects", "--source", "mannequin", "--seeds", "0-1", "--views", "2", "--size", "16",
                "--spp", "1", "--lighting-size", "4", "--workers", "1", "--threads", "1", "--sheet", "3",
                "--split", "all", "--out", str(tmp_path)]
        args = self.parser().parse_args(argv)
        assert args.func(args) == 0
        captured = capsys.readouterr()
        assert "subject-views: 4/4 (100 %)" in captured.err and "ETA" in captured.err  # the progress bar
        assert "4 subject-views of 2 subjects (1 eval subjects)" in captured.out
        assert "source mannequin" in captured.out and "3 portraits" in captured.out
        assert (tmp_path / "contact_sheet.png").read_bytes()[:8] == PNG
        assert sorted(p.name for p in (tmp_path / "fields").iterdir()) == [
            "s000000_v00.safetensors", "s000000_v01.safetensors", "s000001_v00.safetensors",
            "s000001_v01.safetensors"]
        stamp = (tmp_path / "fields" / "s000000_v00.safetensors").stat().st_mtime_ns
        args = self.parser().parse_args([*argv[:-4], "--sheet", "0", "--out", str(tmp_path), "--sparse"])
        assert args.func(args) == 0  # resumed: nothing left to render, the sparse sidecars written
        assert (tmp_path / "fields" / "s000000_v00.safetensors").stat().st_mtime_ns == stamp
        out = capsys.readouterr().out
        assert "this run rendered 0" in out and "wrote 4 sparse-relighting sidecar(s)" in out
        assert len(list((tmp_path / "fields").glob("*.sparse.safetensors"))) == 4

    def test_default_source_falls_back_to_mannequins(self, tmp_path, capsys, monkeypatch):
        from kornia_ilum_lab.synth.cli import _subject_source

        monkeypatch.setenv("KORNIA_ILUM_MAKEHUMAN", str(tmp_path / "nowhere"))
        monkeypatch.setenv("KORNIA_ILUM_SHARED_DATA", str(tmp_path / "nowhere"))
        assert _subject_source(None, None).name == "mannequin"
        assert "using the mannequins" in capsys.readouterr().err
        assert _subject_source("mannequin", None).name == "mannequin"
        with pytest.raises(IlumError, match="cannot load the MakeHuman assets"):  # asked for clothes: no fallback
            _subject_source(None, None, clothes=True)
        with pytest.raises(ValueCheckError, match="takes no clothes"):
            _subject_source("mannequin", None, clothes=True)
