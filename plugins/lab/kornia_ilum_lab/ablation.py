r"""The paper's ablations (LeGendre et al. 2020, Table 4), as one command: ``kornia-ilum ablate``.

Each row of :data:`ABLATIONS` is a training run of ``ours`` that differs from the baseline row in one thing,
and the eval set it is scored on. The baseline is ``ours``'s training recipe (:data:`BASELINE`, the flags of
issue 22's long run: the crop term and the energy term on) at a reduced budget (:data:`ABLATION_STEPS` steps
of 32 by default). The rows:

- ``no-multi-scale``: the rendering loss at 32 px only (:attr:`~kornia_ilum_lab.train.TrainConfig.multi_scale`);
- ``no-adversarial``: no adversarial term, so no discriminator (``lambda_adv = 0``);
- ``no-face-detector``: crops that no face detector placed: the crop's centre moves by up to half its side and
  its side changes by up to a factor ``e^0.7`` (against 0.10 and ``e^0.15`` for a detector's crop). The light
  stage renders head-and-shoulders framings in which the face takes most of the frame, so a random crop of the
  render is such a crop. Scored on crops of the same kind: at inference there is no detector either;
- ``black-background``: the portraits over black, in training and in the eval set (as SIPR is trained);
- ``log-l2``: ``mean((log(1 + L_pred) - log(1 + L_true))^2)`` on the mirror ball in place of ``L_rec``
  (:func:`~kornia_ilum_lab.train.losses.log_l2_loss`);
- ``background-only``: the backgrounds alone, no subject, in training and in the eval set.

:func:`run_ablations` trains the rows one after the other, each in ``OUT/NAME`` (a run that was cut resumes
bit-exactly from its checkpoint; a finished one is not trained again), scores every row and the baseline on
the row's eval set, and writes ``OUT/ablations.md``, ``OUT/ablations.rst`` (the table of docs/training.rst)
and ``OUT/ablations.json``. A row's paired differences
(:func:`~kornia_ilum_lab.evaluation.report.paired_differences`) are against the baseline on the same portraits
with the row's input, so a row whose input differs (no face, black, other crops) is compared with what the
baseline does with that input too.
"""

from __future__ import annotations

import argparse
import json
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from kornia_ilum.core.cli import positive_int
from kornia_ilum.core.errors import ValueCheckError
from kornia_ilum.core.files import atomic_write
from kornia_ilum_lab.evaluation import (
    BRDF_NAMES,
    EvalSet,
    build_eval_set,
    load_checkpoint,
    paired_differences,
    predict,
    score,
)
from kornia_ilum_lab.train import TrainConfig, train

__all__ = ["ABLATIONS", "ABLATION_STEPS", "BASELINE", "Ablation", "ablation_config", "add_ablate_parser",
           "format_ablations", "run_ablations"]

#: The baseline's training settings beyond :class:`~kornia_ilum_lab.train.TrainConfig`'s defaults: those of issue
#: 22's long ``ours`` run (the crop term and the energy term; the shipped weights were fine-tuned with the crop
#: term only, the model card says why), so that each row takes one thing away from the full recipe.
BASELINE: dict[str, Any] = {"lambda_crop": 1.0, "crop_pairs": 8, "lambda_energy": 0.5}
#: The reduced budget of every row: steps of 32.
ABLATION_STEPS = 900


@dataclass(frozen=True)
class Ablation:
    r"""One row of the ablation table.

    Args:
        name: the row's name (``kornia-ilum ablate --only NAME``).
        paper: what the row takes away, as the paper's Table 4 names it.
        train: :class:`~kornia_ilum_lab.train.TrainConfig` settings over :data:`BASELINE`; ``"data"`` is merged
            into the baseline's data settings.
        background: the eval set's background (:func:`~kornia_ilum_lab.evaluation.build_eval_set`).
        portraits: the eval set's other portrait settings (``portraits`` of
            :func:`~kornia_ilum_lab.evaluation.build_eval_set`).

    Examples:
        >>> row = ABLATIONS["no-face-detector"]
        >>> row.paper, row.background
        ('no face detector (random crops)', 'environment')
        >>> row.eval_key  # rows with this key share one eval set
        ('environment', (('crop_extent', 0.7), ('crop_position', 0.5)))
        >>> Ablation("mine", "my change", {"lambda_adv": 0.0}).eval_key == ABLATIONS["baseline"].eval_key
        True
    """

    name: str
    paper: str
    train: dict[str, Any] = field(default_factory=dict)
    background: str = "environment"
    portraits: dict[str, Any] = field(default_factory=dict)

    @property
    def eval_key(self) -> tuple[str, tuple[tuple[str, Any], ...]]:
        """What fixes the row's eval set: rows with the same key share it."""
        return self.background, tuple(sorted(self.portraits.items()))


_WIDE_CROPS = {"crop_position": 0.5, "crop_extent": 0.7}

#: The rows, the baseline first (module docstring).
ABLATIONS: dict[str, Ablation] = {a.name: a for a in (
    Ablation("baseline", "ours, the full method"),
    Ablation("no-multi-scale", "no multi-scale losses", {"multi_scale": False}),
    Ablation("no-adversarial", "no adversarial loss", {"lambda_adv": 0.0}),
    Ablation("no-face-detector", "no face detector (random crops)", {"data": _WIDE_CROPS},
             portraits=_WIDE_CROPS),
    Ablation("black-background", "black background", {"data": {"background": "black", "plain_background": 0.0}},
             background="black"),
    Ablation("log-l2", "log-L2 loss on the HDR lighting instead of the rendering losses", {"loss": "log_l2"}),
    Ablation("background-only", "background only (no face)", {"data": {"subject": False, "plain_background": 0.0}},
             portraits={"subject": False}),
)}


def ablation_config(name: str, out: str | os.PathLike[str], **settings: Any) -> TrainConfig:
    r"""The training run of row ``name``: :data:`BASELINE`, then ``settings`` (the caches, steps, seed, ...),
    then the row's own changes, in ``out``.

    Args:
        name: the row (:data:`ABLATIONS`).
        out: the run's folder (:attr:`~kornia_ilum_lab.train.TrainConfig.out`).
        settings: other :class:`~kornia_ilum_lab.train.TrainConfig` settings (``cache`` at least); their ``data``
            is merged with the row's, the row's settings winning.

    Returns:
        the row's :class:`~kornia_ilum_lab.train.TrainConfig`.

    Raises:
        ValueCheckError: no row ``name``.

    Examples:
        >>> config = ablation_config("no-adversarial", "runs/x", cache=("cache",), steps=900)
        >>> config.lambda_adv, config.lambda_energy, config.steps
        (0.0, 0.5, 900)
        >>> ablation_config("black-background", "runs/y", cache=("cache",)).data["background"]
        'black'
    """
    if name not in ABLATIONS:
        raise ValueCheckError(f"no ablation {name!r}; the rows are: {', '.join(ABLATIONS)}")
    row = ABLATIONS[name].train
    merged: dict[str, Any] = {**BASELINE, **settings, **{k: v for k, v in row.items() if k != "data"}}
    merged["data"] = {**settings.get("data", {}), **row.get("data", {})}
    return TrainConfig(out=str(out), **merged)


def _row_scores(eval_set: EvalSet, weights: Path, batch_size: int) -> tuple[dict[str, Any], str]:
    model, digest = load_checkpoint("ours", weights)
    return score(predict(model, eval_set.images, batch_size), eval_set.mirror_ball), digest


def run_ablations(names: Sequence[str], out: str | os.PathLike[str], *, cache: Sequence[str],
                  eval_cache: Sequence[str], hdri: Sequence[str] = (), steps: int = ABLATION_STEPS,
                  samples: int = 512, batch_size: int = 32, **settings: Any) -> dict[str, Any]:
    r"""Train rows ``names`` (the baseline always) in ``out/NAME``, score them, write ``out/ablations.md``,
    ``out/ablations.rst`` and ``out/ablations.json``; returns the JSON's content.

    Args:
        names: the rows (:data:`ABLATIONS`), in the order to train them.
        out: the folder of the runs and the tables.
        cache: the light-stage caches of training (their ``"train"`` subjects).
        eval_cache: the caches of the eval set (their ``"eval"`` subjects).
        hdri: folders of real maps: their ``"train"`` maps in training, ``"eval"`` maps in the eval sets.
        steps: steps of 32 per row.
        samples: portraits per eval set.
        batch_size: crops per forward pass in the scoring.
        settings: other :class:`~kornia_ilum_lab.train.TrainConfig` settings of every row (``seed``, ``threads``,
            ``log_every``, ...).

    Returns:
        the content of ``ablations.json``: ``steps``, ``batch``, ``samples``, ``baseline`` (:data:`BASELINE`),
        ``cache``, ``eval_cache``, ``hdri``, and ``rows``: per row, ``paper``, ``weights``, ``sha256``,
        ``wall_time_s``, ``background``, ``portraits``, ``l_rec`` and ``baseline_l_rec`` per sphere, and
        ``paired_vs_baseline`` (:func:`~kornia_ilum_lab.evaluation.report.paired_differences`).

    Raises:
        ValueCheckError: a name of ``names`` is no row (checked before any training).

    Examples:
        The rows are checked before anything is trained:

        >>> run_ablations(["no-such-row"], "runs/ablations", cache=[], eval_cache=[])  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        kornia.core.exceptions.ValueCheckError: no ablation ['no-such-row']; the rows are: baseline, ...

        A real run trains one model per row (light-stage caches with train and eval subjects):

        >>> result = run_ablations(["log-l2"], "runs/ablations", cache=["lightstage/"],
        ...                        eval_cache=["lightstage/"])  # doctest: +SKIP
        >>> list(result["rows"])  # doctest: +SKIP
        ['baseline', 'log-l2']
    """
    unknown = [n for n in names if n not in ABLATIONS]
    if unknown:
        raise ValueCheckError(f"no ablation {unknown}; the rows are: {', '.join(ABLATIONS)}")
    rows = ["baseline", *[n for n in dict.fromkeys(names) if n != "baseline"]]
    out = Path(out)
    weights = {}
    for name in rows:
        print(f"ablation {name}: training {out / name}", flush=True)
        config = ablation_config(name, out / name, cache=tuple(cache), hdri=tuple(hdri), steps=steps, **settings)
        summary = train(config)
        weights[name] = (out / name / summary["weights"]["file"], summary["wall_time_s"])
    sets: dict[Any, tuple[EvalSet, dict[str, Any]]] = {}  # eval key -> the set and the baseline's scores on it
    table: dict[str, Any] = {}
    for name in rows:
        row = ABLATIONS[name]
        if row.eval_key not in sets:
            eval_set = build_eval_set(eval_cache, hdri, samples=samples, background=row.background,
                                      portraits=row.portraits, progress=True)
            sets[row.eval_key] = eval_set, _row_scores(eval_set, weights["baseline"][0], batch_size)[0]
        eval_set, base = sets[row.eval_key]
        scores, digest = _row_scores(eval_set, weights[name][0], batch_size)
        table[name] = {
            "paper": row.paper, "weights": str(weights[name][0]), "sha256": digest,
            "wall_time_s": round(weights[name][1], 1), "background": row.background,
            "portraits": {k: repr(v) for k, v in row.portraits.items()},
            "l_rec": {b: float(scores[b].double().mean()) for b in BRDF_NAMES},
            "baseline_l_rec": {b: float(base[b].double().mean()) for b in BRDF_NAMES},
            "paired_vs_baseline": paired_differences(scores, base),
        }
    result = {"steps": steps, "batch": settings.get("batch", 32), "samples": samples, "baseline": BASELINE,
              "cache": list(cache), "eval_cache": list(eval_cache), "hdri": list(hdri), "rows": table}
    out.mkdir(parents=True, exist_ok=True)
    atomic_write(out / "ablations.json", lambda tmp: tmp.write_text(json.dumps(result, indent=2) + "\n"))
    for fmt, suffix in (("markdown", "md"), ("rst", "rst")):
        text = format_ablations(result, fmt)
        atomic_write(out / f"ablations.{suffix}", lambda tmp, text=text: tmp.write_text(text))
    return result


def format_ablations(result: dict[str, Any], fmt: str = "markdown") -> str:
    r"""The ablation table: per row, what it takes away, its eval input, ``L_rec`` per sphere, the baseline's on
    the same eval set, and the paired difference with its 95 % interval (positive: the row is worse).

    Args:
        result: what :func:`run_ablations` returns (or ``ablations.json``).
        fmt: ``"markdown"`` (``ablations.md``) or ``"rst"`` (``ablations.rst``: the list-table of
            docs/training.rst, pasted as it is).

    Returns:
        the table, ending with a newline.

    Raises:
        ValueCheckError: another ``fmt``.

    Examples:
        >>> same = {"mean": 0.0, "low": -0.001, "high": 0.001}
        >>> row = {"paper": "the full method", "background": "environment", "portraits": {},
        ...        "l_rec": {b: 0.1 for b in BRDF_NAMES}, "baseline_l_rec": {b: 0.1 for b in BRDF_NAMES},
        ...        "paired_vs_baseline": {b: same for b in BRDF_NAMES}}
        >>> result = {"steps": 900, "batch": 32, "samples": 512, "rows": {"baseline": row}}
        >>> print(format_ablations(result).splitlines()[-1])
        | baseline | the full method | environment | 0.1000 / 0.1000 / 0.1000 | 0.1000 / 0.1000 / 0.1000 | (itself) |
        >>> format_ablations(result, "rst").splitlines()[0]
        '.. list-table::'
    """
    head = ("row", "takes away", "eval input", "L_rec", "baseline on that input", "row - baseline [95 %]")
    rows = []
    for name, row in result["rows"].items():
        diff = "; ".join(f"{p['mean']:+.4f} [{p['low']:+.4f}, {p['high']:+.4f}]"
                         for p in (row["paired_vs_baseline"][b] for b in BRDF_NAMES))
        what = row["background"] + "".join(f", {k}={v}" for k, v in row["portraits"].items())
        rows.append((name, row["paper"], what, " / ".join(f"{row['l_rec'][b]:.4f}" for b in BRDF_NAMES),
                     " / ".join(f"{row['baseline_l_rec'][b]:.4f}" for b in BRDF_NAMES),
                     diff if name != "baseline" else "(itself)"))
    if fmt == "markdown":
        lines = [f"Ablations: `ours`, {result['steps']} steps of {result['batch']} per row, {result['samples']} "
                 "eval portraits; L_rec (lower is better) as diffuse / matte silver / mirror.", "",
                 "| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
        lines += ["| " + " | ".join(cells) + " |" for cells in rows]
    elif fmt == "rst":
        lines = [".. list-table::", "   :header-rows: 1", "   :widths: 12 16 16 18 18 30", ""]
        head = tuple(c.replace("L_rec", "``L_rec``") for c in head)
        for cells in [head, *[(f"``{r[0]}``", *r[1:]) for r in rows]]:
            lines += [f"   * - {cells[0]}", *[f"     - {c}" for c in cells[1:]]]
    else:
        raise ValueCheckError(f"fmt must be 'markdown' or 'rst', got {fmt!r}")
    return "\n".join(lines) + "\n"


_HELP = """\
Run the paper's ablations (LeGendre et al. 2020, Table 4): train ours once per row, each without one part of
the method, at a reduced budget; score every row and the baseline on the row's eval set; write
OUT/ablations.md and OUT/ablations.json. Rows: {rows}.

Each run lives in OUT/NAME and resumes from its checkpoint when the command is run again (a finished run is
not trained again), so the table can be built over several sessions; --only NAME trains and scores one row
(and the baseline).

examples:
  kornia-ilum ablate --cache lightstage/ --eval-cache lightstage/ --hdri ../shared/data/hdri --out runs/ablations
  kornia-ilum ablate --cache lightstage/ --eval-cache lightstage/ --out runs/ablations --only log-l2
"""


def add_ablate_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Add ``ablate`` to the ``kornia-ilum`` subcommands.

    Args:
        subparsers: the subparsers of ``kornia-ilum``'s parser (:meth:`argparse.ArgumentParser.add_subparsers`).

    Returns:
        the ``ablate`` parser; its ``func`` default is :func:`run_ablate`.

    Examples:
        >>> parser = argparse.ArgumentParser()
        >>> _ = add_ablate_parser(parser.add_subparsers())
        >>> args = parser.parse_args(["ablate", "--cache", "c/", "--eval-cache", "e/", "--out", "runs/a",
        ...                           "--only", "log-l2"])
        >>> args.only, args.steps == ABLATION_STEPS, args.func is run_ablate
        (['log-l2'], True, True)
    """
    cmd = subparsers.add_parser("ablate", help="the paper's ablations: one training run per row, and the table",
                                description=_HELP.format(rows=", ".join(ABLATIONS)),
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    cmd.add_argument("--cache", nargs="+", required=True, metavar="DIR", help="light-stage caches of training")
    cmd.add_argument("--eval-cache", nargs="+", required=True, metavar="DIR",
                     help="light-stage caches whose eval subjects are scored")
    cmd.add_argument("--hdri", nargs="*", default=[], metavar="DIR", help="folders of real lat-long HDR maps")
    cmd.add_argument("--out", required=True, metavar="OUT", help="the folder of the runs and the table")
    cmd.add_argument("--only", nargs="+", default=None, metavar="NAME", choices=list(ABLATIONS),
                     help="these rows only (and the baseline)")
    cmd.add_argument("--steps", type=positive_int, default=ABLATION_STEPS,
                     help=f"steps of 32 per row (default: {ABLATION_STEPS})")
    cmd.add_argument("--samples", type=positive_int, default=512, metavar="N", help="eval portraits (512)")
    cmd.add_argument("--seed", type=int, default=0, help="seed of every row's data and initialisation")
    cmd.add_argument("--threads", type=positive_int, default=None, help="torch threads of the training")
    cmd.add_argument("--log-every", type=positive_int, default=20, metavar="N")
    cmd.add_argument("--checkpoint-every", type=positive_int, default=100, metavar="N")
    cmd.set_defaults(func=run_ablate)
    return cmd


def run_ablate(args: argparse.Namespace) -> int:
    """Run ``kornia-ilum ablate``; prints the table.

    Args:
        args: the options of :func:`add_ablate_parser`'s parser.

    Returns:
        the exit status, 0 (a failure raises).
    """
    result = run_ablations(args.only or list(ABLATIONS), args.out, cache=args.cache, eval_cache=args.eval_cache,
                           hdri=args.hdri, steps=args.steps, samples=args.samples, seed=args.seed,
                           threads=args.threads, log_every=args.log_every, checkpoint_every=args.checkpoint_every)
    print(format_ablations(result), end="")
    print(f"wrote {Path(args.out) / 'ablations.md'} and {Path(args.out) / 'ablations.json'}")
    return 0
