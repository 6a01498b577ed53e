"""kornia_ilum_lab.evaluation.split: the held-out subjects and maps, and the synth command's split filter."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest
import torch

from kornia_ilum.core.errors import HDRIOError, TypeCheckError, ValueCheckError
from kornia_ilum_lab.evaluation import eval_environment_sources, eval_fields, heldout_maps
from kornia_ilum.io import write_hdr
from kornia_ilum_lab.synth.cli import add_synth_subjects_parser, split_seeds
from kornia_ilum_lab.synth.environments.real import HDRFolderSource, folder_splits, guess_label, hdri_split
from tests.lab.evaluation.helpers import tiny_field


class TestSplits:
    def test_hdri_split_is_stable_by_name(self, hdri) -> None:
        assert [hdri_split(n) for n in ("studio.exr", "forest.exr", "interior.exr")] == ["eval", "eval", "train"]
        assert hdri_split("studio.exr") == hdri_split(hdri / "studio.exr") == hdri_split(Path("x/y/studio.exr"))
        assert folder_splits(hdri) == {"forest.exr": "eval", "interior.exr": "train", "studio.exr": "eval"}
        names = [f"map_{i}.hdr" for i in range(2000)]
        share = sum(hdri_split(n) == "eval" for n in names) / len(names)
        assert 0.2 < share < 0.3

    def test_folder_source_split(self, hdri) -> None:
        train, ev, every = (HDRFolderSource(hdri, height=8, split=s) for s in ("train", "eval", None))
        assert set(train.names).isdisjoint(ev.names) and set(train.names) | set(ev.names) == set(every.names)
        assert ev.names == ("forest.exr", "studio.exr") and "split='eval'" in repr(ev)
        with pytest.raises(ValueCheckError, match="split"):
            HDRFolderSource(hdri, split="test")

    def test_folder_without_eval_maps(self, tmp_path) -> None:
        write_hdr(tmp_path / "interior.exr", torch.ones(3, 4, 8))
        with pytest.raises(HDRIOError, match="of split 'eval'"):
            HDRFolderSource(tmp_path, split="eval")
        with pytest.raises(HDRIOError, match="of split 'eval'"):
            eval_environment_sources([tmp_path])

    def test_shared_folders_hold_indoor_and_outdoor_eval_maps(self, shared_data) -> None:
        folders = [shared_data / "hdri", shared_data / "hdri_more"]
        maps = heldout_maps(folders)
        ev = {n: lab for f in maps.values() for n, lab in f["eval"].items()}
        assert set(ev.values()) == {"indoor", "outdoor"}
        assert sorted(maps[str(folders[0])]["eval"]) == ["forest.exr", "studio.exr", "sunrise.exr"]
        assert len(ev) == 12 and sum(v == "indoor" for v in ev.values()) == 7
        for f in maps.values():
            assert set(f["eval"]).isdisjoint(f["train"])
        # the README's labels of hdri_more: 24 indoor, 15 outdoor
        more = [n for n in folder_splits(folders[1])]
        assert sum(guess_label(n) == "indoor" for n in more) == 24 and len(more) == 39

    def test_eval_fields_and_synth_seed_filter(self, caches) -> None:
        fields = eval_fields(caches)
        assert all(f.meta["split"] == "eval" for f in fields) and len(fields) == 3
        with pytest.raises(ValueCheckError, match="no eval subject"):
            eval_fields([], [tiny_field(0, 1)])
        with pytest.raises(ValueCheckError, match="both"):
            eval_fields([caches[0], caches[0]])
        assert split_seeds(range(6), "eval") == [1, 3] and split_seeds(range(3), None) == [0, 1, 2]
        assert split_seeds(range(6), "train") == [0, 2, 4, 5]

    def test_eval_environment_sources(self, hdri) -> None:
        sources = eval_environment_sources([hdri], height=16)
        names = [type(s).__name__ for s in sources]
        assert names == ["SkySource", "IndoorSource", "PortraitLightSource", "HDRFolderSource"]
        assert sources[3].names == ("forest.exr", "studio.exr") and sources[3].split == "eval"
        assert sources[2].height == 16
        with pytest.raises(TypeCheckError, match="sequence of folders"):
            eval_fields(str(hdri))  # one folder, not a sequence of them


def test_synth_subjects_split_flag_is_marked_only_when_given() -> None:
    parser = argparse.ArgumentParser(prog="kornia-ilum")
    sub = parser.add_subparsers(dest="command")
    add_synth_subjects_parser(sub)
    default = parser.parse_args(["synth", "subjects", "--seeds", "0-5"])
    given = parser.parse_args(["synth", "subjects", "--seeds", "0-5", "--split", "eval"])
    assert default.split == "train" and not getattr(default, "split_given", False)  # renders every seed
    assert given.split == "eval" and given.split_given
    assert split_seeds(given.seeds, given.split) == [1, 3]
