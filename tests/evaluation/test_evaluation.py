"""The held-out evaluation: splits, eval set, oracles, tables and the ``evaluate`` command, on a tiny cache."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import pytest
import torch

from kornia_ilum.core.errors import HDRIOError, MissingWeightsError, ValueCheckError
from kornia_ilum.evaluation import (
    BRDF_NAMES,
    EVAL_SEED,
    ORACLES,
    build_eval_set,
    eval_environment_sources,
    eval_fields,
    evaluate,
    format_markdown,
    heldout_maps,
    load_estimator,
    oracle_predictions,
    score,
    summarize,
)
from kornia_ilum.evaluation.cli import add_evaluate_parser, parse_weights, run_evaluate
from kornia_ilum.geometry import mirror_ball_directions, mirror_ball_solid_angles
from kornia_ilum.io import write_hdr
from kornia_ilum.metrics import relative_radiance
from kornia_ilum.sh import sh_project
from kornia_ilum.synth.cli import split_seeds
from kornia_ilum.synth.environments.real import HDRFolderSource, folder_splits, guess_label, hdri_split
from kornia_ilum.synth.lightstage import LANDMARK_NAMES, subject_split
from kornia_ilum.synth.lightstage.cache import field_path, write_field
from kornia_ilum.synth.lightstage.olat import ReflectanceField
from kornia_ilum.synth.lightstage.scene import Camera

SIZE = 32  # render side of the tiny fields
N = 24  # eval samples in the tests


def tiny_field(seed: int, tone: int) -> ReflectanceField:
    """A grey Lambertian sphere filling a 32 x 32 view, lit by the 32 x 32 mirror-ball basis, with a ring of
    landmarks (no Mitsuba: the field is written down)."""
    c = (torch.arange(SIZE, dtype=torch.float64) + 0.5) / SIZE * 2 - 1
    y, x = torch.meshgrid(-c, c, indexing="ij")
    r2 = x**2 + y**2
    alpha = (r2 <= 0.9).double()
    normals = torch.stack([x, y, (1 - r2).clamp(min=0).sqrt()], -1).reshape(-1, 3)
    d, valid = mirror_ball_directions(32, dtype=torch.float64)
    omega = mirror_ball_solid_angles(32, dtype=torch.float64).flatten()
    cos = (normals @ d.reshape(-1, 3).T).clamp(min=0) * valid.flatten()
    albedo = torch.tensor([0.5, 0.35, 0.3], dtype=torch.float64)[:, None, None] * (1 + 0.1 * seed % 3)
    field = (albedo * (alpha.flatten()[:, None] * cos * omega / math.pi)).to(torch.bfloat16)
    angles = 2 * math.pi * torch.arange(len(LANDMARK_NAMES)) / len(LANDMARK_NAMES)
    landmarks = torch.stack([16 + 8 * angles.cos(), 17 + 9 * angles.sin()], -1)
    meta = {"landmarks": landmarks.tolist(), "split": subject_split(seed), "skin_tone": tone, "lighting_size": 32}
    camera = Camera(fov_deg=40.0, distance=4.0, yaw_deg=0.0, pitch_deg=0.0, size=SIZE)
    return ReflectanceField(field, alpha[None].float(), torch.tensor([8.0, 8.0, 24.0, 26.0]), camera, seed, meta)


def write_cache(out: Path, seeds_tones: list[tuple[int, int]]) -> Path:
    entries = []
    for seed, tone in seeds_tones:
        rf = tiny_field(seed, tone)
        path = field_path(seed, 0)
        write_field(out / path, rf)
        entries.append({"subject_seed": seed, "view_index": 0, "path": path, "split": subject_split(seed),
                        "skin_tone": tone})
    (out / "manifest.json").write_text(json.dumps({"format": "kornia_ilum.olat-cache.v2", "entries": entries}))
    return out


@pytest.fixture(scope="module")
def caches(tmp_path_factory) -> list[Path]:
    """Two caches: seeds 0 (train), 1 and 3 (eval); and an eval-only one with seed 5 (train) and 7 (eval)."""
    assert [subject_split(s) for s in (0, 1, 3, 5)] == ["train", "eval", "eval", "train"]
    eval_seven = next(s for s in range(6, 100) if subject_split(s) == "eval")
    a = write_cache(tmp_path_factory.mktemp("cache_a"), [(0, 2), (1, 3), (3, 6)])
    b = write_cache(tmp_path_factory.mktemp("cache_b"), [(5, 4), (eval_seven, 9)])
    return [a, b]


@pytest.fixture(scope="module")
def hdri(tmp_path_factory) -> Path:
    """Tiny maps: studio.exr, forest.exr (eval) and interior.exr (train)."""
    folder = tmp_path_factory.mktemp("hdri")
    for name, value in (("studio.exr", 1.0), ("forest.exr", 2.0), ("interior.exr", 50.0)):
        write_hdr(folder / name, torch.full((3, 16, 32), value))
    return folder


@pytest.fixture(scope="module")
def eval_set(caches, hdri):
    return build_eval_set(caches, [hdri], samples=N, fields_per_chunk=2, lightings_per_field=4)


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


class TestEvalSet:
    def test_contents(self, eval_set, hdri) -> None:
        assert eval_set.images.shape == (N, 3, 256, 256) and eval_set.images.dtype == torch.uint8
        assert eval_set.mirror_ball.shape == (N, 3, 32, 32)
        assert all(subject_split(s) == "eval" for s in eval_set.subject_seed)
        assert "real:interior.exr" not in eval_set.source  # a train map never shows up
        d = eval_set.description
        assert d["samples"] == N and d["seed"] == EVAL_SEED and sum(d["labels"].values()) == N
        assert d["eval_maps"] == {str(hdri): {"forest.exr": "outdoor", "studio.exr": "indoor"}}
        assert set(d["skin_tones"]) <= {"3", "6", "9"} and len(d["subjects"]) == 3

    def test_deterministic(self, eval_set, caches, hdri) -> None:
        again = build_eval_set(caches, [hdri], samples=N, fields_per_chunk=2, lightings_per_field=4)
        assert torch.equal(again.images, eval_set.images) and torch.equal(again.mirror_ball, eval_set.mirror_ball)
        assert again.label == eval_set.label and again.source == eval_set.source

    def test_black_background_variant_is_the_same_portraits(self, eval_set, caches, hdri) -> None:
        black = build_eval_set(caches, [hdri], samples=N, fields_per_chunk=2, lightings_per_field=4,
                               background="black")
        assert black.description["background"] == "black" and eval_set.description["background"] == "environment"
        assert black.label == eval_set.label and black.subject_seed == eval_set.subject_seed
        assert black.source == eval_set.source
        assert not torch.equal(black.images, eval_set.images)
        # the same lighting up to the exposure, which meters the (now black) background too
        ratio = black.mirror_ball.sum((1, 2, 3)) / eval_set.mirror_ball.sum((1, 2, 3))
        rescaled = eval_set.mirror_ball * ratio[:, None, None, None]
        torch.testing.assert_close(black.mirror_ball, rescaled, rtol=1e-3, atol=1e-6)


class TestScores:
    def test_oracles(self) -> None:
        gt = torch.rand(3, 3, 32, 32) * 2
        out = oracle_predictions(gt)
        assert set(out) == set(ORACLES)
        assert relative_radiance(out["mean of GT"], gt).abs().max() < 1e-5
        assert relative_radiance(out["SH of GT"], gt).abs().max() < 1e-3
        torch.testing.assert_close(sh_project(out["SH of GT"]), sh_project(gt), atol=1e-4, rtol=1e-4)
        sun = torch.zeros(1, 3, 32, 32)
        sun[..., 16, 5] = 1000.0
        assert oracle_predictions(sun)["SH of GT"].min() < 0  # unclamped: the ringing stays negative

    def test_score_shapes(self) -> None:
        gt = torch.rand(4, 3, 32, 32)
        s = score(gt * 0.5, gt)
        assert all(s[b].shape == (4,) for b in BRDF_NAMES) and s["relative_radiance"].shape == (4, 3)
        torch.testing.assert_close(s["relative_radiance"], torch.full((4, 3), 0.5))


class TestEvaluate:
    def test_tables(self, eval_set, untrained_name) -> None:
        results = evaluate(eval_set, ["uniform", untrained_name])
        assert set(results["methods"]) == {"uniform", *ORACLES}
        assert "MissingWeightsError" in results["skipped"][untrained_name]
        summary = summarize(results, eval_set)
        t1, t2 = summary["table1_l_rec"], summary["table2_relative_radiance"]
        for name in ("uniform", *ORACLES):
            assert set(t1[name]) == {"indoor", "outdoor", "all"}
            assert all(isinstance(t1[name]["all"][b], float) for b in BRDF_NAMES)
            assert len(t2[name]["all"]["mean"]) == 3 and min(t2[name]["all"]["mean_abs"]) >= 0
            tones = summary["per_skin_tone"][name]
            assert sum(row["count"] for row in tones.values()) == N
        assert max(abs(v) for v in t2["mean of GT"]["all"]["mean"]) < 1e-4
        markdown = format_markdown(summary)
        assert "## Table 1" in markdown and "| uniform |" in markdown and "untrained: MissingWeightsError" in markdown
        json.dumps(summary)  # JSON-ready

    def test_paired_differences(self, eval_set) -> None:
        results = evaluate(eval_set, ["uniform"])
        scores = results["methods"]
        paired = summarize(results, eval_set, reference="uniform")["paired"]
        assert paired["reference"] == "uniform" and set(paired["methods"]) == set(ORACLES)
        for name, rows in paired["methods"].items():
            for b in BRDF_NAMES:
                d = scores[name]["scores"][b] - scores["uniform"]["scores"][b]
                r = rows[b]
                assert math.isclose(r["mean"], float(d.double().mean()), rel_tol=1e-9, abs_tol=1e-12)
                assert r["low"] <= r["mean"] <= r["high"] and 0 <= r["better"] <= 1
        assert summarize(results, eval_set)["paired"] == {"reference": None, "methods": {}}  # no ours scored
        assert "## Paired differences: L_rec(method) - L_rec(uniform)" in format_markdown(
            summarize(results, eval_set, reference="uniform"))

    def test_weights_checkpoint(self, eval_set, tmp_path) -> None:
        import safetensors.torch

        from kornia_ilum.estimators import create_estimator

        net = create_estimator("ours", pretrained=False)
        path = tmp_path / "ckpt.safetensors"
        safetensors.torch.save_file({k: v.contiguous() for k, v in net.state_dict().items()}, str(path))
        loaded = load_estimator("ours", path)
        assert not loaded.training
        with pytest.raises(MissingWeightsError):
            load_estimator("ours", tmp_path / "missing.safetensors")
        with pytest.raises(ValueCheckError, match="safetensors"):
            load_estimator("ours", tmp_path / "ckpt.pt")

    def test_cli(self, caches, hdri, tmp_path, capsys) -> None:
        parser = argparse.ArgumentParser(prog="kornia-ilum")
        add_evaluate_parser(parser.add_subparsers(dest="command"))
        args = parser.parse_args(["evaluate", "--cache", str(caches[0]), "--cache", str(caches[1]), "--hdri",
                                  str(hdri), "--samples", "8", "--estimator", "uniform", "--estimator", "ours",
                                  "--out", str(tmp_path)])
        assert args.func(args) == 0
        printed = capsys.readouterr().out
        assert "## Table 1" in printed and "| ours |" in printed
        summary = json.loads((tmp_path / "evaluation.json").read_text())
        assert set(summary["table1_l_rec"]) == {"uniform", "ours", *ORACLES} and summary["eval_set"]["samples"] == 8
        assert (tmp_path / "evaluation.md").read_text().startswith("# Held-out evaluation")
        assert run_evaluate is args.func
        assert parse_weights("a=b.safetensors") == ("a", "b.safetensors")
        with pytest.raises(argparse.ArgumentTypeError):
            parse_weights("nothing")


def test_synth_subjects_split_flag_is_marked_only_when_given() -> None:
    from kornia_ilum.synth.cli import add_synth_subjects_parser

    parser = argparse.ArgumentParser(prog="kornia-ilum")
    sub = parser.add_subparsers(dest="command")
    add_synth_subjects_parser(sub)
    default = parser.parse_args(["synth", "subjects", "--seeds", "0-5"])
    given = parser.parse_args(["synth", "subjects", "--seeds", "0-5", "--split", "eval"])
    assert default.split == "train" and not getattr(default, "split_given", False)  # renders every seed
    assert given.split == "eval" and given.split_given
    assert split_seeds(given.seeds, given.split) == [1, 3]
