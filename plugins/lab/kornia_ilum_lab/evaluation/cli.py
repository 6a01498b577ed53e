r"""``kornia-ilum evaluate``: the held-out evaluation of the registered estimators, with the two oracles.

:func:`add_evaluate_parser` adds the command to the subparsers of ``kornia-ilum``; :func:`run_evaluate` runs
it: build the eval set (:func:`~kornia_ilum_lab.evaluation.build_eval_set`), score every registered estimator (or
the ``--estimator`` ones, and ``--weights`` checkpoints) and the oracles, run the checks
(:mod:`~kornia_ilum_lab.evaluation.checks`, ``--checks``) on every scored estimator, print the tables and write
them as Markdown and JSON.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

from kornia_ilum.core.cli import key_value, positive_int
from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.detection import DEFAULT_DETECTOR
from kornia_ilum.estimators import RUNTIMES
from kornia_ilum_lab.evaluation.checks import (
    CHECKS,
    EXPOSURE_FACTORS,
    check_runner,
    default_photos,
    face_crops,
    flash_checks,
)
from kornia_ilum_lab.evaluation.curve import equal_budget, format_equal_budget, learning_curve, read_curve, write_curve
from kornia_ilum_lab.evaluation.evaluate import BRDF_NAMES, build_eval_set, evaluate, load_checkpoint, load_estimator
from kornia_ilum_lab.evaluation.colour import colour_markdown
from kornia_ilum_lab.evaluation.flash import flash_crops, flash_markdown, load_flash_set
from kornia_ilum_lab.evaluation.report import format_markdown, summarize, write_report
from kornia_ilum_lab.evaluation.rule import shipping_rule

__all__ = ["DEFAULT_CHECKS", "add_evaluate_parser", "parse_checks", "parse_weights", "print_curve",
           "run_evaluate"]

#: The checks run unless ``--checks`` says otherwise (and ``"flash"`` with ``--flash``).
DEFAULT_CHECKS: tuple[str, ...] = tuple(c for c in CHECKS if c != "flash")

_HELP = """\
Evaluate lighting estimators on the project's held-out eval set, which no training uses: the eval subjects
of the light-stage caches (subject_split), lit by the eval real maps of --hdri (hdri_split: about one name in
four) and by procedural skies and rooms of the eval sampler seed (EVAL_SEED = 1000003), photographed as the
training portraits are. The set is deterministic (the same samples every run). Scores every registered
estimator (an estimator without weights is reported as skipped) and two oracles, "SH of GT" (order-2 SH of
the ground truth, unclamped) and "mean of GT" (constant lighting with the true energy). Tables: L_rec per
sphere for indoor / outdoor / all, relative radiance per channel, and both per skin tone.

Checks (--checks, default all four; "none" for none), on every scored estimator: "transfer", the label-free
transfer check (energy estimated with the background, over black and over grey, and the truth, per skin tone,
with 95 % intervals over subjects and the spread across tones);
"exposure", E(k x) / (k E(x)) for k = 0.5 and 0.25 on the eval crops and on real photos (--photos, default
scikit-image's astronaut, cut by --detector); "crop", the spread of the estimate over --jitters crops jittered
as a detector's boxes are, on the first --jitter-samples portraits rendered again as wider context crops;
"spread", whether the estimator's spread of the log energy holds the truth as often as it says (within +-1
and +-2 spreads, per skin tone; estimators without a spread are reported as such); "colour", the same crops
greyscale, desaturated, white-balanced warmer and cooler and graded (teal-orange, faded, sepia): how far the
main light turns and how its strength changes, on the eval crops, the real photos and the real-flash photos;
"flash" (with --flash DIR, which adds it), real faces under one flash of known direction each (the Extended
Yale Face Database B's names: yaleB01_P00A+035E+40.pgm): the main light's direction error by the flash's
angle to the camera axis, left/right and up/down sign agreement, the spread of the strength across people
under one flash. With --flash and no --cache, only the real-flash and colour checks on those photographs run.

examples:
  kornia-ilum evaluate --cache lightstage/ --hdri ../shared/data/hdri ../shared/data/hdri_more --out eval/
  kornia-ilum evaluate --cache lightstage/ --cache eval_subjects/ --estimator uniform --samples 128
  kornia-ilum evaluate --cache lightstage/ --weights ours=runs/a/best.safetensors --json eval.json
  kornia-ilum evaluate --cache lightstage/ --background black --estimator sipr --estimator ours
  kornia-ilum evaluate --cache lightstage/ --checks transfer,exposure --photos me.jpg group.png --out eval/
  kornia-ilum evaluate --cache lightstage/ --flash ../shared/data/yaleb_dev --weights ours=runs/a/ours.safetensors
  kornia-ilum evaluate --flash ../shared/data/yaleb_dev --estimator ours --estimator sh   # real flashes only
  kornia-ilum evaluate --cache lightstage/ --curve runs/a --curve runs/b   # two curves, at equal budgets
  kornia-ilum evaluate --curve docs/_static/ours22_curve.csv --curve runs/b/curve.csv   # from written curves
"""


def parse_checks(text: str) -> tuple[str, ...]:
    """A comma list of checks (``transfer,exposure,crop``), or ``none`` / ``all``.

    Args:
        text: the value of ``--checks``; blanks around the names are ignored.

    Returns:
        the checks named, in the order of :data:`~kornia_ilum_lab.evaluation.checks.CHECKS`; empty for ``none``
        (or an empty text).

    Raises:
        argparse.ArgumentTypeError: an unknown check (argparse reports it as a usage error).

    Examples:
        >>> parse_checks("crop,transfer"), parse_checks("none"), parse_checks("all")[-2:]
        (('transfer', 'crop'), (), ('colour', 'flash'))
    """
    names = [t.strip() for t in text.split(",") if t.strip()]
    if names in (["none"], []):
        return ()
    if names == ["all"]:
        return CHECKS
    unknown = [n for n in names if n not in CHECKS]
    if unknown:
        raise argparse.ArgumentTypeError(f"unknown checks {unknown}; choose from {', '.join(CHECKS)}, all or "
                                         "none")
    return tuple(c for c in CHECKS if c in names)


def _jitters(text: str) -> int:
    value = positive_int(text)
    if value < 2:
        raise argparse.ArgumentTypeError(f"must be at least 2 (a spread), got {text!r}")
    return value


def _factor(text: str) -> float:
    value = float(text)
    if not value >= 1.0:
        raise argparse.ArgumentTypeError(f"must be a number >= 1, got {text!r}")
    return value


def parse_weights(text: str) -> tuple[str, str]:
    """``NAME=PATH.safetensors`` -> ``(NAME, PATH)``.

    Args:
        text: the value of ``--weights``; split at its first ``=``.

    Returns:
        ``(name, path)``, as given (the path is not checked here).

    Raises:
        argparse.ArgumentTypeError: no ``=``, or an empty name or path.

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

    Args:
        subparsers: from ``parser.add_subparsers()`` of the ``kornia-ilum`` parser.

    Returns:
        the ``evaluate`` parser; its ``func`` default is :func:`run_evaluate`.

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
    cmd.add_argument("--cache", action="append", metavar="DIR",
                     help="a light-stage cache; its eval subjects are used (repeatable; needed unless every "
                     "--curve is a curve.csv)")
    cmd.add_argument("--hdri", nargs="*", default=[], metavar="DIR",
                     help="folders of real maps; their eval maps are used (default: procedural only)")
    cmd.add_argument("--samples", type=positive_int, default=512, metavar="N", help="eval portraits (512)")
    cmd.add_argument("--background", choices=("environment", "black"), default="environment",
                     help="the portraits' background: the matching environment (default, as ours is trained) "
                     "or black (the same portraits, as SIPR is trained)")
    cmd.add_argument("--portraits", nargs="*", default=[], metavar="KEY=VALUE", type=key_value,
                     help="settings of the eval portraits (PortraitConfig's, e.g. surroundings=1.0: a wall "
                     "and a floor lit by the same environment; linear_response=1.0; plain_background=1.0); "
                     "the same draws otherwise, so every estimator is scored on the same portraits")
    cmd.add_argument("--estimator", action="append", default=None, metavar="NAME",
                     help="score only this registered estimator (repeatable; default: all)")
    cmd.add_argument("--weights", action="append", type=parse_weights, default=[], metavar="NAME=PATH",
                     help="also score a .safetensors checkpoint of the registered estimator class NAME "
                     "(its SHA-256 is printed and recorded)")
    cmd.add_argument("--checks", type=parse_checks, default=None, metavar="LIST",
                     help="checks on every scored estimator: a comma list of transfer, exposure, crop, spread, "
                     "colour, flash, or all, or none (default: all but flash; flash too with --flash)")
    cmd.add_argument("--flash", metavar="DIR",
                     help="real photographs under one known flash each (e.g. ../shared/data/yaleb_dev, read in "
                     "place): adds the flash check and the colour check on them")
    cmd.add_argument("--jitter-samples", type=positive_int, default=256, metavar="N",
                     help="portraits of the crop check: the first N of the eval set (256, at most --samples)")
    cmd.add_argument("--jitters", type=_jitters, default=8, metavar="J",
                     help="jittered crops per portrait in the crop check (at least 2; 8)")
    cmd.add_argument("--colour-samples", type=positive_int, default=256, metavar="N",
                     help="portraits of the colour check: the first N of the eval set (256; seven looks each)")
    cmd.add_argument("--context", type=_factor, default=1.5, metavar="F",
                     help="the crop check's context crops: F times the nominal face crop (1.5)")
    cmd.add_argument("--photos", nargs="+", default=None, metavar="FILE",
                     help="real photos of the exposure and colour checks (default: scikit-image's astronaut)")
    cmd.add_argument("--detector", default=DEFAULT_DETECTOR, metavar="NAME",
                     help=f"the detector that cuts the real photos' face crops ({DEFAULT_DETECTOR})")
    cmd.add_argument("--tta", type=positive_int, default=None, metavar="N",
                     help="also score every estimator with test-time augmentation over N jittered crops and "
                     "their mirrors (as NAME+ttaN; 2N passes per crop)")
    cmd.add_argument("--runtime", action="append", default=[], metavar="RUNTIME",
                     choices=[r for r in RUNTIMES if r not in ("auto", "eager")],
                     help="also score every estimator computed by this runtime (bf16, onnx, onnx-int8), as "
                     "NAME+RUNTIME; repeat for several")
    cmd.add_argument("--curve", action="append", default=[], metavar="RUN",
                     help="instead of the tables: the learning curve of a training run kept with "
                     "--snapshot-every, L_rec of each snapshot, written to RUN/curve.csv and RUN/curve.png "
                     "(repeatable; with several, also the runs at equal portraits seen and equal wall time; "
                     "a path ending in .csv is a curve.csv written before, read instead of scored)")
    cmd.add_argument("--rule", action="store_true",
                     help="judge each --weights file NAME=FILE against the shipped weights of NAME by the shipping "
                     "rule (L_rec limits, tone spread, real flash, colour check; docs/training.rst); needs the "
                     "transfer and colour checks and --flash")
    cmd.add_argument("--no-oracles", action="store_true", help="leave out the two oracles")
    cmd.add_argument("--batch-size", type=positive_int, default=32, metavar="B", help="crops per batch (32)")
    cmd.add_argument("--out", metavar="DIR", help="write DIR/evaluation.md and DIR/evaluation.json")
    cmd.add_argument("--markdown", metavar="FILE", help="write the Markdown tables here")
    cmd.add_argument("--json", metavar="FILE", help="write the JSON summary here")
    cmd.set_defaults(func=run_evaluate)
    return cmd


def print_curve(run: str, rows: list[dict]) -> None:
    """Write a run's learning curve (:func:`~kornia_ilum_lab.evaluation.curve.write_curve`) and print it.

    Args:
        run: the run's folder; ``curve.csv`` (and ``curve.png``) are written into it.
        rows: the rows of :func:`~kornia_ilum_lab.evaluation.curve.learning_curve`.

    Returns:
        None; the table (wall time in minutes) and the paths written are printed.

    Examples:
        Without matplotlib (hidden here), only the CSV is written:

        >>> import tempfile
        >>> from unittest import mock
        >>> rows = [{"step": 400, "samples": 12800, "elapsed_s": 393.8, "diffuse": 0.16, "matte_silver": 0.18,
        ...          "mirror": 0.33}]
        >>> with tempfile.TemporaryDirectory() as run, mock.patch.dict("sys.modules", {"matplotlib": None}):
        ...     print_curve(run, rows)  # doctest: +ELLIPSIS
        learning curve of ...: L_rec on the eval split per snapshot
        | step | portraits | wall time (min) | diffuse | matte_silver | mirror |
        |---:|---:|---:|---:|---:|---:|
        | 400 | 12800 | 6.6 | 0.1600 | 0.1800 | 0.3300 |
        wrote .../curve.csv
    """
    print(f"learning curve of {run}: L_rec on the eval split per snapshot")
    print("| step | portraits | wall time (min) | " + " | ".join(BRDF_NAMES) + " |")
    print("|---:|---:|---:|" + "---:|" * len(BRDF_NAMES))
    for r in rows:
        print(f"| {r['step']} | {r['samples']} | {r['elapsed_s'] / 60:.1f} | "
              + " | ".join(f"{r[b]:.4f}" for b in BRDF_NAMES) + " |")
    for path in write_curve(run, rows):
        print(f"wrote {path}")


def run_evaluate(args: argparse.Namespace) -> int:
    """Run ``evaluate`` from parsed arguments (module docstring); prints the tables, returns 0.

    ``args`` needs ``cache`` unless every ``curve`` is a ``curve.csv``; the other options of
    :func:`add_evaluate_parser` are optional (their defaults).

    Args:
        args: the parsed command line of :func:`add_evaluate_parser`, or any namespace with some of its
            attributes.

    Returns:
        0, the command's exit status.

    Raises:
        ValueCheckError: no cache (and curves to score), or no eval subject in the caches.
        HDRIOError: a ``--hdri`` folder is missing or holds no eval map.

    Examples:
        Two curves written before, compared at equal budgets (no cache needed):

        >>> import contextlib, io, tempfile
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     for name, diffuse in (("a", 0.2), ("b", 0.15)):
        ...         _ = Path(tmp, f"{name}.csv").write_text("step,samples,elapsed_s,diffuse,matte_silver,mirror\\n"
        ...                                                 f"400,12800,393.8,{diffuse},0.18,0.33\\n")
        ...     with contextlib.redirect_stdout(io.StringIO()) as out:
        ...         code = run_evaluate(argparse.Namespace(curve=[f"{tmp}/a.csv", f"{tmp}/b.csv"]))
        >>> code, "at equal budgets" in out.getvalue()
        (0, True)
        >>> run_evaluate(argparse.Namespace())  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        kornia.core.exceptions.ValueCheckError: evaluate needs --cache DIR (a light-stage cache with eval subjects); ...
    """
    t0 = time.perf_counter()
    hdri, samples = getattr(args, "hdri", None) or [], getattr(args, "samples", 512)
    background = getattr(args, "background", "environment")
    curves = getattr(args, "curve", None) or []
    written = [c for c in curves if str(c).endswith(".csv")]  # curves scored before: read, not scored again
    flash_dir = getattr(args, "flash", None)
    checks = _checks(args, flash_dir)
    if not getattr(args, "cache", None) and flash_dir and not curves:
        return _flash_only(args, flash_dir, checks)
    if not getattr(args, "cache", None) and not (curves and len(written) == len(curves)):
        raise ValueCheckError("evaluate needs --cache DIR (a light-stage cache with eval subjects); only "
                              "--curve with curve.csv files, or --flash DIR, goes without")
    portraits = dict(getattr(args, "portraits", None) or [])
    eval_set = None if len(written) == len(curves) and curves else build_eval_set(
        args.cache, hdri, samples=samples, background=background, progress=True, portraits=portraits)
    if curves:
        found = {}
        for run in curves:
            if run in written:
                found[run] = read_curve(run)
                continue
            found[run] = learning_curve(eval_set, run, getattr(args, "batch_size", 32))
            print_curve(run, found[run])
        if len(found) > 1:
            print("\nat equal budgets (each run at its last snapshot within the budget):")
            print(format_equal_budget(equal_budget(found)), end="")
        return 0
    options = {"ks": list(EXPOSURE_FACTORS), "jitters": getattr(args, "jitters", 8), "position": 0.10,
               "extent": 0.15, "seed": 0, "colour_samples": getattr(args, "colour_samples", 256)}
    context_set, photos, about_photos = None, None, {}
    if "crop" in checks:
        subset = min(getattr(args, "jitter_samples", 256), samples)
        context_set = build_eval_set(args.cache, hdri, samples=subset, background=background,
                                     context=getattr(args, "context", 1.5), progress=True,
                                     portraits=portraits)
    if "exposure" in checks or "colour" in checks:  # the real photos of both
        listed = getattr(args, "photos", None)
        detector = getattr(args, "detector", DEFAULT_DETECTOR)
        photos, names, no_face = face_crops(listed or default_photos(), detector)
        about_photos = {"photo_names": names, "photos_left_out": no_face, "detector": detector}
        for name, reason in no_face.items():
            print(f"real photos: {name} left out: {reason}")
    flash = _flash_photos(flash_dir, getattr(args, "detector", DEFAULT_DETECTOR)) if flash_dir else None
    if flash is not None:
        about_photos["flash"] = {"folder": str(flash_dir), "photos": len(flash[0]), "no_face": int(flash[2].sum())}
    weights = list(getattr(args, "weights", None) or [])
    batch_size = getattr(args, "batch_size", 32)
    runner = check_runner(eval_set, checks, context_set=context_set, photos=photos, flash=flash,
                          batch_size=batch_size, **options) if checks else None
    results = evaluate(eval_set, getattr(args, "estimator", None), weights=weights,
                       oracles=not getattr(args, "no_oracles", False), batch_size=batch_size, checks=runner,
                       tta=getattr(args, "tta", None), runtimes=getattr(args, "runtime", None) or ())
    if checks:
        results["checks"] = {"names": list(checks), **options, **about_photos,
                             "context_set": None if context_set is None else context_set.description}
    summary = summarize(results, eval_set)
    if getattr(args, "rule", False):
        summary["rule"] = [shipping_rule(summary, name, name.split("@")[0]) for name in summary["table1_l_rec"]
                           if "@" in name and name.split("@")[0] in summary["table1_l_rec"]]
    summary["seconds"]["total"] = round(time.perf_counter() - t0, 2)
    print(format_markdown(summary), end="")
    for path in write_report(summary, *_report_paths(args)):
        print(f"wrote {path}")
    print(f"eval set built in {eval_set.description['build_seconds']:.1f} s; total {summary['seconds']['total']:.1f} s")
    return 0


def _checks(args: argparse.Namespace, flash_dir: str | None) -> tuple[str, ...]:
    """The checks to run: ``--checks``, else the defaults (and ``"flash"`` with ``--flash``)."""
    given = getattr(args, "checks", None)
    checks = tuple(given) if given is not None else DEFAULT_CHECKS + (("flash",) if flash_dir else ())
    if "flash" in checks and not flash_dir:
        raise ValueCheckError("the flash check needs --flash DIR: real photographs under one known flash each "
                              "(e.g. ../shared/data/yaleb_dev)")
    return checks


def _flash_photos(folder: str, detector: str) -> tuple:
    """The real-flash photographs of ``folder`` and their crops, cut once for every estimator."""
    flash_set = load_flash_set(folder)
    print(f"real-flash check: {len(flash_set)} photographs of {len(set(flash_set.subjects))} people in {folder}")
    crops, fell_back = flash_crops(flash_set, detector)
    return flash_set, crops, fell_back


def _flash_only(args: argparse.Namespace, folder: str, checks: tuple[str, ...]) -> int:
    """``--flash`` without ``--cache``: the real-flash check (and the colour check on the same photographs) for
    the chosen estimators and weight files; prints the tables and writes them where asked."""
    flash = _flash_photos(folder, getattr(args, "detector", DEFAULT_DETECTOR))
    chosen = [c for c in checks if c in ("flash", "colour")]
    methods: dict[str, Any] = {}
    names = list(getattr(args, "estimator", None) or ["ours"])
    loaded = [(name, load_estimator(name)) for name in names]
    for name, path in getattr(args, "weights", None) or []:
        estimator, digest = load_checkpoint(name, path)
        loaded.append((f"{name}@{digest[:8]}", estimator))
    for label, estimator in loaded:
        methods[label] = flash_checks(estimator, flash, chosen, batch_size=getattr(args, "batch_size", 32))
    lines = [f"# Real photographs under one known flash: {folder}"]
    lines += colour_markdown({n: t["colour"] for n, t in methods.items() if "colour" in t})
    lines += flash_markdown({n: t["flash"] for n, t in methods.items() if "flash" in t})
    text = "\n".join(lines) + "\n"
    print(text, end="")
    summary = {"flash": {"folder": str(folder), "photos": len(flash[0]), "no_face": int(flash[2].sum())},
               "checks": methods}
    for path in write_report(summary, *_report_paths(args), text=text):
        print(f"wrote {path}")
    return 0


def _report_paths(args: argparse.Namespace) -> tuple[Path | None, Path | None]:
    """Where the Markdown and JSON go: ``--markdown`` and ``--json``, else ``--out``'s two files, else nowhere."""
    out = getattr(args, "out", None)
    markdown = getattr(args, "markdown", None) or (Path(out) / "evaluation.md" if out else None)
    return markdown, getattr(args, "json", None) or (Path(out) / "evaluation.json" if out else None)
