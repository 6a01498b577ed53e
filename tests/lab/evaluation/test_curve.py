"""kornia_ilum_lab.evaluation.curve: the learning curve of a run's snapshots, and ``evaluate --curve``."""

from __future__ import annotations

import argparse
import csv

import pytest
import safetensors.torch
import torch

from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.estimators import OursEstimator
from kornia_ilum_lab.evaluation import (
    BRDF_NAMES,
    CURVE_FIELDS,
    equal_budget,
    evaluate,
    format_equal_budget,
    learning_curve,
    read_curve,
    snapshot_files,
)
from kornia_ilum_lab.evaluation.cli import add_evaluate_parser
from kornia_ilum_lab.train import save_snapshot


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A run folder with two snapshots of ``ours``, a random one and its weights halved (steps 2 and 4)."""
    folder = tmp_path_factory.mktemp("run")
    torch.manual_seed(0)
    model = OursEstimator().eval()
    save_snapshot(folder, model, name="ours", step=4, samples=128,
                  elapsed_s=90.0)  # written out of order: the curve sorts by step
    with torch.no_grad():
        for p in model.parameters():
            p.mul_(0.5)
    save_snapshot(folder, model, name="ours", step=2, samples=64, elapsed_s=45.5)
    return folder


class TestLearningCurve:
    def test_one_row_per_snapshot_in_step_order_scored_as_evaluate_scores(self, eval_set, run) -> None:
        rows = learning_curve(eval_set, run, batch_size=8)
        assert [(r["step"], r["samples"], r["elapsed_s"]) for r in rows] == [(2, 64, 45.5), (4, 128, 90.0)]
        assert all(set(r) == set(CURVE_FIELDS) for r in rows)
        last = snapshot_files(run)[-1]
        reference = evaluate(eval_set, [], weights={"ours": last}, oracles=False, batch_size=8)["methods"]
        scores = reference[f"ours@{last.name}"]["scores"]
        for b in BRDF_NAMES:
            assert rows[1][b] == pytest.approx(float(scores[b].mean()), rel=1e-5)
        assert rows[0]["diffuse"] != rows[1]["diffuse"]

    def test_a_run_without_snapshots_or_a_file_without_metadata(self, eval_set, tmp_path) -> None:
        with pytest.raises(ValueCheckError, match="--snapshot-every"):
            learning_curve(eval_set, tmp_path)
        (tmp_path / "snapshots").mkdir()
        plain = tmp_path / "snapshots" / "step_000001.safetensors"
        safetensors.torch.save_file(OursEstimator().state_dict(), str(plain))  # a weight file, no metadata
        with pytest.raises(ValueCheckError, match="not a training snapshot"):
            learning_curve(eval_set, tmp_path)

    def test_evaluate_curve_writes_the_csv_and_the_figure(self, caches, hdri, run, capsys) -> None:
        parser = argparse.ArgumentParser(prog="kornia-ilum")
        add_evaluate_parser(parser.add_subparsers(dest="command"))
        args = parser.parse_args(["evaluate", "--cache", str(caches[0]), "--cache", str(caches[1]), "--hdri",
                                  str(hdri), "--samples", "8", "--curve", str(run)])
        assert args.func(args) == 0
        printed = capsys.readouterr().out
        assert "learning curve of" in printed and "| 4 | 128 | 1.5 |" in printed and "## Table 1" not in printed
        with open(run / "curve.csv", newline="") as f:
            rows = list(csv.DictReader(f))
        assert [r["step"] for r in rows] == ["2", "4"] and list(rows[0]) == list(CURVE_FIELDS)
        assert (run / "curve.png").read_bytes()[:4] == b"\x89PNG"
        assert not list(run.glob(".*tmp*"))


class TestEqualBudget:
    @staticmethod
    def _rows(*points: tuple[int, float, float]) -> list[dict]:
        return [{"step": i + 1, "samples": s, "elapsed_s": t, **dict.fromkeys(BRDF_NAMES, v)}
                for i, (s, t, v) in enumerate(points)]

    def test_each_run_at_its_last_snapshot_within_the_shared_budgets(self) -> None:
        cheap = self._rows((100, 10.0, 0.30), (200, 20.0, 0.20), (300, 30.0, 0.15))
        costly = self._rows((100, 40.0, 0.25), (150, 60.0, 0.22))
        table = equal_budget({"cheap": cheap, "costly": costly})
        assert table["samples"]["budget"] == 150 and table["elapsed_s"]["budget"] == 30.0
        assert table["samples"]["runs"]["cheap"]["samples"] == 100  # not interpolated: the last snapshot within
        assert table["samples"]["runs"]["costly"]["samples"] == 150
        assert table["elapsed_s"]["runs"]["cheap"]["diffuse"] == 0.15
        assert table["elapsed_s"]["runs"]["costly"] is None  # no snapshot within 30 s
        text = format_equal_budget(table)
        assert "| portraits 150 | cheap | 1 | 100 |" in text and "| wall time 0.5 min | costly | - |" in text

    def test_needs_two_runs_with_snapshots(self) -> None:
        with pytest.raises(ValueCheckError, match="at least two runs"):
            equal_budget({"a": self._rows((1, 1.0, 0.1))})
        with pytest.raises(ValueCheckError, match="at least two runs"):
            equal_budget({"a": self._rows((1, 1.0, 0.1)), "b": []})


class TestReadCurve:
    def test_reads_back_what_write_curve_wrote(self, run, eval_set) -> None:
        rows = learning_curve(eval_set, run, batch_size=8)
        from kornia_ilum_lab.evaluation import write_curve

        write_curve(run, rows)
        back = read_curve(run / "curve.csv")
        assert [(r["step"], r["samples"]) for r in back] == [(r["step"], r["samples"]) for r in rows]
        for got, want in zip(back, rows):
            for k in ("elapsed_s", *BRDF_NAMES):
                assert got[k] == pytest.approx(want[k], rel=1e-5)

    def test_missing_empty_or_foreign_files_are_typed_errors(self, tmp_path) -> None:
        with pytest.raises(ValueCheckError, match="cannot read the learning curve"):
            read_curve(tmp_path / "nope.csv")
        (tmp_path / "empty.csv").write_text("")
        with pytest.raises(ValueCheckError, match="not a curve.csv"):
            read_curve(tmp_path / "empty.csv")
        (tmp_path / "other.csv").write_text("a,b\n1,2\n")
        with pytest.raises(ValueCheckError, match="missing: step"):
            read_curve(tmp_path / "other.csv")
        (tmp_path / "text.csv").write_text(",".join(CURVE_FIELDS) + "\n1,2,x,0.1,0.2,0.3\n")
        with pytest.raises(ValueCheckError, match="not a number"):
            read_curve(tmp_path / "text.csv")

    def test_evaluate_reads_written_curves_without_a_cache(self, tmp_path, capsys) -> None:
        header = ",".join(CURVE_FIELDS) + "\n"
        (tmp_path / "a.csv").write_text(header + "1,100,10,0.3,0.3,0.3\n2,200,20,0.2,0.2,0.2\n")
        (tmp_path / "b.csv").write_text(header + "1,100,40,0.25,0.25,0.25\n")
        parser = argparse.ArgumentParser(prog="kornia-ilum")
        add_evaluate_parser(parser.add_subparsers(dest="command"))
        args = parser.parse_args(["evaluate", "--curve", str(tmp_path / "a.csv"), "--curve", str(tmp_path / "b.csv")])
        assert args.func(args) == 0
        printed = capsys.readouterr().out
        assert "at equal budgets" in printed and "| portraits 100 |" in printed
        assert sorted(p.name for p in tmp_path.iterdir()) == ["a.csv", "b.csv"]  # nothing written
        args = parser.parse_args(["evaluate", "--curve", str(tmp_path / "a.csv"), "--curve", str(tmp_path)])
        with pytest.raises(ValueCheckError, match="needs --cache"):
            args.func(args)
