"""kornia_ilum_lab.train.cli: the ``kornia-ilum train`` parser and how it builds the run's settings."""

from __future__ import annotations

import argparse

import pytest

import kornia_ilum_lab.train.cli as train_cli
from kornia_ilum_lab.train import BRDF_WEIGHTS, TrainConfig
from kornia_ilum_lab.train.cli import add_train_parser, run_train


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="kornia-ilum")
    add_train_parser(parser.add_subparsers(dest="command"))
    return parser


class TestParser:
    def test_defaults_are_the_configs(self) -> None:
        args = _parser().parse_args(["train", "--cache", "a", "b", "--out", "run"])
        d = TrainConfig(out="", cache=("-",))
        assert args.cache == ["a", "b"] and args.hdri == [] and args.data == [] and args.model == []
        for name in ("estimator", "steps", "batch", "lr", "seed", "device", "bf16", "channels_last",
                     "checkpoint_every", "log_every", "snapshot_every", "lambda_adv", "lambda_crop", "crop_pairs",
                     "lambda_colour", "colour_pairs",
                     "lambda_energy", "init", "workers", "threads"):
            assert getattr(args, name) == getattr(d, name), name
        assert args.brdf_weights == BRDF_WEIGHTS and args.func is run_train

    def test_settings_and_flags(self) -> None:
        args = _parser().parse_args(["train", "--cache", "a", "--out", "run", "--no-bf16", "--channels-last",
                                     "--data", "fields_per_chunk=8", "sphere_sizes=[4, 32]", "crop=face"])
        assert args.bf16 is False and args.channels_last is True
        assert args.data == [("fields_per_chunk", 8), ("sphere_sizes", [4, 32]), ("crop", "face")]

    @pytest.mark.parametrize("bad", [["--steps", "-1"], ["--data", "=1"], ["--data", "no_equals"]])
    def test_bad_arguments(self, bad, capsys) -> None:
        with pytest.raises(SystemExit):
            _parser().parse_args(["train", "--cache", "a", "--out", "run", *bad])
        capsys.readouterr()


def test_run_train_passes_the_settings_and_prints_the_weights(monkeypatch, capsys) -> None:
    seen = {}

    def fake_train(config: TrainConfig) -> dict:
        seen["config"] = config
        return {"steps": 3, "wall_time_s": 90.0,
                "weights": {"file": "ours.safetensors", "dtype": "float16", "sha256": "ab" * 32}}

    monkeypatch.setattr(train_cli, "train", fake_train)
    args = _parser().parse_args(["train", "--cache", "c1", "c2", "--out", "run", "--steps", "3",
                                 "--lr", "1e-3", "--workers", "0", "--data", "shuffle=2",
                                 "--model", "normalize_exposure=False", "--init", "w.safetensors",
                                 "--lambda-crop", "0.5", "--crop-pairs", "4", "--lambda-energy", "0.25"])
    assert run_train(args) == 0
    config = seen["config"]
    assert config.cache == ("c1", "c2") and config.steps == 3 and config.lr == 1e-3 and config.workers == 0
    assert config.model == {"normalize_exposure": False}
    assert (config.init, config.lambda_crop, config.crop_pairs, config.lambda_energy) == ("w.safetensors", 0.5, 4, 0.25)
    assert config.data == {"shuffle": 2} and config.bf16 is None  # decided by the run, not by the parser
    assert f"run/ours.safetensors  float16  sha256 {'ab' * 32}  3 steps in 1.5 min" in capsys.readouterr().out
