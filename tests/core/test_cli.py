"""Tests of kornia_ilum.core.cli: the argument types every sub-command of ``kornia-ilum`` shares."""

from __future__ import annotations

import argparse

import pytest

from kornia_ilum import cli
from kornia_ilum.core.cli import fraction, key_value, nonnegative_int, positive_int
from kornia_ilum_lab.evaluation import cli as evaluation_cli
from kornia_ilum_lab.synth import cli as synth_cli
from kornia_ilum_lab.train import cli as train_cli


class TestPositiveInt:
    def test_values(self):
        assert positive_int("1") == 1 and positive_int("512") == 512 and positive_int(" 7 ") == 7

    @pytest.mark.parametrize("text", ["0", "-3", "x", "1.5", ""])
    def test_rejects(self, text):
        with pytest.raises(argparse.ArgumentTypeError, match=rf"must be a positive integer, got {text!r}"):
            positive_int(text)

    def test_in_a_parser(self, capsys):
        parser = argparse.ArgumentParser(prog="p")
        parser.add_argument("--n", type=positive_int)
        assert parser.parse_args(["--n", "3"]).n == 3
        with pytest.raises(SystemExit):
            parser.parse_args(["--n", "0"])
        assert "argument --n: must be a positive integer, got '0'" in capsys.readouterr().err


class TestNonnegativeInt:
    def test_values(self):
        assert nonnegative_int("0") == 0 and nonnegative_int(" 0 ") == 0 and nonnegative_int("48") == 48

    @pytest.mark.parametrize("text", ["-1", "x", "-0.0"])
    def test_rejects(self, text):
        with pytest.raises(argparse.ArgumentTypeError, match="must be a positive integer"):
            nonnegative_int(text)


class TestFraction:
    def test_values(self):
        assert fraction("0") == 0.0 and fraction("0.15") == 0.15 and fraction(" 0.999 ") == 0.999

    @pytest.mark.parametrize("text", ["1", "-0.1", "x", "nan", "inf"])
    def test_rejects(self, text):
        with pytest.raises(argparse.ArgumentTypeError, match=r"must be a fraction in \[0, 1\)"):
            fraction(text)


class TestKeyValue:
    def test_values(self):
        assert key_value("colour_looks=0.3") == ("colour_looks", 0.3)
        assert key_value("crop=face") == ("crop", "face") and key_value("pairs=True") == ("pairs", True)
        assert key_value("plain_level=(0.5, 2)") == ("plain_level", (0.5, 2))

    @pytest.mark.parametrize("text", ["nothing", "=1", "two words=1"])
    def test_rejects(self, text):
        with pytest.raises(argparse.ArgumentTypeError, match="must be KEY=VALUE"):
            key_value(text)


def test_every_sub_command_uses_the_shared_types():
    """One definition: the sub-commands import the types, they do not define their own."""
    for module in (cli, synth_cli, train_cli, evaluation_cli):
        assert module.positive_int is positive_int, module.__name__
    assert synth_cli.nonnegative_int is nonnegative_int and synth_cli.fraction is fraction
    assert train_cli.key_value is key_value and evaluation_cli.key_value is key_value
