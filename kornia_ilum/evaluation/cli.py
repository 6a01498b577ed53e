r"""``kornia-ilum evaluate``: the held-out evaluation of the registered estimators, with the two oracles.

:func:`add_evaluate_parser` adds the command to the subparsers of ``kornia-ilum``; :func:`run_evaluate` runs
it: build the eval set (:func:`~kornia_ilum.evaluation.build_eval_set`), score every registered estimator (or
the ``--estimator`` ones, and ``--weights`` checkpoints) and the oracles, print the tables and write them as
Markdown and JSON.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from kornia_ilum.core.cli import positive_int
from kornia_ilum.evaluation.evaluate import build_eval_set, evaluate
from kornia_ilum.evaluation.report import format_markdown, summarize, write_report

__all__ = ["add_evaluate_parser", "parse_weights", "run_evaluate"]

_HELP = """\
Evaluate lighting estimators on the project's held-out eval set, which no training uses: the eval subjects
of the light-stage caches (subject_split), lit by the eval real maps of --hdri (hdri_split: about one name in
four) and by procedural skies and rooms of the eval sampler seed (EVAL_SEED = 1000003), photographed as the
training portraits are. The set is deterministic (the same samples every run). Scores every registered
estimator (an estimator without weights is reported as skipped) and two oracles, "SH of GT" (order-2 SH of
the ground truth, unclamped) and "mean of GT" (constant lighting with the true energy). Tables: L_rec per
sphere for indoor / outdoor / all, relative radiance per channel, and both per skin tone.

examples:
  kornia-ilum evaluate --cache lightstage/ --hdri ../shared/data/hdri ../shared/data/hdri_more --out eval/
  kornia-ilum evaluate --cache lightstage/ --cache eval_subjects/ --estimator uniform --samples 128
  kornia-ilum evaluate --cache lightstage/ --weights ours=runs/a/best.safetensors --json eval.json
  kornia-ilum evaluate --cache lightstage/ --background black --estimator sipr --estimator ours
"""


def parse_weights(text: str) -> tuple[str, str]:
    """``NAME=PATH.safetensors`` -> ``(NAME, PATH)``.

    Examples:
        >>> parse_weights("ours=runs/best.safetensors")
        ('ours', 'runs/best.safetensors')
    """
    name, sep, path = text.partition("=")
    if not (sep and name and path):
        raise argparse.ArgumentTypeError(f"weights must look like NAME=PATH.safetensors, got {text!r}")
    return name, path


def add_evaluate_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Add ``evaluate`` to ``subparsers``.

    Examples:
        >>> parser = argparse.ArgumentParser(prog="kornia-ilum")
        >>> _ = add_evaluate_parser(parser.add_subparsers(dest="command"))
        >>> args = parser.parse_args(["evaluate", "--cache", "a", "--cache", "b", "--estimator", "uniform"])
        >>> args.cache, args.estimator, args.samples, args.hdri, args.func.__name__
        (['a', 'b'], ['uniform'], 512, [], 'run_evaluate')
    """
    cmd = subparsers.add_parser(
        "evaluate",
        help="score the estimators and two oracles on the held-out eval set",
        description=_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    cmd.add_argument("--cache", action="append", required=True, metavar="DIR",
                     help="a light-stage cache; its eval subjects are used (repeatable)")
    cmd.add_argument("--hdri", nargs="*", default=[], metavar="DIR",
                     help="folders of real maps; their eval maps are used (default: procedural only)")
    cmd.add_argument("--samples", type=positive_int, default=512, metavar="N", help="eval portraits (512)")
    cmd.add_argument("--background", choices=("environment", "black"), default="environment",
                     help="the portraits' background: the matching environment (default, as ours is trained) "
                     "or black (the same portraits, as SIPR is trained)")
    cmd.add_argument("--estimator", action="append", default=None, metavar="NAME",
                     help="score only this registered estimator (repeatable; default: all)")
    cmd.add_argument("--weights", action="append", type=parse_weights, default=[], metavar="NAME=PATH",
                     help="also score a .safetensors checkpoint of the registered estimator class NAME "
                     "(its SHA-256 is printed and recorded)")
    cmd.add_argument("--no-oracles", action="store_true", help="leave out the two oracles")
    cmd.add_argument("--batch-size", type=positive_int, default=32, metavar="B", help="crops per batch (32)")
    cmd.add_argument("--out", metavar="DIR", help="write DIR/evaluation.md and DIR/evaluation.json")
    cmd.add_argument("--markdown", metavar="FILE", help="write the Markdown tables here")
    cmd.add_argument("--json", metavar="FILE", help="write the JSON summary here")
    cmd.set_defaults(func=run_evaluate)
    return cmd


def run_evaluate(args: argparse.Namespace) -> int:
    """Run ``evaluate`` from parsed arguments (module docstring); prints the tables, returns 0.

    ``args`` needs ``cache``; the other options of :func:`add_evaluate_parser` are optional (their defaults).

    Raises:
        ValueCheckError: no eval subject in the caches.
        HDRIOError: a ``--hdri`` folder is missing or holds no eval map.
    """
    t0 = time.perf_counter()
    eval_set = build_eval_set(args.cache, getattr(args, "hdri", None) or [], getattr(args, "samples", 512),
                              background=getattr(args, "background", "environment"), progress=True)
    weights = dict(getattr(args, "weights", None) or [])
    results = evaluate(eval_set, getattr(args, "estimator", None), weights,
                       oracles=not getattr(args, "no_oracles", False), batch_size=getattr(args, "batch_size", 32))
    summary = summarize(results, eval_set)
    summary["seconds"]["total"] = round(time.perf_counter() - t0, 2)
    print(format_markdown(summary), end="")
    out = getattr(args, "out", None)
    markdown = getattr(args, "markdown", None) or (Path(out) / "evaluation.md" if out else None)
    json_path = getattr(args, "json", None) or (Path(out) / "evaluation.json" if out else None)
    for path in write_report(summary, markdown, json_path):
        print(f"wrote {path}")
    print(f"eval set built in {eval_set.description['build_seconds']:.1f} s; total {summary['seconds']['total']:.1f} s")
    return 0
