"""kornia_ilum_lab.commands: the lab's sub-commands, as the library's ``kornia-ilum`` finds them."""

from __future__ import annotations

import argparse
import sys

from kornia_ilum_lab import commands


def test_each_command_adds_its_parser_lazily() -> None:
    for name in ("synth", "train", "evaluate", "ablate"):
        command = getattr(commands, name)
        assert isinstance(command, commands.Command) and command.help
        parser = argparse.ArgumentParser(prog="kornia-ilum")
        sub = parser.add_subparsers(dest="command")
        command.add_parser(sub)
        assert name in sub.choices


def test_loading_the_commands_loads_no_lab_package() -> None:
    """The entry points load this module for the help lines: it must not import the light stage or training."""
    assert not any(m.startswith(("kornia_ilum_lab.synth.", "kornia_ilum_lab.train.")) and m in sys.modules
                   and "commands" in m for m in sys.modules)
    source = open(commands.__file__).read()
    top = source.split("def _add_synth", 1)[0]
    assert "import kornia_ilum_lab." not in top and "from kornia_ilum_lab." not in top
