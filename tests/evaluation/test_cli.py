"""kornia_ilum.evaluation.cli: the ``kornia-ilum evaluate`` command."""

from __future__ import annotations

import argparse
import json

import pytest

from kornia_ilum.evaluation import ORACLES
from kornia_ilum.evaluation.cli import add_evaluate_parser, parse_weights, run_evaluate


class TestEvaluateCommand:
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
