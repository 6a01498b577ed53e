"""kornia_ilum_lab.evaluation.cli: the ``kornia-ilum evaluate`` command."""

from __future__ import annotations

import argparse
import json

import pytest

from kornia_ilum_lab.evaluation import CHECKS, ORACLES
from kornia_ilum_lab.evaluation import cli as evaluation_cli
from kornia_ilum_lab.evaluation.cli import DEFAULT_CHECKS, add_evaluate_parser, parse_checks, parse_weights, run_evaluate


class TestEvaluateCommand:
    def test_cli(self, caches, hdri, tmp_path, capsys) -> None:
        parser = argparse.ArgumentParser(prog="kornia-ilum")
        add_evaluate_parser(parser.add_subparsers(dest="command"))
        args = parser.parse_args(["evaluate", "--cache", str(caches[0]), "--cache", str(caches[1]), "--hdri",
                                  str(hdri), "--samples", "8", "--estimator", "uniform", "--estimator", "ours",
                                  "--jitter-samples", "3", "--jitters", "2", "--out", str(tmp_path)])
        assert args.checks is None  # all of them but the real flash by default (DEFAULT_CHECKS)
        assert args.func(args) == 0
        printed = capsys.readouterr().out
        assert "## Table 1" in printed and "| ours |" in printed
        summary = json.loads((tmp_path / "evaluation.json").read_text())
        assert set(summary["table1_l_rec"]) == {"uniform", "ours", *ORACLES} and summary["eval_set"]["samples"] == 8
        markdown = (tmp_path / "evaluation.md").read_text()
        assert markdown.startswith("# Held-out evaluation")
        for title in ("## Transfer check", "## Exposure equivariance", "## Crop stability"):
            assert title in markdown and title in printed
        assert "| ours | real photos | 1 |" in markdown and "| uniform | all | 3 |" in markdown
        assert set(summary["checks"]) == {"uniform", "ours"}
        assert set(summary["checks"]["ours"]) == {*DEFAULT_CHECKS, "tone_spread", "seconds"}
        assert "## Colour check" in markdown
        assert summary["checks"]["ours"]["transfer"]["all"]["count"] == 8
        assert summary["checks"]["ours"]["crop"]["all"]["count"] == 3
        settings = summary["check_settings"]
        assert settings["photo_names"] == ["skimage.data.astronaut"] and settings["jitters"] == 2
        assert settings["context_set"]["samples"] == 3 and settings["context_set"]["context"] == 1.5

    def test_checks_option(self, caches, hdri, tmp_path) -> None:
        parser = argparse.ArgumentParser(prog="kornia-ilum")
        add_evaluate_parser(parser.add_subparsers(dest="command"))
        args = parser.parse_args(["evaluate", "--cache", str(caches[0]), "--samples", "4", "--estimator",
                                  "uniform", "--checks", "none", "--no-oracles", "--json",
                                  str(tmp_path / "e.json")])
        assert args.checks == () and args.func(args) == 0
        assert "checks" not in json.loads((tmp_path / "e.json").read_text())
        assert parse_checks("crop,transfer") == ("transfer", "crop") and parse_checks("all") == CHECKS
        with pytest.raises(argparse.ArgumentTypeError, match="unknown checks"):
            parse_checks("transfer,speed")
        assert run_evaluate is args.func
        assert parse_weights("a=b.safetensors") == ("a", "b.safetensors")
        with pytest.raises(argparse.ArgumentTypeError):
            parse_weights("nothing")


def test_portraits_option_reaches_both_eval_sets(monkeypatch, caches, tmp_path) -> None:
    """``--portraits KEY=VALUE``: the eval set and the crop check's context set are built with them, and the
    report records them."""
    real, seen = evaluation_cli.build_eval_set, []

    def recording(*args, **kwargs):
        seen.append(kwargs.get("portraits"))
        return real(*args, **kwargs)

    monkeypatch.setattr(evaluation_cli, "build_eval_set", recording)
    parser = argparse.ArgumentParser(prog="kornia-ilum")
    add_evaluate_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["evaluate", "--cache", str(caches[0]), "--samples", "4", "--estimator",
                              "uniform", "--no-oracles", "--checks", "crop", "--jitter-samples", "2",
                              "--jitters", "2", "--portraits", "surroundings=1.0", "--out", str(tmp_path)])
    assert args.portraits == [("surroundings", 1.0)] and args.func(args) == 0
    assert seen == [{"surroundings": 1.0}] * 2
    summary = json.loads((tmp_path / "evaluation.json").read_text())
    assert summary["eval_set"]["portraits"]["surroundings"] == "1.0"
