"""The lab's sub-commands of ``kornia-ilum``, found by the library through the ``kornia_ilum.commands`` entry
points: each is a :class:`Command` with its help line and the function that adds its parser.

Loading this module imports no heavy package: a command's own module (which may load the light stage) is
imported only when that command's parser is built, so ``kornia-ilum estimate`` and ``--help`` start without it.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass

__all__ = ["Command", "ablate", "evaluate", "synth", "train"]


@dataclass(frozen=True)
class Command:
    """A sub-command of ``kornia-ilum``: its ``help`` line, and ``add_parser(subparsers)``, which adds its parser
    (with a ``func`` default that runs it)."""

    help: str
    add_parser: Callable[[argparse._SubParsersAction], object]


def _add_synth(sub: argparse._SubParsersAction) -> None:
    from kornia_ilum_lab.synth.cli import (  # lazy: only when the command is named
        add_synth_check_skin_parser,
        add_synth_environments_parser,
        add_synth_subjects_parser,
    )

    add_synth_environments_parser(sub)
    add_synth_subjects_parser(sub)
    add_synth_check_skin_parser(sub)


def _add_train(sub: argparse._SubParsersAction) -> None:
    from kornia_ilum_lab.train.cli import add_train_parser  # lazy: the training package loads the light stage

    add_train_parser(sub)


def _add_evaluate(sub: argparse._SubParsersAction) -> None:
    from kornia_ilum_lab.evaluation.cli import add_evaluate_parser  # lazy: evaluation loads the light stage

    add_evaluate_parser(sub)


def _add_ablate(sub: argparse._SubParsersAction) -> None:
    from kornia_ilum_lab.ablation import add_ablate_parser  # lazy: the ablations train and evaluate

    add_ablate_parser(sub)


#: ``kornia-ilum synth``: environments, light-stage subjects and the skin check.
synth = Command("synthesis: lighting environments and light-stage subjects", _add_synth)
#: ``kornia-ilum train``.
train = Command("train an estimator on the light stage", _add_train)
#: ``kornia-ilum evaluate``.
evaluate = Command("score the estimators and two oracles on the held-out eval set", _add_evaluate)
#: ``kornia-ilum ablate``.
ablate = Command("the paper's ablations: one training run per row, and the table", _add_ablate)
